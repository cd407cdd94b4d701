"""What the explicit steppers compute, and that the sources cache follows the emitter's code.

- A step evaluates only the stages whose derivatives reach the result (`needed_stages`):
  Dormand-Prince's 7th stage exists for the embedded error estimate (b_7 = 0) and is skipped.
  The expected sets come from the tableaux as printed in Hairer-Norsett-Wanner I, Table II.5.2
  (dopri5) and Butcher's classical RK4, not from the code under test.
- A small dynamics kernel is inlined into the stages (`hot_dynamics`); the numbers a step
  produces do not depend on that choice (compared with a build that calls it).
- The rendered-sources cache key covers the package's own modules, so an edited emitter is not
  served sources rendered by the old one.
"""
from __future__ import annotations

import os
import re
from pathlib import Path

import numpy as np
import pytest

from lagcodegen import catalog, pipeline
from lagcodegen.codegen import steppers
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.codegen.steppers import needed_stages
from lagcodegen.integrators.tableaux import ButcherTableau, get_tableau
from lagcodegen.symbolic.derive import derive_equations


def _stepper_source(source: str, prefix: str, method: str) -> str:
    start = source.index(f"static int {prefix}_{method}_step(")
    return source[start:source.index("\n}\n", start)]


def test_dormand_prince_skips_its_error_estimate_stage():
    assert needed_stages(get_tableau("dopri5")) == [True] * 6 + [False]


@pytest.mark.parametrize("name", ["euler", "heun", "kutta3", "rk4", "rk38"])
def test_classical_methods_need_every_stage(name):
    assert all(needed_stages(get_tableau(name)))


def test_stage_feeding_only_a_needed_stage_is_kept():
    # b = (0, 0, 1, 0): stages 1 and 2 have b_i = 0 but feed stage 3 (a_21, a_32 nonzero);
    # stage 4 feeds nothing. Expected by reading the tableau.
    tableau = ButcherTableau("padded", ((0, 0, 0, 0), ("1/2", 0, 0, 0), (0, 1, 0, 0), (0, 0, 1, 0)),
                             (0, 0, 1, 0), (0, "1/2", 1, 1), 1, "padded")
    assert needed_stages(tableau) == [True, True, True, False]


@pytest.fixture(scope="module")
def double_pendulum_system():
    eom = derive_equations(catalog.double_pendulum())
    return reduce_expressions(eom, ["rhs"], None)


def test_rendered_dopri5_step_evaluates_six_stages(double_pendulum_system):
    sources = render_sources(double_pendulum_system, methods=["dopri5", "rk4"])
    prefix = sources.layout.prefix
    dopri5 = _stepper_source(sources.source, prefix, "dopri5")
    rk4 = _stepper_source(sources.source, prefix, "rk4")
    assert len(re.findall(rf"{prefix}_dynamics\w*\(", dopri5)) == 6
    assert len(re.findall(rf"{prefix}_dynamics\w*\(", rk4)) == 4


def test_small_dynamics_is_inlined_and_large_is_called(double_pendulum_system):
    small = render_sources(double_pendulum_system, methods=["rk4"])
    assert "static LCG_HOT_INLINE int lcg_double_pendulum_dynamics_hot(" in small.source
    assert "lcg_double_pendulum_dynamics_hot(" in _stepper_source(small.source, "lcg_double_pendulum", "rk4")
    chain = reduce_expressions(derive_equations(catalog.pendulum_chain(6)), ["rhs"], None)
    assert chain.kernel("dynamics").ops_after > steppers.HOT_DYNAMICS_MAX_OPS
    large = render_sources(chain, methods=["rk4"])
    assert "LCG_HOT_INLINE" not in large.source
    assert "_dynamics_hot" not in large.source


def test_inlined_stages_give_the_same_numbers_as_calls(monkeypatch, tmp_path):
    """The same steps with the dynamics inlined and called: equal to rounding (the reference
    is the called build, whose RK4 the order tests check against DOP853)."""
    from lagcodegen.run.simulate import simulate

    model = catalog.double_pendulum()
    x0 = {"q1": 1.0, "q2": 0.5, "q1_d": 0.0, "q2_d": 0.0}
    runs = {}
    for hot_limit in (steppers.HOT_DYNAMICS_MAX_OPS, -1):
        monkeypatch.setattr(steppers, "HOT_DYNAMICS_MAX_OPS", hot_limit)
        system = pipeline.compile_model(model, methods=["rk4", "dopri5"], cache_dir=tmp_path / f"limit{hot_limit}")
        source = (system.path.parent / f"{system.layout.prefix}.c").read_text()
        assert ("_dynamics_hot" in source) == (hot_limit >= 0)
        runs[hot_limit] = [simulate(system, x0, t_end=2.0, h=1e-2, method=m).x for m in ("rk4", "dopri5")]
    for inlined, called in zip(runs[steppers.HOT_DYNAMICS_MAX_OPS], runs[-1]):
        np.testing.assert_allclose(inlined, called, rtol=1e-13, atol=1e-13)


@pytest.mark.parametrize("model,x0", [(lambda: catalog.pendulum_chain(6), [0.3] * 6 + [0.0] * 6),
                                      (catalog.slider_crank, None)], ids=["chain6", "slider_crank"])
def test_a_shared_dynamics_kernel_gives_the_same_numbers(model, x0, monkeypatch, tmp_path):
    """The dynamics kernel compiled once in part 2 (LCG_SHARED, the limit lowered to 0) and once in
    each part (the limit out of reach): the same C function in another translation unit, so the
    same bits after 200 RK4 and 200 dopri5 steps (the reference is the usual build, whose RK4 the
    order tests check against DOP853)."""
    from lagcodegen.run.simulate import simulate

    model = model()
    runs = {}
    for limit in (0, 10 ** 9):
        monkeypatch.setattr(steppers, "SHARED_DYNAMICS_MIN_OPS", limit)
        system = pipeline.compile_model(model, methods=["rk4", "dopri5"], cache_dir=tmp_path / f"limit{limit}")
        assert ("LCG_SHARED int" in system.sources.source) == (limit == 0)
        start = x0 if x0 is not None else catalog.slider_crank_state(0.4, 2.0)
        runs[limit] = [simulate(system, start, t_end=2.0, h=1e-2, method=m).x for m in ("rk4", "dopri5")]
    for shared, usual in zip(runs[0], runs[10 ** 9]):
        np.testing.assert_array_equal(shared, usual)


def test_sources_key_follows_the_package_code(monkeypatch):
    eom = derive_equations(catalog.double_pendulum())
    args = (eom, ["rhs"], None, ("rk4",), "double")
    key = pipeline._sources_key(*args)
    assert pipeline._sources_key(*args) == key
    monkeypatch.setattr(pipeline, "_package_digest", lambda: "an edited emitter")
    assert pipeline._sources_key(*args) != key


def test_sources_key_follows_every_field_of_the_equations():
    """A measurement, an input or a constraint edited under the same model name gets new sources
    (these were once outside the key: a stale kernel with status OK)."""
    import dataclasses

    import sympy as sp

    eom = derive_equations(catalog.double_pendulum())
    args = (["rhs"], None, ("rk4",), "double")
    key = pipeline._sources_key(eom, *args)
    assert pipeline._sources_key(derive_equations(catalog.double_pendulum()), *args) == key  # a second derivation
    q1 = eom.q[0]
    for change in ({"measurements": (("y", q1),)}, {"measurements": (("y", 2 * q1),)},
                   {"inputs": (sp.Symbol("tau"),)}, {"n_dependent": 1}):
        assert pipeline._sources_key(dataclasses.replace(eom, **change), *args) != key, change


def test_equations_digest_follows_values_not_sharing_or_types():
    """The digest is a Merkle tree over the expressions (`pipeline._NodeDigests`). Equal values
    digest alike however their subexpressions are shared; values that differ only in type
    (Float(1.0) == Integer(1) in sympy, but they print differently) or in a symbol's assumptions
    digest apart; an expression deeper than the recursion limit digests. Expected relations by
    construction of the inputs (written here), not by the digest."""
    import sys

    import sympy as sp

    x, y = sp.symbols("x y")
    shared = sp.sin(x) * y
    sp.core.cache.clear_cache()  # else sympy's cache hands back the same objects
    alone = sp.Mul(sp.sin(sp.Symbol("x")), sp.Symbol("y"))
    assert alone is not shared and alone.args[0] is not shared.args[0]
    digest = pipeline._values_digest
    assert digest(((shared + 1, shared ** 2),)) == digest(((alone + 1, alone ** 2),))
    assert digest((x * sp.Float(1.0) + y,)) != digest((x * 1 + y,))
    assert digest((sp.Float(2.0) * x,)) != digest((2 * x,))
    assert digest((sp.Symbol("x", positive=True) + y,)) != digest((x + y,))
    assert digest((x - y,)) != digest((y - x,))
    assert digest((sp.Dummy("d"),)) != digest((sp.Dummy("d"),))  # as pickled: each Dummy is its own
    f = sp.Function("f")
    deep = x
    for _ in range(sys.getrecursionlimit() + 100):
        deep = f(deep)
    assert digest((deep,)) == digest((deep,)) != digest((f(deep),))


def test_sources_key_is_the_same_in_every_process(tmp_path):
    import subprocess
    import sys

    script = ("from lagcodegen import derive_equations, catalog, pipeline; "
              "print(pipeline._sources_key(derive_equations(catalog.centrifugal_governor()), ['rhs'], None, "
              "('rk4',), 'double'))")
    keys = {subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True,
                           env={**os.environ, "PYTHONHASHSEED": seed}).stdout for seed in ("0", "1")}
    assert len(keys) == 1, keys


def test_code_digest_covers_every_module_and_template(tmp_path):
    """A module edited anywhere in the package, subpackages included, or a template edited,
    changes the digest behind the sources key (else the cache would serve stale C after a move
    into subpackages); bytecode and other files do not."""
    package, templates = tmp_path / "pkg", tmp_path / "templates"
    (package / "codegen").mkdir(parents=True)
    templates.mkdir()
    (package / "__init__.py").write_text("")
    (package / "codegen" / "render.py").write_text("X = 1\n")
    (templates / "model.c.j2").write_text("/* {{ model }} */\n")
    before = pipeline.code_digest(package, templates)
    (package / "codegen" / "cached.pyc").write_bytes(b"\0")
    (templates / "notes.txt").write_text("not a template")
    assert pipeline.code_digest(package, templates) == before
    (package / "codegen" / "render.py").write_text("X = 2\n")
    after_module = pipeline.code_digest(package, templates)
    assert after_module != before
    (templates / "model.c.j2").write_text("/* {{ model }} edited */\n")
    assert pipeline.code_digest(package, templates) not in (before, after_module)
    (package / "codegen" / "render.py").rename(package / "render.py")  # a move alone changes it too
    assert pipeline.code_digest(package, templates) != after_module


def test_template_dir_is_found_from_the_package_and_missing_templates_are_named(monkeypatch, tmp_path):
    import lagcodegen
    from lagcodegen.codegen.render import template_dir

    assert (template_dir() / "model.c.j2").is_file()
    monkeypatch.setattr(lagcodegen, "__file__", str(tmp_path / "src" / "lagcodegen" / "__init__.py"))
    with pytest.raises(FileNotFoundError, match="model.c.j2"):
        template_dir()


def test_package_digest_reads_the_installed_package():
    from lagcodegen.codegen.render import template_dir

    assert pipeline._package_digest() == pipeline.code_digest(Path(pipeline.__file__).resolve().parent,
                                                              template_dir())


@pytest.mark.compiler
@pytest.mark.parametrize("model,shared", [("double_pendulum", False), ("slider_crank", False),
                                          ("double_pendulum", True), ("slider_crank", True)])
def test_build_parts_define_every_exported_function_once(model, shared, tmp_path, require_tool, monkeypatch):
    """LCG_BUILD_PART 1 and 2 (the parallel build) together define each exported function
    exactly once, and part 0 (the default, the embedded build) defines all of them. A shared
    dynamics kernel (`steppers.SHARED_DYNAMICS_MIN_OPS`, lowered here to 0) is defined once, in
    part 2, and internal in part 0."""
    import subprocess

    from lagcodegen.integrators.schemes import DEFAULT_METHODS

    monkeypatch.setattr(steppers, "SHARED_DYNAMICS_MIN_OPS", 0 if shared else 10 ** 9)
    if shared:  # the double pendulum's kernel is small enough to be inlined instead
        monkeypatch.setattr(steppers, "HOT_DYNAMICS_MAX_OPS", -1)

    gcc, nm_tool = require_tool("gcc"), require_tool("nm")
    eom = derive_equations(getattr(catalog, model)())
    methods = [m for m in DEFAULT_METHODS if not eom.m or m in ("rk4", "dopri5", "euler")]
    outputs = ["rhs", "mass_matrix", "energy"] + (["jacobian", "momentum"] if not eom.m else
                                                   ["constraints", "multipliers"])
    sources = render_sources(reduce_expressions(eom, outputs, None), methods=methods)
    (tmp_path / sources.header_name).write_text(sources.header)
    (tmp_path / sources.source_name).write_text(sources.source)
    defined = {}
    for part in (0, 1, 2):
        obj = tmp_path / f"part{part}.o"
        subprocess.run([gcc, "-O0", "-std=c99", f"-DLCG_BUILD_PART={part}", "-c",
                        str(tmp_path / sources.source_name), "-o", str(obj)], check=True)
        nm = subprocess.run([nm_tool, "--defined-only", "-g", str(obj)], capture_output=True, text=True, check=True)
        defined[part] = [line.split()[-1] for line in nm.stdout.splitlines() if line.split()[1] == "T"]
    exported = sorted(defined[0])
    prefix = sources.layout.prefix
    assert f"{prefix}_simulate" in exported and f"{prefix}_step_rk4" in exported
    kernel = f"{prefix}_dynamics" if not eom.m else f"{prefix}_dynamics_constrained"
    assert (f"LCG_SHARED int {kernel}(" in sources.source) == shared
    assert sorted(defined[1] + defined[2]) == sorted(exported + ([kernel] if shared else []))
    assert (kernel in defined[2]) == shared and kernel not in defined[1] + defined[0]


def test_the_header_documents_the_driven_drivers_arguments(driven_oscillator):
    """Found by review: for a model with inputs and measurements the header's simulate and sweep
    prototypes left inputs, context, hold, r_out, y_out, the per-member knot tables and the
    measurement summaries undocumented (a shared table overran under AddressSanitizer). The words
    are checked against what the drivers do (templates/steppers.c.j2: each member's own table,
    hold = 1 the ramp, y_min/y_max written unconditionally)."""
    from lagcodegen import derive_equations

    model = driven_oscillator("documented", measurements={"spring": lambda x, F, m, k, c: -k * x})
    header = render_sources(reduce_expressions(derive_equations(model), ("rhs", "measurements")),
                            methods=["rk4"]).header
    simulate_doc = header[:header.index("int lcg_documented_simulate(")].rsplit("/*", 1)[1]
    sweep_doc = header[:header.index("void lcg_documented_sweep(")].rsplit("/*", 1)[1]
    assert "The 1 inputs come from inputs(context, t, x, r) (not NULL" in simulate_doc
    assert "with hold = 1 also at the step's end" in simulate_doc and "r_out (or NULL)" in simulate_doc
    assert "y_out (or NULL) receives the 1 measurements" in simulate_doc
    assert "its own table of n_knots knots (times input_t + m * n_knots, values input_r + m * n_knots * 1)" \
        in " ".join(sweep_doc.split())
    assert "y_final, y_min and y_max + m * 1 (required)" in " ".join(sweep_doc.split())
