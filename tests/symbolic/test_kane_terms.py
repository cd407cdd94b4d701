"""Kane's equations formed from shared velocity terms (symbolic/kane_terms.py) against sympy's own.

The reference is a second derivation route: sympy's ``KanesMethod.kanes_equations`` of the same
bodies, loads and kinematic equations with every speed independent (its mass matrix and forcing),
and for the velocity constraints' rate, sympy's jacobian of A u + b contracted with qd. Both are
compared numerically at random states and parameters.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, ModelError, derive_equations
from lagcodegen.codegen.reduce import count_operations
from lagcodegen.symbolic.equations import make_substitution, plain_symbols
from lagcodegen.symbolic.kane_terms import kane_terms
from lagcodegen.symbolic.sympy_models import _every_speed_independent

TOOL = Path(__file__).resolve().parents[2] / "tools" / "sympy_peer_survey.py"
t = me.dynamicsymbols._t


def survey_tool():
    spec = importlib.util.spec_from_file_location("sympy_peer_survey", TOOL)
    survey = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = survey  # its dataclass looks itself up there
    spec.loader.exec_module(survey)
    return survey


def plain_route(method):
    coords, speeds = list(method.q), list(method.u)
    q, u = plain_symbols(coords, speeds, ())
    renamed = make_substitution(coords, speeds, q, u, "test")
    aux = list(getattr(method, "_uaux", ()))
    zero = {a: 0 for a in aux} | {a.diff(t): 0 for a in aux}
    return q, u, (lambda expr, what: renamed(sp.sympify(expr).xreplace(zero), what))


def sympy_reference(method, to_plain):
    kindiff = method.kindiffdict()
    unreduced = _every_speed_independent(method, kindiff)
    table = {c.diff(t): kindiff[c.diff(t)] for c in method.q}
    return (to_plain(unreduced.mass_matrix.xreplace(table), "M"), to_plain(unreduced.forcing.xreplace(table), "F"))


def assert_equal_at_random_points(pairs, rng, points=4, tolerance=1e-12):
    symbols = sorted(set().union(*(a.free_symbols | b.free_symbols for a, b in pairs)), key=str)
    for _ in range(points):
        values = dict(zip(symbols, rng.uniform(0.3, 1.3, len(symbols)) * rng.choice([-1, 1], len(symbols))))
        for ours, theirs in pairs:
            a = np.array(ours.xreplace(values).evalf(), dtype=float)
            b = np.array(theirs.xreplace(values).evalf(), dtype=float)
            assert np.allclose(a, b, rtol=tolerance, atol=tolerance * (1 + np.abs(b).max())), (a, b)


@pytest.fixture(scope="module")
def bicycle():
    return survey_tool().first_kane("test_kane3", "test_bicycle")


def test_the_bicycle_equations_equal_sympys_with_fewer_operations(bicycle):
    q, u, to_plain = plain_route(bicycle)
    kindiff = bicycle.kindiffdict()
    motion = list(bicycle._k_nh * sp.Matrix(bicycle.u) + bicycle._f_nh)
    terms = kane_terms(bicycle, kindiff, to_plain, motion)
    assert terms is not None
    M, F = sympy_reference(bicycle, to_plain)
    w = to_plain(sp.Matrix(motion), "w")
    qd = to_plain(sp.Matrix([kindiff[c.diff(t)] for c in bicycle.q]), "qd")
    rates = w.jacobian(sp.Matrix(q)) * qd  # no explicit t in the bicycle's constraints
    assert_equal_at_random_points([(terms.mass_matrix, M), (terms.forcing, F), (terms.motion_rates, rates)],
                                  np.random.default_rng(3))
    ours = sp.cse(list(terms.mass_matrix) + list(terms.forcing) + list(terms.motion_rates))
    theirs = sp.cse(list(M) + list(F) + list(rates))
    # 2026-11-26: 1513 against 2445 (sympy's cse, default order)
    assert count_operations([e for _, e in ours[0]] + ours[1]) < 0.85 * count_operations(
        [e for _, e in theirs[0]] + theirs[1])


def particle_and_bodies():
    """A particle on a spinning arm (explicit t in its velocity), a rigid body with an inertia
    written in a frame fixed to it, a torque on a frame that is no body's and a force at a point
    that is no mass centre: every branch of the formulation."""
    q1, q2, q3 = me.dynamicsymbols("q1 q2 q3")
    u1, u2, u3 = me.dynamicsymbols("u1 u2 u3")
    m, M, L, k, c, g, Ix, Iy, Iz, w0 = sp.symbols("m M L k c g Ix Iy Iz w0")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [q1 + w0 * t ** 2, N.z])  # driven: explicit t in the angle
    B = A.orientnew("B", "Axis", [q2, A.x])
    C = B.orientnew("C", "Axis", [sp.pi / 6, B.y])  # fixed to B: the inertia is written here
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q3 * A.x)
    G = P.locatenew("G", L * B.z)
    H = G.locatenew("H", L * B.y)  # a load point that is no mass centre
    for point, frame in ((P, A), (G, B), (H, B)):
        point.v2pt_theory(O if point is P else (P if point is G else G), N, frame)
    P.set_vel(N, P.pos_from(O).dt(N))
    G.set_vel(N, G.pos_from(O).dt(N))
    H.set_vel(N, H.pos_from(O).dt(N))
    kd = [q1.diff() - u1, q2.diff() - u2, q3.diff() - u3]
    particle = me.Particle("p", P, m)
    body = me.RigidBody("b", G, B, M, (me.inertia(C, Ix, Iy, Iz), G))
    loads = [(P, -k * q3 * A.x - c * u3 * A.x), (G, -M * g * N.z), (H, -c * H.vel(N)), (A, -c * u1 * N.z),
             (B, -k * q2 * A.x)]
    kane = me.KanesMethod(N, q_ind=[q1, q2, q3], u_ind=[u1, u2, u3], kd_eqs=kd)
    kane.kanes_equations([particle, body], loads)
    return kane


def test_particles_torques_loose_loads_and_explicit_time_equal_sympys():
    kane = particle_and_bodies()
    q, u, to_plain = plain_route(kane)
    terms = kane_terms(kane, kane.kindiffdict(), to_plain)
    assert terms is not None
    M, F = sympy_reference(kane, to_plain)
    assert_equal_at_random_points([(terms.mass_matrix, M), (terms.forcing, F)], np.random.default_rng(5))


def test_a_set_acceleration_keeps_sympys_equations():
    """sympy's Kane reads an acceleration set with a2pt_theory as given; it need not be the derivative
    of the velocity (sympy's test_kane.test_aux sets one that is not), so this formulation steps aside."""
    kane = particle_and_bodies()
    kane.bodies[1].masscenter.set_acc(kane._inertial, 0 * kane._inertial.x)
    assert kane_terms(kane, kane.kindiffdict(), plain_route(kane)[2]) is None


def crank(inertia_of, axis: str = "z"):
    """A body on a crank turning about the inertial ``axis``; its central inertia
    ``inertia_of(B, q1)`` in the crank's frame B."""
    q1, u1 = me.dynamicsymbols("q1 u1")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [q1, getattr(N, axis)])
    O = me.Point("O")
    O.set_vel(N, 0)
    G = O.locatenew("G", B.x)
    G.v2pt_theory(O, N, B)
    kane = me.KanesMethod(N, q_ind=[q1], u_ind=[u1], kd_eqs=[q1.diff() - u1])
    kane.kanes_equations([me.RigidBody("crank", G, B, sp.Symbol("m"), (inertia_of(B, q1), G))], [])
    return kane


def test_an_inertia_that_changes_with_the_state_keeps_sympys_equations():
    J = sp.Symbol("J")
    kane = crank(lambda B, q1: me.inertia(B, J * (1 + q1 ** 2), J, J))
    assert kane_terms(kane, kane.kindiffdict(), plain_route(kane)[2]) is None


def test_a_load_that_sympy_cancels_does_not_leave_an_undeclared_symbol():
    """sympy's test_kane2.test_non_central_inertia: a force Q1 along a direction its point does not move
    in (with the auxiliary speed zero). sympy's expanded equations drop Q1; here the product would be
    zero only after simplification, so the route keeps sympy's equations and Q1 need not be declared."""
    survey = survey_tool()
    kane = next(r.system for r in survey.collect(("test_kane2",)) if r.source.endswith("test_non_central_inertia"))
    parameters = sorted((kane.mass_matrix_full.free_symbols | kane.forcing_full.free_symbols) - {t}, key=str)
    assert "Q1" not in {p.name for p in parameters}
    eom = derive_equations(Model("non_central", parameters=parameters, sympy_model=kane))
    assert not any(s.name == "Q1" for s in eom.forcing.free_symbols)


def test_a_longer_chain_gains_more():
    """sympy's own n-link pendulum on a cart (sympy.physics.mechanics.models), 8 links: sympy's
    expanded equations repeat each link's velocity in every later link's terms; the shared terms
    do not (2026-11-26: M and F 688 operations after CSE against 1221)."""
    from sympy.physics.mechanics.models import n_link_pendulum_on_cart

    kane = n_link_pendulum_on_cart(n=8, cart_force=False, joint_torques=False)
    q, u, to_plain = plain_route(kane)
    terms = kane_terms(kane, kane.kindiffdict(), to_plain)
    M, F = sympy_reference(kane, to_plain)
    assert_equal_at_random_points([(terms.mass_matrix, M), (terms.forcing, F)], np.random.default_rng(7), points=2)
    ours = sp.cse(list(terms.mass_matrix) + list(terms.forcing))
    theirs = sp.cse(list(M) + list(F))
    assert count_operations([e for _, e in ours[0]] + ours[1]) < 0.7 * count_operations(
        [e for _, e in theirs[0]] + theirs[1])


def test_a_mass_that_changes_keeps_sympys_equations():
    """sympy's Kane adds m' v to the inertia force of a mass that changes with q or t (a review found
    -2 m q u^2 missing from a particle of mass m (1 + q^2)); this formulation steps aside for it."""
    q, u = me.dynamicsymbols("q u")
    m, k = sp.symbols("m k")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    P.set_vel(N, u * N.x)
    for mass in (m * (1 + q ** 2), m * (1 + t)):
        kane = me.KanesMethod(N, [q], [u], kd_eqs=[q.diff() - u])
        kane.kanes_equations([me.Particle("p", P, mass)], [(P, -k * q * N.x)])
        assert kane_terms(kane, kane.kindiffdict(), plain_route(kane)[2]) is None
        eom = derive_equations(Model("varying_mass", parameters=[k, m], sympy_model=kane))
        expected = plain_route(kane)[2](kane.forcing[0], "F")  # sympy's, in the route's plain symbols
        assert sp.simplify(eom.forcing[0] - expected) == 0


def test_a_quaternion_frame_keeps_sympys_equations():
    """A quaternion's direction cosines are a rotation only on |q| = 1; a translating body's mass
    centre velocity written in the body frame then weighs m |q|^4 off it, where sympy's dot products
    in N give m (found in review). Such a frame keeps sympy's equations: M[v, v] = m at any q."""
    q0, q1, q2, q3, x = me.dynamicsymbols("q0:4 x")
    w1, w2, w3, v = me.dynamicsymbols("w1:4 v")
    m, J = sp.symbols("m J")
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Quaternion", [q0, q1, q2, q3])
    B.set_ang_vel(N, w1 * B.x + w2 * B.y + w3 * B.z)
    G = me.Point("O").locatenew("G", x * N.x)
    G.set_vel(N, v * N.x)
    Q = sp.Matrix([[-q1, -q2, -q3], [q0, -q3, q2], [q3, q0, -q1], [-q2, q1, q0]])
    kd = list(sp.Matrix([q0, q1, q2, q3]).diff() - Q * sp.Matrix([w1, w2, w3]) / 2) + [x.diff() - v]
    kane = me.KanesMethod(N, [q0, q1, q2, q3, x], [w1, w2, w3, v], kd_eqs=kd)
    kane.kanes_equations([me.RigidBody("b", G, B, m, (me.inertia(B, J, 2 * J, 3 * J), G))], [])
    assert kane_terms(kane, kane.kindiffdict(), plain_route(kane)[2]) is None
    eom = derive_equations(Model("quaternion_body", parameters=[J, m], sympy_model=kane))
    assert eom.mass_matrix[3, 3] == m


def test_an_inertia_with_a_one_sided_product_is_refused_naming_the_body():
    """A product of inertia written on one side only makes sympy's own mass matrix unsymmetric
    (found in review): no LDL^T of M reads that as written, so the model is refused."""
    m, Jx, Jz, Jxz = sp.symbols("m Jx Jz Jxz")
    kane = crank(lambda B, q1: Jx * (B.x | B.x) + Jx * (B.y | B.y) + Jz * (B.z | B.z) + Jxz * (B.x | B.z), axis="y")
    with pytest.raises(ModelError, match=r"inertia of rigid body crank is not symmetric.*entry \(0, 2\) is Jxz"):
        derive_equations(Model("lopsided", parameters=[m, Jx, Jz, Jxz], sympy_model=kane))


def test_a_nan_mass_is_refused_naming_the_entry():
    """Hostile input: a mass of nan made the shared-terms assembly raise a bare TypeError (sympy's
    nan times a Matrix is nan); sympy's equations then name the mass matrix entry, as before."""
    kane = crank(lambda B, q1: me.inertia(B, 1, 1, 1))
    kane.bodies[0].mass = sp.nan
    kane.kanes_equations(kane.bodies, [])
    with pytest.raises(ModelError, match=r"mass matrix, entry \(0, 0\) is nan"):
        derive_equations(Model("nan_mass", parameters=[], sympy_model=kane))
