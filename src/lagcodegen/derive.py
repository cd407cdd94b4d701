"""Stage: Model -> EquationsOfMotion.

Every derivation route returns the same target form, in generalized coordinates q (n) and
generalized speeds u (n)::

    qd = K(q, u, t)               kinematic equations (K = u for the Lagrange routes)
    M(q, t) ud = F(q, u, t)       dynamic equations; M symmetric positive definite

Lagrange II (energies route), with p = dT/du, never forming d/dt(dT/dqd) symbolically::

    M = d2T/du2 (the Hessian of T in the speeds)
    F = dT/dq - (dp/dq) u - dp/dt - dV/dq - dR/du + Q

d'Alembert-Lagrange (bodies route): with r(q, t) a mass centre, J = dr/dq its partial
velocities, a0 = (dv/dq) u + dv/dt the speed-dependent acceleration, and for a rigid body the
body-frame angular velocity w = Jw u + w_t, alpha0 = (dw/dq) u + dw/dt, inertia I::

    M = sum m J^T J + Jw^T I Jw
    F = sum J^T (f - m a0) + Jw^T (tau - I alpha0 - w x I w)

(Lurie, Analytical Mechanics, ch. 3; Kane & Levinson, Dynamics: Theory and Applications, ch. 4).
Terms shared by many bodies are grouped, so M_jk of a chain comes out as
(m_k + ... + m_n) * (...) rather than n separate products. The inertia part of F stays
nested, -J^T (sum of m_i a0_i over the bodies sharing a position term), so that CSE finds a
chain's prefix and suffix sums (O(n) per coordinate); terms that depend on t are expanded
instead, so that the sin^2 + cos^2 of a frame spun in time cancels and t drops out.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

from .model import TIME, Model, ModelError, ROUTE_BODIES, ROUTE_ENERGIES, check_declared
from .grouping import GroupedSum, components, sparse_diff
from .holonomic import BAUMGARTE_ALPHA, BAUMGARTE_BETA, holonomic_terms
from .quadratic import NotQuadratic, quadratic_terms

ROUTE_TITLES = {
    ROUTE_ENERGIES: "Lagrange II (energies)",
    ROUTE_BODIES: "d'Alembert-Lagrange (points and bodies)",
}


@dataclass(frozen=True)
class EquationsOfMotion:
    """``qd = K(q, u, t)``, ``M(q, t) ud = F(q, u, t)``, in plain symbols.

    Attributes
    ----------
    name, route : str
    t : Symbol
    coordinates, speeds : tuple
        The dynamicsymbols q_i(t) and generalized speeds (qd_i(t), or Kane's u_i(t)).
    q, u : tuple of Symbol, (n,)
        Plain symbols standing for ``coordinates`` and ``speeds`` in every expression below.
    parameters : tuple of Symbol
    parameter_values : dict Symbol -> float (defaults; may be partial)
    mass_matrix : ImmutableMatrix, (n, n), symmetric
    forcing : ImmutableMatrix, (n, 1)
    kinematics : ImmutableMatrix, (n, 1); qd = kinematics
    kinetic_energy, potential_energy : Expr or None
    points : tuple of (name, ImmutableMatrix (d, 1))
    constraints : ImmutableMatrix (m, 1)
        Holonomic constraints phi(q, t) = 0 (m = 0 without them). Then M ud = F - A^T lambda,
        A = dphi/dq, with A ud = ``constraint_bias`` (gamma, Baumgarte terms included; their
        parameters ``baumgarte_alpha``, ``baumgarte_beta`` default to 0); see `holonomic`.
    constraint_jacobian : ImmutableMatrix (m, n)
    constraint_rate : ImmutableMatrix (m, 1); dphi/dt
    constraint_bias : ImmutableMatrix (m, 1); gamma
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

    @property
    def m(self) -> int:
        """Number of holonomic constraints."""
        return self.constraints.rows

    @property
    def n(self) -> int:
        return len(self.q)

    @property
    def mass_matrix_full(self) -> sp.ImmutableMatrix:
        """(2n, 2n) block diag(I, M) of the first-order form in x = (q, u)."""
        n = self.n
        full = sp.zeros(2 * n, 2 * n)
        full[:n, :n] = sp.eye(n)
        full[n:, n:] = self.mass_matrix
        return sp.ImmutableMatrix(full)

    @property
    def forcing_full(self) -> sp.ImmutableMatrix:
        """(2n, 1) right-hand side (K; F) of the first-order form."""
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


def derive_equations(model: Model) -> EquationsOfMotion:
    """Derive `EquationsOfMotion` from a validated `Model`, by its route."""
    if model.route == ROUTE_ENERGIES:
        return _derive_from_energies(model)
    if model.route == ROUTE_BODIES:
        return _derive_from_bodies(model)
    from . import importers  # sympy-model route lives beside, not inside, the core routes

    return importers.derive_from_sympy(model)


# -- symbols ----------------------------------------------------------------------------------
def plain_symbols(coordinates, speeds, parameters) -> tuple[tuple, tuple]:
    """Plain Symbols for q_i(t) (same name) and their speeds (name + '_d', or Kane's u name)."""
    q = tuple(sp.Symbol(c.func.__name__) for c in coordinates)
    u = tuple(sp.Symbol(s.func.__name__ if isinstance(s, AppliedUndef) else s.expr.func.__name__ + "_d")
              for s in speeds)
    taken = {p.name: "parameter" for p in parameters}
    for sym in q + u:
        if sym.name in taken:
            raise ModelError(f"name {sym.name!r} is used by a {taken[sym.name]} and by a coordinate or speed")
        taken[sym.name] = "coordinate or speed"
    return q, u


def make_substitution(coordinates, speeds, q, u, what: str) -> Callable:
    """Return ``to_plain(expr)``: dynamicsymbols -> plain symbols, raising on leftovers."""
    table = dict(zip(speeds, u))  # Derivative(q(t), t) for the Lagrange routes, u(t) for Kane's
    table.update(zip(coordinates, q))

    def to_plain(expr, where: str = what):
        expr = sp.sympify(expr)
        out = expr.xreplace(table)
        left = [a for a in out.atoms(sp.Derivative, AppliedUndef)]
        if left:
            raise ModelError(f"{where} contains {', '.join(sorted(map(str, left)))}, which is not a "
                             f"coordinate or a speed of this model")
        return out
    return to_plain


# -- Lagrange II ------------------------------------------------------------------------------
def _lagrange_symbols(model: Model):
    """Coordinates, speeds qd, their plain symbols q, u and the substitution into them."""
    coords = model.coordinates
    # the same Derivative objects c.diff(t) builds, without the cost of evaluating them
    speeds = tuple(sp.Derivative(c, TIME, evaluate=False) for c in coords)
    q, u = plain_symbols(coords, speeds, model.parameters)
    return coords, speeds, q, u, make_substitution(coords, speeds, q, u, "model")


def _derive_from_energies(model: Model) -> EquationsOfMotion:
    coords, speeds, q, u, to_plain = _lagrange_symbols(model)
    T = to_plain(model.kinetic_energy, "kinetic energy")
    V = to_plain(model.potential_energy, "potential energy")
    R = to_plain(model.dissipation, "dissipation function")
    try:
        M, b, T0 = _quadratic_form(T, q, u, model.parameters)
        F = _lagrange_forcing(M, b, T0, q, u)
    except NotQuadratic:  # e.g. T written with speeds inside functions: differentiate it as a whole
        M, F = _hessian_form(T, q, u)
    _check_mass_matrix(M, coords, u)
    for j, c in enumerate(coords):
        Q = to_plain(model.generalized_forces.get(c, 0), f"generalized force on {c}")
        F[j] += -V.diff(q[j]) - R.diff(u[j]) + Q
    return _assemble(model, coords, speeds, q, u, M, F, sp.Matrix(u), T, V, to_plain)


def _quadratic_form(T, q, u, parameters):
    """M (n, n), b (n) and T0 of T = 1/2 u^T M u + b^T u + T0, with shared products grouped."""
    n = len(u)
    M_sum, b, T0 = GroupedSum(), [[] for _ in range(n)], []
    for key, weight, expr in quadratic_terms(T, u, parameters):
        number, weight = weight.as_coeff_Mul()
        if len(key) == 2:
            k, j = key  # k <= j; a c u_j^2 term gives M_jj = 2 c, a c u_j u_k term M_jk = c
            M_sum.add((j, k), weight, (2 if j == k else 1) * number * expr)
        elif len(key) == 1:
            b[key[0]].append(number * weight * expr)
        else:
            T0.append(number * weight * expr)
    M = sp.zeros(n, n)
    for j in range(n):
        for k in range(j + 1):
            M[j, k] = M[k, j] = M_sum.value((j, k))
    return M, [sp.Add(*terms) for terms in b], sp.Add(*T0)


def _lagrange_forcing(M, b, T0, q, u) -> sp.Matrix:
    """F_j = dT/dq_j - d/dt(dT/du_j) + M_j. ud, from M, b, T0 (Christoffel form)::

        F_j = sum_kl (1/2 dM_kl/dq_j - dM_jl/dq_k) u_k u_l + sum_k (db_k/dq_j - db_j/dq_k) u_k
              + dT0/dq_j - sum_l dM_jl/dt u_l - db_j/dt

    Each entry is differentiated once per variable it contains (the chain's M_kl: q_k, q_l).
    """
    n, t = len(q), TIME
    variables = list(q) + [t]

    def partials(expr) -> dict:
        symbols = expr.free_symbols
        return {x: sparse_diff(expr, x) for x in variables if x in symbols}

    dM = {(k, l): partials(M[k, l]) for k in range(n) for l in range(k + 1)}
    db, dT0 = [partials(bj) for bj in b], partials(T0)

    def dm(j, l, x):  # dM_jl/dx, M symmetric
        return dM[max(j, l), min(j, l)].get(x, sp.S.Zero)

    F = sp.zeros(n, 1)
    for j in range(n):
        terms = [dT0.get(q[j], 0), -db[j].get(t, 0)]
        for k in range(n):
            terms.append((db[k].get(q[j], 0) - db[j].get(q[k], 0)) * u[k])
            terms.append(-dm(j, k, t) * u[k])
            for l in range(k + 1):
                weight = u[k] * u[l]
                half = sp.Rational(1, 2) if k == l else sp.S.One  # M_kl and M_lk both count
                terms.append((half * dm(k, l, q[j]) - dm(j, l, q[k]) - (dm(j, k, q[l]) if k != l else 0)) * weight)
        F[j] = sp.Add(*terms)
    return F


def _hessian_form(T, q, u):
    """M = d2T/du2 and F = dT/dq - (dp/dq) u - dp/dt, p = dT/du: the general, slower route."""
    n, t = len(u), TIME
    p = [T.diff(uj) for uj in u]
    M = sp.zeros(n, n)
    for j in range(n):
        for k in range(j + 1):
            M[j, k] = M[k, j] = p[j].diff(u[k])
    F = sp.zeros(n, 1)
    for j in range(n):
        transport = sp.Add(*[p[j].diff(qk) * uk for qk, uk in zip(q, u)])
        F[j] = T.diff(q[j]) - transport - p[j].diff(t)
    return M, F


def _check_mass_matrix(M: sp.Matrix, coords, u) -> None:
    for j, c in enumerate(coords):
        if M[j, j] == 0:
            raise ModelError(
                f"coordinate {c.func.__name__!r} has no inertia: its speed does not appear in the kinetic "
                f"energy, so the mass matrix is singular (row {j})")
    speeds = set(u)
    for (j, k), entry in M.todok().items():
        if entry.free_symbols & speeds:
            raise ModelError(
                f"the kinetic energy is not quadratic in the speeds: M[{j},{k}] depends on "
                f"{', '.join(sorted(map(str, entry.free_symbols & speeds)))}")


# -- d'Alembert-Lagrange ----------------------------------------------------------------------
@dataclass(frozen=True)
class _TermMotion:
    """Kinematics of one additive term s(q, t) of a position component."""

    partials: dict   # k -> ds/dq_k (nonzero only)
    velocity: Any    # sum_k ds/dq_k u_k + ds/dt
    acceleration: Any  # speed-dependent part: sum_k dv/dq_k u_k + dv/dt


def _term_motion(term, q, u, t, cache: dict) -> _TermMotion:
    if term in cache:
        return cache[term]
    symbols = term.free_symbols
    partials = {k: sparse_diff(term, qk) for k, qk in enumerate(q) if qk in symbols}
    partials = {k: d for k, d in partials.items() if d != 0}
    v = sp.Add(*[d * u[k] for k, d in partials.items()], sparse_diff(term, t))
    v_symbols = v.free_symbols
    a0 = sp.Add(*[sparse_diff(v, qk) * u[k] for k, qk in enumerate(q) if qk in v_symbols], sparse_diff(v, t))
    cache[term] = motion = _TermMotion(partials, v, a0)
    return motion


def _derive_from_bodies(model: Model) -> EquationsOfMotion:
    """Translation by pairs of position terms shared between bodies; rotation body by body."""
    coords, speeds, q, u, to_plain = _lagrange_symbols(model)
    N, O, t, n = model.frame, model.origin, TIME, len(q)
    gravity = to_plain(components(model.gravity, N), "gravity") if model.gravity is not None else sp.zeros(3, 1)

    pair_mass: dict = {}   # ((component, s), (component, s')) -> masses of bodies holding both terms
    term_mass: dict = {}   # (component, s) -> masses of bodies holding s
    M_sum, F_sum = GroupedSum(), GroupedSum()
    T, body_terms = [], []
    for body in model.bodies:
        m = to_plain(body.mass, f"mass of {body.name}")
        r = to_plain(components(body.masscenter.pos_from(O), N), f"position of {body.name}")
        terms = [(c, s) for c in range(3) for s in sp.Add.make_args(r[c]) if s != 0]
        body_terms.append((m, terms))
        for a in terms:
            term_mass.setdefault(a, []).append(m)
            for b in terms:
                if a[0] == b[0]:
                    pair_mass.setdefault((a, b), []).append(m)
        if isinstance(body, me.RigidBody):
            _add_rotation(body, M_sum, F_sum, T, to_plain, N, q, u, t)

    motion: dict = {}
    V = []
    for (c, s), masses in term_mass.items():
        mass = sp.Add(*masses)
        if gravity[c] != 0:
            V.append(-mass * gravity[c] * s)
            for j, d in _term_motion(s, q, u, t, motion).partials.items():
                F_sum.add(j, mass, d * gravity[c])
    for ((_, s), (_, s2)), masses in pair_mass.items():
        mass = sp.Add(*masses)
        a, b = _term_motion(s, q, u, t, motion), _term_motion(s2, q, u, t, motion)
        for j, dj in a.partials.items():
            for k, dk in b.partials.items():
                if k <= j:
                    M_sum.add((j, k), mass, dj * dk)
    inertia = _inertia_forces(body_terms, motion, F_sum, q, u, t, n)
    T += [m * sp.Add(*[_square(v) for v in _velocity(terms, motion, q, u, t)]) / 2 for m, terms in body_terms]

    for load in model.loads:
        _add_load(load, F_sum, to_plain, N, O, q, u)

    M = sp.zeros(n, n)
    for j in range(n):
        for k in range(j + 1):
            M[j, k] = M[k, j] = M_sum.value((j, k))
    _check_mass_matrix(M, coords, u)
    Vx = to_plain(model.potential_energy, "potential energy")
    R = to_plain(model.dissipation, "dissipation function")
    F = sp.zeros(n, 1)
    for j, c in enumerate(coords):
        Q = to_plain(model.generalized_forces.get(c, 0), f"generalized force on {c}")
        F[j] = F_sum.value(j) + inertia[j] - Vx.diff(q[j]) - R.diff(u[j]) + Q
    return _assemble(model, coords, speeds, q, u, M, F, sp.Matrix(u), sp.Add(*T), sp.Add(Vx, *V), to_plain)


def _velocity(terms, motion, q, u, t) -> list:
    """Nonzero components of a mass centre's velocity, from its position terms."""
    parts: dict = {}
    for c, s in terms:
        parts.setdefault(c, []).append(_term_motion(s, q, u, t, motion).velocity)
    return [v for v in (sp.Add(*p) for p in parts.values()) if v != 0]


def _square(v):
    """v**2; a sum is squared unevaluated, as sympy would leave it, without its costly checks."""
    return sp.Pow(v, 2, evaluate=False) if v.is_Add else v ** 2


def _inertia_forces(body_terms, motion, F_sum, q, u, t, n) -> list:
    """Speed-dependent generalized inertia forces -sum_i m_i a0_i . dr_i/dq_j, kept nested.

    a0_i (the part of body i's acceleration not proportional to qdd) is summed once per body
    and weighted by its mass once per set of bodies sharing a position term, so a chain's
    Coriolis and centripetal terms cost O(n) sums per coordinate instead of a product per pair
    of position terms; CSE then shares the prefix and suffix sums.
    """
    acceleration = {}  # (component, body index) -> a0 component
    holders: dict = {}  # (component, term) -> body indices holding it
    for i, (_, terms) in enumerate(body_terms):
        for c, s in terms:
            acceleration.setdefault((c, i), []).append(_term_motion(s, q, u, t, motion).acceleration)
            holders.setdefault((c, s), []).append(i)
    acceleration = {key: sp.Add(*parts) for key, parts in acceleration.items()}
    weighted: dict = {}  # (component, bodies) -> sum of m_i a0_i
    forces = [[] for _ in range(n)]
    for (c, s), bodies in holders.items():
        if t in s.free_symbols or any(t in acceleration[(c, i)].free_symbols for i in bodies):
            # expanded, so that sin^2 + cos^2 of a frame spun in time merge and t drops out
            for j, d in _term_motion(s, q, u, t, motion).partials.items():
                for i in bodies:
                    F_sum.add(j, -body_terms[i][0], d * acceleration[(c, i)])
            continue
        key = (c, tuple(bodies))
        if key not in weighted:
            weighted[key] = sp.Add(*[body_terms[i][0] * acceleration[(c, i)] for i in bodies])
        if weighted[key] == 0:
            continue
        for j, d in _term_motion(s, q, u, t, motion).partials.items():
            forces[j].append(-d * weighted[key])
    return [sp.Add(*f) for f in forces]


def _add_rotation(body, M_sum, F_sum, T, to_plain, N, q, u, t) -> None:
    B = body.frame
    w = to_plain(components(B.ang_vel_in(N), B), f"angular velocity of {body.name}")
    I = to_plain(body.central_inertia.to_matrix(B), f"inertia of {body.name}")
    Jw = w.jacobian(u)
    alpha0 = w.jacobian(q) * sp.Matrix(u) + w.diff(t)
    Iw = I * w
    torque = -(I * alpha0 + w.cross(Iw))
    n = len(q)
    for j in range(n):
        IJ = I * Jw[:, j]
        for k in range(j + 1):
            M_sum.add_dot((j, k), 1, IJ, Jw[:, k])
        F_sum.add_dot(j, 1, Jw[:, j], torque)
    T.append((w.T * Iw)[0] / 2)


def _add_load(load, F_sum, to_plain, N, O, q, u) -> None:
    if load.is_torque:
        B = load.where
        w = to_plain(components(B.ang_vel_in(N), B), f"angular velocity of frame {B}")
        J = w.jacobian(u)
        f = to_plain(components(load.vector, B), f"torque on {B}")
    else:
        r = to_plain(components(load.where.pos_from(O), N), f"position of point {load.where}")
        J = r.jacobian(q)
        f = to_plain(components(load.vector, N), f"force on {load.where}")
    for j in range(len(q)):
        F_sum.add_dot(j, 1, J[:, j], f)


# -- shared tail ------------------------------------------------------------------------------
def _assemble(model, coords, speeds, q, u, M, F, K, T, V, to_plain) -> EquationsOfMotion:
    check_declared([("mass matrix", M), ("forcing", F)], model.parameters, (), extra=q + u)
    points = []
    for name, where in model.points.items():
        if isinstance(where, me.Point):
            pos = components(where.pos_from(model.origin), model.frame)
        else:
            pos = sp.Matrix(list(where) + [0] * (3 - len(where)))  # planar points get z = 0
        points.append((name, sp.ImmutableMatrix(to_plain(pos, f"point {name!r}"))))
    route = ROUTE_TITLES.get(model.route, model.route)
    parameters, values, constrained = tuple(model.parameters), dict(model.parameter_values), {}
    if model.constraints:
        if list(K) != list(u):
            raise ModelError("holonomic constraints need generalized speeds equal to the coordinate rates")
        phi = sp.Matrix([to_plain(c, f"constraint {i}") for i, c in enumerate(model.constraints)])
        terms = holonomic_terms(phi, q, u, TIME)
        constrained = {"constraints": sp.ImmutableMatrix(phi), "constraint_jacobian": terms["A"],
                       "constraint_rate": terms["phi_t"], "constraint_bias": terms["gamma"]}
        parameters += (BAUMGARTE_ALPHA, BAUMGARTE_BETA)
        values.update({BAUMGARTE_ALPHA: 0.0, BAUMGARTE_BETA: 0.0})
        route += " with holonomic constraints (Lagrange I)"
    return EquationsOfMotion(
        name=model.name, route=route, t=TIME, coordinates=tuple(coords), speeds=tuple(speeds),
        q=tuple(q), u=tuple(u), parameters=parameters, parameter_values=values,
        mass_matrix=sp.ImmutableMatrix(M), forcing=sp.ImmutableMatrix(F), kinematics=sp.ImmutableMatrix(K),
        kinetic_energy=T, potential_energy=V, points=tuple(points), **constrained)
