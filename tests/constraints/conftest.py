"""Fixtures of the closed-loop (Lagrange I) tests: the constrained catalog systems compiled once
per session, a caller for single C kernels, and the 30-digit augmented-system reference.

The constrained systems are not in ``catalog.EXAMPLES`` (see the comment there), so the
session-wide ``compiled_example`` fixture cannot build them; ``compiled_system`` does the same
for any catalog builder, in the same private cache dir (``kernel_cache_dir``).
"""
from __future__ import annotations

import mpmath
import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations

#: digits of the mpmath reference solves
DIGITS = 30


@pytest.fixture(scope="session")
def constrained_eom():
    """``constrained_eom(builder_name)``: `derive_equations` of ``catalog.<builder_name>()``, memoized."""
    memo: dict = {}

    def get(name: str):
        if name not in memo:
            memo[name] = derive_equations(getattr(catalog, name)())
        return memo[name]

    return get


@pytest.fixture(scope="session")
def compiled_system(kernel_cache_dir, constrained_eom):
    """``compiled_system(builder_name, precision="double", methods=("rk4",))`` via `compile_model`
    (default outputs: rhs, energy, points, constraints, multipliers), memoized per session."""
    from lagcodegen.pipeline import compile_model

    memo: dict = {}

    def get(name: str, precision: str = "double", methods=("rk4",)):
        key = (name, precision, tuple(methods))
        if key not in memo:
            memo[key] = compile_model(constrained_eom(name), methods=tuple(methods), precision=precision)
        return memo[key]

    return get


@pytest.fixture(scope="session")
def call_kernel():
    """``call_kernel(system, suffix, x, p, *sizes, t=0.0) -> (return value, [arrays])``: calls
    ``lcg_<model>_<suffix>(t, x, p, out_1, ..., out_k)`` with fresh output arrays of ``sizes``."""

    def call(system, suffix, x, p, *sizes, t=0.0):
        ffi = system.ffi
        x = np.ascontiguousarray(x, dtype=np.float64)
        p = np.ascontiguousarray(p, dtype=np.float64)
        outs = [np.zeros(size) for size in sizes]
        function = getattr(system.lib, f"{system.layout.prefix}_{suffix}")
        value = function(t, ffi.from_buffer("double[]", x), ffi.from_buffer("double[]", p),
                         *(ffi.from_buffer("double[]", o, require_writable=True) for o in outs))
        return value, outs

    return call


def augmented_solve(M, F, A, gamma):
    """Solve [[M, A^T], [A, 0]] [ud; lam] = [F; gamma] with mpmath at ``DIGITS`` digits.

    The first-kind system of Haug, Computer-Aided Kinematics and Dynamics of Mechanical Systems
    (1989), sec. 6.3: solved here as one dense LU of
    the (n + m) square matrix, a different route from the generated range-space solve
    (LDL^T of M, Cholesky of A M^-1 A^T). Inputs: mpmath-convertible nested lists; returns
    (ud (n,), lam (m,)) as floats.
    """
    with mpmath.workdps(DIGITS):
        M, A = mpmath.matrix(M), mpmath.matrix(A)
        n, m = M.rows, A.rows
        K = mpmath.zeros(n + m, n + m)
        b = mpmath.zeros(n + m, 1)
        for i in range(n):
            b[i] = mpmath.mpf(F[i])
            for j in range(n):
                K[i, j] = M[i, j]
        for i in range(m):
            b[n + i] = mpmath.mpf(gamma[i])
            for j in range(n):
                K[n + i, j] = K[j, n + i] = A[i, j]
        z = mpmath.lu_solve(K, b)
        return np.array([float(z[i]) for i in range(n)]), np.array([float(z[n + i]) for i in range(m)])


@pytest.fixture(scope="session", name="augmented_solve")
def _augmented_solve_fixture():
    """`augmented_solve` as a fixture (conftest modules are not importable by name)."""
    return augmented_solve


@pytest.fixture(scope="session")
def eom_augmented_reference():
    """``reference(eom, x, p, t=0)``: (ud, lam) of the derived M, F, A and gamma, evaluated by
    sympy at 30 digits at exactly the binary inputs and solved by `augmented_solve`. Checks the
    C (CSE, printer, range-space solve) against the symbolic equations it was generated from."""

    def reference(eom, x, p, t=0.0):
        values = {s: sp.Float(float(v), DIGITS) for s, v in zip(eom.q + eom.u, x)}
        values |= {s: sp.Float(float(v), DIGITS) for s, v in zip(eom.parameters, p)}
        values[eom.t] = sp.Float(float(t), DIGITS)
        ev = lambda matrix: matrix.xreplace(values).evalf(DIGITS).tolist()  # noqa: E731
        F, gamma = ev(eom.forcing), ev(eom.constraint_bias)
        return augmented_solve(ev(eom.mass_matrix), [f[0] for f in F], ev(eom.constraint_jacobian),
                               [g[0] for g in gamma])

    return reference

