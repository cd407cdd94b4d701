"""A thin disc rolling without slipping in 3D: two velocity constraints with multipliers (issue 14).

Coordinates: the contact point (x, y), yaw psi, lean theta (about the heading), spin phi; the
bodies route with ``motion_constraints``: the disc's material point at the contact has zero
velocity. Independent references:
- the rolling kinematics by hand: x' = r cos(psi) phi', y' = r sin(psi) phi';
- sympy's own ``test_linearize_rolling_disc_kane`` (Kane, with the dependent speeds eliminated):
  its precomputed upright linearization A_sol (m = r = g = 1), whose eigenvalues are all zero at
  the critical spin rate 1/sqrt(3) (= sqrt(g / (3 r)), Routh's stability limit for a thin disc),
  a pair +-i w_lean above it (here w_lean = 1 at 1.5 times critical), a real pair below it.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

CRITICAL = 1 / np.sqrt(3)  # spin rate, m = r = g = 1


def rolling_disc() -> Model:
    x, y, psi, theta, phi = me.dynamicsymbols("x y psi theta phi")
    m, r, g = sp.symbols("m r g", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    heading = N.orientnew("Y", "Axis", [psi, N.z])
    lean = heading.orientnew("L", "Axis", [theta, heading.x])
    body = lean.orientnew("D", "Axis", [phi, lean.y])
    contact = O.locatenew("C", x * N.x + y * N.y)
    centre = contact.locatenew("G", r * lean.z)
    disc = me.RigidBody("disc", centre, body, m, (me.inertia(body, m * r ** 2 / 4, m * r ** 2 / 2, m * r ** 2 / 4),
                                                  centre))
    slip = centre.pos_from(O).dt(N) + body.ang_vel_in(N).cross(contact.pos_from(centre))
    return Model("rolling_disc", [x, y, psi, theta, phi], [m, r, g], bodies=[disc], gravity=-g * N.z, frame=N,
                 origin=O, motion_constraints=[slip.dot(N.x), slip.dot(N.y)],
                 parameter_values={"m": 1.0, "r": 1.0, "g": 1.0}, points={"centre": centre})


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    return compile_model(rolling_disc(), methods=("rk4",), cache_dir=tmp_path_factory.mktemp("disc"))


def sympy_upright_a(spin: float) -> np.ndarray:
    """A_sol of sympy's test_linearize_rolling_disc_kane at q1 = 0, q3d = spin."""
    q1, q3d = sp.symbols("q1 q3d")
    A_sol = sp.Matrix([[0, 0, 0, 0, 0, 0, 0, 1],
                       [0, 0, 0, 0, 0, 1, 0, 0],
                       [0, 0, 0, 0, 0, 0, 1, 0],
                       [sp.sin(q1) * q3d, 0, 0, 0, 0, -sp.sin(q1), -sp.cos(q1), 0],
                       [-sp.cos(q1) * q3d, 0, 0, 0, 0, sp.cos(q1), -sp.sin(q1), 0],
                       [0, sp.Rational(4, 5), 0, 0, 0, 0, 0, 6 * q3d / 5],
                       [0, 0, 0, 0, 0, 0, 0, 0],
                       [0, 0, 0, 0, 0, -2 * q3d, 0, 0]])
    return np.array(A_sol.subs({q1: 0, q3d: spin}), dtype=float)


def test_the_rolling_constraints_are_the_textbook_ones():
    eom = derive_equations(rolling_disc())
    x, y, psi, theta, phi = eom.q
    assert eom.m == 2 and eom.n_holonomic == 0
    r = sp.Symbol("r", positive=True)
    expected = sp.Matrix([[1, 0, 0, 0, -r * sp.cos(psi)], [0, 1, 0, 0, -r * sp.sin(psi)]])
    assert sp.simplify(sp.Matrix(eom.constraint_jacobian) - expected) == sp.zeros(2, 5)


def lean_period(run) -> float:
    """Mean period of theta(t) from its upward zero crossings, interpolated between samples."""
    th, t = run["theta"], run.t
    k = np.nonzero((th[:-1] < 0) & (th[1:] >= 0))[0]
    crossings = t[k] - th[k] * (t[k + 1] - t[k]) / (th[k + 1] - th[k])
    return float(np.diff(crossings).mean())


def test_upright_rolling_above_the_critical_speed_wobbles_at_sympys_frequency(system):
    spin = 1.5 * CRITICAL
    eigenvalues = np.linalg.eigvals(sympy_upright_a(spin))
    w_lean = np.abs(eigenvalues.imag).max()
    assert np.abs(eigenvalues.real).max() < 1e-12  # neutrally stable: a pure oscillation
    lean_rate = 1e-4
    x0 = [0, 0, 0, 0, 0, spin, 0, 0, lean_rate, spin]  # x' = r phi' (rolling), upright, spinning
    run = simulate(system, x0, t_end=40.0, h=1e-3, project=True, residuals=True)
    assert run.ok and np.abs(run.residuals).max() < 1e-12
    np.testing.assert_allclose(lean_period(run), 2 * np.pi / w_lean, rtol=1e-6)
    np.testing.assert_allclose(np.abs(run["theta"]).max(), lean_rate / w_lean, rtol=1e-3)


def test_below_the_critical_speed_the_disc_falls(system):
    spin = 0.5 * CRITICAL
    assert np.linalg.eigvals(sympy_upright_a(spin)).real.max() > 0.1  # sympy: a growing mode
    run = simulate(system, [0, 0, 0, 0, 0, spin, 0, 0, 1e-4, spin], t_end=15.0, h=1e-3, project=True)
    assert np.abs(run["theta"]).max() > 0.3


def test_the_eigenvalues_vanish_at_the_critical_speed():
    """sympy's own assertion, kept here as the reference this file relies on."""
    assert np.abs(np.linalg.eigvals(sympy_upright_a(CRITICAL))).max() < 1e-6


def test_consistent_initial_speeds_and_a_named_violation():
    """consistent_state completes the speeds the rolling constraints fix (x' = r cos(psi) phi',
    y' = r sin(psi) phi', by hand) and names each constraint a held set violates."""
    from lagcodegen.statics.consistent import consistent_state

    eom = derive_equations(rolling_disc())
    q0, u0 = consistent_state(eom, {"x": 0, "y": 0, "psi": 0.3, "theta": 0.1, "phi": 0},
                              {"phi": 2.0, "theta": 0.01, "psi": 0.0})
    np.testing.assert_allclose(u0, [2 * np.cos(0.3), 2 * np.sin(0.3), 0.0, 0.01, 2.0], atol=1e-14)
    with pytest.raises(ValueError, match=r"velocity constraint 0: .* has residual -1.91067; velocity constraint 1"):
        consistent_state(eom, {"x": 0, "y": 0, "psi": 0.3, "theta": 0.1, "phi": 0}, {"phi": 2.0, "x": 0.0, "y": 0.0})


def test_dependent_velocity_constraints_stop_with_a_status(tmp_path):
    """The same rolling constraint twice: A loses rank, the run stops at once with SINGULAR_CONSTRAINTS."""
    import warnings

    from lagcodegen.status import Status

    model = rolling_disc()
    doubled = Model("rolling_disc_doubled", model.coordinates, model.parameters, bodies=model.bodies,
                    gravity=model.gravity, frame=model.frame, origin=model.origin,
                    motion_constraints=list(model.motion_constraints) + [2 * model.motion_constraints[0]],
                    parameter_values={"m": 1.0, "r": 1.0, "g": 1.0})
    system = compile_model(doubled, methods=("rk4",), cache_dir=tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        run = simulate(system, [0, 0, 0, 0, 0, 1.0, 0, 0, 0, 1.0], t_end=1.0, h=1e-3)
    assert run.status == Status.SINGULAR_CONSTRAINTS and run.failed_step == 1


@pytest.mark.parametrize("factor", [1.5, 0.5])
def test_linearization_about_upright_rolling_matches_sympys(factor):
    """linearize_state reduces to the 8 directions the rolling constraints allow; its nonzero
    eigenvalues are those of sympy's A_sol (the zeros form Jordan blocks: compared by size only)."""
    from lagcodegen.statics.state_space import linearize_state

    spin = factor * CRITICAL
    linear = linearize_state(derive_equations(rolling_disc()), [0, 0, 0, 0, 0, spin, 0, 0, 0, spin], values={})
    assert linear.basis.shape == (10, 8)
    ours = linear.eigenvalues()
    theirs = np.linalg.eigvals(sympy_upright_a(spin))
    significant = lambda lam: np.sort_complex(lam[np.abs(lam) > 1e-3])  # noqa: E731
    np.testing.assert_allclose(significant(ours), significant(theirs), atol=1e-8)
    assert np.abs(ours[np.abs(ours) <= 1e-3]).max() < 1e-5 and (np.abs(ours) <= 1e-3).sum() == 6


def test_linearization_refuses_an_inconsistent_state():
    from lagcodegen.statics.state_space import linearize_state

    with pytest.raises(ValueError, match=r"violates constraint row 0 .*\(consistent_state\)"):
        linearize_state(derive_equations(rolling_disc()), [0, 0, 0, 0, 0, 0.0, 0, 0, 0, 1.0], values={})
