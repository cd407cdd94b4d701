"""codegen/lu.py: the unrolled LU with partial pivoting of the eliminated dynamics' A_D.

Expected values: the looped ``_dense_factor`` / ``_dense_substitute`` the generated C carries
(a second route: the same operations, so the same bits are required, the pivots, det and the
singular verdicts included), and numpy.linalg.solve / det for the values (independent of both).
Compiled alone through cffi, as the generated code builds (DEFAULT_FLAGS, -Wall -Wextra -Werror).
"""
from __future__ import annotations

import importlib.util
import re

import numpy as np
import pytest

from lagcodegen.codegen.lu import UNROLLED_LU_MAX, lu_factor_lines, lu_substitute_lines
from lagcodegen.native.build import DEFAULT_FLAGS

pytestmark = pytest.mark.compiler

COLUMNS = 3


def _looped_helpers(real: str) -> str:
    """The looped helpers as a model with dependent speeds carries them (the Chaplygin sleigh, y'
    dependent)."""
    import sympy.physics.mechanics as me
    from test_chaplygin_sleigh import sleigh

    from lagcodegen import derive_equations
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources

    eom = derive_equations(sleigh(dependent_speeds=[me.dynamicsymbols("y")]))
    source = render_sources(reduce_expressions(eom, ["rhs", "dependent_speeds"], {}), precision=real,
                            methods=("rk4",)).source
    functions = []
    for name in ("dense_factor", "dense_substitute"):
        match = re.search(r"static LCG_HOT_INLINE (?:int|void) (\w+_" + name + r")\(.*?\n}\n", source, re.S)
        functions.append(match.group(0).replace(match.group(1), f"looped_{name}").replace("LCG_HOT_INLINE ", ""))
    return "\n".join(functions)


def _unrolled(n: int, real: str) -> str:
    body = [f"{real} det;"] + [f"{real} LU_{i}_{j} = A[{i * n + j}];" for i in range(n) for j in range(n)]
    body += lu_factor_lines(n, real, "0")
    body.append("for (int c = 0; c < cols; ++c)")
    body += lu_substitute_lines(n, real, [f"B[{i} * cols + c]" for i in range(n)])
    body += [f"A[{i * n + j}] = LU_{i}_{j};" for i in range(n) for j in range(n)] + ["*det_out = det;", "return 1;"]
    return (f"int unrolled_{n}({real} *A, {real} *B, int cols, {real} scale, {real} *det_out)\n{{\n    "
            + "\n    ".join(body) + "\n}\n")


@pytest.fixture(scope="module", params=["double", "float"])
def solvers(request, tmp_path_factory):
    import cffi

    real = request.param
    sizes = range(1, UNROLLED_LU_MAX + 1)
    wrappers = (f"int looped({real} *A, {real} *B, int n, int cols, {real} scale, {real} *det, int *ipiv)\n"
                "{\n    if (!looped_dense_factor(A, ipiv, n, scale, det)) return 0;\n"
                "    looped_dense_substitute(A, ipiv, B, n, cols);\n    return 1;\n}\n")
    declarations = [f"int looped({real} *A, {real} *B, int n, int cols, {real} scale, {real} *det, int *ipiv);"]
    declarations += [f"int unrolled_{n}({real} *A, {real} *B, int cols, {real} scale, {real} *det_out);"
                     for n in sizes]
    ffi = cffi.FFI()
    ffi.cdef("\n".join(declarations))
    name = f"_lcg_unrolled_lu_test_{real}"
    source = ("#include <math.h>\n" + _looped_helpers(real) + wrappers
              + "".join(_unrolled(n, real) for n in sizes))
    ffi.set_source(name, source, extra_compile_args=list(DEFAULT_FLAGS) + ["-Wall", "-Wextra", "-Werror"],
                   libraries=["m"])
    path = ffi.compile(tmpdir=str(tmp_path_factory.mktemp(name)))
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    dtype = np.float32 if real == "float" else np.float64

    def call(A, B, scale, function):
        """(ok, A's factors, X, det) of one C call on copies in the C scalar type."""
        A, B = np.array(A, dtype=dtype, order="C"), np.array(B, dtype=dtype, order="C")
        det = np.zeros(1, dtype=dtype)
        buffer = lambda a: module.ffi.from_buffer(f"{real}[]", a, require_writable=True)  # noqa: E731
        ok = function(buffer(A), buffer(B), len(A), B.shape[1], scale, buffer(det))
        return ok, A, B, det[0]

    def looped(A, B, scale=0.0):
        ipiv = module.ffi.new("int[]", len(A))
        return call(A, B, scale, lambda a, b, n, cols, s, det: module.lib.looped(a, b, n, cols, s, det, ipiv))

    def unrolled(A, B, scale=0.0):
        function = getattr(module.lib, f"unrolled_{len(A)}")
        return call(A, B, scale, lambda a, b, n, cols, s, det: function(a, b, cols, s, det))

    return real, dtype, looped, unrolled


def _cases(rng):
    """(A, B): random, pivoting forced at every step (small diagonal), ties in |entry|, integers."""
    for n in range(1, UNROLLED_LU_MAX + 1):
        for _ in range(20):
            yield rng.standard_normal((n, n)), rng.standard_normal((n, COLUMNS))
        A = rng.standard_normal((n, n))
        np.fill_diagonal(A, 1e-3)
        yield A, rng.standard_normal((n, COLUMNS))
        yield rng.choice([-1.0, 1.0], (n, n)) + np.eye(n) * 0.5, rng.standard_normal((n, COLUMNS))
        yield np.rot90(np.eye(n)) * 3.0 + 0.25, rng.integers(-4, 5, (n, COLUMNS)).astype(float)


def test_the_unrolled_lu_gives_the_looped_bits_and_numpys_values(solvers):
    real, dtype, looped, unrolled = solvers
    rng = np.random.default_rng(20261127)
    tolerance = 1e-9 if real == "double" else 2e-3
    checked = 0
    for A, B in _cases(rng):
        ok_loop, LU_loop, X_loop, det_loop = looped(A, B)
        ok, LU, X, det = unrolled(A, B)
        assert ok == ok_loop
        if not ok:
            continue
        checked += 1
        np.testing.assert_array_equal(LU, LU_loop)
        np.testing.assert_array_equal(X, X_loop)
        assert det == det_loop
        A32 = np.array(A, dtype=dtype).astype(float)  # the matrix the C saw
        if np.linalg.cond(A32) < 1e4:
            np.testing.assert_allclose(X, np.linalg.solve(A32, np.array(B, dtype=dtype)), rtol=tolerance,
                                       atol=tolerance)
            assert det == pytest.approx(np.linalg.det(A32), rel=tolerance)
    assert checked > 100


@pytest.mark.parametrize("n", range(2, UNROLLED_LU_MAX + 1))
def test_a_singular_or_non_finite_matrix_is_refused_as_by_the_loops(solvers, n):
    """Rank n - 1 (a row the sum of two others, or a zero column), the scale's own test (all
    zeros), and a NaN or an infinite entry: both forms return 0."""
    _, _, looped, unrolled = solvers
    rng = np.random.default_rng(n)
    B = rng.standard_normal((n, 1))
    dependent = rng.standard_normal((n, n))
    dependent[-1] = dependent[0] + (dependent[1] if n > 2 else 0.0)
    zero_column = rng.standard_normal((n, n))
    zero_column[:, n // 2] = 0.0
    with_nan, with_inf = rng.standard_normal((n, n)), rng.standard_normal((n, n))
    with_nan[n - 1, 0], with_inf[0, n - 1] = np.nan, np.inf
    for A in (dependent, zero_column, np.zeros((n, n)), with_nan, with_inf):
        assert looped(A, B)[0] == 0
        assert unrolled(A, B)[0] == 0


def test_the_scale_argument_sets_the_rank_tolerance_as_in_the_loops(solvers):
    """A pivot of 1e-13 against a scale of 1: singular for both; against A's own entries (scale 0):
    regular for both (the sleigh's 1 x 1 A_D is cos(theta), judged against A_I's entries)."""
    real, _, looped, unrolled = solvers
    tiny = 1e-13 if real == "double" else 1e-7
    A, B = np.array([[tiny]]), np.array([[1.0]])
    assert looped(A, B, 1.0)[0] == unrolled(A, B, 1.0)[0] == 0
    assert looped(A, B, 0.0)[0] == unrolled(A, B, 0.0)[0] == 1
