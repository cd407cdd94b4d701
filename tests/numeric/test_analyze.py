"""measures.py against independent values: synthetic data with known answers, the stability
polynomial of RK4, and the structure of the figures (figures.py)."""
from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from lagcodegen import catalog
from lagcodegen.analysis import figures, measures
from lagcodegen.native.build import compiler_available
from lagcodegen.run.simulate import Status, Trajectory, jacobian, parameter_vector

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")

CHAIN_X0 = (0.0, 0.01, -0.01, 0.0, 0.0, 0.0)  # stiff spring stretched, everything at rest


def synthetic_trajectory(t, energy) -> Trajectory:
    t = np.asarray(t, dtype=float)
    return Trajectory(t=t, x=np.zeros((t.size, 2)), names=("q", "q_d"), energy=np.asarray(energy, dtype=float),
                      points=None, point_names=(), status=Status.OK, failed_step=None, failed_time=None,
                      method="rk4", h=float(t[1] - t[0]))


@pytest.fixture(scope="module")
def chain():
    if not compiler_available():
        pytest.skip("no C compiler / Python headers")
    from lagcodegen.pipeline import compile_model

    return compile_model(catalog.stiff_chain(), methods=("rk4", "symplectic_euler", "backward_euler"))


# -- observed_order ---------------------------------------------------------------------------
@pytest.mark.parametrize("p", [1.0, 2.0, 4.0, 5.0])
def test_observed_order_of_exact_power_law(p):
    h = np.array([0.1, 0.05, 0.025, 0.0125])
    assert measures.observed_order(h, 3.7 * h ** p) == pytest.approx(p, abs=1e-12)  # err = C h^p exactly


def test_observed_order_window_drops_floor_and_preasymptotic_points():
    h = 2.0 ** -np.arange(1, 12)
    err = np.maximum(2.0 * h ** 4, 1e-12)  # fourth order down to a round-off floor at 1e-12
    assert measures.observed_order(h, err, window=(1e-10, 1.0)) == pytest.approx(4.0, abs=1e-12)
    assert measures.observed_order(h, err) < 3.9  # without the window the floor bends the fit
    err[0] = 1e3  # a blown-up run at the largest step
    assert measures.observed_order(h, err, window=(1e-10, 1.0)) == pytest.approx(4.0, abs=1e-12)


def test_observed_order_skips_nonfinite_and_needs_two_points():
    assert measures.observed_order([0.1, 0.05, 0.025], [np.inf, 1e-2, 2.5e-3]) == pytest.approx(2.0)
    assert math.isnan(measures.observed_order([0.1, 0.05], [np.nan, 1e-3]))
    with pytest.raises(ValueError, match="same length"):
        measures.observed_order([0.1, 0.05], [1e-3])


# -- energy_drift -----------------------------------------------------------------------------
def test_energy_drift_of_linear_drift_plus_oscillation():
    t = np.linspace(0.0, 10.0, 1001)
    rate, a = 3e-4, 1e-3
    energy = -2.0 + a + rate * t + a * (np.cos(2 * np.pi * t) - 1.0)  # E0 = -2 + a
    drift = measures.energy_drift(synthetic_trajectory(t, energy))
    assert drift["e0"] == pytest.approx(-2.0 + a, abs=1e-15)
    # |E - E0| = |rate t + a (cos 2 pi t - 1)| peaks at t = 10 (cos = 1): 3e-3; its minimum
    # -1.85e-3 near t = 0.5 is smaller in size
    assert drift["max_abs"] == pytest.approx(rate * 10.0, rel=1e-9)
    assert drift["max_rel"] == pytest.approx(rate * 10.0 / (2.0 - a), rel=1e-9)
    assert drift["final"] == pytest.approx(rate * 10.0, rel=1e-9)
    # the cosine is symmetric about t = 5 and t - 5 antisymmetric: it adds nothing to the
    # least-squares slope, which is the rate exactly
    assert drift["rate"] == pytest.approx(rate, rel=1e-9)


def test_energy_drift_needs_energy():
    traj = dataclasses.replace(synthetic_trajectory([0.0, 1.0], [1.0, 1.0]), energy=None)
    with pytest.raises(ValueError, match="energy=True"):
        measures.energy_drift(traj)


def test_an_empty_trajectory_is_refused_by_name_not_with_an_index_error():
    empty = dataclasses.replace(synthetic_trajectory([0.0, 1.0], [1.0, 1.0]), t=np.zeros(0), x=np.zeros((0, 2)),
                                energy=np.zeros(0))
    with pytest.raises(ValueError, match="no samples"):
        measures.energy_drift(empty)
    with pytest.raises(ValueError, match="'empty' has no samples"):
        figures.plot_energy_error({"empty": empty}, "test")


# -- stability --------------------------------------------------------------------------------
@needs_cc
@pytest.mark.compiler
def test_measured_stability_limit_of_rk4_is_two_sqrt_two(chain):
    w = float(np.max(np.abs(np.linalg.eigvals(jacobian(chain, np.asarray(CHAIN_X0), parameter_vector(chain))))))
    assert w == pytest.approx(141.4, rel=1e-3)  # sqrt of the stiff eigenvalue ~ sqrt(2 K / m)
    limit = measures.measured_stability_limit(chain, "rk4", CHAIN_X0, w)
    # RK4: |R(iy)|^2 = 1 - y^6/72 + y^8/576 <= 1 exactly for y <= sqrt(8) (HW II, Sec. IV.2)
    assert limit == pytest.approx(2 * math.sqrt(2), rel=0.03)
    symplectic = measures.measured_stability_limit(chain, "symplectic_euler", CHAIN_X0, w)
    assert symplectic == pytest.approx(2.0, rel=0.03)  # trace of the step map 2 - (h w)^2 in [-2, 2]
    assert measures.measured_stability_limit(chain, "backward_euler", CHAIN_X0, w, hi=100.0) == math.inf


def test_theoretical_stability_limits():
    assert measures.theoretical_stability_limit("rk4") == pytest.approx(2 * math.sqrt(2))
    assert measures.theoretical_stability_limit("symplectic_euler") == 2.0
    assert measures.theoretical_stability_limit("euler") == 0.0
    assert measures.theoretical_stability_limit("implicit_midpoint") == math.inf


# -- work precision ---------------------------------------------------------------------------
@needs_cc
@pytest.mark.compiler
def test_work_precision_records_and_order(chain):
    from scipy.linalg import expm

    J = jacobian(chain, np.asarray(CHAIN_X0), parameter_vector(chain))
    exact = expm(1.0 * J) @ np.asarray(CHAIN_X0)  # the chain is linear: x(t) = exp(J t) x0
    steps = [1600, 3200, 6400]
    # t_end = 1 s: there the fourth-order phase error dominates the max-norm (at t = 0.5 s the
    # stiff speed is near an extremum and the fifth-order amplitude error still shows)
    records = measures.work_precision(chain, CHAIN_X0, 1.0, ["rk4"], steps, reference=exact, repeats=1)
    assert [r.n_steps for r in records] == steps
    assert all(r.ok and r.seconds > 0 and r.h == pytest.approx(1.0 / r.n_steps) for r in records)
    assert measures.observed_order([r.h for r in records], [r.error for r in records]) == pytest.approx(4.0, abs=0.15)
    diverged = measures.work_precision(chain, CHAIN_X0, 1.0, ["rk4"], [20], reference=exact, repeats=1)[0]
    with pytest.raises(ValueError, match=r"steps\[1\] must be a positive integer, got 0"):  # found by review
        measures.work_precision(chain, CHAIN_X0, 1.0, ["rk4"], [20, 0], reference=exact, repeats=1)
    assert diverged.error > 1.0 or not diverged.ok  # h w = 7.1 > 2.83: unstable


@needs_cc
@pytest.mark.compiler
def test_scipy_work_precision_records(chain):
    records = measures.scipy_work_precision(chain, CHAIN_X0, 0.2, methods=("RK45", "Radau"), tolerances=(1e-6,),
                                           repeats=1)
    assert [(r.method, r.tolerance, r.h, r.n_steps) for r in records] == [
        ("scipy:RK45", 1e-6, None, None), ("scipy:Radau", 1e-6, None, None)]
    # against DOP853 at 1e-12; an adaptive run at rtol = atol = 1e-6 lands within ~1e-3 of it
    assert all(r.ok and r.nfev > 0 and 0 < r.error < 1e-3 and r.seconds > 0 for r in records)


# -- figures ----------------------------------------------------------------------------------
def fake_records():
    rec = measures.WorkRecord
    return [rec("rk4", 0.1, None, 10, None, 1e-3, 1e-4, True),
            rec("rk4", 0.05, None, 20, None, 6e-5, 2e-4, True),
            rec("euler", 0.1, None, 10, None, 1e-1, 5e-5, True),
            rec("euler", 0.05, None, 20, None, np.inf, 1e-4, False),  # diverged
            rec("scipy:RK45", None, 1e-6, None, 500, 1e-6, 1e-2, True)]


def test_plot_work_precision_has_one_line_per_method():
    import matplotlib.pyplot as plt
    from matplotlib.figure import Figure

    open_before = plt.get_fignums()
    fig = figures.plot_work_precision(fake_records(), "test")
    assert plt.get_fignums() == open_before  # a bare Figure: no pyplot state, nothing to show
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert [line.get_label() for line in ax.get_lines()] == ["rk4", "euler", "scipy:RK45"]
    assert len(ax.get_lines()[1].get_xdata()) == 1  # the failed euler run is left out
    assert ax.get_xscale() == ax.get_yscale() == "log"


def test_plot_stability_has_two_bars_per_method():
    from matplotlib.figure import Figure

    measured = {"euler": 0.04, "rk4": 2.83, "backward_euler": math.inf}
    theory = {"euler": 0.0, "rk4": 2.83, "backward_euler": math.inf}
    fig = figures.plot_stability(measured, theory, note="a note")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert len(ax.patches) == 2 * len(measured)
    assert [t.get_text() for t in ax.get_xticklabels()] == list(measured)


def test_plot_energy_error_has_one_line_per_trajectory():
    from matplotlib.figure import Figure

    t = np.linspace(0.0, 1.0, 11)
    trajectories = {"a": synthetic_trajectory(t, 1.0 + 1e-6 * t), "b": synthetic_trajectory(t, 1.0 - 1e-3 * t)}
    fig = figures.plot_energy_error(trajectories, "test")
    assert isinstance(fig, Figure)
    ax = fig.axes[0]
    assert [line.get_label() for line in ax.get_lines()] == ["a", "b"]
    assert ax.get_yscale() == "log"
    assert np.isnan(ax.get_lines()[0].get_ydata()[0])  # |E - E0| = 0 at t = 0 is left off the log axis
