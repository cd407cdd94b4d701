"""Stage helper for run: the inputs r of a driven model, as the C drivers read them.

`simulate` and `sweep` accept the inputs as a constant, an array sampled at every step (or every
stride), a table (t_i, r_i) interpolated linearly in C, or a Python callable of (t, x). The first
three become one `InputTable` of knots (an array of samples becomes a step function under a
zero-order hold, each row held until half a step before the next row's time, and the line through
the rows under a first-order hold); the callable becomes a cffi
callback (`CallableInputs`), a Python call per step. Every check names the input it refused.
"""
from __future__ import annotations

import math
import numbers
import reprlib
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from ..status import Status
from .arguments import keyed_by_name

HOLDS = {"zoh": 0, "foh": 1}
#: a table must reach the run's end to within this fraction of a step (the last time is t0 + n h)
_COVER_SLACK = 1e-9


class InputError(ValueError):
    """Inputs that cannot drive the run; the message names the input."""


@dataclass(frozen=True)
class InputTable:
    """Knots of all inputs: ``times`` (k,) non-decreasing (a repeated time is a jump), ``values``
    (k, n_r); read like the C ``<prefix>_table_inputs``."""

    times: np.ndarray
    values: np.ndarray

    def at(self, t: float) -> np.ndarray:
        """The inputs at time t: linear between knots, the later value at a jump, held beyond the ends."""
        i = int(np.searchsorted(self.times, t, side="right")) - 1
        if i < 0:
            return self.values[0].copy()
        if i + 1 >= len(self.times) or t <= self.times[i]:
            return self.values[i].copy()
        w = (t - self.times[i]) / (self.times[i + 1] - self.times[i])
        return self.values[i] + w * (self.values[i + 1] - self.values[i])

    def before(self, t: float) -> np.ndarray:
        """The limit from the left at time t: at a jump, the value before it (as `at` elsewhere)."""
        i = int(np.searchsorted(self.times, t, side="left"))
        if i < len(self.times) and self.times[i] == t:
            return self.values[i].copy()
        return self.at(t)


def hold_code(hold) -> int:
    """``"zoh"`` (held over each step) or ``"foh"`` (a ramp between the step's ends), as the C flag."""
    if not isinstance(hold, str) or hold.lower() not in HOLDS:
        raise ValueError(f"hold must be one of {', '.join(map(repr, HOLDS))}, got {hold!r}")
    return HOLDS[hold.lower()]


def resolve_inputs(layout, inputs, t0: float, h: float, n_steps: int, stride: int, hold: str = "zoh",
                   exact_jumps: bool = False):
    """``inputs`` as an `InputTable` or, for a callable, the callable itself (checked later, per call).
    An array of samples is a step function under ``hold="zoh"``, the line between them under "foh";
    the step function jumps half a step before each sample time, which is where no driver's step
    starts, or with ``exact_jumps`` at the sample times themselves (for a reader at any time)."""
    names = layout.inputs
    if not names:
        if inputs is not None:
            raise InputError(f"model {layout.model!r} has no inputs; drop inputs=")
        return None
    if inputs is None:
        raise InputError(f"model {layout.model!r} is driven by the input(s) {', '.join(names)}: pass inputs= "
                         "(a constant, an array per step, a table (t, r) or a callable f(t, x))")
    if callable(inputs) and not isinstance(inputs, np.ndarray):
        return inputs
    t_end = t0 + n_steps * h
    if isinstance(inputs, Mapping):
        return _table_by_name(layout, inputs, t0, t_end)
    if _is_table(inputs):
        table = _table(inputs[0], inputs[1], names, ", ".join(names))
        _check_cover(table, t0, t_end, h, ", ".join(names))
        return table
    values = np.asarray(_numbers(inputs, ", ".join(names)), dtype=float)
    n_r = len(names)
    if values.ndim == 0 or (values.ndim == 1 and values.size == n_r):
        return _constant(values.reshape(n_r), names)
    if values.ndim == 1 and n_r == 1:
        values = values.reshape(-1, 1)
    if values.ndim != 2 or values.shape[1] != n_r:
        raise InputError(f"inputs of shape {values.shape} do not fit the {n_r} input(s) {', '.join(names)}: give "
                         f"{n_r} constant value(s), an array of shape (steps, {n_r}), a table (t, r) or a callable")
    return _sampled(values, names, t0, h, n_steps, stride, linear=hold_code(hold) == HOLDS["foh"],
                    margin=0.0 if exact_jumps else h / 2)


def is_sampled(layout, inputs) -> bool:
    """``inputs`` is an array of rows per step or stride (not a constant, table, mapping or callable)."""
    if inputs is None or callable(inputs) or isinstance(inputs, Mapping) or _is_table(inputs):
        return False
    try:
        return np.size(inputs) > len(layout.inputs)
    except (TypeError, ValueError):
        return False


def _is_table(inputs) -> bool:
    if not isinstance(inputs, tuple) or len(inputs) != 2:
        return False
    return all(not isinstance(part, (str, bytes)) and np.ndim(part) >= 1 for part in inputs)


def _holds_bool(values) -> bool:
    """True when a list or tuple (nested) holds a bool: numpy reads [True, 0.0] as the floats [1.0, 0.0]
    (found 2026-11-27: a constant, a table or rows of inputs so ran with 1.0, where a bool alone is refused)."""
    stack = [values]
    while stack:
        value = stack.pop()
        if isinstance(value, (bool, np.bool_)):
            return True
        if isinstance(value, (list, tuple)):
            stack.extend(value)
    return False


def _numbers(values, what: str):
    """``values`` as a float array; a TypeError naming ``what`` for strings, bools, None or objects."""
    try:
        raw = np.asarray(values)
        if raw.dtype.kind in "bUSc":
            raise TypeError(f"dtype {raw.dtype}")
        if isinstance(values, (list, tuple)) and _holds_bool(values):
            raise TypeError("a bool is not a number")
        if raw.dtype == object and any(v is None for v in raw.ravel()):
            raise TypeError("None is not a number")
        return np.asarray(values, dtype=float)
    except (TypeError, ValueError, OverflowError) as error:
        # reprlib: a million rows of a per-step signal would otherwise all be printed
        raise TypeError(f"input {what}: values must be real numbers, got {reprlib.repr(values)} ({error})") from None


def _finite(values: np.ndarray, names, times=None) -> None:
    bad = ~np.isfinite(values)
    if bad.any():
        row, column = (int(i) for i in np.argwhere(bad)[0])
        where = f" at t = {times[row]:g}" if times is not None else ""
        raise InputError(f"input {names[column]!r} is not finite{where}: {values[row, column]}")


def _constant(values: np.ndarray, names) -> InputTable:
    values = values.reshape(1, -1)
    _finite(values, names)
    return InputTable(times=np.zeros(1), values=values)


def _sampled(values: np.ndarray, names, t0: float, h: float, n_steps: int, stride: int,
             linear: bool = False, margin: float = 0.0) -> InputTable:
    """An array per step (n_steps or n_steps + 1 rows) or per stride: under a zero-order hold a step
    function, row k held until row k + 1 takes over ``margin`` before its time (half a step: a
    driver's step time that rounds below the sample time, as in float, still reads row k + 1 there);
    under a first-order hold the line between rows (the last row held when none is given for the end)."""
    rows = values.shape[0]
    spacing = None
    for every in dict.fromkeys((1, stride)):
        samples = n_steps // every
        if rows in (samples, samples + 1) and samples * every == n_steps:
            spacing = every
            break
    if spacing is None:
        expected = f"{n_steps} or {n_steps + 1}"
        if stride > 1 and n_steps % stride == 0:
            expected += f" (per step), or {n_steps // stride} or {n_steps // stride + 1} (per stride {stride})"
        raise InputError(f"inputs {', '.join(names)}: an array of {rows} rows does not match the run: "
                         f"expected {expected} rows")
    times = t0 + (np.arange(rows) * spacing) * h  # as t0 + k * spacing * h, bit for bit (k * spacing exact)
    _finite(values, names, times)
    if linear:
        return InputTable(times=times, values=values)
    # knots (t_0, r_0), (t_1 - margin, r_0), (t_1 - margin, r_1), (t_2 - margin, r_1), ...: the jumps to r_k
    jumps = np.repeat(times[1:] - margin, 2)
    step_times = np.concatenate([times[:1], jumps])
    step_values = np.repeat(values, 2, axis=0)[:-1]
    return InputTable(times=step_times, values=step_values)


def _table(times, values, names, what: str) -> InputTable:
    times = np.asarray(_numbers(times, what), dtype=float)
    values = np.asarray(_numbers(values, what), dtype=float)
    if times.ndim != 1:
        raise InputError(f"input {what}: the table's times must be a 1-D array, got shape {times.shape}")
    if times.size < 1:
        raise InputError(f"input {what}: the table has no knots (empty times)")
    if values.ndim == 1 and len(names) == 1:
        values = values.reshape(-1, 1)
    if values.shape != (times.size, len(names)):
        raise InputError(f"input {what}: a table of {times.size} times needs values of shape "
                         f"({times.size}, {len(names)}) (or ({times.size},) for one input), got {values.shape}")
    if not np.all(np.isfinite(times)):
        raise InputError(f"input {what}: the table's times are not finite: {times[~np.isfinite(times)][0]}")
    steps = np.diff(times)
    if np.any(steps <= 0):
        k = int(np.argmax(steps <= 0))
        raise InputError(f"input {what}: the table's times must increase, but t[{k + 1}] = {times[k + 1]:g} "
                         f"follows t[{k}] = {times[k]:g}")
    _finite(values, names, times)
    return InputTable(times=times, values=values)


def _check_cover(table: InputTable, t0: float, t_end: float, h: float, what: str) -> None:
    check_cover(table.times, t0, t_end, h, what)


def check_cover(times, t0: float, t_end: float, h: float, what: str) -> None:
    """InputError unless a table of ``times`` (one knot: a constant) covers the run t0 .. t_end."""
    if len(times) == 1:
        return
    slack = _COVER_SLACK * abs(h)
    if times[0] > t0 + slack or times[-1] < t_end - slack:
        raise InputError(f"input {what}: the table covers t = {times[0]:g} .. {times[-1]:g}, "
                         f"shorter than the run t = {t0:g} .. {t_end:g}")


def _table_by_name(layout, inputs: Mapping, t0: float, t_end: float) -> InputTable:
    """{name: constant or (times, values)}: every input named once; tables merged on the union of
    their knots (linear interpolation on a finer grid reproduces each piecewise-linear signal)."""
    names = layout.inputs
    given = keyed_by_name(inputs, "inputs")
    unknown = [k for k in given if k not in names]
    if unknown:
        raise InputError(f"unknown input(s) {', '.join(unknown)}; inputs of {layout.model!r}: {', '.join(names)}")
    missing = [k for k in names if k not in given]
    if missing:
        raise InputError(f"no value for input(s) {', '.join(missing)} of {layout.model!r}")
    tables = []
    for name in names:
        value = given[name]
        if _is_table(value):
            table = _table(value[0], value[1], (name,), repr(name))
            _check_cover(table, t0, t_end, 1.0, repr(name))
        elif isinstance(value, numbers.Real) and not isinstance(value, bool) or \
                (isinstance(value, np.ndarray) and value.ndim == 0):
            if isinstance(value, (bool, np.bool_)):
                raise TypeError(f"input {name!r} must be a real number, got {value!r}")
            table = _constant(np.array([float(value)]), (name,))
        else:
            raise InputError(f"input {name!r}: give a constant or a table (times, values), got {value!r}")
        tables.append(table)
    knots = np.unique(np.concatenate([t.times for t in tables if t.times.size > 1] or [np.zeros(1)]))
    # np.interp is `InputTable.at` for these strictly increasing tables, over all knots at once (found
    # by review: a Python loop over 1e6 knots took 9.6 s)
    values = np.column_stack([np.interp(knots, table.times, table.values[:, 0]) for table in tables])
    return InputTable(times=knots, values=values)


def check_float_range(layout, values: np.ndarray, members: bool = False) -> None:
    """An InputError naming the first input value (..., n_r) beyond the range of a float kernel, and
    its member with ``members`` (the leading axis): the lane kernel called it a diverged state, the
    scalar one a non-finite input, and simulate stopped at step 1 naming none (found by reviews)."""
    if layout.precision != "float":
        return
    beyond = np.argwhere(np.abs(values) > np.finfo(np.float32).max)
    if beyond.size:
        index = tuple(beyond[0])
        where = f"member {index[0]}: " if members else ""
        raise InputError(f"{where}input {layout.inputs[index[-1]]!r} = {float(values[index])!r} is beyond the "
                         "range of the float kernel")


_PLAIN_NUMBERS = (float, int, np.float64)  # not bool (a subclass of int), not complex or float32


class CallableInputs:
    """A Python callable f(t, x) -> r behind the C drivers' input function (a cffi callback).

    It never raises into C: a wrong shape or an exception stops the run with
    ``Status.INPUT_FAILED``, a NaN or infinite value with ``NONFINITE_INPUT``; ``detail`` says
    which input and why, ``error`` keeps the exception. A KeyboardInterrupt or SystemExit stops
    the run the same way and is raised again once the C call returns (`reraise`).

    One call per step, at the step's start: at ``final_time`` (the run's end, read only for its last
    sample and the singularity monitor's look past it) the values of the last step stay, held as
    over that step (found by review: an extra call at the end advanced a stateful controller once
    more per run, and failed completed runs whose reference had one value per step).
    """

    def __init__(self, system, function: Callable, final_time: float | None = None, h: float | None = None):
        self.function = function
        self.final_time, self.h = final_time, h
        self.last: np.ndarray | None = None
        self.names = system.layout.inputs
        self.n_state = system.layout.n_state
        self.dtype = np.float32 if system.layout.precision == "float" else np.float64
        self._limit = float(np.finfo(self.dtype).max)  # finite values cast to the kernel's precision stay finite
        self.detail: str | None = None
        self.error: BaseException | None = None
        ffi = system.ffi
        self._ffi = ffi
        # error=: what C gets should an exception still escape _call (cffi's default 0 is LCG_OK)
        self.callback = ffi.callback(f"{system.layout.prefix}_input_fn", self._call, error=int(Status.INPUT_FAILED))

    def reraise(self) -> None:
        """Raise a KeyboardInterrupt or SystemExit the callable raised (the run stopped at it)."""
        if isinstance(self.error, (KeyboardInterrupt, SystemExit)):
            raise self.error

    def _fail(self, code: Status, detail: str) -> int:
        self.detail = detail
        return int(code)

    def _call(self, context, t, x_pointer, r_pointer) -> int:
        ffi, dtype = self._ffi, self.dtype
        if self.last is not None and self.final_time is not None and abs(float(t) - self.final_time) <= self.h / 4:
            np.frombuffer(ffi.buffer(r_pointer, self.last.nbytes), dtype=dtype)[:] = self.last
            return int(Status.OK)
        x = np.frombuffer(ffi.buffer(x_pointer, self.n_state * np.dtype(dtype).itemsize), dtype=dtype).copy()
        try:
            result = self.function(float(t), x)
        except BaseException as error:  # noqa: BLE001 - never into C (cffi would print it and return 0, OK)
            self.error = error  # Ctrl-C or SystemExit: the run stops here and `reraise` raises it after
            return self._fail(Status.INPUT_FAILED, f"the input callable raised {type(error).__name__}: {error} "
                                                   f"at t = {float(t):g}")
        try:
            return self._store(result, float(t), r_pointer)
        except BaseException as error:  # noqa: BLE001 - found by review: an int of 400 digits (OverflowError) or a
            # tensor whose __array__ raises escaped into cffi, which returned 0 (OK) with r unwritten
            self.error = error
            return self._fail(Status.INPUT_FAILED, f"reading the input callable's result at t = {float(t):g} raised "
                                                   f"{type(error).__name__}: {error}")

    def _plain(self, result) -> list | None:
        """The values of a plain ``result`` (a list or tuple of Python floats and ints and numpy float64
        scalars, or a 1-D float64 array, of the right length), each finite and within the kernel's range; else None, and
        `_store` checks it in full (found by review: the full checks took 21 us per step, a typical
        controller 0.3 us)."""
        kind = type(result)
        if kind is np.ndarray:
            if result.dtype != np.float64 or result.ndim != 1:
                return None
            result = result.tolist()
        elif kind is not list and kind is not tuple:
            return None
        if len(result) != len(self.names):
            return None
        limit = self._limit
        for v in result:
            if type(v) not in _PLAIN_NUMBERS or not -limit <= v <= limit:
                return None  # a bool, another numpy scalar, NaN, infinite, beyond range: the full checks word it
        return result

    def _store(self, result, t: float, r_pointer) -> int:
        """Check the callable's ``result`` and write it to ``r_pointer``; a status code."""
        ffi, dtype = self._ffi, self.dtype
        plain = self._plain(result)
        if plain is not None:
            cast = np.array(plain, dtype=dtype)
            np.frombuffer(ffi.buffer(r_pointer, cast.nbytes), dtype=dtype)[:] = cast
            self.last = cast
            return int(Status.OK)
        try:
            kind = np.asarray(result).dtype.kind
        except (TypeError, ValueError):  # ragged: refused below
            kind = "O"
        if kind not in "USbc" and isinstance(result, (list, tuple)) and _holds_bool(result):
            kind = "b"  # [True, 0.0] is a float array to numpy
        if kind in "USbc":  # a string would parse as a number, a complex would lose its imaginary part,
            # a bool is refused as a constant input is (found by review: [True] ran as 1.0)
            what = type(result).__name__ if np.ndim(result) == 0 else \
                "bool values" if kind == "b" else f"{np.asarray(result).dtype} values"
            return self._fail(Status.INPUT_FAILED, f"the input callable returned {what} at t = {float(t):g}; "
                                                   f"expected {len(self.names)} real number(s) for "
                                                   f"{', '.join(self.names)}")
        try:
            values = None if result is None else \
                np.asarray(result, dtype=float).reshape(-1) if np.ndim(result) <= 1 else None
        except (TypeError, ValueError):
            values = None
        if values is None or values.size != len(self.names):
            # a dict or another object: its type, not the shape () numpy gives it (found by review)
            shape = np.shape(result) if kind != "O" and result is not None else type(result).__name__
            return self._fail(Status.INPUT_FAILED, f"the input callable returned {shape!r} at t = {float(t):g}; "
                                                   f"expected {len(self.names)} value(s) for {', '.join(self.names)}")
        bad = [name for name, v in zip(self.names, values) if not math.isfinite(v)]
        if bad:
            return self._fail(Status.NONFINITE_INPUT, f"input {bad[0]!r} = {values[self.names.index(bad[0])]} at "
                                                      f"t = {float(t):g}")
        with np.errstate(over="ignore"):
            cast = values.astype(dtype)
        beyond = [name for name, v in zip(self.names, cast) if not math.isfinite(v)]
        if beyond:  # found by review: 1e39 into a float kernel stopped with no word of the input
            value = float(values[self.names.index(beyond[0])])
            return self._fail(Status.NONFINITE_INPUT, f"input {beyond[0]!r} = {value!r} at t = {float(t):g} is beyond "
                                                      "the range of the float kernel")
        out = np.frombuffer(ffi.buffer(r_pointer, len(self.names) * np.dtype(dtype).itemsize), dtype=dtype)
        out[:] = cast
        self.last = cast
        return int(Status.OK)
