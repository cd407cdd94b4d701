"""Stage: EquationsOfMotion -> equilibria, linearization.

Principle of virtual displacements (Lagrange; Lurie, Analytical Mechanics, ch. 2; Goldstein,
Classical Mechanics, sec. 1.4): a configuration q* of a system ``M(q, t) ud = F(q, u, t)`` is an
equilibrium when the system, placed there at rest, stays there, i.e. when the generalized forces
at rest vanish::

    F(q*, u = 0, t) = 0        (n equations in q*)

For a rheonomic model (coordinates measured in a frame moving in a prescribed way) F at rest
also holds the transport inertia forces (centrifugal forces of a spinning frame), so its zeros are
the *relative* equilibria, at rest in the moving frame. They exist only if the conditions do not
depend on t; `equilibrium_conditions` checks that.

Models with holonomic constraints: `constrained.constrained_equilibrium`.

About an equilibrium q0 the small motions dq = q - q0 obey the linear model::

    M0 dqdd + C0 dqd + K0 dq = 0,
    M0 = M(q0, t0),  C0 = -dF/du (q0, 0, t0),  K0 = -dF/dq (q0, 0, t0),  t0 = 0.

Time convention: everything is evaluated at t0 = 0. For a steady relative equilibrium of a
uniformly moving frame (the governor) M and F do not depend on t in the moving coordinates, so
the choice does not matter; where the force at rest or M0, C0, K0 depend on t at q0 the linear
model is time-varying (a pendulum on a vibrating pivot), and `linearize` refuses it
(`statics.state_space.linearize_state` gives the Jacobian frozen at a chosen t0).

Undamped natural frequencies solve ``K0 v = w**2 M0 v`` (Lagrange-Dirichlet: q0 is stable when
K0 is positive definite); C0 (damping, and the gyroscopic Coriolis terms of a moving frame) is
left out of them.
"""
from __future__ import annotations

import dataclasses
import itertools
import math
import numbers
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.linalg
import scipy.optimize
import sympy as sp

from ..symbolic.derive import EquationsOfMotion

SIMPLIFY_MAX_N = 6        # above this, entries are never simplified (time checks go numeric)
MAX_GUESSES = 512         # size of the default grid of starting points
DEGENERATE_SLOPE = 1e-6   # an equilibrium whose Jacobian has a singular value below this, per equation's slope
DEGENERATE_SPREAD = 1e-4  # degenerate ones this close (relative; rad for angles) are one
LINEAR_GRID = (-2.0, 2.0)  # default guess range of coordinates that are not angles
FAR_OUT = 5.0              # a degenerate root beyond FAR_OUT times LINEAR_GRID's reach is one at infinity
_TRIG = (sp.sin, sp.cos, sp.tan)


# -- conditions ---------------------------------------------------------------------------------
def equilibrium_conditions(eom: EquationsOfMotion) -> sp.ImmutableMatrix:
    """The generalized forces at rest, ``F(q, u=0, t)``, shape (n, 1), free of t.

    An entry that contains t is simplified (``trigsimp``, then ``simplify``; for n > 6 neither,
    only a numeric check at seeded random points); if t survives, it is a genuine dependence.

    Raises
    ------
    ValueError
        If an entry depends on t (the search needs F at rest free of t; points where it vanishes at
        every t, a Kapitza pendulum's upright and hanging positions, are not searched for).
    """
    require_closed_form(eom, "equilibrium_conditions")
    G = eom.forcing.xreplace({ui: 0 for ui in eom.u})
    return sp.ImmutableMatrix([_steady_entry(eom, i, g) for i, g in enumerate(G)])


#: functions that are not analytic where they switch: the complex step would differentiate them
#: wrongly, and sampling cannot show a switch absent
NOT_ANALYTIC = (sp.Abs, sp.sign, sp.Piecewise, sp.Heaviside, sp.Min, sp.Max, sp.floor, sp.ceiling, sp.re, sp.im,
                sp.arg, sp.conjugate, sp.DiracDelta)


def require_closed_form(eom: EquationsOfMotion, what: str) -> None:
    """The statics read M and F, which a kinematic tree's recursive formulation does not form (it
    failed with numpy's and sympy's own errors): a ValueError saying how to get them."""
    if eom.tree is not None:
        raise ValueError(f"{what} needs the closed-form M and F, which the recursive formulation of "
                         f"{eom.name!r} does not form; Model(..., formulation='closed') forms them")


def _free_of_t(eom: EquationsOfMotion, g: sp.Expr) -> sp.Expr | None:
    """g without t when its value does not depend on t (simplified for small models, else sampled),
    else None."""
    t = eom.t
    if t not in g.free_symbols:
        return g
    if eom.n <= SIMPLIFY_MAX_N:
        g = sp.trigsimp(g)
        if t in g.free_symbols:
            g = sp.simplify(g)
        if t not in g.free_symbols:
            return g
    if _independent_of_t(eom, g):
        return g.xreplace({t: 0})  # the value is the same at every t
    return None


def _steady_entry(eom: EquationsOfMotion, i: int, g: sp.Expr) -> sp.Expr:
    steady = _free_of_t(eom, g)
    if steady is not None:
        return steady
    t = eom.t
    raise ValueError(
        f"equilibrium condition F[{i}] (coordinate {eom.q[i]}) of model {eom.name!r} depends on "
        f"{t} at rest: {g}; find_equilibria solves for configurations that are equilibria at every t "
        "only where F at rest is free of t (a point where it vanishes for all t, such as a Kapitza "
        "pendulum's upright, is not searched for: check it by substituting it into F)")


def _independent_of_t(eom: EquationsOfMotion, g: sp.Expr, samples: int = 4) -> bool:
    """Numerically: does g(q, p, t) keep its value over t at seeded random (q, p)? A switch in t
    (Heaviside(t - 10), a Piecewise) is a dependence outright: no finite set of times shows it
    absent. Otherwise g is analytic in t, and equal values at random times (not round ones: found by
    review, sin(100 pi t) vanished at all of 0, 0.37, 1.1, 2.9 and 7.3) mean it is constant."""
    t = eom.t
    if any(t in f.free_symbols for f in g.atoms(*NOT_ANALYTIC)):
        return False
    others = sorted(g.free_symbols - {t}, key=str)
    f = sp.lambdify(others + [t], g, "numpy")
    rng = np.random.default_rng(0)
    times = np.concatenate([[0.0], rng.uniform(0.1, 10.0, 6), 10.0 ** rng.uniform(-4.0, 6.0, 6)])
    seen = False
    with np.errstate(all="ignore"):
        for _ in range(samples):
            point = rng.uniform(0.5, 2.0, len(others))
            values = np.array([complex(f(*point, tk)) for tk in times])
            if not np.all(np.isfinite(values)):
                continue
            seen = True
            if np.max(np.abs(values - values[0])) > 1e-9 * (1.0 + np.max(np.abs(values))):
                return False
    return seen


# -- equilibria ---------------------------------------------------------------------------------
def find_equilibria(eom: EquationsOfMotion, values: Mapping | None = None,
                    guesses: Any = None, inputs: Any = None) -> list[dict]:
    """Equilibria: configurations q* with ``F(q*, 0, t) = 0``.

    Parameters
    ----------
    eom : EquationsOfMotion
    values : mapping parameter (Symbol or name) -> float, optional
        None: solve symbolically (``sympy.solve`` on the per-entry simplified conditions; for
        n > 6 the entries are passed unsimplified). A mapping (``{}`` for the catalog defaults):
        solve numerically, with ``values`` overriding ``eom.parameter_values``.
    guesses : array_like (k, n) or (n,); rows may be mappings q (Symbol or name) -> float, optional
        Numeric starting points. Default: a deterministic grid, angle-like coordinates over
        [-pi, pi), the others over `LINEAR_GRID` (pass guesses for other scales); at most
        `MAX_GUESSES` points, a seeded random sample of the box when the grid would be bigger.
        From the default grid, a root with a singular Jacobian beyond `FAR_OUT` times the grid's
        reach is taken for one at infinity (a force that decays, as exp(-x^2) does) and dropped.
    inputs : sequence (n_r,) or mapping input (Symbol or name) -> value
        The inputs held constant; required when the model has inputs.

    Returns
    -------
    list of dict q_symbol -> expr (symbolic) or float (numeric)
        Symbolic: as ``sympy.solve`` gives them (branches may repeat modulo 2 pi; ``[{}]`` when
        every configuration is an equilibrium). Numeric: unique roots, sorted, angle-like
        coordinates (those that enter M and F only through sin/cos/tan of integer multiples) are
        reduced to (-pi, pi] and deduplicated modulo 2 pi.

    Examples
    --------
    The pendulum hangs (theta = 0) or stands (theta = pi):

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model, derive_equations
    >>> theta = me.dynamicsymbols("theta")
    >>> m, g, l = sp.symbols("m g l", positive=True)
    >>> pendulum = Model("pendulum", [theta], [m, g, l], kinetic_energy=m * l**2 * theta.diff()**2 / 2,
    ...                  potential_energy=-m * g * l * sp.cos(theta),
    ...                  parameter_values={"m": 1.0, "g": 9.81, "l": 1.0})
    >>> eom = derive_equations(pendulum)
    >>> from lagcodegen.statics.equilibria import find_equilibria
    >>> find_equilibria(eom)
    [{theta: 0}, {theta: pi}]
    """
    require_closed_form(eom, "find_equilibria")
    _check_unconstrained(eom, "find_equilibria", "statics.constrained.constrained_equilibrium (holonomic "
                         "constraints, with their multipliers)")
    eom = hold_inputs(eom, inputs)
    G = equilibrium_conditions(eom)
    if values is None:
        if guesses is not None:
            raise ValueError("guesses are starting points of the numeric search: pass values= too "
                             "(values={} for the model's default parameter values)")
        return _solve_symbolic(eom, G)
    return _solve_numeric(eom, G, resolve_values(eom, values), guesses)


def _solve_symbolic(eom: EquationsOfMotion, G: sp.Matrix) -> list[dict]:
    simplify = sp.simplify if eom.n <= SIMPLIFY_MAX_N else (lambda e: e)
    equations = [e for e in (simplify(g) for g in G) if e != 0]
    if not equations:
        return [{}]
    try:
        return sp.solve(equations, list(eom.q), dict=True)
    except NotImplementedError as err:
        raise ValueError(f"sympy cannot solve the equilibrium conditions of model {eom.name!r} "
                         f"({err}); pass values= for a numeric search") from None


def _solve_numeric(eom: EquationsOfMotion, G: sp.Matrix, vals: dict, guesses: Any) -> list[dict]:
    n, q = eom.n, list(eom.q)
    Gn = substitute_values(eom, G, vals, "equilibrium conditions")
    fun = vector_function(q, Gn, (n,))
    jac = vector_function(q, Gn.jacobian(q), (n, n))
    angles = angle_like(eom)
    # angles taken modulo 2 pi: the equations are periodic in them, and a guess of 1e12 rad made the
    # tolerance (which scales with |q|) so loose that a stalled root passed (found by review)
    starts = np.array([reduce_angles(x, angles) for x in _starting_points(eom, guesses, angles)])
    # the degeneracy test reads slopes at starts near a root: those of the coarse grid (8 per axis),
    # whose distance from a root does not shrink as the search grid gets denser
    coarse = starts if guesses is not None else _starting_points(eom, None, angles, per_axis_max=8)
    with np.errstate(all="ignore"):
        # size of the terms of each equation at the starts, |F_i| and |dF_i/dq| |q|: a start that is
        # already a root has |F| at round-off level, which alone would make the tolerance unreachable.
        # Per equation: one scale for all let a small force (m2 = 0.01 beside m1 = 100) pass anywhere
        sizes = np.zeros(n)
        for x0 in starts:
            row = np.maximum(np.abs(fun(x0)), np.abs(jac(x0)) @ np.abs(x0))
            sizes = np.maximum(sizes, np.where(np.isfinite(row), row, 0.0))
        tol = 1e-9 * np.maximum(sizes, 1e-12 * max(float(sizes.max(initial=0.0)), 1e-300))
        roots = []
        for x0 in starts:
            x = _polished(fun, jac, reduce_angles(scipy.optimize.root(fun, x0, jac=jac, method="hybr",
                                                                 options={"xtol": 1e-13}).x, angles), tol)
            residual = fun(x)
            if np.all(np.isfinite(x)) and np.all(np.isfinite(residual)) and np.all(np.abs(residual) <= tol):
                roots.append(_canonical(x, angles))
        found = _unique(roots, angles)
        singular = [x for x in found if _degenerate(jac, x, coarse, angles)]
        if guesses is None:  # roots at infinity: a force that decays (exp(-x^2), 1/x) is as small as the
            # tolerance far out, and hybr walked there from the grid (found by review: 165 'equilibria'
            # of V = -exp(-x^2) at |x| > 12); degenerate and beyond FAR_OUT times the grid's reach
            reach = FAR_OUT * max(abs(v) for v in LINEAR_GRID)
            far = [x for x in singular if np.any(np.where(angles, 0.0, np.abs(x)) > reach)]
            found = [x for x in found if not any(x is y for y in far)]
            singular = [x for x in singular if not any(x is y for y in far)]
        if len(singular) > 1:
            merged = _unique(singular, angles, tol=DEGENERATE_SPREAD)
            found = [x for x in found if not any(x is y for y in singular)
                     or any(x is y for y in merged)]
            singular = merged
    if singular:
        warnings.warn(f"{len(singular)} of the {len(found)} equilibria of model {eom.name!r} found have a singular "
                      f"Jacobian of the equilibrium conditions (e.g. at q = {list(map(float, singular[0]))}): not "
                      "isolated (a continuum, a free coordinate or g = 0: the points returned are where the starting "
                      "points fell) or degenerate; hold the free coordinates, or read them as one family",
                      EquilibriumWarning, stacklevel=3)
    return [dict(zip(q, map(float, x))) for x in found]


def _polished(fun, jac, x: np.ndarray, tol: np.ndarray) -> np.ndarray:
    """A few Newton steps from hybr's root, each kept only if no equation's residual, relative to its
    tolerance, grows: hybr stops on the step size of the whole vector, and an equation of small terms
    beside one of large terms was left 2e-9 rad off (found by review: two roots at q2 = 2e-9 and 3e-9
    beside the one at 0, when the denser grid started there)."""
    for _ in range(3):
        r = fun(x)
        J = jac(x)
        if not (np.all(np.isfinite(r)) and np.all(np.isfinite(J))):
            return x
        step = np.linalg.lstsq(J, r, rcond=None)[0]
        y = x - step
        ry = fun(y)
        if not (np.all(np.isfinite(ry)) and np.max(np.abs(ry) / tol) <= np.max(np.abs(r) / tol)):
            return x
        x = y
    return x


def _degenerate(jac, x: np.ndarray, starts: np.ndarray, angles: tuple) -> bool:
    """A singular Jacobian at the root x: of rank below n relative to its own largest entry (a
    continuum, a free coordinate), or with a singular value below DEGENERATE_SLOPE of each equation's
    slopes at the three starts nearest x (a double root, a saddle-node: there the Jacobian is as small
    as the root's error, and the roots from different starts came back as a cluster of distinct
    ones; found by review: 7 'equilibria' over 4e-8 rad for one at pi/2). Near starts, not all of
    them: slopes far away (1e7 at 10 from a quartic well's centre) made every root there look
    degenerate (found by review of the first form of this test)."""
    with np.errstate(all="ignore"):
        J = jac(x)
        if not np.all(np.isfinite(J)) or not np.abs(J).max() > 0:
            return True
        if np.linalg.matrix_rank(J, tol=1e-9 * np.abs(J).max()) < len(x):
            return True
        gap = np.abs(starts - x)
        gap = np.where(angles, np.abs(np.mod(starts - x + np.pi, 2 * np.pi) - np.pi), gap)
        near = starts[np.argsort(np.linalg.norm(gap, axis=1))[:3]]
        slopes = np.zeros(len(x))
        for x0 in near:
            J0 = np.abs(jac(x0))
            slopes = np.maximum(slopes, np.where(np.isfinite(J0), J0, 0.0).max(axis=1, initial=0.0))
        if not np.all(slopes > 0):
            return False
        return bool(np.linalg.svd(J / slopes[:, None], compute_uv=False).min() < DEGENERATE_SLOPE)


class EquilibriumWarning(UserWarning):
    """find_equilibria found equilibria that are not isolated (or are degenerate)."""


def vector_function(q: list, expr: sp.Matrix, shape: tuple):
    f = sp.lambdify([q], expr, "numpy")
    return lambda x: np.asarray(f(x), dtype=float).reshape(shape)


def angle_like(eom: EquationsOfMotion, extra=()) -> tuple[bool, ...]:
    """Per coordinate: does it enter M and F (and the ``extra`` expressions) only as
    sin/cos/tan(k q + ...), k an integer?

    Those coordinates are angles: the equations are 2 pi-periodic in them.
    """
    exprs = list(eom.mass_matrix) + list(eom.forcing) + [sp.sympify(e) for e in extra]
    trig = set().union(*(e.atoms(*_TRIG) for e in exprs))
    flags = []
    for qi in eom.q:
        inside = {f for f in trig if qi in f.free_symbols}
        periodic = bool(inside) and all(f.args[0].diff(qi).is_integer for f in inside)
        hidden = {f: sp.Dummy() for f in inside}
        flags.append(periodic and not any(qi in e.xreplace(hidden).free_symbols for e in exprs))
    return tuple(flags)


def _starting_points(eom: EquationsOfMotion, guesses: Any, angles: tuple,
                     per_axis_max: int | None = None) -> np.ndarray:
    n = eom.n
    if guesses is not None:
        guesses = [guesses] if isinstance(guesses, Mapping) else guesses
        rows = [coordinate_point(eom, g) if isinstance(g, Mapping) else g for g in guesses]
        try:
            x0 = np.array(rows, dtype=float)
        except (TypeError, ValueError):
            x0 = np.array(None)  # ragged rows: reported below
        if x0.ndim == 1:
            x0 = x0.reshape(-1, 1) if n == 1 else x0.reshape(1, -1)
        if x0.ndim != 2 or x0.shape[1] != n:
            raise ValueError(f"guesses must have shape (k, {n}) for coordinates "
                             f"{', '.join(map(str, eom.q))}; got {guesses!r}")
        if not np.all(np.isfinite(x0)):  # found by review: a NaN guess returned [] with no word
            row = int(np.argwhere(~np.isfinite(x0))[0][0])
            raise ValueError(f"guesses[{row}] = {x0[row].tolist()} is not finite")
        return x0
    # as many per axis as MAX_GUESSES allows (found by review: a cap of 8 gave one coordinate 8 starts,
    # and a rotor with 12 detent equilibria came back with 4 of them, no warning)
    per_axis = max(2, min(per_axis_max or MAX_GUESSES, int(MAX_GUESSES ** (1.0 / n) + 1e-9)))
    axes = [-np.pi + 2 * np.pi * np.arange(per_axis) / per_axis if a
            else np.linspace(*LINEAR_GRID, per_axis) for a in angles]
    if per_axis ** n <= MAX_GUESSES:
        return np.array(list(itertools.product(*axes)), dtype=float)
    low = np.array([-np.pi if a else LINEAR_GRID[0] for a in angles])
    high = np.array([np.pi if a else LINEAR_GRID[1] for a in angles])
    return np.random.default_rng(0).uniform(low, high, (MAX_GUESSES, n))


def reduce_angles(x: np.ndarray, angles: tuple) -> np.ndarray:
    """Angle-like entries reduced to (-pi, pi], the others as they are."""
    y = np.array(x, dtype=float)
    for i, a in enumerate(angles):
        if a and np.isfinite(y[i]):
            y[i] = np.pi - np.mod(np.pi - y[i], 2 * np.pi)
    return y


def _canonical(x: np.ndarray, angles: tuple) -> np.ndarray:
    """Angle-like entries reduced to (-pi, pi] (-pi within 1e-9 taken as pi); round-off around zero
    (|x| < 1e-12) set to 0."""
    y = reduce_angles(x, angles)
    y = np.where(np.array(angles, dtype=bool) & (y <= -np.pi + 1e-9), y + 2 * np.pi, y)
    return np.where(np.abs(y) < 1e-12, 0.0, y)


def _unique(roots: list, angles: tuple, tol: float = 1e-9) -> list:
    """The distinct roots: two are one when every coordinate agrees to ``tol`` of its size (angles:
    ``tol`` rad apart, modulo 2 pi), with a floor of 1e-12 of that coordinate's largest root, for
    roots at zero. The roots converge to about 1e-13 (hybr's xtol); an absolute 1e-6 merged
    distinct roots of micro-scale models (found by review: a double well of a = 2e-7 lost 0 and +a)."""
    if not roots:
        return []
    floor = 1e-12 * np.abs(np.array(roots, dtype=float)).max(axis=0)
    kept: list = []
    for x in roots:
        if not any(_same(x, y, angles, tol, floor) for y in kept):
            kept.append(x)
    return sorted(kept, key=lambda x: tuple(np.round(x, 9)))


def _same(x: np.ndarray, y: np.ndarray, angles: tuple, tol: float, floor: np.ndarray) -> bool:
    d = np.abs(x - y)
    d = np.where(angles, np.abs(np.mod(x - y + np.pi, 2 * np.pi) - np.pi), d)
    limit = np.where(angles, tol, tol * np.maximum(np.abs(x), np.abs(y)) + floor)
    return bool(np.all(d <= limit))


# -- values and points --------------------------------------------------------------------------
def resolve_values(eom: EquationsOfMotion, values: Mapping) -> dict:
    """``eom.parameter_values`` updated by ``values`` (keys: parameter Symbols or names)."""
    by_name = {p.name: p for p in eom.parameters}
    out = dict(eom.parameter_values)
    if not isinstance(values, Mapping):  # found by review: [9.81] failed in dict() with no word on values
        raise ValueError(f"values must be a mapping parameter (Symbol or name) -> number, got {values!r}")
    for key, value in values.items():
        symbol = by_name.get(key.name if isinstance(key, sp.Symbol) else key)
        if symbol is None:
            raise ValueError(f"unknown parameter {key!r} for model {eom.name!r} "
                             f"(parameters: {', '.join(by_name) or 'none'})")
        try:
            out[symbol] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"parameter {symbol} needs a number, got {value!r}") from None
        if isinstance(value, (bool, np.bool_)) or not math.isfinite(out[symbol]):  # NaN gives NaN matrices
            raise ValueError(f"parameter {symbol} needs a finite number, got {value!r}")
    return out


def substitute_values(eom: EquationsOfMotion, expr: sp.Matrix, vals: dict, what: str) -> sp.Matrix:
    """``expr`` with the parameters replaced by numbers; names any parameter left without one."""
    out = expr.xreplace({p: sp.Float(v) for p, v in vals.items()})
    missing = sorted(out.free_symbols & set(eom.parameters), key=str)
    if missing:
        raise ValueError(f"{what} of model {eom.name!r}: no value for parameter(s) "
                         f"{', '.join(map(str, missing))}; pass them in values=")
    return out


def coordinate_point(eom: EquationsOfMotion, q0: Any) -> tuple:
    """q0 as a tuple of n entries; q0 is a sequence or a mapping (q Symbol or name) -> value."""
    return named_point(eom, eom.q, q0, "q0", "coordinate")


def named_point(eom: EquationsOfMotion, symbols, given: Any, argument: str, kind: str,
                entry: str = "{argument} entry for {symbol}") -> tuple:
    """``given`` (a sequence in ``symbols`` order, or a mapping by Symbol, name or dynamicsymbol)
    as a tuple; a wrong length, an unknown or missing name, a string, None or a non-finite value
    is an error naming ``argument`` and the entry."""
    names = ", ".join(map(str, symbols))
    if isinstance(given, Mapping):
        by_name = {s.name: s for s in symbols}
        found = {}
        for key, value in given.items():
            symbol = by_name.get(input_key_name(key))
            if symbol is None:
                article = "an" if kind[0] in "aeiou" else "a"
                raise ValueError(f"{key!r} is not {article} {kind} of model {eom.name!r} ({kind}s: {names})")
            found[symbol] = value
        missing = [str(s) for s in symbols if s not in found]
        if missing:
            raise ValueError(f"no value for {kind}(s) {', '.join(missing)} of model {eom.name!r}")
        values = tuple(found[s] for s in symbols)
    elif isinstance(given, np.ndarray):
        values = tuple(np.ravel(given))
    elif isinstance(given, (numbers.Number, sp.Basic)):
        values = (given,)
    else:
        values = tuple(given)
    if len(values) != len(symbols):
        raise ValueError(f"{argument} has {len(values)} entries; model {eom.name!r} has {len(symbols)} "
                         f"{kind}(s) ({names})")
    for symbol, value in zip(symbols, values):
        _check_entry(entry.format(argument=argument, symbol=symbol), value)
    return values


def _check_entry(what: str, value) -> None:
    """A point entry is a number or a sympy expression: not a string (sympify would turn "a" into a
    new symbol), not NaN or infinite (NaN matrices)."""
    if isinstance(value, (str, bytes, bool, np.bool_)) or value is None:
        raise TypeError(f"{what} must be a number or sympy expression, got {value!r}")
    if isinstance(value, numbers.Real) and not math.isfinite(float(value)):
        raise ValueError(f"{what} must be finite, got {value!r}")
    if isinstance(value, sp.Basic) and value.is_number and value.has(sp.nan, sp.zoo, sp.oo, -sp.oo):
        raise ValueError(f"{what} must be finite, got {value!r}")


# -- linearization ------------------------------------------------------------------------------
@dataclass(frozen=True)
class LinearModel:
    """``M0 dqdd + C0 dqd + K0 dq = 0`` about the equilibrium q0 (see the module docstring).

    Attributes
    ----------
    q : tuple of Symbol, (n,)
    q0 : tuple, (n,)
    M0, C0, K0 : ndarray (n, n) when built with values, else sympy ImmutableMatrix (n, n)
    """

    q: tuple
    q0: tuple
    M0: Any
    C0: Any
    K0: Any

    def eigenvalues(self) -> np.ndarray:
        """w**2 of ``K0 v = w**2 M0 v``, ascending, shape (n,); those within eigh's round-off,
        16 n eps (|K0| + |w^2| |M0|) |M0^-1| (2-norms), are 0."""
        return self._eig()[0]

    @property
    def stable(self) -> bool:
        """True when every w**2 > 0 (K0 positive definite: Lagrange-Dirichlet) and the damping, C0's
        symmetric part, is positive semidefinite; a zero (neutral) or negative w**2 then gives
        False. Otherwise the undamped test cannot tell (negative damping destabilizes a positive
        K0, a gyroscopic C0 can stabilize a negative one): with K0 positive definite, True when
        every eigenvalue of the first-order system (`first_order_eigenvalues`) has a negative real
        part; with K0 not positive definite and a gyroscopic C0, a ValueError."""
        positive = bool(np.all(self.eigenvalues() > 0))
        C0 = _numeric_matrix(self.C0, "C0")
        size = max(np.max(np.abs(C0), initial=0.0), 1e-300)
        damping = np.linalg.eigvalsh((C0 + C0.T) / 2)
        if positive and damping.min(initial=0.0) >= -1e-12 * size:
            return True
        if positive:
            rates = self.first_order_eigenvalues()
            return bool(np.all(rates.real < -1e-12 * max(np.max(np.abs(rates)), 1e-300)))
        if np.max(np.abs(C0 - C0.T), initial=0.0) > 1e-12 * size:
            raise ValueError("K0 is not positive definite and C0 has a gyroscopic (skew) part, which can "
                             "stabilize it: read first_order_eigenvalues() (purely imaginary: marginally "
                             "stable in the linear approximation; a positive real part: unstable)")
        return False

    def first_order_eigenvalues(self) -> np.ndarray:
        """Eigenvalues of ``[[0, I], [-M0^-1 K0, -M0^-1 C0]]``, the first-order form of the linear
        model with its damping and gyroscopic terms, shape (2 n,), sorted by real part."""
        M0, C0, K0 = (_numeric_matrix(A, name) for A, name in ((self.M0, "M0"), (self.C0, "C0"), (self.K0, "K0")))
        n = M0.shape[0]
        try:
            A = np.block([[np.zeros((n, n)), np.eye(n)],
                          [-np.linalg.solve(M0, K0), -np.linalg.solve(M0, C0)]])
        except np.linalg.LinAlgError:
            raise ValueError(f"M0 is singular at q0 = {self.q0}: no first-order form") from None
        rates = np.linalg.eigvals(A)
        return rates[np.argsort(rates.real, kind="stable")]

    def natural_frequencies(self) -> np.ndarray:
        """Undamped natural frequencies in rad/s, shape (n,), ascending in w**2.

        Real when the equilibrium is stable; an unstable direction (w**2 < 0) gives an imaginary
        entry i*sqrt(-w**2) (its growth rate), and then the array is complex.
        """
        lam = self.eigenvalues()
        if np.any(lam < 0):
            return np.sqrt(lam.astype(complex))
        return np.sqrt(lam)

    def mode_shapes(self) -> np.ndarray:
        """Columns v_k, shape (n, n), in the order of `natural_frequencies`; v^T M0 v = I,
        each column's largest-magnitude entry positive."""
        return self._eig()[1]

    def _eig(self) -> tuple[np.ndarray, np.ndarray]:
        M0, K0 = (_numeric_matrix(A, name) for A, name in ((self.M0, "M0"), (self.K0, "K0")))
        asym = np.max(np.abs(K0 - K0.T), initial=0.0)
        if asym > 1e-9 * max(np.max(np.abs(K0)), 1e-300):
            j, k = np.unravel_index(np.argmax(np.abs(K0 - K0.T)), K0.shape)
            raise ValueError(f"K0 is not symmetric (K0[{j},{k}] != K0[{k},{j}]: circulatory forces); "
                             "undamped natural frequencies are not defined")
        try:
            lam, V = scipy.linalg.eigh((K0 + K0.T) / 2, M0)
        except np.linalg.LinAlgError:
            raise ValueError(f"M0 is not positive definite at q0 = {self.q0}") from None
        # a zero mode comes back as round-off of eigh's backward error, about n eps |K0| |M0^-1| (measured
        # on 2000 random free spring chains: below 0.25 of it); a relative 1e-10 zeroed the soft modes of
        # a stiff chain (found by review: w^2 = 0.63 beside 2e11)
        bound = 16 * len(lam) * np.finfo(float).eps * np.linalg.norm(np.linalg.inv(M0), 2)
        noise = bound * (np.linalg.norm(K0, 2) + np.abs(lam) * np.linalg.norm(M0, 2))
        lam = np.where(np.abs(lam) <= noise, 0.0, lam)
        signs = np.sign(V[np.argmax(np.abs(V), axis=0), np.arange(V.shape[1])])
        return lam, V * np.where(signs == 0, 1.0, signs)


def _numeric_matrix(A: Any, name: str) -> np.ndarray:
    if isinstance(A, np.ndarray):
        return A
    free = sorted(A.free_symbols, key=str)
    if free:
        raise ValueError(f"{name} still contains {', '.join(map(str, free))}: "
                         "linearize with values= for numeric frequencies")
    return np.array(A.evalf(), dtype=float)


def linearize(eom: EquationsOfMotion, q0: Any, values: Mapping | None = None, inputs: Any = None) -> LinearModel:
    """The `LinearModel` about q0 at u = 0, t = 0, in the coordinates' rates.

    With generalized speeds other than the coordinate rates (Kane's u = W(q) qd, e.g. u2 = q1' +
    q2') the equations are taken to the rates first: M0 = W^T M W, C0 = -W^T dF/du W,
    K0 = -W^T dF/dq at the equilibrium (F = 0 there, so dW/dq drops out), W = (dK/du)^-1 at rest.
    For the first-order linearization about any state (steady motions, inputs) see
    `statics.state_space.linearize_state`.

    Parameters
    ----------
    eom : EquationsOfMotion
    q0 : sequence (n,) or mapping q (Symbol or name) -> value
        An equilibrium (e.g. an entry of `find_equilibria`); numbers or sympy expressions.
    values : mapping parameter (Symbol or name) -> float, optional
        None: M0, C0, K0 are sympy matrices. A mapping (``{}`` for the defaults): numpy arrays,
        ``values`` overriding ``eom.parameter_values``.
    inputs : sequence (n_r,) or mapping input (Symbol or name) -> value
        The inputs held constant; required when the model has inputs.

    Raises
    ------
    ValueError
        Wrong q0 length or unknown coordinate; unknown or missing parameter; q0 no equilibrium;
        the force at rest or M0, C0, K0 depending on t at q0 (a time-varying linear model); F not
        differentiable at rest (``sign(u)`` friction, for instance); a model with constraints
        (use `statics.state_space.linearize_state`).

    Examples
    --------
    About the hanging pendulum, M0 = m l^2 and K0 = m g l: omega = sqrt(g / l) = 3.132092 rad/s;
    about the standing one K0 = -m g l, unstable:

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model, derive_equations
    >>> theta = me.dynamicsymbols("theta")
    >>> m, g, l = sp.symbols("m g l", positive=True)
    >>> pendulum = Model("pendulum", [theta], [m, g, l], kinetic_energy=m * l**2 * theta.diff()**2 / 2,
    ...                  potential_energy=-m * g * l * sp.cos(theta),
    ...                  parameter_values={"m": 1.0, "g": 9.81, "l": 1.0})
    >>> eom = derive_equations(pendulum)
    >>> from lagcodegen.statics.equilibria import linearize
    >>> linearize(eom, [0.0]).K0
    Matrix([[g*l*m]])
    >>> hanging = linearize(eom, [0.0], {})
    >>> round(float(hanging.natural_frequencies()[0]), 6), hanging.stable
    (3.132092, True)
    >>> linearize(eom, [3.141592653589793], {}).stable
    False
    """
    require_closed_form(eom, "linearize")
    _check_unconstrained(eom, "linearize", "statics.state_space.linearize_state, which reduces to the "
                         "independent states")
    eom = hold_inputs(eom, inputs)
    if eom.n_q != eom.n_u:  # the quaternion body: sympy's det() of a non-square W failed with no words
        raise ValueError(f"linearize needs one speed per coordinate: model {eom.name!r} has {eom.n_q} coordinates "
                         f"and {eom.n_u} speeds; use statics.state_space.linearize_state")
    point = coordinate_point(eom, q0)
    at = {qi: sp.sympify(v) for qi, v in zip(eom.q, point)}
    rest = {ui: 0 for ui in eom.u}
    C = _smooth(eom, -eom.forcing.jacobian(eom.u), eom.u).xreplace(rest)
    K = _smooth(eom, -eom.forcing.xreplace(rest).jacobian(eom.q), eom.q)  # d/dq commutes with u = 0
    _check_steady(eom, at, rest, [("M", eom.mass_matrix), ("C0", C), ("K0", K)], values)
    at[eom.t] = sp.S.Zero
    mats = [sp.ImmutableMatrix(A.xreplace(at)) for A in (eom.mass_matrix, C, K)]
    _check_at_rest(eom, at, rest, mats[2], values)
    if list(eom.kinematics) != list(eom.u):
        mats = _in_coordinate_rates(eom, mats, rest, at)
    if values is None:
        return LinearModel(tuple(eom.q), point, *mats)
    vals = resolve_values(eom, values)
    arrays = [np.array(substitute_values(eom, A, vals, f"linear model {name}").evalf(), dtype=float)
              for A, name in zip(mats, ("M0", "C0", "K0"))]
    for name, array in zip(("M0", "C0", "K0"), arrays):  # found by review: scipy's "must not contain infs"
        bad = np.argwhere(~np.isfinite(array))
        if bad.size:
            i, j = bad[0]
            raise ValueError(f"the linear model of {eom.name!r} is not finite: {name}[{i}, {j}] = {array[i, j]} at "
                             f"the parameter values {', '.join(f'{p} = {v:g}' for p, v in vals.items())}")
    numbers = {p: sp.Float(v) for p, v in vals.items()}
    return LinearModel(tuple(eom.q), tuple(float(sp.sympify(v).xreplace(numbers)) for v in point), *arrays)


def _check_unconstrained(eom: EquationsOfMotion, what: str, instead: str) -> None:
    """These read M and F alone: with constraints (multipliers or dependent speeds) F = 0 is not the
    equilibrium condition and M, F's Jacobians are not the motion's (a constrained pendulum gave
    frequencies 0 and no equilibria): a ValueError naming what to use instead."""
    if eom.m or eom.n_dependent:
        kind = (f"{eom.m} constraint(s) with multipliers" if eom.m else
                f"{eom.n_dependent} dependent speed(s)")
        raise ValueError(f"{what} takes models without constraints: {eom.name!r} has {kind}, and M and F "
                         f"alone leave out the constraint forces; use {instead}")


def _check_steady(eom: EquationsOfMotion, at: dict, rest: dict, matrices: list, values) -> None:
    """A ValueError when the equations at q0 depend on t: the force at rest (q0 is then an equilibrium
    at some instants only) or M, C0, K0 (the linear model is time-varying: a pendulum on a vibrating
    pivot hangs at rest at every t, but its stability is Mathieu's, not that of the model frozen at
    t = 0; found by review, which saw 'stable' there inside the first resonance tongue)."""
    t = eom.t
    if t not in set().union(eom.forcing.free_symbols, *(A.free_symbols for _, A in matrices)):
        return
    vals = dict(eom.parameter_values) if values is None else resolve_values(eom, values)
    numbers = {p: sp.Float(v) for p, v in vals.items()}
    force = sp.Matrix(eom.forcing).xreplace(rest).xreplace(at).xreplace(numbers)
    for j, entry in enumerate(force):
        if t in entry.free_symbols and _free_of_t(eom, entry) is None:
            raise ValueError(f"model {eom.name!r} depends on {t} at q0: the generalized force at rest on "
                             f"{eom.q[j]} is {entry}, so q0 is no equilibrium at every t; "
                             "linearize_state(..., t0=) gives the Jacobian frozen at one instant")
    for name, A in matrices:
        A = sp.Matrix(A).xreplace(at).xreplace(numbers)
        for j, k in itertools.product(range(A.rows), range(A.cols)):
            if t in A[j, k].free_symbols and _free_of_t(eom, A[j, k]) is None:
                raise ValueError(f"model {eom.name!r} depends on {t} at q0: {name}[{j},{k}] = {A[j, k]}, so the "
                                 "linear model about q0 varies in time and its stability is not that of the model "
                                 "frozen at one instant (a pendulum on a vibrating pivot: Mathieu's); "
                                 "linearize_state(..., t0=) gives the Jacobian frozen at one instant")


def _check_at_rest(eom: EquationsOfMotion, at: dict, rest: dict, K: sp.Matrix, values) -> None:
    """A ValueError naming the first coordinate whose generalized force at rest does not vanish at q0
    (q0 is then no equilibrium, and the linear model about it means nothing). Checked in numbers
    (``values`` over the model's defaults) where every parameter has one."""
    vals = dict(eom.parameter_values) if values is None else resolve_values(eom, values)
    numbers = {p: sp.Float(v) for p, v in vals.items()}
    force = sp.Matrix(eom.forcing).xreplace(rest).xreplace(at).xreplace(numbers)
    stiffness = sp.Matrix(K).xreplace(numbers)
    if force.free_symbols or stiffness.free_symbols:
        # symbolic: an entry sympy shows nonzero (found by review: a pendulum at theta = 1/2 with no
        # parameter values gave K0 = g l m cos(1/2) with no error)
        for i, residual in enumerate(force):
            if residual.free_symbols and residual.equals(0) is False:
                raise ValueError(f"q0 = {[at[c] for c in eom.q]} is no equilibrium of model {eom.name!r}: the "
                                 f"generalized force on {eom.q[i]} at rest is {residual}, not 0; find one with "
                                 "find_equilibria, or linearize about any state with "
                                 "statics.state_space.linearize_state")
        return
    force, stiffness = (np.array(A.evalf(), dtype=float) for A in (force, stiffness))
    # angles modulo 2 pi: the force is periodic in them, and |q0| of 6e8 rad loosened the test until a
    # point 0.5 rad from any equilibrium passed (found by review)
    q0 = reduce_angles(np.array([float(sp.sympify(at[c]).xreplace(numbers)) for c in eom.q]), angle_like(eom))
    for i, (residual, row) in enumerate(zip(force.ravel(), stiffness)):
        # relative to the row's stiffness (and its terms |K_i| |q0|), with no absolute floor: a floor
        # of 1 took any state of a 1 mg pendulum (forces ~1e-8) for an equilibrium
        size = max(np.abs(row).max(initial=0.0), float(np.abs(row) @ np.abs(q0)), 1e-300)
        if not abs(residual) <= 1e-8 * size:
            raise ValueError(f"q0 = {[float(sp.sympify(v).xreplace(numbers)) for v in (at[c] for c in eom.q)]} "
                             f"is no equilibrium of model {eom.name!r}: the generalized force on {eom.q[i]} at rest "
                             f"is {residual:.6g}, not 0; find one with find_equilibria, or linearize about any state "
                             "with statics.state_space.linearize_state")


def _in_coordinate_rates(eom: EquationsOfMotion, mats: list, rest: dict, at: dict) -> list:
    """M0, C0, K0 in the coordinate rates when u = W qd (W = (dK/du)^-1 at rest)."""
    standing = sp.Matrix(eom.kinematics).xreplace(rest).xreplace(at)
    if any(sp.simplify(e) != 0 for e in standing):
        raise ValueError(f"model {eom.name!r}: the coordinates move at u = 0 (qd = K(q, 0, t) = "
                         f"{list(standing)}); no linear model at rest")
    rates = sp.Matrix(eom.kinematics).jacobian(eom.u).xreplace(rest).xreplace(at)
    if rates.det() == 0:
        raise ValueError(f"model {eom.name!r}: qd = K(q, u) is not invertible in u at q0; no linear model")
    W = rates.inv()
    M0, C0, K0 = (sp.Matrix(A) for A in mats)
    return [sp.ImmutableMatrix(sp.simplify(A)) for A in (W.T * M0 * W, W.T * C0 * W, W.T * K0)]


def hold_inputs(eom: EquationsOfMotion, inputs: Any) -> EquationsOfMotion:
    """``eom`` with its inputs replaced by constant values (a sequence in ``eom.inputs`` order or a
    mapping by Symbol or name); ValueError naming an input without a value or an unknown one."""
    if not eom.inputs:
        # an empty list or mapping says as much; anything else is a mistake (found by review: 0.0 passed,
        # and an array of two raised numpy's "truth value of an array ... is ambiguous")
        if inputs is not None and not (isinstance(inputs, (Mapping, Sequence, np.ndarray)) and len(inputs) == 0):
            raise ValueError(f"model {eom.name!r} has no inputs, got inputs={inputs!r}")
        return eom
    if inputs is None:
        raise ValueError(f"model {eom.name!r} has inputs {', '.join(map(str, eom.inputs))}: pass their "
                         "values, e.g. inputs={" + ", ".join(f"'{r}': 0.0" for r in eom.inputs) + "}")
    table = dict(zip(eom.inputs, input_point(eom, inputs)))

    def held(expr):
        return expr.xreplace(table) if isinstance(expr, sp.Basic) else expr

    # every expression, not only M and F: found by review, an input left in V or a measurement
    # failed to compile ("symbol r has no C name") and stayed a symbol in linearize's C matrix
    fields = {name: held(getattr(eom, name)) for name in (
        "mass_matrix", "forcing", "kinematics", "kinetic_energy", "potential_energy", "constraints",
        "constraint_jacobian", "constraint_rate", "constraint_bias", "reaction_equations", "configuration")}
    tree = eom.tree
    if tree is not None:
        tree = dataclasses.replace(tree, assignments=tuple((s, held(e)) for s, e in tree.assignments),
                                   accelerations=tuple(map(held, tree.accelerations)),
                                   pivots=tuple(map(held, tree.pivots)), energy=held(tree.energy),
                                   pivot_scales=tuple(map(held, tree.pivot_scales)),
                                   points=tuple((n, tuple(map(held, xyz))) for n, xyz in tree.points))
    return dataclasses.replace(eom, **fields, points=tuple((n, held(e)) for n, e in eom.points),
                               measurements=tuple((n, held(e)) for n, e in eom.measurements), tree=tree, inputs=())


def input_point(eom: EquationsOfMotion, inputs: Any) -> tuple:
    """``inputs`` as a tuple in ``eom.inputs`` order (sympified); names the culprit when wrong."""
    return tuple(sp.sympify(v) for v in named_point(eom, eom.inputs, inputs, "inputs", "input",
                                                         entry="input {symbol}"))


def input_key_name(key: Any) -> str:
    """A mapping key naming an input: a string, a Symbol or a dynamicsymbol r(t)."""
    if isinstance(key, str):
        return key
    if isinstance(key, sp.Symbol):
        return key.name
    func = getattr(key, "func", None)
    return getattr(func, "__name__", str(key))


def _smooth(eom: EquationsOfMotion, J: sp.Matrix, wrt: Sequence) -> sp.Matrix:
    """J unchanged, or ValueError naming the first entry sympy could not differentiate smoothly."""
    for (i, j), entry in sp.Matrix(J).todok().items():
        if entry.has(sp.Derivative, sp.DiracDelta, sp.Subs):
            raise ValueError(f"forcing F[{i}] of model {eom.name!r} is not differentiable in {wrt[j]} "
                             f"at rest (non-smooth term such as Coulomb or rolling friction with sign()); "
                             f"no linear model")
    return J
