"""Statics found wrong or unclear by the review of session 12 (helper-35), each against a hand result."""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations
from lagcodegen.statics.constrained import constrained_equilibrium
from lagcodegen.statics.equilibria import LinearModel, find_equilibria, linearize
from lagcodegen.statics.state_space import linearize_state


def test_a_small_force_beside_a_large_one_still_has_to_vanish():
    """Was: 10 'equilibria' of the double pendulum with m1 = l1 = 100, m2 = l2 = 0.01, six of them with
    |F2| at 95-98 % of m2 g l2 (one tolerance for both equations). By hand, F = (-(m1 + m2) g l1 sin q1,
    -m2 g l2 sin q2): exactly the four points with q1, q2 in {0, pi}."""
    eom = derive_equations(catalog.double_pendulum())
    found = find_equilibria(eom, values={"l1": 100.0, "m1": 100.0, "m2": 0.01, "l2": 0.01})
    points = sorted((round(abs(p[eom.q[0]]), 9), round(abs(p[eom.q[1]]), 9)) for p in found)
    assert points == sorted((a, b) for a in (0.0, round(math.pi, 9)) for b in (0.0, round(math.pi, 9)))


def _pendulum(m: float, length: float):
    theta = me.dynamicsymbols("theta")
    ms, ls, g = sp.symbols("m l g", positive=True)
    model = Model("pendulum", [theta], [ms, ls, g], kinetic_energy=ms * ls ** 2 * theta.diff() ** 2 / 2,
                  potential_energy=-ms * g * ls * sp.cos(theta), parameter_values={ms: m, ls: length, g: 9.81})
    return derive_equations(model)


def test_a_micro_pendulum_off_its_equilibrium_is_no_equilibrium():
    """Was: m = 1e-6 kg, l = 1 mm at theta = 1.4 taken for an equilibrium (force -9.7e-9, under an absolute
    floor of 1e-8), 'stable' at 40.8 rad/s. By hand: only theta = 0 is, with w^2 = g / l."""
    eom = _pendulum(1e-6, 1e-3)
    with pytest.raises(ValueError, match=r"q0 = \[1\.4\] is no equilibrium"):
        linearize(eom, [1.4], {})
    assert linearize(eom, [0.0], {}).eigenvalues() == pytest.approx([9.81 / 1e-3], rel=1e-12)


def test_a_micro_four_bar_has_the_equilibria_of_the_full_size_one():
    """Was: masses x 1e-9, lengths x 1e-3 and the torque x 1e-12 (so m g l and tau scale alike) returned
    the guess itself. Scaling every force term by the same factor leaves the equilibrium angles as
    they are: the full-size linkage's are the reference."""
    eom = derive_equations(catalog.four_bar())
    # tau = 1 N m: the default 5 N m is more than gravity holds (the crank turns over; no equilibrium)
    defaults = {p.name: v for p, v in eom.parameter_values.items()} | {"tau": 1.0}
    micro = {}
    for name, value in defaults.items():
        if name.startswith("m"):
            micro[name] = value * 1e-9
        elif name.startswith("l") or name == "d":
            micro[name] = value * 1e-3
        elif name == "tau":
            micro[name] = value * 1e-12
        else:
            micro[name] = value
    for crank in (-1.5, 0.8):
        guess = catalog.four_bar_state(crank)[:3]  # on the constraints
        q_full, _ = constrained_equilibrium(eom, guess, {"tau": 1.0})
        q_micro, _ = constrained_equilibrium(eom, guess, micro)
        assert q_micro == pytest.approx(q_full, abs=1e-8), (crank, micro)


def _linear(C0, K0) -> LinearModel:
    n = len(K0)
    return LinearModel(tuple(sp.symbols(f"x0:{n}")), (0.0,) * n, np.eye(n), np.array(C0, float), np.array(K0, float))


def test_negative_damping_is_not_stable():
    """Was: m x'' - c x' + k x = 0 (c = 0.5, k = 4) 'stable' (K0 > 0 alone). By hand its eigenvalues are
    (c +- sqrt(c^2 - 4 k)) / 2 = 0.25 +- 1.984i: unstable; with +c, -0.25 +- 1.984i: stable."""
    negative, positive = _linear([[-0.5]], [[4.0]]), _linear([[0.5]], [[4.0]])
    assert negative.stable is False and positive.stable is True
    rates = sorted(negative.first_order_eigenvalues(), key=lambda z: z.imag)
    assert rates == pytest.approx([0.25 - 1j * math.sqrt(3.9375), 0.25 + 1j * math.sqrt(3.9375)])


def test_a_gyroscopic_saddle_is_not_judged_by_its_stiffness():
    """A rotating saddle (Omega = 2, k = 1): K0 = diag(k - Omega^2, -k - Omega^2) = diag(-3, -5) and the
    gyroscopic C0 = [[0, -2 Omega], [2 Omega, 0]]. Was: stable False from K0 alone. By hand,
    det(l^2 I + l C0 + K0) = (l^2 + 3)(l^2 + 5): eigenvalues +-i sqrt(3), +-i sqrt(5), no growth."""
    saddle = _linear([[0.0, -4.0], [4.0, 0.0]], [[-3.0, 0.0], [0.0, -5.0]])
    with pytest.raises(ValueError, match="gyroscopic"):
        _ = saddle.stable
    rates = saddle.first_order_eigenvalues()
    assert np.abs(rates.real).max() < 1e-12
    assert sorted(np.abs(rates.imag)) == pytest.approx([math.sqrt(3)] * 2 + [math.sqrt(5)] * 2)


def test_linearize_names_a_model_with_more_coordinates_than_speeds():
    """Was: a bare NonSquareMatrixError('') for a quaternion body (4 coordinates, 3 speeds)."""
    from tests.numeric.test_kane_speeds import _quaternion_body

    kane, frame, inertias, _ = _quaternion_body()
    eom = derive_equations(Model("quaternion_body", parameters=list(inertias), sympy_model=kane, frame=frame))
    with pytest.raises(ValueError, match="one speed per coordinate: model 'quaternion_body' has 4 coordinates "
                                         "and 3 speeds; use statics.state_space.linearize_state"):
        linearize(eom, [1.0, 0.0, 0.0, 0.0], {"I1": 1.0, "I2": 2.0, "I3": 3.0})


def test_linearize_state_refuses_a_time_that_is_not_finite():
    """Was: t0 = nan gave A with a NaN entry and no error."""
    eom = _pendulum(1.0, 1.0)
    with pytest.raises(ValueError, match="t0 must be finite"):
        linearize_state(eom, [0.1, 0.0], values={}, t0=float("nan"))


def test_a_continuum_of_equilibria_is_warned_of():
    """Was: the double pendulum with g = 0 (every configuration an equilibrium, by hand: F = 0) gave its
    64 starting points as 64 equilibria with no word. With gravity, the four isolated ones, no warning."""
    import warnings

    from lagcodegen.statics.equilibria import EquilibriumWarning

    eom = derive_equations(catalog.double_pendulum())
    with pytest.warns(EquilibriumWarning, match="singular Jacobian of the equilibrium conditions"):
        find_equilibria(eom, values={"g": 0.0})
    with warnings.catch_warnings():
        warnings.simplefilter("error", EquilibriumWarning)
        assert len(find_equilibria(eom, values={})) == 4


def test_an_inconsistent_state_is_named_before_any_rank_test():
    """Was: the all-zero four-bar state (the CLI's default) blamed "[[M, A^T], [A, 0]] ... constraints
    that lost rank"; by hand its loop closure is l1 + l2 - l3 - d = 0.1 + 0.35 - 0.3 - 0.4 = -0.25."""
    with pytest.raises(ValueError, match=r"violates constraint row 0 of model 'four_bar' \(residual -0\.25\)"):
        linearize_state(derive_equations(catalog.four_bar()), [0.0] * 6, values={})


def test_first_order_eigenvalues_name_a_singular_mass_matrix():
    """Found trying the new method with M0 = 0: numpy's bare "Singular matrix"."""
    model = LinearModel((sp.Symbol("x"),), (0.0,), np.zeros((1, 1)), np.zeros((1, 1)), np.ones((1, 1)))
    with pytest.raises(ValueError, match=r"M0 is singular at q0 = \(0\.0,\): no first-order form"):
        model.first_order_eigenvalues()
