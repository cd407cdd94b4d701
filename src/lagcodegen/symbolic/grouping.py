"""Helper: sums of many products, grouped before any CSE, and cheap exact rewrites.

Deriving M and F of a multibody system sums m_i * (product of partial velocities) over bodies;
`GroupedSum` merges equal products across bodies so that a chain's M_jk comes out as
(m_k + ... + m_n) * (...), `merge_pythagorean` folds c sin^2 + c cos^2 into c, and
`sparse_diff` and `components` avoid sympy's general machinery where the structure is known.
"""
from __future__ import annotations

import sympy as sp


class GroupedSum:
    """Per-entry sums of ``coefficient * term``, grouping equal terms and equal coefficients.

    Summing m_i * X over bodies i that share the product X yields (m_a + m_b + ...) * X:
    one product instead of one per body, before any CSE.
    """

    def __init__(self):
        self.entries: dict = {}

    def add(self, index, coefficient, expr) -> None:
        terms = self.entries.setdefault(index, {})
        if expr.is_Add or any(factor.is_Add for factor in sp.Mul.make_args(expr)):
            expr = sp.expand_mul(expr)
        for term in sp.Add.make_args(expr):
            coeff, rest = term.as_coeff_Mul()
            terms.setdefault(rest, []).append(coeff * coefficient)

    def add_dot(self, index, coefficient, a, b) -> None:
        """Add coefficient * a.b for column vectors a, b."""
        for ai, bi in zip(a, b):
            if ai != 0 and bi != 0:
                self.add(index, coefficient, ai * bi)

    def value(self, index):
        terms = self.entries.get(index, {})
        grouped = _by_coefficient(terms)
        for _ in range(2):  # a Pythagorean merge can produce a term that already exists
            regrouped: dict = {}
            merged = False
            for coefficient, group in grouped.items():
                kept = merge_pythagorean(group)
                merged |= len(kept) < len(group)
                for term in kept:
                    coeff, rest = term.as_coeff_Mul()
                    regrouped.setdefault(rest, []).append(coeff * coefficient)
            if not merged:
                break
            grouped = _by_coefficient(regrouped)
        return sp.Add(*[c * sp.Add(*group) for c, group in grouped.items()])


def _by_coefficient(terms: dict) -> dict:
    grouped: dict = {}
    for term, coefficients in terms.items():
        coefficient = _factored_sum(coefficients)
        if coefficient.could_extract_minus_sign():  # -m * X and m * Y share the group m * (Y - X)
            coefficient, term = -coefficient, -term
        if coefficient != 0:
            grouped.setdefault(coefficient, []).append(term)
    return grouped


def _factored_sum(terms: list):
    """sum(terms) with what every term shares pulled out: 2*l1*l2*m2 + 2*l1*l2*m3 ->
    2*l1*l2*(m2 + m3). Exact factors only (no gcd of powers); cheaper than sympy's factor_terms."""
    terms = [t for t in terms if t != 0]  # a zero's number would divide the others below (0/0)
    if len(terms) <= 1:
        return terms[0] if terms else sp.S.Zero
    split = [t.as_coeff_Mul() for t in terms]
    shared = set(sp.Mul.make_args(split[0][1]))
    for _, rest in split[1:]:
        shared &= set(sp.Mul.make_args(rest))
    numbers = {number for number, _ in split}
    number = numbers.pop() if len(numbers) == 1 else sp.S.One
    if not shared and number == 1:
        return sp.Add(*terms)
    inner = [sp.Mul(n / number, *[f for f in sp.Mul.make_args(rest) if f not in shared]) for n, rest in split]
    content, primitive = sp.Add(*inner).as_content_primitive()  # 2*m3 + 2*m4 -> 2, m3 + m4
    return number * content * sp.Mul(*shared) * primitive


def merge_pythagorean(terms: list) -> list:
    """Replace each pair c*sin(x)**2, c*cos(x)**2 in ``terms`` by c (exact, cheap, no trigsimp)."""
    terms = list(terms)
    changed = True
    while changed:
        changed = False
        seen: dict = {}
        for i, term in enumerate(terms):
            for factor in sp.Mul.make_args(term):
                if factor.is_Pow and factor.exp == 2 and isinstance(factor.base, (sp.sin, sp.cos)):
                    rest = sp.Mul(*[f for f in sp.Mul.make_args(term) if f is not factor])
                    key = (rest, factor.base.args[0])
                    partner = seen.get((key, sp.cos if isinstance(factor.base, sp.sin) else sp.sin))
                    if partner is not None:
                        terms[partner], terms[i] = rest, sp.S.Zero
                        changed = True
                        break
                    seen[(key, type(factor.base))] = i
            if changed:
                break
        terms = [t for t in terms if t != 0]
    return terms


def components(vector, frame) -> sp.Matrix:
    """Components (3, 1) of a sympy.physics.vector Vector in ``frame``.

    Vector.to_matrix takes three dot products through the frames' bases; summing each stored
    (measure, frame) part rotated by the cached direction cosine matrix is cheaper.
    """
    parts = [measure if part == frame else frame.dcm(part) * measure for measure, part in vector.args]
    if len(parts) == 1:
        return parts[0]
    return sp.ImmutableMatrix([sp.Add(*[p[i] for p in parts]) for i in range(3)])  # one matrix, not a sum


def sparse_diff(expr, x):
    """d expr / dx, applying the sum and product rules only to the parts that contain x."""
    if x not in expr.free_symbols:
        return sp.S.Zero
    if expr.is_Add:
        return sp.Add(*[sparse_diff(arg, x) for arg in expr.args])
    if expr.is_Mul:
        args = expr.args
        return sp.Add(*[sp.Mul(*args[:i], sparse_diff(f, x), *args[i + 1:])
                        for i, f in enumerate(args) if x in f.free_symbols])
    if expr == x:
        return sp.S.One
    if isinstance(expr, (sp.sin, sp.cos)):  # the chain rule without sympy's Derivative machinery
        inner = sparse_diff(expr.args[0], x)
        return sp.cos(expr.args[0]) * inner if isinstance(expr, sp.sin) else -sp.sin(expr.args[0]) * inner
    if expr.is_Pow and expr.exp.is_Integer and x not in expr.exp.free_symbols:
        return expr.exp * expr.base ** (expr.exp - 1) * sparse_diff(expr.base, x)
    return expr.diff(x)
