"""`symbolic.differentiation.derivative` against sympy's expr.diff: the same expression, node for
node (srepr), on the terms its rules cover and on what it hands to sympy."""
from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen.symbolic.differentiation import derivative, jacobian

x, y, z = sp.symbols("x y z")
a = sp.Symbol("a", positive=True)
q = me.dynamicsymbols("q")

EXPRESSIONS = [
    x, y, sp.Integer(3), sp.Rational(1, 3), x * y, 3 * x ** 2 * y, x + y * z, sp.sin(x) * sp.cos(y),
    sp.sin(x * y + z) ** 2, 1 / (x + y), (x + y) ** sp.Rational(3, 2), sp.sqrt(x ** 2 + y ** 2), x ** y,
    sp.exp(x * y), sp.log(x + a), sp.tan(x), sp.atan2(y, x), sp.Abs(x - y), sp.sign(x),
    sp.Piecewise((x, y > 0), (y, True)),
    sp.cos(sp.sin(x) * y) * sp.sin(y) - 2 * x * sp.cos(x + y) / (1 + y ** 2), a * x / (a + sp.cos(x) ** 2),
    sp.sin(x) * sp.sin(x + y) * sp.cos(y - z) * (x - y) ** 3, -x, -sp.sin(x) * y,
]


def test_derivative_is_sympys_node_for_node():
    """Reference: sympy's expr.diff(s), compared by srepr (the same tree, not only equal values)."""
    memo: dict = {}
    for expr in EXPRESSIONS:
        for symbol in (x, y, z, a):
            assert sp.srepr(derivative(expr, symbol, memo)) == sp.srepr(expr.diff(symbol)), (expr, symbol)
            assert sp.srepr(derivative(expr, symbol)) == sp.srepr(expr.diff(symbol)), (expr, symbol)


def test_a_function_of_time_is_sympys_own():
    """Reference: sympy's diff with respect to q(t), which derivative hands to sympy."""
    expr = sp.sin(q) * x + q ** 2
    assert derivative(expr, q) == expr.diff(q) == sp.cos(q) * x + 2 * q


def test_jacobian_is_sympys():
    """Reference: sympy's Matrix.jacobian."""
    rows = [sp.sin(x) * y + z ** 2, x * y * z, sp.cos(x + y) / (1 + z ** 2)]
    assert jacobian(rows, [x, y, z]) == sp.Matrix(rows).jacobian([x, y, z])
