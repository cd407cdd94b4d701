"""The walks of `lagcodegen.walk` against sympy's own (free_symbols, atoms, preorder_traversal):
each distinct node once, the same answers."""
from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen.walk import atoms_of, distinct_nodes, free_symbols_of

x, y, n = sp.symbols("x y n")
q = me.dynamicsymbols("q")

CASES = [
    x, sp.Integer(3), sp.Float(1.5), q, q.diff(), q.diff(me.dynamicsymbols._t, 2),
    sp.sin(q) * x + y ** 2, sp.Piecewise((x, y > 0), (n, True)),
    sp.Derivative(x * y, y), sp.Derivative(x, y), sp.Derivative(x, (y, n)),
    sp.Integral(x * y, y), sp.Integral(x, (y, 0, n)), sp.Lambda(y, x * y), sp.Subs(x * y, y, n),
    sp.ImmutableMatrix([[x, sp.cos(y)], [n, 2]]),
]


def test_free_symbols_as_sympy_says():
    """sympy's free_symbols is the reference, bound variables (Derivative, Integral, Lambda, Subs) included."""
    for expr in CASES:
        assert free_symbols_of([expr]) == expr.free_symbols, expr
    assert free_symbols_of(CASES) == set().union(*(e.free_symbols for e in CASES))
    assert free_symbols_of([1, "text", None]) == set()


def test_atoms_and_nodes_as_sympy_says():
    """sympy's atoms(types) and the set of preorder_traversal are the references."""
    for expr in CASES:
        for types in ((sp.Derivative,), (sp.Function,), (sp.Symbol, sp.Number), (sp.Pow,)):
            assert atoms_of([expr], *types) == expr.atoms(*types), (expr, types)
        assert set(distinct_nodes([expr])) == set(sp.preorder_traversal(expr)), expr


def test_shared_subtrees_are_visited_once():
    """A chain e_k = e_(k-1) * (e_(k-1) + 1) holds 2^k copies of e_0 as a tree; the walk meets k + ... nodes."""
    expr = sp.sin(x)
    for _ in range(40):
        expr = expr * (expr + 1)
    nodes = list(distinct_nodes([expr]))
    assert len(nodes) == len(set(nodes)) < 200
    assert free_symbols_of([expr]) == {x}
    assert atoms_of([expr], sp.sin) == {sp.sin(x)}


def test_with_zeros_is_xreplace_by_zero():
    """sympy's xreplace({s: 0}) is the reference, on finite expressions, node for node (srepr)."""
    from lagcodegen.walk import with_zeros

    u, v = sp.symbols("u v")
    cases = [x * u + y, sp.sin(x) * u * v - 2 * y * v + sp.cos(u) * x, (u + x) ** 2 * y, 1 / (x + u),
             sp.Float(2.0) * x * u + sp.Float(2.0) * x + 2 * y, sp.sin(u * x) + sp.exp(v) * x,
             sp.Piecewise((u * x, y > 0), (x, True)), q.diff() * u + q]
    memo: dict = {}
    for expr in cases:
        rule = {u: 0, v: 0}
        assert sp.srepr(with_zeros(expr, (u, v), memo)) == sp.srepr(expr.xreplace(rule)), expr
        assert sp.srepr(with_zeros(expr, (u, v))) == sp.srepr(expr.xreplace(rule)), expr
