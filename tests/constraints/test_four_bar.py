"""The four-bar linkage in redundant coordinates (theta1 crank, theta2 coupler, theta3 rocker; two
loop-closure constraints, Lagrange I): a Grashof crank-rocker turns full circles with the
constraints held, and a folded-flat (change-point) configuration is reported, not hidden in NaNs.

References:
- Grashof's criterion and the rocker's limit positions (Norton, Design of Machinery, ch. 2, the
  Grashof condition, and ch. 3, toggle positions of a crank-rocker): with the crank the shortest
  link and s + l < p + q the crank revolves fully; the rocker's extremes occur when crank and
  coupler are collinear, |O B| = l2 + l1 (extended) and l2 - l1 (folded), so by
  the law of cosines in the triangle O O4 B, theta3 = pi - acos((d^2 + l3^2 - |O B|^2) / (2 d l3)).
- rank loss: A = dphi/dq = [[-l1 sin(theta1), -l2 sin(theta2), l3 sin(theta3)], [l1 cos(theta1),
  l2 cos(theta2), -l3 cos(theta3)]] has its 2x2 minors l_i l_j sin(theta_i - theta_j), so it
  loses rank exactly when all three links are parallel; at theta1 = theta2 = theta3 = 0 its first
  row vanishes (also sympy ``Matrix.rank`` of the derived A below). Only a change-point linkage
  (s + l = p + q) can be assembled there.
- kernels: the 30-digit augmented solve of the derived equations (conftest).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.run.simulate import Status, parameter_vector, simulate

H = 1e-4
LENGTH_NAMES = ("l1", "l2", "l3", "d")


@pytest.fixture(scope="module")
def linkage(compiled_system):
    return compiled_system("four_bar")


def test_default_lengths_are_a_grashof_crank_rocker():
    s, *middle, l = sorted(catalog.FOUR_BAR_GRASHOF)
    assert s == catalog.FOUR_BAR_GRASHOF[0]  # the crank is the shortest link
    assert s + l < sum(middle)
    s, *middle, l = sorted(catalog.FOUR_BAR_FOLDING)
    assert s + l == pytest.approx(sum(middle))  # change point: it can fold flat


def rocker_limits(l1, l2, l3, d) -> tuple:
    """theta3 at the two toggle positions (crank and coupler collinear), B above the x axis."""
    angles = [math.pi - math.acos((d * d + l3 * l3 - rho * rho) / (2 * d * l3)) for rho in (l2 + l1, l2 - l1)]
    return min(angles), max(angles)


def test_crank_turns_full_circles_with_bounded_residuals(linkage):
    """From rest at theta1 = 0, tau = 5 N m (above the largest gravity torque): 1 s, 1e4 rk4
    steps with projection."""
    x0 = catalog.four_bar_state(0.0, 0.0)
    run = simulate(linkage, x0, 1.0, H, "rk4", project=True, residuals=True, multipliers=True).check()
    turns = (run["theta1"][-1] - run["theta1"][0]) / (2 * math.pi)
    residual = np.abs(run.residuals).max()
    low, high = rocker_limits(*catalog.FOUR_BAR_GRASHOF)
    theta3 = run["theta3"]
    print(f"\ncrank turns in 1 s: {turns:.2f} (final speed {run['theta1_d'][-1]:.1f} rad/s); max residual "
          f"{residual:.3g}; rocker {theta3.min():.6f} to {theta3.max():.6f} rad (toggle positions "
          f"{low:.6f}, {high:.6f}); max |lambda| {np.abs(run.multipliers).max(axis=0)}")
    assert turns > 3
    assert np.all(np.diff(run["theta1"]) > 0)  # it never stops or turns back
    assert residual < 1e-10
    # the rocker swings between its toggle positions and never beyond
    assert theta3.min() == pytest.approx(low, abs=1e-6)
    assert theta3.max() == pytest.approx(high, abs=1e-6)


def test_residual_drift_without_projection(linkage):
    x0 = catalog.four_bar_state(0.0, 0.0)
    free, kept = (np.abs(simulate(linkage, x0, 1.0, H, "rk4", stride=100, project=p, residuals=True)
                         .check().residuals).max() for p in (False, True))
    print(f"\n1e4 steps: max residual without projection {free:.3g}, with {kept:.3g}")
    assert kept < 1e-10 < free


def folded_state():
    """All links flat on the x axis (FOUR_BAR_FOLDING lengths): O, A = (0.1, 0), B = (0.4, 0) and
    O4 = (0.2, 0), with a crank speed and the coupler and rocker at rest (A u = (0, 0.1) != 0, but
    the singularity is positional: any speeds give the same rank loss)."""
    return [0.0, 0.0, 0.0, 1.0, 0.0, 0.0]


def test_folded_flat_jacobian_loses_rank():
    eom = derive_equations(catalog.four_bar(lengths=catalog.FOUR_BAR_FOLDING))
    values = dict(zip(eom.q, folded_state()[:3])) | dict(eom.parameter_values)
    assert max(abs(v) for v in sp.Matrix(eom.constraints).xreplace(values)) < 1e-15  # it is assembled
    A = sp.Matrix(eom.constraint_jacobian).xreplace(values)
    assert A.rank() == 1
    assert {s.name: v for s, v in eom.parameter_values.items() if s.name in LENGTH_NAMES} == \
        dict(zip(LENGTH_NAMES, catalog.FOUR_BAR_FOLDING))


def test_folded_flat_is_reported_as_singular_constraints(linkage, call_kernel):
    """The lengths are free parameters: the Grashof build runs the change-point linkage too."""
    params = dict(zip(LENGTH_NAMES, catalog.FOUR_BAR_FOLDING))
    with pytest.warns(RuntimeWarning, match="constraint Jacobian lost rank"):
        run = simulate(linkage, folded_state(), 0.1, H, "rk4", params=params, project=True, residuals=True)
    assert run.status == Status.SINGULAR_CONSTRAINTS
    assert run.failed_step == 1 and run.failed_time == 0.0
    assert run.x.shape == (1, 6) and np.all(np.isfinite(run.x))  # only the initial sample, no NaNs
    with pytest.raises(RuntimeError, match="lost rank"):
        run.check()
    p = parameter_vector(linkage, params)
    status, _ = call_kernel(linkage, "multipliers", folded_state(), p, 2, 3)
    assert status == Status.SINGULAR_CONSTRAINTS
    status, (xdot,) = call_kernel(linkage, "rhs", folded_state(), p, 6)
    assert status == Status.SINGULAR_CONSTRAINTS
    # a Grashof state, assembled, is fine (A has full rank whenever the links are not all parallel)
    status, _ = call_kernel(linkage, "multipliers", catalog.four_bar_state(0.0, 1.0), parameter_vector(linkage), 2, 3)
    assert status == Status.OK


def test_projection_reports_the_folded_configuration(linkage):
    """`_project` at the folded state: phi = 0 already, the velocity step meets the rank loss."""
    ffi = linkage.ffi
    x = np.array(folded_state())
    p = parameter_vector(linkage, dict(zip(LENGTH_NAMES, catalog.FOUR_BAR_FOLDING)))
    status = linkage.lib.lcg_four_bar_project(0.0, ffi.from_buffer("double[]", x), ffi.from_buffer("double[]", p))
    assert status == Status.SINGULAR_CONSTRAINTS


def test_kernels_match_the_augmented_system(linkage, constrained_eom, call_kernel, eom_augmented_reference, rng):
    eom = constrained_eom("four_bar")
    defaults = parameter_vector(linkage)
    worst = 0.0
    for _ in range(5):
        x = np.concatenate([rng.uniform(-math.pi, math.pi, 3), rng.uniform(-10, 10, 3)])
        p = defaults * rng.uniform(0.7, 1.3, defaults.size) + np.r_[np.zeros(9), rng.uniform(0, 10, 2)]
        ud_ref, lam_ref = eom_augmented_reference(eom, x, p)
        status, (xdot,) = call_kernel(linkage, "rhs", x, p, 6)
        assert status == Status.OK
        status, (lam, _) = call_kernel(linkage, "multipliers", x, p, 2, 3)
        assert status == Status.OK
        scale = max(1.0, np.abs(ud_ref).max(), np.abs(lam_ref).max())
        worst = max(worst, np.abs(xdot[3:] - ud_ref).max() / scale, np.abs(lam - lam_ref).max() / scale)
    print(f"\nworst relative error of ud, lambda at 5 random states: {worst:.3g}")
    assert worst < 1e-12


def test_the_state_helper_is_assembled():
    """`catalog.four_bar_state` against the loop equations themselves, around the circle."""
    l1, l2, l3, d = catalog.FOUR_BAR_GRASHOF
    for theta1 in np.linspace(0.0, 2 * math.pi, 13):
        t1, t2, t3, w1, w2, w3 = catalog.four_bar_state(theta1, 3.0)
        assert l1 * math.cos(t1) + l2 * math.cos(t2) - l3 * math.cos(t3) - d == pytest.approx(0, abs=1e-15)
        assert l1 * math.sin(t1) + l2 * math.sin(t2) - l3 * math.sin(t3) == pytest.approx(0, abs=1e-15)
        assert -l1 * math.sin(t1) * w1 - l2 * math.sin(t2) * w2 + l3 * math.sin(t3) * w3 == pytest.approx(0, abs=1e-14)
        assert l1 * math.cos(t1) * w1 + l2 * math.cos(t2) * w2 - l3 * math.cos(t3) * w3 == pytest.approx(0, abs=1e-14)
        assert t3 > 0  # B above the x axis: the open branch
