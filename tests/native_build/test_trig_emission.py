"""A source defines exactly the sine/cosine helpers it calls (templates/trig.c.j2 and the lane
wrappers of templates/lanes.c.j2), so it builds under ``-std=c99 -Wall -Wextra -Wpedantic
-Werror`` with clang as well as gcc: clang rejects an unused static function (gcc does not warn
for ``static inline`` ones, which is how ``lcg_sin``/``lcg_cos`` went unnoticed in generated/),
and a missing one is an implicit declaration, an error too.

The model is a simple pendulum, V = -m g l cos(theta), whose outputs call sine and cosine
separately: the forcing -m g l sin(theta) only sine, the energy only cosine, mass matrix m l^2
neither (Goldstein, Classical Mechanics, sec. 1.4), so every subset of the helpers is needed
by some source below.
"""
from __future__ import annotations

import itertools
import subprocess

import pytest
import sympy as sp
import sympy.physics.mechanics as me

pytestmark = pytest.mark.compiler

#: output sets calling sin only (forcing; rhs: M ud = F), cos only (energy), both, and neither
OUTPUT_SETS = (("forcing",), ("rhs",), ("energy",), ("rhs", "energy"), ("mass_matrix",))
FLAGS = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-c"]


@pytest.fixture(scope="module")
def sources(tmp_path_factory):
    """Every (outputs, precision, trig, lanes) variant of the pendulum, written to disk:
    {label: path of the .c file}."""
    from lagcodegen import derive_equations
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources
    from lagcodegen.model import Model

    m, l, g = sp.symbols("m l g", positive=True)
    theta = me.dynamicsymbols("theta")
    eom = derive_equations(Model("pendulum", [theta], (m, l, g), kinetic_energy=m * l ** 2 * theta.diff() ** 2 / 2,
                                 potential_energy=-m * g * l * sp.cos(theta),
                                 parameter_values={m: 1.0, l: 1.0, g: 9.81}))
    root = tmp_path_factory.mktemp("trig_emission")
    written = {}
    for outputs in OUTPUT_SETS:
        system = reduce_expressions(eom, outputs)
        methods = ("rk4",) if "rhs" in outputs else ()
        for precision, trig, lanes in itertools.product(("double", "float"), ("libm", "inline"), (0, 4)):
            label = f"{'+'.join(outputs)}-{precision}-{trig}-lanes{lanes}"
            generated = render_sources(system, precision, methods=methods, trig=trig, lanes=lanes)
            folder = root / label
            folder.mkdir()
            (folder / generated.header_name).write_text(generated.header)
            (folder / generated.source_name).write_text(generated.source)
            written[label] = folder / generated.source_name
    return written


@pytest.mark.parametrize("compiler", ["gcc", "clang"])
def test_every_trig_variant_builds_warning_free(sources, compiler, require_tool):
    cc = require_tool(compiler)
    failed = []
    for label, source in sources.items():
        extra = ["-Wdouble-promotion"] if "-float-" in label else []
        result = subprocess.run([cc, *FLAGS, *extra, str(source), "-o", str(source.with_suffix(".o"))],
                                capture_output=True, text=True, timeout=120)
        if result.returncode != 0:
            failed.append(f"{label}:\n{result.stderr[-1500:]}")
    assert not failed, f"{len(failed)} of {len(sources)} variants fail under {compiler}:\n" + "\n".join(failed)


def test_the_variants_call_each_helper_subset(sources):
    """Guards the test above against a model change that would stop exercising the subsets:
    some variant calls only sin, some only cos (read from the printed C on purpose: this checks
    the test's inputs, not a decision of the code)."""
    called = {label: {f for f in ("lcg_sin", "lcg_cos") if f + "(" in path.read_text() or f + "f(" in path.read_text()}
              for label, path in sources.items() if "-inline-" in label}
    assert {"lcg_sin"} in called.values() and {"lcg_cos"} in called.values()
    assert {"lcg_sin", "lcg_cos"} in called.values() and set() in called.values()


@pytest.mark.parametrize("optimization", ["-O2", "-O3"])
def test_a_driven_model_with_a_measured_input_builds_warning_free(tmp_path, optimization, require_tool):
    """Found by review: the sweep of a driven model measured a member whose start is not finite with
    its inputs unread (uninitialised r: undefined behaviour, and gcc -O2 -Werror failed on
    "'r' may be used uninitialized"). Now they read NaN until read."""
    from lagcodegen import derive_equations
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources
    from lagcodegen.model import Model

    cc = require_tool("gcc")
    x, force = me.dynamicsymbols("x F")
    m, k = sp.symbols("m k", positive=True)
    eom = derive_equations(Model("spring_mass", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                 potential_energy=k * x ** 2 / 2, generalized_forces={x: force}, inputs=[force],
                                 measurements={"power": force * x.diff()}))
    generated = render_sources(reduce_expressions(eom, ("rhs", "measurements")), "double", methods=("rk4",))
    (tmp_path / generated.header_name).write_text(generated.header)
    (tmp_path / generated.source_name).write_text(generated.source)
    built = subprocess.run([cc, *FLAGS, optimization, str(tmp_path / generated.source_name), "-o",
                            str(tmp_path / "model.o")], capture_output=True, text=True, timeout=300)
    assert built.returncode == 0, built.stderr
