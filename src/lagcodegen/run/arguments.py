"""Stage helper for run: check the arguments of `simulate` and `sweep` before any C call.

Every check raises an error naming the argument (``h``, ``t_end``, ``stride``, a parameter or a
state variable) instead of letting ``float()``, ``range()``, numpy or cffi fail anonymously
(an OverflowError from cffi for a step count beyond C ``long``, a TypeError from a comparison
with ``None``). Wrong types raise TypeError, wrong values ValueError.

`output_bytes` and `check_output_size` estimate the memory a run keeps before it is allocated
and refuse more than `output_limit` (half the physical memory), with the size and a ``stride``
that fits in the message; the CLI reuses them.
"""
from __future__ import annotations

import math
import numbers
import operator
import os
import warnings

import numpy as np

#: the C drivers count steps in ``long``; 64 bits on every platform lagcodegen builds for but
#: Windows (where cffi's own range check still raises, after this one)
MAX_STEPS = 2 ** 63 - 1
#: the fraction of physical memory a run's kept samples may take
OUTPUT_MEMORY_FRACTION = 0.5
_FALLBACK_LIMIT = 16 * 2 ** 30


def keyed_by_name(mapping, what: str) -> dict:
    """``mapping`` with its keys as names: a str as it is, a sympy Symbol or dynamicsymbol by its
    ``name`` (so ``{q1: 1.0}`` and ``{"q1": 1.0}`` mean the same); two keys of one name raise."""
    named: dict = {}
    for key, value in mapping.items():
        name = key if isinstance(key, str) else str(getattr(key, "name", key))
        if name in named:
            raise ValueError(f"{what} names {name!r} twice")
        named[name] = value
    return named


def real_number(value, what: str) -> float:
    """``value`` as a finite float; TypeError for non-numbers (str, None, bool, complex),
    ValueError for NaN, infinities and ints too large for a double, each naming ``what``."""
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise TypeError(f"{what} must be a real number, got {value!r} ({type(value).__name__})")
    try:
        number = float(value)
    except (OverflowError, TypeError, ValueError) as error:
        raise ValueError(f"{what} = {value!r} is not representable as a double ({error})") from None
    if not math.isfinite(number):
        raise ValueError(f"{what} must be finite, got {number}")
    return number


def real_values(values, names, what: str) -> list:
    """``[real_number(v, f"{what} {name!r}") ...]``: one float per named entry."""
    return [real_number(value, f"{what} {name!r}") for name, value in zip(names, values)]


def flag(value, what: str) -> bool:
    """``value`` as a bool; only True/False (numpy's too): ``energy="no"`` must not mean yes."""
    if not isinstance(value, (bool, np.bool_)):
        raise TypeError(f"{what} must be True or False, got {value!r} ({type(value).__name__})")
    return bool(value)


def positive_int(value, what: str) -> int:
    """``value`` as a positive int (numpy integers welcome, bools and floats not)."""
    if isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{what} must be a positive integer, got {value!r}")
    try:
        number = operator.index(value)
    except TypeError:
        raise ValueError(f"{what} must be a positive integer, got {value!r} ({type(value).__name__})") from None
    if number < 1:
        raise ValueError(f"{what} must be a positive integer, got {value!r}")
    return number


def method_name(method) -> str:
    """The method name, lower case; TypeError naming ``method`` for anything but a string."""
    if not isinstance(method, str):
        raise TypeError(f"method must be a method name (str), got {method!r} ({type(method).__name__})")
    return method.lower()


def step_count(t0: float, t_end: float, h: float) -> int:
    """Number of steps of size h from t0 to t_end; t_end - t0 must be a multiple of h."""
    t0, t_end, h = real_number(t0, "t0"), real_number(t_end, "t_end"), real_number(h, "h")
    if not h > 0:
        raise ValueError(f"step h must be positive and finite, got {h}")
    span = t_end - t0
    if not math.isfinite(span):
        raise ValueError(f"t_end - t0 = {t_end} - {t0} overflows a double")
    if not span > 0:
        raise ValueError(f"t_end ({t_end}) must be greater than t0 ({t0})")
    ratio = span / h
    if not ratio < MAX_STEPS:  # also inf, for a subnormal h
        raise ValueError(f"t_end - t0 = {span:g} with step h = {h:g} is {ratio:.3g} steps, more than the "
                         f"C step counter holds (2^63 - 1): raise h or shorten t_end")
    n = int(round(ratio))
    if n < 1 or abs(n * h - span) > 1e-9 * max(1.0, abs(span)):
        raise ValueError(f"t_end - t0 = {span} is not a whole number of steps h = {h}")
    return n


class FloatTimeWarning(UserWarning):
    """A run reaches times where the kernel's precision (float, or double far from 0) cannot resolve its step."""


def check_time_resolution(layout, t0: float, t_end: float, h: float) -> None:
    """The kernel holds t in its precision: past about 2^22 steps from 0 (float) or 2^51 (double)
    its spacing exceeds h/4, and t0 + k h no longer tells the steps apart (found by review: with
    t/h near 2^23 in float, and with t0 = 2^40, h = 2^-14 in double, an array of inputs per step was
    read at the wrong rows, status OK). A driven model is refused (its inputs are looked up by
    time); any other run gets a FloatTimeWarning (the recorded times, and the time an explicitly
    time-dependent model sees, are that coarse)."""
    largest = max(abs(t0), abs(t_end))
    single = layout.precision == "float"
    spacing = float(np.spacing(np.float32(largest) if single else np.float64(largest)))
    if not spacing > abs(h) / 4:
        return
    text = (f"a {'float' if single else 'double'} kernel holds the time in {'float' if single else 'double'}, "
            f"whose spacing near t = {largest:g} is {spacing:.3g}, more than h/4 = {abs(h) / 4:.3g}")
    remedy = ("use a double kernel (precision='double'), a larger h, or times nearer 0" if single else
              "use a larger h, or times nearer 0 (count them from the run's start)")
    if layout.inputs:
        raise ValueError(f"{text}: the inputs {', '.join(layout.inputs)} would be read at the wrong steps; {remedy}")
    warnings.warn(f"{text}: the recorded times, and the time the model sees, are that coarse; {remedy}",
                  FloatTimeWarning, stacklevel=3)


class StrideWarning(UserWarning):
    """The stride does not divide the step count: the samples end before the final state."""


def stride_within(stride, n_steps: int) -> int:
    """``stride`` checked as a positive int no larger than the step count (a larger one keeps
    only the initial state and silently drops the final one); a `StrideWarning` when it does not
    divide the step count (the last sample is then not the final state)."""
    stride = positive_int(stride, "stride")
    if stride > n_steps:
        raise ValueError(f"stride = {stride} exceeds the number of steps ({n_steps}): only the initial "
                         f"state would be kept; use stride <= {n_steps}")
    if n_steps % stride:
        warnings.warn(StrideWarning(
            f"stride = {stride} does not divide the {n_steps} steps: the samples end after step "
            f"{n_steps - n_steps % stride}, {n_steps % stride} step(s) before the final state (a sweep's "
            "x_final is the final state); use a stride that divides the step count"), stacklevel=3)
    return stride


def output_limit() -> int:
    """Bytes a run may keep: `OUTPUT_MEMORY_FRACTION` of the physical memory (16 GiB when the
    platform does not say)."""
    try:
        total = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):
        return _FALLBACK_LIMIT
    return int(total * OUTPUT_MEMORY_FRACTION) if total > 0 else _FALLBACK_LIMIT


def output_bytes(layout, n_steps: int, stride: int = 1, *, n_members: int = 1, energy: bool = False,
                 points: bool = False, residuals: bool = False, multipliers: bool = False,
                 trajectory: bool = True) -> int:
    """Bytes of the samples a run keeps: n_members * (n_steps // stride + 1) samples of
    t, x (2n), and the optional energy (1), points (3 per point), residuals (2m) and multipliers
    with constraint forces (m + n). ``layout`` is ``system.layout``; ``trajectory=False`` (a sweep
    keeping final states only) counts none."""
    if not trajectory:
        return 0
    n, m = layout.n_u, layout.n_constraints
    per_sample = 1 + layout.n_state + energy + 3 * len(layout.points) * points + 2 * m * residuals + \
        (m + n) * multipliers
    itemsize = 4 if layout.precision == "float" else 8
    return n_members * (n_steps // stride + 1) * per_sample * itemsize


def check_output_size(nbytes: int, n_steps: int, stride: int, what: str, limit: int | None = None,
                      size_of=None) -> None:
    """Refuse (`OutputTooLargeError`) when ``nbytes`` of kept samples exceed ``limit`` (default
    `output_limit`), naming the size and the smallest stride that fits: by bisection on
    ``size_of(stride)`` (the bytes at that stride, fixed parts included) when given, else with
    ``nbytes`` taken as proportional to the samples."""
    bound = output_limit() if limit is None else _checked_limit(limit)
    if nbytes <= bound:
        return
    samples = n_steps // stride + 1
    if size_of is None:
        size_of = lambda s: nbytes * (n_steps // s + 1) / samples  # noqa: E731
    smallest = None
    if size_of(n_steps) <= bound:  # the size does not grow with the stride: bisect for the least that fits
        low, high = stride, n_steps  # size_of(low) > bound >= size_of(high)
        while high - low > 1:
            middle = (low + high) // 2
            low, high = (low, middle) if size_of(middle) <= bound else (middle, high)
        smallest = high
    hint = "run fewer members"
    if smallest is not None:
        # the least that also divides the steps (found by review: the suggestion then warned that the
        # samples end before the final state)
        bound_search = min(n_steps, 2 * smallest, smallest + 10 ** 6)  # a bounded search: n_steps can be 1e12
        dividing = next((d for d in range(smallest, bound_search + 1) if n_steps % d == 0), None)
        hint = f"keep fewer samples with stride >= {smallest}" + (
            f" ({dividing}, the least such that divides the {n_steps} steps, keeps the final state)"
            if dividing is not None and dividing != smallest else "")
    check_memory(nbytes, f"{what} would keep {samples} samples", hint, limit)


def check_memory(nbytes: int, what: str, hint: str, limit: int | None = None) -> None:
    """Refuse (`OutputTooLargeError`) ``nbytes`` above ``limit`` (default `output_limit`)."""
    source = "half the physical memory" if limit is None else "max_output_bytes"
    limit = output_limit() if limit is None else _checked_limit(limit)
    if nbytes > limit:
        raise OutputTooLargeError(f"{what}: {format_bytes(nbytes)}, more than the limit of "
                                  f"{format_bytes(limit)} ({source}); {hint}")


def _checked_limit(limit) -> int:
    """``max_output_bytes`` as a positive int; TypeError or ValueError naming it ("1e9" failed in a
    comparison with no name, -1 gave "more than the limit of -1 B")."""
    if isinstance(limit, bool) or not isinstance(limit, numbers.Integral):
        raise TypeError(f"max_output_bytes must be a positive integer (bytes), got {type(limit).__name__} {limit!r}")
    if limit <= 0:
        raise ValueError(f"max_output_bytes must be a positive integer (bytes), got {limit}")
    return int(limit)


def format_bytes(n: float) -> str:
    """``n`` bytes as e.g. ``"7.28 TiB"``."""
    units, k = ("B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"), 0
    while n >= 1024 and k < len(units) - 1:
        n, k = n / 1024, k + 1
    return f"{n:.3g} {units[k]}" if k else f"{n:.0f} B"


class OutputTooLargeError(ValueError):
    """The samples a run would keep do not fit in memory; the message gives the size and a stride."""


def unwritable(target) -> str | None:
    """Why the file ``target`` cannot be written (strerror), or None: opened for appending and
    removed again if it was new (os.access says yes to root everywhere, /proc included)."""
    from pathlib import Path

    target = Path(target)
    existed = target.exists()
    try:
        with open(target, "ab"):
            pass
    except OSError as error:
        return error.strerror or str(error)
    if not existed:
        target.unlink()
    return None


def missing_constraints(layout, asked) -> str:
    """Why the options ``asked`` (project, residuals, multipliers) do not apply to a model without
    constraints kept with multipliers: it has none, or it eliminated its velocity constraints."""
    need = f"{', '.join(f'{name}=True' for name in asked)} need{'s' if len(asked) == 1 else ''}"
    if layout.dependent_speeds:
        return (f"{need} constraints kept with multipliers; model {layout.model!r} eliminates its velocity "
                f"constraints (dependent speeds {', '.join(layout.dependent_speeds)}), which then hold to "
                "round-off without projection and have no multipliers; Model(..., formulation='multipliers') "
                "keeps them")
    return f"{need} constraints (holonomic or on the velocities); model {layout.model!r} has none"
