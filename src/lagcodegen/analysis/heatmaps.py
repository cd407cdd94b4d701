"""Stage: SweepResult -> figures: heatmaps of one per-member field over a 2-D parameter grid.

A *field* names one number per member: ``"q_max:q1"`` (max |q1| over the run),
``"x_final:phi_d"`` (a final state variable), ``"energy_error"`` (max |E - E0|),
``"blowup_time"``, ``"steps_done"`` or ``"status"``; or it is any (n_members,) array the caller
computed, e.g. `first_crossing_time` from the kept trajectories.

`plot_heatmap` draws the field over two swept columns, x = the second column and y = the first
(the C order of `SweepResult.on_grid`), on log axes where the axis values are geometric. Members
that did not complete (status != OK) are painted grey and counted in the title, so a blow-up is
never mistaken for a small value. The figure is a `matplotlib.figure.Figure` with the Agg canvas
(``fig.savefig``); nothing is shown and no pyplot state is touched. ``fig.axes[0]`` is the map
(data coordinates are the swept values, so theory curves can be drawn on it), ``fig.axes[1]``
the colorbar.
"""
from __future__ import annotations

import math
import warnings
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..run.simulate import Status
from ..run.sweep import CHUNK_FAILED, NOT_RUN, SWEEP_STATUS_NAMES, SweepResult

if TYPE_CHECKING:
    from matplotlib.figure import Figure

#: fields with one value per member, and those that take a state-variable name after a colon
SCALAR_FIELDS = ("energy_error", "blowup_time", "steps_done", "status")
PER_VARIABLE_FIELDS = ("q_max", "x_final", "y_final", "y_min", "y_max")
_MEASUREMENT_LABELS = {"y_final": "final {}", "y_min": "min {} over the run", "y_max": "max {} over the run"}
#: fields that describe failures, so failed members are not greyed out for them
FAILURE_FIELDS = ("blowup_time", "steps_done", "status")
_LABELS = {"energy_error": "max |E - E0| over the run", "blowup_time": "time of failure",
           "steps_done": "steps done", "status": "status"}
_FAILED_GREY, _NOT_RUN_GREY = "0.45", "0.82"
#: +inf, -inf and (log scale) values <= 0 of completed members: colours no default colormap takes
_INFINITE_COLOURS, _NONPOSITIVE_COLOUR = ("#ff1493", "#00bfff"), "#f5deb3"


def resolve_field(field: str, coordinate_names: Sequence[str], state_names: Sequence[str],
                  measurement_names: Sequence[str] = ()) -> tuple:
    """``(attribute, column index or None, label)`` of a field name; ValueError names the culprit.

    ``"q_max"`` alone is accepted for one-coordinate models; otherwise ``"q_max:<coordinate>"``;
    ``y_final``, ``y_min`` and ``y_max`` take a measurement's name.
    """
    attribute, _, variable = str(field).partition(":")
    if attribute in SCALAR_FIELDS and not variable:
        return attribute, None, _LABELS[attribute]
    measured = ", y_final/y_min/y_max:<measurement>" if measurement_names else ""
    if attribute not in PER_VARIABLE_FIELDS:
        raise ValueError(f"unknown field {field!r}; fields: {', '.join(SCALAR_FIELDS)}, "
                         f"q_max:<coordinate>, x_final:<state variable>{measured}")
    kind, names = {"q_max": ("coordinate", coordinate_names), "x_final": ("state variable", state_names)}.get(
        attribute, ("measurement", measurement_names))
    names = tuple(names)
    if not names:
        raise ValueError(f"field {field!r}: the model has no measurements")
    if not variable and len(names) == 1:
        variable = names[0]
    if variable not in names:
        raise ValueError(f"field {field!r} needs a {kind} after the colon: one of {', '.join(names)}")
    label = {"q_max": f"max |{variable}| over the run", "x_final": f"final {variable}"}.get(
        attribute) or _MEASUREMENT_LABELS[attribute].format(variable)
    return attribute, names.index(variable), label


def field_values(result: SweepResult, field: str) -> tuple[np.ndarray, str]:
    """``(values (n_members,) float, label)`` of a named field of a sweep."""
    attribute, column, label = resolve_field(field, result.coordinate_names, result.state_names,
                                             result.measurement_names)
    data = getattr(result, attribute)
    if data is None:
        raise ValueError(f"this sweep recorded no {attribute!r} (a model without energies, or track_energy=False)")
    data = np.asarray(data, dtype=np.float64)
    return (data if column is None else data[:, column]), label


def first_crossing_time(result: SweepResult, names: Sequence[str], threshold: float = math.pi) -> np.ndarray:
    """First time any |x_name| exceeds ``threshold``, per member, from the kept trajectories.

    Between two kept samples the time is interpolated linearly in max |x_name|. A decimated
    trajectory (stride > 1) can step over an excursion shorter than the sample spacing: members
    whose ``q_max`` says they crossed but whose samples never do get NaN and a RuntimeWarning
    (sweep again with a smaller stride). Use: time until the first flip of a pendulum,
    ``first_crossing_time(result, ("q1", "q2"), math.pi)``.

    Returns
    -------
    ndarray (n_members,)
        NaN for members that never cross (within t_end, or before they failed).
    """
    if result.trajectories is None:
        raise ValueError("first_crossing_time needs the trajectories: sweep with trajectories=True")
    unknown = [name for name in names if name not in result.state_names]
    if unknown or not names:
        raise ValueError(f"unknown state variable(s) {unknown or names}; state: {', '.join(result.state_names)}")
    columns = [result.state_names.index(name) for name in names]
    size = np.abs(result.trajectories[:, :, columns]).max(axis=2)  # (n_members, n_out); NaN after a failure
    with np.errstate(invalid="ignore"):
        above = size > threshold
    crossed = above.any(axis=1)
    k = np.argmax(above, axis=1)
    before = np.maximum(k - 1, 0)
    rows = np.arange(len(k))
    a0, a1 = size[rows, before], size[rows, k]
    with np.errstate(invalid="ignore", divide="ignore"):
        fraction = np.where(k > 0, (threshold - a0) / (a1 - a0), 0.0)
    times = result.t[before] + np.clip(fraction, 0.0, 1.0) * (result.t[k] - result.t[before])
    times = np.where(crossed, times, np.nan)
    _warn_missed(result, columns, crossed, threshold)
    return times


def _warn_missed(result: SweepResult, columns, crossed, threshold) -> None:
    coords = [c for c in columns if c < len(result.coordinate_names)]
    if not coords:
        return
    with np.errstate(invalid="ignore"):
        missed = (np.asarray(result.q_max)[:, coords] > threshold).any(axis=1) & ~crossed
    if missed.any():
        warnings.warn(f"{int(missed.sum())} member(s) exceed {threshold:g} between kept samples only; "
                      "their crossing time is NaN (sweep with a smaller stride)", RuntimeWarning, stacklevel=3)


def product_axes(values: np.ndarray, columns: Sequence[str]) -> tuple[tuple, tuple]:
    """``((axis_0, axis_1), (index_0, index_1))`` when the rows of ``values (n_members, 2)``
    form a complete Cartesian product (each pair once); ValueError otherwise."""
    axes, index = [], []
    for j in range(2):
        axis, inverse = np.unique(values[:, j], return_inverse=True)
        axes.append(axis)
        index.append(inverse.ravel())
    pairs = index[0] * len(axes[1]) + index[1]
    if len(values) != len(axes[0]) * len(axes[1]) or len(np.unique(pairs)) != len(values):
        raise ValueError(f"the members do not form a complete grid over {columns[0]!r} x {columns[1]!r} "
                         f"({len(values)} members, {len(axes[0])} x {len(axes[1])} distinct values)")
    return tuple(axes), tuple(index)


def grid_axes(result: SweepResult, x: str | None = None, y: str | None = None) -> tuple:
    """``(names (y, x), axes (y_axis, x_axis), member index (iy, ix))`` of a 2-D view of a sweep.

    Default: a sweep over exactly two columns, y = the first, x = the second. With ``x`` and
    ``y`` named, any sweep (grid or table, extra columns allowed) whose members form a complete
    grid over those two columns.
    """
    if x is None or y is None:
        if len(result.columns) != 2:
            raise ValueError(f"a heatmap needs two swept columns, this sweep varies {', '.join(result.columns)}; "
                             "name both with x= and y=")
        if x is None and y is None:
            y, x = result.columns
        elif x is None:
            x = next((c for c in result.columns if c != y), None)
        else:
            y = next((c for c in result.columns if c != x), None)
        if result.grid is not None and (y, x) == result.columns:
            for name, axis in zip((y, x), result.grid):
                repeated = np.unique(np.asarray(axis, dtype=float), return_counts=True)
                if np.any(repeated[1] > 1):  # found by review: one of the two cells had zero height
                    raise ValueError(f"grid axis {name!r} repeats {float(repeated[0][repeated[1] > 1][0])!r}: a "
                                     "heatmap has one cell per value, so each member of that value could not be "
                                     "shown; sweep distinct values")
            shape = tuple(len(axis) for axis in result.grid)
            return (y, x), tuple(np.asarray(a, dtype=float) for a in result.grid), \
                np.unravel_index(np.arange(result.n_members), shape)
    missing = [name for name in (y, x) if name not in result.columns]
    if missing:
        raise ValueError(f"not swept: {', '.join(map(repr, missing))}; columns: {', '.join(result.columns)}")
    if x == y:
        raise ValueError(f"x and y must differ, both are {x!r}")
    values = result.values[:, [result.columns.index(y), result.columns.index(x)]]
    axes, index = product_axes(values, (y, x))
    return (y, x), axes, index


def gridded(result: SweepResult, values: np.ndarray, x: str | None = None, y: str | None = None) -> tuple:
    """``((y, x), (y_axis, x_axis), z (ny, nx), status (ny, nx))``: per-member ``values`` and
    statuses placed on the 2-D grid of `grid_axes`, both axes sorted ascending."""
    (y, x), (y_axis, x_axis), (iy, ix) = grid_axes(result, x, y)
    z = np.full((len(y_axis), len(x_axis)), np.nan)
    status = np.full(z.shape, NOT_RUN, dtype=int)
    z[iy, ix], status[iy, ix] = values, result.status
    y_order, x_order = np.argsort(y_axis, kind="stable"), np.argsort(x_axis, kind="stable")
    rows_cols = np.ix_(y_order, x_order)
    return (y, x), (y_axis[y_order], x_axis[x_order]), z[rows_cols], status[rows_cols]


def is_geometric(axis: np.ndarray) -> bool:
    """True for >= 3 positive, geometrically spaced values spanning more than a factor 4."""
    axis = np.sort(np.asarray(axis, dtype=float))
    if axis.size < 3 or axis[0] <= 0 or axis[-1] / axis[0] < 4:
        return False
    steps = np.diff(np.log(axis))
    return bool(np.allclose(steps, steps[0], rtol=1e-6))


def wants_log(axis: np.ndarray) -> bool:
    """A log axis for geometric values, and for any positive ones spanning two decades or more
    (found by review: k = 1, 10, 1e3, 1e4 on a linear axis left the k = 1 row under a pixel)."""
    axis = np.sort(np.asarray(axis, dtype=float))
    if axis.size < 2 or axis[0] <= 0:
        return False
    return is_geometric(axis) or bool(axis[-1] / axis[0] >= 100)


def _axis_log(values: np.ndarray, forced, name: str) -> bool:
    if forced is None:
        return wants_log(values)
    if forced and np.min(values) <= 0:
        raise ValueError(f"a log axis for {name!r} needs positive values, got {np.min(values):g}")
    return bool(forced)


def _edges(axis: np.ndarray, log: bool) -> np.ndarray:
    """Cell edges around sorted axis values (midpoints; geometric ones on a log axis)."""
    if axis.size == 1:
        v = axis[0]
        return np.array([v / 1.1, v * 1.1]) if log else np.array([v - 0.5, v + 0.5])
    values = np.log(axis) if log else axis
    inner = (values[1:] + values[:-1]) / 2
    edges = np.concatenate([[2 * values[0] - inner[0]], inner, [2 * values[-1] - inner[-1]]])
    return np.exp(edges) if log else edges


def plot_heatmap(result: SweepResult, field: str | np.ndarray, *, title: str | None = None,
                 label: str | None = None, log: bool = False, x: str | None = None, y: str | None = None,
                 cmap: str = "viridis", mask_failed: bool | None = None,
                 nan_label: str | None = None, x_log: bool | None = None, y_log: bool | None = None) -> Figure:
    """Heatmap of one field over two swept columns.

    Parameters
    ----------
    result : SweepResult
        A 2-D grid sweep, or any sweep whose members form a complete grid over ``x`` and ``y``.
    field : str or ndarray (n_members,)
        A field name (module docstring) or one value per member.
    title, label : str, optional
        Figure title (the counts of failed members are appended) and colorbar label; defaults
        describe the field.
    log : bool
        Logarithmic colour scale (values <= 0 count as no value).
    x, y : str, optional
        Column names of the axes; default x = the second swept column, y = the first.
    mask_failed : bool, optional
        Paint members with status != OK grey instead of their value. Default: True, except for
        the fields that describe failures (``status``, ``blowup_time``, ``steps_done``).
    nan_label : str, optional
        Legend text for completed members whose value is NaN (white cells); default
        "completed (no failure)" for ``blowup_time``, else "no value (NaN)".
    x_log, y_log : bool, optional
        Logarithmic axes; default: for positive values spaced geometrically or spanning two
        decades or more.

    Returns
    -------
    matplotlib.figure.Figure
        ``axes[0]``: the map in data coordinates; ``axes[1]``: the colorbar.
    """
    name = field if isinstance(field, str) else None
    if name is not None:
        values, default_label = field_values(result, name)
    else:
        values, default_label = np.asarray(field, dtype=np.float64).ravel(), "value"
        if values.shape != (result.n_members,):
            raise ValueError(f"field array has {values.size} values, the sweep {result.n_members} members")
    (y, x), (y_axis, x_axis), z, status = gridded(result, values, x, y)
    if mask_failed is None:
        mask_failed = name not in FAILURE_FIELDS
    fig, ax = _new_figure()
    x_log, y_log = _axis_log(x_axis, x_log, x), _axis_log(y_axis, y_log, y)
    edges = (_edges(x_axis, x_log), _edges(y_axis, y_log))
    if name == "status":
        _draw_status(fig, ax, edges, status, label or default_label)
    else:
        # members not run, or lost with their chunk, have no value of any field (found by review:
        # blowup_time drew them white as "completed (no failure)", steps_done as 0 steps)
        hidden = ((status != Status.OK) & mask_failed) | (status == NOT_RUN) | (status == CHUNK_FAILED)
        _draw_values(fig, ax, edges, z, hidden, log, cmap, label or default_label)
    if nan_label is None:
        nan_label = "completed (no failure)" if name == "blowup_time" else "no value (NaN)"
    handles = _draw_failed(ax, edges, status, z, mask_failed and name != "status", nan_label,
                           log and name != "status", lost=name != "status")
    ax.set_xscale("log" if x_log else "linear")
    ax.set_yscale("log" if y_log else "linear")
    for axis, values, is_log in ((ax.xaxis, x_axis, x_log), (ax.yaxis, y_axis, y_log)):
        _plain_log_ticks(axis, is_log)
        if len(values) <= 8:  # few values: tick each one
            axis.set_ticks(values, [f"{v:g}" for v in values])
            axis.set_ticks([], minor=True)
    ax.set_xlim(edges[0][0], edges[0][-1])
    ax.set_ylim(edges[1][0], edges[1][-1])
    ax.set_xlabel(x)
    ax.set_ylabel(y)
    ax.set_title(_title(title or f"{default_label} over {y} and {x}", status))
    add_legend_entries(fig, handles)
    return fig


def add_legend_entries(fig: Figure, handles: Sequence) -> None:
    """Add artists (or proxy artists with labels) to the legend below the map of a
    `plot_heatmap` figure, next to the counts of failed and NaN members already there."""
    if not handles and not fig.legends:
        return
    old = list(fig.legends[0].legend_handles) if fig.legends else []
    for legend in list(fig.legends):
        legend.remove()
    handles = old + list(handles)
    if handles:
        fig.legend(handles=handles, loc="outside lower center", ncols=min(len(handles), 3), fontsize="small")


def _new_figure(size=(8.0, 6.0)):
    from matplotlib.figure import Figure  # Agg canvas via savefig; no pyplot, no GUI

    fig = Figure(figsize=size, dpi=100, layout="constrained")
    return fig, fig.add_subplot()


def _plain_log_ticks(axis, log: bool) -> None:
    """Plain-number tick labels on a log axis (0.3, 20, not 3x10^-1), on the ticks matplotlib
    would label (minor ones only when the axis spans few decades)."""
    from matplotlib.ticker import LogFormatter

    class PlainLogFormatter(LogFormatter):
        def __call__(self, x, pos=None):
            return f"{x:g}" if super().__call__(x, pos) else ""

    if log:
        axis.set_major_formatter(PlainLogFormatter(labelOnlyBase=False))
        axis.set_minor_formatter(PlainLogFormatter(labelOnlyBase=False, minor_thresholds=(1.5, 0.6)))


def _draw_values(fig, ax, edges, z, hidden, log, cmap, label) -> None:
    from matplotlib.colors import LogNorm, Normalize

    shown = np.isfinite(z) & ~hidden & ((z > 0) if log else True)
    data = np.ma.masked_where(~shown, z)
    if shown.any():
        lo, hi = float(data.min()), float(data.max())
    else:
        lo, hi = (1.0, 10.0) if log else (0.0, 1.0)
    if hi == lo:  # a constant field still gets a readable colorbar
        lo, hi = (lo / 2, hi * 2) if log else (lo - 0.5, hi + 0.5)
    norm = LogNorm(lo, hi) if log else Normalize(lo, hi)
    mesh = ax.pcolormesh(edges[0], edges[1], data, cmap=cmap, norm=norm, shading="flat")
    bar = fig.colorbar(mesh, ax=ax, label=label)
    _plain_log_ticks(bar.ax.yaxis, log)


#: one distinct colour per status code (the sweep's CHUNK_FAILED and NOT_RUN first); a new
#: `Status` without an entry here fails `status_legend`, not silently shares a colour
STATUS_COLOURS = {CHUNK_FAILED: "#000000", NOT_RUN: _NOT_RUN_GREY, Status.OK: "#2a9d8f",
                  Status.SINGULAR_MASS_MATRIX: "#e76f51", Status.NONFINITE_STATE: "#9b2226",
                  Status.NEWTON_FAILED: "#f4a261", Status.UNKNOWN_METHOD: "#6d597a",
                  Status.SINGULAR_CONSTRAINTS: "#457b9d", Status.NONFINITE_INPUT: "#e9c46a",
                  Status.INPUT_FAILED: "#8ab17d", Status.BAD_ARGUMENT: "#bc6c25"}


def status_legend() -> tuple[list, list, list]:
    """(codes, names, colours) of every status a sweep reports, codes ascending and consecutive."""
    codes = sorted([*SWEEP_STATUS_NAMES, *(int(s) for s in Status)])
    missing = [code for code in codes if code not in STATUS_COLOURS]
    if missing or codes != list(range(codes[0], codes[-1] + 1)):
        raise ValueError(f"status codes without a colour or not consecutive: {missing or codes}")
    names = [SWEEP_STATUS_NAMES.get(code) or Status(code).name.lower() for code in codes]
    return codes, names, [STATUS_COLOURS[code] for code in codes]


def _draw_status(fig, ax, edges, status, label) -> None:
    from matplotlib.colors import BoundaryNorm, ListedColormap

    codes, names, colors = status_legend()
    norm = BoundaryNorm(np.arange(codes[0] - 0.5, codes[-1] + 1), len(codes))
    mesh = ax.pcolormesh(edges[0], edges[1], status, cmap=ListedColormap(colors), norm=norm, shading="flat")
    bar = fig.colorbar(mesh, ax=ax, label=label, ticks=codes)
    bar.ax.set_yticklabels(names)


def _draw_failed(ax, edges, status, z, paint: bool, nan_label: str, log: bool = False, lost: bool = True) -> list:
    """Grey cells for failed members (when ``paint``) and for members not run or lost with their
    chunk (when ``lost``: they have no value even of a failure field), cells of their own colour for
    infinite values (and values <= 0 on a log scale); legend handles for them and NaN."""
    from matplotlib.colors import ListedColormap
    from matplotlib.patches import Patch

    handles = []
    not_run, chunk_failed = status == NOT_RUN, status == CHUNK_FAILED
    failed = (status != Status.OK) & ~not_run & ~chunk_failed
    for cells, grey, text, drawn in ((failed, _FAILED_GREY, "failed (status != ok)", paint),
                                     (chunk_failed, _FAILED_GREY, "lost (their chunk raised)", paint or lost),
                                     (not_run, _NOT_RUN_GREY, "not run", paint or lost)):
        if cells.any() and drawn:
            ax.pcolormesh(edges[0], edges[1], np.ma.masked_where(~cells, np.ones(z.shape)),
                          cmap=ListedColormap([grey]), shading="flat")
            handles.append(Patch(facecolor=grey, label=f"{text}: {int(cells.sum())}"))
    shown = ((status == Status.OK) | (not paint)) & ~(lost & (not_run | chunk_failed))  # members drawn by value
    # an infinite value is a blow-up, not a missing one: its own colour (found by review: the
    # worst members of a sweep were white and counted as "no value (NaN)")
    for cells, colour, text in ((np.isposinf(z) & shown, _INFINITE_COLOURS[0], "+inf"),
                                (np.isneginf(z) & shown, _INFINITE_COLOURS[1], "-inf"),
                                ((z <= 0) & shown if log else np.zeros(z.shape, bool), _NONPOSITIVE_COLOUR,
                                 "<= 0 (no place on the log scale)")):
        if cells.any():
            ax.pcolormesh(edges[0], edges[1], np.ma.masked_where(~cells, np.ones(z.shape)),
                          cmap=ListedColormap([colour]), shading="flat")
            handles.append(Patch(facecolor=colour, edgecolor="0.3", label=f"{text}: {int(cells.sum())}"))
    blank = np.isnan(z) & (status == Status.OK)
    if blank.any():
        ax.set_facecolor("white")
        handles.append(Patch(facecolor="white", edgecolor="0.3", label=f"{nan_label}: {int(blank.sum())}"))
    return handles


def _title(text: str, status: np.ndarray) -> str:
    failed = int(np.sum((status != Status.OK) & (status != NOT_RUN)))
    not_run = int(np.sum(status == NOT_RUN))
    notes = []
    if failed:
        notes.append(f"{failed} of {status.size} members failed")
    if not_run:
        notes.append(f"{not_run} of {status.size} not run (interrupted)")
    return text + (f"\n({'; '.join(notes)})" if notes else "")
