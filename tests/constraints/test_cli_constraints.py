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
