"""LinearModel about a neutral equilibrium: the pendulum on a free cart (mutation survivors in
LinearModel._eig and linearize, docs/mutation.md).

Hand derivation: about th = 0 the cart mode is neutral (w^2 = 0: no restoring force on x), the
swing mode has w^2 = g (mc + m) / (mc l); M0 = [[mc + m, m l], [m l, m l^2]], K0 = diag(0, m g l).
"""
from __future__ import annotations

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.statics.equilibria import linearize


def test_free_cart_pendulum_has_an_exactly_neutral_mode():
    x, th = me.dynamicsymbols("x th")
    mc, m, l, g = sp.symbols("mc m l g", positive=True)
    xd, thd = x.diff(), th.diff()
    T = (mc + m) * xd ** 2 / 2 + m * l * sp.cos(th) * xd * thd + m * l ** 2 * thd ** 2 / 2
    model = Model("cart_pendulum", [x, th], [mc, m, l, g], kinetic_energy=T, potential_energy=-m * g * l * sp.cos(th),
                  parameter_values={"mc": 2.0, "m": 0.5, "l": 0.8, "g": 9.81})
    eom = derive_equations(model)
    linear = linearize(eom, {"x": 0, "th": 0}, {})
    assert linear.q == tuple(eom.q) and linear.q0 == (0.0, 0.0)
    assert all(isinstance(v, float) for v in linear.q0)
    np.testing.assert_allclose(linear.M0, [[2.5, 0.4], [0.4, 0.32]], rtol=1e-15)
    np.testing.assert_allclose(linear.K0, [[0.0, 0.0], [0.0, 0.5 * 9.81 * 0.8]], rtol=1e-15)
    w2 = linear.eigenvalues()
    assert w2[0] == 0.0  # the neutral cart mode, zeroed exactly
    np.testing.assert_allclose(w2[1], 9.81 * 2.5 / (2.0 * 0.8), rtol=1e-12)
    assert linear.stable is False  # neutral is not stable (Lagrange-Dirichlet needs K0 > 0)
    shapes = linear.mode_shapes()
    np.testing.assert_allclose(shapes.T @ linear.M0 @ shapes, np.eye(2), atol=1e-12)
    assert np.all(shapes[np.argmax(np.abs(shapes), axis=0), [0, 1]] > 0)
