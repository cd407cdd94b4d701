"""Butcher tableaux: consistency, exact order conditions, linear stability.

Models: ``scipy/integrate/_ivp/tests/test_rk.py`` (coefficient identities) and
``ketch/nodepy: nodepy/unit_tests.py`` (order and stability of named methods). Every
expected value cites its independent source: a textbook, a hand derivation shown in the
comment, or a second computational route (numpy floats instead of the module's exact
sympy route).
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
import sympy as sp

from lagcodegen.integrators.order_conditions import TAU, RootedTree, trees_of_order, trees_up_to
from lagcodegen.integrators.tableaux import (
    BACKWARD_EULER,
    DOPRI5,
    EULER,
    HEUN,
    IMPLICIT_MIDPOINT,
    KUTTA3,
    MIDPOINT_EXPLICIT,
    RADAU_IIA3,
    RK4,
    RK38,
    SDIRK2,
    TABLEAUX,
    ButcherTableau,
    Z,
    get_tableau,
)

ALL = pytest.mark.parametrize("tab", list(TABLEAUX.values()), ids=list(TABLEAUX))
EXPLICIT = [t for t in TABLEAUX.values() if t.explicit]
IMPLICIT = [t for t in TABLEAUX.values() if not t.explicit]


def R_numeric(tab: ButcherTableau, z):
    """R(z) = 1 + z b^T (I - z A)^{-1} 1 by float linear solves (HW II, Sec. IV.3), for a scalar
    or an array of z; independent of the module's exact series/determinant route."""
    z = np.asarray(z, dtype=complex)
    s = tab.stages
    lhs = np.eye(s) - z[..., None, None] * tab.a_float
    k = np.linalg.solve(lhs, np.ones(z.shape + (s, 1), dtype=complex))[..., 0]
    return 1 + z * (k @ tab.b_float)


def first_exit(tab: ButcherTableau, direction: complex, y_max: float = 6.0) -> float:
    """First y > 0 where |R(y * direction)| exceeds 1, by grid scan + brentq on the float route."""
    ys = np.linspace(1e-3, y_max, 60001)
    bad = np.nonzero(np.abs(R_numeric(tab, ys * direction)) - 1 > 1e-13)[0]
    assert bad.size, f"{tab.name}: no exit below {y_max}"
    i = bad[0]
    excess = lambda y: abs(complex(R_numeric(tab, y * direction))) - 1
    return scipy.optimize.brentq(excess, ys[i - 1], ys[i], xtol=1e-14)


# -- rooted trees -----------------------------------------------------------------------------
def test_tree_counts_match_oeis_a000081():
    # OEIS A000081: number of rooted trees with n nodes: 1, 1, 2, 4, 9, 20, 48, 115.
    assert [len(trees_of_order(n)) for n in range(1, 9)] == [1, 1, 2, 4, 9, 20, 48, 115]
    assert len(trees_up_to(6)) == 37  # partial sums of A000081: 37 conditions for order 6


def test_tree_generator_is_consistent_with_butcher_identities():
    # alpha(t) = n!/(sigma(t) gamma(t)) counts the monotone labellings of t (HNW I, Sec. II.2),
    # so summed over |t| = n it counts increasing trees on n nodes: (n-1)!, since node k+1
    # hangs off any of the k earlier nodes. Checks symmetry, density and completeness at once.
    for n in range(1, 8):
        trees = trees_of_order(n)
        assert len(set(trees)) == len(trees)
        assert sum(math.factorial(n) // (t.symmetry * t.density) for t in trees) == math.factorial(n - 1)


def test_tree_densities_of_low_order():
    # gamma of [tau tau] is 3 and of [[tau]] is 6: the conditions b.c^2 = 1/3, b.A.c = 1/6.
    assert RootedTree((TAU, TAU)).density == 3
    assert RootedTree((RootedTree((TAU,)),)).density == 6
    assert RootedTree((TAU, RootedTree((TAU,)))) == RootedTree((RootedTree((TAU,)), TAU))  # canonical
    assert str(RootedTree((TAU, RootedTree((TAU,))))) == "[τ [τ]]"


# -- consistency and order ----------------------------------------------------------------------
@ALL
def test_registry_key_is_name(tab):
    assert get_tableau(tab.name) is tab
    assert get_tableau(tab.name.upper()) is tab


@ALL
def test_row_sums_and_weights_exact(tab):
    for i in range(tab.stages):
        assert sp.simplify(sum(tab.a[i]) - tab.c[i]) == 0
    assert sp.simplify(sum(tab.b) - 1) == 0
    np.testing.assert_allclose(tab.a_float.sum(axis=1), tab.c_float, atol=1e-15)
    assert tab.a_float.shape == (tab.stages, tab.stages) and tab.b_float.shape == (tab.stages,)


@ALL
def test_order_conditions_hold_up_to_declared_order(tab):
    residuals = tab.order_conditions(tab.order)
    assert len(residuals) == len(trees_up_to(tab.order))
    nonzero = {str(t): r for t, r in residuals.items() if sp.simplify(r) != 0}
    assert not nonzero, nonzero
    assert tab.satisfies_order(tab.order)


@ALL
def test_order_conditions_fail_at_next_order(tab):
    # None of the registered methods is superconvergent for general f: each is known to have
    # exactly its declared order (sources in tableaux.py).
    assert not tab.satisfies_order(tab.order + 1)
    failing = [t for t, r in tab.order_conditions(tab.order + 1).items() if sp.simplify(r) != 0]
    assert failing and all(t.order == tab.order + 1 for t in failing)


def hand_conditions(tab: ButcherTableau) -> list[float]:
    """The 8 conditions for order 4 written out (Kutta 1901; HNW I, Sec. II.1), float route."""
    A, b, c = tab.a_float, tab.b_float, tab.c_float
    return [b.sum() - 1, b @ c - 1 / 2, b @ c**2 - 1 / 3, b @ A @ c - 1 / 6, b @ c**3 - 1 / 4,
            b @ (c * (A @ c)) - 1 / 8, b @ A @ c**2 - 1 / 12, b @ A @ A @ c - 1 / 24]


@ALL
def test_tree_conditions_agree_with_hand_written_ones(tab):
    # Orders 1..4 have 1, 1, 2, 4 conditions; hand_conditions lists them in that grouping.
    hand = hand_conditions(tab)
    for p, n_cond in zip(range(1, 5), (1, 2, 4, 8)):
        assert tab.satisfies_order(p) == bool(np.allclose(hand[:n_cond], 0, atol=1e-13)), p


# -- stability polynomial of explicit methods --------------------------------------------------
@pytest.mark.parametrize("tab", EXPLICIT, ids=[t.name for t in EXPLICIT])
def test_stability_polynomial_starts_with_exponential(tab):
    # Order p implies R(z) = e^z + O(z^{p+1}): coefficients 1/k! for k <= p (HW II, Sec. IV.2);
    # degree <= s for an explicit s-stage method.
    poly = sp.Poly(tab.stability_polynomial(), Z)
    assert poly.degree() <= tab.stages
    coeffs = [poly.coeff_monomial(Z**k) for k in range(tab.order + 1)]
    assert coeffs == [sp.Rational(1, math.factorial(k)) for k in range(tab.order + 1)]
    assert poly.coeff_monomial(Z ** (tab.order + 1)) != sp.Rational(1, math.factorial(tab.order + 1))


def test_dopri5_stability_polynomial_tail():
    # HW II, Sec. IV.2: DOPRI5's R(z) = sum_{k<=5} z^k/k! + z^6/600.
    expected = sum(Z**k / sp.factorial(k) for k in range(6)) + Z**6 / 600
    assert sp.expand(DOPRI5.stability_polynomial() - expected) == 0


@ALL
def test_stability_function_matches_float_linear_solve(tab):
    R = sp.lambdify(Z, tab.stability_polynomial(), "numpy")
    for z in (-0.7, 0.3 + 1.1j, -2.5 - 0.4j, 1.7j):
        assert abs(complex(R(z)) - complex(R_numeric(tab, z))) < 1e-12


# -- stability limits -------------------------------------------------------------------------
@pytest.mark.parametrize(
    "tab, literature",
    # Stability regions of the p = s = 1..4 methods (HW II, Sec. IV.2, Fig. 2.1): real
    # intervals [-2, 0], [-2, 0], [-2.5127, 0], [-2.7853, 0]. Euler: |1 - y| <= 1 iff y <= 2;
    # order 2: 1 - y + y^2/2 = 1 at y = 2. No literature value for DOPRI5 is used: the float
    # route below is its independent check.
    [(EULER, 2.0), (HEUN, 2.0), (MIDPOINT_EXPLICIT, 2.0), (KUTTA3, 2.5127), (RK4, 2.7853),
     (RK38, 2.7853), (DOPRI5, None)],
    ids=lambda v: getattr(v, "name", ""),
)
def test_real_stability_limit(tab, literature):
    limit = tab.real_stability_limit()
    if literature is not None:
        assert limit == pytest.approx(literature, abs=1e-4)
    assert limit == pytest.approx(first_exit(tab, -1.0), abs=1e-10)  # independent float route


@pytest.mark.parametrize(
    "tab, exact",
    # Hand derivations of |R(iy)|^2 for R = truncated exponential:
    #   Euler 1 + y^2 and Heun/midpoint 1 + y^4/4 exceed 1 for all y > 0: limit 0;
    #   Kutta3 1 - y^4/12 + y^6/36 = 1 at y^2 = 3; RK4 1 - y^6/72 + y^8/576 = 1 at y^2 = 8
    #   (HW II, Sec. IV.2: RK4 contains [-2.83i, 2.83i]).
    [(EULER, 0.0), (HEUN, 0.0), (MIDPOINT_EXPLICIT, 0.0), (KUTTA3, math.sqrt(3)),
     (RK4, 2 * math.sqrt(2)), (RK38, 2 * math.sqrt(2))],
    ids=lambda v: getattr(v, "name", ""),
)
def test_imag_stability_limit(tab, exact):
    assert tab.imag_stability_limit() == pytest.approx(exact, abs=1e-10)


def test_dopri5_imag_limit_matches_float_route():
    # The small imaginary-axis interval of DOPRI5, from |R(iy)|^2 - 1 ~ -y^6/1800 near 0.
    limit = DOPRI5.imag_stability_limit()
    assert 0.9 < limit < 1.1
    assert limit == pytest.approx(first_exit(DOPRI5, 1j, y_max=2.0), abs=1e-10)


@pytest.mark.parametrize("tab", IMPLICIT, ids=[t.name for t in IMPLICIT])
def test_implicit_methods_are_a_stable(tab):
    # A-stability: |R(z)| <= 1 on Re z <= 0 (HW II, Sec. IV.3); by the maximum
    # principle a grid of the closed left half-plane suffices as a check.
    R = sp.lambdify(Z, tab.stability_polynomial(), "numpy")
    x = -np.concatenate([[0.0], np.logspace(-3, 4, 60)])
    y = np.concatenate([-np.logspace(-3, 4, 60), [0.0], np.logspace(-3, 4, 60)])
    zz = x[:, None] + 1j * y[None, :]
    assert np.all(np.abs(R(zz)) <= 1 + 1e-12)
    assert tab.real_stability_limit() == math.inf
    assert tab.imag_stability_limit() == math.inf


@pytest.mark.parametrize("theta", [sp.Rational(1, 4), sp.sqrt(2) / 4], ids=["1/4", "sqrt2/4"])
def test_limits_of_a_non_a_stable_implicit_method(theta):
    # theta-method, theta < 1/2: R(z) = (1 + (1 - theta) z) / (1 - theta z). Hand derivation:
    # on z = -y, R >= -1 iff y (1 - 2 theta) <= 2, so the real limit is 2 / (1 - 2 theta);
    # on z = iy, |R|^2 - 1 = (1 - 2 theta) y^2 / |1 - i theta y|^2 > 0, so the limit is 0.
    # theta = sqrt(2)/4 exercises the algebraic-coefficient root finder.
    tab = ButcherTableau("theta", [[theta]], [1], [theta], 1)
    assert tab.real_stability_limit() == pytest.approx(float(2 / (1 - 2 * theta)), abs=1e-10)
    assert tab.imag_stability_limit() == 0.0


@pytest.mark.parametrize("tab", [BACKWARD_EULER, SDIRK2, RADAU_IIA3], ids=lambda t: t.name)
def test_l_stable_methods_damp_infinity(tab):
    # L-stability: A-stable (tested above) and R(inf) = 0 (HW II, Sec. IV.3).
    assert sp.limit(tab.stability_polynomial(), Z, sp.oo) == 0


@pytest.mark.parametrize(
    "tab, pade",
    # Pade approximants of e^z (HW II, Sec. IV.3-IV.5): backward Euler (0,1), implicit midpoint
    # (1,1), Radau IIA s = 2 the (1,2) subdiagonal one.
    [(BACKWARD_EULER, 1 / (1 - Z)), (IMPLICIT_MIDPOINT, (1 + Z / 2) / (1 - Z / 2)),
     (RADAU_IIA3, (1 + Z / 3) / (1 - 2 * Z / 3 + Z**2 / 6))],
    ids=lambda v: getattr(v, "name", ""),
)
def test_implicit_stability_functions_are_pade(tab, pade):
    assert sp.simplify(tab.stability_polynomial() - pade) == 0


def test_implicit_midpoint_preserves_modulus_on_imaginary_axis():
    # |R(iy)| = 1 exactly: the undamped oscillator keeps its amplitude (symplectic, HW II IV.3).
    y = sp.Symbol("y", real=True)
    R = IMPLICIT_MIDPOINT.stability_polynomial()
    assert sp.simplify(R.subs(Z, sp.I * y) * R.subs(Z, -sp.I * y) - 1) == 0
    assert sp.limit(R, Z, sp.oo) == -1  # A-stable, not L-stable


def test_structure_flags():
    assert all(t.explicit and t.kind == "explicit" for t in EXPLICIT)
    assert [t.name for t in IMPLICIT if t.diagonally_implicit] == [
        "backward_euler", "implicit_midpoint", "sdirk2"]
    assert RADAU_IIA3.kind == "implicit" and not RADAU_IIA3.diagonally_implicit
    assert DOPRI5.stages == 7 and RK4.stages == 4


# -- construction and validation ---------------------------------------------------------------
def test_entries_become_exact():
    tab = ButcherTableau("mine", [[0, 0], ["2/3", 0]], [sp.Rational(1, 4), "0.75"], [0, "2/3"], 2)
    assert tab.a == ((0, 0), (sp.Rational(2, 3), 0)) and tab.b == (sp.Rational(1, 4), sp.Rational(3, 4))
    assert all(isinstance(x, sp.Rational) for x in tab.b + tab.c)
    assert SDIRK2.a[0][0] == 1 - sp.sqrt(2) / 2  # algebraic entries stay exact


def test_sum_b_not_one_is_rejected_by_name():
    with pytest.raises(ValueError, match=r"'bad_weights'.*sum\(b\)"):
        ButcherTableau("bad_weights", [[0, 0], ["1/2", 0]], ["1/2", "1/3"], [0, "1/2"], 1)


def test_wrong_row_sum_is_rejected_by_name():
    with pytest.raises(ValueError, match=r"'bad_rows'.*row sum of a\[1\]"):
        ButcherTableau("bad_rows", [[0, 0], ["1/3", 0]], ["1/2", "1/2"], [0, "1/2"], 1)


@pytest.mark.parametrize(
    "a, b, c, order, message",
    [([[0, 0]], [1], [0], 1, "square"),
     ([[0]], [1, 0], [0], 1, "len"),
     ([[0.5]], [1], [0.5], 1, r"a\[0\]\[0\].*exact"),
     ([[sp.Symbol("x")]], [1], [0], 1, "exact real"),
     ([[0]], [1], [0], 0, "order"),
     ([[0]], [1], [0], True, "order")],
)
def test_malformed_tableaux_are_rejected(a, b, c, order, message):
    with pytest.raises(ValueError, match=rf"'broken'.*{message}"):
        ButcherTableau("broken", a, b, c, order)


def test_unknown_name_lists_known_ones():
    with pytest.raises(KeyError, match="rk4.*sdirk2|sdirk2.*rk4"):
        get_tableau("rk5")


def test_readable_output():
    text = str(RK4)
    assert text.splitlines()[0].startswith("rk4") and "1/6" in text and "1/3" in text
    tex = RADAU_IIA3.latex()
    assert tex.startswith(r"\begin{array}{c|cc}") and r"\frac{5}{12}" in tex and r"\hline" in tex
