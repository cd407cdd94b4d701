"""Consistent initial states (`lagcodegen.statics.consistent`) and equilibria with multipliers
(`lagcodegen.statics.constrained.constrained_equilibrium`) of models with holonomic constraints.

Sources:
[BJ]  Beer & Johnston, Vector Mechanics for Engineers: Statics, ch. 10 (method of virtual work:
      a mechanism with one degree of freedom is in equilibrium when the virtual work of the
      applied forces vanishes for every virtual displacement compatible with the constraints;
      the slider-crank is its standard example) and sec. 4.6 (a massless link loaded only at two
      pins is a two-force member: its force acts along the link).
[Haug] E. J. Haug, Computer-Aided Kinematics and Dynamics of Mechanical Systems, sec. 3.5
      (assembly: positions solve phi = 0, speeds solve A u = -phi_t) and sec. 6.3 (M ud + A^T lam
      = F: the multipliers of Cartesian joint constraints are the joint reaction forces).
Each expected value is derived by hand next to its test; the multipliers are also checked against
an independent route, the dynamic (KKT) equations at rest, numerically and in the compiled C.
"""
import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.statics.consistent import consistent_state, constraint_residuals
from lagcodegen.statics.constrained import constrained_equilibrium


# -- models -------------------------------------------------------------------------------------
def cartesian_pendulum(moving_pivot: bool = False):
    """Bob of mass m at (x, y) (y up) on a rod of length l: phi = (x - s)^2 + y^2 - l^2, with the
    pivot at s = 0, or moving as s(t) = a sin(w t) (rheonomic)."""
    x, y = me.dynamicsymbols("x y")
    m, g, l, a, w = sp.symbols("m g l a w")
    t = me.dynamicsymbols._t
    s = a * sp.sin(w * t) if moving_pivot else 0
    params = [m, g, l] + ([a, w] if moving_pivot else [])
    values = {m: 2.0, g: 9.81, l: 1.3, a: 0.2, w: 3.0}
    return derive_equations(Model(
        "cartesian_pendulum_test", [x, y], params, kinetic_energy=m * (x.diff() ** 2 + y.diff() ** 2) / 2,
        potential_energy=m * g * y, constraints=[(x - s) ** 2 + y ** 2 - l ** 2],
        parameter_values={p: values[p] for p in params}))


# Slider-crank in a horizontal plane (no gravity), redundant coordinates: crank angle theta about
# the fixed pivot O, rod angle beta (below the x axis, from the crank pin B to the slider pin C),
# slider position (x_s, y_s). Constraints: the rod closes the loop at C (x and y) and the guide
# keeps y_s = 0:
#   phi_0 = r cos(theta) + L cos(beta) - x_s,  phi_1 = r sin(theta) - L sin(beta) - y_s,  phi_2 = y_s.
# Loads: a torque tau on the crank (Q_theta = tau) and a force P on the slider pointing to -x
# (Q_xs = -P). M = diag(J, J_r, m_s, m_s) is positive definite; at rest it plays no role.
R, L_ROD = 0.1, 0.3


@pytest.fixture(scope="module")
def slider_crank():
    th, be, xs, ys = me.dynamicsymbols("theta beta x_s y_s")
    r, L, J, Jr, ms, tau, P = sp.symbols("r L J J_r m_s tau P")
    T = (J * th.diff() ** 2 + Jr * be.diff() ** 2 + ms * (xs.diff() ** 2 + ys.diff() ** 2)) / 2
    return derive_equations(Model(
        "slider_crank_test", [th, be, xs, ys], [r, L, J, Jr, ms, tau, P], kinetic_energy=T,
        generalized_forces={th: tau, xs: -P},
        constraints=[r * sp.cos(th) + L * sp.cos(be) - xs, r * sp.sin(th) - L * sp.sin(be) - ys, ys],
        parameter_values={r: R, L: L_ROD, J: 0.01, Jr: 0.02, ms: 0.5, tau: 0.0, P: 0.0}))


def crank_geometry(theta):
    """Hand kinematics [BJ ch. 10]: L sin(beta) = r sin(theta), x = r cos(theta) + L cos(beta);
    differentiating, L cos(beta) dbeta = r cos(theta) dtheta, so
    dx/dtheta = -r (sin(theta) + cos(theta) tan(beta))."""
    beta = math.asin(R * math.sin(theta) / L_ROD)
    x = R * math.cos(theta) + L_ROD * math.cos(beta)
    return beta, x, -R * (math.sin(theta) + math.cos(theta) * math.tan(beta))


def crank_state(eom, theta):
    """Consistent configuration at crank angle theta (the rod starts near beta = 0)."""
    q0, _ = consistent_state(eom, {"theta": theta, "beta": 0.0, "x_s": R + L_ROD}, fix=["theta"])
    return q0


THETAS = (0.7, 2.2, 4.0)  # dx/dtheta < 0, < 0, > 0: the balancing P changes sign


# -- consistent states: Cartesian pendulum ------------------------------------------------------
# l = 1.3, x = 0.5: y = +-sqrt(1.69 - 0.25) = +-1.2 (a 5-12-13 triangle).
@pytest.mark.parametrize("y_guess, y_expected", [(-0.3, -1.2), (0.3, 1.2), (-5.0, -1.2)])
def test_pendulum_given_x_the_guess_picks_the_branch_of_y(y_guess, y_expected):
    eom = cartesian_pendulum()
    q0, u0 = consistent_state(eom, {"x": 0.5, "y": y_guess}, fix=["x"])
    np.testing.assert_allclose(q0, [0.5, y_expected], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(u0, [0.0, 0.0])


def test_pendulum_given_x_only_starts_y_at_zero_and_still_converges():
    # y = 0 makes A_free = 2 y singular: the seeded restarts must leave it; either branch is valid
    q0, _ = consistent_state(cartesian_pendulum(), {"x": 0.5})
    assert q0[0] == 0.5 and abs(abs(q0[1]) - 1.2) < 1e-12


@pytest.mark.parametrize("angle", [0.3, -2.0, math.pi / 2])
def test_pendulum_point_off_the_circle_is_projected_radially(angle):
    # The minimum-norm Gauss-Newton step on x^2 + y^2 = l^2 is radial, so a point 2 % outside
    # the circle lands on l (sin a, -cos a): the angle a = atan2(x, -y) of the start is kept.
    eom = cartesian_pendulum()
    start = 1.02 * 1.3 * np.array([math.sin(angle), -math.cos(angle)])
    q0, _ = consistent_state(eom, {"x": start[0], "y": start[1]}, fix=())
    np.testing.assert_allclose(q0, 1.3 * np.array([math.sin(angle), -math.cos(angle)]), rtol=0, atol=1e-12)


def test_pendulum_speeds_follow_from_a_given_xd():
    # d/dt (x^2 + y^2) = 2 x xd + 2 y yd = 0  ->  yd = -x xd / y = -0.5 * 0.6 / (-1.2) = 0.25
    eom = cartesian_pendulum()
    q0, u0 = consistent_state(eom, {"x": 0.5, "y": -1.0}, {"x_d": 0.6}, fix=["x"])
    np.testing.assert_allclose(u0, [0.6, 0.25], rtol=1e-13)
    np.testing.assert_allclose(constraint_residuals(eom, q0, u0), [0.0, 0.0], atol=1e-12)
    # a speed may be named by its coordinate as well
    np.testing.assert_allclose(consistent_state(eom, {"x": 0.5, "y": -1.0}, {"x": 0.6}, fix=["x"])[1], u0)


def test_pendulum_given_speeds_are_projected_onto_the_tangent_when_not_held():
    # nearest speed on the tangent line x xd + y yd = 0 at (0.5, -1.2): remove the radial part
    eom = cartesian_pendulum()
    q0, u0 = consistent_state(eom, {"x": 0.5, "y": -1.2}, {"x_d": 1.0, "y_d": 1.0}, fix_u=())
    radial = q0 / 1.3
    np.testing.assert_allclose(u0, np.ones(2) - (np.ones(2) @ radial) * radial, atol=1e-14)


def test_rheonomic_pivot_speeds_include_dphi_dt():
    # phi = (x - s)^2 + y^2 - l^2, s = a sin(w t): at t = 0.4, with e = x - s,
    # y = -sqrt(l^2 - e^2) and 2 e (xd - sd) + 2 y yd = 0  ->  yd = -e (xd - sd) / y, sd = a w cos(w t).
    eom = cartesian_pendulum(moving_pivot=True)
    t, x, xd = 0.4, 0.5, 0.6
    s, sd = 0.2 * math.sin(3.0 * t), 0.2 * 3.0 * math.cos(3.0 * t)
    y = -math.sqrt(1.3 ** 2 - (x - s) ** 2)
    q0, u0 = consistent_state(eom, {"x": x, "y": -1.0}, {"x_d": xd}, fix=["x"], t=t)
    np.testing.assert_allclose(q0, [x, y], rtol=1e-13)
    np.testing.assert_allclose(u0, [xd, -(x - s) * (xd - sd) / y], rtol=1e-12)
    np.testing.assert_allclose(constraint_residuals(eom, q0, u0, t=t), [0.0, 0.0], atol=1e-12)


# -- consistent states: errors name the violated constraint -------------------------------------
def test_holding_x_and_y_off_the_circle_names_constraint_0_and_its_residual():
    # 0.5^2 + 1.0^2 - 1.3^2 = 1.25 - 1.69 = -0.44
    with pytest.raises(ValueError, match=r"constraint 0: -l\*\*2 \+ x\*\*2 \+ y\*\*2 = 0 has residual -0\.44\b"):
        consistent_state(cartesian_pendulum(), {"x": 0.5, "y": 1.0})


def test_holding_x_beyond_the_rod_reports_the_least_squares_residual():
    # x = 2 > l: the best y is 0, where phi = 4 - 1.69 = 2.31
    with pytest.raises(ValueError, match=r"constraint 0: .* has residual 2\.31\b.*y = 0\b"):
        consistent_state(cartesian_pendulum(), {"x": 2.0, "y": -1.0}, fix=["x"])


def test_held_speeds_off_the_tangent_name_the_velocity_constraint():
    # 2 x xd + 2 y yd = 2 (0.5 * 1 + (-1.2) * 1) = -1.4
    with pytest.raises(ValueError, match=r"velocity constraint 0: .* has residual -1\.4\b"):
        consistent_state(cartesian_pendulum(), {"x": 0.5, "y": -1.2}, {"x_d": 1.0, "y_d": 1.0})


@pytest.mark.parametrize("kwargs, culprit", [
    (dict(q={"z": 1.0}), "'z' is not a coordinate"),
    (dict(q={"x": 0.5}, fix=["y"]), "y of model .* held fixed but have no given value"),
    (dict(q={"x": 0.5}, values={"k": 1.0}), "unknown parameter 'k'"),
])
def test_bad_inputs_are_named(kwargs, culprit):
    with pytest.raises(ValueError, match=culprit):
        consistent_state(cartesian_pendulum(), **kwargs)


def test_constraint_residuals_of_an_inconsistent_state():
    # phi = 0.36 + 0.81 - 1.69 = -0.52;  w = 2 (0.6 * 1 + 0.9 * 2) = 4.8
    got = constraint_residuals(cartesian_pendulum(), {"x": 0.6, "y": 0.9}, [1.0, 2.0])
    np.testing.assert_allclose(got, [-0.52, 4.8], rtol=1e-13)


# -- equilibria with multipliers: Cartesian pendulum --------------------------------------------
@pytest.mark.parametrize("y_guess, sign", [(-0.9, 1.0), (0.9, -1.0)])
def test_pendulum_at_rest_multiplier_is_the_rod_tension(y_guess, sign):
    # At (0, -+l): F = (0, -m g), A = (0, -+2 l); F - A^T lam = 0 gives lam = +-m g / (2 l).
    # The constraint force -A^T lam = (0, m g) holds the bob: tension 2 l lam = m g hanging,
    # compression (lam < 0) standing upright.
    eom = cartesian_pendulum()
    q, lam = constrained_equilibrium(eom, {"x": 0.1, "y": y_guess})
    np.testing.assert_allclose(q, [0.0, -sign * 1.3], atol=1e-12)
    np.testing.assert_allclose(lam, [sign * 2.0 * 9.81 / (2 * 1.3)], rtol=1e-12)


# -- equilibria with multipliers: slider-crank --------------------------------------------------
@pytest.mark.parametrize("theta", THETAS)
def test_slider_crank_virtual_work_balance_needs_no_holding_torque(slider_crank, theta):
    # [BJ ch. 10] virtual work tau dtheta - P dx = 0 for every admissible dtheta:
    #   P = tau / (dx/dtheta). With that P the crank, held at theta, needs no extra torque.
    beta, x, dx = crank_geometry(theta)
    tau = 2.0
    q, lam = constrained_equilibrium(slider_crank, crank_state(slider_crank, theta),
                                     {"tau": tau, "P": tau / dx}, fix=["theta"])
    np.testing.assert_allclose(q, [theta, beta, x, 0.0], atol=1e-13)
    assert abs(lam[3]) < 1e-10 * abs(tau)


@pytest.mark.parametrize("theta", THETAS)
def test_slider_crank_force_that_balances_a_crank_torque(slider_crank, theta):
    # Holding the slider at x(theta) under the crank torque: the holding force -lam_hold (on x_s)
    # replaces the load -P, so the balancing load is P = lam_hold = tau / (dx/dtheta) [BJ ch. 10].
    beta, x, dx = crank_geometry(theta)
    tau = 2.0
    q, lam = constrained_equilibrium(slider_crank, crank_state(slider_crank, theta),
                                     {"tau": tau, "P": 0.0}, fix=["x_s"])
    np.testing.assert_allclose(q, [theta, beta, x, 0.0], atol=1e-12)
    np.testing.assert_allclose(lam[3], tau / dx, rtol=1e-10)


@pytest.mark.parametrize("theta", THETAS)
def test_slider_crank_multipliers_are_the_pin_and_guide_reactions(slider_crank, theta):
    # Massless rod at rest = two-force member [BJ sec. 4.6]: compression C along B -> C,
    # direction (cos beta, -sin beta). Slider: x: C cos(beta) - P = 0; y: -C sin(beta) + N = 0,
    # so C = P / cos(beta), guide normal force N = P tan(beta).
    # Constraint forces on the slider are -A^T lam: on x_s, lam_0 (the pin's x-force) = P;
    # on y_s, lam_1 - lam_2 = 0 with lam_1 the pin's y-force -C sin(beta) = -P tan(beta) and
    # -lam_2 = N. The driving torque needed (-lam_hold) is, by virtual work, P dx/dtheta.
    beta, _, dx = crank_geometry(theta)
    P = 5.0
    guess = crank_state(slider_crank, theta) + [0.05, 0.0, 0.0, 0.0]  # the mapping sets theta
    q, lam = constrained_equilibrium(slider_crank, guess, {"P": P}, fix={"theta": theta})
    assert q[0] == theta
    t = math.tan(beta)
    np.testing.assert_allclose(lam, [P, -P * t, -P * t, -P * dx], rtol=1e-10, atol=1e-12)


def _kkt_at_rest(eom, q, values):
    """Second route: the first-kind equations [M A^T; A 0] [ud; lam] = [F; gamma] at u = 0."""
    vals = {p: values.get(p.name, v) for p, v in eom.parameter_values.items()}
    rest = {**{ui: 0.0 for ui in eom.u}, **dict(zip(eom.q, q)), eom.t: 0.0, **vals}
    M, A, F, gamma = (np.array(sp.Matrix(X).xreplace(rest).evalf(), dtype=float) for X in
                      (eom.mass_matrix, eom.constraint_jacobian, eom.forcing, eom.constraint_bias))
    n, m = eom.n, eom.m
    K = np.block([[M, A.T], [A, np.zeros((m, m))]])
    sol = np.linalg.solve(K, np.concatenate([F.ravel(), gamma.ravel()]))
    return sol[:n], sol[n:]


def test_slider_crank_balanced_state_is_at_rest_in_the_dynamic_equations(slider_crank):
    theta = THETAS[0]
    values = {"tau": 2.0, "P": 2.0 / crank_geometry(theta)[2]}
    q, lam = constrained_equilibrium(slider_crank, crank_state(slider_crank, theta), values, fix=["theta"])
    ud, lam_dyn = _kkt_at_rest(slider_crank, q, values)
    np.testing.assert_allclose(ud, np.zeros(4), atol=1e-9)
    np.testing.assert_allclose(lam_dyn, lam[:3], rtol=1e-10)


@pytest.mark.compiler
def test_slider_crank_compiled_multipliers_agree_at_rest(slider_crank, kernel_cache_dir):
    # Third route: the generated C solves the first-kind system for lam at the balanced state.
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import parameter_vector

    theta = THETAS[2]
    values = {"tau": 2.0, "P": 2.0 / crank_geometry(theta)[2]}
    q, lam = constrained_equilibrium(slider_crank, crank_state(slider_crank, theta), values, fix=["theta"])
    system = compile_model(slider_crank, outputs=["multipliers"], methods=(), cache_dir=kernel_cache_dir)
    x = np.concatenate([q, np.zeros(4)])
    p = parameter_vector(system, values)
    lam_c, Q = np.zeros(3), np.zeros(4)
    fb = system.ffi.from_buffer
    status = getattr(system.lib, f"{system.layout.prefix}_multipliers")(
        0.0, fb("double[]", x), fb("double[]", p), fb("double[]", lam_c, require_writable=True),
        fb("double[]", Q, require_writable=True))
    assert status == 0
    np.testing.assert_allclose(lam_c, lam[:3], rtol=1e-10)


def test_constrained_equilibrium_errors_name_the_culprit(slider_crank):
    q0 = crank_state(slider_crank, 0.7)
    with pytest.raises(ValueError, match="'phi' is not a coordinate"):
        constrained_equilibrium(slider_crank, q0, fix=["phi"])
    x = me.dynamicsymbols("x")
    free = derive_equations(Model("free_mass_test", [x], [], kinetic_energy=x.diff() ** 2 / 2))
    with pytest.raises(ValueError, match="no holonomic constraints"):
        constrained_equilibrium(free, [0.0])
    with pytest.raises(ValueError, match="depends on t"):
        constrained_equilibrium(cartesian_pendulum(moving_pivot=True), [0.0, -1.3])
