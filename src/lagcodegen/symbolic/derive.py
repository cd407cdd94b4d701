"""Stage: Model -> EquationsOfMotion.

Every derivation route returns the same target form, in generalized coordinates q (n) and
generalized speeds u (n)::

    qd = K(q, u, t)               kinematic equations (K = u for the Lagrange routes)
    M(q, t) ud = F(q, u, t)       dynamic equations; M symmetric positive definite

Lagrange II (energies route), with p = dT/du, never forming d/dt(dT/dqd) symbolically::

    M = d2T/du2 (the Hessian of T in the speeds)
    F = dT/dq - (dp/dq) u - dp/dt - dV/dq - dR/du + Q

One module per route: `energies` (Lagrange II), `bodies` (d'Alembert-Lagrange, points and
bodies), `sympy_models` (sympy's LagrangesMethod, KanesMethod, System); the pieces they share (the
equations object, symbols, assembly) are in `equations`.
"""
from __future__ import annotations

import numpy as np
import sympy as sp

from ..model import ROUTE_BODIES, ROUTE_ENERGIES, ROUTE_SYMPY, ROUTE_TREE, Model, ModelError
from ..walk import atoms_of
from .bodies import derive_from_bodies
from .energies import derive_from_energies
from .equations import EquationsOfMotion
from .sympy_models import derive_from_sympy
from .trees import derive_from_tree

__all__ = ["EquationsOfMotion", "derive_equations", "ROUTES"]

#: the derivation routes by `Model.route`: a new route is one module of this subpackage and one line here
ROUTES = {
    ROUTE_ENERGIES: derive_from_energies,
    ROUTE_BODIES: derive_from_bodies,
    ROUTE_SYMPY: derive_from_sympy,
    ROUTE_TREE: derive_from_tree,
}


def derive_equations(model: Model) -> EquationsOfMotion:
    """Derive `EquationsOfMotion` from a validated `Model`, by its route.

    Examples
    --------
    The mass on a spring gives M = m and F = -k x (m x'' = -k x):

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0})
    >>> from lagcodegen import derive_equations
    >>> eom = derive_equations(model)
    >>> eom.mass_matrix, eom.forcing
    (Matrix([[m]]), Matrix([[-k*x]]))
    """
    try:
        route = ROUTES[model.route]
    except KeyError:
        raise ModelError(f"model {model.name!r} has the route {model.route!r}, which no derivation "
                         f"serves (routes: {', '.join(ROUTES)})") from None
    eom = route(model)
    check_derived(model, eom)
    speeds = {s.name for s in eom.u}
    for name, _ in eom.measurements:  # a trajectory's columns are looked up by name
        if name in speeds:
            raise ModelError(f"measurement {name!r} has the name of a speed of model {model.name!r}; rename it")
    return eom


def check_derived(model: Model, eom: EquationsOfMotion) -> None:
    """`ModelError` for what a derivation cannot carry into the equations: a DiracDelta (the
    derivative of a step) or an unevaluated derivative (floor of a coordinate) in a force, and a jump
    in an energy (`energy_jump`). Every route's equations pass here, a tree's through
    `pipeline` too (found by review: trees skipped it, and a recursive tree has no forcing: its
    assignments and the model's own energies are read instead)."""
    forces = [(f"the generalized force along {eom.u[i]}", f) for i, f in enumerate(eom.forcing)] \
        if eom.forcing is not None else []
    if eom.tree is not None:
        forces += [(f"the recursive kernel's term {symbol}", expr) for symbol, expr in eom.tree.assignments]
    for what, force in forces:
        # the printer named only F[i] and a CSE temporary (found by review)
        deltas = sorted(map(str, atoms_of([sp.sympify(force)], sp.DiracDelta)))
        if deltas:
            raise ModelError(f"model {model.name!r}: {what} holds {deltas[0]}, the derivative of a step in the "
                             "potential or kinetic energy, the dissipation or a force (Heaviside, sign or Abs of "
                             "a coordinate); its impulse cannot be integrated: write it without the step")
        derivatives = sorted(map(str, atoms_of([sp.sympify(force)], sp.Derivative)))
        if derivatives:  # floor, ceiling, Mod of a coordinate: sympy leaves their derivative unevaluated
            raise ModelError(f"model {model.name!r}: {what} holds {derivatives[0]}, which sympy cannot evaluate "
                             "(floor, ceiling or Mod of a coordinate in an energy, the dissipation or a force): "
                             "write it without that function")
    energies = [("potential", eom.potential_energy), ("kinetic", eom.kinetic_energy)]
    if eom.potential_energy is None and model.potential_energy is not None:  # a recursive tree's
        plain = {q: sp.Symbol(q.func.__name__) for q in model.coordinates}
        energies[0] = ("potential", sp.sympify(model.potential_energy).xreplace(plain))
        coordinates = tuple(plain.values())
    else:
        coordinates = tuple(eom.q)
    for what, energy in energies:
        jump = energy_jump(energy, coordinates, eom.t, eom.parameter_values)
        if jump is not None:
            coordinate, where, size, condition = jump
            raise ModelError(f"model {model.name!r}: the {what} energy jumps by {size:.3g} where {coordinate} = "
                             f"{where:.9g} (its Piecewise condition {condition}): the jump's force is an impulse "
                             "that the derivative drops, so the motion would cross it as if it were not there; "
                             "make the pieces meet at the boundary")


#: where `energy_jump` looks for the boundaries of a condition nonlinear in a coordinate
_SCAN = np.linspace(-20.0, 20.0, 8001) + 0.00123456789  # off round numbers: a root there has no sign


def energy_jump(energy, coordinates, t, values) -> tuple | None:
    """(coordinate, boundary value, jump, condition) of the first boundary of a Piecewise in ``energy``
    across which it jumps, or None. Each relational g(c) of the conditions gives boundaries in each
    coordinate c it reads, the other symbols at the model's values (1 where it has none: a boundary
    crossing holds for any): where g is linear in c, its root; else the sign changes of g on a grid of
    c in [-20, 20], bisected (found by review: |x| < 1 and x^2 < 1 were not looked at). The energy is
    evaluated (40 digits) either side of each boundary and twice as far, at a step far below the
    boundary's scale (found by review: a jump at x = 1e6 was hidden by the slope over 1e-7 relative),
    and a step that the slopes either side do not account for is a jump."""
    if not isinstance(energy, sp.Basic) or not energy.has(sp.Piecewise):
        return None
    coordinates = [c for c in coordinates if isinstance(c, sp.Symbol)]
    point = {t: sp.Float("0.37", 40)}
    for symbol in energy.free_symbols:
        if symbol not in coordinates and symbol != t:
            value = values.get(symbol, values.get(getattr(symbol, "name", None), 1))
            try:
                point[symbol] = sp.Float(float(value), 40)
            except (TypeError, ValueError):  # a symbolic value: any point of the boundary tells
                point[symbol] = sp.Float(1)
    rest = {c: sp.Float(0.1 + 0.07 * k, 40) for k, c in enumerate(coordinates)}
    for piecewise in sorted(energy.atoms(sp.Piecewise), key=sp.default_sort_key):
        for condition in (c for _, c in piecewise.args):
            if not isinstance(condition, sp.Basic):
                continue
            for relation in sorted(condition.atoms(sp.core.relational.Relational), key=sp.default_sort_key):
                g = relation.lhs - relation.rhs
                for c in coordinates:
                    if c not in g.free_symbols:
                        continue
                    at = {**point, **{o: v for o, v in rest.items() if o != c}}
                    for boundary, exact in _boundaries(g.xreplace(at), c):
                        jump = _jump_at(energy.xreplace(at), c, boundary, exact)
                        if jump is not None:
                            return c, float(boundary), jump, relation
    return None


def _boundaries(g, c) -> list:
    """(value, exact) of the roots of g(c) (other symbols substituted): the root of a linear g exactly,
    else up to 20 sign changes of g on `_SCAN`, bisected in double precision."""
    if sp.diff(g, c, 2).equals(0):
        slope = sp.diff(g, c).evalf(40)
        if not slope.is_Number or slope == 0:
            return []
        root = (c - g / slope).xreplace({c: 0}).evalf(40)
        return [(root, True)] if root.is_Number and root.is_finite and root.is_real else []
    try:
        function = sp.lambdify(c, g, "math")
        values = np.array([function(float(v)) for v in _SCAN], dtype=float)
    except (TypeError, ValueError, ZeroDivisionError, OverflowError):
        return []
    roots = []
    for k in np.flatnonzero(np.sign(values[:-1]) * np.sign(values[1:]) < 0)[:20]:
        low, high = float(_SCAN[k]), float(_SCAN[k + 1])
        for _ in range(60):
            middle = (low + high) / 2
            if np.sign(function(middle)) == np.sign(values[k]):
                low = middle
            else:
                high = middle
        roots.append((sp.Float((low + high) / 2, 40), False))
    return roots


def _jump_at(energy, c, boundary, exact: bool):
    """The jump of ``energy`` (a function of c alone) across ``boundary``, or None where it meets."""
    step = sp.Float("1e-20" if exact else "1e-12", 40) * (1 + abs(boundary))
    sample = [energy.xreplace({c: boundary + k * step}).evalf(40) for k in (-2, -1, 1, 2)]
    if not all(v.is_Number and v.is_finite for v in sample):
        return None
    left2, left, right, right2 = sample
    size = abs(right - left)
    if size > 10 * (abs(right2 - right) + abs(left - left2)) + sp.Float("1e-12") * (1 + abs(left)):
        return float(right - left)
    return None
