"""Stage helper for run: the members of a sweep (a Cartesian grid or an explicit table) as
per-member initial states and parameter vectors, every axis checked by name.
"""
from __future__ import annotations

import numbers
from collections.abc import Mapping, Sequence

import numpy as np

from ..native.build import CompiledSystem
from .simulate import check_signs, initial_state, parameter_vector, real_dtype


def cartesian_members(grid: Mapping[str, Sequence[float]]) -> tuple[tuple, np.ndarray, tuple]:
    """(columns, values (n_members, n_columns), axes) of the Cartesian product of ``grid``."""
    columns, axes = grid_axes(grid)
    return columns, cartesian_product(axes), axes


def grid_axes(grid: Mapping[str, Sequence[float]]) -> tuple[tuple, tuple]:
    """(columns, axes): the checked axes of a grid; errors name the axis."""
    if not isinstance(grid, Mapping):
        raise TypeError(f"grid must be a mapping name -> values, got {type(grid).__name__}")
    if not grid:
        raise ValueError("the grid is empty: give at least one name with values")
    columns = _column_names(grid)
    axes = tuple(column_values(name, axis, "grid axis") for name, axis in zip(columns, grid.values()))
    for name, axis in zip(columns, axes):
        if axis.size == 0:
            raise ValueError(f"grid axis {name!r} has no values")
    return columns, axes


def cartesian_product(axes) -> np.ndarray:
    """(prod len, len(axes)) rows of the product of ``axes`` in C order (last axis fastest)."""
    mesh = np.meshgrid(*axes, indexing="ij")
    return np.column_stack([m.ravel() for m in mesh]).astype(float) if mesh else np.empty((1, 0))


def table_members(members: Mapping[str, Sequence[float]]) -> tuple[tuple, np.ndarray]:
    """(columns, values) of an explicit member table: equal-length columns by name."""
    if not isinstance(members, Mapping):
        raise TypeError(f"members must be a mapping name -> values, got {type(members).__name__}")
    if not members:
        raise ValueError("the member table is empty")
    columns = _column_names(members)
    arrays = [column_values(name, v, "member column") for name, v in zip(columns, members.values())]
    lengths = {a.size for a in arrays}
    if len(lengths) != 1 or 0 in lengths:
        raise ValueError(f"member table columns must be non-empty and equally long, got lengths "
                         f"{dict(zip(columns, (a.size for a in arrays)))}")
    return columns, np.column_stack(arrays)


def _column_names(table: Mapping) -> tuple:
    columns = tuple(getattr(name, "name", str(name)) for name in table)
    twice = sorted({name for name in columns if columns.count(name) > 1})
    if twice:
        raise ValueError(f"{', '.join(map(repr, twice))} given more than once")
    return columns


def column_values(name: str, values, what: str) -> np.ndarray:
    """One grid axis or table column as a 1-D float array (a scalar is one value); TypeError
    for non-numbers, ValueError for nested or ragged values, naming the column."""
    if np.ma.is_masked(values):  # np.asarray keeps the masked entries' values: they would run
        raise ValueError(f"{what} {name!r} is a masked array with masked entries; pass only the values to run")
    try:
        array = np.asarray(values)
    except ValueError as error:  # ragged nesting
        raise ValueError(f"{what} {name!r} has values of uneven shape ({error})") from None
    if array.ndim > 1:
        raise ValueError(f"{what} {name!r} must be a flat sequence of numbers, got shape {array.shape}")
    if array.dtype.kind not in "iuf":  # strings, bools, complex, or objects to look at one by one
        # the caller's own objects where possible: numpy turns (1.0, "x") into two strings
        items = list(values) if isinstance(values, (list, tuple)) else array.astype(object).ravel()
        bad = [v for v in items if isinstance(v, (bool, np.bool_)) or not isinstance(v, numbers.Real)]
        if bad:
            raise TypeError(f"{what} {name!r} holds a non-number: {bad[0]!r} ({type(bad[0]).__name__})")
    try:
        return array.astype(float).ravel()
    except OverflowError:
        raise ValueError(f"{what} {name!r} holds a number beyond the double range") from None


def member_arrays(system: CompiledSystem, columns, values, x0, params):
    """Per-member x0 (n_members, 2n) and p (n_members, n_p) for the columns varied."""
    layout = system.layout
    state_names = layout.coordinates + layout.speeds
    fixed = {name for name, _ in layout.fixed}
    for name in columns:
        if name in fixed:
            raise ValueError(f"{name!r} is fixed at build time and cannot be swept; free parameters: "
                             f"{', '.join(layout.parameters) or 'none'}")
        if name not in layout.parameters and name not in state_names and name not in layout.inputs:
            inputs = f", nor an input ({', '.join(layout.inputs)})" if layout.inputs else ""
            raise ValueError(f"cannot sweep {name!r}: not a free parameter ({', '.join(layout.parameters) or 'none'})"
                             f" nor a state variable ({', '.join(state_names)}){inputs}")
    bad = np.argwhere(~np.isfinite(values))
    if bad.size:  # found by review: one NaN among 10000 members was named by column only
        member, j = bad[0]
        raise ValueError(f"swept {columns[j]!r} = {float(values[member, j])!r} (member {member}) is not finite")
    dtype = real_dtype(system)
    if isinstance(x0, Mapping):  # swept state variables need no base value
        x0 = {**{name: 0.0 for name in columns if name in state_names}, **x0}
    base_x = initial_state(system, x0)
    base_p = parameter_vector(system, params)
    xs = np.repeat(base_x[None, :], len(values), axis=0)
    ps = np.repeat(base_p[None, :], len(values), axis=0) if base_p.size else np.zeros((len(values), 1), dtype)
    for j, name in enumerate(columns):
        if name in layout.parameters:
            ps[:, layout.parameters.index(name)] = values[:, j]
        elif name in state_names:
            xs[:, state_names.index(name)] = values[:, j]
    for j, name in enumerate(columns):
        if name in layout.parameters or name in state_names:
            with np.errstate(over="ignore"):  # the overflow is what this finds (numpy warned of the cast)
                beyond = np.nonzero(~np.isfinite(values[:, j].astype(dtype)))[0]
            if beyond.size:  # finite doubles beyond the float range
                raise ValueError(f"swept {name!r} = {float(values[beyond[0], j])!r} (member {beyond[0]}) is beyond the "
                                 f"range of the {layout.precision} kernel")
    if layout.parameters:
        check_signs(layout, ps, lambda name, member: f"swept {name!r} (member {member})", names=set(columns))
    return np.ascontiguousarray(xs, dtype=dtype), np.ascontiguousarray(ps, dtype=dtype)


def check_member_starts(system: CompiledSystem, xs, ps, t0: float, columns, values) -> None:
    """Every member's initial state as `simulate` checks it (`simulate.check_start`): a ValueError
    naming the first member off Kane's configuration constraints; and a `ConstraintDriftWarning`
    naming the members that start off constraints with multipliers by more than the drift tolerance
    (simulate warns of the same through its residuals). A member whose eliminated dependent speeds
    cannot be solved at its start (a singular constraint Jacobian in them) is left to the run, which
    gives it SINGULAR_CONSTRAINTS as it gives a singular start of any other model (found by review:
    one such member refused the whole sweep)."""
    from .drift import DRIFT_TOLERANCE
    from .simulate import _check_configuration, member_offsets

    layout = system.layout
    configured = f"{layout.prefix}_project" in layout.functions and not layout.n_constraints
    if not (configured or layout.n_constraints):
        return  # nothing a start can violate (eliminated speeds: a singular start is left to the run)
    n_p = len(layout.parameters)
    tolerance = DRIFT_TOLERANCE[layout.precision]
    if configured:
        for i, (x, p) in enumerate(zip(xs, ps)):
            try:
                _check_configuration(system, x, p[:n_p], t0)
            except ValueError as error:
                raise ValueError(f"member {i} ({_member_text(columns, values[i])}): {error}") from None
    offsets = member_offsets(system, xs, ps[:, :n_p], t0)
    off = [] if offsets is None else [(int(i), float(offsets[i])) for i in np.flatnonzero(~(offsets <= tolerance))]
    _warn_off(off, f"start off the constraints of model {layout.model!r} (max |phi| or |A u + dphi/dt| > "
                   f"{tolerance:g})", "start each member on its constraints", columns, values, start=True)


def check_member_ends(system: CompiledSystem, x_final, ps, t_end: float, status, columns, values) -> None:
    """A `ConstraintDriftWarning` naming the members that ended OK but off their constraints with
    multipliers by more than the drift tolerance (a sweep keeps no residuals: its members' drift
    went unseen where simulate warns; found by review, a pendulum in Cartesian coordinates ended
    2 % short of its rod with status OK)."""
    from .drift import DRIFT_TOLERANCE
    from .simulate import Status, member_offsets

    layout = system.layout
    if not layout.n_constraints:
        _check_configuration_ends(system, x_final, ps, t_end, status, columns, values)
        return
    n_p, tolerance = len(layout.parameters), DRIFT_TOLERANCE[layout.precision]
    ended = np.flatnonzero(np.asarray(status) == int(Status.OK))
    offsets = member_offsets(system, np.asarray(x_final)[ended], np.asarray(ps)[ended, :n_p], t_end)
    drifted = [] if offsets is None else np.flatnonzero(~(offsets <= tolerance))
    off = [(int(ended[k]), float(offsets[k])) for k in drifted]
    _warn_off(off, f"of model {layout.model!r} drifted off the constraints (max |phi| or |A u + dphi/dt| > "
                   f"{tolerance:g} at the end)", "sweep with project=True or a smaller h", columns, values)


def _check_configuration_ends(system: CompiledSystem, x_final, ps, t_end: float, status, columns, values) -> None:
    """The same for Kane's configuration constraints of an eliminated build (``<prefix>_project``
    solves them for the dependent coordinates, as `drift.warn_if_configuration_drifted` does for
    simulate): members that ended OK with a dependent coordinate more than the drift tolerance from
    where the constraints put it (found by review: a Kane four-bar swept for 500 s opened its loop
    by 2.6e-4 with status OK and no word, where simulate warned)."""
    from .drift import DRIFT_TOLERANCE
    from .simulate import Status, projected_rows

    layout = system.layout
    if f"{layout.prefix}_project" not in layout.functions:
        return
    n_p, tolerance = len(layout.parameters), DRIFT_TOLERANCE[layout.precision]
    ended = np.flatnonzero(np.asarray(status) == int(Status.OK))
    states = np.asarray(x_final)[ended]
    codes, projected = projected_rows(system, np.full(len(ended), t_end), states, np.asarray(ps)[ended, :n_p])
    moved = np.abs(projected[:, :layout.n_q] - states[:, :layout.n_q]).astype(np.float64).max(axis=1, initial=0.0)
    off = [(int(ended[k]), np.inf if codes[k] != 0 else float(moved[k]))
           for k in np.flatnonzero((codes != 0) | ~(moved <= tolerance))]
    _warn_off(off, f"of model {layout.model!r} drifted off the configuration constraints (a dependent coordinate "
                   f"more than {tolerance:g} from where they put it at the end)", "sweep with project=True or a "
                   "smaller h", columns, values)


def _warn_off(off: list, what: str, advice: str, columns, values, start: bool = False) -> None:
    """One `ConstraintDriftWarning` (at the ``start``: `StartOffConstraintsWarning`) for the members
    (index, offset) in ``off``, naming the worst."""
    import warnings

    from .drift import ConstraintDriftWarning, StartOffConstraintsWarning

    if off:
        worst = max(off, key=lambda item: item[1] if item[1] == item[1] else np.inf)
        example = _member_text(columns, values[worst[0]])
        warnings.warn(f"{len(off)} member(s) {what}, e.g. member {worst[0]} ({example}) with {worst[1]:.3g}: {advice}",
                      StartOffConstraintsWarning if start else ConstraintDriftWarning, stacklevel=4)


def _member_text(columns, row) -> str:
    return ", ".join(f"{name} = {float(value):g}" for name, value in zip(columns, row))


def member_input_tables(system: CompiledSystem, columns, values, inputs, member_inputs, t0: float, h: float,
                        n_steps: int, stride: int, hold: str = "zoh", limit: int | None = None):
    """Per-member input tables (times (n_members, k), values (n_members, k, n_r)) for a driven model.

    A swept input (a column named like it) scales that input's base signal from ``inputs``
    (constant 1 where ``inputs`` gives none): its amplitude. ``member_inputs`` instead gives each
    member its own inputs, as `simulate` takes them (no callables); shorter tables are padded
    with their last knot, which reads the same. ``limit``: as ``max_output_bytes``, the tables
    counted against it before they are made (found by review: 400 members of a 20001-knot table
    took 262 MiB under max_output_bytes = 1e6).
    """
    from .arguments import check_memory
    from .inputs import InputError, InputTable, resolve_inputs

    def check_tables(knots: int) -> None:  # times and values, and the kernel's copy of both
        check_memory(2 * 8 * n_members * knots * (1 + n_r), f"the input tables of the sweep's {n_members} members "
                     f"({knots} knots each) would need", "sweep fewer members or give coarser input tables", limit)

    layout = system.layout
    n_members, n_r = len(values), len(layout.inputs)
    if not n_r:
        if inputs is not None or member_inputs is not None:
            raise InputError(f"model {layout.model!r} has no inputs; drop inputs= and member_inputs=")
        return None
    swept = [j for j, name in enumerate(columns) if name in layout.inputs]
    if member_inputs is not None:
        if inputs is not None or swept:
            raise ValueError("give member_inputs= alone: not with inputs= or swept inputs")
        if isinstance(member_inputs, (str, bytes, Mapping)) or len(member_inputs) != n_members:
            raise InputError(f"member_inputs must give one input spec per member ({n_members}), got "
                             f"{type(member_inputs).__name__}")
        tables, knots = [], 1
        for m, spec in enumerate(member_inputs):
            if callable(spec) and not isinstance(spec, np.ndarray):
                raise InputError(f"member_inputs[{m}] is a callable: sweeps take constants, arrays or tables")
            try:
                tables.append(resolve_inputs(layout, spec, t0, h, n_steps, stride, hold))
            except InputError as error:
                raise InputError(f"member_inputs[{m}]: {error}") from None
            if tables[-1].times.size > knots:
                knots = tables[-1].times.size
                check_tables(knots)
    else:
        swept_names = {columns[j] for j in swept}
        if inputs is None and set(layout.inputs) - swept_names:
            missing = ", ".join(sorted(set(layout.inputs) - swept_names))
            raise InputError(f"model {layout.model!r} is driven by {missing}: pass inputs= (the base signal) "
                             "or sweep it")
        if callable(inputs) and not isinstance(inputs, np.ndarray):
            raise InputError("a sweep takes its inputs as constants, arrays or tables, not a callable")
        if isinstance(inputs, Mapping):  # a swept input inputs= does not name: base 1, as documented
            named = {getattr(key, "name", str(key)) for key in inputs}
            inputs = {**{name: 1.0 for name in sorted(swept_names - named)}, **inputs}
        base = InputTable(np.zeros(1), np.ones((1, n_r))) if inputs is None else \
            resolve_inputs(layout, inputs, t0, h, n_steps, stride, hold)
        check_tables(base.times.size)
        scale = np.ones((n_members, n_r))
        for j in swept:
            scale[:, layout.inputs.index(columns[j])] = values[:, j]
        times = np.repeat(base.times[None, :], n_members, axis=0)
        with np.errstate(over="ignore", invalid="ignore"):
            scaled = base.values[None, :, :] * scale[:, None, :]
        bad = np.argwhere(~np.isfinite(scaled))
        if bad.size:  # 1e300 * 1e10: simulate refuses such an input by name, a sweep ran it
            member, _, column = bad[0]
            raise InputError(f"member {member}: input {layout.inputs[column]!r} scaled by the swept "
                             f"{layout.inputs[column]!r} = {float(scale[member, column])!r} is not finite")
        return times, _within_precision(layout, scaled)
    k = max(t.times.size for t in tables)
    # each member's table, its last knot repeated to k knots (np.pad per member took 56-74 us of it)
    times = np.empty((len(tables), k))
    table_values = np.empty((len(tables), k, tables[0].values.shape[1]))
    for member, table in enumerate(tables):
        size = table.times.size
        times[member, :size], times[member, size:] = table.times, table.times[-1]
        table_values[member, :size], table_values[member, size:] = table.values, table.values[-1]
    return times, _within_precision(layout, table_values)


def _within_precision(layout, values: np.ndarray) -> np.ndarray:
    """``values`` (n_members, k, n_r), checked against a float kernel's range (`inputs.check_float_range`)."""
    from .inputs import check_float_range

    check_float_range(layout, values, members=True)
    return values
