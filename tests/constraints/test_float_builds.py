"""Float builds of the constrained systems: they compile for a Cortex-M4F (single-precision FPU)
with the flags of tests/native_build/test_cortex_m.py (no warnings, no double promotion, no mutable
static state, nothing but libm), and the host float build keeps the constraints to float
precision with projection.

The constrained systems are not in ``catalog.EXAMPLES`` (regenerate asks every example for the
jacobian output, which they lack), so tests/native_build/test_cortex_m.py does not see them; this file
renders their float C itself.
"""
from __future__ import annotations

import math
import subprocess

import numpy as np
import pytest

from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.run.simulate import simulate

MODELS = ("cartesian_pendulum", "slider_crank", "four_bar")
OUTPUTS = ("rhs", "energy", "points", "constraints", "multipliers")  # compile_model's defaults
METHODS = ("euler", "heun", "rk4", "dopri5")
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wdouble-promotion", "-Werror",
         "-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", "-O2", "-c"]
LIBM = {"sinf", "cosf", "sqrtf", "fabsf", "tanf", "asinf", "acosf", "atan2f", "powf"}
FREESTANDING = {"memcpy", "memmove", "memset", "memcmp"}  # GCC may emit these for any target


def run(argv) -> str:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{' '.join(map(str, argv))}\n{result.stderr}"
    return result.stdout


@pytest.mark.compiler
@pytest.mark.parametrize("name", MODELS)
def test_float_kernel_builds_for_cortex_m4(name, constrained_eom, require_tool, tmp_path):
    gcc, size, nm = (require_tool(t) for t in ("arm-none-eabi-gcc", "arm-none-eabi-size", "arm-none-eabi-nm"))
    sources = render_sources(reduce_expressions(constrained_eom(name), OUTPUTS), "float", methods=METHODS)
    (tmp_path / sources.header_name).write_text(sources.header)
    source = tmp_path / sources.source_name
    source.write_text(sources.source)
    obj = tmp_path / (source.stem + ".o")
    run([gcc, *FLAGS, source, "-o", obj])
    text, data, bss = (int(v) for v in run([size, "-B", obj]).splitlines()[1].split()[:3])
    undefined = set(run([nm, "-u", obj]).split()) - {"U"}
    exported = [line.split()[-1] for line in run([nm, "-g", "--defined-only", obj]).splitlines() if line.strip()]
    print(f"\n{source.name}: Cortex-M4F text {text} B, data {data}, bss {bss}; needs {sorted(undefined)}")
    assert data == 0 and bss == 0
    assert undefined <= LIBM | FREESTANDING
    prefix = sources.layout.prefix
    assert {f"{prefix}_multipliers", f"{prefix}_project", f"{prefix}_residuals"} <= set(exported)
    assert all(e.startswith(prefix + "_") for e in exported)


def test_host_float_build_keeps_the_constraint(compiled_system):
    """The Cartesian pendulum in float, 10 s at h = 1e-3: with projection the residual stays at
    the float projection tolerance (1e-6 in the generated C), well under the unprojected drift."""
    system = compiled_system("cartesian_pendulum", precision="float")
    x0 = [math.sin(1.0), -math.cos(1.0), 0.0, 0.0]
    free, kept = (np.abs(simulate(system, x0, 10.0, 1e-3, "rk4", stride=100, project=p, residuals=True)
                         .check().residuals).max(axis=0) for p in (False, True))
    print(f"\nfloat: max |phi|, |A u| without projection {free}, with {kept}")
    assert kept[0] < 2e-6 and kept[1] < 1e-6
    assert free[0] > 5 * kept[0]


@pytest.mark.compiler
@pytest.mark.parametrize("compiler", ["gcc", "clang"])
@pytest.mark.parametrize("precision", ["double", "float"])
def test_an_eliminated_model_builds_without_warnings(compiler, precision, require_tool, tmp_path):
    """Found by review: the eliminated sleigh's C (dependent speeds solved in the dynamics, no LDL^T
    of M) defined <prefix>_pivot_failure without calling it, and -Wall -Wextra -Werror, the README's
    flags, refused it with gcc and clang."""
    from test_chaplygin_sleigh import sleigh
    from test_velocity_elimination import Y

    from lagcodegen import derive_equations

    cc = require_tool(compiler)
    eom = derive_equations(sleigh(dependent_speeds=[Y]))
    sources = render_sources(reduce_expressions(eom, ("rhs", "energy", "points")), precision, methods=METHODS)
    (tmp_path / sources.header_name).write_text(sources.header)
    source = tmp_path / sources.source_name
    source.write_text(sources.source)
    run([cc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-O2", "-c", source,
         "-o", tmp_path / "sleigh.o"])
