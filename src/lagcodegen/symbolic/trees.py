"""Route: a kinematic tree (Model.tree) -> EquationsOfMotion, in closed form or recursively.

Which formulation suits a tree depends on its size: M(q) and F(q, u) in closed form cost about
n^2 to n^3 operations per evaluation and a compile time that grows faster still, while the
articulated-body algorithm (Featherstone, Rigid Body Dynamics Algorithms, 2008, table 7.1) costs
a fixed number of operations per link. `choose_formulation` estimates both and picks the cheaper
one unless ``Model.formulation`` names one; the choice and its figures travel with the
equations (``EquationsOfMotion.formulation``) into the compile report and the C header.

Closed form: the tree becomes sympy frames, points and bodies (`bodies_model`) for the points and
bodies route. Recursive: the three passes of the algorithm are written out link by link as
scalar assignments (Robotran's symbolic recursion: Samin and Fisette, Symbolic modeling of
multibody systems, 2003), with every product by a structural zero dropped as it is formed, so a
planar chain keeps only its planar terms and a joint axis along z its one column. The
assignments and what each output reads from them are a `TreeKernels`.

Spatial vectors follow Featherstone: motion [w; v], force [n; f], in link coordinates at the
link frame's origin. Gravity enters as the base accelerating against it, a_0 = [0; -g].
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import sympy as sp
import sympy.physics.mechanics as me

from ..model import Model, ModelError
from ..tree import joint_map, three_entries
from .equations import EquationsOfMotion, assemble, lagrange_symbols

# The cost model of `choose_formulation`: operations after CSE per evaluation of the dynamics, fitted
# to the counts of `reduce_expressions(eom, ["rhs"] (or ["rhs", "jacobian"]), {})` for
# pendulum_chain(n, route="tree") and spherical_chain(n) in each formulation (sympy 1.14, 2026-11-25;
# `python tools/tree_costs.py --spherical 1,2 --steps` prints them again):
#   planar chain, n =        2     4     6     8     12    16
#     closed dynamics       49   116   200   300   548   860     ~ 3.4 n^2
#     closed jacobian      119   412   863  1470  3096  5338     ~ 21 n^2 (its reduce: 0.9 s at n = 6,
#                                                                 5.7 s at 12, 14.5 s at 16)
#     recursive dynamics    94   359   632   909  1475  2057     ~ 128 n
#   spherical chain, 3 and 6 joints: closed 298 and 9452 (~ 1.2 n^5), recursive 132 and 717
# The closed form also solves M ud = F by an unrolled LDL^T: about n^3 / 3 operations. RK4 steps
# measured with them (ns; closed / recursive): n = 5 412 / 889, 8 897 / 1434, 12 1804 / 2363,
# 16 3509 / 4110, 20 9217 / 3486: the estimates cross where the step times do (n ~ 17).
PLANAR_CLOSED_OPS_PER_ENTRY = 3.4     # times n^2
SPATIAL_CLOSED_OPS = 1.2              # times n^5: a 3D tree's closed-form entries nest rotations
RECURSIVE_OPS_PER_LINK = 128
CLOSED_JACOBIAN_FACTOR = 6            # the closed form's symbolic Jacobian against its dynamics
#: with implicit methods the closed form also needs its symbolic Jacobian, whose CSE and build grow
#: superlinearly (default methods, cold compile_model of the planar chain: closed 2.2 s at n = 5,
#: 4.3 s at 8, 10.3 s at 12, 24 s at 16; recursive 0.85, 1.14, 1.46, 2.18 s); above this estimate
#: the recursive kernel (whose Jacobian is central differences of the compiled rhs) is chosen
CLOSED_JACOBIAN_BUDGET = 600


def planar(model: Model) -> bool:
    """True when every revolute joint of the tree turns about the same axis (a planar tree)."""
    axes = {tuple(float(c) for c in link.axis) for link in model.tree if link.joint == "revolute"}
    return len(axes) <= 1


@dataclass(frozen=True)
class TreeKernels:
    """The recursive formulation's straight-line code: ``assignments`` (Symbol, Expr) in order, each
    reading the state, parameters, inputs and earlier assignments; the outputs read them.

    Attributes
    ----------
    accelerations : tuple of Expr, (n,)
        ud, the generalized accelerations (of the model's coordinates).
    pivots : tuple of Expr, (n,)
        The articulated-body pivots D_i = S_i^T I^A_i S_i (the LDL^T pivots of M in joint
        variables): zero when the tree is singular at the state (a massless end of the tree).
    pivot_scales : tuple of Expr, (n,)
        The trace of the block of I^A_i that D_i reads (angular for a revolute joint, linear for a
        prismatic one): D_i <= it, so a D_i below `PIVOT_ROUNDING` of it is rounding of a zero (a
        mass on the joint's axis given through runtime parameters), not a pivot.
    energy : Expr
        T + V.
    points : tuple of (name, (x, y, z))
    angles : tuple of bool, (n,)
        Coordinate j moves revolute joints only: the dynamics vary with it on a scale of a radian
        whatever its value (the difference Jacobian's step, `outputs._difference_jacobian_c`).
    """

    assignments: tuple
    accelerations: tuple
    pivots: tuple
    energy: object
    points: tuple
    angles: tuple = ()
    pivot_scales: tuple = ()


@dataclass(frozen=True)
class FormulationChoice:
    name: str           # "closed" or "recursive"
    closed_ops: int     # estimated operations per evaluation of ud, closed form with its solve
    recursive_ops: int  # the same for the recursive kernel
    reason: str

    def report(self) -> str:
        return (f"{self.name} ({self.reason}; estimated operations per evaluation: "
                f"closed form {self.closed_ops}, recursive {self.recursive_ops})")


def choose_formulation(model: Model, implicit: bool = True) -> FormulationChoice:
    """The formulation of ``model``'s tree: as Model.formulation says, else the cheaper estimate.

    Estimates (module constants, fitted to measured counts): the closed form's K, M and F grow like
    n^2 for a planar tree and much faster for a 3D one, plus n^3 / 3 for its LDL^T solve; the
    recursive kernel costs a fixed number per link. With ``implicit`` (the methods need the
    Jacobian; the default methods do) a closed form whose symbolic Jacobian would exceed
    CLOSED_JACOBIAN_BUDGET operations is not chosen: its CSE and build dominate the compile."""
    n = len(model.tree)
    entries = PLANAR_CLOSED_OPS_PER_ENTRY * n ** 2 if planar(model) else SPATIAL_CLOSED_OPS * n ** 5
    closed = int(entries + n ** 3 / 3)
    recursive = RECURSIVE_OPS_PER_LINK * n
    if model.formulation in ("closed", "recursive"):
        return FormulationChoice(model.formulation, closed, recursive, "as the model asks")
    if recursive < closed:
        return FormulationChoice("recursive", closed, recursive, f"chosen by cost for {n} links")
    if implicit and CLOSED_JACOBIAN_FACTOR * entries > CLOSED_JACOBIAN_BUDGET:
        return FormulationChoice("recursive", closed, recursive,
                                 f"chosen for {n} links: the closed form's Jacobian (implicit methods) "
                                 f"would take ~{int(CLOSED_JACOBIAN_FACTOR * entries)} operations")
    return FormulationChoice("closed", closed, recursive, f"chosen by cost for {n} links")


def derive_from_tree(model: Model, implicit: bool = True) -> EquationsOfMotion:
    """The equations of ``model``'s tree in the formulation `choose_formulation` picks (``implicit``:
    whether the kernels will need the Jacobian; compile_model knows, derive_equations assumes so)."""
    choice = choose_formulation(model, implicit)
    if choice.name == "closed":
        eom = _derive_bodies(bodies_model(model))
        return replace(eom, route=f"kinematic tree ({len(model.tree)} links), closed form",
                       formulation=choice.report())
    return derive_recursive(model, choice)


def _derive_bodies(model: Model) -> EquationsOfMotion:
    from .bodies import derive_from_bodies

    return derive_from_bodies(model)


# -- closed form: the tree as sympy bodies ---------------------------------------------------------
def bodies_model(model: Model) -> Model:
    """The same system on the points and bodies route: a frame and a body per link."""
    N, O = me.ReferenceFrame("N"), me.Point("O")
    frames, origins, bodies, points = {None: N}, {None: O}, [], {}
    # (axis, angle) when a link's frame is the ground's turned about one fixed axis (a planar
    # tree): its frame is then oriented from the ground by the summed angle, so that positions
    # read l sin(q2) rather than nested turns l sin(q1) cos(q2 - q1) + ... (absolute angles sum
    # to one coordinate); None once the turns are about different axes
    turned = {None: (None, sp.S.Zero)}
    for link in model.tree:
        parent_frame, parent_origin = frames[link.parent], origins[link.parent]
        axis = _vector(link.axis, parent_frame)
        joint = parent_origin.locatenew(f"{link.name}_joint", _vector(link.offset, parent_frame))
        frame = me.ReferenceFrame(f"{link.name}_frame")
        about = turned.get(link.parent)
        if link.joint == "revolute":
            if about is not None and about[0] in (None, link.axis):
                turned[link.name] = (link.axis, about[1] + link.variable)
                frame.orient_axis(N, _vector(link.axis, N), turned[link.name][1])
            else:
                turned[link.name] = None
                frame.orient_axis(parent_frame, axis, link.variable)
            origin = joint
        else:
            turned[link.name] = about
            frame.orient_axis(parent_frame, axis, 0)
            origin = joint.locatenew(f"{link.name}_origin", link.variable * axis)
        frames[link.name], origins[link.name] = frame, origin
        center = origin.locatenew(f"{link.name}_center", _vector(link.center, frame))
        Ixx, Iyy, Izz, Ixy, Iyz, Izx = link.inertia
        if any(i != 0 for i in link.inertia):
            inertia = me.inertia(frame, Ixx, Iyy, Izz, Ixy, Iyz, Izx)
            bodies.append(me.RigidBody(link.name, center, frame, link.mass, (inertia, center)))
        elif link.mass != 0:
            bodies.append(me.Particle(link.name, center, link.mass))
        for name, xyz in link.points.items():
            points[name] = origin.locatenew(name, _vector(xyz, frame))
    if not bodies:  # found by review: the bodies route's own message blamed Model(bodies=...) and energies
        raise ModelError(f"model {model.name!r}: no link of its tree has a mass or an inertia, so it has no kinetic "
                         "energy and no joint's acceleration is determined; give its links masses")
    gravity = _vector(three_entries(model.gravity), N) if model.gravity is not None else None
    return Model(model.name, model.coordinates, model.parameters, potential_energy=model.potential_energy,
                 generalized_forces=model.generalized_forces, dissipation=model.dissipation, bodies=bodies,
                 gravity=gravity, frame=N, origin=O, points=points, parameter_values=model.parameter_values,
                 inputs=model.inputs, measurements=model.measurements, links=model.links)


def _vector(xyz, frame) -> me.Vector:
    return xyz[0] * frame.x + xyz[1] * frame.y + xyz[2] * frame.z


# -- recursive: the articulated-body algorithm written out ------------------------------------------

#: a numeric articulated pivot below this fraction of the largest numeric entry of the link's
#: articulated inertia is float rounding of an exact zero (the mass on the axis, given as floats)
PIVOT_ROUNDING = 1e-12


def _rounding_zero(pivot, inertia) -> bool:
    """True for a pivot that is a number at rounding level of the articulated inertia's entries."""
    if not pivot.is_Number:
        return False
    entries = [abs(float(e)) for row in inertia for e in row if sp.sympify(e).is_Number]
    return bool(entries) and abs(float(pivot)) <= PIVOT_ROUNDING * max(entries)

class _Recorder:
    """Named scalar assignments; an expression that is already a symbol, a number or a negated
    symbol is used in place (no assignment)."""

    def __init__(self, taken):
        self.assignments: list = []
        self.taken = set(taken)

    def bind(self, expr, name: str):
        expr = sp.sympify(expr)
        if expr.is_Atom or (expr.is_Mul and len(expr.args) == 2 and expr.args[0] == -1 and expr.args[1].is_Atom):
            return expr
        while name in self.taken:
            name += "_"
        self.taken.add(name)
        symbol = sp.Symbol(name)
        self.assignments.append((symbol, expr))
        return symbol

    def vector(self, values, name: str, labels: str) -> list:
        return [self.bind(v, f"{name}_{label}") for v, label in zip(values, labels)]

    def matrix(self, rows, name: str) -> list:
        return [[self.bind(e, f"{name}_{i}{j}") for j, e in enumerate(row)] for i, row in enumerate(rows)]

    def symmetric(self, rows, name: str) -> list:
        """Bind the lower triangle of a symmetric matrix, mirrored."""
        size = len(rows)
        bound = [[None] * size for _ in range(size)]
        for j in range(size):
            for k in range(j + 1):
                bound[j][k] = bound[k][j] = self.bind(rows[j][k], f"{name}_{j}{k}")
        return bound


# Small dense algebra on lists (rows of sympy expressions), skipping structural zeros: sympy's
# Matrix products go through its polynomial domains and cost several times more here.
def _dot(a, b):
    return sp.Add(*[x * y for x, y in zip(a, b) if x != 0 and y != 0])


def _mm(A, B):
    columns = list(zip(*B))
    return [[_dot(row, col) for col in columns] for row in A]


def _mv(A, x):
    return [_dot(row, x) for row in A]


def _tr(A):
    return [list(col) for col in zip(*A)]


def _add(A, B):
    return [[x + y for x, y in zip(ra, rb)] for ra, rb in zip(A, B)]


def _vadd(a, b):
    return [x + y for x, y in zip(a, b)]


def _vsub(a, b):
    return [x - y for x, y in zip(a, b)]


def _cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _skew(r):
    return [[0, -r[2], r[1]], [r[2], 0, -r[0]], [-r[1], r[0], 0]]


def _rotation(axis, c, s):
    """Columns: the child's axes in the parent's frame, a turn about unit ``axis`` (Rodrigues)."""
    a, ax = list(axis), _skew(axis)
    return [[(c if i == j else 0) + s * ax[i][j] + (1 - c) * a[i] * a[j] for j in range(3)] for i in range(3)]


def _blocks(A, B, C):
    """[[A, B], [B^T, C]] as 6 rows."""
    Bt = _tr(B)
    return [A[i] + B[i] for i in range(3)] + [Bt[i] + C[i] for i in range(3)]


def _spatial_inertia(link):
    """[[Ic + m cx cx^T, m cx], [m cx^T, m 1]] at the link frame's origin (Featherstone (2.63))."""
    Ixx, Iyy, Izz, Ixy, Iyz, Izx = link.inertia
    Ic = [[Ixx, Ixy, Izx], [Ixy, Iyy, Iyz], [Izx, Iyz, Izz]]
    cx, m = _skew(link.center), link.mass
    upper = _add(Ic, [[m * e for e in row] for row in _mm(cx, _tr(cx))])
    mass = [[m if i == j else 0 for j in range(3)] for i in range(3)]
    return _blocks(upper, [[m * e for e in row] for row in cx], mass)


def _cross_motion(v, w):
    """v x w for motion vectors [w; v]."""
    return _cross(v[:3], w[:3]) + _vadd(_cross(v[:3], w[3:]), _cross(v[3:], w[:3]))


def _cross_force(v, f):
    """v x* f for a force vector f = [n; f]."""
    return _vadd(_cross(v[:3], f[:3]), _cross(v[3:], f[3:])) + _cross(v[:3], f[3:])


@dataclass
class _Joint:
    """One link's joint transform: E (parent to link coordinates), r (link origin in the parent's
    frame) and the motion subspace S (6 numbers)."""

    E: list
    r: list
    S: list

    def motion(self, v) -> list:
        """X v: a parent's motion vector in link coordinates."""
        omega = v[:3]
        return _mv(self.E, omega) + _mv(self.E, _vsub(v[3:], _cross(self.r, omega)))

    def force_to_parent(self, f) -> list:
        """X^T f: a link's force vector in parent coordinates."""
        Et = _tr(self.E)
        lin = _mv(Et, f[3:])
        return _vadd(_mv(Et, f[:3]), _cross(self.r, lin)) + lin

    def inertia_to_parent(self, I, rec: _Recorder, name: str) -> list:
        """X^T I X in blocks: rotate (each block named, so that products of sums do not grow),
        then shift by r (Featherstone (2.66))."""
        E, Et, rx = self.E, _tr(self.E), _skew(self.r)
        A, B, C = [row[:3] for row in I[:3]], [row[3:] for row in I[:3]], [row[3:] for row in I[3:]]
        A1 = rec.symmetric(_mm(Et, _mm(A, E)), f"{name}A")
        C1 = rec.symmetric(_mm(Et, _mm(C, E)), f"{name}C")
        B1 = rec.matrix(_mm(Et, _mm(B, E)), f"{name}B")
        B2 = _add(B1, _mm(rx, C1))
        A2 = _add(_add(A1, _mm(rx, _tr(B1))), [[-e for e in row] for row in _add(_mm(B1, rx), _mm(_mm(rx, C1), rx))])
        return _blocks(A2, B2, C1)


def derive_recursive(model: Model, choice: FormulationChoice | None = None) -> EquationsOfMotion:
    """EquationsOfMotion whose dynamics, energy and points are `TreeKernels` (no closed-form M, F)."""
    coords, speeds, q, u, to_plain = lagrange_symbols(model)
    links, n = model.tree, len(model.tree)
    P = joint_map(links, coords)
    theta = [to_plain(link.variable, f"joint variable of link {link.name!r}") for link in links]
    theta_d = [sp.Add(*[P[i, j] * u[j] for j in range(n) if P[i, j] != 0]) for i in range(n)]
    gravity = [to_plain(g, "gravity") for g in three_entries(model.gravity)] if model.gravity is not None \
        else [0, 0, 0]
    taken = {s.name for s in (*q, *u, *model.parameters)} | {str(r) for r in model.inputs}
    rec = _Recorder(taken)
    index = {link.name: i for i, link in enumerate(links)}
    parent = [None if link.parent is None else index[link.parent] for link in links]
    spatial = ("wx", "wy", "wz", "vx", "vy", "vz")
    forces = ("nx", "ny", "nz", "fx", "fy", "fz")

    # generalized forces of the coordinates, then of the joint variables: P^T tau = Q
    V = to_plain(model.potential_energy, "potential energy")
    R = to_plain(model.dissipation, "dissipation function")
    Q = [to_plain(model.generalized_forces.get(c, 0), f"generalized force on {c}") - V.diff(q[j]) - R.diff(u[j])
         for j, c in enumerate(coords)]
    Q = [rec.bind(Qj, f"Q_{j}") for j, Qj in enumerate(Q)]
    tau = [rec.bind(t, f"tau_{i}") for i, t in enumerate(_solve_transposed(P, Q))]

    # pass 1: velocities, bias accelerations and forces, link by link from the ground
    joints, v, c, pA, IA = [], [], [], [], []
    for i, link in enumerate(links):
        qi = rec.bind(theta[i], f"theta_{i}")
        qdi = rec.bind(theta_d[i], f"theta_d_{i}")
        axis = list(link.axis)
        offset = [to_plain(o, f"offset of link {link.name!r}") for o in link.offset]
        if link.joint == "revolute":
            cos_i, sin_i = rec.bind(sp.cos(qi), f"c_{i}"), rec.bind(sp.sin(qi), f"s_{i}")
            joint = _Joint(_tr(_rotation(axis, cos_i, sin_i)), offset, axis + [0, 0, 0])
        else:
            identity = [[1 if a == b else 0 for b in range(3)] for a in range(3)]
            joint = _Joint(identity, [o + qi * a for o, a in zip(offset, axis)], [0, 0, 0] + axis)
        joints.append(joint)
        relative = [e * qdi for e in joint.S]
        vi = relative if parent[i] is None else _vadd(joint.motion(v[parent[i]]), relative)
        vi = rec.vector(vi, f"v{i}", spatial)
        v.append(vi)
        c.append(rec.vector(_cross_motion(vi, relative), f"c{i}", spatial))
        I = _spatial_inertia(_plain_link(link, to_plain))
        pA.append(_cross_force(vi, _mv(I, vi)))
        IA.append(I)

    # pass 2: articulated inertias and bias forces, from the leaves to the ground
    U, D, u_, D_inverse, D_scale = [None] * n, [None] * n, [None] * n, [None] * n, [None] * n
    for i in reversed(range(n)):
        Ii = rec.symmetric(IA[i], f"IA{i}")
        pi = rec.vector(pA[i], f"pA{i}", forces)
        S = joints[i].S
        U[i] = rec.vector(_mv(Ii, S), f"U{i}", "012345")
        D[i] = rec.bind(_dot(S, U[i]), f"D_{i}")
        if D[i] == 0 or _rounding_zero(D[i], IA[i]):
            # 1 / D would print as zoo (or, from float data, 1 / 1.7e-17 as a huge finite pivot found by
            # review): refused as the closed form refuses a speed without inertia
            raise ModelError(f"model {model.name!r}: link {links[i].name!r} (joint variable {theta[i]}) has no "
                             "inertia: the articulated inertia about its joint's axis is zero (it and the links it "
                             "carries have no mass, or their mass lies on that axis and no inertia about it), so its "
                             "joint's acceleration is not determined; give it a mass or an inertia about its axis")
        blocks = [k for k in range(6) if any(S[b] != 0 for b in range(3 * (k // 3), 3 * (k // 3) + 3))]
        D_scale[i] = rec.bind(sp.Add(*(Ii[k][k] for k in blocks)), f"Dscale_{i}")
        u_[i] = rec.bind(tau[i] - _dot(S, pi), f"u_{i}")
        Dinv = rec.bind(1 / D[i], f"Dinv_{i}")
        D_inverse[i] = Dinv
        if parent[i] is None:
            continue
        Ia = [[Ii[a][b] - U[i][a] * U[i][b] * Dinv for b in range(6)] for a in range(6)]
        axis = [k for k in range(6) if S[k] != 0]
        if len(axis) == 1:  # Ia S = 0 exactly: with S along a coordinate axis, its row and column vanish
            for k in range(6):
                Ia[axis[0]][k] = Ia[k][axis[0]] = sp.S.Zero
        Ia = rec.symmetric(Ia, f"Ia{i}")
        scaled = rec.bind(u_[i] * Dinv, f"uD_{i}")
        pa = rec.vector(_vadd(_vadd(pi, _mv(Ia, c[i])), [e * scaled for e in U[i]]), f"pa{i}", forces)
        j = parent[i]
        IA[j] = _add(IA[j], joints[i].inertia_to_parent(Ia, rec, f"XIa{i}"))
        pA[j] = _vadd(pA[j], joints[i].force_to_parent(pa))

    # pass 3: accelerations from the ground to the leaves
    a = [None] * n
    theta_dd = [None] * n
    base = [0, 0, 0] + [-g for g in gravity]
    for i in range(n):
        a_in = _vadd(joints[i].motion(base if parent[i] is None else a[parent[i]]), c[i])
        a_in = rec.vector(a_in, f"a{i}_in", spatial)
        theta_dd[i] = rec.bind((u_[i] - _dot(U[i], a_in)) * D_inverse[i], f"theta_dd_{i}")
        a[i] = rec.vector(_vadd(a_in, [e * theta_dd[i] for e in joints[i].S]), f"a{i}", spatial)
    accelerations = tuple(rec.bind(e, f"qdd_{j}") for j, e in enumerate(_solve(P, theta_dd)))

    energy, points = _energy_and_points(model, links, parent, joints, v, gravity, V, rec, to_plain)
    angles = tuple(all(links[i].joint == "revolute" for i in range(n) if P[i, j] != 0) for j in range(n))
    kernels = TreeKernels(assignments=tuple(rec.assignments), accelerations=accelerations, pivots=tuple(D),
                          pivot_scales=tuple(D_scale),
                          energy=energy, points=points, angles=angles)
    eom = assemble(model, coords, speeds, q, u, None, None, sp.ImmutableMatrix(u), None, None, to_plain,
                   inputs_checked=True, positions={})
    choice = choice or choose_formulation(model)
    return replace(eom, route=f"kinematic tree ({n} links), recursive (articulated-body algorithm)",
                   tree=kernels, formulation=choice.report(),
                   points=tuple((name, None) for name, _ in points))


def _plain_link(link, to_plain):
    where = f"link {link.name!r}"
    return replace(link, mass=to_plain(link.mass, f"mass of {where}"),
                   center=tuple(to_plain(x, f"centre of mass of {where}") for x in link.center),
                   inertia=tuple(to_plain(x, f"inertia of {where}") for x in link.inertia))


def _energy_and_points(model, links, parent, joints, v, gravity, V, rec, to_plain):
    """T = sum of 1/2 v^T I v, V = the model's potential energy plus -m g . (position of the
    centre of mass), and the named points, from each link's rotation and origin in the ground frame."""
    rotation, origin, T, Vg, points = [], [], [], [], []
    for i, link in enumerate(links):
        Et, r = _tr(joints[i].E), joints[i].r
        if parent[i] is None:
            Ri, pi = Et, r
        else:
            Ri, pi = _mm(rotation[parent[i]], Et), _vadd(origin[parent[i]], _mv(rotation[parent[i]], r))
        Ri = rec.matrix(Ri, f"R{i}")
        pi = rec.vector(pi, f"r{i}", "xyz")
        rotation.append(Ri)
        origin.append(pi)
        plain = _plain_link(link, to_plain)
        if plain.mass != 0 or any(x != 0 for x in plain.inertia):
            T.append(sp.Rational(1, 2) * _dot(v[i], _mv(_spatial_inertia(plain), v[i])))
            Vg.append(-plain.mass * _dot(gravity, _vadd(pi, _mv(Ri, list(plain.center)))))
        for name, xyz in link.points.items():
            local = [to_plain(x, f"point {name!r}") for x in xyz]
            points.append((name, tuple(_vadd(pi, _mv(Ri, local)))))
    return sp.Add(*T) + sp.Add(*Vg) + V, tuple(points)


def _solve(P: sp.Matrix, b) -> list:
    """x with P x = b, by substitution when P is triangular up to a column order (a tree's
    absolute angles), else with the exact inverse."""
    order = _triangular_order(P)
    n = P.rows
    if order is None:
        inverse = P.inv()
        return [sp.Add(*[inverse[j, i] * b[i] for i in range(n) if inverse[j, i] != 0]) for j in range(n)]
    x = [None] * n
    for i, col in enumerate(order):  # row i determines x[col] from the columns of earlier rows
        rest = sp.Add(*[P[i, k] * x[k] for k in range(n) if k != col and P[i, k] != 0])
        x[col] = (b[i] - rest) / P[i, col]
    return x


def _solve_transposed(P: sp.Matrix, b) -> list:
    """y with P^T y = b, by back substitution when `_solve` can substitute."""
    order = _triangular_order(P)
    n = P.rows
    if order is None:
        inverse = P.T.inv()
        return [sp.Add(*[inverse[j, i] * b[i] for i in range(n) if inverse[j, i] != 0]) for j in range(n)]
    y = [None] * n
    for i in reversed(range(n)):
        col = order[i]
        rest = sp.Add(*[P[k, col] * y[k] for k in range(i + 1, n) if P[k, col] != 0])
        y[i] = (b[col] - rest) / P[i, col]
    return y


def _triangular_order(P: sp.Matrix):
    """For each row i the column it introduces, when every other column of row i was introduced
    by an earlier row (P lower triangular after reordering its columns); else None."""
    introduced, order = set(), []
    for i in range(P.rows):
        new = [k for k in range(P.cols) if P[i, k] != 0 and k not in introduced]
        if len(new) != 1:
            return None
        order.append(new[0])
        introduced.add(new[0])
    return order
