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

import sympy as sp

from ..model import ROUTE_BODIES, ROUTE_ENERGIES, ROUTE_SYMPY, ROUTE_TREE, Model, ModelError
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
    for i, force in enumerate(eom.forcing if eom.forcing is not None else ()):  # a recursive tree has none
        # the printer named only F[i] and a CSE temporary (found by review)
        deltas = sorted(map(str, sp.sympify(force).atoms(sp.DiracDelta)))
        if deltas:
            raise ModelError(f"model {model.name!r}: the generalized force along {eom.u[i]} holds {deltas[0]}, the "
                             "derivative of a step in the potential or kinetic energy, the dissipation or a force "
                             "(Heaviside, sign or Abs of a coordinate); its impulse cannot be integrated: write it "
                             "without the step")
    speeds = {s.name for s in eom.u}
    for name, _ in eom.measurements:  # a trajectory's columns are looked up by name
        if name in speeds:
            raise ModelError(f"measurement {name!r} has the name of a speed of model {model.name!r}; rename it")
    return eom
