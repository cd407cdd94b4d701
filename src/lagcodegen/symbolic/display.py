"""Helper: the textbook display of the equations (never what is emitted).

The emitted form of M and F is chosen for speed (`codegen/reduce.py` runs CSE on it as derived);
a reader wants what a textbook prints: ``m2 l1 l2 cos(q1 - q2)``, not
``m2*(l1*l2*sin(q1)*sin(q2) + l1*l2*cos(q1)*cos(q2))``. `display_form` expands, combines
trigonometric sums into angle sums and differences (``trigsimp``), then collects the terms by
their trigonometric factors with each coefficient factored. Imports no stage.
"""
from __future__ import annotations

import sympy as sp


def display_form(expr):
    """``expr`` as a textbook prints it: angle differences combined, common factors pulled out."""
    expr = sp.sympify(expr)
    if expr.is_number or not expr.free_symbols:
        return expr
    combined = sp.expand(sp.trigsimp(sp.expand(sp.expand_trig(expr))))
    factors = sorted(combined.atoms(sp.sin, sp.cos, sp.tan), key=sp.default_sort_key)
    if not factors:
        return sp.factor(combined)
    return sp.collect(combined, factors, func=sp.factor)


def display_matrix(matrix) -> sp.ImmutableMatrix:
    return sp.ImmutableMatrix(sp.Matrix(matrix).applyfunc(display_form))


def display_equations(eom) -> tuple:
    """(M, F) of ``eom`` (an `EquationsOfMotion`) in display form."""
    return display_matrix(eom.mass_matrix), display_matrix(eom.forcing)


def latex_equations(eom) -> str:
    """``M(q, t) \\dot u = F(q, u, t)`` in LaTeX, display form (and ``\\dot q = K`` when K is not u)."""
    M, F = display_equations(eom)
    rates = list(eom.kinematics)
    permuted = sorted(rates, key=str) == sorted(eom.u, key=str)  # u = qd, perhaps reordered (dependent speeds last)
    if permuted:  # the accelerations are qdd
        ud = sp.Matrix([sp.Symbol(rf"\ddot{{{sp.latex(eom.q[rates.index(u)])}}}") for u in eom.u])
    else:
        ud = sp.Matrix([sp.Symbol(rf"\dot{{{sp.latex(u)}}}") for u in eom.u])
    text = rf"{sp.latex(M)} {sp.latex(ud)} = {sp.latex(F)}"
    if not permuted:
        qd = sp.Matrix([sp.Symbol(rf"\dot{{{sp.latex(q)}}}") for q in eom.q])
        text += rf", \quad {sp.latex(qd)} = {sp.latex(display_matrix(eom.kinematics))}"
    return text
