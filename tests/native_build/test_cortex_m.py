"""The float kernels in generated/ build for a Cortex-M4F (single-precision FPU) without warnings
or double promotion, hold no mutable global/static state (.data and .bss are 0) and need
nothing but libm (plus the mem* functions GCC may emit for any target, see below).

The code-size table is printed (``pytest -s``) and written to ``cortex_m4_sizes.txt`` in the
test's tmp dir; the path is printed too.
"""
from __future__ import annotations

import subprocess
from pathlib import Path

import pytest

pytestmark = pytest.mark.compiler

GENERATED = Path(__file__).resolve().parents[2] / "generated"
FLOAT_SOURCES = sorted(GENERATED.glob("*/lcg_*_f32.c"))
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wdouble-promotion", "-Werror",
         "-mcpu=cortex-m4", "-mthumb", "-mfloat-abi=hard", "-mfpu=fpv4-sp-d16", "-O2", "-c"]
#: single-precision <math.h> functions the kernels may call (C99 section 7.12)
LIBM = {f + "f" for f in """sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp
exp2 expm1 log log10 log1p log2 pow sqrt cbrt hypot fabs fmod copysign floor ceil round trunc
fmin fmax fma erf erfc tgamma lgamma""".split()}
#: GCC "requires the freestanding environment provide memcpy, memmove, memset and memcmp" (GCC
#: manual, "C Language Standards"): at -O2 it may turn a zeroing loop into a memset call.
FREESTANDING = {"memcpy", "memmove", "memset", "memcmp"}


def run(argv) -> str:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{' '.join(map(str, argv))}\n{result.stderr}"
    return result.stdout


@pytest.fixture(scope="module")
def objects(tmp_path_factory, require_tool):
    """Every float kernel compiled for Cortex-M4F: {source: object path}."""
    gcc = require_tool("arm-none-eabi-gcc")
    out = tmp_path_factory.mktemp("cortex_m4")
    assert FLOAT_SOURCES, f"no lcg_*_f32.c under {GENERATED}"
    built = {}
    for source in FLOAT_SOURCES:
        obj = out / (source.stem + ".o")
        run([gcc, *FLAGS, source, "-o", obj])
        built[source] = obj
    return built


def test_code_size_table(objects, require_tool, tmp_path):
    size = require_tool("arm-none-eabi-size")
    rows = []
    for source, obj in objects.items():
        lines = run([size, "-B", obj]).splitlines()  # Berkeley format: text data bss dec hex
        text, data, bss = (int(v) for v in lines[1].split()[:3])
        rows.append((source.stem, text, data, bss))
    width = max(len(r[0]) for r in rows)
    table = [f"Cortex-M4F code size (arm-none-eabi-gcc -O2 {' '.join(FLAGS[6:10])})",
             f"{'object':<{width}}  {'text':>7}  {'data':>5}  {'bss':>5}"]
    table += [f"{name:<{width}}  {text:>7}  {data:>5}  {bss:>5}" for name, text, data, bss in rows]
    table.append(f"{'total':<{width}}  {sum(r[1] for r in rows):>7}  {sum(r[2] for r in rows):>5}  "
                 f"{sum(r[3] for r in rows):>5}")
    report = tmp_path / "cortex_m4_sizes.txt"
    report.write_text("\n".join(table) + "\n")
    print("\n" + "\n".join(table) + f"\n(table written to {report})")
    stateful = [(name, data, bss) for name, _, data, bss in rows if data or bss]
    assert not stateful, f"kernels with mutable global/static state (.data/.bss bytes): {stateful}"
    assert all(text > 0 for _, text, _, _ in rows)


def test_only_libm_is_needed(objects, require_tool):
    nm = require_tool("arm-none-eabi-nm")
    for source, obj in objects.items():
        undefined = set(run([nm, "-u", obj]).split()) - {"U"}
        # LIBM holds only the float variants: a double `sin` or `sqrt` would fail here too
        assert undefined <= LIBM | FREESTANDING, f"{source.name} needs {sorted(undefined - LIBM - FREESTANDING)}"


def test_exports_carry_the_prefix(objects, require_tool):
    nm = require_tool("arm-none-eabi-nm")
    for source, obj in objects.items():
        symbols = [line.split() for line in run([nm, "-g", "--defined-only", obj]).splitlines()]
        names = [s[-1] for s in symbols if s]
        assert names and all(n.startswith(source.stem + "_") for n in names), (source.name, names)
