"""Helper of the FMU export: the FMI variables of one kernel layout, in one table.

`fmi_variables` is the single source of truth for names, value references, causality and
start values: ``modelDescription.xml`` (`description.py`) lists its rows and the C wrapper
(``templates/fmu_core.c.j2``) receives its value-reference ranges (`VariableTable.ranges`), so the
two cannot disagree. Value references are consecutive and grouped by kind, in this order:

==============  ===========================  ==================================================
kind            causality (FMI 2.0 and 3.0)  values
==============  ===========================  ==================================================
state           output, continuous, exact    x = (q, u), 2n (Model Exchange: the states)
derivative      local, continuous, calc.     der(x), 2n (Model Exchange: their derivatives)
parameter       parameter, tunable, exact    the free parameters, p[] order
input           input, continuous            the inputs r, start 0
step            parameter, fixed, exact      ``step_size``, the Co-Simulation fixed step
fixed           local, constant, exact       parameters folded into the C (read only)
energy          output, continuous, calc.    T + V (when the model has energies)
point           output, continuous, calc.    ``<point>.x``, ``.y``, ``.z`` of each named point
measurement     output, continuous, calc.    the model's output expressions y
time            independent, continuous      ``time`` (FMI 3.0 only, which requires it)
==============  ===========================  ==================================================

The model states no units, so no variable has one.
"""
from __future__ import annotations

from dataclasses import dataclass

#: the kinds in value-reference order (the C wrapper's ranges follow it)
KINDS = ("state", "derivative", "parameter", "input", "step", "fixed", "energy", "point", "measurement", "time")
#: name of the Co-Simulation step parameter
STEP_NAME = "step_size"
#: kind -> (causality, variability, initial), the same in FMI 2.0 and 3.0
ATTRIBUTES = {
    "state": ("output", "continuous", "exact"),
    "derivative": ("local", "continuous", "calculated"),
    "parameter": ("parameter", "tunable", "exact"),
    "input": ("input", "continuous", None),
    "step": ("parameter", "fixed", "exact"),
    "fixed": ("local", "constant", "exact"),
    "energy": ("output", "continuous", "calculated"),
    "point": ("output", "continuous", "calculated"),
    "measurement": ("output", "continuous", "calculated"),
    "time": ("independent", "continuous", None),
}


class VariableError(ValueError):
    """Two FMI variables would share a name; the message names both."""


@dataclass(frozen=True)
class FmiVariable:
    """One ScalarVariable: ``value_reference`` (0-based, consecutive), ``index`` (1-based position
    in ModelVariables, which ModelStructure refers to), ``derivative_of``: for a derivative, the
    index of its state."""

    name: str
    kind: str
    value_reference: int
    description: str
    start: float | None = None
    derivative_of: int | None = None

    @property
    def index(self) -> int:
        return self.value_reference + 1

    @property
    def causality(self) -> str:
        return ATTRIBUTES[self.kind][0]

    @property
    def variability(self) -> str:
        return ATTRIBUTES[self.kind][1]

    @property
    def initial(self) -> str | None:
        return ATTRIBUTES[self.kind][2]


@dataclass(frozen=True)
class VariableTable:
    """The variables of one FMU, value-reference order."""

    variables: tuple

    def of_kind(self, kind: str) -> tuple:
        return tuple(v for v in self.variables if v.kind == kind)

    @property
    def ranges(self) -> dict:
        """``{kind: first value reference}`` and ``"end"``: the C wrapper's dispatch table."""
        first, vr = {}, 0
        for kind in KINDS:
            first[kind] = vr
            vr += len(self.of_kind(kind))
        first["end"] = vr
        return first


def fmi_variables(layout, x0, p, h: float, *, method: str, has_energy: bool,
                  fmi_version: str = "2.0") -> VariableTable:
    """The variable table of a kernel ``layout`` (`render.KernelLayout`) with start values ``x0``
    (2n), ``p`` (free parameters, p[] order) and the Co-Simulation step ``h``; FMI 3.0 adds the
    independent variable ``time``.

    Raises `VariableError` when two variables would have the same name (a measurement called
    like a state, a parameter called ``step_size``, ...), naming both.
    """
    rows = []

    def add(name, kind, description, start=None, derivative_of=None):
        rows.append(FmiVariable(name, kind, len(rows), description, start, derivative_of))

    states = layout.coordinates + layout.speeds
    for i, name in enumerate(states):
        what = "coordinate" if i < layout.n_q else "speed"
        add(name, "state", f"{what} x[{i}]", float(x0[i]))
    for i, name in enumerate(states):
        add(f"der({name})", "derivative", f"time derivative of {name}", derivative_of=i + 1)
    for i, name in enumerate(layout.parameters):
        add(name, "parameter", f"parameter p[{i}]", float(p[i]))
    for i, name in enumerate(layout.inputs):
        add(name, "input", f"input r[{i}], held over each step (zero-order hold)", 0.0)
    add(STEP_NAME, "step", f"Co-Simulation: the fixed step of {method} inside doStep (Model Exchange "
                           f"ignores it)", float(h))
    for name, value in layout.fixed:
        add(name, "fixed", "parameter folded into the C code", float(value))
    if has_energy:
        add("energy", "energy", "total mechanical energy T + V")
    for point in layout.points:
        for axis in "xyz":
            add(f"{point}.{axis}", "point", f"{axis} coordinate of point {point}")
    for name in layout.measurements:
        add(name, "measurement", "output expression of the model")
    if fmi_version == "3.0":
        add("time", "time", "simulation time")
    _check_unique(rows)
    return VariableTable(tuple(rows))


def _check_unique(rows) -> None:
    seen = {}
    for row in rows:
        if row.name in seen:
            other = seen[row.name]
            raise VariableError(f"FMI variable name {row.name!r} is taken twice: by the {other.kind} and by the "
                                f"{row.kind} of that name; rename one in the model")
        seen[row.name] = row
