"""Stage: EquationsOfMotion -> the linearization of the first-order form about any state.

With x = (q, u) and inputs r the equations are ``xd = f(x, r, t)``,
``f = (K(q, u, r, t), M(q, t)^-1 F(q, u, r, t))``. About an operating point (x0, r0, t0), not
necessarily an equilibrium (a steady motion with nonzero speeds, a wheel spinning), small
deviations obey ``dxd = A dx + B dr`` with::

    A = [[dK/dq,                    dK/du   ],
         [M^-1 (dF/dq - dM/dq ud0), M^-1 dF/du]],     ud0 = M^-1 F at the point
    B = [[dK/dr], [M^-1 dF/dr]]

(the derivative of M^-1 F is M^-1 (dF - dM M^-1 F)). Any choice of generalized speeds works,
since nothing assumes u = qd. Models with holonomic constraints are not covered here.
"""
from __future__ import annotations

import math
import numbers as real_numbers
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp
from sympy.matrices.exceptions import NonInvertibleMatrixError

from ..symbolic.derive import EquationsOfMotion
from .consistent import residual_sizes
from .equilibria import NOT_ANALYTIC, input_point, named_point, require_closed_form, resolve_values, substitute_values


@dataclass(frozen=True)
class StateSpace:
    """``dxd = A dx + B dr`` about (x0, r0) at t0, x = (q, u).

    Attributes
    ----------
    states : tuple of Symbol, (2n,)
        q then u.
    inputs : tuple of Symbol, (n_r,)
    x0, r0 : tuple
    t0 : float or Expr
    A : ndarray (2n, 2n) with values, else sympy ImmutableMatrix
    B : ndarray (2n, n_r) with values, else sympy ImmutableMatrix (2n x 0 without inputs)
    C, D : like A and B, (n_y, 2n) and (n_y, n_r)
        ``dy = C dx + D dr`` for the model's measurements y = h(q, u, r, t) (0 rows without).
    measurements : tuple of str, (n_y,)
    basis, A_reduced, B_reduced : ndarray or None
        Constrained models: an orthonormal basis N (2n, k) of the states the constraints allow
        at x0 (the tangent space of phi = 0, A u + b = 0), and ``A_reduced = N^T A N``,
        ``B_reduced = N^T B``: the linearization in those k independent directions, whose
        eigenvalues `eigenvalues` reports (the constraint directions only carry zeros).
    """

    states: tuple
    inputs: tuple
    x0: tuple
    r0: tuple
    t0: Any
    A: Any
    B: Any
    C: Any = None
    D: Any = None
    measurements: tuple = ()
    basis: Any = None
    A_reduced: Any = None
    B_reduced: Any = None

    def eigenvalues(self) -> np.ndarray:
        """Eigenvalues of A (complex), sorted by modulus (the natural frequency), then imaginary part."""
        if self.A_reduced is not None:
            A = np.asarray(self.A_reduced, dtype=float)
        else:
            A = np.asarray(self.A, dtype=float) if isinstance(self.A, np.ndarray) else _numeric(self.A, "A")
        values = np.linalg.eigvals(A)
        return values[np.lexsort((values.imag, np.round(np.abs(values), 12)))]

    def frequencies(self) -> np.ndarray:
        """Natural frequencies |lambda| (rad/s) of the eigenvalues, in their order."""
        return np.abs(self.eigenvalues())

    def damping_ratios(self) -> np.ndarray:
        """-Re(lambda) / |lambda| per eigenvalue (1 for a pure decay, 0 undamped, < 0 growing;
        NaN for lambda = 0)."""
        lam = self.eigenvalues()
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(np.abs(lam) > 0, -lam.real / np.abs(lam), np.nan)


def _numeric(matrix, name: str) -> np.ndarray:
    free = sorted(matrix.free_symbols, key=str)
    if free:
        raise ValueError(f"{name} still contains {', '.join(map(str, free))}: linearize with values= "
                         "for numbers")
    return np.array(matrix.evalf(), dtype=float)


def linearize_state(eom: EquationsOfMotion, x0: Any, r0: Any = None, values: Mapping | None = None,
                    t0: Any = 0) -> StateSpace:
    """A and B of ``xd = f(x, r, t)`` about (x0, r0, t0), and C, D of the measurements y = h(x, r, t).

    Parameters
    ----------
    eom : EquationsOfMotion
        With or without constraints (constrained: about a consistent state, and ``A_reduced`` in
        the directions the constraints allow).
    x0 : sequence (2n,) or mapping state (Symbol or name) -> value
        The operating state (q, u); any state, not only an equilibrium. With dependent speeds
        eliminated, also the state simulate takes, (q, independent speeds): the velocity
        constraints complete it.
    r0 : sequence (n_r,) or mapping input -> value
        The inputs there; required when the model has inputs.
    values : mapping parameter -> float, optional
        None: A and B are sympy matrices (exact, in the parameters); a mapping (``{}`` for the
        defaults): numpy arrays.
    t0 : number, optional
        Time of the operating point (rheonomic models).

    Examples
    --------
    A damped oscillator m x'' + c x' + k x = F: A = [[0, 1], [-k/m, -c/m]], B = [[0], [1/m]].

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model, derive_equations
    >>> x, F = me.dynamicsymbols("x F")
    >>> m, c, k = sp.symbols("m c k", positive=True)
    >>> model = Model("oscillator", [x], [m, c, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, generalized_forces={x: F - c * x.diff()}, inputs=[F])
    >>> linear = linearize_state(derive_equations(model), [0, 0], [0])
    >>> linear.A, linear.B
    (Matrix([
    [   0,    1],
    [-k/m, -c/m]]), Matrix([
    [  0],
    [1/m]]))
    """
    if eom.m and values is None:
        raise ValueError(f"model {eom.name!r} has constraints: its linearization is numeric; pass values= "
                         "({} for the defaults)")
    require_closed_form(eom, "linearize_state")
    if isinstance(t0, (str, bytes, bool)) or not isinstance(t0, (real_numbers.Real, sp.Basic)):
        raise TypeError(f"t0 must be a real number, got {t0!r}")  # was "Cannot convert expression to float"
    if isinstance(t0, real_numbers.Real) and not math.isfinite(float(t0)):  # A had NaN entries, no error
        raise ValueError(f"t0 must be finite, got {t0!r}")
    states = tuple(eom.q) + tuple(eom.u)
    if eom.n_dependent:
        x0 = _with_dependent_speeds(eom, x0, values, t0)
    point = _state_point(eom, x0)
    if eom.inputs and r0 is None:
        raise ValueError(f"model {eom.name!r} has inputs {', '.join(map(str, eom.inputs))}: pass r0")
    held = input_point(eom, r0) if eom.inputs else ()
    if not eom.inputs and r0 is not None and len(np.atleast_1d(r0)) != 0:
        raise ValueError(f"model {eom.name!r} has no inputs, got r0={r0!r}")
    if values is not None:  # numbers, or expressions in the parameters that values= gives
        entries = [(f"x0 entry for {s}", v) for s, v in zip(states, point)] + [("t0", t0)]
        for what, value in entries + [(f"r0 entry for {s}", v) for s, v in zip(eom.inputs, held)]:
            value = sp.sympify(value)
            stray = sorted(map(str, value.free_symbols - set(eom.parameters)))
            if stray:
                raise ValueError(f"{what} holds {', '.join(stray)}, which is no parameter of model {eom.name!r}: "
                                 "with values= the point is numeric")
            if value.is_real is False or value.has(sp.I):
                raise ValueError(f"{what} must be real, got {value}")
    at = dict(zip(states, point)) | dict(zip(eom.inputs, held)) | {eom.t: sp.sympify(t0)}
    M, F, K = (sp.Matrix(X) for X in (eom.mass_matrix, eom.forcing, eom.kinematics))
    r = list(eom.inputs)
    parts = {"M": M, "F": F, "K": K, "dK/dx": K.jacobian(states),
             "dK/dr": K.jacobian(r) if r else sp.zeros(eom.n_q, 0)}
    if not eom.m:  # a constrained model differentiates its whole Lagrange I solve instead (`_constrained`)
        parts |= {"dF/dq": F.jacobian(eom.q), "dF/du": F.jacobian(eom.u),
                  "dF/dr": F.jacobian(r) if r else sp.zeros(eom.n_u, 0)}
    Y = sp.Matrix([y for _, y in eom.measurements]) if eom.measurements else sp.zeros(0, 1)
    parts["dh/dx"] = Y.jacobian(states) if eom.measurements else sp.zeros(0, eom.n_state)
    parts["dh/dr"] = Y.jacobian(r) if eom.measurements and r else sp.zeros(len(eom.measurements), len(r))
    names = tuple(name for name, _ in eom.measurements)
    dM = [] if eom.m else [M.diff(qc) for qc in eom.q]
    for name, matrix in parts.items():
        # at the point: sign(u) is smooth where u != 0, and DiracDelta(0.5) is 0 (found by review: the
        # bar on rollers was refused at x_d = 0.5, where A exists)
        _check_smooth(eom, matrix.xreplace(at), name)
    if values is None:
        here = {name: matrix.xreplace(at) for name, matrix in parts.items()}
        for name, matrix in here.items():
            _check_defined(eom, name, matrix, point, held)
        dM_here = [X.xreplace(at) for X in dM]
        solve = lambda rhs: here["M"].LUsolve(rhs)  # noqa: E731
        try:
            ud0 = solve(here["F"])
        except NonInvertibleMatrixError:
            raise ValueError(f"the mass matrix of model {eom.name!r} is singular at x0 = {list(point)}: "
                             f"M = {here['M'].tolist()}; no linearization") from None
        A_lower = solve(here["dF/dq"] - sp.Matrix.hstack(*[X * ud0 for X in dM_here])).row_join(solve(here["dF/du"]))
        A = here["dK/dx"].col_join(A_lower)
        B = here["dK/dr"].col_join(solve(here["dF/dr"])) if r else sp.zeros(eom.n_state, 0)
        return StateSpace(states, tuple(r), point, held, t0, sp.ImmutableMatrix(sp.simplify(A)),
                          sp.ImmutableMatrix(sp.simplify(B)), sp.ImmutableMatrix(sp.simplify(here["dh/dx"])),
                          sp.ImmutableMatrix(sp.simplify(here["dh/dr"])), names)
    vals = resolve_values(eom, values)

    def number(X, what):
        value = substitute_values(eom, X.xreplace(at), vals, f"linearization: {what}").evalf()
        _check_defined(eom, what, value, point, held)
        return np.array(value, dtype=float)
    if eom.m:
        return _constrained(eom, states, point, held, at, vals, number, parts, t0)
    here = {name: number(matrix, name) for name, matrix in parts.items()}
    M_here = here["M"]
    if not np.all(np.isfinite(M_here)) or np.linalg.matrix_rank(M_here) < eom.n_u:
        raise ValueError(f"the mass matrix of model {eom.name!r} is singular or not finite at x0 = {list(point)} "
                         f"with these parameter values: M = {M_here.tolist()}; no linearization")
    ud0 = np.linalg.solve(M_here, here["F"].ravel())
    dM_ud = np.column_stack([number(X, f"dM/d{qc}") @ ud0 for X, qc in zip(dM, eom.q)]) if eom.n_q else \
        np.zeros((0, 0))
    A = np.vstack([here["dK/dx"], np.hstack([np.linalg.solve(M_here, here["dF/dq"] - dM_ud),
                                              np.linalg.solve(M_here, here["dF/du"])])])
    B = np.vstack([here["dK/dr"], np.linalg.solve(M_here, here["dF/dr"])]) if r else np.zeros((eom.n_state, 0))
    _check_finite(eom, {"A": A, "B": B, "C": here["dh/dx"], "D": here["dh/dr"]}, vals)
    numbers = {p: sp.Float(v) for p, v in vals.items()}
    as_float = lambda v: float(sp.sympify(v).xreplace(numbers))  # noqa: E731
    return StateSpace(states, tuple(r), tuple(map(as_float, point)), tuple(map(as_float, held)),
                      as_float(t0), A, B, here["dh/dx"].reshape(len(names), eom.n_state),
                      here["dh/dr"].reshape(len(names), len(r)), names)


def _check_defined(eom: EquationsOfMotion, name: str, matrix: sp.Matrix, point, held) -> None:
    """A ValueError naming the first entry of ``matrix`` that is infinite or undefined at the point
    (found by review: a measurement 1/x at x = 0 gave C = [[zoo, 0]] with no word, and with values=
    numpy's "Cannot convert complex to float", naming nothing)."""
    for (i, j), entry in np.ndenumerate(np.array(sp.Matrix(matrix).tolist(), dtype=object).reshape(matrix.shape)):
        entry = sp.sympify(entry)
        if entry.has(sp.zoo, sp.nan, sp.oo, -sp.oo) or (entry.is_number and entry.is_real is False):
            at = f"x0 = {list(point)}" + (f", r0 = {list(held)}" if held else "")
            name = {"dh/dx": "C = dh/dx", "dh/dr": "D = dh/dr"}.get(name, name)
            raise ValueError(f"the linearization of model {eom.name!r} is undefined at {at}: {name}[{i}, {j}] = "
                             f"{entry} (an expression of the model is not differentiable or infinite there)")


def _check_finite(eom: EquationsOfMotion, matrices: dict, values: Mapping) -> None:
    """A ValueError naming the first matrix with an infinite or NaN entry (found by review: A with
    inf entries was returned, and numpy's "Array must not contain infs or NaNs" came later, from
    the eigenvalues, naming nothing)."""
    for name, matrix in matrices.items():
        matrix = np.asarray(matrix, dtype=float)
        bad = np.argwhere(~np.isfinite(matrix))
        if bad.size:
            i, j = bad[0]
            sizes = sorted((abs(float(v)), str(p), float(v)) for p, v in values.items() if float(v) != 0)
            hint = f" (parameters from {sizes[0][1]} = {sizes[0][2]:g} to {sizes[-1][1]} = {sizes[-1][2]:g})" \
                if sizes else ""
            raise ValueError(f"the linearization of model {eom.name!r} is not finite: {name}[{i}, {j}] = "
                             f"{matrix[i, j]} at these parameter values{hint}")


def _constrained(eom, states, point, held, at, vals, number, parts, t0) -> StateSpace:
    """Lagrange I about (x0, r0): z = (ud, lambda) solves K z = rhs with K = [[M, A^T], [A, 0]],
    rhs = (F, gamma), so dz/dv = K^-1 (drhs/dv - dK/dv z) for every state and input v; then the
    same in the directions the constraints allow (module docstring of `StateSpace`)."""
    from scipy.linalg import null_space

    n, m, r = eom.n_u, eom.m, list(eom.inputs)  # n: speeds, the size of M
    M, A = sp.Matrix(eom.mass_matrix), sp.Matrix(eom.constraint_jacobian)
    K = sp.Matrix(sp.BlockMatrix([[M, A.T], [A, sp.zeros(m, m)]]))
    rhs = sp.Matrix.vstack(sp.Matrix(eom.forcing), sp.Matrix(eom.constraint_bias))
    # consistency first: an inconsistent start was blamed on a rank loss (found by review)
    held_rows = eom.n_holonomic
    c = sp.Matrix.vstack(sp.Matrix(eom.constraints)[:held_rows, :],
                         A * sp.Matrix(eom.u) + sp.Matrix(eom.constraint_rate))
    residual = number(c, "constraints").ravel()
    positions, velocities = residual_sizes(eom)
    # relative to the size of each row's terms, with no absolute floor (found by review: a rod of
    # l = 1e-6 with its bob at l/2 linearized as a rod half as long)
    limit = 1e-8 * number(sp.Matrix.vstack(positions[:held_rows, :], velocities), "constraints").ravel()
    if not np.all(np.abs(residual) <= limit):
        worst = int(np.argmax(np.abs(residual) - limit))
        point_values = number(sp.Matrix(states), "x0")
        raise ValueError(f"x0 = {point_values.ravel().tolist()} violates constraint row {worst} of model {eom.name!r} "
                         f"(residual {residual[worst]:.3g}): linearize about a consistent state (consistent_state)")
    K_here = number(K, "constraint matrix [[M, A^T], [A, 0]]")
    if not np.all(np.isfinite(K_here)) or np.linalg.matrix_rank(K_here) < n + m:
        raise ValueError(f"[[M, A^T], [A, 0]] of model {eom.name!r} is singular at x0 = {list(point)}: a singular mass "
                         "matrix or constraints that lost rank; no linearization")
    z = np.linalg.solve(K_here, number(rhs, "forcing and gamma").ravel())
    columns = []
    in_K, in_rhs = K.free_symbols, rhs.free_symbols
    variables = list(states) + r
    fixed = {v: sp.sympify(at[v]) for v in variables} | {eom.t: sp.sympify(t0)}
    fixed |= {p: sp.Float(value) for p, value in vals.items()}

    def partial(X: sp.Matrix, v, what: str) -> np.ndarray:
        """dX/dv at the point, exactly: every other variable and parameter is set first, so the
        derivative is taken of a function of v alone (whole-tree derivatives took minutes for the
        Whipple bicycle)."""
        alone = X.xreplace({w: value for w, value in fixed.items() if w != v})
        return number(_smooth(eom, alone.diff(v), what), what)

    parameters = tuple(sorted(vals, key=str))
    stepped = _complex_step_terms(eom, tuple(variables), parameters)
    base = np.array([complex(fixed[v]) for v in variables] + [complex(fixed[eom.t])]
                    + [complex(vals[p]) for p in parameters])
    for k, v in enumerate(variables):  # K holds no speeds or inputs: most of its derivatives are zero
        if stepped is not None:
            try:
                dK, drhs = _complex_step(stepped, base, k)
            except TypeError:  # a numpy function that takes no complex arguments (arctan2): symbolic ones
                stepped = None
        if stepped is None:
            dK = partial(K, v, f"d[[M, A^T], [A, 0]]/d{v}") if v in in_K else np.zeros(K.shape)
            drhs = partial(rhs, v, f"d(F, gamma)/d{v}") if v in in_rhs else np.zeros((n + m, 1))
        columns.append(np.linalg.solve(K_here, drhs.ravel() - dK @ z)[:n])
    lower = np.column_stack(columns) if columns else np.zeros((n, 0))
    size = eom.n_state
    A_full = np.vstack([number(parts["dK/dx"], "dK/dx"), lower[:, :size]])
    B_full = np.vstack([number(parts["dK/dr"], "dK/dr") if r else np.zeros((eom.n_q, 0)), lower[:, size:]])
    basis = null_space(number(c.jacobian(states), "constraint Jacobian"))
    names = tuple(name for name, _ in eom.measurements)
    numbers = {p: sp.Float(v) for p, v in vals.items()}
    as_float = lambda v: float(sp.sympify(v).xreplace(numbers))  # noqa: E731
    C = number(parts["dh/dx"], "dh/dx").reshape(len(names), size)
    D = number(parts["dh/dr"], "dh/dr").reshape(len(names), len(r))
    return StateSpace(states, tuple(r), tuple(map(as_float, point)), tuple(map(as_float, held)), as_float(t0),
                      A_full, B_full, C, D, names, basis=basis, A_reduced=basis.T @ A_full @ basis,
                      B_reduced=basis.T @ B_full)


#: the complex step: f(x + i h) = f(x) + i h f'(x) + O(h^2), so Im f / h = f'(x) to rounding for any h this small
COMPLEX_STEP = 1e-30


#: id(eom) -> (eom, variables, parameters, function): a model's linearizations at many states
#: (a speed sweep of eigenvalues) lambdify its terms once
_STEP_TERMS: dict = {}


def _complex_step_terms(eom: EquationsOfMotion, variables: tuple, parameters: tuple):
    held = _STEP_TERMS.get(id(eom))
    if held is not None and held[0] is eom and held[1:3] == (variables, parameters):
        return held[3]
    terms = _lambdified_terms(eom, variables, parameters)
    if len(_STEP_TERMS) >= 4:
        _STEP_TERMS.pop(next(iter(_STEP_TERMS)))
    _STEP_TERMS[id(eom)] = (eom, variables, parameters, terms)
    return terms


def _lambdified_terms(eom: EquationsOfMotion, variables: tuple, parameters: tuple):
    """[[M, A^T], [A, 0]] and (F, gamma) as one numpy function of (variables, t, parameters), for
    derivatives by the complex step (Squire and Trapp, SIAM Review 40 (1998) 110; Martins, Sturdza
    and Alonso, ACM TOMS 29 (2003) 245): exact to rounding, and a cheap evaluation per variable
    where the symbolic derivatives took seconds each for the Whipple bicycle. None when a term is
    not analytic (then the symbolic derivatives, which name such a term)."""
    M, A = sp.Matrix(eom.mass_matrix), sp.Matrix(eom.constraint_jacobian)
    K = sp.Matrix(sp.BlockMatrix([[M, A.T], [A, sp.zeros(eom.m, eom.m)]]))
    rhs = sp.Matrix.vstack(sp.Matrix(eom.forcing), sp.Matrix(eom.constraint_bias))
    if K.has(*NOT_ANALYTIC) or rhs.has(*NOT_ANALYTIC) or K.has(sp.Derivative) or rhs.has(sp.Derivative):
        return None
    return sp.lambdify(list(variables) + [eom.t] + list(parameters), [K, rhs], modules="numpy", cse=True)


def _complex_step(terms, base: np.ndarray, k: int) -> tuple:
    """d/dv_k of [[M, A^T], [A, 0]] and (F, gamma) at ``base``, v_k stepped by i COMPLEX_STEP."""
    args = base.copy()
    args[k] += 1j * COMPLEX_STEP
    K, rhs = terms(*args)
    return (np.imag(np.asarray(K, dtype=complex)) / COMPLEX_STEP,
            np.imag(np.asarray(rhs, dtype=complex)).reshape(-1, 1) / COMPLEX_STEP)


def _smooth(eom: EquationsOfMotion, matrix: sp.Matrix, what: str) -> sp.Matrix:
    _check_smooth(eom, matrix, what)
    return matrix


def _with_dependent_speeds(eom: EquationsOfMotion, x0: Any, values: Mapping, t0: Any) -> Any:
    """x0 of a model with eliminated dependent speeds as simulate takes it, (q, independent speeds)
    (a sequence of that length, or a mapping without the dependent speeds), completed by the
    dependent speeds the velocity constraints give there; a full state (q, u) is taken as it is."""
    p = eom.n_u - eom.n_dependent
    reduced, dependent = tuple(eom.q) + tuple(eom.u[:p]), tuple(eom.u[p:])
    if isinstance(x0, Mapping):
        names = {key if isinstance(key, str) else getattr(key, "name", str(key)) for key in x0}
        given = [u.name for u in dependent if u.name in names]
        if len(given) == len(dependent):
            return x0
        if given:
            raise ValueError(f"x0 gives the dependent speed(s) {', '.join(given)} of model {eom.name!r} but not "
                             f"{', '.join(u.name for u in dependent if u.name not in names)}: give all of them "
                             "(a full state) or none (the velocity constraints complete them)")
        point = named_point(eom, reduced, x0, "x0", "state")
    else:
        flat = np.ravel(np.asarray(x0, dtype=object)) if not isinstance(x0, (str, bytes)) else x0
        if len(flat) != len(reduced):
            return x0  # a full state, or a wrong length that _state_point names
        point = named_point(eom, reduced, flat, "x0", "state")
    A = sp.Matrix(eom.constraint_jacobian)
    at = dict(zip(reduced, map(sp.sympify, point))) | {eom.t: sp.sympify(t0)}
    vals = resolve_values(eom, values)
    A_D = np.array(substitute_values(eom, A[:, p:].xreplace(at), vals, "the dependent block A_D").evalf(),
                   dtype=float)
    rest = sp.Matrix([sum((A[i, k] * eom.u[k] for k in range(p)), sp.S.Zero) + eom.constraint_rate[i]
                      for i in range(eom.m)])
    b = np.array(substitute_values(eom, rest.xreplace(at), vals, "the velocity constraints").evalf(),
                 dtype=float).ravel()
    scale = max(np.abs(np.asarray(substitute_values(eom, A.xreplace(at), vals, "A").evalf(), dtype=float)).max(),
                0.0)
    if not np.all(np.isfinite(A_D)) or np.linalg.matrix_rank(A_D, tol=1e-12 * scale) < eom.n_dependent:
        raise ValueError(f"the velocity constraints of model {eom.name!r} do not fix the dependent speeds "
                         f"{', '.join(map(str, dependent))} at x0 = {list(point)}: A_D = {A_D.tolist()} lost rank")
    return tuple(point) + tuple(np.linalg.solve(A_D, -b))


def _state_point(eom: EquationsOfMotion, x0: Any) -> tuple:
    states = tuple(eom.q) + tuple(eom.u)
    return tuple(sp.sympify(v) for v in named_point(eom, states, x0, "x0", "state"))


def _check_smooth(eom: EquationsOfMotion, matrix: sp.Matrix, what: str) -> None:
    for (i, j), entry in matrix.todok().items():
        if entry.has(sp.Derivative, sp.DiracDelta, sp.Subs):
            raise ValueError(f"{what}[{i}, {j}] of model {eom.name!r} is not differentiable (a non-smooth term "
                             "such as sign() friction); no linearization")
