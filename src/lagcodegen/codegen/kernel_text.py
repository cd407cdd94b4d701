"""Helper: C names of a reduced system's symbols and the lines every kernel function starts with.

The output registry (`outputs.py`) writes each function's body with a `KernelWriter`; the
renderer (`render.py`) lays the functions out with the templates.
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

from ..model import TIME
from .csyntax import EmitError, record
from .printer import CPrinter, mangle

if TYPE_CHECKING:
    from .reduce import ReducedKernel, ReducedSystem

#: local names the generated code uses itself; user symbols are renamed around them
RESERVED = {"t", "x", "p", "out", "M", "F", "ud", "qd", "xdot", "B", "J", "c", "status", "work", "h",
            "i", "j", "k", "m", "s", "method", "stride", "n_steps", "steps_done", "A", "C", "Y", "z",
            "lam", "Q", "phi", "phi_t", "project", "part_values",
            # the kernels' own parameters and locals (found by review: a parameter named gauge, the
            # dynamics' argument, failed to compile with "redeclared as different kind of symbol")
            "gauge", "H", "det", "entry", "factor", "pivot", "saved", "scale", "size", "sum", "swap", "width",
            "xs", "fp", "fm", "angle", "acc", "cols", "count", "n", "product", "terms", "positions", "t0",
            # the momentum kernel's output G (found by review: a parameter G, the gravitational
            # constant, failed to compile with the default methods) and the steps' stage gauge
            "G", "stage_gauge"}
#: ... and those of the functions of a model with inputs or measurements (only then, so that the
#: names of the other models' symbols do not change)
DRIVEN_RESERVED = {"r", "dr", "rs", "r0", "r1", "y", "Fx", "Fr", "Jr", "Br", "hold", "inputs", "context"}
#: ... and those of the functions of a model whose dependent speeds are eliminated
DEPENDENT_RESERVED = {"u_dep", "dep_status", "AD", "b", "Mfull", "Fvec", "gamma", "AD_dep", "scale_dep", "LU",
                      "ipiv", "X", "gD", "top"}


def _reduced_locals(n: int) -> set:
    """Locals of the eliminated dynamics' reduction to the independent speeds (A_D's unrolled LU,
    M C, C^T M C, the reduced forcing)."""
    names = set()
    for j in range(n):
        names |= {f"rest_{j}", f"Fr_{j}", f"largest_{j}", f"b_{j}"}
        for k in range(n):
            names |= {f"MC_{j}_{k}", f"Mr_{j}_{k}", f"LU_{j}_{k}"}
    return names


@dataclass(frozen=True)
class Names:
    """C names of every symbol and the prefix of the exported functions."""

    prefix: str
    symbols: dict   # Symbol -> C local name
    state_index: dict  # Symbol -> index into x
    param_index: dict  # Symbol -> index into p
    accel_index: dict  # Symbol -> index into ud (jacobian kernel only)
    input_index: dict = None  # Symbol -> index into r (models with inputs)
    dependent_index: dict = None  # Symbol -> index into u_dep (eliminated dependent speeds)


def _solver_locals(n: int) -> set:
    """Locals of the unrolled LDL^T code (M_j_k, F_j, D_j, ...) and of the recursive dynamics
    (pivot_j): user names must avoid them."""
    names = set()
    for j in range(n):
        names |= {f"F_{j}", f"D_{j}", f"Dinv_{j}", f"y_{j}", f"w_{j}", f"yc_{j}", f"wc_{j}", f"pivot_{j}"}
        for k in range(n):
            names |= {f"M_{j}_{k}", f"L_{j}_{k}", f"LD_{j}_{k}"}
    return names


def names_for(system: ReducedSystem, model_name: str) -> Names:
    """C names of ``system``'s symbols (CSE temporaries first), clear of the generated code's own."""
    taken = set(RESERVED) | _solver_locals(max(len(system.q), len(system.u) + len(system.u_dependent)))
    if system.inputs or system.measurements:
        taken |= DRIVEN_RESERVED
    if system.u_dependent or system.reactions:
        taken |= DEPENDENT_RESERVED | {"RJ"} | _reduced_locals(len(system.u) + len(system.u_dependent))
    temporaries = [s for k in system.kernels for s, _ in k.temporaries]
    symbols = {}
    for s in dict.fromkeys(temporaries):  # cse names first: tmp0, tmp1, ...
        symbols[s] = mangle(s.name, taken)
    for s in system.q + system.u + system.u_dependent + system.inputs + system.free_parameters + system.accelerations:
        symbols[s] = mangle(s.name, taken)
    symbols[system.t] = "t"
    body = mangle(model_name)
    if body != body.lower() or body != model_name:  # found by review: the macros (LCG_PENDULUM_H) and, on
        # some file systems, the file names fold case, so "Pendulum" and "pendulum" clashed in one firmware,
        # and mangling made "arm-left" and "arm_left" (or "for" and "for_") one prefix: a name with capitals,
        # or one mangling changed, gets 8 hex digits of its sha256
        body = f"{body}_{hashlib.sha256(model_name.encode()).hexdigest()[:8]}"
    prefix = "lcg_" + body
    state = {s: i for i, s in enumerate(system.q + system.u)}
    params = {s: i for i, s in enumerate(system.free_parameters)}
    accel = {s: i for i, s in enumerate(system.accelerations)}
    inputs = {s: i for i, s in enumerate(system.inputs)}
    dependent = {s: i for i, s in enumerate(system.u_dependent)} or None
    return Names(prefix=prefix, symbols=symbols, state_index=state, param_index=params, accel_index=accel,
                 input_index=inputs, dependent_index=dependent)


@dataclass(frozen=True)
class KernelWriter:
    """What an output's C body is written with: the system, its C names, the printer, the scalar type."""

    system: ReducedSystem
    names: Names
    printer: CPrinter
    real: str

    @property
    def prefix(self) -> str:
        return self.names.prefix

    @property
    def n_q(self) -> int:
        return len(self.system.q)

    @property
    def n_u(self) -> int:
        return len(self.system.u)

    @property
    def n_state(self) -> int:
        return len(self.system.q) + len(self.system.u)

    @property
    def n_dependent(self) -> int:
        return len(self.system.u_dependent)

    @property
    def n_m(self) -> int:
        """Size of M and F: the state's speeds and the eliminated dependent ones."""
        return len(self.system.u) + len(self.system.u_dependent)

    @property
    def n_inputs(self) -> int:
        return len(self.system.inputs)

    @property
    def arguments(self) -> str:
        """The arguments every kernel function starts with (those that cannot read the inputs)."""
        return f"{self.real} t, const {self.real} *x, const {self.real} *p"

    @property
    def driven_arguments(self) -> str:
        """The arguments of a function that evaluates the dynamics: with ``const real *r`` when the
        model has inputs, else as `arguments`."""
        if not self.n_inputs:
            return self.arguments
        return f"{self.real} t, const {self.real} *x, const {self.real} *r, const {self.real} *p"

    @property
    def rp(self) -> str:
        """What such a function passes on after ``t, x``: ``r, p`` or ``p``."""
        return "r, p" if self.n_inputs else "p"

    def expr(self, expr, where: str) -> str:
        """``expr`` as C; an expression the printer refuses is an EmitError naming ``where``."""
        try:
            return self.printer.doprint(expr)
        except ValueError as err:
            raise EmitError(f"cannot print {where}: {err}") from err

    def head(self, kernel: ReducedKernel, touches_state: bool = False, reads_inputs: bool = False,
             on_singular: str | None = None, dependent_solve: list | None = None) -> list:
        """Input aliases, (void) casts of unused arguments and the CSE temporaries of ``kernel``
        (``reads_inputs``: the function has the argument ``r``). A kernel that reads eliminated
        dependent speeds first solves for them; ``on_singular`` is the statement run when that
        solve fails (else their NaN values carry on). ``dependent_solve``: lines that leave them
        in ``u_dep`` from the kernel's own temporaries, run after the temporaries that do not read
        them (in place of a call of ``<prefix>_dependent_speeds``)."""
        index = self.names.dependent_index or {}
        split = dependent_solve is not None
        inputs, unused = self._input_lines(kernel, reads_inputs)
        if touches_state and "x" in unused:
            unused.remove("x")
        dependent = [] if split else self._dependent_lines(kernel, on_singular)
        if dependent:  # the call of <prefix>_dependent_speeds reads t, x and p
            unused = [arg for arg in unused if arg not in ("t", "x", "p")]
        lines = [f"/* Inputs ({len(inputs)}) */"] + inputs + dependent + [f"(void){arg};" for arg in unused]
        summary = (f"/* Intermediate terms ({len(kernel.temporaries)}), total ops {kernel.ops_after} "
                   f"(before CSE {kernel.ops_before})")
        if not split:
            return lines + [summary + " */"] + self._temporary_lines(kernel.temporaries)
        # the dependent speeds solved between the temporaries that do not read them and those that
        # do (CSE orders each after what it reads, so both groups keep their order)
        reads_dependent, before, later = set(index), [], []
        for s, expr in kernel.temporaries:
            if expr.free_symbols & reads_dependent:
                later.append((s, expr))
                reads_dependent.add(s)
            else:
                before.append((s, expr))
        lines += [summary + "; first those that do not read the dependent speeds */"]
        lines += self._temporary_lines(before) + dependent_solve
        lines += [f"const {self.real} {self.names.symbols[s]} = u_dep[{i}];" for s, i in index.items()
                  if s in kernel.symbols]
        lines.append("/* the intermediate terms that read the dependent speeds */")
        return lines + self._temporary_lines(later)

    def _temporary_lines(self, temporaries) -> list:
        return [f"const {self.real} {self.names.symbols[s]} = {self.expr(expr, self.names.symbols[s])};"
                for s, expr in temporaries]

    def _dependent_lines(self, kernel: ReducedKernel, on_singular: str | None) -> list:
        """The eliminated dependent speeds the kernel reads, from ``<prefix>_dependent_speeds``."""
        index = self.names.dependent_index or {}
        if not any(s in kernel.symbols for s in index):
            return []
        real = self.real
        lines = [f"{real} u_dep[{len(index)}];",
                 f"const int dep_status = {self.prefix}_dependent_speeds(t, x, p, u_dep);"]
        lines.append(f"if (dep_status != LCG_OK) {on_singular}" if on_singular else "(void)dep_status;")
        lines += [f"const {real} {self.names.symbols[s]} = u_dep[{i}];" for s, i in index.items()
                  if s in kernel.symbols]
        return lines

    def _input_lines(self, kernel: ReducedKernel, reads_inputs: bool) -> tuple[list, list]:
        """Aliases ``const double q1 = x[0];`` for the inputs a kernel reads, and unused arguments."""
        used, names, real = kernel.symbols, self.names, self.real
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
        for s, i in (names.input_index or {}).items():
            if s in used:
                lines.append(f"const {real} {names.symbols[s]} = r[{i}];")
        unused = []
        if not any(s in used for s in names.state_index):
            unused.append("x")
        if not any(s in used for s in names.param_index):
            unused.append("p")
        if TIME not in used:
            unused.append("t")
        if names.input_index and reads_inputs and not any(s in used for s in names.input_index):
            unused.append("r")
        return lines, unused


#: assignments per part function of a big recursive kernel: gcc's register allocation grows faster
#: than linearly in one function's length (n = 50 chain: 5.0 s at -O3 as one function)
PART_ASSIGNMENTS = 200


def kernel_parts(w: KernelWriter, kernel: ReducedKernel, stem: str, driven: bool) -> tuple[list, list]:
    """A long kernel as static part functions ``<prefix>_<stem>_part<k>`` run in order, which pass
    the values later parts and the results read through the caller's array ``part_values``.
    Returns (the part functions, the caller's lines up to its results); a short kernel: no parts
    and `KernelWriter.head`'s lines."""
    temporaries = kernel.temporaries
    if len(temporaries) <= PART_ASSIGNMENTS:
        return [], w.head(kernel, touches_state=True, reads_inputs=driven)
    chunks = [temporaries[k:k + PART_ASSIGNMENTS] for k in range(0, len(temporaries), PART_ASSIGNMENTS)]
    home = {symbol: k for k, chunk in enumerate(chunks) for symbol, _ in chunk}
    read_later: set = set()
    for k, chunk in enumerate(chunks):
        for _, expr in chunk:
            read_later |= {s for s in expr.free_symbols if home.get(s, k) < k}
    for _, expr in kernel.results:
        read_later |= {s for s in expr.free_symbols if s in home}
    slot = {symbol: i for i, symbol in enumerate(s for s, _ in temporaries if s in read_later)}
    real, prefix = w.real, w.prefix
    arguments = w.driven_arguments if driven else w.arguments
    passed = f"t, x, {w.rp}" if driven else "t, x, p"
    parts, calls = [], [f"{real} part_values[{max(len(slot), 1)}];"]
    for k, chunk in enumerate(chunks):
        part = replace(kernel, name=f"{kernel.name}_part{k}", temporaries=chunk, results=(), ops_before=0,
                       ops_after=0)
        imported = sorted({s for _, e in chunk for s in e.free_symbols if home.get(s, k) < k}, key=slot.get)
        body = [f"const {real} {w.names.symbols[s]} = part_values[{slot[s]}];" for s in imported]
        body += w.head(part, reads_inputs=driven)
        body += [f"part_values[{slot[s]}] = {w.names.symbols[s]};" for s, _ in chunk if s in slot]
        name = f"{prefix}_{stem}_part{k}"
        parts.append(record("void", name, f"{arguments}, {real} *part_values",
                            f"Assignments {k * PART_ASSIGNMENTS} to {k * PART_ASSIGNMENTS + len(chunk) - 1} of "
                            f"{stem} ({len(temporaries)} in {len(chunks)} parts).", body, static=True))
        calls.append(f"{name}({passed}, part_values);")
    tail = replace(kernel, temporaries=(), ops_before=0, ops_after=0)
    head = [line for line in w.head(tail, touches_state=True, reads_inputs=driven) if not line.startswith("(void)")]
    loads = [f"const {real} {w.names.symbols[s]} = part_values[{slot[s]}];"
             for s in sorted({s for _, e in kernel.results for s in e.free_symbols if s in slot}, key=slot.get)]
    return parts, calls + head + loads


def results(kernel: ReducedKernel, block: str) -> dict:
    """The kernel's results of one block, by (i, j)."""
    return {(i, j): expr for (b, i, j), expr in kernel.results if b == block}
