"""Stage: EquationsOfMotion -> equilibria of constrained models.

The principle of virtual displacements with multipliers: at rest, F(q, 0) = A(q)^T lambda and
phi(q) = 0 (sign convention M ud + A^T lambda = F; the constraint forces on the system are
-A^T lambda). Holding coordinates fixed turns their equations into unknown actuator forces, so
"the force a slider-crank transmits at rest under a torque" is one call.
"""
from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import scipy.optimize
import sympy as sp

from ..symbolic.derive import EquationsOfMotion
from .consistent import checked_tolerance
from .equilibria import (
    angle_like,
    coordinate_point,
    equilibrium_conditions,
    hold_inputs,
    reduce_angles,
    resolve_values,
    substitute_values,
    vector_function,
)


def constrained_equilibrium(eom: EquationsOfMotion, q_guess: Any, values: Mapping | None = None, *,
                            fix: Any = None, tol: float = 1e-10, inputs: Any = None) -> tuple[np.ndarray, np.ndarray]:
    """Equilibrium of a model with holonomic constraints, and its multipliers.

    Principle of virtual displacements with constraints (Lagrange; Lurie, Analytical Mechanics,
    ch. 2): at rest, with the sign convention of the equations of motion
    ``M ud + A^T lambda = F`` (A = dphi/dq; the constraint forces on the system are -A^T lambda)::

        F(q, u=0) - A(q)^T lambda = 0      (n equations)
        phi(q) = 0                         (m equations)

    solved for q (n) and lambda (m) by ``scipy.optimize.root`` (hybr, analytic Jacobian; lm as
    the fallback). With redundant Cartesian-like coordinates the lambda are the reactions of the
    joints: for a bob on a rod, phi = x^2 + y^2 - l^2, the rod tension is 2 l lambda.

    A held coordinate q_k = c (``fix``) is one more constraint whose multiplier is the force that
    holds it: its equation k is dropped from the solve and ``lambda_k = F_k - (A^T lambda)_k`` is
    reported after the m constraint multipliers. The generalized force an actuator must apply at
    q_k is ``-lambda_k`` (for a crank angle: the driving torque needed for equilibrium; 0 when the
    modelled loads already balance). Holding the slider of a slider-crank instead of the crank
    gives the slider force that balances a given crank torque.

    Parameters
    ----------
    eom : EquationsOfMotion
        With constraints (``eom.m > 0``) that do not depend on t; F at rest must not either.
    q_guess : sequence (n,) or mapping q (Symbol or name) -> float
        Starting point; also the values of the coordinates ``fix`` names.
    values : mapping parameter (Symbol or name) -> float, optional
        Overrides ``eom.parameter_values``.
    fix : coordinate, sequence of coordinates, or mapping coordinate -> value, optional
        Coordinates held at prescribed values (from ``q_guess`` unless a mapping gives them).
    tol : float
        Accepted residual relative to the size of the forces and constraint terms.
    inputs : sequence (n_r,) or mapping input (Symbol or name) -> value
        The inputs held constant; required when the model has inputs.

    Returns
    -------
    q : ndarray (n,)
    lam : ndarray (m + k,)
        The m constraint multipliers, then one per held coordinate in the order of ``eom.q``.

    Raises
    ------
    ValueError
        No constraints, a time-dependent constraint or F, unknown names, multipliers that are
        not unique (A restricted to the free coordinates has rank < m), or no convergence (the
        message names the worst equation and its residual).
    """
    # found by review: with no inputs= a driven model failed with "Cannot convert expression to float"
    eom = hold_inputs(eom, inputs)
    tol = checked_tolerance(tol, "constrained_equilibrium")
    _check_static_constraints(eom)
    vals = resolve_values(eom, {} if values is None else values)
    q0 = np.array(coordinate_point(eom, q_guess), dtype=float)
    held = _held(eom, fix, q0)
    q0[list(held)] = list(held.values())
    free = [i for i in range(eom.n) if i not in held]
    # the round-off allowance reads the free angles modulo 2 pi where every equation is periodic in
    # them: at 1e11 rad it let points off the constraints pass (found by review)
    angles = angle_like(eom, extra=eom.constraints)
    periodic = tuple(angles[i] for i in free) + (False,) * eom.m
    lam = sp.Matrix(sp.symbols(f"lambda_0:{eom.m}", cls=sp.Dummy))
    A = substitute_values(eom, sp.Matrix(eom.constraint_jacobian), vals, "constraint Jacobian")
    F = substitute_values(eom, equilibrium_conditions(eom), vals, "equilibrium conditions")
    phi = substitute_values(eom, sp.Matrix(eom.constraints), vals, "constraints")
    G = sp.Matrix.vstack((F - A.T * lam).extract(free, [0]), phi).xreplace(
        {eom.q[i]: sp.Float(v) for i, v in held.items()})
    z = [eom.q[i] for i in free] + list(lam)
    F_num, A_num = vector_function(list(eom.q), F, (eom.n,)), vector_function(list(eom.q), A, A.shape)
    lam0 = np.linalg.lstsq(A_num(q0)[:, free].T, F_num(q0)[free], rcond=None)[0]
    x = _root(eom, vector_function(z, G, (len(z),)), vector_function(z, G.jacobian(z), (len(z), len(z))),
              np.concatenate([q0[free], lam0]), z, lambda x: _force_scale(F_num, A_num, q0, free, x), tol, periodic)
    q, lam_c = q0.copy(), x[len(free):]
    q[free] = x[:len(free)]
    rank = np.linalg.matrix_rank(A_num(q)[:, free])
    if rank < eom.m:
        raise ValueError(f"multipliers of model {eom.name!r} are not unique at q = {q}: the constraint "
                         f"Jacobian over the free coordinates has rank {rank} < {eom.m} constraints")
    holding = (F_num(q) - A_num(q).T @ lam_c)[list(held)]
    return q, np.concatenate([lam_c, holding])


def _check_static_constraints(eom: EquationsOfMotion) -> None:
    if eom.m == 0:
        raise ValueError(f"model {eom.name!r} has no holonomic constraints; use find_equilibria")
    if eom.dependent_coordinates and eom.n_holonomic < eom.m:  # found by review: a Kane four-bar was
        # told its constraints hold no configuration; before, it returned a point off its loop, status OK
        raise ValueError(f"model {eom.name!r} holds its configuration by a KanesMethod's configuration "
                         "constraints (q_dependent) and its motion by velocity constraints: constrained_equilibrium "
                         "solves holonomic constraints with multipliers only (the energies and bodies routes' "
                         "constraints=, a LagrangesMethod's hol_coneqs)")
    if eom.n_holonomic < eom.m:  # found by review: x, y of a sleigh drifted to 1e10 with no word
        raise ValueError(f"model {eom.name!r} has {eom.m - eom.n_holonomic} velocity constraint(s): they hold no "
                         "configuration, so its equilibria are not isolated; constrained_equilibrium takes "
                         "holonomic constraints only (statics.steady and statics.state_space.linearize_state "
                         "take velocity constraints)")
    for i, c in enumerate(eom.constraints):
        if eom.t in c.free_symbols:
            raise ValueError(f"constraint {i} of model {eom.name!r} depends on {eom.t}: {c}; "
                             "no static equilibrium under a moving constraint")


def _force_scale(F_num, A_num, q0: np.ndarray, free: list, x: np.ndarray) -> np.ndarray:
    """Size of the terms of each equation at x = (q_free, lambda): max(|F_i|, (|A|^T |lambda|)_i) for
    the force rows, (|A| |q|)_j and |A_j| max|q| for the constraints; each at least 1e-6 of its
    group's largest (a row whose terms all vanish there, y_s = 0 at y_s = 1e-78, keeps a size).
    Relative, with no floor of 1: one scale of at least 1 took the guess of a micro four-bar
    (forces ~1e-12) for its equilibrium."""
    q = q0.copy()
    q[free] = x[:len(free)]
    A = np.abs(A_num(q))
    forces = np.maximum(np.abs(F_num(q)), A.T @ np.abs(x[len(free):]))[free]
    lengths = np.maximum(A @ np.abs(q), A.sum(axis=1) * np.max(np.abs(q), initial=0.0))
    groups = [np.maximum(g, 1e-6 * np.max(g, initial=0.0)) for g in (forces, lengths)]
    return np.maximum(np.concatenate(groups), 1e-300)


def _held(eom: EquationsOfMotion, fix: Any, q0: np.ndarray) -> dict:
    """Index -> value of the held coordinates (values from a mapping ``fix``, else from q0)."""
    if fix is None:
        return {}
    if isinstance(fix, (str, sp.Symbol)):
        fix = [fix]
    by_name = {qi.name: i for i, qi in enumerate(eom.q)}
    held = {}
    for key in fix:
        i = by_name.get(key.name if isinstance(key, sp.Symbol) else key)
        if i is None:
            raise ValueError(f"fix: {key!r} is not a coordinate of model {eom.name!r} "
                             f"(coordinates: {', '.join(by_name)})")
        value = fix[key] if isinstance(fix, Mapping) else q0[i]
        try:
            held[i] = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"fix: coordinate {eom.q[i]} needs a number, got {value!r}") from None
        if not np.isfinite(held[i]):  # found by review: sympy's AccumulationBounds error, or residual nan
            raise ValueError(f"fix: coordinate {eom.q[i]} needs a finite value, got {value!r}")
    return dict(sorted(held.items()))


def _root(eom: EquationsOfMotion, fun, jac, x0: np.ndarray, z: list, scale, tol: float, periodic: tuple) -> np.ndarray:
    """scipy root (hybr, then lm) on the equations each divided by its size at x0 (forces of 1e-12 N m
    beside constraints of 1e-3 m otherwise stall the solver); ValueError naming the worst equation
    if neither converges."""
    best = x0
    with np.errstate(all="ignore"):
        rows = scale(x0)
        rows = np.where(np.isfinite(rows) & (rows > 0), rows, 1.0)
        scaled, scaled_jac = (lambda x: fun(x) / rows), (lambda x: jac(x) / rows[:, None])
        for method in ("hybr", "lm"):
            x = scipy.optimize.root(scaled, best, jac=scaled_jac, method=method, options={"xtol": 1e-14}).x
            r = fun(x)
            # plus the round-off of the rows' evaluation at x (found by review: an upright pinned bar,
            # l m g sin(theta) at the double nearest pi, 1.2e-15, was refused against 9.8e-16)
            rounding = 16 * np.finfo(float).eps * (np.abs(jac(x)) @ np.abs(reduce_angles(x, periodic)))
            if np.all(np.isfinite(r)) and np.all(np.abs(r) <= tol * scale(x) + rounding):
                return x
            if np.all(np.isfinite(r)) and np.max(np.abs(r)) < np.max(np.abs(fun(best))):
                best = x
    r = fun(best)
    k = int(np.argmax(np.abs(r) / scale(best)))
    free = len(z) - eom.m
    what = (f"equilibrium equation of coordinate {z[k]}" if k < free else
            f"constraint {k - free}: {eom.constraints[k - free]} = 0")
    raise ValueError(f"no constrained equilibrium of model {eom.name!r} found from the guess: "
                     f"{what} has residual {r[k]:.6g}")
