"""``lagcodegen simulate/sweep ... --input NAME=VALUE|NAME=FILE.csv [--hold foh]`` on a driven model
file (issue 13, item 7). Expected values: the damped oscillator's textbook step response
x(t) = F/k (1 - e^(-zeta w t)(cos w_d t + zeta/sqrt(1 - zeta^2) sin w_d t)), and RK4 on a forcing
linear between knots on the steps, which is exact for this linear system up to RK4's own error."""
from __future__ import annotations

import re

import numpy as np
import pytest

from lagcodegen.cli.arguments import EXIT_USAGE
from lagcodegen.cli.commands import main

MODEL = '''
import sympy as sp, sympy.physics.mechanics as me
from lagcodegen import Model
x, F = me.dynamicsymbols("x F")
m, k, c = sp.symbols("m k c", positive=True)
model = Model("driven_cli", [x], [m, k, c], kinetic_energy=m * x.diff()**2/2, potential_energy=k*x**2/2,
              generalized_forces={x: F - c*x.diff()}, inputs=[F], parameter_values={"m": 1.0, "k": 4.0, "c": 0.5},
              measurements={"spring_force": -k * x})
'''


def step_response(t, force, k=4.0, c=0.5, m=1.0):
    w, zeta = np.sqrt(k / m), c / (2 * np.sqrt(k * m))
    wd = w * np.sqrt(1 - zeta ** 2)
    return force / k * (1 - np.exp(-zeta * w * t) * (np.cos(wd * t) + zeta / np.sqrt(1 - zeta ** 2) * np.sin(wd * t)))


@pytest.fixture
def model_file(tmp_path):
    path = tmp_path / "driven.py"
    path.write_text(MODEL)
    return path


def final_x(text: str) -> float:
    return float(re.search(r"x = (-?[\d.e+-]+),", text).group(1))


def test_a_constant_input(model_file, capsys):
    code = main(["simulate", str(model_file), "--t-end", "2", "--h", "1e-3", "--x0", "x=0", "--input", "F=0.5"])
    out = capsys.readouterr().out
    assert code == 0
    assert final_x(out) == pytest.approx(step_response(2.0, 0.5), abs=1e-8)
    spring = float(re.search(r"spring_force = (-?[\d.e+-]+)", out).group(1))
    assert spring == pytest.approx(-4 * final_x(out), rel=1e-8)  # its definition -k x


def test_a_csv_table_on_a_first_order_hold(model_file, tmp_path, capsys):
    table = tmp_path / "force.csv"
    table.write_text("t,F\n0,1\n2,1\n")  # a constant written as a table: the same step response
    code = main(["simulate", str(model_file), "--t-end", "2", "--h", "1e-3", "--x0", "x=0", "--input",
                 f"F={table}", "--hold", "foh"])
    assert code == 0
    assert final_x(capsys.readouterr().out) == pytest.approx(step_response(2.0, 1.0), abs=1e-8)


@pytest.mark.parametrize("first_time", ["-0.5", "+0", ".0", "-.25"])
def test_a_csv_without_a_header_keeps_its_first_row(model_file, tmp_path, capsys, first_time):
    """Found by review: a first row beginning with -, + or . was taken for a header and dropped.
    Here the table (t_first, 0), (1, 2), (2, 2) starts the run between its first two knots, so
    the input at t = 0 is the line between them, np.interp by hand (dropping the row would leave
    t = 0 uncovered)."""
    table = tmp_path / "force.csv"
    table.write_text(f"{first_time},0\n1,2\n2,2\n")
    data = saved(["simulate", model_file, "--t-end", "2", "--h", "1e-3", "--x0", "x=0", "--input", f"F={table}"],
                 tmp_path)
    assert data["inputs"][0, 0] == pytest.approx(np.interp(0.0, [float(first_time), 1.0, 2.0], [0.0, 2.0, 2.0]),
                                                 abs=1e-15)


def saved(argv, tmp_path):
    """Run ``lagcodegen argv --out <tmp>.npz``; assert exit 0 and return the .npz it wrote."""
    out = tmp_path / "saved.npz"
    assert main([*map(str, argv), "--out", str(out)]) == 0
    return np.load(out)


def test_the_saved_run_keeps_the_inputs(model_file, tmp_path, capsys):
    # found by review: --out dropped the inputs (and measurements, residuals, multipliers)
    data = saved(["simulate", model_file, "--t-end", "1", "--h", "1e-3", "--x0", "x=0", "--input", "F=1.5"], tmp_path)
    assert data["input_names"].tolist() == ["F"] and str(data["hold"]) == "zoh"
    np.testing.assert_array_equal(data["inputs"], np.full((1001, 1), 1.5))
    np.testing.assert_allclose(data["x"][:, 0], step_response(data["t"], 1.5), atol=1e-10)
    assert data["measurement_names"].tolist() == ["spring_force"]
    np.testing.assert_allclose(data["measurements"][:, 0], -4.0 * data["x"][:, 0], rtol=1e-15)  # -k x


def test_a_sweep_over_the_input(model_file, tmp_path, capsys):
    data = saved(["sweep", model_file, "--t-end", "2", "--h", "1e-3", "--x0", "x=0", "--grid", "F=0.5,2"], tmp_path)
    np.testing.assert_allclose(data["x_final"][:, 0], step_response(2.0, np.array([0.5, 2.0])), atol=1e-8)


def test_an_input_both_swept_and_given_is_refused(model_file, capsys):
    # found by review: the grid's values won and --input F=3 was silently ignored
    code = main(["sweep", str(model_file), "--t-end", "2", "--h", "1e-3", "--x0", "x=0", "--grid", "F=0.5,2",
                 "--input", "F=3"])
    assert code == EXIT_USAGE
    assert "--input 'F' is swept by --grid/--table too" in capsys.readouterr().err


@pytest.mark.parametrize("extra, message", [
    ([], "driven by the input"),
    (["--input", "F=nope.csv"], "'nope.csv' is neither a number nor a file"),
    (["--input", "F"], "must look like name=value"),
    (["--input", "F=1", "--input", "F=2"], "'F' is given twice"),
    (["--input", "G=1"], "unknown input"),
    (["--input", "F=inf"], "must be finite"),
    (["--input", "F=TABLE"], "shorter than the run"),
    (["--input", "F=BAD"], "must have two columns"),
])
def test_bad_inputs_on_the_command_line(model_file, tmp_path, capsys, extra, message):
    (tmp_path / "short.csv").write_text("0,1\n1,1\n")
    (tmp_path / "bad.csv").write_text("0,1,2\n1,1,2\n")
    extra = [e.replace("TABLE", str(tmp_path / "short.csv")).replace("BAD", str(tmp_path / "bad.csv")) for e in extra]
    code = main(["simulate", str(model_file), "--t-end", "2", "--h", "1e-3", "--x0", "x=0", *extra])
    assert code == EXIT_USAGE
    assert message in capsys.readouterr().err


def test_a_sweep_keeps_the_measurements_summaries(model_file, tmp_path, capsys):
    """Found by review (session 16): the .npz, said to hold every SweepResult array, dropped y_final,
    y_min and y_max, and no --field named them. Expected: spring_force = -k x with the textbook step
    response, at the end and at its extreme over the steps (the same grid of times)."""
    out = tmp_path / "sweep.npz"
    code = main(["sweep", str(model_file), "--grid", "F=0.5,1,2", "--t-end", "2", "--h", "1e-3", "--x0", "x=0",
                 "--field", "y_min:spring_force", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0 and "y_min:spring_force (min spring_force over the run)" in text, text
    saved = np.load(out)
    assert list(saved["measurement_names"]) == ["spring_force"]
    times = np.arange(2001) * 1e-3
    for member, force in enumerate((0.5, 1.0, 2.0)):
        assert saved["y_final"][member, 0] == pytest.approx(-4 * step_response(2.0, force), abs=1e-7)
        assert saved["y_min"][member, 0] == pytest.approx(-4 * step_response(times, force).max(), abs=1e-7)
        assert saved["y_max"][member, 0] == pytest.approx(0.0, abs=1e-12)  # x >= 0 from rest under F > 0
    assert "the model has no measurements" in _usage_error(["sweep", "double_pendulum", "--grid", "m2=1,2",
                                                             "--t-end", "0.01", "--h", "1e-3", "--x0", "q1=1,q2=0",
                                                             "--field", "y_max:f"], capsys)


def _usage_error(argv, capsys) -> str:
    code = main(argv)
    captured = capsys.readouterr()
    assert code == EXIT_USAGE, captured
    return captured.err
