"""Helper: integration schemes as data.

A Runge-Kutta method for ``y' = f(t, y)`` with step ``h`` is its Butcher tableau::

    k_i     = f(t_n + c_i h, y_n + h sum_j a_ij k_j),   i = 1..s
    y_{n+1} = y_n + h sum_i b_i k_i

`ButcherTableau` holds ``a`` (s, s), ``b`` (s,), ``c`` (s,) as exact sympy numbers and
validates them; the emitter prints them as ``static const`` arrays and the C stepper reads
them, so no method has hand-written C. Order conditions (rooted trees, `order_conditions`) and
linear stability (``R(z)`` for ``y' = lambda y``, ``z = h lambda``) are computed from the
same data, so the declared ``order`` and the stability limits are checked, not trusted.
This module imports no pipeline stage.

References: Hairer, Norsett, Wanner, *Solving ODEs I* (2nd ed., 1993), Secs. II.1-II.5;
Hairer, Wanner, *Solving ODEs II* (2nd ed., 1996), Secs. IV.2-IV.6; Butcher, *Numerical
Methods for ODEs* (3rd ed., 2016), Ch. 3.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np
import sympy as sp

from .order_conditions import RootedTree, elementary_weights, trees_up_to

Z = sp.Symbol("z")  # h * lambda, the argument of the stability function
_Y = sp.Symbol("y", real=True)  # distance along the negative real or the imaginary axis


def _is_zero(expr: sp.Expr) -> bool:
    expr = sp.expand(expr)
    return expr == 0 or sp.simplify(expr) == 0


def _exact(value: Any, tableau: str, where: str) -> sp.Expr:
    """An exact real sympy number from an int, Rational, "1/6"-style string or sympy number."""
    what = f"tableau {tableau!r}: {where} = {value!r}"
    if isinstance(value, str):
        try:
            value = sp.sympify(value, rational=True)  # "0.1" means exactly 1/10
        except (sp.SympifyError, SyntaxError, TypeError) as exc:
            raise ValueError(f"{what} is not a number") from exc
    if isinstance(value, sp.Basic):
        if not (value.is_number and value.is_real) or value.has(sp.Float):
            raise ValueError(f"{what} must be an exact real number (no symbols, no Floats)")
        return value
    if isinstance(value, bool) or not isinstance(value, numbers.Rational):
        kind = type(value).__name__
        raise ValueError(f"{what} must be exact (int, Rational or a string like '1/6'), not {kind}")
    return sp.Rational(value.numerator, value.denominator)


_NUMERIC_STABILITY_FUNCTIONS: dict = {}  # tableau -> numpy R(z); kept out of the (picklable) tableau


def _numeric_stability_function(tableau):
    """R(z) = P(z) / Q(z) for numpy arrays, by Horner on the coefficients (sympy's lambdify of R took
    150 ms of the first simulate() of a process; a key of the coefficients' strings 0.3 ms of each)."""
    key = tableau  # frozen: hashed by its coefficients
    if key not in _NUMERIC_STABILITY_FUNCTIONS:
        P, Q = tableau._stability_parts
        top = np.array([complex(c) for c in P.all_coeffs()])
        bottom = np.array([complex(c) for c in Q.all_coeffs()])
        _NUMERIC_STABILITY_FUNCTIONS[key] = lambda z: np.polyval(top, z) / np.polyval(bottom, z)
    return _NUMERIC_STABILITY_FUNCTIONS[key]


@dataclass(frozen=True)
class ButcherTableau:
    """A Runge-Kutta method ``(A, b, c)`` with exact coefficients and a declared order.

    Parameters
    ----------
    name : str
        Registry key and C identifier fragment, e.g. ``"rk4"``.
    a : (s, s) nested sequence
        Stage coefficients; entries are ints, Rationals, strings like ``"1/6"`` or exact
        sympy numbers such as ``1 - sqrt(2)/2``. Stored as a tuple of row tuples.
    b : (s,) sequence
        Weights, ``sum(b) == 1``.
    c : (s,) sequence
        Nodes, ``c_i == sum_j a_ij``.
    order : int
        Declared order ``p``; `satisfies_order` checks it.
    title : str, optional
        Human-readable description with its source.

    Raises
    ------
    ValueError
        Naming the tableau and the failing check (entry, shape, row sum, ``sum(b)``, order).
    """

    name: str
    a: tuple[tuple[sp.Expr, ...], ...]
    b: tuple[sp.Expr, ...]
    c: tuple[sp.Expr, ...]
    order: int
    title: str = ""

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise ValueError(f"tableau name must be a non-empty str, got {self.name!r}")
        name = self.name
        try:
            rows, b, c = [tuple(row) for row in self.a], tuple(self.b), tuple(self.c)
        except TypeError as exc:
            raise ValueError(f"tableau {name!r}: a must be (s, s), b and c (s,) sequences") from exc
        s = len(rows)
        if s == 0 or any(len(row) != s for row in rows):
            raise ValueError(f"tableau {name!r}: a must be square, got row lengths {[len(r) for r in rows]}")
        if len(b) != s or len(c) != s:
            raise ValueError(f"tableau {name!r}: len(b) = {len(b)} and len(c) = {len(c)} must equal s = {s}")
        a = tuple(tuple(_exact(x, name, f"a[{i}][{j}]") for j, x in enumerate(r)) for i, r in enumerate(rows))
        b = tuple(_exact(x, name, f"b[{i}]") for i, x in enumerate(b))
        c = tuple(_exact(x, name, f"c[{i}]") for i, x in enumerate(c))
        for i in range(s):
            if not _is_zero(sum(a[i]) - c[i]):
                row_sum = sp.expand(sum(a[i]))
                raise ValueError(f"tableau {name!r}: row sum of a[{i}] is {row_sum}, but c[{i}] = {c[i]}")
        if not _is_zero(sum(b) - 1):
            raise ValueError(f"tableau {name!r}: sum(b) = {sp.expand(sum(b))}, must be 1")
        if isinstance(self.order, bool) or not isinstance(self.order, int) or self.order < 1:
            raise ValueError(f"tableau {name!r}: order must be a positive int, got {self.order!r}")
        for field, value in (("a", a), ("b", b), ("c", c)):
            object.__setattr__(self, field, value)  # frozen: store the exact, validated form

    # -- structure -------------------------------------------------------------------------
    @property
    def stages(self) -> int:
        """Number of stages ``s``."""
        return len(self.b)

    @property
    def explicit(self) -> bool:
        """True if ``a`` is strictly lower triangular (each stage uses earlier ones only)."""
        return all(self.a[i][j] == 0 for i in range(self.stages) for j in range(i, self.stages))

    # -- the scheme protocol (`schemes.Scheme`) ---------------------------------------------
    @property
    def stepper(self) -> str:
        """The C stepper that runs this tableau: ``"explicit"`` or ``"implicit"`` (Newton)."""
        return "explicit" if self.explicit else "implicit"

    @property
    def outputs(self) -> tuple:
        """Kernel outputs the stepper needs: the rhs, and the Jacobian for Newton's iteration."""
        return ("rhs",) if self.explicit else ("rhs", "jacobian")

    @property
    def lane_capable(self) -> bool:
        """Whether the lane-group sweep kernel can run it (explicit stages only)."""
        return self.explicit

    @property
    def implicit(self) -> bool:
        return not self.explicit

    @property
    def diagonally_implicit(self) -> bool:
        """True for DIRK methods: ``a`` lower triangular with a nonzero diagonal entry."""
        lower = all(self.a[i][j] == 0 for i in range(self.stages) for j in range(i + 1, self.stages))
        return lower and not self.explicit

    @property
    def kind(self) -> str:
        """``"explicit"``, ``"diagonally_implicit"`` or ``"implicit"`` (fully implicit)."""
        if self.explicit:
            return "explicit"
        return "diagonally_implicit" if self.diagonally_implicit else "implicit"

    @property
    def a_float(self) -> np.ndarray:
        """``a`` as float64, shape (s, s)."""
        return np.array([[float(x) for x in row] for row in self.a], dtype=float)

    @property
    def b_float(self) -> np.ndarray:
        """``b`` as float64, shape (s,)."""
        return np.array([float(x) for x in self.b], dtype=float)

    @property
    def c_float(self) -> np.ndarray:
        """``c`` as float64, shape (s,)."""
        return np.array([float(x) for x in self.c], dtype=float)

    # -- order -----------------------------------------------------------------------------
    def order_conditions(self, p: int) -> dict[RootedTree, sp.Expr]:
        """Residuals ``Phi(t) - 1/gamma(t)`` of the order conditions for all trees ``|t| <= p``.

        The method has order ``>= p`` iff all residuals vanish (HNW I, Sec. II.2; Butcher
        2016, Ch. 3).

        Parameters
        ----------
        p : int
            Highest tree order, ``p >= 1``.

        Returns
        -------
        dict of RootedTree to sympy.Expr
            Exact, expanded residuals; keys ordered by tree order, ``str(tree)`` is Butcher's
            bracket notation (``[τ [τ]]``).
        """
        trees = trees_up_to(p)
        weights = elementary_weights(trees, self.a, self.b)
        return {t: sp.expand(phi - sp.Rational(1, t.density)) for t, phi in zip(trees, weights)}

    def satisfies_order(self, p: int) -> bool:
        """True if every order condition up to order ``p`` holds exactly.

        Parameters
        ----------
        p : int
            Order to check, ``p >= 1``.
        """
        return all(_is_zero(r) for r in self.order_conditions(p).values())

    # -- linear stability ------------------------------------------------------------------
    @cached_property
    def _stability_parts(self) -> tuple[sp.Poly, sp.Poly]:
        """``(P, Q)`` with ``R(z) = P(z) / Q(z)``, as polynomials in `Z`."""
        s = self.stages
        A, b, e = sp.Matrix(self.a), sp.Matrix([self.b]), sp.ones(s, 1)
        if self.explicit:  # A nilpotent: R(z) = 1 + sum_k z^k b^T A^(k-1) 1
            terms, v = [sp.Integer(1)], e
            for k in range(1, s + 1):
                terms.append((b * v)[0, 0] * Z**k)
                v = A * v
            return sp.Poly(sp.expand(sum(terms)), Z), sp.Poly(1, Z)
        eye = sp.eye(s)  # R(z) = det(I - zA + z 1 b^T) / det(I - zA)  (HW II, Sec. IV.3)
        P = sp.expand((eye - Z * A + Z * e * b).det(method="berkowitz"))
        Q = sp.expand((eye - Z * A).det(method="berkowitz"))
        return sp.Poly(P, Z), sp.Poly(Q, Z)

    def stability_polynomial(self) -> sp.Expr:
        """Stability function ``R(z) = 1 + z b^T (I - z A)^{-1} 1`` in the symbol `Z`.

        One step of ``y' = lambda y`` multiplies ``y`` by ``R(h lambda)`` (Hairer-Wanner II,
        Sec. IV.2-IV.3).

        Returns
        -------
        sympy.Expr
            Expanded polynomial in `Z` for explicit methods (use ``sympy.Poly(R, Z)`` for its
            coefficients); the rational function ``P(z) / Q(z)`` otherwise.
        """
        P, Q = self._stability_parts
        if Q.degree() == 0:
            return sp.expand(P.as_expr() / Q.as_expr())
        return P.as_expr() / Q.as_expr()

    def real_stability_limit(self) -> float:
        """Largest ``x`` with ``|R(-y)| <= 1`` for all ``y`` in ``[0, x]``; ``inf`` if unbounded.

        Stiffness bound for a damped mode ``lambda < 0``: stable for ``h |lambda| <= x``.
        Euler 2, RK4 2.7853 (HW II, Sec. IV.2). Computed from the real roots of
        ``P(-y)^2 - Q(-y)^2``.
        """
        return self._real_stability_limit

    @cached_property
    def _real_stability_limit(self) -> float:
        # cached (found 2026-11-27): every simulate() call asked for both limits, and their exact root
        # isolation took 17 ms of a 1-step double pendulum run that needs 0.1 ms
        P, Q = (p.as_expr().subs(Z, -_Y) for p in self._stability_parts)
        return _stable_interval_end(sp.Poly(sp.expand(P**2 - Q**2), _Y))

    def imag_stability_limit(self) -> float:
        """Largest ``x`` with ``|R(iy)| <= 1`` for all ``y`` in ``[0, x]``; ``inf`` if unbounded.

        Step bound ``h omega <= x`` for an undamped oscillator (RK4: ``2 sqrt(2)``; explicit
        Euler and Heun: 0). Computed from the real roots of ``|P(iy)|^2 - |Q(iy)|^2``.
        """
        return self._imag_stability_limit

    @cached_property
    def _imag_stability_limit(self) -> float:
        P, Q = (p.as_expr() for p in self._stability_parts)
        modulus2 = lambda f: f.subs(Z, sp.I * _Y) * f.subs(Z, -sp.I * _Y)  # |f(iy)|^2, real coefficients
        return _stable_interval_end(sp.Poly(sp.expand(modulus2(P) - modulus2(Q)), _Y))

    def amplification(self, h_lambda: np.ndarray) -> np.ndarray:
        """|R(h lambda)| per eigenvalue: the growth of each linear mode in one step."""
        with np.errstate(over="ignore", invalid="ignore"):  # a huge h*lambda overflows R: unstable
            return np.abs(_numeric_stability_function(self)(h_lambda))

    def unstable_step(self, h: float, settled: np.ndarray, n_steps: int) -> tuple[bool, str]:
        """(unstable, the region in words; "" when stable): the step h amplifies the non-growing modes
        ``settled`` (eigenvalues with Re <= 0 of the Jacobian) more than tenfold over ``n_steps`` steps."""
        growth = float(np.max(self.amplification(h * settled)))
        unstable = not growth <= 1 + 1e-12 and not n_steps * math.log(growth) <= math.log(10.0)
        if not unstable:  # the words are for the warning only: their exact roots took 110 ms per method
            return False, ""
        return True, (f"h*w < {self.imag_stability_limit():.4g} on the imaginary axis, "
                      f"{self.real_stability_limit():.4g} on the negative real axis")

    # -- display ---------------------------------------------------------------------------
    def _cells(self) -> tuple[list[list[str]], list[str]]:
        """Rows ``[c_i, a_i1, ...]`` and the ``b`` row as strings; blanks above an explicit diagonal."""
        rows = [[str(self.c[i])] + [
            "" if self.explicit and j >= i else str(self.a[i][j]) for j in range(self.stages)
        ] for i in range(self.stages)]
        return rows, [str(x) for x in self.b]

    def __str__(self) -> str:
        rows, b = self._cells()
        width = max(len(x) for x in [*b, *(x for r in rows for x in r)])
        line = lambda first, rest: f"{first:>{width}} | " + "  ".join(f"{x:>{width}}" for x in rest)
        body = [line(r[0], r[1:]).rstrip() for r in rows]
        rule = "-" * (width + 1) + "+" + "-" * (len(line("", b)) - width - 2)
        head = f"{self.name} ({self.title + ', ' if self.title else ''}order {self.order})"
        return "\n".join([head, *body, rule, line("", b)])

    def latex(self) -> str:
        """The tableau as a LaTeX ``array`` (``c | A`` over ``b``)."""
        tex = lambda x: sp.latex(x) if x != "" else ""
        rows = [[self.c[i]] + [
            "" if self.explicit and j >= i else self.a[i][j] for j in range(self.stages)
        ] for i in range(self.stages)]
        lines = [" & ".join(tex(x) for x in r) + r" \\" for r in rows]
        lines.append(r"\hline")
        lines.append(" & " + " & ".join(tex(x) for x in self.b))
        return "\\begin{array}{c|" + "c" * self.stages + "}\n" + "\n".join(lines) + "\n\\end{array}"


def _positive_roots(g: sp.Poly) -> list[float]:
    """Distinct real roots ``> 0`` of ``g`` (with ``g(0) != 0``), ascending."""
    if g.degree() < 1:
        return []
    if g.domain.is_QQ or g.domain.is_ZZ:  # exact isolation copes with multiple roots
        roots = {float(r.evalf(30)) for r in sp.Poly(g.as_expr(), _Y, domain="QQ").real_roots()}
    else:  # algebraic coefficients: square-free part has simple roots, found to 30 digits
        simple = sp.Poly(g.as_expr(), _Y, extension=True).sqf_part()
        roots = {float(sp.re(r)) for r in simple.nroots(n=30, maxsteps=200) if abs(sp.im(r)) < 1e-20}
    return sorted(r for r in roots if r > 0)


def _stable_interval_end(g: sp.Poly) -> float:
    """Largest ``x`` with ``g <= 0`` on ``[0, x]``, given ``g(0) = 0``; ``inf`` if unbounded.

    ``g`` changes sign only at its positive roots, so one probe inside each gap between
    consecutive roots decides the sign there; a double root (touching zero) passes.
    """
    if g.is_zero:
        return math.inf
    while g.coeff_monomial(1) == 0 and g.degree() > 0:  # y^k > 0 for y > 0: drop it
        g = sp.Poly(sp.cancel(g.as_expr() / _Y), _Y, domain=g.domain)
    edges = [0.0, *_positive_roots(g)]
    for left, right in zip(edges, [*edges[1:], None]):
        probe = (left + right) / 2 if right is not None else 2 * left + 1
        if float(g.eval(sp.Float(probe, 30))) > 0:
            return left
    return math.inf


def _tableau(name: str, a, b, c, order: int, title: str) -> ButcherTableau:
    return ButcherTableau(name, tuple(map(tuple, a)), tuple(b), tuple(c), order, title)


_G = 1 - sp.sqrt(2) / 2  # gamma of SDIRK2: root of gamma^2 - 2 gamma + 1/2 = 0 in (0, 1)

# Explicit Euler (HNW I, Sec. I.7 and II.1): the 1-stage explicit method.
EULER = _tableau("euler", [[0]], [1], [0], 1, "explicit Euler")
# Heun (1900), the explicit trapezoidal rule: the 2-stage order-2 family of HNW I, Sec. II.1
# (Butcher 2016, Sec. 32) with c_2 = 1.
HEUN = _tableau("heun", [[0, 0], [1, 0]], ["1/2", "1/2"], [0, 1], 2, "Heun, explicit trapezoidal rule")
# Runge (1895), explicit midpoint: the same family with c_2 = 1/2 (HNW I, Sec. II.1).
MIDPOINT_EXPLICIT = _tableau(
    "midpoint", [[0, 0], ["1/2", 0]], [0, 1], [0, "1/2"], 2, "Runge, explicit midpoint")
# Kutta (1901), third order: HNW I, Sec. II.1, Table 1.1 ("Kutta, order 3").
KUTTA3 = _tableau(
    "kutta3", [[0, 0, 0], ["1/2", 0, 0], [-1, 2, 0]], ["1/6", "2/3", "1/6"], [0, "1/2", 1], 3,
    "Kutta's third-order method")
# HNW I, Sec. II.1, Table 1.2 (left): the classical Runge-Kutta method (Kutta 1901).
RK4 = _tableau(
    "rk4", [[0, 0, 0, 0], ["1/2", 0, 0, 0], [0, "1/2", 0, 0], [0, 0, 1, 0]],
    ["1/6", "1/3", "1/3", "1/6"], [0, "1/2", "1/2", 1], 4, "classical Runge-Kutta")
# HNW I, Sec. II.1, Table 1.2 (right): Kutta's 3/8 rule.
RK38 = _tableau(
    "rk38", [[0, 0, 0, 0], ["1/3", 0, 0, 0], ["-1/3", 1, 0, 0], [1, -1, 1, 0]],
    ["1/8", "3/8", "3/8", "1/8"], [0, "1/3", "2/3", 1], 4, "Kutta's 3/8 rule")
# Dormand & Prince, J. Comput. Appl. Math. 6 (1980) 19-26; HNW I, Sec. II.5, Table 5.2. The
# 5th-order solution (b = row 7, b_7 = 0, FSAL); the same numbers as scipy's RK45.
DOPRI5 = _tableau(
    "dopri5",
    [[0] * 7,
     ["1/5"] + [0] * 6,
     ["3/40", "9/40"] + [0] * 5,
     ["44/45", "-56/15", "32/9"] + [0] * 4,
     ["19372/6561", "-25360/2187", "64448/6561", "-212/729"] + [0] * 3,
     ["9017/3168", "-355/33", "46732/5247", "49/176", "-5103/18656"] + [0] * 2,
     ["35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0]],
    ["35/384", 0, "500/1113", "125/192", "-2187/6784", "11/84", 0],
    [0, "1/5", "3/10", "4/5", "8/9", 1, 1], 5, "Dormand-Prince 5(4), 5th-order solution")
# HW II, Sec. IV.3 (R(z) = 1/(1-z)): implicit Euler, L-stable; Radau IIA with s = 1.
BACKWARD_EULER = _tableau("backward_euler", [[1]], [1], [1], 1, "implicit Euler")
# HW II, Sec. IV.5 (Gauss, s = 1); symplectic (Hairer-Lubich-Wanner, GNI, Thm. VI.4.3), A-stable.
IMPLICIT_MIDPOINT = _tableau("implicit_midpoint", [["1/2"]], [1], ["1/2"], 2, "implicit midpoint, Gauss s=1")
# Alexander, SIAM J. Numer. Anal. 14 (1977) 1006-1021; HW II, Sec. IV.6: 2-stage SDIRK,
# stiffly accurate (b = last row of a), hence L-stable, gamma = 1 - 1/sqrt(2).
SDIRK2 = _tableau("sdirk2", [[_G, 0], [1 - _G, _G]], [1 - _G, _G], [_G, 1], 2, "Alexander's L-stable SDIRK")
# HW II, Sec. IV.5, Table 5.5 (Radau IIA, s = 2): order 2s - 1 = 3, L-stable.
RADAU_IIA3 = _tableau(
    "radau_iia3", [["5/12", "-1/12"], ["3/4", "1/4"]], ["3/4", "1/4"], ["1/3", 1], 3, "Radau IIA, 2 stages")

TABLEAUX: dict[str, ButcherTableau] = {
    t.name: t for t in (EULER, HEUN, MIDPOINT_EXPLICIT, KUTTA3, RK4, RK38, DOPRI5,
                        BACKWARD_EULER, IMPLICIT_MIDPOINT, SDIRK2, RADAU_IIA3)
}


def get_tableau(name: str) -> ButcherTableau:
    """The registered tableau called ``name`` (case-insensitive).

    Raises
    ------
    KeyError
        If unknown; the message lists the known names.
    """
    key = name.strip().lower() if isinstance(name, str) else name
    if key not in TABLEAUX:
        raise KeyError(f"unknown tableau {name!r}; known: {', '.join(sorted(TABLEAUX))}")
    return TABLEAUX[key]
