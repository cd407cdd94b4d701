"""Inputs in the model and the linearization about any operating point (issue 13, symbolic part).

Independent references:
- sympy's own ``KanesMethod.linearize(A_and_B=True)`` on ``n_link_pendulum_on_cart`` with the
  cart force and joint torques as inputs (A and B at random parameters, to 1e-10);
- central finite differences (step 1e-6) of xd = f(x, r) built from sympy's M and F with
  numpy, at steady motions with nonzero speeds, where sympy's linearizer needs the accelerations;
- hand-derived equations: m x'' + c x' + k x = F, and the conservative double pendulum whose
  frequencies do not depend on the choice of generalized speeds.
"""
from __future__ import annotations

import random

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from sympy.physics.mechanics.models import n_link_pendulum_on_cart

from lagcodegen import Model, derive_equations
from lagcodegen.codegen.reduce import KernelError, reduce_expressions
from lagcodegen.model import ModelError
from lagcodegen.statics.equilibria import find_equilibria, hold_inputs, linearize
from lagcodegen.statics.state_space import linearize_state

t = me.dynamicsymbols._t
SEED = 20261125


def cart_pendulum(n: int):
    kane = n_link_pendulum_on_cart(n=n, cart_force=True, joint_torques=True)
    inputs = sorted(me.find_dynamicsymbols(kane.forcing) - set(kane.q) - set(kane.u)
                    - set(kane.q.diff(t)), key=str)  # F(t), T1(t), ..., Tn(t)
    parameters = sorted((kane.mass_matrix.free_symbols | kane.forcing.free_symbols) - {t}, key=str)
    return kane, inputs, parameters


@pytest.mark.parametrize("n", [1, 2])
def test_a_b_match_sympy_linearize_on_the_cart_pendulum(n):
    kane, inputs, parameters = cart_pendulum(n)
    eom = derive_equations(Model(f"cart_{n}", parameters=parameters, sympy_model=kane, inputs=inputs))
    assert [r.name for r in eom.inputs] == [r.func.__name__ for r in inputs]
    rng = random.Random(SEED + n)
    values = {p: rng.uniform(0.5, 2.0) for p in parameters}
    q0 = [rng.uniform(-1, 1) for _ in kane.q]
    r0 = [rng.uniform(-1, 1) for _ in inputs]
    # sympy: at rest, with the inputs at r0 (sympy wants the accelerations when they are not zero)
    op = dict(zip(kane.q, q0)) | dict.fromkeys(kane.u, 0) | dict(zip(inputs, r0))
    M_full = kane.mass_matrix_full.xreplace(op).xreplace(values)
    ud = (kane.mass_matrix.xreplace(op).xreplace(values)).LUsolve(kane.forcing.xreplace(op).xreplace(values))
    op |= dict(zip(kane.u.diff(t), ud)) | dict(zip(kane.q.diff(t), [0] * len(kane.q)))
    A_ref, B_ref, r_order = kane.linearize(A_and_B=True, op_point=op, linear_solver="LU")
    A_ref = np.array(A_ref.xreplace(values).evalf(), dtype=float)
    B_ref = np.array(B_ref.xreplace(values).evalf(), dtype=float)
    assert M_full.shape[0] == 2 * len(kane.q)
    ours = linearize_state(eom, q0 + [0] * len(kane.u), r0, values={p.name: v for p, v in values.items()})
    column = [list(inputs).index(r) for r in r_order]  # sympy orders the inputs its own way
    np.testing.assert_allclose(ours.A, A_ref, rtol=1e-10, atol=1e-10)
    np.testing.assert_allclose(ours.B[:, column], B_ref, rtol=1e-10, atol=1e-10)


def reference_rhs(kane, inputs, values):
    q, u = list(kane.q), list(kane.u)
    x = sp.symbols(f"x0:{2 * len(q)}")
    r = sp.symbols(f"r0:{len(inputs)}")
    table = dict(zip(q + u, x)) | dict(zip(inputs, r))
    kin = kane.kindiffdict()
    qd = sp.Matrix([kin[c.diff(t)] for c in q])
    M = kane.mass_matrix.xreplace(values).xreplace(table)
    F = kane.forcing.xreplace(values).xreplace(table)
    M_f, F_f, K_f = (sp.lambdify([x, r], X, "numpy") for X in (M, F, qd.xreplace(values).xreplace(table)))

    def f(state, force):
        ud = np.linalg.solve(np.array(M_f(state, force), dtype=float), np.array(F_f(state, force), dtype=float).ravel())
        return np.concatenate([np.array(K_f(state, force), dtype=float).ravel(), ud])
    return f


def central_differences(f, x0, r0, step=1e-6):
    A = np.column_stack([(f(x0 + step * e, r0) - f(x0 - step * e, r0)) / (2 * step) for e in np.eye(len(x0))])
    B = np.column_stack([(f(x0, r0 + step * e) - f(x0, r0 - step * e)) / (2 * step) for e in np.eye(len(r0))])
    return A, B


def test_steady_motion_with_speeds_matches_finite_differences():
    """Away from rest (speeds nonzero, the pendulum swinging, accelerations nonzero) the dM/dq ud0
    terms matter: compare with central differences of sympy's own f(x, r)."""
    kane, inputs, parameters = cart_pendulum(2)
    eom = derive_equations(Model("cart_2", parameters=parameters, sympy_model=kane, inputs=inputs))
    rng = random.Random(SEED)
    values = {p: rng.uniform(0.5, 2.0) for p in parameters}
    x0 = np.array([rng.uniform(-1, 1) for _ in range(6)])
    r0 = np.array([rng.uniform(-1, 1) for _ in range(3)])
    A_fd, B_fd = central_differences(reference_rhs(kane, inputs, values), x0, r0)
    ours = linearize_state(eom, x0, r0, values={p.name: v for p, v in values.items()})
    np.testing.assert_allclose(ours.A, A_fd, rtol=1e-6, atol=1e-6)
    np.testing.assert_allclose(ours.B, B_fd, rtol=1e-6, atol=1e-6)
    assert np.max(np.abs(ours.A[3:, :3])) > 0.1  # the state is far from rest: the test sees dM/dq ud0


def test_damped_oscillator_with_a_force_input():
    x, F = me.dynamicsymbols("x F")
    m, c, k = sp.symbols("m c k", positive=True)
    model = Model("oscillator", [x], [m, c, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  generalized_forces={x: F - c * x.diff()}, inputs=[F])
    eom = derive_equations(model)
    assert eom.forcing[0] == eom.inputs[0] - c * eom.u[0] - k * eom.q[0]
    linear = linearize_state(eom, [0, 0], {"F": 0})
    assert linear.A == sp.Matrix([[0, 1], [-k / m, -c / m]]) and linear.B == sp.Matrix([[0], [1 / m]])
    numeric = linearize_state(eom, [0, 0], [0], values={"m": 2.0, "c": 0.4, "k": 8.0})
    wn, zeta = 2.0, 0.4 / (2 * np.sqrt(8.0 * 2.0))  # wn = sqrt(k/m), zeta = c / (2 sqrt(k m))
    np.testing.assert_allclose(numeric.frequencies(), [wn, wn], rtol=1e-12)
    np.testing.assert_allclose(numeric.damping_ratios(), [zeta, zeta], rtol=1e-12)
    # a constant force F0 moves the equilibrium to F0 / k
    held = hold_inputs(eom, {"F": 3.0})
    assert held.inputs == () and find_equilibria(held) == [{eom.q[0]: 3.0 / k}]


def kane_double_pendulum(relative: bool):
    """Two point masses on rigid links, speeds u1 = q1', u2 = q1' + q2' (relative angles q2) or u = q'."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    u1, u2 = me.dynamicsymbols("u1 u2")
    m, l, g = sp.symbols("m l g", positive=True)
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", (q1, N.z))
    B = A.orientnew("B", "Axis", (q2, A.z))
    O = me.Point("O")
    O.set_vel(N, 0)
    P1 = O.locatenew("P1", -l * A.y)
    P2 = P1.locatenew("P2", -l * B.y)
    if relative:
        kdes = [u1 - q1.diff(t), u2 - q1.diff(t) - q2.diff(t)]
    else:
        kdes = [u1 - q1.diff(t), u2 - q2.diff(t)]
    kin = sp.solve(kdes, [q1.diff(t), q2.diff(t)])
    A.set_ang_vel(N, kin[q1.diff(t)] * N.z)
    B.set_ang_vel(N, (kin[q1.diff(t)] + kin[q2.diff(t)]) * N.z)
    P1.v2pt_theory(O, N, A)
    P2.v2pt_theory(P1, N, B)
    bodies = [me.Particle("p1", P1, m), me.Particle("p2", P2, m)]
    loads = [(P1, -m * g * N.y), (P2, -m * g * N.y)]
    kane = me.KanesMethod(N, [q1, q2], [u1, u2], kd_eqs=kdes)
    kane.kanes_equations(bodies, loads)
    return Model("kane_double_pendulum", parameters=[m, l, g], sympy_model=kane,
                 parameter_values={"m": 1.0, "l": 1.0, "g": 9.81})


def test_kane_speeds_double_pendulum_is_conservative_in_the_old_view():
    """With u2 = q1' + q2' the rest linearization was called circulatory (K0 not symmetric).
    Taken to the coordinate rates it is the same pendulum: equal frequencies for both speed
    choices, w^2 = (2 -+ sqrt 2) g / l for equal masses and lengths (hand derivation)."""
    frequencies = []
    for relative in (False, True):
        model = linearize(derive_equations(kane_double_pendulum(relative)), [0, 0], {})
        assert np.allclose(model.K0, model.K0.T)
        frequencies.append(model.natural_frequencies())
    expected = np.sqrt([(2 - np.sqrt(2)) * 9.81, (2 + np.sqrt(2)) * 9.81])
    np.testing.assert_allclose(frequencies[0], expected, rtol=1e-12)
    np.testing.assert_allclose(frequencies[1], expected, rtol=1e-12)
    both = [linearize_state(derive_equations(kane_double_pendulum(r)), [0, 0, 0, 0], values={}) for r in (False, True)]
    np.testing.assert_allclose(both[0].frequencies(), both[1].frequencies(), rtol=1e-12)


# -- bad input ----------------------------------------------------------------------------------
def test_inputs_are_refused_where_they_cannot_go():
    x, F = me.dynamicsymbols("x F")
    m, k = sp.symbols("m k", positive=True)
    T = m * x.diff() ** 2 / 2
    with pytest.raises(ModelError, match="input 'F' appears in kinetic_energy"):
        Model("bad", [x], [m, k], kinetic_energy=(m + F) * x.diff() ** 2 / 2, inputs=[F])
    with pytest.raises(ModelError, match="input 'k' is also a parameter"):
        Model("bad", [x], [m, k], kinetic_energy=T, inputs=[k])
    with pytest.raises(ModelError, match="input 'x' is also a coordinate"):
        Model("bad", [x], [m, k], kinetic_energy=T, inputs=[x])
    with pytest.raises(ModelError, match="listed twice"):
        Model("bad", [x], [m, k], kinetic_energy=T, inputs=[F, F])
    with pytest.raises(ModelError, match="functions of time that are not coordinates: F"):
        Model("bad", [x], [m, k], kinetic_energy=T, generalized_forces={x: F})
    with pytest.raises(ModelError, match="must be a dynamicsymbol"):
        Model("bad", [x], [m, k], kinetic_energy=T, inputs=["F"])


def test_a_sympy_model_with_an_unlisted_specified_function_names_inputs():
    kane, inputs, parameters = cart_pendulum(1)
    with pytest.raises(ModelError, match=r"inputs=\["):
        derive_equations(Model("cart", parameters=parameters, sympy_model=kane))


def test_inputs_reach_the_kernels_or_fold_in_when_held():
    x, F = me.dynamicsymbols("x F")
    m, k = sp.symbols("m k", positive=True)
    eom = derive_equations(Model("driven", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                 potential_energy=k * x ** 2 / 2, generalized_forces={x: F}, inputs=[F]))
    reduced = reduce_expressions(eom, ["forcing"])
    assert reduced.inputs == (sp.Symbol("F"),)
    assert reduced.kernel("forcing").results[0][1] == sp.Symbol("F") - k * eom.q[0]
    with pytest.raises(KernelError, match="unknown output"):
        reduce_expressions(eom, ["thrust"])
    held = reduce_expressions(hold_inputs(eom, [1.5]), ["forcing"])  # a constant input folds in
    assert held.kernel("forcing").results[0][1] == 1.5 - k * eom.q[0]
    with pytest.raises(ValueError, match="inputs=\\{'F': 0.0\\}"):
        linearize(eom, [0])
    with pytest.raises(ValueError, match="'G' is not an input"):
        linearize(eom, [0], inputs={"G": 1.0})
    with pytest.raises(ValueError, match="input F must be finite"):
        linearize_state(eom, [0, 0], [float("nan")])
    with pytest.raises(ValueError, match="x0 has 3 entries"):
        linearize_state(eom, [0, 0, 0], [0])
    with pytest.raises(ValueError, match="pass r0"):
        linearize_state(eom, [0, 0])
    with pytest.raises(ValueError, match="mass matrix of model 'driven' is singular"):
        linearize_state(eom, [0, 0], [0], values={"m": 0.0, "k": 1.0})
    with pytest.raises(ValueError, match="x0 entry for x must be finite"):
        linearize_state(eom, [float("nan"), 0], [0])


def sympy_driven_models():
    """sympy.physics.mechanics.models' systems driven by specified functions of t (their inputs)."""
    from sympy.physics.mechanics.models import multi_mass_spring_damper

    cases = [(f"cart_{n}", lambda n=n: n_link_pendulum_on_cart(n=n, cart_force=True, joint_torques=True))
             for n in (1, 2, 3)]
    cases += [(f"springs_{n}", lambda n=n: multi_mass_spring_damper(n, apply_gravity=True, apply_external_forces=True))
              for n in (1, 2, 3)]
    return cases


@pytest.mark.parametrize("name, build", sympy_driven_models(), ids=lambda c: c if isinstance(c, str) else "")
def test_sympy_driven_models_match_sympy_with_their_inputs(name, build):
    """The specified forces and torques of sympy's own example systems are inputs now: M and F equal
    sympy's (its mass_matrix and forcing, renamed to plain symbols); without inputs= the message
    says how to declare them."""
    kane = build()
    inputs = sorted(me.find_dynamicsymbols(kane.forcing) - set(kane.q) - set(kane.u) - set(kane.q.diff(t)), key=str)
    assert inputs, name
    parameters = sorted((kane.mass_matrix.free_symbols | kane.forcing.free_symbols) - {t}, key=str)
    eom = derive_equations(Model(name, parameters=parameters, sympy_model=kane, inputs=inputs))
    rename = dict(zip(inputs, eom.inputs)) | dict(zip(kane.q, eom.q)) | dict(zip(kane.u, eom.u))
    kin = kane.kindiffdict()
    assert sp.simplify(kane.mass_matrix.xreplace(kin).xreplace(rename) - eom.mass_matrix) == sp.zeros(eom.n, eom.n)
    assert sp.simplify(kane.forcing.xreplace(kin).xreplace(rename) - eom.forcing) == sp.zeros(eom.n, 1)
    with pytest.raises(ModelError, match="inputs="):
        derive_equations(Model(name, parameters=parameters, sympy_model=build()))


@pytest.mark.parametrize("route", ["energies", "bodies"])
def test_governor_relative_equilibrium_in_the_first_order_form(route):
    """The governor spinning at omega about its relative equilibrium cos a0 = (P + Q) g / (P l omega^2):
    A has eigenvalues +-i w with w^2 = P omega^2 sin^2 a0 / (P + 2 Q sin^2 a0) (hand derivation,
    as in test_statics), so its damping ratios are 0."""
    from lagcodegen import catalog

    eom = derive_equations(catalog.centrifugal_governor(route))
    v = {p.name: x for p, x in eom.parameter_values.items()}
    P, Q, length, g, omega = (v[k] for k in ("P", "Q", "l", "g", "omega"))
    a0 = np.arccos((P + Q) * g / (P * length * omega ** 2))
    s2 = np.sin(a0) ** 2
    w = np.sqrt(P * omega ** 2 * s2 / (P + 2 * Q * s2))
    linear = linearize_state(eom, [a0, 0.0], values={})
    np.testing.assert_allclose(np.sort(linear.eigenvalues().imag), [-w, w], rtol=1e-10)
    np.testing.assert_allclose(linear.eigenvalues().real, 0.0, atol=1e-10)
    np.testing.assert_allclose(linear.damping_ratios(), 0.0, atol=1e-10)


def test_a_constrained_model_with_atan2_linearizes():
    # found by review: numpy's arctan2 takes no complex step (a bare TypeError). A Cartesian pendulum
    # with a torsion spring k theta^2 / 2 on theta = atan2(x, -y): m l^2 theta'' = -m g l theta - k theta
    # about hanging, so the eigenvalues are +-i sqrt(g / l + k / (m l^2)) (by hand).
    m, l, g, k = sp.symbols("m l g k", positive=True)
    x, y = me.dynamicsymbols("x y")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    bob = O.locatenew("bob", x * N.x + y * N.y)
    model = Model("cartesian_torsion", [x, y], (m, l, g, k), bodies=[me.Particle("bob", bob, m)],
                  gravity=-g * N.y, frame=N, origin=O, potential_energy=k * sp.atan2(x, -y) ** 2 / 2,
                  constraints=[x ** 2 + y ** 2 - l ** 2], parameter_values={m: 2.0, l: 1.5, g: 9.81, k: 3.0})
    eigenvalues = linearize_state(derive_equations(model), [0.0, -1.5, 0.0, 0.0], values={}).eigenvalues()
    expected = np.sqrt(9.81 / 1.5 + 3.0 / (2.0 * 1.5 ** 2))
    np.testing.assert_allclose(np.sort(eigenvalues.imag), [-expected, expected], rtol=1e-12)
    np.testing.assert_allclose(eigenvalues.real, 0.0, atol=1e-12)


def test_steady_eigenvalues_check_the_cyclic_coordinates_and_the_motion():
    # found by review: a non-cyclic coordinate named cyclic, or a state that is not steady, gave
    # eigenvalues without a word; the symbolic linearization at a singular M raised sympy's bare error
    from lagcodegen.statics.steady import SteadyMotion, steady_eigenvalues, steady_motion

    theta, phi = me.dynamicsymbols("theta phi")
    m, g, l = sp.symbols("m g l", positive=True)
    eom = derive_equations(Model("steady_pendulum", [theta], [m, g, l], kinetic_energy=m * l ** 2 * theta.diff() ** 2 / 2,
                                 potential_energy=-m * g * l * sp.cos(theta),
                                 parameter_values={"m": 1.0, "g": 9.81, "l": 1.0}))
    hanging = steady_motion(eom, {"theta": 0.1}, ["theta"], ["theta_d"])
    np.testing.assert_allclose(np.sort(steady_eigenvalues(eom, hanging, [], ["theta_d"]).imag),
                               [-np.sqrt(9.81), np.sqrt(9.81)], rtol=1e-10)  # +-i sqrt(g / l), by hand
    with pytest.raises(ValueError, match="theta is not cyclic in model 'steady_pendulum'"):
        steady_eigenvalues(eom, hanging, ["theta"], ["theta_d"])
    tilted = SteadyMotion(hanging.names, np.array([1.2, 0.0]), 0.0, np.zeros(1))
    with pytest.raises(ValueError, match=r"no steady motion.*d/dt theta_d = -9\.1433"):  # -g/l sin 1.2
        steady_eigenvalues(eom, tilted, [], ["theta_d"])
    spherical = derive_equations(Model("spherical", [theta, phi], [m, g, l],
                                       kinetic_energy=m * l ** 2 * (theta.diff() ** 2
                                                                    + sp.sin(theta) ** 2 * phi.diff() ** 2) / 2,
                                       potential_energy=-m * g * l * sp.cos(theta)))
    with pytest.raises(ValueError, match="mass matrix of model 'spherical' is singular at x0"):
        linearize_state(spherical, [0, 0, 0, 0])


def _spring_from_a_moving_anchor():
    """A mass on a spring whose anchor sits at the input r: V = k (x - r)^2 / 2, a measurement of
    the stretch x - r (the input in V and in a measurement, not only in F)."""
    x, r = me.dynamicsymbols("x r")
    m, k, c = sp.symbols("m k c", positive=True)
    return Model("moving_anchor", [x], [m, k, c], kinetic_energy=m * x.diff()**2 / 2,
                 potential_energy=k * (x - r)**2 / 2, generalized_forces={x: -c * x.diff()}, inputs=[r],
                 measurements={"stretch": x - r}, parameter_values={"m": 1.0, "k": 4.0, "c": 0.5})


def test_hold_inputs_reaches_the_energy_and_the_measurements():
    """Found by review: hold_inputs replaced the inputs in M and F only. With r held at 0.5 the
    energy kernel failed to compile ("symbol r has no C name") and linearize_state's C kept the
    symbol r. By hand: V = k (x - 1/2)^2 / 2, stretch = x - 1/2, so at x = 0.5, u = 0 the energy is
    0, C = [1, 0], D is empty, and A = [[0, 1], [-k/m, -c/m]] = [[0, 1], [-4, -0.5]]."""
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    held = hold_inputs(derive_equations(_spring_from_a_moving_anchor()), {"r": 0.5})
    assert held.inputs == ()
    for expr in [held.potential_energy, *(e for _, e in held.measurements), *held.forcing]:
        assert not any(s.name == "r" for s in sp.sympify(expr).free_symbols), expr
    system = compile_model(held, methods=("rk4",), outputs=("rhs", "energy", "measurements"))
    run = simulate(system, [0.5, 0.0], t_end=0.1, h=0.01, energy=True)
    np.testing.assert_allclose(run.x[-1], [0.5, 0.0], atol=1e-15)  # at rest at the anchor
    np.testing.assert_allclose(run.energy, 0.0, atol=1e-15)
    np.testing.assert_allclose(run.measurements[:, 0], 0.0, atol=1e-15)
    lin = linearize_state(held, [0.5, 0.0], values={})
    np.testing.assert_allclose(np.asarray(lin.A, float), [[0, 1], [-4, -0.5]], atol=1e-12)
    np.testing.assert_allclose(np.asarray(lin.C, float), [[1, 0]], atol=1e-12)


def test_steady_motion_of_a_driven_model_asks_for_its_inputs():
    """Found by review: steady_motion on a model with inputs failed with sympy's bare "Cannot
    convert expression to float". Now it names the inputs (as find_equilibria does), and with
    inputs= holds them: a mass on a turntable spinning at w = 2 with a spring k (x - L) has, by
    hand, k (x - L) = m x w^2, so x = k L / (k - m w^2) = 10 / 6 for m = 1, k = 10, L = 1; a
    constant torque tau = 0 keeps the spin steady."""
    from lagcodegen.statics.steady import steady_motion

    x, phi, tau = me.dynamicsymbols("x phi tau")
    m, k, L = sp.symbols("m k L", positive=True)
    eom = derive_equations(Model("turntable", [x, phi], [m, k, L],
                                 kinetic_energy=m * (x.diff()**2 + x**2 * phi.diff()**2) / 2,
                                 potential_energy=k * (x - L)**2 / 2, generalized_forces={phi: tau}, inputs=[tau],
                                 parameter_values={"m": 1.0, "k": 10.0, "L": 1.0}))
    given = {"x": 1.0, eom.u[1].name: 2.0}
    with pytest.raises(ValueError, match="model 'turntable' has inputs tau: pass their values"):
        steady_motion(eom, given, ["x"], [eom.u[0].name])
    motion = steady_motion(eom, given, ["x"], [eom.u[0].name], inputs={"tau": 0.0})
    assert motion.values["x"] == pytest.approx(10 / 6, rel=1e-12)


def test_a_linearization_that_overflows_is_named():
    """Found by review: with g = 1e308 the double pendulum's A held -inf and was returned (the
    command line printed it), then the eigenvalues failed with numpy's "Array must not contain infs
    or NaNs", naming nothing. By hand A[2, 0] = -(m1 + m2) g / (m1 l1) at rest overflows."""
    from lagcodegen import catalog

    eom = derive_equations(catalog.example("double_pendulum"))
    with pytest.raises(ValueError, match=r"the linearization of model 'double_pendulum' is not finite: A\[2, 0\] = "
                                         r"-inf .*g = 1e\+308"):
        linearize_state(eom, [0.0, 0.0, 0.0, 0.0], values={"g": 1e308})


def test_a_sign_term_is_smooth_away_from_its_switch():
    """Found by review: the bar on rollers (rolling friction ~ sign(x')) was refused at x' = 0.5,
    where sign is locally constant and A exists. By hand its F is gravity plus a constant friction
    there, so A = [[0, 1], [0, 0]]; at x' = 0 the switch itself is still refused."""
    from lagcodegen import catalog

    eom = derive_equations(catalog.example("bar_on_rollers"))
    np.testing.assert_array_equal(np.asarray(linearize_state(eom, [0.0, 0.5], values={}).A, float), [[0, 1], [0, 0]])
    with pytest.raises(ValueError, match="not differentiable"):
        linearize_state(eom, [0.0, 0.0], values={})
