"""Hostile names: model, coordinate, parameter and point names that are C keywords, <math.h>
functions, lagcodegen's own local names, or text with spaces, quotes, semicolons and comment
delimiters (sympy accepts any string as a Symbol or Function name).

Each hostile model is the double pendulum stated with energies; the reference is the same
physics with plain names (``a``, ``b``, ``m1`` ... ``g``), so every kernel must return the same
numbers (the second route: only the names differ). The generated C must build under
``gcc -std=c99 -Wall -Wextra -Wpedantic -Werror`` (float also ``-Wdouble-promotion``) and through
``build_module``, and a name may appear verbatim only inside a C comment that it cannot close.
"""
from __future__ import annotations

import functools
import re
import subprocess

import numpy as np
import pytest
import sympy as sp

from lagcodegen import derive_equations
from lagcodegen.codegen.outputs import DEFAULT_OUTPUTS
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.model import TIME, Model
from lagcodegen.native.build import build_module

STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Wshadow", "-Werror"]
PLAIN = ("plain_pendulum", ("a", "b"), ("m1", "m2", "l1", "l2", "g"), ("bob1", "bob2"))
METHODS = ("rk4", "implicit_midpoint")  # exercise both stepper templates with the prefix
#: (id, model name, 2 coordinate names, 5 parameter names (m1 m2 l1 l2 g), 2 point names)
CASES = [
    ("keywords", "int", ("double", "sin"), ("int", "t0", "x", "p", "M"), ("float", "cos")),
    ("locals", "double", ("x", "p"), ("tmp0", "out", "lcg_x", "M", "sin"), ("out", "p")),
    ("math", "sin", ("tmp0", "out"), ("x", "p", "t0", "double", "int"), ("sqrt", "M")),
    ("spaces", "my model", ("M", "lcg_x"), ("my mass", 'a"b', "c d", "tmp1", "out"), ("bob 1", "bob 2")),
    ("quotes", 'a"b', ('q"1', "q 2"), ('m"1', "m 2", "l;1", "l2", "g'"), ('"tip"', "it's")),
    ("injection", 'x; system("rm -rf /"); double y', ("x; y", 'z"'),
     ('p; exit(1);', "F", "ud", "xdot", "status"), ('x"); abort(); ("', "J")),
    ("cse_names", "tmp0", ("tmp1", "tmp2"), ("tmp3", "tmp4", "tmp5", "tmp6", "tmp0"), ("tmp7", "D_0")),
    ("solver_names", "lcg_x", ("M_0_0", "F_0"), ("D_0", "Dinv_0", "L_1_0", "y_0", "w_0"), ("qd", "B")),
    ("unicode", "pendule θ", ("θ₁", "θ₂"), ("m₁", "m₂", "ℓ₁", "ℓ₂", "g"), ("⊕", "bob")),
    ("newline", "two\nlines", ("q\n1", "q2"), ("m\\1", "m2", "l1", "l2", "g"), ("p\n", "q")),
]
#: names containing the comment delimiters; kept apart so a failure names the exact problem
COMMENT_CASES = [
    ("close_in_model", "evil */ model", ("a", "b"), ("m1", "m2", "l1", "l2", "g"), ("bob1", "bob2")),
    ("close_in_coordinate", "pendulum", ("a*/b", "/*c"), ("m1", "m2", "l1", "l2", "g"), ("bob1", "bob2")),
    ("close_in_parameter", "pendulum", ("a", "b"),
     ("*/ int main(void) { return 0; } /*", "m2", "l1", "l2", "g"), ("bob1", "bob2")),
    ("close_in_point", "pendulum", ("a", "b"), ("m1", "m2", "l1", "l2", "g"), ("tip */ x", "bob2")),
]


def pendulum(model_name, coordinates, parameters, points) -> Model:
    """Planar double pendulum by energies (Goldstein 3rd ed., sec. 1.6), any names."""
    q1, q2 = (sp.Function(c)(TIME) for c in coordinates)
    m1, m2, l1, l2, g = (sp.Symbol(n, positive=True) for n in parameters)
    x1, y1 = l1 * sp.sin(q1), -l1 * sp.cos(q1)
    x2, y2 = x1 + l2 * sp.sin(q2), y1 - l2 * sp.cos(q2)
    speed2 = lambda x, y: x.diff(TIME) ** 2 + y.diff(TIME) ** 2  # noqa: E731
    T = m1 * speed2(x1, y1) / 2 + m2 * speed2(x2, y2) / 2
    V = g * (m1 * y1 + m2 * y2)
    return Model(model_name, [q1, q2], (m1, m2, l1, l2, g), kinetic_energy=T, potential_energy=V,
                 points={points[0]: (x1, y1), points[1]: (x2, y2)},
                 parameter_values={m1: 1.0, m2: 2.0, l1: 1.5, l2: 0.7, g: 9.81})


@functools.cache
def reduced(case):
    """Derived and CSE'd once per case (cases are tuples of strings)."""
    _, model_name, coordinates, parameters, points = case
    eom = derive_equations(pendulum(model_name, coordinates, parameters, points))
    return reduce_expressions(eom, DEFAULT_OUTPUTS)


def sources_of(case, precision="double", methods=METHODS):
    """The C of ``case``; numeric comparisons pass ``methods=()``, the steppers only use the
    prefix and cost build time, while the strict-warning compiles keep them."""
    return render_sources(reduced(case), precision, methods=methods)


def gcc_strict(sources, tmp_path, gcc, precision):
    folder = tmp_path / precision
    folder.mkdir()
    (folder / sources.header_name).write_text(sources.header)
    (folder / sources.source_name).write_text(sources.source)
    flags = STRICT + (["-Wdouble-promotion"] if precision == "float" else [])
    argv = [gcc, *flags, "-c", str(folder / sources.source_name), "-o", str(folder / "kernel.o")]
    run = subprocess.run(argv, capture_output=True, text=True)
    assert run.returncode == 0, f"{' '.join(argv)}\n{run.stderr}\n--- header ---\n{sources.header[:3000]}"


# --- lexical checks ---------------------------------------------------------------------------

_TOKENS = re.compile(r'"(?:\\.|[^"\\\n])*"|/\*.*?\*/|//[^\n]*', re.S)


def comment_spans(code: str) -> list:
    """(start, end) of every C comment, found the way the C lexer finds them (strings first)."""
    return [m.span() for m in _TOKENS.finditer(code) if not m.group(0).startswith('"')]


def without_comments(code: str) -> str:
    return _TOKENS.sub(lambda m: m.group(0) if m.group(0).startswith('"') else " ", code)


def hostile(names) -> list:
    """The names that are not plain identifiers (those are mangled, never printed as code)."""
    return [n for n in names if not re.fullmatch(r"[A-Za-z0-9_]+", n)]


def assert_names_stay_in_comments(text: str, names, where: str) -> None:
    spans = comment_spans(text)
    for name in hostile(names):
        start = text.find(name)
        while start != -1:
            end = start + len(name)
            assert any(a <= start and end <= b for a, b in spans), (
                f"{where}: name {name!r} appears outside a C comment (or closes one) at offset {start}:\n"
                f"{text[max(0, start - 200):end + 200]}")
            start = text.find(name, start + 1)
    code = without_comments(text)
    for line in code.splitlines():
        if '"' in line:  # the only string literals: the own-header include, the header's extern "C", and
            # the inline trig's fixed pragma (templates/trig.c.j2)
            assert re.fullmatch(r'\s*#include "lcg_[A-Za-z0-9_]+\.h"\s*|extern "C" \{\s*|'
                                r'#define LCG_TRIG_STRICT _Pragma\("clang fp reassociate\(off\)"\)\s*', line), \
                f"{where}: {line!r}"


def case_names(case) -> list:
    _, model_name, coordinates, parameters, points = case
    return [model_name, *coordinates, *(c + "_d" for c in coordinates), *parameters, *points]


# --- numbers: hostile names give the plain model's values -------------------------------------

def call_all(system, t, x, p) -> dict:
    ffi, lib, layout = system.ffi, system.lib, system.layout
    n, real, prefix = layout.n, layout.precision, layout.prefix
    xs, ps = ffi.new(f"{real}[]", list(x)), ffi.new(f"{real}[]", list(p))
    out = {}
    for name, size in (("mass_matrix", n * n), ("forcing", n), ("accel", n), ("rhs", 2 * n),
                       ("points", 3 * len(layout.points)), ("jacobian", 4 * n * n)):
        buf = ffi.new(f"{real}[]", size)
        status = getattr(lib, f"{prefix}_{name}")(t, xs, ps, buf)
        assert status in (None, 0), f"{prefix}_{name} returned {status}"
        out[name] = np.array(list(buf))
    out["energy"] = np.array([getattr(lib, f"{prefix}_energy")(t, xs, ps)])
    return out


@pytest.fixture(scope="module")
def plain_system(kernel_cache_dir):
    return build_module(sources_of(("plain",) + PLAIN, methods=()))


def check_same_numbers(system, plain, rng):
    assert system.layout.n == plain.layout.n == 2
    for _ in range(3):
        t = float(rng.uniform(0, 2))
        x = np.concatenate([rng.uniform(-1.2, 1.2, 2), rng.uniform(-1, 1, 2)])
        p = np.array([1.0, 2.0, 1.5, 0.7, 9.81]) * rng.uniform(0.7, 1.3, 5)
        got, want = call_all(system, t, x, p), call_all(plain, t, x, p)
        for key in want:
            # same maths, CSE may order terms differently with other names: double rounding only
            error = np.abs(got[key] - want[key]) / np.maximum(1.0, np.abs(want[key]))
            assert error.max() <= 1e-12, f"{key}: {got[key]} != {want[key]}"


@pytest.mark.compiler
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_hostile_names_compile_strict(case, tmp_path, require_tool):
    gcc = require_tool("gcc")
    for precision in ("double", "float"):
        sources = sources_of(case, precision)
        gcc_strict(sources, tmp_path, gcc, precision)
        for attr in ("header", "source", "cdef"):
            assert_names_stay_in_comments(getattr(sources, attr), case_names(case), f"{case[0]} {attr}")
        assert re.fullmatch(r"lcg_[A-Za-z0-9_]+", sources.layout.prefix)


@pytest.mark.compiler
@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_hostile_names_give_plain_values(case, plain_system, rng):
    sources = sources_of(case, methods=())
    layout = sources.layout
    _, model_name, coordinates, parameters, points = case
    # the layout keeps the user's names; only the C identifiers are mangled
    assert layout.model == model_name
    assert layout.coordinates == coordinates and layout.parameters == parameters
    assert layout.points == points
    check_same_numbers(build_module(sources), plain_system, rng)


@pytest.mark.compiler
@pytest.mark.parametrize("case", COMMENT_CASES, ids=[c[0] for c in COMMENT_CASES])
def test_names_cannot_close_comments(case, tmp_path, require_tool, plain_system, rng):
    """A name holding ``*/`` must not end the header's input table (or any other) comment."""
    gcc = require_tool("gcc")
    sources = sources_of(case)
    for attr in ("header", "source", "cdef"):
        assert_names_stay_in_comments(getattr(sources, attr), case_names(case), f"{case[0]} {attr}")
    gcc_strict(sources, tmp_path, gcc, "double")
    check_same_numbers(build_module(sources_of(case, methods=())), plain_system, rng)


@pytest.mark.compiler
def test_parameter_named_t_is_not_time(tmp_path, require_tool, plain_system, rng):
    """A parameter Symbol('t', positive=True) is not the time symbol Symbol('t'): the kernels
    read it from p[] and must still mark the unused time argument ``(void)t;``."""
    gcc = require_tool("gcc")
    case = ("param_t", "pendulum", ("a", "b"), ("t", "m2", "l1", "l2", "g"), ("bob1", "bob2"))
    check_same_numbers(build_module(sources_of(case, methods=())), plain_system, rng)
    gcc_strict(sources_of(case), tmp_path, gcc, "double")


# --- long names: every identifier and file name stays bounded ---------------------------------

#: lengths around C99's 63 significant characters of an internal identifier, and far beyond
LONG = {"1": "a", "63": "a" * 63, "64": "a" * 64, "250": "a" * 250, "punct50": "!@#$%^&*()" * 5,
        "unicode": "θέσηγωνίαπεδουλου" * 6, "keyword": "double"}


@pytest.mark.parametrize("name", list(LONG.values()), ids=list(LONG))
def test_mangle_is_bounded_safe_and_deterministic(name):
    from lagcodegen.codegen.printer import RESERVED_NAMES, mangle

    out = mangle(name)
    assert re.fullmatch(r"[A-Za-z_][A-Za-z0-9_]*", out) and len(out) <= 63
    assert out not in RESERVED_NAMES and not out.lower().startswith("lcg_")
    assert mangle(name) == out  # deterministic
    assert len(mangle(name, max_len=40)) <= 40
    taken = set()
    first, second = mangle(name, taken), mangle(name, taken)  # a clash in one scope
    assert first != second and len(second) <= 63 and taken == {first, second}


def test_mangle_keeps_short_names_and_separates_long_ones():
    from lagcodegen.codegen.printer import mangle

    assert mangle("a" * 63) == "a" * 63  # at the limit: unchanged, as before the bound
    assert mangle("a" * 64).startswith("a" * 54 + "_") and len(mangle("a" * 64)) == 63
    # names that differ only after the cut must not collide (a hash of the whole name)
    stem = "link" * 30
    variants = {mangle(stem + tail) for tail in ("1", "2", "_1", " 1", "θ")}
    assert len(variants) == 5 and all(v.startswith(stem[:54]) for v in variants)
    assert mangle("double") == "double_"


#: (id, model name, coordinates, parameters, points): long and odd names everywhere
LONG_CASES = [
    ("len250", "m" * 250, ("q" * 250 + "1", "q" * 250 + "2"), ("m1", "m2", "l1", "l2", "g" * 300),
     ("bob1", "bob2")),
    ("len63_64", "m" * 63, ("a" * 63, "a" * 64), ("b" * 64, "b" * 65, "l1", "l2", "g"), ("p" * 64, "bob2")),
    ("punct", "!@#$%^&*()" * 5, ("?" * 50, "+" * 50), ("m1", "m2", ";" * 50, "l2", "g"), ("bob1", "bob2")),
    ("unicode", "θέσηγωνίαπεδουλου" * 6, ("θ" * 40, "φ" * 40), ("m₁" * 30, "m₂" * 30, "l1", "l2", "g"),
     ("bob1", "bob2")),
    ("after_cut", "pendulum", ("x" * 80 + "1", "x" * 80 + "2"), ("y" * 80 + "1", "y" * 80 + "2", "l1", "l2", "g"),
     ("bob1", "bob2")),
]


@pytest.mark.compiler
@pytest.mark.parametrize("case", LONG_CASES, ids=[c[0] for c in LONG_CASES])
def test_long_names_build_and_give_plain_values(case, tmp_path, require_tool, plain_system, rng):
    # These raised "OSError: File name too long" (model names) before identifiers were bounded.
    gcc = require_tool("gcc")
    sources = sources_of(case)
    gcc_strict(sources, tmp_path, gcc, "double")
    for file_name in (sources.header_name, sources.source_name):
        assert len(file_name.encode()) <= 80
    identifiers = set(re.findall(r"\b[A-Za-z_][A-Za-z0-9_]*\b", without_comments(sources.source)))
    assert max(len(i) for i in identifiers if not i.startswith("lcg_")) <= 63
    system = build_module(sources_of(case, methods=()))
    assert len(system.module_name) <= 63 and len(system.path.name.encode()) <= 120
    assert system.layout.model == case[1] and system.layout.coordinates == case[2]  # names kept
    check_same_numbers(system, plain_system, rng)


def test_models_differing_after_the_cut_get_different_prefixes():
    plain = ("plain",) + PLAIN
    first = sources_of(("a",) + ("z" * 100 + "1",) + plain[2:], methods=())
    second = sources_of(("b",) + ("z" * 100 + "2",) + plain[2:], methods=())
    assert first.layout.prefix != second.layout.prefix and first.header_name != second.header_name


@pytest.mark.compiler
def test_cli_emit_writes_bounded_file_names(tmp_path, capsys):
    from lagcodegen.cli.commands import main

    model_file = tmp_path / "long_model.py"
    model_file.write_text(
        "from lagcodegen import catalog\n"
        f"model = catalog.pendulum_chain(1, name={'pendulum' * 40!r})\n")
    assert main(["emit", str(model_file), "--out", str(tmp_path / "out")]) == 0
    written = sorted(p.name for p in (tmp_path / "out").iterdir())
    assert len(written) == 2 and all(len(name) <= 80 for name in written), written
    assert written[0].startswith("lcg_pendulumpendulum")


def _declared_identifiers(sources) -> list:
    """Every identifier the generated C declares (locals, arguments, arrays), in sorted order."""
    declared = set()
    for text in (sources.header, sources.source):
        declared |= set(re.findall(r"\b(?:double|float|int|long)\s+(?:const\s+)?\**\s*([A-Za-z_]\w*)", text))
    return sorted(name for name in declared if not name.lower().startswith("lcg_"))


def _kinds():
    """(plain model builder, outputs, methods): a driven plant with every output an embedded user
    asks for, a recursive tree, a model with an eliminated dependent speed; each takes extra
    parameters, all entering through their mean S (so any set of them gives the same physics)."""
    import sympy.physics.mechanics as me

    from lagcodegen import Link

    def driven(name, extra):
        x, F = me.dynamicsymbols("x F")
        S = sum(extra, sp.S.Zero) / len(extra) if extra else sp.Integer(4)
        return Model(name, [x], list(extra), kinetic_energy=x.diff()**2 / 2, potential_energy=S * x**2 / 2,
                     generalized_forces={x: F - x.diff() / 2}, inputs=[F], measurements={"stretch": x},
                     points={"bob": (x, 0)}, parameter_values={e: 4.0 for e in extra})

    def tree(name, extra):
        q = me.dynamicsymbols("q")
        S = sum(extra, sp.S.Zero) / len(extra) if extra else sp.Float(9.81)
        return Model(name, [q], list(extra), tree=[Link("rod", None, "revolute", (0, 0, 1), q, mass=1,
                                                       center=(0, -1, 0))],
                     gravity=(0, -S, 0), parameter_values={e: 9.81 for e in extra}, formulation="recursive")

    def eliminated(name, extra):
        t = TIME
        x, y, theta = me.dynamicsymbols("x y theta")
        S = sum(extra, sp.S.Zero) / len(extra) if extra else sp.Float(0.3)
        xc, yc = x + S * sp.cos(theta), y + S * sp.sin(theta)
        T = (xc.diff(t)**2 + yc.diff(t)**2) / 2 + theta.diff(t)**2 / 4
        blade = -x.diff(t) * sp.sin(theta) + y.diff(t) * sp.cos(theta)
        return Model(name, [x, y, theta], list(extra), kinetic_energy=T, motion_constraints=[blade],
                     dependent_speeds=[y], parameter_values={e: 0.3 for e in extra})

    def conservative(name, extra):  # for the momentum kernel of symplectic Euler (its output G)
        x = me.dynamicsymbols("x")
        S = sum(extra, sp.S.Zero) / len(extra) if extra else sp.Integer(4)
        return Model(name, [x], list(extra), kinetic_energy=(1 + x**2) * x.diff()**2 / 2,
                     potential_energy=S * x**2 / 2, parameter_values={e: 4.0 for e in extra})

    return {"driven": (driven, ("rhs", "jacobian", "step_jacobian", "energy", "points", "measurements"),
                       ("rk4", "implicit_midpoint")),
            "symplectic": (conservative, ("rhs", "momentum", "energy"), ("rk4", "symplectic_euler")),
            "tree": (tree, ("rhs", "jacobian", "energy", "points"), ("rk4", "implicit_midpoint")),
            "eliminated": (eliminated, ("rhs",), ("rk4",))}


@pytest.mark.compiler
@pytest.mark.parametrize("kind", ["driven", "tree", "eliminated", "symplectic"])
def test_every_identifier_of_the_generated_c_can_name_a_parameter(kind, tmp_path):
    """Found by review: a parameter named gauge (the dynamics' argument), Br (a local of the
    driven jacobian), pivot_0 (of the recursive dynamics) or G (the momentum kernel's output, with
    the default methods) failed to compile. Here every
    identifier the plain model's C declares names a parameter of the same physics at once; the
    kernels must build and give the plain model's numbers (the second route: only names differ)."""
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    build, outputs, methods = _kinds()[kind]
    plain = build(f"names_plain_{kind}", [])
    plain_sources = render_sources(reduce_expressions(derive_equations(plain), outputs), methods=list(methods))
    layout = plain_sources.layout
    own = {*layout.coordinates, *layout.speeds, *layout.dependent_speeds, *layout.inputs}  # its own symbols
    names = [n for n in _declared_identifiers(plain_sources) if n not in own]
    assert {"gauge", "status", "work"} <= set(names)  # the names of the review and the common ones
    assert kind != "symplectic" or "G" in names
    hostile = build(f"names_hostile_{kind}", [sp.Symbol(n, positive=True) for n in names])
    runs = []
    for model in (plain, hostile):
        system = compile_model(model, outputs=outputs, methods=methods, cache_dir=tmp_path)
        x0 = {"x": 0.3, "x_d": 0.1} if kind in ("driven", "symplectic") else {"q": 0.5} if kind == "tree" else \
            {"x": 0.0, "y": 0.0, "theta": -0.8, "x_d": 0.5, "theta_d": 2.0}
        extra = {"inputs": [0.0]} if kind == "driven" else {}
        method = "symplectic_euler" if kind == "symplectic" else "rk4"
        runs.append(simulate(system, x0, t_end=0.5, h=1e-3, method=method, **extra))
    assert runs[0].ok and runs[1].ok
    np.testing.assert_allclose(runs[1].x, runs[0].x, rtol=1e-12, atol=1e-12)
