"""-ffast-math and the status codes (found by review): -ffinite-math-only, part of -ffast-math,
compiles isfinite() and x != x away, and a run whose state turned NaN then ended with status OK.
lagcodegen's own builds add -fno-finite-math-only after the caller's flags; the generated C refuses
to compile under -ffinite-math-only, for the embedded users who build it themselves. The expected
status comes from the state itself: q1_d = 1e200 overflows to NaN within a step.
"""
from __future__ import annotations

import shutil
import subprocess
import warnings
from pathlib import Path

import pytest

from lagcodegen import catalog
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import sweep
from lagcodegen.status import Status

pytestmark = pytest.mark.compiler
GENERATED = Path(__file__).resolve().parents[2] / "generated"


def test_a_fast_math_build_still_reports_a_nan_state(tmp_path):
    system = compile_model(catalog.double_pendulum(), fixed={"g": 9.81}, methods=("rk4",),
                           extra_compile_args=("-ffast-math",), cache_dir=tmp_path)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = simulate(system, {"q1": 1.0, "q2": 0.5, "q1_d": 1e200}, t_end=0.01, h=1e-3, check_stability=False)
        assert run.status == Status.NONFINITE_STATE
        for kernel in ("scalar", "auto"):
            result = sweep(system, members={"q1_d": [1.0, 1e200]}, x0={"q1": 1.0, "q2": 0.5}, t_end=0.01, h=1e-3,
                           kernel=kernel)
            assert result.status.tolist() == [Status.OK, Status.NONFINITE_STATE], kernel


@pytest.mark.skipif(shutil.which("gcc") is None, reason="needs gcc")
def test_the_generated_c_refuses_finite_math_only(tmp_path):
    source = GENERATED / "double_pendulum" / "lcg_double_pendulum.c"
    argv = ["gcc", "-std=c99", "-O2", "-c", str(source), "-I", str(source.parent), "-o", str(tmp_path / "k.o")]
    assert subprocess.run(argv, capture_output=True).returncode == 0
    failed = subprocess.run([*argv, "-ffast-math"], capture_output=True, text=True)
    assert failed.returncode != 0 and "-fno-finite-math-only" in failed.stderr
    assert subprocess.run([*argv, "-ffast-math", "-fno-finite-math-only"], capture_output=True).returncode == 0
