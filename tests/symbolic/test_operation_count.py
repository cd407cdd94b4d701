"""codegen.reduce.count_operations against its reference, sympy.count_ops itself: the same number
for every expression the kernels of the catalog's examples hold before and after CSE, and for
the cases count_ops treats specially (negative and fractional coefficients, subtraction, division,
exp, undefined functions)."""
from __future__ import annotations

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import catalog
from lagcodegen.codegen.reduce import count_operations, reduce_expressions
from lagcodegen.symbolic.derive import derive_equations

x, y, z = sp.symbols("x y z")
f = sp.Function("f")
q = me.dynamicsymbols("q")

EDGE_CASES = [
    sp.S.One, sp.S.Zero, sp.Rational(-1, 3), sp.Integer(-2), sp.Float(2.5), x, -x, -2 * x, x / 3, -x / 3,
    1 / x, -1 / x, 2 / x, x / y, -x / y, x ** -2, x - y, -x - y, -x + y, -x - y - z, x + y + z,
    sp.exp(x), sp.E, sp.exp(-x) * y, sp.sin(x) * sp.cos(y) - 3 * x ** 2 / (1 + y), f(x) + f(y) ** 2,
    sp.sqrt(x) - sp.Abs(y), sp.Max(x, y) + sp.Min(x, z), q.diff() * sp.sin(q), sp.Piecewise((x, x > 0), (-x, True)),
    (x + y) * (x - y) / (2 * z), -(x + y) / 3, sp.Mul(-1, x + y, evaluate=False), sp.sign(x) * y,
]


@pytest.mark.parametrize("expr", EDGE_CASES, ids=[str(e) for e in EDGE_CASES])
def test_each_special_case_counts_as_count_ops_does(expr):
    assert count_operations([expr]) == sp.count_ops(expr)


def test_a_repeated_subtree_counts_at_every_occurrence():
    shared = sp.sin(x) * sp.cos(y) + x ** 3
    exprs = [shared * z, shared + 1, -shared]
    assert count_operations(exprs) == sum(sp.count_ops(e) for e in exprs)


@pytest.mark.parametrize("name", sorted(catalog.EXAMPLES))
def test_every_catalog_kernel_counts_as_count_ops_does(name):
    eom = derive_equations(catalog.EXAMPLES[name]())
    outputs = ["rhs", "energy", "points"] + (["jacobian"] if not eom.m and eom.n <= 5 else [])
    system = reduce_expressions(eom, [o for o in outputs if o != "energy" or eom.energy is not None], {})
    for kernel in system.kernels:
        temporaries = [e for _, e in kernel.temporaries]
        results = [e for _, e in kernel.results]
        assert count_operations(temporaries + results) == kernel.ops_after
        assert count_operations(temporaries + results) == \
            sum(int(sp.count_ops(e)) for e in temporaries) + sum(int(sp.count_ops(e)) for e in results)
