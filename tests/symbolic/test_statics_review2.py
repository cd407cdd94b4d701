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
    J, c = sp.symbols("J c", positive=True)
    torque = sp.Symbol("tau", real=True)  # either sign (it was declared positive and given -8)
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


def test_a_stiff_chain_keeps_its_soft_modes():
    """Was: w^2 = [0, 0, 2e11] and stable False for catalog.stiff_chain with k = 1, K = 1e11 (w^2 below
    1e-10 of the largest zeroed). Expected: scipy's eigh of the stiffness matrix written by hand from
    V (unit masses, walls, springs k, K between m2 and m3): all positive, about 0.634, 2.366, 2e11."""
    import scipy.linalg

    from lagcodegen import catalog
    from lagcodegen.statics.equilibria import linearize

    k, K = 1.0, 1e11
    lin = linearize(derive_equations(catalog.stiff_chain()), [0, 0, 0], {"k": k, "K": K})
    by_hand = scipy.linalg.eigh(np.array([[2 * k, -k, 0], [-k, k + K, -K], [0, -K, K + k]]), eigvals_only=True)
    np.testing.assert_allclose(lin.eigenvalues()[:2], by_hand[:2], rtol=1e-3)  # eigh: n eps |K| ~ 1e-4 absolute
    assert lin.stable


@pytest.mark.parametrize("centre, a, m", [(0.0, 2e-7, 1e-9), (1e4, 0.004, 1.0)], ids=["micro", "far from 0"])
def test_close_equilibria_stay_distinct(centre, a, m):
    """Was: one equilibrium of a double well whose three are 2e-7 apart (roots merged within an absolute
    1e-6, and within 1e-6 relative at 1e4). By hand: V = k ((x - c)^2 - a^2)^2 / (4 a^2) has
    F = -k (x - c) ((x - c)^2 - a^2) / a^2, zero at x = c - a, c, c + a."""
    from lagcodegen.statics.equilibria import find_equilibria

    x = me.dynamicsymbols("x")
    ms, k, half_width, c = sp.symbols("m k a c", positive=True)
    eom = derive_equations(Model("double_well", [x], [ms, k, half_width, c], kinetic_energy=ms * x.diff() ** 2 / 2,
                                 potential_energy=k * ((x - c) ** 2 - half_width ** 2) ** 2 / (4 * half_width ** 2),
                                 parameter_values={"m": m, "k": 1.0, "a": a, "c": centre}))
    guesses = (centre + np.linspace(-2.5 * a, 2.5 * a, 11)).reshape(-1, 1)
    found = sorted(p[eom.q[0]] for p in find_equilibria(eom, values={}, guesses=guesses))
    np.testing.assert_allclose(found, [centre - a, centre, centre + a], rtol=1e-12, atol=1e-12 * a)


def test_a_slow_spin_up_is_no_steady_spin():
    """Was: a free flywheel with tau / J = 5e-11 rad/s^2 returned as spinning steadily at 100 rad/s
    (an absolute tolerance of 1e-10). By hand J phi'' = tau has no steady spin for tau != 0, at any
    scale; with tau = 0 every spin is steady."""
    phi = me.dynamicsymbols("phi")
    J, torque = sp.symbols("J tau", positive=True)
    model = Model("free_flywheel", [phi], [J, torque], kinetic_energy=J * phi.diff() ** 2 / 2,
                  generalized_forces={phi: torque}, parameter_values={"J": 2.0, "tau": 1e-10})
    eom = derive_equations(model)
    with pytest.raises(ValueError, match="no solution"):
        steady_motion(eom, {"phi_d": 100.0}, ["phi"], ["phi_d"])
    assert steady_motion(eom, {"phi_d": 100.0}, ["phi"], ["phi_d"], values={"tau": 0.0}).values["phi_d"] == 100.0


@pytest.mark.parametrize("value", [float("inf"), float("nan"), "a lot"])
def test_a_held_coordinate_needs_a_finite_number(value):
    """Was: sympy's AccumulationBounds printer error for inf, 'residual nan' for NaN; neither named fix=."""
    from lagcodegen import catalog
    from lagcodegen.statics.constrained import constrained_equilibrium

    eom = derive_equations(catalog.slider_crank())
    with pytest.raises(ValueError, match="fix: coordinate theta needs a"):
        constrained_equilibrium(eom, list(catalog.slider_crank_state(0.4)[:5]), fix={"theta": value})


@pytest.mark.parametrize("tol", [-1.0, 0.0, float("nan"), "1e-9", True])
def test_a_tolerance_must_be_a_positive_number(tol):
    """A negative tol accepted the double pendulum's rest as steady (the residual, 0, is <= -0); NaN gave
    a 'relative to its terms nan' message. Both tolerances are now checked by name."""
    from lagcodegen import catalog
    from lagcodegen.statics.consistent import consistent_state

    with pytest.raises(ValueError, match="tol must be a positive finite number"):
        steady_motion(derive_equations(catalog.double_pendulum()), {"q1_d": 0.0}, ["q1"], ["q1_d"], tol=tol)
    with pytest.raises(ValueError, match="tol must be a positive finite number"):
        consistent_state(derive_equations(catalog.cartesian_pendulum()), {"x": 0.5}, tol=tol)
