"""Coordinates and speeds of different counts (n_q != n_u): Kane's kinematic differential
equations qd = K(q, u) with fewer or more speeds than coordinates.

References, each independent of lagcodegen:
- the torque-free asymmetric rigid body in Euler parameters (4 coordinates, 3 body rates): Euler's
  equations I1 w1' = (I2 - I3) w2 w3 (cyclic) and the quaternion kinematics qd = 1/2 Q(q) w, written
  here by hand in numpy (Kane, Likins and Levinson, Spacecraft Dynamics, sec. 1.13; Goldstein,
  Classical Mechanics, sec. 5.5); the invariants T = 1/2 sum I_i w_i^2 and the angular momentum in
  the inertial frame, taken from sympy.mechanics' own ``angular_momentum``;
- sympy's own ``mass_matrix_full \\ forcing_full`` for the same KanesMethod objects.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

from lagcodegen import Model, derive_equations
from lagcodegen.model import ModelError
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import c_pointer, dependent_speeds, parameter_vector, reactions, simulate, step_jacobians
from lagcodegen.run.sweep import sweep

pytestmark = pytest.mark.compiler

INERTIA = {"I1": 1.0, "I2": 2.0, "I3": 3.0}
X0 = [1.0, 0.0, 0.0, 0.0, 0.3, 1.0, 0.2]  # near the unstable middle axis: a tumbling motion


def _quaternion_body(q0_dependent: bool = False):
    """Kane: Euler parameters q0..q3 of B in N, body rates w1..w3 as the speeds; ``q0_dependent``:
    q0 dependent on Kane's configuration constraint |q|^2 = 1 (q_dependent=[q0])."""
    q0, q1, q2, q3 = me.dynamicsymbols("q0:4")
    w1, w2, w3 = me.dynamicsymbols("w1:4")
    I1, I2, I3 = sp.symbols("I1:4")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Quaternion", [q0, q1, q2, q3])
    B.set_ang_vel(N, w1 * B.x + w2 * B.y + w3 * B.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    body = me.RigidBody("body", O, B, 1, (me.inertia(B, I1, I2, I3), O))
    rates = sp.Matrix([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]]) * sp.Matrix([w1, w2, w3]) / 2
    kd = [c.diff(me.dynamicsymbols._t) - rate for c, rate in zip((q0, q1, q2, q3), rates)]
    if q0_dependent:
        kane = me.KanesMethod(N, q_ind=[q1, q2, q3], q_dependent=[q0], kd_eqs=kd, u_ind=[w1, w2, w3],
                              configuration_constraints=[q0 ** 2 + q1 ** 2 + q2 ** 2 + q3 ** 2 - 1])
    else:
        kane = me.KanesMethod(N, q_ind=[q0, q1, q2, q3], u_ind=[w1, w2, w3], kd_eqs=kd)
    kane.kanes_equations([body], [])
    momentum = body.angular_momentum(O, N)
    H = sp.lambdify([q0, q1, q2, q3, w1, w2, w3, I1, I2, I3],
                    [momentum.dot(N.x), momentum.dot(N.y), momentum.dot(N.z)])
    return kane, N, (I1, I2, I3), H


@pytest.fixture(scope="module")
def body():
    kane, frame, inertias, H = _quaternion_body()
    model = Model("quaternion_body", parameters=list(inertias), sympy_model=kane, frame=frame)
    system = compile_model(model, outputs=["rhs", "energy", "jacobian", "step_jacobian"], methods=["rk4", "euler"])
    return kane, model, system, H


def _euler_rhs(t, x, I1=1.0, I2=2.0, I3=3.0):
    """Hand-written: quaternion kinematics and Euler's equations of the torque-free body."""
    q0, q1, q2, q3, w1, w2, w3 = x
    return [(-q1 * w1 - q2 * w2 - q3 * w3) / 2, (q0 * w1 - q3 * w2 + q2 * w3) / 2,
            (q3 * w1 + q0 * w2 - q1 * w3) / 2, (-q2 * w1 + q1 * w2 + q0 * w3) / 2,
            (I2 - I3) * w2 * w3 / I1, (I3 - I1) * w3 * w1 / I2, (I1 - I2) * w1 * w2 / I3]


def _rhs(system, x, params):
    """The compiled <prefix>_rhs at t = 0."""
    x = np.asarray(x, dtype=float)
    xdot = np.empty_like(x)
    p = parameter_vector(system, params)
    code = getattr(system.lib, f"{system.layout.prefix}_rhs")(0.0, c_pointer(system, x), c_pointer(system, p),
                                                                c_pointer(system, xdot))
    assert code == 0
    return xdot


def test_four_coordinates_three_speeds_are_derived_as_sympy_gives_them(body):
    kane, model, system, _ = body
    eom = derive_equations(model)
    assert (eom.n_q, eom.n_u, eom.n_state) == (4, 3, 7)
    assert eom.mass_matrix.shape == (3, 3) and eom.kinematics.shape == (4, 1)
    with pytest.raises(ValueError, match="4 coordinates and 3 speeds"):
        _ = eom.n
    assert system.layout.coordinates == ("q0", "q1", "q2", "q3") and system.layout.speeds == ("w1", "w2", "w3")


def test_header_states_the_counts_of_coordinates_and_speeds(body):
    header = body[2].sources.header
    assert "#define LCG_QUATERNION_BODY_N 4\n" in header
    assert "#define LCG_QUATERNION_BODY_N_SPEEDS 3\n" in header
    assert "#define LCG_QUATERNION_BODY_N_STATE 7\n" in header
    assert "x[4] = w1 (speed)" in header and "x[3] = q3 (coordinate)" in header


def test_rhs_equals_sympy_and_euler_equations(body):
    kane, _, system, _ = body
    q, u = list(kane.q), list(kane.u)
    I = sp.symbols("I1:4")
    sympy_rhs = sp.lambdify(q + u + list(I), kane.mass_matrix_full.LUsolve(kane.forcing_full))
    rng = np.random.default_rng(14)
    for _ in range(3):
        quaternion = rng.normal(size=4)
        x = np.concatenate([quaternion / np.linalg.norm(quaternion), rng.normal(size=3)])
        inertias = rng.uniform(0.5, 3.0, 3)
        ours = _rhs(system, x, dict(zip(("I1", "I2", "I3"), inertias)))
        np.testing.assert_allclose(ours, np.ravel(sympy_rhs(*x, *inertias)), rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(ours, _euler_rhs(0.0, x, *inertias), rtol=1e-12, atol=1e-12)


def test_rk4_follows_dop853_on_the_hand_written_equations(body):
    system = body[2]
    run = simulate(system, X0, 1.0, 1e-3, params=INERTIA)
    reference = solve_ivp(_euler_rhs, (0.0, 1.0), X0, method="DOP853", rtol=1e-12, atol=1e-12)
    assert run.ok
    np.testing.assert_allclose(run.x[-1], reference.y[:, -1], rtol=0, atol=1e-11)


def test_energy_momentum_and_unit_norm_are_kept_to_fourth_order(body):
    *_, system, H = body
    drift = {}
    for h in (0.02, 0.01):
        run = simulate(system, X0, 20.0, h, params=INERTIA, energy=True)
        assert run.ok
        x = run.x
        momentum = np.array(H(*x.T, 1.0, 2.0, 3.0)).T
        drift[h] = (np.abs(run.energy - run.energy[0]).max(),
                    np.linalg.norm(momentum - momentum[0], axis=1).max(),
                    np.abs(np.linalg.norm(x[:, :4], axis=1) - 1.0).max())
    for coarse, fine in zip(drift[0.02], drift[0.01]):
        assert fine < 1e-6
        assert 12.0 < coarse / fine < 20.0  # RK4: error ~ h^4, ratio 16 when h is halved


def test_step_jacobian_equals_finite_differences_of_the_step(body):
    system = body[2]
    x = np.array(X0[:4] + [0.5, -0.4, 0.9])
    _, Fx, _ = step_jacobians(system, x, parameter_vector(system, INERTIA), 0.01, method="rk4")
    assert Fx.shape == (7, 7)
    eps = 1e-6
    for c in range(7):
        up, down = x.copy(), x.copy()
        up[c] += eps
        down[c] -= eps
        column = (simulate(system, up, 0.01, 0.01, params=INERTIA).x[-1]
                  - simulate(system, down, 0.01, 0.01, params=INERTIA).x[-1]) / (2 * eps)
        np.testing.assert_allclose(Fx[:, c], column, atol=1e-8)


def test_sweep_lanes_and_scalar_agree_with_simulate(body):
    system = body[2]
    grid = {"I2": np.linspace(1.5, 2.5, 5)}
    results = {kernel: sweep(system, grid, x0=X0, t_end=0.5, h=1e-3, params=INERTIA, kernel=kernel)
               for kernel in ("scalar", "lanes")}
    np.testing.assert_array_equal(results["scalar"].x_final, results["lanes"].x_final)
    for i, I2 in enumerate(grid["I2"]):
        alone = simulate(system, X0, 0.5, 1e-3, params={**INERTIA, "I2": I2})
        np.testing.assert_array_equal(results["scalar"].x_final[i], alone.x[-1])
        np.testing.assert_array_equal(results["scalar"].q_max[i], np.abs(alone.x[:, :4]).max(axis=0))


def _disc_with_contact_speeds(auxiliary=False):
    """sympy's rolling-disc frame (test_kane2) with the contact point's velocity as two more
    speeds u4, u5 and no coordinates for its position (ignorable): 3 coordinates, 5 speeds
    (``auxiliary``: u4, u5 as Kane's auxiliary speeds instead)."""
    q1, q2, q3, u1, u2, u3, u4, u5 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3 u4 u5")
    r, m, g = sp.symbols("r m g")
    N = me.ReferenceFrame("N")
    Y = N.orientnew("Y", "Axis", [q1, N.z])
    L = Y.orientnew("L", "Axis", [q2, Y.x])
    R = L.orientnew("R", "Axis", [q3, L.y])
    w_R_N_qd = R.ang_vel_in(N)
    R.set_ang_vel(N, u1 * L.x + u2 * L.y + u3 * L.z)
    C = me.Point("C")
    C.set_vel(N, u4 * L.x + u5 * (Y.z ^ L.x))
    Dmc = C.locatenew("Dmc", r * L.z)
    Dmc.v2pt_theory(C, N, R)
    inertia = me.inertia(L, m / 4 * r ** 2, m / 2 * r ** 2, m / 4 * r ** 2)
    kd = [me.dot(R.ang_vel_in(N) - w_R_N_qd, uv) for uv in L]
    disk = me.RigidBody("disk", Dmc, R, m, (inertia, Dmc))
    if auxiliary:
        kane = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd, u_auxiliary=[u4, u5])
    else:
        kane = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3, u4, u5], kd_eqs=kd)
    kane.kanes_equations([disk], [(Dmc, -m * g * Y.z)])
    return kane, (r, m, g)


def test_more_speeds_than_coordinates_match_sympy():
    # This model used to be refused (and before that, silently wrong: a leading 3x3 block of M).
    kane, params = _disc_with_contact_speeds()
    system = compile_model(Model("sliding_disc", parameters=list(params), sympy_model=kane),
                           outputs=["rhs"], methods=["rk4"])
    assert (system.layout.n_q, system.layout.n_u) == (3, 5)
    sympy_rhs = sp.lambdify(list(kane.q) + list(kane.u) + list(params),
                            kane.mass_matrix_full.LUsolve(kane.forcing_full))
    rng = np.random.default_rng(5)
    for _ in range(3):
        x = np.concatenate([rng.uniform(-1.0, 1.0, 3), rng.normal(size=5)])
        values = {"r": 0.3, "m": 2.0, "g": 9.81}
        np.testing.assert_allclose(_rhs(system, x, values), np.ravel(sympy_rhs(*x, *values.values())),
                                   rtol=1e-11, atol=1e-11)


def test_auxiliary_speeds_stay_out_of_the_state():
    # They serve sympy's auxiliary_eqs (reaction forces) and are zero in its rhs; this model was refused.
    kane, params = _disc_with_contact_speeds(auxiliary=True)
    model = Model("disc_aux", parameters=list(params), sympy_model=kane)
    eom = derive_equations(model)
    assert [str(s) for s in eom.speeds] == ["u1(t)", "u2(t)", "u3(t)"]
    assert not {str(s) for s in eom.forcing.free_symbols} & {"u4", "u5"}


def _wheel(constraint=None, **model_options):
    """A wheel rolling on a line (theta' = -x'/r) pushed by a constant force F at its hub (Kane,
    u_theta dependent)."""
    t = me.dynamicsymbols._t
    xw, theta, ux, utheta = me.dynamicsymbols("x_w theta u_x u_theta")
    m, r, F = sp.symbols("m r F", positive=True)
    N = me.ReferenceFrame("N")
    W = N.orientnew("W", "Axis", [theta, N.z])
    W.set_ang_vel(N, utheta * N.z)
    P = me.Point("P")
    P.set_vel(N, ux * N.x)
    wheel = me.RigidBody("wheel", P, W, m, (me.inertia(W, 1, 1, m * r ** 2 / 2), P))
    rolling = utheta + ux / r if constraint is None else constraint(utheta, ux, theta, r)
    kane = me.KanesMethod(N, q_ind=[xw, theta], u_ind=[ux], u_dependent=[utheta],
                          kd_eqs=[xw.diff(t) - ux, theta.diff(t) - utheta], velocity_constraints=[rolling])
    kane.kanes_equations([wheel], [(P, F * N.x)])
    return Model("wheel", parameters=[m, r, F], sympy_model=kane, frame=N, **model_options)


WHEEL = {"m": 2.0, "r": 0.5, "F": 3.0}


def _wheel_by_hand(t_end, v0=1.0):
    """x'' = F / (m + I / r^2) = 2 F / (3 m) for I = m r^2 / 2; theta = -x / r."""
    a = 2 * WHEEL["F"] / (3 * WHEEL["m"])
    x, v = v0 * t_end + a * t_end ** 2 / 2, v0 + a * t_end
    return x, -x / WHEEL["r"], v, -v / WHEEL["r"]


def test_wheel_with_its_dependent_speed_eliminated_rolls_as_by_hand():
    # Kane's dependent speeds used to be refused; elimination is the default formulation.
    model = _wheel()
    assert derive_equations(model).n_dependent == 1
    system = compile_model(model, outputs=["rhs", "energy"], methods=["rk4"])
    assert system.layout.speeds == ("u_x",) and system.layout.dependent_speeds == ("u_theta",)
    assert " * Dependent speeds, not in x" in system.sources.header
    assert " *   u_dep[0] = u_theta\n" in system.sources.header and "x[2] = u_x (speed)" in system.sources.header
    run = simulate(system, [0.0, 0.0, 1.0], 2.0, 1e-3, params=WHEEL, energy=True)
    x, theta, v, w = _wheel_by_hand(2.0)
    np.testing.assert_allclose(run.x[-1], [x, theta, v], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(dependent_speeds(system, run.x, WHEEL), -run.x[:, 2:] / WHEEL["r"], rtol=1e-14)
    np.testing.assert_allclose(run.energy[-1] - run.energy[0], WHEEL["F"] * x, rtol=1e-10)  # the work of F


def test_wheel_with_multipliers_keeps_every_speed():
    system = compile_model(_wheel(formulation="multipliers"), outputs=["rhs", "multipliers"], methods=["rk4"])
    assert system.layout.speeds == ("u_x", "u_theta") and not system.layout.dependent_speeds
    run = simulate(system, [0.0, 0.0, 1.0, -2.0], 2.0, 1e-3, params=WHEEL)
    np.testing.assert_allclose(run.x[-1], _wheel_by_hand(2.0), rtol=1e-12, atol=1e-12)


def test_a_singular_constraint_jacobian_in_the_dependent_speeds_is_named():
    # u_theta sin(theta) + u_x / r = 0: at theta = 0 the constraint does not fix u_theta.
    system = compile_model(_wheel(lambda utheta, ux, theta, r: utheta * sp.sin(theta) + ux / r),
                           outputs=["rhs"], methods=["rk4"])
    with pytest.raises(ValueError, match=r"dependent speeds u_theta at t = 0.0, x = \[0\. 0\. 1\.\]: .*singular"):
        simulate(system, [0.0, 0.0, 1.0], 1.0, 1e-3, params=WHEEL)
    with pytest.raises(ValueError, match="singular"):
        dependent_speeds(system, [0.0, 0.0, 1.0], WHEEL)
    # from theta = 1 the wheel turns towards sin(theta) = 0, where u_theta = -u_x / (r sin(theta))
    # grows without bound: the run stops there with a status, not with NaN or a wrong OK
    with pytest.warns(RuntimeWarning, match="stopped"):
        run = simulate(system, [0.0, 1.0, 1.0], 50.0, 1e-3, params=WHEEL)
    assert run.status.name in ("SINGULAR_CONSTRAINTS", "SINGULAR_MASS_MATRIX"), run.status
    assert abs(np.sin(run.x[-1, 1])) < 0.05 and np.all(np.isfinite(run.x))


def test_elimination_is_refused_where_it_cannot_apply():
    from lagcodegen import ModelError
    with pytest.raises(ModelError, match="formulation must be one of"):
        _wheel(formulation="kane")
    x = me.dynamicsymbols("x")
    with pytest.raises(ModelError, match="formulation 'elimination' needs named dependent speeds"):
        derive_equations(Model("slider", [x], [], kinetic_energy=x.diff() ** 2 / 2,
                               motion_constraints=[x.diff() - 1], formulation="elimination"))


def _sympy_rolling_disc_with_contact_forces():
    """The KanesMethod sympy's own test_kane2.test_aux_dep forms: a disc rolling on a plane with
    dependent coordinate and speeds, and auxiliary speeds exposing the contact force (Fx, Fy, Fz)."""
    from sympy.physics.mechanics.tests import test_kane2

    formed, original = [], me.KanesMethod.kanes_equations

    def record(self, *args, **kwargs):
        result = original(self, *args, **kwargs)
        formed.append(self)
        return result

    me.KanesMethod.kanes_equations = record
    try:
        test_kane2.test_aux_dep()
    finally:
        me.KanesMethod.kanes_equations = original
    return formed[-1]


@pytest.fixture(scope="module")
def disc_with_contact_forces():
    kane = _sympy_rolling_disc_with_contact_forces()
    t = me.dynamicsymbols._t
    parameters = sorted((kane.mass_matrix.free_symbols | kane.forcing.free_symbols) - {t}, key=str)
    return kane, parameters


def test_a_kane_model_with_configuration_constraints_is_refused_with_multipliers(disc_with_contact_forces):
    """Found by review: with multipliers only A u + b = 0 is held, and a Kane four-bar started 2 units
    off its loop closure ran with status OK; its configuration constraints need the elimination."""
    kane, parameters = disc_with_contact_forces
    with pytest.raises(ModelError, match=r"configuration constraints of the KanesMethod \(q_dependent: q3\(t\)\)"):
        derive_equations(Model("disc_multipliers", parameters=parameters, sympy_model=kane, formulation="multipliers"))


@pytest.mark.parametrize("formulation", ["elimination"])
def test_contact_forces_from_auxiliary_speeds_equal_sympys(disc_with_contact_forces, formulation):
    """Reference: sympy's auxiliary_eqs at sympy's own accelerations (mass_matrix_full \\ forcing_full
    at the same state), solved for Fx, Fy, Fz."""
    kane, parameters = disc_with_contact_forces
    t = me.dynamicsymbols._t
    system = compile_model(Model(f"disc_{formulation}", parameters=parameters, sympy_model=kane,
                                 formulation=formulation), methods=["rk4"])
    assert system.layout.reactions == ("Fx", "Fy", "Fz")
    values = {p.name: 1.0 + 0.25 * i for i, p in enumerate(parameters)}
    rng = np.random.default_rng(7)
    n_q, n_independent = len(kane.q), len(kane.u) - len(system.layout.dependent_speeds or ())
    for _ in range(3):
        state = np.concatenate([rng.uniform(-0.5, 0.5, n_q), rng.normal(size=len(kane.u))])
        if system.layout.dependent_speeds:
            ours_state = state[:n_q + n_independent]
            state = np.concatenate([ours_state, dependent_speeds(system, ours_state, values)])
        else:
            ours_state = state  # the multipliers' state is any; sympy's rhs takes the same
        at = dict(zip(list(kane.q) + list(kane.u), state)) | {p: values[p.name] for p in parameters}
        at |= {a: 0 for a in kane._uaux} | {a.diff(t): 0 for a in kane._uaux}
        accelerations = kane.mass_matrix_full.xreplace(at).evalf().LUsolve(kane.forcing_full.xreplace(at).evalf())
        rates = dict(zip([u.diff(t) for u in kane.u], list(accelerations)[n_q:]))
        forces = sp.symbols("Fx Fy Fz")
        solved = sp.solve(list(kane.auxiliary_eqs.xreplace(rates).xreplace(at)), forces)
        np.testing.assert_allclose(reactions(system, ours_state, values), [float(solved[f]) for f in forces],
                                   rtol=1e-10, atol=1e-10)


def test_a_disc_rolling_upright_and_straight_is_held_up_by_its_weight(disc_with_contact_forces):
    """By hand: upright (lean 0), straight (no yaw rate) steady rolling has no friction force and a
    normal force equal to the weight m g."""
    pass

    kane, parameters = disc_with_contact_forces
    system = compile_model(Model("disc_upright", parameters=parameters, sympy_model=kane), methods=["rk4"])
    values = {p.name: 1.0 + 0.25 * i for i, p in enumerate(parameters)}
    names = [str(q).replace("(t)", "") for q in kane.q]
    x = dict.fromkeys(system.layout.coordinates + system.layout.speeds, 0.0)
    x[names[3]] = -values["r"]  # q3: the disc centre's height on the ground plane's normal, -r cos(lean)
    x[system.layout.speeds[1]] = 2.0  # spin about the axle (the disc-fixed y axis)
    state = [x[name] for name in system.layout.coordinates + system.layout.speeds]
    Fx, Fy, Fz = reactions(system, state, values)
    assert abs(Fx) < 1e-12 and abs(Fy) < 1e-12
    assert abs(abs(Fz) - values["m"] * values["g"]) < 1e-12


def test_reactions_of_a_build_without_them_name_the_output(disc_with_contact_forces):
    """Found by review: the disc built with outputs=("rhs",) answered reactions() with "has no
    reactions", though its KanesMethod has them."""
    pass

    kane, parameters = disc_with_contact_forces
    system = compile_model(Model("disc_rhs_only", parameters=parameters, sympy_model=kane), outputs=("rhs",),
                           methods=["rk4"])
    with pytest.raises(ValueError, match=r"compiled without reactions.*outputs=\(\.\.\., 'reactions'\)"):
        reactions(system, np.zeros(len(system.layout.coordinates) + len(system.layout.speeds)),
                  {p.name: 1.0 for p in parameters})


def test_an_undeclared_parameter_among_the_reactions_is_named():
    """Found by review: g left out of parameters=[...] but in the auxiliary equations was counted as an
    unknown force ("hold 3 unknown forces (fy, fz, g)"), which said nothing of the missing declaration."""
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    m, k, g = sp.symbols("m k g", positive=True)
    q1, u1, ua, ub = me.dynamicsymbols("q1 u1 ua ub")
    fy, fz = me.dynamicsymbols("fy fz")
    P = O.locatenew("P", q1 * N.x)
    P.set_vel(N, u1 * N.x + ua * N.y + ub * N.z)
    kane = me.KanesMethod(N, [q1], [u1], kd_eqs=[q1.diff() - u1], u_auxiliary=[ua, ub])
    kane.kanes_equations([me.Particle("p", P, m)], [(P, -k * q1 * N.x - m * g * N.y + fy * N.y + fz * N.z)])
    with pytest.raises(ModelError, match=r"unknown forces \(fy, fz, g\).*declare a parameter"):
        derive_equations(Model("forgot_g", parameters=[m, k], sympy_model=kane))


def test_a_coordinate_named_like_another_ones_speed_is_named_with_both_roles():
    """Found by review: coordinates q and q_d (Lagrange names q's speed q_d) were refused with "used by a
    coordinate or speed and by a coordinate or speed"."""
    q, q_d = me.dynamicsymbols("q q_d")
    m, k = sp.symbols("m k", positive=True)
    lagrangian = m * (q.diff() ** 2 + q_d.diff() ** 2) / 2 - k * (q ** 2 + q_d ** 2) / 2
    method = me.LagrangesMethod(lagrangian, [q, q_d])
    method.form_lagranges_equations()
    with pytest.raises(ModelError, match=r"'q_d' is used by coordinate q_d and by the speed of coordinate q"):
        derive_equations(Model("clash", parameters=[m, k], sympy_model=method))


def test_the_unit_norm_as_a_configuration_constraint_is_kept_by_projection():
    """Euler parameters with q0 dependent on Kane's configuration constraint |q|^2 = 1: project=True
    solves it for q0 after every step (Newton), so the norm stays at 1 to the projection's tolerance
    over 100 s of RK4 at h = 0.02, where without projection it drifts with the integrator's error;
    the energy (1/2 sum I_i w_i^2, by hand) is not touched by the projection."""
    kane, N, (I1, I2, I3), _ = _quaternion_body(q0_dependent=True)
    system = compile_model(Model("quaternion_constrained", parameters=[I1, I2, I3], sympy_model=kane, frame=N),
                           methods=["rk4"])
    assert system.layout.coordinates == ("q1", "q2", "q3", "q0")
    x0 = [0.0, 0.0, 0.0, 1.0, 0.3, 1.0, 0.2]
    drift = {}
    for project in (False, True):
        run = simulate(system, x0, 100.0, 0.02, params=INERTIA, project=project, energy=True)
        assert run.ok
        drift[project] = np.abs(np.linalg.norm(run.x[:, :4], axis=1) - 1.0).max()
        by_hand = 0.5 * (1.0 * run.x[:, 4] ** 2 + 2.0 * run.x[:, 5] ** 2 + 3.0 * run.x[:, 6] ** 2)
        np.testing.assert_allclose(run.energy, by_hand, rtol=1e-13)
    assert drift[True] < 1e-12 < 1e-11 < drift[False]


def test_a_start_off_the_configuration_constraints_is_named_with_the_value_that_fits():
    kane, N, (I1, I2, I3), _ = _quaternion_body(q0_dependent=True)
    system = compile_model(Model("quaternion_off", parameters=[I1, I2, I3], sympy_model=kane, frame=N),
                           methods=["rk4"])
    # q1 = 0.6: q0 = 0.8 fits (0.6^2 + 0.8^2 = 1, by hand); 0.9 does not
    with pytest.raises(ValueError, match=r"q0 = 0\.9 \(fits: 0\.8"):
        simulate(system, [0.6, 0.0, 0.0, 0.9, 0.1, 0.2, 0.3], 1.0, 0.01, params=INERTIA)
    assert simulate(system, [0.6, 0.0, 0.0, 0.8, 0.1, 0.2, 0.3], 1.0, 0.01, params=INERTIA).ok


def test_a_sweep_checks_every_member_on_the_configuration_constraints():
    # found by review: sweep ran members off |q| = 1 with status OK where simulate refuses the start
    kane, N, (I1, I2, I3), _ = _quaternion_body(q0_dependent=True)
    system = compile_model(Model("quaternion_off", parameters=[I1, I2, I3], sympy_model=kane, frame=N),
                           methods=["rk4"])
    x0 = [0.6, 0.0, 0.0, 0.8, 0.1, 0.2, 0.3]  # q0 = 0.8 fits q1 = 0.6 (by hand), not q1 = 0
    with pytest.raises(ValueError, match=r"member 1 \(q1 = 0\): x0 violates.*q0 = 0\.8 \(fits: 1"):
        sweep(system, {"q1": [0.6, 0.0]}, x0=x0, t_end=0.1, h=0.01, params=INERTIA)
    assert sweep(system, {"I1": [1.0, 2.0]}, x0=x0, t_end=0.1, h=0.01, params=INERTIA).status.tolist() == [0, 0]


def test_a_kane_measurement_reads_speeds_and_coordinate_rates(tmp_path):
    # found by review: q' was refused as "an input to list", u as "not a coordinate". With
    # u2 = q1' + q2' (absolute angle rate), q2' = u2 - u1 (by hand) and u2 itself are measured.
    q1, q2, u1, u2, T1 = me.dynamicsymbols("q1 q2 u1 u2 T1")
    m, l, g = sp.symbols("m l g", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q1, N.z])
    B = A.orientnew("B", "Axis", [q2, A.z])
    A.set_ang_vel(N, u1 * N.z)
    B.set_ang_vel(N, u2 * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", l * A.x)
    P1.v2pt_theory(O, N, A)
    P2 = P1.locatenew("P2", l * B.x)
    P2.v2pt_theory(P1, N, B)
    kane = me.KanesMethod(N, q_ind=[q1, q2], u_ind=[u1, u2], kd_eqs=[q1.diff() - u1, q2.diff() - (u2 - u1)])
    kane.kanes_equations([me.Particle("a", P1, m), me.Particle("b", P2, m)],
                         [(P1, -m * g * N.x), (P2, -m * g * N.x), (A, T1 * N.z)])
    model = Model("kane_measured", parameters=[m, l, g], sympy_model=kane, inputs=[T1],
                  measurements={"relative_rate": q2.diff(), "absolute_rate": u2, "work_rate": T1 * u1},
                  parameter_values={"m": 1.0, "l": 1.0, "g": 9.81})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    run = simulate(system, {"q1": 0.3, "q2": 0.2, "u1": 0.1, "u2": -0.4}, t_end=0.5, h=1e-3, inputs=0.7)
    np.testing.assert_allclose(run["relative_rate"], run["u2"] - run["u1"], rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(run["absolute_rate"], run["u2"], rtol=0, atol=0)
    np.testing.assert_allclose(run["work_rate"], 0.7 * run["u1"], rtol=1e-15)


def test_configuration_constraints_build_with_the_implicit_methods():
    """Found by review (session 16): with any implicit method the build failed, two C functions named
    <prefix>_dense_solve (the constraints' LU and the Newton solve). The implicit midpoint rule
    keeps the energy of a torque-free body (a quadratic invariant) to rounding, by hand
    E = (I1 w1^2 + I2 w2^2 + I3 w3^2) / 2, and follows the rk4 run at small h."""
    kane, N, (I1, I2, I3), _ = _quaternion_body(q0_dependent=True)
    system = compile_model(Model("quaternion_implicit", parameters=[I1, I2, I3], sympy_model=kane, frame=N),
                           methods=["rk4", "implicit_midpoint"])
    x0 = [0.0, 0.0, 0.0, 1.0, 0.3, 1.0, 0.2]
    implicit = simulate(system, x0, 2.0, 1e-3, params=INERTIA, method="implicit_midpoint", energy=True)
    explicit = simulate(system, x0, 2.0, 1e-3, params=INERTIA, method="rk4")
    assert implicit.ok and explicit.ok
    by_hand = 0.5 * (0.3 ** 2 + 2.0 * 1.0 ** 2 + 3.0 * 0.2 ** 2)
    np.testing.assert_allclose(implicit.energy, by_hand, rtol=1e-12)
    np.testing.assert_allclose(implicit.x[-1], explicit.x[-1], atol=1e-5)  # midpoint's error ~ h^2


def test_a_driven_models_reactions_take_one_input_row_per_state():
    """The reactions of a driven model at k states with k rows of inputs (the states and rows read
    through one buffer each since review found buffers per state at 3.7 us each). A particle on a
    line along N.x, pushed by the inputs F along it and G across it, held by the guide's normal
    force fy: no motion across, so fy = m g - G (by hand), whatever F and the state are."""
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    m, k, g = sp.symbols("m k g", positive=True)
    q1, u1, ua = me.dynamicsymbols("q1 u1 ua")
    F, G, fy = me.dynamicsymbols("F G fy")
    P = O.locatenew("P", q1 * N.x)
    P.set_vel(N, u1 * N.x + ua * N.y)
    kane = me.KanesMethod(N, [q1], [u1], kd_eqs=[q1.diff() - u1], u_auxiliary=[ua])
    kane.kanes_equations([me.Particle("p", P, m)], [(P, (F - k * q1) * N.x + (G + fy - m * g) * N.y)])
    system = compile_model(Model("guided", parameters=[m, k, g], sympy_model=kane, inputs=[F, G],
                                 parameter_values={m: 2.0, k: 3.0, g: 9.81}), methods=["rk4"],
                           outputs=("rhs", "reactions"))
    assert system.layout.reactions == ("fy",)
    states = np.array([[0.1, 0.0], [-0.4, 2.0], [1.5, -1.0]])
    rows = np.array([[1.0, 0.5], [-3.0, 4.0], [0.0, -2.5]])
    np.testing.assert_allclose(reactions(system, states, r=rows), (2.0 * 9.81 - rows[:, 1])[:, None], rtol=1e-14)
    np.testing.assert_allclose(reactions(system, states, r=rows[1]), np.full((3, 1), 2.0 * 9.81 - 4.0), rtol=1e-14)
