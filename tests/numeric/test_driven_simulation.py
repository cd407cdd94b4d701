"""Driven models in C: inputs r held over a step (ZOH) or on a ramp (FOH), from a constant, an array
per step or per stride, a table interpolated in C, or a Python callable of (t, x) (issue 13).

Independent references, all written here without the code under test:
- the damped oscillator m x'' + c x' + k x = F from rest under a constant F: the textbook step
  response x(t) = F/k (1 - e^(-zeta w t) (cos w_d t + zeta / sqrt(1 - zeta^2) sin w_d t));
- scipy's DOP853 at rtol = atol = 1e-12 on a numpy right-hand side of the same equation, with
  the input signal from ``numpy.interp``, integrated knot to knot;
- a numpy RK4 loop with the input held at r_k over step k (the discrete map the ZOH C step must
  equal to rounding);
- the Jacobian df/dr by hand: (0, 1/m).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

from lagcodegen import Model
from lagcodegen.pipeline import compile_model
from lagcodegen.run.inputs import InputError
from lagcodegen.run.simulate import jacobian, simulate, solve_reference
from lagcodegen.run.sweep import sweep
from lagcodegen.status import Status

M, K, C = 1.0, 4.0, 0.5


@pytest.fixture(scope="module")
def oscillator(tmp_path_factory, driven_oscillator):
    return compile_model(driven_oscillator(), methods=("rk4", "euler", "radau_iia3", "symplectic_euler"),
                         cache_dir=tmp_path_factory.mktemp("driven"))


def step_response(t, force):
    """m x'' + c x' + k x = force from rest (underdamped)."""
    w = np.sqrt(K / M)
    zeta = C / (2 * np.sqrt(K * M))
    wd = w * np.sqrt(1 - zeta ** 2)
    decay = np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * t))
    return force / K * (1 - decay)


def numpy_rhs(signal):
    def f(t, y):
        return np.array([y[1], (signal(t, y) - C * y[1] - K * y[0]) / M])
    return f


def dop853(signal, t_eval, breaks=()):
    """DOP853 at 1e-12 from rest, restarted at every knot of the signal."""
    edges = [t_eval[0], *[b for b in breaks if t_eval[0] < b < t_eval[-1]], t_eval[-1]]
    y, out = np.zeros(2), []
    for a, b in zip(edges[:-1], edges[1:]):
        inside = t_eval[(t_eval >= a) & (t_eval < b)]
        solution = solve_ivp(numpy_rhs(signal), (a, b), y, method="DOP853", rtol=1e-12, atol=1e-12,
                             t_eval=np.union1d(inside, [b]))
        out.append(solution.y.T[np.isin(solution.t, inside)])
        y = solution.y[:, -1]
    out.append(y[None, :])
    return np.concatenate(out)


@pytest.mark.parametrize("method, tolerance", [("rk4", 1e-10), ("radau_iia3", 1e-7), ("symplectic_euler", 5e-4)])
def test_a_constant_input_gives_the_textbook_step_response(oscillator, method, tolerance):
    run = simulate(oscillator, {"x": 0.0}, t_end=3.0, h=1e-3, method=method, inputs=2.0)
    assert run.ok
    np.testing.assert_allclose(run["x"], step_response(run.t, 2.0), atol=tolerance)
    assert np.all(run.inputs == 2.0) and run["F"].shape == run.t.shape


def test_a_table_on_a_first_order_hold_matches_dop853_at_fourth_order(oscillator):
    knots = np.linspace(0.0, 2.0, 11)
    values = np.sin(3 * knots) + knots ** 2 / 4
    signal = lambda t, y: np.interp(t, knots, values)  # noqa: E731
    errors = []
    for h in (1e-2, 5e-3):
        run = simulate(oscillator, {"x": 0.0}, t_end=2.0, h=h, inputs=(knots, values), hold="foh")
        reference = dop853(signal, run.t, knots)
        errors.append(np.abs(run.x - reference).max())
        np.testing.assert_allclose(run["F"], np.interp(run.t, knots, values), rtol=0, atol=1e-14)
    assert errors[1] < 1e-9
    assert 12 < errors[0] / errors[1] < 20  # 2^4: the knots lie on the steps, so RK4 keeps its order
    # the same table held over each step is a first-order method in h
    zoh = [np.abs(simulate(oscillator, {"x": 0.0}, t_end=2.0, h=h, inputs=(knots, values)).x
                  - dop853(signal, np.linspace(0, 2, int(round(2 / h)) + 1), knots)).max() for h in (1e-2, 5e-3)]
    assert 1.8 < zoh[0] / zoh[1] < 2.2


def test_solve_reference_reads_the_same_signal(oscillator):
    knots = np.linspace(0.0, 1.0, 6)
    values = np.cos(2 * knots)
    t_eval = np.linspace(0, 1, 101)
    _, ours = solve_reference(oscillator, {"x": 0.0}, t_eval, inputs=(knots, values))
    np.testing.assert_allclose(ours, dop853(lambda t, y: np.interp(t, knots, values), t_eval, knots)[:, :],
                               atol=1e-10)


def rk4_loop(stage_input, h, n_steps):
    """Numpy RK4 from rest whose stage at the fraction c of step k takes the input stage_input(k, c)."""
    y, out = np.zeros(2), [np.zeros(2)]
    for k in range(n_steps):
        f = numpy_rhs(lambda c, y, k=k: stage_input(k, c))
        k1 = f(0, y)
        k2 = f(0.5, y + h / 2 * k1)
        k3 = f(0.5, y + h / 2 * k2)
        k4 = f(1, y + h * k3)
        y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        out.append(y)
    return np.array(out)


def rk4_held(r_steps, h, n_steps):
    """r_k held over step k: the discrete plant x+ = step(x, r)."""
    return rk4_loop(lambda k, c: r_steps[k], h, n_steps)


def test_an_array_per_step_is_held_over_each_step(oscillator):
    h, n = 0.01, 200
    r = np.sin(0.7 * np.arange(n)) + 0.3
    run = simulate(oscillator, {"x": 0.0}, t_end=n * h, h=h, inputs=r)
    np.testing.assert_allclose(run.x, rk4_held(r, h, n), rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(run["F"][:-1], r)
    # n + 1 rows: the last only recorded; a 2-D (n, 1) array is the same
    again = simulate(oscillator, {"x": 0.0}, t_end=n * h, h=h, inputs=np.append(r, 9.0).reshape(-1, 1))
    np.testing.assert_array_equal(again.x, run.x)
    assert again["F"][-1] == 9.0


def test_an_array_per_stride_is_held_over_the_stride(oscillator):
    h, n, stride = 0.01, 200, 10
    r = np.cos(np.arange(n // stride))
    run = simulate(oscillator, {"x": 0.0}, t_end=n * h, h=h, stride=stride, inputs=r)
    np.testing.assert_allclose(run.x, rk4_held(np.repeat(r, stride), h, n)[::stride], rtol=1e-12, atol=1e-13)


def test_the_exported_step_takes_r(oscillator):
    """x+ = step(x, r, p): the embedded engineer's plant, called directly through cffi."""
    ffi, lib, prefix = oscillator.ffi, oscillator.lib, oscillator.layout.prefix
    t = ffi.new("double *", 0.0)
    x = ffi.new("double[]", [0.0, 0.0])
    r = ffi.new("double[]", [1.5])
    p = ffi.new("double[]", [M, K, C])
    work = ffi.new("double[]", int(getattr(lib, f"{prefix.upper()}_WORK_RK4")))
    for _ in range(100):
        assert getattr(lib, f"{prefix}_step_rk4")(t, x, r, p, 0.01, work) == Status.OK
    np.testing.assert_allclose([x[0], x[1]], rk4_held([1.5] * 100, 0.01, 100)[-1], rtol=1e-13)
    assert t[0] == pytest.approx(1.0)
    # first-order hold from r0 to r1 over one step equals the driver's foh on a two-knot table
    x2 = ffi.new("double[]", [0.0, 0.0])
    t[0] = 0.0
    getattr(lib, f"{prefix}_step_rk4_foh")(t, x2, ffi.new("double[]", [0.0]), ffi.new("double[]", [2.0]), p, 0.5,
                                           work)
    run = simulate(oscillator, {"x": 0.0}, t_end=0.5, h=0.5, inputs=([0.0, 0.5], [0.0, 2.0]), hold="foh",
                   check_stability=False)
    np.testing.assert_array_equal([x2[0], x2[1]], run.x[-1])


def test_a_nan_input_to_the_exported_steps_is_named_as_an_input(oscillator):
    """Found by review: a NaN r (a bad sensor value in a firmware loop) passed to the step functions
    came back as LCG_NONFINITE_STATE, "the run diverged". Now every exported step says
    LCG_NONFINITE_INPUT and leaves t and x as they were."""
    ffi, lib, prefix = oscillator.ffi, oscillator.lib, oscillator.layout.prefix
    p = ffi.new("double[]", [M, K, C])
    work = ffi.new("double[]", int(getattr(lib, f"{prefix.upper()}_WORK_SIZE")))
    good, bad = ffi.new("double[]", [1.0]), ffi.new("double[]", [math.nan])
    methods = {name: i for i, name in enumerate(oscillator.layout.methods)}
    calls = [lambda t, x, name=name: getattr(lib, f"{prefix}_step_{name}")(t, x, bad, p, 0.01, work)
             for name in methods]
    calls += [lambda t, x: getattr(lib, f"{prefix}_step_rk4_foh")(t, x, good, bad, p, 0.01, work),
              lambda t, x: getattr(lib, f"{prefix}_step_rk4_foh")(t, x, bad, good, p, 0.01, work),
              lambda t, x: getattr(lib, f"{prefix}_step_monitored")(methods["rk4"], t[0], x, bad, ffi.NULL, p, 0.01,
                                                                        work, 1, 0),
              lambda t, x: getattr(lib, f"{prefix}_step_monitored")(methods["rk4"], t[0], x, good, bad, p, 0.01,
                                                                        work, 1, 0)]
    for call in calls:
        t, x = ffi.new("double *", 0.25), ffi.new("double[]", [0.5, -0.5])
        assert call(t, x) == Status.NONFINITE_INPUT
        assert t[0] == 0.25 and [x[0], x[1]] == [0.5, -0.5]


def test_the_stability_check_covers_a_callable_without_calling_it(oscillator):
    """Found by review: with inputs from a callable the stability pre-check was skipped. The
    oscillator's frequencies are -c/2m +- i sqrt(k/m - (c/2m)^2) (|lambda| = 2): h = 2 puts h|lambda|
    = 4 beyond RK4's interval (2.83), so the check must warn; the callable is not called by it (a
    controller with state would advance), so it sees the same calls with the check off."""
    from lagcodegen.run.simulate import StabilityWarning

    calls = []

    def controller(t, x):
        calls.append(t)
        return [0.0]

    with pytest.warns(StabilityWarning, match="outside rk4's stability region"):
        simulate(oscillator, {"x": 1.0}, t_end=20.0, h=2.0, inputs=controller)
    checked, calls[:] = list(calls), []
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        simulate(oscillator, {"x": 1.0}, t_end=20.0, h=2.0, inputs=controller, check_stability=False)
    assert checked == calls


def test_symplectic_euler_refuses_a_first_order_hold(oscillator):
    """Found by review: symplectic_euler reads the inputs once per step, and hold='foh' ran bit for
    bit as 'zoh' without a word."""
    table = ([0.0, 1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="hold='foh' does not apply to symplectic_euler"):
        simulate(oscillator, {"x": 1.0}, t_end=1.0, h=0.01, method="symplectic_euler", inputs=table, hold="foh")
    with pytest.raises(ValueError, match="hold='foh' does not apply to symplectic_euler"):
        sweep(oscillator, {"k": [K]}, x0={"x": 1.0}, t_end=1.0, h=0.01, method="symplectic_euler", inputs=table,
              hold="foh")


def test_a_feedback_callable_closes_the_loop(oscillator):
    """F = -3 x - 1.5 x' makes m x'' + (c + 1.5) x' + (k + 3) x = 0: against DOP853 on that system."""
    gain = lambda t, state: [-3.0 * state[0] - 1.5 * state[1]]  # noqa: E731
    run = simulate(oscillator, {"x": 1.0}, t_end=2.0, h=1e-3, inputs=gain)
    solution = solve_ivp(lambda t, y: [y[1], (-(K + 3) * y[0] - (C + 1.5) * y[1]) / M], (0, 2), [1.0, 0.0],
                         method="DOP853", rtol=1e-12, atol=1e-12, t_eval=run.t)
    # ZOH of a feedback law: first order in h (h = 1e-3)
    np.testing.assert_allclose(run.x, solution.y.T, atol=3e-3)
    # each sample records the F its state gave, the last one the F held over the last step (one call per step)
    np.testing.assert_allclose(run["F"][:-1], -3.0 * run["x"][:-1] - 1.5 * run.x[:-1, 1], atol=1e-14)
    assert run["F"][-1] == run["F"][-2]


def test_inputs_by_name_merge_tables_and_constants(tmp_path):
    x, F, G = me.dynamicsymbols("x F G")
    m = sp.symbols("m", positive=True)
    model = Model("two_inputs", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2, generalized_forces={x: F + 2 * G},
                  inputs=[F, G], parameter_values={"m": 1.0})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    knots = np.array([0.0, 0.5, 1.0])
    run = simulate(system, {"x": 0.0}, t_end=1.0, h=0.01, inputs={"F": (knots, [0.0, 1.0, 0.0]), "G": 0.25},
                   hold="foh")
    np.testing.assert_allclose(run["G"], 0.25)
    np.testing.assert_allclose(run["F"], np.interp(run.t, knots, [0.0, 1.0, 0.0]), atol=1e-15)
    # x'' = F + 2 G from rest, by hand: x(1) = integral_0^1 (1 - s) (F(s) + 2 G) ds
    # = 2 G / 2 + (the triangle's area 1/2 times 1 - its centroid 1/2) = 0.25 + 0.25; RK4 on a
    # forcing linear between knots that lie on the steps is exact (x is a cubic there)
    assert run["x"][-1] == pytest.approx(0.5, abs=1e-12)


def rk4_ramped(r_at, h, n_steps):
    """The stages of step k on the line from r_at(t_k) to r_at(t_k + h) (a first-order hold)."""
    return rk4_loop(lambda k, c: r_at(k * h) + (r_at((k + 1) * h) - r_at(k * h)) * c, h, n_steps)


def test_an_array_per_stride_on_a_first_order_hold_is_the_line_between_rows(oscillator):
    # found by review: the rows were held for stride - 1 steps and ramped within the last step only
    h, n, stride = 0.01, 200, 10
    r = np.cos(np.arange(n // stride + 1))
    run = simulate(oscillator, {"x": 0.0}, t_end=n * h, h=h, stride=stride, inputs=r, hold="foh")
    line = lambda t: np.interp(t, np.arange(r.size) * stride * h, r)  # noqa: E731
    np.testing.assert_allclose(run.x, rk4_ramped(line, h, n)[::stride], rtol=1e-12, atol=1e-13)
    np.testing.assert_array_equal(run["F"], r)


def test_a_float_kernel_reads_row_k_at_step_k(tmp_path, driven_oscillator):
    # found by review: float step times t0 + (float)k h fell below the sample times the rows were
    # keyed to (computed in double), and a third of the steps read the row before
    system = compile_model(driven_oscillator("driven_oscillator_rows_f32"), methods=("rk4",), precision="float",
                           cache_dir=tmp_path)
    h, n = 0.01, 300
    r = np.arange(n, dtype=float)
    for stride in (1, 10):
        rows = r[::stride]
        run = simulate(system, {"x": 0.0}, t_end=n * h, h=h, stride=stride, inputs=rows, check_stability=False)
        np.testing.assert_array_equal(run["F"][:-1], rows)
    run = simulate(system, {"x": 0.0}, t_end=n * h, h=h, inputs=r, check_stability=False)
    exact = rk4_held(r, h, n)
    assert np.abs(run.x - exact).max() < 1e-5 * np.abs(exact).max()  # float rounding, not a late row
    swept = sweep(system, {"k": [K]}, x0={"x": 0.0}, t_end=n * h, h=h, inputs=r)
    assert np.abs(swept.x_final[0] - exact[-1]).max() < 1e-5 * np.abs(exact).max()


def test_a_float_kernel_refuses_times_it_cannot_resolve(tmp_path, driven_oscillator):
    """Found by review: past t/h of about 2^22 float cannot tell t0 + k h from its neighbours, and
    rows per step were read a row off with status OK (94 of 201 at t0 = 1e4, h = 1e-3). Float's
    spacing is 2^-11 (4.9e-4, above h/4) from t = 4096 and 2^-12 (2.4e-4) just below it, where the
    rows still come out exactly (the reference: the rows themselves). A model without inputs is
    only warned (its recorded times are that coarse); a double kernel is not."""
    from lagcodegen.run.arguments import FloatTimeWarning

    system = compile_model(driven_oscillator("driven_oscillator_late_f32"), methods=("rk4",), precision="float",
                           cache_dir=tmp_path)
    h, n = 1e-3, 200
    rows = np.arange(n + 1) % 7 * 1.0
    t0 = 4096 - (n + 1) * h
    with warnings.catch_warnings():
        warnings.simplefilter("error", FloatTimeWarning)
        run = simulate(system, {"x": 0.0}, t0=t0, t_end=t0 + n * h, h=h, inputs=rows, check_stability=False)
    np.testing.assert_array_equal(run["F"], rows)
    for start in (4096.0, 1e4):
        with pytest.raises(ValueError, match=r"spacing near t = .* more than h/4 = 0.00025: the inputs F would "
                                             r"be read at the wrong steps"):
            simulate(system, {"x": 0.0}, t0=start, t_end=start + n * h, h=h, inputs=rows)
        with pytest.raises(ValueError, match="the inputs F would be read at the wrong steps"):
            sweep(system, {"k": [K]}, x0={"x": 0.0}, t0=start, t_end=start + n * h, h=h, inputs=rows)
    x = me.dynamicsymbols("x")
    free = Model("free_oscillator_late", [x], [], kinetic_energy=x.diff()**2 / 2, potential_energy=2 * x**2)
    for precision, warned in (("float", True), ("double", False)):
        plain = compile_model(free, methods=("rk4",), precision=precision, cache_dir=tmp_path)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            simulate(plain, {"x": 1.0}, t0=1e4, t_end=1e4 + n * h, h=h, check_stability=False)
        assert any(issubclass(w.category, FloatTimeWarning) for w in caught) == warned


def test_a_double_kernel_refuses_times_it_cannot_resolve(tmp_path, driven_oscillator):
    """Found by review: the same in double, farther out. At t0 = 2^40 double's spacing is 2^-12
    (2.4e-4), above h/4 for h = 2^-14, and 767 of 1024 rows per step were read at the wrong rows,
    status OK. At t0 = 2^30 the spacing, 2^-22, is far below h/4, and every row is read as given
    (the reference: the rows themselves); an undriven model far out is warned, not refused."""
    from lagcodegen.run.arguments import FloatTimeWarning

    system = compile_model(driven_oscillator("driven_oscillator_late"), methods=("rk4",), cache_dir=tmp_path)
    h, n = 2.0 ** -14, 1024
    rows = np.arange(n + 1, dtype=float)
    with warnings.catch_warnings():
        warnings.simplefilter("error", FloatTimeWarning)
        run = simulate(system, {"x": 0.0}, t0=2.0 ** 30, t_end=2.0 ** 30 + n * h, h=h, inputs=rows,
                       check_stability=False)
    np.testing.assert_array_equal(run["F"], rows)
    with pytest.raises(ValueError, match=r"a double kernel .* spacing near t = .* more than h/4 .* the inputs F "
                                         r"would be read at the wrong steps"):
        simulate(system, {"x": 0.0}, t0=2.0 ** 40, t_end=2.0 ** 40 + n * h, h=h, inputs=rows)
    x = me.dynamicsymbols("x")
    free = compile_model(Model("free_oscillator_far", [x], [], kinetic_energy=x.diff()**2 / 2,
                               potential_energy=2 * x**2), methods=("rk4",), cache_dir=tmp_path)
    with pytest.warns(FloatTimeWarning, match="a double kernel"):
        simulate(free, {"x": 1.0}, t0=2.0 ** 40, t_end=2.0 ** 40 + n * h, h=h, check_stability=False)


def zero_order_hold_exact(r, h: float) -> np.ndarray:
    """The oscillator from rest under r_k held over step k, exactly: the zero-order-hold map
    x+ = e^(A h) x + A^-1 (e^(A h) - I) B r_k; shape (len(r) + 1, 2)."""
    from scipy.linalg import expm
    A, B = np.array([[0.0, 1.0], [-K / M, -C / M]]), np.array([0.0, 1.0 / M])
    Phi = expm(A * h)
    Gamma = np.linalg.solve(A, (Phi - np.eye(2)) @ B)
    exact = [np.zeros(2)]
    for value in r:
        exact.append(Phi @ exact[-1] + Gamma * value)
    return np.array(exact)


def test_solve_reference_takes_an_array_as_the_step_function_it_is(oscillator):
    # found by review: the array's repeated knot times made empty segments (a TypeError). The exact
    # zero-order-hold map is the reference.
    h, n = 0.05, 40
    r = np.sin(np.arange(n))
    t, ours = solve_reference(oscillator, {"x": 0.0}, np.arange(n + 1) * h, inputs=r)
    np.testing.assert_allclose(ours, zero_order_hold_exact(r, h), rtol=0, atol=1e-11)


def test_solve_reference_keeps_the_rows_on_the_run_s_steps(oscillator):
    """Found by review: solve_reference took the step of an input array from t_eval's spacing, so
    t_eval = run.t[1:] (or strided) moved the rows in time and the reference was 7.5e-3 off, without
    an error. Now such a t_eval needs h=; with it every t_eval gives the exact zero-order-hold map
    x+ = e^(A h) x + A^-1 (e^(A h) - I) B r_k."""
    h, n = 0.05, 40
    r = np.where(np.arange(n) * h < 0.5, 0.0, 5.0)
    exact = zero_order_hold_exact(r, h)
    grid = np.arange(n + 1) * h
    with pytest.raises(ValueError, match="an array of inputs per step needs the run's step: pass h="):
        solve_reference(oscillator, {"x": 0.0}, grid[1:], inputs=r)
    for t_eval in (grid[1:], grid[::4], grid[-1:]):
        t, ours = solve_reference(oscillator, {"x": 0.0}, t_eval, inputs=r, h=h)
        np.testing.assert_allclose(ours, exact[np.searchsorted(grid, t_eval)], rtol=0, atol=1e-11)


def test_the_jacobian_gives_df_dr(oscillator):
    J, B = jacobian(oscillator, [0.1, -0.2], [M, K, C], r=[0.3], with_inputs=True)
    np.testing.assert_allclose(J, [[0, 1], [-K / M, -C / M]], atol=1e-15)
    np.testing.assert_allclose(B, [[0.0], [1.0 / M]], atol=1e-15)


def test_float_kernels_with_inputs(tmp_path, driven_oscillator):
    system = compile_model(driven_oscillator("driven_oscillator_f32"), methods=("rk4",), precision="float",
                           cache_dir=tmp_path)
    run = simulate(system, {"x": 0.0}, t_end=2.0, h=1e-2, inputs=2.0)
    assert run.ok and run.x.dtype == np.float32
    np.testing.assert_allclose(run["x"], step_response(run.t.astype(float), 2.0), atol=1e-5)


# -- bad input: each names the input; a failure mid-run keeps the trajectory so far ------------------
@pytest.mark.parametrize("inputs, match", [
    (None, "driven by the input"),
    (([0.0, 1.0, 0.5, 2.0], [0, 1, 2, 3]), r"must increase, but t\[2\] = 0.5 follows t\[1\] = 1"),
    (([0.0, 0.5], [0.0, 1.0]), "shorter than the run"),
    (([0.0, 1.0, 2.0], [[0.0, 1.0]] * 3), r"values of shape \(3, 1\)"),
    (([0.0, 2.0], [0.0, np.nan]), r"input 'F' is not finite at t = 2"),
    (np.ones(7), "7 rows does not match the run"),
    ({"G": 1.0}, "unknown input"),
    ({}, "no value for input"),
    (float("inf"), "input 'F' is not finite"),
    ((np.array([]), np.array([])), "the table has no knots"),
])
def test_bad_inputs_are_named(oscillator, inputs, match):
    with pytest.raises(InputError, match=match):
        simulate(oscillator, {"x": 0.0}, t_end=2.0, h=0.01, inputs=inputs)


def test_bad_input_types_and_holds(oscillator):
    with pytest.raises(TypeError, match="real numbers"):
        simulate(oscillator, {"x": 0.0}, t_end=1.0, h=0.01, inputs="0.5")
    with pytest.raises(TypeError, match="None is not a number"):
        simulate(oscillator, {"x": 0.0}, t_end=1.0, h=0.01, inputs=[None])
    with pytest.raises(ValueError, match="hold must be one of"):
        simulate(oscillator, {"x": 0.0}, t_end=1.0, h=0.01, inputs=0.5, hold="cubic")
    with pytest.raises(ValueError, match="hold='foh'.*callable"):
        simulate(oscillator, {"x": 0.0}, t_end=1.0, h=0.01, inputs=lambda t, x: [0.0], hold="foh")


def test_an_undriven_model_refuses_inputs(tmp_path):
    x = me.dynamicsymbols("x")
    model = Model("free_mass", [x], [], kinetic_energy=x.diff() ** 2 / 2, potential_energy=x ** 2 / 2)
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    with pytest.raises(InputError, match="has no inputs"):
        simulate(system, {"x": 1.0}, t_end=1.0, h=0.01, inputs=1.0)


@pytest.mark.parametrize("callable_, status, detail", [
    (lambda t, x: 1 / 0 if t > 0.5 else [0.0], Status.INPUT_FAILED, "raised ZeroDivisionError"),
    (lambda t, x: [0.0, 1.0] if t > 0.5 else [0.0], Status.INPUT_FAILED, r"returned \(2,\).*expected 1 value"),
    (lambda t, x: [np.nan] if t > 0.5 else [0.0], Status.NONFINITE_INPUT, "input 'F' = nan"),
    (lambda t, x: "a" if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned"),
    (lambda t, x: None if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned 'NoneType'"),
    # found by review: a string parsed as a number, a complex lost its imaginary part (or was named a shape)
    (lambda t, x: "1.0" if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned str.*expected 1 real number"),
    (lambda t, x: [1.0 + 0.5j] if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned complex128 values"),
    # found by review: a dict or an object was reported as "returned ()", a bool ran as 1.0
    (lambda t, x: {"F": 1.0} if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned 'dict'.*expected 1 value"),
    (lambda t, x: object() if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned 'object'"),
    (lambda t, x: [True] if t > 0.5 else [0.0], Status.INPUT_FAILED, "returned bool values.*expected 1 real"),
])
def test_a_failing_callable_stops_with_a_status_and_keeps_the_run(oscillator, callable_, status, detail):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = simulate(oscillator, {"x": 1.0}, t_end=1.0, h=0.01, inputs=callable_)
    assert run.status == status
    assert len(run.t) == 52 and run.t[-1] == pytest.approx(0.51)  # every sample up to the failing read
    assert np.isnan(run.inputs[-1]).all() and np.all(run.inputs[:-1] == 0.0)
    assert np.all(np.isfinite(run.x))
    import re
    assert re.search(detail, run.message) and any(re.search(detail, str(w.message)) for w in caught)


@pytest.mark.parametrize("interrupt", [KeyboardInterrupt, SystemExit])
def test_ctrl_c_in_a_feedback_callable_stops_the_run_and_is_raised(oscillator, interrupt):
    # found by review: cffi printed the exception and took the callback's result as 0 (OK), so the run
    # went on with the last input to its end with status OK, and Ctrl-C could not stop it
    calls = []

    def controller(t, x):
        calls.append(t)
        if t >= 0.5:
            raise interrupt
        return [-3.0 * x[0]]

    with pytest.raises(interrupt):
        simulate(oscillator, {"x": 1.0}, t_end=1.0, h=0.01, inputs=controller)
    assert len(calls) == 51 and calls[-1] == pytest.approx(0.5)  # stopped at the first raise


# -- measurements y = h(q, u, r, t) and sweeps over input amplitudes ------------------------------
@pytest.fixture(scope="module")
def measured(tmp_path_factory, driven_oscillator):
    model = driven_oscillator("driven_measured", measurements={"spring_force": lambda x, F, m, k, c: -k * x,
                                                                "input_power": lambda x, F, m, k, c: F * x.diff()})
    return compile_model(model, methods=("rk4",), cache_dir=tmp_path_factory.mktemp("measured"))


def test_measurements_are_recorded_by_name(measured):
    knots = np.linspace(0, 2, 5)
    run = simulate(measured, {"x": 0.1}, t_end=2.0, h=1e-3, inputs=(knots, np.cos(knots)))
    assert run.measurement_names == ("spring_force", "input_power")
    np.testing.assert_allclose(run["spring_force"], -K * run["x"], rtol=1e-15)  # the definitions, by hand
    np.testing.assert_allclose(run["input_power"], run["F"] * run.x[:, 1], rtol=1e-15)


def test_a_sweep_over_input_amplitude_scales_the_base_signal(measured):
    knots = np.array([0.0, 1.0, 2.0])
    shape = np.array([0.0, 1.0, 1.0])
    result = sweep(measured, {"F": [0.5, 2.0], "k": [1.0, 4.0]}, x0={"x": 0.0}, t_end=2.0, h=1e-3,
                   inputs=(knots, shape), hold="foh")
    for member, (amplitude, k) in enumerate(result.values):
        # second route: one simulate per member with the scaled table
        run = simulate(measured, {"x": 0.0}, t_end=2.0, h=1e-3, inputs=(knots, amplitude * shape), hold="foh",
                       params={"k": k})
        np.testing.assert_allclose(result.x_final[member], run.x[-1], rtol=1e-13)
        np.testing.assert_allclose(result.y_final[member], run.measurements[-1], rtol=1e-13)
        np.testing.assert_allclose(result.y_min[member], run.measurements.min(axis=0), rtol=1e-13)
        np.testing.assert_allclose(result.y_max[member], run.measurements.max(axis=0), rtol=1e-13)
    # a swept input with no base signal is a constant: the textbook step response's end value
    constant = sweep(measured, {"F": [1.0, 2.0]}, x0={"x": 0.0}, t_end=3.0, h=1e-3)
    np.testing.assert_allclose(constant.x_final[:, 0], step_response(3.0, np.array([1.0, 2.0])), atol=1e-10)


def test_a_nan_sample_makes_the_sweep_summary_nan(tmp_path, driven_oscillator):
    # found by review: "if (y < low)" skipped NaN samples once a run was under way (finite y_min although
    # most samples were NaN) and kept a NaN from t0 (NaN although most were finite); an energy inf from
    # the start gave energy_error 0. Undamped from x = +-1 with F = 0, x = +-cos 2t (by hand) changes
    # sign, so sqrt(x) is NaN at some steps either way; at x = 1e160, x^2 overflows the energy.
    model = driven_oscillator("driven_root", measurements={"root": lambda x, F, m, k, c: sp.sqrt(x)})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    for start in (1.0, -1.0):
        run = simulate(system, {"x": start}, t_end=2.0, h=1e-3, inputs=0.0, params={"c": 0.0})
        assert np.isnan(run["root"]).any() and np.isfinite(run["root"]).any()
        result = sweep(system, {"k": [K]}, x0={"x": start}, t_end=2.0, h=1e-3, inputs=0.0, params={"c": 0.0})
        assert result.status[0] == Status.OK
        assert np.isnan(result.y_min[0, 0]) and np.isnan(result.y_max[0, 0])
    result = sweep(system, {"k": [K]}, x0={"x": 1e160}, t_end=0.01, h=1e-3, inputs=0.0)
    assert np.isnan(result.energy_error[0])


def test_member_inputs_give_each_member_its_own_signal(measured):
    specs = [1.0, ([0.0, 1.0, 2.0], [0.0, 1.0, 1.0])]
    result = sweep(measured, members={"k": [1.0, 4.0]}, x0={"x": 0.0}, t_end=2.0, h=1e-3, member_inputs=specs)
    for member, spec in enumerate(specs):
        run = simulate(measured, {"x": 0.0}, t_end=2.0, h=1e-3, inputs=spec, params={"k": result.values[member, 0]})
        np.testing.assert_allclose(result.x_final[member], run.x[-1], rtol=1e-13)


def test_bad_sweep_inputs_are_named(measured):
    with pytest.raises(InputError, match="driven by F"):
        sweep(measured, {"k": [1.0, 2.0]}, x0={"x": 0.0}, t_end=1.0, h=0.01)
    with pytest.raises(InputError, match="not a callable"):
        sweep(measured, {"k": [1.0, 2.0]}, x0={"x": 0.0}, t_end=1.0, h=0.01, inputs=lambda t, x: [0.0])
    with pytest.raises(InputError, match="one input spec per member"):
        sweep(measured, {"k": [1.0, 2.0]}, x0={"x": 0.0}, t_end=1.0, h=0.01, member_inputs=[1.0])
    with pytest.raises(InputError, match=r"member_inputs\[1\]: input F: the table covers"):
        sweep(measured, {"k": [1.0, 2.0]}, x0={"x": 0.0}, t_end=1.0, h=0.01,
              member_inputs=[1.0, ([0.0, 0.5], [1.0, 1.0])])
    with pytest.raises(ValueError, match=r"nor an input \(F\)"):
        sweep(measured, {"G": [1.0]}, x0={"x": 0.0}, t_end=1.0, h=0.01, inputs=1.0)


def test_the_lane_kernel_takes_inputs_held_per_member(tmp_path):
    """Constant inputs per member ride in the lane kernel as parameters: with libm's sin/cos in the
    lanes, every member equals the scalar kernel's bit for bit (the second route), and varying
    inputs fall back to the scalar kernel."""
    import dataclasses

    from lagcodegen import catalog

    base = catalog.double_pendulum()
    q1, q2 = base.coordinates
    tau1, tau2 = me.dynamicsymbols("tau1 tau2")
    model = dataclasses.replace(base, name="lane_driven_dp", generalized_forces={q1: tau1 - tau2, q2: tau2},
                                inputs=[tau1, tau2])
    system = compile_model(model, methods=("rk4",), lanes=4, lane_trig="libm", cache_dir=tmp_path)
    grid = {"tau1": np.linspace(-1, 1, 6), "m1": [0.5, 1.0, 2.0]}
    common = dict(x0={"q1": 1.0, "q2": 0.5}, t_end=2.0, h=1e-3, inputs={"tau1": 1.0, "tau2": -0.3},
                  track_energy=False)
    lanes = sweep(system, grid, kernel="lanes", **common)
    scalar = sweep(system, grid, kernel="scalar", **common)
    assert lanes.kernel == "lanes" and scalar.kernel == "scalar"
    np.testing.assert_array_equal(lanes.x_final, scalar.x_final)
    np.testing.assert_array_equal(lanes.status, scalar.status)
    with pytest.raises(ValueError, match="inputs that vary in time run on the scalar kernel"):
        sweep(system, grid, kernel="lanes", **(common | {"inputs": {"tau1": ([0, 2], [0, 1]), "tau2": 0.0}}))


def test_an_input_in_the_potential_energy_compiles_without_the_energy_output(tmp_path):
    # found by review: the energy kernel E(t, x, p) read r (a C compiler error); E(q, u, r) conserves
    # nothing to track, so the output is left out and named when asked for. V = k x^2 / 2 - F x from
    # rest: x = F / k (1 - cos 2t) with k = 4, m = 1 (by hand).
    from lagcodegen.codegen.outputs import KernelError

    x, F = me.dynamicsymbols("x F")
    m, k = sp.symbols("m k", positive=True)
    model = Model("potential_input", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=k * x ** 2 / 2 - F * x, inputs=[F], parameter_values={"m": 1.0, "k": 4.0})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    assert not any(name.endswith("_energy") for name in system.layout.functions)
    run = simulate(system, {"x": 0.0}, t_end=2.0, h=1e-3, inputs=2.0)
    np.testing.assert_allclose(run["x"], 2.0 / 4.0 * (1 - np.cos(2 * run.t)), atol=1e-11)
    with pytest.raises(KernelError, match=r"energy of model 'potential_input' holds the input\(s\) F"):
        compile_model(model, methods=("rk4",), outputs=("rhs", "energy"), cache_dir=tmp_path)


def test_a_swept_input_that_inputs_does_not_name_has_base_one(tmp_path):
    """Found by review: sweeping F with inputs={"G": 0.5} raised "no value for input(s) F", though a
    swept input's base is documented as constant 1 where inputs= gives none. Second route: one
    simulate per member with F at the swept value."""
    x, F, G = me.dynamicsymbols("x F G")
    m, k = sp.symbols("m k", positive=True)
    model = Model("two_forces", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  generalized_forces={x: F + 2 * G}, inputs=[F, G], parameter_values={m: 1.0, k: 4.0})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    result = sweep(system, {"F": [1.0, 3.0]}, x0={"x": 0.0}, t_end=1.0, h=1e-3, inputs={"G": 0.5}, progress=False)
    for member, force in enumerate((1.0, 3.0)):
        run = simulate(system, {"x": 0.0}, t_end=1.0, h=1e-3, inputs={"F": force, "G": 0.5})
        np.testing.assert_allclose(result.x_final[member], run.x[-1], rtol=1e-14)


class _TensorLike:
    """A result numpy cannot read: as a torch tensor that requires grad, its __array__ raises."""

    def __array__(self, *args, **kwargs):
        raise RuntimeError("Can't call numpy() on Tensor that requires grad")


@pytest.mark.parametrize("result, error", [([10 ** 400], "OverflowError"), (_TensorLike(), "RuntimeError")])
def test_a_callable_result_numpy_cannot_read_stops_the_run(oscillator, result, error):
    """Found by review (session 16): the conversion raised past the callback into cffi, which
    returned 0 (OK): the run went on with F unwritten (6.9e-310, stack memory), status OK. Expected:
    INPUT_FAILED at the first step, the exception named, as for a callable that raises itself."""
    with pytest.warns(RuntimeWarning, match="stopped at step 1"):
        run = simulate(oscillator, {"x": 1.0}, t_end=1.0, h=1e-2, inputs=lambda t, state: result)
    assert run.status == Status.INPUT_FAILED and error in run.detail, run.detail


def test_an_input_beyond_the_float_range_is_named(tmp_path, driven_oscillator):
    """Found by review (session 16): 1e39 (finite in double, beyond float's 3.4e38) stopped a float
    run at step 1 with no word of the input, numpy warning of an overflow in a cast; and the measurement
    reading F was then called undefined, though the input had failed, not its expression."""
    system = compile_model(driven_oscillator("driven_float_range", measurements={"power": lambda x, F, m, k, c: F * x}),
                           methods=("rk4",), precision="float", cache_dir=tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("error", RuntimeWarning)  # no "overflow encountered in cast"
        for inputs in (1e39, np.full(101, 1e39), {"F": 1e39}):
            with pytest.raises(InputError, match=r"input 'F' = 1e\+39 is beyond the range of the float kernel"):
                simulate(system, {"x": 0.5}, t_end=1.0, h=1e-2, inputs=inputs)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = simulate(system, {"x": 0.5}, t_end=1.0, h=1e-2, inputs=lambda t, state: [1e39])
    assert run.status == Status.NONFINITE_INPUT
    assert run.detail == "input 'F' = 1e+39 at t = 0 is beyond the range of the float kernel"
    assert not [w for w in caught if "undefined" in str(w.message) or "overflow" in str(w.message)], \
        [str(w.message) for w in caught]


def test_a_feedback_callable_is_called_once_per_step(oscillator):
    """Found by review (session 16): n_steps + 1 calls (one more at t_end, for the last sample), so a
    stateful controller advanced once more per run (one run of 200 steps and two of 100 differed by
    1.2e-3), and a reference of one value per step (indexed by round(t / h)) failed a completed run.
    Expected by counting: one call per step, at its start; the last sample holds the last step's F."""
    calls = []

    def controller(t, state):
        calls.append(t)
        return [-3.0 * state[0] - 1.5 * state[1]]

    whole = simulate(oscillator, {"x": 1.0}, t_end=2.0, h=1e-2, inputs=controller)
    assert whole.ok and len(calls) == 200 and calls[-1] == pytest.approx(1.99)
    assert whole["F"][-1] == -3.0 * whole.x[-2, 0] - 1.5 * whole.x[-2, 1]  # held over the last step
    calls.clear()
    first = simulate(oscillator, {"x": 1.0}, t_end=1.0, h=1e-2, inputs=controller)
    second = simulate(oscillator, first.x[-1], t0=1.0, t_end=2.0, h=1e-2, inputs=controller)
    assert len(calls) == 200
    np.testing.assert_array_equal(second.x[-1], whole.x[-1])
    reference = np.linspace(0.0, 1.0, 100)  # one value per step
    run = simulate(oscillator, {"x": 0.0}, t_end=1.0, h=1e-2, inputs=lambda t, state: [reference[round(t / 1e-2)]])
    assert run.ok, run.message


def test_an_input_given_as_a_parameter_or_state_is_named_as_an_input(oscillator):
    """Found by review (session 16): "unknown parameter 'F'" and "unknown state variable(s) ['F']"
    for the model's own input."""
    with pytest.raises(ValueError, match=r"'F' is an input of model 'driven_oscillator', not a parameter: pass it "
                                         r"in inputs="):
        simulate(oscillator, {"x": 1.0}, t_end=0.1, h=1e-2, params={"F": 1.0}, inputs=0.0)
    with pytest.raises(ValueError, match=r"'F': input\(s\) of model 'driven_oscillator', not in the state"):
        simulate(oscillator, {"x": 1.0, "F": 1.0}, t_end=0.1, h=1e-2, inputs=0.0)


@pytest.mark.parametrize("result", [[0.3], (0.3,), np.array([0.3]), [np.float64(0.3)], 0.3, np.array(0.3)])
def test_every_accepted_form_of_a_callable_result_drives_as_the_constant_does(oscillator, result):
    """A controller's result as a list, tuple, array or numpy scalar (the common forms take a short path
    since review found the full checks at 21 us per step): the run equals the constant input's to the
    last bit (the same value into the same C stepping loop)."""
    constant = simulate(oscillator, {"x": 1.0}, t_end=0.2, h=0.01, inputs=0.3)
    run = simulate(oscillator, {"x": 1.0}, t_end=0.2, h=0.01, inputs=lambda t, x: result)
    assert run.ok and np.array_equal(run.x, constant.x) and np.array_equal(run.inputs, constant.inputs)


@pytest.fixture(scope="module")
def two_inputs(tmp_path_factory):
    """m x'' + k x = F + G: two inputs, so that a bool can stand beside a number."""
    x, F, G = me.dynamicsymbols("x F G")
    m, k = sp.symbols("m k", positive=True)
    model = Model("two_inputs", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  generalized_forces={x: F + G}, inputs=[F, G], parameter_values={m: 1.0, k: 4.0})
    return compile_model(model, methods=("rk4",), cache_dir=tmp_path_factory.mktemp("two_inputs"))


@pytest.mark.parametrize("result", [[True, 0.0], (0.5, np.bool_(False)), [1, True]])
def test_a_bool_among_a_controllers_numbers_is_refused(two_inputs, result):
    """A bool is refused as an input value (as a constant input's is); numpy reads [True, 0.0] as a float
    array, and it ran as 1.0 (found 2026-11-27, trying the short path for plain results)."""
    system = two_inputs
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = simulate(system, {"x": 1.0}, t_end=0.01, h=1e-3, inputs=lambda t, x: result)
    assert run.status == Status.INPUT_FAILED and "returned bool values" in run.message, run.message


@pytest.mark.parametrize("inputs", [[True, 0.0], (np.array([0.0, 1.0]), [[True, 0.0], [0.0, 0.0]]),
                                    [[0.0, np.bool_(True)]] * 11])
def test_a_bool_among_an_input_signals_numbers_is_refused(two_inputs, inputs):
    """A constant, a table and rows per step: numpy reads [True, 0.0] as floats, and it ran as 1.0
    (found 2026-11-27); a bool alone was refused already."""
    system = two_inputs
    with pytest.raises(TypeError, match=r"input F, G: values must be real numbers, got .* \(a bool is not a number\)"):
        simulate(system, {"x": 1.0}, t_end=0.01, h=1e-3, inputs=inputs)
