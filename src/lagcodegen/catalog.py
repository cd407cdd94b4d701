"""Textbook systems, defined once and reused by examples, tests, benchmarks and generated/.

Each builder returns a `Model`; ``route="energies"`` states it by T, V, Q (Lagrange II) and
``route="bodies"`` by particles, rigid bodies and loads (d'Alembert-Lagrange) where the geometry
is natural; ``route="tree"`` states a kinematic tree link by link (`tree.Link`), which big
models compile recursively. Weights (P, Q) are forces, as in the problem books: masses are P/g.
"""
from __future__ import annotations

import math

import sympy as sp
import sympy.physics.mechanics as me

from .model import TIME, Model
from .tree import Link

ROUTES = ("energies", "bodies")


def _check_route(route: str, routes=ROUTES) -> None:
    if route not in routes:
        raise ValueError(f"route must be one of {ROUTES}, got {route!r}")


def rolling_wheels(route: str = "energies") -> Model:
    """Two wheels (weight P each, inertia J about the centre, radius r) joined by a translating rod
    (weight Q), rolling without slipping down an incline beta; s is the distance travelled."""
    _check_route(route)
    P, Q, J, r, g, beta = sp.symbols("P Q J r g beta", positive=True)
    s = me.dynamicsymbols("s")
    params = (P, Q, J, r, g, beta)
    values = {P: 20.0, Q: 10.0, J: 0.05, r: 0.3, g: 9.81, beta: 0.3}
    if route == "energies":
        T = (2 * P + Q) / (2 * g) * s.diff() ** 2 + J * (s.diff() / r) ** 2
        V = -(2 * P + Q) * s * sp.sin(beta)
        return Model("rolling_wheels", [s], params, kinetic_energy=T, potential_energy=V,
                     parameter_values=values)
    N = me.ReferenceFrame("N")  # x down the incline, y normal to it
    O = me.Point("O")
    bodies = []
    for side in ("left", "right"):
        frame = me.ReferenceFrame(f"W_{side}")
        frame.orient_axis(N, N.z, -s / r)
        centre = O.locatenew(f"C_{side}", s * N.x)
        bodies.append(me.RigidBody(f"wheel_{side}", centre, frame, P / g, (J * me.outer(N.z, N.z), centre)))
    bodies.append(me.Particle("rod", O.locatenew("R", s * N.x), Q / g))
    gravity = g * (sp.sin(beta) * N.x - sp.cos(beta) * N.y)
    return Model("rolling_wheels", [s], params, bodies=bodies, gravity=gravity, frame=N, origin=O,
                 parameter_values=values)


def elastic_pendulum(route: str = "energies") -> Model:
    """A ball (mass m) on a spring (stiffness k, natural length l0) swinging in a vertical plane;
    polar coordinates r (spring length) and phi (angle from the downward vertical)."""
    _check_route(route)
    m, k, l0, g = sp.symbols("m k l0 g", positive=True)
    r, phi = me.dynamicsymbols("r phi")
    params = (m, k, l0, g)
    values = {m: 1.0, k: 40.0, l0: 1.0, g: 9.81}
    spring = k * (r - l0) ** 2 / 2
    position = (r * sp.sin(phi), -r * sp.cos(phi))
    if route == "energies":
        T = m * (r.diff() ** 2 + r ** 2 * phi.diff() ** 2) / 2
        V = -m * g * r * sp.cos(phi) + spring
        return Model("elastic_pendulum", [r, phi], params, kinetic_energy=T, potential_energy=V,
                     points={"ball": position}, parameter_values=values)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    ball = O.locatenew("ball", position[0] * N.x + position[1] * N.y)
    return Model("elastic_pendulum", [r, phi], params, bodies=[me.Particle("ball", ball, m)],
                 potential_energy=spring, gravity=-g * N.y, frame=N, origin=O,
                 points={"ball": ball}, parameter_values=values)


def disk_spring_rod(route: str = "energies") -> Model:
    """A uniform disk (mass M, radius R) rolling on the floor, its centre held by a horizontal
    spring (k), with a uniform rod (mass m, length l) hinged at the centre; x is the centre's
    displacement from the spring's rest position, phi the rod's angle from the downward vertical."""
    _check_route(route)
    M, R, k, m, l, g = sp.symbols("M R k m l g", positive=True)
    x, phi = me.dynamicsymbols("x phi")
    params = (M, R, k, m, l, g)
    values = {M: 2.0, R: 0.25, k: 50.0, m: 1.0, l: 1.0, g: 9.81}
    rod_centre = (x + l / 2 * sp.sin(phi), -l / 2 * sp.cos(phi))
    if route == "energies":
        xd, phid = x.diff(), phi.diff()
        T_disk = M * xd ** 2 / 2 + (M * R ** 2 / 2) * (xd / R) ** 2 / 2
        T_rod = m * (rod_centre[0].diff(TIME) ** 2 + rod_centre[1].diff(TIME) ** 2) / 2 \
            + (m * l ** 2 / 12) * phid ** 2 / 2
        V = k * x ** 2 / 2 - m * g * l / 2 * sp.cos(phi)
        return Model("disk_spring_rod", [x, phi], params, kinetic_energy=T_disk + T_rod, potential_energy=V,
                     parameter_values=values)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    disk_frame, rod_frame = me.ReferenceFrame("D"), me.ReferenceFrame("B")
    disk_frame.orient_axis(N, N.z, -x / R)
    rod_frame.orient_axis(N, N.z, phi)
    centre = O.locatenew("C", x * N.x)
    rod_mid = centre.locatenew("G", -l / 2 * rod_frame.y)
    disk = me.RigidBody("disk", centre, disk_frame, M, (M * R ** 2 / 2 * me.outer(N.z, N.z), centre))
    rod = me.RigidBody("rod", rod_mid, rod_frame, m, (m * l ** 2 / 12 * me.outer(N.z, N.z), rod_mid))
    return Model("disk_spring_rod", [x, phi], params, bodies=[disk, rod], potential_energy=k * x ** 2 / 2,
                 gravity=-g * N.y, frame=N, origin=O, parameter_values=values)


def bar_on_rollers() -> Model:
    """A bar (mass m1) on two uniform cylindrical rollers (mass m2 each, radius r) going down an
    incline beta, rolling without slipping at all four contacts; x is the rollers' displacement
    (the bar moves 2x). Rolling friction (coefficient delta, a length) acts at every contact with a
    moment delta * N opposing the rolling; the normal forces are (m1/2 + m2) g cos(beta) at the
    incline and m1/2 g cos(beta) at the bar, so its virtual work gives the generalized force
    Q_x = -2 delta (m1 + m2) g cos(beta) sign(xd) / r."""
    m1, m2, r, g, beta, delta = sp.symbols("m1 m2 r g beta delta", positive=True)
    x = me.dynamicsymbols("x")
    xd = x.diff()
    T = m1 * (2 * xd) ** 2 / 2 + 2 * (m2 * xd ** 2 / 2 + (m2 * r ** 2 / 2) * (xd / r) ** 2 / 2)
    V = -(m1 * 2 * x + 2 * m2 * x) * g * sp.sin(beta)
    rolling = -2 * delta * (m1 + m2) * g * sp.cos(beta) * sp.sign(xd) / r
    return Model("bar_on_rollers", [x], (m1, m2, r, g, beta, delta), kinetic_energy=T, potential_energy=V,
                 generalized_forces={x: rolling},
                 parameter_values={m1: 10.0, m2: 2.0, r: 0.1, g: 9.81, beta: 0.2, delta: 0.002})


def centrifugal_governor(route: str = "bodies") -> Model:
    """A centrifugal governor spun at constant omega about the vertical: two balls (weight P each)
    on weightless rods of length l hinged on the axis, and a sleeve (weight Q) on the axis joined to
    the balls by rods of length l; alpha is the rods' angle from the vertical. Rheonomic.

    Named points (y up, the axis through the hinge at the origin): ``ball_1``, ``ball_2`` at
    (+-l sin(alpha) cos(omega t), -l cos(alpha), -+l sin(alpha) sin(omega t)) and ``sleeve`` at
    (0, -2 l cos(alpha), 0), joined by the four rods (``links``)."""
    _check_route(route)
    P, Q, l, g, omega = sp.symbols("P Q l g omega", positive=True)
    alpha = me.dynamicsymbols("alpha")
    params = (P, Q, l, g, omega)
    values = {P: 10.0, Q: 20.0, l: 0.5, g: 9.81, omega: 10.0}
    links = (("origin", "ball_1"), ("ball_1", "sleeve"), ("sleeve", "ball_2"), ("ball_2", "origin"))
    if route == "energies":
        ad = alpha.diff()
        T = P / g * (l ** 2 * ad ** 2 + l ** 2 * sp.sin(alpha) ** 2 * omega ** 2) \
            + Q / (2 * g) * (2 * l * sp.sin(alpha) * ad) ** 2
        V = -2 * P * l * sp.cos(alpha) - 2 * Q * l * sp.cos(alpha)
        ball = lambda sign: (sign * l * sp.sin(alpha) * sp.cos(omega * TIME), -l * sp.cos(alpha),
                             -sign * l * sp.sin(alpha) * sp.sin(omega * TIME))
        points = {"ball_1": ball(1), "sleeve": (0, -2 * l * sp.cos(alpha), 0), "ball_2": ball(-1)}
        return Model("centrifugal_governor", [alpha], params, kinetic_energy=T, potential_energy=V,
                     parameter_values=values, points=points, links=links)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    spinning = me.ReferenceFrame("S")
    spinning.orient_axis(N, N.y, omega * TIME)
    balls = [me.Particle(f"ball_{i}", O.locatenew(f"B{i}", sign * l * sp.sin(alpha) * spinning.x
                                                  - l * sp.cos(alpha) * spinning.y), P / g)
             for i, sign in ((1, 1), (2, -1))]
    sleeve = me.Particle("sleeve", O.locatenew("S", -2 * l * sp.cos(alpha) * N.y), Q / g)
    points = {body.name: body.masscenter for body in (balls[0], sleeve, balls[1])}
    return Model("centrifugal_governor", [alpha], params, bodies=balls + [sleeve], gravity=-g * N.y,
                 frame=N, origin=O, parameter_values=values, points=points, links=links)


def gear_hoist(route: str = "energies") -> Model:
    """A hoist: a torque M on gear 1 (weight P1, radius of gyration rho1, pitch radius r1) drives
    gear 2 (P2, rho2, r2), on whose shaft a drum (radius r) winds a rope lifting a load (weight Q);
    phi is gear 1's rotation, the load rises r r1/r2 phi."""
    _check_route(route)
    M, P1, P2, Q, rho1, rho2, r1, r2, r, g = sp.symbols("M P1 P2 Q rho1 rho2 r1 r2 r g", positive=True)
    phi = me.dynamicsymbols("phi")
    params = (M, P1, P2, Q, rho1, rho2, r1, r2, r, g)
    values = {M: 60.0, P1: 100.0, P2: 300.0, Q: 500.0, rho1: 0.1, rho2: 0.25, r1: 0.1, r2: 0.3,
              r: 0.15, g: 9.81}
    lift = r * r1 / r2 * phi
    if route == "energies":
        phid = phi.diff()
        T = (P1 / g * rho1 ** 2 * phid ** 2 + P2 / g * rho2 ** 2 * (r1 / r2 * phid) ** 2
             + Q / g * lift.diff(TIME) ** 2) / 2
        return Model("gear_hoist", [phi], params, kinetic_energy=T, potential_energy=Q * lift,
                     generalized_forces={phi: M}, parameter_values=values)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    A, B = me.ReferenceFrame("A"), me.ReferenceFrame("B")
    A.orient_axis(N, N.z, phi)
    B.orient_axis(N, N.z, -r1 / r2 * phi)
    gear1 = me.RigidBody("gear1", O, A, P1 / g, (P1 / g * rho1 ** 2 * me.outer(N.z, N.z), O))
    hub = O.locatenew("H", (r1 + r2) * N.x)
    gear2 = me.RigidBody("gear2", hub, B, P2 / g, (P2 / g * rho2 ** 2 * me.outer(N.z, N.z), hub))
    load = me.Particle("load", hub.locatenew("L", r * N.x + lift * N.y), Q / g)
    return Model("gear_hoist", [phi], params, bodies=[gear1, gear2, load], loads=[(A, M * N.z)],
                 gravity=-g * N.y, frame=N, origin=O, parameter_values=values)


def pendulum_chain(n: int = 3, route: str = "bodies", name: str | None = None) -> Model:
    """Planar chain of n point masses m_i on massless rods l_i, hinged at the origin under gravity
    g; q_i is link i's absolute angle from the downward vertical. ``route="tree"`` states the
    same chain as revolute joints about z whose angles are q_i - q_(i-1)."""
    _check_route(route, ROUTES + ("tree",))
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"a pendulum chain needs n >= 1 links, got {n!r}")
    q = me.dynamicsymbols(f"q1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}", positive=True)
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    g = sp.Symbol("g", positive=True)
    params = tuple(m) + tuple(l) + (g,)
    values = {**{mi: 1.0 for mi in m}, **{li: 1.0 for li in l}, g: 9.81}
    name = name or f"pendulum_chain_{n}"
    if route == "tree":
        links = [Link(f"link{i + 1}", None if i == 0 else f"link{i}", "revolute", (0, 0, 1),
                      q[i] - (q[i - 1] if i else 0), offset=(0, -l[i - 1] if i else 0, 0), mass=m[i],
                      center=(0, -l[i], 0), points={f"bob{i + 1}": (0, -l[i], 0)}) for i in range(n)]
        return Model(name, q, params, tree=links, gravity=(0, -g, 0), parameter_values=values)
    if route == "energies":
        x, y, positions = sp.S.Zero, sp.S.Zero, []
        for qi, li in zip(q, l):
            x, y = x + li * sp.sin(qi), y - li * sp.cos(qi)
            positions.append((x, y))
        T = sum(mi * (px.diff(TIME) ** 2 + py.diff(TIME) ** 2) / 2 for mi, (px, py) in zip(m, positions))
        V = sum(mi * g * py for mi, (_, py) in zip(m, positions))
        return Model(name, q, params, kinetic_energy=T, potential_energy=V,
                     points={f"bob{i + 1}": pos for i, pos in enumerate(positions)}, parameter_values=values)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    bodies, points, previous = [], {}, O
    for i, (qi, li, mi) in enumerate(zip(q, l, m)):
        bob = previous.locatenew(f"P{i + 1}", (li * sp.sin(qi)) * N.x - (li * sp.cos(qi)) * N.y)
        bodies.append(me.Particle(f"bob{i + 1}", bob, mi))
        points[f"bob{i + 1}"] = previous = bob
    return Model(name, q, params, bodies=bodies, gravity=-g * N.y, frame=N, origin=O, points=points,
                 parameter_values=values)


def double_pendulum(route: str = "bodies") -> Model:
    """The planar double pendulum: point masses m1, m2 on massless rods l1, l2 under gravity g;
    q1, q2 are the rods' absolute angles from the downward vertical (`pendulum_chain`, n = 2)."""
    return pendulum_chain(2, route=route, name="double_pendulum")


def pendulum_chain_5(route: str = "bodies") -> Model:
    """The planar five-link pendulum: point masses m1..m5 on massless rods l1..l5 under gravity g;
    q1..q5 are the rods' absolute angles from the downward vertical (`pendulum_chain`, n = 5)."""
    return pendulum_chain(5, route=route)


def stiff_chain() -> Model:
    """Three masses on a line between two walls joined by springs k (wall-m1, m1-m2, m3-wall) and
    one stiff spring K (m2-m3); x_i are displacements from rest. Linear, undamped: its largest
    frequency is the square root of the largest eigenvalue of M^-1 K_stiffness."""
    m1, m2, m3, k, K = sp.symbols("m1 m2 m3 k K", positive=True)
    x = me.dynamicsymbols("x1:4")
    T = sum(m * xi.diff() ** 2 for m, xi in zip((m1, m2, m3), x)) / 2
    V = (k * x[0] ** 2 + k * (x[1] - x[0]) ** 2 + K * (x[2] - x[1]) ** 2 + k * x[2] ** 2) / 2
    return Model("stiff_chain", x, (m1, m2, m3, k, K), kinetic_energy=T, potential_energy=V,
                 parameter_values={m1: 1.0, m2: 1.0, m3: 1.0, k: 1.0, K: 1.0e4})


# -- closed loops: Lagrange's equations of the first kind -------------------------------------
def cartesian_pendulum() -> Model:
    """A point mass m on a rigid massless rod l hinged at the origin, in Cartesian coordinates
    x, y (y up) with the holonomic constraint x^2 + y^2 - l^2 = 0 and gravity -g in y.

    Lagrange I: m xdd = -2 x lambda, m ydd = -m g - 2 y lambda, so the rod tension (pulling the
    mass towards the hinge) is 2 l lambda = m (g cos(theta) + l thetad^2), theta = atan2(x, -y)."""
    m, l, g = sp.symbols("m l g", positive=True)
    x, y = me.dynamicsymbols("x y")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    bob = O.locatenew("bob", x * N.x + y * N.y)
    return Model("cartesian_pendulum", [x, y], (m, l, g), bodies=[me.Particle("bob", bob, m)],
                 gravity=-g * N.y, frame=N, origin=O, points={"bob": bob},
                 constraints=[x ** 2 + y ** 2 - l ** 2], parameter_values={m: 1.0, l: 1.0, g: 9.81})


def _slider_crank_symbols():
    m1, m2, m3, r, L, g, tau = sp.symbols("m1 m2 m3 r L g tau", positive=True)
    values = {m1: 1.0, m2: 2.0, m3: 1.0, r: 0.1, L: 0.3, g: 9.81, tau: 1.0}
    return (m1, m2, m3, r, L, g, tau), values


def slider_crank(route: str = "bodies") -> Model:
    """An in-line slider-crank in redundant coordinates (Lagrange I; Haug, Computer-Aided
    Kinematics and Dynamics of Mechanical Systems, sec. 6.4; Nikravesh, ch. 7).

    Crank: uniform rod (mass m1, length r) hinged at the origin O, angle theta from the x axis.
    Connecting rod: uniform (mass m2, length L) from the crank pin A to the slider pin B, centre
    (xc, yc), angle phi measured clockwise from the x axis (A -> B points along (cos phi, -sin phi),
    so phi = asin(r sin(theta) / L) in the usual assembly). Slider: mass m3 at B = (s, 0).
    Coordinates q = (theta, xc, yc, phi, s) (n = 5), closed by m = 4 constraints::

        xc - L/2 cos(phi) - r cos(theta) = 0     rod end A = crank tip
        yc + L/2 sin(phi) - r sin(theta) = 0
        xc + L/2 cos(phi) - s            = 0     rod end B = slider
        yc - L/2 sin(phi)                = 0     B on the x axis

    A constant torque tau drives the crank; gravity g acts in -y (default 9.81, set g = 0 to drop
    it). Defaults: r = 0.1, L = 0.3, m1 = 1, m2 = 2, m3 = 1, tau = 1. `slider_crank_minimal` is
    the same mechanism in theta alone; `slider_crank_state` gives a consistent state."""
    _check_route(route)
    (m1, m2, m3, r, L, g, tau), values = _slider_crank_symbols()
    theta, xc, yc, phi, s = me.dynamicsymbols("theta xc yc phi s")
    q = [theta, xc, yc, phi, s]
    constraints = [xc - L / 2 * sp.cos(phi) - r * sp.cos(theta), yc + L / 2 * sp.sin(phi) - r * sp.sin(theta),
                   xc + L / 2 * sp.cos(phi) - s, yc - L / 2 * sp.sin(phi)]
    params = (m1, m2, m3, r, L, g, tau)
    points = {"crank_pin": (r * sp.cos(theta), r * sp.sin(theta)), "rod_centre": (xc, yc), "slider": (s, 0)}
    if route == "energies":
        T = (m1 * r ** 2 / 3 * theta.diff() ** 2 + m2 * (xc.diff() ** 2 + yc.diff() ** 2)
             + m2 * L ** 2 / 12 * phi.diff() ** 2 + m3 * s.diff() ** 2) / 2
        V = g * (m1 * r / 2 * sp.sin(theta) + m2 * yc)
        return Model("slider_crank", q, params, kinetic_energy=T, potential_energy=V,
                     generalized_forces={theta: tau}, points=points, constraints=constraints,
                     parameter_values=values)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    crank_frame, rod_frame = me.ReferenceFrame("K"), me.ReferenceFrame("R")
    crank_frame.orient_axis(N, N.z, theta)
    rod_frame.orient_axis(N, N.z, -phi)
    crank_centre = O.locatenew("Gk", r / 2 * crank_frame.x)
    rod_centre = O.locatenew("Gr", xc * N.x + yc * N.y)
    bodies = [
        me.RigidBody("crank", crank_centre, crank_frame, m1,
                     (m1 * r ** 2 / 12 * me.outer(N.z, N.z), crank_centre)),
        me.RigidBody("rod", rod_centre, rod_frame, m2, (m2 * L ** 2 / 12 * me.outer(N.z, N.z), rod_centre)),
        me.Particle("slider", O.locatenew("B", s * N.x), m3),
    ]
    return Model("slider_crank", q, params, bodies=bodies, loads=[(crank_frame, tau * N.z)],
                 gravity=-g * N.y, frame=N, origin=O, points=points, constraints=constraints,
                 parameter_values=values)


def slider_crank_minimal() -> Model:
    """`slider_crank` in its one minimal coordinate theta (Lagrange II), the closed-form
    kinematics: phi = asin(r sin(theta) / L), rod centre = A + L/2 (cos(phi), -sin(phi)),
    slider s = r cos(theta) + L cos(phi); same parameters and defaults."""
    (m1, m2, m3, r, L, g, tau), values = _slider_crank_symbols()
    theta = me.dynamicsymbols("theta")
    phi = sp.asin(r * sp.sin(theta) / L)
    xc, yc = r * sp.cos(theta) + L / 2 * sp.cos(phi), r * sp.sin(theta) - L / 2 * sp.sin(phi)
    s = r * sp.cos(theta) + L * sp.cos(phi)
    speed2 = lambda *c: sum(ci.diff(TIME) ** 2 for ci in c)
    T = (m1 * r ** 2 / 3 * theta.diff() ** 2 + m2 * speed2(xc, yc) + m2 * L ** 2 / 12 * phi.diff(TIME) ** 2
         + m3 * speed2(s)) / 2
    V = g * (m1 * r / 2 * sp.sin(theta) + m2 * yc)
    points = {"crank_pin": (r * sp.cos(theta), r * sp.sin(theta)), "rod_centre": (xc, yc), "slider": (s, 0)}
    return Model("slider_crank_minimal", [theta], (m1, m2, m3, r, L, g, tau), kinetic_energy=T,
                 potential_energy=V, generalized_forces={theta: tau}, points=points, parameter_values=values)


#: four-bar link lengths (crank l1, coupler l2, rocker l3, ground d): Grashof crank-rocker,
#: s + l = 0.1 + 0.4 = 0.5 < p + q = 0.35 + 0.3 = 0.65 with the crank the shortest link
FOUR_BAR_GRASHOF = (0.1, 0.35, 0.3, 0.4)
#: a change-point linkage, s + l = 0.1 + 0.3 = p + q = 0.2 + 0.2: at theta1 = theta2 = theta3 = 0
#: all four links lie flat on the x axis (O, A = (0.1, 0), B = (0.4, 0), O4 = (0.2, 0)) and the
#: constraint Jacobian loses rank
FOUR_BAR_FOLDING = (0.1, 0.3, 0.2, 0.2)


def four_bar(lengths=FOUR_BAR_GRASHOF) -> Model:
    """A planar four-bar linkage in redundant coordinates (Lagrange I): crank O A (uniform, mass
    m1, length l1) hinged at O = (0, 0), coupler A B (m2, l2), rocker O4 B (m3, l3) hinged at
    O4 = (d, 0); theta1, theta2, theta3 are the links' absolute angles from the x axis, closed by

        l1 cos(theta1) + l2 cos(theta2) - l3 cos(theta3) - d = 0
        l1 sin(theta1) + l2 sin(theta2) - l3 sin(theta3)     = 0

    A constant torque tau drives the crank; gravity g in -y. ``lengths = (l1, l2, l3, d)`` sets
    the default lengths: `FOUR_BAR_GRASHOF` (0.1, 0.35, 0.3, 0.4; the crank turns full circles;
    Grashof: s + l <= p + q, crank shortest) or `FOUR_BAR_FOLDING` (0.1, 0.3, 0.2, 0.2, a change-point
    linkage that folds flat at theta1 = theta2 = theta3 = 0, where A = dphi/dq has rank 1). The
    lengths stay free parameters. Defaults: m1 = 1, m2 = 2, m3 = 1.5, g = 9.81, tau = 5 (above the largest
    gravity torque on the crank, max dV/dtheta1 = 2.3 N m, so it turns from rest).
    Named points: the crank pin ``A``, the rocker pin ``B`` and the fixed pivot ``O4``.
    Consistent states: `four_bar_state`."""
    theta1, theta2, theta3 = me.dynamicsymbols("theta1 theta2 theta3")
    m1, m2, m3, l1, l2, l3, d, g, tau = sp.symbols("m1 m2 m3 l1 l2 l3 d g tau", positive=True)
    if len(lengths) != 4 or not all(float(v) > 0 for v in lengths):
        raise ValueError(f"lengths must be four positive numbers (l1, l2, l3, d), got {lengths!r}")
    values = {m1: 1.0, m2: 2.0, m3: 1.5, g: 9.81, tau: 5.0}
    values.update(zip((l1, l2, l3, d), map(float, lengths)))
    N, O = me.ReferenceFrame("N"), me.Point("O")
    frames = [me.ReferenceFrame(f"B{i}") for i in (1, 2, 3)]
    for frame, angle in zip(frames, (theta1, theta2, theta3)):
        frame.orient_axis(N, N.z, angle)
    A = O.locatenew("A", l1 * frames[0].x)
    O4 = O.locatenew("O4", d * N.x)
    centres = [O.locatenew("G1", l1 / 2 * frames[0].x), A.locatenew("G2", l2 / 2 * frames[1].x),
               O4.locatenew("G3", l3 / 2 * frames[2].x)]
    bodies = [me.RigidBody(name, G, frame, mass, (mass * length ** 2 / 12 * me.outer(N.z, N.z), G))
              for name, G, frame, mass, length in zip(("crank", "coupler", "rocker"), centres, frames,
                                                       (m1, m2, m3), (l1, l2, l3))]
    constraints = [l1 * sp.cos(theta1) + l2 * sp.cos(theta2) - l3 * sp.cos(theta3) - d,
                   l1 * sp.sin(theta1) + l2 * sp.sin(theta2) - l3 * sp.sin(theta3)]
    points = {"A": A, "B": A.locatenew("B", l2 * frames[1].x), "O4": O4}  # the chain O A B O4 (animation)
    return Model("four_bar", [theta1, theta2, theta3], (m1, m2, m3, l1, l2, l3, d, g, tau), bodies=bodies,
                 loads=[(frames[0], tau * N.z)], gravity=-g * N.y, frame=N, origin=O, points=points,
                 constraints=constraints, parameter_values=values)


def four_bar_state(theta1: float, theta1_d: float = 0.0, lengths=FOUR_BAR_GRASHOF,
                   open_branch: bool = True) -> tuple:
    """A consistent `four_bar` state (theta1, theta2, theta3, and their rates) at crank angle
    theta1 and crank speed theta1_d: B is the intersection of the circles about A (radius l2) and
    O4 (radius l3), above the line A O4 when ``open_branch``; the rates solve A u = 0."""
    l1, l2, l3, d = map(float, lengths)
    ax, ay = l1 * math.cos(theta1), l1 * math.sin(theta1)
    ex, ey = d - ax, -ay  # A -> O4
    e = math.hypot(ex, ey)
    along = (l2 ** 2 - l3 ** 2 + e ** 2) / (2 * e)
    across = math.sqrt(l2 ** 2 - along ** 2) * (1 if open_branch else -1)
    bx, by = ax + (along * ex - across * ey) / e, ay + (along * ey + across * ex) / e
    theta2, theta3 = math.atan2(by - ay, bx - ax), math.atan2(by, bx - d)
    # l2 w2 e2' - l3 w3 e3' = -l1 w1 e1' (e' = (-sin, cos)), by Cramer's rule
    det = l2 * l3 * math.sin(theta3 - theta2)
    theta2_d = -l1 * l3 * theta1_d * math.sin(theta3 - theta1) / det
    theta3_d = -l1 * l2 * theta1_d * math.sin(theta2 - theta1) / det
    return theta1, theta2, theta3, theta1_d, theta2_d, theta3_d


def slider_crank_state(theta: float, theta_d: float = 0.0, r: float = 0.1, L: float = 0.3) -> tuple:
    """A consistent `slider_crank` state (theta, xc, yc, phi, s, then their rates) from the
    closed-form kinematics of `slider_crank_minimal` at crank angle theta and speed theta_d."""
    phi = math.asin(r * math.sin(theta) / L)
    phi_d = r * math.cos(theta) * theta_d / (L * math.cos(phi))
    xc, yc = r * math.cos(theta) + L / 2 * math.cos(phi), r * math.sin(theta) - L / 2 * math.sin(phi)
    xc_d = -r * math.sin(theta) * theta_d - L / 2 * math.sin(phi) * phi_d
    yc_d = r * math.cos(theta) * theta_d - L / 2 * math.cos(phi) * phi_d
    s, s_d = r * math.cos(theta) + L * math.cos(phi), -r * math.sin(theta) * theta_d - L * math.sin(phi) * phi_d
    return theta, xc, yc, phi, s, theta_d, xc_d, yc_d, phi_d, s_d


#: the committed examples (generated/, `lagcodegen examples`, the example-wide tests). The
#: closed-loop systems above (cartesian_pendulum, slider_crank, four_bar) are not listed: they
#: start from consistent states of their own (`slider_crank_state`, `four_bar_state`), which
#: those callers do not give; tests/constraints covers them.
def ragdoll(links_per_branch: int = 6, formulation: str | None = None) -> Model:
    """A planar ragdoll: a pelvis (mass m0, inertia J0 about its centre) free in the vertical plane
    (x, y slide, phi turns it) with three branches (two legs and a spine) of ``links_per_branch``
    uniform rods each (mass m, length l, inertia m l^2/12 about the centre), hinged end to end by
    joints with torsional springs k and dampers c; gravity g along -y. The coordinates are the
    pelvis's x, y, phi and each joint's relative angle; 3 + 3 * links_per_branch bodies of which
    the first two (the slides) are massless."""
    if not isinstance(links_per_branch, int) or links_per_branch < 1:
        raise ValueError(f"a ragdoll needs links_per_branch >= 1, got {links_per_branch!r}")
    x, y, phi = me.dynamicsymbols("x y phi")
    m0, J0, m, l, k, c, g = sp.symbols("m0 J0 m l k c g", positive=True)
    links = [Link("slide_x", None, "prismatic", (1, 0, 0), x),
             Link("slide_y", "slide_x", "prismatic", (0, 1, 0), y),
             Link("pelvis", "slide_y", "revolute", (0, 0, 1), phi, mass=m0, inertia=(0, 0, J0, 0, 0, 0),
                  points={"pelvis": (0, 0, 0)})]
    angles, joints = [x, y, phi], []
    # the legs hang from the pelvis's sides, the spine rises from its middle
    branches = (("left_leg", (-l / 4, 0, 0), -1), ("right_leg", (l / 4, 0, 0), -1), ("spine", (0, 0, 0), 1))
    for branch, hip, direction in branches:
        parent, offset = "pelvis", hip
        for i in range(links_per_branch):
            theta = me.dynamicsymbols(f"{branch}_{i + 1}")
            name = f"{branch}{i + 1}"
            links.append(Link(name, parent, "revolute", (0, 0, 1), theta, offset=offset, mass=m,
                              center=(0, direction * l / 2, 0), inertia=(0, 0, m * l ** 2 / 12, 0, 0, 0),
                              points={f"{name}_end": (0, direction * l, 0)}))
            angles.append(theta)
            joints.append(theta)
            parent, offset = name, (0, direction * l, 0)
    V = sum(k * q ** 2 / 2 for q in joints)
    R = sum(c * q.diff(TIME) ** 2 / 2 for q in joints)
    values = {m0: 10.0, J0: 0.5, m: 2.0, l: 0.4, k: 50.0, c: 0.5, g: 9.81}
    return Model(f"ragdoll_{3 * links_per_branch + 3}", angles, (m0, J0, m, l, k, c, g), tree=links,
                 gravity=(0, -g, 0), potential_energy=V, dissipation=R, parameter_values=values,
                 formulation=formulation)


def spherical_chain(n: int = 3, formulation: str | None = None) -> Model:
    """A 3D chain of n uniform rods (mass m, length l, inertia m l^2/12 about the transverse axes,
    m r^2/2 about their own axis) hanging along -z from the origin, joined end to end by spherical
    joints; each spherical joint is three revolute axes z, x, y of its link's frame (angles
    a_i, b_i, c_i, relative to the rod above; the first two massless); gravity g along -z."""
    if not isinstance(n, int) or n < 1:
        raise ValueError(f"a spherical chain needs n >= 1 links, got {n!r}")
    m, l, r, g = sp.symbols("m l r g", positive=True)
    links, coordinates, parent, offset = [], [], None, (0, 0, 0)
    transverse, axial = m * l ** 2 / 12, m * r ** 2 / 2
    for i in range(1, n + 1):
        a, b, c = me.dynamicsymbols(f"a{i} b{i} c{i}")
        links += [Link(f"rod{i}_z", parent, "revolute", (0, 0, 1), a, offset=offset),
                  Link(f"rod{i}_x", f"rod{i}_z", "revolute", (1, 0, 0), b),
                  Link(f"rod{i}", f"rod{i}_x", "revolute", (0, 1, 0), c, mass=m, center=(0, 0, -l / 2),
                       inertia=(transverse, transverse, axial, 0, 0, 0), points={f"tip{i}": (0, 0, -l)})]
        coordinates += [a, b, c]
        parent, offset = f"rod{i}", (0, 0, -l)
    values = {m: 1.0, l: 0.5, r: 0.02, g: 9.81}
    return Model(f"spherical_chain_{n}", coordinates, (m, l, r, g), tree=links, gravity=(0, 0, -g),
                 parameter_values=values, formulation=formulation)


EXAMPLES = {
    "rolling_wheels": rolling_wheels,
    "elastic_pendulum": elastic_pendulum,
    "disk_spring_rod": disk_spring_rod,
    "bar_on_rollers": bar_on_rollers,
    "centrifugal_governor": centrifugal_governor,
    "gear_hoist": gear_hoist,
    "double_pendulum": double_pendulum,
    "pendulum_chain_5": pendulum_chain_5,
    "stiff_chain": stiff_chain,
    "cartesian_pendulum": cartesian_pendulum,
    "slider_crank": slider_crank,
    "slider_crank_minimal": slider_crank_minimal,
    "four_bar": four_bar,
}


def example(name: str) -> Model:
    """The catalog model called ``name`` (see `EXAMPLES`)."""
    try:
        return EXAMPLES[name]()
    except KeyError:
        raise KeyError(f"no example called {name!r}; examples: {', '.join(EXAMPLES)}") from None
