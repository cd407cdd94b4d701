"""Compiled kernels against independent routes, for every catalog example.

Routes (STYLE.md section 8, "compiled = lambdified = CSE-off kernels"):

1. sympy at 30 significant digits: M, F, K, E and the points of `derive_equations` with the
   inputs substituted exactly (``sp.Float(v, 30)`` of the very binary value the C receives),
   and ud = ``M.LUsolve(F)`` in 30-digit arithmetic. This is the truth the C is compared with.
2. ``sympy.lambdify`` (numpy) of the same CSE-off matrices, ud by ``numpy.linalg.solve``.
3. The Jacobian kernel against a central finite difference of the compiled rhs (the test
   uses finite differences; the library computes the Jacobian analytically).

Error measure everywhere: ``|got - want| / max(1, |want|)`` element by element (relative
for values above 1, absolute below), see `assert_close`.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.codegen.csyntax import EmitError
from lagcodegen.codegen.outputs import KernelError
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.model import TIME, Model

# Models with holonomic constraints solve the augmented (first-kind) system instead of M ud = F and
# have no Jacobian kernel; tests/constraints checks them against a 30-digit augmented solve.
EXAMPLES = sorted(name for name in catalog.EXAMPLES if not catalog.example(name).constraints)
N_STATES = 5
DIGITS = 30
#: double: 30-digit sympy is exact to ~1e-30, so this bounds the kernel's own rounding (a few
#: hundred operations at eps = 2.2e-16 and an LDL^T solve; observed worst 7e-15, in
#: pendulum_chain_5). float: eps = 1.2e-7, amplified by the same operations and the solve
#: (observed worst 6e-6, pendulum_chain_5 and the rheonomic governor); 1e-4 leaves a margin of
#: ~15 for other seeds, while a wrong formula shows as O(1). (A double/float mix-up, a double
#: literal or sin instead of sinf, only makes float *more* accurate: -Wdouble-promotion in
#: `test_generated_c_compiles_strict` catches that, not this tolerance.)
RTOL = {"double": 1e-12, "float": 1e-4}
PRECISIONS = ("double", "float")
NP_REAL = {"double": np.float64, "float": np.float32}
ALL_OUTPUTS = ("mass_matrix", "forcing", "accel", "rhs", "energy", "points", "jacobian")


# --- inputs and routes -------------------------------------------------------------------------

def random_inputs(eom, rng, count=N_STATES):
    """``count`` seeded (t, x, p): q in +-[0.2, 1.2] (away from singular configurations such as
    r = 0 of the elastic pendulum), u in +-[0.1, 1] (away from the sign(u) switch of the rolling
    friction, so finite differences never straddle it), t in [0, 2] (rheonomic models), and each
    default parameter scaled by a factor in [0.7, 1.3] so that p[] order matters."""
    n = eom.n
    defaults = np.array([eom.parameter_values[s] for s in eom.parameters], dtype=float)
    samples = []
    for _ in range(count):
        q = rng.choice([-1.0, 1.0], n) * rng.uniform(0.2, 1.2, n)
        u = rng.choice([-1.0, 1.0], n) * rng.uniform(0.1, 1.0, n)
        p = defaults * rng.uniform(0.7, 1.3, len(defaults))
        samples.append((float(rng.uniform(0.0, 2.0)), np.concatenate([q, u]), p))
    return samples


def rounded(t, x, p, precision):
    """The inputs as the kernel of ``precision`` sees them (float rounds every input)."""
    real = NP_REAL[precision]
    return float(real(t)), np.asarray(x, real).astype(float), np.asarray(p, real).astype(float)


def sympy_reference(eom, t, x, p) -> dict:
    """Route 1: every output evaluated by sympy at 30 digits at exactly these binary inputs."""
    n = eom.n
    values = {s: sp.Float(float(v), DIGITS) for s, v in zip(eom.q + eom.u, x)}
    values |= {s: sp.Float(float(v), DIGITS) for s, v in zip(eom.parameters, p)}
    values[eom.t] = sp.Float(float(t), DIGITS)
    ev = lambda expr: expr.xreplace(values).evalf(DIGITS)  # noqa: E731
    M = ev(eom.mass_matrix)
    F = ev(eom.forcing)
    ud = M.LUsolve(F).evalf(DIGITS)
    K = ev(eom.kinematics)
    out = {"mass_matrix": np.array(M.tolist(), dtype=float).ravel(),
           "forcing": np.array(F, dtype=float).ravel(),
           "accel": np.array(ud, dtype=float).ravel(),
           "rhs": np.concatenate([np.array(K, dtype=float).ravel(), np.array(ud, dtype=float).ravel()])}
    if eom.energy is not None:
        out["energy"] = np.array([float(ev(eom.energy))])
    if eom.points:
        out["points"] = np.concatenate([np.array(ev(pos), dtype=float).ravel() for _, pos in eom.points])
    assert all(np.all(np.isfinite(v)) for v in out.values())
    assert n * n == out["mass_matrix"].size
    return out


def lambdified(eom):
    """Route 2: numpy functions of (t, *x, *p) from the CSE-off sympy matrices."""
    args = [eom.t, *eom.q, *eom.u, *eom.parameters]
    funcs = {"mass_matrix": sp.lambdify(args, eom.mass_matrix, "numpy"),
             "forcing": sp.lambdify(args, eom.forcing, "numpy"),
             "kinematics": sp.lambdify(args, eom.kinematics, "numpy")}
    if eom.energy is not None:
        funcs["energy"] = sp.lambdify(args, eom.energy, "numpy")
    if eom.points:
        funcs["points"] = sp.lambdify(args, sp.Matrix.vstack(*[pos for _, pos in eom.points]), "numpy")

    def evaluate(t, x, p) -> dict:
        call = lambda f: np.asarray(f(t, *x, *p), dtype=float)  # noqa: E731
        M, F = call(funcs["mass_matrix"]), call(funcs["forcing"]).ravel()
        ud = np.linalg.solve(M, F)
        out = {"mass_matrix": M.ravel(), "forcing": F, "accel": ud,
               "rhs": np.concatenate([call(funcs["kinematics"]).ravel(), ud])}
        if "energy" in funcs:
            out["energy"] = call(funcs["energy"]).reshape(1)
        if "points" in funcs:
            out["points"] = call(funcs["points"]).ravel()
        return out

    return evaluate


def compiled_outputs(system, t, x, p, only=None) -> dict:
    """Call every kernel in ``system`` (or those named in ``only``) at (t, x, p); int kernels
    must return LCG_OK. Buffer sizes come from the system's own layout."""
    ffi, lib, layout = system.ffi, system.lib, system.layout
    real, n, n_points = layout.precision, layout.n, len(layout.points)
    xs = ffi.new(f"{real}[]", [float(v) for v in x])
    ps = ffi.new(f"{real}[]", [float(v) for v in p] or [0.0])
    sizes = {"mass_matrix": n * n, "forcing": n, "accel": n, "rhs": 2 * n,
             "points": 3 * n_points, "jacobian": 4 * n * n}
    out = {}
    for name, size in sizes.items():
        func = getattr(lib, f"{layout.prefix}_{name}", None)
        if func is None or (only is not None and name not in only):
            continue
        buf = ffi.new(f"{real}[]", max(size, 1))
        status = func(t, xs, ps, buf)
        if name in ("accel", "rhs", "jacobian"):
            assert status == 0, f"{layout.prefix}_{name} returned status {status}"
        out[name] = np.array(list(buf)[:size], dtype=float)
    energy = getattr(lib, f"{layout.prefix}_energy", None)
    if energy is not None and (only is None or "energy" in only):
        out["energy"] = np.array([energy(t, xs, ps)], dtype=float)
    return out


def assert_close(got: dict, want: dict, rtol: float, context: str) -> float:
    """Every key of ``want`` present in ``got`` and |got - want| / max(1, |want|) <= rtol."""
    worst = 0.0
    for key, expected in want.items():
        assert key in got, f"{context}: kernel {key} missing"
        value = got[key]
        assert value.shape == expected.shape, f"{context}: {key} shape {value.shape} != {expected.shape}"
        error = np.abs(value - expected) / np.maximum(1.0, np.abs(expected))
        worst = max(worst, float(error.max(initial=0.0)))
        assert np.all(error <= rtol), (
            f"{context}: {key} differs by {error.max():.3g} (rtol {rtol:g})\n got  {value}\n want {expected}")
    return worst


# --- 1. compiled = sympy at 30 digits ---------------------------------------------------------

@pytest.mark.compiler
@pytest.mark.parametrize("precision", PRECISIONS)
@pytest.mark.parametrize("name", EXAMPLES)
def test_compiled_equals_sympy_30_digits(name, precision, compiled_example, example_eom, rng):
    eom = example_eom(name)
    system = compiled_example(name, precision)
    for t, x, p in random_inputs(eom, rng):
        t, x, p = rounded(t, x, p, precision)  # reference at the inputs the kernel really sees
        want = sympy_reference(eom, t, x, p)
        got = compiled_outputs(system, t, x, p)
        assert_close(got, want, RTOL[precision], f"{name} ({precision}) at t={t}, x={x}, p={p}")


# --- 2. compiled = lambdified (CSE off) -----------------------------------------------------

@pytest.mark.compiler
@pytest.mark.parametrize("name", EXAMPLES)
def test_compiled_equals_lambdified(name, compiled_example, example_eom, rng):
    eom = example_eom(name)
    system = compiled_example(name, "double")
    evaluate = lambdified(eom)
    for t, x, p in random_inputs(eom, rng):
        want = evaluate(t, x, p)
        got = compiled_outputs(system, t, x, p)
        # both are double evaluations of the same maths in different orders: each is within
        # ~1e-13 of the 30-digit value (test above), so they agree to the double tolerance
        assert_close(got, want, RTOL["double"], f"{name} lambdified at t={t}, x={x}")


# --- 3. Jacobian = central finite difference of the compiled rhs ------------------------------

def finite_difference_jacobian(system, t, x, p, n):
    """Central differences of the compiled rhs, step 1e-6 * max(1, |x_c|) (truncation error
    ~h^2 ~ 1e-12, rounding ~eps |f| / h ~ 1e-10 |f|)."""
    N = 2 * n
    J = np.empty((N, N))
    for c in range(N):
        step = 1e-6 * max(1.0, abs(x[c]))
        plus, minus = x.copy(), x.copy()
        plus[c] += step
        minus[c] -= step
        f_plus = compiled_outputs(system, t, plus, p, only=("rhs",))["rhs"]
        f_minus = compiled_outputs(system, t, minus, p, only=("rhs",))["rhs"]
        J[:, c] = (f_plus - f_minus) / (plus[c] - minus[c])
    return J


@pytest.mark.compiler
@pytest.mark.parametrize("name", EXAMPLES)
def test_jacobian_equals_finite_difference(name, compiled_example, example_eom, rng):
    eom = example_eom(name)
    system = compiled_example(name, "double")
    for t, x, p in random_inputs(eom, rng):
        J = compiled_outputs(system, t, x, p, only=("jacobian",))["jacobian"]
        J = J.reshape(2 * eom.n, 2 * eom.n)
        J_fd = finite_difference_jacobian(system, t, x, p, eom.n)
        # scale: the largest entry of J (a stiff spring's K/m = 1e4 next to O(1) entries makes
        # the finite-difference rounding ~1e-10 * 1e4 in every entry of the same column)
        scale = max(1.0, float(np.abs(J_fd).max()))
        error = np.abs(J - J_fd).max() / scale
        # observed worst 7e-10 (pendulum_chain_5); 1e-6 as the finite-difference accuracy
        assert error <= 1e-6, f"{name}: Jacobian vs finite difference {error:.3g}\n{J}\n{J_fd}"


@pytest.mark.compiler
@pytest.mark.parametrize("name", EXAMPLES)
def test_float_jacobian_equals_double(name, compiled_example, example_eom, rng):
    """The float Jacobian against the double one (checked above) at float-rounded inputs."""
    eom = example_eom(name)
    single, double = compiled_example(name, "float"), compiled_example(name, "double")
    for t, x, p in random_inputs(eom, rng):
        t, x, p = rounded(t, x, p, "float")
        want = compiled_outputs(double, t, x, p, only=("jacobian",))["jacobian"]
        got = compiled_outputs(single, t, x, p, only=("jacobian",))["jacobian"]
        scale = max(1.0, float(np.abs(want).max()))
        assert np.abs(got - want).max() / scale <= RTOL["float"], name


# --- fixed parameters are folded ------------------------------------------------------------

FIXED = {"g": 9.81, "l1": 1.3}


def with_fixed(eom, p, fixed: dict) -> tuple:
    """(every parameter, ``fixed`` values in place; the free ones alone, in p[] order)."""
    names = [s.name for s in eom.parameters]
    p = p.copy()
    for name, value in fixed.items():
        p[names.index(name)] = value
    return p, [v for name, v in zip(names, p) if name not in fixed]


@pytest.mark.compiler
def test_fixed_parameters_give_the_same_numbers(compiled_example, example_eom, rng):
    eom = example_eom("double_pendulum")
    free = compiled_example("double_pendulum", "double")
    folded = compiled_example("double_pendulum", "double", fixed=FIXED)
    assert folded.layout.parameters == ("m1", "m2", "l2")
    assert dict(folded.layout.fixed) == FIXED
    for t, x, p in random_inputs(eom, rng):
        p, p_free = with_fixed(eom, p, FIXED)
        want = compiled_outputs(free, t, x, p)
        got = compiled_outputs(folded, t, x, p_free)
        # folding changes the evaluation order (9.81 * 1.3 is one constant), not the maths
        assert_close(got, want, RTOL["double"], f"fixed {FIXED} at x={x}")
        assert_close(got, sympy_reference(eom, t, x, p), RTOL["double"], "fixed vs sympy")


def test_fixed_parameters_are_folded_and_listed(example_eom):
    eom = example_eom("double_pendulum")
    system = reduce_expressions(eom, ALL_OUTPUTS, fixed=FIXED)
    assert system.ops_saved_by_fixing > 0
    assert [s.name for s in system.free_parameters] == ["m1", "m2", "l2"]
    sources = render_sources(system, "double")
    header = sources.header
    table = header.split("Fixed parameters")[1].split("*/")[0]
    assert re.search(r"^ \*\s+g = 9\.81$", table, re.M), header
    assert re.search(r"^ \*\s+l1 = 1\.3$", table, re.M), header
    params = header.split("Parameters p")[1].split("Fixed parameters")[0]
    assert re.findall(r"p\[(\d+)\] = (\S+)", params) == [("0", "m1"), ("1", "m2"), ("2", "l2")]
    # no kernel reads beyond the three free parameters
    assert max(int(i) for i in re.findall(r"\bp\[(\d+)\]", sources.source)) == 2


def _all_fixed(eom) -> dict:
    """Every parameter fixed at its default times a factor that no other value shares (none 0 or 1)."""
    return {s.name: eom.parameter_values[s] * (1.1 + 0.013 * i) for i, s in enumerate(eom.parameters)}


@pytest.mark.parametrize("name", EXAMPLES)
def test_folding_every_parameter_never_costs_operations(example_eom, name):
    """The kernels with their parameters free bound the folded ones: a number substituted before CSE
    is distributed over the sum it multiplies (2.0*(x + y) -> 2.0*x + 2.0*y), so folding there made
    pendulum_chain_5's dynamics 185 operations against 151 free, the Whipple bicycle's 1704 against
    1441. Folded after CSE, or before it where numbers combine, whichever is cheaper."""
    eom = example_eom(name)
    outputs = tuple(o for o in ALL_OUTPUTS if not (o == "energy" and eom.energy is None))
    free = reduce_expressions(eom, outputs)
    folded = reduce_expressions(eom, outputs, fixed=_all_fixed(eom))
    assert folded.free_parameters == ()
    for kernel in free.kernels:
        assert folded.kernel(kernel.name).ops_after <= kernel.ops_after, (name, kernel.name)


@pytest.mark.compiler
@pytest.mark.parametrize("name", ["pendulum_chain_5", "centrifugal_governor"])
def test_every_parameter_folded_gives_the_30_digit_numbers(compiled_example, example_eom, rng, name):
    """pendulum_chain_5 keeps its values after CSE (named constants), the governor folds them before
    (its numbers combine terms); both against sympy at 30 digits with the same values (route 1)."""
    eom = example_eom(name)
    fixed = _all_fixed(eom)
    folded = compiled_example(name, "double", fixed=fixed)
    assert folded.layout.parameters == ()
    p = np.array([fixed[s.name] for s in eom.parameters])
    for t, x, _ in random_inputs(eom, rng):
        got = compiled_outputs(folded, t, x, [])
        assert_close(got, sympy_reference(eom, t, x, p), RTOL["double"], f"{name} folded at x={x}")


@pytest.mark.compiler
def test_a_number_like_pi_folds_with_any_parameter_fixed(tmp_path):
    """Found by review of the fold: V = 2 pi^2 k x^2 with m or k fixed was refused ("its term pi**2 of
    fixed parameters only is pi**2"). By hand: M = m, F = -4 pi^2 k x, so ud = -4 pi^2 k x / m."""
    import sympy.physics.mechanics as me

    from lagcodegen.pipeline import compile_model

    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    model = Model("pi_spring", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=2 * sp.pi ** 2 * k * x ** 2, parameter_values={m: 1.0, k: 4.0})
    for fixed, free in (({"m": 2.0}, {"k": 3.5}), ({"k": 3.5}, {"m": 2.0}), ({"m": 2.0, "k": 3.5}, {})):
        system = compile_model(model, outputs=("rhs",), fixed=fixed, cache_dir=tmp_path)
        got = compiled_outputs(system, 0.0, [0.7, -0.2], [free[name] for name in system.layout.parameters])
        assert got["rhs"] == pytest.approx([-0.2, -4 * np.pi ** 2 * 3.5 * 0.7 / 2.0], rel=1e-14), fixed


@pytest.mark.compiler
def test_a_piecewise_model_folds_its_fixed_parameters(tmp_path):
    """Found in the last read of the fold: a Piecewise spring with any parameter fixed failed with
    "'BooleanTrue' object has no attribute 'evalf'" (its condition True taken for a number). By hand,
    V = k x^2 / 2 (x > 0), c k x^2 (else): ud = -k x / m, or -2 c k x / m; and a condition on a fixed
    parameter (k > 1) is decided at build time."""
    import sympy.physics.mechanics as me

    from lagcodegen.pipeline import compile_model

    x = me.dynamicsymbols("x")
    m, k, c = sp.symbols("m k c", positive=True)
    for condition in (x > 0, k > 1):
        spring = sp.Piecewise((k * x ** 2 / 2, condition), (c * k * x ** 2, True))
        model = Model("piecewise_spring", [x], [m, k, c], kinetic_energy=m * x.diff() ** 2 / 2,
                      potential_energy=spring, parameter_values={m: 1.0, k: 2.0, c: 3.0})
        for fixed in ({"k": 2.5}, {"m": 2.0, "k": 0.5, "c": 3.0}, {"c": 1.0}):
            values = {"m": 1.5, "k": 2.0, "c": 3.0} | fixed
            system = compile_model(model, outputs=("rhs",), fixed=fixed, cache_dir=tmp_path)
            free = [values[name] for name in system.layout.parameters]
            for position in (0.4, -0.4):
                steep = position > 0 if condition == (x > 0) else values["k"] > 1
                factor = 1.0 if steep else 2 * values["c"]
                got = compiled_outputs(system, 0.0, [position, 0.0], free)["rhs"]
                assert got == pytest.approx([0.0, -factor * values["k"] * position / values["m"]], rel=1e-14), fixed


@pytest.mark.compiler
def test_a_parameter_fixed_at_one_inside_a_sine_folds(compiled_example, example_eom, rng):
    """Found by review of the fold: rolling_wheels with beta = 1.0 (fixed exactly to 1 before CSE) and
    g fixed was refused ("its term sin(1) ..."). Against sympy at 30 digits with the same values."""
    eom = example_eom("rolling_wheels")
    fixed = {"beta": 1.0, "g": 9.81}
    system = compiled_example("rolling_wheels", "double", fixed=fixed)
    for t, x, p in random_inputs(eom, rng):
        p, free = with_fixed(eom, p, fixed)
        assert_close(compiled_outputs(system, t, x, free), sympy_reference(eom, t, x, p), RTOL["double"],
                     f"rolling_wheels {fixed} at x={x}")


@pytest.mark.parametrize("precision, fixed, message", [
    ("float", {"l1": 1e-150}, r"cannot print l1: literal .* is too small for float: it would be 0"),
    ("double", {"m2": 1e-200, "l2": 1e-200}, r"literal .*E-401 is too small for double: it would be 0"),
    ("double", {"m2": 1e200, "l2": 1e200}, r"literal .*E\+399 is out of range for double"),
])
def test_a_folded_literal_beyond_the_c_type_is_named(example_eom, precision, fixed, message):
    """Found by review: such literals reached the C text (1.0e-150F, 9.99e-401), where gcc warns
    "floating constant truncated to zero" and the value is lost; float overflow was refused already."""
    system = reduce_expressions(example_eom("double_pendulum"), ("rhs",), fixed=fixed)
    with pytest.raises(EmitError, match=message):
        render_sources(system, precision)


def test_a_fixed_value_that_makes_an_entry_complex_is_named():
    """Found by review of the fold: V = k x^2 sqrt(L - 2) with L fixed below 2 reached the C printer
    ("the imaginary unit I is not supported"), naming only F[0]."""
    import sympy.physics.mechanics as me

    x = me.dynamicsymbols("x")
    m, k, length = sp.symbols("m k L", positive=True)
    model = Model("sqrt_spring", [x], [m, k, length], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=k * x ** 2 * sp.sqrt(length - 2), parameter_values={m: 1.0, k: 1.0, length: 3.0})
    eom = derive_equations(model)
    for value in (1.5, 1.0):  # folded after CSE, and (1.0) before it
        with pytest.raises(KernelError, match=rf"with L = {value} folded in, F\[0\] is not real"):
            reduce_expressions(eom, ("rhs",), fixed={"L": value})


# --- only the requested outputs ---------------------------------------------------------------

def test_only_requested_outputs_are_generated(example_eom):
    eom = example_eom("double_pendulum")
    sources = render_sources(reduce_expressions(eom, ("rhs",)), "double")
    for text in (sources.source, sources.header, sources.cdef):
        assert "lcg_double_pendulum_rhs" in text
        for absent in ("_mass_matrix", "_forcing", "_energy", "_points", "_jacobian", "_accel("):
            assert absent not in text, f"{absent} generated although only rhs was requested"
    assert sources.layout.functions == ("lcg_double_pendulum_rhs",)


@pytest.mark.compiler
def test_only_requested_outputs_are_compiled(compiled_example, example_eom, rng):
    eom = example_eom("double_pendulum")
    system = compiled_example("double_pendulum", "double", outputs=("rhs",))
    exported = {name for name in dir(system.lib) if name.startswith("lcg_")}
    assert exported == {"lcg_double_pendulum_rhs"}
    t, x, p = random_inputs(eom, rng, 1)[0]
    want = sympy_reference(eom, t, x, p)["rhs"]
    assert_close(compiled_outputs(system, t, x, p), {"rhs": want}, RTOL["double"], "rhs only")


# --- a singular mass matrix returns a status, not NaN ----------------------------------------

def singular_particle() -> Model:
    """T = m q^2 qd^2 / 2, V = k q^2 / 2: M = m q^2 vanishes at q = 0.
    Lagrange: m q^2 qdd + m q qd^2 + k q = 0, so qdd = -qd^2 / q - k / (m q) for q != 0."""
    q = sp.Function("q")(TIME)
    m, k = sp.symbols("m k", positive=True)
    return Model("singular_particle", [q], (m, k), kinetic_energy=m * q ** 2 * q.diff() ** 2 / 2,
                 potential_energy=k * q ** 2 / 2, parameter_values={m: 2.0, k: 3.0})


@pytest.mark.compiler
@pytest.mark.parametrize("precision", PRECISIONS)
def test_singular_mass_matrix_returns_status(precision, kernel_cache_dir):
    from lagcodegen.pipeline import compile_model

    system = compile_model(singular_particle(), outputs=("accel", "rhs", "jacobian"), methods=(),
                           precision=precision)
    ffi, lib, real = system.ffi, system.lib, precision
    prefix = system.layout.prefix
    p = ffi.new(f"{real}[]", [2.0, 3.0])
    out = ffi.new(f"{real}[]", 4)
    singular = ffi.new(f"{real}[]", [0.0, 0.5])
    for func in ("accel", "rhs", "jacobian"):
        status = getattr(lib, f"{prefix}_{func}")(0.0, singular, p, out)
        assert status == 1, f"{func} at q = 0 returned {status}, want LCG_SINGULAR_MASS_MATRIX (1)"
    # away from q = 0 the same kernel works: hand-derived qdd = -qd^2/q - k/(m q)
    q, qd, m, k = 0.7, 0.5, 2.0, 3.0
    regular = ffi.new(f"{real}[]", [q, qd])
    assert getattr(lib, f"{prefix}_rhs")(0.0, regular, p, out) == 0
    want = np.array([qd, -qd ** 2 / q - k / (m * q)])
    assert np.allclose(list(out)[:2], want, rtol=RTOL[precision], atol=RTOL[precision])


# --- committed C in generated/: self-contained, no state, strict-warning clean ----------------

GENERATED = Path(__file__).resolve().parents[2] / "generated"
GENERATED_C = sorted(GENERATED.glob("*/lcg_*.c"))
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]


def strip_comments(code: str) -> str:
    """C text without /* */ and // comments (string literals kept)."""
    pattern = re.compile(r'"(?:\\.|[^"\\])*"|/\*.*?\*/|//[^\n]*', re.S)
    return pattern.sub(lambda m: m.group(0) if m.group(0).startswith('"') else " ", code)


def file_scope_statements(code: str) -> list:
    """Top-level statements/definitions heads of comment-free C (text at brace depth 0)."""
    heads, depth, current = [], 0, []
    for ch in code:
        if ch == "{":
            if depth == 0:
                heads.append("".join(current).strip())
                current = []
            depth += 1
        elif ch == "}":
            depth -= 1
        elif depth == 0:
            if ch == ";":
                heads.append("".join(current).strip())
                current = []
            else:
                current.append(ch)
    return [" ".join(h.split()) for h in heads if h.strip()]


def test_generated_files_are_found():
    assert {p.parent.name for p in GENERATED_C} >= set(catalog.EXAMPLES)


@pytest.mark.parametrize("source", GENERATED_C, ids=[p.name for p in GENERATED_C])
def test_generated_c_is_self_contained(source):
    header = source.with_suffix(".h")
    code = strip_comments(source.read_text())
    header_code = strip_comments(header.read_text())
    for text in (code, header_code):
        assert "malloc" not in text and "free(" not in text and "Python.h" not in text
    includes = re.findall(r"^\s*#\s*include\s*(\S+)", code, re.M)
    assert includes == ["<math.h>", f'"{header.name}"'], includes
    assert re.findall(r"^\s*#\s*include", header_code, re.M) == []
    code = re.sub(r"\btypedef\b[^;{]*(\{[^}]*\})?[^;]*;", "", code)  # types (trig.c.j2) hold no state
    for head in file_scope_statements(re.sub(r"^\s*#.*$", "", code, flags=re.M)):
        is_function = "(" in head.split("=")[0]
        if not is_function:
            # file-scope data must be `static const` (coefficient tables); no mutable state
            assert head.startswith("static const "), f"{source.name}: file-scope variable `{head}`"


@pytest.mark.compiler
@pytest.mark.parametrize("source", GENERATED_C, ids=[p.name for p in GENERATED_C])
def test_generated_c_compiles_strict(source, tmp_path, require_tool):
    gcc = require_tool("gcc")
    flags = STRICT + (["-Wdouble-promotion"] if source.stem.endswith("_f32") else [])
    obj = tmp_path / (source.stem + ".o")
    run = subprocess.run([gcc, *flags, "-O2", "-c", str(source), "-o", str(obj)],
                         capture_output=True, text=True)
    assert run.returncode == 0, f"{source.name}:\n{run.stderr}"
    nm = subprocess.run([require_tool("nm"), str(obj)], capture_output=True, text=True, check=True)
    data = [line for line in nm.stdout.splitlines() if line.split()[-2:-1] and line.split()[-2] in "DdBbCGgSsV"]
    assert data == [], f"{source.name} has data/bss symbols (global or static state): {data}"
    exported = [line.split()[-1] for line in nm.stdout.splitlines() if line.split()[-2:-1] == ["T"]]
    prefix = source.stem
    assert exported and all(name.startswith(prefix + "_") for name in exported), exported
