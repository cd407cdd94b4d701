"""Bad model descriptions raise `ModelError` whose message names the culprit.

Each case states one mistake a user makes and the name(s) the message must contain, so the user
can find the mistake without reading a sympy traceback. Errors found only when deriving (a
singular mass matrix) are raised by `derive_equations`, still as `ModelError`.
"""
from __future__ import annotations

import re

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, ModelError, derive_equations

t = me.dynamicsymbols._t
m, k, g, l = sp.symbols("m k g l", positive=True)
x, y = me.dynamicsymbols("x y")
T_x = m * x.diff(t) ** 2 / 2


def raises_naming(*names: str):
    """pytest.raises(ModelError) whose message mentions every name in ``names`` as a word."""
    pattern = "".join(rf"(?=.*(?<![\w]){re.escape(n)}(?![\w]))" for n in names)
    return pytest.raises(ModelError, match=re.compile(pattern, re.S))


def test_coordinate_that_is_a_plain_symbol():
    x_plain = sp.Symbol("x")
    with raises_naming("x") as info:
        Model("bad", [x_plain], [m], kinetic_energy=m * x_plain ** 2 / 2)
    assert "function of time" in str(info.value) or "dynamicsymbols" in str(info.value)


def test_coordinate_missing_from_kinetic_energy():
    # y appears only in V: d2T/dy'2 = 0, the mass matrix is singular; the message names y.
    model = Model("bad", [x, y], [m, k], kinetic_energy=T_x, potential_energy=k * (x - y) ** 2 / 2)
    with raises_naming("y") as info:
        derive_equations(model)
    assert "'x'" not in str(info.value)
    assert "singular" in str(info.value) or "inertia" in str(info.value)


def test_coordinate_missing_from_kinetic_energy_bodies_route():
    # Same mistake in the bodies route: the particle's position does not depend on y.
    N, O = me.ReferenceFrame("N"), me.Point("O")
    ball = me.Particle("ball", O.locatenew("P", x * N.x), m)
    model = Model("bad", [x, y], [m, k], bodies=[ball], potential_energy=k * y ** 2 / 2, frame=N, origin=O)
    with raises_naming("y"):
        derive_equations(model)


def test_undeclared_free_symbols_are_listed():
    with raises_naming("g", "l", "k") as info:
        Model("bad", [x], [m], kinetic_energy=T_x, potential_energy=k * x ** 2 / 2 + m * g * l * x)
    assert "potential" in str(info.value)  # names the expression too


def test_undeclared_symbol_in_kinetic_energy():
    with raises_naming("m"):
        Model("bad", [x], [], kinetic_energy=T_x)


def test_undeclared_symbol_in_generalized_force():
    c = sp.Symbol("c", positive=True)
    with raises_naming("c"):
        Model("bad", [x], [m], kinetic_energy=T_x, generalized_forces={x: -c * x.diff(t)})


def test_undeclared_symbol_in_a_body_position_names_the_body():
    # Body positions are read when the model is validated; the message names the body and the symbol.
    N, O = me.ReferenceFrame("N"), me.Point("O")
    ball = me.Particle("ball", O.locatenew("P", (x + l) * N.x), m)
    with raises_naming("ball", "l") as info:
        Model("bad", [x], [m], bodies=[ball], frame=N, origin=O)
    assert "not declared" in str(info.value)


def test_symbol_declared_as_parameter_and_coordinate():
    with raises_naming("x"):
        Model("bad", [x], [m, sp.Symbol("x")], kinetic_energy=T_x)


NON_SYMPY = [pytest.param(f, b, id=f"{f}-{i}")
             for f in ("kinetic_energy", "potential_energy", "dissipation")
             for b, i in (("m*x'**2/2", "str"), ([x ** 2], "list"), ((x,), "tuple"))]
# None means "not given" for kinetic_energy (then the model has no kinetic energy at all); for
# the fields with a default of 0 it is a mistake.
NON_SYMPY += [pytest.param(f, None, id=f"{f}-None") for f in ("potential_energy", "dissipation")]


@pytest.mark.parametrize("field, bad", NON_SYMPY)
def test_non_sympy_expression(field, bad):
    kwargs = {"kinetic_energy": T_x, field: bad}
    with raises_naming(field) as info:
        Model("bad", [x], [m], **kwargs)
    assert type(bad).__name__ in str(info.value)


def test_kinetic_energy_not_given():
    with raises_naming("bad") as info:
        Model("bad", [x], [m])
    assert "kinetic energy" in str(info.value)


@pytest.mark.parametrize("bad", ["1", [1.0]], ids=["str", "list"])
def test_non_sympy_generalized_force(bad):
    with raises_naming("x") as info:
        Model("bad", [x], [m], kinetic_energy=T_x, generalized_forces={x: bad})
    assert "generalized force" in str(info.value)


@pytest.mark.parametrize("bad", [sp.Eq(T_x, 0), sp.ImmutableMatrix([T_x]), sp.Tuple(T_x)],
                         ids=["Eq", "ImmutableMatrix", "Tuple"])
def test_sympy_object_that_is_not_a_scalar_expression(bad):
    # A sympy object that is not a scalar expression must be refused like a string or a list,
    # with the field named, rather than fail inside the derivation.
    with raises_naming("kinetic_energy"):
        derive_equations(Model("bad", [x], [m], kinetic_energy=bad))


@pytest.mark.parametrize("bad", ["x", [x]], ids=["str", "list"])
def test_non_symbol_parameter(bad):
    with raises_naming(str(bad if isinstance(bad, str) else "x")):
        Model("bad", [x], [m, bad], kinetic_energy=T_x)


@pytest.mark.parametrize("key", [y, sp.Symbol("x"), "x", x.diff(t)], ids=["other_function", "plain_symbol",
                                                                         "string", "speed"])
def test_generalized_force_keyed_by_non_coordinate(key):
    with raises_naming(str(key)) as info:
        Model("bad", [x], [m], kinetic_energy=T_x, generalized_forces={key: 1})
    assert "not a coordinate" in str(info.value)


def test_function_of_time_that_is_not_a_coordinate_in_potential():
    f = me.dynamicsymbols("f")  # e.g. a prescribed support motion the user forgot to write out
    with raises_naming("f") as info:
        Model("bad", [x], [m, k], kinetic_energy=T_x, potential_energy=k * (x - f) ** 2 / 2)
    assert "potential" in str(info.value)


def test_function_of_time_that_is_not_a_coordinate_in_kinetic_energy():
    with raises_naming("y"):
        Model("bad", [x], [m], kinetic_energy=m * (x.diff(t) + y.diff(t)) ** 2 / 2)


def test_parameter_with_other_assumptions_is_named_clearly():
    # m declared without assumptions, but T uses m(positive=True): sympy treats them as different
    # symbols. The message must say why "m" is refused, not "uses m (declared: m)".
    with raises_naming("m") as info:
        Model("bad", [x], [sp.Symbol("m")], kinetic_energy=T_x)
    assert "assumption" in str(info.value)


def test_kinetic_energy_not_quadratic_in_speeds():
    with raises_naming("x_d"):
        derive_equations(Model("bad", [x], [m], kinetic_energy=m * x.diff(t) ** 4))


def test_coordinates_none():
    with pytest.raises(ModelError, match="coordinate"):
        Model("bad", None, [m], kinetic_energy=T_x)


def test_gravity_that_is_not_a_vector():
    N, O = me.ReferenceFrame("N"), me.Point("O")
    ball = me.Particle("ball", O.locatenew("P", x * N.x), m)
    with raises_naming("gravity"):
        Model("bad", [x], [m, g], bodies=[ball], gravity=-g, frame=N, origin=O)


def test_sympy_model_of_wrong_type():
    with raises_naming("sympy_model", "str"):
        Model("bad", parameters=[m], sympy_model="LagrangesMethod")


def test_sympy_model_with_undeclared_parameter():
    u = me.dynamicsymbols("u")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", x * N.x)
    P.set_vel(N, u * N.x)
    kane = me.KanesMethod(N, q_ind=[x], u_ind=[u], kd_eqs=[x.diff(t) - u])
    kane.kanes_equations([me.Particle("ball", P, m)], [(P, -k * x * N.x)])
    with raises_naming("k"):
        derive_equations(Model("bad", parameters=[m], sympy_model=kane))


def _bodies_model(**options):
    """A particle on x and a rod at angle theta, with the frames the options put vectors in."""
    x, theta = me.dynamicsymbols("x theta")
    m, g, k = sp.symbols("m g k", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    B = N.orientnew("B", "Axis", [theta, N.z])
    Z = me.ReferenceFrame("Z")  # oriented to nothing
    P = O.locatenew("P", x * N.x)
    G = P.locatenew("G", B.x)
    particle = me.Particle("p", P, m)
    rod = me.RigidBody("rod", G, B, m, (me.inertia(Z if options.get("inertia_in_Z") else B, 1, 1, 1), G))
    bodies = [particle, rod] + [particle] * bool(options.get("twice"))
    return Model("bodies", [x, theta], [m, g, k], bodies=bodies, frame=N, origin=O,
                 loads=[(P, k * Z.x)] if options.get("load_in_Z") else [],
                 gravity=-g * Z.y if options.get("gravity_in_Z") else None)


@pytest.mark.parametrize("option, culprit", [
    ("load_in_Z", r"load on P \(written in frame Z\) is not oriented relative to the inertial frame N"),
    ("gravity_in_Z", r"gravity \(written in frame Z\) is not oriented"),
    ("inertia_in_Z", r"inertia of body 'rod' \(written in frame Z\) is not oriented"),
    ("twice", "body 'p' is listed twice in bodies"),
])
def test_vectors_in_unconnected_frames_and_a_body_twice_are_named(option, culprit):
    """Found by review: sympy's bare "No connecting orientation path found between N and Z" for a
    load, gravity or inertia written in a frame with no orientation to N; a body listed twice had
    its mass counted twice (M[0, 0] = 3 m)."""
    with pytest.raises(ModelError, match=culprit):
        _bodies_model(**{option: True})


def test_a_notebook_shows_large_equations_as_text():
    """Found by review: a notebook cell ending with the equations of a 3-link spatial chain waited
    minutes for their display form (55 s for one entry). Beyond LATEX_NODE_LIMIT nodes in M and F
    the LaTeX form is declined (None: the notebook shows the text repr); the double pendulum's is
    given and holds its M."""
    from lagcodegen import catalog, derive_equations

    small = derive_equations(catalog.example("double_pendulum"))
    assert small._repr_latex_().startswith("$\\displaystyle")
    assert derive_equations(catalog.pendulum_chain(12))._repr_latex_() is None


def test_an_acceleration_in_a_kane_measurement_is_named_as_such():
    """Found by review (session 16): the refusal spoke of "a constraint on the accelerations"."""
    import sympy.physics.mechanics as me

    q, u = me.dynamicsymbols("q u")
    mass = sp.Symbol("m", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q * N.x)
    P.set_vel(N, u * N.x)
    kane = me.KanesMethod(N, [q], [u], kd_eqs=[q.diff() - u])
    kane.kanes_equations([me.Particle("p", P, mass)], [(P, -q * N.x)])
    with pytest.raises(ModelError, match=r"measurement 'a' contains the acceleration .*: only coordinates, speeds "
                                         r"and time may appear here \(measure what the state gives"):
        derive_equations(Model("kane_acceleration", parameters=[mass], sympy_model=kane,
                               measurements={"a": u.diff()}))
