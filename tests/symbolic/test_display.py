"""The textbook display of the equations (issue 16, item 2), never what is emitted.

Reference: the double pendulum as Landau and Lifshitz (Mechanics, sec. 5, problem 1) write it,
M = [[(m1 + m2) l1^2, m2 l1 l2 cos(q1 - q2)], [m2 l1 l2 cos(q1 - q2), m2 l2^2]] and
F = (-(m1 + m2) g l1 sin q1 - m2 l1 l2 q2'^2 sin(q1 - q2), -m2 g l2 sin q2 + m2 l1 l2 q1'^2 sin(q1 - q2)):
the display form must equal it structurally (sympy ==, no simplify); for catalog models the
display form must equal the emitted one in value (at random points; the small models: trigsimp on
the 5-link chain takes a minute).
"""
from __future__ import annotations

import random

import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.cli.commands import main
from lagcodegen.symbolic.display import display_form


def test_the_double_pendulum_displays_as_the_textbook_writes_it():
    eom = derive_equations(catalog.double_pendulum())
    q1, q2 = eom.q
    q1d, q2d = eom.u
    P = {p.name: p for p in eom.parameters}
    m1, m2, l1, l2, g = (P[k] for k in ("m1", "m2", "l1", "l2", "g"))
    M, F = eom.display()
    assert M == sp.Matrix([[l1 ** 2 * (m1 + m2), l1 * l2 * m2 * sp.cos(q1 - q2)],
                           [l1 * l2 * m2 * sp.cos(q1 - q2), l2 ** 2 * m2]])
    assert F == sp.Matrix([-g * l1 * (m1 + m2) * sp.sin(q1) - l1 * l2 * m2 * q2d ** 2 * sp.sin(q1 - q2),
                           -g * l2 * m2 * sp.sin(q2) + l1 * l2 * m2 * q1d ** 2 * sp.sin(q1 - q2)])
    assert eom.mass_matrix != M  # the emitted form is left as derived
    assert r"\cos{\left(q_{1} - q_{2} \right)}" in eom._repr_latex_()


@pytest.mark.parametrize("name", ["elastic_pendulum", "centrifugal_governor", "disk_spring_rod", "cartesian_pendulum"])
def test_the_display_form_has_the_same_value(name):
    eom = derive_equations(catalog.EXAMPLES[name]())
    rng = random.Random(7)
    M, F = eom.display()
    symbols = sorted((eom.mass_matrix.free_symbols | eom.forcing.free_symbols), key=str)
    for _ in range(2):
        at = {s: sp.Float(rng.uniform(0.3, 1.3)) for s in symbols}
        for shown, emitted in ((M, eom.mass_matrix), (F, eom.forcing)):
            difference = (sp.Matrix(shown) - sp.Matrix(emitted)).xreplace(at).evalf()
            assert all(abs(v) < 1e-9 for v in difference), name


def test_display_form_leaves_numbers_and_plain_products():
    x, y = sp.symbols("x y")
    assert display_form(sp.Integer(3)) == 3
    assert display_form(x * y + x) == x * (y + 1)


def test_the_cli_prints_the_display_form_and_latex(capsys):
    assert main(["derive", "double_pendulum", "--display"]) == 0
    assert "M[0, 1] = l1*l2*m2*cos(q1 - q2)" in capsys.readouterr().out
    assert main(["derive", "double_pendulum", "--latex"]) == 0
    assert r"\ddot{q_{1}}" in capsys.readouterr().out
