"""Routes found wrong by the review of session 14 (helper-49), against energies derived by hand."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations


def _pendulum_parts():
    m, length, g = sp.symbols("m l g", positive=True)
    q = me.dynamicsymbols("q")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    B = N.orientnew("B", "Axis", (q, N.z))
    P = O.locatenew("P", -length * B.y)
    P.v2pt_theory(O, N, B)
    bob = me.Particle("bob", P, m)
    bob.potential_energy = -m * g * length * sp.cos(q)
    return (m, length, g), q, N, O, bob


def test_a_kinetic_term_of_the_lagrangian_outside_the_bodies_stays_kinetic():
    """Was: T from bodies=[bob] alone and V = T - L, so a rotor's Jm q'^2 / 2 written into L landed in V
    with a minus sign: energy -8.372 for -6.372, status OK. By hand E = (m l^2 + Jm) q'^2 / 2 - m g l cos q."""
    (m, length, g), q, N, _, bob = _pendulum_parts()
    Jm = sp.Symbol("Jm", positive=True)
    L = me.Lagrangian(N, bob) + Jm * q.diff(me.dynamicsymbols._t) ** 2 / 2
    method = me.LagrangesMethod(L, [q], bodies=[bob], frame=N)
    values = {m: 1.0, length: 1.0, g: 9.81, Jm: 0.5}
    eom = derive_equations(Model("motor_pendulum", parameters=[m, length, g, Jm], sympy_model=method,
                                 parameter_values=values))
    at = {**values, eom.q[0]: 0.3, eom.u[0]: 2.0}
    assert float(eom.energy.xreplace(at)) == pytest.approx(0.5 * 1.5 * 4.0 - 9.81 * np.cos(0.3), rel=1e-14)
    assert not (eom.potential_energy.free_symbols & set(eom.u))


def test_bodies_listing_some_of_the_lagrangians_bodies_keep_the_energy():
    """Was: V = -m g l cos q - m x'^2 with bodies=[rod] and L of the cart and the rod. By hand,
    T = 3 m x'^2 / 2 + m l cos q x' q' + m l^2 q'^2 / 2, V = -m g l cos q (cart of mass 2m)."""
    (m, length, g), q, N, O, _ = _pendulum_parts()
    t = me.dynamicsymbols._t
    x = me.dynamicsymbols("x")
    C = O.locatenew("C", x * N.x)
    C.set_vel(N, x.diff(t) * N.x)
    R = N.orientnew("R", "Axis", (q, N.z))
    G = C.locatenew("G", -length * R.y)
    G.v2pt_theory(C, N, R)
    cart, rod = me.Particle("cart", C, 2 * m), me.Particle("rod", G, m)
    rod.potential_energy = -m * g * length * sp.cos(q)
    method = me.LagrangesMethod(me.Lagrangian(N, cart, rod), [x, q], bodies=[rod], frame=N)
    values = {m: 1.0, length: 1.0, g: 9.81}
    eom = derive_equations(Model("cart_pendulum", parameters=[m, length, g], sympy_model=method,
                                 parameter_values=values))
    (X, Q), (XD, QD) = eom.q, eom.u
    at = {**values, X: 0.1, Q: 0.3, XD: 0.5, QD: 2.0}
    hand = 0.5 * 3 * 0.25 + np.cos(0.3) * 0.5 * 2.0 + 0.5 * 4.0 - 9.81 * np.cos(0.3)
    assert float(eom.energy.xreplace(at)) == pytest.approx(hand, rel=1e-14)
