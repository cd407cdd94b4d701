"""Stage: user description -> validated `Model`.

A model is stated in one of three ways, all consumed by `derive.derive_equations`:

* energies: generalized coordinates, kinetic energy T, potential energy V, non-potential
  generalized forces Q and a Rayleigh dissipation function R (Lagrange II);
* points and bodies: sympy.physics.mechanics Particles and RigidBodies whose positions are
  functions of q and t, with loads and gravity (d'Alembert-Lagrange, generalized inertia forces);
* an existing sympy model: a ``LagrangesMethod``, ``KanesMethod`` or ``System``.

`Model` validates its input and computes nothing else.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

from .grouping import components

TIME = me.dynamicsymbols._t

ROUTE_ENERGIES = "energies"
ROUTE_BODIES = "bodies"
ROUTE_SYMPY = "sympy"


class ModelError(ValueError):
    """A model description is inconsistent; the message names the culprit."""


def _as_expr(value: Any, what: str) -> sp.Expr:
    if isinstance(value, sp.Expr) and not getattr(value, "is_Matrix", False):
        return value
    if isinstance(value, sp.Basic):
        raise ModelError(f"{what} must be a scalar sympy expression, got {type(value).__name__}: {value}")
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return sp.sympify(value)
    raise ModelError(f"{what} must be a sympy expression or a number, got {type(value).__name__}: {value!r}")


def _is_coordinate(obj: Any) -> bool:
    return isinstance(obj, AppliedUndef) and obj.args == (TIME,)


def _dynamic_functions(expr: sp.Basic) -> set:
    """Applied undefined functions (q(t), x(t), ...) inside ``expr``."""
    return {f for f in expr.atoms(AppliedUndef)}


@dataclass(frozen=True)
class Load:
    """A force on a point (``where`` is a Point) or a torque on a frame (a ReferenceFrame)."""

    where: Any
    vector: Any

    @property
    def is_torque(self) -> bool:
        return isinstance(self.where, me.ReferenceFrame)


@dataclass(frozen=True)
class Model:
    """A mechanical system, validated, ready for `derive.derive_equations`.

    Parameters
    ----------
    name : str
        Model name; used in generated C (mangled to an identifier there).
    coordinates : sequence of dynamicsymbols
        Generalized coordinates q_i(t). For ``sympy_model`` they are taken from the model.
    parameters : sequence of sympy.Symbol
        Every constant symbol the model uses (masses, lengths, g, ...), declared explicitly.
    kinetic_energy : Expr, optional
        T(q, qd, t), energies route.
    potential_energy : Expr, optional
        V(q, t); allowed in the energies and bodies routes (springs, for example).
    generalized_forces : mapping coordinate -> Expr, optional
        Non-potential generalized forces Q_i(q, qd, t) from virtual work: damping, applied torques,
        Coulomb or rolling friction with ``sign(qd)``.
    dissipation : Expr, optional
        Rayleigh dissipation function R(q, qd, t); contributes -dR/dqd_i.
    bodies : sequence of Particle / RigidBody, optional
        Points-and-bodies route; needs ``frame`` (inertial) and ``origin`` (fixed point).
    loads : sequence of (Point, Vector) / (ReferenceFrame, Vector) / sympy Force, Torque
    gravity : Vector, optional
        Gravitational acceleration, applied to every body at its mass centre.
    points : mapping name -> Point or sequence of 2-3 expressions, optional
        Positions to output (plots, animation); Points need ``frame`` and ``origin``.
    parameter_values : mapping Symbol -> float, optional
        Default numeric values (used by examples and simulation when not overridden).
    sympy_model : LagrangesMethod, KanesMethod or System, optional
        An existing sympy model; coordinates and speeds are taken from it.
    constraints : sequence of Expr, optional
        Holonomic constraints phi_i(q, t) = 0 (possibly rheonomic) between redundant coordinates:
        Lagrange's equations of the first kind, with multipliers.
    """

    name: str
    coordinates: Sequence[Any] = ()
    parameters: Sequence[Any] = ()
    kinetic_energy: Any = None
    potential_energy: Any = 0
    generalized_forces: Mapping[Any, Any] = field(default_factory=dict)
    dissipation: Any = 0
    bodies: Sequence[Any] = ()
    loads: Sequence[Any] = ()
    gravity: Any = None
    frame: Any = None
    origin: Any = None
    points: Mapping[str, Any] = field(default_factory=dict)
    parameter_values: Mapping[Any, float] = field(default_factory=dict)
    sympy_model: Any = None
    constraints: Sequence[Any] = ()

    def __post_init__(self) -> None:
        self._check_name()
        set_ = lambda attr, value: object.__setattr__(self, attr, value)  # noqa: E731 (frozen)
        for attr in ("coordinates", "parameters", "bodies", "loads", "constraints"):
            if not isinstance(getattr(self, attr), (list, tuple)):
                raise ModelError(f"{attr} must be a list or tuple, got {type(getattr(self, attr)).__name__}")
        set_("parameters", tuple(self.parameters))
        self._check_parameters()
        if self.sympy_model is not None:
            set_("coordinates", tuple(_sympy_model_coordinates(self.sympy_model)))
        set_("coordinates", tuple(self.coordinates))
        self._check_coordinates()
        set_("potential_energy", _as_expr(self.potential_energy, "potential_energy"))
        set_("dissipation", _as_expr(self.dissipation, "dissipation"))
        if self.kinetic_energy is not None:
            set_("kinetic_energy", _as_expr(self.kinetic_energy, "kinetic_energy"))
        set_("generalized_forces", self._checked_forces())
        set_("bodies", tuple(self.bodies))
        set_("loads", tuple(_as_load(load) for load in self.loads))
        set_("points", dict(self.points))
        set_("parameter_values", self._checked_values())
        set_("constraints", tuple(_as_expr(c, f"constraint {i}") for i, c in enumerate(self.constraints)))
        self._check_route()
        self._check_symbols()

    @property
    def route(self) -> str:
        if self.sympy_model is not None:
            return ROUTE_SYMPY
        if self.bodies:
            return ROUTE_BODIES
        return ROUTE_ENERGIES

    # -- validation -----------------------------------------------------------------------
    def _check_name(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ModelError(f"model name must be a non-empty string, got {self.name!r}")

    def _check_parameters(self) -> None:
        seen = set()
        for p in self.parameters:
            if not isinstance(p, sp.Symbol):
                raise ModelError(f"parameter {p!r} must be a sympy Symbol, got {type(p).__name__}")
            if p == TIME:
                raise ModelError(f"parameter {p.name!r} is the time symbol; give the parameter another name")
            if p.name in seen:
                raise ModelError(f"parameter {p.name!r} is declared twice")
            seen.add(p.name)

    def _check_coordinates(self) -> None:
        if not self.coordinates:
            raise ModelError(f"model {self.name!r} has no generalized coordinates")
        names = set()
        parameter_names = {p.name for p in self.parameters}
        for q in self.coordinates:
            if not _is_coordinate(q):
                raise ModelError(
                    f"coordinate {q!r} is not a function of time; declare it with "
                    f"sympy.physics.mechanics.dynamicsymbols('{q}')")
            qname = q.func.__name__
            if qname in names:
                raise ModelError(f"coordinate {qname!r} is listed twice")
            if qname in parameter_names:
                raise ModelError(f"symbol {qname!r} is declared both as a parameter and as a coordinate")
            names.add(qname)

    def _checked_forces(self) -> dict:
        forces = {}
        for q, Q in dict(self.generalized_forces).items():
            if q not in self.coordinates:
                raise ModelError(f"generalized force given for {q!r}, which is not a coordinate "
                                 f"(coordinates: {', '.join(map(str, self.coordinates))})")
            forces[q] = _as_expr(Q, f"generalized force on {q}")
        return forces

    def _checked_values(self) -> dict:
        values = {}
        for p, v in dict(self.parameter_values).items():
            if p not in self.parameters:
                raise ModelError(f"value given for {p!r}, which is not a declared parameter")
            values[p] = float(v)
        return values

    def _check_route(self) -> None:
        if self.sympy_model is not None:
            if self.kinetic_energy is not None or self.bodies:
                raise ModelError("give either sympy_model or kinetic_energy/bodies, not both")
            return
        if self.bodies and self.kinetic_energy is not None:
            raise ModelError("give either kinetic_energy (energies route) or bodies, not both")
        if not self.bodies and self.kinetic_energy is None:
            raise ModelError(f"model {self.name!r} needs a kinetic energy, bodies or a sympy model")
        needs_frame = bool(self.bodies) or any(isinstance(p, me.Point) for p in self.points.values())
        if needs_frame and (not isinstance(self.frame, me.ReferenceFrame) or not isinstance(self.origin, me.Point)):
            raise ModelError("bodies and Point outputs need frame= (inertial ReferenceFrame) and origin= (fixed Point)")
        for body in self.bodies:
            if not isinstance(body, (me.Particle, me.RigidBody)):
                raise ModelError(f"body {body!r} is not a sympy Particle or RigidBody")

    def _check_symbols(self) -> None:
        """Every free symbol is t or declared; every function of t is a coordinate."""
        exprs = [("kinetic_energy", self.kinetic_energy), ("potential_energy", self.potential_energy),
                 ("dissipation", self.dissipation)]
        exprs += [(f"generalized force on {q}", Q) for q, Q in self.generalized_forces.items()]
        for body in self.bodies:
            exprs.append((f"mass of {body.name}", _as_expr(body.mass, f"mass of {body.name}")))
        for name, pos in self.points.items():
            if not isinstance(pos, me.Point):
                if not isinstance(pos, (tuple, list)) or len(pos) not in (2, 3):
                    raise ModelError(f"point {name!r} must be a Point or 2 or 3 expressions, got {pos!r}")
                for i, c in enumerate(pos):
                    exprs.append((f"point {name!r} component {i}", _as_expr(c, f"point {name!r}")))
        if self.gravity is not None:
            if not isinstance(self.gravity, me.Vector):
                raise ModelError(f"gravity must be a sympy.physics.vector Vector (e.g. -g*N.y), got {self.gravity!r}")
            exprs.append(("gravity", components(self.gravity, self.frame)))
        for i, phi in enumerate(self.constraints):
            if phi.atoms(sp.Derivative):
                raise ModelError(f"constraint {i} ({phi}) contains speeds: only holonomic constraints "
                                 "phi(q, t) = 0 are supported")
            if not _dynamic_functions(phi) & set(self.coordinates):
                raise ModelError(f"constraint {i} ({phi}) involves no coordinate")
            exprs.append((f"constraint {i}", phi))
        check_declared(exprs, self.parameters, self.coordinates)


def check_declared(exprs, parameters, coordinates, extra=()) -> None:
    """Raise `ModelError` listing undeclared symbols or functions of time found in ``exprs``.

    ``exprs`` is a sequence of (description, expression) pairs.
    """
    allowed = set(parameters) | {TIME} | set(extra)
    for what, expr in exprs:
        if expr is None:
            continue
        check_symbols_declared(what, expr.free_symbols - allowed, parameters)
        unknown = sorted(_dynamic_functions(expr) - set(coordinates), key=str)
        if unknown:
            raise ModelError(f"{what} uses functions of time that are not coordinates: "
                             f"{', '.join(map(str, unknown))}")


def check_symbols_declared(what: str, undeclared: set, parameters) -> None:
    """Raise `ModelError` naming ``what`` when ``undeclared`` (its stray free symbols) is not empty."""
    if not undeclared:
        return
    extra = sorted(undeclared, key=str)
    declared = {p.name: p for p in parameters}
    for sym in extra:
        if sym.name in declared:
            raise ModelError(
                f"{what} uses symbol {sym.name!r} with assumptions {sym.assumptions0} but the declared "
                f"parameter {sym.name!r} has {declared[sym.name].assumptions0}; use the same Symbol")
    raise ModelError(
        f"{what} uses symbols not declared as parameters: {', '.join(map(str, extra))} "
        f"(declared: {', '.join(map(str, parameters)) or 'none'})")


def _as_load(load: Any) -> Load:
    if isinstance(load, Load):
        return load
    try:
        where, vector = load  # also unpacks sympy's Force and Torque (named tuples)
    except (TypeError, ValueError):
        raise ModelError(f"load {load!r} must be (Point, Vector) or (ReferenceFrame, Vector)") from None
    if not isinstance(where, (me.Point, me.ReferenceFrame)):
        raise ModelError(f"load {load!r}: the first item must be a Point (force) or ReferenceFrame (torque)")
    if not isinstance(vector, me.Vector):
        raise ModelError(f"load on {where}: {vector!r} is not a sympy.physics.vector Vector")
    return Load(where, vector)


def _sympy_model_coordinates(obj: Any) -> list:
    if isinstance(obj, me.System):
        return list(obj.q)
    if isinstance(obj, me.LagrangesMethod):
        return list(obj.q)
    if isinstance(obj, me.KanesMethod):
        return list(obj.q)
    raise ModelError(f"sympy_model must be a LagrangesMethod, KanesMethod or System, got {type(obj).__name__}")
