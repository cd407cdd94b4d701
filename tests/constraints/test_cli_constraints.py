"""The command line on a closed loop: a partial --x0 is completed to a consistent state and
--project holds the constraints."""
from __future__ import annotations

import numpy as np
import pytest

from lagcodegen.cli.commands import main


@pytest.mark.compiler
def test_simulate_slider_crank_from_the_crank_angle_alone(tmp_path, capsys):
    out = tmp_path / "run.npz"
    code = main(["simulate", "slider_crank", "--t-end", "0.5", "--h", "1e-4", "--x0", "theta=0.5",
                 "--project", "--out", str(out)])
    printed = capsys.readouterr().out
    assert code == 0 and "consistent initial state: theta = 0.5" in printed
    assert "(projected every step)" in printed
    run = np.load(out)
    names = [str(n) for n in run["names"]]
    theta, s = run["x"][:, names.index("theta")], run["x"][:, names.index("s")]
    # Independent check of the loop closure at every sample: the slider sits where the crank
    # (r = 0.1) and the rod (L = 0.3, catalog defaults) put it, s = r cos(theta) + sqrt(L^2 - r^2 sin^2(theta)).
    r, L = 0.1, 0.3
    assert np.max(np.abs(s - (r * np.cos(theta) + np.sqrt(L**2 - (r * np.sin(theta))**2)))) < 1e-10


def test_an_inconsistent_x0_is_refused_naming_the_constraint(capsys):
    code = main(["simulate", "cartesian_pendulum", "--t-end", "0.1", "--h", "1e-3", "--x0", "x=2"])
    error = capsys.readouterr().err
    assert code == 2 and error.startswith("lagcodegen simulate: error: --x0") and "constraint 0" in error


def test_a_complete_x0_off_the_constraints_is_refused(capsys):
    """Found by review: a full --x0 off the constraints ran (exit 0) as another system, a rod of
    0.6 for the catalog's rod of 1, the warning blaming drift. By hand: phi = x^2 + y^2 - l^2 =
    0.36 - 1 = -0.64 at x = 0.6, y = 0; a consistent full --x0 (0.6, -0.8) runs."""
    code = main(["simulate", "cartesian_pendulum", "--t-end", "0.1", "--h", "1e-3", "--x0", "x=0.6,y=0"])
    error = capsys.readouterr().err
    assert code == 2 and error.count("\n") == 1
    assert "--x0 is off constraint row 0 of cartesian_pendulum on the positions, phi = -0.64" in error
    assert main(["simulate", "cartesian_pendulum", "--t-end", "0.1", "--h", "1e-3", "--x0", "x=0.6,y=-0.8"]) == 0


SLEIGH = '''
import sympy as sp, sympy.physics.mechanics as me
from lagcodegen import Model
t = me.dynamicsymbols._t
x, y, theta = me.dynamicsymbols("x y theta")
m, I, a = sp.symbols("m I a", positive=True)
xc, yc = x + a * sp.cos(theta), y + a * sp.sin(theta)
T = m * (xc.diff(t) ** 2 + yc.diff(t) ** 2) / 2 + I * theta.diff(t) ** 2 / 2
blade = -x.diff(t) * sp.sin(theta) + y.diff(t) * sp.cos(theta)
model = Model("sleigh", [x, y, theta], [m, I, a], kinetic_energy=T, motion_constraints=[blade],
              parameter_values={"m": 1.0, "I": 0.5, "a": 0.3}, dependent_speeds=[y],
              points={"blade": (x, y), "centre": (xc, yc)})
'''


def _sleigh_reference(theta0, x_d0, theta_d0, m, inertia, a, t_end):
    """The Chaplygin sleigh in its blade frame (Neimark and Fufaev; Bloch, Nonholonomic Mechanics
    and Control, 1.7): v' = a w^2, w' = -m a v w / (I + m a^2), theta' = w, x' = v cos(theta),
    y' = v sin(theta), v the speed along the blade; scipy DOP853 at rtol = atol = 1e-12."""
    from scipy.integrate import solve_ivp

    def rhs(_, s):
        x, y, theta, v, w = s
        return [v * np.cos(theta), v * np.sin(theta), w, a * w**2, -m * a * v * w / (inertia + m * a**2)]

    start = [0.0, 0.0, theta0, x_d0 / np.cos(theta0), theta_d0]
    return solve_ivp(rhs, (0, t_end), start, method="DOP853", rtol=1e-12, atol=1e-12).y[:3, -1]


@pytest.mark.compiler
def test_the_command_line_runs_a_model_with_eliminated_speeds(tmp_path, capsys):
    """Found by review: simulate, animate and sweep refused every model with eliminated dependent
    speeds ("output 'constraints' needs constraints with multipliers"), an output the user had not
    asked for; and the --plot of a model with fewer speeds than coordinates left theta out."""
    import lagcodegen.cli.runs as runs

    model = tmp_path / "sleigh.py"
    model.write_text(SLEIGH)
    out, plot = tmp_path / "run.npz", tmp_path / "run.png"
    x0 = "x=0,y=0,x_d=0.5,theta_d=2,theta=-0.8"
    drawn = []
    real_plot = runs.plot_coordinates

    def plot_coordinates(*args):
        figure = real_plot(*args)
        drawn.extend(line.get_label() for line in figure.axes[0].get_lines())
        return figure

    runs.plot_coordinates = plot_coordinates
    try:
        code = main(["simulate", str(model), "--t-end", "1", "--h", "1e-3", "--x0", x0, "--out", str(out),
                     "--plot", str(plot)])
    finally:
        runs.plot_coordinates = real_plot
    assert code == 0, capsys.readouterr().err
    assert drawn == ["x", "y", "theta"] and plot.is_file()
    run = np.load(out)
    names = [str(n) for n in run["names"]]
    got = [run["x"][-1, names.index(n)] for n in ("x", "y", "theta")]
    np.testing.assert_allclose(got, _sleigh_reference(-0.8, 0.5, 2.0, 1.0, 0.5, 0.3, 1.0), atol=1e-9)
    assert main(["sweep", str(model), "--t-end", "0.1", "--h", "1e-3", "--x0", x0, "--grid", "m=0.5:2:3"]) == 0
    assert "status: ok 3" in capsys.readouterr().out


def test_a_millimetre_rod_started_at_half_its_length_is_refused(capsys):
    """Found by review: with an absolute floor (1 + max |x0|) in the check, a rod of l = 1e-3 started
    at y = -l/2 ran, exit 0. By hand phi = x^2 + y^2 - l^2 = -7.5e-7, 43 % of the size of its terms."""
    code = main(["simulate", "cartesian_pendulum", "--t-end", "0.01", "--h", "1e-5", "--x0", "x=0,y=-0.0005",
                 "--param", "l=0.001"])
    assert code == 2 and "--x0 is off constraint row 0 of cartesian_pendulum on the positions" in capsys.readouterr().err


def test_linearize_completes_a_partial_state_as_simulate_does(capsys):
    """Found by review: `linearize slider_crank --at theta=0.3` was refused ("violates constraint row
    0 ... (consistent_state)"), though simulate completes the same --x0. The completed state must
    close the loop (by hand, s = r cos(theta) + sqrt(L^2 - r^2 sin^2(theta)), r = 0.1, L = 0.3)."""
    code = main(["linearize", "slider_crank", "--at", "theta=0.3"])
    out = capsys.readouterr().out
    assert code == 0 and "consistent initial state: theta = 0.3" in out
    completed = dict(item.split(" = ") for item in out.split("consistent initial state: ")[1].splitlines()[0].split(", "))
    r, L, theta = 0.1, 0.3, 0.3
    assert float(completed["s"]) == pytest.approx(r * np.cos(theta) + np.sqrt(L**2 - (r * np.sin(theta))**2), rel=1e-8)
    assert "eigenvalue, frequency" in out
    code = main(["linearize", "slider_crank", "--at", "theta=0.3,s=0.1"])
    assert code == 2 and "--at is inconsistent with the constraints" in capsys.readouterr().err
