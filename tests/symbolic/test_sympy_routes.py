"""The sympy-model route: LagrangesMethod, KanesMethod (speeds u != qd) and System, wrapped in
`Model(sympy_model=...)`, against the catalog's energies route and hand-derived equations.

Independent sources: sympy's own derivations (Lagrange, Kane) of models stated here from points
and frames, compared with the catalog's Lagrange II derivation at seeded random states, at 30
significant digits, relative 1e-10; and the hand derivations written in the comments.
Model: ``sympy/physics/mechanics/tests/test_lagrange.py`` (``test_dub_pen``) and
``sympy/physics/mechanics/tests/test_kane.py``.
"""
from __future__ import annotations

import functools
import random

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations

t = me.dynamicsymbols._t
DIGITS = 30
RTOL = sp.Float("1e-10", DIGITS)
SEED = 7

m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
PENDULUM_PARAMETERS = (m1, m2, l1, l2, g)


# -- numeric helpers ------------------------------------------------------------------------------
def random_rationals(rng: random.Random, count: int, low: float, high: float) -> list:
    """Exact rationals, so that evalf carries the full working precision."""
    return [sp.Rational(round(rng.uniform(low, high) * 1000), 1000) for _ in range(count)]


def speed_derivatives(eom, parameter_values: dict, q_values, u_values, t_value=0) -> sp.Matrix:
    """ud = M^-1 F at one state, at DIGITS significant digits."""
    table = {**parameter_values, **dict(zip(eom.q, q_values)), **dict(zip(eom.u, u_values)), eom.t: t_value}
    M = eom.mass_matrix.xreplace(table).evalf(DIGITS)
    F = eom.forcing.xreplace(table).evalf(DIGITS)
    return M.LUsolve(F).evalf(DIGITS)


def coordinate_accelerations(eom, parameter_values: dict, q_values, u_values, t_value=0):
    """(qdd, qd) at one state, from qd = K(q, u, t): qdd = dK/du ud + dK/dq K + dK/dt."""
    ud = speed_derivatives(eom, parameter_values, q_values, u_values, t_value)
    K = sp.Matrix(eom.kinematics)
    table = {**parameter_values, **dict(zip(eom.q, q_values)), **dict(zip(eom.u, u_values)), eom.t: t_value}
    Ku = K.jacobian(eom.u).xreplace(table).evalf(DIGITS)
    Kq = K.jacobian(eom.q).xreplace(table).evalf(DIGITS)
    Kt = K.diff(eom.t).xreplace(table).evalf(DIGITS)
    qd = K.xreplace(table).evalf(DIGITS)
    qdd = Ku * ud + Kq * qd + Kt
    return qdd.evalf(DIGITS), qd.evalf(DIGITS)


def assert_close(got, expected, what: str) -> None:
    got, expected = sp.Matrix(got), sp.Matrix(expected)
    assert got.shape == expected.shape, what
    scale = max(sp.Float(1, DIGITS), *[abs(e) for e in expected])
    for a, b in zip(got, expected):
        assert abs(a - b) <= RTOL * scale, f"{what}: {a} != {b}"


# -- the double pendulum as sympy models ----------------------------------------------------------
def _pendulum_frames(angle1, angle2):
    """Frames and bobs of the planar double pendulum; angle_i absolute, from the downward vertical,
    bob i at l_i (sin, -cos) from the previous one (the catalog's geometry)."""
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (angle1, N.z))
    B = N.orientnew("B", "Axis", (angle2, N.z))
    O = me.Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", -l1 * A.y)
    P2 = P1.locatenew("P2", -l2 * B.y)
    return N, A, B, O, P1, P2


def double_pendulum_lagranges_method():
    """sympy LagrangesMethod in the catalog's absolute angles q1, q2 (as in ``test_dub_pen``)."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    N, A, B, O, P1, P2 = _pendulum_frames(q1, q2)
    P1.v2pt_theory(O, N, A)
    P2.v2pt_theory(P1, N, B)
    bob1, bob2 = me.Particle("bob1", P1, m1), me.Particle("bob2", P2, m2)
    bob1.potential_energy = m1 * g * P1.pos_from(O).dot(N.y)
    bob2.potential_energy = m2 * g * P2.pos_from(O).dot(N.y)
    L = me.Lagrangian(N, bob1, bob2)
    return me.LagrangesMethod(L, [q1, q2], frame=N), N


def double_pendulum_kanes_method(formed: bool):
    """sympy KanesMethod in relative angles: a1 is link 1's absolute angle, a2 link 2's angle
    relative to link 1; speeds u1 = a1', u2 = a1' + a2' (link 2's absolute rate), so u != qd."""
    a1, a2 = me.dynamicsymbols("a1 a2")
    u1, u2 = me.dynamicsymbols("u1 u2")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (a1, N.z))
    B = A.orientnew("B", "Axis", (a2, A.z))
    A.set_ang_vel(N, u1 * N.z)
    B.set_ang_vel(N, u2 * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", -l1 * A.y)
    P2 = P1.locatenew("P2", -l2 * B.y)
    P1.v2pt_theory(O, N, A)
    P2.v2pt_theory(P1, N, B)
    bodies = [me.Particle("bob1", P1, m1), me.Particle("bob2", P2, m2)]
    loads = [(P1, -m1 * g * N.y), (P2, -m2 * g * N.y)]
    kd = [a1.diff(t) - u1, a1.diff(t) + a2.diff(t) - u2]
    if formed:
        kane = me.KanesMethod(N, q_ind=[a1, a2], u_ind=[u1, u2], kd_eqs=kd)
        kane.kanes_equations(bodies, loads)
    else:  # the importer forms the equations from the bodies and loads given here
        kane = me.KanesMethod(N, q_ind=[a1, a2], u_ind=[u1, u2], kd_eqs=kd, bodies=bodies, forcelist=loads)
    return kane, N


def double_pendulum_system():
    """sympy System (Kane's method underneath), absolute angles q1, q2, speeds w_i = q_i'."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    w1, w2 = me.dynamicsymbols("w1 w2")
    ground = me.RigidBody("ground")
    N, O = ground.frame, ground.masscenter
    system = me.System.from_newtonian(ground)
    A = me.ReferenceFrame("A")
    B = me.ReferenceFrame("B")
    A.orient_axis(N, N.z, q1)
    B.orient_axis(N, N.z, q2)
    A.set_ang_vel(N, w1 * N.z)
    B.set_ang_vel(N, w2 * N.z)
    P1 = O.locatenew("P1", -l1 * A.y)
    P2 = P1.locatenew("P2", -l2 * B.y)
    O.set_vel(N, 0)
    P1.v2pt_theory(O, N, A)
    P2.v2pt_theory(P1, N, B)
    system.add_coordinates(q1, q2)
    system.add_speeds(w1, w2)
    system.add_kdes(w1 - q1.diff(t), w2 - q2.diff(t))
    system.add_bodies(me.Particle("bob1", P1, m1), me.Particle("bob2", P2, m2))
    system.apply_uniform_gravity(-g * N.y)
    system.validate_system()
    return system, N


def catalog_state(rng: random.Random):
    parameters = dict(zip(PENDULUM_PARAMETERS, random_rationals(rng, 5, 0.3, 3.0)))
    angles = random_rationals(rng, 2, -3.0, 3.0)
    rates = random_rationals(rng, 2, -4.0, 4.0)
    return parameters, angles, rates


@pytest.fixture(scope="module")
def catalog_double_pendulum():
    return derive_equations(catalog.double_pendulum("energies"))


def test_lagranges_method_matches_catalog(catalog_double_pendulum):
    lm, N = double_pendulum_lagranges_method()
    eom = derive_equations(Model("dp_lagrange", parameters=PENDULUM_PARAMETERS, sympy_model=lm, frame=N))
    assert [s.name for s in eom.q] == ["q1", "q2"] and [s.name for s in eom.u] == ["q1_d", "q2_d"]
    assert eom.kinematics == sp.ImmutableMatrix(eom.u)
    rng = random.Random(SEED)
    for _ in range(5):
        parameters, angles, rates = catalog_state(rng)
        expected = speed_derivatives(catalog_double_pendulum, parameters, angles, rates)
        assert_close(speed_derivatives(eom, parameters, angles, rates), expected, "LagrangesMethod")
    # Same Lagrangian: T + V equals the catalog's energy up to a constant.
    difference = sp.simplify(sp.expand(sp.expand_trig(eom.energy - catalog_double_pendulum.energy)))
    assert not difference.free_symbols & {*eom.q, *eom.u, eom.t}


@pytest.mark.parametrize("formed", [True, False], ids=["kanes_equations_called", "formed_by_importer"])
def test_kanes_method_relative_speeds_matches_catalog(catalog_double_pendulum, formed):
    kane, N = double_pendulum_kanes_method(formed)
    eom = derive_equations(Model("dp_kane", parameters=PENDULUM_PARAMETERS, sympy_model=kane, frame=N))
    assert [s.name for s in eom.q] == ["a1", "a2"] and [s.name for s in eom.u] == ["u1", "u2"]
    u1, u2 = eom.u
    # kd_eqs solved for qd: a1' = u1, a2' = u2 - u1.
    assert sp.simplify(eom.kinematics - sp.Matrix([u1, u2 - u1])) == sp.zeros(2, 1)
    rng = random.Random(SEED + 1)
    for _ in range(5):
        parameters, angles, rates = catalog_state(rng)  # catalog's absolute q1, q2 and q1', q2'
        relative = [angles[0], angles[1] - angles[0]]     # a1 = q1, a2 = q2 - q1
        speeds = rates                                     # u1 = q1', u2 = a1' + a2' = q2'
        add_, ad_ = coordinate_accelerations(eom, parameters, relative, speeds)
        assert_close(ad_, [rates[0], rates[1] - rates[0]], "Kane kinematics")
        expected = speed_derivatives(catalog_double_pendulum, parameters, angles, rates)
        # q1'' = a1'', q2'' = a1'' + a2''
        assert_close([add_[0], add_[0] + add_[1]], expected, "KanesMethod")
    if eom.energy is not None:
        T_catalog = catalog_double_pendulum.kinetic_energy.subs(
            dict(zip(catalog_double_pendulum.u, eom.u)), simultaneous=True).subs(
            dict(zip(catalog_double_pendulum.q, [eom.q[0], eom.q[0] + eom.q[1]])), simultaneous=True)
        assert sp.simplify(sp.expand(sp.expand_trig(eom.kinetic_energy - T_catalog))) == 0


def test_system_matches_catalog(catalog_double_pendulum):
    system, N = double_pendulum_system()
    eom = derive_equations(Model("dp_system", parameters=PENDULUM_PARAMETERS, sympy_model=system, frame=N))
    assert [s.name for s in eom.q] == ["q1", "q2"] and [s.name for s in eom.u] == ["w1", "w2"]
    rng = random.Random(SEED + 2)
    for _ in range(5):
        parameters, angles, rates = catalog_state(rng)
        qdd, qd = coordinate_accelerations(eom, parameters, angles, rates)
        assert_close(qd, rates, "System kinematics")
        expected = speed_derivatives(catalog_double_pendulum, parameters, angles, rates)
        assert_close(qdd, expected, "System")


# -- a 3D rigid body: a body hung in a two-axis gimbal --------------------------------------------
# A rigid body B with central principal inertias I1, I2, I3 (all different) about B.x, B.y, B.z,
# mass m, mass centre at distance d below the fixed pivot O along -B.z. Frame A turns psi about the
# vertical N.z, B turns theta about A.x; gravity -g N.z.
#
# Hand derivation: B.y = cos(th) A.y + sin(th) A.z, B.z = -sin(th) A.y + cos(th) A.z, so
#   A.z = sin(th) B.y + cos(th) B.z,  w = th' B.x + psi' sin(th) B.y + psi' cos(th) B.z,
#   v_G = w x (-d B.z) = d (th' B.y - psi' sin(th) B.x),  |v_G|^2 = d^2 (th'^2 + psi'^2 sin^2(th)),
#   T = 1/2 [(I1 + m d^2) th'^2 + ((I2 + m d^2) sin^2(th) + I3 cos^2(th)) psi'^2],
#   V = m g (-d B.z . N.z) = -m g d cos(th).
# With J(th) = (I2 + m d^2) sin^2(th) + I3 cos^2(th) and K = I2 + m d^2 - I3, in (psi, th):
#   M = diag(J, I1 + m d^2),
#   F_psi = -J'(th) th' psi' = -2 K sin(th) cos(th) th' psi',
#   F_th  = 1/2 J'(th) psi'^2 - m g d sin(th) = K sin(th) cos(th) psi'^2 - m g d sin(th).
m, d, I1, I2, I3 = sp.symbols("m d I1 I2 I3", positive=True)
GIMBAL_PARAMETERS = (m, d, I1, I2, I3, g)


def gimbal_geometry(psi, theta):
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (psi, N.z))
    B = A.orientnew("B", "Axis", (theta, A.x))
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", -d * B.z)
    G.v2pt_theory(O, N, B)
    body = me.RigidBody("body", G, B, m, (me.inertia(B, I1, I2, I3), G))
    return N, A, B, O, G, body


def gimbal_hand(eom):
    (_, th), (psid, thd) = eom.q, eom.u
    J = (I2 + m * d ** 2) * sp.sin(th) ** 2 + I3 * sp.cos(th) ** 2
    K = I2 + m * d ** 2 - I3
    M = sp.Matrix([[J, 0], [0, I1 + m * d ** 2]])
    F = sp.Matrix([-2 * K * sp.sin(th) * sp.cos(th) * thd * psid,
                   K * sp.sin(th) * sp.cos(th) * psid ** 2 - m * g * d * sp.sin(th)])
    return M, F


def gimbal_model(route: str, with_frame: bool = False) -> Model:
    """The same body stated five ways: energies (hand T, V), bodies, Lagrange, Kane, System.

    ``with_frame`` passes ``frame=`` to the sympy models too (the importer then also computes the
    kinetic energy of Kane's bodies); without it the Kane and System models give M and F only.
    """
    psi, theta = me.dynamicsymbols("psi theta")
    models = {}
    # energies route: T and V typed from the hand derivation above
    T = ((I1 + m * d ** 2) * theta.diff(t) ** 2
         + ((I2 + m * d ** 2) * sp.sin(theta) ** 2 + I3 * sp.cos(theta) ** 2) * psi.diff(t) ** 2) / 2
    models["energies"] = Model("gimbal", [psi, theta], GIMBAL_PARAMETERS, kinetic_energy=T,
                               potential_energy=-m * g * d * sp.cos(theta))
    N, A, B, O, G, body = gimbal_geometry(psi, theta)
    models["bodies"] = Model("gimbal", [psi, theta], GIMBAL_PARAMETERS, bodies=[body], gravity=-g * N.z,
                             frame=N, origin=O)
    body.potential_energy = m * g * G.pos_from(O).dot(N.z)
    lm = me.LagrangesMethod(me.Lagrangian(N, body), [psi, theta], frame=N)
    models["lagrange"] = Model("gimbal", parameters=GIMBAL_PARAMETERS, sympy_model=lm, frame=N)
    # Kane: speeds u1 = theta' (= w.B.x), u2 = psi', i.e. in the other order than q = (psi, theta)
    u1, u2 = me.dynamicsymbols("u1 u2")
    N, A, B, O, G, body = gimbal_geometry(psi, theta)
    kane = me.KanesMethod(N, q_ind=[psi, theta], u_ind=[u1, u2],
                          kd_eqs=[theta.diff(t) - u1, psi.diff(t) - u2])
    kane.kanes_equations([body], [(G, -m * g * N.z)])
    models["kane"] = Model("gimbal", parameters=GIMBAL_PARAMETERS, sympy_model=kane,
                           frame=N if with_frame else None)
    # System
    ground = me.RigidBody("ground")
    N, O = ground.frame, ground.masscenter
    A, B = me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_axis(N, N.z, psi)
    B.orient_axis(A, A.x, theta)
    O.set_vel(N, 0)
    G = O.locatenew("G", -d * B.z)
    G.v2pt_theory(O, N, B)
    w1, w2 = me.dynamicsymbols("w1 w2")
    system = me.System.from_newtonian(ground)
    system.add_coordinates(psi, theta)
    system.add_speeds(w1, w2)
    system.add_kdes(w1 - psi.diff(t), w2 - theta.diff(t))
    system.add_bodies(me.RigidBody("body", G, B, m, (me.inertia(B, I1, I2, I3), G)))
    system.apply_uniform_gravity(-g * N.z)
    system.validate_system()
    models["system"] = Model("gimbal", parameters=GIMBAL_PARAMETERS, sympy_model=system,
                             frame=N if with_frame else None)
    return models[route]


@pytest.fixture(scope="module")
def gimbal_equations():
    """derive_equations per route, once per test session (a fixture, not a module-level cache: a
    mutation run forks its test runs from one process, and a cache filled before the fork would
    hand every mutant the unmutated equations)."""
    return functools.cache(lambda route: derive_equations(gimbal_model(route)))


@pytest.mark.parametrize("route", ["energies", "bodies", "lagrange"])
def test_gimbal_matches_hand_derivation(route, gimbal_equations):
    eom = gimbal_equations(route)
    M, F = gimbal_hand(eom)
    assert sp.simplify(M - eom.mass_matrix) == sp.zeros(2, 2)
    assert sp.simplify(F - eom.forcing) == sp.zeros(2, 1)


@pytest.mark.parametrize("route", ["bodies", "lagrange", "kane", "system"])
def test_gimbal_routes_agree_numerically(route, gimbal_equations):
    reference = gimbal_equations("energies")
    eom = gimbal_equations(route)
    rng = random.Random(SEED + 3)
    for _ in range(5):
        parameters = dict(zip(GIMBAL_PARAMETERS, random_rationals(rng, len(GIMBAL_PARAMETERS), 0.3, 3.0)))
        angles = random_rationals(rng, 2, -3.0, 3.0)
        rates = random_rationals(rng, 2, -4.0, 4.0)  # psi', theta'
        expected = speed_derivatives(reference, parameters, angles, rates)
        if route == "kane":  # u1 = theta', u2 = psi'
            qdd, qd = coordinate_accelerations(eom, parameters, angles, rates[::-1])
        else:
            qdd, qd = coordinate_accelerations(eom, parameters, angles, rates)
        assert_close(qd, rates, f"{route} kinematics")
        assert_close(qdd, expected, route)


@pytest.mark.parametrize("route", ["kane", "system"])
def test_gimbal_kane_kinetic_energy_in_speeds(route):
    # With frame= given, the importer computes T of Kane's bodies. The body's angular velocity was
    # set by orient_axis, so it is written with psi', theta'; T must come out in Kane's speeds
    # (qd replaced through the kinematic equations), equal to the hand T of the comment above.
    eom = derive_equations(gimbal_model(route, with_frame=True))
    th = eom.q[1]
    qd = list(eom.kinematics)  # (psi', theta') in terms of the speeds
    T = ((I1 + m * d ** 2) * qd[1] ** 2
         + ((I2 + m * d ** 2) * sp.sin(th) ** 2 + I3 * sp.cos(th) ** 2) * qd[0] ** 2) / 2
    assert eom.kinetic_energy is not None
    assert sp.simplify(sp.expand(sp.expand_trig(eom.kinetic_energy - T))) == 0


# -- rheonomic: pendulum hung from a moving point -------------------------------------------------
@pytest.mark.parametrize("direction", ["horizontal", "vertical"])
@pytest.mark.parametrize("route", ["energies", "bodies"])
def test_pendulum_with_oscillating_support(direction, route):
    # Hand derivation from T and V. The support moves as s(t) = a sin(omega t) along x (horizontal)
    # or y (vertical); the bob (m, rod l) is at the support + l (sin(phi), -cos(phi)).
    # horizontal: T = m/2 (s'^2 + 2 s' l cos(phi) phi' + l^2 phi'^2), V = -m g l cos(phi);
    #   d/dt(dT/dphi') - dT/dphi = m l^2 phi'' + m l s'' cos(phi), so
    #   m l^2 phi'' = -m l (g sin(phi) + s'' cos(phi)) = -m l (g sin(phi) - a omega^2 sin(omega t) cos(phi)).
    # vertical:   T = m/2 (s'^2 + 2 s' l sin(phi) phi' + l^2 phi'^2), V = m g (s - l cos(phi));
    #   m l^2 phi'' = -m l (g + s'') sin(phi) = -m l (g - a omega^2 sin(omega t)) sin(phi)
    #   (Kapitza's pendulum).
    mass, length, a, omega = sp.symbols("m l a omega", positive=True)
    phi = me.dynamicsymbols("phi")
    s = a * sp.sin(omega * t)
    if direction == "horizontal":
        x, y = s + length * sp.sin(phi), -length * sp.cos(phi)
    else:
        x, y = length * sp.sin(phi), s - length * sp.cos(phi)
    parameters = (mass, length, a, omega, g)
    if route == "energies":
        T = mass * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2
        model = Model("shaken_pendulum", [phi], parameters, kinetic_energy=T, potential_energy=mass * g * y)
    else:
        N, O = me.ReferenceFrame("N"), me.Point("O")
        bob = me.Particle("bob", O.locatenew("P", x * N.x + y * N.y), mass)
        model = Model("shaken_pendulum", [phi], parameters, bodies=[bob], gravity=-g * N.y, frame=N, origin=O)
    eom = derive_equations(model)
    (p,), _ = eom.q, eom.u
    if direction == "horizontal":
        F = -mass * length * (g * sp.sin(p) - a * omega ** 2 * sp.sin(omega * t) * sp.cos(p))
    else:
        F = -mass * length * (g - a * omega ** 2 * sp.sin(omega * t)) * sp.sin(p)
    assert sp.simplify(eom.mass_matrix[0, 0] - mass * length ** 2) == 0
    assert sp.simplify(F - eom.forcing[0]) == 0
    acceleration = eom.forcing[0] / eom.mass_matrix[0, 0]
    assert sp.simplify(acceleration - F / (mass * length ** 2)) == 0
    assert t in acceleration.free_symbols  # rheonomic: explicit time survives


def _turning_frame_particle():
    """A particle on a spring k (x^2 + y^2)/2, coordinates x, y in a frame B turning at w about N.z."""
    x, y = me.dynamicsymbols("x y")
    m, w, k = sp.symbols("m w k", positive=True)
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_axis(N, N.z, w * me.dynamicsymbols._t)
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * B.x + y * B.y)
    P.set_vel(B, x.diff() * B.x + y.diff() * B.y)
    P.v1pt_theory(O, N, B)
    particle = me.Particle("p", P, m)
    V = k * (x ** 2 + y ** 2) / 2
    return x, y, (m, w, k), N, particle, V


def test_a_lagranges_method_energy_is_not_split_wrongly():
    """Found by review: T and V were taken as L - L(u=0) and -L(u=0), which moves the speed-free part
    of T (a moving frame's) into V with the wrong sign: T = -1.5, V = -1.5 at x = 1, y = 0, x' = 0,
    y' = -1, where by hand the velocity in N is (x' - w y, y' + w x) = (0, 1) for w = 2, so
    T = m/2 |v_N|^2 = 0.5, and V = k/2 (x^2 + y^2) = 0.5. Now a
    LagrangesMethod with its bodies and frame gives T and V from them; one with L alone, where the
    split is ambiguous (terms of degree 1 in the speeds), gives no energy."""
    x, y, (m, w, k), N, particle, V = _turning_frame_particle()
    values = {m: 1.0, w: 2.0, k: 1.0}
    L = me.Lagrangian(N, particle) - V
    with_bodies = me.LagrangesMethod(L, [x, y], bodies=[particle], frame=N)
    eom = derive_equations(Model("turning", parameters=[m, w, k], sympy_model=with_bodies, parameter_values=values))
    state = {**values, **dict(zip(eom.q, (1.0, 0.0))), **dict(zip(eom.u, (0.0, -1.0)))}
    assert float(eom.kinetic_energy.xreplace(state)) == pytest.approx(0.5, abs=1e-14)
    assert float(eom.potential_energy.xreplace(state)) == pytest.approx(0.5, abs=1e-14)
    alone = derive_equations(Model("turning_alone", parameters=[m, w, k], sympy_model=me.LagrangesMethod(L, [x, y]),
                                   parameter_values=values))
    assert alone.energy is None


def test_fields_a_route_does_not_read_are_refused():
    """Found by review: loads and gravity on the energies route, and generalized forces,
    dissipation, loads, gravity and constraints beside a sympy model, were accepted and left out
    of the equations (F = 0 where F0 - m g was given)."""
    from lagcodegen import ModelError

    x = me.dynamicsymbols("x")
    m, g, c = sp.symbols("m g c", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    P = O.locatenew("P", x * N.y)
    with pytest.raises(ModelError, match="loads, gravity act on bodies"):
        Model("falling", [x], [m, g], kinetic_energy=m * x.diff() ** 2 / 2, loads=[(P, m * N.y)], gravity=-g * N.y,
              frame=N, origin=O)
    lm = me.LagrangesMethod(m * x.diff() ** 2 / 2, [x])
    for field, value in (("generalized_forces", {x: -c * x.diff()}), ("dissipation", c * x.diff() ** 2 / 2),
                         ("gravity", -g * N.y), ("constraints", [x - 1])):
        with pytest.raises(ModelError, match=f"a sympy model brings its own forces and constraints; {field}"):
            Model("lm", parameters=[m, g, c], sympy_model=lm, **{field: value})


def test_a_body_whose_inertia_changes_is_refused_on_the_bodies_route():
    """Found by review: a skater with Izz = I0 / (1 + a t) got theta'' = 0 on the bodies route, where
    d/dt(I theta') = 0 gives theta'' = -I'/I theta' (the route's I alpha + w x I w holds for a
    constant I only). Such a body is refused, naming it and what its inertia changes with."""
    from lagcodegen import ModelError

    theta = me.dynamicsymbols("theta")
    i0, a = sp.symbols("I0 a", positive=True)
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", (theta, N.z))
    O = me.Point("O")
    O.set_vel(N, 0)
    skater = me.RigidBody("skater", O, B, 1, (me.inertia(B, 1, 1, i0 / (1 + a * me.dynamicsymbols._t)), O))
    with pytest.raises(ModelError, match="the central inertia of body 'skater' changes with t"):
        derive_equations(Model("skater", [theta], [i0, a], bodies=[skater], frame=N, origin=O))


def test_a_mass_that_changes_only_past_the_sample_points_is_refused():
    """Found by review: m0 (1 + Max(0, t - 3)) is constant where the guard sampled it (t = -1.3,
    0.4, 2.2), and the bodies route integrated m(t) x'' = -k x, dropping m' x' (x(8) 1.14 against
    0.435 from d/dt(m x') = -k x). A piecewise function of t or q in a mass is now a change."""
    from lagcodegen import ModelError

    x = me.dynamicsymbols("x")
    m0, k = sp.symbols("m0 k", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x)
    particle = me.Particle("p", P, m0 * (1 + sp.Max(0, me.dynamicsymbols._t - 3)))
    with pytest.raises(ModelError, match="the mass of body 'p' changes with t"):
        derive_equations(Model("m_max", [x], [m0, k], bodies=[particle], frame=N, origin=O,
                               potential_energy=k * x ** 2 / 2))
