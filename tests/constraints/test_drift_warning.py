"""A constrained run that drifts off its constraints warns (`ConstraintDriftWarning`).

Without projection the four-bar's loop-closure residual grows while the status stays OK (the
slider-crank reached |phi| = 0.12 m that way). The reference residual is the loop closure typed
from the mechanism (Norton, Design of Machinery, ch. 4, the vector loop R2 + R3 - R4 - R1 = 0):

    phi1 = l1 cos(theta1) + l2 cos(theta2) - l3 cos(theta3) - d
    phi2 = l1 sin(theta1) + l2 sin(theta2) - l3 sin(theta3)

evaluated with sympy at the run's kept states, independently of the compiled residual kernel.
"""
from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog
from lagcodegen.run.simulate import DRIFT_TOLERANCE, ConstraintDriftWarning, simulate

pytestmark = pytest.mark.compiler

H, T_END, STRIDE = 1e-3, 1.0, 10


@pytest.fixture(scope="module")
def linkage(compiled_system):
    return compiled_system("four_bar")


def loop_closure(states: np.ndarray) -> np.ndarray:
    """max(|phi1|, |phi2|) of the hand-typed loop closure at each state (rows theta1..3, rates)."""
    l1, l2, l3, d, t1, t2, t3 = sp.symbols("l1 l2 l3 d theta1 theta2 theta3")
    phi = sp.Matrix([l1 * sp.cos(t1) + l2 * sp.cos(t2) - l3 * sp.cos(t3) - d,
                     l1 * sp.sin(t1) + l2 * sp.sin(t2) - l3 * sp.sin(t3)])
    lengths = dict(zip((l1, l2, l3, d), catalog.FOUR_BAR_GRASHOF))
    f = sp.lambdify((t1, t2, t3), phi.subs(lengths), "numpy")
    return np.array([np.abs(np.asarray(f(*x[:3]), dtype=float)).max() for x in states])


def test_a_drifting_run_warns_with_the_max_residual_and_its_time(linkage):
    x0 = catalog.four_bar_state(0.0, 0.0)
    with pytest.warns(ConstraintDriftWarning) as caught:
        run = simulate(linkage, x0, T_END, H, "rk4", stride=STRIDE)
    assert run.ok and run.residuals is None  # recorded for the check, returned only when asked
    message = str(caught[0].message)
    size, at = map(float, re.search(r"max \|phi\| = (\S+) at t = (\S+) ", message).groups())
    reference = loop_closure(run.x)
    assert reference[-1] > DRIFT_TOLERANCE["double"]  # the final state alone is off by more
    assert size == pytest.approx(reference.max(), rel=1e-2)  # printed to 3 digits
    assert at == pytest.approx(run.t[int(np.argmax(reference))])
    assert "project=True" in message and "Baumgarte" in message


def test_the_tolerance_is_the_users(linkage):
    x0 = catalog.four_bar_state(0.0, 0.0)
    run = simulate(linkage, x0, T_END, H, "rk4", stride=STRIDE, residuals=True, drift_tolerance=math.inf)
    largest = np.abs(run.residuals[:, :2]).max()
    assert largest == pytest.approx(loop_closure(run.x).max(), rel=1e-6)  # the kernel's phi agrees
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # above the drift: silent; switched off: silent
        simulate(linkage, x0, T_END, H, "rk4", stride=STRIDE, drift_tolerance=2 * largest)
    with pytest.warns(ConstraintDriftWarning, match=r"drift_tolerance = 1e-11"):
        simulate(linkage, x0, 0.1, H, "rk4", stride=STRIDE, drift_tolerance=1e-11)


def test_a_projected_run_does_not_warn(linkage):
    x0 = catalog.four_bar_state(0.0, 0.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        run = simulate(linkage, x0, T_END, H, "rk4", stride=STRIDE, project=True)
    assert loop_closure(run.x).max() < 1e-9


def test_a_start_off_the_positions_alone_is_not_called_drift(linkage):
    """Found by review: a start off phi = 0 with consistent velocities (here at rest, so A u = 0)
    ran holding its offset and was blamed on drift ("use project=True ... or a smaller h"). phi by
    hand as below, at theta2 moved by 0.05 from a consistent state."""
    x0 = np.array(catalog.four_bar_state(0.3, 1.0), dtype=float)
    x0[1] += 0.05
    x0[3:] = 0.0
    l1, l2, l3, d = 0.1, 0.35, 0.3, 0.4
    phi_x = l1 * math.cos(x0[0]) + l2 * math.cos(x0[1]) - l3 * math.cos(x0[2]) - d
    phi_y = l1 * math.sin(x0[0]) + l2 * math.sin(x0[1]) - l3 * math.sin(x0[2])
    with pytest.warns(ConstraintDriftWarning) as caught:
        simulate(linkage, x0, t_end=0.01, h=1e-3, residuals=True)
    message = str(caught[0].message)
    assert len(caught) == 1 and "started off the constraints on the positions" in message
    assert "drifted" not in message and "velocities" not in message
    found = float(re.search(r"max \|phi\| = ([0-9.e-]+) at", message).group(1))
    assert found == pytest.approx(max(abs(phi_x), abs(phi_y)), rel=1e-2), message


def test_a_start_off_both_levels_names_both(linkage):
    """Found by review: theta2 moved by 0.05 from a consistent four-bar state warned of the velocity
    residual alone (0.00165), not of |phi| (0.0146), the larger. phi by hand: the loop closure's
    x-component l1 cos(theta1) + l2 cos(theta2) - l3 cos(theta3) - d at the moved theta2."""
    x0 = np.array(catalog.four_bar_state(0.3, 1.0), dtype=float)
    x0[1] += 0.05
    l1, l2, l3, d = 0.1, 0.35, 0.3, 0.4
    phi_x = l1 * math.cos(x0[0]) + l2 * math.cos(x0[1]) - l3 * math.cos(x0[2]) - d
    phi_y = l1 * math.sin(x0[0]) + l2 * math.sin(x0[1]) - l3 * math.sin(x0[2])
    with pytest.warns(ConstraintDriftWarning, match="started off the constraints on the positions.* and on the "
                                                    "velocities") as caught:
        simulate(linkage, x0, t_end=0.01, h=1e-3, residuals=True)
    message = str(caught[0].message)
    found = float(re.search(r"on the positions, max \|phi\| = ([0-9.e-]+) and", message).group(1))
    assert found == pytest.approx(max(abs(phi_x), abs(phi_y)), rel=1e-2), message
