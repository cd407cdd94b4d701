"""The Whipple bicycle, the field's benchmark (Meijaard, Papadopoulos, Ruina and Schwab, Proc. R.
Soc. A 463 (2007) 1955-1982), built with lagcodegen's own constraints: the bodies route, the
front wheel's ground contact as a holonomic constraint (it fixes the frame pitch) and rolling
without slipping of both wheels as four velocity constraints, with multipliers.

The geometry, the frames and the parameter values follow sympy's own test of the same bicycle
(sympy/physics/mechanics/tests/test_kane3.py, BSD licence; there a KanesMethod with dependent
coordinates and speeds), with the wheel angles and the rear contact (x, y) made coordinates here.
Reference: the benchmark's linearized lean/steer state matrix printed in that test file (``Res``,
which sympy checks against its own linearization to 1e-12); the four eigenvalues of
``linearize_state``'s reduced matrix at upright straight running must equal its eigenvalues
(weave, capsize, castor), and the other six are the neutral directions (zero).
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from sympy import pi

from lagcodegen import Model, derive_equations
from lagcodegen.statics.consistent import consistent_state
from lagcodegen.statics.state_space import linearize_state


def benchmark_values() -> dict:
    """The benchmark bicycle's parameters in the model's geometry (sympy's test_kane3 conversion)."""
    rear, front, hta, trail, wheelbase = 0.3, 0.35, float(pi / 2 - pi / 10), 0.08, 1.02
    frame_x, frame_z, fork_x, fork_z = 0.3, 0.9, 0.9, 0.7
    rake = -(trail * np.sin(hta) - front * np.cos(hta))
    frame_length = wheelbase * np.sin(hta) - (rake - (front - rear) * np.cos(hta))
    frame_cg_norm = (frame_z - rear - (frame_x / np.sin(hta)) * np.cos(hta)) * np.sin(hta)
    frame_cg_par = frame_x / np.sin(hta) + (frame_z - rear - frame_x / np.sin(hta) * np.cos(hta)) * np.cos(hta)
    a, b = fork_z - front, wheelbase - fork_x
    c = np.hypot(a, b)
    fork_length = wheelbase * np.cos(hta) - (front - rear) * np.sin(hta)
    fork_cg_norm = rake + c * np.sin(np.pi / 2 - hta - np.arccos(a / c))
    fork_cg_par = c * np.cos((np.pi / 2 - hta) - np.arccos(a / c)) - fork_length
    return {"WFrad": front, "WRrad": rear, "htangle": hta, "forkoffset": rake, "forklength": fork_length,
            "framelength": frame_length, "forkcg1": fork_cg_par, "forkcg3": fork_cg_norm, "framecg1": frame_cg_norm,
            "framecg3": frame_cg_par, "Iwr11": 0.0603, "Iwr22": 0.12, "Iwf11": 0.1405, "Iwf22": 0.28,
            "Ifork11": 0.05892, "Ifork22": 0.06, "Ifork33": 0.00708, "Ifork31": 0.00756, "Iframe11": 9.2,
            "Iframe22": 11.0, "Iframe33": 2.8, "Iframe31": -2.4, "mfork": 4.0, "mframe": 85.0, "mwf": 3.0,
            "mwr": 2.0, "g": 9.81}


def whipple() -> Model:
    x, y, q1, q2, q3, q4, q5, q6 = me.dynamicsymbols("x y q1 q2 q3 q4 q5 q6")  # yaw, roll, rear wheel,
    values = benchmark_values()                                                # pitch, steer, front wheel
    P = {name: sp.Symbol(name) for name in values}
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    yaw = N.orientnew("Y", "Axis", [q1, N.z])
    roll = yaw.orientnew("R", "Axis", [q2, yaw.x])
    frame = roll.orientnew("Frame", "Axis", [q4 + P["htangle"], roll.y])
    rear_wheel = frame.orientnew("WR", "Axis", [q3, frame.y])
    frame_inertia_frame = frame.orientnew("TempFrame", "Axis", [-P["htangle"], frame.y])
    fork = frame.orientnew("Fork", "Axis", [q5, frame.x])
    fork_inertia_frame = fork.orientnew("TempFork", "Axis", [-P["htangle"], fork.y])
    front_wheel = fork.orientnew("WF", "Axis", [q6, fork.y])
    rear_contact = O.locatenew("WR_cont", x * N.x + y * N.y)
    rear_centre = rear_contact.locatenew("WR_mc", P["WRrad"] * roll.z)
    steer = rear_centre.locatenew("Steer", P["framelength"] * frame.z)
    frame_centre = rear_centre.locatenew("Frame_mc", -P["framecg1"] * frame.x + P["framecg3"] * frame.z)
    fork_centre = steer.locatenew("Fork_mc", -P["forkcg1"] * fork.x + P["forkcg3"] * fork.z)
    front_centre = steer.locatenew("WF_mc", P["forklength"] * fork.x + P["forkoffset"] * fork.z)
    front_contact = front_centre.locatenew(
        "WF_cont", P["WFrad"] * (me.dot(fork.y, yaw.z) * fork.y - yaw.z).normalize())
    bodies = [
        me.RigidBody("frame", frame_centre, frame, P["mframe"], (me.inertia(
            frame_inertia_frame, P["Iframe11"], P["Iframe22"], P["Iframe33"], 0, 0, P["Iframe31"]), frame_centre)),
        me.RigidBody("fork", fork_centre, fork, P["mfork"], (me.inertia(
            fork_inertia_frame, P["Ifork11"], P["Ifork22"], P["Ifork33"], 0, 0, P["Ifork31"]), fork_centre)),
        me.RigidBody("rear_wheel", rear_centre, rear_wheel, P["mwr"],
                     (me.inertia(frame, P["Iwr11"], P["Iwr22"], P["Iwr11"]), rear_centre)),
        me.RigidBody("front_wheel", front_centre, front_wheel, P["mwf"],
                     (me.inertia(fork, P["Iwf11"], P["Iwf22"], P["Iwf11"]), front_centre))]

    def contact_velocity(centre, wheel, contact):  # of the wheel's material point at the contact
        return centre.pos_from(O).dt(N) + wheel.ang_vel_in(N).cross(contact.pos_from(centre))

    rear = contact_velocity(rear_centre, rear_wheel, rear_contact)
    front = contact_velocity(front_centre, front_wheel, front_contact)
    return Model("whipple_bicycle", [x, y, q1, q2, q3, q4, q5, q6], list(P.values()), bodies=bodies,
                 gravity=-P["g"] * N.z, frame=N, origin=O,
                 constraints=[front_contact.pos_from(rear_contact).dot(yaw.z)],
                 motion_constraints=[rear.dot(yaw.x), rear.dot(yaw.y), front.dot(yaw.x), front.dot(yaw.y)],
                 parameter_values={P[name]: value for name, value in values.items()})


def benchmark_matrix(speed: float) -> np.ndarray:
    """``Res`` of sympy's test_kane3: the benchmark's lean/steer matrix at forward speed v."""
    v = speed
    return np.array([[0, 0, 1.0, 0], [0, 0, 0, 1.0],
                     [9.48977444677355, -0.891197738059089 * v ** 2 - 0.571523173729245, -0.105522449805691 * v,
                      -0.330515398992311 * v],
                     [11.7194768719633, -1.97171508499972 * v ** 2 + 30.9087533932407, 3.67680523332152 * v,
                      -3.08486552743311 * v]])


@pytest.fixture(scope="module")
def bicycle():
    return derive_equations(whipple())


def test_the_bicycle_has_one_holonomic_and_four_velocity_constraints(bicycle):
    assert bicycle.m == 5 and bicycle.n_holonomic == 1
    assert "holonomic and velocity constraints" in bicycle.route


def upright_eigenvalues(bicycle, speed: float) -> np.ndarray:
    """Eigenvalues of ``linearize_state``'s reduced matrix at upright straight running at ``speed``."""
    upright = dict.fromkeys(("x", "y", "q1", "q2", "q3", "q4", "q5", "q6"), 0.0)
    q0, u0 = consistent_state(bicycle, upright, {"q1": 0, "q2": 0, "q3": speed / 0.3, "q5": 0},
                              fix=tuple(upright))
    np.testing.assert_allclose(u0[:2], [speed, 0.0], atol=1e-12)  # the rear contact rolls forward at v
    linear = linearize_state(bicycle, list(q0) + list(u0), values={})
    assert linear.basis.shape == (16, 10)
    return linear.eigenvalues()


@pytest.mark.parametrize("speed", [0.0, 2.0, 4.0, 5.0, 6.0, 8.0, 10.0])
def test_upright_running_eigenvalues_equal_the_benchmark(bicycle, speed):
    """From 0 to 10 m/s; at 5 m/s: weave -0.775 +- 4.465i, capsize -0.323, castor -14.08
    (Meijaard et al., table 2)."""
    ours = upright_eigenvalues(bicycle, speed)
    reference = np.linalg.eigvals(benchmark_matrix(speed))
    for value in reference:
        assert np.abs(ours - value).min() < 1e-8 * max(1.0, abs(value)), (value, ours)
    assert np.sort(np.abs(ours))[:6].max() < 1e-6


def test_the_self_stable_speed_range_is_the_benchmarks(bicycle):
    """The weave and capsize speeds, 4.292 and 6.024 m/s (Meijaard et al. 2007; 4.2923825 and
    6.0242620 from the benchmark matrix by brentq): the largest real part of the non-neutral
    eigenvalues changes sign within +-0.005 m/s of each."""
    def largest_real_part(speed):
        values = upright_eigenvalues(bicycle, speed)
        return values[np.abs(values) > 1e-6].real.max()

    assert largest_real_part(4.2874) > 0 > largest_real_part(4.2974)
    assert largest_real_part(6.0193) < 0 < largest_real_part(6.0293)


def test_the_nonlinear_bicycle_rights_itself_at_5_and_falls_at_3_m_s(bicycle, tmp_path):
    """The compiled nonlinear model from upright with a roll rate of 0.5 rad/s: at 5 m/s (inside the
    benchmark's self-stable range, 4.29 to 6.02 m/s; every eigenvalue above has a negative real
    part) the roll dies out; at 3 m/s (weave unstable) it grows until the bicycle lies down."""
    import warnings

    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    system = compile_model(bicycle, methods=("rk4",), outputs=("rhs", "constraints"), cache_dir=tmp_path)
    upright = dict.fromkeys(("x", "y", "q1", "q2", "q3", "q4", "q5", "q6"), 0.0)
    peaks = {}
    for speed in (5.0, 3.0):
        q0, u0 = consistent_state(bicycle, upright, {"q1": 0, "q2": 0.5, "q3": speed / 0.3, "q5": 0},
                                  fix=tuple(upright))
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # the fallen bicycle reaches a singular configuration
            run = simulate(system, list(q0) + list(u0), t_end=5.0, h=1e-3, project=True, stride=10)
        roll = np.abs(run["q2"])
        peaks[speed] = (roll[:100].max(), roll[-100:].max(), run.ok)
    first, last, ok = peaks[5.0]
    assert ok and last < 0.2 * first
    first, last, _ = peaks[3.0]
    assert last > 3 * first
