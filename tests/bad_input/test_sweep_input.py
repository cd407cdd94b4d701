"""Bad arguments of `sweep`: every one raises before any member runs, naming the argument.

Before these checks ``chunk_size=-3`` ran no member and returned ``completed=True`` (``range``
with a negative step is empty), ``chunk_size=0`` raised range()'s own error, a string in a grid
raised float()'s error naming nothing, and a nested axis was flattened silently.
The model is the catalog double pendulum (state q1, q2, q1_d, q2_d; free m1, m2, l1, l2, g).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lagcodegen.run.arguments import OutputTooLargeError
from lagcodegen.run.sweep import sweep

pytestmark = pytest.mark.compiler

COMMON = {"x0": (0.5, 0.0, 0.0, 0.0), "t_end": 0.1, "h": 0.01}
GRID = {"m2": (0.5, 1.0, 2.0)}


@pytest.fixture(scope="module")
def pendulum(compiled_example):
    return compiled_example("double_pendulum", outputs=("rhs", "energy"), methods=("rk4", "euler"))


@pytest.mark.parametrize("changes, error, culprit", [
    # how the members run
    ({"chunk_size": -3}, ValueError, r"^chunk_size must be a positive integer, got -3"),
    ({"chunk_size": 0}, ValueError, r"^chunk_size must be a positive integer, got 0"),
    ({"chunk_size": 2.5}, ValueError, r"^chunk_size must be a positive integer"),
    ({"threads": 0}, ValueError, r"^threads must be a positive integer, got 0"),
    ({"threads": "4"}, ValueError, r"^threads must be a positive integer, got '4'"),
    ({"kernel": "fast"}, ValueError, r"kernel must be one of \('auto', 'lanes', 'scalar'\), got 'fast'"),
    ({"kernel": None}, ValueError, r"kernel must be one of"),
    ({"client": "tcp://127.0.0.1:8786"}, TypeError, r"^client must be a dask.distributed Client.*str"),
    ({"progress": "yes"}, TypeError, r"^progress must be True or False"),
    ({"trajectories": "yes"}, TypeError, r"^trajectories must be True or False"),
    ({"track_energy": 1}, TypeError, r"^track_energy must be True or False"),
    ({"project": None}, TypeError, r"^project must be True or False"),
    ({"project": True}, ValueError, r"project=True needs constraints \(holonomic or on the velocities\); model 'double_pendulum'"),
    # the time grid and method, as in simulate
    ({"h": None}, TypeError, r"^h must be a real number"),
    ({"h": 1e-320}, ValueError, r"step h = 9.99989e-321 is inf steps"),
    ({"t_end": math.inf}, ValueError, r"^t_end must be finite"),
    ({"t0": "0"}, TypeError, r"^t0 must be a real number"),
    ({"stride": 10 ** 30, "trajectories": True}, ValueError, r"stride = 10{30} exceeds the number of steps \(10\)"),
    ({"stride": -1}, ValueError, r"^stride must be a positive integer"),
    ({"method": 4}, TypeError, r"^method must be a method name"),
    # x0 and params, by name
    ({"x0": ("a", 0.0, 0.0, 0.0)}, TypeError, r"initial state variable 'q1'"),
    ({"x0": (0.5, 0.0, 0.0)}, ValueError, r"needs 4 values"),
    ({"x0": {"q1": 0.5, "q2": math.nan}}, ValueError, r"not finite in q2"),
    ({"params": {"l1": "long"}}, TypeError, r"parameter 'l1'"),
    ({"params": {"g": math.inf}}, ValueError, r"parameter 'g' must be finite"),
    ({"params": {"m3": 1.0}}, ValueError, r"unknown parameter 'm3'"),
    # grid axes, by name
    ({"grid": {"m2": ("heavy", 1.0)}}, TypeError, r"grid axis 'm2' holds a non-number: 'heavy'"),
    ({"grid": {"m2": (1.0, None)}}, TypeError, r"grid axis 'm2' holds a non-number: None"),
    ({"grid": {"m2": (True, False)}}, TypeError, r"grid axis 'm2' holds a non-number: True"),
    ({"grid": {"m2": (1.0, 1j)}}, TypeError, r"grid axis 'm2' holds a non-number"),
    ({"grid": {"m2": [[1.0, 2.0], [3.0, 4.0]]}}, ValueError, r"grid axis 'm2' must be a flat sequence.*\(2, 2\)"),
    ({"grid": {"m2": [[1.0, 2.0], [3.0]]}}, ValueError, r"grid axis 'm2' has values of uneven shape"),
    ({"grid": {"m2": [10 ** 400]}}, ValueError, r"grid axis 'm2' holds a number beyond the double range"),
    ({"grid": {"m2": ()}}, ValueError, r"grid axis 'm2' has no values"),
    ({"grid": {"m2": (1.0, math.nan)}}, ValueError, r"swept 'm2' = nan \(member 1\) is not finite"),
    ({"grid": [("m2", (1.0, 2.0))]}, TypeError, r"^grid must be a mapping"),
    ({"grid": {"m2": GRID["m2"], "theta": (0.1,)}}, ValueError, r"cannot sweep 'theta'"),
    ({"grid": None, "members": {"m2": (1.0, "x")}}, TypeError, r"member column 'm2' holds a non-number: 'x'"),
    ({"grid": None, "members": {"m2": (1.0, 2.0), "q1": (0.1,)}}, ValueError, r"equally long.*'q1': 1"),
    ({"grid": None, "members": "m2=1"}, TypeError, r"^members must be a mapping"),
])
def test_a_bad_argument_is_named(pendulum, changes, error, culprit):
    arguments = {"grid": GRID} | COMMON | changes
    with pytest.raises(error, match=culprit):
        sweep(pendulum, arguments.pop("grid"), **arguments)


def test_a_name_given_twice_is_refused(pendulum):
    import sympy as sp

    # the Symbol m2 and the string "m2" name the same column
    with pytest.raises(ValueError, match=r"'m2' given more than once"):
        sweep(pendulum, {sp.Symbol("m2"): (1.0,), "m2": (2.0,)}, **COMMON)


def test_a_scalar_axis_is_one_value(pendulum):
    result = sweep(pendulum, {"m2": 1.5, "l2": (0.5, 1.0)}, **COMMON)
    assert result.completed and result.n_members == 2
    assert np.array_equal(result.values, [[1.5, 0.5], [1.5, 1.0]])


def test_every_member_runs_for_any_valid_chunk_size(pendulum):
    """chunk_size from 1 to beyond the member count: all 3 members run, one result."""
    results = [sweep(pendulum, GRID, chunk_size=c, threads=1, **COMMON) for c in (1, 2, 3, 100)]
    for result in results:
        assert result.completed and np.all(result.status == 0) and np.all(result.steps_done == 10)
        assert np.array_equal(result.x_final, results[0].x_final)


def test_a_grid_beyond_memory_is_refused_before_it_is_built(pendulum):
    """Six axes of 1000 values: 1e18 members; itertools.product would have run for ever."""
    grid = {name: np.linspace(0.5, 2.0, 1000) for name in ("m1", "m2", "l1", "l2", "g", "q1")}
    with pytest.raises(OutputTooLargeError, match=r"the sweep of 10{18} members would need: .*EiB.*fewer members"):
        sweep(pendulum, grid, **COMMON)


def test_kept_trajectories_beyond_memory_are_refused_with_a_stride(pendulum):
    """3 members x 1001 samples x 4 doubles = 96096 bytes of trajectories alone (hand count)."""
    with pytest.raises(OutputTooLargeError, match=r"the sweep of 3 members would keep 1001 samples.*stride >= \d+"):
        sweep(pendulum, GRID, trajectories=True, max_output_bytes=90_000, **(COMMON | {"t_end": 10.0}))
    kept = sweep(pendulum, GRID, trajectories=True, stride=10, max_output_bytes=90_000, **(COMMON | {"t_end": 10.0}))
    assert kept.completed and kept.trajectories.shape == (3, 101, 4)


def test_the_stride_a_refusal_suggests_fits_and_is_the_least_that_does(pendulum):
    # found by review: the hint spread the per-member arrays over the samples, and the stride it named
    # was refused again with a larger one
    import re

    grid, run = {"m2": np.linspace(0.5, 2.0, 10)}, COMMON | {"t_end": 10.0}
    with pytest.raises(OutputTooLargeError) as refused:
        sweep(pendulum, grid, trajectories=True, max_output_bytes=4000, **run)
    stride = int(re.search(r"stride >= (\d+)", str(refused.value)).group(1))
    assert sweep(pendulum, grid, trajectories=True, stride=stride, max_output_bytes=4000, **run).completed
    with pytest.raises(OutputTooLargeError):
        sweep(pendulum, grid, trajectories=True, stride=stride - 1, max_output_bytes=4000, **run)


@pytest.mark.parametrize("limit, error, message", [
    ("1e9", TypeError, "max_output_bytes must be a positive integer \\(bytes\\), got str '1e9'"),
    (-1, ValueError, "max_output_bytes must be a positive integer \\(bytes\\), got -1"),
    (0, ValueError, "got 0"),
])
def test_a_memory_limit_that_is_no_positive_integer_is_named(pendulum, limit, error, message):
    """Found by review: "1e9" failed in a comparison naming nothing; -1 ran into "more than the limit of -1 B"."""
    with pytest.raises(error, match=message):
        sweep(pendulum, GRID, trajectories=True, max_output_bytes=limit, **COMMON)


def test_a_masked_grid_axis_is_refused(pendulum):
    """Found by review: a masked entry of a numpy masked array ran as a member (np.asarray keeps it)."""
    axis = np.ma.masked_array([0.5, 1.0, 2.0], mask=[False, True, False])
    with pytest.raises(ValueError, match="grid axis 'm2' is a masked array with masked entries"):
        sweep(pendulum, {"m2": axis}, **COMMON)


def test_a_swept_input_that_overflows_names_the_member(driven_oscillator, tmp_path):
    """Found by review: base 1e300 swept by F = 1e10 overflowed to inf and ran (statuses 2 on the lane
    kernel, 6 on the scalar one), where simulate refuses a non-finite input by name."""
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.inputs import InputError

    system = compile_model(driven_oscillator(), methods=("rk4",), cache_dir=tmp_path)
    for kernel in ("auto", "scalar"):
        with pytest.raises(InputError, match="member 1: input 'F' scaled by the swept 'F' = 10000000000.0 is not finite"):
            sweep(system, {"F": [1.0, 1e10]}, x0={"x": 0.3}, t_end=1.0, h=1e-2, inputs=1e300, kernel=kernel)
