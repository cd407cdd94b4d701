"""The inline sine and cosine of templates/trig.c.j2, compiled alone through cffi.

Expected values: mpmath at 50 digits (double), and for float the exact value too (mpmath), so the
bound is on |got - sin x| in units of the last place of the float result (the correctly rounded
float is within 0.5 of it). Measured bounds (this sample and, for float, every float with
|x| <= 1e4 by an exhaustive run against glibc's double sin/cos): double below 0.75 ulp on this sample, float
below 0.81 ulp; a review's 2e7-point random search found 0.795 ulp (double cos at
-228.59097455667677), now in the sample. Asserted: double <= 0.8 ulp, float <= 0.9 ulp (faithful: never 1 ulp off the
correctly rounded float). Beyond the limit, NaN and infinities the scalar forms must equal glibc.
"""
from __future__ import annotations

import math

import mpmath
import numpy as np
import pytest

from lagcodegen.codegen.render import trig_source
from lagcodegen.native.build import DEFAULT_FLAGS

pytestmark = pytest.mark.compiler

LIMIT = {"double": 1.0e6, "float": 1.0e4}
BOUND_ULP = {"double": 0.8, "float": 0.9}
WRAPPERS = """
void vec_sin(const {t} *x, {t} *y, long n) {{ long i; for (i = 0; i < n; ++i) y[i] = lcg_sin{s}(x[i]); }}
void vec_cos(const {t} *x, {t} *y, long n) {{ long i; for (i = 0; i < n; ++i) y[i] = lcg_cos{s}(x[i]); }}
void vec_sin_fast(const {t} *x, {t} *y, long n) {{ long i; for (i = 0; i < n; ++i) y[i] = lcg_sin{s}_fast(x[i]); }}
void vec_cos_fast(const {t} *x, {t} *y, long n) {{ long i; for (i = 0; i < n; ++i) y[i] = lcg_cos{s}_fast(x[i]); }}
void vec_libm(const {t} *x, {t} *s, {t} *c, long n) {{ long i; for (i = 0; i < n; ++i) {{ s[i] = sin{s}(x[i]); c[i] = cos{s}(x[i]); }} }}
"""
NAMES = ("vec_sin", "vec_cos", "vec_sin_fast", "vec_cos_fast")


@pytest.fixture(scope="module", params=["double", "float"])
def trig(request, tmp_path_factory):
    """(precision, numpy dtype, {name: vectorized function})."""
    import cffi

    precision = request.param
    real, suffix = precision, "f" if precision == "float" else ""
    wrappers = WRAPPERS.format(t=real, s=suffix)
    ffi = cffi.FFI()
    ffi.cdef("".join(line.split("{")[0].strip() + ";\n" for line in wrappers.strip().splitlines()))
    name = f"_lcg_trig_test_{precision}"
    ffi.set_source(name, "#include <math.h>\n" + trig_source(precision) + wrappers,
                   extra_compile_args=list(DEFAULT_FLAGS) + ["-Wall", "-Wextra", "-Werror"], libraries=["m"])
    out = tmp_path_factory.mktemp(name)
    import importlib.util
    path = ffi.compile(tmpdir=str(out))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    dtype = np.float32 if precision == "float" else np.float64

    def vectorized(fname):
        def call(x):
            x = np.ascontiguousarray(x, dtype=dtype)
            y = np.empty_like(x)
            getattr(module.lib, fname)(module.ffi.from_buffer(f"{real}[]", x),
                                       module.ffi.from_buffer(f"{real}[]", y, require_writable=True), len(x))
            return y
        return call

    def libm(x):
        x = np.ascontiguousarray(x, dtype=dtype)
        s, c = np.empty_like(x), np.empty_like(x)
        buf = lambda a: module.ffi.from_buffer(f"{real}[]", a, require_writable=True)  # noqa: E731
        module.lib.vec_libm(buf(x), buf(s), buf(c), len(x))
        return s, c
    functions = {n: vectorized(n) for n in NAMES}
    functions["libm"] = libm
    return precision, dtype, functions


def ulp_errors(got, x, exact, precision) -> np.ndarray:
    """|got - f(x)| / ulp(f(x)) with f(x) from mpmath at 50 digits."""
    mantissa, lowest = (24, -149) if precision == "float" else (53, -1074)
    errors = []
    with mpmath.workdps(50):
        for g, xi in zip(got.tolist(), x.tolist()):
            want = exact(mpmath.mpf(xi))
            if want == 0:
                errors.append(0.0 if g == 0 else math.inf)
                continue
            exponent = int(mpmath.floor(mpmath.log(abs(want), 2)))
            ulp = mpmath.mpf(2) ** max(exponent - mantissa + 1, lowest)
            errors.append(float(abs(mpmath.mpf(g) - want) / ulp))
    return np.array(errors)


def samples(precision, dtype, rng, n=3000) -> dict:
    limit = LIMIT[precision]
    signs = lambda: rng.choice([-1.0, 1.0], n)  # noqa: E731
    k = rng.integers(1, int(limit * 2 / math.pi), n)
    with mpmath.workdps(40):  # the representable numbers nearest to k pi/2, and a few ulps off
        near = np.array([float(mpmath.mpf(int(i)) * mpmath.pi / 2) for i in k]).astype(dtype)
    near = near + rng.integers(-3, 4, n).astype(dtype) * np.spacing(near)
    tiny_exponent = -45 if precision == "float" else -320
    # the worst a review's 2e7-point random search found: sin 0.781, cos 0.795 ulp (double)
    worst = {"worst found": np.array([530081.7538090303, -228.59097455667677])} if precision == "double" else {}
    return worst | {
        "|x| <= pi/4": rng.uniform(-0.8, 0.8, n).astype(dtype),
        "|x| <= 10": rng.uniform(-10.0, 10.0, n).astype(dtype),
        "log-uniform up to the limit": (signs() * 10.0 ** rng.uniform(-3, math.log10(limit), n)).astype(dtype),
        "uniform up to the limit": rng.uniform(-limit, limit, n).astype(dtype),
        "near multiples of pi/2": near,
        "tiny and subnormal": (signs() * 10.0 ** rng.uniform(tiny_exponent, -3, n)).astype(dtype),
    }


def test_ulp_bound(trig, rng):
    precision, dtype, f = trig
    for what, x in samples(precision, dtype, rng).items():
        for name, exact in (("vec_sin", mpmath.sin), ("vec_cos", mpmath.cos)):
            errors = ulp_errors(f[name](x), x, exact, precision)
            worst = int(np.argmax(errors))
            assert errors[worst] <= BOUND_ULP[precision], \
                f"{precision} {name} on {what}: {errors[worst]:.3f} ulp at x = {float(x[worst])!r}"


def test_fast_forms_equal_scalar_forms_within_the_limit(trig, rng):
    precision, dtype, f = trig
    x = np.concatenate(list(samples(precision, dtype, rng, 500).values()))
    np.testing.assert_array_equal(f["vec_sin_fast"](x), f["vec_sin"](x))
    np.testing.assert_array_equal(f["vec_cos_fast"](x), f["vec_cos"](x))


def test_signed_zero_and_odd_even_symmetry(trig, rng):
    precision, dtype, f = trig
    zeros = np.array([0.0, -0.0], dtype=dtype)
    assert np.array_equal(np.signbit(f["vec_sin"](zeros)), [False, True])  # sin(+-0) = +-0 (C99 F.9.1.6)
    assert np.all(f["vec_cos"](zeros) == 1)
    x = rng.uniform(0, LIMIT[precision], 2000).astype(dtype)
    np.testing.assert_array_equal(f["vec_sin"](-x), -f["vec_sin"](x))
    np.testing.assert_array_equal(f["vec_cos"](-x), f["vec_cos"](x))


def test_beyond_the_limit_nan_and_infinities_are_libm(trig, rng):
    """Expected values: glibc's own sin and cos (the fallback must be exactly them)."""
    precision, dtype, f = trig
    limit = LIMIT[precision]
    big = np.finfo(dtype).max
    x = np.concatenate([rng.uniform(limit, 1e8, 200), -10.0 ** rng.uniform(math.log10(limit), 30, 200),
                        [np.nextafter(dtype(limit), dtype(np.inf)), big, -big, np.inf, -np.inf, np.nan]]).astype(dtype)
    s, c = f["libm"](x)
    np.testing.assert_array_equal(f["vec_sin"](x), s)  # NaN == NaN for assert_array_equal
    np.testing.assert_array_equal(f["vec_cos"](x), c)
    assert np.all(np.isnan(f["vec_sin"](np.array([np.nan, np.inf, -np.inf], dtype=dtype))))


def test_trig_source_rejects_unknown_precision():
    from lagcodegen.codegen.render import EmitError

    with pytest.raises(EmitError, match="precision"):
        trig_source("half")
