"""Helper: rooted trees and the Runge-Kutta order conditions they index.

A Runge-Kutta method ``(A, b, c)`` has order ``p`` exactly when, for every rooted tree ``t``
with at most ``p`` vertices, the elementary weight equals the inverse density::

    Phi(t) = b^T g(t) = 1 / gamma(t),

where ``g(tau) = 1`` (the one-vertex tree) and ``g([t_1 ... t_m]) = (A g(t_1)) * ... *
(A g(t_m))`` componentwise, and ``gamma(tau) = 1``, ``gamma(t) = |t| gamma(t_1) ...
gamma(t_m)`` (Butcher, *Numerical Methods for Ordinary Differential Equations*, 3rd ed.,
Wiley 2016, Ch. 3, Secs. 30-31; Hairer-Norsett-Wanner I, 2nd ed., Sec. II.2).

Trees are built from their subtrees (Butcher's ``[t_1 ... t_m]`` notation) and kept in a
canonical form (children sorted), so equal trees compare and hash equal. This module
imports no pipeline stage.
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache
from math import factorial

import sympy as sp


def _sort_key(tree: RootedTree) -> tuple[int, str]:
    return (tree.order, str(tree))


@dataclass(frozen=True)
class RootedTree:
    """A rooted tree ``[t_1 ... t_m]``, given by the subtrees hanging off its root.

    Parameters
    ----------
    children : tuple of RootedTree
        Subtrees of the root, in any order; stored sorted (canonical form). ``()`` is the
        one-vertex tree ``tau``.
    """

    children: tuple[RootedTree, ...] = ()

    def __post_init__(self) -> None:
        object.__setattr__(self, "children", tuple(sorted(self.children, key=_sort_key)))

    @property
    def order(self) -> int:
        """Number of vertices ``|t|``."""
        return 1 + sum(child.order for child in self.children)

    @property
    def density(self) -> int:
        """Density ``gamma(t) = |t| * prod gamma(t_i)``."""
        gamma = self.order
        for child in self.children:
            gamma *= child.density
        return gamma

    @property
    def symmetry(self) -> int:
        """``sigma(t) = prod sigma(t_i)^{m_i} m_i!`` over distinct subtrees of multiplicity m_i."""
        sigma = 1
        for child in set(self.children):
            m = self.children.count(child)
            sigma *= child.symmetry**m * factorial(m)
        return sigma

    def __str__(self) -> str:
        if not self.children:
            return "τ"
        return "[" + " ".join(str(child) for child in self.children) + "]"


TAU = RootedTree()


def _grow(tree: RootedTree) -> set[RootedTree]:
    """All trees obtained from ``tree`` by attaching one new leaf to any vertex."""
    grown = {RootedTree(tree.children + (TAU,))}
    for i, child in enumerate(tree.children):
        for bigger in _grow(child):
            grown.add(RootedTree(tree.children[:i] + (bigger,) + tree.children[i + 1 :]))
    return grown


@cache
def trees_of_order(n: int) -> tuple[RootedTree, ...]:
    """All rooted trees with ``n`` vertices, each once, sorted canonically.

    Counts are 1, 1, 2, 4, 9, 20, 48, 115 for n = 1..8 (OEIS A000081).
    """
    if not isinstance(n, int) or isinstance(n, bool) or n < 1:
        raise ValueError(f"tree order must be a positive int, got {n!r}")
    if n == 1:
        return (TAU,)
    trees: set[RootedTree] = set()
    for smaller in trees_of_order(n - 1):
        trees |= _grow(smaller)
    return tuple(sorted(trees, key=_sort_key))


def trees_up_to(p: int) -> tuple[RootedTree, ...]:
    """All rooted trees with 1..p vertices, by order, then canonically (``p >= 1``)."""
    if not isinstance(p, int) or isinstance(p, bool) or p < 1:
        raise ValueError(f"highest tree order must be a positive int, got {p!r}")
    return tuple(tree for n in range(1, p + 1) for tree in trees_of_order(n))


def elementary_weights(
    trees: Sequence[RootedTree], a: Sequence[Sequence[sp.Expr]], b: Sequence[sp.Expr]
) -> list[sp.Expr]:
    """Elementary weights ``Phi(t) = b^T g(t)`` of a Runge-Kutta method, exact.

    Parameters
    ----------
    trees : sequence of RootedTree
    a : (s, s) nested sequence of sympy numbers
    b : (s,) sequence of sympy numbers

    Returns
    -------
    list of sympy.Expr, one per tree, expanded.
    """
    s = len(b)
    memo: dict[RootedTree, list[sp.Expr]] = {}

    def stage_vector(tree: RootedTree) -> list[sp.Expr]:  # g(t), shape (s,)
        if tree not in memo:
            g = [sp.Integer(1)] * s
            for child in tree.children:
                gc = stage_vector(child)
                ag = [sum((a[i][j] * gc[j] for j in range(s)), sp.Integer(0)) for i in range(s)]
                g = [sp.expand(g[i] * ag[i]) for i in range(s)]
            memo[tree] = g
        return memo[tree]

    return [sp.expand(sum((b[i] * stage_vector(t)[i] for i in range(s)), sp.Integer(0))) for t in trees]
