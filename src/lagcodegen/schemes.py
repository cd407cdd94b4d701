"""Helper: the integration schemes a kernel can be built with, by name.

Runge-Kutta methods are Butcher tableaux (`tableaux.TABLEAUX`): explicit ones run the generic
explicit stepper, implicit ones the generic simplified-Newton stepper with the analytic
Jacobian. The one non-RK scheme is semi-implicit (symplectic) Euler,
``u+ = u + h ud(q, u)``, ``q+ = q + h K(q, u+)``: symplectic when M is constant (linear chains,
oscillators; Hairer-Lubich-Wanner, Geometric Numerical Integration, Thm. VI.3.3), first order
and merely semi-implicit when M depends on q.
"""
from __future__ import annotations

from dataclasses import dataclass

from .tableaux import TABLEAUX, ButcherTableau

KIND_EXPLICIT = "explicit"
KIND_IMPLICIT = "implicit"
KIND_SYMPLECTIC_EULER = "symplectic_euler"


@dataclass(frozen=True)
class SymplecticEuler:
    """Semi-implicit Euler: declares ``order`` and ``kind`` like a tableau.

    On y'' = -w^2 y it is stable for h w < 2 (its map has trace 2 - (h w)^2).
    """

    name: str = "symplectic_euler"
    order: int = 1
    title: str = "semi-implicit (symplectic) Euler"

    @property
    def kind(self) -> str:
        return KIND_SYMPLECTIC_EULER

    def imag_stability_limit(self) -> float:
        return 2.0


SYMPLECTIC_EULER = SymplecticEuler()


def scheme_kind(scheme) -> str:
    if isinstance(scheme, SymplecticEuler):
        return KIND_SYMPLECTIC_EULER
    return KIND_EXPLICIT if scheme.explicit else KIND_IMPLICIT


SCHEMES: dict = {**TABLEAUX, SYMPLECTIC_EULER.name: SYMPLECTIC_EULER}
DEFAULT_METHODS = ("euler", "symplectic_euler", "heun", "kutta3", "rk4", "rk38", "dopri5",
                   "implicit_midpoint", "backward_euler", "sdirk2", "radau_iia3")


def get_scheme(name: str):
    """The scheme called ``name`` (case-insensitive); KeyError lists the known names."""
    key = str(name).lower()
    if key not in SCHEMES:
        raise KeyError(f"unknown method {name!r}; methods: {', '.join(sorted(SCHEMES))}")
    return SCHEMES[key]


def needs_jacobian(methods) -> bool:
    return any(scheme_kind(get_scheme(m)) == KIND_IMPLICIT for m in methods)


def is_tableau(scheme) -> bool:
    return isinstance(scheme, ButcherTableau)
