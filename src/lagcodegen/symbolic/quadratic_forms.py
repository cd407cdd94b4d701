"""Helper: read a kinetic energy as a quadratic form in the speeds, without expanding it.

``T(q, u, t) = 1/2 u^T M u + b^T u + T0`` is recovered by walking T's expression tree:
sums add, products multiply (truncated at degree 2 in u), and squares of linear forms expand
into their pairwise products only. Constant factors made of parameters alone stay apart as
*weights*, so that m_i * (l_j cos q_j)(l_k cos q_k) from body i can later be grouped with the
same product from other bodies as (m_a + m_b + ...) * (...). A chain's T becomes M in O(n^3)
products instead of the O(n^4) of differentiating the whole T twice.
"""
from __future__ import annotations

import sympy as sp


class NotQuadratic(ValueError):
    """T is not a polynomial of degree <= 2 in the speeds (as written)."""


def quadratic_terms(T, u, parameters) -> list:
    """Entries (key, weight, expr) whose sum is T.

    ``key`` is () for T0, (j,) for the coefficient of u_j, (j, k) with j <= k for that of
    u_j u_k; ``weight`` depends on parameters only; ``expr`` on q, t and parameters.
    """
    index = {s: i for i, s in enumerate(u)}
    return _poly(sp.sympify(T), index, frozenset(index), frozenset(parameters))


def _poly(expr, index, speeds, parameters) -> list:
    symbols = expr.free_symbols
    if not symbols & speeds:
        return [((), expr, sp.S.One)] if symbols <= parameters else [((), sp.S.One, expr)]
    if expr in index:
        return [((index[expr],), sp.S.One, sp.S.One)]
    if expr.is_Add:
        return [entry for arg in expr.args for entry in _poly(arg, index, speeds, parameters)]
    if expr.is_Mul:
        weight = sp.Mul(*[f for f in expr.args if f.free_symbols <= parameters])
        result = [((), weight, sp.S.One)]
        for factor in expr.args:
            if not factor.free_symbols <= parameters:
                result = _product(result, _poly(factor, index, speeds, parameters))
        return result
    if expr.is_Pow and expr.exp in (1, 2):
        base = _poly(expr.base, index, speeds, parameters)
        return base if expr.exp == 1 else _product(base, base)
    raise NotQuadratic(f"{expr} is not polynomial in the speeds")


def _product(a: list, b: list) -> list:
    out = []
    for key_a, weight_a, expr_a in a:
        for key_b, weight_b, expr_b in b:
            key = tuple(sorted(key_a + key_b))
            if len(key) > 2:
                raise NotQuadratic("a product of more than two speeds")
            out.append((key, weight_a * weight_b, expr_a * expr_b))
    return out
