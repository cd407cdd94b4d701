"""Observed order of every default method through the whole pipeline (compile_model + simulate).

The double pendulum (catalog, default parameters m1 = m2 = l1 = l2 = 1, g = 9.81) starts at rest
from q = (0.3, 0.1) rad: small-to-moderate amplitude, regular motion, largest linear frequency
sqrt(g (2 + sqrt 2)) = 5.79 rad/s. The final state at T = 2 s is compared with DOP853 at
rtol = atol = 1e-12 (`lagcodegen.run.simulate.solve_reference`); the observed order is the slope of
log(error) against log(h) (np.polyfit) over each method's asymptotic range.

The step ranges are chosen per method (measured once, see the table printed by
`test_local_slopes_and_order_table` with ``-s``): every error lies between ERROR_FLOOR (1e-10:
100 times the tolerance of the DOP853 reference, rtol = atol = 1e-12, and far above the implicit
methods' Newton tolerance 1e-13) and ERROR_CEILING, and the local slope between neighbours is
within LOCAL_TOLERANCE of the order. The first-order methods need small steps (their
h^2 term is large at this amplitude); dopri5 (order 5) uses large steps so its error stays far
above the reference's and the Newton tolerance (1e-13) is irrelevant for the explicit methods; the
implicit methods' errors stay >= 1e-9, far above the accumulated Newton residuals.
"""
from __future__ import annotations

import numpy as np
import pytest

from lagcodegen.integrators import schemes
from lagcodegen.run.simulate import simulate, solve_reference

X0 = (0.3, 0.1, 0.0, 0.0)  # q1, q2 [rad], q1_d, q2_d [rad/s]
T_END = 2.0
TOLERANCE = 0.15  # STYLE.md section 8: slope within +-0.15 of the declared order
LOCAL_TOLERANCE = 0.3  # between neighbours: two errors, no averaging
ERROR_FLOOR = 1e-10  # >> the reference's error and the Newton tolerance 1e-13
ERROR_CEILING = 5e-2

# Steps per T_END (h = T_END / N), doubling: inside the asymptotic range of each method on this
# problem (local slopes measured on a finer grid: all within 0.15 of the order).
STEPS = {
    "euler": (4000, 8000, 16000, 32000, 64000),
    "symplectic_euler": (1000, 2000, 4000, 8000, 16000),
    "heun": (1000, 2000, 4000, 8000, 16000),
    "kutta3": (100, 200, 400, 800, 1600),
    "rk4": (200, 400, 800, 1600),
    "rk38": (200, 400, 800, 1600),
    "dopri5": (80, 120, 160, 240, 320),
    "implicit_midpoint": (200, 400, 800, 1600),
    "backward_euler": (4000, 8000, 16000, 32000, 64000),
    "sdirk2": (200, 400, 800, 1600),
    "radau_iia3": (100, 200, 400, 800, 1600),
}


@pytest.fixture(scope="module")
def double_pendulum(compiled_example):
    """One build with every default method (conftest's session cache of catalog builds)."""
    return compiled_example("double_pendulum", methods=schemes.DEFAULT_METHODS)


@pytest.fixture(scope="module")
def reference(double_pendulum):
    """Final state at T_END from DOP853 at rtol = atol = 1e-12 (the independent reference)."""
    _, x = solve_reference(double_pendulum, X0, [T_END], rtol=1e-12, atol=1e-12)
    return x[-1]


@pytest.fixture(scope="module")
def observed(double_pendulum, reference):
    """method -> (h (k,), error (k,), slope): final-state error norms and their fitted slope."""
    results = {}
    for method in schemes.DEFAULT_METHODS:
        h = np.array([T_END / n for n in STEPS[method]])
        errors = np.array([
            np.linalg.norm(simulate(double_pendulum, X0, T_END, step, method).check().x[-1] - reference)
            for step in h])
        slope = np.polyfit(np.log(h), np.log(errors), 1)[0]
        results[method] = (h, errors, slope)
    return results


def test_every_default_method_has_a_step_range():
    assert set(STEPS) == set(schemes.DEFAULT_METHODS)
    assert all(len(n) >= 4 for n in STEPS.values())


@pytest.mark.parametrize("method", schemes.DEFAULT_METHODS)
def test_errors_lie_in_the_measurable_range(observed, method):
    """Guards the choice of h: above the reference's accuracy, below the pre-asymptotic regime."""
    _, errors, _ = observed[method]
    assert np.all(errors > ERROR_FLOOR), errors
    assert np.all(errors < ERROR_CEILING), errors
    assert np.all(np.diff(errors) < 0), f"{method}: error does not decrease with h: {errors}"


@pytest.mark.parametrize("method", schemes.DEFAULT_METHODS)
def test_observed_order_matches_declared_order(observed, method):
    # Expected: the order declared by the scheme, proved for the tableaux by the order conditions
    # (tests/tableaux) and by HNW I, Sec. II.1-II.5 / HW II, Sec. IV.5-IV.6 (cited in tableaux.py).
    declared = schemes.get_scheme(method).order
    _, _, slope = observed[method]
    assert slope == pytest.approx(declared, abs=TOLERANCE), f"{method}: observed order {slope:.3f}"


def test_local_slopes_and_order_table(observed):
    """Each pair of neighbouring steps shows the declared order too, not only the fitted slope
    over the range (a range that bends, pre-asymptotic at one end or at the reference's accuracy
    at the other, can fit the right slope on average); the table prints with ``pytest -s``."""
    lines = [f"\nObserved order, double pendulum q0 = {X0[:2]}, T = {T_END} s, vs DOP853 1e-12",
             f"{'method':<18} {'declared':>8} {'observed':>9}   h range          error range"]
    for method in schemes.DEFAULT_METHODS:
        h, errors, slope = observed[method]
        lines.append(f"{method:<18} {schemes.get_scheme(method).order:>8} {slope:>9.3f}   "
                     f"{h.max():.2e}..{h.min():.2e}  {errors.max():.2e}..{errors.min():.2e}")
    print("\n".join(lines))
    for method in schemes.DEFAULT_METHODS:
        h, errors, _ = observed[method]
        local = np.diff(np.log(errors)) / np.diff(np.log(h))
        declared = schemes.get_scheme(method).order
        assert np.all(np.abs(local - declared) < LOCAL_TOLERANCE), f"{method}: local slopes {local}"
