"""Helper: partial derivatives with sympy's rules, without its Derivative machinery.

``expr.diff(s)`` builds a Derivative, recomputes the free symbols of every subexpression it
enters and asks assumptions on the way; forming the Whipple bicycle's equations took 1562 such
calls and 0.62 s. `derivative` applies the same rules to Add, Mul, Pow, sin and cos (the
product rule term by term, as sympy's Mul does; sympy's own Pow and Function formulas) and
memoizes them, so its results are sympy's, node for node (tests/symbolic/test_differentiation.py
compares them); any other node is differentiated by sympy. A term whose factor's derivative is
0 is dropped, not multiplied out: sympy's 0 * f asks whether f is finite (0 * oo is nan), a walk
over f, and the terms here are finite (`model.check_well_defined` refuses infinities), where
0 * f is 0. Imports no stage.
"""
from __future__ import annotations

import sympy as sp

__all__ = ["derivative", "jacobian"]


def derivative(expr, symbol, memo: dict | None = None):
    """``expr.diff(symbol)`` for a Symbol ``symbol``; ``memo`` (a dict) carries results between calls."""
    memo = {} if memo is None else memo
    key = (expr, symbol)
    known = memo.get(key)
    if known is not None:
        return known
    if not getattr(symbol, "is_Symbol", False):  # q(t), a matrix, ...: sympy's own
        result = sp.sympify(expr).diff(symbol)
    elif expr.is_Symbol:
        result = sp.S.One if expr == symbol else sp.S.Zero
    elif expr.is_Number or symbol not in expr.free_symbols:
        result = sp.S.Zero
    elif expr.is_Add:
        result = sp.Add(*[derivative(a, symbol, memo) for a in expr.args])
    elif expr.is_Mul:
        factors = list(expr.args)
        terms = [(i, derivative(f, symbol, memo)) for i, f in enumerate(factors)]
        result = sp.Add(*[sp.Mul(*factors[:i], d, *factors[i + 1:]) for i, d in terms if d != 0])
    elif expr.is_Pow:
        base, exponent = expr.args
        d_base, d_exponent = derivative(base, symbol, memo), derivative(exponent, symbol, memo)
        by_exponent = d_exponent * sp.log(base) if d_exponent != 0 else sp.S.Zero
        by_base = d_base * exponent / base if d_base != 0 else sp.S.Zero
        result = expr * (by_exponent + by_base)
    elif isinstance(expr, (sp.sin, sp.cos)):
        d_argument = derivative(expr.args[0], symbol, memo)
        result = sp.S.Zero if d_argument.is_zero else sp.Add(expr.fdiff(1) * d_argument)
    else:
        result = expr.diff(symbol)
    memo[key] = result
    return result


def jacobian(exprs, symbols) -> sp.Matrix:
    """``Matrix(exprs).jacobian(symbols)`` by `derivative`."""
    memo: dict = {}
    return sp.Matrix([[derivative(sp.sympify(e), s, memo) for s in symbols] for e in exprs])
