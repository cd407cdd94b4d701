"""Stage: EquationsOfMotion -> consistent initial states of constrained models.

A model with holonomic constraints phi(q, t) = 0 (m of them, in n redundant coordinates, see
`holonomic`) can only start from a state that satisfies them and their time derivative::

    phi(q0, t0) = 0                              (m equations, position level)
    w = A(q0, t0) u0 + dphi/dt(q0, t0) = 0       (m equations, velocity level; A = dphi/dq)

The user usually knows a few coordinates (the crank angle, the x of a pendulum bob) and wants
the rest to follow. `consistent_state` holds the known ones fixed and solves for the others
(Haug, Computer-Aided Kinematics and Dynamics of Mechanical Systems, sec. 3.5 "assembly
analysis"; Nikravesh, Computer-Aided Analysis of Mechanical Systems, sec. 4.3):

* positions: Gauss-Newton on phi in the free coordinates, each step the *minimum-norm* solution
  of ``A_free dq = -phi``, with a backtracking line search on ``|phi|``. From a start near the
  constraint manifold this ends close to the orthogonal projection of the start (exactly so
  when the steps keep one direction: the radial projection onto a circle). When it stalls
  (start at a point where A_free loses rank, or no solution) scipy's ``least_squares`` and a
  few seeded perturbed starts are tried before giving up;
* speeds: linear, ``A_free u_free = -(dphi/dt + A_fixed u_fixed)``; u_free is the given value
  (or 0) plus the minimum-norm correction, i.e. the least-norm solution where the speeds are
  underdetermined and the nearest consistent speeds to the given ones otherwise.

If the constraints cannot be met (values given inconsistently, too many coordinates held) a
`ValueError` names each violated constraint by index and expression, with its residual at the
best least-squares point.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import scipy.optimize
import sympy as sp
from sympy.core.function import AppliedUndef

from ..symbolic.derive import EquationsOfMotion
from .equilibria import coordinate_point, resolve_values, substitute_values

MAX_ITERATIONS = 50   # Gauss-Newton steps per start (quadratic convergence needs ~5)
RETRIES = 3           # perturbed restarts after a stall
PERTURBATION = 1e-2   # relative size of a restart's perturbation of the free coordinates


def consistent_state(eom: EquationsOfMotion, q: Any = None, u: Any = None, *,
                     values: Mapping | None = None, t: float = 0.0, fix: Sequence | None = None,
                     fix_u: Sequence | None = None, tol: float = 1e-12) -> tuple[np.ndarray, np.ndarray]:
    """An initial state (q0, u0) satisfying phi(q0, t) = 0 and A u0 + dphi/dt = 0.

    Parameters
    ----------
    eom : EquationsOfMotion
        With or without constraints (without: q0, u0 are the given values, 0 elsewhere).
    q : mapping coordinate (Symbol or name) -> float, or sequence (n,), optional
        Known coordinates and starting values of the others (0 for those not given). The start
        of a free coordinate picks the branch: a pendulum bob at given x has y = +-sqrt(l^2 - x^2).
        A sequence gives every coordinate.
    u : mapping speed or coordinate (Symbol or name: ``"x_d"`` or ``"x"``) -> float, or sequence (n,)
    values : mapping parameter (Symbol or name) -> float, optional
        Overrides ``eom.parameter_values``.
    t : float
        Time of the initial state (rheonomic constraints).
    fix : sequence of coordinates (Symbol or name), optional
        Coordinates held at their given values; default: every coordinate given in ``q``. Pass
        ``fix=()`` to project a whole given configuration onto the constraints.
    fix_u : sequence of speeds or coordinates, optional
        Speeds held at their given values; default: every speed given in ``u``.
    tol : float
        Accepted residual, relative to the size of the terms it is made of (`constraint_scales`):
        ``|phi_i| <= tol * (sum_k |term_k of phi_i| + sum_j |A_ij| (|q_j| + max |q|))`` and
        ``|w_i| <= tol * (sum_j |A_ij| (|u_j| + max |u|) + |dphi_i/dt|)``; no absolute floor, so a
        model of micrometres is held to its constraints as one of metres.

    Returns
    -------
    q0, u0 : ndarray (n,), in the order of ``eom.q`` and ``eom.u``

    Raises
    ------
    ValueError
        Unknown coordinate, speed or parameter, a held coordinate without a value, or
        constraints that cannot be satisfied (the message names each violated constraint: index,
        expression, residual).
    """
    checked_tolerance(tol, "consistent_state")
    functions = _constraint_functions(eom, values, t)
    q0, held = _given(eom, q, fix, list(eom.q), "coordinate")
    if len(eom.configuration):  # found by review: a Kane four-bar 2 units off its loop closure was returned
        q0 = _solve_configuration(eom, values, t, q0, held, tol)
    if eom.m:
        q0 = _solve_positions(eom, functions, q0, held, tol)
    u0, held_u = _given(eom, u, fix_u, list(eom.u), "speed")
    if eom.m:
        u0 = _solve_speeds(eom, functions, q0, u0, held_u, tol)
    return q0, u0


def constraint_residuals(eom: EquationsOfMotion, q: Any, u: Any, values: Mapping | None = None,
                         t: float = 0.0) -> np.ndarray:
    """phi(q, t) then A u + dphi/dt, shape (2m,) (the layout of the C ``_residuals``).

    q, u: sequences (n,) or mappings naming every coordinate (and speed; missing speeds are 0).
    """
    phi, A, phi_t, _ = _constraint_functions(eom, values, t)
    qv = np.array(coordinate_point(eom, q), dtype=float)
    uv = _given(eom, u, (), list(eom.u), "speed")[0]
    return np.concatenate([phi(qv), A(qv) @ uv + phi_t(qv)])


def term_sizes(rows) -> sp.Matrix:
    """Per row, the size a residual of the row is measured against: its rounding level is a small
    multiple of eps times this, propagated to first order through the expression: the sum of |terms|
    of a sum; for a product, each factor's size times the |others| (and |value| itself); for a
    positive integer power p of a sum b, p |b|^(p-1) size(b) (and |value|); else |expr|. A product's |value| alone is 0
    at its roots, which only an exact 0 then passed (found by review: a bead's steady angle on a
    spinning hoop, F = sin(theta) (cos(theta) - g / (R W^2)) m R^2 W^2, was refused at residuals of
    7e-15); and size(b)^p, tried first, let (x - 1000)^2 + 1e-4 pass for 0 (found by review)."""
    return sp.Matrix([_size(sp.sympify(row)) for row in rows])


def _size(expr: sp.Expr) -> sp.Expr:
    if expr.is_Add:
        return sp.Add(*[_size(term) for term in expr.args])
    if expr.is_Mul:
        factors = expr.args
        sizes = [_size(f) for f in factors]
        # the factors whose own rounding is more than their |value| (sums, powers of sums)
        inexact = [i for i, (f, size) in enumerate(zip(factors, sizes)) if size != sp.Abs(f)]
        value = sp.Abs(expr)
        if not inexact:
            return value
        return value + sp.Add(*[sizes[i] * sp.Mul(*[sp.Abs(g) for j, g in enumerate(factors) if j != i])
                                for i in inexact])
    if expr.is_Pow and expr.exp.is_Integer and expr.exp > 0 and not expr.base.is_Atom:
        return sp.Abs(expr) + expr.exp * sp.Abs(expr.base) ** (expr.exp - 1) * _size(expr.base)
    return sp.Abs(expr)  # an atom, or a power of one (its rounding is that of the products: |value|)


def checked_tolerance(tol, what: str) -> float:
    """``tol`` as a positive finite number, else a ValueError naming ``what``'s tol."""
    if isinstance(tol, bool) or not isinstance(tol, numbers.Real) or not 0 < tol < math.inf:
        raise ValueError(f"{what}: tol must be a positive finite number, got {tol!r}")
    return float(tol)


def residual_sizes(eom: EquationsOfMotion) -> tuple[sp.Matrix, sp.Matrix]:
    """The size of the terms of phi_i and of A u + dphi/dt, symbolically, m rows each (see
    `constraint_scales`)."""
    A = sp.Matrix(eom.constraint_jacobian)
    absolute = A.applyfunc(sp.Abs)
    terms = term_sizes(eom.constraints)

    def sizes(symbols):  # |x_j| + max_k |x_k|, as in `_scale`
        largest = sp.Max(*[sp.Abs(s) for s in symbols])
        return sp.Matrix([sp.Abs(s) + largest for s in symbols])

    positions = terms + sp.Matrix(eom.constraints).jacobian(list(eom.q)).applyfunc(sp.Abs) * sizes(eom.q)
    velocities = absolute * sizes(eom.u) + sp.Matrix(eom.constraint_rate).applyfunc(sp.Abs)
    return positions, velocities


def constraint_scales(eom: EquationsOfMotion, q: Any, u: Any, values: Mapping | None = None,
                      t: float = 0.0) -> np.ndarray:
    """The size of the terms each row of `constraint_residuals` is made of, shape (2m,): for phi_i,
    sum_k |term_k| over its terms plus sum_j |A_ij| (|q_j| + max |q|); for A u + dphi/dt,
    sum_j |A_ij| (|u_j| + max |u|) + |dphi_i/dt|. A residual is at rounding level when it is a
    small multiple of eps times this. There is no absolute floor (found by review: with 1 + ..., a
    pendulum of l = 1e-6 passed with its bob at half the rod's length)."""
    _, A, phi_t, phi_size = _constraint_functions(eom, values, t)
    qv = np.array(coordinate_point(eom, q), dtype=float)
    uv = _given(eom, u, (), list(eom.u), "speed")[0]
    J = A(qv)
    return np.concatenate([_scale(J, qv, phi_size(qv)), _scale(J, uv, phi_t(qv))])


# -- inputs ---------------------------------------------------------------------------------------
def _constraint_functions(eom: EquationsOfMotion, values: Mapping | None, t: float) -> tuple:
    """Numeric phi(q) (m,), A(q) (m, n), dphi/dt(q) (m,) and the size of phi's terms (m,: sum_k
    |term_k|) at time t with the parameters substituted."""
    vals = resolve_values(eom, {} if values is None else values)
    vals = {**vals, eom.t: float(t)}
    q, m, n = list(eom.q), eom.m, eom.n
    if m == 0:
        return (lambda x: np.zeros(0),) + (lambda x: np.zeros((0, n)),) + (lambda x: np.zeros(0),) * 2
    sizes = term_sizes(eom.constraints)
    out = []
    for expr, shape, what in ((eom.constraints, (m,), "constraints"),
                              (eom.constraint_jacobian, (m, n), "constraint Jacobian"),
                              (eom.constraint_rate, (m,), "constraint rate"),
                              (sizes, (m,), "constraints")):
        f = sp.lambdify([q], substitute_values(eom, sp.Matrix(expr), vals, what), "numpy")
        out.append(lambda x, f=f, shape=shape: np.asarray(f(x), dtype=float).reshape(shape))
    return tuple(out)


def _given(eom: EquationsOfMotion, given: Any, fix: Sequence | None, symbols: list,
           kind: str) -> tuple[np.ndarray, list]:
    """Start vector (given values, 0 elsewhere) and the sorted indices held fixed."""
    index = _name_index(eom, symbols)
    start = np.zeros(eom.n)
    named = set()
    if given is not None and not isinstance(given, Mapping):
        values = np.ravel(np.asarray(given, dtype=float))
        if values.shape != (eom.n,):
            raise ValueError(f"{kind}s: {values.size} values given; model {eom.name!r} has {eom.n} "
                             f"({', '.join(map(str, symbols))})")
        given = dict(zip(symbols, values))
    for key, value in dict(given or {}).items():
        i = _lookup(eom, index, key, kind)
        try:
            start[i] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"{kind} {symbols[i]} needs a number, got {value!r}") from None
        if not np.isfinite(start[i]):
            raise ValueError(f"{kind} {symbols[i]} is not finite: {value!r}")
        named.add(i)
    if fix is None:
        return start, sorted(named)
    if isinstance(fix, (str, sp.Symbol)):
        fix = [fix]
    held = sorted({_lookup(eom, index, key, kind) for key in fix})
    missing = [str(symbols[i]) for i in held if i not in named]
    if missing:
        raise ValueError(f"{kind}(s) {', '.join(missing)} of model {eom.name!r} are to be held fixed "
                         f"but have no given value")
    return start, held


def _name_index(eom: EquationsOfMotion, symbols: list) -> dict:
    """Names (and, for speeds, the names of the coordinates whose rate a speed is) -> index. By the
    kinematics qd_i = u_k, not by position: the elimination formulation puts the dependent rates
    last (a review found {"psi": 0.5} set phi_d in a rolling disc, status OK)."""
    index = {s.name: i for i, s in enumerate(symbols)}
    if symbols == list(eom.u):
        speeds = {u: k for k, u in enumerate(eom.u)}
        for qi, rate in zip(eom.q, eom.kinematics):
            if rate in speeds and qi.name not in index:
                index[qi.name] = speeds[rate]
    return index


def _lookup(eom: EquationsOfMotion, index: dict, key: Any, kind: str) -> int:
    if isinstance(key, AppliedUndef):  # the model's own dynamicsymbol, x(t)
        name = key.func.__name__
    else:
        name = key.name if isinstance(key, sp.Symbol) else str(key)
    if name not in index:
        raise ValueError(f"{key!r} is not a {kind} of model {eom.name!r} "
                         f"({kind}s: {', '.join(index)})")
    return index[name]


# -- positions ------------------------------------------------------------------------------------
def _solve_positions(eom, functions, q0: np.ndarray, held: list, tol: float) -> np.ndarray:
    phi, A, _, phi_size = functions
    free = [i for i in range(eom.n) if i not in held]
    best = q0.copy()
    if free and not _converged(phi(best), A(best), best, tol, phi_size(best)):
        rng = np.random.default_rng(0)
        for attempt in range(RETRIES + 1):
            start = q0.copy()
            if attempt:  # a start where A_free loses rank (y = 0 on a circle) stalls every solver
                start[free] += PERTURBATION * (1.0 + np.abs(start[free])) * rng.standard_normal(len(free))
            x = _gauss_newton(phi, A, phi_size, start, free, tol)
            if not _converged(phi(x), A(x), x, tol, phi_size(x)):
                x = _least_squares(phi, A, x, free)
            if _norm(phi(x)) < _norm(phi(best)):
                best = x
            if _converged(phi(best), A(best), best, tol, phi_size(best)):
                break
    r, J = phi(best), A(best)
    if not _converged(r, J, best, tol, phi_size(best)):
        _raise_violated(eom, r, tol * _scale(J, best, phi_size(best)), best, held, "coordinate")
    return best


def _solve_configuration(eom, values, t: float, q0: np.ndarray, held: list, tol: float) -> np.ndarray:
    """Kane's configuration constraints f(q, t) = 0 solved for the dependent coordinates not held
    (as the C projection of an eliminated build does), the others as given."""
    vals = {**resolve_values(eom, {} if values is None else values), eom.t: float(t)}
    q = list(eom.q)
    rows = sp.Matrix(eom.configuration)
    jacobian = rows.jacobian(q)
    terms = term_sizes(rows)
    f, J, size = (sp.lambdify([q], substitute_values(eom, matrix, vals, "configuration constraints"), "numpy")
                  for matrix in (rows, jacobian, terms))
    k = rows.rows
    residual = lambda x: np.asarray(f(x), dtype=float).reshape(k)  # noqa: E731
    slope = lambda x: np.asarray(J(x), dtype=float).reshape(k, len(q))  # noqa: E731
    sizes = lambda x: np.asarray(size(x), dtype=float).reshape(k)  # noqa: E731
    free = [d for d in eom.dependent_coordinates if d not in held]
    x = q0.copy()
    if free and not _converged(residual(x), slope(x), x, tol, sizes(x)):
        def embed(z):
            y = q0.copy()
            y[free] = z
            return y
        solution = scipy.optimize.least_squares(lambda z: residual(embed(z)), q0[free],
                                                jac=lambda z: slope(embed(z))[:, free], method="lm",
                                                xtol=1e-15, ftol=1e-15, gtol=1e-15)
        x = embed(solution.x)
    r = residual(x)
    if not _converged(r, slope(x), x, tol, sizes(x)):
        bad = [i for i in range(k) if not abs(r[i]) <= tol * _scale(slope(x), x, sizes(x))[i]]
        names = ", ".join(str(q[d]) for d in free) or "none"
        raise ValueError(f"cannot satisfy the configuration constraints of model {eom.name!r} by the dependent "
                         f"coordinates not given ({names}): " + "; ".join(
                             f"configuration constraint {i}: {rows[i]} = 0 has residual {r[i]:.6g}" for i in bad)
                         + " (" + ", ".join(f"{s} = {v:.12g}" for s, v in zip(q, x)) + ")")
    return x


def _gauss_newton(phi, A, phi_size, x: np.ndarray, free: list, tol: float) -> np.ndarray:
    """Minimum-norm Gauss-Newton steps in the free coordinates, backtracking on |phi|."""
    x = x.copy()
    for _ in range(MAX_ITERATIONS):
        r, J = phi(x), A(x)
        if _converged(r, J, x, tol, phi_size(x)):
            break
        dz = np.linalg.lstsq(J[:, free], -r, rcond=None)[0]
        norm, step = _norm(r), 1.0
        while step > 1e-10:
            trial = x.copy()
            trial[free] += step * dz
            if _norm(phi(trial)) < (1.0 - 1e-4 * step) * norm:
                break
            step /= 2
        else:
            break  # no descent along the Gauss-Newton direction: stalled
        x = trial
    return x


def _least_squares(phi, A, x: np.ndarray, free: list) -> np.ndarray:
    """scipy's trust-region least squares over the free coordinates (robust when GN stalls)."""
    def embed(z):
        y = x.copy()
        y[free] = z
        return y
    sol = scipy.optimize.least_squares(lambda z: phi(embed(z)), x[free], jac=lambda z: A(embed(z))[:, free],
                                       method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15)
    return embed(sol.x)


def _norm(r: np.ndarray) -> float:
    return float(np.linalg.norm(r)) if np.all(np.isfinite(r)) else np.inf


def _scale(J: np.ndarray, x: np.ndarray, b: Any) -> np.ndarray:
    """Per constraint: sum_j |J_ij| (|x_j| + max_k |x_k|) + |b_i|, the size of the terms making up
    the residual (b: the size of phi's own terms, or dphi/dt). The max_k term is the row's floor at
    the state's own scale: y_s = 0 (a slider on its guide) has terms as small as y_s itself."""
    return np.abs(J) @ (np.abs(x) + np.abs(x).max(initial=0.0)) + np.abs(b)


def _converged(r: np.ndarray, J: np.ndarray, x: np.ndarray, tol: float, b: Any) -> bool:
    return bool(np.all(np.isfinite(r)) and np.all(np.abs(r) <= tol * _scale(J, x, b)))


# -- speeds ---------------------------------------------------------------------------------------
def _solve_speeds(eom, functions, q0: np.ndarray, u0: np.ndarray, held: list, tol: float) -> np.ndarray:
    _, A, phi_t, _ = functions
    J, b = A(q0), phi_t(q0)
    free = [i for i in range(eom.n) if i not in held]
    u = u0.copy()
    if free:  # nearest to the given free speeds (0 when not given): minimum-norm correction
        u[free] += np.linalg.lstsq(J[:, free], -(b + J @ u), rcond=None)[0]
    w = J @ u + b
    if not _converged(w, J, u, tol, b):
        _raise_violated(eom, w, tol * _scale(J, u, b), u, held, "speed", at=q0)
    return u


# -- errors ---------------------------------------------------------------------------------------
def _raise_violated(eom, r: np.ndarray, limit: np.ndarray, x: np.ndarray, held: list, kind: str,
                    at: np.ndarray | None = None):
    """ValueError naming every constraint (index, expression, residual) with |r_i| > limit_i."""
    if kind == "coordinate":
        level, symbols, exprs = "constraint", list(eom.q), list(eom.constraints)
    else:
        level, symbols = "velocity constraint", list(eom.u)
        exprs = list(sp.Matrix(eom.constraint_jacobian) * sp.Matrix(eom.u) + sp.Matrix(eom.constraint_rate))
    bad = [i for i in range(len(r)) if not abs(r[i]) <= limit[i]]
    lines = [f"{level} {i}: {exprs[i]} = 0 has residual {r[i]:.6g}" for i in bad]
    held_names = ", ".join(str(symbols[i]) for i in held) or "none"
    state = ", ".join(f"{s} = {v:.12g}" for s, v in zip(symbols, x))
    if at is not None:
        state += " at " + ", ".join(f"{s} = {v:.12g}" for s, v in zip(eom.q, at))
    cause = "inconsistent given values or too many held fixed" if held else "no solution found"
    raise ValueError(f"cannot satisfy the {level}s of model {eom.name!r} with {kind}(s) {held_names} held "
                     f"fixed ({cause}): " + "; ".join(lines) + f" (best least-squares {kind}s: {state})")
