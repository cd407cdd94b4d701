"""Rayleigh's dissipation function R(q, qd): the energies route adds -dR/dqd_j to F_j.

References, independent of the derivation:
- the damped oscillator m x'' + c x' + k x = 0, whose exact underdamped solution is typed by hand
  (any vibrations text, e.g. Meirovitch, Elements of Vibration Analysis, ch. 1);
- a two-mass chain whose damper forces are typed by hand as generalized forces Q (virtual work of
  the dashpots c1 on x1 and c2 between x1 and x2), derived by the same route without R.
Flipping the sign of the Rayleigh term in the energies route fails every test here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

t = me.dynamicsymbols._t
m, k, c = sp.symbols("m k c", positive=True)
x = me.dynamicsymbols("x")
VALUES = {m: 2.0, k: 50.0, c: 1.2}  # zeta = c / (2 sqrt(k m)) = 0.06: underdamped


def damped_oscillator() -> Model:
    return Model("damped_oscillator", [x], [m, k, c],
                 kinetic_energy=m * x.diff(t) ** 2 / 2, potential_energy=k * x ** 2 / 2,
                 dissipation=c * x.diff(t) ** 2 / 2, parameter_values=VALUES)


def exact_damped(t_values, x0, v0):
    """x(t) of m x'' + c x' + k x = 0 for zeta < 1, by hand."""
    mass, stiffness, damping = VALUES[m], VALUES[k], VALUES[c]
    omega = math.sqrt(stiffness / mass)
    zeta = damping / (2 * math.sqrt(stiffness * mass))
    omega_d = omega * math.sqrt(1 - zeta ** 2)
    decay = np.exp(-zeta * omega * t_values)
    return decay * (x0 * np.cos(omega_d * t_values)
                    + (v0 + zeta * omega * x0) / omega_d * np.sin(omega_d * t_values))


def test_rayleigh_term_gives_the_damping_force():
    eom = derive_equations(damped_oscillator())
    (q,), (u,) = eom.q, eom.u
    assert sp.simplify(eom.mass_matrix[0, 0] - m) == 0
    assert sp.simplify(eom.forcing[0] - (-c * u - k * q)) == 0


def test_damped_oscillator_decays_as_the_exact_solution():
    system = compile_model(damped_oscillator(), methods=("rk4",))
    x0, v0, t_end, h = 0.3, -0.5, 10.0, 1e-3
    run = simulate(system, [x0, v0], t_end, h, "rk4")
    assert run.status.name == "OK"
    expected = exact_damped(run.t, x0, v0)
    # RK4 at h = 1e-3 on omega = 5 rad/s: global error ~ (omega h)^4 t_end ~ 6e-9 of the amplitude
    np.testing.assert_allclose(run.x[:, 0], expected, rtol=0, atol=1e-8)
    # the amplitude after 10 s is e^{-zeta omega t} = e^{-3} of the start: the decay is there
    assert abs(run.x[-1, 0]) < 0.1 * x0


def test_two_mass_chain_rayleigh_equals_hand_typed_dashpot_forces():
    x1, x2 = me.dynamicsymbols("x1 x2")
    c1, c2, k1, k2 = sp.symbols("c1 c2 k1 k2", positive=True)
    v1, v2 = x1.diff(t), x2.diff(t)
    T = m * (v1 ** 2 + v2 ** 2) / 2
    V = k1 * x1 ** 2 / 2 + k2 * (x2 - x1) ** 2 / 2
    params = [m, c1, c2, k1, k2]
    with_rayleigh = Model("chain_r", [x1, x2], params, kinetic_energy=T, potential_energy=V,
                          dissipation=c1 * v1 ** 2 / 2 + c2 * (v2 - v1) ** 2 / 2)
    # virtual work of the dashpots, typed by hand: dW = -c1 v1 dx1 - c2 (v2 - v1)(dx2 - dx1)
    with_forces = Model("chain_q", [x1, x2], params, kinetic_energy=T, potential_energy=V,
                        generalized_forces={x1: -c1 * v1 + c2 * (v2 - v1), x2: -c2 * (v2 - v1)})
    a, b = derive_equations(with_rayleigh), derive_equations(with_forces)
    assert (a.forcing - b.forcing).applyfunc(sp.expand) == sp.zeros(2, 1)
    # and the damping really is there: dF/du is minus the damping matrix typed by hand
    damping = sp.Matrix([[c1 + c2, -c2], [-c2, c2]])
    assert sp.simplify(a.forcing.jacobian(sp.Matrix(a.u)) + damping) == sp.zeros(2, 2)


def test_bodies_route_adds_the_rayleigh_term_too():
    # the same oscillator as a particle on a rail (d'Alembert-Lagrange route)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    ball = me.Particle("ball", O.locatenew("P", x * N.x), m)
    model = Model("damped_rail", [x], [m, k, c], bodies=[ball], frame=N, origin=O,
                  potential_energy=k * x ** 2 / 2, dissipation=c * x.diff(t) ** 2 / 2)
    eom = derive_equations(model)
    (q,), (u,) = eom.q, eom.u
    assert sp.simplify(eom.forcing[0] - (-c * u - k * q)) == 0


def test_abs_of_a_coordinate_or_speed_differentiates_as_real(tmp_path):
    # found by review: the plain symbols were not real, so d|x|/dx came out in re() and im() terms,
    # which the C printer refused naming a CSE temporary. V = k |x|^3 / 3 and R = c |x'|^3 / 3 give
    # the forces -k x |x| and -c x' |x'| (by hand).
    x = me.dynamicsymbols("x")
    m, k, c = sp.symbols("m k c", positive=True)
    model = Model("cubic", [x], [m, k, c], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=k * sp.Abs(x) ** 3 / 3, dissipation=c * sp.Abs(x.diff()) ** 3 / 3,
                  parameter_values={m: 1.0, k: 2.0, c: 0.1})
    eom = derive_equations(model)
    q, u = eom.q[0], eom.u[0]
    assert not eom.forcing.has(sp.re, sp.im)
    for value, rate in [(0.7, -1.3), (-0.4, 2.0)]:
        at = {q: value, u: rate, k: 2.0, c: 0.1}
        by_hand = -2.0 * value * abs(value) - 0.1 * rate * abs(rate)
        assert float(eom.forcing[0].xreplace(at)) == pytest.approx(by_hand, rel=1e-14)
    compile_model(model, methods=("rk4",), outputs=("rhs",), cache_dir=tmp_path)
