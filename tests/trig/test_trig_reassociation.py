"""The inline sine and cosine under the compilers' fast-math flags (found by review).

The argument reduction rounds x 2/pi by adding and subtracting 1.5 * 2^k and carries its error in
two-sums: under reassociation gcc and clang fold both away, and lcg_sin(-3.6652) came out as
-4.4e-16 instead of 0.5. The old guard looked for __FAST_MATH__ only, which neither compiler
defines once any part of fast-math is switched off, and lagcodegen's own builds always add
-fno-finite-math-only (tests/native_build/test_fast_math.py): so every inline and lane-kernel sine
was wrong with status OK in a build given -ffast-math. Now gcc's builds call libm where it says
it reassociates (__ASSOCIATIVE_MATH__), and clang's turn reassociation off in the trig bodies.

Expected values: Python's math.sin and math.cos (glibc, correctly rounded on this sample to well
within the bound), and for the end-to-end check DOP853 at rtol = atol = 1e-12 on the double
pendulum's textbook equations (point masses on massless rods, absolute angles), written here.
"""
from __future__ import annotations

import math
import shutil
import subprocess
import warnings

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from lagcodegen import catalog
from lagcodegen.codegen.render import trig_source
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import sweep

pytestmark = pytest.mark.compiler

FAST_MATH = [("-ffast-math", "-fno-finite-math-only"), ("-Ofast", "-fno-finite-math-only"),
             ("-fassociative-math", "-fno-signed-zeros", "-fno-trapping-math"),
             ("-funsafe-math-optimizations", "-fno-finite-math-only")]
POINTS = [-3.6652, -2.5, -1.0, -0.3, 0.1, 0.7, 1.5707963267948966, 2.0, 3.14159, 10.0, 123.456, -987.25]
PROGRAM = """
#include <stdio.h>
#include <math.h>
{trig}
int main(void)
{{
    static const double points[] = {{ {points} }};
    unsigned i;
    for (i = 0; i < sizeof points / sizeof points[0]; ++i) {{
        volatile {real} x = ({real})points[i];  /* volatile: no constant folding of the calls */
        printf("%.17g %.17g %.17g %.17g\\n", (double)lcg_sin{s}(x), (double)lcg_cos{s}(x),
               (double)lcg_sin{s}_fast(x), (double)lcg_cos{s}_fast(x));
    }}
    return 0;
}}
"""


@pytest.mark.parametrize("flags", FAST_MATH, ids=lambda f: " ".join(f))
@pytest.mark.parametrize("precision", ["double", "float"])
@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_inline_trig_is_right_under_fast_math(tmp_path, compiler, precision, flags):
    if shutil.which(compiler) is None:
        pytest.skip(f"needs {compiler}")
    real, suffix = precision, "f" if precision == "float" else ""
    source = tmp_path / "trig.c"
    source.write_text(PROGRAM.format(trig=trig_source(precision), real=real, s=suffix,
                                     points=", ".join(repr(x) for x in POINTS)))
    binary = tmp_path / "trig"
    built = subprocess.run([compiler, "-std=c99", "-O2", "-Wall", "-Wextra", "-Wpedantic", "-Werror", *flags,
                            str(source), "-o", str(binary), "-lm"], capture_output=True, text=True)
    assert built.returncode == 0, built.stderr
    rows = np.loadtxt(subprocess.run([str(binary)], capture_output=True, text=True, check=True).stdout.splitlines())
    tolerance = 4e-16 if precision == "double" else 2e-7  # a few units of rounding of |values| <= 1
    for x, (sine, cosine, sine_fast, cosine_fast) in zip(POINTS, rows):
        x = float(np.float32(x)) if precision == "float" else x
        assert abs(sine - math.sin(x)) <= tolerance and abs(sine_fast - math.sin(x)) <= tolerance, (x, sine)
        assert abs(cosine - math.cos(x)) <= tolerance and abs(cosine_fast - math.cos(x)) <= tolerance, (x, cosine)


def double_pendulum_rhs(_, y, m1=1.0, m2=1.0, l1=1.0, l2=1.0, g=9.81):
    """Point masses on massless rods, absolute angles from the downward vertical (textbook form)."""
    q1, q2, w1, w2 = y
    d = q1 - q2
    a = np.array([[(m1 + m2) * l1, m2 * l2 * math.cos(d)], [l1 * math.cos(d), l2]])
    b = np.array([-m2 * l2 * w2 ** 2 * math.sin(d) - (m1 + m2) * g * math.sin(q1),
                  l1 * w1 ** 2 * math.sin(d) - g * math.sin(q2)])
    return [w1, w2, *np.linalg.solve(a, b)]


def test_a_fast_math_build_with_inline_trig_and_lanes_integrates_right(tmp_path):
    """simulate (inline sin/cos) and the lane sweep kernel (always the branch-free forms) of a
    -ffast-math build follow the textbook double pendulum; before, both were off by about 2.9."""
    values = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}
    system = compile_model(catalog.double_pendulum(), fixed=values, methods=("rk4",), trig="inline",
                           extra_compile_args=("-ffast-math",), cache_dir=tmp_path)
    x0 = [1.0, 0.5, 0.0, 0.0]
    reference = solve_ivp(double_pendulum_rhs, (0.0, 1.0), x0, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        run = simulate(system, x0, t_end=1.0, h=1e-3)
        lanes = sweep(system, members={"q1": [1.0, 1.0, 1.0, 1.0]}, x0={"q2": 0.5}, t_end=1.0, h=1e-3,
                      kernel="auto")
    assert run.ok and np.max(np.abs(run.x[-1] - reference)) < 1e-9
    assert (lanes.status == 0).all() and np.max(np.abs(lanes.x_final - reference)) < 1e-9
