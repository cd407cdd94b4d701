"""Stage: sympy LagrangesMethod / KanesMethod / System / JointsMethod model -> EquationsOfMotion.

sympy has already derived ``M ud = F`` for these objects; this route renames their
dynamicsymbols to plain symbols and takes the kinematic equations from Kane's
``kindiffdict`` (qd = K(q, u, t)), so Kane's generalized speeds pass through unchanged.
"""
from __future__ import annotations

import sympy as sp
import sympy.physics.mechanics as me

from ..model import TIME, Model, ModelError, check_well_defined
from .equations import assemble, check_mass_matrix, make_substitution, plain_symbols


def derive_from_sympy(model: Model):
    method = _formed_method(model.sympy_model)
    coords = tuple(method.q)
    if isinstance(method, me.LagrangesMethod):
        # private: sympy 1.14 keeps the Lagrangian only in _L
        check_well_defined("the sympy model's Lagrangian", sp.sympify(method._L))
        held = list(method._hol_coneqs)  # private: sympy 1.14 keeps the holonomic constraints only there
        motion = list(method.coneqs)[len(held):]  # coneqs = (d/dt hol_coneqs, nonhol_coneqs)
        speeds = tuple(c.diff(TIME) for c in coords)
        kin_dynamic = sp.Matrix(speeds)
        route = "sympy LagrangesMethod"
    else:
        speeds = tuple(method.u)
        kindiff = method.kindiffdict()
        kin_dynamic = sp.Matrix([kindiff[c.diff(TIME)] for c in coords])
        route = "sympy KanesMethod (Kane)"
    q, u = plain_symbols(coords, speeds, model.parameters)
    to_plain = make_substitution(coords, speeds, q, u, "sympy model", inputs=model.inputs)
    qdot_table = {} if isinstance(method, me.LagrangesMethod) else {
        c.diff(TIME): k for c, k in zip(coords, kin_dynamic)}
    n_u = len(speeds)
    # Lagrange I: without lambda's columns
    M = to_plain(method.mass_matrix[:, :n_u].xreplace(qdot_table), "mass matrix")
    F = to_plain(method.forcing.xreplace(qdot_table), "forcing")
    K = to_plain(kin_dynamic, "kinematic equations")
    for what, matrix in (("mass matrix", M), ("forcing", F), ("kinematic equations", K)):
        for (i, j), entry in sorted(matrix.todok().items()):
            check_well_defined(f"the sympy model's {what}, entry ({i}, {j})", entry)
    check_mass_matrix(M, coords, u, speeds)
    T, V = _energies(method, model, to_plain)
    constraints, motion = (held, motion) if isinstance(method, me.LagrangesMethod) else ((), ())
    eom = assemble(model, coords, speeds, q, u, M, F, K, T, V, to_plain, constraints=constraints, motion=motion)
    if eom.m:  # assemble's " with ... constraints (Lagrange I)"
        route += eom.route[eom.route.index(" with "):]
    elif isinstance(method, me.LagrangesMethod):
        route += " (Lagrange II)"
    return _with_route(eom, route)


def _formed_method(obj):
    """The LagrangesMethod or KanesMethod behind ``obj``, with its equations formed."""
    if isinstance(obj, me.JointsMethod):
        if obj.method is None:
            obj.form_eoms()
        obj = obj.method
    if isinstance(obj, me.System):
        if obj.eom_method is None:
            obj.form_eoms()
        obj = obj.eom_method
    if isinstance(obj, me.LagrangesMethod):
        if obj.eom is None:
            obj.form_lagranges_equations()
        return obj
    if isinstance(obj, me.KanesMethod):
        if obj._fr is None:
            if not obj.bodies:
                raise ModelError("KanesMethod has no bodies: call kanes_equations(bodies, loads) "
                                 "or pass bodies= to KanesMethod")
            obj.kanes_equations(obj.bodies, obj.loads)
        return obj
    raise ModelError(f"sympy_model must be a LagrangesMethod, KanesMethod, System or JointsMethod, got "
                     f"{type(obj).__name__}")


def _energies(method, model: Model, to_plain):
    """(T, V): from the Lagrangian L = T - V split at u = 0, or from Kane's bodies."""
    if isinstance(method, me.LagrangesMethod):
        lagrangian = method._L[0] if isinstance(method._L, sp.MatrixBase) else method._L
        L = to_plain(lagrangian, "Lagrangian")
        rest = to_plain(sp.Matrix([c.diff(TIME) for c in method.q]), "speeds")
        at_rest = L.xreplace({s: 0 for s in rest})
        return L - at_rest, -at_rest + to_plain(model.potential_energy, "potential energy")
    bodies = method.bodies or ()
    if not bodies or model.frame is None:
        return None, None
    T = to_plain(me.kinetic_energy(model.frame, *bodies).xreplace(method.kindiffdict()), "kinetic energy")
    V = to_plain(sum((b.potential_energy for b in bodies), sp.S.Zero) + model.potential_energy,
                 "potential energy")
    return T, V


def _with_route(eom, route: str):
    from dataclasses import replace
    return replace(eom, route=route)
