"""What the documentation promised and the code did not do, found by the review of session 14
(helper-48); expectations by hand."""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations
from lagcodegen.model import ModelError
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import ConstraintDriftWarning, StabilityWarning, simulate

pytestmark = pytest.mark.compiler


def test_the_stability_pre_check_runs_without_the_jacobian_output():
    """Was: no StabilityWarning for an RK4-only build (every CLI run): the stiff chain at h = 0.04 ran to
    8.6e74, status OK. By hand its fastest frequency is sqrt(2K + k) ~ 141.4 rad/s for k = 1, K = 1e4
    (unit masses; the catalog's defaults), so h w = 5.66 against RK4's 2.83 on the imaginary axis."""
    system = compile_model(catalog.stiff_chain(), methods=("rk4",))
    assert f"{system.layout.prefix}_jacobian" not in system.layout.functions
    x0 = {"x1": 0.1, "x2": 0.0, "x3": 0.0}
    with pytest.warns(StabilityWarning, match=r"w = 141\.4"):
        simulate(system, x0, t_end=0.2, h=0.04)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        simulate(system, x0, t_end=0.2, h=0.01)  # h w = 1.41: inside


def test_the_drift_check_does_not_depend_on_the_outputs_asked_for():
    """Was: outputs=("rhs",) left out the residuals, and a pendulum in x, y (rod 1, started on it at 0.5 rad)
    drifted 9.3e-3 off its rod with no warning. phi = x^2 + y^2 - 1 by hand from the trajectory."""
    system = compile_model(catalog.cartesian_pendulum(), methods=("euler",), outputs=("rhs",))
    with pytest.warns(ConstraintDriftWarning):
        run = simulate(system, {"x": np.sin(0.5), "y": -np.cos(0.5)}, t_end=1.0, h=1e-3, method="euler")
    assert np.abs(run["x"] ** 2 + run["y"] ** 2 - 1.0).max() > 1e-6


def test_a_body_position_that_reads_a_speed_is_refused():
    """Was: l sin(q) N.x + q' N.y accepted (its velocity holds q''), M = l^2 m cos^2 q, gravity gone."""
    m, length, g = sp.symbols("m l g", positive=True)
    q = me.dynamicsymbols("q")
    N, O = me.ReferenceFrame("N"), me.Point("O")
    P = O.locatenew("P", length * sp.sin(q) * N.x + q.diff() * N.y)
    with pytest.raises(ModelError, match="the position of body b contains the speed"):
        derive_equations(Model("bad", [q], [m, length, g], bodies=[me.Particle("b", P, m)], gravity=-g * N.y,
                               frame=N, origin=O))
