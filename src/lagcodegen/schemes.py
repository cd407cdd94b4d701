"""Helper: the integration schemes a kernel can be built with, by name.

Runge-Kutta methods are Butcher tableaux (`tableaux.TABLEAUX`): explicit ones run the generic
explicit stepper, implicit ones the generic simplified-Newton stepper with the analytic
Jacobian. The one non-RK scheme is symplectic (semi-implicit) Euler in momentum form,
p = M(q) u: ``M(q) v = p + h G(q, v)``, ``q+ = q + h v``, ``p+ = M(q) v`` with G = dL/dq + Q
(Hairer-Lubich-Wanner, Geometric Numerical Integration, Thm. VI.3.3): symplectic for any M(q);
for constant M it reduces to ``u+ = u + h ud(q, u)``, ``q+ = q + h u+``. It needs
T = 1/2 u^T M(q) u (`cse.momentum_obstacle` says when a model does not qualify).
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
    title: str = "symplectic (semi-implicit) Euler, momentum form"

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
