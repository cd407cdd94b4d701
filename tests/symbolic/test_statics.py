"""Equilibria and linearized models (`lagcodegen.statics.equilibria`) against closed forms.

Sources:
[LL] Landau & Lifshitz, Mechanics, 3rd ed.: sec. 5 Problem 4 (Lagrangian of the governor: two
     masses on rods of length a, a sleeve on the axis, spun at Omega), sec. 23 Problem 2 (small
     oscillations of the coplanar double pendulum), sec. 30 (pendulum with a vibrating support).
[Lynch] P. Lynch, "The swinging spring: a simple model of atmospheric balance", in Large-Scale
     Atmosphere-Ocean Dynamics II, Cambridge UP, 2002: elastic frequency sqrt(k/m), pendular
     frequency sqrt(g/l) with l the stretched length at rest.
Hand derivations are written out next to the tests that use them.
"""
import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations
from lagcodegen.statics.equilibria import LinearModel, angle_like, equilibrium_conditions, find_equilibria, linearize

ROUTES = ("energies", "bodies")


def _params(eom):
    return {p.name: p for p in eom.parameters}


# -- centrifugal governor (rheonomic) ---------------------------------------------------------
# [LL sec. 5 Problem 4] with m1 = P/g, m2 = Q/g, a = l:
#   L = (P/g) l^2 (ad^2 + omega^2 sin^2 a) + 2 (Q/g) l^2 ad^2 sin^2 a + 2 (P + Q) l cos a.
# At rest the effective potential U = -2 (P+Q) l cos a - (P/g) l^2 omega^2 sin^2 a is stationary:
#   dU/da = 2 l sin a ((P+Q) - (P/g) l omega^2 cos a) = 0  ->  sin a = 0  or
#   cos a = (P + Q) g / (P l omega^2)   (relative equilibrium, exists when this is <= 1).
# Small oscillations about it: M0 = 2 P l^2/g + 4 Q l^2 sin^2 a0 / g, K0 = d2U/da2 =
#   2 P l^2 omega^2 sin^2 a0 / g, so w^2 = P omega^2 sin^2 a0 / (P + 2 Q sin^2 a0).
# About a = 0: K0 = 2 (P+Q) l - 2 P l^2 omega^2 / g, negative (unstable) when
#   omega^2 > (P + Q) g / (P l).

@pytest.mark.parametrize("route", ROUTES)
def test_governor_relative_equilibrium_is_a_symbolic_solution(route):
    eom = derive_equations(catalog.centrifugal_governor(route))
    P, Q, l, g, omega = (_params(eom)[k] for k in ("P", "Q", "l", "g", "omega"))
    alpha = eom.q[0]
    solutions = find_equilibria(eom)
    cos_star = (P + Q) * g / (P * l * omega ** 2)
    relative = [s for s in solutions if sp.simplify(sp.cos(s[alpha]) - cos_star) == 0]
    assert relative, solutions
    assert any(s[alpha] == 0 for s in solutions)
    # every solution satisfies the conditions (substitution, then simplify)
    G = equilibrium_conditions(eom)
    for s in solutions:
        assert sp.simplify(G[0].xreplace(s)) == 0


@pytest.mark.parametrize("route", ROUTES)
def test_governor_numeric_equilibria_at_defaults(route):
    eom = derive_equations(catalog.centrifugal_governor(route))
    v = {p.name: x for p, x in eom.parameter_values.items()}
    a0 = math.acos((v["P"] + v["Q"]) * v["g"] / (v["P"] * v["l"] * v["omega"] ** 2))
    found = [s[eom.q[0]] for s in find_equilibria(eom, values={})]
    # sin a = 0 gives 0 and pi; the relative equilibrium +-a0 (mirror images); reduced to (-pi, pi]
    np.testing.assert_allclose(found, sorted([-a0, 0.0, a0, math.pi]), atol=1e-10)


@pytest.mark.parametrize("route", ROUTES)
def test_governor_oscillation_about_relative_equilibrium(route):
    eom = derive_equations(catalog.centrifugal_governor(route))
    v = {p.name: x for p, x in eom.parameter_values.items()}
    P, Q, l, g, omega = (v[k] for k in ("P", "Q", "l", "g", "omega"))
    a0 = math.acos((P + Q) * g / (P * l * omega ** 2))
    s2 = math.sin(a0) ** 2
    lin = linearize(eom, [a0], values={})
    np.testing.assert_allclose(lin.M0, [[2 * P * l ** 2 / g + 4 * Q * l ** 2 * s2 / g]], rtol=1e-12)
    np.testing.assert_allclose(lin.K0, [[2 * P * l ** 2 * omega ** 2 * s2 / g]], rtol=1e-10)
    np.testing.assert_allclose(lin.natural_frequencies(), [math.sqrt(P * omega ** 2 * s2 / (P + 2 * Q * s2))],
                               rtol=1e-10)
    assert lin.stable
    vertical = linearize(eom, [0.0], values={})
    assert omega ** 2 > (P + Q) * g / (P * l) and not vertical.stable
    np.testing.assert_allclose(vertical.K0, [[2 * (P + Q) * l - 2 * P * l ** 2 * omega ** 2 / g]], rtol=1e-12)


def test_governor_below_critical_speed_hangs_stably():
    # omega^2 < (P + Q) g / (P l): no relative equilibrium, a = 0 is stable (same hand derivation)
    eom = derive_equations(catalog.centrifugal_governor())
    found = [s[eom.q[0]] for s in find_equilibria(eom, values={"omega": 5.0})]
    np.testing.assert_allclose(found, [0.0, math.pi], atol=1e-12)
    assert linearize(eom, [0.0], values={"omega": 5.0}).stable


# -- pendulums ---------------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_simple_pendulum_frequency_symbolic(route):
    # w^2 = g / l for small swings of a simple pendulum ([LL] sec. 21)
    eom = derive_equations(catalog.pendulum_chain(1, route=route))
    p = _params(eom)
    lin = linearize(eom, [0])
    assert sp.simplify(lin.K0[0, 0] / lin.M0[0, 0] - p["g"] / p["l1"]) == 0
    lin = linearize(eom, [0], values={"g": 9.81, "l1": 2.0})
    np.testing.assert_allclose(lin.natural_frequencies(), [math.sqrt(9.81 / 2.0)], rtol=1e-12)


@pytest.mark.parametrize("route", ROUTES)
def test_double_pendulum_equal_masses_and_lengths(route):
    # [LL] sec. 23 Problem 2 with m1 = m2, l1 = l2 = l: w^2 = (g / l) (2 -+ sqrt 2)
    eom = derive_equations(catalog.double_pendulum(route))
    g, l = 9.81, 0.7
    lin = linearize(eom, {"q1": 0, "q2": 0}, values={"m1": 1.3, "m2": 1.3, "l1": l, "l2": l, "g": g})
    expected = np.sqrt(g / l * np.array([2 - math.sqrt(2), 2 + math.sqrt(2)]))
    np.testing.assert_allclose(lin.natural_frequencies(), expected, rtol=1e-12)
    assert lin.stable
    V = lin.mode_shapes()
    np.testing.assert_allclose(V.T @ lin.M0 @ V, np.eye(2), atol=1e-12)
    np.testing.assert_allclose(V.T @ lin.K0 @ V, np.diag(expected ** 2), atol=1e-10)


@pytest.mark.parametrize("route", ROUTES)
def test_double_pendulum_general_masses(route):
    # [LL] sec. 23 Problem 2: w^2 = g / (2 l1 l2 m1) * ((m1+m2)(l1+l2)
    #                               -+ sqrt((m1+m2) ((m1+m2)(l1+l2)^2 - 4 l1 l2 m1)))
    eom = derive_equations(catalog.double_pendulum(route))
    m1, m2, l1, l2, g = 0.8, 1.7, 1.2, 0.5, 9.81
    lin = linearize(eom, [0.0, 0.0], values={"m1": m1, "m2": m2, "l1": l1, "l2": l2, "g": g})
    root = math.sqrt((m1 + m2) * ((m1 + m2) * (l1 + l2) ** 2 - 4 * l1 * l2 * m1))
    w2 = g / (2 * l1 * l2 * m1) * np.array([(m1 + m2) * (l1 + l2) - root, (m1 + m2) * (l1 + l2) + root])
    np.testing.assert_allclose(lin.natural_frequencies() ** 2, w2, rtol=1e-12)


def damped_double_pendulum(damping: str) -> Model:
    """Point masses m1, m2 on massless rods l1, l2; q1, q2 absolute angles from the downward
    vertical; viscous joint dampers c1 (pivot, rate qd1) and c2 (elbow, relative rate qd2 - qd1),
    given as a Rayleigh function or as the generalized forces -dR/dqd it stands for."""
    m1, m2, l1, l2, g, c1, c2 = sp.symbols("m1 m2 l1 l2 g c1 c2", positive=True)
    q1, q2 = me.dynamicsymbols("q1 q2")
    t = me.dynamicsymbols._t
    qd1, qd2 = q1.diff(t), q2.diff(t)
    x1, y1 = l1 * sp.sin(q1), -l1 * sp.cos(q1)
    x2, y2 = x1 + l2 * sp.sin(q2), y1 - l2 * sp.cos(q2)
    T = sum(m * (x.diff(t) ** 2 + y.diff(t) ** 2) for m, x, y in ((m1, x1, y1), (m2, x2, y2))) / 2
    V = g * (m1 * y1 + m2 * y2)
    R = c1 * qd1 ** 2 / 2 + c2 * (qd2 - qd1) ** 2 / 2
    extra = ({"dissipation": R} if damping == "rayleigh" else
             {"generalized_forces": {q1: -c1 * qd1 + c2 * (qd2 - qd1), q2: -c2 * (qd2 - qd1)}})
    return Model(f"damped_double_pendulum_{damping}", [q1, q2], (m1, m2, l1, l2, g, c1, c2),
                 kinetic_energy=T, potential_energy=V, **extra)


@pytest.mark.parametrize("damping", ["rayleigh", "generalized_forces"])
def test_damped_double_pendulum_matrices_by_hand(damping):
    """M0, C0, K0 of the damped double pendulum at the downward rest position, typed by hand.

    M0, K0: the textbook linearized double pendulum ([LL] sec. 23 Problem 2, absolute angles):
        M0 = [[(m1 + m2) l1^2, m2 l1 l2], [m2 l1 l2, m2 l2^2]],  K0 = diag((m1 + m2) g l1, m2 g l2).
    C0 on paper: R = c1 qd1^2 / 2 + c2 (qd2 - qd1)^2 / 2 is quadratic in qd, so
        dR/dqd1 = c1 qd1 - c2 (qd2 - qd1) = (c1 + c2) qd1 - c2 qd2,  dR/dqd2 = -c2 qd1 + c2 qd2,
    and C0 = d2R/dqd2 = [[c1 + c2, -c2], [-c2, c2]]: symmetric, positive definite for c1, c2 > 0.
    A sign flip of C0 in `linearize` fails here (an undamped model cannot see it).
    """
    eom = derive_equations(damped_double_pendulum(damping))
    m1, m2, l1, l2, g, c1, c2 = (_params(eom)[name] for name in ("m1", "m2", "l1", "l2", "g", "c1", "c2"))
    M0 = sp.Matrix([[(m1 + m2) * l1 ** 2, m2 * l1 * l2], [m2 * l1 * l2, m2 * l2 ** 2]])
    C0 = sp.Matrix([[c1 + c2, -c2], [-c2, c2]])
    K0 = sp.diag((m1 + m2) * g * l1, m2 * g * l2)
    lin = linearize(eom, [0, 0])
    for got, want in ((lin.M0, M0), (lin.C0, C0), (lin.K0, K0)):
        assert sp.simplify(sp.Matrix(got) - want) == sp.zeros(2, 2)
    values = {"m1": 0.8, "m2": 1.7, "l1": 1.2, "l2": 0.5, "g": 9.81, "c1": 0.3, "c2": 0.45}
    numeric = linearize(eom, {"q1": 0, "q2": 0}, values=values)
    np.testing.assert_allclose(numeric.C0, [[0.75, -0.45], [-0.45, 0.45]], rtol=1e-14)
    np.testing.assert_allclose(numeric.M0, [[2.5 * 1.44, 1.7 * 0.6], [1.7 * 0.6, 1.7 * 0.25]], rtol=1e-14)
    np.testing.assert_allclose(numeric.K0, np.diag([2.5 * 9.81 * 1.2, 1.7 * 9.81 * 0.5]), rtol=1e-14)


@pytest.mark.parametrize("route", ROUTES)
def test_inverted_double_pendulum_is_unstable(route):
    # upright (pi, pi): K0 = -diag((m1+m2) g l1, m2 g l2), negative definite -> both w^2 < 0
    eom = derive_equations(catalog.double_pendulum(route))
    assert angle_like(eom) == (True, True)
    found = {(round(s[eom.q[0]], 9), round(s[eom.q[1]], 9)) for s in find_equilibria(eom, values={})}
    pi = round(math.pi, 9)
    assert found == {(0.0, 0.0), (0.0, pi), (pi, 0.0), (pi, pi)}
    lin = linearize(eom, [sp.pi, sp.pi], values={})
    np.testing.assert_allclose(lin.K0, -np.diag([2 * 9.81, 9.81]), atol=1e-12)
    assert not lin.stable
    w = lin.natural_frequencies()
    assert np.iscomplexobj(w) and np.all(w.real == 0) and np.all(w.imag > 0)
    # the same magnitudes as the hanging frequencies, (g/l)(2 -+ sqrt 2), now growth rates
    np.testing.assert_allclose(sorted(w.imag ** 2), 9.81 * np.array([2 - math.sqrt(2), 2 + math.sqrt(2)]))


# -- elastic pendulum ---------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_elastic_pendulum_static_stretch_and_frequencies(route):
    # at rest hanging: k (r0 - l0) = m g -> r0 = l0 + m g / k; [Lynch]: w_spring = sqrt(k/m),
    # w_swing = sqrt(g / r0)
    eom = derive_equations(catalog.elastic_pendulum(route))
    r, phi = eom.q
    p = _params(eom)
    m, k, l0, g = (p[name] for name in ("m", "k", "l0", "g"))
    symbolic = find_equilibria(eom)
    assert any(sp.simplify(s[r] - (l0 + m * g / k)) == 0 and s[phi] == 0 for s in symbolic)

    values = {"m": 0.5, "k": 30.0, "l0": 0.8, "g": 9.81}
    r0 = values["l0"] + values["m"] * values["g"] / values["k"]
    numeric = find_equilibria(eom, values=values)
    hanging = [s for s in numeric if abs(s[phi]) < 1e-12]
    assert len(hanging) == 1 and math.isclose(hanging[0][r], r0, rel_tol=1e-12)
    lin = linearize(eom, hanging[0], values=values)
    expected = sorted([math.sqrt(values["k"] / values["m"]), math.sqrt(values["g"] / r0)])
    np.testing.assert_allclose(lin.natural_frequencies(), expected, rtol=1e-12)
    assert angle_like(eom) == (False, True)


# -- disk, spring and rod -----------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_disk_spring_rod_against_hand_linearization(route):
    # Hand computation at x = 0, phi = 0 (the rod hanging):
    #   T = (1/2)(3M/2) xd^2                                   rolling disk: M xd^2/2 + (M R^2/2)(xd/R)^2/2
    #     + (1/2) m (xd^2 + l xd phid cos phi + l^2 phid^2 / 4) rod centre (x + l/2 sin phi, -l/2 cos phi)
    #     + (1/2)(m l^2 / 12) phid^2                            rod about its centre
    #   V = k x^2 / 2 - m g (l/2) cos phi
    # so M0 = [[3M/2 + m, m l/2], [m l/2, m l^2/3]], K0 = diag(k, m g l/2), C0 = 0, and
    # det(K0 - w^2 M0) = 0 is a quadratic a w^4 - b w^2 + c = 0 with a = det M0,
    # b = k m l^2/3 + (3M/2 + m) m g l/2, c = k m g l/2.
    eom = derive_equations(catalog.disk_spring_rod(route))
    vals = {"M": 2.0, "R": 0.25, "k": 50.0, "m": 1.0, "l": 1.0, "g": 9.81}
    M, k, m, l, g = (vals[name] for name in ("M", "k", "m", "l", "g"))
    M0 = np.array([[1.5 * M + m, m * l / 2], [m * l / 2, m * l ** 2 / 3]])
    K0 = np.diag([k, m * g * l / 2])
    lin = linearize(eom, [0.0, 0.0], values=vals)
    np.testing.assert_allclose(lin.M0, M0, rtol=1e-12)
    np.testing.assert_allclose(lin.K0, K0, rtol=1e-12)
    np.testing.assert_allclose(lin.C0, np.zeros((2, 2)), atol=0)
    a, b, c = np.linalg.det(M0), k * m * l ** 2 / 3 + (1.5 * M + m) * m * g * l / 2, k * m * g * l / 2
    w2 = np.array([b - math.sqrt(b * b - 4 * a * c), b + math.sqrt(b * b - 4 * a * c)]) / (2 * a)
    np.testing.assert_allclose(lin.natural_frequencies(), np.sqrt(w2), rtol=1e-12)
    assert lin.stable


# -- time dependence ------------------------------------------------------------------------------
def _shaken_pendulum():
    # pivot oscillating vertically, y = a cos(w t) ([LL] sec. 30): F at rest has the term
    # m l a w^2 cos(w t) sin(theta), so no steady equilibrium exists except where sin(theta) = 0
    m, l, g, a, w = sp.symbols("m l g a w", positive=True)
    th = me.dynamicsymbols("theta")
    t = me.dynamicsymbols._t
    x, y = l * sp.sin(th), a * sp.cos(w * t) - l * sp.cos(th)
    T = m / 2 * (x.diff(t) ** 2 + y.diff(t) ** 2)
    return Model("shaken", [th], (m, l, g, a, w), kinetic_energy=T, potential_energy=m * g * y)


def test_time_dependent_conditions_raise_naming_the_entry():
    eom = derive_equations(_shaken_pendulum())
    # found by review: the message said "no steady (relative) equilibrium exists", though theta = 0
    # and pi (sin(theta) = 0 above) are equilibria at every t; it now says they are not searched for
    with pytest.raises(ValueError, match=r"F\[0\] \(coordinate theta\).*depends on t.*not searched for"):
        equilibrium_conditions(eom)


@pytest.mark.parametrize("n", [2, 7])
def test_spurious_time_is_removed(n):
    # V = k (sin^2 wt + cos^2 wt) sum q_i^2 / 2 is k sum q_i^2 / 2: conditions -k q_i, no t.
    # n = 2 goes through trigsimp, n = 7 through the numeric check; a real t-term still raises.
    k, w, a = sp.symbols("k w a", positive=True)
    q = me.dynamicsymbols(f"q1:{n + 1}")
    t = me.dynamicsymbols._t
    one = sp.sin(w * t) ** 2 + sp.cos(w * t) ** 2
    T = sum(qi.diff(t) ** 2 for qi in q) / 2
    V = sum(k * one * qi ** 2 / 2 for qi in q)
    eom = derive_equations(Model(f"spurious{n}", q, (k, w, a), kinetic_energy=T, potential_energy=V))
    G = equilibrium_conditions(eom)
    assert all(sp.expand(G[i] + k * eom.q[i]) == 0 for i in range(n))
    forced = derive_equations(Model(f"forced{n}", q, (k, w, a), kinetic_energy=T,
                                    potential_energy=V + a * sp.cos(w * t) * q[-1]))
    with pytest.raises(ValueError, match=rf"F\[{n - 1}\] \(coordinate q{n}\)"):
        equilibrium_conditions(forced)


# -- errors name the culprit --------------------------------------------------------------------
@pytest.fixture(scope="module")
def double():
    return derive_equations(catalog.double_pendulum())


def test_unknown_parameter_name(double):
    with pytest.raises(ValueError, match="unknown parameter 'gee'"):
        linearize(double, [0, 0], values={"gee": 9.81})
    with pytest.raises(ValueError, match="unknown parameter 'gee'"):
        find_equilibria(double, values={"gee": 9.81})


def test_missing_parameter_value(double):
    from dataclasses import replace
    bare = replace(double, parameter_values={})
    with pytest.raises(ValueError, match="no value for parameter.*l1, l2, m1, m2"):
        linearize(bare, [0, 0], values={"g": 9.81})


def test_q0_of_wrong_length_or_unknown_coordinate(double):
    with pytest.raises(ValueError, match="q0 has 3 entries.*2 coordinate"):
        linearize(double, [0, 0, 0])
    with pytest.raises(ValueError, match="'z' is not a coordinate"):
        linearize(double, {"q1": 0, "z": 0})
    with pytest.raises(ValueError, match="no value for coordinate.*q2"):
        linearize(double, {"q1": 0})


def test_non_smooth_friction_has_no_linear_model():
    eom = derive_equations(catalog.bar_on_rollers())
    with pytest.raises(ValueError, match=r"F\[0\].*not differentiable in x_d"):
        linearize(eom, [0.0], values={})


def test_symbolic_model_needs_values_for_frequencies(double):
    lin = linearize(double, [0, 0])
    assert isinstance(lin, LinearModel) and isinstance(lin.M0, sp.MatrixBase)
    with pytest.raises(ValueError, match="M0 still contains l1, l2, m1, m2"):
        lin.natural_frequencies()


def test_guesses_need_values(double):
    with pytest.raises(ValueError, match="pass values="):
        find_equilibria(double, guesses=[[0.1, 0.1]])
    found = find_equilibria(double, values={}, guesses=[[0.1, -0.2], {"q1": 3.0, "q2": 0.1}])
    flat = [float(s[q]) for s in found for q in double.q]
    assert flat == pytest.approx([0.0, 0.0, math.pi, 0.0])


@pytest.mark.parametrize("q0, error, culprit", [
    ([math.nan, 0.0], ValueError, r"q0 entry for q1\b must be finite"),
    ({"q1": 0.0, "q2": math.inf}, ValueError, r"q0 entry for q2\b must be finite"),
    ([0.0, sp.oo], ValueError, r"q0 entry for q2\b must be finite"),
    (["a", 0.0], TypeError, r"q0 entry for q1\b must be a number"),  # sympify("a") is a new symbol
    ([0.0, None], TypeError, r"q0 entry for q2\b"),
])
def test_non_finite_or_non_numeric_q0_is_refused(double, q0, error, culprit):
    """Before, NaN gave NaN matrices and "a" a linear model in a stray symbol a."""
    with pytest.raises(error, match=culprit):
        linearize(double, q0, values={})


@pytest.mark.parametrize("value", [math.nan, math.inf, True])
def test_non_finite_parameter_values_are_refused(double, value):
    with pytest.raises(ValueError, match=r"parameter m2 needs a finite number"):
        linearize(double, [0.0, 0.0], values={"m2": value})


def test_linearize_refuses_a_point_that_is_no_equilibrium():
    # found by review: linearize took q0 = 1.2 of the pendulum and reported it stable with omega = 1.885.
    # At rest there the generalized force is -m g l sin(1.2) = -9.1433 (by hand), not 0.
    theta, tau = me.dynamicsymbols("theta tau")
    m, g, l = sp.symbols("m g l", positive=True)
    pendulum = Model("pendulum_off", [theta], [m, g, l], kinetic_energy=m * l ** 2 * theta.diff() ** 2 / 2,
                     potential_energy=-m * g * l * sp.cos(theta), generalized_forces={theta: tau}, inputs=[tau],
                     parameter_values={"m": 1.0, "g": 9.81, "l": 1.0})
    eom = derive_equations(pendulum)
    for values in (None, {}):
        with pytest.raises(ValueError, match=r"q0 = \[1\.2\] is no equilibrium.*force on theta at rest is -9\.1433"):
            linearize(eom, [1.2], values, inputs=[0.0])
    # held at the torque that balances gravity there, it is one: K0 = m g l cos(1.2) (by hand)
    held = linearize(eom, [1.2], {}, inputs=[9.81 * math.sin(1.2)])
    assert held.K0[0, 0] == pytest.approx(9.81 * math.cos(1.2), rel=1e-12)


def test_constrained_models_are_sent_to_the_constrained_tools():
    # found by review: a pendulum as a particle on x^2 + y^2 = l^2 (sympy LagrangesMethod, hol_coneqs)
    # got M0 = I, K0 = 0, frequencies [0, 0] from linearize and no equilibria from find_equilibria.
    # The hanging pendulum's frequency is sqrt(g / l) = 3.13209 rad/s (by hand), which
    # linearize_state gives (its reduced eigenvalues are +-3.13209j).
    from lagcodegen.statics.state_space import linearize_state

    x, y = me.dynamicsymbols("x y")
    m, l, g = sp.symbols("m l g")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x + y * N.y)
    P.set_vel(N, x.diff() * N.x + y.diff() * N.y)
    particle = me.Particle("p", P, m)
    particle.potential_energy = m * g * y
    method = me.LagrangesMethod(me.Lagrangian(N, particle), [x, y], hol_coneqs=[x ** 2 + y ** 2 - l ** 2])
    eom = derive_equations(Model("pendulum_on_a_circle", parameters=[m, l, g], sympy_model=method,
                                 parameter_values={m: 1.0, l: 1.0, g: 9.81}))
    with pytest.raises(ValueError, match=r"linearize takes models without constraints: 'pendulum_on_a_circle' has "
                                         r"1 constraint\(s\) with multipliers.*use statics.state_space.linearize_state"):
        linearize(eom, [0.0, -1.0], {})
    with pytest.raises(ValueError, match="find_equilibria takes models without constraints.*constrained_equilibrium"):
        find_equilibria(eom, {})
    eigenvalues = np.linalg.eigvals(linearize_state(eom, [0.0, -1.0, 0.0, 0.0], values={}).A)
    assert sorted(abs(eigenvalues.imag))[-1] == pytest.approx(math.sqrt(9.81), rel=1e-9)
