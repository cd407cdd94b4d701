"""The Lagrange II (energies) route: Model -> EquationsOfMotion.

With p = dT/du, never forming d/dt(dT/dqd) symbolically::

    M = d2T/du2 (the Hessian of T in the speeds)
    F = dT/dq - (dp/dq) u - dp/dt - dV/dq - dR/du + Q
"""
from __future__ import annotations

import sympy as sp

from ..model import TIME, Model
from .equations import EquationsOfMotion, assemble, check_mass_matrix, lagrange_symbols
from .grouping import GroupedSum, sparse_diff
from .quadratic_forms import NotQuadratic, quadratic_terms


# -- Lagrange II ------------------------------------------------------------------------------
def derive_from_energies(model: Model) -> EquationsOfMotion:
    coords, speeds, q, u, to_plain = lagrange_symbols(model)
    T = to_plain(model.kinetic_energy, "kinetic energy")
    V = to_plain(model.potential_energy, "potential energy")
    R = to_plain(model.dissipation, "dissipation function")
    try:
        M, b, T0 = _quadratic_form(T, q, u, model.parameters)
        F = _lagrange_forcing(M, b, T0, q, u)
    except NotQuadratic:  # e.g. T written with speeds inside functions: differentiate it as a whole
        M, F = _hessian_form(T, q, u)
    check_mass_matrix(M, coords, u)
    for j, c in enumerate(coords):
        Q = to_plain(model.generalized_forces.get(c, 0), f"generalized force on {c}")
        F[j] += -V.diff(q[j]) - R.diff(u[j]) + Q
    return assemble(model, coords, speeds, q, u, M, F, sp.Matrix(u), T, V, to_plain,
                    inputs_checked=True)


def _quadratic_form(T, q, u, parameters):
    """M (n, n), b (n) and T0 of T = 1/2 u^T M u + b^T u + T0, with shared products grouped."""
    n = len(u)
    M_sum, b, T0 = GroupedSum(), [[] for _ in range(n)], []
    for key, weight, expr in quadratic_terms(T, u, parameters):
        number, weight = weight.as_coeff_Mul()
        if len(key) == 2:
            k, j = key  # k <= j; a c u_j^2 term gives M_jj = 2 c, a c u_j u_k term M_jk = c
            M_sum.add((j, k), weight, (2 if j == k else 1) * number * expr)
        elif len(key) == 1:
            b[key[0]].append(number * weight * expr)
        else:
            T0.append(number * weight * expr)
    M = sp.zeros(n, n)
    for j in range(n):
        for k in range(j + 1):
            M[j, k] = M[k, j] = M_sum.value((j, k))
    return M, [sp.Add(*terms) for terms in b], sp.Add(*T0)


def _lagrange_forcing(M, b, T0, q, u) -> sp.Matrix:
    """F_j = dT/dq_j - d/dt(dT/du_j) + M_j. ud, from M, b, T0 (Christoffel form)::

        F_j = sum_kl (1/2 dM_kl/dq_j - dM_jl/dq_k) u_k u_l + sum_k (db_k/dq_j - db_j/dq_k) u_k
              + dT0/dq_j - sum_l dM_jl/dt u_l - db_j/dt

    Each entry is differentiated once per variable it contains (the chain's M_kl: q_k, q_l).
    """
    n, t = len(q), TIME
    variables = list(q) + [t]

    def partials(expr) -> dict:
        symbols = expr.free_symbols
        return {x: sparse_diff(expr, x) for x in variables if x in symbols}

    dM = {(k, l): partials(M[k, l]) for k in range(n) for l in range(k + 1)}
    db, dT0 = [partials(bj) for bj in b], partials(T0)

    def dm(j, l, x):  # dM_jl/dx, M symmetric
        return dM[max(j, l), min(j, l)].get(x, sp.S.Zero)

    F = sp.zeros(n, 1)
    for j in range(n):
        terms = [dT0.get(q[j], 0), -db[j].get(t, 0)]
        for k in range(n):
            terms.append((db[k].get(q[j], 0) - db[j].get(q[k], 0)) * u[k])
            terms.append(-dm(j, k, t) * u[k])
            for l in range(k + 1):
                weight = u[k] * u[l]
                half = sp.Rational(1, 2) if k == l else sp.S.One  # M_kl and M_lk both count
                terms.append((half * dm(k, l, q[j]) - dm(j, l, q[k]) - (dm(j, k, q[l]) if k != l else 0)) * weight)
        F[j] = sp.Add(*terms)
    return F


def _hessian_form(T, q, u):
    """M = d2T/du2 and F = dT/dq - (dp/dq) u - dp/dt, p = dT/du: the general, slower route."""
    n, t = len(u), TIME
    p = [T.diff(uj) for uj in u]
    M = sp.zeros(n, n)
    for j in range(n):
        for k in range(j + 1):
            M[j, k] = M[k, j] = p[j].diff(u[k])
    F = sp.zeros(n, 1)
    for j in range(n):
        transport = sp.Add(*[p[j].diff(qk) * uk for qk, uk in zip(q, u)])
        F[j] = T.diff(q[j]) - transport - p[j].diff(t)
    return M, F
