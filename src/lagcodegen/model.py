"""Stage: user description -> validated `Model`.

A model is stated in one of three ways, all consumed by `derive.derive_equations`:

* energies: generalized coordinates, kinetic energy T, potential energy V, non-potential
  generalized forces Q and a Rayleigh dissipation function R (Lagrange II);
* points and bodies: sympy.physics.mechanics Particles and RigidBodies whose positions are
  functions of q and t, with loads and gravity (d'Alembert-Lagrange, generalized inertia forces);
* an existing sympy model: a ``LagrangesMethod``, ``KanesMethod`` or ``System``;
* a kinematic tree stated link by link (`tree.Link`: joints, masses, points), for which the
  equations are formed in closed form or by a recursive algorithm (`symbolic.tree`).

`Model` validates its input and computes nothing else.
"""
from __future__ import annotations

import math
import numbers
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

from .symbolic.grouping import components
from .tree import TreeError, checked_tree, three_entries
from .walk import atoms_of, distinct_nodes, free_symbols_of

TIME = me.dynamicsymbols._t

ROUTE_ENERGIES = "energies"
ROUTE_BODIES = "bodies"
ROUTE_SYMPY = "sympy"
ROUTE_TREE = "tree"
#: how velocity constraints with dependent speeds enter (Model.formulation; None: elimination when possible)
#: ... and for a kinematic tree (Model.tree; None: the cost model of `symbolic.tree` chooses)
FORMULATIONS = (None, "elimination", "multipliers", "closed", "recursive")


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


def _check_no_speed(entries, what: str) -> None:
    """`ModelError` when a position's ``entries`` hold a speed: positions depend on q and t only."""
    rates = sorted({d for entry in entries for d in sp.sympify(entry).atoms(sp.Derivative)}, key=str)
    if rates:
        raise ModelError(f"{what} contains the speed {rates[0]}: positions depend on the coordinates and t only")


def _function_assumptions(f) -> dict:
    """The assumptions a dynamicsymbol was declared with (real=True, ...); {} for none."""
    return dict(getattr(f.func, "_kwargs", None) or {})


def _dynamic_functions(expr: sp.Basic) -> set:
    """Applied undefined functions (q(t), x(t), ...) inside ``expr`` (a matrix: its entries)."""
    return atoms_of(_entries(expr), AppliedUndef)


def _entries(expr) -> list:
    """A matrix's entries, or [expr]: what the walks of `walk` take."""
    return list(expr) if isinstance(expr, sp.MatrixBase) else [expr]


@dataclass(frozen=True)
class Load:
    """A force on a point (``where`` is a Point) or a torque on a frame (a ReferenceFrame)."""

    where: Any
    vector: Any

    @property
    def is_torque(self) -> bool:
        return isinstance(self.where, me.ReferenceFrame)


def _frames_of(value) -> list:
    """The frames a sympy Vector or Dyadic is written in."""
    frames = []
    if isinstance(value, me.Vector):
        frames = [frame for _, frame in value.args]
    elif isinstance(value, me.Dyadic):
        frames = [frame for term in value.args for v in term[1:] for _, frame in v.args]
    unique: list = []
    for frame in frames:
        if frame not in unique:
            unique.append(frame)
    return unique


def _given(value) -> bool:
    """A Model field set to something other than its empty default (0, None, (), {})."""
    if value is None:
        return False
    if isinstance(value, (Mapping, Sequence)) and not isinstance(value, str):
        return len(value) > 0
    try:
        return bool(sp.sympify(value) != 0)
    except (sp.SympifyError, TypeError):
        return True


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
    links : sequence of (name, name), optional
        Pairs of point names an animation joins by a segment (rods, links of a linkage);
        ``"origin"`` is the fixed origin the positions are measured from (unless a point has that
        name). Empty: `lagcodegen.analysis.animation` draws the chain from the origin through
        the points in the order they are declared.
    parameter_values : mapping Symbol -> float, optional
        Default numeric values (used by examples and simulation when not overridden).
    sympy_model : LagrangesMethod, KanesMethod, System or JointsMethod, optional
        An existing sympy model; coordinates and speeds are taken from it. Its energy output (a
        KanesMethod's needs ``frame``) is T + V with V the bodies' ``potential_energy`` plus
        ``potential_energy`` here: gravity given as loads is not in it.
    constraints : sequence of Expr, optional
        Holonomic constraints phi_i(q, t) = 0 (possibly rheonomic) between redundant coordinates:
        Lagrange's equations of the first kind, with multipliers.
    inputs : sequence of dynamicsymbols or Symbols, optional
        Inputs r (torques, forces set by a controller while the model runs). They may enter V,
        the generalized forces, the dissipation function and the loads, linearly or not, and so
        the forcing F; never the kinetic energy, masses, inertias, positions or constraints (their
        rates would enter the equations, and the mass matrix must not depend on them). In a sympy
        model every specified function of t that is not a coordinate or speed must be listed here.
    motion_constraints : sequence of Expr, optional
        Constraints on the velocities, ``a(q, t) . qd + b(q, t) = 0`` (linear in the coordinate
        rates; rolling without slipping in 3D, a knife edge), energies and bodies routes, with
        multipliers as for the holonomic ones (the first kind extended to velocity constraints):
        ``M ud + A^T lambda = F`` with A stacking dphi/dq and the rows a; their multipliers are the
        constraint forces, Baumgarte's alpha and the projection act on them too. With
        ``dependent_speeds`` named they are eliminated instead (see there).
    formulation : {None, "elimination", "multipliers"}, optional
        How velocity constraints with named dependent speeds (Kane's ``u_dependent``) enter the
        equations: ``"elimination"`` (the default then) keeps the independent speeds in the state
        and computes the dependent ones from the constraints at every evaluation (Kane's minimal
        ODE; a singular constraint Jacobian in them is the status LCG_SINGULAR_CONSTRAINTS);
        ``"multipliers"`` keeps every speed in the state and adds the constraint forces (Lagrange I).
        Models without dependent speeds always use multipliers; on the energies and bodies routes
        ``"elimination"`` needs ``dependent_speeds``.
    dependent_speeds : sequence of dynamicsymbols, optional
        Energies and bodies routes with ``motion_constraints`` (and no holonomic ``constraints``):
        the coordinates whose rates the velocity constraints determine, one per motion constraint
        (the Chaplygin sleigh's ``[y]``: y' = x' tan(theta)); they are eliminated as Kane's
        ``u_dependent`` are, unless ``formulation="multipliers"``. The state is then q and the
        other rates in the declared order; `lagcodegen.run.simulate.dependent_speeds` gives these.
        Which rates are dependent decides where their constraint Jacobian block is singular
        (here cos(theta) = 0): the user names them, as in Kane's method.
    measurements : mapping name -> Expr, optional
        Output expressions y = h(q, qd, r, t) (sensor readings, a spring force, a contact
        point's coordinate): compiled into one C function ``<prefix>_measurements`` and recorded
        in trajectories and sweeps by name. In a Kane model write them in q, its speeds u and r.

    Examples
    --------
    A mass on a spring, by its energies:

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0})
    >>> model.route
    'energies'
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
    tree: Sequence[Any] = ()
    frame: Any = None
    origin: Any = None
    points: Mapping[str, Any] = field(default_factory=dict)
    parameter_values: Mapping[Any, float] = field(default_factory=dict)
    sympy_model: Any = None
    constraints: Sequence[Any] = ()
    inputs: Sequence[Any] = ()
    measurements: Mapping[str, Any] = field(default_factory=dict)
    motion_constraints: Sequence[Any] = ()
    links: Sequence[Any] = ()
    formulation: str | None = None
    dependent_speeds: Sequence[Any] = ()

    def __post_init__(self) -> None:
        self._check_name()
        set_ = lambda attr, value: object.__setattr__(self, attr, value)  # noqa: E731 (frozen)
        for attr in ("coordinates", "parameters", "bodies", "loads", "constraints", "inputs", "motion_constraints"):
            if not isinstance(getattr(self, attr), (list, tuple)):
                raise ModelError(f"{attr} must be a list or tuple, got {type(getattr(self, attr)).__name__}")
        set_("parameters", tuple(self.parameters))
        self._check_parameters()
        if self.sympy_model is not None:
            set_("coordinates", tuple(_sympy_model_coordinates(self.sympy_model)))
        set_("coordinates", tuple(self.coordinates))
        self._check_coordinates()
        set_("tree", self._checked_tree())
        set_("inputs", tuple(self.inputs))
        self._check_inputs()
        set_("potential_energy", _as_expr(self.potential_energy, "potential_energy"))
        set_("dissipation", _as_expr(self.dissipation, "dissipation"))
        if self.kinetic_energy is not None:
            set_("kinetic_energy", _as_expr(self.kinetic_energy, "kinetic_energy"))
        self._check_coordinate_assumptions()
        set_("generalized_forces", self._checked_forces())
        set_("bodies", tuple(self.bodies))
        set_("loads", tuple(_as_load(load) for load in self.loads))
        set_("points", dict(self.points))
        set_("parameter_values", self._checked_values())
        set_("constraints", tuple(_as_expr(c, f"constraint {i}") for i, c in enumerate(self.constraints)))
        set_("measurements", self._checked_measurements())
        set_("motion_constraints", tuple(_as_expr(c, f"motion constraint {i}")
                                         for i, c in enumerate(self.motion_constraints)))
        set_("links", self._checked_links())
        if self.formulation not in FORMULATIONS:
            raise ModelError(f"formulation must be one of {', '.join(map(repr, FORMULATIONS))}, "
                             f"got {self.formulation!r}")
        set_("dependent_speeds", self._checked_dependent_speeds())
        self._check_route()
        self._check_connected()
        self._check_symbols()

    @property
    def route(self) -> str:
        if self.tree:
            return ROUTE_TREE
        if self.sympy_model is not None:
            return ROUTE_SYMPY
        if self.bodies:
            return ROUTE_BODIES
        return ROUTE_ENERGIES

    # -- validation -----------------------------------------------------------------------
    def _check_name(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ModelError(f"model name must be a non-empty string, got {self.name!r}")
        try:  # found by review: a lone surrogate ("osc\udcff") passed here, then a bare UnicodeEncodeError
            self.name.encode("utf-8")
        except UnicodeEncodeError as err:
            raise ModelError(f"model name {self.name!r} is not valid Unicode text ({err.reason} at position "
                             f"{err.start})") from None

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
            if qname == TIME.name:
                raise ModelError(f"coordinate {qname!r} has the name of the time symbol; give the coordinate another "
                                 "name")
            if qname in names:
                raise ModelError(f"coordinate {qname!r} is listed twice")
            if qname in parameter_names:
                raise ModelError(f"symbol {qname!r} is declared both as a parameter and as a coordinate")
            names.add(qname)

    def _check_inputs(self) -> None:
        taken = {p.name: "parameter" for p in self.parameters} | {TIME.name: "time symbol"}
        taken |= {c.func.__name__: "coordinate" for c in self.coordinates}
        seen = set()
        for r in self.inputs:
            if not (isinstance(r, sp.Symbol) or _is_coordinate(r)):
                raise ModelError(f"input {r!r} must be a dynamicsymbol r(t) or a Symbol, got {type(r).__name__}")
            name = input_name(r)
            if name in taken:
                raise ModelError(f"input {name!r} is also a {taken[name]} of model {self.name!r}")
            if name in seen:
                raise ModelError(f"input {name!r} is listed twice")
            seen.add(name)

    def _checked_forces(self) -> dict:
        forces = {}
        for q, Q in dict(self.generalized_forces).items():
            if q not in self.coordinates:
                raise ModelError(f"generalized force given for {q!r}, which is not a coordinate "
                                 f"(coordinates: {', '.join(map(str, self.coordinates))})")
            forces[q] = _as_expr(Q, f"generalized force on {q}")
        return forces

    def _checked_values(self) -> dict:
        """Values by parameter Symbol; keys may be the Symbols or their names."""
        by_name = {p.name: p for p in self.parameters}
        declared = ", ".join(by_name) or "none"
        values = {}
        for key, value in dict(self.parameter_values).items():
            p = by_name.get(key) if isinstance(key, str) else key
            if p not in self.parameters:
                if isinstance(key, sp.Symbol) and key.name in by_name:
                    raise ModelError(
                        f"value given for {key.name!r} with assumptions {key.assumptions0}, but the declared "
                        f"parameter {key.name!r} has {by_name[key.name].assumptions0}; use the same Symbol")
                raise ModelError(f"value given for {key!r}, which is not a declared parameter (declared: {declared})")
            values[p] = finite_number(value, f"parameter_values[{p.name!r}]")
            wrong = sign_error(p.name, values[p], sign_assumption(p), f"parameter_values[{p.name!r}]")
            if wrong:
                raise ModelError(f"model {self.name!r}: {wrong}")
        return values

    def _checked_tree(self) -> tuple:
        if not self.tree:
            return ()
        try:
            tree = checked_tree(self.tree, self.coordinates)
        except TreeError as error:
            raise ModelError(f"model {self.name!r}: {error}") from None
        given = [name for name in ("kinetic_energy", "bodies", "loads", "sympy_model", "constraints",
                                   "motion_constraints", "frame", "origin", "points")
                 if getattr(self, name) not in (None, (), [], {})]
        if given:
            raise ModelError(f"model {self.name!r}: a tree brings its bodies, frames and points; drop "
                             f"{', '.join(given)} (springs and drives go in potential_energy, "
                             "generalized_forces and dissipation)")
        if self.gravity is not None and three_entries(self.gravity) is None:
            raise ModelError(f"model {self.name!r}: a tree's gravity is 3 components in the ground frame (a list, "
                             f"tuple, 1-D array or sympy Matrix), got {self.gravity!r}")
        return tree

    def tree_points(self) -> tuple:
        """Names of the points of a tree's links, in link order."""
        return tuple(name for link in self.tree for name in link.points)

    def _checked_dependent_speeds(self) -> tuple:
        """Coordinates whose rates the motion constraints determine: one per constraint, no repeats."""
        if not isinstance(self.dependent_speeds, (list, tuple)):
            raise ModelError(f"dependent_speeds must be a list or tuple of coordinates, got "
                             f"{type(self.dependent_speeds).__name__}")
        by_name = {c.func.__name__: c for c in self.coordinates if hasattr(c, "func")}
        # a coordinate by its name too (found by review: dependent_speeds=["y"] was "not a coordinate
        # (coordinates: x, y)")
        named = tuple(by_name.get(q, q) if isinstance(q, str) else q for q in self.dependent_speeds)
        if not named:
            return named
        if self.sympy_model is not None:
            raise ModelError("dependent_speeds are for the energies and bodies routes; a KanesMethod brings its own "
                             "(u_dependent=)")
        for q in named:
            if q not in self.coordinates:
                hint = f" (name the coordinate {q.args[0]}, not its rate)" if isinstance(q, sp.Derivative) else ""
                raise ModelError(f"dependent speed {q!r} is not a coordinate of model {self.name!r}{hint} "
                                 f"(coordinates: {', '.join(c.func.__name__ for c in self.coordinates)})")
            if named.count(q) > 1:
                raise ModelError(f"dependent speed {q.func.__name__!r} is listed twice")
        if self.constraints:
            raise ModelError(f"dependent_speeds with holonomic constraints= are not supported (model {self.name!r}): "
                             "only velocity constraints are eliminated; drop dependent_speeds (multipliers)")
        if len(named) != len(self.motion_constraints):
            raise ModelError(f"dependent_speeds names {len(named)} coordinate(s) "
                             f"({', '.join(q.func.__name__ for q in named)}) for {len(self.motion_constraints)} "
                             "motion constraint(s): name one per motion constraint")
        return named

    def _check_coordinate_assumptions(self) -> None:
        """A function of t named like a coordinate but with other assumptions (dynamicsymbols('x',
        real=True) against dynamicsymbols('x')) is another function to sympy: named as such (found by
        review: the messages said x(t) is not a coordinate, coordinates: x(t))."""
        by_name = {q.func.__name__: q for q in self.coordinates if isinstance(q, AppliedUndef)}
        given = [self.kinetic_energy, self.potential_energy, self.dissipation, *self.constraints,
                 *self.motion_constraints]
        if isinstance(self.generalized_forces, Mapping):
            given += [*self.generalized_forces.keys(), *self.generalized_forces.values()]
        for expr in given:
            if not isinstance(expr, sp.Basic):
                continue
            for f in _dynamic_functions(expr):
                q = by_name.get(f.func.__name__)
                if q is not None and f != q:
                    raise ModelError(f"{f} has the assumptions {_function_assumptions(f)} but the coordinate {q} has "
                                     f"{_function_assumptions(q)}: sympy takes them for two functions; use the same "
                                     "dynamicsymbol")

    def _check_route(self) -> None:
        if self.tree:
            if self.formulation in ("elimination", "multipliers"):
                raise ModelError(f"model {self.name!r}: formulation {self.formulation!r} is for velocity "
                                 "constraints; a tree takes 'closed', 'recursive' or None")
            return
        if self.formulation in ("closed", "recursive"):
            raise ModelError(f"model {self.name!r}: formulation {self.formulation!r} is for a kinematic tree "
                             "(Model(tree=[Link(...), ...])); this model states no tree")
        if self.sympy_model is not None:
            if self.kinetic_energy is not None or self.bodies:
                raise ModelError("give either sympy_model or kinetic_energy/bodies, not both")
            # found by review: these were accepted and silently left out of the equations
            ignored = [name for name in ("generalized_forces", "dissipation", "loads", "gravity", "constraints")
                       if _given(getattr(self, name))]
            if ignored:
                raise ModelError(f"model {self.name!r}: a sympy model brings its own forces and constraints; "
                                 f"{', '.join(ignored)} would be left out: put them into the sympy model "
                                 "(its loads, hol_coneqs, ...)")
            return
        if self.bodies and self.kinetic_energy is not None:
            raise ModelError("give either kinetic_energy (energies route) or bodies, not both")
        if not self.bodies:
            ignored = [name for name in ("loads", "gravity") if _given(getattr(self, name))]
            if ignored:  # found by review: accepted on the energies route and left out of F
                raise ModelError(f"model {self.name!r}: {', '.join(ignored)} act on bodies (Model(bodies=[...])); "
                                 "by energies, give their work as generalized_forces or potential_energy")
        if not self.bodies and self.kinetic_energy is None:
            raise ModelError(f"model {self.name!r} needs a kinetic energy, bodies or a sympy model")
        needs_frame = bool(self.bodies) or any(isinstance(p, me.Point) for p in self.points.values())
        if needs_frame and (not isinstance(self.frame, me.ReferenceFrame) or not isinstance(self.origin, me.Point)):
            raise ModelError("bodies and Point outputs need frame= (inertial ReferenceFrame) and origin= (fixed Point)")
        for body in self.bodies:
            if not isinstance(body, (me.Particle, me.RigidBody)):
                raise ModelError(f"body {body!r} is not a sympy Particle or RigidBody")

    def _check_connected(self) -> None:
        """Every body, load and Point output can be located in ``frame`` from ``origin``: sympy's
        bare "No Connecting Path" would otherwise surface mid-derivation, naming no input."""
        if self.frame is None or self.origin is None:
            return
        located = [(f"body {body.name!r} (its mass centre {body.masscenter.name})", body.masscenter)
                   for body in self.bodies]
        located += [(f"load on point {load.where.name}", load.where) for load in self.loads
                    if not load.is_torque]
        located += [(f"point output {name!r}", pos) for name, pos in self.points.items()
                    if isinstance(pos, me.Point)]
        for what, point in located:
            try:
                point.pos_from(self.origin)
            except ValueError as error:
                raise ModelError(f"{what} has no position relative to origin {self.origin.name}: "
                                 f"set it with {point.name}.set_pos(...) ({error})") from None
        oriented = [(f"body {body.name!r} (its frame {body.frame})", body.frame) for body in self.bodies
                    if isinstance(body, me.RigidBody)]
        oriented += [(f"torque load on frame {load.where}", load.where) for load in self.loads if load.is_torque]
        # the frames the vectors are written in too (found by review: a load, gravity or inertia
        # in an unconnected frame failed with sympy's bare "No connecting orientation path")
        written = [(f"load on {getattr(load.where, 'name', load.where)}", load.vector) for load in self.loads]
        written += [("gravity", self.gravity)] if isinstance(self.gravity, me.Vector) else []
        written += [(f"inertia of body {body.name!r}", body.central_inertia) for body in self.bodies
                    if isinstance(body, me.RigidBody)]
        for what, vector in written:
            for frame in _frames_of(vector):
                oriented.append((f"{what} (written in frame {frame})", frame))
        for what, frame in oriented:
            try:
                frame.dcm(self.frame)
            except ValueError as error:
                raise ModelError(f"{what} is not oriented relative to the inertial frame {self.frame}: "
                                 f"orient it with {frame}.orient_axis(...) ({error})") from None
        # the velocity set on the origin itself, not one sympy's Point.vel infers from another point's
        # (found by review: Kane-style speeds set on P1 made a fixed O "move" by l (u1 - q1'))
        moving = getattr(self.origin, "_vel_dict", {}).get(self.frame, 0)
        if moving != 0 and any(sp.simplify(e) != 0 for e in _vector_entries(moving)):
            # found by review: a shaking table's velocity was dropped, the equations those of a fixed one
            raise ModelError(f"origin {self.origin.name} moves in frame {self.frame} (velocity {moving}): the origin "
                             "must be fixed; write the motion into the bodies' positions as functions of t")
        seen: dict = {}
        for body in self.bodies:  # found by review: a body listed twice had its mass counted twice
            if id(body) in seen:
                raise ModelError(f"model {self.name!r}: body {body.name!r} is listed twice in bodies")
            seen[id(body)] = body

    def _check_symbols(self) -> None:
        """Every free symbol is t or declared; every function of t is a coordinate; no nan,
        infinity or imaginary unit; no speed in V or phi; no acceleration anywhere."""
        exprs = [("kinetic_energy", self.kinetic_energy), ("potential_energy", self.potential_energy),
                 ("dissipation", self.dissipation)]
        exprs += [(f"generalized force on {q}", Q) for q, Q in self.generalized_forces.items()]
        exprs += [(f"measurement {name!r}", y) for name, y in self.measurements.items()]
        for link in self.tree:  # the joint variable was checked with the tree
            exprs += [(f"{what} of link {link.name!r}", e) for what, values in (
                ("mass", (link.mass,)), ("offset", link.offset), ("centre of mass", link.center),
                ("inertia", link.inertia)) for e in values]
            exprs += [(f"point {name!r} of link {link.name!r}", e) for name, xyz in link.points.items() for e in xyz]
        for body in self.bodies:
            exprs.append((f"mass of {body.name}", _as_expr(body.mass, f"mass of {body.name}")))
            if isinstance(body, me.RigidBody):
                exprs += [(f"inertia of {body.name}", entry) for entry in _dyadic_entries(body.inertia[0])]
            position = _vector_entries(body.masscenter.pos_from(self.origin))
            # found by review: its velocity then held q'' and the equations were garbage, status OK
            _check_no_speed(position, f"the position of body {body.name}")
            exprs += [(f"position of body {body.name}", entry) for entry in position]
            if isinstance(body, me.RigidBody) and self.frame is not None:
                # found by review: an input in it was accepted and its rate dropped from the equations
                exprs += [(f"angular velocity of body {body.name}", entry)
                          for entry in _vector_entries(body.frame.ang_vel_in(self.frame))]
            if self.sympy_model is None and body.potential_energy != 0:
                # sympy's attribute for its Lagrangian(), which its KanesMethod ignores: counting it could
                # double gravity, dropping it lost a spring (found by review: F = 0, status OK)
                raise ModelError(f"body {body.name!r} carries a potential_energy ({body.potential_energy}), which "
                                 "the bodies route does not read: give it as Model(potential_energy=...) (and "
                                 "gravity as gravity=), and set the body's to 0")
        for load in self.loads:
            kind = "torque on frame" if load.is_torque else "force on point"
            exprs += [(f"{kind} {load.where.name}", entry) for entry in _vector_entries(load.vector)]
            if not load.is_torque:  # as a body's position (found by review: a speed in it was dropped)
                _check_no_speed(_vector_entries(load.where.pos_from(self.origin)),
                                f"the position of the load's point {load.where.name}")
        for name, pos in self.points.items():
            if not isinstance(pos, me.Point):
                if not isinstance(pos, (tuple, list)) or len(pos) not in (2, 3):
                    raise ModelError(f"point {name!r} must be a Point or 2 or 3 expressions, got {pos!r}")
                for i, c in enumerate(pos):
                    exprs.append((f"point {name!r} component {i}", _as_expr(c, f"point {name!r}")))
        if self.gravity is not None and self.tree:
            exprs += [(f"gravity component {i}", _as_expr(g, "gravity"))
                      for i, g in enumerate(three_entries(self.gravity))]
        elif self.gravity is not None:
            if not isinstance(self.gravity, me.Vector):
                raise ModelError(f"gravity must be a sympy.physics.vector Vector (e.g. -g*N.y), got {self.gravity!r}")
            exprs.append(("gravity", components(self.gravity, self.frame)))
        for name, pos in self.points.items():
            if isinstance(pos, me.Point):
                exprs += [(f"point {name!r}", entry) for entry in _vector_entries(pos.pos_from(self.origin))]
        for i, phi in enumerate(self.constraints):
            if phi.atoms(sp.Derivative):
                raise ModelError(f"constraint {i} ({phi}) contains speeds "
                                 f"{', '.join(map(str, sorted(phi.atoms(sp.Derivative), key=str)))}: only "
                                 "holonomic constraints phi(q, t) = 0 are supported")
            if not _dynamic_functions(phi) & set(self.coordinates):
                raise ModelError(f"constraint {i} ({phi}) involves no coordinate")
            exprs.append((f"constraint {i}", phi))
        if self.motion_constraints and self.sympy_model is not None:
            raise ModelError("motion_constraints are for the energies and bodies routes; a sympy model brings its own")
        for i, c in enumerate(self.motion_constraints):
            check_well_defined(f"motion constraint {i}", c)  # nan * x' folds to nan: name that first
            if not _dynamic_functions(c) & set(self.coordinates):
                raise ModelError(f"motion constraint {i} ({c}) involves no coordinate")
            exprs.append((f"motion constraint {i}", c))
        speeds = sorted(self.potential_energy.atoms(sp.Derivative), key=str)
        if speeds:
            raise ModelError(f"potential_energy contains the speed {speeds[0]}: V must be a function of the "
                             "coordinates and t only; put velocity-dependent terms in kinetic_energy or "
                             "generalized_forces")
        for what, expr in exprs:
            check_well_defined(what, expr)
        self._check_input_places(exprs)
        functions = tuple(self.coordinates) + tuple(r for r in self.inputs if not isinstance(r, sp.Symbol))
        if self.sympy_model is not None:  # Kane's speeds are functions of time of their own
            functions += tuple(_sympy_model_speeds(self.sympy_model))
        check_declared(exprs, self.parameters, functions,
                       extra=tuple(r for r in self.inputs if isinstance(r, sp.Symbol)))

    def _checked_measurements(self) -> dict:
        """name -> Expr; names are distinct identifiers that are not state or input names."""
        if not isinstance(self.measurements, Mapping):
            raise ModelError(f"measurements must be a mapping name -> expression, got "
                             f"{type(self.measurements).__name__}")
        taken = {str(q.func.__name__) if hasattr(q, "func") else str(q) for q in self.coordinates}
        taken |= {input_name(r) for r in self.inputs}
        checked = {}
        for name, expr in self.measurements.items():
            if not isinstance(name, str) or not name.isidentifier():
                raise ModelError(f"measurement name {name!r} must be an identifier string")
            if name in taken:
                raise ModelError(f"measurement {name!r} has the name of a coordinate or input; rename it")
            checked[name] = _as_expr(expr, f"measurement {name!r}")
        return checked

    def _checked_links(self) -> tuple:
        """Pairs of distinct point names (or ``"origin"``), as a tuple of 2-tuples."""
        if not isinstance(self.links, (list, tuple)):
            raise ModelError(f"links must be a list or tuple of (name, name) pairs, got {type(self.links).__name__}")
        known = (*self.points, *self.tree_points(), "origin")
        checked = []
        for link in self.links:
            if not (isinstance(link, (list, tuple)) and len(link) == 2 and all(isinstance(n, str) for n in link)):
                raise ModelError(f"link {link!r} must be a pair of point names (name, name)")
            for name in link:
                if name not in known:
                    raise ModelError(f"link {tuple(link)!r} names {name!r}, which is not a point of model "
                                     f"{self.name!r} (points: {', '.join(known)})")
            if link[0] == link[1]:
                raise ModelError(f"link {tuple(link)!r} joins point {link[0]!r} to itself")
            checked.append(tuple(link))
        return tuple(checked)

    def _check_input_places(self, exprs) -> None:
        """Inputs may drive the forcing (V, Q, R, loads, gravity), not T, masses, positions or phi."""
        if not self.inputs:
            return
        allowed = ("potential_energy", "dissipation", "generalized force", "torque on", "force on", "gravity",
                   "measurement")
        for what, expr in exprs:
            if expr is None or what.startswith(allowed):
                continue
            atoms = expr.free_symbols | _dynamic_functions(expr)
            for r in self.inputs:
                if r in atoms:
                    raise ModelError(f"input {input_name(r)!r} appears in {what}: inputs may enter the potential "
                                     "energy, generalized forces, dissipation and loads only (in the kinetic "
                                     "energy, a mass or a position its rate would enter the equations)")


_UNDEFINED_ATOMS = ((sp.nan, "nan"), (sp.zoo, "complex infinity (zoo)"), (sp.oo, "infinity (oo)"),
                    (sp.S.NegativeInfinity, "-infinity (-oo)"), (sp.I, "the imaginary unit I"))
_UNDEFINED_LABELS = dict(_UNDEFINED_ATOMS)


def input_name(r: Any) -> str:
    """The name of an input: its Symbol's, or its dynamicsymbol's function name."""
    return r.name if isinstance(r, sp.Symbol) else r.func.__name__


def check_well_defined(what: str, expr: sp.Basic) -> None:
    """Raise `ModelError` when ``expr`` holds nan, an infinity, I or an acceleration: sympy folds
    ``V + nan`` to nan, whose derivative is 0, so the term would vanish without a word."""
    if expr is None or not isinstance(expr, sp.Basic):
        return
    for atom, label in _UNDEFINED_ATOMS:
        if expr == atom:
            raise ModelError(f"{what} is {label} (a nan or infinite value folds the whole expression)")
    # one walk over the distinct nodes (a sympy model's forcing is large, and each has() or atoms() is a walk)
    undefined, accelerations, powers, functions = set(), set(), set(), set()
    for node in distinct_nodes([expr]):
        if node in _UNDEFINED_LABELS:
            undefined.add(node)
        elif isinstance(node, sp.Derivative):
            if node.derivative_count > 1:
                accelerations.add(node)
        elif isinstance(node, sp.Pow):
            powers.add(node)
        elif isinstance(node, sp.Function):
            functions.add(node)
    for atom, label in _UNDEFINED_ATOMS:
        if atom in undefined:
            raise ModelError(f"{what} contains {label}: {expr}")
    if accelerations:
        raise ModelError(f"{what} contains the acceleration {sorted(accelerations, key=str)[0]}: energies, "
                         "forces and positions may depend on coordinates, speeds and t only")
    # a constant that is complex without an I atom (found by review: (-1)**(1/3) is 0.5 + 0.866 I in
    # sympy, printed as cbrt(-1) = -1 in C, so the kernel ran a different model with status OK)
    for power in powers:
        if power.is_number and power.is_extended_real is False:
            raise ModelError(f"{what} contains the complex constant {power} = {sp.N(power, 6)}: sympy takes the "
                             "principal root of a negative number; write the real value (e.g. -1 for (-1)**(1/3))")
    # and a function outside its real domain (found by review: k asin(2) x^2 ran to "diverged")
    for function in functions:
        if function.is_number and function.is_extended_real is False:
            raise ModelError(f"{what} contains the complex constant {function} = {sp.N(function, 6)}: its "
                             "argument is outside the function's real domain")


#: sign assumptions of a parameter Symbol, and the values each admits: the sign, or 0 (the limit a
#: sweep of a mass ratio reaches; the run's singularity monitor speaks for it), not the other sign
SIGN_ASSUMPTIONS = {"positive": lambda v: v >= 0, "nonnegative": lambda v: v >= 0,
                    "negative": lambda v: v <= 0, "nonpositive": lambda v: v <= 0}


def sign_assumption(symbol) -> str | None:
    """The sign assumption ``symbol`` was declared with (positive=True, ...), or None."""
    for name in SIGN_ASSUMPTIONS:
        if getattr(symbol, f"is_{name}", None) is True:
            return name
    return None


def sign_error(name: str, value: float, assumption: str | None, what: str) -> str | None:
    """The message for a ``value`` of parameter ``name`` of the sign its declared ``assumption``
    excludes: sympy simplified the equations under it (sqrt(l**2) -> l for a positive l), so they need
    not hold for such a value (found by review: m1 = -1 for a positive m1 ran until a singular mass
    matrix, blamed on the step)."""
    if assumption is None or SIGN_ASSUMPTIONS[assumption](value):
        return None
    return (f"{what} = {value!r}, but {name!r} is declared {assumption} (sympy simplified the equations under "
            "that assumption, so they need not hold for this value); give a value of that sign, or declare "
            "the symbol without the assumption")


def finite_number(value: Any, what: str) -> float:
    """``value`` as a finite float, or a `ModelError` naming ``what``."""
    # a complex value of numpy's converts to float dropping its imaginary part (found by review)
    if isinstance(value, (bool, str, bytes)) or (isinstance(value, numbers.Complex)
                                                 and not isinstance(value, numbers.Real)):
        raise ModelError(f"{what} must be a finite number, got {type(value).__name__} {value!r}")
    try:
        number = float(value)
    except OverflowError:  # an int beyond the double range (found by review: a bare OverflowError)
        raise ModelError(f"{what} must be a finite number, got an integer of {len(str(abs(int(value))))} digits, "
                         "beyond the double range") from None
    except (TypeError, ValueError):
        raise ModelError(f"{what} must be a finite number, got {type(value).__name__} {value!r}") from None
    if not math.isfinite(number):
        raise ModelError(f"{what} must be a finite number, got {value!r}")
    return number


def _vector_entries(vector) -> list:
    """Every measure number of a sympy Vector, in the frames it is stored in."""
    if not isinstance(vector, me.Vector):
        return []
    # nan * N.x builds a Vector whose measure is a bare nan instead of a (3, 1) Matrix
    return [entry for measure, _frame in vector.args
            for entry in (measure if isinstance(measure, sp.MatrixBase) else [measure])]


def _dyadic_entries(dyadic) -> list:
    return [coefficient for coefficient, _first, _second in getattr(dyadic, "args", ())]


def check_declared(exprs, parameters, coordinates, extra=()) -> None:
    """Raise `ModelError` listing undeclared symbols or functions of time found in ``exprs``.

    ``exprs`` is a sequence of (description, expression) pairs.
    """
    allowed = set(parameters) | {TIME} | set(extra)
    for what, expr in exprs:
        if expr is None:
            continue
        check_symbols_declared(what, free_symbols_of(_entries(expr)) - allowed, parameters)
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


def _check_joints_connected(method) -> None:
    """Every joint of a JointsMethod hangs from the Newtonian body through the others: sympy's own
    error for a loose one ("Velocity of point ... has not been defined") names no joint."""
    roots = [body for body in method.bodies if getattr(body, "frame", None) == method.frame]
    connected = set(roots)
    pending = list(method._joints)  # private: sympy 1.14 keeps the joints only there
    while pending:
        ready = [joint for joint in pending if joint.parent in connected]
        if not ready:
            joint = pending[0]
            raise ModelError(f"JointsMethod: joint {joint.name!r} hangs from body {joint.parent.name!r}, which no "
                             f"joint connects to the Newtonian body {roots[0].name if roots else method.frame}: "
                             "add the joint that carries it")
        for joint in ready:
            connected.add(joint.child)
            pending.remove(joint)


def _sympy_model_speeds(obj: Any) -> list:
    """The speeds of a KanesMethod or System (a JointsMethod's formed method), else none."""
    method = getattr(obj, "method", None) if isinstance(obj, me.JointsMethod) else obj
    return list(getattr(method, "u", None) or ()) if isinstance(method, (me.KanesMethod, me.System)) else []


def _sympy_model_coordinates(obj: Any) -> list:
    if isinstance(obj, me.JointsMethod):  # its bodies and joints formed into a Kane or Lagrange method
        _check_joints_connected(obj)
        if obj.method is None:
            obj.form_eoms()
        return _sympy_model_coordinates(obj.method)
    if isinstance(obj, (me.System, me.LagrangesMethod, me.KanesMethod)):
        return list(obj.q)  # every count of coordinates and speeds (symbolic/sympy_models.py)
    raise ModelError(f"sympy_model must be a LagrangesMethod, KanesMethod, System or JointsMethod, got "
                     f"{type(obj).__name__}")
