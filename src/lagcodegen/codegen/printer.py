"""Helper: sympy expressions -> C99 expressions, and any string -> a safe C identifier.

Used by ``render.py``; imports no pipeline stage.

- :func:`mangle` maps arbitrary text (model, coordinate and parameter names) to an identifier
  that matches ``[A-Za-z_][A-Za-z0-9_]*``, is not a C keyword or a name that ``<math.h>`` or
  the other standard headers may declare, and cannot clash with lagcodegen's own ``lcg_``
  namespace. The output can never inject code: it holds only ``[A-Za-z0-9_]``.
- :class:`CPrinter` subclasses sympy's ``C99CodePrinter`` (``sympy/printing/c.py``). Symbols
  print as their mapped local name; ``precision="float"`` maps sympy's ``real`` type to
  ``float32`` through ``type_aliases``, so literals print as ``1.0F`` and functions as
  ``sqrtf``. Nothing is ever promoted to ``double`` implicitly in float mode. With
  ``trig="inline"`` sine and cosine print as the inline functions of ``templates/trig.c.j2``
  (``lcg_sin``, ``lcg_cosf``, ...), with ``trig="libm"`` (the default) as ``sin``, ``cosf``, ...
"""
from __future__ import annotations

import re

import numpy
import sympy
from sympy.codegen.ast import float32, float64, real
from sympy.core.function import AppliedUndef
from sympy.printing.c import C99CodePrinter
from sympy.printing.codeprinter import PrintMethodNotImplementedError
from sympy.printing.precedence import PRECEDENCE, precedence

__all__ = ["mangle", "CPrinter", "RESERVED_NAMES", "MUL_POW_MAX", "TRIG_MODES", "DEFAULT_TRIG"]

# --- reserved names -----------------------------------------------------------------------

_C_KEYWORDS = """
auto break case char const continue default do double else enum extern float for goto if
inline int long register restrict return short signed sizeof static struct switch typedef
union unsigned void volatile while _Bool _Complex _Imaginary _Alignas _Alignof _Atomic
_Generic _Noreturn _Static_assert _Thread_local alignas alignof bool constexpr false nullptr
static_assert thread_local true typeof typeof_unqual _BitInt _Decimal32 _Decimal64
_Decimal128 asm fortran __asm__ __inline__ __restrict__ __attribute__ __typeof__ __extension__
""".split()

# <math.h> functions (C99 + POSIX/GNU extensions); f and l variants are added below.
_MATH_FUNCTIONS = """
acos asin atan atan2 cos sin tan acosh asinh atanh cosh sinh tanh exp exp2 expm1 frexp ilogb
ldexp log log10 log1p log2 logb modf scalbn scalbln cbrt fabs hypot pow sqrt erf erfc lgamma
tgamma ceil floor nearbyint rint lrint llrint round lround llround trunc fmod remainder remquo
copysign nan nextafter nexttoward fdim fmax fmin fma gamma j0 j1 jn y0 y1 yn drem finite
significand scalb exp10 pow10 sincos lgamma_r gamma_r isinf isnan fminmag fmaxmag roundeven
""".split()

_MATH_MACROS = """
HUGE_VAL HUGE_VALF HUGE_VALL INFINITY NAN FP_INFINITE FP_NAN FP_NORMAL FP_SUBNORMAL FP_ZERO
FP_FAST_FMA FP_FAST_FMAF FP_FAST_FMAL FP_ILOGB0 FP_ILOGBNAN MATH_ERRNO MATH_ERREXCEPT
math_errhandling fpclassify isfinite isinf isnan isnormal signbit isgreater isgreaterequal
isless islessequal islessgreater isunordered issignaling iszero issubnormal iscanonical
float_t double_t signgam M_E M_LOG2E M_LOG10E M_LN2 M_LN10 M_PI M_PI_2 M_PI_4 M_1_PI M_2_PI
M_2_SQRTPI M_SQRT2 M_SQRT1_2 MAXFLOAT HUGE X_TLOSS DOMAIN SING OVERFLOW UNDERFLOW TLOSS PLOSS
exception matherr
""".split()

# Other standard-header and compiler-predefined names a generated file could see
# (<stddef.h>, <stdint.h>, <stdbool.h>, <complex.h>, <errno.h>, <float.h>, <limits.h>,
# GNU-mode predefined macros, cffi/Python glue).
_OTHER_RESERVED = """
NULL EOF errno assert offsetof size_t ptrdiff_t wchar_t max_align_t int8_t int16_t int32_t
int64_t uint8_t uint16_t uint32_t uint64_t intptr_t uintptr_t intmax_t uintmax_t complex
imaginary I CMPLX CMPLXF EDOM ERANGE EILSEQ CHAR_BIT INT_MAX INT_MIN UINT_MAX LONG_MAX
LONG_MIN FLT_MAX FLT_MIN FLT_EPSILON FLT_EVAL_METHOD DBL_MAX DBL_MIN DBL_EPSILON DECIMAL_DIG
main unix linux i386 __STDC__ FILE stdin stdout stderr printf malloc free abs labs exit
""".split()


def _with_fl_variants(names):
    return {v for n in names for v in (n, n + "f", n + "l")}


RESERVED_NAMES = frozenset(
    set(_C_KEYWORDS)
    | _with_fl_variants(_MATH_FUNCTIONS)
    | set(_MATH_MACROS)
    | {m + "l" for m in _MATH_MACROS if m.startswith("M_")}
    | set(_OTHER_RESERVED)
)
"""Names :func:`mangle` never returns unchanged (keywords, ``<math.h>`` names, common macros)."""

_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def _escape(ch: str) -> str:
    """``_xHH_`` for ASCII, ``_uHHHH_`` / ``_UHHHHHHHH_`` beyond; ``' '`` and ``-`` become ``_``."""
    if ch in " -":
        return "_"
    cp = ord(ch)
    if cp < 0x80:
        return f"_x{cp:02x}_"
    if cp < 0x10000:
        return f"_u{cp:04x}_"
    return f"_U{cp:08x}_"


def mangle(name: str, taken: set | None = None, max_len: int = 63) -> str:
    """Map any string to a safe, deterministic C identifier of at most ``max_len`` characters.

    Rules, in order:

    1. characters outside ``[A-Za-z0-9_]`` become ``_xHH_`` (``_uHHHH_`` beyond ASCII),
       space and ``-`` become ``_``; the empty string becomes ``v_``;
    2. a leading digit or underscore, or a leading ``lcg_`` (lagcodegen's exported
       namespace), gets the prefix ``v_`` (``_X...`` and ``__...`` are reserved by C);
    3. a name in :data:`RESERVED_NAMES` gets the suffix ``_`` (``sin`` -> ``sin_``);
    4. a result longer than ``max_len`` keeps its first ``max_len - 9`` characters and gets
       ``_`` plus 8 hex digits of the sha256 of the whole ``name``: readable, bounded, and
       names that differ only beyond the cut still differ;
    5. with ``taken``, a clash adds ``_2``, ``_3``, ... (shortened again by rule 4 if needed)
       and the result is added to ``taken``.

    The bound keeps every file name built from an identifier (``lcg_<model>.c``, the module
    ``_lcg_<model>_<key16>``) far below the 255-byte limit of common file systems, and local
    names within the 63 significant characters C99 (5.2.4.1) guarantees for internal
    identifiers. Exported names (``lcg_<model>_<function>``) can be longer than the 31
    characters C99 guarantees for external identifiers; gcc, clang and MSVC keep them all.

    Parameters
    ----------
    name : str
        Any text.
    taken : set of str, optional
        Names already in use in the same C scope; updated in place.
    max_len : int
        Longest result, at least 16.

    Returns
    -------
    str
        Matches ``[A-Za-z_][A-Za-z0-9_]*``; depends only on ``name``, ``taken`` and ``max_len``.

    Examples
    --------
    >>> mangle("double"), mangle("θ₁"), mangle("2nd link")
    ('double_', 'v__u03b8__u2081_', 'v_2nd_link')
    >>> len(mangle("a" * 250)), mangle("a" * 250) == mangle("a" * 249)
    (63, False)
    """
    if not isinstance(name, str):
        raise TypeError(f"mangle expects a str, got {type(name).__name__}: {name!r}")
    if not isinstance(max_len, int) or max_len < 16:
        raise ValueError(f"mangle max_len must be an int >= 16, got {max_len!r}")

    def bounded(text: str) -> str:
        if len(text) <= max_len:
            return text
        from hashlib import sha256  # here, not at the top: only this function may change
        whole = sha256(f"{name}\0{text}".encode("utf-8", "surrogatepass")).hexdigest()[:8]
        return f"{text[:max_len - 9]}_{whole}"

    out = "".join(c if (c.isascii() and (c.isalnum() or c == "_")) else _escape(c) for c in name)
    if not out or out[0].isdigit() or out[0] == "_" or out.lower().startswith("lcg_"):
        out = "v_" + out
    if out in RESERVED_NAMES:
        out += "_"
    out = bounded(out)
    if taken is not None:
        base, k = out, 1
        while out in taken or out in RESERVED_NAMES:
            k += 1
            out = bounded(f"{base}_{k}")
        taken.add(out)
    assert _IDENT.fullmatch(out) and len(out) <= max_len, out
    return out


# --- printer ------------------------------------------------------------------------------

MUL_POW_MAX = 4
"""Integer powers up to this exponent print as products (``x*x*x``) when the base is atomic."""
_MUL_POW_MAX_COMPOSITE = 3  # composite bases are repeated in the text; keep them short

TRIG_MODES = ("inline", "libm")
"""How sin and cos print: the inline functions of ``templates/trig.c.j2``, or ``<math.h>`` calls."""
DEFAULT_TRIG = "inline"
"""The kernels' default (render_sources, compile_model, the CLI): the inline forms took 4-14 % less
time per RK4 step than glibc's sincos in every kernel measured in session 20 (docs/benchmarks.txt).
`CPrinter` alone prints libm calls unless told otherwise: it cannot define the inline functions."""

_LOCAL_NAME = re.compile(r"[A-Za-z_][A-Za-z0-9_]*(\[[0-9]+\])?")
_NUMBER = re.compile(r"[0-9]+(\.[0-9]*)?([eE][+-]?[0-9]+)?F?")
_CALL = re.compile(r"[A-Za-z_][A-Za-z0-9_]*\(.*\)", re.S)


def _signed_sum(left: tuple, right: tuple, last: bool) -> tuple:
    """(negative, text) of the sum of two signed terms (negative, text), as one addition or
    subtraction; the text in parentheses unless it is the ``last`` (outermost) one."""
    (left_negative, a), (right_negative, b) = left, right
    if left_negative and not right_negative:
        text, negative = f"{b} - {a}", False
    else:
        text, negative = f"{a} {'-' if right_negative and not left_negative else '+'} {b}", left_negative
    return negative, text if last else f"({text})"


def _closes_at_end(s: str, open_at: int) -> bool:
    """True if the parenthesis opened at ``s[open_at]`` is closed by the last character."""
    depth = 0
    for i in range(open_at, len(s)):
        depth += {"(": 1, ")": -1}.get(s[i], 0)
        if depth == 0:
            return i == len(s) - 1
    return False


def _is_atomic(s: str) -> bool:
    """True if C text ``s`` is a name, a non-negative literal, a call or fully parenthesized."""
    if _LOCAL_NAME.fullmatch(s) or _NUMBER.fullmatch(s):
        return True
    if _CALL.fullmatch(s):
        return _closes_at_end(s, s.index("("))
    return s.startswith("(") and _closes_at_end(s, 0)


class CPrinter(C99CodePrinter):
    """C99 expression printer for one kernel's local names and scalar type.

    Parameters
    ----------
    precision : {"double", "float"}
        Scalar type; ``"float"`` prints ``1.0F``, ``sinf``, ``powf`` and never a double.
    names : dict of sympy.Basic to str
        Local C name of every symbol (or applied function such as ``q1(t)``) that may occur,
        e.g. ``{theta1: "theta1", l1: "p[2]"}``. Each name is an identifier, optionally
        followed by a constant index.
    trig : {"inline", "libm"}
        ``"inline"`` prints ``sin``/``cos`` as ``lcg_sin``/``lcg_cos`` (float: ``lcg_sinf``,
        ``lcg_cosf``), defined by ``templates/trig.c.j2``; ``"libm"`` (the printer's default: its
        text must compile without the template) as the ``<math.h>`` calls. ``printed_trig`` tells
        afterwards whether any sine or cosine was printed (in either mode).

    Rules
    -----
    1. An unmapped symbol raises ``ValueError("symbol x has no C name")``.
    2. A function without a ``<math.h>`` equivalent raises ``ValueError`` naming it.
    3. Integer powers up to :data:`MUL_POW_MAX` are products, ``x**-n`` is ``1.0/(...)``,
       ``x**(1/2)`` is ``sqrt``, ``x**(-1/2)`` is ``1.0/sqrt``, ``x**(3/2)`` is ``x*sqrt(x)`` and
       ``x**(-3/2)`` is ``1.0/(x*sqrt(x))`` (half-integer powers up to ``MUL_POW_MAX + 1/2``); other
       powers call ``pow``.
    4. Rationals are exact quotients of literals in the scalar type, ``(1.0/3.0)``;
       ``pi``, ``E`` and friends are literals (no ``M_PI``: it is not C99).
    5. Output is deterministic and on one line.
    """

    _default_settings = dict(C99CodePrinter._default_settings, strict=True)

    def __init__(self, precision: str = "double", names: dict | None = None, trig: str = "libm"):
        if precision not in ("double", "float"):
            raise ValueError(f"precision must be 'double' or 'float', got {precision!r}")
        if trig not in TRIG_MODES:
            raise ValueError(f"trig must be one of {TRIG_MODES}, got {trig!r}")
        names = dict(names or {})
        for key, value in names.items():
            if not isinstance(value, str) or not _LOCAL_NAME.fullmatch(value):
                raise ValueError(f"C name {value!r} of {key} is not a C identifier")
        scalar = float32 if precision == "float" else float64
        super().__init__({"type_aliases": {real: scalar}, "math_macros": {}})
        self.precision = precision
        self.trig = trig
        self.printed_trig = False
        self._names = names

    # --- names ---------------------------------------------------------------------------
    def _print(self, expr, **kwargs):
        if isinstance(expr, sympy.Basic) and not expr.is_Number:
            name = self._names.get(expr)
            if name is not None:
                return name
        return super()._print(expr, **kwargs)

    def _print_Symbol(self, expr):
        raise ValueError(f"symbol {expr} has no C name")

    _print_Dummy = _print_Wild = _print_Symbol

    def _print_not_supported(self, expr):
        if isinstance(expr, AppliedUndef):
            raise ValueError(f"function {expr.func.__name__} in {expr} has no C name "
                             "(undefined functions cannot be printed; substitute a symbol)")
        what = expr.func.__name__ if isinstance(expr, sympy.Function) else type(expr).__name__
        raise ValueError(f"function {what} in {expr} is not supported by the C printer "
                         "(no C99 <math.h> equivalent)")

    def _print_Derivative(self, expr):
        raise ValueError(f"{expr} is not supported by the C printer (substitute a symbol)")

    _print_Integral = _print_Derivative

    def _print_ImaginaryUnit(self, expr):
        raise ValueError("the imaginary unit I is not supported by the C printer (real kernels only)")

    def _print_ComplexInfinity(self, expr):
        raise ValueError("zoo (complex infinity) is not supported by the C printer")

    # --- sums ----------------------------------------------------------------------------
    def _print_Add(self, expr, order=None):
        """A sum as a balanced tree of its terms, ``(a + b) + (c - d)``, not C's left-to-right
        chain ``a + b + c - d``: the chain's n - 1 additions each wait for the one before, the
        tree's only log2(n) deep (pairwise summation; its rounding error also grows with log n,
        not n). The Whipple bicycle's RK4 step took 5 % less time (docs/benchmarks.txt,
        session 20). Each term is signed as sympy's printer signs it, and a pair of a positive
        and a negative term prints as one subtraction, so no negation is added."""
        signed = []  # (negative, text)
        for term in self._as_ordered_terms(expr, order=order):
            text = self._print(term)
            negative = text.startswith("-") and not term.is_Add
            if negative:
                text = text[1:]
            if precedence(term) < PRECEDENCE["Add"] or term.is_Add:
                text = f"({text})"
            signed.append((negative, text))
        while len(signed) > 1:
            pairs = [_signed_sum(signed[i], signed[i + 1], last=len(signed) == 2) for i in range(0, len(signed) - 1, 2)]
            signed = pairs + signed[len(pairs) * 2:]
        negative, text = signed[0]
        return f"-({text})" if negative else text

    # --- numbers -------------------------------------------------------------------------
    def _literal(self, value) -> str:
        return self._print_Float(sympy.Float(value, 30))

    def _print_Float(self, flt):
        if flt.is_finite and not flt.is_zero:  # a literal the C type rounds to inf or 0: compilers warn, values lost
            real = numpy.float32 if self.precision == "float" else numpy.float64
            with numpy.errstate(over="ignore", under="ignore"):
                rounded = real(float(flt))
            if not numpy.isfinite(rounded):
                raise ValueError(f"literal {flt} is out of range for {self.precision} (from fixed parameter "
                                 "values? leave them free, or rescale the model's units)")
            if rounded == 0:
                raise ValueError(f"literal {flt} is too small for {self.precision}: it would be 0 (from fixed "
                                 "parameter values? leave them free, or rescale the model's units)")
        return super()._print_Float(flt)

    def _print_Integer(self, expr):
        if abs(int(expr)) < 2**31:
            return str(int(expr))
        return self._literal(expr)  # would overflow a C int literal

    def _print_Rational(self, expr):
        p, q = int(expr.p), int(expr.q)
        if max(abs(p), q) > 2**53:  # not exact as a literal anyway
            return self._literal(expr)
        suffix = self._get_literal_suffix(real)
        body = f"({abs(p)}.0{suffix}/{q}.0{suffix})"
        return "-" + body if p < 0 else body

    def _print_NumberSymbol(self, expr):
        return self._literal(expr.evalf(40))

    _print_Pi = _print_Exp1 = _print_EulerGamma = _print_GoldenRatio = _print_NumberSymbol
    _print_Catalan = _print_TribonacciConstant = _print_NumberSymbol

    def _print_BooleanTrue(self, expr):
        return "1"

    def _print_BooleanFalse(self, expr):
        return "0"

    # --- sine and cosine ------------------------------------------------------------------
    def _print_trig(self, expr, name: str) -> str:
        self.printed_trig = True
        if self.trig == "libm":
            return self._print_math_func(expr)
        return f"lcg_{name}{self._get_func_suffix(real)}({self._print(expr.args[0])})"

    def _print_sin(self, expr):
        return self._print_trig(expr, "sin")

    def _print_cos(self, expr):
        return self._print_trig(expr, "cos")

    # --- powers --------------------------------------------------------------------------
    def _base(self, base) -> str:
        s = self._print(base)
        return s if _is_atomic(s) else f"({s})"

    def _product(self, base, n: int) -> str | None:
        s = self._base(base)
        limit = MUL_POW_MAX if _LOCAL_NAME.fullmatch(s) else _MUL_POW_MAX_COMPOSITE
        return "*".join([s] * n) if n <= limit else None

    def _print_Pow(self, expr):
        b, e = expr.base, expr.exp
        one = self._print_Float(sympy.Float(1.0))
        suffix = self._get_func_suffix(real)
        if e.is_Integer and e != 0:
            prod = self._product(b, abs(int(e)))
            if prod is not None:
                return prod if e > 0 else f"{one}/{prod if abs(int(e)) == 1 else f'({prod})'}"
        if e == sympy.S.Half:
            return f"sqrt{suffix}({self._print(b)})"
        if e == -sympy.S.Half:
            return f"{one}/sqrt{suffix}({self._print(b)})"
        if e.is_Rational and e.q == 2 and abs(e.p) <= 2 * MUL_POW_MAX + 1:
            # x**(n/2) = x**((n-1)/2) * sqrt(x): one sqrt and products instead of a pow call (pow
            # costs several sqrts' time; the Whipple bicycle's contact geometry has x**(-3/2))
            whole = self._product(b, (abs(int(e.p)) - 1) // 2)
            if whole is not None:
                root = f"{whole}*sqrt{suffix}({self._print(b)})"
                return root if e > 0 else f"{one}/({root})"
        if e == sympy.Rational(1, 3):
            return f"cbrt{suffix}({self._print(b)})"
        return f"pow{suffix}({self._print(b)}, {self._print(e)})"

    def parenthesize(self, item, level, strict=False):
        s = self._print(item)
        if _is_atomic(s):  # a C primary expression never needs parentheses
            return s
        prec = precedence(item)
        wrap = prec < level or (not strict and prec <= level)
        # A power printed as a product or quotient needs parentheses where the sympy
        # precedence of Pow says it does not: ``a/(x*x)``, never ``a/x*x``.
        # sympy prints a negative product at the precedence of Add, so the same holds there:
        # ``-x/(L*L)``, never ``-x/L*L``.
        wrap = wrap or (isinstance(item, sympy.Pow) and level >= PRECEDENCE["Add"] and ("*" in s or "/" in s))
        return f"({s})" if wrap else s

    # --- piecewise and friends -----------------------------------------------------------
    def _cast(self, s: str) -> str:
        return f"(({self.precision})({s}))"

    def _print_sign(self, expr):
        x = self._base(expr.args[0])
        return self._cast(f"({x} > 0) - ({x} < 0)")

    def _print_Heaviside(self, expr):
        x = self._base(expr.args[0])
        h0 = expr.args[1] if len(expr.args) > 1 else sympy.S.Half
        return (f"(({x} > 0) ? {self._print(sympy.Float(1))} : "
                f"(({x} < 0) ? {self._print(sympy.Float(0))} : {self._base(h0)}))")

    def _print_Mod(self, expr):
        # sympy's Mod takes the sign of the divisor; C's fmod that of the dividend.
        x, y = (self._base(a) for a in expr.args)
        return f"({x} - {y}*floor{self._get_func_suffix(real)}({x}/{y}))"

    def _print_Piecewise(self, expr):
        if expr.args[-1].cond != sympy.true:
            raise ValueError(f"Piecewise {expr} needs a final (value, True) branch")
        out = self._base(expr.args[-1].expr)
        for e, c in reversed(expr.args[:-1]):
            out = f"(({self._print(c)}) ? {self._base(e)} : {out})"
        return out

    def doprint(self, expr, assign_to=None):
        """One-line C expression for ``expr`` (``assign_to`` is not supported: templates assign)."""
        if assign_to is not None:
            raise ValueError("CPrinter prints expressions; the templates write assignments")
        try:
            return super().doprint(sympy.sympify(expr))
        except PrintMethodNotImplementedError as exc:  # sympy's own "unsupported" path
            raise ValueError(f"{expr} is not supported by the C printer: {exc}") from None
