"""A parameter that is not finite, passed to the exported C entry points (a firmware reading a
corrupted configuration): each refuses it with LCG_BAD_ARGUMENT and leaves t and x as they were.

Found by review: a mass falling onto a one-sided stop, V = m g x + k/2 Max(0, -x - gap)^2, with gap =
NaN ran 1000 steps of step_rk4, simulate and step_monitored with LCG_OK and fell through the stop:
fmax(0, NaN) is 0, so no later test saw the NaN. Python's simulate refused it by name; the C did not.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import parameter_vector
from lagcodegen.status import Status

pytestmark = pytest.mark.compiler


@pytest.fixture(scope="module")
def stop(tmp_path_factory):
    x = me.dynamicsymbols("x")
    m, k, gap, g = sp.symbols("m k gap g", positive=True)
    model = Model("stop", [x], [m, k, gap, g], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=m * g * x + k * sp.Max(0, -x - gap) ** 2 / 2,
                  parameter_values={m: 1.0, k: 1000.0, gap: 0.5, g: 9.81})
    return compile_model(model, methods=("rk4", "backward_euler"), outputs=("rhs", "energy", "step_jacobian"),
                         cache_dir=tmp_path_factory.mktemp("stop"))


@pytest.mark.parametrize("bad", [math.nan, math.inf])
def test_every_entry_point_refuses_a_parameter_that_is_not_finite(stop, bad):
    ffi, lib, prefix = stop.ffi, stop.lib, stop.layout.prefix
    p = ffi.new("double[]", [1.0, 1000.0, bad, 9.81])
    work = ffi.new("double[]", int(getattr(lib, f"{prefix.upper()}_WORK_SIZE")))
    rk4 = stop.layout.methods.index("rk4")

    def fresh():
        return ffi.new("double *", 0.25), ffi.new("double[]", [0.1, -0.2])

    steps = {name: (lambda t, x, name=name: getattr(lib, f"{prefix}_step_{name}")(t, x, p, 1e-3, work))
             for name in stop.layout.methods}
    steps["step_jacobian_rk4"] = lambda t, x: lib.lcg_stop_step_jacobian_rk4(t, x, p, 1e-3, ffi.new("double[4]"),
                                                                             work)
    steps["step_monitored"] = lambda t, x: lib.lcg_stop_step_monitored(rk4, t[0], x, p, 1e-3, work, 1, 0)
    for name, call in steps.items():
        t, x = fresh()
        assert call(t, x) == Status.BAD_ARGUMENT, name
        assert t[0] == 0.25 and [x[0], x[1]] == [0.1, -0.2], name
    t_out, x_out, done = ffi.new("double[2]", [math.nan] * 2), ffi.new("double[4]", [math.nan] * 4), ffi.new("long *")
    status = lib.lcg_stop_simulate(rk4, 0.0, [0.1, -0.2], p, 1e-3, 10, 10, 0, t_out, x_out, ffi.NULL, ffi.NULL,
                                   ffi.NULL, ffi.NULL, work, done)
    assert status == Status.BAD_ARGUMENT and done[0] == 0 and math.isnan(t_out[0])
    # the sweep: only the member with the bad parameter is refused; the other runs (free fall to the stop)
    ps = np.array([[1.0, 1000.0, 0.5, 9.81], [1.0, 1000.0, bad, 9.81]])
    x0s, x_final = np.zeros((2, 2)), np.full((2, 2), np.nan)
    status, steps_done = np.full(2, -1, np.intc), np.zeros(2, np.int_)
    lib.lcg_stop_sweep(rk4, 2, ffi.from_buffer("double[]", x0s), ffi.from_buffer("double[]", ps), 0.0, 1e-3, 10, 10,
                       0, 0, ffi.from_buffer("double[]", x_final), ffi.from_buffer("double[]", np.zeros(2)),
                       ffi.from_buffer("double[]", np.zeros(2)), ffi.from_buffer("int[]", status),
                       ffi.from_buffer("long[]", steps_done), ffi.NULL, work)
    assert list(status) == [Status.OK, Status.BAD_ARGUMENT] and list(steps_done) == [10, 0]
    # by hand, free fall from rest: x(0.01) = -g t^2 / 2 (RK4 exact for a constant force)
    assert x_final[0, 0] == pytest.approx(-9.81 * 0.01 ** 2 / 2, rel=1e-12)


def test_the_projection_reports_a_nan_residual(compiled_example):
    """Found by review: the projection's largest |phi| was taken with `fabs(phi) > size`, which drops a
    NaN, so with the rod length l = NaN it returned LCG_OK (x unchanged, phi NaN), and with a NaN
    coordinate LCG_SINGULAR_CONSTRAINTS. Both are now LCG_NONFINITE_STATE."""
    system = compiled_example("cartesian_pendulum", outputs=("rhs",), methods=("rk4",))
    ffi, lib, layout = system.ffi, system.lib, system.layout
    project = getattr(lib, f"{layout.prefix}_project")
    good = [float(v) for v in parameter_vector(system)]
    bad_length = list(good)
    bad_length[list(layout.parameters).index("l")] = math.nan
    state = [0.6, -0.8, 0.3, 0.0]
    for p, x in ((bad_length, state), (good, [math.nan] + state[1:])):
        x = ffi.new("double[]", x)
        assert project(0.0, x, ffi.new("double[]", p)) == Status.NONFINITE_STATE
