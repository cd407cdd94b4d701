"""The equations object every derivation route returns, and the steps the routes share:
plain symbols for q(t) and their speeds, the substitution into them, the mass-matrix checks and
the assembly of `EquationsOfMotion` (points, holonomic constraints, Baumgarte parameters)."""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

from ..model import (
    ROUTE_BODIES,
    ROUTE_ENERGIES,
    TIME,
    Model,
    ModelError,
    check_declared,
    check_symbols_declared,
    input_name,
)
from ..walk import with_zeros
from .differentiation import jacobian
from .grouping import components
from .holonomic import BAUMGARTE_ALPHA, BAUMGARTE_BETA, holonomic_terms, motion_terms

ROUTE_TITLES = {
    ROUTE_ENERGIES: "Lagrange II (energies)",
    ROUTE_BODIES: "d'Alembert-Lagrange (points and bodies)",
}


def without_baumgarte(expr):
    """``expr`` with Baumgarte's terms dropped, for dependent speeds eliminated: they are solved from the
    velocity constraints at every evaluation, so w = A u + b is zero there and -2 alpha w vanishes
    (and there is no phi for -beta^2 phi)."""
    terms, memo = (BAUMGARTE_ALPHA, BAUMGARTE_BETA), {}
    if isinstance(expr, sp.MatrixBase):
        return expr.applyfunc(lambda entry: with_zeros(entry, terms, memo))
    return with_zeros(expr, terms, memo)


#: expression nodes of M and F beyond which a notebook shows the equations as text
LATEX_NODE_LIMIT = 4000


def _nodes_beyond(exprs, limit: int) -> bool:
    """More than ``limit`` nodes in ``exprs`` (counted until the limit)."""
    count = 0
    for expr in exprs:
        for _ in sp.preorder_traversal(expr):
            count += 1
            if count > limit:
                return True
    return False


@dataclass(frozen=True)
class EquationsOfMotion:
    """``qd = K(q, u, t)``, ``M(q, t) ud = F(q, u, t)``, in plain symbols.

    Attributes
    ----------
    name, route : str
    t : Symbol
    coordinates, speeds : tuple
        The dynamicsymbols q_i(t) and generalized speeds (qd_i(t), or Kane's u_i(t)).
    q, u : tuple of Symbol, (n_q,) and (n_u,)
        Plain symbols standing for ``coordinates`` and ``speeds`` in every expression below
        (n_u differs from n_q for Kane's speeds such as a quaternion's body rates).
    parameters : tuple of Symbol
    parameter_values : dict Symbol -> float (defaults; may be partial)
    mass_matrix : ImmutableMatrix, (n_u, n_u), symmetric
    forcing : ImmutableMatrix, (n_u, 1)
    kinematics : ImmutableMatrix, (n_q, 1); qd = kinematics
    kinetic_energy, potential_energy : Expr or None
    points : tuple of (name, ImmutableMatrix (d, 1))
    constraints : ImmutableMatrix (m, 1)
        Holonomic constraints phi(q, t) = 0 (m = 0 without them). Then M ud = F - A^T lambda,
        A = dphi/dq, with A ud = ``constraint_bias`` (gamma, Baumgarte terms included; their
        parameters ``baumgarte_alpha``, ``baumgarte_beta`` default to 0); see `holonomic`.
    constraint_jacobian : ImmutableMatrix (m, n)
    constraint_rate : ImmutableMatrix (m, 1); dphi/dt
    constraint_bias : ImmutableMatrix (m, 1); gamma
    inputs : tuple of Symbol, (n_r,)
        Plain symbols of the model's inputs r; they appear in F (and K), never in M.
    measurements : tuple of (str, Expr)
        Output expressions y = h(q, u, r, t) by name.
    n_holonomic : int
        The first rows of the constraint terms are holonomic (phi(q, t) = 0); the other m -
        n_holonomic are velocity constraints A u + b = 0, whose phi rows are 0 and whose
        ``constraint_rate`` rows hold b.
    n_dependent : int
        0, or m when the velocity constraints are eliminated (Model.formulation, Kane's
        u_dependent or Model.dependent_speeds): the last m speeds are dependent, computed from
        A u + b = 0, and the state holds q and the first n_u - m speeds; M, F, A and gamma stay
        those of every speed. On the energies and bodies routes the speeds are the coordinate
        rates with the dependent ones moved last, so K is then a permutation of u.
    reactions : tuple of Symbol
        Unknown constraint forces (a contact's normal and friction forces) that Kane's auxiliary
        speeds expose; ``reaction_equations`` (one row per auxiliary speed, linear in them) hold
        in q, u and the accelerations, for which ``reaction_accelerations`` (one per speed) stand.
    configuration : ImmutableMatrix (k, 1)
        Kane's configuration constraints f(q, t) = 0, solved for the ``dependent_coordinates``
        (indices into q) by the projection after a step; the dynamics reach them only through
        the velocity constraints (sympy's rhs integrates those coordinates freely).
    tree : trees.TreeKernels or None
        A kinematic tree in the recursive formulation: its dynamics, energy and points as
        straight-line assignments; ``mass_matrix``, ``forcing`` and the energies are then None
        (never formed) and the points' expressions too (``points`` keeps their names).
    formulation : str
        How a tree's equations were formed and why (`trees.choose_formulation`); "" otherwise.
    """

    name: str
    route: str
    t: sp.Symbol
    coordinates: tuple
    speeds: tuple
    q: tuple
    u: tuple
    parameters: tuple
    parameter_values: dict
    mass_matrix: sp.ImmutableMatrix
    forcing: sp.ImmutableMatrix
    kinematics: sp.ImmutableMatrix
    kinetic_energy: Any
    potential_energy: Any
    points: tuple
    constraints: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 1, [])
    constraint_jacobian: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 0, [])
    constraint_rate: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 1, [])
    constraint_bias: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 1, [])
    inputs: tuple = ()
    measurements: tuple = ()
    n_holonomic: int = 0
    n_dependent: int = 0
    reactions: tuple = ()
    reaction_equations: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 1, [])
    reaction_accelerations: tuple = ()
    configuration: sp.ImmutableMatrix = sp.ImmutableMatrix(0, 1, [])
    dependent_coordinates: tuple = ()
    tree: Any = None
    formulation: str = ""

    def display(self) -> tuple:
        """(M, F) as a textbook prints them (`display.display_form`); the emitted form is unchanged."""
        from .display import display_equations

        return display_equations(self)

    def _repr_latex_(self) -> str | None:
        """Notebooks render the equations in display form; large ones (more than
        `LATEX_NODE_LIMIT` expression nodes in M and F) as text, since the display form takes
        minutes there (found by review: 55 s for one entry of a 3-link spatial chain) and a notebook
        asks for it whenever a cell ends with the equations."""
        from .display import latex_equations

        if self.mass_matrix is None or _nodes_beyond([*self.mass_matrix, *self.forcing], LATEX_NODE_LIMIT):
            return None
        return f"$\\displaystyle {latex_equations(self)}$"

    @property
    def m(self) -> int:
        """Number of holonomic constraints."""
        return self.constraints.rows

    @property
    def n_q(self) -> int:
        """Number of coordinates q."""
        return len(self.q)

    @property
    def n_u(self) -> int:
        """Number of generalized speeds u (the size of M); differs from n_q for Kane's speeds
        such as a quaternion's body rates (4 coordinates, 3 speeds)."""
        return len(self.u)

    @property
    def n_state(self) -> int:
        """Size of the first-order state x = (q, u)."""
        return len(self.q) + len(self.u)

    @property
    def n(self) -> int:
        """The common count of coordinates and speeds; an error when they differ (use n_q, n_u)."""
        if len(self.q) != len(self.u):
            raise ValueError(f"model {self.name!r} has {len(self.q)} coordinates and {len(self.u)} speeds: "
                             "this step needs one speed per coordinate (n_q == n_u)")
        return len(self.q)

    @property
    def mass_matrix_full(self) -> sp.ImmutableMatrix:
        """(n_q + n_u, n_q + n_u) block diag(I, M) of the first-order form in x = (q, u)."""
        n_q, n_u = self.n_q, self.n_u
        full = sp.zeros(n_q + n_u, n_q + n_u)
        full[:n_q, :n_q] = sp.eye(n_q)
        full[n_q:, n_q:] = self.mass_matrix
        return sp.ImmutableMatrix(full)

    @property
    def forcing_full(self) -> sp.ImmutableMatrix:
        """(n_q + n_u, 1) right-hand side (K; F) of the first-order form."""
        return sp.ImmutableMatrix.vstack(self.kinematics, self.forcing)

    @property
    def energy(self):
        """Total mechanical energy T + V, or None when the route gives no energies."""
        if self.kinetic_energy is None or self.potential_energy is None:
            return None
        return self.kinetic_energy + self.potential_energy

    def to_dynamic(self, expr):
        """Rewrite ``expr`` from plain symbols to dynamicsymbols (for display)."""
        back = dict(zip(self.q, self.coordinates))
        back.update(zip(self.u, self.speeds))
        return sp.sympify(expr).xreplace(back)

# -- symbols ----------------------------------------------------------------------------------
def plain_symbols(coordinates, speeds, parameters) -> tuple[tuple, tuple]:
    """Plain Symbols for q_i(t) (same name) and their speeds (name + '_d', or Kane's u name)."""
    q = tuple(sp.Symbol(c.func.__name__, real=True) for c in coordinates)
    u = tuple(sp.Symbol(s.func.__name__ if isinstance(s, AppliedUndef) else s.expr.func.__name__ + "_d", real=True)
              for s in speeds)
    taken = {p.name: "a parameter" for p in parameters} | {TIME.name: "the time symbol"}
    roles = [f"coordinate {c.func.__name__}" for c in coordinates] + \
        [f"speed {s.func.__name__}" if isinstance(s, AppliedUndef)
         else f"the speed of coordinate {s.expr.func.__name__} (named <coordinate>_d)" for s in speeds]
    for sym, role in zip(q + u, roles):
        if sym.name in taken:
            raise ModelError(f"name {sym.name!r} is used by {taken[sym.name]} and by {role}; rename it")
        taken[sym.name] = role
    return q, u


def input_symbols(inputs) -> tuple:
    """Plain Symbols for the inputs (a dynamicsymbol r(t) becomes Symbol r; a Symbol stays)."""
    return tuple(r if isinstance(r, sp.Symbol) else sp.Symbol(input_name(r)) for r in inputs)


def make_substitution(coordinates, speeds, q, u, what: str, parameters=None, inputs=(), reactions=()) -> Callable:
    """Return ``to_plain(expr)``: dynamicsymbols -> plain symbols, raising on leftovers and, when
    ``parameters`` is given, on free symbols that are not parameters, t, q, u or inputs.
    ``reactions``: the unknown forces of Kane's auxiliary equations, named as such when they are
    left over."""
    table = dict(zip(speeds, u))  # Derivative(q(t), t) for the Lagrange routes, u(t) for Kane's
    table.update(zip(coordinates, q))
    r = input_symbols(inputs)
    table.update(zip(inputs, r))
    allowed = None if parameters is None else set(parameters) | {TIME} | set(q) | set(u) | set(r)

    def to_plain(expr, where: str = what):
        expr = sp.sympify(expr)
        out = expr.xreplace(table)
        left = [a for a in out.atoms(sp.Derivative, AppliedUndef)]
        if left:
            # the rate of an input reads Derivative(r, t) here: xreplace renamed the input inside it
            rates = sorted(str(a) for a in left if isinstance(a, sp.Derivative) and a.expr in set(inputs) | set(r))
            if rates:
                raise ModelError(f"{where} contains the input rate {rates[0]}: inputs may enter the forcing, "
                                 "their rates may not")
            # found by review: both were told to list themselves as inputs
            higher = sorted(str(a) for a in left if isinstance(a, sp.Derivative)
                            and a.expr in set(coordinates) | set(speeds) | set(q) | set(u))
            if higher:
                # found by review: a measurement was told of "a constraint on the accelerations"
                why = (" (a constraint on the accelerations is not supported)" if "constraint" in where else
                       " (measure what the state gives; an acceleration is an output of the dynamics)"
                       if "measurement" in where else "")
                raise ModelError(f"{where} contains the acceleration {higher[0]}: only coordinates, speeds and "
                                 f"time may appear here{why}")
            exposed = sorted(str(a) for a in left if a in set(reactions))
            if exposed:
                raise ModelError(f"{where} contains {exposed[0]}, a force the auxiliary speeds expose, in the "
                                 "equations of the model's own speeds: lagcodegen forms them for every speed, the "
                                 "dependent ones too, so a reaction must do work on auxiliary speeds only, or act "
                                 "along the velocity constraints (a rolling contact's force, held by them); here it "
                                 "also does work on a speed of the model; give it a direction no speed of the "
                                 "model moves its point in, or drop it from the loads")
            raise ModelError(f"{where} contains {', '.join(sorted(map(str, left)))}, which is not a "
                             f"coordinate or a speed of this model; a specified function of time that "
                             f"drives the model is an input: list it in Model(..., inputs=[...])")
        if allowed is not None:
            check_symbols_declared(where, out.free_symbols - allowed, parameters)
        return out
    return to_plain


def lagrange_symbols(model: Model):
    """Coordinates, speeds qd, their plain symbols q, u and the substitution into them."""
    coords = model.coordinates
    # the same Derivative objects c.diff(t) builds, without the cost of evaluating them
    speeds = tuple(sp.Derivative(c, TIME, evaluate=False) for c in coords)
    q, u = plain_symbols(coords, speeds, model.parameters)
    return coords, speeds, q, u, make_substitution(coords, speeds, q, u, "model", model.parameters, model.inputs)

def check_mass_matrix(M: sp.Matrix, coords, u, speeds=None) -> None:
    """A zero diagonal entry of M names its coordinate (or, when the speeds are not one per
    coordinate, its generalized speed among ``speeds``)."""
    owners = coords if speeds is None or len(speeds) == len(coords) else speeds
    for j, c in enumerate(owners):
        if M[j, j] == 0:
            what = "coordinate" if owners is coords else "generalized speed"
            raise ModelError(
                f"{what} {_name(c)!r} has no inertia: its speed does not appear in the kinetic "
                f"energy, so the mass matrix is singular (row {j})")
    speeds = set(u)
    for (j, k), entry in M.todok().items():
        if entry.free_symbols & speeds:
            raise ModelError(
                f"the kinetic energy is not quadratic in the speeds: M[{j},{k}] depends on "
                f"{', '.join(sorted(map(str, entry.free_symbols & speeds)))}")


def _name(symbol) -> str:
    return symbol.func.__name__ if symbol.args else str(symbol)  # q1(t) -> "q1"


# -- assembly ---------------------------------------------------------------------------------
def dependent_last(coords, u, speeds, M, F, dependent) -> tuple:
    """(u, speeds, M, F) with the rates of the ``dependent`` coordinates moved last (in their
    given order), the others kept in declared order: rows and columns of M, rows of F."""
    last = [list(coords).index(c) for c in dependent]
    order = [j for j in range(len(u)) if j not in last] + last
    M, F = sp.Matrix(M), sp.Matrix(F)
    return (tuple(u[j] for j in order), tuple(speeds[j] for j in order), M.extract(order, order),
            F.extract(order, [0]))


def _check_smooth(model, rows, gamma, n_holonomic: int) -> None:
    """A ModelError naming the constraint whose derivatives hold a delta or step function (Abs(x)
    or sign(x) in it): A ud = gamma needs it differentiable twice (holonomic) or once (on the
    velocities); before, the C printer refused 'DiracDelta' in gamma without naming the constraint."""
    for i, (row, bias) in enumerate(zip(rows, gamma)):
        kinks = bias.atoms(sp.DiracDelta, sp.Heaviside)
        if kinks:
            kind = "constraint" if i < n_holonomic else "motion constraint"
            index = i if i < n_holonomic else i - n_holonomic
            raise ModelError(f"model {model.name!r}: {kind} {index} ({row}) is not smooth: its derivative along "
                             f"the motion holds {sorted(map(str, kinks))[0]} (from Abs, sign or a step in it); "
                             "write it without the kink, e.g. one constraint per side")


def _check_dependent_block(model, A, u, m: int) -> None:
    """A_D, the last m columns of A (the dependent speeds), must not be singular everywhere: a speed
    no constraint involves, or a constraint involving none of them, is named."""
    p = len(u) - m
    for j in range(m):
        if all(A[i, p + j] == 0 for i in range(m)):
            raise ModelError(f"model {model.name!r}: dependent speed {u[p + j]} appears in no motion constraint, so "
                             "the constraints cannot determine it; name the rates the constraints involve")
    for i in range(m):
        if all(A[i, p + j] == 0 for j in range(m)):
            raise ModelError(f"model {model.name!r}: motion constraint {i} involves none of the dependent speeds "
                             f"{', '.join(map(str, u[p:]))}; name one of the rates it involves")


def _immutable(matrix) -> sp.ImmutableMatrix:
    return matrix if isinstance(matrix, sp.ImmutableMatrix) else sp.ImmutableMatrix(matrix)


def assemble(model, coords, speeds, q, u, M, F, K, T, V, to_plain, inputs_checked=False,
             positions=None, constraints=None, motion=None, motion_rates=None) -> EquationsOfMotion:
    """The equations object; M and F are searched for undeclared symbols unless every input
    went through a ``to_plain`` that checks them (``inputs_checked``). ``positions`` maps Points
    whose components in the model's frame are already known (in plain symbols). ``constraints``
    (holonomic, phi(q, t) = 0) and ``motion`` (velocity constraints, linear in the coordinate
    rates) default to the model's; a sympy model brings its own."""
    named = tuple(getattr(model, "dependent_speeds", ()))
    if model.formulation == "elimination" and model.sympy_model is None and not named:
        raise ModelError(f"model {model.name!r}: formulation 'elimination' needs named dependent speeds: name the "
                         "coordinates whose rates the motion constraints determine, Model(..., dependent_speeds=[...]) "
                         "(a KanesMethod gives them as u_dependent=)")
    constraints = tuple(model.constraints) if constraints is None else tuple(constraints)
    motion = tuple(getattr(model, "motion_constraints", ())) if motion is None else tuple(motion)
    eliminated = bool(named) and model.formulation != "multipliers"
    if eliminated:  # the dependent speeds last; K keeps qd_j = (the speed of q_j): a permutation of u
        u, speeds, M, F = dependent_last(coords, u, speeds, M, F, named)
    r = input_symbols(model.inputs)
    if not inputs_checked:
        check_declared([("mass matrix", M), ("forcing", F)], model.parameters, (), extra=q + u + r)
    for (j, k), entry in (sp.Matrix(M).todok().items() if M is not None else ()):
        held = sorted(entry.free_symbols & set(r), key=str)
        if held:
            raise ModelError(f"input {held[0]} enters the mass matrix (M[{j},{k}] = {entry}): inputs may "
                             "enter the forcing only")
    points, positions = [], positions or {}
    for name, where in model.points.items():
        if isinstance(where, me.Point) and where in positions:
            points.append((name, sp.ImmutableMatrix(positions[where])))
            continue
        if isinstance(where, me.Point):
            pos = components(where.pos_from(model.origin), model.frame)
        else:
            pos = sp.Matrix(list(where) + [0] * (3 - len(where)))  # planar points get z = 0
        points.append((name, sp.ImmutableMatrix(to_plain(pos, f"point {name!r}"))))
    route = ROUTE_TITLES.get(model.route, model.route)
    parameters, values, constrained = tuple(model.parameters), dict(model.parameter_values), {}
    if constraints or motion:
        if constraints and list(K) != list(u):
            raise ModelError("holonomic constraints need generalized speeds equal to the coordinate rates; "
                             "with Kane's speeds state them as velocity constraints")
        phi = sp.Matrix([to_plain(c, f"constraint {i}") for i, c in enumerate(constraints)])
        check_declared([(f"constraint {i}", c) for i, c in enumerate(phi)], model.parameters, (), extra=q + u + r)
        w = sp.Matrix([to_plain(c, f"motion constraint {i}") for i, c in enumerate(motion)])
        check_declared([(f"motion constraint {i}", c) for i, c in enumerate(w)], model.parameters, (),
                       extra=q + u + r)
        # the velocity constraints' A, taken once: motion_terms reuses it
        A_w = jacobian(w, u) if w.rows else None
        for i in range(w.rows):
            nonlinear = [s for j, s in enumerate(u) if A_w[i, j].has(*u)]
            if nonlinear:
                raise ModelError(f"motion constraint {i} ({motion[i]}) is not linear in the speeds (in "
                                 f"{speeds[list(u).index(nonlinear[0])]}); velocity constraints must read "
                                 "a(q, t) . qd + b(q, t)")
            if not any(A_w[i, j] != 0 for j in range(len(u))):
                raise ModelError(f"motion constraint {i} ({motion[i]}) involves no speed: a constraint on the "
                                 "positions belongs in constraints=")
        blocks = []
        if phi.rows:
            blocks.append(dict(holonomic_terms(phi, q, u, TIME), phi=phi))
        if w.rows:
            rates = None if motion_rates is None else \
                sp.Matrix(to_plain(sp.Matrix(motion_rates), "acceleration constraints"))
            blocks.append(motion_terms(w, q, u, TIME, K, rates=rates, A=A_w))
        stack = lambda key: sp.ImmutableMatrix(sp.Matrix.vstack(*[sp.Matrix(b[key]) for b in blocks]))  # noqa: E731
        _check_smooth(model, [*phi, *w], stack("gamma"), phi.rows)
        constrained = {"constraints": stack("phi"), "constraint_jacobian": stack("A"),
                       "constraint_rate": stack("phi_t"), "constraint_bias": stack("gamma"),
                       "n_holonomic": phi.rows}
        kinds = " and ".join(k for k, rows in (("holonomic", phi.rows), ("velocity", w.rows)) if rows)
        route += f" with {kinds} constraints (Lagrange I)"
        if eliminated:
            _check_dependent_block(model, constrained["constraint_jacobian"], u, w.rows)
            constrained["n_dependent"] = w.rows
            constrained["constraint_bias"] = without_baumgarte(constrained["constraint_bias"])
            route = route.replace("(Lagrange I)", f"(dependent speeds {', '.join(map(str, u[-w.rows:]))} eliminated)")
        else:
            parameters += (BAUMGARTE_ALPHA, BAUMGARTE_BETA)
            values.update({BAUMGARTE_ALPHA: 0.0, BAUMGARTE_BETA: 0.0})
    return EquationsOfMotion(
        name=model.name, route=route, t=TIME, coordinates=tuple(coords), speeds=tuple(speeds),
        q=tuple(q), u=tuple(u), parameters=parameters, parameter_values=values,
        mass_matrix=None if M is None else _immutable(M), forcing=None if F is None else _immutable(F),
        kinematics=_immutable(K),
        kinetic_energy=T, potential_energy=V, points=tuple(points), inputs=r,
        measurements=tuple((name, to_plain(y, f"measurement {name!r}")) for name, y in model.measurements.items()),
        **constrained)
