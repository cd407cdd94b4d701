"""The status heatmap paints every status code in its own colour.

Before, the colour list had one entry fewer than the codes (NOT_RUN plus six `Status` values), so
the colormap stretched six colours over seven bins and ``unknown_method`` and
``singular_constraints`` came out the same. The codes expected here are listed independently of
heatmap.py: the six C status values 0..5 (``LCG_*``, `Status`) and the sweep's own NOT_RUN (-1)
and CHUNK_FAILED (-2).
"""
from __future__ import annotations

import matplotlib
import numpy as np
import pytest

from lagcodegen.analysis.heatmaps import plot_heatmap
from lagcodegen.run.simulate import Status
from lagcodegen.run.sweep import CHUNK_FAILED, NOT_RUN, sweep

pytestmark = pytest.mark.compiler

CODES = {-2: "chunk_failed", -1: "not_run", 0: "ok", 1: "singular_mass_matrix", 2: "nonfinite_state",
         3: "newton_failed", 4: "unknown_method", 5: "singular_constraints", 6: "nonfinite_input",
         7: "input_failed", 8: "bad_argument"}


@pytest.fixture(scope="module")
def status_figure(compiled_example):
    """A 2 x 2 grid of the double pendulum; m2 = -0.5 fails (singular mass matrix)."""
    system = compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4",))
    result = sweep(system, {"m2": (-0.5, 1.0), "l2": (0.5, 1.0)}, x0=(0.5, 0.0, 0.0, 0.0), t_end=0.1, h=0.01)
    assert sorted(set(result.status)) == [0, 1]
    return plot_heatmap(result, "status")


def test_the_codes_are_the_known_ones():
    assert {int(s): s.name.lower() for s in Status} == {k: v for k, v in CODES.items() if k >= 0}
    assert (CHUNK_FAILED, NOT_RUN) == (-2, -1)


def test_every_status_has_its_own_colour(status_figure):
    mesh = status_figure.axes[0].collections[0]
    colours = {code: matplotlib.colors.to_hex(mesh.cmap(mesh.norm(code))) for code in CODES}
    assert len(set(colours.values())) == len(CODES), colours
    # each cell shows its member's colour: the failing row (m2 = -0.5) differs from the rest
    faces = [matplotlib.colors.to_hex(c) for c in mesh.to_rgba(np.asarray(mesh.get_array()).ravel())]
    assert faces[:2] == [colours[1]] * 2 and faces[2:] == [colours[0]] * 2


def test_the_colorbar_names_every_status(status_figure):
    bar = status_figure.axes[1]
    ticks = {round(t): label.get_text() for t, label in zip(bar.get_yticks(), bar.get_yticklabels())}
    assert ticks == CODES
    assert np.all(np.diff(sorted(ticks)) == 1)


@pytest.fixture(scope="module")
def completed_grid(compiled_example):
    """A 2 x 2 grid of the double pendulum whose members all complete."""
    system = compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4",))
    result = sweep(system, {"m2": (1.0, 2.0), "l2": (0.5, 1.0)}, x0=(0.5, 0.0, 0.0, 0.0), t_end=0.1, h=0.01)
    assert not result.status.any()
    return result


def _legend(figure) -> list:
    return [text.get_text() for text in figure.legends[0].get_texts()]


def _cells(figure, colour) -> np.ndarray:
    """The grid cells (row-major, y then x) painted ``colour`` by a single-colour mesh."""
    for mesh in figure.axes[0].collections:
        colours = mesh.cmap.colors if hasattr(mesh.cmap, "colors") else ()
        if len(colours) == 1 and matplotlib.colors.to_hex(colours[0]) == matplotlib.colors.to_hex(colour):
            return ~np.ma.getmaskarray(mesh.get_array()).ravel()
    return np.zeros(0, bool)


def test_infinite_values_are_not_drawn_as_missing(completed_grid):
    """Found by review: members that completed with an infinite value (an energy error that
    overflowed) were white and counted as "no value (NaN)", so the worst members of a sweep looked
    like members without data. Here the member values are given, so the expected cells are known:
    grid order is m2 then l2, the map's rows m2 (y) and columns l2 (x)."""
    values = np.array([np.inf, np.nan, 1.0, -np.inf])
    figure = plot_heatmap(completed_grid, values)
    legend = _legend(figure)
    assert "+inf: 1" in legend and "-inf: 1" in legend and "no value (NaN): 1" in legend
    assert list(_cells(figure, "#ff1493")) == [True, False, False, False]
    assert list(_cells(figure, "#00bfff")) == [False, False, False, True]
    logged = plot_heatmap(completed_grid, np.array([0.0, 1.0, 10.0, np.inf]), log=True)
    legend = _legend(logged)
    assert "<= 0 (no place on the log scale): 1" in legend and "+inf: 1" in legend
    assert not any(text.startswith("no value") for text in legend)


def test_a_wide_axis_is_logarithmic_even_when_not_geometric(compiled_example):
    """Found by review: k = 1, 10, 1e3, 1e4 (not geometric) got a linear axis from -3.5 to 14500,
    where the k = 1 row took under a pixel. Positive values spanning two decades or more now get a
    log axis, whose cells are the same height for each decade (edges at the geometric midpoints:
    sqrt(1 * 10) = 3.16 between the first two rows, by hand); x_log/y_log override."""
    system = compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4",))
    result = sweep(system, {"g": (1.0, 10.0, 1e3, 1e4), "l2": (0.5, 1.0)}, x0=(0.5, 0.0, 0.0, 0.0), t_end=0.01,
                   h=0.01)
    figure = plot_heatmap(result, "q_max:q1")
    axes = figure.axes[0]
    assert axes.get_yscale() == "log" and axes.get_xscale() == "linear"
    low, high = axes.get_ylim()
    assert low > 0 and low == pytest.approx(1.0 / np.sqrt(10.0)) and high == pytest.approx(1e4 * np.sqrt(10.0))
    assert plot_heatmap(result, "q_max:q1", y_log=False).axes[0].get_yscale() == "linear"
    with pytest.raises(ValueError, match="a log axis for 'l2' needs positive values"):
        plot_heatmap(sweep(system, {"g": (1.0, 2.0), "l2": (0.0, 1.0)}, x0=(0.5, 0.0, 0.0, 0.0), t_end=0.01,
                           h=0.01), "q_max:q1", x_log=True)
