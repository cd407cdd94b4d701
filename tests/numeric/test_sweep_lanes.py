"""The lane-group sweep kernel (``lcg_<m>_sweep_lanes``, `lane_kernel.py`) against the scalar one.

Independent source of every expected value: the scalar kernel ``lcg_<m>_sweep`` of the same
build (members one after another, libm's sin/cos), itself checked against `simulate` in
``test_sweep.py`` (where the lane kernel, built with libm trig, must match it bitwise too).
Here the lane kernel uses its branch-free sin/cos: a member whose trig arguments stay beyond
``LCG_TRIG_LIMIT`` goes through the scalar fallback with libm and must match bitwise; other
members differ by the polynomials' rounding only, which over the short runs below stays far
under 1e-9 (the double pendulum at h = 0.01 for 100 steps; measured ~1e-13).
"""
from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose, assert_array_equal

from lagcodegen.codegen.lane_kernel import DEFAULT_LANES
from lagcodegen.run.simulate import Status, work_size
from lagcodegen.run.sweep import sweep

pytestmark = pytest.mark.compiler

METHODS = ("euler", "rk4", "dopri5", "backward_euler")
X0 = (0.6, -0.4, 0.0, 0.3)
COMMON = dict(x0=X0, t0=0.25, t_end=1.25, h=0.01, progress=False)
FIELDS = ("x_final", "q_max", "energy_error", "trajectories")
STATES_ATOL = {"double": 1e-9, "float": 2e-3}  # fast vs libm sin/cos, 100 steps


@pytest.fixture(scope="module")
def pendulum(compiled_example):
    return compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=METHODS)


def both(system, grid, **kwargs):
    options = {**COMMON, **kwargs}
    lanes = sweep(system, grid, kernel="lanes", **options)
    scalar = sweep(system, grid, kernel="scalar", **options)
    assert (lanes.kernel, scalar.kernel) == ("lanes", "scalar")
    assert_array_equal(lanes.status, scalar.status)
    assert_array_equal(lanes.steps_done, scalar.steps_done)
    return lanes, scalar


@pytest.mark.parametrize("method", ("euler", "rk4", "dopri5"))
def test_fast_trig_lanes_match_scalar_kernel(pendulum, method):
    grid = {"m2": (0.5, 1.0, 2.0), "q1": np.linspace(-2.5, 2.5, 7)}  # 21 members: a partial group
    lanes, scalar = both(pendulum, grid, method=method, trajectories=True, stride=3)
    assert_array_equal(lanes.status, Status.OK)
    for name in FIELDS:
        assert_allclose(getattr(lanes, name), getattr(scalar, name), rtol=0, atol=STATES_ATOL["double"],
                        err_msg=name)


def test_arguments_beyond_the_fast_range_use_libm_bitwise(pendulum):
    """q1, q2 near 1e12 keep every sin/cos argument beyond LCG_TRIG_LIMIT: the lane falls back to
    the scalar dynamics and energy with libm at every stage, so it equals the scalar kernel
    exactly; its group neighbours (small angles) take the polynomial path."""
    far = 1.0e12
    members = {"q1": (far, 0.3, far + 0.5, -0.2), "q2": (far, 0.1, -far, 0.4)}
    options = {**COMMON, "method": "rk4", "trajectories": True}
    lanes = sweep(pendulum, members=members, kernel="lanes", **options)
    scalar = sweep(pendulum, members=members, kernel="scalar", **options)
    for name in FIELDS:
        got, want = getattr(lanes, name), getattr(scalar, name)
        assert_array_equal(got[[0, 2]], want[[0, 2]], err_msg=name)
        assert_allclose(got[[1, 3]], want[[1, 3]], rtol=0, atol=STATES_ATOL["double"], err_msg=name)


@pytest.mark.parametrize("method", ("euler", "rk4"))
def test_failing_lanes_do_not_disturb_their_group(pendulum, method):
    """Negative and zero masses (singular M from the first step) and a huge speed (non-finite
    state after a few steps) share lane groups with healthy members: statuses, steps and the
    last finite states equal the scalar kernel's, and each healthy member's results equal those
    of a sweep over the healthy members alone (so the failures changed nothing around them)."""
    m2 = (1.0, -1.0, 2.0, 0.0, 1.5, 1.0, 0.7, 1.2, -0.5, 1.0, 0.9)
    speed = (0.3, 0.3, 0.3, 0.3, 0.3, 1e154, 0.3, 0.3, 0.3, 0.3, 1e154)
    members = {"m2": m2, "q2_d": speed}
    lanes, scalar = both(pendulum, None, members=members, method=method, trajectories=True)
    failed = lanes.status != Status.OK
    assert set(lanes.status[failed]) == {Status.SINGULAR_MASS_MATRIX, Status.NONFINITE_STATE}
    singular = lanes.status == Status.SINGULAR_MASS_MATRIX
    assert_array_equal(lanes.x_final[singular], scalar.x_final[singular])  # x0: failed at step 1
    assert_allclose(lanes.x_final[failed], scalar.x_final[failed], rtol=1e-9, atol=0)  # sin/cos rounding
    healthy = ~failed
    alone = sweep(pendulum, members={k: np.asarray(v)[healthy] for k, v in members.items()}, kernel="lanes",
                  method=method, trajectories=True, **COMMON)
    for name in FIELDS:
        assert_array_equal(getattr(lanes, name)[healthy], getattr(alone, name), err_msg=name)
        assert_allclose(getattr(lanes, name)[healthy], getattr(scalar, name)[healthy], rtol=0,
                        atol=STATES_ATOL["double"], err_msg=name)
    assert np.isnan(lanes.trajectories[failed, -1]).all()


def test_grouping_does_not_change_results(pendulum):
    grid = {"m1": np.linspace(0.5, 2.0, 5), "q1": np.linspace(-1.0, 1.0, 4)}  # 20 members
    base = sweep(pendulum, grid, threads=1, chunk_size=10**6, **COMMON)
    for threads, chunk in ((1, 1), (2, 3), (2, None), (3, DEFAULT_LANES + 1)):
        other = sweep(pendulum, grid, threads=threads, chunk_size=chunk, **COMMON)
        for name in FIELDS + ("status", "steps_done"):
            assert_array_equal(getattr(other, name), getattr(base, name), err_msg=name)


def test_float_lanes_match_float_scalar(compiled_example):
    system = compiled_example("double_pendulum", precision="float", outputs=("rhs", "energy"), methods=("rk4",))
    lanes, scalar = both(system, {"m2": (0.5, 1.0, 2.0)}, method="rk4")
    assert lanes.x_final.dtype == np.float32
    assert_allclose(lanes.x_final, scalar.x_final, rtol=0, atol=STATES_ATOL["float"])


def test_kernel_choice(pendulum, compiled_example):
    grid = {"m2": (0.5, 1.0)}
    assert sweep(pendulum, grid, method="rk4", **COMMON).kernel == "lanes"
    assert sweep(pendulum, grid, method="backward_euler", **COMMON).kernel == "scalar"
    with pytest.raises(ValueError, match="'backward_euler' is not an explicit Runge-Kutta"):
        sweep(pendulum, grid, method="backward_euler", kernel="lanes", **COMMON)
    with pytest.raises(ValueError, match="kernel must be one of"):
        sweep(pendulum, grid, kernel="simd", **COMMON)
    plain = compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4",), lanes=0)
    # a build with lanes compiles the lane kernel only when a sweep first needs it
    assert pendulum.lane_build is not None and f"{pendulum.layout.prefix}_sweep_lanes" not in pendulum.layout.functions
    assert plain.lane_build is None
    assert sweep(plain, grid, **COMMON).kernel == "scalar"
    with pytest.raises(ValueError, match="built without the lane kernel"):
        sweep(plain, grid, kernel="lanes", **COMMON)


def test_the_lane_variant_is_built_and_keyed_once_per_process(pendulum):
    """Found by review: every sweep keyed the lane source again (0.6-0.9 ms); the variant is now kept."""
    first = pendulum.lane_variant()
    assert first is pendulum.lane_variant() and first.layout.prefix == pendulum.layout.prefix


def test_two_lane_trig_choices_of_one_scalar_module_keep_their_own_lane_kernels(compiled_example):
    """The scalar module of lane_trig="fast" and of "libm" is one (same source, same key); the kept lane
    variant must still follow each object's own choice (a first version kept it by the scalar key, and
    the libm sweep then ran the fast kernel: lanes differed from scalar in the last bit, in CI)."""
    fast = compiled_example("double_pendulum", outputs=("rhs",), methods=("rk4",), lane_trig="fast")
    libm = compiled_example("double_pendulum", outputs=("rhs",), methods=("rk4",), lane_trig="libm")
    assert fast.key == libm.key
    fast_lanes, libm_lanes = fast.lane_variant(), libm.lane_variant()
    assert fast_lanes.key != libm_lanes.key and libm.lane_variant() is libm_lanes


def test_c_refuses_methods_without_a_lane_stepper(pendulum):
    """The C entry point itself returns LCG_UNKNOWN_METHOD for an implicit method's number."""
    lane_system = pendulum.lane_variant()
    ffi, lib, layout = lane_system.ffi, lane_system.lib, lane_system.layout
    x0 = np.array([X0], dtype=float)
    p = np.array([[1.0, 1.0, 1.0, 1.0, 9.81]])
    status, steps = np.full(1, -1, np.intc), np.zeros(1, np.int_)
    out = [np.zeros((1, 4)), np.zeros((1, 2)), np.zeros(1)]
    ptr = lambda a: ffi.from_buffer("double[]", a)  # noqa: E731
    code = getattr(lib, f"{layout.prefix}_sweep_lanes")(
        layout.methods.index("backward_euler"), 1, ptr(x0), ptr(p), 0.0, 0.01, 10, 1, 0, *map(ptr, out),
        ffi.from_buffer("int[]", status), ffi.from_buffer("long[]", steps), ffi.NULL)
    assert code == Status.UNKNOWN_METHOD and status[0] == -1


@pytest.mark.parametrize("n_steps, h, stride, t0", [(-3, 0.01, 1, 0.0), (10, float("nan"), 1, 0.0),
                                                    (10, float("inf"), 1, 0.0), (10, 0.01, 0, 0.0),
                                                    (10, 0.01, -4, 0.0), (10, 0.01, 1, float("nan"))])
def test_c_refuses_arguments_out_of_range(pendulum, n_steps, h, stride, t0):
    """The C entry points (called directly, as from C: the Python sweep checks these first)
    return LCG_BAD_ARGUMENT and write nothing: traj is sized by n_steps / stride, so a negative
    count or stride had samples written past the buffer (found by review: stride <= 0 ran with
    stride 1, writing n_steps + 1 samples, and returned OK)."""
    lane_system = pendulum.lane_variant()
    ffi = lane_system.ffi
    ptr = lambda a: ffi.from_buffer("double[]", a)  # noqa: E731
    x0 = np.array([X0], dtype=float)
    p = np.array([[1.0, 1.0, 1.0, 1.0, 9.81]])
    for system in (lane_system, pendulum):
        status, steps = np.full(1, -1, np.intc), np.full(1, -1, np.int_)
        out = [np.full((1, 4), np.nan), np.full((1, 2), np.nan), np.full(1, np.nan)]
        traj = np.full((1, 4), np.nan)
        start = (system.layout.methods.index("rk4"), 1, ptr(x0), ptr(p), t0, h, n_steps, stride)
        results = (*map(ptr, out), ffi.from_buffer("int[]", status), ffi.from_buffer("long[]", steps), ptr(traj))
        if system is lane_system:  # (..., stride, track_energy, results)
            code = getattr(system.lib, f"{system.layout.prefix}_sweep_lanes")(*start, 1, *results)
            assert code == Status.BAD_ARGUMENT and status[0] == -1 and steps[0] == -1
        else:  # (..., stride, project, track_energy, results, work)
            work = np.full(work_size(system), np.nan)
            getattr(system.lib, f"{system.layout.prefix}_sweep")(*start, 0, 1, *results, ptr(work))
            assert status[0] == Status.BAD_ARGUMENT and steps[0] == 0
        assert np.isnan(traj).all() and all(np.isnan(a).all() for a in out)
        t_out, x_out, done = np.full(1, np.nan), np.full(4, np.nan), np.full(1, -1, np.int_)
        work = np.full(work_size(pendulum), np.nan)
        code = getattr(pendulum.lib, f"{pendulum.layout.prefix}_simulate")(
            pendulum.layout.methods.index("rk4"), t0, ptr(x0), ptr(p), h, n_steps, stride, 0, ptr(t_out), ptr(x_out),
            ffi.NULL, ffi.NULL, ffi.NULL, ffi.NULL, ptr(work), ffi.from_buffer("long[]", done))
        assert code == Status.BAD_ARGUMENT and done[0] == 0 and np.isnan(t_out).all() and np.isnan(x_out).all()


def _unconstrained_examples():
    from lagcodegen import catalog
    from lagcodegen.model import Model

    names = []
    for name in catalog.EXAMPLES:
        model = catalog.example(name)
        if not (isinstance(model, Model) and model.constraints):
            names.append(name)
    return names


@pytest.mark.parametrize("name", _unconstrained_examples())
def test_every_catalog_model_lanes_equal_scalar_with_libm_trig(compiled_example, example_eom, name):
    """Every unconstrained catalog model (its own symbol names beside the lane code's locals, its
    own mass-matrix sparsity): the lane kernel built with libm trig equals the scalar kernel
    bitwise over 11 members (a partial group) and 200 RK4 steps."""
    if example_eom(name).m:
        pytest.skip("constrained: the scalar kernel only")
    system = compiled_example(name, outputs=("rhs", "energy"), methods=("rk4",), lane_trig="libm")
    layout = system.layout
    column = layout.parameters[0] if layout.parameters else layout.coordinates[0]
    base = dict(layout.defaults).get(column, 1.0) or 1.0
    options = dict(x0=[0.3 + 0.1 * i for i in range(2 * layout.n)], t_end=0.2, h=1e-3, method="rk4",
                   progress=False, trajectories=True, stride=50)
    grid = {column: base * np.linspace(0.8, 1.2, 11)}
    lanes = sweep(system, grid, kernel="lanes", **options)
    scalar = sweep(system, grid, kernel="scalar", **options)
    for field in FIELDS + ("status", "steps_done"):
        assert_array_equal(getattr(lanes, field), getattr(scalar, field), err_msg=field)
