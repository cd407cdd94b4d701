"""Helper of the sympy route: Kane's unreduced equations of a KanesMethod's bodies and loads, written
for evaluation rather than display.

sympy's ``kanes_equations`` writes every entry of M and F as one expression in q and u: each
body's acceleration comes from differentiating its whole velocity expression, and the products
V_r . (m a) are multiplied out. Here the same equations are formed from shared terms:

- the velocities of the mass centres, the angular velocities, the load points' velocities and the
  velocity constraints are written once, in plain symbols, and CSE'd together;
- the partial velocities are their derivatives with respect to each speed, taken through those
  shared terms (the chain rule over the CSE's assignments);
- the part of each acceleration that does not hold ud is the forward-mode derivative of the same
  terms along (qd = K(q, u, t), ud = 0, dt = 1); the velocity constraints' rate comes the same way;
- each body's angular velocity is written in a frame where its central inertia is constant (E),
  and the inertia torque is I d/dt(w_E) + w_E x (I w); the mass centres' velocities in each body's
  E or all in one frame T, whichever shares best (fewest operations of the velocity terms after
  CSE), and a = d/dt(v_T) + w_T x v_T; d/dt(components) = (partial velocities) ud + (forward mode);
- M = sum m V_r . V_s + W_r . I W_s, F = sum V_r . (f - m a0) + W_r . (tau - I alpha0 - w_E x I w).

The results are full expressions again (the shared terms substituted back), so the kernels' CSE
finds the sharing: the Whipple bicycle's dynamics kernel takes 1441 operations after CSE and
`factor_sums` instead of 1971 from sympy's equations, and its RK4 step about 1.8x less time
(2026-11-26, measured at 1525 against 2189, before the factoring). A model this does
not write gets None, and the route keeps sympy's own equations: an acceleration set with
a2pt_theory or set_acc (sympy reads it as given); a mass or an inertia that changes with the state;
a direction cosine matrix that is a rotation only on a constraint (a quaternion's off |q| = 1, where
these components and sympy's dot products part); a velocity that reads an input; a frame with no
orientation to the inertial one; a load term sympy's expansion cancels and this one keeps.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

from ..model import ModelError
from ..walk import free_symbols_of
from .differentiation import derivative

__all__ = ["KaneTerms", "kane_terms", "dyadic_frames"]


@dataclass(frozen=True)
class KaneTerms:
    """M (n_u x n_u), F (n_u) of every speed independent, and the velocity constraints' rate
    w_q qd + w_t (one row per constraint; empty without constraints), in plain symbols."""

    mass_matrix: sp.Matrix
    forcing: sp.Matrix
    motion_rates: sp.Matrix


class _NotCovered(Exception):
    """A body, load or velocity this formulation does not write; sympy's own equations stay."""


def kane_terms(method: me.KanesMethod, kindiff: dict, to_plain, motion=(), inputs=(),
               known=None, inertias=None) -> KaneTerms | None:
    """The unreduced Kane equations of ``method``'s bodies and loads (see the module docstring),
    or None when a body, load or velocity is outside what this formulation writes.

    ``to_plain(expr, what)`` renames dynamicsymbols to the route's plain symbols (auxiliary speeds
    zero); ``motion`` are the velocity constraints A u + b in dynamicsymbols; ``inputs`` the plain
    input symbols (a velocity that reads one has a rate this cannot form). ``known``: the symbols
    the equations may hold (parameters, inputs, q, u, t); a load term that sympy's expanded
    equations cancel (a force along a direction no speed moves its point in) can survive here
    as a product that is zero only after simplification, and then sympy's equations are kept.
    ``inertias``: {body: (frame, the matrix of its central inertia there)} already formed."""
    try:
        terms = _Formulation(method, kindiff, to_plain, inputs, inertias or {}).equations(motion)
    except (_NotCovered, ModelError, ValueError, TypeError):  # sympy's own equations say what is wrong, if anything
        return None
    if known is not None:
        for matrix in (terms.mass_matrix, terms.forcing, terms.motion_rates):
            if free_symbols_of(matrix) - set(known):
                return None
    return terms


@dataclass
class _Body:
    mass: sp.Expr
    inertia: sp.Matrix | None  # central inertia in E; None for a particle
    velocity: slice  # rows of the shared velocity terms: the mass centre's v in T (3)
    translation_frame: slice | None  # w_T in T (3); None when T is the inertial frame
    omega: slice | None  # w in E (3)
    omega_frame: slice | None  # w_E in E (3)
    force: sp.Matrix  # resultant of the loads at the mass centre, in T
    torque: sp.Matrix  # resultant of the torques on the body's frame, in E


class _Formulation:
    def __init__(self, method, kindiff, to_plain, inputs, inertias):
        self.frame = method._inertial  # private: sympy 1.14 keeps the inertial frame only there
        self.kindiff = kindiff
        self.to_plain = to_plain
        self.inputs = set(inputs)
        self.method = method
        self.inertias = inertias
        self.rows: list = []  # velocity-level expressions, plain
        self.rotations: dict = {}  # frame -> its DCM to the inertial frame is a rotation everywhere
        self.random = np.random.default_rng(20261126)
        self.q = list(to_plain(sp.Matrix(list(method.q)), "coordinates"))
        self.u = list(to_plain(sp.Matrix(list(method.u)), "speeds"))
        self.state = set(self.q) | set(self.u) | {me.dynamicsymbols._t}

    def plain(self, vector, frame, what) -> list:
        if isinstance(vector, me.Vector):
            for other in {frame} | {f for _, f in vector.args}:
                self.check_rotation(other)
        try:
            components = vector.to_matrix(frame) if isinstance(vector, me.Vector) else sp.Matrix([0, 0, 0])
        except ValueError as error:  # no orientation path to the frame
            raise _NotCovered(str(error)) from None
        return list(self.to_plain(components.xreplace(self.kindiff), what))

    def check_rotation(self, frame) -> None:
        """Components change frames here where sympy's dot products may not: that is the same only
        while every direction cosine matrix is a rotation. A quaternion's (or a DCM given by the
        user) is one only on |q| = 1, and off it sympy's equations differ from these, so such a
        model keeps sympy's. Checked numerically at a point of random coordinates and parameters."""
        if frame in self.rotations:
            return
        try:
            dcm = frame.dcm(self.frame)
        except ValueError as error:  # no orientation path to the frame
            raise _NotCovered(str(error)) from None
        functions = sorted(me.find_dynamicsymbols(dcm), key=str)
        symbols = sorted(dcm.free_symbols, key=str)
        values = dict(zip(functions + symbols, self.random.uniform(-1.7, 1.7, len(functions) + len(symbols))))
        try:
            matrix = np.array(dcm.xreplace(values).evalf(), dtype=float)
        except TypeError:  # not a number at that point
            raise _NotCovered(f"the orientation of {frame} has no value at a sample point") from None
        self.rotations[frame] = bool(np.allclose(matrix @ matrix.T, np.eye(3), atol=1e-9))
        if not self.rotations[frame]:
            raise _NotCovered(f"the direction cosines of {frame} are a rotation only on a constraint")

    def add_rows(self, values) -> slice:
        start = len(self.rows)
        self.rows.extend(values)
        return slice(start, len(self.rows))

    def inertia_frame(self, body):
        """The frame the central inertia is written in (constant there), for a rigid body."""
        frames = dyadic_frames(body.central_inertia)
        if len(frames) > 1:
            raise _NotCovered(f"the inertia of {body} is written in several frames")
        return frames[0] if frames else body.frame

    def equations(self, motion) -> KaneTerms:
        method, N = self.method, self.frame
        entries = []  # (body, E, its inertia in E)
        for body in method.bodies:
            # sympy's Kane reads an acceleration set with a2pt_theory / set_acc / set_ang_acc as given,
            # which need not be the derivative of the velocity this differentiates
            if N in body.masscenter._acc_dict or (isinstance(body, me.RigidBody) and N in body.frame._ang_acc_dict):
                raise _NotCovered(f"the acceleration of {body} is set, not derived")
            if isinstance(body, me.RigidBody):
                E = self.inertia_frame(body)
                given = self.inertias.get(body)
                matrix = given[1] if given is not None and given[0] == E else body.central_inertia.to_matrix(E)
                inertia = self.to_plain(matrix, f"the inertia of {body}")
                if inertia.free_symbols & self.state:
                    raise _NotCovered(f"the inertia of {body} changes with the state")
                entries.append((body, E, inertia))
            else:
                entries.append((body, N, None))
        bodies = []  # (body, T, E, _Body)
        for (body, E, inertia), (T, velocity) in zip(entries, self.mass_centre_velocities(entries)):
            if inertia is not None:
                omega = self.add_rows(self.plain(body.frame.ang_vel_in(N), E, f"the angular velocity of {body}"))
                omega_frame = self.add_rows(self.plain(E.ang_vel_in(N), E, f"the angular velocity of {E}"))
            else:
                omega, omega_frame = None, None
            velocity = self.add_rows(velocity)
            translation_frame = None if T is N else self.add_rows(
                self.plain(T.ang_vel_in(N), T, f"the angular velocity of {T}"))
            mass = sp.sympify(self.to_plain(body.mass, f"the mass of {body}"))
            if mass.free_symbols & self.state:  # sympy's Kane adds m' v for it
                raise _NotCovered(f"the mass of {body} changes with the state or time")
            bodies.append((body, T, E, _Body(mass, inertia, velocity, translation_frame, omega, omega_frame,
                                             sp.zeros(3, 1), sp.zeros(3, 1))))
        loose = []  # loads not at a mass centre or on a body's frame: (rows of the point or frame's velocity, vector)
        for point_or_frame, vector in method.loads or ():
            if isinstance(point_or_frame, me.Point):
                owner = next(((T, b) for body, T, _, b in bodies if body.masscenter is point_or_frame), None)
                frame = owner[0] if owner else N
                force = sp.Matrix(self.plain(vector, frame, f"the force at {point_or_frame}"))
                if owner:
                    owner[1].force += force
                else:
                    rows = self.add_rows(self.plain(point_or_frame.vel(N), N, f"the velocity of {point_or_frame}"))
                    loose.append((rows, force))
            else:
                owner = next(((E, b) for body, _, E, b in bodies
                              if isinstance(body, me.RigidBody) and body.frame is point_or_frame), None)
                frame = owner[0] if owner else point_or_frame
                torque = sp.Matrix(self.plain(vector, frame, f"the torque on {point_or_frame}"))
                if owner:
                    owner[1].torque += torque
                else:
                    rows = self.add_rows(self.plain(point_or_frame.ang_vel_in(N), frame,
                                                    f"the angular velocity of {point_or_frame}"))
                    loose.append((rows, torque))
        constraints = self.add_rows([self.to_plain(w, f"velocity constraint {i}") for i, w in enumerate(motion)])
        return self.assemble([b for *_, b in bodies], loose, constraints)

    def mass_centre_velocities(self, entries) -> list:
        """(T, the mass centre's velocity in T) per body: each in the frame of its inertia (E), or all
        in one body's frame or inertia frame, whichever CSEs to the fewest operations (a frame with
        no orientation to the inertial one is skipped). The Whipple bicycle's kernel took 1548
        operations with every velocity in the frame of its rear body, 1677 in each body's E (before
        `factor_sums`)."""
        N = self.frame
        options = [[(E, body.masscenter.vel(N)) for body, E, _ in entries]]
        common = {E for _, E, _ in entries} | {body.frame for body, _, inertia in entries if inertia is not None}
        if len(common) > 1:
            options += [[(T, body.masscenter.vel(N)) for body, _, _ in entries] for T in sorted(common, key=str)]
        best, fewest = None, None
        for i, option in enumerate(options):
            try:
                rows = [(T, self.plain(v, T, f"the velocity of {body.masscenter}"))
                        for (T, v), (body, _, _) in zip(option, entries)]
            except _NotCovered:
                if i == 0:  # in each body's own E: a velocity this cannot write
                    raise
                continue  # a common frame with no orientation to the inertial one
            assignments, reduced = sp.cse(self.rows + [c for _, velocity in rows for c in velocity], order="canonical")
            ops = sum(sp.count_ops(e) for e in [v for _, v in assignments] + reduced)
            if fewest is None or ops < fewest:
                best, fewest = rows, ops
        return best

    def assemble(self, bodies, loose, constraints) -> KaneTerms:
        method, t, q, u = self.method, me.dynamicsymbols._t, self.q, self.u
        qd = list(self.to_plain(sp.Matrix([self.kindiff[c.diff(t)] for c in method.q]), "kinematic equations"))
        for i, row in enumerate(self.rows):
            if row.free_symbols & self.inputs:
                raise _NotCovered(f"velocity term {i} reads an input")
        assignments, reduced = sp.cse(self.rows, symbols=sp.numbered_symbols("kv", cls=sp.Dummy), order="canonical")
        definitions = dict(assignments)
        qd_symbols = [sp.Dummy(f"{c}_rate") for c in q]
        seeds = dict(zip(q, qd_symbols)) | {t: sp.S.One}
        rates: dict = {}  # assigned symbol -> symbol of its rate (absent: zero)
        derivatives: dict = {}  # derivative's memo
        rate_assignments = []

        def rate(expr):
            terms = []
            for s in expr.free_symbols:
                seed = seeds.get(s, rates.get(s))
                if seed is not None:
                    terms.append(derivative(expr, s, derivatives) * seed)
            return sp.Add(*terms)

        for symbol, expr in assignments:
            value = rate(expr)
            if value != 0:
                rates[symbol] = sp.Dummy(f"{symbol}_rate")
                rate_assignments.append((rates[symbol], value))
        partials: dict = {}  # (assigned symbol, speed) -> symbol or 0
        partial_assignments = []

        def partial(expr, speed):
            terms = []
            for s in expr.free_symbols:
                if s == speed:
                    terms.append(derivative(expr, s, derivatives))
                elif s in definitions:
                    inner = partial_of(s, speed)
                    if inner != 0:
                        terms.append(derivative(expr, s, derivatives) * inner)
            return sp.Add(*terms)

        def partial_of(symbol, speed):
            key = (symbol, speed)
            if key not in partials:
                value = partial(definitions[symbol], speed)
                partials[key] = 0 if value == 0 else sp.Dummy(f"{symbol}_{speed}")
                if value != 0:
                    partial_assignments.append((partials[key], value))
            return partials[key]

        def block(rows):
            return sp.Matrix(reduced[rows])

        def rate_block(rows):
            return sp.Matrix([rate(e) for e in reduced[rows]])

        def partials_block(rows):
            return [sp.Matrix([partial(e, s) for e in reduced[rows]]) for s in u]

        n = len(u)
        M, F = sp.zeros(n, n), sp.zeros(n, 1)
        for body in bodies:
            V = partials_block(body.velocity)
            v = block(body.velocity)
            a0 = rate_block(body.velocity)
            if body.translation_frame is not None:
                a0 += _cross(block(body.translation_frame), v)
            if body.omega is not None:
                w, w_frame = block(body.omega), block(body.omega_frame)
                W = partials_block(body.omega)
                I = body.inertia
                IW = [_product(I, W_s) for W_s in W]
                torque = body.torque - _product(I, rate_block(body.omega)) - _cross(w_frame, _product(I, w))
            force = body.force - body.mass * a0
            for r in range(n):
                for s in range(r, n):
                    entry = body.mass * _dot(V[r], V[s])
                    if body.omega is not None:
                        entry += _dot(W[r], IW[s])
                    M[r, s] += entry
                    if s != r:
                        M[s, r] += entry
                F[r] += _dot(V[r], force)
                if body.omega is not None:
                    F[r] += _dot(W[r], torque)
        for rows, vector in loose:
            for r, V_r in enumerate(partials_block(rows)):
                F[r] += _dot(V_r, vector)
        motion_rates = rate_block(constraints)
        full: dict = dict(zip(qd_symbols, qd))
        for symbol, expr in assignments + partial_assignments + rate_assignments:
            full[symbol] = expr.xreplace(full)
        return KaneTerms(mass_matrix=M.xreplace(full), forcing=F.xreplace(full),
                         motion_rates=motion_rates.xreplace(full))


def _times(a, b):
    """a * b, 0 without forming it when either is 0: sympy's 0 * expr asks whether expr is finite
    (0 * oo is nan), a walk over the whole expression (half the time of forming the Whipple
    bicycle's M and F went there). The expressions here are finite, so the result is sympy's."""
    return sp.S.Zero if a == 0 or b == 0 else a * b


def _dot(a, b):
    """a . b of two column matrices (Matrix.dot, by `_times`)."""
    return sp.Add(*[_times(x, y) for x, y in zip(a, b)])


def _product(A, b) -> sp.Matrix:
    """A b of a matrix and a column matrix (A * b, by `_times`)."""
    return sp.Matrix([_dot(A.row(i), b) for i in range(A.rows)])


def _cross(a, b) -> sp.Matrix:
    """a x b of two 3-vectors as column matrices (Matrix.cross, by `_times`)."""
    return sp.Matrix([_times(a[1], b[2]) - _times(a[2], b[1]), _times(a[2], b[0]) - _times(a[0], b[2]),
                      _times(a[0], b[1]) - _times(a[1], b[0])])


def dyadic_frames(dyadic) -> list:
    """The frames a dyadic's terms are written in (sorted by name; empty for a zero dyadic)."""
    return sorted({vector.args[0][1] for term in dyadic.args for vector in term[1:] if vector.args}, key=str)
