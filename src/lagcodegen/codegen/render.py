"""Stage: ReducedKernel -> CSources (C header, C source and cffi cdef text).

The printer writes the maths; Jinja2 templates in ``templates/`` write the layout.
"""
from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path

import jinja2
import sympy as sp

from ..model import TIME
from ..status import STATUS_TABLE
from .csyntax import EmitError, comment_text, literal, record
from .lane_kernel import lane_context
from .ldlt import ldlt_factor_lines, ldlt_substitution_lines
from .printer import DEFAULT_TRIG, TRIG_MODES, CPrinter, mangle
from .reduce import OUTPUT_KERNELS, ReducedKernel, ReducedSystem
from .steppers import hot_dynamics, stepper_context

__all__ = ["CSources", "EmitError", "KernelLayout", "render_sources", "template_dir", "comment_text",
           "trig_source"]


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
    methods : tuple of str
        Integration schemes compiled in; a method's number in ``simulate`` is its index here.
    defaults : tuple of (str, float)
        Default values of free parameters that have one.
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
    methods: tuple = ()
    defaults: tuple = ()
    n_constraints: int = 0

    @property
    def n(self) -> int:
        return len(self.coordinates)


@dataclass(frozen=True)
class CSources:
    """Generated C text for one model: ``header`` (``header_name``), ``source`` and the cffi cdef;
    ``source_key`` is the digest of the layout and function bodies printed in their comments."""

    layout: KernelLayout
    header_name: str
    header: str
    source_name: str
    source: str
    cdef: str
    source_key: str



PRECISIONS = ("double", "float")
#: local names the generated code uses itself; user symbols are renamed around them
_RESERVED = {"t", "x", "p", "out", "M", "F", "ud", "qd", "xdot", "B", "J", "c", "status", "work", "h",
             "i", "j", "k", "m", "s", "method", "stride", "n_steps", "steps_done", "A", "C", "Y", "z",
             "lam", "Q", "phi", "phi_t", "project"}


def template_dir() -> Path:
    """Where the Jinja2 templates live: inside the installed package (the wheel puts them at
    ``lagcodegen/templates``), else at the top of the source tree that holds the package."""
    import lagcodegen

    package = Path(lagcodegen.__file__).resolve().parent
    for candidate in (package / "templates", package.parent.parent / "templates"):
        if (candidate / "model.c.j2").is_file():
            return candidate
    raise FileNotFoundError(f"lagcodegen's templates (model.c.j2, ...) are neither in {package / 'templates'} "
                            f"nor in {package.parent.parent / 'templates'}: reinstall the package")


@functools.lru_cache(maxsize=1)
def template_environment() -> jinja2.Environment:
    """One environment per process: it keeps the compiled templates, which cost more than a
    render (the lane variant and every later model reuse them)."""
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
    accel_index: dict  # Symbol -> index into ud (jacobian kernel only)


def _solver_locals(n: int) -> set:
    """Locals of the unrolled LDL^T code (M_j_k, F_j, D_j, ...): user names must avoid them."""
    names = set()
    for j in range(n):
        names |= {f"F_{j}", f"D_{j}", f"Dinv_{j}", f"y_{j}", f"w_{j}"}
        for k in range(n):
            names |= {f"M_{j}_{k}", f"L_{j}_{k}", f"LD_{j}_{k}"}
    return names


def _names(system: ReducedSystem, model_name: str) -> _Names:
    taken = set(_RESERVED) | _solver_locals(len(system.q))
    temporaries = [s for k in system.kernels for s, _ in k.temporaries]
    symbols = {}
    for s in dict.fromkeys(temporaries):  # cse names first: tmp0, tmp1, ...
        symbols[s] = mangle(s.name, taken)
    for s in system.q + system.u + system.free_parameters + system.accelerations:
        symbols[s] = mangle(s.name, taken)
    symbols[system.t] = "t"
    prefix = "lcg_" + mangle(model_name)
    state = {s: i for i, s in enumerate(system.q + system.u)}
    params = {s: i for i, s in enumerate(system.free_parameters)}
    accel = {s: i for i, s in enumerate(system.accelerations)}
    return _Names(prefix=prefix, symbols=symbols, state_index=state, param_index=params, accel_index=accel)


def render_sources(system: ReducedSystem, precision: str = "double", model_name: str | None = None,
                   methods=(), trig: str = DEFAULT_TRIG, lanes: int = 0, lane_trig: str = "fast") -> CSources:
    """Render the C header, source and cffi cdef of ``system``.

    Parameters
    ----------
    system : ReducedSystem
    precision : {"double", "float"}
        Scalar type of every array and literal (float: ``sinf``, ``1.0F``, no promotion).
    model_name : str, optional
        Name used for the C prefix; defaults to the model's name.
    methods : sequence of str
        Integration schemes (`schemes.SCHEMES`) to compile as ``step_<name>`` functions and into
        the ``simulate`` driver; needs the ``rhs`` output, implicit ones also ``jacobian``.
    trig : {"libm", "inline"}
        ``"libm"`` (default): plain ``sin``/``cos`` calls; ``"inline"``: the inline functions of
        ``templates/trig.c.j2`` (below 1 ulp, sin and cos of one angle share the reduction).
        The source defines only the functions of that template it calls.
    lanes : int
        0: no lane kernel. Else also ``<prefix>_sweep_lanes``, which runs ``lanes`` members side by
        side for the explicit methods (see `lane_kernel.py`); host use, it is never in ``generated/``.
    lane_trig : {"fast", "libm"}
        sin/cos inside the lane loops: branch-free polynomials (vectorizable), or libm's (then the
        lane kernel equals the scalar sweep bit for bit, for tests).
    """
    if precision not in PRECISIONS:
        raise EmitError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    if trig not in TRIG_MODES:
        raise EmitError(f"trig must be one of {TRIG_MODES}, got {trig!r}")
    model_name = model_name or system.name
    names = _names(system, model_name)
    printer = _KernelPrinter(precision=precision, names=names.symbols, trig=trig)
    real = precision
    functions = []
    if any(out in system.outputs for out in _CHECKED_OUTPUTS):
        functions.append(_finite_result_record(names.prefix, real))
    if any(out in system.outputs for out in ("accel", "rhs", "multipliers")):
        functions += _dynamics_records(system, names, printer, real)
        if system.n_constraints and any(out in system.outputs for out in ("accel", "rhs")):
            m, prefix = system.n_constraints, names.prefix
            functions.append(record(
                f"int {prefix}_dynamics({real} t, const {real} *x, const {real} *p, {real} *qd, {real} *ud, "
                f"{real} *gauge)",
                "qd and ud of the constrained system (gauge: see dynamics_constrained).",
                [f"{real} lam[{m}];", f"return {prefix}_dynamics_constrained(t, x, p, qd, ud, lam, 0, gauge);"],
                static=True))
    functions += [_function_record(system, system.kernel(_kernel_of(out)), names, printer, real, out)
                  for out in system.outputs]
    steppers = stepper_context(system, names, real, list(methods))
    steppers |= lane_context(system, names, real, list(methods), lanes, lane_trig)
    stepper_prototypes = steppers.pop("exported")
    if steppers["has_lanes"]:
        stepper_prototypes.append(steppers["lane_prototype"])
    if "constraints" in system.outputs:
        prefix = names.prefix
        stepper_prototypes = [
            record(f"void {prefix}_residuals({real} t, const {real} *x, const {real} *p, {real} *out)",
                   f"Constraint residuals: phi ({system.n_constraints}), then A u + dphi/dt "
                   f"({system.n_constraints}).", []),
            record(f"int {prefix}_project({real} t, {real} *x, const {real} *p)",
                   "Project x onto the constraint manifold (positions, then speeds); returns a status code.",
                   [])] + stepper_prototypes
    layout = _layout(system, names, real, model_name, functions + stepper_prototypes,
                     tuple(m["name"] for m in steppers["methods"]))
    context = _context(system, names, layout, functions, real) | steppers
    context["prototypes"] = context["prototypes"] + stepper_prototypes
    context |= _trig_context(printer, steppers)
    context["needs_spd"] = bool((context["has_constraints"] and (context["has_dynamics"]
                                                                 or context["has_constraint_terms"]))
                                or context["has_symplectic_euler"])
    env = template_environment()
    header_name = f"{names.prefix}.h"
    source_name = f"{names.prefix}.c"
    context["header_name"] = header_name
    header = env.get_template("model.h.j2").render(context, template="model.h.j2")
    source = env.get_template("model.c.j2").render(context, template="model.c.j2")
    cdef = env.get_template("model.cdef.j2").render(context)
    return CSources(layout=layout, header_name=header_name, header=header, source_name=source_name,
                    source=source, cdef=cdef, source_key=context["key"])


class _KernelPrinter(CPrinter):
    """A `CPrinter` that also records which of sin and cos it printed (``trig_calls``), so the
    source defines exactly the inline functions it calls (`_trig_context`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.trig_calls = set()

    def _print_trig(self, expr, name: str) -> str:
        self.trig_calls.add(name)
        return super()._print_trig(expr, name)


def _trig_context(printer: _KernelPrinter, steppers: dict) -> dict:
    """Which functions of templates/trig.c.j2 the source calls; it defines those and no others,
    since clang rejects an unused static function under -Wall -Werror (gcc does not warn for
    static inline ones). The kernels call lcg_sin/lcg_cos (float: lcg_sinf/lcg_cosf) only with
    trig="inline", and those call the branch-free _fast forms, as do the lane kernel's sin and
    cos wrappers (templates/lanes.c.j2, lane_trig="fast"). Nothing else does: with trig="libm"
    and no lanes (the committed generated/ files) the template is left out."""
    calls = printer.trig_calls if printer.trig == "inline" else set()
    emit = {f"emit_{name}": name in calls for name in ("sin", "cos")}
    emit |= {f"emit_{name}_fast": name in calls or steppers.get(f"lane_uses_{name}", False)
             for name in ("sin", "cos")}
    return {"has_trig": any(emit.values())} | emit | _trig_template_context(printer.precision)


def _trig_template_context(precision: str) -> dict:
    suffix = "f" if precision == "float" else ""
    return {"is_float": precision == "float", "trig_sin": f"lcg_sin{suffix}", "trig_cos": f"lcg_cos{suffix}",
            "mantissa_bits": 23 if precision == "float" else 52}


def trig_source(precision: str = "double") -> str:
    """The C text of ``templates/trig.c.j2`` alone, every function in it (needs ``<math.h>``),
    e.g. to test it."""
    if precision not in PRECISIONS:
        raise EmitError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    every = {"emit_sin": True, "emit_cos": True, "emit_sin_fast": True, "emit_cos_fast": True}
    return template_environment().get_template("trig.c.j2").render(every | _trig_template_context(precision))


def _kernel_of(output: str) -> str:
    return OUTPUT_KERNELS[output]


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
    for s, i in names.accel_index.items():
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = ud[{i}];")
    unused = []
    if not any(s in used for s in names.state_index):
        unused.append("x")
    if not any(s in used for s in names.param_index):
        unused.append("p")
    if TIME not in used:
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
        return record(f"void {prefix}_mass_matrix({args}, {real} *M)",
                       f"Mass matrix M(q, t), row-major {n} x {n}.", body)
    if output == "forcing":
        body = _body_head(kernel, names, printer, real) + ["/* Forcing */"]
        for (j, _), expr in _results(kernel, "F").items():
            body.append(f"F[{j}] = {_print(printer, expr, f'F[{j}]')};")
        return record(f"void {prefix}_forcing({args}, {real} *F)", f"Forcing F(q, u, t), {n} values.", body)
    if output == "accel":
        body = [f"{real} qd[{n}];",
                f"return {prefix}_finite_result({prefix}_dynamics(t, x, p, qd, ud, 0), ud, {n});"]
        return record(f"int {prefix}_accel({args}, {real} *ud)",
                       "Generalized accelerations ud solving M ud = F; returns a status code.", body)
    if output == "rhs":
        body = [f"return {prefix}_finite_result({prefix}_dynamics(t, x, p, xdot, xdot + {n}, 0), xdot, {2 * n});"]
        return record(f"int {prefix}_rhs({args}, {real} *xdot)",
                       f"First-order right-hand side xdot = f(t, x), x = (q, u), {2 * n} values; "
                       "returns a status code. xdot must not alias x.", body)
    if output == "energy":
        body = _body_head(kernel, names, printer, real)
        body.append(f"return {_print(printer, _results(kernel, 'E')[(0, 0)], 'energy')};")
        return record(f"{real} {prefix}_energy({args})", "Total mechanical energy T + V.", body)
    if output == "points":
        body = _body_head(kernel, names, printer, real) + ["/* Point positions (x, y, z) */"]
        for (i, c), expr in _results(kernel, "P").items():
            point = system.point_names[i]
            body.append(f"out[{3 * i + c}] = {_print(printer, expr, f'point {point}')};  "
                        f"/* {comment_text(point)}.{'xyz'[c]} */")
        return record(f"void {prefix}_points({args}, {real} *out)",
                       f"Positions of {len(system.point_names)} named points, 3 values each.", body)
    if output == "jacobian":
        return _jacobian_record(system, kernel, names, printer, real)
    if output == "multipliers":
        body = [f"{real} qd[{n}], ud[{n}];",
                f"const int status = {prefix}_dynamics_constrained(t, x, p, qd, ud, lam, Q, 0);",
                f"return {prefix}_finite_result(status, lam, {system.n_constraints});"]
        return record(f"int {prefix}_multipliers({args}, {real} *lam, {real} *Q)",
                      f"Multipliers lam ({system.n_constraints}) and generalized constraint forces "
                      f"Q = A^T lam ({n}, or NULL): M ud = F - A^T lam.", body)
    if output == "constraints":
        m = system.n_constraints
        body = _body_head(kernel, names, printer, real) + ["/* phi, A = dphi/dq, dphi/dt */"]
        body += [f"phi[{i}] = {_print(printer, e, f'phi[{i}]')};" for (i, _), e in _results(kernel, "R").items()]
        body += [f"A[{i * n + j}] = {_print(printer, e, f'dphi[{i}]/dq[{j}]')};"
                 for (i, j), e in _results(kernel, "A").items()]
        body += [f"phi_t[{i}] = {_print(printer, e, f'dphi[{i}]/dt')};" for (i, _), e in _results(kernel, "T").items()]
        return record(f"void {prefix}_constraint_terms({args}, {real} *phi, {real} *A, {real} *phi_t)",
                      f"Constraints phi ({m}), their Jacobian A = dphi/dq (row-major {m} x {n}) and dphi/dt ({m}).",
                      body)
    if output == "momentum":
        body = _body_head(kernel, names, printer, real) + ["/* Mass matrix, lower triangle, mirrored */"]
        for (j, k), expr in _results(kernel, "M").items():
            body.append(f"M[{j * n + k}] = {_print(printer, expr, f'M[{j}][{k}]')};")
            if j != k:
                body.append(f"M[{k * n + j}] = M[{j * n + k}];")
        body.append("/* G = dL/dq + Q */")
        body += [f"G[{j}] = {_print(printer, expr, f'G[{j}]')};" for (j, _), expr in _results(kernel, "G").items()]
        return record(f"void {prefix}_momentum({args}, {real} *M, {real} *G)",
                       f"M(q) (row-major {n} x {n}) and G = dL/dq + Q, for symplectic Euler in p = M u.", body)
    raise EmitError(f"unknown output {output!r}")


def _dynamics_records(system, names, printer, real) -> list:
    """Static kernel behind accel and rhs: K, M, F with joint CSE, then an unrolled LDL^T solve
    (with an always-inlined copy for the explicit steppers when it is small, `hot_dynamics`)."""
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
    nonzero = {jk for jk, e in M.items() if e != 0}
    failure = f"{prefix}_pivot_failure(x)"
    m = system.n_constraints
    if not m:
        factor, LD = ldlt_factor_lines(n, nonzero, real, failure)
        body += factor + _gauge_lines(n) + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}",
                                                                    lambda i: f"ud[{i}]")
        body.append("return LCG_OK;")
        signature = f"({real} t, const {real} *x, const {real} *p, {real} *qd, {real} *ud, {real} *gauge)"
        doc = ("K, M and F with shared temporaries, then M ud = F by LDL^T; gauge (or NULL) receives the "
               f"{n} pivots of M (the singularity monitor of the drivers).")
        if not hot_dynamics(system):
            return [record(f"int {prefix}_dynamics{signature}", doc, body, static=True)]
        return [record(f"int {prefix}_dynamics_hot{signature}",
                       doc[:-1] + "; inlined into every explicit Runge-Kutta stage.", body, hot=True),
                record(f"int {prefix}_dynamics{signature}", "The same, as one function for the other callers.",
                       [f"return {prefix}_dynamics_hot(t, x, p, qd, ud, gauge);"], static=True)]
    body += _constrained_solve_lines(kernel, printer, real, n, m, nonzero, failure, prefix)
    return [record(f"int {prefix}_dynamics_constrained({real} t, const {real} *x, const {real} *p, {real} *qd, "
                  f"{real} *ud, {real} *lam, {real} *Q, {real} *gauge)",
                  "K, M, F, A = dphi/dq and gamma with shared temporaries; M ud + A^T lam = F, A ud = gamma "
                  "by the range-space method (LDL^T of M, Cholesky of A M^-1 A^T); Q = A^T lam if not NULL; "
                  f"gauge (or NULL) receives the {n} pivots of M, the {m} of A M^-1 A^T and A "
                  "(the singularity monitor of the drivers).",
                  body, static=True)]


def _gauge_lines(n: int, indent: bool = True) -> list:
    """Store the LDL^T pivots D_j of M into gauge[j] (when gauge is not NULL): the drivers' singularity
    monitor compares them between accepted states (`steppers.gauge_context`)."""
    stores = [f"gauge[{j}] = D_{j};" for j in range(n)]
    if not indent:
        return stores
    return ["if (gauge) {  /* pivots of M, for the drivers' singularity monitor */"] + \
        ["    " + line for line in stores] + ["}"]


def _constrained_solve_lines(kernel, printer, real, n, m, nonzero, failure, prefix) -> list:
    body = [f"{real} A[{m * n}], C[{m}], z[{n}], Y[{n * m}];", "int c, i;", "/* A = dphi/dq, gamma */"]
    for (i, j), expr in _results(kernel, "A").items():
        body.append(f"A[{i * n + j}] = {_print(printer, expr, f'dphi[{i}]/dq[{j}]')};")
    for (i, _), expr in _results(kernel, "C").items():
        body.append(f"C[{i}] = {_print(printer, expr, f'gamma[{i}]')};")
    factor, LD = ldlt_factor_lines(n, nonzero, real, failure)
    body += factor + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}", lambda i: f"z[{i}]")
    body.append(f"for (c = 0; c < {m}; ++c) {{  /* Y = M^-1 A^T */")
    body += ["    " + line for line in ldlt_substitution_lines(
        n, LD, real, lambda i: f"A[c * {n} + {i}]", lambda i: f"Y[{i * m} + c]")]
    body += ["}",
             f"c = {prefix}_multipliers_solve(A, Y, z, C, lam, gauge ? gauge + {n} : 0);",
             "if (c != 1) return c == 0 ? LCG_SINGULAR_CONSTRAINTS : LCG_NONFINITE_STATE;",
             "if (gauge) {  /* after the solves: a failed step leaves the last accepted gauge */"]
    body += ["    " + line for line in _gauge_lines(n, indent=False)]
    body += [f"    for (i = 0; i < {m * n}; ++i) gauge[{n + m} + i] = A[i];",
             "}",
             f"for (i = 0; i < {n}; ++i) {{",
             f"    {real} acc = z[i];",
             f"    for (c = 0; c < {m}; ++c) acc -= Y[i * {m} + c] * lam[c];",
             "    ud[i] = acc;",
             "}",
             "if (Q) {",
             f"    for (i = 0; i < {n}; ++i) {{",
             f"        {real} acc = {literal(0, real)};",
             f"        for (c = 0; c < {m}; ++c) acc += A[c * {n} + i] * lam[c];",
             "        Q[i] = acc;",
             "    }",
             "}",
             "return LCG_OK;"]
    return body


#: outputs returning a status whose values are checked for NaN and infinity before LCG_OK
_CHECKED_OUTPUTS = ("accel", "rhs", "multipliers", "jacobian")


def _finite_result_record(prefix: str, real: str) -> dict:
    """A finite state can still give NaN or infinite derivatives (F overflowing for a huge
    parameter, 0 * inf): the public kernels report that instead of LCG_OK. The drivers' own
    steps are checked on the new state, so the steppers do not pay for this."""
    return record(f"int {prefix}_finite_result(int status, const {real} *values, int count)",
                  "status, or LCG_NONFINITE_STATE when status is LCG_OK but a value is NaN or infinite.",
                  ["int i;", "if (status != LCG_OK) return status;",
                   "for (i = 0; i < count; ++i) {", "    if (!isfinite(values[i])) return LCG_NONFINITE_STATE;",
                   "}", "return LCG_OK;"], static=True)


def _jacobian_record(system, kernel, names, printer, real) -> dict:
    """J = df/dx of the first-order system: [[dK/dq, dK/du], [-M^-1 dG/dq, -M^-1 dG/du]]."""
    n, prefix = len(system.q), names.prefix
    size = 2 * n
    body = [f"{real} qd[{n}];", f"{real} ud[{n}];", f"{real} B[{n}][{size}];", "int c;",
            f"const int status = {prefix}_dynamics(t, x, p, qd, ud, 0);",
            "if (status != LCG_OK) return status;"]
    body += _body_head(kernel, names, printer, real, touches_state=True)
    M = _results(kernel, "M")
    body.append("/* Mass matrix, lower triangle */")
    for (j, k), expr in M.items():
        if expr != 0 or j == k:
            body.append(f"const {real} M_{j}_{k} = {_print(printer, expr, f'M[{j}][{k}]')};")
    body.append("/* B = -dG/dx, G = M ud - F */")
    for (j, c), expr in _results(kernel, "G").items():
        value = f"-({_print(printer, expr, f'dG[{j}]/dx[{c}]')})" if expr != 0 else literal(0, real)
        body.append(f"B[{j}][{c}] = {value};")
    body.append("/* Kinematic rows dK/dx */")
    DK = _results(kernel, "DK")
    for j in range(n):
        for c in range(size):
            if DK:
                value = _print(printer, DK[(j, c)], f"dK[{j}]/dx[{c}]")
            else:
                value = literal(1 if c == n + j else 0, real)
            body.append(f"J[{j * size + c}] = {value};")
    factor, LD = ldlt_factor_lines(n, {jk for jk, e in M.items() if e != 0}, real, f"{prefix}_pivot_failure(x)")
    body += factor
    body.append(f"for (c = 0; c < {size}; ++c) {{")
    solve = ldlt_substitution_lines(n, LD, real, lambda i: f"B[{i}][c]",
                                    lambda i: f"J[{(n + i) * size} + c]")
    body += ["    " + line for line in solve]
    body += ["}", f"return {prefix}_finite_result(LCG_OK, J, {size * size});"]
    return record(f"int {prefix}_jacobian({real} t, const {real} *x, const {real} *p, {real} *J)",
                   f"Jacobian df/dx of the first-order right-hand side, row-major {size} x {size}; "
                   "returns a status code.", body)


def _layout(system: ReducedSystem, names: _Names, real: str, model_name: str, functions: list,
            methods: tuple) -> KernelLayout:
    exported = tuple(f["decl"].split("(")[0].split()[-1] for f in functions if not f["static"])
    return KernelLayout(
        model=model_name, prefix=names.prefix, precision=real,
        coordinates=tuple(s.name for s in system.q), speeds=tuple(s.name for s in system.u),
        parameters=tuple(s.name for s in system.free_parameters),
        fixed=tuple((s.name, v) for s, v in system.fixed_parameters),
        points=system.point_names, functions=exported, methods=methods, n_constraints=system.n_constraints,
        defaults=tuple((p.name, system.parameter_values[p]) for p in system.free_parameters
                       if p in system.parameter_values))


def _context(system: ReducedSystem, names: _Names, layout: KernelLayout, functions: list, real: str) -> dict:
    from .. import __version__

    n = len(system.q)
    state_rows = [{"index": i, "name": comment_text(s.name), "c_name": names.symbols[s],
                   "kind": "coordinate" if i < n else "speed"}
                  for i, s in enumerate(system.q + system.u)]
    param_rows = [{"index": i, "name": comment_text(s.name), "c_name": names.symbols[s]}
                  for i, s in enumerate(system.free_parameters)]
    fixed_rows = [{"name": comment_text(s.name), "value": repr(v)} for s, v in system.fixed_parameters]
    point_rows = [{"index": 3 * i, "name": comment_text(name)} for i, name in enumerate(system.point_names)]
    key_text = repr((layout, [(f["decl"], f["body"]) for f in functions]))
    upper = names.prefix.upper()
    return {
        "version": __version__, "sympy_version": sp.__version__, "model": comment_text(layout.model),
        "route": system.route, "key": hashlib.sha256(key_text.encode()).hexdigest()[:16],
        "prefix": names.prefix, "guard": f"{upper}_H", "macro": upper, "real": real,
        "n": n, "n_state": 2 * n, "n_params": len(param_rows), "n_points": len(point_rows),
        "state_rows": state_rows, "param_rows": param_rows, "fixed_rows": fixed_rows,
        "point_rows": point_rows, "has_fixed": bool(fixed_rows),
        "status_codes": [{"name": row.c_name, "value": row.code, "doc": row.message} for row in STATUS_TABLE],
        "prototypes": [f for f in functions if not f["static"]], "functions": functions,
        "has_dynamics": any(f" {names.prefix}_dynamics" in f["decl"] for f in functions),
        "has_hot": any(f["hot"] for f in functions),
        "has_constraints": system.n_constraints > 0, "n_constraints": system.n_constraints,
        "n_constraint_matrix": system.n_constraints * n, "n_constraints_squared": system.n_constraints ** 2,
        "has_constraint_terms": "constraints" in system.outputs,
        "constraint_tolerance": literal(1e-12 if real == "double" else 1e-6, real),
        "projection_iterations": 10, "n_residuals": 2 * system.n_constraints,
        "n_multiplier_values": system.n_constraints + n,
        "rank_tolerance": literal(1e-12 if real == "double" else 1e-6, real),
    }


