"""Step Jacobians dx+/dx and dx+/dr of the explicit methods (issue 13, item 5).

Independent references:
- for the linear oscillator x' = A x + B r the exact discrete maps: explicit Euler
  x+ = (I + hA) x + hB r, RK4 x+ = P(hA) x + h Q(hA) B r with P the degree-4 Taylor polynomial of
  exp and Q(z) = 1 + z/2 + z^2/6 + z^3/24 (Hairer-Norsett-Wanner I, sec. II.1);
- central finite differences of the compiled step itself on the nonlinear cart-pole;
- the continuous A, B as h -> 0: (Fx - I)/h -> A and Fr/h -> B, with A and B derived by hand
  from the cart-pole's Lagrangian (the upright linearization in examples/cart_pole_lqr.py).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.codegen.outputs import KernelError
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import jacobian, simulate, step_jacobians
from lagcodegen.statics.state_space import linearize_state
from lagcodegen.symbolic.derive import derive_equations

M, K, C = 1.0, 4.0, 0.5


@pytest.fixture(scope="module")
def oscillator(tmp_path_factory, driven_oscillator):
    return compile_model(driven_oscillator("jac_oscillator"), methods=("rk4", "euler", "dopri5"),
                         outputs=("rhs", "jacobian", "step_jacobian"), cache_dir=tmp_path_factory.mktemp("jac"))


@pytest.fixture(scope="module")
def cart_pole(tmp_path_factory, cart_pole_example):
    example = cart_pole_example
    plant = compile_model(example.cart_pole(), methods=("rk4", "dopri5"), outputs=("rhs", "step_jacobian"),
                          cache_dir=tmp_path_factory.mktemp("cart_pole"))
    p = [example.PARAMETERS[name] for name in plant.layout.parameters]
    return example, plant, p


def test_linear_maps_are_exact(oscillator):
    A = np.array([[0.0, 1.0], [-K / M, -C / M]])
    B = np.array([[0.0], [1.0 / M]])
    x0, r0, h = [0.3, -0.1], [0.7], 0.1
    z = h * A
    eye = np.eye(2)
    P = eye + z + z @ z / 2 + z @ z @ z / 6 + z @ z @ z @ z / 24
    Q = h * (eye + z / 2 + z @ z / 6 + z @ z @ z / 24) @ B
    x1, Fx, Fr = step_jacobians(oscillator, x0, [M, K, C], h, "rk4", r=r0)
    np.testing.assert_allclose(Fx, P, atol=1e-15)
    np.testing.assert_allclose(Fr, Q, atol=1e-15)
    np.testing.assert_allclose(x1, P @ x0 + Q[:, 0] * r0[0], atol=1e-15)
    x1, Fx, Fr = step_jacobians(oscillator, x0, [M, K, C], h, "euler", r=r0)
    np.testing.assert_allclose(Fx, eye + z, atol=1e-15)
    np.testing.assert_allclose(Fr, h * B, atol=1e-15)
    # the step it takes is the compiled simulate's step
    run = simulate(oscillator, x0, t_end=h, h=h, method="rk4", inputs=r0, check_stability=False)
    np.testing.assert_array_equal(step_jacobians(oscillator, x0, [M, K, C], h, "rk4", r=r0)[0], run.x[-1])


@pytest.mark.parametrize("method", ["rk4", "dopri5"])
def test_nonlinear_step_jacobians_match_finite_differences(cart_pole, method):
    _, plant, p = cart_pole
    x0, r0, h = np.array([0.1, 0.7, -0.4, 1.3]), np.array([2.5]), 0.02
    _, Fx, Fr = step_jacobians(plant, x0, p, h, method, r=r0)
    step = lambda x, r: step_jacobians(plant, x, p, h, method, r=r)[0]  # noqa: E731
    eps = 1e-6
    fd_x = np.column_stack([(step(x0 + eps * e, r0) - step(x0 - eps * e, r0)) / (2 * eps) for e in np.eye(4)])
    fd_r = ((step(x0, r0 + eps) - step(x0, r0 - eps)) / (2 * eps))[:, None]
    np.testing.assert_allclose(Fx, fd_x, rtol=1e-7, atol=1e-8)
    np.testing.assert_allclose(Fr, fd_r, rtol=1e-7, atol=1e-9)


def test_step_jacobians_tend_to_the_continuous_a_and_b(cart_pole):
    example, plant, p = cart_pole
    mc, mp, length, g = (example.PARAMETERS[k] for k in ("m_cart", "m_pole", "l", "g"))
    # by hand from L = T - V at upright: (mc + mp) x'' + mp l th'' = F, x'' + l th'' = g th
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2, 1], A[3, 1] = -mp * g / mc, (mc + mp) * g / (mc * length)
    B = np.array([[0.0], [0.0], [1 / mc], [-1 / (mc * length)]])
    symbolic = linearize_state(derive_equations(example.cart_pole()), [0, 0, 0, 0], [0], values=example.PARAMETERS)
    np.testing.assert_allclose(symbolic.A, A, atol=1e-12)
    np.testing.assert_allclose(symbolic.B, B, atol=1e-12)
    errors = []
    for h in (1e-2, 1e-3):
        _, Fx, Fr = step_jacobians(plant, [0, 0, 0, 0], p, h, "rk4", r=[0.0])
        errors.append(max(np.abs((Fx - np.eye(4)) / h - A).max(), np.abs(Fr / h - B).max()))
    assert errors[1] < 2e-2 and 8 < errors[0] / errors[1] < 12  # first order in h: (Fx - I)/h = A + hA^2/2 + ...


def test_float_step_jacobians(tmp_path, cart_pole_example):
    example = cart_pole_example
    plant = compile_model(example.cart_pole(), methods=("rk4",), outputs=("rhs", "step_jacobian"), precision="float",
                          cache_dir=tmp_path)
    p = [example.PARAMETERS[name] for name in plant.layout.parameters]
    _, Fx, Fr = step_jacobians(plant, [0.1, 0.2, 0.0, 0.0], p, 0.01, r=[1.0])
    assert Fx.dtype == np.float32
    double = compile_model(example.cart_pole(), methods=("rk4",), outputs=("rhs", "step_jacobian"), cache_dir=tmp_path)
    _, Fx64, Fr64 = step_jacobians(double, [0.1, 0.2, 0.0, 0.0], p, 0.01, r=[1.0])
    np.testing.assert_allclose(Fx, Fx64, atol=1e-5)
    np.testing.assert_allclose(Fr, Fr64, atol=1e-6)


def test_step_jacobians_are_refused_where_they_do_not_exist(oscillator):
    from lagcodegen import catalog

    with pytest.raises(KernelError, match="step_jacobian.*constrained model 'four_bar'"):
        compile_model(catalog.four_bar(), methods=("rk4",), outputs=("rhs", "step_jacobian"))
    with pytest.raises(ValueError, match="is driven by F: pass r="):
        step_jacobians(oscillator, [0.0, 0.0], [M, K, C], 0.1)
    with pytest.raises(ValueError, match="r 'F' must be finite, got nan"):
        step_jacobians(oscillator, [0.0, 0.0], [M, K, C], 0.1, r=[np.nan])


@pytest.mark.parametrize("call, match", [
    # found by review: p, and jacobian's x and r, went to C unchecked (reads past their ends)
    (lambda s: step_jacobians(s, [0.5, 0.0], [M], 0.01, r=[0.0]), r"p needs 3 value\(s\) \(m, k, c\), got 1"),
    (lambda s: step_jacobians(s, [0.5, 0.0], [M, K, C, 9.0], 0.01, r=[0.0]), "p needs 3 value.*got 4"),
    (lambda s: step_jacobians(s, [0.5, 0.0], [M, np.nan, C], 0.01, r=[0.0]), "p 'k' must be finite"),
    (lambda s: jacobian(s, [0.5], [M, K, C], r=[0.0]), r"x needs 2 value\(s\) \(x, x_d\), got 1"),
    (lambda s: jacobian(s, [0.5, 0.0], [M, K], r=[0.0]), "p needs 3 value"),
    (lambda s: jacobian(s, [0.5, 0.0], [M, K, C], r=[]), r"r needs 1 value\(s\) \(F\), got 0"),
    (lambda s: jacobian(s, [0.5, 0.0], [M, K, C], r=[np.nan]), "r 'F' must be finite"),
    (lambda s: jacobian(s, [0.5, 0.0], [M, K, C]), "is driven by F: pass r="),
    (lambda s: jacobian(s, [[0.5, 0.0]], [M, K, C], r=[0.0]), "x must be a sequence of 2"),
    # float64 arrays, which take a short path when well formed (review: the checks per entry took 29 us)
    (lambda s: jacobian(s, np.array([0.5, np.nan]), np.array([M, K, C]), r=np.array([0.0])), "x 'x_d' must be finite"),
    (lambda s: jacobian(s, np.array([0.5, 0.0]), np.array([M, K, np.inf]), r=np.array([0.0])), "p 'c' must be finite"),
    (lambda s: jacobian(s, np.array([0.5]), np.array([M, K, C]), r=np.array([0.0])), "x needs 2 value"),
    (lambda s: jacobian(s, np.array([0.5, 0.0]), np.array([M, K, C]), r=np.array([-np.inf])), "r 'F' must be finite"),
    (lambda s: step_jacobians(s, np.array([[0.5, 0.0]]), np.array([M, K, C]), 0.01, r=np.array([0.0])),
     r"needs 2 values \(x, x_d\), got 2 in shape \(1, 2\)"),
])
def test_the_low_level_calls_check_x_p_and_r(oscillator, call, match):
    with pytest.raises(ValueError, match=match):
        call(oscillator)


def test_the_low_level_calls_take_parameters_by_name(oscillator):
    J = jacobian(oscillator, [0.5, 0.0], {"m": M, "k": K, "c": C}, r=[0.0])
    np.testing.assert_allclose(J, [[0, 1], [-K / M, -C / M]], atol=1e-15)  # the oscillator by hand


def test_c_and_d_of_the_measurements(cart_pole_example):
    """y = (pole tip x, pole tip y) = (x + l sin th, l cos th): C by hand at any state; D = 0;
    a measurement that reads the force directly has D = its coefficient."""
    example = cart_pole_example
    eom = derive_equations(example.cart_pole())
    th = 0.3
    linear = linearize_state(eom, [0.2, th, 0.5, -1.0], [1.5], values=example.PARAMETERS)
    length = example.PARAMETERS["l"]
    assert linear.measurements == ("pole_tip_x", "pole_tip_y")
    np.testing.assert_allclose(linear.C, [[1, length * np.cos(th), 0, 0], [0, -length * np.sin(th), 0, 0]], atol=1e-14)
    np.testing.assert_allclose(linear.D, np.zeros((2, 1)), atol=0)
    x, F = me.dynamicsymbols("x F")
    m, c = sp.symbols("m c", positive=True)
    model = Model("sensed", [x], [m, c], kinetic_energy=m * x.diff() ** 2 / 2, generalized_forces={x: F - c * x.diff()},
                  inputs=[F], measurements={"net_force": F - c * x.diff()})
    exact = linearize_state(derive_equations(model), [0, 0], [0])
    assert exact.C == sp.Matrix([[0, -c]]) and exact.D == sp.Matrix([[1]])


def test_a_step_jacobian_checks_what_the_step_checks(cart_pole):
    """Found by review: step_jacobian_rk4 returned OK with a NaN new state (the cart position, which
    no force reads, NaN) and with a NaN time, where step_rk4 returns NONFINITE_STATE and
    BAD_ARGUMENT for the same call. Now both agree, and a failed step leaves t and x as they were."""
    from lagcodegen.status import Status

    _, plant, p = cart_pole
    ffi, lib, prefix = plant.ffi, plant.lib, plant.layout.prefix
    n = plant.layout.n_state
    work = ffi.new("double[]", int(getattr(lib, f"{prefix.upper()}_WORK_JACOBIAN_RK4")))
    Fx, Fr = ffi.new("double[]", n * n), ffi.new("double[]", n * len(plant.layout.inputs))
    r, params = ffi.new("double[]", [0.0]), ffi.new("double[]", p)

    def both(state, time, h):
        codes, states = [], []
        for step in ("step_jacobian_rk4", "step_rk4"):
            t, x = ffi.new("double *", time), ffi.new("double[]", state)
            args = (t, x, r, params, h, Fx, Fr, work) if step.startswith("step_jacobian") else \
                (t, x, r, params, h, work)
            codes.append(getattr(lib, f"{prefix}_{step}")(*args))
            states.append(([x[i] for i in range(n)], t[0]))
        return codes, states

    names = plant.layout.coordinates + plant.layout.speeds
    nan_cart = [np.nan if name == names[0] else 0.1 for name in names]
    codes, states = both(nan_cart, 0.0, 0.01)
    assert codes == [Status.NONFINITE_STATE] * 2
    for x, t in states:
        assert t == 0.0 and np.isnan(x[0]) and x[1:] == nan_cart[1:]  # left as it was
    codes, _ = both([0.0, 0.1, 0.0, 0.0], np.nan, 0.01)
    assert codes == [Status.BAD_ARGUMENT] * 2
    codes, _ = both([0.0, 0.1, 0.0, 0.0], 0.0, np.inf)
    assert codes == [Status.BAD_ARGUMENT] * 2
    big = [1.7e308 if name == names[0] else 0.0 for name in names]
    big[len(plant.layout.coordinates)] = 1e308  # the cart's speed: x + h v overflows
    codes, _ = both(big, 0.0, 1.0)
    assert codes == [Status.NONFINITE_STATE] * 2


def test_a_step_jacobian_without_an_explicit_method_is_refused(driven_oscillator):
    """Found by review: emitted with only implicit methods, or none, the step_jacobian output was
    silently left out."""
    from lagcodegen.codegen.csyntax import EmitError
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources

    system = reduce_expressions(derive_equations(driven_oscillator("jac_refused")), ("rhs", "jacobian", "step_jacobian"))
    for methods in ((), ("implicit_midpoint",)):
        with pytest.raises(EmitError, match="output 'step_jacobian' is the Jacobian of an explicit step"):
            render_sources(system, "double", methods=list(methods))


def test_symplectic_euler_is_named_as_having_no_step_jacobian(tmp_path, driven_oscillator):
    """Found by review (session 16): the refusal said "compile it with ... an explicit method", and
    symplectic Euler is one: it has no step Jacobian kernel."""
    plant = compile_model(driven_oscillator("jac_symplectic"), methods=("rk4", "symplectic_euler"),
                          outputs=("rhs", "step_jacobian"), cache_dir=tmp_path)
    with pytest.raises(ValueError, match=r"no step Jacobian for 'symplectic_euler'.*symplectic_euler has none"):
        step_jacobians(plant, [0.1, 0.0], {}, 1e-2, method="symplectic_euler", r=[0.0])
