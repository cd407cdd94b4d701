"""Model descriptions that used to derive a wrong model without a word, or crash naming nothing.

Issue 11, items 1-3 and the model-level bullets: nan, infinities and I in any input; speeds in V
or phi; accelerations anywhere; sympy models whose speeds do not match their coordinates; bodies,
loads and points sympy cannot locate; parameter values keyed by name, or not numbers. Each case
asserts `ModelError` and that the message names the input (and the culprit where there is one).
"""
from __future__ import annotations

import re

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, ModelError, derive_equations

t = me.dynamicsymbols._t
m, k, c, r, g = sp.symbols("m k c r g", positive=True)
x, y = me.dynamicsymbols("x y")
xd = x.diff(t)
T_x = m * xd ** 2 / 2
V_x = k * x ** 2 / 2


def raises_naming(*names: str):
    """pytest.raises(ModelError) whose message contains every string in ``names``."""
    pattern = "".join(rf"(?=.*{re.escape(n)})" for n in names)
    return pytest.raises(ModelError, match=re.compile(pattern, re.S))


def oscillator(**fields):
    fields.setdefault("kinetic_energy", T_x)
    fields.setdefault("potential_energy", V_x)
    return Model("osc", [x], [m, k, c], **fields)


UNDEFINED = {
    "nan float": float("nan"),
    "nan": sp.nan,
    "zoo": sp.zoo,
    "oo": sp.oo,
    "-oo": -sp.oo,
    "I": sp.I,
}


@pytest.mark.parametrize("value", list(UNDEFINED.values()), ids=list(UNDEFINED))
@pytest.mark.parametrize("field, build, label", [
    ("potential_energy", lambda bad: V_x + bad, "potential_energy"),
    ("potential_energy", lambda bad: bad * x, "potential_energy"),
    ("kinetic_energy", lambda bad: T_x + bad * xd ** 2, "kinetic_energy"),
    ("dissipation", lambda bad: bad * c * xd ** 2, "dissipation"),
    ("generalized_forces", lambda bad: {x: -c * xd + bad}, "generalized force on x(t)"),
], ids=["V+bad", "bad*x", "T", "R", "Q"])
def test_energies_route_refuses_undefined_values(field, build, label, value):
    # sympy folds V + nan to nan, whose derivative is 0: the spring vanished and the run said OK.
    with raises_naming(label):
        oscillator(**{field: build(value)})


@pytest.mark.parametrize("field, build", [
    ("potential_energy", lambda bad: bad * k * x ** 2),
    ("generalized_forces", lambda bad: {x: -c * xd * bad}),
], ids=["V", "Q"])
@pytest.mark.parametrize("value", [(-1) ** sp.Rational(1, 3), sp.Integer(-8) ** sp.Rational(1, 3)], ids=["-1", "-8"])
def test_a_complex_constant_without_i_is_refused(field, build, value):
    """Found by review: (-1)**(1/3) is 0.5 + 0.866 I in sympy (principal root; no I atom), and the C
    printer wrote cbrt(-1) = -1: the kernel ran another model with status OK."""
    assert value.is_extended_real is False  # the premise: sympy's value is complex
    with raises_naming(field if field == "potential_energy" else "generalized force", "complex constant"):
        oscillator(**{field: build(value)})


@pytest.mark.parametrize("value", [sp.nan, sp.zoo, sp.oo], ids=["nan", "zoo", "oo"])
def test_undefined_value_times_zero_is_refused(value):
    # 0*nan, 0*zoo and 0*oo are all nan in sympy: V = 0*nan used to become a free spring-less model.
    with raises_naming("potential_energy is nan"):
        oscillator(potential_energy=0 * value)


@pytest.mark.parametrize("value", [sp.nan, sp.zoo, sp.oo, sp.I], ids=["nan", "zoo", "oo", "I"])
def test_constraint_and_point_output_refuse_undefined_values(value):
    with raises_naming("constraint 0"):
        Model("pair", [x, y], [m, k], kinetic_energy=m * (xd ** 2 + y.diff(t) ** 2) / 2,
              constraints=[x - y + value])
    with raises_naming("point 'tip'"):
        oscillator(points={"tip": (x, value * x)})


def _ball_on_rail(along=x, mass=m, load=None, inertia=None):
    """A ball at ``along`` * N.x from O; optionally a load ``load`` * N.x on it and, when
    ``inertia`` is given, a rigid ball with that moment about its first axis."""
    N, O = me.ReferenceFrame("N"), me.Point("O")
    P = O.locatenew("P", along * N.x)
    if inertia is None:
        body = me.Particle("ball", P, mass)
    else:
        B = N.orientnew("B", "Axis", [0, N.z])
        body = me.RigidBody("ball", P, B, mass, (me.inertia(B, inertia, 1, 1), P))
    loads = [(P, load * N.x)] if load is not None else []
    return dict(bodies=[body], frame=N, origin=O, loads=loads)


@pytest.mark.parametrize("value", [sp.nan, sp.zoo, sp.oo, sp.I], ids=["nan", "zoo", "oo", "I"])
@pytest.mark.parametrize("where, label", [
    ("along", "position of body ball"),
    ("mass", "mass of ball"),
    ("load", "force on point P"),
    ("inertia", "inertia of ball"),
])
def test_bodies_route_refuses_undefined_values(where, label, value):
    bad = {"along": x + value, "mass": m + value, "load": -k * x + value, "inertia": m * value}[where]
    with raises_naming(label):
        Model("rail", [x], [m, k], **_ball_on_rail(**{where: bad}))


def test_speed_in_potential_energy_is_named():
    # V = k xd^2/2 + k x^2/2 used to derive F = -k x: the speed term vanished in dV/dq.
    with raises_naming("potential_energy", "Derivative(x(t), t)"):
        oscillator(potential_energy=k * xd ** 2 / 2 + V_x)


def test_speed_in_a_holonomic_constraint_is_named():
    with raises_naming("constraint 0", "Derivative(x(t), t)"):
        Model("pair", [x, y], [m], kinetic_energy=m * (xd ** 2 + y.diff(t) ** 2) / 2,
              constraints=[xd - y])


@pytest.mark.parametrize("field, build, label", [
    ("kinetic_energy", lambda a: T_x + m * x * a, "kinetic_energy"),
    ("generalized_forces", lambda a: {x: -m * a}, "generalized force on x(t)"),
    ("dissipation", lambda a: c * a ** 2, "dissipation"),
], ids=["T", "Q", "R"])
def test_accelerations_are_refused(field, build, label):
    with raises_naming(label, "Derivative(x(t), (t, 2))"):
        oscillator(**{field: build(x.diff(t, 2))})


def test_acceleration_in_a_load_is_refused():
    setup = _ball_on_rail(load=-m * x.diff(t, 2))
    with raises_naming("force on point P", "(t, 2)"):
        Model("rail", [x], [m, k], **setup)


# -- sympy models whose speeds do not match their coordinates ------------------------------------
def test_lagranges_method_with_nan_lagrangian_is_refused():
    L = T_x - V_x + sp.nan * x
    method = me.LagrangesMethod(L, [x])
    method.form_lagranges_equations()
    with raises_naming("sympy model", "nan"):
        derive_equations(Model("nan_lagrangian", parameters=[m, k], sympy_model=method))


# -- bodies, loads and points sympy cannot locate ("No Connecting Path") -------------------------
def test_body_with_no_path_to_the_origin_is_named():
    N, O = me.ReferenceFrame("N"), me.Point("O")
    floating = me.Point("floating")  # never located relative to O
    ball = me.Particle("ball", floating, m)
    with raises_naming("body 'ball'", "floating", "origin O"):
        Model("lost", [x], [m], bodies=[ball], frame=N, origin=O)


def test_load_on_an_unlocated_point_is_named():
    setup = _ball_on_rail()
    stray = me.Point("stray")
    setup["loads"] = [(stray, -k * x * setup["frame"].x)]
    with raises_naming("load on point stray"):
        Model("rail", [x], [m, k], **setup)


def test_point_output_with_no_path_is_named():
    setup = _ball_on_rail()
    with raises_naming("point output 'marker'", "marker"):
        Model("rail", [x], [m, k], points={"marker": me.Point("marker")}, **setup)


def test_rigid_body_frame_not_oriented_is_named():
    N, O = me.ReferenceFrame("N"), me.Point("O")
    B = me.ReferenceFrame("B")  # never oriented relative to N
    P = O.locatenew("P", x * N.x)
    disk = me.RigidBody("disk", P, B, m, (me.inertia(B, 1, 1, 1), P))
    with raises_naming("body 'disk'", "frame B", "inertial frame N"):
        Model("lost", [x], [m], bodies=[disk], frame=N, origin=O)


# -- parameter values --------------------------------------------------------------------------
def test_parameter_values_accept_names():
    model = oscillator(parameter_values={"m": 2, "k": 8.0, c: 0.5})
    assert model.parameter_values == {m: 2.0, k: 8.0, c: 0.5}


@pytest.mark.parametrize("values, names", [
    ({"mass": 1}, ["'mass'", "declared: m, k, c"]),
    ({m: float("nan")}, ["parameter_values['m']", "nan"]),
    ({k: float("inf")}, ["parameter_values['k']", "inf"]),
    ({m: "1.0"}, ["parameter_values['m']", "str"]),
    ({m: True}, ["parameter_values['m']", "bool"]),
    ({m: None}, ["parameter_values['m']", "NoneType"]),
    ({m: x}, ["parameter_values['m']"]),
    ({sp.Symbol("m"): 1.0}, ["'m'", "assumptions", "same Symbol"]),
], ids=["unknown name", "nan", "inf", "string", "bool", "None", "expression", "assumptions"])
def test_bad_parameter_values_are_named(values, names):
    with raises_naming(*names):
        oscillator(parameter_values=values)


@pytest.mark.parametrize("measurements, match", [
    ({"x": "x"}, "measurement 'x' has the name of a coordinate or input"),
    ({"F": "x"}, "measurement 'F' has the name of a coordinate or input"),
    ({"acc": "xdd"}, "measurement 'acc' contains the acceleration"),
    ({"bad": "zz"}, "measurement 'bad' uses symbols not declared as parameters: zz"),
    ({"1a": "x"}, "measurement name '1a' must be an identifier"),
    ({"u": "nan"}, "measurement 'u' is nan"),
])
def test_bad_measurements_are_named(measurements, match):
    """Output expressions y = h(q, u, r, t) (issue 13): each refusal names the measurement."""
    x, F = me.dynamicsymbols("x F")
    m = sp.symbols("m")
    table = {"x": x, "xdd": x.diff(me.dynamicsymbols._t, 2), "zz": sp.Symbol("zz"), "nan": sp.nan}
    with pytest.raises(ModelError, match=match):
        Model("sensed", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2, generalized_forces={x: F}, inputs=[F],
              measurements={name: table[key] for name, key in measurements.items()})


def test_a_measurement_named_like_a_speed_is_refused():
    # found by review: traj["x_d"] then returned the speed, not the measurement
    from lagcodegen import derive_equations

    x = me.dynamicsymbols("x")
    m = sp.symbols("m")
    model = Model("sensed_speed", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2, measurements={"x_d": 2 * x})
    with pytest.raises(ModelError, match="measurement 'x_d' has the name of a speed of model 'sensed_speed'"):
        derive_equations(model)


def test_a_joints_method_with_a_loose_joint_is_named():
    # sympy's own error ("Velocity of point c_masscenter has not been defined") names no joint
    import warnings

    q1, q2, u1, u2 = me.dynamicsymbols("q1 q2 u1 u2")
    length = sp.Symbol("l")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # sympy 1.14 deprecates Body
        ground, a, b, c = me.Body("ground"), me.Body("a", mass=m), me.Body("b", mass=m), me.Body("c", mass=m)
        carried = me.PinJoint("j1", ground, a, coordinates=q1, speeds=u1, child_point=length * a.x)
        loose = me.PinJoint("j2", b, c, coordinates=q2, speeds=u2, child_point=length * c.x)
        method = me.JointsMethod(ground, carried, loose)
    with raises_naming("joint 'j2'", "body 'b'", "Newtonian body ground"):
        Model("loose", parameters=[m, length], sympy_model=method)


def test_a_coordinate_or_input_named_like_time_is_refused():
    # found by review: a coordinate t(t) became the plain symbol t, the time: derive_equations returned a
    # forcing mixing the two without a word, and the C compiler failed on "redeclaration of t"
    t_coordinate, F = me.dynamicsymbols("t F")
    m, k = sp.symbols("m k")
    with pytest.raises(ModelError, match="coordinate 't' has the name of the time symbol"):
        Model("time_clash", [t_coordinate], [m, k], kinetic_energy=m * t_coordinate.diff() ** 2 / 2)
    x, t_input = me.dynamicsymbols("x t")
    with pytest.raises(ModelError, match="input 't' is also a time symbol"):
        Model("time_input", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, generalized_forces={x: t_input},
              inputs=[t_input])


# -- sympy models: inputs where they cannot go, symbols only in constraints (found by review) ----------

def test_an_input_in_a_sympy_models_constraints_is_named():
    """An input r(t) in a LagrangesMethod's hol_coneqs (a pendulum of driven length) was taken as a
    constant in the constraint's derivatives, and the C then failed to compile; in nonhol_coneqs or
    a Kane velocity constraint it was reported as an undeclared function."""
    x, y, r = me.dynamicsymbols("x y r")
    m, g = sp.symbols("m g")
    lagrangian = m * (x.diff() ** 2 + y.diff() ** 2) / 2 - m * g * y  # a particle in a vertical plane
    holonomic = me.LagrangesMethod(lagrangian, [x, y], hol_coneqs=[x ** 2 + y ** 2 - r ** 2])
    rolling = me.LagrangesMethod(lagrangian, [x, y], nonhol_coneqs=[x.diff() - r])
    for method, what in ((holonomic, "holonomic constraint 0"), (rolling, "velocity constraint 0")):
        with pytest.raises(ModelError, match=f"input 'r' appears in the sympy model's {what}: inputs may drive "
                                             "the loads only"):
            derive_equations(Model("driven_constraint", parameters=[m, g], sympy_model=method, inputs=[r]))


def test_a_declared_inputs_rate_in_a_sympy_model_is_named_as_one():
    """A pendulum whose support moves by a declared input s(t): sympy's forcing holds s''. It was
    reported as an undeclared function "to list in inputs=[...]", though s was listed."""
    q, u, s = me.dynamicsymbols("q u s")
    m, length, g = sp.symbols("m l g")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    support = O.locatenew("S", s * N.x)
    support.set_vel(N, s.diff() * N.x)
    B = N.orientnew("B", "Axis", [q, N.z])
    B.set_ang_vel(N, u * N.z)
    bob = support.locatenew("P", -length * B.y)
    bob.v2pt_theory(support, N, B)
    method = me.KanesMethod(N, [q], [u], kd_eqs=[u - q.diff()])
    method.kanes_equations([me.Particle("p", bob, m)], [(bob, -m * g * N.y)])
    with pytest.raises(ModelError, match=r"forcing contains the input rate Derivative\(s, \(t, 2\)\): inputs may "
                                         "enter the forcing, their rates may not"):
        derive_equations(Model("moving_support", parameters=[m, length, g], sympy_model=method, inputs=[s]))


def test_a_symbol_only_in_kanes_configuration_constraints_is_named():
    """A four-bar whose ground link l4 appears only in the configuration constraints: left out of
    parameters=, it reached the C printer ("symbol l4 has no C name")."""
    q1, q2, q3, u1, u2, u3 = me.dynamicsymbols("q1 q2 q3 u1 u2 u3")
    l1, l2, l3, l4, m, g = sp.symbols("l1 l2 l3 l4 m g")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    frames = [N.orientnew(name, "Axis", [angle, N.z]) for name, angle in (("A", q1), ("B", q2), ("C", q3))]
    for frame, speed in zip(frames, (u1, u2, u3)):
        frame.set_ang_vel(N, speed * N.z)
    P1 = O.locatenew("P1", l1 * frames[0].x)
    P2 = P1.locatenew("P2", l2 * frames[1].x)
    P3 = P2.locatenew("P3", l3 * frames[2].x)
    for point in (P1, P2, P3):
        point.set_vel(N, point.pos_from(O).dt(N).subs({q1.diff(): u1, q2.diff(): u2, q3.diff(): u3}))
    loop = P3.pos_from(O) - l4 * N.x
    method = me.KanesMethod(N, [q1], [u1], kd_eqs=[u1 - q1.diff(), u2 - q2.diff(), u3 - q3.diff()],
                            q_dependent=[q2, q3], configuration_constraints=[loop.dot(N.x), loop.dot(N.y)],
                            u_dependent=[u2, u3], velocity_constraints=[P3.vel(N).dot(N.x), P3.vel(N).dot(N.y)])
    method.kanes_equations([me.Particle(f"p{i}", P, m) for i, P in enumerate((P1, P2, P3))],
                           [(P, -m * g * N.y) for P in (P1, P2, P3)])
    with pytest.raises(ModelError, match="configuration constraint 0 uses symbols not declared as parameters: l4"):
        derive_equations(Model("four_bar", parameters=[l1, l2, l3, m, g], sympy_model=method))


def test_a_constraint_with_a_kink_is_named():
    """Found by review: constraints=[Abs(x) + y - l] failed in the C printer ("cannot print gamma[0]:
    function DiracDelta"), not naming the constraint. d^2|x|/dx^2 = 2 DiracDelta(x) (by hand)."""
    x, y = me.dynamicsymbols("x y")
    m, g, length = sp.symbols("m g l", positive=True)
    model = Model("kinked", [x, y], [m, g, length], kinetic_energy=m * (x.diff() ** 2 + y.diff() ** 2) / 2,
                  potential_energy=m * g * y, constraints=[sp.Abs(x) + y - length])
    with pytest.raises(ModelError, match=r"constraint 0 \(-l \+ y \+ Abs\(x\)\) is not smooth: .* DiracDelta\(x\)"):
        derive_equations(model)


def test_a_step_in_the_potential_is_named_before_the_printer():
    """Found by review: V = k x Heaviside(x - 1) jumps by k at x = 1; its derivative holds
    DiracDelta(x - 1), and the C printer refused it naming only F[0] and a CSE temporary. Now the
    derivation names the delta and the step. A kink (V = k |x|, a force jump) stays accepted."""
    with raises_naming("generalized force along x_d", "DiracDelta(x - 1)", "step"):
        derive_equations(oscillator(potential_energy=k * x * sp.Heaviside(x - 1)))
    assert derive_equations(oscillator(potential_energy=k * sp.Abs(x))).forcing[0] != 0


def test_a_jump_in_a_piecewise_energy_is_named():
    """Found by review: V = Piecewise((k x^2/2, x < 1), (k x^2/2 + 3, True)) jumps by 3 at x = 1 (by
    hand); its derivative is -k x on both sides, so the motion crossed the step as if it were not
    there, with status OK. Now the derivation names the jump, the coordinate and where. Pieces that
    meet (a one-sided spring, continuous at x = 1) stay accepted, as does a Piecewise whose
    condition reads no coordinate. A floor of a coordinate (its derivative unevaluated) is named."""
    with raises_naming("potential energy jumps by 3", "x = 1", "x < 1"):
        derive_equations(oscillator(potential_energy=sp.Piecewise((k * x ** 2 / 2, x < 1),
                                                                  (k * x ** 2 / 2 + 3, True))))
    with raises_naming("kinetic energy jumps by", "x = -0.5"):
        derive_equations(oscillator(kinetic_energy=sp.Piecewise((T_x, 2 * x + 1 > 0), (2 * T_x, True))))
    meeting = sp.Piecewise((k * (x - 1) ** 2 / 2, x > 1), (0, True))
    assert derive_equations(oscillator(potential_energy=meeting)).forcing[0] != 0
    assert derive_equations(oscillator(potential_energy=sp.Piecewise((V_x, k > 1), (2 * V_x, True)))).forcing[0] != 0
    with raises_naming("generalized force along x_d", "Derivative(floor(x), x)"):
        derive_equations(oscillator(potential_energy=V_x + sp.floor(x)))
    # found by review: conditions nonlinear in the coordinate (a box |x| < 1, x^2 < 1) were not looked
    # at, and a jump far out (x = 1e6, beside k x^2/2) hid in the slope over a 1e-7 relative step
    for condition, where in ((sp.Abs(x) < 1, "x = -1"), (x ** 2 < 1, "x = -1"), (x < 10 ** 6, "x = 1000000")):
        with raises_naming("potential energy jumps by", where):
            derive_equations(oscillator(potential_energy=V_x + sp.Piecewise((0, condition), (3, True))))
    smooth = sp.Piecewise((k * (x ** 2 - 1) ** 2, x ** 2 > 1), (0, True))  # meets at x = +-1
    assert derive_equations(oscillator(potential_energy=smooth)).forcing[0] != 0


def test_a_value_beyond_the_double_range_or_complex_is_named():
    """Found by review: parameter_values={k: 10**400} and fixed={"k": 10**400} raised a bare
    OverflowError, and numpy's complex 4+3j became 4.0 with only numpy's ComplexWarning."""
    import numpy as np

    from lagcodegen.codegen.outputs import KernelError
    from lagcodegen.pipeline import compile_model

    with raises_naming("parameter_values['k']", "integer of 401 digits", "beyond the double range"):
        oscillator(parameter_values={k: 10 ** 400})
    with raises_naming("parameter_values['k']", "complex128"):
        oscillator(parameter_values={k: np.complex128(4 + 3j)})
    with pytest.raises(KernelError, match="fixed parameter 'k' must be finite, got an integer of 401 digits"):
        compile_model(oscillator(), fixed={"k": 10 ** 400})


def _particle_on_a_line(name="ball", mass=m):
    N, O = me.ReferenceFrame("N"), me.Point("O")
    P = O.locatenew("P", x * N.x)
    O.set_vel(N, 0)
    P.set_vel(N, P.pos_from(O).dt(N))
    return N, O, P, me.Particle(name, P, mass)


def test_a_bodys_own_potential_energy_is_named_not_dropped():
    """Found by review: Particle.potential_energy (sympy's attribute for its Lagrangian(), which its
    KanesMethod ignores) was dropped on the bodies route: the spring k x^2/2 vanished, F = 0, status
    OK. Counting it could double a gravity also given as gravity=, so it is refused by name; given
    as Model(potential_energy=...) it gives F = -k x (by hand)."""
    N, O, _, ball = _particle_on_a_line()
    ball.potential_energy = k * x ** 2 / 2
    with raises_naming("body 'ball' carries a potential_energy", "Model(potential_energy=...)"):
        Model("spring_ball", [x], [m, k], bodies=[ball], frame=N, origin=O)
    ball.potential_energy = 0
    eom = derive_equations(Model("spring_ball", [x], [m, k], bodies=[ball], frame=N, origin=O,
                                 potential_energy=k * x ** 2 / 2))
    assert list(eom.forcing) == [-k * eom.q[0]]


def test_the_bodies_route_refuses_what_it_would_drop():
    """Found by review, each accepted with status OK and a wrong motion (by hand in each case):
    an input s(t) in a rotor's angular velocity (th' + s): J th'' = -k th - J s', but s' was dropped;
    a mass m0 (1 + sin(10 pi t)) that the constancy samples at t = -1.3, 0.4, 2.2 (zeros of the sine)
    took as constant (m' x' dropped); an origin moving at V0 sin(t) (a shaking table) taken as fixed;
    a load's point at x + c x' (the speed dropped from its partial velocity); a constant asin(2),
    complex, which ran to "diverged"; and x(t) declared real=True against a coordinate x(t)
    without, which the messages called "not a coordinate (coordinates: x(t))"."""
    th, s = me.dynamicsymbols("th s")
    J = sp.Symbol("J", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    R = N.orientnew("R", "Axis", [th, N.z])
    R.set_ang_vel(N, (th.diff(t) + s) * N.z)
    O.set_vel(N, 0)
    rotor = me.RigidBody("rotor", O, R, J, (me.inertia(R, 0, 0, J), O))
    with raises_naming("input 's' appears in angular velocity of body rotor"):
        Model("rotor", [th], [J, k], bodies=[rotor], frame=N, origin=O, potential_energy=k * th ** 2 / 2,
              inputs=[s])
    N, O, P, _ = _particle_on_a_line()
    shaking = me.Particle("b", P, m * (1 + sp.sin(10 * sp.pi * t) / 2))
    with raises_naming("the mass of body 'b' changes with t"):
        derive_equations(Model("shaker", [x], [m, k], bodies=[shaking], frame=N, origin=O,
                               potential_energy=k * x ** 2 / 2))
    N, O, P, ball = _particle_on_a_line()
    O.set_vel(N, c * sp.sin(t) * N.x)
    with raises_naming("origin O moves in frame N", "must be fixed"):
        Model("table", [x], [m, c], bodies=[ball], frame=N, origin=O)
    # a velocity sympy infers for O from another point's (Kane-style speeds set on P) is no motion of
    # O (found by review: the first version of this check refused such a model as "O moves")
    N, O, u = me.ReferenceFrame("N"), me.Point("O"), me.dynamicsymbols("u")
    P = O.locatenew("P", x * N.x)
    P.set_vel(N, u * N.x)  # O has no velocity of its own: O.vel(N) is inferred as (u - x') N.x
    ball = me.Particle("ball", P, m)
    assert derive_equations(Model("kane_style", [x], [m, k], bodies=[ball], frame=N, origin=O,
                                  potential_energy=k * x ** 2 / 2)).mass_matrix[0] == m
    N, O, P, ball = _particle_on_a_line()
    Q = O.locatenew("Q", (x + c * xd) * N.x)
    with raises_naming("the position of the load's point Q contains the speed"):
        Model("load", [x], [m, c], bodies=[ball], frame=N, origin=O, loads=[(Q, c * N.y)])
    with raises_naming("potential_energy contains the complex constant asin(2)", "real domain"):
        oscillator(potential_energy=k * sp.asin(2) * x ** 2)
    x_real = me.dynamicsymbols("x", real=True)
    with raises_naming("x(t) has the assumptions", "'real': True", "use the same dynamicsymbol"):
        oscillator(potential_energy=k * x_real ** 2 / 2)
