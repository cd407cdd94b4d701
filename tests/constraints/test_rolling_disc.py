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


def rolling_disc(**extra) -> Model:
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
                 parameter_values={"m": 1.0, "r": 1.0, "g": 1.0}, points={"centre": centre}, **extra)


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


def test_speeds_given_by_coordinate_name_land_on_that_coordinates_rate_in_either_formulation(tmp_path):
    """Found by review: with formulation="elimination" the speeds are reordered (dependent rates
    last) and a speed given by its coordinate's name was put at that coordinate's position: {"phi":
    2.0} set y' = 2. The expected values are the test above's, by hand. And a run started off the
    rolling constraints warns: it keeps the slip all run."""
    import warnings

    from lagcodegen.run.drift import ConstraintDriftWarning
    from lagcodegen.statics.consistent import consistent_state

    x, y = me.dynamicsymbols("x y")
    start = {"x": 0, "y": 0, "psi": 0.3, "theta": 0.1, "phi": 0}
    eom = derive_equations(rolling_disc(formulation="elimination", dependent_speeds=[x, y]))
    q0, u0 = consistent_state(eom, start, {"phi": 2.0, "theta": 0.01, "psi": 0.0})
    speeds = dict(zip((s.name for s in eom.u), u0))
    assert speeds == pytest.approx({"x_d": 2 * np.cos(0.3), "y_d": 2 * np.sin(0.3), "psi_d": 0.0, "theta_d": 0.01,
                                    "phi_d": 2.0}, abs=1e-14)
    multipliers = compile_model(rolling_disc(), methods=("rk4",), cache_dir=tmp_path)
    slipping = [0, 0, 0.3, 0.1, 0, 0.5, 0.0, 0.0, 0.0, 2.0]  # x' = 0.5, where r cos(psi) phi' = 1.91
    with pytest.warns(ConstraintDriftWarning, match="started off the constraints on the velocities"):
        simulate(multipliers, slipping, t_end=0.01, h=1e-3)
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConstraintDriftWarning)
        simulate(multipliers, list(q0) + [speeds[f"{name}_d"] for name in ("x", "y", "psi", "theta", "phi")],
                 t_end=0.01, h=1e-3)


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


def _sympy_textbook_disc(linearized_at=None):
    """The rolling disc of sympy's test_kane.test_rolling_disc (Kane; its rolling is built into
    the velocities: the contact point has none): yaw q1, lean q2, spin q3, body rates u1..u3 in
    the lean frame. Returns the lean acceleration u1'(q2, u2, u3) with u1 = 0, lambdified; or, with
    ``linearized_at`` = (q2, u2, u3), the eigenvalues of sympy's own ``KanesMethod.linearize`` there."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, 0)
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    inertia = me.inertia(L, m / 4 * r ** 2, m / 2 * r ** 2, m / 4 * r ** 2)
    kd = [me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L]
    kane = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd)
    kane.kanes_equations([me.RigidBody("disc", Dmc, R, m, (inertia, Dmc))], [(Dmc, -m * g * Y.z)])
    if linearized_at is not None:
        lean, spin, turn = linearized_at
        A = kane.linearize(A_and_B=True, op_point={q1: 0, q2: lean, q3: 0, u1: 0, u2: spin, u3: turn})[0]
        return np.linalg.eigvals(np.array(A.xreplace({r: 1, m: 1, g: 1}).evalf(), dtype=float))
    rhs = kane.mass_matrix.LUsolve(kane.forcing).xreplace({r: 1, m: 1, g: 1, u1: 0})
    return sp.lambdify([q2, u2, u3], rhs[0])


def test_a_steady_turn_is_found_and_equals_the_textbook_discs():
    """steady_motion on this file's disc (velocity constraints, multipliers): lean 0.3 rad turning at
    psi' = 0.5 rad/s; the spin phi' that keeps the lean is the one for which sympy's own textbook
    disc (a separate model, rolling in its velocities) has no lean acceleration: with u1 = 0,
    u2 = phi' + psi' sin(lean), u3 = psi' cos(lean) in its lean frame. The other accelerations vanish
    too, and the compiled nonlinear disc holds the turn."""
    from scipy.optimize import brentq

    from lagcodegen.statics.steady import steady_eigenvalues, steady_motion

    eom = derive_equations(rolling_disc())
    lean, yaw_rate = 0.3, 0.5
    turn = steady_motion(eom, {"theta": lean, "psi_d": yaw_rate, "phi_d": 1.0},
                         unknowns=["phi_d", "x_d", "y_d"], steady=["theta_d"])
    spin = turn.values["phi_d"]
    lean_acceleration = _sympy_textbook_disc()
    reference = brentq(lambda phi_d: lean_acceleration(lean, phi_d + yaw_rate * np.sin(lean),
                                                       yaw_rate * np.cos(lean)), spin - 0.5, spin + 0.5, xtol=1e-14)
    assert abs(spin - reference) < 1e-10
    np.testing.assert_allclose(turn.accelerations[[2, 3, 4]], 0.0, atol=1e-12)  # psi'', theta'', phi''
    system = compile_model(eom, methods=("rk4",), outputs=("rhs", "constraints"))
    run = simulate(system, turn.state, t_end=2.0, h=1e-3, project=True)
    assert run.ok and np.abs(run["theta"] - lean).max() < 1e-9 and np.abs(run["psi_d"] - yaw_rate).max() < 1e-9
    # its stability: the reduced linearization (x, y, yaw and spin cyclic) against sympy's own
    # linearization of its textbook disc at the same motion: here an unstable pair +-0.2178
    ours = np.sort_complex(steady_eigenvalues(eom, turn, cyclic=["x", "y", "psi", "phi"],
                                              speeds=["psi_d", "theta_d", "phi_d"]))
    theirs = _sympy_textbook_disc((lean, spin + yaw_rate * np.sin(lean), yaw_rate * np.cos(lean)))
    theirs = np.sort_complex(theirs[np.abs(theirs) > 1e-9])
    assert len(theirs) == 2 and theirs.real.max() > 0.2
    for value in theirs:
        assert np.abs(ours - value).min() < 1e-9, (ours, theirs)
    assert np.sort(np.abs(ours))[:2].max() < 1e-9  # the other two: neutral (a neighbouring steady turn)


def test_steady_motion_names_its_bad_input():
    from lagcodegen.statics.steady import steady_motion

    eom = derive_equations(rolling_disc())
    with pytest.raises(ValueError, match="'lean' is no state"):
        steady_motion(eom, {"theta": 0.3}, unknowns=["lean", "x_d", "y_d"], steady=["theta_d"])
    with pytest.raises(ValueError, match="2 unknowns .* for 3 equations"):
        steady_motion(eom, {"theta": 0.3}, unknowns=["x_d", "y_d"], steady=["theta_d"])
    with pytest.raises(ValueError, match="'theta' is a coordinate"):
        steady_motion(eom, {"theta": 0.3}, unknowns=["phi_d", "x_d", "y_d"], steady=["theta"])


def test_steady_lists_with_a_repeat_or_speeds_the_constraints_cannot_complete_are_named():
    """Found by review: a repeated unknown was silently dropped ("no solution from the given guesses"),
    a repeated speed gave numpy's "Last 2 dimensions of the array must be square", and naming the speeds
    the constraints solve for (x_d, y_d) a bare "Singular matrix"."""
    from lagcodegen.statics.steady import steady_eigenvalues, steady_motion

    eom = derive_equations(rolling_disc())
    with pytest.raises(ValueError, match="unknowns names 'x_d' more than once"):
        steady_motion(eom, {"theta": 0.3, "psi_d": 0.5}, unknowns=["x_d", "x_d", "phi_d"], steady=["theta_d"])
    turn = steady_motion(eom, {"theta": 0.3, "psi_d": 0.5, "phi_d": 1.0}, unknowns=["phi_d", "x_d", "y_d"],
                         steady=["theta_d"])
    with pytest.raises(ValueError, match="'psi_d' named more than once"):
        steady_eigenvalues(eom, turn, cyclic=["x", "y", "psi", "phi"], speeds=["psi_d", "psi_d", "phi_d"])
    with pytest.raises(ValueError, match="the velocity constraints do not fix the speeds not named"):
        steady_eigenvalues(eom, turn, cyclic=["x", "y", "psi", "phi"], speeds=["x_d", "y_d", "phi_d"])
