"""Sweeps found wrong by the review of session 14 (helper-43); expectations by hand (array sizes, the
float range) or from `simulate` run alone."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog
from lagcodegen.pipeline import compile_model
from lagcodegen.run.arguments import OutputTooLargeError
from lagcodegen.run.inputs import InputError
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import sweep

pytestmark = pytest.mark.compiler


def _driven_pendulum(precision="double"):
    th, F = me.dynamicsymbols("th F")
    m, length, g, c = sp.symbols("m l g c", positive=True)
    model = Model("driven_pend", [th], [m, length, g, c], kinetic_energy=m * length ** 2 * th.diff() ** 2 / 2,
                  potential_energy=-m * g * length * sp.cos(th), generalized_forces={th: F - c * th.diff()},
                  inputs=[F], parameter_values={m: 1.0, length: 0.7, g: 9.81, c: 0.2})
    return compile_model(model, methods=("rk4",), precision=precision)


def test_input_tables_count_against_max_output_bytes():
    """Was: run, 262 MiB more resident under max_output_bytes = 1e6. By hand, 400 members x at least 20001
    knots x (time + F) x 8 B >= 122 MiB of tables, far past 1e6."""
    system = _driven_pendulum()
    signal = np.sin(np.arange(20000) * 1e-3)[:, None]
    with pytest.raises(OutputTooLargeError, match=r"the input tables of the sweep's 400 members \(\d+ knots each\)"):
        sweep(system, {"m": np.linspace(0.5, 1.5, 400)}, x0={"th": 1.0}, t_end=20.0, h=1e-3, inputs=signal,
              max_output_bytes=10 ** 6, threads=1)


@pytest.mark.parametrize("kernel", ["auto", "scalar"])
def test_a_float_input_beyond_the_float_range_is_named(kernel):
    """Was: NONFINITE_STATE (lanes) or NONFINITE_INPUT (scalar) for a swept amplitude of 1e39, beyond
    float's 3.4e38, where a swept parameter of that size is refused up front."""
    system = _driven_pendulum("float")
    with pytest.raises(InputError, match=r"member 1: input 'F' = 1e\+39 is beyond the range of the float kernel"):
        sweep(system, {"F": [1.0, 1e39, 2.0]}, x0={"th": 1.0}, t_end=0.1, h=1e-2, kernel=kernel)


def test_stride_is_for_kept_trajectories_only():
    """Was: a StrideWarning and, for stride > steps, a ValueError, with no trajectory kept. The results are
    those of simulate run alone (the same C step), whatever the stride."""
    system = compile_model(catalog.double_pendulum(), methods=("rk4",))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        for stride in (7, 1000):
            result = sweep(system, {"m2": [1.0, 2.0]}, x0=[1, 0, 0, 0], t_end=1.0, h=1e-2, stride=stride,
                           kernel="scalar")
            assert result.trajectories is None
            alone = simulate(system, [1, 0, 0, 0], 1.0, 1e-2, params={"m2": 2.0})
            np.testing.assert_array_equal(result.x_final[1], alone.x[-1])
    with pytest.raises((TypeError, ValueError), match="stride"):
        sweep(system, {"m2": [1.0, 2.0]}, x0=[1, 0, 0, 0], t_end=1.0, h=1e-2, stride=0)


@pytest.mark.parametrize("trajectories", [False, True])
def test_an_input_array_is_read_as_simulate_reads_it(trajectories):
    """Found by review (session 16): without trajectories the kernel's stride of n_steps made a 2-row
    array of a 100-step run pass as samples at t0 and t_end (status OK, a ramp nobody asked for),
    where simulate refuses it; and the per-stride array simulate(stride=5) takes was refused. The
    expectations are simulate's own refusal and simulate's run of the same array alone."""
    system = _driven_pendulum()
    run = {"x0": {"th": 1.0}, "t_end": 1.0, "h": 1e-2}
    two_rows = np.array([[0.0], [1.0]])
    with pytest.raises(InputError, match=r"an array of 2 rows does not match the run: expected 100 or 101 rows"):
        simulate(system, run["x0"], run["t_end"], run["h"], inputs=two_rows, hold="foh")
    with pytest.raises(InputError, match=r"an array of 2 rows does not match the run: expected 100 or 101 rows"):
        sweep(system, {"m": [1.0]}, inputs=two_rows, hold="foh", trajectories=trajectories, **run)
    per_stride = np.linspace(0.0, 1.0, 21)[:, None]
    result = sweep(system, {"m": [1.0, 2.0]}, inputs=per_stride, stride=5, trajectories=trajectories,
                   kernel="scalar", **run)
    alone = simulate(system, run["x0"], run["t_end"], run["h"], stride=5, inputs=per_stride, params={"m": 2.0})
    np.testing.assert_array_equal(result.x_final[1], alone.x[-1])


def test_a_heatmap_refuses_a_repeated_grid_value():
    """Was: {"m2": [1, 1, 2]} drawn with one m2 = 1 row of zero height (members 0 and 1 invisible)."""
    from lagcodegen.analysis.heatmaps import plot_heatmap

    system = compile_model(catalog.double_pendulum(), methods=("rk4",))
    result = sweep(system, {"m2": [1.0, 1.0, 2.0], "l2": [1.0, 2.0]}, x0={"q1": 1, "q2": 0}, t_end=0.1, h=1e-2)
    with pytest.raises(ValueError, match=r"grid axis 'm2' repeats 1\.0"):
        plot_heatmap(result, np.arange(6.0))


def test_the_sweep_help_lists_every_member_status():
    """Was: a hand-written list that stopped at 5 (no 6-8, -1, -2). Every code a member can have is in
    the status table (UNKNOWN_METHOD is refused before a sweep runs)."""
    from lagcodegen.cli.arguments import SWEEP_EPILOG
    from lagcodegen.status import STATUS_TABLE, SWEEP_STATUS_TABLE

    text = " ".join(SWEEP_EPILOG.split())
    for row in STATUS_TABLE + SWEEP_STATUS_TABLE:
        if row.name != "UNKNOWN_METHOD":
            assert f"{row.code} {row.name.lower().replace('_', ' ')}" in text
