"""Every catalog system against its hand-derived equation of motion, by both routes.

Each expected ``M``, ``F`` or acceleration is typed here from an independent source named in the
comment above it (a hand derivation from T and V whose steps are written out, or a closed form
checked by hand). Comparisons are exact: ``simplify(expected - got) == 0``; ``expand_trig`` and
``expand`` run first only to make ``simplify`` fast (both are exact rewrites).
Model: ``sympy/physics/mechanics/tests/test_lagrange.py`` (``test_dub_pen``).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations

ROUTES = ("energies", "bodies")
SEED = 20240611


def is_zero(expr) -> bool:
    """Exact: ``simplify(expr) == 0`` after the exact rewrites expand_trig and expand."""
    return sp.simplify(sp.expand(sp.expand_trig(sp.sympify(expr)))) == 0


def matrix_is_zero(matrix) -> bool:
    return all(is_zero(entry) for entry in matrix)


def positive(names: str, seq: bool = False):
    """Parameter symbols as the catalog declares them (positive=True, so they compare equal)."""
    return sp.symbols(names, positive=True, seq=seq)


def plain(eom, name: str) -> sp.Symbol:
    """The plain symbol standing for coordinate or speed ``name`` in ``eom``."""
    table = {s.name: s for s in eom.q + eom.u}
    return table[name]


def acceleration(eom):
    """ud = M^-1 F, solved symbolically (only for n <= 2)."""
    assert eom.n <= 2
    return eom.mass_matrix.LUsolve(eom.forcing)


def check_common_form(eom, n: int) -> None:
    """Shapes, M symmetric, kinematics qd = u (Lagrange routes), speeds named <q>_d."""
    assert eom.n == n
    assert eom.mass_matrix.shape == (n, n)
    assert eom.forcing.shape == (n, 1)
    assert eom.mass_matrix == eom.mass_matrix.T
    assert eom.kinematics == sp.ImmutableMatrix(eom.u)
    assert [s.name for s in eom.u] == [f"{c.name}_d" for c in eom.q]


# -- rolling wheels -------------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_rolling_wheels_acceleration(route):
    # Hand derivation from T and V. The rod (weight Q) and both wheel centres translate with speed
    # s', the wheels (weight P, inertia J about the centre) spin at s'/r (rolling without slip):
    #   T = (2P + Q)/(2g) s'^2 + 2 * J/2 (s'/r)^2,   V = -(2P + Q) s sin(beta).
    # Lagrange II: ((2P + Q)/g + 2J/r^2) s'' = (2P + Q) sin(beta), hence
    #   s'' = (2P + Q) g r^2 sin(beta) / ((2P + Q) r^2 + 2 J g)     (the closed form).
    P, Q, J, r, g, beta = positive("P Q J r g beta")
    eom = derive_equations(catalog.rolling_wheels(route))
    check_common_form(eom, 1)
    expected = (2 * P + Q) * g * r ** 2 * sp.sin(beta) / ((2 * P + Q) * r ** 2 + 2 * J * g)
    assert is_zero(expected - acceleration(eom)[0])
    assert is_zero(eom.mass_matrix[0, 0] - ((2 * P + Q) / g + 2 * J / r ** 2))


# -- elastic pendulum -----------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_elastic_pendulum_equations(route):
    # Hand derivation from T and V (ball of mass m at (r sin(phi), -r cos(phi))):
    #   T = m/2 (r'^2 + r^2 phi'^2),   V = -m g r cos(phi) + k/2 (r - l0)^2.
    # r:    d/dt(m r') - m r phi'^2 - m g cos(phi) + k (r - l0) = 0
    #       => m r'' = m r phi'^2 + m g cos(phi) - k (r - l0);
    # phi:  d/dt(m r^2 phi') + m g r sin(phi) = 0
    #       => m r^2 phi'' = -2 m r r' phi' - m g r sin(phi).
    m, k, l0, g = positive("m k l0 g")
    eom = derive_equations(catalog.elastic_pendulum(route))
    check_common_form(eom, 2)
    r, phi = eom.q
    rd, phid = plain(eom, "r_d"), plain(eom, "phi_d")
    M = sp.Matrix([[m, 0], [0, m * r ** 2]])
    F = sp.Matrix([m * r * phid ** 2 + m * g * sp.cos(phi) - k * (r - l0),
                   -2 * m * r * rd * phid - m * g * r * sp.sin(phi)])
    assert matrix_is_zero(M - eom.mass_matrix)
    assert matrix_is_zero(F - eom.forcing)


# -- disk with spring and hinged rod --------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_disk_spring_rod_equations(route):
    # Hand derivation from T and V. Disk (M, R) rolling: T_disk = M x'^2/2 + (M R^2/2)(x'/R)^2/2
    # = 3/4 M x'^2. Rod (m, l) centre at (x + l/2 sin(phi), -l/2 cos(phi)), so
    # v^2 = x'^2 + l x' phi' cos(phi) + l^2 phi'^2/4, plus rotation m l^2/12 phi'^2/2:
    #   T = (3M/4 + m/2) x'^2 + m l/2 cos(phi) x' phi' + m l^2/6 phi'^2,
    #   V = k x^2/2 - m g l/2 cos(phi).
    # M = [[3M/2 + m, m l/2 cos(phi)], [m l/2 cos(phi), m l^2/3]].
    # x:   d/dt(dT/dx') = M11 x'' + M12 phi'' - m l/2 sin(phi) phi'^2; dT/dx = 0
    #      => F_x = m l/2 sin(phi) phi'^2 - k x.
    # phi: d/dt(dT/dphi') = M21 x'' + M22 phi'' - m l/2 sin(phi) x' phi';
    #      dT/dphi = -m l/2 sin(phi) x' phi' (the x' phi' terms cancel)
    #      => F_phi = -m g l/2 sin(phi).
    M_, R, k, m, l, g = positive("M R k m l g")
    eom = derive_equations(catalog.disk_spring_rod(route))
    check_common_form(eom, 2)
    x, phi = eom.q
    phid = plain(eom, "phi_d")
    M = sp.Matrix([[3 * M_ / 2 + m, m * l / 2 * sp.cos(phi)],
                   [m * l / 2 * sp.cos(phi), m * l ** 2 / 3]])
    F = sp.Matrix([m * l / 2 * sp.sin(phi) * phid ** 2 - k * x,
                   -m * g * l / 2 * sp.sin(phi)])
    assert matrix_is_zero(M - eom.mass_matrix)
    assert matrix_is_zero(F - eom.forcing)


# -- bar on rollers with rolling friction ---------------------------------------------------------
@pytest.mark.parametrize("direction", [1, -1], ids=["moving_down", "moving_up"])
def test_bar_on_rollers_rolling_friction_opposes_speed(direction):
    # Hand derivation from T, V and the virtual work of rolling friction. The bar (m1) moves 2x,
    # each roller (m2, r) translates x and spins x'/r:
    #   T = m1 (2x')^2/2 + 2 (m2 x'^2/2 + (m2 r^2/2)(x'/r)^2/2) = (2 m1 + 3/2 m2) x'^2,
    #   V = -(2 m1 + 2 m2) g x sin(beta).
    # Rolling friction: each roller turns at x'/r relative to both the incline and the bar, with
    # normal forces (m1/2 + m2) g cos(beta) below and m1/2 g cos(beta) above, so the moments
    # delta N oppose the rolling with total power -2 delta (m1 + m2) g cos(beta) |x'|/r:
    #   Q_x = -2 delta (m1 + m2) g cos(beta) sign(x')/r.
    # Hence (4 m1 + 3 m2) x'' = 2 (m1 + m2) g (sin(beta) - delta cos(beta) sign(x')/r).
    m1, m2, r, g, beta, delta = positive("m1 m2 r g beta delta")
    eom = derive_equations(catalog.bar_on_rollers())
    check_common_form(eom, 1)
    xd = plain(eom, "x_d")
    speed = sp.Symbol("v", positive=True)
    ud = acceleration(eom)[0].subs(xd, direction * speed)
    expected = 2 * (m1 + m2) * g * (sp.sin(beta) - direction * delta * sp.cos(beta) / r) / (4 * m1 + 3 * m2)
    assert is_zero(expected - ud)
    # The friction part of the forcing has the sign opposite to the speed (beta < pi/2).
    friction = eom.forcing[0].subs(xd, direction * speed) - eom.forcing[0].subs(delta, 0)
    assert is_zero(friction + direction * 2 * delta * (m1 + m2) * g * sp.cos(beta) / r)
    values = {m1: 10, m2: 2, r: sp.Rational(1, 10), g: sp.Rational(981, 100), beta: sp.Rational(1, 5),
              delta: sp.Rational(1, 500), speed: sp.Rational(3, 10)}
    assert sp.sign(friction.subs(values)) == -direction
    assert is_zero(eom.mass_matrix[0, 0] - (4 * m1 + 3 * m2))


# -- centrifugal governor -------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_centrifugal_governor_equation(route):
    # Hand derivation from T and V (rheonomic: the frame spins at constant omega). Each ball
    # (weight P) is at distance l sin(alpha) from the axis: v^2 = l^2 alpha'^2 + l^2 sin^2(alpha)
    # omega^2; the sleeve (weight Q) is at depth 2 l cos(alpha), speed 2 l sin(alpha) alpha':
    #   T = P/g (l^2 alpha'^2 + l^2 omega^2 sin^2(alpha)) + 2 Q/g l^2 sin^2(alpha) alpha'^2,
    #   V = -2 (P + Q) l cos(alpha).
    # M = 2 l^2 (P + 2 Q sin^2(alpha))/g;
    # dT/dalpha = 2 P l^2 omega^2 sin cos/g + 4 Q l^2 sin cos alpha'^2/g,
    # d/dt(dT/dalpha') = M alpha'' + 8 Q l^2 sin cos alpha'^2/g, so
    # F = 2 P l^2 omega^2 sin(alpha) cos(alpha)/g - 4 Q l^2 sin cos alpha'^2/g - 2 (P + Q) l sin(alpha).
    P, Q, l, g, omega = positive("P Q l g omega")
    eom = derive_equations(catalog.centrifugal_governor(route))
    check_common_form(eom, 1)
    (alpha,), (ad,) = eom.q, eom.u
    s, c = sp.sin(alpha), sp.cos(alpha)
    M = 2 * l ** 2 * (P + 2 * Q * s ** 2) / g
    F = 2 * P * l ** 2 * omega ** 2 * s * c / g - 4 * Q * l ** 2 * s * c * ad ** 2 / g - 2 * (P + Q) * l * s
    assert is_zero(M - eom.mass_matrix[0, 0])
    assert is_zero(F - eom.forcing[0])
    assert eom.t not in eom.mass_matrix.free_symbols | eom.forcing.free_symbols


@pytest.mark.parametrize("route", ROUTES)
def test_centrifugal_governor_relative_equilibrium(route):
    # From F above at alpha' = 0: F = 2 l sin(alpha) (P l omega^2 cos(alpha)/g - (P + Q)), zero at
    # cos(alpha) = (P + Q) g / (P l omega^2) (the classical governor equilibrium).
    P, Q, l, g, omega = positive("P Q l g omega")
    eom = derive_equations(catalog.centrifugal_governor(route))
    (alpha,), (ad,) = eom.q, eom.u
    at_rest = eom.forcing[0].subs(ad, 0)
    equilibrium = sp.acos((P + Q) * g / (P * l * omega ** 2))
    assert is_zero(at_rest.subs(alpha, equilibrium))
    # ... and only there (a nearby angle is not an equilibrium), numerically:
    values = {P: 10, Q: 20, l: sp.Rational(1, 2), g: sp.Rational(981, 100), omega: 10}
    alpha_eq = float(equilibrium.subs(values))
    assert abs(float(at_rest.subs(values).subs(alpha, alpha_eq))) < 1e-12
    assert abs(float(at_rest.subs(values).subs(alpha, alpha_eq + 0.1))) > 1e-3


# -- gear hoist -----------------------------------------------------------------------------------
@pytest.mark.parametrize("route", ROUTES)
def test_gear_hoist_load_acceleration(route):
    # Hand derivation from T and V. Gear 1 turns phi, gear 2 turns r1/r2 phi, the load rises
    # h = r r1/r2 phi:
    #   T = (P1 rho1^2 + P2 rho2^2 (r1/r2)^2 + Q r^2 (r1/r2)^2) phi'^2/(2g),  V = Q h,  Q_phi = M.
    # Lagrange II: phi'' = g r2 (M r2 - Q r r1) / (P1 rho1^2 r2^2 + P2 rho2^2 r1^2 + Q r^2 r1^2),
    # and the load's acceleration h'' = r r1/r2 phi'' is the closed form
    #   g r r1 (M r2 - Q r r1) / (P1 rho1^2 r2^2 + (P2 rho2^2 + Q r^2) r1^2).
    M, P1, P2, Q, rho1, rho2, r1, r2, r, g = positive("M P1 P2 Q rho1 rho2 r1 r2 r g")
    eom = derive_equations(catalog.gear_hoist(route))
    check_common_form(eom, 1)
    load_acceleration = r * r1 / r2 * acceleration(eom)[0]
    expected = g * r * r1 * (M * r2 - Q * r * r1) / (P1 * rho1 ** 2 * r2 ** 2 + (P2 * rho2 ** 2 + Q * r ** 2) * r1 ** 2)
    assert is_zero(expected - load_acceleration)


# -- pendulum chain and double pendulum -----------------------------------------------------------
def chain_closed_form(eom, n: int):
    """Textbook closed form of the planar n-link chain of point masses (absolute angles).

    Hand derivation: bob i is at sum_{j<=i} l_j (sin q_j, -cos q_j), so its velocity is
    sum_{j<=i} l_j q_j' (cos q_j, sin q_j) and, with mu_jk = sum_{i>=max(j,k)} m_i,
      T = 1/2 sum_jk mu_jk l_j l_k cos(q_j - q_k) q_j' q_k',   V = -g sum_j l_j cos(q_j) sum_{i>=j} m_i.
    M_jk = mu_jk l_j l_k cos(q_j - q_k). With d/dt(dT/dq_j') = sum_k M_jk q_k''
    - sum_k mu_jk l_j l_k sin(q_j - q_k) (q_j' - q_k') q_k' and
    dT/dq_j = -sum_k mu_jk l_j l_k sin(q_j - q_k) q_j' q_k', the q_j' q_k' terms cancel:
      F_j = -sum_k mu_jk l_j l_k sin(q_j - q_k) q_k'^2 - g l_j sin(q_j) sum_{i>=j} m_i.
    For n = 2 this is the double pendulum of sympy's ``test_dub_pen`` (there with gravity along x).
    """
    m = positive(" ".join(f"m{i}" for i in range(1, n + 1)), seq=True)
    l = positive(" ".join(f"l{i}" for i in range(1, n + 1)), seq=True)
    g = sp.Symbol("g", positive=True)
    q, u = eom.q, eom.u

    def mu(j, k):
        return sp.Add(*m[max(j, k):])

    M = sp.Matrix(n, n, lambda j, k: mu(j, k) * l[j] * l[k] * sp.cos(q[j] - q[k]))
    F = sp.Matrix(n, 1, lambda j, _: -sp.Add(*[mu(j, k) * l[j] * l[k] * sp.sin(q[j] - q[k]) * u[k] ** 2
                                               for k in range(n)])
                  - g * l[j] * sp.sin(q[j]) * sp.Add(*m[j:]))
    return M, F


@pytest.mark.parametrize("route", ROUTES)
@pytest.mark.parametrize("n", [1, 2, 3, 4])
def test_pendulum_chain_closed_form(n, route):
    eom = derive_equations(catalog.pendulum_chain(n, route))
    check_common_form(eom, n)
    M, F = chain_closed_form(eom, n)
    assert matrix_is_zero(M - eom.mass_matrix)
    assert matrix_is_zero(F - eom.forcing)


@pytest.mark.parametrize("route", ROUTES)
def test_double_pendulum_closed_form(route):
    # chain_closed_form with n = 2, written out (hand derivation, see chain_closed_form):
    #   M = [[(m1 + m2) l1^2, m2 l1 l2 cos(q1 - q2)], [m2 l1 l2 cos(q1 - q2), m2 l2^2]],
    #   F = [-m2 l1 l2 sin(q1 - q2) q2'^2 - (m1 + m2) g l1 sin(q1),
    #        m2 l1 l2 sin(q1 - q2) q1'^2 - m2 g l2 sin(q2)].
    m1, m2, l1, l2, g = positive("m1 m2 l1 l2 g")
    eom = derive_equations(catalog.double_pendulum(route))
    check_common_form(eom, 2)
    (q1, q2), (u1, u2) = eom.q, eom.u
    c, s = sp.cos(q1 - q2), sp.sin(q1 - q2)
    M = sp.Matrix([[(m1 + m2) * l1 ** 2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2 ** 2]])
    F = sp.Matrix([-m2 * l1 * l2 * s * u2 ** 2 - (m1 + m2) * g * l1 * sp.sin(q1),
                   m2 * l1 * l2 * s * u1 ** 2 - m2 * g * l2 * sp.sin(q2)])
    assert matrix_is_zero(M - eom.mass_matrix)
    assert matrix_is_zero(F - eom.forcing)
    assert matrix_is_zero(sp.Matrix(chain_closed_form(eom, 2)[0]) - M)


# -- properties shared by every system ------------------------------------------------------------
SYSTEMS = {
    "rolling_wheels": catalog.rolling_wheels,
    "elastic_pendulum": catalog.elastic_pendulum,
    "disk_spring_rod": catalog.disk_spring_rod,
    "centrifugal_governor": catalog.centrifugal_governor,
    "gear_hoist": catalog.gear_hoist,
    "double_pendulum": catalog.double_pendulum,
    "pendulum_chain_3": lambda route: catalog.pendulum_chain(3, route),
    "pendulum_chain_5": lambda route: catalog.pendulum_chain(5, route),
}
CASES = [pytest.param(name, route, id=f"{name}-{route}") for name in SYSTEMS for route in ROUTES]
CASES.append(pytest.param("bar_on_rollers", None, id="bar_on_rollers"))


def build(name: str, route):
    if name == "bar_on_rollers":
        return catalog.bar_on_rollers()
    return SYSTEMS[name](route)


@pytest.mark.parametrize("name, route", CASES)
def test_mass_matrix_symmetric_positive_definite(name, route):
    # M is the Hessian of T > 0 in the speeds: symmetric positive definite at every state with
    # positive parameters (seeded random states; coordinates in (-3, 3), parameters in (0.2, 3)).
    eom = derive_equations(build(name, route))
    M = eom.mass_matrix
    assert M == M.T
    args = [*eom.q, *eom.parameters, eom.t]
    numeric = sp.lambdify(args, M, "numpy")
    rng = np.random.default_rng(SEED)
    for _ in range(5):
        values = [*rng.uniform(-3.0, 3.0, eom.n), *rng.uniform(0.2, 3.0, len(eom.parameters)),
                  rng.uniform(0.0, 10.0)]
        Mx = np.asarray(numeric(*values), dtype=float)
        np.testing.assert_allclose(Mx, Mx.T, rtol=0, atol=1e-14 * np.abs(Mx).max())
        assert np.linalg.eigvalsh(Mx).min() > 0, (name, route, values)


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_routes_give_same_energy(name):
    # Second derivation route: T + V of the energies route and of the bodies route differ by a
    # constant at most (V's zero level may differ); it must not depend on q, u or t.
    energies = derive_equations(SYSTEMS[name]("energies"))
    bodies = derive_equations(SYSTEMS[name]("bodies"))
    assert energies.q == bodies.q and energies.u == bodies.u
    difference = sp.simplify(sp.expand(sp.expand_trig(energies.energy - bodies.energy)))
    assert not difference.free_symbols & {*energies.q, *energies.u, energies.t}, difference
    assert is_zero(energies.kinetic_energy - bodies.kinetic_energy)


@pytest.mark.parametrize("name", list(SYSTEMS))
def test_routes_give_same_equations(name):
    # Second derivation route: M and F of Lagrange II and of d'Alembert-Lagrange coincide.
    energies = derive_equations(SYSTEMS[name]("energies"))
    bodies = derive_equations(SYSTEMS[name]("bodies"))
    assert matrix_is_zero(energies.mass_matrix - bodies.mass_matrix)
    assert matrix_is_zero(energies.forcing - bodies.forcing)
