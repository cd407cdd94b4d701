"""Helper: the integration schemes a kernel can be built with, by name.

Runge-Kutta methods are Butcher tableaux (`tableaux.TABLEAUX`): explicit ones run the generic
explicit stepper, implicit ones the generic simplified-Newton stepper with the analytic
Jacobian. The one non-RK scheme is symplectic (semi-implicit) Euler in momentum form,
p = M(q) u: ``M(q) v = p + h G(q, v)``, ``q+ = q + h v``, ``p+ = M(q) v`` with G = dL/dq + Q
(Hairer-Lubich-Wanner, Geometric Numerical Integration, Thm. VI.3.3): symplectic for any M(q);
for constant M it reduces to ``u+ = u + h ud(q, u+)`` (the speeds at the step's end: a damping force
makes it implicit in u+, solved by sweeps that contract by h |d ud/du|), ``q+ = q + h u+``. It needs
T = 1/2 u^T M(q) u (`codegen.outputs.momentum_obstacle` says when a model does not qualify).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from .tableaux import TABLEAUX

#: the C steppers (`steppers` renders one per kind); `Scheme.stepper` names one
KIND_EXPLICIT = "explicit"
KIND_IMPLICIT = "implicit"
KIND_SYMPLECTIC_EULER = "symplectic_euler"
#: canonical order of the outputs schemes need (the sources key depends on the order)
_OUTPUT_ORDER = ("rhs", "jacobian", "momentum")


class Scheme(Protocol):
    """What every integration scheme declares; a Runge-Kutta method is a `ButcherTableau`, a
    non-RK scheme a small class like `SymplecticEuler`. Nothing else switches on the scheme."""

    name: str
    order: int
    title: str

    @property
    def stepper(self) -> str: ...       # KIND_*: which C stepper runs it

    @property
    def outputs(self) -> tuple: ...     # kernel outputs the stepper calls

    @property
    def lane_capable(self) -> bool: ...  # the lane-group sweep kernel can run it

    @property
    def implicit(self) -> bool: ...     # solves for its stages (Newton)

    def imag_stability_limit(self) -> float: ...

    def unstable_step(self, h: float, settled, n_steps: int) -> tuple[bool, str]: ...
    # (unstable, its stability region in words) for the Jacobian's non-growing eigenvalues


@dataclass(frozen=True)
class SymplecticEuler:
    """Semi-implicit Euler: declares ``order`` and ``kind`` like a tableau.

    On y'' = -w^2 y it is stable for h w < 2 (its map has trace 2 - (h w)^2).
    """

    name: str = "symplectic_euler"
    order: int = 1
    title: str = "symplectic (semi-implicit) Euler, momentum form"

    stepper: str = KIND_SYMPLECTIC_EULER
    outputs: tuple = ("rhs", "momentum")  # rhs for the stability pre-check and the first sample
    lane_capable: bool = False
    implicit: bool = False  # no Newton: fixed-point sweeps on v (contracting by h |d ud/du|)

    def imag_stability_limit(self) -> float:
        return 2.0

    def unstable_step(self, h: float, settled, n_steps: int) -> tuple[bool, str]:
        """Its map on y'' = -w^2 y has |trace| < 2 only for h w < 2; past that a mode grows
        geometrically whatever n_steps is."""
        w = float(max(abs(complex(e)) for e in settled))
        return h * w >= self.imag_stability_limit(), f"h*w < {self.imag_stability_limit():g}"


SYMPLECTIC_EULER = SymplecticEuler()


SCHEMES: dict = {**TABLEAUX, SYMPLECTIC_EULER.name: SYMPLECTIC_EULER}
DEFAULT_METHODS = ("euler", "symplectic_euler", "heun", "kutta3", "rk4", "rk38", "dopri5",
                   "implicit_midpoint", "backward_euler", "sdirk2", "radau_iia3")


def get_scheme(name: str):
    """The scheme called ``name`` (case-insensitive); KeyError lists the known names."""
    key = str(name).lower()
    if key not in SCHEMES:
        raise KeyError(f"unknown method {name!r}; methods: {', '.join(sorted(SCHEMES))}")
    return SCHEMES[key]


def required_outputs(methods) -> tuple:
    """The kernel outputs the integrators ``methods`` need, in a fixed order: the one
    method/output policy of the pipeline, the command line and tools/regenerate.py."""
    needed = {output for method in methods for output in get_scheme(method).outputs}
    def rank(output: str) -> tuple:
        return (_OUTPUT_ORDER.index(output) if output in _OUTPUT_ORDER else len(_OUTPUT_ORDER), output)
    return tuple(sorted(needed, key=rank))
