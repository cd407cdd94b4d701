"""Recorded outputs undefined at a finite state are warned of, naming the output (found by review:
a point at (sqrt(x), 0) and a measurement log(x) were NaN at 60 % of a run's samples, status OK,
no word, and the animation silently left the point out).

The model is the harmonic oscillator m x'' = -k x, k/m = 4, from x = 1 at rest: x(t) = cos(2t)
exactly, negative from t = pi/4 on, so sqrt(x) and log(x) are undefined at the samples with
cos(2t) < 0 (counted from the exact solution).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import UndefinedOutputWarning, simulate

pytestmark = pytest.mark.compiler


def test_outputs_undefined_at_finite_states_are_named(tmp_path):
    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    model = Model("root_oscillator", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  points={"p": (sp.sqrt(x), 0)}, measurements={"y": sp.log(x), "plain": x},
                  parameter_values={"m": 1.0, "k": 4.0})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        run = simulate(system, {"x": 1.0}, 2.0, 1e-3, points=True, energy=True)
    assert run.ok
    messages = [str(w.message) for w in caught if w.category is UndefinedOutputWarning]
    negative = int(np.sum(np.cos(2 * np.arange(2001) * 1e-3) < 0))  # exact solution's samples with x < 0
    assert len(messages) == 2 and messages[0].startswith("point 'p'") and messages[1].startswith("measurement 'y'")
    for message in messages:
        count = int(message.split(" at ")[1].split(" of ")[0])
        first = float(message.split("first at t = ")[1].split(" ")[0])
        assert abs(count - negative) <= 1 and abs(first - math.pi / 4) <= 1e-3
    with warnings.catch_warnings():  # defined everywhere: nothing said
        warnings.simplefilter("error", UndefinedOutputWarning)
        simulate(system, {"x": 1.0}, 0.7, 1e-3, points=True, energy=True)
