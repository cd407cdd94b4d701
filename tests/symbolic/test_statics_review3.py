"""Statics found wrong by the review of session 16 (helper-55), each against a hand result or an
independent integration (scipy's DOP853 at rtol = atol = 1e-12 on equations written here)."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

from lagcodegen import Model, derive_equations
from lagcodegen.statics.equilibria import linearize

t = me.dynamicsymbols._t
theta = me.dynamicsymbols("theta")
m, length, g, amplitude, w = sp.symbols("m l g a w", positive=True)


def test_a_point_at_rest_only_at_some_instants_is_no_equilibrium():
    """Was: K0 = 9.81 and stable = True at theta = 0 under a torque 5 sin(2 t). By hand theta = 0 is at
    rest there only where sin(2 t) = 0."""
    forced = derive_equations(Model("forced", [theta], [m, length, g, amplitude, w],
                                    kinetic_energy=m * length ** 2 * theta.diff() ** 2 / 2,
                                    potential_energy=-m * g * length * sp.cos(theta),
                                    generalized_forces={theta: amplitude * sp.sin(w * t)},
                                    parameter_values={"m": 1.0, "l": 1.0, "g": 9.81, "a": 5.0, "w": 2.0}))
    with pytest.raises(ValueError, match=r"model 'forced' depends on t at q0: the generalized force at rest on "
                                         r"theta is 5\.0\*sin\(2\.0\*t\), so q0 is no equilibrium at every t"):
        linearize(forced, [0.0], {})


def test_a_time_varying_linear_model_is_refused():
    """Was: K0 = 4.905 and stable = True for a pendulum on a pivot y = a cos(w t) in the first resonance
    tongue (w = 2 sqrt(g / l), a = l / 8). By hand theta'' = -(g - a w^2 cos(w t)) sin(theta) / l; the
    Floquet multipliers of its linearization over one period (DOP853) show the hanging position
    unstable, which no model frozen at one instant can say."""
    values = {"m": 1.0, "l": 1.0, "g": 9.81, "a": 0.125, "w": 2 * np.sqrt(9.81)}
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    bob = O.locatenew("P", length * sp.sin(theta) * N.x + (amplitude * sp.cos(w * t) - length * sp.cos(theta)) * N.y)
    pivot = derive_equations(Model("vibrating_pivot", [theta], [m, length, g, amplitude, w],
                                   bodies=[me.Particle("bob", bob, m)], gravity=-g * N.y, frame=N, origin=O,
                                   parameter_values=values))

    def mathieu(time, s):
        return [s[1], -(values["g"] - values["a"] * values["w"] ** 2 * np.cos(values["w"] * time)) / values["l"] * s[0]]

    period = 2 * np.pi / values["w"]
    monodromy = np.column_stack([solve_ivp(mathieu, [0, period], e, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
                                 for e in np.eye(2)])
    assert np.max(np.abs(np.linalg.eigvals(monodromy))) > 1.4  # unstable: the frozen model's "stable" was wrong
    with pytest.raises(ValueError, match=r"model 'vibrating_pivot' depends on t at q0: K0\[0,0\] = .*cos\(.*t\), so "
                                         r"the linear model about q0 varies in time"):
        linearize(pivot, [0.0], {})


def test_a_symbolic_point_off_equilibrium_is_refused():
    """Was: K0 = g l m cos(1/2) with no error, parameters left symbolic. By hand the force at rest at
    theta = 1/2 is -m g l sin(1/2), not 0 (with values= the same call was refused already)."""
    pendulum = derive_equations(Model("pendulum", [theta], [m, g, length],
                                      kinetic_energy=m * length ** 2 * theta.diff() ** 2 / 2,
                                      potential_energy=-m * g * length * sp.cos(theta)))
    with pytest.raises(ValueError, match=r"q0 = \[1/2\] is no equilibrium of model 'pendulum': the generalized "
                                         r"force on theta at rest is -g\*l\*m\*sin\(1/2\), not 0"):
        linearize(pendulum, [sp.Rational(1, 2)])
    assert linearize(pendulum, [sp.pi]).K0 == sp.Matrix([[-g * length * m]])  # by hand: -m g l, standing


def test_a_double_root_is_one_equilibrium_with_a_warning():
    """Was: 7 'equilibria' spread over 1.57079630-1.57079634 and no warning. By hand, a torque
    tau = m g l holds the pendulum at rest only where sin(theta) = 1: theta = pi/2, a saddle-node
    (dF/dtheta = -m g l cos(pi/2) = 0 there)."""
    from lagcodegen.statics.equilibria import EquilibriumWarning, find_equilibria

    torque = sp.Symbol("tau", positive=True)
    eom = derive_equations(Model("torqued", [theta], [m, length, g, torque],
                                 kinetic_energy=m * length ** 2 * theta.diff() ** 2 / 2,
                                 potential_energy=-m * g * length * sp.cos(theta), generalized_forces={theta: torque},
                                 parameter_values={"m": 1.0, "l": 1.0, "g": 9.81, "tau": 9.81}))
    with pytest.warns(EquilibriumWarning, match=r"1 of the 1 equilibria of model 'torqued' found have a singular"):
        roots = find_equilibria(eom, {})
    assert len(roots) == 1 and roots[0][eom.q[0]] == pytest.approx(np.pi / 2, abs=1e-4)


def test_a_steady_motion_where_the_force_is_one_product():
    """Was: 14 of 20 of a bead's relative equilibria on a hoop spun at W refused ("no solution ... The
    solution converged"), and F = c (x^2 - 2)(1 + x^2) refused at x = sqrt(2): a product's residual was
    measured against |F| itself, 0 at its roots. By hand, cos(theta0) = g / (R W^2) on the hoop."""
    from lagcodegen.statics.steady import steady_motion

    x = me.dynamicsymbols("x")
    radius, spin, c = sp.symbols("R Omega c", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    bead = O.locatenew("P", radius * sp.sin(theta) * (sp.cos(spin * t) * N.x + sp.sin(spin * t) * N.y)
                       - radius * sp.cos(theta) * N.z)
    hoop = derive_equations(Model("hoop", [theta], [m, radius, g, spin], bodies=[me.Particle("b", bead, m)],
                                  gravity=-g * N.z, frame=N, origin=O,
                                  parameter_values={"m": 1.0, "R": 0.5, "g": 9.81, "Omega": 6.0}))
    for W in np.linspace(4.5, 12.0, 7):
        motion = steady_motion(hoop, {"theta": 1.0}, unknowns=["theta"], steady=["theta_d"], values={"Omega": W})
        assert motion.values["theta"] == pytest.approx(np.arccos(9.81 / (0.5 * W ** 2)), abs=1e-12)
    product = derive_equations(Model("product_force", [x], [m, c], kinetic_energy=m * x.diff() ** 2 / 2,
                                     generalized_forces={x: c * (x ** 2 - 2) * (1 + x ** 2)},
                                     parameter_values={"m": 1.0, "c": 3.0}))
    assert steady_motion(product, {"x": 1.4}, unknowns=["x"], steady=["x_d"]).values["x"] == pytest.approx(
        np.sqrt(2), abs=1e-12)


def test_a_steady_search_that_reaches_a_singular_mass_matrix_names_it():
    """Was: numpy's bare "LinAlgError: Singular matrix" from inside scipy's root. A spherical pendulum,
    T = m l^2 (theta'^2 + sin^2(theta) phi'^2) / 2: by hand M = diag(m l^2, m l^2 sin^2 theta) is
    singular at theta = 0, where the search for the conical motion at phi' = 10 from theta = 0.5 lands."""
    from lagcodegen.statics.steady import steady_motion

    phi = me.dynamicsymbols("phi")
    spherical = derive_equations(Model("spherical_pendulum", [theta, phi], [m, length, g],
                                       kinetic_energy=m * length ** 2 * (theta.diff() ** 2
                                                                         + sp.sin(theta) ** 2 * phi.diff() ** 2) / 2,
                                       potential_energy=-m * g * length * sp.cos(theta),
                                       parameter_values={"m": 1.0, "l": 1.0, "g": 9.81}))
    with pytest.raises(ValueError, match=r"steady motion of model 'spherical_pendulum': the search reached the "
                                         r"configuration theta = 0, phi = 0, where the mass matrix .* is singular"):
        steady_motion(spherical, {"theta": 0.5, "phi_d": 10.0}, unknowns=["theta"], steady=["theta_d"])
    motion = steady_motion(spherical, {"theta": 1.4, "phi_d": 10.0}, unknowns=["theta"], steady=["theta_d"])
    assert motion.values["theta"] == pytest.approx(np.arccos(9.81 / 100.0), abs=1e-12)  # by hand: g / (l W^2)


def test_constrained_equilibrium_holds_inputs():
    """Was: no inputs= (find_equilibria, linearize and steady_motion take one) and "Cannot convert
    expression to float" on a driven model. By hand, a bob on a rod x^2 + y^2 = l^2 under gravity and a
    horizontal force F: tan(angle) = F / (m g), x = l sin(angle), and lambda = F / (2 x) from F = 2 x lambda."""
    from lagcodegen.statics.constrained import constrained_equilibrium

    x, y, force = me.dynamicsymbols("x y F")
    eom = derive_equations(Model("rod_with_force", [x, y], [m, length, g],
                                 kinetic_energy=m * (x.diff() ** 2 + y.diff() ** 2) / 2, potential_energy=m * g * y,
                                 generalized_forces={x: force}, inputs=[force], constraints=[x ** 2 + y ** 2 - length ** 2],
                                 parameter_values={"m": 1.0, "l": 1.0, "g": 9.81}))
    with pytest.raises(ValueError, match=r"model 'rod_with_force' has inputs F: pass their values"):
        constrained_equilibrium(eom, [0.1, -0.9], {})
    for bad in (float("nan"), -1.0):
        with pytest.raises(ValueError, match=r"constrained_equilibrium: tol must be a positive finite number"):
            constrained_equilibrium(eom, [0.1, -0.9], {}, inputs=[3.0], tol=bad)
    q, lam = constrained_equilibrium(eom, [0.1, -0.9], {}, inputs={"F": 3.0})
    angle = np.arctan(3.0 / 9.81)
    np.testing.assert_allclose(q, [np.sin(angle), -np.cos(angle)], rtol=1e-10)
    np.testing.assert_allclose(lam, [3.0 / (2 * np.sin(angle))], rtol=1e-10)


def test_statics_arguments_name_the_culprit():
    """Found by review: each of these named nothing ("Cannot convert expression to float", numpy's
    "truth value of an array ... is ambiguous"), passed silently (a NaN guess gave [], inputs=0.0 on a
    model without inputs), or contradicted itself (the model's own Symbol phi_d was "no state ...
    (states: ..., phi_d)"; dependent_speeds=["y"] was "not a coordinate (coordinates: x, y)")."""
    import math

    from lagcodegen import catalog
    from lagcodegen.statics.equilibria import find_equilibria
    from lagcodegen.statics.state_space import linearize_state
    from lagcodegen.statics.steady import steady_motion

    dp = derive_equations(catalog.double_pendulum())
    cases = [
        (lambda: linearize_state(dp, [0, 0, 0, 0], values={}, t0="a"), TypeError, r"^t0 must be a real number, got 'a'"),
        (lambda: linearize_state(dp, [sp.Symbol("a"), 0, 0, 0], values={}), ValueError,
         r"^x0 entry for q1 holds a, which is no parameter of model 'double_pendulum'"),
        (lambda: linearize_state(dp, [1j, 0, 0, 0], values={}), ValueError, r"^x0 entry for q1 must be real"),
        (lambda: find_equilibria(dp, {}, guesses=[[math.nan, 0.0]]), ValueError, r"^guesses\[0\] = \[nan, 0\.0\] is not finite"),
        (lambda: linearize(dp, [0, 0], {}, inputs=0.0), ValueError, r"model 'double_pendulum' has no inputs, got inputs=0\.0"),
        (lambda: linearize(dp, [0, 0], {}, inputs=np.array([1.0, 2.0])), ValueError,
         r"model 'double_pendulum' has no inputs, got inputs=array"),
    ]
    for call, error, message in cases:
        with pytest.raises(error, match=message):
            call()
    assert linearize(dp, [0, 0], {}, inputs=[]).K0.shape == (2, 2)  # an empty list says "no inputs"

    phi = me.dynamicsymbols("phi")
    torque, drag = sp.symbols("tau c", positive=True)
    # J phi'' = tau - c phi': by hand the steady spin is tau / c = 3, named by the model's own Symbol
    flywheel = derive_equations(Model("flywheel", [phi], [m, torque, drag], kinetic_energy=m * phi.diff() ** 2 / 2,
                                      generalized_forces={phi: torque - drag * phi.diff()},
                                      parameter_values={"m": 2.0, "tau": 6.0, "c": 2.0}))
    by_symbol = steady_motion(flywheel, {"phi_d": 1.0}, unknowns=[flywheel.u[0]], steady=[flywheel.u[0]])
    assert by_symbol.values["phi_d"] == pytest.approx(3.0, rel=1e-12)
    with pytest.raises(TypeError, match=r"steady motion: steady must be a list of state names, got 'phi_d'"):
        steady_motion(flywheel, {"phi_d": 1.0}, unknowns=["phi_d"], steady="phi_d")
    x, y = me.dynamicsymbols("x y")
    sleigh = Model("sleigh", [x, y], [m], kinetic_energy=m * (x.diff() ** 2 + y.diff() ** 2) / 2,
                   motion_constraints=[y.diff() - x.diff()], dependent_speeds=["y"])
    assert sleigh.dependent_speeds == (y,)


def test_a_linearization_undefined_at_the_point_is_named():
    """Found by review (session 16, helper-60): a measurement 1/x at x = 0 gave C = [[zoo, 0]] with no
    word (symbolic) or "Cannot convert complex to float" (values=); a complex or symbolic r0 raised
    the same bare TypeError. By hand d(1/x)/dx = -1/x^2 is infinite at x = 0."""
    from lagcodegen.statics.state_space import linearize_state

    x, force = me.dynamicsymbols("x F")
    k = sp.Symbol("k", positive=True)
    eom = derive_equations(Model("inverse_measured", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                 potential_energy=k * x ** 2 / 2, generalized_forces={x: force}, inputs=[force],
                                 measurements={"inverse": 1 / x}, parameter_values={"m": 1.0, "k": 4.0}))
    for values in ({}, None):
        with pytest.raises(ValueError, match=r"model 'inverse_measured' is undefined at x0 = \[0, 0\], r0 = \[0\]: "
                                             r"C = dh/dx\[0, 0\] = zoo"):
            linearize_state(eom, [0, 0], [0], values=values)
    with pytest.raises(ValueError, match=r"r0 entry for F must be real"):
        linearize_state(eom, [1, 0], [1j], values={})
    with pytest.raises(ValueError, match=r"r0 entry for F holds z, which is no parameter"):
        linearize_state(eom, [1, 0], [sp.Symbol("z")], values={})
    assert linearize_state(eom, [2.0, 0.0], [0.0], values={}).C[0, 0] == pytest.approx(-0.25)  # -1/x^2 at x = 2


def test_no_steady_motion_where_the_force_never_vanishes_far_from_zero():
    """Found by review of the product sizes above: sizing (x - x0)^2 as (|x| + |x0|)^2 = 4e6 accepted
    x = x0 = 1000 as a steady state of F = -k (x - x0)^2 - tau, residual 1e-4. By hand F <= -tau < 0
    everywhere: there is none."""
    from lagcodegen.statics.steady import steady_motion

    x = me.dynamicsymbols("x")
    k, x0, tau = sp.symbols("k x0 tau", positive=True)
    well = derive_equations(Model("cubic_well", [x], [m, k, x0, tau], kinetic_energy=m * x.diff() ** 2 / 2,
                                  potential_energy=k * (x - x0) ** 3 / 3, generalized_forces={x: -tau},
                                  parameter_values={"m": 1.0, "k": 1.0, "x0": 1000.0, "tau": 1e-4}))
    with pytest.raises(ValueError, match=r"steady motion of model 'cubic_well': no solution"):
        steady_motion(well, {"x": 1000.0}, unknowns=["x"], steady=["x_d"])


def test_three_close_simple_equilibria_far_from_zero_are_kept_apart():
    """Found by review of the degenerate-root merging above: V = k ((x - c)^2 - a^2)^2 / (4 a^2) with
    c = 100, a = 0.005 came back as one 'degenerate' equilibrium. By hand F = -k (x - c)((x - c)^2 - a^2)
    / a^2 has the three simple roots c - a, c, c + a (F' = -2k, k, -2k): no warning."""
    import warnings

    from lagcodegen.statics.equilibria import find_equilibria

    x = me.dynamicsymbols("x")
    k, c, a = sp.symbols("k c a", positive=True)
    well = derive_equations(Model("double_well", [x], [m, k, c, a], kinetic_energy=m * x.diff() ** 2 / 2,
                                  potential_energy=k * ((x - c) ** 2 - a ** 2) ** 2 / (4 * a ** 2),
                                  parameter_values={"m": 1.0, "k": 1.0, "c": 100.0, "a": 0.005}))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        roots = find_equilibria(well, {}, guesses=np.linspace(90.0, 110.0, 201).reshape(-1, 1))
    np.testing.assert_allclose(sorted(r[well.q[0]] for r in roots), [99.995, 100.0, 100.005], rtol=0, atol=1e-9)
