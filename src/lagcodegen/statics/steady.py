"""Stage: EquationsOfMotion -> steady motions (upright rolling, a disc's steady turn, a governor's
relative equilibrium): states where chosen accelerations vanish while the system moves.

A steady motion holds some coordinates constant (a lean angle) and some speeds constant (a spin, a
yaw rate) while cyclic coordinates advance. Given the known parts of the state, `steady_motion`
solves for the rest::

    phi(q, t) = 0, A u + b = 0              (the model's constraints, when it has them)
    ud_j(q, u, t) = 0 for every steady speed  (from M ud + A^T lambda = F, A ud = gamma)

as many equations as unknowns (scipy's ``root``, MINPACK's hybrid method, from the given values),
then `linearize_state` about the result gives its stability (``eigenvalues()`` in the directions
the constraints allow). The accelerations come from the same Lagrange I solve `linearize_state`
differentiates, lambdified once per model.
"""
from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..symbolic.derive import EquationsOfMotion
from .consistent import checked_tolerance, residual_sizes, term_sizes
from .equilibria import (
    hold_inputs,
    input_key_name,
    named_point,
    require_closed_form,
    resolve_values,
    substitute_values,
)

#: the functions that switch, as the complex step must see them: the branch the real part is on,
#: continued analytically (Martins, Sturdza and Alonso, ACM TOMS 29 (2003) 245, sec. 3: abs by the
#: sign of the real part). numpy's own abs takes the modulus (no derivative in the imaginary part)
#: and its sign of a complex z is z/|z|; found by review: a flywheel with drag c phi'|phi'| got half
#: its eigenvalue. Piecewise, Min, Max and Heaviside print as comparisons, which numpy makes on the
#: real part first.
_COMPLEX_STEP_SAFE = {
    "Abs": lambda z: np.where(np.real(z) < 0, -z, z),
    "sign": lambda z: np.sign(np.real(z)),
    "floor": lambda z: np.floor(np.real(z)),
    "ceiling": lambda z: np.ceil(np.real(z)),
    "re": lambda z: z,  # of a real argument: the argument itself
    "im": lambda z: 0 * np.real(z),
    "conjugate": lambda z: z,
}
_MODULES = [_COMPLEX_STEP_SAFE, "numpy"]


@dataclass(frozen=True)
class SteadyMotion:
    """A solved steady motion: ``state`` (q, u in the model's order, by name in ``values``), the
    largest residual of the solved equations, and the accelerations of every speed there."""

    names: tuple
    state: np.ndarray
    residual: float
    accelerations: np.ndarray

    @property
    def values(self) -> dict:
        return dict(zip(self.names, self.state.tolist()))


def steady_motion(eom: EquationsOfMotion, given: Mapping, unknowns: Sequence[str], steady: Sequence[str], *,
                  values: Mapping | None = None, t: float = 0.0, tol: float = 1e-10, inputs=None) -> SteadyMotion:
    """Solve for a steady motion of ``eom``.

    Parameters
    ----------
    given : mapping state name -> value
        The known coordinates and speeds (a state not named is 0) and the starting guesses of the
        unknowns.
    unknowns : sequence of str
        States solved for; as many as the constraint rows plus the steady speeds.
    steady : sequence of str
        Speeds whose accelerations vanish.
    values : mapping parameter -> float, optional
        Parameter values (default: the model's).
    inputs : sequence or mapping, optional
        The inputs held constant (`hold_inputs`); required when the model has inputs.
    tol : float
        Accepted residual of each equation, relative to the size of its terms (a constraint row's
        as `consistent.constraint_scales`; an acceleration's, |K^-1| times the sum of |terms| of F
        and gamma).

    Raises ValueError naming the culprit: an unknown state name, a count of unknowns that does not
    match the equations, or no convergence (with the residual reached).
    """
    from scipy.optimize import root

    require_closed_form(eom, "steady_motion")
    eom = hold_inputs(eom, inputs)  # found by review: a driven model failed with "Cannot convert expression to float"

    checked_tolerance(tol, "steady motion")
    # names as strings, Symbols or dynamicsymbols (found by review: the model's own Symbol phi_d was "no
    # state ... (states: ..., phi_d)", and steady="theta_d" was read letter by letter: "'t' is no state")
    for label, listed in (("unknowns", unknowns), ("steady", steady)):
        if isinstance(listed, (str, bytes)) or not isinstance(listed, (Sequence, np.ndarray)):
            raise TypeError(f"steady motion: {label} must be a list of state names, got {listed!r}")
    unknowns, steady = ([input_key_name(name) for name in listed] for listed in (unknowns, steady))
    if not steady:
        raise ValueError("steady motion: name at least one steady speed")
    if eom.n_q != eom.n_u:
        raise ValueError(f"steady motion: model {eom.name!r} has {eom.n_q} coordinates and {eom.n_u} speeds; "
                         "steady motions need one speed per coordinate for now")
    states = list(eom.q) + list(eom.u)
    names = tuple(s.name for s in states)
    if not isinstance(given, Mapping):
        raise TypeError(f"given must map state names to values, got {type(given).__name__}")
    known = {str(getattr(k, "name", k)): v for k, v in given.items()}
    x0 = np.array(named_point(eom, states, {name: known.get(name, 0.0) for name in names} | known, "given",
                              "state"), dtype=float)
    index = {name: i for i, name in enumerate(names)}
    for name in list(unknowns) + list(steady):
        if name not in index:
            raise ValueError(f"steady motion: {name!r} is no state of model {eom.name!r} (states: {', '.join(names)})")
    for label, listed in (("unknowns", unknowns), ("steady", steady)):
        twice = sorted({name for name in listed if list(listed).count(name) > 1})
        if twice:  # found by review: a repeated unknown was dropped, and the solve failed with a vague message
            raise ValueError(f"steady motion: {label} names {', '.join(map(repr, twice))} more than once")
    speeds = {s.name: j for j, s in enumerate(eom.u)}
    for name in steady:
        if name not in speeds:
            raise ValueError(f"steady motion: {name!r} is a coordinate; steady names speeds (their "
                             "accelerations vanish)")
    constraint_rows = eom.n_holonomic + eom.m  # phi of the holonomic ones, then A u + b of every row
    rows = constraint_rows + len(steady)
    if len(unknowns) != rows:
        raise ValueError(f"steady motion: {len(unknowns)} unknowns ({', '.join(unknowns)}) for {rows} equations "
                         f"({constraint_rows} constraint rows and {len(steady)} steady speeds)")
    accelerations, constraints, sizes = _functions(eom, values, t)
    solved = [index[name] for name in unknowns]
    wanted = [speeds[name] for name in steady]

    def equations(z: np.ndarray) -> np.ndarray:
        x = x0.copy()
        x[solved] = z
        try:
            return np.concatenate([constraints(x), accelerations(x)[wanted]])
        except np.linalg.LinAlgError:  # found by review: numpy's bare "Singular matrix" from inside root
            point = ", ".join(f"{c} = {x[i]:.6g}" for i, c in enumerate(eom.q))
            raise ValueError(f"steady motion of model {eom.name!r}: the search reached the configuration {point}, "
                             "where the mass matrix (with the constraints: [[M, A^T], [A, 0]]) is singular; start "
                             "from guesses away from it") from None

    result = root(equations, x0[solved], method="hybr", options={"xtol": 1e-14})
    x = x0.copy()
    x[solved] = result.x
    residuals = equations(result.x)
    residual = float(np.max(np.abs(residuals), initial=0.0))
    constraint_sizes, acceleration_sizes = sizes(x)
    # relative to the size of each equation's terms (found by review: an absolute 1e-10 took a free
    # flywheel spun up at 5e-11 rad/s^2 for a steady spin)
    limit = tol * np.concatenate([constraint_sizes, acceleration_sizes[wanted]])
    if not np.all(np.abs(residuals) <= limit):
        relative = np.max(np.abs(residuals) / limit) * tol
        raise ValueError(f"steady motion of model {eom.name!r}: no solution from the given guesses (largest "
                         f"residual {residual:.3g}, relative to its terms {relative:.3g}, "
                         f"after {result.nfev} evaluations: {result.message})")
    return SteadyMotion(names, x, residual, accelerations(x))


def steady_eigenvalues(eom: EquationsOfMotion, motion: SteadyMotion, cyclic: Sequence[str], speeds: Sequence[str],
                       *, values: Mapping | None = None, t: float = 0.0, inputs=None) -> np.ndarray:
    """Eigenvalues of the linearization about a steady motion, in the states it holds steady.

    A steady motion is an equilibrium only of the reduced system without its ``cyclic`` coordinates
    (yaw, spin, the contact point's x and y: coordinates the dynamics do not depend on, which
    advance along the motion); the linearization of the full state at one instant of it is not
    (its Jacobian turns with the cyclic coordinates). The reduced state is the other coordinates and
    the independent ``speeds`` (n_u - m of them for m velocity constraints; the dependent ones are
    solved from the constraints at every state); its Jacobian is taken by the complex step on the
    same Lagrange I solve `steady_motion` uses (Routh's reduction; e.g. Neimark and Fufaev,
    Dynamics of Nonholonomic Systems, ch. 4, for steady motions of a rolling disc).
    """
    require_closed_form(eom, "steady_eigenvalues")
    eom = hold_inputs(eom, inputs)
    names = list(motion.names)
    q_names = [s.name for s in eom.q]
    u_names = [s.name for s in eom.u]
    for name in list(cyclic) + list(speeds):
        if name not in names:
            raise ValueError(f"steady eigenvalues: {name!r} is no state of model {eom.name!r}")
    if any(name not in q_names for name in cyclic):
        raise ValueError("steady eigenvalues: cyclic names coordinates")
    if any(name not in u_names for name in speeds) or len(speeds) != eom.n_u - eom.m:
        raise ValueError(f"steady eigenvalues: name {eom.n_u - eom.m} independent speeds of {', '.join(u_names)} "
                         f"(one per speed not fixed by the {eom.m} velocity constraints)")
    if eom.n_holonomic:
        raise ValueError(f"steady eigenvalues: model {eom.name!r} has holonomic constraints; reduce it to "
                         "independent coordinates first")
    twice = sorted({name for name in list(cyclic) + list(speeds) if (list(cyclic) + list(speeds)).count(name) > 1})
    if twice:  # found by review: numpy's "Last 2 dimensions of the array must be square"
        raise ValueError(f"steady eigenvalues: {', '.join(map(repr, twice))} named more than once")
    kept_q = [i for i, name in enumerate(q_names) if name not in cyclic]
    accelerations = _functions(eom, values, t)[0]
    kept_u = [u_names.index(name) for name in speeds]
    dependent = [j for j in range(eom.n_u) if j not in kept_u]
    n_q = eom.n_q
    vals = {**resolve_values(eom, {} if values is None else values), eom.t: float(t)}
    A = sp.lambdify([list(eom.q)], substitute_values(eom, sp.Matrix(eom.constraint_jacobian), vals, "A"), _MODULES)
    b = sp.lambdify([list(eom.q)], substitute_values(eom, sp.Matrix(eom.constraint_rate), vals, "b"), _MODULES)
    K = sp.lambdify([list(eom.q) + list(eom.u)], substitute_values(eom, sp.Matrix(eom.kinematics), vals, "K"),
                    _MODULES)

    def reduced(s: np.ndarray, base: np.ndarray = motion.state) -> np.ndarray:
        x = base.astype(s.dtype)
        x[kept_q] = s[:len(kept_q)]
        x[[n_q + j for j in kept_u]] = s[len(kept_q):]
        if dependent:  # A_D u_D = -(A_I u_I + b)
            A_here = np.asarray(A(x[:n_q]), dtype=s.dtype)
            rest = A_here[:, kept_u] @ x[[n_q + j for j in kept_u]] + np.asarray(b(x[:n_q]), dtype=s.dtype).ravel()
            try:
                x[[n_q + j for j in dependent]] = np.linalg.solve(A_here[:, dependent], -rest)
            except np.linalg.LinAlgError:  # found by review: a bare "Singular matrix"
                raise ValueError(f"steady eigenvalues: the velocity constraints do not fix the speeds not named "
                                 f"({', '.join(u_names[j] for j in dependent)}) from {', '.join(speeds)}: name "
                                 "speeds whose complement the constraints solve for") from None
        rates = np.asarray(K(x), dtype=s.dtype).ravel()
        return np.concatenate([rates[kept_q], accelerations(x)[kept_u]])

    s0 = np.concatenate([motion.state[kept_q], motion.state[[n_q + j for j in kept_u]]])
    step = 1e-30
    J = np.empty((len(s0), len(s0)))
    for k in range(len(s0)):
        s = s0.astype(complex)
        s[k] += 1j * step
        J[:, k] = np.imag(reduced(s)) / step
    scale = 1.0 + np.abs(J).max(initial=0.0) * (1.0 + np.abs(s0).max(initial=0.0))
    for name in cyclic:  # the reduced system must not read it: its rates' derivative in it vanishes
        base = motion.state.astype(complex)
        base[q_names.index(name)] += 1j * step
        slope = np.abs(np.imag(reduced(s0.astype(complex), base)) / step).max(initial=0.0)
        if not slope <= 1e-8 * scale:
            raise ValueError(f"steady eigenvalues: {name} is not cyclic in model {eom.name!r}: the reduced "
                             f"system's rates change with it (slope {slope:.3g}); name only coordinates the "
                             "dynamics do not read")
    held = reduced(s0.astype(float))  # the reduced state's rates: zero on a steady motion
    reduced_names = [q_names[i] for i in kept_q] + [u_names[j] for j in kept_u]
    for i, rate in enumerate(held):
        if not abs(rate) <= 1e-8 * scale:
            raise ValueError(f"steady eigenvalues: the state {motion.state.tolist()} is no steady motion of model "
                             f"{eom.name!r}: d/dt {reduced_names[i]} = {rate:.6g}, not 0 (find one with steady_motion)")
    return np.linalg.eigvals(J)


def _functions(eom: EquationsOfMotion, values: Mapping | None, t: float) -> tuple:
    """Numeric ud(x) of every speed (the Lagrange I solve when constrained), the constraint rows
    phi (holonomic) then A u + b (velocity), and the size of their terms (the constraint rows' and
    the accelerations': |K^-1| times the sum of |terms| of each row of (F, gamma)), at time t with
    the parameters substituted."""
    vals = {**resolve_values(eom, {} if values is None else values), eom.t: float(t)}
    states = list(eom.q) + list(eom.u)
    M, F = sp.Matrix(eom.mass_matrix), sp.Matrix(eom.forcing)
    A = sp.Matrix(eom.constraint_jacobian)
    m = eom.constraints.rows
    K = sp.Matrix(sp.BlockMatrix([[M, A.T], [A, sp.zeros(m, m)]])) if m else M
    rhs = sp.Matrix.vstack(F, sp.Matrix(eom.constraint_bias)) if m else F
    K_f = sp.lambdify([states], substitute_values(eom, K, vals, "steady motion: M"), _MODULES, cse=True)
    rhs_f = sp.lambdify([states], substitute_values(eom, rhs, vals, "steady motion: F"), _MODULES, cse=True)
    rows = sp.Matrix.vstack(sp.Matrix(eom.constraints)[:eom.n_holonomic, :],
                            A * sp.Matrix(eom.u) + sp.Matrix(eom.constraint_rate)) if m else sp.zeros(0, 1)
    rows_f = sp.lambdify([states], substitute_values(eom, rows, vals, "steady motion: constraints"), _MODULES)
    n = eom.n_u
    terms = term_sizes(rhs)
    terms_f = sp.lambdify([states], substitute_values(eom, terms, vals, "steady motion: F"), "numpy")
    if m:
        positions, velocities = residual_sizes(eom)
        row_sizes = sp.Matrix.vstack(positions[:eom.n_holonomic, :], velocities)
    else:
        row_sizes = sp.zeros(0, 1)
    row_sizes_f = sp.lambdify([states], substitute_values(eom, row_sizes, vals, "steady motion: constraints"),
                              "numpy")

    def accelerations(x: np.ndarray) -> np.ndarray:  # complex x too (the complex step)
        return np.linalg.solve(np.asarray(K_f(x), dtype=x.dtype), np.asarray(rhs_f(x), dtype=x.dtype).ravel())[:n]

    def constraints(x: np.ndarray) -> np.ndarray:
        return np.asarray(rows_f(x), dtype=float).ravel()

    def sizes(x: np.ndarray) -> tuple:
        inverse = np.abs(np.linalg.inv(np.asarray(K_f(x), dtype=float)))
        return (np.asarray(row_sizes_f(x), dtype=float).ravel(),
                (inverse @ np.asarray(terms_f(x), dtype=float).ravel())[:n])

    return accelerations, constraints, sizes
