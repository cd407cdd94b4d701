"""Helper: walks over sympy expressions that visit each distinct subexpression once.

Equations formed from shared terms (`symbolic.kane_terms` substitutes its shared velocity terms
back) hold the same subtree many times. sympy's ``preorder_traversal``, ``atoms`` and
``free_symbols`` walk every occurrence; these walk each distinct node once (the Whipple
bicycle's forcing: 22658 nodes as a tree, 508 distinct). Imports no stage.
"""
from __future__ import annotations

from collections.abc import Iterable, Iterator

import sympy as sp

__all__ = ["distinct_nodes", "atoms_of", "free_symbols_of", "with_zeros"]

#: Basic's own free_symbols (the union over the arguments); a class that overrides it binds
#: variables (Derivative, Integral, Lambda, Subs) or is a symbol itself, and answers for itself
_UNION_OF_ARGUMENTS = sp.Basic.__dict__["free_symbols"]
_UNION_CLASSES: dict = {}


def _unites_arguments(cls: type) -> bool:
    """Whether ``cls`` keeps Basic's free_symbols (looked up in the MRO: a function class such as
    sin has a metaclass whose own free_symbols hides the instances' on the class)."""
    known = _UNION_CLASSES.get(cls)
    if known is None:
        owner = next(k for k in cls.__mro__ if "free_symbols" in k.__dict__)
        known = _UNION_CLASSES[cls] = owner.__dict__["free_symbols"] is _UNION_OF_ARGUMENTS
    return known


def distinct_nodes(exprs: Iterable, into=None) -> Iterator[sp.Basic]:
    """Every distinct node of ``exprs`` (sympy objects; other items are skipped), once each, in no
    particular order; ``into(node)``, when given, says whether to walk into a node's arguments."""
    seen: set = set()
    stack = [e for e in exprs if isinstance(e, sp.Basic)]
    while stack:
        node = stack.pop()
        if node in seen:
            continue
        seen.add(node)
        yield node
        if into is None or into(node):
            stack.extend(node.args)


def atoms_of(exprs: Iterable, *types) -> set:
    """The nodes of ``exprs`` that are instances of ``types``: ``expr.atoms(*types)`` over all of them."""
    return {node for node in distinct_nodes(exprs) if isinstance(node, types)}


def free_symbols_of(exprs: Iterable) -> set:
    """The union of ``expr.free_symbols`` over ``exprs``, with the same rules: a node whose class
    defines free_symbols (a Symbol, or a Derivative or Integral that binds its variables) is asked."""
    found: set = set()
    for node in distinct_nodes(exprs, into=lambda n: _unites_arguments(type(n))):
        if not _unites_arguments(type(node)):
            found |= node.free_symbols
    return found


def with_zeros(expr, symbols, memo: dict | None = None):
    """``expr.xreplace({s: 0 for s in symbols})`` without forming 0 * f: a product with a factor that
    became 0 is 0 at once, where sympy's Mul asks whether the other factors are finite (0 * oo is
    nan), a walk over each (the Whipple bicycle's velocity constraints at u = 0 and its bias without
    Baumgarte's terms took 0.1 s of it). The expressions here are finite, so the result is
    xreplace's; ``memo`` carries results between calls (keyed by value: Float(2.0) * x and 2 * x
    are different keys)."""
    memo = {} if memo is None else memo
    zeros = frozenset(symbols)

    def rewrite(node):
        known = memo.get(node)
        if known is not None:
            return known
        if node in zeros:
            result = sp.S.Zero
        elif not node.args:
            result = node
        else:
            args = [rewrite(a) for a in node.args]
            if node.is_Mul and any(a is sp.S.Zero for a in args):
                result = sp.S.Zero
            elif all(a is b for a, b in zip(args, node.args)):
                result = node
            else:
                result = node.func(*args)
        memo[node] = result
        return result

    return rewrite(sp.sympify(expr))
