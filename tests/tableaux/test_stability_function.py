"""The numeric side of a tableau's linear stability (amplification, unstable_step, the end of a
stability interval with a gap) and the edges of its construction and display, in pure Python:
mutation survivors in `integrators/tableaux.py` (docs/mutation.md). No C is compiled.

Hand derivations next to each test; R(z) = 1 + z + ... + z^p / p! for the explicit methods of
order p <= 4 (Hairer-Wanner II, Sec. IV.2), R(z) = 1 / (1 - z) for implicit Euler.
"""
from __future__ import annotations

import math
import warnings
from fractions import Fraction

import numpy as np
import pytest
import sympy as sp

from lagcodegen.integrators import tableaux
from lagcodegen.integrators.tableaux import (
    BACKWARD_EULER,
    EULER,
    HEUN,
    IMPLICIT_MIDPOINT,
    RK4,
    ButcherTableau,
    Z,
    get_tableau,
)


@pytest.fixture(autouse=True)
def fresh_numeric_functions(monkeypatch):
    """An empty cache of lambdified R(z), so each test builds (and checks) its own entries."""
    monkeypatch.setattr(tableaux, "_NUMERIC_STABILITY_FUNCTIONS", {})


def _two_stage(name, a21, b2):
    """Explicit 2 stages: R(z) = 1 + z + b2 a21 z^2."""
    b1 = 1 - sp.Rational(b2)
    return ButcherTableau(name, [[0, 0], [a21, 0]], [b1, b2], [0, a21], 1)


# -- amplification ------------------------------------------------------------------------------
def test_amplification_by_hand():
    # RK4: R(-1) = 1 - 1 + 1/2 - 1/6 + 1/24 = 3/8; R(i) = 13/24 + 5i/6, |R|^2 = 569/576
    np.testing.assert_allclose(RK4.amplification(np.array([-1.0, 1j])), [0.375, math.sqrt(569 / 576)], rtol=1e-14)
    np.testing.assert_allclose(EULER.amplification(np.array([-3.0])), [2.0], rtol=1e-15)
    np.testing.assert_allclose(BACKWARD_EULER.amplification(np.array([-1.0, 2j])), [0.5, 1 / math.sqrt(5)], rtol=1e-15)


def test_tableaux_sharing_a_name_keep_their_own_stability_function():
    # same name and b, different a: R = 1 + z + z^2/2 and 1 + z + z^2/4 at z = -2: 1 and 0;
    # same name and a, different b: R = 1 + z + z^2/4 and 1 + z + z^2/2
    heun_like, half = _two_stage("mine", 1, "1/2"), _two_stage("mine", "1/2", "1/2")
    midpoint_like = _two_stage("mine", "1/2", 1)
    z = np.array([-2.0])
    assert heun_like.amplification(z).tolist() == [1.0]
    assert half.amplification(z).tolist() == [0.0]
    assert midpoint_like.amplification(z).tolist() == [1.0]


def test_a_huge_step_overflows_silently_and_is_unstable():
    # RK4 at z = -1e200: z^2 overflows to inf, z^4 - z^3 is inf - inf = nan; no warning escapes
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        growth = RK4.amplification(np.array([-1e200]))
        assert not growth[0] <= 1
        assert RK4.unstable_step(1e200, np.array([-1.0]), 10)[0] is True


# -- unstable_step ------------------------------------------------------------------------------
def test_unstable_step_multiplies_h_by_the_eigenvalues():
    # RK4, h lambda = 0.1 * (-30) = -3: R(-3) = 1 - 3 + 9/2 - 9/2 + 27/8 = 11/8 per step
    assert RK4.unstable_step(0.1, np.array([-30.0]), 100)[0] is True
    assert RK4.unstable_step(0.1, np.array([-20.0]), 100)[0] is False  # R(-2) = 1/3


@pytest.mark.parametrize("n_steps, unstable", [(10, False), (1000, True)])
def test_slow_growth_counts_over_the_run(n_steps, unstable):
    # explicit Euler on an undamped mode, h w = 0.1: |R| = sqrt(1.01) per step; over the run
    # 1.01^(n/2): 1.05 after 10 steps (kept), 145 after 1000 (more than tenfold)
    assert EULER.unstable_step(0.1, np.array([1j, -1j]), n_steps)[0] is unstable


@pytest.mark.parametrize("decay, unstable", [(-11.5, True), (-10.5, False)])
def test_tenfold_is_the_threshold(decay, unstable):
    # explicit Euler, h = 1: |1 + h lambda| = 10.5 (beyond tenfold) and 9.5, in one step
    assert EULER.unstable_step(1.0, np.array([decay]), 1)[0] is unstable


def test_round_off_growth_of_a_neutral_mode_is_ignored():
    # |1 + 1e-6 i| = 1 + 5e-13: within the 1e-12 allowed for round-off, however long the run
    assert EULER.unstable_step(1e-6, np.array([1j]), 10**14)[0] is False
    assert EULER.unstable_step(1e-5, np.array([1j]), 10**14)[0] is True  # 1 + 5e-11


def test_unstable_step_names_both_limits():
    # h lambda = -3, past RK4's 2.785 on the real axis (HW II, Sec. IV.2): |R(-3)| = 1.375
    unstable, region = RK4.unstable_step(1.0, np.array([-3.0]), 10)
    assert unstable and region == "h*w < 2.828 on the imaginary axis, 2.785 on the negative real axis"
    assert RK4.unstable_step(1.0, np.array([-1.0]), 10) == (False, "")


# -- stability intervals with a gap -------------------------------------------------------------
def test_real_limit_stops_at_the_first_crossing():
    # R(z) = 1 + z + 3 z^2 / 25 (a21 = 1/5, b2 = 3/5). On z = -y: R <= 1 iff y <= 25/3, and
    # R >= -1 iff 3 y^2 / 25 - y + 2 >= 0, roots (1 -+ 1/5) / (6/25) = 10/3 and 5. So |R| <= 1 on
    # [0, 10/3] and again on [5, 25/3]: the limit is 10/3, not 25/3.
    tab = _two_stage("gap", "1/5", "3/5")
    assert sp.expand(tab.stability_polynomial() - (1 + Z + sp.Rational(3, 25) * Z ** 2)) == 0
    assert tab.real_stability_limit() == pytest.approx(10 / 3, rel=1e-14)
    inside, gap, back = tab.amplification(np.array([-3.0, -4.0, -6.0]))
    assert inside <= 1 < gap and back <= 1  # 19/25, 27/25, 17/25
    assert tab.imag_stability_limit() == 0.0  # |R(iy)|^2 = 1 + 19 y^2 / 25 + 9 y^4 / 625


def test_implicit_stability_function_is_kept_as_a_fraction():
    # implicit midpoint: R = (1 + z/2) / (1 - z/2), numerator and denominator as they are
    assert sp.fraction(IMPLICIT_MIDPOINT.stability_polynomial()) == (1 + Z / 2, 1 - Z / 2)
    assert sp.fraction(BACKWARD_EULER.stability_polynomial()) == (1, 1 - Z)


# -- construction -------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["", 5])
def test_name_must_be_a_non_empty_str(name):
    with pytest.raises(ValueError, match="tableau name must be a non-empty str"):
        ButcherTableau(name, [[0]], [1], [0], 1)


def test_entry_errors_name_the_tableau_and_the_entry():
    with pytest.raises(ValueError, match=r"^tableau 'named': b\[0\] = 0\.5 must be exact \(int, Rational or a string like '1/6'\), not float$"):
        ButcherTableau("named", [[0, 0], [1, 0]], [0.5, "1/2"], [0, 1], 1)
    with pytest.raises(ValueError, match=r"^tableau 'named': c\[1\] = 1\.0 must be exact .*not float$"):
        ButcherTableau("named", [[0, 0], [1, 0]], ["1/2", "1/2"], [0, 1.0], 1)
    with pytest.raises(ValueError, match=r"row sum of a\[1\] is 1/3, but c\[1\] = 1/2$"):
        ButcherTableau("named", [[0, 0], ["1/3", 0]], ["1/2", "1/2"], [0, "1/2"], 1)
    with pytest.raises(ValueError, match=r"sum\(b\) = 2, must be 1"):
        ButcherTableau("named", [[0, 0], [1, 0]], [1, 1], [0, 1], 1)


@pytest.mark.parametrize("entry", [sp.Symbol("x", real=True), sp.Float("0.5")])
def test_real_symbols_and_floats_are_not_exact(entry):
    with pytest.raises(ValueError, match=r"a\[0\]\[0\] = .* must be an exact real number"):
        ButcherTableau("named", [[entry]], [1], [entry], 1)


def test_fractions_are_exact_rationals():
    tab = ButcherTableau("fractions", [[0, 0], [Fraction(2, 3), 0]], [Fraction(1, 4), Fraction(3, 4)],
                         [0, Fraction(2, 3)], 2)
    assert tab.a[1][0] == sp.Rational(2, 3) and tab.b == (sp.Rational(1, 4), sp.Rational(3, 4))


def test_row_sums_equal_after_simplification():
    # 1 / (1 + sqrt 2) = sqrt 2 - 1 (rationalize the denominator); expand alone does not see it
    a21 = 1 / (1 + sp.sqrt(2))
    assert sp.expand(a21 - (sp.sqrt(2) - 1)) != 0
    tab = ButcherTableau("radical", [[0, 0], [a21, 0]], ["1/2", "1/2"], [0, sp.sqrt(2) - 1], 1)
    assert tab.c[1] == sp.sqrt(2) - 1


def test_get_tableau_of_a_non_string_is_a_key_error():
    with pytest.raises(KeyError, match="unknown tableau 3"):
        get_tableau(3)


# -- display (c | A over b; blanks on and above an explicit diagonal) ----------------------------
def test_text_layout():
    # width = longest cell (3, "1/2"); cells right-aligned, two spaces apart, trailing blanks cut
    assert str(HEUN) == "\n".join([
        "heun (Heun, explicit trapezoidal rule, order 2)",
        "  0 |",
        "  1 |   1",
        "----+---------",
        "    | 1/2  1/2"])
    untitled = ButcherTableau("untitled", [["1/2", 0], [0, "1/2"]], ["1/2", "1/2"], ["1/2", "1/2"], 2)
    assert str(untitled) == "\n".join([
        "untitled (order 2)",
        "1/2 | 1/2    0",
        "1/2 |   0  1/2",
        "----+---------",
        "    | 1/2  1/2"])


def test_latex_layout():
    assert HEUN.latex() == "\n".join([
        r"\begin{array}{c|cc}",
        r"0 &  &  \\",
        r"1 & 1 &  \\",
        r"\hline",
        r" & \frac{1}{2} & \frac{1}{2}",
        r"\end{array}"])
    assert IMPLICIT_MIDPOINT.latex() == "\n".join([
        r"\begin{array}{c|c}",
        r"\frac{1}{2} & \frac{1}{2} \\",
        r"\hline",
        r" & 1",
        r"\end{array}"])


@pytest.mark.parametrize("name", sorted(tableaux.TABLEAUX))
def test_amplification_is_the_exact_stability_function_without_lambdify(name, monkeypatch):
    """|R(z)| by Horner on the coefficients of P and Q equals R evaluated exactly (sympy, 30 digits) at
    points on both axes, in the left half-plane and far out; and no lambdify is needed (it took 150 ms
    of each process's first simulate, found 2026-11-27)."""
    tableau = tableaux.TABLEAUX[name]
    exact = tableau.stability_polynomial()
    points = np.array([-0.3, -2.5, 1.5j, -1 + 2j, -7 - 0.5j, -40.0])
    monkeypatch.setattr(sp, "lambdify", lambda *args, **kwargs: pytest.fail("lambdify called"))
    ours = tableau.amplification(points)
    for z, value in zip(points, ours):
        expected = abs(complex(exact.subs(Z, sp.Float(z.real, 30) + sp.I * sp.Float(z.imag, 30)).evalf(30)))
        assert value == pytest.approx(expected, rel=1e-13), (z, value, expected)
