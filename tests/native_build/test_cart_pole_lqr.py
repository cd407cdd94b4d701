"""The embedded control loop of examples/cart_pole_lqr: the emitted cart-pole header and source
with balance.c (an LQR gain from the plant's step Jacobians) build warning-free with gcc and
clang, balance the pole from a 0.2 rad tilt, and agree with the same loop run in Python through
``simulate(inputs=callable)``; the float variant builds for a Cortex-M4F without mutable state.
"""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate, step_jacobians

pytestmark = pytest.mark.compiler

WARNINGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
CORTEX_M4F = ["-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", "-O2", "-c"]


@pytest.fixture(scope="module")
def example(cart_pole_example):
    return cart_pole_example


@pytest.fixture(scope="module")
def design(example, tmp_path_factory):
    """The plant compiled for Python, its discrete LQR gain and the Python closed loop."""
    plant = compile_model(example.cart_pole(), methods=("rk4",), outputs=("rhs", "step_jacobian"),
                          cache_dir=tmp_path_factory.mktemp("cart_pole"))
    p = [example.PARAMETERS[name] for name in plant.layout.parameters]
    _, Fx, Fr = step_jacobians(plant, [0, 0, 0, 0], p, example.H, r=[0.0])
    gain = example.discrete_lqr(Fx, Fr)
    run = simulate(plant, {"x": 0.0, "theta": example.TILT}, t_end=example.STEPS * example.H, h=example.H,
                   inputs=lambda t, x: [-gain @ x])
    return gain, run


def build_and_run(compiler: str, directory: Path) -> tuple[int, np.ndarray]:
    binary = directory / f"balance_{Path(compiler).name}"
    sources = sorted(str(s) for s in directory.glob("*.c"))
    built = subprocess.run([compiler, *WARNINGS, "-O2", "-I", str(directory), *sources, "-lm", "-o", str(binary)],
                           capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stderr
    ran = subprocess.run([str(binary)], capture_output=True, text=True, timeout=60)
    numbers = [float(v) for v in re.findall(r"(-?\d\.\d+e[-+]\d+)", ran.stdout)]
    return ran.returncode, np.array(numbers)


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_the_c_loop_balances_the_pole_as_the_python_loop_does(example, design, compiler, require_tool, tmp_path):
    tool = require_tool(compiler)
    gain, run = design
    assert run.ok and abs(run["theta"][-1]) < example.SETTLED  # the Python loop settles
    assert abs(run["theta"]).max() == pytest.approx(example.TILT)  # from the initial tilt, never beyond
    code, final = build_and_run(tool, example.emit(tmp_path, gain))
    assert code == 0, f"the C loop did not settle: {final}"
    # the same plant and controller: the C loop's final state is the Python loop's (printed to 4 digits)
    np.testing.assert_allclose(final, run.x[-1], rtol=1e-3, atol=1e-9)


def test_the_float_loop_balances_the_pole(example, design, require_tool, tmp_path):
    gcc = require_tool("gcc")
    gain, _ = design
    directory = example.emit(tmp_path, gain, precision="float")
    assert "typedef float plant_real;" in (directory / "cart_pole_plant.h").read_text()
    code, final = build_and_run(gcc, directory)
    assert code == 0, f"the float C loop did not settle: {final}"


def test_the_float_loop_builds_for_a_cortex_m4(example, design, require_tool, tmp_path):
    gcc = require_tool("arm-none-eabi-gcc")
    size = require_tool("arm-none-eabi-size")
    gain, _ = design
    directory = example.emit(tmp_path, gain, precision="float")
    for source in sorted(directory.glob("*.c")):
        obj = tmp_path / (source.stem + ".o")
        built = subprocess.run([gcc, *WARNINGS, "-Wdouble-promotion", *CORTEX_M4F, "-I", str(directory), str(source),
                                "-o", str(obj)], capture_output=True, text=True, timeout=300)
        assert built.returncode == 0, built.stderr
        if source.stem.startswith("lcg_"):
            text, data, bss = (int(v) for v in subprocess.run([size, "-B", str(obj)], capture_output=True,
                                                              text=True).stdout.splitlines()[1].split()[:3])
            assert text > 0 and data == 0 and bss == 0
