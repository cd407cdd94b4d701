"""Bad input to ``compile_model`` and the build: fixed values that are not numbers, names that
are not parameters, an empty model name, a missing compiler or missing Python headers, and a
model whose build is expensive (a named warning before gcc starts, not minutes of silence).
Every error is checked for its type and for naming the culprit.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog, derive_equations, pipeline
from lagcodegen.codegen.reduce import KernelError, reduce_expressions
from lagcodegen.model import TIME, Model, ModelError
from lagcodegen.native import build, build_cost, cache
from lagcodegen.native.build import BuildError, compiler_available
from lagcodegen.pipeline import compile_model

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    monkeypatch.setattr(build, "_MEMO", {})
    return root


@pytest.fixture(scope="module")
def pendulum(example_eom):
    return example_eom("double_pendulum")  # parameters m1 m2 l1 l2 g, coordinates q1 q2


# --- fixed values -----------------------------------------------------------------------------

@pytest.mark.parametrize("value", ["abc", "9.81", None, float("nan"), float("inf"), -math.inf, 1 + 2j,
                                   True, sp.Symbol("x"), sp.nan, sp.oo, sp.I, [9.81], object()],
                         ids=lambda v: type(v).__name__ + ":" + repr(v)[:12])
def test_non_numeric_fixed_value_names_the_parameter(pendulum, fresh_cache, value):
    with pytest.raises(KernelError) as info:
        compile_model(pendulum, fixed={"g": value}, methods=("rk4",))
    message = str(info.value)
    assert "'g'" in message and ("real number" in message or "finite" in message), message
    assert not fresh_cache.exists() or not any(fresh_cache.rglob("*.so"))  # nothing was built


@pytest.mark.parametrize("value", ["abc", None, True, float("nan"), [9.81], object()],
                         ids=lambda v: type(v).__name__)
def test_reduce_expressions_names_a_non_numeric_fixed_value(pendulum, value):
    # the stage called directly (without compile_model's check) used to raise float()'s bare error
    with pytest.raises(KernelError, match="'g'"):
        reduce_expressions(pendulum, ["rhs"], {"g": value})


@pytest.mark.parametrize("key, culprit, what", [
    ("gravity", "gravity", "not a parameter"),
    (sp.Symbol("k"), "k", "not a parameter"),
    ("q1", "q1", "a coordinate"),
    (sp.Function("q2")(TIME), "q2", "a coordinate"),
])
def test_fixed_name_that_is_not_a_parameter_is_named(pendulum, fresh_cache, key, culprit, what):
    with pytest.raises(KernelError) as info:
        compile_model(pendulum, fixed={key: 1.0}, methods=("rk4",))
    message = str(info.value)
    assert repr(culprit) in message and what in message and "m1" in message, message


@pytest.mark.parametrize("value, expected", [(np.float32(2.5), 2.5), (np.int64(3), 3.0), (sp.Rational(1, 4), 0.25),
                                             (sp.pi, math.pi), (7, 7.0)])
def test_numeric_fixed_values_of_any_kind_are_accepted(pendulum, value, expected):
    assert pipeline._checked_fixed(pendulum, {"g": value}) == {"g": expected}
    assert pipeline._checked_fixed(pendulum, {sp.Symbol("g", positive=True): value}) == {"g": expected}


def test_a_fixed_value_that_leaves_an_entry_undefined_is_named(fresh_cache):
    """Found by review: V = k x^2 log(L) with L fixed at 0 failed in the C printer, naming only F[0]
    ("zoo is not supported"), not the fixed value that made it."""
    import sympy.physics.mechanics as me

    x = me.dynamicsymbols("x")
    m, k, length = sp.symbols("m k L", positive=True)
    model = Model("log_spring", [x], [m, k, length], kinetic_energy=m * x.diff() ** 2 / 2,
                  potential_energy=k * x ** 2 * sp.log(length), parameter_values={m: 1.0, k: 1.0, length: 2.0})
    with pytest.raises(KernelError, match=r"with L = 0\.0 folded in, F\[0\] is undefined \(zoo\)"):
        compile_model(model, methods=("rk4",), fixed={"L": 0.0})


def test_one_output_or_method_given_as_a_string_is_that_one(pendulum, fresh_cache):
    """Found by review: outputs="rhs" read as the outputs 'r', 'h', 's' ("unknown output 'r'")."""
    one = compile_model(pendulum, outputs="rhs", methods="rk4")
    assert one.layout.methods == ("rk4",) and one.layout.functions == \
        compile_model(pendulum, outputs=("rhs",), methods=("rk4",)).layout.functions


def test_empty_model_name_is_a_model_error():
    q = sp.Function("q")(TIME)
    for name in ("", "   "):
        with pytest.raises(ModelError, match="model name must be a non-empty string"):
            Model(name, [q], (), kinetic_energy=q.diff(TIME) ** 2 / 2)
    # found by review (session 16): accepted, then a bare UnicodeEncodeError in the cache key
    with pytest.raises(ModelError, match=r"model name 'osc\\udcff' is not valid Unicode text \(surrogates not allowed"):
        Model("osc\udcff", [q], (), kinetic_energy=q.diff(TIME) ** 2 / 2)


# --- compiler and headers ---------------------------------------------------------------------

def test_missing_compiler_names_it_and_how_to_install(pendulum, fresh_cache, tmp_path, monkeypatch):
    missing = str(tmp_path / "no-such-cc")
    monkeypatch.setenv("CC", missing)
    with pytest.raises(BuildError) as info:
        compile_model(pendulum, methods=("rk4",))
    message = str(info.value)
    assert missing in message and "apt-get install gcc" in message and "set CC" in message


@pytest.mark.compiler
@needs_cc
def test_missing_python_headers_say_install_python3_dev(pendulum, fresh_cache, tmp_path, monkeypatch):
    empty = tmp_path / "include"
    empty.mkdir()
    real = build.sysconfig.get_paths

    def no_headers(*args, **kwargs):
        return {**real(*args, **kwargs), "include": str(empty)}

    monkeypatch.setattr(build.sysconfig, "get_paths", no_headers)
    with pytest.raises(BuildError) as info:
        compile_model(pendulum, methods=("rk4",))
    message = str(info.value)
    assert "Python.h" in message and str(empty) in message and "python3-dev" in message
    assert "double_pendulum" in message


# --- build cost -------------------------------------------------------------------------------

def test_estimate_reads_the_op_counts_after_cse(pendulum, fresh_cache, monkeypatch):
    # The estimate's inputs are the kernels' operation counts after CSE (ReducedKernel.ops_after,
    # the second route: reduce_expressions called directly) and the methods compiled in.
    seen = []
    real = pipeline.estimate_build_cost

    def spy(model, ops, methods):
        seen.append((model, dict(ops), tuple(methods)))
        return real(model, ops, methods)

    monkeypatch.setattr(pipeline, "estimate_build_cost", spy)
    monkeypatch.setattr(build, "_compiler_identity", lambda command: "no compiler needed")
    monkeypatch.setattr(build, "_fetch", lambda job, root: (None, None, root / "x.so", None))  # skip gcc
    compile_model(pendulum, methods=("rk4", "heun"))
    compile_model(pendulum, methods=("rk4", "heun"))  # from the sources cache: same inputs
    system = reduce_expressions(pendulum, ["rhs", "energy", "points"])
    expected = {k.name: k.ops_after for k in system.kernels}
    assert seen == [("double_pendulum", expected, ("heun", "rk4"))] * 2 or \
        seen == [("double_pendulum", expected, ("rk4", "heun"))] * 2, seen


def test_estimate_grows_with_the_chain_and_the_methods():
    costs = []
    for n in (2, 3, 4):
        system = reduce_expressions(derive_equations(catalog.pendulum_chain(n)),
                                    ["rhs", "energy", "points", "jacobian", "momentum"])
        ops = {k.name: k.ops_after for k in system.kernels}
        default = build_cost.estimate_build_cost(f"chain{n}", ops, pipeline.DEFAULT_METHODS)
        rk4 = build_cost.estimate_build_cost(f"chain{n}", ops, ("rk4",))
        assert rk4.seconds < default.seconds and default.cheaper_seconds <= rk4.seconds
        assert default.cheaper_megabytes <= default.megabytes
        costs.append(default)
    assert costs[0].seconds < costs[1].seconds < costs[2].seconds
    assert costs[0].megabytes < costs[1].megabytes < costs[2].megabytes
    assert all(c.seconds < build_cost.MAX_SECONDS and c.megabytes < build_cost.MAX_MEGABYTES for c in costs)


def test_large_kernels_pass_the_default_limits():
    # Operation counts of the 40-link chain's kernels (extrapolated, ~n^2, from n = 5..30 in the
    # calibration table of build_cost.py): a build reported at 6 minutes and 2.6 GB.
    ops = {"dynamics": 4300, "energy": 722, "points": 278, "jacobian": 32200, "momentum": 16500}
    cost = build_cost.estimate_build_cost("chain40", ops, pipeline.DEFAULT_METHODS)
    assert cost.seconds > build_cost.MAX_SECONDS or cost.megabytes > build_cost.MAX_MEGABYTES
    assert cost.cheaper_seconds < build_cost.MAX_SECONDS and cost.cheaper_megabytes < build_cost.MAX_MEGABYTES


@pytest.mark.compiler
@needs_cc
def test_expensive_build_warns_first_with_cheaper_options(pendulum, fresh_cache, monkeypatch):
    monkeypatch.setattr(build_cost, "MAX_SECONDS", 0.0)  # every build is "expensive"
    with pytest.warns(build_cost.BuildCostWarning) as record:
        system = compile_model(pendulum, methods=("rk4", "heun"))
    (warning,) = [w for w in record if issubclass(w.category, build_cost.BuildCostWarning)]
    message = str(warning.message)
    assert "'double_pendulum'" in message and "estimated to take ~" in message and "MB" in message
    assert "methods=('rk4',)" in message and "fewer outputs" in message and "dynamics" in message
    assert warning.filename == __file__  # points at the caller of compile_model

    build._MEMO.clear()  # cached now: loading it again compiles nothing and warns nothing
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", build_cost.BuildCostWarning)
        again = compile_model(pendulum, methods=("rk4", "heun"))
    assert again.key == system.key


@pytest.mark.compiler
@needs_cc
def test_small_build_does_not_warn(pendulum, fresh_cache):
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error", build_cost.BuildCostWarning)
        compile_model(pendulum, methods=("rk4",))
