"""printer.py: safe C identifiers and sympy -> C99 expressions in double and float.

Expected values: C keyword list from ISO/IEC 9899:2011 §6.4.1 (plus C23 additions);
<math.h> names from §7.12 and glibc's <math.h>; numeric values of printed expressions
are compared with sympy's own evaluation of the same expression (``evalf``).
"""
from __future__ import annotations

import re
import shutil
import subprocess

import pytest
import sympy as sp

from lagcodegen.codegen.printer import CPrinter, mangle

GCC = shutil.which("gcc")
needs_gcc = pytest.mark.skipif(GCC is None, reason="gcc not installed")
STRICT = ["-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror"]
IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")

# ISO C11 §6.4.1 keywords, C23 additions, and a few GNU spellings.
C_KEYWORDS = """auto break case char const continue default do double else enum extern float
for goto if inline int long register restrict return short signed sizeof static struct switch
typedef union unsigned void volatile while _Alignas _Alignof _Atomic _Bool _Complex _Generic
_Imaginary _Noreturn _Static_assert _Thread_local alignas alignof bool constexpr false nullptr
static_assert thread_local true typeof asm""".split()
# C99 §7.12 and glibc <math.h> (functions, f/l variants, macros, POSIX constants).
MATH_NAMES = """sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh exp exp2 expm1
log log10 log1p log2 logb pow sqrt cbrt hypot fabs fmod remainder remquo copysign nan nextafter
fdim fmax fmin fma ceil floor trunc round lround llround rint lrint nearbyint frexp ldexp modf
scalbn scalbln ilogb erf erfc lgamma tgamma gamma j0 j1 jn y0 y1 yn sinf cosf sqrtf powf fabsf
expf logf sinl cosl tanf atan2f fmaxf fminf signbit isnan isinf isfinite isnormal fpclassify
isgreater isless NAN INFINITY HUGE_VAL HUGE_VALF FP_NAN FP_ZERO FP_INFINITE M_PI M_E M_PI_2
M_SQRT2 M_LN2 M_1_PI float_t double_t signgam""".split()
OTHER = "NULL errno EOF I complex assert offsetof size_t main unix linux".split()


def compile_c(code: str, tmp_path, *flags: str, link: bool = False) -> subprocess.CompletedProcess:
    path = tmp_path / "t.c"
    path.write_text(code)
    out = tmp_path / ("t" if link else "t.o")
    argv = [GCC, *flags, str(path), "-o", str(out)] + (["-lm"] if link else ["-c"])
    run = subprocess.run(argv, capture_output=True, text=True)
    assert run.returncode == 0, f"{' '.join(argv)}\n{run.stderr}\n--- source ---\n{code}"
    return run


# --- mangle --------------------------------------------------------------------------------

@pytest.mark.parametrize("word", C_KEYWORDS + MATH_NAMES + OTHER)
def test_reserved_words_are_renamed(word):
    got = mangle(word)
    assert got != word and IDENT.fullmatch(got)
    assert mangle(got) == got  # already safe: a fixed point


@pytest.mark.parametrize("name", ["lcg_rhs", "LCG_x", "_Bool", "__x", "_x", "_X1"])
def test_reserved_prefixes_are_renamed(name):
    got = mangle(name)
    assert IDENT.fullmatch(got) and not got.lower().startswith("lcg_") and not got.startswith("_")


@pytest.mark.parametrize("name", [
    "", " ", "a b", 'say "hi"', "it's", "a;b", "*/", "/*", "//", "a\nb", "a\\", "#define X",
    "θ1", "l₁", "😀", "1link", "9", "x-y", "m[0]", "f(x)", "a; system(\"rm -rf /\"); double b",
])
def test_any_text_becomes_a_plain_identifier(name):
    got = mangle(name)
    assert IDENT.fullmatch(got), got
    assert mangle(name) == got  # deterministic


def test_plain_names_are_kept():
    for name in ["theta1", "l1", "m_cart", "q", "Theta", "x0"]:
        assert mangle(name) == name


def test_taken_makes_names_unique_deterministically():
    raw = ["a", "a", "a b", "a-b", "a_b", "sin", "sin_", "sin", "a_2", "int", "int_"]
    first, second = set(), set()
    got = [mangle(n, first) for n in raw]
    assert got == [mangle(n, second) for n in raw]
    assert len(set(got)) == len(raw) and set(got) == first
    assert all(IDENT.fullmatch(g) for g in got)
    assert got[:2] == ["a", "a_2"]


@pytest.mark.compiler
@needs_gcc
def test_mangled_reserved_names_compile_beside_math_h(tmp_path):
    taken = set()
    names = [mangle(w, taken) for w in C_KEYWORDS + MATH_NAMES + OTHER]
    decls = "\n".join(f"    double {n} = {i}.0;" for i, n in enumerate(names))
    total = " + ".join(names)
    code = (f"#include <math.h>\n#include <stddef.h>\n#include <errno.h>\n#include <stdbool.h>\n"
            f"double f(double x);\ndouble f(double x)\n{{\n{decls}\n"
            f"    return sin(x) + pow(x, 2.0) + {total};\n}}\n")
    compile_c(code, tmp_path, *STRICT)
    compile_c(code, tmp_path, "-std=gnu99", "-Wall", "-Werror")  # gnu mode defines `unix`, `linux`


@pytest.mark.compiler
@needs_gcc
def test_injection_attempt_compiles_to_the_right_value(tmp_path):
    evil = 'a; system("rm -rf /"); double b'
    name = mangle(evil)
    assert ";" not in name and '"' not in name and " " not in name
    code = (f"#include <stdio.h>\nstatic double lcg_t_{name}(double {name}) {{ return 2.0*{name}; }}\n"
            f"int main(void) {{ printf(\"%.1f\\n\", lcg_t_{name}(21.0)); return 0; }}\n")
    compile_c(code, tmp_path, *STRICT, link=True)
    run = subprocess.run([str(tmp_path / "t")], capture_output=True, text=True, timeout=30)
    assert run.stdout.strip() == "42.0"


# --- CPrinter: exact text ------------------------------------------------------------------

x, y, z = sp.symbols("x y z", real=True)
NAMES = {x: "x", y: "y", z: "p[2]"}


@pytest.mark.parametrize("expr, double, single", [
    (x**2, "x*x", "x*x"),
    (x**3, "x*x*x", "x*x*x"),
    (x**-1, "1.0/x", "1.0F/x"),
    (x**-2, "1.0/(x*x)", "1.0F/(x*x)"),
    (sp.sqrt(x), "sqrt(x)", "sqrtf(x)"),
    (1 / sp.sqrt(x), "1.0/sqrt(x)", "1.0F/sqrtf(x)"),
    (x**sp.Rational(3, 2), "x*sqrt(x)", "x*sqrtf(x)"),
    (x**sp.Rational(-3, 2), "1.0/(x*sqrt(x))", "1.0F/(x*sqrtf(x))"),
    ((x + y)**sp.Rational(-5, 2), "1.0/((x + y)*(x + y)*sqrt(x + y))", "1.0F/((x + y)*(x + y)*sqrtf(x + y))"),
    (x**sp.Rational(11, 2), "pow(x, (11.0/2.0))", "powf(x, (11.0F/2.0F))"),
    (x**y, "pow(x, y)", "powf(x, y)"),
    (x**7, "pow(x, 7)", "powf(x, 7)"),
    ((x + y)**2, "(x + y)*(x + y)", "(x + y)*(x + y)"),
    (y / x**2, "y/(x*x)", "y/(x*x)"),
    (z**2, "p[2]*p[2]", "p[2]*p[2]"),
    (sp.Rational(1, 3) * x, "(1.0/3.0)*x", "(1.0F/3.0F)*x"),
    (sp.sin(x) + sp.cos(y), "sin(x) + cos(y)", "sinf(x) + cosf(y)"),
    (sp.Abs(x), "fabs(x)", "fabsf(x)"),
    (sp.sign(x), "((double)((x > 0) - (x < 0)))", "((float)((x > 0) - (x < 0)))"),
    (sp.atan2(y, x), "atan2(y, x)", "atan2f(y, x)"),
    (sp.Float(0.5) * x, "0.5*x", "0.5F*x"),
    (sp.pi * x, "3.1415926535897932*x", "3.14159265F*x"),  # C99 has no M_PI
])
def test_expected_text(expr, double, single):
    assert CPrinter("double", NAMES).doprint(expr) == double
    assert CPrinter("float", NAMES).doprint(expr) == single


def test_unmapped_symbol_is_named():
    with pytest.raises(ValueError, match="symbol w has no C name"):
        CPrinter("double", NAMES).doprint(x * sp.Symbol("w"))


@pytest.mark.parametrize("expr, culprit", [
    (sp.Function("f")(x), "f"),
    (sp.besselj(0, x), "besselj"),
    (sp.LambertW(x), "LambertW"),
    (sp.Derivative(sp.Function("q")(x), x), "Derivative"),
    (sp.I * x, "imaginary unit"),
])
def test_unsupported_raises_naming_the_function(expr, culprit):
    with pytest.raises(ValueError, match=culprit):
        CPrinter("double", NAMES).doprint(expr)


def test_bad_names_and_precision_rejected():
    with pytest.raises(ValueError, match="not a C identifier"):
        CPrinter("double", {x: "x; y"})
    with pytest.raises(ValueError, match="precision"):
        CPrinter("long double", NAMES)


def test_printing_is_deterministic():
    expr = sp.sin(x) * sp.cos(y)**2 + sp.exp(-x / 3) - sp.Rational(5, 7) * z**3
    outputs = {CPrinter("float", NAMES).doprint(expr) for _ in range(3)}
    assert len(outputs) == 1


# --- CPrinter: compiled values -------------------------------------------------------------

EXPRS = [
    x**2, x**3, x**-1, x**-3, sp.sqrt(y), 1 / sp.sqrt(y), x**y.subs(y, sp.Rational(3, 2)),
    x**sp.Rational(-3, 2), (x + y)**sp.Rational(5, 2) / y**sp.Rational(-7, 2),
    y**x, sp.Rational(1, 3) * x - sp.Rational(2, 7), y / x**2, y / (x**2 * z), -x**2,
    (x + y)**3 / (y - z)**2, sp.sin(x) * sp.cos(y)**2 + sp.tan(z), sp.exp(-x / 3) * sp.log(y),
    sp.Abs(z), sp.sign(z), sp.sign(x - sp.Rational(7, 10)) + 2 * sp.sign(x), sp.Max(x, y, z), sp.Min(x, z),
    sp.Heaviside(z), sp.Heaviside(x), sp.Heaviside(x - sp.Rational(7, 10)), sp.atan2(z, x), sp.pi * x + sp.E, sp.sqrt(2) * x,
    sp.Float(0.1) * y, sp.Piecewise((x, z > 0), (y, True)), sp.Mod(z, y), sp.cot(x),
    sp.asinh(z) + sp.acos(z) + sp.cosh(x), sp.cbrt(y), sp.floor(z) + sp.ceiling(z), 2 * x / 3,
]
POINT = {x: sp.Rational(7, 10), y: sp.Rational(13, 10), z: sp.Rational(-2, 5)}


def kernel(precision: str) -> str:
    printer = CPrinter(precision, {x: "x", y: "y", z: "z"})
    t = precision
    lines = [f"    out[{i}] = {printer.doprint(e)};" for i, e in enumerate(EXPRS)]
    return (f"#include <math.h>\nvoid kernel({t} *out, const {t} *in);\n"
            f"void kernel({t} *out, const {t} *in)\n{{\n"
            f"    const {t} x = in[0];\n    const {t} y = in[1];\n    const {t} z = in[2];\n"
            + "\n".join(lines) + "\n}\n")


def test_float_mode_never_mentions_double():
    code = kernel("float")
    body = code.split("{", 1)[1]
    assert "sinf(" in body and "1.0F" in body and "double" not in body
    literals = re.findall(r"(?<![\w.])(\d+\.\d*(?:[eE][+-]?\d+)?F?)", body)
    assert literals and all(lit.endswith("F") for lit in literals), literals
    doubles = r"\b(sin|cos|tan|exp|log|pow|sqrt|fabs|fmax|fmin|atan2|floor|ceil|cbrt|asinh|acos|cosh)\("
    assert not re.search(doubles, body), re.search(doubles, body)


@pytest.mark.compiler
@needs_gcc
@pytest.mark.parametrize("precision", ["double", "float"])
def test_kernel_compiles_warning_free(precision, tmp_path):
    compile_c(kernel(precision), tmp_path, *STRICT, "-Wdouble-promotion", "-Wfloat-conversion")


@pytest.mark.compiler
@needs_gcc
@pytest.mark.parametrize("precision, rtol", [("double", 1e-13), ("float", 2e-6)])
def test_compiled_values_match_sympy(precision, rtol, tmp_path):
    fmt = "%.17g" if precision == "double" else "%.9g"
    main = (f"#include <stdio.h>\nint main(void)\n{{\n    const {precision} in[3] = "
            f"{{{', '.join(str(float(POINT[s])) + ('F' if precision == 'float' else '') for s in (x, y, z))}}};\n"
            f"    {precision} out[{len(EXPRS)}];\n    int i;\n    kernel(out, in);\n"
            f"    for (i = 0; i < {len(EXPRS)}; ++i) printf(\"{fmt}\\n\", (double)out[i]);\n"
            "    return 0;\n}\n")
    compile_c(kernel(precision) + main, tmp_path, *STRICT, link=True)
    run = subprocess.run([str(tmp_path / "t")], capture_output=True, text=True, timeout=30)
    got = [float(v) for v in run.stdout.split()]
    expected = [float(e.subs(POINT).evalf(30)) for e in EXPRS]
    for e, g, want in zip(EXPRS, got, expected):
        assert g == pytest.approx(want, rel=rtol, abs=rtol), e


@pytest.mark.parametrize("make", [
    lambda x, L, y: -x / L**2, lambda x, L, y: -x * y / L**3, lambda x, L, y: -x / (L + y)**2,
    lambda x, L, y: x / L**2, lambda x, L, y: -L**2 * y + x, lambda x, L, y: -(x / (L * y**2)),
    lambda x, L, y: 3 * x / (2 * L**2 * y**3), lambda x, L, y: -(L + y)**2 / x**4,
])
def test_negative_products_with_powers_keep_their_denominators(make):
    # Regression: a negative product has sympy's Add precedence, and -x/L**2 once printed as
    # -x/L*L. The printed C (only + - * / and parentheses here) is also valid Python, so its value
    # is checked against sympy's evaluation (independent of the printer) at a sample point.
    x, L, y = sp.symbols("x L y")
    expr = make(x, L, y)
    code = CPrinter(names={x: "x", L: "L", y: "y"}).doprint(expr)
    values = {"x": 0.7, "L": 1.9, "y": 0.45}
    got = eval(code, {}, dict(values))  # noqa: S307 (arithmetic only)
    want = float(expr.subs({x: 0.7, L: 1.9, y: 0.45}))
    assert got == pytest.approx(want, rel=1e-14), code


# --- CPrinter: sums as balanced trees ------------------------------------------------------

a, b, c, d, e, f, g, h = TERMS = sp.symbols("a b c d e f g h", real=True)
TERM_NAMES = {s: str(s) for s in TERMS}


@pytest.mark.parametrize("expr, text", [
    (a + b, "a + b"),
    (a - b, "a - b"),
    (-a - b, "-(a + b)"),
    (a + b + c, "(a + b) + c"),
    (a + b + c + d, "(a + b) + (c + d)"),
    (a - b - c - d, "(a - b) - (c + d)"),
    (-a + b - c + d, "(b - a) + (d - c)"),
    (-a - b - c, "-((a + b) + c)"),
    (a + b + c + d + e + f + g + h, "((a + b) + (c + d)) + ((e + f) + (g + h))"),
    (a * (b - c - d) + e, "a*((b - c) - d) + e"),
])
def test_sums_print_as_balanced_trees(expr, text):
    """Hand-derived: sympy's order of the terms, paired neighbour by neighbour (a positive and a
    negative term as one subtraction), so an n-term sum is log2(n) additions deep, not n - 1."""
    assert CPrinter("double", TERM_NAMES).doprint(expr) == text


SUMS = [
    a + b + c + d + e, -a - b - c - d - e - f - g, a - 2 * b + 3 * c - d / e + f * g - h,
    -(a + b) ** 2 - c * d + e * (a - b + c - d + e - f), sp.Rational(1, 3) * a - b - sp.Rational(5, 7),
    -a * b - c * d - e * f - g * h + 1, a * (b - c - d) - e * (f + g + h) - (a - b) / (c + d),
    -a + 2, 1 - a - b, sp.Float(0.25) * a - b * c,
]


@pytest.mark.parametrize("expr", SUMS)
def test_balanced_sums_keep_their_value(expr):
    """The printed C (+, -, *, / and parentheses only) is also Python: its value at a sample point
    against sympy's evaluation of the expression at 30 digits (independent of the printer)."""
    point = dict(zip(TERMS, (0.7, -1.3, 2.1, 0.45, -0.9, 1.7, -2.5, 0.33)))
    text = CPrinter("double", TERM_NAMES).doprint(expr).replace("1.0/", "1/")
    got = eval(text, {}, {str(s): v for s, v in point.items()})  # noqa: S307 (the printer's own text)
    assert got == pytest.approx(float(expr.evalf(30, subs=point)), rel=1e-14, abs=1e-14)
