"""Velocity constraints with multipliers (issue 14): the Chaplygin sleigh.

A rigid body (mass m, inertia I about its mass centre) slides on a plane on a knife edge at
P = (x, y), its blade along the body axis at angle theta; the mass centre sits a ahead of P on that
axis. The blade cannot slide sideways: -x' sin(theta) + y' cos(theta) = 0, a constraint on the
velocities only. With v the speed of P along the blade, w = theta' and J = I + m a^2 the classical
equations (Neimark and Fufaev, Dynamics of Nonholonomic Systems, ch. III; Bloch, Nonholonomic
Mechanics and Control, sec. 1.7) are m v' = m a w^2, J w' = -m a v w, which conserve
E = (m v^2 + J w^2) / 2 and integrate in closed form:

    v(t) = V tanh(a m V t / J + artanh(v0 / V)),  w(t) = sign(w0) sqrt(m / J) sqrt(V^2 - v^2),

V = sqrt(2 E / m): the velocity turns into the blade's direction and the spin dies out.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, ModelError, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

VALUES = {"m": 2.0, "I": 0.3, "a": 0.4}
t = me.dynamicsymbols._t


def sleigh(arm: str = "a", **extra) -> Model:
    """The sleigh; ``arm`` names the lever arm's symbol (its value stays VALUES["a"])."""
    x, y, theta = me.dynamicsymbols("x y theta")
    m, I, a = sp.symbols(f"m I {arm}", positive=True)
    xc, yc = x + a * sp.cos(theta), y + a * sp.sin(theta)
    T = m * (xc.diff(t) ** 2 + yc.diff(t) ** 2) / 2 + I * theta.diff(t) ** 2 / 2
    blade = -x.diff(t) * sp.sin(theta) + y.diff(t) * sp.cos(theta)
    values = {"m": VALUES["m"], "I": VALUES["I"], arm: VALUES["a"]}
    return Model("chaplygin_sleigh", [x, y, theta], [m, I, a], kinetic_energy=T, motion_constraints=[blade],
                 parameter_values=values, **extra)


def closed_form(times, v0, w0):
    m, I, a = VALUES["m"], VALUES["I"], VALUES["a"]
    J = I + m * a ** 2
    V = np.sqrt(v0 ** 2 + J * w0 ** 2 / m)
    v = V * np.tanh(a * m * V * times / J + np.arctanh(v0 / V))
    return v, np.sign(w0) * np.sqrt(m / J) * np.sqrt(np.maximum(V ** 2 - v ** 2, 0.0))


@pytest.fixture(scope="module")
def system(tmp_path_factory):
    return compile_model(sleigh(), methods=("rk4",), cache_dir=tmp_path_factory.mktemp("sleigh"))


def test_the_equations_have_one_velocity_constraint():
    eom = derive_equations(sleigh())
    assert eom.m == 1 and eom.n_holonomic == 0 and "velocity constraints (Lagrange I)" in eom.route
    assert eom.constraints == sp.Matrix([[0]])
    x, y, theta = eom.q
    assert eom.constraint_jacobian == sp.Matrix([[-sp.sin(theta), sp.cos(theta), 0]])


@pytest.mark.parametrize("v0, w0", [(0.5, 2.0), (-0.3, -1.5)])
def test_the_sleigh_follows_the_closed_form(system, v0, w0):
    x0 = {"x": 0.0, "y": 0.0, "theta": 0.0, "x_d": v0, "y_d": 0.0, "theta_d": w0}
    run = simulate(system, x0, t_end=6.0, h=1e-3, project=True, residuals=True, multipliers=True)
    assert run.ok
    theta, xd, yd, w = run["theta"], run["x_d"], run["y_d"], run["theta_d"]
    v = xd * np.cos(theta) + yd * np.sin(theta)
    v_exact, w_exact = closed_form(run.t, v0, w0)
    np.testing.assert_allclose(v, v_exact, atol=1e-9)
    np.testing.assert_allclose(w, w_exact, atol=1e-9)
    assert np.abs(run.residuals).max() < 1e-12  # no sideways slip
    # the spin has gone into the blade's direction by the end, as the closed form says
    assert abs(w[-1]) < 0.05 * abs(w0) and abs(v[-1]) > abs(v0)


def test_baumgarte_damps_a_sideways_slip(system):
    """Started with a sideways slip w0 = y'(0) = 0.01: the multipliers keep w' = 0 (the slip stays),
    Baumgarte's term makes w' = -2 alpha w, so w(t) = w0 exp(-2 alpha t) (by hand)."""
    x0 = {"x": 0.0, "y": 0.0, "theta": 0.0, "x_d": 0.5, "y_d": 0.01, "theta_d": 2.0}
    loose = simulate(system, x0, t_end=0.5, h=1e-3, residuals=True)
    np.testing.assert_allclose(loose.residuals[:, 1], 0.01, rtol=1e-10)
    held = simulate(system, x0, t_end=0.5, h=1e-3, residuals=True, params={"baumgarte_alpha": 5.0})
    np.testing.assert_allclose(held.residuals[:, 1], 0.01 * np.exp(-10.0 * held.t), rtol=1e-7, atol=1e-15)


def test_sympy_lagranges_method_with_nonhol_coneqs_is_the_same_model():
    """Second route: the sleigh built as a sympy LagrangesMethod with nonhol_coneqs."""
    ours = derive_equations(sleigh())
    x, y, theta = me.dynamicsymbols("x y theta")
    m, I, a = sp.symbols("m I a", positive=True)
    xc, yc = x + a * sp.cos(theta), y + a * sp.sin(theta)
    L = m * (xc.diff(t) ** 2 + yc.diff(t) ** 2) / 2 + I * theta.diff(t) ** 2 / 2
    method = me.LagrangesMethod(L, [x, y, theta], nonhol_coneqs=[-x.diff(t) * sp.sin(theta)
                                                                 + y.diff(t) * sp.cos(theta)])
    theirs = derive_equations(Model("sleigh_sympy", parameters=[m, I, a], sympy_model=method))
    assert "velocity constraints" in theirs.route
    for name in ("mass_matrix", "forcing", "constraint_jacobian", "constraint_rate", "constraint_bias"):
        difference = sp.simplify(sp.Matrix(getattr(ours, name)) - sp.Matrix(getattr(theirs, name)))
        assert difference == sp.zeros(*difference.shape), name


@pytest.mark.parametrize("blade, match", [
    ("nonlinear", r"motion constraint 0 .* is not linear in the speeds \(in Derivative\(x\(t\), t\)\)"),
    ("no_speed", "involves no speed: a constraint on the positions belongs in constraints="),
    ("acceleration", "motion constraint 0 contains the acceleration"),
    ("undeclared", "motion constraint 0 uses symbols not declared as parameters: k"),
    ("nan", "motion constraint 0 is nan"),
])
def test_bad_motion_constraints_are_named(blade, match):
    x, y, theta = me.dynamicsymbols("x y theta")
    m = sp.symbols("m", positive=True)
    T = m * (x.diff(t) ** 2 + y.diff(t) ** 2) / 2 + theta.diff(t) ** 2 / 2
    constraint = {"nonlinear": x.diff(t) ** 2 - y.diff(t), "no_speed": x - y,
                  "acceleration": x.diff(t, 2) - y.diff(t), "undeclared": sp.Symbol("k") * x.diff(t),
                  "nan": sp.nan * x.diff(t)}[blade]
    with pytest.raises(ModelError, match=match):
        derive_equations(Model("bad_blade", [x, y, theta], [m], kinetic_energy=T, motion_constraints=[constraint]))


@pytest.mark.parametrize("speed", [0.7, -0.7])
def test_straight_sliding_is_stable_forward_and_unstable_backward(speed):
    """About v = V, w = 0 the closed-form equations give w' = -(m a V / J) w: one eigenvalue
    -m a V / J in the 5 allowed directions, the rest 0 (by hand)."""
    from lagcodegen.statics.state_space import linearize_state

    linear = linearize_state(derive_equations(sleigh()), [0, 0, 0, speed, 0, 0], values={})
    m, I, a = VALUES["m"], VALUES["I"], VALUES["a"]
    eigenvalues = linear.eigenvalues()
    assert linear.basis.shape == (6, 5)
    np.testing.assert_allclose(eigenvalues[np.abs(eigenvalues) > 1e-9], [-m * a * speed / (I + m * a ** 2)], rtol=1e-12)
    with pytest.raises(ValueError, match="numeric; pass values="):
        linearize_state(derive_equations(sleigh()), [0, 0, 0, speed, 0, 0])
