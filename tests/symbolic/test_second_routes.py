"""Second derivation routes for two pieces the textbook models reach only partly (mutation run,
docs/mutation.md): the general Hessian route of Lagrange II and the Baumgarte-stabilized
constraint acceleration.

Independent references:
- sympy's ``LagrangesMethod`` for a rheonomic T with q-dependent and t-dependent M and gyroscopic
  terms (the Hessian route must give the same M and F);
- the total time derivatives of phi(q(t), t) taken by sympy along an arbitrary motion q(t): with
  A qdd = gamma, phi'' + 2 alpha phi' + beta^2 phi must vanish identically (Baumgarte, 1972).
"""
from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen.symbolic.energies import _hessian_form
from lagcodegen.symbolic.holonomic import BAUMGARTE_ALPHA, BAUMGARTE_BETA, holonomic_terms

t = me.dynamicsymbols._t


def test_hessian_route_matches_sympy_lagranges_method_on_a_rheonomic_t():
    q1, q2 = me.dynamicsymbols("q1 q2")
    a, b = sp.symbols("a b", positive=True)
    qd1, qd2 = q1.diff(t), q2.diff(t)
    T = ((2 + sp.cos(q2)) * qd1 ** 2 + (1 + t ** 2) * qd2 ** 2) / 2 + a * q1 * t * qd1 * qd2 \
        + b * sp.sin(q1) * t * qd2 + a * t * q2 ** 2
    method = me.LagrangesMethod(T, [q1, q2])
    method.form_lagranges_equations()
    x1, x2, v1, v2 = sp.symbols("x1 x2 v1 v2")
    plain = {qd1: v1, qd2: v2, q1: x1, q2: x2}
    M, F = _hessian_form(T.subs(plain), [x1, x2], [v1, v2])
    M_ref = method.mass_matrix.subs(plain)
    F_ref = method.forcing.subs(plain)
    assert sp.simplify(M - M_ref) == sp.zeros(2, 2)
    assert sp.simplify(F - F_ref) == sp.zeros(2, 1)


def test_gamma_gives_baumgarte_stabilized_constraint_motion():
    q1, q2 = me.dynamicsymbols("q1 q2")
    c = sp.Symbol("c", positive=True)
    phi = sp.Matrix([q1 ** 2 * sp.cos(t) + q2 * q1 - c * t ** 2, sp.sin(q2) * t - q1 * c])  # rheonomic, coupled
    x1, x2, v1, v2 = sp.symbols("x1 x2 v1 v2")
    to_plain = {q1.diff(t): v1, q2.diff(t): v2, q1: x1, q2: x2}
    terms = holonomic_terms(phi.subs(to_plain), [x1, x2], [v1, v2], t)
    qdd = sp.Matrix([q1.diff(t, 2), q2.diff(t, 2)])
    along = {q1.diff(t, 2): sp.Symbol("a1"), q2.diff(t, 2): sp.Symbol("a2")}
    phi_d, phi_dd = phi.diff(t), phi.diff(t, 2)
    alpha, beta = BAUMGARTE_ALPHA, BAUMGARTE_BETA
    stabilized = (phi_dd + 2 * alpha * phi_d + beta ** 2 * phi).subs(along).subs(to_plain)
    residual = (terms["A"] * qdd.subs(along) - terms["gamma"]) - stabilized
    assert sp.simplify(residual) == sp.zeros(2, 1)
    assert sp.simplify(terms["w"] - phi_d.subs(to_plain)) == sp.zeros(2, 1)


def test_bodies_route_cart_pendulum_matches_the_textbook():
    """A cart x with a pendulum bob at (x + l sin th, -l cos th), and first a slider y on its own
    (a body whose acceleration has no velocity-dependent part, so its inertia term is zero and must
    be skipped without skipping the bob's). Hand derivation (e.g. Ogata, Modern Control
    Engineering, the pendulum on a cart with the bob hanging):
    (mc + m) x'' + m l cos th th'' = m l sin th th'^2 + f,  m l cos th x'' + m l^2 th'' = -m g l sin th,
    ms y'' = -ms g."""
    from lagcodegen import Model, derive_equations

    y, x, th = me.dynamicsymbols("y x th")
    ms, mc, m, l, g, f = sp.symbols("ms mc m l g f", positive=True)
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    cart = O.locatenew("C", x * N.x)
    bob = O.locatenew("P", (x + l * sp.sin(th)) * N.x - l * sp.cos(th) * N.y)
    slider = O.locatenew("S", y * N.y)
    model = Model("cart_pendulum", [y, x, th], [ms, mc, m, l, g, f],
                  bodies=[me.Particle("slider", slider, ms), me.Particle("cart", cart, mc), me.Particle("bob", bob, m)],
                  loads=[(cart, f * N.x)], gravity=-g * N.y, frame=N, origin=O)
    eom = derive_equations(model)
    Y, X, TH = eom.q
    YD, XD, THD = eom.u
    M_hand = sp.Matrix([[ms, 0, 0], [0, mc + m, m * l * sp.cos(TH)], [0, m * l * sp.cos(TH), m * l ** 2]])
    F_hand = sp.Matrix([-ms * g, m * l * sp.sin(TH) * THD ** 2 + f, -m * g * l * sp.sin(TH)])
    assert sp.simplify(eom.mass_matrix - M_hand) == sp.zeros(3, 3)
    assert sp.simplify(eom.forcing - F_hand) == sp.zeros(3, 1)
