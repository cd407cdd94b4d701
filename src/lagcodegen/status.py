"""Helper: the status codes every stage agrees on, in one table.

The C kernels' ``LCG_*`` defines (`render`, templates ``model.h.j2`` and ``model.cdef.j2``), the
Python enum `Status` with its messages, the sweep-only codes and ``docs/status.md`` are all made
from `STATUS_TABLE`; a test checks the committed docs against `status_markdown`. Imports no stage.
"""
from __future__ import annotations

import enum
from dataclasses import dataclass


@dataclass(frozen=True)
class StatusCode:
    """One status: its Python name (the C define is ``LCG_<name>``), code and message."""

    name: str
    code: int
    message: str

    @property
    def c_name(self) -> str:
        return f"LCG_{self.name}"


#: codes the generated C returns (the order is the C header's)
STATUS_TABLE = (
    StatusCode("OK", 0, "success"),
    StatusCode("SINGULAR_MASS_MATRIX", 1, "the mass matrix is singular or not positive definite, or a step "
                                          "changed its pivots more than 100-fold (a singular configuration "
                                          "crossed, or a step too coarse for the monitor: a smaller h tells)"),
    StatusCode("NONFINITE_STATE", 2, "the state or its derivatives became NaN or infinite (the run diverged)"),
    StatusCode("NEWTON_FAILED", 3, "a Newton iteration did not converge (an implicit step's, symplectic "
                                   "Euler's velocity iteration, or the projection onto the constraints)"),
    StatusCode("UNKNOWN_METHOD", 4, "the method is not compiled into this kernel"),
    StatusCode("SINGULAR_CONSTRAINTS", 5, "the constraint Jacobian lost rank (redundant constraints, a "
                                          "singular configuration, or a step that crossed one or neared it "
                                          "faster than the step resolves)"),
    StatusCode("NONFINITE_INPUT", 6, "an input value is NaN or infinite"),
    StatusCode("INPUT_FAILED", 7, "the input function failed (a callable raised or returned the wrong shape, "
                                  "or an empty input table)"),
    StatusCode("BAD_ARGUMENT", 8, "an argument of a C driver or step function is out of range (n_steps < 0, "
                                  "stride < 1, a time or step size that is not finite): nothing was run or "
                                  "written"),
)
#: codes only a sweep gives its members (never returned by C)
SWEEP_STATUS_TABLE = (
    StatusCode("NOT_RUN", -1, "not run: the sweep was interrupted before this member's chunk"),
    StatusCode("CHUNK_FAILED", -2, "not run: this member's chunk raised (see SweepResult.errors)"),
)


class _StatusBase(enum.IntEnum):
    """Behaviour of `Status`; its members come from `STATUS_TABLE`."""

    @property
    def message(self) -> str:
        return _MESSAGES[int(self)]

    # IntEnum prints its value ("0"); print the name, and keep numeric format specs numeric
    def __str__(self) -> str:
        return self.name

    def __format__(self, spec: str) -> str:
        if spec and spec[-1] in "bcdeEfFgGnoxX%":
            return format(int(self), spec)
        return format(self.name, spec)


_MESSAGES = {row.code: row.message for row in STATUS_TABLE + SWEEP_STATUS_TABLE}
#: status codes of the generated C (``LCG_*`` in the header), as a Python enum
Status = _StatusBase("Status", [(row.name, row.code) for row in STATUS_TABLE], module=__name__,
                     qualname="Status")
NOT_RUN, CHUNK_FAILED = (row.code for row in SWEEP_STATUS_TABLE)
#: names of the sweep-only status codes, next to `Status`' own
SWEEP_STATUS_NAMES = {row.code: row.name.lower() for row in SWEEP_STATUS_TABLE}


def status_message(code: int) -> str:
    """The message of any status code, C or sweep-only."""
    return _MESSAGES[int(code)]


def status_markdown() -> str:
    """``docs/status.md``: every status code, its C define and its message."""
    lines = ["# Status codes", "",
             "Generated from `src/lagcodegen/status.py` (`STATUS_TABLE`); "
             "`tests/test_status_table.py` checks this file is current.", "",
             "| code | Python (`Status`) | C define | meaning |", "|---:|---|---|---|"]
    lines += [f"| {row.code} | `{row.name}` | `{row.c_name}` | {row.message} |" for row in STATUS_TABLE]
    lines += ["", "Sweep members only (`SweepResult.status`; never returned by the C):", "",
              "| code | name | meaning |", "|---:|---|---|"]
    lines += [f"| {row.code} | `{row.name}` | {row.message} |" for row in SWEEP_STATUS_TABLE]
    return "\n".join(lines) + "\n"
