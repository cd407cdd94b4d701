"""The emitted header as firmware uses it: from C++, and beside other models' headers.

Found by review: the header had no ``extern "C"``, so g++ compiled a caller and the link failed
("undefined reference to lcg_..._step_rk4(double*, ...)"); and two models whose names differ
only in case ("Pendulum", "pendulum") shared the include guard and every macro (the macros fold
case), so including both dropped the second header. The reference values come from the same
kernel through Python (`simulate`), the second route into the same C.
"""
from __future__ import annotations

import subprocess

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, derive_equations
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

pytestmark = pytest.mark.compiler

X0 = (0.5, 0.0)
H = 0.01


def _pendulum(name: str, length: float) -> Model:
    """A simple pendulum of the given length (g = 9.81): T = l^2 q'^2 / 2, V = -g l cos q."""
    q = me.dynamicsymbols("q")
    g, l = sp.symbols("g l", positive=True)
    return Model(name, [q], [g, l], kinetic_energy=l**2 * q.diff()**2 / 2, potential_energy=-g * l * sp.cos(q),
                 parameter_values={g: 9.81, l: length})


def _emit(model: Model, directory):
    sources = render_sources(reduce_expressions(derive_equations(model), ("rhs",)), methods=["rk4"])
    (directory / sources.header_name).write_text(sources.header)
    (directory / sources.source_name).write_text(sources.source)
    return sources


def _run(argv):
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, f"{' '.join(map(str, argv))}:\n{result.stdout}\n{result.stderr}"
    return result.stdout


def _one_step(model: Model) -> np.ndarray:
    return simulate(compile_model(model, methods=("rk4",), outputs=("rhs",)), X0, t_end=H, h=H,
                    check_stability=False).x[-1]


def test_two_models_differing_in_case_and_a_cxx_caller(tmp_path, require_tool):
    gcc, gxx = require_tool("gcc"), require_tool("g++")
    upper, lower = _pendulum("Pendulum", 2.0), _pendulum("pendulum", 1.0)
    a, b = _emit(upper, tmp_path), _emit(lower, tmp_path)
    assert a.header_name.lower() != b.header_name.lower()  # apart on case-folding file systems too
    pa, pb = a.layout.prefix, b.layout.prefix
    caller = tmp_path / "caller.cpp"
    caller.write_text(f"""
#include <cstdio>
#include "{a.header_name}"
#include "{b.header_name}"
static void step(int (*f)(double *, double *, const double *, double, double *), double l) {{
    double t = 0.0, x[2] = {{{X0[0]}, {X0[1]}}}, p[2] = {{9.81, l}}, work[64];
    if (f(&t, x, p, {H}, work) != LCG_OK) {{ std::printf("failed\\n"); return; }}
    std::printf("%.17g %.17g\\n", x[0], x[1]);
}}
int main() {{
    static_assert({pa.upper()}_N_STATE == 2 && {pb.upper()}_N_STATE == 2, "both headers seen");
    step({pa}_step_rk4, 2.0);
    step({pb}_step_rk4, 1.0);
    return 0;
}}
""")
    objects = []
    for sources in (a, b):
        obj = tmp_path / (sources.source_name + ".o")
        _run([gcc, "-std=c99", "-O2", "-c", tmp_path / sources.source_name, "-o", obj])
        objects.append(obj)
    exe = tmp_path / "caller"
    _run([gxx, "-std=c++11", "-Wall", "-Werror", "-I", tmp_path, caller, *objects, "-o", exe, "-lm"])
    lines = _run([exe]).split("\n")
    np.testing.assert_allclose([float(v) for v in lines[0].split()], _one_step(upper), rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose([float(v) for v in lines[1].split()], _one_step(lower), rtol=1e-15, atol=1e-15)


def test_names_mangling_merges_get_prefixes_of_their_own(tmp_path, require_tool):
    """Found by review: "arm-left", "arm left" and "arm_left" all became lcg_arm_left (one include guard,
    one file name: emitting both overwrote the first, linking both failed), as did "for" and "for_".
    A name mangling changed now gets 8 hex digits of its sha256; a plain one keeps its prefix. All
    four link into one program."""
    gcc = require_tool("gcc")
    names = ("arm-left", "arm left", "arm_left", "for", "for_")
    sources = [_emit(_pendulum(name, 1.0), tmp_path) for name in names]
    prefixes = [s.layout.prefix for s in sources]
    assert len(set(prefixes)) == len(names) and len({s.header_name for s in sources}) == len(names)
    assert prefixes[2] == "lcg_arm_left" and prefixes[4] == "lcg_for_"
    main = tmp_path / "main.c"
    main.write_text("".join(f'#include "{s.header_name}"\n' for s in sources) + "int main(void) { return 0; }\n")
    _run([gcc, "-std=c99", "-Wall", "-Werror", "-I", tmp_path, main,
          *(tmp_path / s.source_name for s in sources), "-o", tmp_path / "all", "-lm"])
