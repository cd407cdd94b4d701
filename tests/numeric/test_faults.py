"""Failed runs and bad inputs: status codes, the kept samples, warnings and error messages.

Expected failure points come from independent computations: the explicit Euler recurrence
x+ = (I + h A) x of the stiff chain in numpy (A from the hand-written mass and stiffness
matrices), and the analytic mass matrices of the models built here.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.integrators import schemes
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import SimulationError, StabilityWarning, Status, simulate

IMPLICIT = ("implicit_midpoint", "backward_euler", "sdirk2", "radau_iia3")
CHAIN_X0 = (0.1, 0.05, -0.05, 0.0, 0.0, 0.0)


@pytest.fixture(scope="module")
def chain(compiled_example):
    return compiled_example("stiff_chain", methods=schemes.DEFAULT_METHODS)


@pytest.fixture(scope="module")
def double_pendulum(compiled_example):
    return compiled_example("double_pendulum", methods=schemes.DEFAULT_METHODS)


@pytest.fixture(scope="module")
def singular_at_origin(kernel_cache_dir):
    """T = m (q qd)^2 / 2, V = q^2 / 2: the 1x1 mass matrix m q^2 vanishes at q = 0."""
    m = sp.Symbol("m", positive=True)
    q = me.dynamicsymbols("q")
    model = Model("singular_at_origin", [q], (m,), kinetic_energy=m * (q * q.diff()) ** 2 / 2,
                  potential_energy=q ** 2 / 2, parameter_values={m: 1.0})
    return compile_model(model, methods=schemes.DEFAULT_METHODS)


def euler_overflow_step(h: float, x0, max_steps: int) -> int:
    """First step (1-based) at which explicit Euler on the stiff chain leaves the finite doubles,
    computed in numpy from M = I, K = [[2k, -k, 0], [-k, k + K, -K], [0, -K, K + k]], k = 1, K = 1e4."""
    k, K = 1.0, 1.0e4
    stiffness = np.array([[2 * k, -k, 0.0], [-k, k + K, -K], [0.0, -K, K + k]])
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-stiffness, np.zeros((3, 3))]])
    x = np.array(x0, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        for step in range(1, max_steps + 1):
            x = x + h * (A @ x)
            if not np.all(np.isfinite(x)):
                return step
    raise AssertionError("no overflow")


# -- non-finite state -----------------------------------------------------------------------
@pytest.mark.parametrize("stride", [1, 10])
def test_nonfinite_state_is_reported_with_the_failing_step(chain, stride):
    h, n_steps, t0 = 0.1, 1000, 0.5  # h w = 14.1, far outside Euler's region
    expected_step = euler_overflow_step(h, CHAIN_X0, n_steps)
    with pytest.warns(StabilityWarning), pytest.warns(RuntimeWarning, match=f"step {expected_step}"):
        traj = simulate(chain, CHAIN_X0, t0 + n_steps * h, h, "euler", t0=t0, stride=stride)
    assert traj.status == Status.NONFINITE_STATE and not traj.ok
    assert traj.failed_step == expected_step
    assert traj.failed_time == pytest.approx(t0 + (traj.failed_step - 1) * h, rel=1e-12)
    # Samples: every stride-th state of the steps that completed (0 .. failed_step - 1), all finite.
    assert len(traj.t) == (traj.failed_step - 1) // stride + 1
    assert np.all(np.isfinite(traj.x)) and np.all(np.isfinite(traj.t))
    assert traj.t[-1] <= traj.failed_time + 1e-12
    assert np.allclose(traj.t, t0 + stride * h * np.arange(len(traj.t)))
    with pytest.raises(SimulationError, match=f"step {expected_step}") as info:
        traj.check()
    assert info.value.trajectory is traj


def test_status_prints_its_name_and_keeps_its_value(chain):
    """print(traj.status) gave "0": IntEnum's str is the number. The C codes (LCG_*) stay."""
    assert [int(s) for s in Status] == [0, 1, 2, 3, 4, 5, 6, 7, 8]
    assert str(Status.OK) == f"{Status.OK}" == "OK" and f"{Status.NONFINITE_STATE:>16}" == " NONFINITE_STATE"
    assert f"{Status.NONFINITE_STATE:d}" == "2" and Status.NONFINITE_STATE == 2
    assert Status(5) is Status.SINGULAR_CONSTRAINTS and repr(Status.OK) == "<Status.OK: 0>"
    h, n_steps = 0.1, 1000
    expected_step = euler_overflow_step(h, CHAIN_X0, n_steps)
    with pytest.warns(StabilityWarning), pytest.warns(RuntimeWarning):
        failed = simulate(chain, CHAIN_X0, n_steps * h, h, "euler")
    assert str(failed.status) == "NONFINITE_STATE"
    text = repr(failed)
    assert text.startswith("Trajectory(method='euler', h=0.1, ")
    assert f"status=NONFINITE_STATE at step {expected_step} (t = {(expected_step - 1) * h:.6g})" in text
    ok = simulate(chain, CHAIN_X0, 0.01, 1e-3, "rk4")
    assert "11 samples, t = 0 .. 0.01" in repr(ok) and repr(ok).endswith("status=OK)")


def test_check_returns_an_ok_trajectory(chain):
    traj = simulate(chain, CHAIN_X0, 0.01, 1e-3, "rk4")
    assert traj.check() is traj and traj.failed_step is None and traj.failed_time is None


# -- Newton failure -------------------------------------------------------------------------
@pytest.mark.parametrize("method", IMPLICIT)
def test_newton_failure_on_an_absurd_step(double_pendulum, method):
    # h = 0.5 s is ~3 h w for the fast mode (5.79 rad/s) of a strongly nonlinear system: the
    # simplified Newton iteration with the Jacobian frozen at x0 cannot converge (30 iterations).
    h, x0 = 0.5, (0.4, -0.3, 0.0, 0.0)
    with pytest.warns(RuntimeWarning, match="Newton"):
        traj = simulate(double_pendulum, x0, 10 * h, h, method)
    assert traj.status == Status.NEWTON_FAILED
    assert traj.failed_step == 1 and traj.failed_time == 0.0
    assert traj.t.tolist() == [0.0] and np.array_equal(traj.x, [x0])
    with pytest.raises(SimulationError, match="Newton"):
        traj.check()


# -- singular mass matrix -------------------------------------------------------------------
@pytest.mark.parametrize("method", ["backward_euler", "rk4", "euler"])
def test_singular_mass_matrix_at_the_initial_state(singular_at_origin, method):
    # M = m q^2 = 0 at q = 0 (analytic).
    with pytest.warns(RuntimeWarning, match="singular"):
        traj = simulate(singular_at_origin, (0.0, 1.0), 1.0, 0.1, method, check_stability=False)
    assert traj.status == Status.SINGULAR_MASS_MATRIX
    assert traj.failed_step == 1 and traj.failed_time == 0.0 and len(traj.t) == 1
    with pytest.raises(SimulationError, match="singular"):
        traj.check()


def test_singular_mass_matrix_from_a_zero_mass(double_pendulum):
    # m2 = 0: M = [[m1 l1^2, 0], [0, 0]] (analytic, route "bodies"), singular for every q.
    with pytest.warns(RuntimeWarning, match="singular"):
        traj = simulate(double_pendulum, (0.3, 0.1, 0.0, 0.0), 1.0, 0.1, "implicit_midpoint", params={"m2": 0.0})
    assert traj.status == Status.SINGULAR_MASS_MATRIX and traj.failed_step == 1


@pytest.mark.parametrize("method", ["rk4", "euler", "symplectic_euler"])
def test_singular_mass_matrix_with_the_default_stability_check(singular_at_origin, method):
    # The stability check evaluates the Jacobian at x0 first; a singular M there must still end
    # as a SINGULAR_MASS_MATRIX run, not as an exception from the check.
    with pytest.warns(RuntimeWarning, match="singular"):
        traj = simulate(singular_at_origin, (0.0, 1.0), 1.0, 0.1, method)
    assert traj.status == Status.SINGULAR_MASS_MATRIX


@pytest.mark.parametrize("method, h, x0", [
    ("rk4", 0.5, (1.5, -1.0, 3.0, -3.0)),
    ("dopri5", 0.5, (1.5, -1.0, 3.0, -3.0)),
    ("implicit_midpoint", 0.2, (1.5, -1.0, 0.0, 0.0)),
])
def test_a_blow_up_is_never_a_singular_mass_matrix(double_pendulum, method, h, x0):
    # det M = l1^2 l2^2 m2 (m1 + m2 sin^2(q1 - q2)) >= 1 for unit parameters and every finite q
    # (analytic), so SINGULAR_MASS_MATRIX is impossible; the run does blow up (h w >> limits).
    with pytest.warns(RuntimeWarning):
        traj = simulate(double_pendulum, x0, 2000 * h, h, method, check_stability=False)
    assert not traj.ok
    assert traj.status in (Status.NONFINITE_STATE, Status.NEWTON_FAILED), traj.status


# -- bad inputs -------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def chain_fixed_K(compiled_example):
    """K folded into the code; only rk4 compiled in."""
    return compiled_example("stiff_chain", fixed={"K": 1.0e4}, methods=("rk4",))


@pytest.mark.parametrize("kwargs, culprit", [
    ({"method": "rk5"}, "rk5"),
    ({"params": {"mass": 1.0}}, "mass"),
    ({"params": {"k": math.inf}}, "k"),
    ({"params": {"K": math.nan}}, "K"),
    ({"x0": (math.nan, 0, 0, 0, 0, 0)}, "initial state is not finite"),
    ({"x0": (0.1, 0.0, 0.0, 0.0, 0.0)}, "6 values"),
    ({"x0": {"x1": 0.1, "x2": 0.0}}, "x3"),
    ({"x0": {"x1": 0.1, "x2": 0.0, "x3": 0.0, "y": 1.0}}, "y"),
    ({"t_end": 1.05}, "whole number of steps"),
    ({"h": 0.0}, "step h"),
    ({"t_end": 0.0}, "t_end"),
    ({"stride": 0}, "stride"),
    ({"stride": 2.0}, "stride"),
])
def test_bad_inputs_raise_value_error_naming_the_culprit(chain, kwargs, culprit):
    arguments = {"x0": CHAIN_X0, "t_end": 1.0, "h": 0.1, "method": "rk4"} | kwargs
    with pytest.raises(ValueError, match=rf"\b{culprit}\b"):
        simulate(chain, arguments.pop("x0"), arguments.pop("t_end"), arguments.pop("h"), **arguments)


def test_a_numpy_integer_stride_is_accepted(chain):
    traj = simulate(chain, CHAIN_X0, 0.01, 1e-3, "rk4", stride=np.int64(5))
    assert len(traj.t) == 3


def test_a_fixed_parameter_cannot_be_given_at_run_time(chain_fixed_K):
    assert "K" not in chain_fixed_K.layout.parameters
    with pytest.raises(ValueError, match=r"'K'.*fixed"):
        simulate(chain_fixed_K, CHAIN_X0, 1.0, 0.1, "rk4", params={"K": 2.0e4})
    simulate(chain_fixed_K, CHAIN_X0, 0.01, 1e-3, "rk4", params={"k": 2.0}).check()  # free ones still work


def test_a_method_not_compiled_in_is_rejected(chain_fixed_K):
    with pytest.raises(ValueError, match=r"'dopri5'.*compiled: rk4"):
        simulate(chain_fixed_K, CHAIN_X0, 1.0, 0.1, "dopri5")


def _kernel(system, suffix, x, params, size):
    """``lcg_<model>_<suffix>(t, x, p, out)`` -> (status, out)."""
    from lagcodegen.run.simulate import parameter_vector

    x = np.ascontiguousarray(x, dtype=np.float64)
    p = np.ascontiguousarray(parameter_vector(system, params), dtype=np.float64)
    out = np.zeros(size)
    function = getattr(system.lib, f"{system.layout.prefix}_{suffix}")
    status = function(0.0, system.ffi.from_buffer("double[]", x), system.ffi.from_buffer("double[]", p),
                      system.ffi.from_buffer("double[]", out, require_writable=True))
    return Status(status), out


@pytest.mark.parametrize("suffix, size", [("rhs", 4), ("accel", 2), ("jacobian", 16)])
def test_overflowing_derivatives_at_a_finite_state_are_not_ok(double_pendulum, suffix, size):
    # m1 = m2 = 1e300, g = 1e300 at a finite state: F ~ m g sin(q) ~ 1e600 overflows to inf while
    # M ~ 1e300 stays finite, so ud = inf / 1e300. The kernels used to return LCG_OK with inf in ud.
    huge = {"m1": 1e300, "m2": 1e300, "g": 1e300}
    status, out = _kernel(double_pendulum, suffix, [0.3, 0.1, 0.0, 0.0], huge, size)
    assert not np.all(np.isfinite(out))  # the overflow really happens (IEEE arithmetic)
    assert status == Status.NONFINITE_STATE
    # the same kernel at ordinary values is OK and finite
    status, out = _kernel(double_pendulum, suffix, [0.3, 0.1, 0.0, 0.0], None, size)
    assert status == Status.OK and np.all(np.isfinite(out))
