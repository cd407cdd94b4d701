"""Statics found wrong by the review of session 14 (helper-45), each against a hand result."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.statics.steady import steady_eigenvalues, steady_motion


@pytest.mark.parametrize("tau", [8.0, -8.0])
def test_steady_eigenvalues_differentiate_abs_on_its_branch(tau):
    """Was: -1 for a flywheel with quadratic drag (the complex step through numpy's abs, which has no
    derivative in the imaginary part). By hand, J phi'' = tau - c phi' |phi'| spins steadily at
    w0 = sign(tau) sqrt(|tau| / c), and a perturbation of phi' decays at -2 c |w0| / J."""
    phi = me.dynamicsymbols("phi")
    J, c, torque = sp.symbols("J c tau", positive=True)
    eom = derive_equations(Model("flywheel", [phi], [J, c, torque], kinetic_energy=J * phi.diff() ** 2 / 2,
                                 generalized_forces={phi: torque - c * phi.diff() * sp.Abs(phi.diff())},
                                 parameter_values={"J": 2.0, "c": 0.5, "tau": tau}))
    motion = steady_motion(eom, {"phi_d": np.sign(tau)}, ["phi_d"], ["phi_d"])
    assert motion.values["phi_d"] == pytest.approx(np.sign(tau) * 4.0, rel=1e-12)
    np.testing.assert_allclose(steady_eigenvalues(eom, motion, ["phi"], ["phi_d"]), [-2.0], rtol=1e-12)


def test_steady_eigenvalues_take_sign_as_locally_constant():
    """Was: -0.375 (numpy's sign of a complex z is z/|z|). By hand, J phi'' = tau - b phi' - mu sign(phi')
    away from phi' = 0 has the eigenvalue -b/J = -0.25 at its steady spin (tau - mu)/b = 4."""
    phi = me.dynamicsymbols("phi")
    J, b, mu, torque = sp.symbols("J b mu tau", positive=True)
    eom = derive_equations(Model("flywheel_coulomb", [phi], [J, b, mu, torque], kinetic_energy=J * phi.diff() ** 2 / 2,
                                 generalized_forces={phi: torque - b * phi.diff() - mu * sp.sign(phi.diff())},
                                 parameter_values={"J": 2.0, "b": 0.5, "mu": 1.0, "tau": 3.0}))
    motion = steady_motion(eom, {"phi_d": 3.0}, ["phi_d"], ["phi_d"])
    assert motion.values["phi_d"] == pytest.approx(4.0, rel=1e-12)
    np.testing.assert_allclose(steady_eigenvalues(eom, motion, ["phi"], ["phi_d"]), [-0.25], rtol=1e-12)


def _forced_mass(force):
    x = me.dynamicsymbols("x")
    m, k, F0 = sp.symbols("m k F0", positive=True)
    return derive_equations(Model("motor_mount", [x], [m, k, F0], kinetic_energy=m * x.diff() ** 2 / 2,
                                  potential_energy=k * x ** 2 / 2, generalized_forces={x: force(F0)},
                                  parameter_values={"m": 10.0, "k": 1e5, "F0": 50.0}))


@pytest.mark.parametrize("force", [lambda F0: F0 * sp.sin(100 * sp.pi * me.dynamicsymbols._t),
                                   lambda F0: F0 * sp.Heaviside(me.dynamicsymbols._t - 10)],
                         ids=["50 Hz", "switched on at 10 s"])
def test_a_force_in_time_is_no_equilibrium(force):
    """Was: x = 0 returned as an equilibrium (t sampled at 0, 0.37, 1.1, 2.9, 7.3: zeros of
    sin(100 pi t), all before 10 s). By hand, F at rest is -k x + F0 sin(100 pi t), 50 N at x = 0 and
    t = 5 ms; and F0 Heaviside(t - 10) is 50 N at t = 11 s: F at rest depends on t, which the
    docstring says raises."""
    from lagcodegen.statics.equilibria import find_equilibria

    eom = _forced_mass(force)
    for values in (None, {}):
        with pytest.raises(ValueError, match="depends on t"):
            find_equilibria(eom, values=values)


def test_a_time_dependence_that_cancels_still_has_its_equilibrium():
    """The check must not refuse a force whose t cancels: F0 (sin^2(t) + cos^2(t) - 1) is 0, so
    x = 0 stays the one equilibrium of m x'' = -k x (by hand)."""
    from lagcodegen.statics.equilibria import find_equilibria

    t = me.dynamicsymbols._t
    eom = _forced_mass(lambda F0: F0 * (sp.sin(3 * t) ** 2 + sp.cos(3 * t) ** 2 - 1))
    assert [float(p[eom.q[0]]) for p in find_equilibria(eom, values={})] == [0.0]


def test_a_micrometre_pendulum_is_held_to_its_constraint():
    """Was: consistent_state returned (5e-7, -1e-7) unchanged for a rod of l = 1e-6 (phi = -0.74 l^2
    under the absolute floor 1 + ...), and the bob on the hinge with nothing given. By hand, with x
    held at l/2 the bob hangs at y = -sqrt(l^2 - x^2) (the start's branch), and any solution has
    x^2 + y^2 = l^2."""
    from lagcodegen import catalog
    from lagcodegen.statics.consistent import consistent_state

    eom = derive_equations(catalog.cartesian_pendulum())
    length = 1e-6
    q, _ = consistent_state(eom, {"x": 0.5e-6, "y": -0.1e-6}, fix=["x"], values={"l": length})
    np.testing.assert_allclose(q, [0.5e-6, -np.sqrt(length ** 2 - 0.25e-12)], rtol=1e-10)
    q, _ = consistent_state(eom, {}, values={"l": length})
    assert np.hypot(*q) == pytest.approx(length, rel=1e-10)
    with pytest.raises(ValueError, match="constraint 0"):
        consistent_state(eom, {"x": 0.5e-6, "y": -0.1e-6}, values={"l": length})


def test_linearize_state_refuses_a_micrometre_rod_at_half_its_length():
    """Was: accepted at y = -l/2 with l = 1e-6, eigenvalues +-4429j: a rod half as long (by hand, the
    rod of l hanging has +-i sqrt(g/l) = +-3132j)."""
    from lagcodegen import catalog
    from lagcodegen.statics.state_space import linearize_state

    eom = derive_equations(catalog.cartesian_pendulum())
    with pytest.raises(ValueError, match="violates constraint row 0"):
        linearize_state(eom, [0.0, -0.5e-6, 0.0, 0.0], values={"l": 1e-6})
    hanging = linearize_state(eom, [0.0, -1e-6, 0.0, 0.0], values={"l": 1e-6})
    np.testing.assert_allclose(sorted(np.abs(hanging.eigenvalues().imag))[-1], np.sqrt(9.81 / 1e-6), rtol=1e-8)
