"""Stage: EquationsOfMotion -> ReducedSystem (one ReducedKernel per C output function).

Fixed parameters are substituted first (so they fold), then common subexpressions are
eliminated jointly over everything one kernel outputs: the ``dynamics`` kernel, behind the C
``accel`` and ``rhs`` functions, shares temporaries between K, M and F.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import sympy as sp

from ..symbolic.derive import EquationsOfMotion

#: output name -> the kernel that computes it
OUTPUT_KERNELS = {
    "mass_matrix": "mass_matrix",
    "forcing": "forcing",
    "accel": "dynamics",
    "rhs": "dynamics",
    "energy": "energy",
    "points": "points",
    "jacobian": "jacobian",
    "momentum": "momentum",
    "constraints": "constraints",
    "multipliers": "dynamics",
}
DEFAULT_OUTPUTS = ("mass_matrix", "forcing", "accel", "rhs", "energy", "points", "jacobian")


class KernelError(ValueError):
    """Kernel request inconsistent with the equations; the message names the culprit."""


@dataclass(frozen=True)
class ReducedKernel:
    """Straight-line code for one output function.

    Attributes
    ----------
    name : str
        ``mass_matrix``, ``forcing``, ``dynamics``, ``energy`` or ``points``.
    temporaries : tuple of (Symbol, Expr)
        In evaluation order; each may use inputs and earlier temporaries.
    results : tuple of (label, Expr)
        ``label`` is (block, i, j): ("M", j, k) lower triangle, ("F", j, 0), ("K", j, 0),
        ("E", 0, 0), ("P", point, component); the jacobian kernel adds ("G", j, c) = dG_j/dx_c
        for G = M a - F (a the accelerations, `ReducedSystem.accelerations`) and ("DK", j, c).
    ops_before, ops_after : int
        ``sympy.count_ops`` of the results before CSE, and of temporaries plus results after.
    """

    name: str
    temporaries: tuple
    results: tuple
    ops_before: int
    ops_after: int

    @property
    def symbols(self) -> frozenset:
        """Free symbols the kernel reads (inputs only, temporaries excluded)."""
        found = set()
        for _, expr in self.temporaries + self.results:
            found |= expr.free_symbols
        return frozenset(found - {s for s, _ in self.temporaries})


@dataclass(frozen=True)
class ReducedSystem:
    """Everything emission needs: symbol order, parameter split and the kernels.

    ``kinematics_identity`` is True when qd = u (every Lagrange route), so the C copies u.
    ``accelerations`` are the symbols a_j standing for ud_j in the jacobian kernel.
    ``n_constraints`` is m, the number of holonomic constraints.
    ``ops_saved_by_fixing`` counts operations removed, before CSE, by folding fixed parameters.
    """

    name: str
    route: str
    t: sp.Symbol
    q: tuple
    u: tuple
    accelerations: tuple
    free_parameters: tuple
    fixed_parameters: tuple
    parameter_values: dict
    point_names: tuple
    outputs: tuple
    kernels: tuple
    kinematics_identity: bool
    ops_saved_by_fixing: int
    n_constraints: int = 0

    def kernel(self, name: str) -> ReducedKernel:
        for k in self.kernels:
            if k.name == name:
                return k
        raise KeyError(f"kernel {name!r} was not requested (outputs: {', '.join(self.outputs)})")


def reduce_expressions(eom: EquationsOfMotion, outputs=DEFAULT_OUTPUTS,
                       fixed: Mapping | None = None) -> ReducedSystem:
    """Fold ``fixed`` parameters and CSE each requested output's kernel.

    Parameters
    ----------
    eom : EquationsOfMotion
    outputs : sequence of str
        Any of ``DEFAULT_OUTPUTS``; only these are generated.
    fixed : mapping parameter (Symbol or name) -> float, optional
        Parameters folded into the code; every other parameter stays a runtime input ``p[i]``.
    """
    outputs = _checked_outputs(eom, outputs)
    fixed_values = _checked_fixed(eom, fixed or {})
    folding = {p: sp.Float(v, 17) for p, v in fixed_values}
    accelerations = tuple(sp.Dummy(f"{s.name}_dd") for s in eom.u)
    blocks = _output_blocks(eom, outputs, accelerations)
    saved = 0
    kernels = []
    for name, labelled in blocks.items():
        raw = [expr for _, expr in labelled]
        folded = [expr.xreplace(folding) if folding else expr for expr in raw]
        if folding:
            saved += sp.count_ops(raw) - sp.count_ops(folded)
        kernels.append(_reduce(name, [label for label, _ in labelled], folded))
    kinematics_identity = list(eom.kinematics) == list(eom.u)
    fixed_symbols = {p for p, _ in fixed_values}
    return ReducedSystem(
        name=eom.name, route=eom.route, t=eom.t, q=eom.q, u=eom.u, accelerations=accelerations,
        free_parameters=tuple(p for p in eom.parameters if p not in fixed_symbols),
        fixed_parameters=fixed_values, parameter_values=dict(eom.parameter_values),
        point_names=tuple(name for name, _ in eom.points),
        outputs=tuple(outputs), kernels=tuple(kernels), kinematics_identity=kinematics_identity,
        ops_saved_by_fixing=int(saved), n_constraints=eom.m)


def _checked_outputs(eom: EquationsOfMotion, outputs) -> list:
    chosen = []
    for out in outputs:
        if out not in OUTPUT_KERNELS:
            raise KernelError(f"unknown output {out!r}; choose from {', '.join(DEFAULT_OUTPUTS)}")
        if out == "energy" and eom.energy is None:
            raise KernelError(f"model {eom.name!r} has no energies (route {eom.route}); drop 'energy'")
        if out == "points" and not eom.points:
            continue  # nothing to output: the scene names no points
        if out in ("constraints", "multipliers") and not eom.m:
            raise KernelError(f"output {out!r} needs holonomic constraints; model {eom.name!r} has none")
        if out == "jacobian" and eom.m:
            raise KernelError(f"the jacobian output (implicit methods) is not available for the constrained "
                              f"model {eom.name!r} yet; use an explicit method")
        if out == "momentum" and (reason := momentum_obstacle(eom)) is not None:
            raise KernelError(f"the momentum output (symplectic Euler) does not apply to {eom.name!r}: {reason}")
        if out not in chosen:
            chosen.append(out)
    if not chosen:
        raise KernelError("no outputs requested")
    return chosen


def _checked_fixed(eom: EquationsOfMotion, fixed: Mapping) -> tuple:
    by_name = {p.name: p for p in eom.parameters}
    values = []
    for key, value in fixed.items():
        name = key.name if isinstance(key, sp.Symbol) else str(key)
        if name not in by_name:
            raise KernelError(f"cannot fix {name!r}: not a parameter of {eom.name!r} "
                              f"(parameters: {', '.join(by_name)})")
        if isinstance(value, (bool, str, bytes)):
            raise KernelError(f"fixed parameter {name!r} must be a real number, got {type(value).__name__} {value!r}")
        try:
            value = float(value)
        except (TypeError, ValueError):
            raise KernelError(f"fixed parameter {name!r} must be a real number, got "
                              f"{type(value).__name__} {value!r}") from None
        if value != value or value in (float("inf"), float("-inf")):
            raise KernelError(f"fixed parameter {name!r} has a non-finite value {value}")
        values.append((by_name[name], value))
    order = {p: i for i, p in enumerate(eom.parameters)}
    return tuple(sorted(values, key=lambda pv: order[pv[0]]))


def _output_blocks(eom: EquationsOfMotion, outputs, accelerations) -> dict:
    """kernel name -> [(label, expr)], in a fixed order."""
    n = eom.n
    M = eom.mass_matrix
    lower = [(("M", j, k), M[j, k]) for j in range(n) for k in range(j + 1)]
    forcing = [(("F", j, 0), eom.forcing[j]) for j in range(n)]
    blocks: dict = {}
    for out in outputs:
        kernel = OUTPUT_KERNELS[out]
        if kernel in blocks:
            continue
        if kernel == "mass_matrix":
            blocks[kernel] = lower
        elif kernel == "forcing":
            blocks[kernel] = forcing
        elif kernel == "dynamics":
            kin = [] if list(eom.kinematics) == list(eom.u) else \
                [(("K", j, 0), eom.kinematics[j]) for j in range(n)]
            blocks[kernel] = kin + lower + forcing + _constraint_block(eom, with_bias=True)
        elif kernel == "constraints":
            blocks[kernel] = _constraint_block(eom, with_bias=False)
        elif kernel == "energy":
            blocks[kernel] = [(("E", 0, 0), eom.energy)]
        elif kernel == "jacobian":
            blocks[kernel] = lower + _jacobian_block(eom, accelerations)
        elif kernel == "momentum":
            blocks[kernel] = lower + _momentum_block(eom)
        elif kernel == "points":
            blocks[kernel] = [(("P", i, c), pos[c]) for i, (_, pos) in enumerate(eom.points)
                              for c in range(len(pos))]
    return blocks


def _reduce(name: str, labels: list, exprs: list) -> ReducedKernel:
    before = int(sp.count_ops(exprs))
    replacements, reduced = sp.cse(exprs, symbols=sp.numbered_symbols("tmp"), order="canonical")
    after = int(sum(sp.count_ops(v) for _, v in replacements) + sp.count_ops(reduced))
    return ReducedKernel(name=name, temporaries=tuple(replacements),
                         results=tuple(zip(labels, reduced)), ops_before=before, ops_after=after)


def _jacobian_block(eom: EquationsOfMotion, a) -> list:
    """d/dx of G = M(q, t) a - F(q, u, t) (and of K when qd != u), x = (q, u).

    With a = ud the Jacobian of the first-order right-hand side is
    [[dK/dq, dK/du], [-M^-1 dG/dq, -M^-1 dG/du]] (Hairer-Wanner II, sec. VI.1 for the index-1 form).
    """
    n = eom.n
    x = list(eom.q) + list(eom.u)
    G = [sp.Add(*[eom.mass_matrix[j, k] * a[k] for k in range(n) if eom.mass_matrix[j, k] != 0]) - eom.forcing[j]
         for j in range(n)]
    rows = [(("G", j, c), _classical(G[j].diff(xc))) for j in range(n) for c, xc in enumerate(x)]
    if list(eom.kinematics) != list(eom.u):
        rows += [(("DK", j, c), _classical(eom.kinematics[j].diff(xc))) for j in range(n) for c, xc in enumerate(x)]
    return rows


def _classical(derivative):
    """Drop DiracDelta from d sign(u)/du (Coulomb, rolling friction): the Jacobian off the switch."""
    switch = lambda e: isinstance(e, sp.DiracDelta) or (  # noqa: E731
        isinstance(e, sp.Derivative) and isinstance(e.expr, sp.sign))
    if not derivative.has(sp.DiracDelta, sp.Derivative):
        return derivative
    return derivative.replace(switch, lambda e: sp.S.Zero)


def momentum_obstacle(eom: EquationsOfMotion) -> str | None:
    """Why the momentum form p = M(q) u does not describe ``eom`` (None when it does).

    Symplectic Euler in (q, p) needs T = 1/2 u^T M(q) u: no explicit t in M, no term linear in the
    speeds (moving frames, gyroscopic couplings), and qd = u.
    """
    from ..symbolic.quadratic_forms import NotQuadratic, quadratic_terms

    if eom.m:
        return "it has holonomic constraints (its multipliers are not in the momentum form)"
    if list(eom.kinematics) != list(eom.u):
        return "its generalized speeds are not the coordinate rates (qd != u)"
    if eom.t in eom.mass_matrix.free_symbols:
        return "its mass matrix depends on time"
    if eom.kinetic_energy is None:
        return "it gives no kinetic energy to check that T = 1/2 u^T M u"
    try:
        terms = quadratic_terms(eom.kinetic_energy, eom.u, eom.parameters)
    except NotQuadratic:
        return "its kinetic energy is not quadratic in the speeds"
    linear = sp.Add(*[w * e for key, w, e in terms if len(key) == 1])
    if linear != 0:
        return "its kinetic energy has terms linear in the speeds (p != M u)"
    return None


def _momentum_block(eom: EquationsOfMotion) -> list:
    """G = dL/dq + Q = F + sum_kl dM_jl/dq_k u_k u_l (for T = 1/2 u^T M(q) u, p = M u)."""
    n, q, u = eom.n, eom.q, eom.u
    M = eom.mass_matrix
    rows = []
    for j in range(n):
        transport = [M[j, l].diff(q[k]) * u[k] * u[l]
                     for l in range(n) if M[j, l] != 0 for k in range(n) if q[k] in M[j, l].free_symbols]
        rows.append((("G", j, 0), eom.forcing[j] + sp.Add(*transport)))
    return rows


def _constraint_block(eom: EquationsOfMotion, with_bias: bool) -> list:
    """("A", i, j) = dphi_i/dq_j and then ("C", i, 0) = gamma_i (dynamics) or ("R", i, 0) = phi_i,
    ("T", i, 0) = dphi_i/dt (residuals and projection)."""
    m, n = eom.m, eom.n
    rows = [(("A", i, j), eom.constraint_jacobian[i, j]) for i in range(m) for j in range(n)]
    if with_bias:
        return rows + [(("C", i, 0), eom.constraint_bias[i]) for i in range(m)]
    return rows + [(("R", i, 0), eom.constraints[i]) for i in range(m)] + \
        [(("T", i, 0), eom.constraint_rate[i]) for i in range(m)]
