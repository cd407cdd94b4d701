"""Stage: ReducedKernel -> CSources (C header, C source and cffi cdef text).

The printer writes the maths; Jinja2 templates in ``templates/`` write the layout.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class KernelLayout:
    """What the generated C expects and exports, index by index.

    Attributes
    ----------
    model : str
        The model's own name.
    prefix : str
        C identifier prefix of every exported name, ``lcg_<mangled model name>``.
    precision : str
        ``"double"`` or ``"float"``: the scalar type of every array.
    coordinates, speeds : tuple of str, (n,)
        ``x[i]`` = coordinates[i], ``x[n + i]`` = speeds[i].
    parameters : tuple of str
        Free parameters in ``p[]`` order.
    fixed : tuple of (str, float)
        Parameters folded into the code.
    points : tuple of str
        Named points whose positions the ``points`` function writes (3 values each).
    functions : tuple of str
        Exported C function names.
    """

    model: str
    prefix: str
    precision: str
    coordinates: tuple
    speeds: tuple
    parameters: tuple
    fixed: tuple
    points: tuple
    functions: tuple

    @property
    def n(self) -> int:
        return len(self.coordinates)


@dataclass(frozen=True)
class CSources:
    """Generated C text for one model: ``header`` (``header_name``), ``source`` and the cffi cdef."""

    layout: KernelLayout
    header_name: str
    header: str
    source_name: str
    source: str
    cdef: str


# ---------------------------------------------------------------------------------------------
# Rendering
# ---------------------------------------------------------------------------------------------
import hashlib  # noqa: E402  (kept beside the code that uses it)
from pathlib import Path  # noqa: E402

import jinja2  # noqa: E402
import sympy as sp  # noqa: E402

from .cse import ReducedKernel, ReducedSystem  # noqa: E402
from .printer import CPrinter, mangle  # noqa: E402

PRECISIONS = ("double", "float")
STATUS_CODES = (
    ("LCG_OK", 0, "success"),
    ("LCG_SINGULAR_MASS_MATRIX", 1, "a pivot of the LDL^T factorization of M was not positive"),
    ("LCG_NONFINITE_STATE", 2, "the state became NaN or infinite"),
    ("LCG_NEWTON_FAILED", 3, "an implicit step's Newton iteration did not converge"),
)
#: local names the generated code uses itself; user symbols are renamed around them
_RESERVED = {"t", "x", "p", "out", "M", "F", "ud", "qd", "xdot", "lcg_status"}


class EmitError(ValueError):
    """The kernels cannot be written as C; the message names the culprit."""


def template_dir() -> Path:
    """Where the Jinja2 templates live: inside the installed package, else the source tree."""
    installed = Path(__file__).resolve().parent / "templates"
    if installed.is_dir():
        return installed
    return Path(__file__).resolve().parents[2] / "templates"


def _environment() -> jinja2.Environment:
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())), undefined=jinja2.StrictUndefined,
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True, autoescape=False)


@dataclass(frozen=True)
class _Names:
    """C names of every symbol and of the exported functions."""

    prefix: str
    symbols: dict   # Symbol -> C local name
    state_index: dict  # Symbol -> index into x
    param_index: dict  # Symbol -> index into p


def _names(system: ReducedSystem, model_name: str) -> _Names:
    taken = set(_RESERVED)
    temporaries = [s for k in system.kernels for s, _ in k.temporaries]
    symbols = {}
    for s in dict.fromkeys(temporaries):  # cse names first: tmp0, tmp1, ...
        symbols[s] = mangle(s.name, taken)
    for s in system.q + system.u + system.free_parameters:
        symbols[s] = mangle(s.name, taken)
    symbols[system.t] = "t"
    prefix = "lcg_" + mangle(model_name)
    state = {s: i for i, s in enumerate(system.q + system.u)}
    params = {s: i for i, s in enumerate(system.free_parameters)}
    return _Names(prefix=prefix, symbols=symbols, state_index=state, param_index=params)


def render_sources(system: ReducedSystem, precision: str = "double", model_name: str | None = None) -> CSources:
    """Render the C header, source and cffi cdef of ``system``.

    Parameters
    ----------
    system : ReducedSystem
    precision : {"double", "float"}
        Scalar type of every array and literal (float: ``sinf``, ``1.0F``, no promotion).
    model_name : str, optional
        Name used for the C prefix; defaults to the model's name.
    """
    if precision not in PRECISIONS:
        raise EmitError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    model_name = model_name or system.name
    names = _names(system, model_name)
    printer = CPrinter(precision=precision, names=names.symbols)
    real = precision
    functions = []
    if any(out in system.outputs for out in ("accel", "rhs")):
        functions.append(_dynamics_record(system, names, printer, real))
    functions += [_function_record(system, system.kernel(_kernel_of(out)), names, printer, real, out)
                  for out in system.outputs]
    layout = _layout(system, names, real, model_name, functions)
    context = _context(system, names, layout, functions, real)
    env = _environment()
    header_name = f"{names.prefix}.h"
    source_name = f"{names.prefix}.c"
    context["header_name"] = header_name
    header = env.get_template("model.h.j2").render(context, template="model.h.j2")
    source = env.get_template("model.c.j2").render(context, template="model.c.j2")
    cdef = env.get_template("model.cdef.j2").render(context)
    return CSources(layout=layout, header_name=header_name, header=header, source_name=source_name,
                    source=source, cdef=cdef)


def _kernel_of(output: str) -> str:
    from .cse import OUTPUT_KERNELS
    return OUTPUT_KERNELS[output]


def _literal(value: float | int, real: str) -> str:
    text = repr(float(value))
    return text + "F" if real == "float" else text


def _input_lines(kernel: ReducedKernel, names: _Names, real: str) -> tuple[list, list]:
    """Aliases ``const double q1 = x[0];`` for the inputs a kernel reads, and unused arguments."""
    used = kernel.symbols
    lines = []
    for s, i in names.state_index.items():
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = x[{i}];")
    for s, i in names.param_index.items():
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = p[{i}];")
    unused = []
    if not any(s in used for s in names.state_index):
        unused.append("x")
    if not any(s in used for s in names.param_index):
        unused.append("p")
    if not any(s.name == "t" for s in used):
        unused.append("t")
    return lines, unused


def _body_head(kernel: ReducedKernel, names: _Names, printer: CPrinter, real: str,
               touches_state: bool = False) -> list:
    inputs, unused = _input_lines(kernel, names, real)
    if touches_state and "x" in unused:
        unused.remove("x")
    lines = [f"/* Inputs ({len(inputs)}) */"] + inputs
    lines += [f"(void){arg};" for arg in unused]
    lines.append(f"/* Intermediate terms ({len(kernel.temporaries)}), total ops {kernel.ops_after} "
                 f"(before CSE {kernel.ops_before}) */")
    for s, expr in kernel.temporaries:
        lines.append(f"const {real} {names.symbols[s]} = {_print(printer, expr, names.symbols[s])};")
    return lines


def _print(printer: CPrinter, expr, where: str) -> str:
    try:
        return printer.doprint(expr)
    except ValueError as err:
        raise EmitError(f"cannot print {where}: {err}") from err


def _results(kernel: ReducedKernel, block: str) -> dict:
    return {(i, j): expr for (b, i, j), expr in kernel.results if b == block}


def _function_record(system, kernel, names, printer, real, output):
    prefix, n = names.prefix, len(system.q)
    args = f"{real} t, const {real} *x, const {real} *p"
    if output == "mass_matrix":
        body = _body_head(kernel, names, printer, real) + ["/* Mass matrix, lower triangle, mirrored */"]
        for (j, k), expr in _results(kernel, "M").items():
            body.append(f"M[{j * n + k}] = {_print(printer, expr, f'M[{j}][{k}]')};  /* M[{j}][{k}] */")
            if j != k:
                body.append(f"M[{k * n + j}] = M[{j * n + k}];  /* M[{k}][{j}] */")
        return _record(f"void {prefix}_mass_matrix({args}, {real} *M)",
                       f"Mass matrix M(q, t), row-major {n} x {n}.", body)
    if output == "forcing":
        body = _body_head(kernel, names, printer, real) + ["/* Forcing */"]
        for (j, _), expr in _results(kernel, "F").items():
            body.append(f"F[{j}] = {_print(printer, expr, f'F[{j}]')};")
        return _record(f"void {prefix}_forcing({args}, {real} *F)", f"Forcing F(q, u, t), {n} values.", body)
    if output == "accel":
        body = [f"{real} qd[{n}];", f"return {prefix}_dynamics(t, x, p, qd, ud);"]
        return _record(f"int {prefix}_accel({args}, {real} *ud)",
                       "Generalized accelerations ud solving M ud = F; returns a status code.", body)
    if output == "rhs":
        body = [f"return {prefix}_dynamics(t, x, p, xdot, xdot + {n});"]
        return _record(f"int {prefix}_rhs({args}, {real} *xdot)",
                       f"First-order right-hand side xdot = f(t, x), x = (q, u), {2 * n} values; "
                       "returns a status code. xdot must not alias x.", body)
    if output == "energy":
        body = _body_head(kernel, names, printer, real)
        body.append(f"return {_print(printer, _results(kernel, 'E')[(0, 0)], 'energy')};")
        return _record(f"{real} {prefix}_energy({args})", "Total mechanical energy T + V.", body)
    if output == "points":
        body = _body_head(kernel, names, printer, real) + ["/* Point positions (x, y, z) */"]
        for (i, c), expr in _results(kernel, "P").items():
            point = system.point_names[i]
            body.append(f"out[{3 * i + c}] = {_print(printer, expr, f'point {point}')};  /* {point}.{'xyz'[c]} */")
        return _record(f"void {prefix}_points({args}, {real} *out)",
                       f"Positions of {len(system.point_names)} named points, 3 values each.", body)
    raise EmitError(f"unknown output {output!r}")


def _record(decl: str, doc: str, body: list, static: bool = False) -> dict:
    return {"decl": ("static " if static else "") + decl, "doc": doc, "body": body, "static": static}


def _dynamics_record(system, names, printer, real) -> dict:
    """Static kernel behind accel and rhs: K, M, F with joint CSE, then an unrolled LDL^T solve."""
    kernel = system.kernel("dynamics")
    n, prefix = len(system.q), names.prefix
    body = _body_head(kernel, names, printer, real, touches_state=system.kinematics_identity)
    M = _results(kernel, "M")
    body.append("/* Mass matrix, lower triangle */")
    for (j, k), expr in M.items():
        if expr != 0 or j == k:  # structural zeros are skipped by the factorization too
            body.append(f"const {real} M_{j}_{k} = {_print(printer, expr, f'M[{j}][{k}]')};")
    body.append("/* Forcing */")
    for (j, _), expr in _results(kernel, "F").items():
        body.append(f"const {real} F_{j} = {_print(printer, expr, f'F[{j}]')};")
    body.append("/* Kinematics qd = K(q, u, t) */")
    if system.kinematics_identity:
        body += [f"qd[{j}] = x[{n + j}];" for j in range(n)]
    else:
        body += [f"qd[{j}] = {_print(printer, expr, f'qd[{j}]')};"
                 for (j, _), expr in _results(kernel, "K").items()]
    body += ldlt_solve_lines(n, {jk for jk, e in M.items() if e != 0}, real)
    body.append("return LCG_OK;")
    return _record(f"int {prefix}_dynamics({real} t, const {real} *x, const {real} *p, {real} *qd, {real} *ud)",
                   "K, M and F with shared temporaries, then M ud = F by LDL^T.", body, static=True)


def ldlt_solve_lines(n: int, nonzero: set, real: str) -> list:
    """Unrolled LDL^T factorization of M (locals M_j_k, lower) and solve of M ud = F (locals F_j).

    Structural zeros of M are skipped. A pivot that is not positive (or NaN) returns
    LCG_SINGULAR_MASS_MATRIX, so a singular M never produces NaNs silently.
    """
    zero = _literal(0, real)
    one = _literal(1, real)
    lines = [f"/* Solve M ud = F: unrolled LDL^T ({n} x {n}) */"]
    LD: set = set()  # (i, k) with LD_i_k = L_i_k * D_k nonzero

    def terms(pairs):
        return "".join(f" - {a}*{b}" for a, b in pairs)

    for j in range(n):
        pivot = terms((f"L_{j}_{k}", f"LD_{j}_{k}") for k in range(j) if (j, k) in LD)
        lines.append(f"const {real} D_{j} = M_{j}_{j}{pivot};")
        lines.append(f"if (!(D_{j} > {zero})) return LCG_SINGULAR_MASS_MATRIX;")
        lines.append(f"const {real} Dinv_{j} = {one} / D_{j};")
        for i in range(j + 1, n):
            pairs = [(f"LD_{i}_{k}", f"L_{j}_{k}") for k in range(j) if (i, k) in LD and (j, k) in LD]
            if (i, j) not in nonzero and not pairs:
                continue
            head = f"M_{i}_{j}" if (i, j) in nonzero else zero
            lines.append(f"const {real} LD_{i}_{j} = {head}{terms(pairs)};")
            lines.append(f"const {real} L_{i}_{j} = LD_{i}_{j} * Dinv_{j};")
            LD.add((i, j))
    for i in range(n):
        lines.append(f"const {real} y_{i} = F_{i}{terms((f'L_{i}_{k}', f'y_{k}') for k in range(i) if (i, k) in LD)};")
    for i in reversed(range(n)):
        back = terms((f"L_{k}_{i}", f"w_{k}") for k in range(i + 1, n) if (k, i) in LD)
        lines.append(f"const {real} w_{i} = y_{i} * Dinv_{i}{back};")
        lines.append(f"ud[{i}] = w_{i};")
    return lines


def _layout(system: ReducedSystem, names: _Names, real: str, model_name: str, functions: list) -> KernelLayout:
    exported = tuple(f["decl"].split("(")[0].split()[-1] for f in functions if not f["static"])
    return KernelLayout(
        model=model_name, prefix=names.prefix, precision=real,
        coordinates=tuple(s.name for s in system.q), speeds=tuple(s.name for s in system.u),
        parameters=tuple(s.name for s in system.free_parameters),
        fixed=tuple((s.name, v) for s, v in system.fixed_parameters),
        points=system.point_names, functions=exported)


def _context(system: ReducedSystem, names: _Names, layout: KernelLayout, functions: list, real: str) -> dict:
    from . import __version__

    n = len(system.q)
    state_rows = [{"index": i, "name": s.name, "c_name": names.symbols[s],
                   "kind": "coordinate" if i < n else "speed"}
                  for i, s in enumerate(system.q + system.u)]
    param_rows = [{"index": i, "name": s.name, "c_name": names.symbols[s]}
                  for i, s in enumerate(system.free_parameters)]
    fixed_rows = [{"name": s.name, "value": repr(v)} for s, v in system.fixed_parameters]
    point_rows = [{"index": 3 * i, "name": name} for i, name in enumerate(system.point_names)]
    key_text = repr((layout, [(f["decl"], f["body"]) for f in functions]))
    upper = names.prefix.upper()
    return {
        "version": __version__, "sympy_version": sp.__version__, "model": layout.model,
        "route": system.route, "key": hashlib.sha256(key_text.encode()).hexdigest()[:16],
        "prefix": names.prefix, "guard": f"{upper}_H", "macro": upper, "real": real,
        "n": n, "n_state": 2 * n, "n_params": len(param_rows), "n_points": len(point_rows),
        "state_rows": state_rows, "param_rows": param_rows, "fixed_rows": fixed_rows,
        "point_rows": point_rows, "has_fixed": bool(fixed_rows),
        "status_codes": [{"name": c, "value": v, "doc": d} for c, v, d in STATUS_CODES],
        "prototypes": [f for f in functions if not f["static"]], "functions": functions,
    }
