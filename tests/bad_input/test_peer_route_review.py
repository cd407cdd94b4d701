"""Found by review (session 18, helper-71) of sympy models fed as their authors write them: make_rhs
read and wrote past the ends of a short state or short inputs, and a reaction named like a parameter
was silently dropped. The expected tension is Newton's law along the rod, by hand."""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.model import ModelError
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import make_rhs, reactions


def _free_particles(tmp_path):
    q = me.dynamicsymbols("q1:4")
    m, g = sp.symbols("m g")
    lagrangian = sum(m * qi.diff()**2 / 2 - m * g * qi for qi in q)
    method = me.LagrangesMethod(lagrangian, q)
    method.form_lagranges_equations()
    return compile_model(Model("three_particles", parameters=[m, g], sympy_model=method), methods=("rk4",),
                         cache_dir=tmp_path)


def test_make_rhs_refuses_a_state_of_the_wrong_size(tmp_path):
    system = _free_particles(tmp_path)
    f = make_rhs(system, {"m": 1.0, "g": 9.81})
    np.testing.assert_array_equal(f(0.0, np.arange(6.0)), [3.0, 4.0, 5.0, -9.81, -9.81, -9.81])  # q'' = -g
    for bad in (np.zeros(2), np.arange(10.0), np.zeros((2, 6))):
        with pytest.raises(ValueError, match=r"x must hold the 6 values q1, q2, q3, q1_d, q2_d, q3_d of one state"):
            f(0.0, bad)


def test_make_rhs_refuses_inputs_of_the_wrong_size(tmp_path):
    x = me.dynamicsymbols("x")
    force, torque = me.dynamicsymbols("F tau")
    m = sp.Symbol("m", positive=True)
    model = Model("pushed", [x], [m], kinetic_energy=m * x.diff()**2 / 2, generalized_forces={x: force + torque},
                  inputs=[force, torque], parameter_values={"m": 2.0})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    np.testing.assert_allclose(make_rhs(system, inputs=lambda t, s: [1.0, 3.0])(0.0, [0.0, 0.0]), [0.0, 2.0])
    for bad in ([1.0], [1.0, 2.0, 3.0]):
        with pytest.raises(ValueError, match=r"the inputs at t = 0.0 must be 2 values \(F, tau\)"):
            make_rhs(system, inputs=lambda t, s, bad=bad: bad)(0.0, [0.0, 0.0])


def _tensioned_pendulum(damping_name: str):
    th, w, ua, tension = me.dynamicsymbols("theta omega u_a T")
    m, length, g = sp.symbols("m l g")
    damping = sp.Symbol(damping_name)
    N = me.ReferenceFrame("N")
    B = N.orientnew("B", "Axis", [th, N.z])
    B.set_ang_vel(N, w * N.z)
    O = me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", -length * B.y)
    P.set_vel(N, P.pos_from(O).dt(N).subs(th.diff(), w) + ua * B.y)
    method = me.KanesMethod(N, [th], [w], kd_eqs=[th.diff() - w], u_auxiliary=[ua])
    method.kanes_equations([me.Particle("p", P, m)], [(P, -m * g * N.y + tension * B.y - damping * w * length * B.x)])
    return Model("tension", parameters=[m, length, g, damping], sympy_model=method)


def test_a_reaction_named_like_a_parameter_is_refused(tmp_path):
    with pytest.raises(ModelError, match=r"name 'T' is used by a parameter and by the reaction T\(t\)"):
        compile_model(_tensioned_pendulum("T"), methods=("rk4",), outputs=("rhs", "reactions"), cache_dir=tmp_path)
    # renamed, the tension is there: along the rod T = m g cos(theta) + m l omega^2 (Newton, by hand)
    system = compile_model(_tensioned_pendulum("c_d"), methods=("rk4",), outputs=("rhs", "reactions"),
                           cache_dir=tmp_path)
    assert system.layout.reactions == ("T",)
    got = reactions(system, [0.3, 1.0], {"m": 1.0, "l": 1.0, "g": 9.81, "c_d": 0.2})
    np.testing.assert_allclose(got, [9.81 * np.cos(0.3) + 1.0], rtol=1e-12)


def test_joint_speeds_left_undefined_by_lagranges_method_are_named():
    a1, a2, b1, b2 = me.dynamicsymbols("a1 a2 b1 b2")
    m1, m2, length, g = sp.symbols("m1 m2 l1 g")
    ceiling = me.RigidBody("C")
    bob1 = me.RigidBody("B1", mass=m1)
    bob2 = me.RigidBody("B2", mass=m2)
    pin = me.PinJoint("J1", ceiling, bob1, a1, b1, child_point=length * bob1.frame.y)
    slider = me.PrismaticJoint("J2", bob1, bob2, a2, b2, joint_axis=bob1.frame.y)
    system = me.System.from_newtonian(ceiling)
    system.add_joints(pin, slider)
    system.apply_uniform_gravity(-g * ceiling.frame.y)
    system.form_eoms(eom_method=me.LagrangesMethod)
    with pytest.raises(ModelError, match=r"the joints' speeds b1\(t\) are not the rates of their coordinates"):
        compile_model(Model("pin_slider", parameters=[m1, m2, length, g], sympy_model=system), methods=("rk4",))
