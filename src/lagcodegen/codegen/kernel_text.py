"""Helper: C names of a reduced system's symbols and the lines every kernel function starts with.

The output registry (`outputs.py`) writes each function's body with a `KernelWriter`; the
renderer (`render.py`) lays the functions out with the templates.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from ..model import TIME
from .csyntax import EmitError
from .printer import CPrinter, mangle

if TYPE_CHECKING:
    from .reduce import ReducedKernel, ReducedSystem

#: local names the generated code uses itself; user symbols are renamed around them
RESERVED = {"t", "x", "p", "out", "M", "F", "ud", "qd", "xdot", "B", "J", "c", "status", "work", "h",
            "i", "j", "k", "m", "s", "method", "stride", "n_steps", "steps_done", "A", "C", "Y", "z",
            "lam", "Q", "phi", "phi_t", "project"}


@dataclass(frozen=True)
class Names:
    """C names of every symbol and the prefix of the exported functions."""

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


def names_for(system: ReducedSystem, model_name: str) -> Names:
    """C names of ``system``'s symbols (CSE temporaries first), clear of the generated code's own."""
    taken = set(RESERVED) | _solver_locals(len(system.q))
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
    return Names(prefix=prefix, symbols=symbols, state_index=state, param_index=params, accel_index=accel)


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
    def n(self) -> int:
        return len(self.system.q)

    @property
    def arguments(self) -> str:
        """The arguments every kernel function starts with."""
        return f"{self.real} t, const {self.real} *x, const {self.real} *p"

    def expr(self, expr, where: str) -> str:
        """``expr`` as C; an expression the printer refuses is an EmitError naming ``where``."""
        try:
            return self.printer.doprint(expr)
        except ValueError as err:
            raise EmitError(f"cannot print {where}: {err}") from err

    def head(self, kernel: ReducedKernel, touches_state: bool = False) -> list:
        """Input aliases, (void) casts of unused arguments and the CSE temporaries of ``kernel``."""
        inputs, unused = self._input_lines(kernel)
        if touches_state and "x" in unused:
            unused.remove("x")
        lines = [f"/* Inputs ({len(inputs)}) */"] + inputs
        lines += [f"(void){arg};" for arg in unused]
        lines.append(f"/* Intermediate terms ({len(kernel.temporaries)}), total ops {kernel.ops_after} "
                     f"(before CSE {kernel.ops_before}) */")
        for s, expr in kernel.temporaries:
            lines.append(f"const {self.real} {self.names.symbols[s]} = {self.expr(expr, self.names.symbols[s])};")
        return lines

    def _input_lines(self, kernel: ReducedKernel) -> tuple[list, list]:
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
        unused = []
        if not any(s in used for s in names.state_index):
            unused.append("x")
        if not any(s in used for s in names.param_index):
            unused.append("p")
        if TIME not in used:
            unused.append("t")
        return lines, unused


def results(kernel: ReducedKernel, block: str) -> dict:
    """The kernel's results of one block, by (i, j)."""
    return {(i, j): expr for (b, i, j), expr in kernel.results if b == block}
