"""Bad arguments of `simulate`: every one raises before any C call, with an error naming it.

TypeError for a value of the wrong type (a string, None, a bool where a number or a flag
belongs), ValueError for a value out of range (NaN, infinities, h <= 0, more steps than C's
``long`` holds, a stride beyond the run). Before these checks some of them raised an
OverflowError from cffi, a TypeError from a comparison, or a ``float()`` error naming nothing.
The model is the catalog double pendulum: state q1, q2, q1_d, q2_d; free parameters m1, m2,
l1, l2, g.
"""
from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

from lagcodegen.run.arguments import OutputTooLargeError, StrideWarning, output_bytes
from lagcodegen.run.simulate import Status, simulate, warn_if_unstable

pytestmark = pytest.mark.compiler

X0 = (0.5, -0.3, 0.0, 0.0)
RUN = {"x0": X0, "t_end": 0.1, "h": 0.01}


@pytest.fixture(scope="module")
def pendulum(compiled_example):
    """Every output (jacobian for the stability pre-check, energy, points), rk4 and euler."""
    return compiled_example("double_pendulum", methods=("rk4", "euler"))


def run(system, **changes):
    arguments = RUN | changes
    return simulate(system, arguments.pop("x0"), arguments.pop("t_end"), arguments.pop("h"), **arguments)


@pytest.mark.parametrize("changes, error, culprit", [
    # the time grid
    ({"h": 1e-320}, ValueError, r"step h = 9.99989e-321 is inf steps.*2\^63"),  # was OverflowError: cannot convert float infinity
    ({"h": "0.001"}, TypeError, r"^h must be a real number, got '0.001'"),  # was a comparison TypeError
    ({"h": None}, TypeError, r"^h must be a real number, got None"),
    ({"h": True}, TypeError, r"^h must be a real number"),
    ({"h": -0.01}, ValueError, r"step h must be positive"),
    ({"h": math.nan}, ValueError, r"^h must be finite"),
    ({"t_end": math.inf}, ValueError, r"^t_end must be finite"),  # was OverflowError
    ({"t_end": "1"}, TypeError, r"^t_end must be a real number"),
    ({"t_end": 1e300, "h": 1.0}, ValueError, r"1e\+300 steps.*2\^63"),  # more steps than C long holds
    ({"t_end": 10 ** 400}, ValueError, r"^t_end = 1000.*not representable as a double"),
    ({"t_end": -0.1}, ValueError, r"t_end \(-0.1\) must be greater than t0"),
    ({"t0": None}, TypeError, r"^t0 must be a real number"),
    ({"t0": -math.inf}, ValueError, r"^t0 must be finite"),
    ({"t0": -1e308, "t_end": 1e308}, ValueError, r"t_end - t0 .* overflows"),
    ({"stride": 10 ** 30}, ValueError, r"stride = 10{30} exceeds the number of steps \(10\)"),  # was OverflowError
    ({"stride": 11}, ValueError, r"stride = 11 exceeds the number of steps \(10\)"),  # kept x0 only
    ({"stride": "2"}, ValueError, r"^stride must be a positive integer, got '2'"),
    ({"method": None}, TypeError, r"^method must be a method name"),
    ({"method": 4}, TypeError, r"^method must be a method name"),
    # the initial state, by name
    ({"x0": {"q1": "a", "q2": 0.0}}, TypeError, r"initial state variable 'q1'.*'a'"),
    ({"x0": ("0.5", 0.0, 0.0, 0.0)}, TypeError, r"initial state variable 'q1'"),
    ({"x0": (0.5, None, 0.0, 0.0)}, TypeError, r"initial state variable 'q2'.*None"),
    ({"x0": (0.5, 0.0, 0.0, 1j)}, TypeError, r"initial state variable 'q2_d'"),
    ({"x0": (0.5, 0.0, True, 0.0)}, TypeError, r"initial state variable 'q1_d'"),
    ({"x0": {"q1": 0.5, "q2": 0.0, "q1_d": math.inf}}, ValueError, r"not finite in q1_d"),
    ({"x0": (0.5, 0.0, 0.0, math.nan)}, ValueError, r"not finite in q2_d"),
    ({"x0": [[0.5, 0.0], [0.0, 0.0]]}, ValueError, r"needs 4 values \(q1, q2, q1_d, q2_d\).*shape \(2, 2\)"),
    ({"x0": (0.5, 0.0, 0.0)}, ValueError, r"needs 4 values"),
    ({"x0": "0.5"}, TypeError, r"^x0 must be a sequence"),
    ({"x0": 0.5}, TypeError, r"^x0 must be a sequence"),
    ({"x0": {"q1": 0.5, "q2": 0.0, "theta": 1.0}}, ValueError, r"unknown state variable.*'theta'"),
    # the parameters, by name
    ({"params": {"m2": "heavy"}}, TypeError, r"parameter 'm2'.*'heavy'"),  # was float()'s error
    ({"params": {"m2": None}}, TypeError, r"parameter 'm2'"),
    ({"params": {"l1": math.nan}}, ValueError, r"parameter 'l1' must be finite"),
    ({"params": {"g": -math.inf}}, ValueError, r"parameter 'g' must be finite"),
    ({"params": {"mass": 1.0}}, ValueError, r"unknown parameter 'mass'"),
    ({"params": [("m2", 1.0)]}, TypeError, r"^params must be a mapping"),
    # the options: bools only, and only what the model has
    ({"energy": "no"}, TypeError, r"^energy must be True or False"),
    ({"points": 1}, TypeError, r"^points must be True or False"),
    ({"residuals": "yes"}, TypeError, r"^residuals must be True or False"),
    ({"project": None}, TypeError, r"^project must be True or False"),
    ({"check_stability": "off"}, TypeError, r"^check_stability must be True or False"),
    ({"residuals": True}, ValueError, r"residuals=True needs constraints \(holonomic or on the velocities\); model 'double_pendulum'"),
    ({"project": True, "multipliers": True}, ValueError, r"project=True, multipliers=True need constraints"),
    ({"drift_tolerance": -1.0}, ValueError, r"drift_tolerance must be positive"),
    ({"drift_tolerance": "1e-6"}, TypeError, r"drift_tolerance must be a real number"),
])
def test_a_bad_argument_is_named(pendulum, changes, error, culprit):
    with pytest.raises(error, match=culprit):
        run(pendulum, **changes)


def test_energy_and_points_need_the_outputs(compiled_example):
    bare = compiled_example("double_pendulum", outputs=("rhs",), methods=("rk4",))
    with pytest.raises(ValueError, match=r"energy=True: model 'double_pendulum' was compiled without the 'energy'"):
        run(bare, energy=True)
    # the model has named points, but not their C function: the C driver would skip them and
    # return the points array unwritten (np.empty garbage) with status OK
    assert bare.layout.points
    with pytest.raises(ValueError, match=r"points=True: model 'double_pendulum'.*without the 'points' output"):
        run(bare, points=True)


def test_numpy_and_sympy_numbers_are_accepted(pendulum):
    import sympy as sp

    traj = run(pendulum, h=np.float32(0.015625), t_end=np.array(0.125), t0=sp.Integer(0),
               x0={"q1": sp.Float(0.5), "q2": np.int64(0)}, params={"m2": np.float64(1.5)}, energy=np.True_)
    assert traj.ok and len(traj.t) == 9 and traj.x[0, 0] == 0.5  # 0.125 / 0.015625 = 8 steps


# -- output size --------------------------------------------------------------------------------
def test_a_run_beyond_memory_is_refused_with_its_size_and_a_stride(pendulum):
    """t_end = 1e9, h = 1e-3: 1e12 + 1 samples of t and the 4 state variables, in doubles:
    (1e12 + 1) * 5 * 8 bytes = 36.4 TiB (hand count), refused before allocating."""
    with pytest.raises(OutputTooLargeError, match=r"1000000000001 samples: 36.4 TiB.*stride >= \d+") as info:
        run(pendulum, t_end=1e9, h=1e-3, check_stability=False)
    assert isinstance(info.value, ValueError)


def test_a_stride_that_does_not_divide_the_steps_warns_that_the_final_state_is_not_kept(pendulum):
    """Found by review: t_end = 1, h = 0.01, stride = 7 kept samples up to t = 0.98 and said nothing
    (run.x[-1] is not the state at t_end); 98 = 7 * 14 is the last multiple of 7 within 100 steps."""
    with pytest.warns(StrideWarning, match="stride = 7 does not divide the 100 steps: the samples end after step "
                                           "98, 2 step"):
        traj = run(pendulum, t_end=1.0, h=0.01, stride=7)
    assert traj.t[-1] == pytest.approx(0.98)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StrideWarning)
        assert run(pendulum, t_end=1.0, h=0.01, stride=5).t[-1] == pytest.approx(1.0)


def test_the_suggested_stride_fits(pendulum):
    """A 40-byte sample (t and 4 doubles) and a limit of 1000 bytes: 1001 samples do not fit, 25 do:
    1000 // 41 + 1 = 25 samples with stride 41, 1000 // 40 + 1 = 26 with stride 40."""
    with pytest.raises(OutputTooLargeError, match=r"1001 samples: 39.1 KiB, more than the limit of 1000 B \(max_output_bytes\)") as info:
        run(pendulum, t_end=1.0, h=1e-3, max_output_bytes=1000)
    stride = int(re.search(r"stride >= (\d+)", str(info.value)).group(1))
    assert stride == 41
    # and the least stride >= 41 that divides the 1000 steps, 50 (found by review: 41 warned that the
    # samples end before the final state)
    assert "(50, the least such that divides the 1000 steps, keeps the final state)" in str(info.value)
    traj = run(pendulum, t_end=1.0, h=1e-3, stride=stride, max_output_bytes=1000)
    assert traj.ok and traj.x.nbytes + traj.t.nbytes <= 1000
    with pytest.raises(OutputTooLargeError):
        run(pendulum, t_end=1.0, h=1e-3, stride=stride - 1, max_output_bytes=1000)


def test_output_bytes_counts_every_kept_array(pendulum):
    """Per sample: t (1), x (4), energy (1), 3 coordinates per named point; 11 samples."""
    layout = pendulum.layout
    n_points = len(layout.points)
    assert n_points == 2  # the two bobs of the catalog double pendulum
    assert output_bytes(layout, 100, 10) == 11 * 5 * 8
    assert output_bytes(layout, 100, 10, energy=True, points=True) == 11 * (6 + 3 * n_points) * 8
    assert output_bytes(layout, 100, 10, n_members=7) == 7 * 11 * 5 * 8
    traj = run(pendulum, t_end=1.0, h=0.01, stride=10, energy=True, points=True)
    kept = traj.t.nbytes + traj.x.nbytes + traj.energy.nbytes + traj.points.nbytes
    assert kept == output_bytes(layout, 100, 10, energy=True, points=True)


# -- the stability pre-check never crashes ------------------------------------------------------
def test_a_huge_parameter_does_not_crash_the_stability_check(pendulum):
    """m2 = 1e308 overflows the Jacobian (entries ~ m2^2): numpy's eigvals raised LinAlgError out of
    simulate. Now the check is skipped with a note, and the run reports its own status: never
    OK with non-finite samples."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = run(pendulum, params={"m2": 1e308}, t_end=1.0)
    notes = [str(w.message) for w in caught if "pre-check skipped" in str(w.message)]
    assert notes and "not finite" in notes[0]
    assert traj.status != Status.OK or np.all(np.isfinite(traj.x))
    p = np.array([1.0, 1e308, 1.0, 1.0, 9.81])
    assert pendulum.layout.parameters == ("m1", "m2", "l1", "l2", "g")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        assert warn_if_unstable(pendulum, np.array(X0), p, 0.01, "rk4") is False


def test_states_and_parameters_keyed_by_symbols_are_read_by_name(pendulum):
    # found by review: x0 keyed by sympy Symbols passed the name check (str(key)) and was then read
    # with x0.get(name), which found nothing: every value became 0 and the run said OK
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen.export.fmu import _state_start

    q1, q2, q1_d = sp.symbols("q1 q2 q1_d")
    by_string = run(pendulum, x0={"q1": 1.0, "q2": 0.5, "q1_d": 0.3}, params={"m2": 2.0})
    for x0, params in [({q1: 1.0, q2: 0.5, q1_d: 0.3}, {sp.Symbol("m2"): 2.0}),
                       ({me.dynamicsymbols("q1"): 1.0, me.dynamicsymbols("q2"): 0.5, "q1_d": 0.3}, {"m2": 2.0})]:
        np.testing.assert_array_equal(run(pendulum, x0=x0, params=params).x, by_string.x)
    assert by_string.x[0].tolist() == [1.0, 0.5, 0.3, 0.0]
    assert _state_start(pendulum.layout, {q1: 1.0, q2: 0.5}) == [1.0, 0.5, 0.0, 0.0]
    with pytest.raises(ValueError, match="x0 names 'q1' twice"):
        run(pendulum, x0={q1: 1.0, "q1": 2.0, "q2": 0.0})


def test_a_value_of_the_sign_a_parameter_is_declared_without_is_named(pendulum, tmp_path):
    """Found by review: --param m1=-1 for the double pendulum's m1 (declared positive=True) ran until
    a singular mass matrix, the message blaming the step and never naming m1. sympy simplified the
    equations under the assumption (sqrt(l**2) -> l), so they need not hold for such a value. A
    model's own value or a fixed one is refused; a run's is warned about by name and goes on (a
    sweep's member with a negative mass fails alone); 0 (a mass ratio's limit) is neither."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model, ModelError
    from lagcodegen.codegen.outputs import KernelError
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import ParameterSignWarning
    from lagcodegen.run.sweep import sweep

    with pytest.warns(ParameterSignWarning, match=r"parameter 'm1' = -1.0, but 'm1' is declared positive"):
        run(pendulum, params={"m1": -1.0})
    with pytest.warns(ParameterSignWarning, match=r"swept 'm2' \(member 1\) = -0.5, .*declared positive .*"
                                                  r"\(2 of 3 members\)"):
        sweep(pendulum, {"m2": [1.0, -0.5, -2.0]}, x0=X0, t_end=0.1, h=0.01)
    with pytest.warns(ParameterSignWarning) as caught:  # a bad base value: named once, as itself, not "swept"
        sweep(pendulum, {"m2": [1.0, 2.0]}, x0=X0, t_end=0.1, h=0.01, params={"m1": -1.0})
    signs = [str(w.message) for w in caught if issubclass(w.category, ParameterSignWarning)]
    assert len(signs) == 1 and signs[0].startswith("parameter 'm1' = -1.0"), signs
    with warnings.catch_warnings():
        warnings.simplefilter("error", ParameterSignWarning)
        run(pendulum, params={"m2": 0.0}, check_stability=False)
    x = sp.Symbol("x")
    q = me.dynamicsymbols("q")
    k = sp.Symbol("k", nonnegative=True)
    oscillator = dict(kinetic_energy=q.diff() ** 2 / 2, potential_energy=k * q ** 2 / 2)
    with pytest.raises(ModelError, match=r"parameter_values\['k'\] = -4.0, but 'k' is declared nonnegative"):
        Model("o", [q], [k], parameter_values={k: -4.0}, **oscillator)
    with pytest.raises(KernelError, match=r"fixed parameter 'k' = -4.0, but 'k' is declared nonnegative"):
        compile_model(Model("o", [q], [k], **oscillator), fixed={"k": -4.0}, methods=("rk4",), cache_dir=tmp_path)
    assert x.is_positive is None
    plain = sp.Symbol("k")  # no assumption: any value
    compile_model(Model("o", [q], [plain], parameter_values={"k": -4.0}, kinetic_energy=q.diff() ** 2 / 2,
                        potential_energy=plain * q ** 2 / 2), methods=("rk4",), cache_dir=tmp_path)
