"""`lagcodegen.run.sweep`: many members through one compiled kernel, checked member by member.

Independent source of every expected value: `lagcodegen.run.simulate.simulate` run alone with the
member's values. Every test runs against both C kernels of `sweep`: the scalar one drives the
same generated C step function (``lcg_<m>_step_any``) as `simulate`; the lane-group kernel, built
here with libm's sin/cos (``lane_trig="libm"``), evaluates the same printed expressions and stage
sums per lane. Both start from the same state at the same times ``t0 + (k - 1) h``, so states
and ``max |q|`` must agree bitwise (assert_array_equal). The energy drift is compared to ``max |E - E0|`` over the stride-1 energy
samples of `simulate`; the C evaluates both at the same times ``t0 + k h`` (``_record`` in
`simulate`, the tracking loop in `sweep`), so they agree to rounding; 1e-12 relative is asked.

Kernels (each compiled once per module through ``compiled_example`` of ``tests/conftest.py``):
the double pendulum (free m1 m2 l1 l2 g) serves every grid, table, thread and interruption test;
the stiff chain (springs k, K) provides members that diverge with explicit methods; a double
pendulum with g fixed at build time checks that fixed parameters cannot be swept.
"""
from __future__ import annotations

import threading
import time
import warnings

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

import lagcodegen.run.sweep as sweep_module
from lagcodegen.run.simulate import Status, simulate
from lagcodegen.run.sweep import CHUNK_FAILED, NOT_RUN, ChunkError, SweepWarning, sweep

pytestmark = pytest.mark.compiler

METHODS = ("euler", "rk4")
OUTPUTS = ("rhs", "energy")
# double pendulum: base state (q1, q2, q1_d, q2_d), a t0 != 0 so blow-up times are not just k h
X0 = (0.6, -0.4, 0.0, 0.3)
T0, T_END, H = 0.25, 2.25, 0.01
N_STEPS = 200
M2 = (0.5, 1.0, 2.0)
L2 = (0.5, 1.0, 1.5, 2.0)
Q1 = tuple(np.linspace(-1.2, 1.2, 7))
# the energy drift is ~1e-8 (rk4) to ~1 (euler); both routes evaluate E at the same times
ENERGY_RTOL = 1e-12
FIELDS = ("values", "x_final", "q_max", "energy_error", "status", "steps_done", "blowup_time", "t",
          "trajectories")


# Both C kernels behind sweep(): the lane-group kernel (lanes=8, with libm's sin/cos so that it
# must equal simulate bitwise too) and the scalar one (a build without lanes); see lanes.py.
KERNELS = {"lanes": dict(lane_trig="libm"), "scalar": dict(lanes=0)}


@pytest.fixture(scope="module", params=sorted(KERNELS))
def pendulum(compiled_example, request):
    return compiled_example("double_pendulum", outputs=OUTPUTS, methods=METHODS, **KERNELS[request.param])


@pytest.fixture(scope="module", params=sorted(KERNELS))
def stiff(compiled_example, request):
    return compiled_example("stiff_chain", outputs=OUTPUTS, methods=METHODS, **KERNELS[request.param])


def kernel_of(system) -> str:
    """The kernel sweep() runs: a build with lanes compiles its lane variant on first use."""
    return "lanes" if system.lane_build is not None else "scalar"


def alone(system, x0, params, *, t0=T0, t_end=T_END, h=H, method="rk4", stride=1):
    """The reference: one `simulate` run (energy at every kept sample); failures expected here."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a failed run warns; status says it too
        return simulate(system, x0, t_end, h, method, params=params, t0=t0, stride=stride,
                        energy=True, check_stability=False)


def member_inputs(result, base_x0, system):
    """(x0, params) of every member of ``result``: the base values overridden by its row."""
    layout = system.layout
    names = layout.coordinates + layout.speeds
    for row in result.values:
        x0, params = list(base_x0), {}
        for name, value in zip(result.columns, row):
            if name in names:
                x0[names.index(name)] = float(value)
            else:
                params[name] = float(value)
        yield x0, params


def assert_member_matches(result, m, trajectory, n):
    """Member m of a sweep equals the stride-1 `simulate` trajectory of the same values."""
    assert result.status[m] == trajectory.status
    assert result.steps_done[m] == len(trajectory.x) - 1
    assert_array_equal(result.x_final[m], trajectory.x[-1])
    assert_array_equal(result.q_max[m], np.max(np.abs(trajectory.x[:, :n]), axis=0))
    drift = np.max(np.abs(trajectory.energy - trajectory.energy[0]))
    assert_allclose(result.energy_error[m], drift, rtol=ENERGY_RTOL, atol=0)


def assert_results_equal(a, b):
    for name in FIELDS:
        got, want = getattr(a, name), getattr(b, name)
        if want is None:
            assert got is None, name
        else:
            assert_array_equal(got, want, err_msg=name)
    assert a.columns == b.columns and a.completed == b.completed


# --- one kernel, every member ------------------------------------------------------------------

@pytest.mark.parametrize("method", METHODS)
def test_parameter_grid_members_equal_simulate_alone(pendulum, method):
    result = sweep(pendulum, {"m2": M2, "l2": L2}, x0=X0, t0=T0, t_end=T_END, h=H, method=method)
    n = pendulum.layout.n
    assert result.kernel == kernel_of(pendulum)
    assert result.completed and result.n_members == len(M2) * len(L2)
    assert result.columns == ("m2", "l2")
    assert_array_equal(result.grid[0], M2)
    assert_array_equal(result.grid[1], L2)
    # C order: l2 varies fastest
    assert_array_equal(result.values, [(m2, l2) for m2 in M2 for l2 in L2])
    assert result.state_names == ("q1", "q2", "q1_d", "q2_d") and result.coordinate_names == ("q1", "q2")
    assert result.trajectories is None and result.t is None
    assert_array_equal(result.status, Status.OK)
    assert_array_equal(result.steps_done, N_STEPS)
    assert np.all(np.isnan(result.blowup_time))
    for m, (x0, params) in enumerate(member_inputs(result, X0, pendulum)):
        trajectory = alone(pendulum, x0, params, method=method)
        assert trajectory.ok
        assert_member_matches(result, m, trajectory, n)
    # on_grid: axis i of the reshaped field follows grid[i]
    x_final = result.on_grid("x_final")
    assert x_final.shape == (len(M2), len(L2), 2 * n)
    want = alone(pendulum, X0, {"m2": M2[2], "l2": L2[1]}, method=method).x[-1]
    assert_array_equal(x_final[2, 1], want)
    assert result.on_grid("status").shape == (len(M2), len(L2))


def test_initial_state_grid_members_equal_simulate_alone(pendulum):
    result = sweep(pendulum, {"q1": Q1}, x0=X0, t0=T0, t_end=T_END, h=H, params={"l2": 0.8})
    assert result.columns == ("q1",) and result.n_members == len(Q1)
    for m, q1 in enumerate(Q1):
        trajectory = alone(pendulum, (q1, *X0[1:]), {"l2": 0.8})
        assert trajectory.x[0, 0] == q1
        assert_member_matches(result, m, trajectory, pendulum.layout.n)


def test_member_table_equals_grid_members(pendulum):
    common = dict(x0=X0, t0=T0, t_end=T_END, h=H, trajectories=True, stride=10)
    grid = sweep(pendulum, {"m2": M2, "l2": L2}, **common)
    rows = [7, 0, 11, 5, 5]  # any order, repeats allowed
    table = sweep(pendulum, members={"m2": grid.values[rows, 0], "l2": grid.values[rows, 1]}, **common)
    assert table.grid is None and table.columns == ("m2", "l2")
    with pytest.raises(ValueError, match="not a Cartesian grid"):
        table.on_grid("x_final")
    for name in ("values", "x_final", "q_max", "energy_error", "status", "steps_done", "blowup_time",
                 "trajectories"):
        assert_array_equal(getattr(table, name), getattr(grid, name)[rows], err_msg=name)
    assert_array_equal(table.t, grid.t)


@pytest.mark.parametrize("threads", (1, 2, 3))
@pytest.mark.parametrize("chunk_size", (1, 7, None))
def test_results_do_not_depend_on_threads_or_chunks(pendulum, threads, chunk_size):
    # includes a negative mass (7 failing members) so statuses and NaN tails are compared too
    grid = {"m2": (-0.5, 0.5, 1.0, 1.5, 2.0), "q1": Q1}
    common = dict(x0=X0, t0=T0, t_end=T_END, h=H, trajectories=True, stride=10)
    baseline = sweep(pendulum, grid, threads=1, chunk_size=10**6, **common)
    result = sweep(pendulum, grid, threads=threads, chunk_size=chunk_size, **common)
    assert_array_equal(baseline.status[:len(Q1)], Status.SINGULAR_MASS_MATRIX)
    assert_results_equal(result, baseline)


# --- trajectories -------------------------------------------------------------------------------

def test_trajectories_only_when_asked_and_equal_to_simulate_with_stride(pendulum):
    stride = 7
    plain = sweep(pendulum, {"m2": M2}, x0=X0, t0=T0, t_end=T_END, h=H)
    assert plain.trajectories is None and plain.t is None
    result = sweep(pendulum, {"m2": M2}, x0=X0, t0=T0, t_end=T_END, h=H, trajectories=True, stride=stride)
    n_out = N_STEPS // stride + 1
    assert result.trajectories.shape == (len(M2), n_out, 2 * pendulum.layout.n)
    assert result.t.shape == (n_out,)
    # keeping samples does not change the per-member summaries
    for name in ("x_final", "q_max", "energy_error", "status", "steps_done"):
        assert_array_equal(getattr(result, name), getattr(plain, name), err_msg=name)
    for m, m2 in enumerate(M2):
        trajectory = alone(pendulum, X0, {"m2": m2}, stride=stride)
        assert_array_equal(result.trajectories[m], trajectory.x)
        # sweep: t0 + (h stride) j in Python; simulate: t0 + k h in C, k = stride j (1 ulp apart)
        assert_allclose(result.t, trajectory.t, rtol=0, atol=1e-13)


# --- per-member failures ------------------------------------------------------------------------

def test_negative_mass_member_fails_alone(pendulum):
    m2 = (1.0, -1.0, 2.0)
    common = dict(x0=X0, t0=T0, t_end=T_END, h=H, trajectories=True, stride=10)
    result = sweep(pendulum, {"m2": m2}, **common)
    assert result.completed
    assert_array_equal(result.status, [Status.OK, Status.SINGULAR_MASS_MATRIX, Status.OK])
    # the first step's mass-matrix factorisation fails: nothing done, blow-up at t0
    assert_array_equal(result.steps_done, [N_STEPS, 0, N_STEPS])
    assert_array_equal(result.blowup_time, [np.nan, T0, np.nan])
    assert_array_equal(result.x_final[1], X0)  # the last finite state is the initial one
    assert_array_equal(result.q_max[1], np.abs(X0[:2]))
    assert_array_equal(result.trajectories[1, 0], X0)
    assert np.all(np.isnan(result.trajectories[1, 1:]))
    reference = alone(pendulum, X0, {"m2": -1.0})
    assert reference.status == Status.SINGULAR_MASS_MATRIX and reference.failed_time == T0
    # the healthy members are unaffected by their failing neighbour
    healthy = sweep(pendulum, {"m2": (1.0, 2.0)}, **common)
    for name in ("x_final", "q_max", "energy_error", "status", "steps_done", "trajectories"):
        assert_array_equal(getattr(result, name)[[0, 2]], getattr(healthy, name), err_msg=name)


STIFF_X0 = (0.1, 0.0, -0.05, 0.0, 0.0, 0.0)
# K = 1, 1e2: h w <= 0.14, stable (euler grows by < 10x over 200 steps); K = 1e10, 1e14:
# w = sqrt(2 K) ~ 1e5..1e7 rad/s, h w >> 2.83 (rk4's imaginary-axis limit) and every explicit
# step multiplies the stiff mode by ~ (h w)^order: overflow within the 200 steps
STIFF_K = (1.0, 1e2, 1e10, 1e14)


@pytest.mark.parametrize("method", METHODS)
def test_stiff_members_report_nonfinite_state(stiff, method):
    t0, t_end, h, stride = 0.5, 2.5, 0.01, 10
    result = sweep(stiff, {"K": STIFF_K}, x0=STIFF_X0, t0=t0, t_end=t_end, h=h, method=method,
                   trajectories=True, stride=stride)
    assert_array_equal(result.status, [Status.OK, Status.OK, Status.NONFINITE_STATE, Status.NONFINITE_STATE])
    for m, K in enumerate(STIFF_K):
        reference = alone(stiff, STIFF_X0, {"K": K}, t0=t0, t_end=t_end, h=h, method=method)
        assert result.status[m] == reference.status
        assert result.steps_done[m] == len(reference.x) - 1
        assert_array_equal(result.q_max[m], np.max(np.abs(reference.x[:, :3]), axis=0))
        kept = (len(reference.x) - 1) // stride + 1
        assert_array_equal(result.trajectories[m, :kept], reference.x[::stride])
        assert np.all(np.isnan(result.trajectories[m, kept:]))
        if reference.ok:
            assert np.isnan(result.blowup_time[m])
            assert_array_equal(result.x_final[m], reference.x[-1])
        else:
            assert t0 < result.blowup_time[m] < t_end
            assert result.blowup_time[m] == pytest.approx(reference.failed_time, rel=1e-14)
    # the stable members equal a sweep without the diverging ones
    calm = sweep(stiff, {"K": STIFF_K[:2]}, x0=STIFF_X0, t0=t0, t_end=t_end, h=h, method=method)
    for name in ("x_final", "q_max", "energy_error", "steps_done"):
        assert_array_equal(getattr(result, name)[:2], getattr(calm, name), err_msg=name)


@pytest.mark.parametrize("method", METHODS)
def test_diverged_member_keeps_last_finite_state(stiff, method):
    """SweepResult.x_final: "the last finite state when a member failed" (sweep.py docstring)."""
    t0, t_end, h = 0.5, 2.5, 0.01
    result = sweep(stiff, {"K": STIFF_K[2:]}, x0=STIFF_X0, t0=t0, t_end=t_end, h=h, method=method)
    assert_array_equal(result.status, Status.NONFINITE_STATE)
    for m, K in enumerate(STIFF_K[2:]):
        reference = alone(stiff, STIFF_X0, {"K": K}, t0=t0, t_end=t_end, h=h, method=method)
        assert np.all(np.isfinite(result.x_final[m])), result.x_final[m]
        assert_array_equal(result.x_final[m], reference.x[-1])


# --- bad input ----------------------------------------------------------------------------------

COMMON = dict(x0=X0, t_end=T_END, t0=T0, h=H)


@pytest.mark.parametrize("kwargs, match", [
    ({"grid": {"m9": (1.0, 2.0)}}, r"'m9'.*m1, m2, l1, l2, g"),
    ({"grid": {"q9": (1.0,)}}, r"'q9'.*q1, q2, q1_d, q2_d"),
    ({"grid": {}}, r"grid is empty"),
    ({"grid": {"m2": M2, "l2": []}}, r"'l2' has no values"),
    ({"grid": {"m2": (1.0, np.nan)}}, r"swept 'm2' = nan \(member 1\) is not finite"),
    ({"grid": {"l1": (1.0,), "q1": (0.1, np.inf)}}, r"swept 'q1' = inf \(member 1\) is not finite"),
    # found by review (session 16): one NaN among many members was named by its column only
    ({"members": {"m2": (1.0,) * 7 + (np.nan,) + (1.0,) * 5}}, r"swept 'm2' = nan \(member 7\) is not finite"),
    ({"members": {"m2": (1.0, 2.0), "l2": (1.0,)}}, r"equally long.*'m2': 2, 'l2': 1"),
    ({"members": {}}, r"member table is empty"),
    ({"grid": {"m2": M2}, "members": {"m2": M2}}, r"exactly one of grid= .* or members="),
    ({}, r"exactly one of grid= .* or members="),
    ({"grid": {"m2": M2}, "method": "rk5"}, r"'rk5'.*compiled: euler, rk4"),
    ({"grid": {"m2": M2}, "method": "dopri5"}, r"'dopri5' is not compiled"),
    ({"grid": {"m2": M2}, "stride": 0}, r"stride"),
])
def test_bad_input_names_the_culprit(pendulum, kwargs, match):
    with pytest.raises(ValueError, match=match):
        sweep(pendulum, **COMMON, **kwargs)


def test_fixed_parameter_cannot_be_swept(compiled_example):
    fixed_g = compiled_example("double_pendulum", outputs=("rhs",), methods=("rk4",), fixed={"g": 9.81})
    assert "g" not in fixed_g.layout.parameters
    with pytest.raises(ValueError, match=r"'g' is fixed at build time.*free parameters: m1, m2, l1, l2$"):
        sweep(fixed_g, {"g": (9.81, 1.62)}, **COMMON)
    # the free ones still sweep through the same kernel
    assert sweep(fixed_g, {"m2": M2}, **COMMON).completed


def test_a_member_starting_off_its_constraints_is_named(compiled_example):
    # found by review: simulate warns of a start off x^2 + y^2 = l^2, sweep said nothing. (0, -1) is
    # on the constraint for l = 1 and off it by |1 - 4| = 3 for l = 2 (by hand).
    from lagcodegen.run.drift import ConstraintDriftWarning

    system = compiled_example("cartesian_pendulum", outputs=("rhs", "constraints"), methods=("rk4",))
    with pytest.warns(ConstraintDriftWarning, match=r"1 member\(s\) start off.*member 1 \(l = 2\) with 3"):
        result = sweep(system, {"l": [1.0, 2.0]}, x0={"x": 0.0, "y": -1.0}, t_end=0.01, h=1e-3)
    assert result.completed
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConstraintDriftWarning)
        sweep(system, members={"l": [1.0, 2.0], "y": [-1.0, -2.0]}, x0={"x": 0.0}, t_end=0.01, h=1e-3)


def test_members_that_drift_off_their_constraints_are_named_as_simulate_warns(compiled_example):
    # found by review: a sweep kept no residuals and said nothing of members that ended off their
    # constraints with status OK. The Cartesian pendulum from (1, 0) at rest with RK4 at h = 0.05
    # over 10 s ends |phi| = 0.044 off (simulate's own residuals, the second route, warn of it);
    # with h = 1e-3 and projection it stays on.
    from lagcodegen.run.drift import ConstraintDriftWarning

    system = compiled_example("cartesian_pendulum", outputs=("rhs", "constraints"), methods=("rk4",))
    with pytest.warns(ConstraintDriftWarning, match="the run drifted off the constraints"):
        simulate(system, {"x": 1.0, "y": 0.0}, t_end=10.0, h=0.05)
    with pytest.warns(ConstraintDriftWarning, match=r"1 member\(s\) of model .* drifted off the constraints .* "
                                                     r"member 0 \(g = 9.81\)"):
        result = sweep(system, {"g": [9.81]}, x0={"x": 1.0, "y": 0.0}, t_end=10.0, h=0.05)
    assert result.status[0] == Status.OK
    with warnings.catch_warnings():
        warnings.simplefilter("error", ConstraintDriftWarning)
        sweep(system, {"g": [9.81]}, x0={"x": 1.0, "y": 0.0}, t_end=1.0, h=1e-3, project=True)


def test_a_swept_value_beyond_the_float_range_is_named(compiled_example):
    # found by review: 1e39 became inf in the float kernel and the member failed as a singular mass matrix
    system = compiled_example("double_pendulum", precision="float", outputs=("rhs",), methods=("rk4",))
    with pytest.raises(ValueError, match=r"swept 'm2' = 1e\+39 \(member 1\) is beyond the range of the float kernel"):
        sweep(system, {"m2": [1.0, 1e39]}, **COMMON)
    with pytest.raises(ValueError, match=r"swept 'q1_d' = -1e\+39 \(member 0\)"):
        sweep(system, members={"q1_d": [-1e39]}, **COMMON)


# --- Ctrl-C ------------------------------------------------------------------------------------

N_CHUNK, CHUNK = 6, 2  # 12 members in 6 chunks on 1 thread (FIFO: chunk j is the (j+1)-th call)


def test_interrupt_keeps_finished_chunks(pendulum, monkeypatch):
    """KeyboardInterrupt in the main thread (inside `wait`) while chunk 2 is in the C call.

    Chunks 0, 1 have finished; chunk 2 is running (a C call cannot be interrupted, so it runs to
    its end and is kept); chunks 3..5 are queued and must be cancelled: NOT_RUN. Chunk 2 waits
    until the sweep has cancelled the queued futures before finishing, so the outcome does not
    depend on thread timing.
    """
    grid = {"q1": np.linspace(-1.0, 1.0, N_CHUNK * CHUNK)}
    full = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H, threads=1)
    real_call = sweep_module._call
    calls, futures = [], []
    in_flight = threading.Event()

    def call(job, xs, ps, out):
        calls.append(len(xs))
        if len(calls) == 3:  # chunk 2: Ctrl-C arrives while it runs
            in_flight.set()
            deadline = time.monotonic() + 10.0
            while sum(f.cancelled() for f in futures) < N_CHUNK - 3 and time.monotonic() < deadline:
                time.sleep(0.005)
        real_call(job, xs, ps, out)

    def interrupted_wait(fs, timeout=None, return_when=None):
        futures.extend(fs)  # the first call sees every chunk's future
        assert in_flight.wait(timeout=10.0)
        raise KeyboardInterrupt

    monkeypatch.setattr(sweep_module, "_call", call)
    monkeypatch.setattr(sweep_module, "wait", interrupted_wait)
    result = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H, threads=1, chunk_size=CHUNK)
    assert not result.completed
    assert len(calls) == 3, "queued chunks ran after the interruption"
    done = slice(0, 3 * CHUNK)
    for name in ("x_final", "q_max", "energy_error", "status", "steps_done", "blowup_time"):
        assert_array_equal(getattr(result, name)[done], getattr(full, name)[done], err_msg=name)
    rest = slice(3 * CHUNK, None)
    assert_array_equal(result.status[rest], NOT_RUN)
    assert NOT_RUN == -1
    assert_array_equal(result.steps_done[rest], 0)
    for name in ("x_final", "q_max", "energy_error", "blowup_time"):
        assert np.all(np.isnan(getattr(result, name)[rest])), name
    assert_array_equal(result.values, full.values)


def test_interrupt_raised_in_worker_keeps_finished_chunks(pendulum, monkeypatch):
    """The KeyboardInterrupt surfaces through ``future.result()`` instead (a worker's C call
    raising it): chunks 0, 1 are kept, every later chunk is NOT_RUN."""
    grid = {"q1": np.linspace(-1.0, 1.0, N_CHUNK * CHUNK)}
    full = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H)
    real_call = sweep_module._call
    calls = []

    def call(job, xs, ps, out):
        calls.append(len(xs))
        if len(calls) > 2:
            raise KeyboardInterrupt
        real_call(job, xs, ps, out)

    monkeypatch.setattr(sweep_module, "_call", call)
    result = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H, threads=1, chunk_size=CHUNK)
    assert not result.completed
    done = slice(0, 2 * CHUNK)
    for name in ("x_final", "q_max", "energy_error", "status", "steps_done"):
        assert_array_equal(getattr(result, name)[done], getattr(full, name)[done], err_msg=name)
    assert_array_equal(result.status[2 * CHUNK:], NOT_RUN)
    assert np.all(np.isnan(result.x_final[2 * CHUNK:]))


def failing_chunk_call(real_call, bad_q1: float, error: BaseException):
    """A `_call` that raises ``error`` for the chunk holding the member with q1 == bad_q1 (as a
    lost worker or a bug would) and runs the real C call for every other chunk."""
    def call(job, xs, ps, out):
        if np.any(xs[:, 0] == bad_q1):
            raise error
        real_call(job, xs, ps, out)
    return call


@pytest.mark.parametrize("threads", [1, 3])
def test_a_failed_chunk_keeps_the_other_members(pendulum, monkeypatch, threads):
    """Chunk 2 (members 4, 5) raises: before, the exception left sweep() and every finished
    member was lost. Now its members are CHUNK_FAILED (NaN results), the others equal a clean
    sweep of the same grid (the reference, itself checked against `simulate` above), the sweep
    says completed=False, lists the error and warns naming the members and the exception."""
    grid = {"q1": np.linspace(-1.0, 1.0, N_CHUNK * CHUNK)}
    full = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H, threads=threads, chunk_size=CHUNK)
    bad = slice(2 * CHUNK, 3 * CHUNK)
    monkeypatch.setattr(sweep_module, "_call", failing_chunk_call(sweep_module._call, grid["q1"][4],
                                                                  MemoryError("out of memory in chunk")))
    with pytest.warns(SweepWarning, match=r"members 4 to 5 failed \(MemoryError: out of memory in chunk\)"):
        result = sweep(pendulum, grid, x0=X0, t0=T0, t_end=T_END, h=H, threads=threads, chunk_size=CHUNK)
    assert not result.completed
    assert result.errors == (ChunkError(4, 6, "MemoryError: out of memory in chunk"),)
    assert_array_equal(result.status[bad], CHUNK_FAILED)
    assert CHUNK_FAILED == -2 and CHUNK_FAILED not in {int(s) for s in Status} | {NOT_RUN}
    assert_array_equal(result.steps_done[bad], 0)
    for name in ("x_final", "q_max", "energy_error", "blowup_time"):
        assert np.all(np.isnan(getattr(result, name)[bad])), name
    kept = np.ones(result.n_members, bool)
    kept[bad] = False
    for name in ("x_final", "q_max", "energy_error", "status", "steps_done", "blowup_time"):
        assert_array_equal(getattr(result, name)[kept], getattr(full, name)[kept], err_msg=name)


# --- progress bar -------------------------------------------------------------------------------

@pytest.fixture
def bars(monkeypatch):
    """Every tqdm bar the sweep creates (`_progress_bar` imports tqdm.auto.tqdm when called)."""
    import tqdm.auto

    created = []

    class Recording(tqdm.auto.tqdm):
        def __init__(self, *args, **kwargs):
            created.append(kwargs)
            super().__init__(*args, **kwargs)

    monkeypatch.setattr(tqdm.auto, "tqdm", Recording)
    return created


def test_progress_true_shows_a_bar(pendulum, bars, capsys):
    sweep(pendulum, {"m2": M2}, x0=X0, t0=T0, t_end=T_END, h=H, progress=True)
    assert len(bars) == 1 and bars[0]["total"] == len(M2)
    err = capsys.readouterr().err
    assert f"0/{len(M2)}" in err and "member/s" in err


def test_progress_false_shows_nothing(pendulum, bars, capsys):
    sweep(pendulum, {"m2": M2}, x0=X0, t0=T0, t_end=T_END, h=H, progress=False)
    assert bars == []
    assert capsys.readouterr().err == ""


def test_progress_default_is_silent_for_a_short_sweep(pendulum, bars, capsys):
    sweep(pendulum, {"m2": M2}, x0=X0, t0=T0, t_end=T_END, h=H)  # milliseconds, bar delay ~1 s
    assert capsys.readouterr().err == ""


def test_a_drifting_member_is_named_by_its_own_index_among_failed_ones(compiled_example):
    """The end check reads the members that ended OK through one buffer (a loop over members took 30 us
    each; found by review): the one named must be the drifting one, not its place among those checked.
    As above, g = 9.81 at h = 0.05 over 10 s ends 0.044 off; g = 1e12 blows up (not OK); g = 0 stays at
    rest on the constraint."""
    from lagcodegen.run.drift import ConstraintDriftWarning

    system = compiled_example("cartesian_pendulum", outputs=("rhs", "constraints"), methods=("rk4",))
    with pytest.warns(ConstraintDriftWarning, match=r"1 member\(s\) of model .* drifted off the constraints .* "
                                                     r"member 1 \(g = 9.81\)"):
        result = sweep(system, {"g": [1e12, 9.81, 0.0]}, x0={"x": 1.0, "y": 0.0}, t_end=10.0, h=0.05)
    assert result.status[0] != Status.OK and result.status[1] == Status.OK and result.status[2] == Status.OK
