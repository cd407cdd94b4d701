"""Stage: analysis records -> matplotlib figures.

Work-precision diagrams, stability-limit bars and energy-error curves from the records and
trajectories of `lagcodegen.analysis.measures`. Each function builds a `matplotlib.figure.Figure`
directly (Agg canvas, no pyplot state) and returns it; it never shows it.

References: Hairer, Norsett, Wanner, Solving ODEs I (work-precision diagrams, Sec. II.10) and
II (stability domains, Sec. IV.2).
"""
from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..integrators.schemes import SCHEMES

if TYPE_CHECKING:
    from matplotlib.figure import Figure

    from ..run.simulate import Trajectory
    from .measures import WorkRecord


def _figure(size=(9.0, 6.0)):
    from matplotlib.figure import Figure  # Agg canvas via savefig; no pyplot, no GUI

    fig = Figure(figsize=size, dpi=100, layout="constrained")
    return fig, fig.add_subplot()


#: Line colours: fixed-step methods (no grey), then scipy's reference curves in greys.
_COLORS = ("tab:blue", "tab:orange", "tab:green", "tab:red", "tab:purple", "tab:brown", "tab:pink",
           "tab:olive", "tab:cyan", "navy", "darkgoldenrod", "crimson", "teal")
_GREYS = ("black", "dimgrey", "darkgrey", "silver")
_MARKERS = "osD^v<>phH*Xd8P"


def _style(method: str, index: int) -> dict:
    """Explicit methods solid, implicit dash-dot, scipy's adaptive ones dashed grey with open markers."""
    style = {"marker": _MARKERS[index % len(_MARKERS)], "markersize": 5}
    if method.startswith("scipy:"):
        return style | {"linestyle": "--", "color": _GREYS[index % len(_GREYS)], "markerfacecolor": "none"}
    implicit = method in SCHEMES and SCHEMES[method].implicit
    return style | {"linestyle": "-." if implicit else "-", "color": _COLORS[index % len(_COLORS)]}


def plot_work_precision(records: Sequence[WorkRecord], title: str, *, max_error: float = 1e2,
                        error_label: str = "error of x(t_end), max-norm") -> Figure:
    """Work-precision diagram: error against wall time, log-log, one line per method.

    Parameters
    ----------
    records : sequence of WorkRecord
        From `work_precision` and `scipy_work_precision`.
    title : str
    max_error : float
        Failed runs and errors above this (diverged or meaningless) are left out.
    error_label : str
        y-axis label (add the state's units).

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _figure()
    methods = list(dict.fromkeys(r.method for r in records))
    counters = {True: 0, False: 0}  # scipy curves and fixed-step methods count their styles apart
    for method in methods:
        scipy_curve = method.startswith("scipy:")
        style = _style(method, counters[scipy_curve])
        counters[scipy_curve] += 1
        # joined from coarse to fine (large h / loose tolerance first), not by time: timing noise
        # must show as a kink, not reorder the points
        rows = sorted((r for r in records if r.method == method and r.ok and r.error <= max_error),
                      key=lambda r: -(r.h if r.h is not None else r.tolerance))
        if rows:
            ax.plot([r.seconds for r in rows], [max(r.error, 1e-300) for r in rows], label=method, **style)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("wall time per run [s] (best of repeats)")
    ax.set_ylabel(error_label)
    ax.set_title(title)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")
    return fig


def plot_stability(measured: Mapping[str, float], theoretical: Mapping[str, float], *,
                   title: str = "Largest stable h*w on an undamped oscillation",
                   searched_up_to: float = 1e3, note: str = "") -> Figure:
    """Bar chart: measured largest stable h*w per method beside the theoretical limit.

    Parameters
    ----------
    measured : mapping method -> float
        From `measured_stability_limit` (inf: no limit found up to ``searched_up_to``).
    theoretical : mapping method -> float
        From `theoretical_stability_limit` (inf: unconditionally stable).
    title, note : str
        Figure title and a small note in the upper left (say how "measured" was measured).
    searched_up_to : float
        The ``hi`` of the search. Infinite bars are drawn hatched to the top of the axes and
        labelled "no limit found up to <searched_up_to>" (measured) or "no limit (A-stable)".

    Returns
    -------
    matplotlib.figure.Figure
        Two bars per method (measured, theoretical) in ``ax.patches``.
    """
    import textwrap

    fig, ax = _figure()
    methods = list(measured)
    finite = [v for v in [*measured.values(), *theoretical.values()] if math.isfinite(v)]
    top = 1.8 * max(finite, default=1.0)  # headroom for the legend and the note
    x = np.arange(len(methods))
    series = ((-0.2, measured, "measured", "tab:blue", f"no limit found up to {searched_up_to:g}"),
              (0.2, theoretical, "theory: |R(i h w)| <= 1", "tab:orange", "no limit (A-stable)"))
    for offset, values, label, color, unbounded in series:
        heights = [values.get(m, math.nan) for m in methods]
        bars = ax.bar(x + offset, [top if math.isinf(v) else v for v in heights], width=0.4,
                      color=color, label=label, edgecolor="black", linewidth=0.5)
        for bar, v in zip(bars, heights):
            centre = bar.get_x() + bar.get_width() / 2
            if math.isinf(v):
                bar.set_hatch("//")
                bar.set_alpha(0.45)
                ax.text(centre, 0.5 * top, unbounded, ha="center", va="center", rotation=90, fontsize=8)
            elif math.isfinite(v):
                ax.text(centre, v + 0.01 * top, f"{v:.3g}", ha="center", va="bottom", rotation=90, fontsize=8)
    ax.set_xticks(x, methods, rotation=30, ha="right", rotation_mode="anchor")
    ax.set_ylim(0, top)
    ax.set_ylabel("largest stable h*w   (h: step [s], w: fastest frequency [rad/s])")
    ax.set_title(title)
    ax.legend(loc="upper left")
    ax.grid(True, axis="y", alpha=0.3)
    if note:
        ax.text(0.01, 0.87, textwrap.fill(note, 70), transform=ax.transAxes, va="top", fontsize=8,
                bbox={"facecolor": "white", "edgecolor": "lightgrey"})
    return fig


def plot_energy_error(trajectories: Mapping[str, Trajectory], title: str, *,
                      energy_unit: str = "J") -> Figure:
    """|E - E0| against t, log y, one line per trajectory (simulated with ``energy=True``).

    Lines are drawn in the mapping's order, later ones on top. Exact zeros (the first sample)
    are left out of the log axis.

    Parameters
    ----------
    trajectories : mapping label -> Trajectory
        ``t (n_out,)``, ``energy (n_out,)``.
    title : str
    energy_unit : str
        For the y-axis label.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig, ax = _figure()
    for label, traj in trajectories.items():
        if traj.energy is None:
            raise ValueError(f"trajectory {label!r} has no energy samples; simulate with energy=True")
        if len(traj.energy) == 0:
            raise ValueError(f"trajectory {label!r} has no samples (an empty slice?): nothing to plot")
        dE = np.abs(np.asarray(traj.energy, dtype=np.float64) - float(traj.energy[0]))
        ax.plot(traj.t, np.where(dE > 0, dE, np.nan), label=label, linewidth=0.8)
    ax.set_yscale("log")
    ax.set_xlabel("t [s]")
    ax.set_ylabel(f"|E(t) - E(0)|  [{energy_unit}]")
    ax.set_title(title)
    ax.grid(True, which="major", alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig
