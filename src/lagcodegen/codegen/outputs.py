"""Helper: the output registry. Every C output function is one `Output` entry here: the reduced
kernel that computes it (its symbolic rows, CSE'd together), when it applies to a model, and how
its C body is written. `reduce.py` and `render.py` read these tables; nothing else switches on an
output's name. A new output is one kernel (if it needs new rows), one writer and one entry.

Labels of the rows are (block, i, j): ("M", j, k) lower triangle of M, ("F", j, 0), ("K", j, 0),
("E", 0, 0), ("P", point, component); ("G", j, c) = dG_j/dx_c for G = M a - F (a the
accelerations) and ("DK", j, c) in the jacobian kernel; ("G", j, 0) = dL/dq_j + Q_j in the
momentum kernel; ("A", i, j) = dphi_i/dq_j, ("C", i, 0) = gamma_i, ("R", i, 0) = phi_i and
("T", i, 0) = dphi_i/dt for the constraints.
"""
from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..symbolic.differentiation import derivative
from ..symbolic.equations import EquationsOfMotion
from ..symbolic.trees import PIVOT_ROUNDING
from .csyntax import PROJECTION_STALL, UNIT_ROUNDOFF, comment_text, literal, record
from .kernel_text import KernelWriter, kernel_parts, results
from .ldlt import ldlt_factor_lines, ldlt_substitution_lines
from .lu import UNROLLED_LU_MAX, lu_factor_lines, lu_substitute_lines
from .steppers import hot_dynamics, shared_dynamics


class KernelError(ValueError):
    """Kernel request inconsistent with the equations; the message names the culprit."""


# -- symbolic rows, one function per reduced kernel ----------------------------------------------
def _mass_rows(eom: EquationsOfMotion) -> list:
    M = eom.mass_matrix
    return [(("M", j, k), M[j, k]) for j in range(eom.n_u) for k in range(j + 1)]


def _forcing_rows(eom: EquationsOfMotion) -> list:
    return [(("F", j, 0), eom.forcing[j]) for j in range(eom.n_u)]


def _dynamics_rows(eom: EquationsOfMotion, accelerations) -> list:
    kinematics = [] if list(eom.kinematics) == list(eom.u) and not eom.n_dependent else \
        [(("K", j, 0), eom.kinematics[j]) for j in range(eom.n_q)]
    rows = kinematics + _mass_rows(eom) + _forcing_rows(eom) + _constraint_rows(eom, with_bias=True)
    if eom.n_dependent:  # the dependent speeds are solved inside the kernel, sharing A's temporaries
        A, u, p = eom.constraint_jacobian, eom.u, eom.n_u - eom.n_dependent
        rows += [(("BI", i, 0), sp.Add(*[A[i, k] * u[k] for k in range(p)]) + eom.constraint_rate[i])
                 for i in range(eom.m)]
    return rows


def _constraint_rows(eom: EquationsOfMotion, with_bias: bool) -> list:
    """("A", i, j) = dphi_i/dq_j and then ("C", i, 0) = gamma_i (dynamics) or ("R", i, 0) = phi_i,
    ("T", i, 0) = dphi_i/dt (residuals and projection)."""
    m, n = eom.m, eom.constraint_jacobian.cols
    rows = [(("A", i, j), eom.constraint_jacobian[i, j]) for i in range(m) for j in range(n)]
    if with_bias:
        return rows + [(("C", i, 0), eom.constraint_bias[i]) for i in range(m)]
    return rows + [(("R", i, 0), eom.constraints[i]) for i in range(m)] + \
        [(("T", i, 0), eom.constraint_rate[i]) for i in range(m)]


def _dependent_rows(eom: EquationsOfMotion) -> list:
    """("AD", i, j) = A[i, p + j], the constraint Jacobian in the dependent speeds, ("BI", i, 0)
    = the rest of the row, sum_k<p A[i, k] u_k + b_i (p independent speeds): A_D u_dep = -BI; and
    ("AI", i, k) = A[i, k], k < p, the scale of the rank test (`_dependent_system_lines`)."""
    A, u, p = eom.constraint_jacobian, eom.u, eom.n_u - eom.n_dependent
    rows = _constraint_blocks(eom)
    return rows + [(("BI", i, 0), sp.Add(*[A[i, k] * u[k] for k in range(p)]) + eom.constraint_rate[i])
                   for i in range(eom.m)]


def _constraint_blocks(eom: EquationsOfMotion) -> list:
    """("AD", i, j) = A[i, p + j] and ("AI", i, k) = A[i, k]: the constraint Jacobian's dependent and
    independent columns (p independent speeds)."""
    A, p = eom.constraint_jacobian, eom.n_u - eom.n_dependent
    return [(("AD", i, j), A[i, p + j]) for i in range(eom.m) for j in range(eom.n_dependent)] + \
        [(("AI", i, k), A[i, k]) for i in range(eom.m) for k in range(p)]


def _dependent_acceleration_rows(eom: EquationsOfMotion, a) -> list:
    """("AD", i, j) = A[i, p + j] and ("GB", i, 0) = sum_k<p A[i, k] a_k - gamma_i: the dependent
    accelerations solve A_D ud_dep = -GB (A ud = gamma differentiated from the constraints)."""
    A, p = eom.constraint_jacobian, eom.n_u - eom.n_dependent
    rows = _constraint_blocks(eom)
    return rows + [(("GB", i, 0), sp.Add(*[A[i, k] * a[k] for k in range(p)]) - eom.constraint_bias[i])
                   for i in range(eom.m)]


def _reaction_rows(eom: EquationsOfMotion, a) -> list:
    """("RJ", i, j) = d(aux_i)/dR_j and ("RB", i, 0) = aux_i at R = 0 of Kane's auxiliary equations,
    accelerations as the symbols ``a``: the reactions solve RJ R = -RB."""
    rows = [e.xreplace(dict(zip(eom.reaction_accelerations, a))) for e in eom.reaction_equations]
    zero = dict.fromkeys(eom.reactions, 0)
    return [(("RJ", i, j), row.diff(force)) for i, row in enumerate(rows) for j, force in enumerate(eom.reactions)] + \
        [(("RB", i, 0), row.xreplace(zero)) for i, row in enumerate(rows)]


def _configuration_rows(eom: EquationsOfMotion) -> list:
    """("H", i, 0) = f_i(q, t), Kane's configuration constraints, and ("HJ", i, j) = df_i/dq_d(j)
    for the dependent coordinates d: the Newton steps of the projection."""
    f, q, dependent, memo = eom.configuration, eom.q, eom.dependent_coordinates, {}
    return [(("H", i, 0), f[i]) for i in range(f.rows)] + \
        [(("HJ", i, j), derivative(f[i], q[d], memo)) for i in range(f.rows) for j, d in enumerate(dependent)]


def _jacobian_rows(eom: EquationsOfMotion, a) -> list:
    """M, then d/dx of G = M(q, t) a - F(q, u, r, t) (and of K when qd != u), x = (q, u), and
    d/dr of both (labels GR, DKR) when the model has inputs r.

    With a = ud the Jacobian of the first-order right-hand side is
    [[dK/dq, dK/du], [-M^-1 dG/dq, -M^-1 dG/du]] (Hairer-Wanner II, sec. VI.1 for the index-1 form).
    """
    n_q, n_u = eom.n_q, eom.n_u
    x = list(eom.q) + list(eom.u)
    G = [sp.Add(*[eom.mass_matrix[j, k] * a[k] for k in range(n_u) if eom.mass_matrix[j, k] != 0]) - eom.forcing[j]
         for j in range(n_u)]
    memo: dict = {}
    d = lambda expr, symbol: _classical(derivative(expr, symbol, memo))  # noqa: E731
    rows = [(("G", j, c), d(G[j], xc)) for j in range(n_u) for c, xc in enumerate(x)]
    rows += [(("GR", j, c), d(G[j], rc)) for j in range(n_u) for c, rc in enumerate(eom.inputs)]
    if list(eom.kinematics) != list(eom.u):
        rows += [(("DK", j, c), d(eom.kinematics[j], xc)) for j in range(n_q) for c, xc in enumerate(x)]
        rows += [(("DKR", j, c), d(eom.kinematics[j], rc)) for j in range(n_q) for c, rc in enumerate(eom.inputs)]
    return _mass_rows(eom) + rows


def _classical(derivative):
    """Drop DiracDelta from d sign(u)/du (Coulomb, rolling friction): the Jacobian off the switch."""
    switch = lambda e: isinstance(e, sp.DiracDelta) or (  # noqa: E731
        isinstance(e, sp.Derivative) and isinstance(e.expr, sp.sign))
    if not derivative.has(sp.DiracDelta, sp.Derivative):
        return derivative
    return derivative.replace(switch, lambda e: sp.S.Zero)


def _momentum_rows(eom: EquationsOfMotion) -> list:
    """M, then G = dL/dq + Q = F + sum_kl dM_jl/dq_k u_k u_l (for T = 1/2 u^T M(q) u, p = M u)."""
    n, q, u = eom.n, eom.q, eom.u
    M = eom.mass_matrix
    rows = []
    for j in range(n):
        transport = [M[j, l].diff(q[k]) * u[k] * u[l]
                     for l in range(n) if M[j, l] != 0 for k in range(n) if q[k] in M[j, l].free_symbols]
        rows.append((("G", j, 0), eom.forcing[j] + sp.Add(*transport)))
    return _mass_rows(eom) + rows


def _point_rows(eom: EquationsOfMotion) -> list:
    return [(("P", i, c), pos[c]) for i, (_, pos) in enumerate(eom.points) for c in range(len(pos))]


#: reduced kernel -> its rows (eom, acceleration symbols); the outputs sharing a kernel share its CSE
KERNEL_ROWS: dict[str, Callable] = {
    "mass_matrix": lambda eom, a: _mass_rows(eom),
    "forcing": lambda eom, a: _forcing_rows(eom),
    "dynamics": lambda eom, a: _dynamics_rows(eom, a),
    "constraints": lambda eom, a: _constraint_rows(eom, with_bias=False),
    "energy": lambda eom, a: [(("E", 0, 0), eom.energy)],
    "jacobian": _jacobian_rows,
    "momentum": lambda eom, a: _momentum_rows(eom),
    "points": lambda eom, a: _point_rows(eom),
    "measurements": lambda eom, a: [(("Y", i, 0), y) for i, (_, y) in enumerate(eom.measurements)],
    "dependent": lambda eom, a: _dependent_rows(eom),
    "dependent_accelerations": _dependent_acceleration_rows,
    "configuration": lambda eom, a: _configuration_rows(eom),
    "reactions": _reaction_rows,
}


# -- when an output applies ----------------------------------------------------------------------
def momentum_obstacle(eom: EquationsOfMotion) -> str | None:
    """Why the momentum form p = M(q) u does not describe ``eom`` (None when it does).

    Symplectic Euler in (q, p) needs T = 1/2 u^T M(q) u: no explicit t in M, no term linear in the
    speeds (moving frames, gyroscopic couplings), and qd = u.
    """
    from ..symbolic.quadratic_forms import NotQuadratic, quadratic_terms

    if eom.n_holonomic:
        return "it has holonomic constraints (its multipliers are not in the momentum form)"
    if eom.m:  # found by review: a sleigh was said to have holonomic constraints
        return "it has velocity constraints (its multipliers or dependent speeds are not in the momentum form)"
    if eom.tree is not None:
        return "its recursive formulation forms no mass matrix"
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


def _energy_obstacle(eom: EquationsOfMotion) -> str | None:
    if eom.energy is None and eom.tree is None:
        return f"model {eom.name!r} has no energies (route {eom.route}); drop 'energy'"
    energy = eom.tree.energy if eom.tree is not None else eom.energy  # a recursive tree's is its own
    driving = sorted(set(eom.inputs) & energy.free_symbols, key=str) if energy is not None else []
    if driving:  # E(q, u, r): no conserved quantity to track, and the kernel E(t, x, p) cannot read r
        return (f"the energy of model {eom.name!r} holds the input(s) {', '.join(map(str, driving))} (an input in "
                "the potential energy); drop 'energy'")
    return None


def _needs_constraints(output: str) -> Callable[[EquationsOfMotion], str | None]:
    def obstacle(eom: EquationsOfMotion) -> str | None:
        if eom.n_dependent:
            return (f"output {output!r} needs constraints with multipliers; model {eom.name!r} eliminates its "
                    "dependent speeds (Model(..., formulation='multipliers') keeps them)")
        return None if eom.m else (f"output {output!r} needs constraints (holonomic or on the velocities); "
                                   f"model {eom.name!r} has none")
    return obstacle


def _jacobian_obstacle(eom: EquationsOfMotion) -> str | None:
    if eom.n_dependent:
        return (f"the jacobian output (implicit methods) is not available for {eom.name!r}, whose dependent "
                "speeds are eliminated, yet; use an explicit method")
    if eom.m:
        return (f"the jacobian output (implicit methods) is not available for the constrained model "
                f"{eom.name!r} yet; use an explicit method")
    return None


def _closed_form_obstacle(output: str) -> Callable[[EquationsOfMotion], str | None]:
    def obstacle(eom: EquationsOfMotion) -> str | None:
        if eom.tree is None:
            return None
        return (f"output {output!r} needs the closed-form M and F, which the recursive formulation of "
                f"{eom.name!r} does not form; Model(..., formulation='closed') forms them")
    return obstacle


def _step_jacobian_obstacle(eom: EquationsOfMotion) -> str | None:
    if eom.tree is not None:
        return _closed_form_obstacle("step_jacobian")(eom)
    if eom.m:
        return (f"the step_jacobian output (dx+/dx, dx+/dr of the explicit steps) is not available for the "
                f"constrained model {eom.name!r}")
    return None


def _momentum_obstacle_message(eom: EquationsOfMotion) -> str | None:
    reason = momentum_obstacle(eom)
    if reason is None:
        return None
    return f"the momentum output (symplectic Euler) does not apply to {eom.name!r}: {reason}"


# -- C bodies, one writer per output --------------------------------------------------------------
def _mass_matrix_c(w: KernelWriter, kernel) -> dict:
    n = w.n_m
    body = w.head(kernel) + ["/* Mass matrix, lower triangle, mirrored */"]
    for (j, k), expr in results(kernel, "M").items():
        body.append(f"M[{j * n + k}] = {w.expr(expr, f'M[{j}][{k}]')};  /* M[{j}][{k}] */")
        if j != k:
            body.append(f"M[{k * n + j}] = M[{j * n + k}];  /* M[{k}][{j}] */")
    return record("void", f"{w.prefix}_mass_matrix", f"{w.arguments}, {w.real} *M",
                  f"Mass matrix M(q, t), row-major {n} x {n}.", body)


def _forcing_c(w: KernelWriter, kernel) -> dict:
    body = w.head(kernel, reads_inputs=True) + ["/* Forcing */"]
    for (j, _), expr in results(kernel, "F").items():
        body.append(f"F[{j}] = {w.expr(expr, f'F[{j}]')};")
    what = "F(q, u, r, t)" if w.n_inputs else "F(q, u, t)"
    return record("void", f"{w.prefix}_forcing", f"{w.driven_arguments}, {w.real} *F",
                  f"Forcing {what}, {w.n_m} values.", body)


def _accelerations_solve(w: KernelWriter) -> str:
    """Which equations ud solves, for the docs (found by review: a constrained model's said M ud = F)."""
    if w.system.u_dependent:
        return ("Kane's reduced equations of the independent speeds, the dependent ones eliminated by the "
                "velocity constraints")
    if w.system.n_constraints:
        return ("M ud = F - A^T lam with the constraints at acceleration level, A ud = gamma (Lagrange's "
                "equations of the first kind; gamma holds Baumgarte's terms when alpha or beta is set)")
    return "M ud = F"


def _accel_c(w: KernelWriter, kernel) -> dict:
    prefix = w.prefix
    body = [f"{w.real} qd[{w.n_q}];",
            f"return {prefix}_finite_result({prefix}_dynamics(t, x, {w.rp}, qd, ud, 0), ud, {w.n_u});"]
    return record("int", f"{prefix}_accel", f"{w.driven_arguments}, {w.real} *ud",
                  f"Generalized accelerations ud solving {_accelerations_solve(w)}; returns a status code.", body)


def _rhs_c(w: KernelWriter, kernel) -> dict:
    prefix, size = w.prefix, w.n_state
    body = [f"return {prefix}_finite_result({prefix}_dynamics(t, x, {w.rp}, xdot, xdot + {w.n_q}, 0), xdot, {size});"]
    what = "f(t, x, r)" if w.n_inputs else "f(t, x)"
    return record("int", f"{prefix}_rhs", f"{w.driven_arguments}, {w.real} *xdot",
                  f"First-order right-hand side xdot = {what}, x = (q, u), {size} values, ud solving "
                  f"{_accelerations_solve(w)}; returns a status code. xdot must not alias x.", body)


def _energy_c(w: KernelWriter, kernel) -> dict:
    body = kernel_parts(w, kernel, "energy", driven=False)[1] if w.system.recursive else w.head(kernel)
    body.append(f"return {w.expr(results(kernel, 'E')[(0, 0)], 'energy')};")
    return record(w.real, f"{w.prefix}_energy", w.arguments, "Total mechanical energy T + V.", body)


def _points_c(w: KernelWriter, kernel) -> dict:
    names = w.system.point_names
    body = kernel_parts(w, kernel, "points", driven=False)[1] if w.system.recursive else w.head(kernel)
    body.append("/* Point positions (x, y, z) */")
    for (i, c), expr in results(kernel, "P").items():
        body.append(f"out[{3 * i + c}] = {w.expr(expr, f'point {names[i]}')};  "
                    f"/* {comment_text(names[i])}.{'xyz'[c]} */")
    return record("void", f"{w.prefix}_points", f"{w.arguments}, {w.real} *out",
                  f"Positions of {len(names)} named points, 3 values each.", body)


def _measurements_c(w: KernelWriter, kernel) -> dict:
    names = w.system.measurements
    body = w.head(kernel, reads_inputs=True) + ["/* Measurements y = h(q, u, r, t) */"]
    for (i, _), expr in results(kernel, "Y").items():
        body.append(f"y[{i}] = {w.expr(expr, f'measurement {names[i]}')};  /* {comment_text(names[i])} */")
    return record("void", f"{w.prefix}_measurements", f"{w.driven_arguments}, {w.real} *y",
                  f"Measurements y ({len(names)} values): {', '.join(comment_text(n) for n in names)}.", body)


def _jacobian_c(w: KernelWriter, kernel) -> dict:
    """J = df/dx of the first-order system: [[dK/dq, dK/du], [-M^-1 dG/dq, -M^-1 dG/du]]."""
    if w.system.recursive:
        return _difference_jacobian_c(w)
    n_q, n, prefix, real = w.n_q, w.n_u, w.prefix, w.real
    size = w.n_state
    body = [f"{real} qd[{n_q}];", f"{real} ud[{n}];", f"{real} B[{n}][{size}];", "int c;",
            f"const int status = {prefix}_dynamics(t, x, {w.rp}, qd, ud, 0);",
            "if (status != LCG_OK) return status;"]
    n_r = w.n_inputs
    if n_r:
        body.insert(3, f"{real} Br[{n}][{n_r}];")
    body += w.head(kernel, touches_state=True, reads_inputs=True)
    M = results(kernel, "M")
    body.append("/* Mass matrix, lower triangle */")
    for (j, k), expr in M.items():
        if expr != 0 or j == k:
            body.append(f"const {real} M_{j}_{k} = {w.expr(expr, f'M[{j}][{k}]')};")
    body.append("/* B = -dG/dx, G = M ud - F */")
    for (j, c), expr in results(kernel, "G").items():
        value = f"-({w.expr(expr, f'dG[{j}]/dx[{c}]')})" if expr != 0 else literal(0, real)
        body.append(f"B[{j}][{c}] = {value};")
    if n_r:
        body.append("/* Br = -dG/dr */")
        for (j, c), expr in results(kernel, "GR").items():
            value = f"-({w.expr(expr, f'dG[{j}]/dr[{c}]')})" if expr != 0 else literal(0, real)
            body.append(f"Br[{j}][{c}] = {value};")
    body.append("/* Kinematic rows dK/dx */")
    DK = results(kernel, "DK")
    for j in range(n_q):
        for c in range(size):
            if DK:
                value = w.expr(DK[(j, c)], f"dK[{j}]/dx[{c}]")
            else:
                value = literal(1 if c == n_q + j else 0, real)
            body.append(f"J[{j * size + c}] = {value};")
    factor, LD = ldlt_factor_lines(n, {jk for jk, e in M.items() if e != 0}, real, f"{prefix}_pivot_failure(x)")
    body += factor
    body.append(f"for (c = 0; c < {size}; ++c) {{")
    solve = ldlt_substitution_lines(n, LD, real, lambda i: f"B[{i}][c]",
                                    lambda i: f"J[{(n_q + i) * size} + c]")
    body += ["    " + line for line in solve]
    body.append("}")
    arguments, doc = f"{w.driven_arguments}, {real} *J", ""
    if n_r:
        DKR = results(kernel, "DKR")
        body += ["if (Jr) {  /* df/dr: dK/dr, then M^-1 dF/dr */"]
        body += [f"    Jr[{j * n_r + c}] = {w.expr(DKR[(j, c)], f'dK[{j}]/dr[{c}]') if DKR else literal(0, real)};"
                 for j in range(n_q) for c in range(n_r)]
        body.append(f"    for (c = 0; c < {n_r}; ++c) {{")
        solve = ldlt_substitution_lines(n, LD, real, lambda i: f"Br[{i}][c]", lambda i: f"Jr[{(n_q + i) * n_r} + c]")
        body += ["        " + line for line in solve]
        body += ["    }", f"    c = {prefix}_finite_result(LCG_OK, Jr, {size * n_r});",
                 "    if (c != LCG_OK) return c;", "}"]
        arguments += f", {real} *Jr"
        doc = f"; Jr (or NULL) receives df/dr, row-major {size} x {n_r}"
    body.append(f"return {prefix}_finite_result(LCG_OK, J, {size * size});")
    return record("int", f"{prefix}_jacobian", arguments,
                  f"Jacobian df/dx of the first-order right-hand side, row-major {size} x {size}{doc}; "
                  "returns a status code.", body)


def _difference_jacobian_c(w: KernelWriter) -> dict:
    """J = df/dx (and df/dr) by central differences of the dynamics, column by column: 2 N
    evaluations of the recursive kernel instead of a symbolic Jacobian (O(n^2) code) of a big
    tree. Step h_c = eps^(1/3) max(1, |x_c|), or eps^(1/3) for a coordinate that moves revolute
    joints only (f varies with an angle on a scale of a radian at any angle: a step growing with
    it gave errors of 1.6e-6 at 100 rad, 1.5e-2 at 1e4, found by review); error h^2/6 |f^(3)| +
    eps |f| / h, about eps^(2/3) (4e-11 in double, 2e-5 in float) relative to the scale of f and its
    third derivative (for an angle plus eps |x_c| / h, the rounding of x_c + h)."""
    prefix, real, size, n_q = w.prefix, w.real, w.n_state, w.n_q
    fabs = "fabsf" if real == "float" else "fabs"
    relative = literal(float(np.cbrt(np.finfo(np.float32 if real == "float" else np.float64).eps)), real)
    one = literal(1, real)
    angles = w.system.angle_coordinates

    def columns(vector: str, count: int, out: str, args: str) -> list:
        if vector == "xs" and any(angles):
            flags = ", ".join("1" if a else "0" for a in angles) + ", 0" * (count - len(angles))
            scale = f"(angle[c] || {fabs}(saved) <= {one} ? {one} : {fabs}(saved))"
            lead = [f"static const int angle[{count}] = {{{flags}}};  /* columns of coordinates of revolute joints */"]
        else:
            scale, lead = f"({fabs}(saved) > {one} ? {fabs}(saved) : {one})", []
        return lead + [f"for (c = 0; c < {count}; ++c) {{",
                f"    const {real} saved = {vector}[c];",
                f"    const {real} h = {relative} * {scale};  /* eps^(1/3) */",
                f"    {real} width;",
                f"    {vector}[c] = saved + h;",
                f"    status = {prefix}_dynamics({args}, fp, fp + {n_q}, 0);",
                f"    width = {vector}[c];",
                f"    {vector}[c] = saved - h;",
                f"    if (status == LCG_OK) status = {prefix}_dynamics({args}, fm, fm + {n_q}, 0);",
                f"    width -= {vector}[c];  /* the step as represented */",
                f"    {vector}[c] = saved;",
                "    if (status != LCG_OK) return status;",
                f"    for (i = 0; i < {size}; ++i) {out}[i * {count} + c] = (fp[i] - fm[i]) / width;",
                "}"]
    body = [f"{real} xs[{size}], fp[{size}], fm[{size}];", "int c, i, status;",
            f"for (i = 0; i < {size}; ++i) xs[i] = x[i];"]
    n_r = w.n_inputs
    if n_r:
        body.insert(1, f"{real} rs[{n_r}];")
        body.append(f"for (i = 0; i < {n_r}; ++i) rs[i] = r[i];")
    body += columns("xs", size, "J", f"t, xs, {'r, ' if n_r else ''}p")
    arguments, doc = f"{w.driven_arguments}, {real} *J", ""
    if n_r:
        body.append("if (Jr) {  /* df/dr */")
        body += ["    " + line for line in columns("rs", n_r, "Jr", "t, x, rs, p")]
        body += [f"    status = {prefix}_finite_result(LCG_OK, Jr, {size * n_r});",
                 "    if (status != LCG_OK) return status;", "}"]
        arguments += f", {real} *Jr"
        doc = f"; Jr (or NULL) receives df/dr, row-major {size} x {n_r}"
    body.append(f"return {prefix}_finite_result(LCG_OK, J, {size * size});")
    return record("int", f"{prefix}_jacobian", arguments,
                  f"Jacobian df/dx of the first-order right-hand side, row-major {size} x {size}, by central "
                  f"differences of the recursive dynamics (relative error about eps^(2/3)){doc}; returns a "
                  "status code.", body)


def _dependent_speeds_c(w: KernelWriter, kernel) -> dict:
    """u_dep from A_D u_dep = -(A_I u + b), by LU with partial pivoting (`_dense_lu_functions`)."""
    m, real, prefix = w.n_dependent, w.real, w.prefix
    names = ", ".join(s.name for s in w.system.u_dependent)
    body = w.head(kernel) + _dependent_system_lines(w, kernel, "BI")
    body += [f"if ({prefix}_dense_solve(AD, b, {m}, 1, scale, 0)) {{",
             f"    for (i = 0; i < {m}; ++i) u_dep[i] = b[i];",
             f"    return {prefix}_finite_result(LCG_OK, u_dep, {m});",
             "}",
             f"for (i = 0; i < {m}; ++i) u_dep[i] = {literal(0, real)} / {literal(0, real)};",
             "return LCG_SINGULAR_CONSTRAINTS;"]
    return record("int", f"{prefix}_dependent_speeds", f"{w.arguments}, {real} *u_dep",
                  f"The {m} dependent speeds ({names}) from the velocity constraints A u + b = 0; returns a "
                  "status code (LCG_SINGULAR_CONSTRAINTS, and NaN values, when the constraint Jacobian in "
                  "them is singular).", body)


def _dependent_system_lines(w: KernelWriter, kernel, rest: str) -> list:
    """AD (the constraint Jacobian in the dependent speeds, m x m) and b = -(the ``rest`` rows): the
    system A_D v = b that the dependent speeds and their accelerations both solve."""
    m, real = w.n_dependent, w.real
    fabs = "fabsf" if real == "float" else "fabs"
    lines = [f"{real} AD[{m * m}], b[{m}], scale = {literal(0, real)};", "int i;", "/* A_D and the right-hand side */"]
    lines += [f"AD[{i * m + j}] = {w.expr(e, f'A_D[{i}][{j}]')};" for (i, j), e in results(kernel, "AD").items()]
    lines += [f"b[{i}] = -({w.expr(e, f'row {i}')});" for (i, _), e in results(kernel, rest).items()]
    # the rank test is relative to the whole constraint Jacobian: A_D's own largest entry would
    # make a 1 x 1 A_D (cos(theta) of a sleigh) regular until it is exactly 0
    lines.append("/* the scale of the rank test: the largest |entry| of the independent columns of A */")
    entries = [(i, k, e) for (i, k), e in results(kernel, "AI").items() if e != 0]
    if entries:
        lines.append(f"{real} entry;")
    for i, k, e in entries:
        lines += [f"entry = {fabs}({w.expr(e, f'A[{i}][{k}]')});", "if (entry > scale) scale = entry;"]
    return lines


def _dependent_accelerations_c(w: KernelWriter, kernel) -> dict:
    m, p, real, prefix = w.n_dependent, w.n_u, w.real, w.prefix
    body = w.head(kernel, on_singular="return dep_status;") + _dependent_system_lines(w, kernel, "GB")
    body += [f"if (!{prefix}_dense_solve(AD, b, {m}, 1, scale, 0)) return LCG_SINGULAR_CONSTRAINTS;",
             f"for (i = 0; i < {m}; ++i) ud[{p} + i] = b[i];",
             f"return {prefix}_finite_result(LCG_OK, ud, {p + m});"]
    return record("int", f"{prefix}_dependent_accelerations", f"{w.arguments}, {real} *ud",
                  f"Given the {p} independent accelerations in ud[0..{p - 1}], the {m} dependent ones into "
                  f"ud[{p}..{p + m - 1}] (the velocity constraints differentiated); returns a status code.", body)


def _reactions_c(w: KernelWriter, kernel) -> dict:
    """Kane's auxiliary equations solved for the unknown forces at the accelerations of (t, x)."""
    forces, real, prefix = w.system.reactions, w.real, w.prefix
    k = len(forces)
    body = [f"{real} ud[{w.n_m}];", f"int status = {prefix}_accel(t, x, {w.rp}, ud);",
            "if (status != LCG_OK) return status;"]
    if w.n_dependent:
        body += [f"status = {prefix}_dependent_accelerations(t, x, p, ud);", "if (status != LCG_OK) return status;"]
    body += w.head(kernel, touches_state=True, reads_inputs=True, on_singular="return dep_status;")
    body += [f"{real} RJ[{k * k}];", "/* RJ R = -RB: the auxiliary equations, linear in the forces */"]
    body += [f"RJ[{i * k + j}] = {w.expr(e, f'd aux[{i}]/d {forces[j]}')};"
             for (i, j), e in results(kernel, "RJ").items()]
    body += [f"out[{i}] = -({w.expr(e, f'aux[{i}]')});" for (i, _), e in results(kernel, "RB").items()]
    body += [f"if (!{prefix}_dense_solve(RJ, out, {k}, 1, {literal(0, real)}, 0)) return LCG_SINGULAR_CONSTRAINTS;",
             f"return {prefix}_finite_result(LCG_OK, out, {k});"]
    names = ", ".join(s.name for s in forces)
    return record("int", f"{prefix}_reactions", f"{w.driven_arguments}, {real} *out",
                  f"The {k} constraint forces Kane's auxiliary speeds expose ({names}) at (t, x), from the "
                  "auxiliary equations at the accelerations there; returns a status code.", body)


def _configuration_project_c(w: KernelWriter, kernel) -> dict:
    """Newton on Kane's configuration constraints in the dependent coordinates, the others held."""
    real, prefix = w.real, w.prefix
    dependent = w.system.dependent_coordinates
    k = len(dependent)
    tolerance = literal(1e-12 if real == "double" else 1e-6, real)
    fabs = "fabsf" if real == "float" else "fabs"
    stall = literal(PROJECTION_STALL * UNIT_ROUNDOFF[real], real)
    # converged at |H| <= tolerance, or at a Newton step within PROJECTION_STALL units of rounding of
    # the dependent coordinates (H of large terms cannot reach an absolute tolerance; found by review)
    body = [f"{real} H[{k}], HJ[{k * k}];", "int i, iteration, stalled = 0;",
            "for (iteration = 0; iteration <= 10; ++iteration) {",
            f"    {real} size = {literal(0, real)}, moved = {literal(0, real)}, magnitude = {literal(0, real)};",
            f"    {prefix}_configuration_terms(t, x, p, H, HJ);",
            f"    for (i = 0; i < {k}; ++i) {{",
            f"        if ({fabs}(H[i]) > size || isnan(H[i])) size = {fabs}(H[i]);  /* NaN kept */",
            "    }",
            "    if (!isfinite(size)) return LCG_NONFINITE_STATE;",
            f"    if (size <= {tolerance} || stalled) return LCG_OK;",
            "    if (iteration == 10) return LCG_NEWTON_FAILED;",
            f"    if (!{prefix}_dense_solve(HJ, H, {k}, 1, {literal(0, w.real)}, 0)) return LCG_SINGULAR_CONSTRAINTS;"]
    body += [f"    x[{d}] -= H[{j}];" for j, d in enumerate(dependent)]
    body += [f"    if ({fabs}(H[{j}]) > moved) moved = {fabs}(H[{j}]);" for j in range(k)]
    body += [f"    if ({fabs}(x[{d}]) > magnitude) magnitude = {fabs}(x[{d}]);" for d in dependent]
    body += [f"    stalled = moved <= {stall} * magnitude;", "}", "return LCG_NEWTON_FAILED;"]
    names = ", ".join(w.system.q[d].name for d in dependent)
    return record("int", f"{prefix}_project", f"{real} t, {real} *x, const {real} *p",
                  f"Project x onto Kane's configuration constraints: Newton in the dependent coordinates ({names}), "
                  "the others held (at most 10 steps, to rank_tolerance); returns a status code.", body)


def _configuration_terms_function(w: KernelWriter) -> dict:
    kernel = w.system.kernel("configuration")
    k = len(w.system.dependent_coordinates)
    body = w.head(kernel) + [f"H[{i}] = {w.expr(e, f'f[{i}]')};" for (i, _), e in results(kernel, "H").items()]
    body += [f"HJ[{i * k + j}] = {w.expr(e, f'df[{i}]/dq_dep[{j}]')};" for (i, j), e in results(kernel, "HJ").items()]
    return record("void", f"{w.prefix}_configuration_terms",
                  f"{w.arguments}, {w.real} *H, {w.real} *HJ",
                  "Kane's configuration constraints f(q, t) and their Jacobian in the dependent coordinates.",
                  body, static=True)


def _configuration_obstacle(eom: EquationsOfMotion) -> str | None:
    if eom.n_dependent or not eom.m:
        return None
    return (f"the configuration projection of {eom.name!r} is not available with multipliers (its constraints "
            "have their own projection)")


def _multipliers_c(w: KernelWriter, kernel) -> dict:
    n, prefix, real, m = w.n_u, w.prefix, w.real, w.system.n_constraints
    body = [f"{real} qd[{w.n_q}], ud[{n}];",
            f"const int status = {prefix}_dynamics_constrained(t, x, {w.rp}, qd, ud, lam, Q, 0);",
            f"return {prefix}_finite_result(status, lam, {m});"]
    return record("int", f"{prefix}_multipliers", f"{w.driven_arguments}, {real} *lam, {real} *Q",
                  f"Multipliers lam ({m}) and generalized constraint forces "
                  f"Q = A^T lam ({n}, or NULL): M ud = F - A^T lam.", body)


def _constraints_c(w: KernelWriter, kernel) -> dict:
    n, m, real = w.n_u, w.system.n_constraints, w.real
    body = w.head(kernel) + ["/* phi, A = dphi/dq, dphi/dt */"]
    body += [f"phi[{i}] = {w.expr(e, f'phi[{i}]')};" for (i, _), e in results(kernel, "R").items()]
    body += [f"A[{i * n + j}] = {w.expr(e, f'dphi[{i}]/dq[{j}]')};" for (i, j), e in results(kernel, "A").items()]
    body += [f"phi_t[{i}] = {w.expr(e, f'dphi[{i}]/dt')};" for (i, _), e in results(kernel, "T").items()]
    return record("void", f"{w.prefix}_constraint_terms", f"{w.arguments}, {real} *phi, {real} *A, {real} *phi_t",
                  f"Constraints phi ({m}), their Jacobian A = dphi/dq (row-major {m} x {n}) and dphi/dt ({m}).",
                  body)


def _constraints_template_functions(w: KernelWriter) -> list:
    """Prototypes of the residual and projection functions the templates write from the constraint terms."""
    real, m = w.real, w.system.n_constraints
    return [record("void", f"{w.prefix}_residuals", f"{real} t, const {real} *x, const {real} *p, {real} *out",
                   f"Constraint residuals: phi ({m}), then A u + dphi/dt ({m}).", []),
            record("int", f"{w.prefix}_project", f"{real} t, {real} *x, const {real} *p",
                   "Project x onto the constraint manifold (positions, then speeds); returns a status code.", [])]


def _momentum_c(w: KernelWriter, kernel) -> dict:
    n = w.n_u  # the momentum form needs qd = u: n_q == n_u
    body = w.head(kernel, reads_inputs=True) + ["/* Mass matrix, lower triangle, mirrored */"]
    for (j, k), expr in results(kernel, "M").items():
        body.append(f"M[{j * n + k}] = {w.expr(expr, f'M[{j}][{k}]')};")
        if j != k:
            body.append(f"M[{k * n + j}] = M[{j * n + k}];")
    body.append("/* G = dL/dq + Q */")
    body += [f"G[{j}] = {w.expr(expr, f'G[{j}]')};" for (j, _), expr in results(kernel, "G").items()]
    return record("void", f"{w.prefix}_momentum", f"{w.driven_arguments}, {w.real} *M, {w.real} *G",
                  f"M(q) (row-major {n} x {n}) and G = dL/dq + Q, for symplectic Euler in p = M u.", body)


# -- the registry ---------------------------------------------------------------------------------
def _applies(eom: EquationsOfMotion) -> str | None:
    return None


@dataclass(frozen=True)
class Output:
    """One C output function.

    ``kernel`` names its rows in `KERNEL_ROWS`; ``write`` returns its C function record;
    ``obstacle`` says why it does not apply to a model (None when it does); ``empty`` is True for
    a model that gives it nothing to compute (it is then left out silently); ``checked``: it
    returns a status after checking its values are finite; ``calls_dynamics``: its body calls the
    unconstrained-form solve ``<prefix>_dynamics``; ``template_functions``: functions the
    templates write for it (declared with it); ``default``: in `DEFAULT_OUTPUTS`;
    ``constrained``: every constrained model gets it; ``requires``: outputs whose C functions
    it calls (added with it). A ``write`` that returns None leaves the function to the templates.
    """

    name: str
    kernel: str
    write: Callable[[KernelWriter, object], dict]
    obstacle: Callable[[EquationsOfMotion], str | None] = _applies
    empty: Callable[[EquationsOfMotion], bool] = lambda eom: False
    checked: bool = False
    calls_dynamics: bool = False
    template_functions: Callable[[KernelWriter], list] = lambda w: []
    default: bool = False
    constrained: bool = False
    requires: tuple = ()


OUTPUTS: dict[str, Output] = {o.name: o for o in (
    Output("mass_matrix", "mass_matrix", _mass_matrix_c, obstacle=_closed_form_obstacle("mass_matrix"), default=True),
    Output("forcing", "forcing", _forcing_c, obstacle=_closed_form_obstacle("forcing"), default=True),
    Output("accel", "dynamics", _accel_c, checked=True, calls_dynamics=True, default=True),
    Output("rhs", "dynamics", _rhs_c, checked=True, calls_dynamics=True, default=True),
    Output("energy", "energy", _energy_c, obstacle=_energy_obstacle, default=True),
    Output("points", "points", _points_c, empty=lambda eom: not eom.points, default=True),
    Output("measurements", "measurements", _measurements_c, empty=lambda eom: not eom.measurements, default=True),
    Output("jacobian", "jacobian", _jacobian_c, obstacle=_jacobian_obstacle, checked=True, calls_dynamics=True,
           default=True),
    Output("momentum", "momentum", _momentum_c, obstacle=_momentum_obstacle_message),
    Output("constraints", "constraints", _constraints_c, obstacle=_needs_constraints("constraints"),
           template_functions=_constraints_template_functions, constrained=True),
    Output("multipliers", "dynamics", _multipliers_c, obstacle=_needs_constraints("multipliers"), checked=True,
           constrained=True),
    Output("step_jacobian", "jacobian", lambda w, kernel: None, obstacle=_step_jacobian_obstacle,
           requires=("jacobian",)),
    Output("dependent_speeds", "dependent", _dependent_speeds_c, empty=lambda eom: not eom.n_dependent,
           checked=True, default=True),
    Output("dependent_accelerations", "dependent_accelerations", _dependent_accelerations_c,
           empty=lambda eom: not eom.n_dependent, checked=True),
    Output("reactions", "reactions", _reactions_c, empty=lambda eom: not eom.reactions, checked=True, default=True,
           requires=("accel",)),
    Output("configuration", "configuration", _configuration_project_c, obstacle=_configuration_obstacle,
           empty=lambda eom: not eom.dependent_coordinates, default=True),
)}
DEFAULT_OUTPUTS = tuple(name for name, o in OUTPUTS.items() if o.default)


def checked_outputs(eom: EquationsOfMotion, outputs) -> list:
    """``outputs`` without repeats or empty ones; KernelError for an unknown or inapplicable one."""
    chosen = []
    for name in outputs:
        if name not in OUTPUTS:
            raise KernelError(f"unknown output {name!r}; choose from {', '.join(OUTPUTS)}")
        output = OUTPUTS[name]
        if output.empty(eom):
            continue
        reason = output.obstacle(eom)
        if reason is not None:
            raise KernelError(reason)
        for needed in output.requires + (name,):
            if needed not in chosen:
                chosen.append(needed)
    if not chosen:
        raise KernelError("no outputs requested")
    if eom.n_dependent and "dependent_speeds" not in chosen:  # every kernel reading them calls it
        chosen.insert(0, "dependent_speeds")
    if eom.n_dependent and "reactions" in chosen and "dependent_accelerations" not in chosen:
        chosen.insert(chosen.index("reactions"), "dependent_accelerations")
    return chosen


def applicable_outputs(eom: EquationsOfMotion, wanted) -> list:
    """The outputs of ``wanted`` that apply to ``eom``, then those every model of its kind gets
    (constraint terms and multipliers of a constrained model)."""
    chosen = [name for name in wanted if OUTPUTS[name].obstacle(eom) is None]
    if eom.m and not eom.n_dependent:
        chosen += [name for name, o in OUTPUTS.items() if o.constrained and name not in chosen]
    return chosen


def applicable_methods(eom: EquationsOfMotion, methods) -> tuple:
    """The methods of ``methods`` whose outputs all apply to ``eom`` (no symplectic Euler without
    the momentum form, no implicit method for a constrained model yet)."""
    from ..integrators.schemes import get_scheme

    return tuple(m for m in methods if all(OUTPUTS[o].obstacle(eom) is None for o in get_scheme(m).outputs))


# -- the static functions the outputs share -------------------------------------------------------
def support_functions(w: KernelWriter) -> list:
    """Static C functions the requested outputs call, in the order the source defines them."""
    outputs = [OUTPUTS[name] for name in w.system.outputs]
    functions = []
    for stem in ("energy", "points") if w.system.recursive else ():
        if stem in w.system.outputs:
            functions += kernel_parts(w, w.system.kernel(stem), stem, driven=False)[0]
    if any(o.checked for o in outputs):
        functions.append(_finite_result_function(w))
    if w.n_dependent or w.system.reactions or w.system.dependent_coordinates:
        functions += _dense_lu_functions(w)
    if w.system.dependent_coordinates:
        functions.append(_configuration_terms_function(w))
    if any(o.kernel == "dynamics" for o in outputs):
        functions += _dynamics_functions(w)
        if w.system.n_constraints and any(o.calls_dynamics for o in outputs):
            m, prefix, real = w.system.n_constraints, w.prefix, w.real
            functions.append(record(
                "int", f"{prefix}_dynamics",
                f"{w.driven_arguments}, {real} *qd, {real} *ud, {real} *gauge",
                "qd and ud of the constrained system (gauge: see dynamics_constrained).",
                [f"{real} lam[{m}];", f"return {prefix}_dynamics_constrained(t, x, {w.rp}, qd, ud, lam, 0, gauge);"],
                static=True))
    return functions


def _dense_lu_functions(w: KernelWriter) -> list:
    """LU with partial pivoting of a small dense A (n x n), its substitution, and the solve of A X = B
    built on the two. The dependent speeds' A_D is factored once per evaluation of the dynamics and
    both its solves (the dependent speeds with Kane's C, and the accelerations' g_D) substitute. A
    pivot not above rank_tolerance times the larger of ``scale`` and the largest |entry| of A is a
    singular A (the dependent speeds' Jacobian lost rank); det(A), whose sign change between two
    states is a singular A crossed, goes to the drivers' singularity monitor. U's diagonal is kept
    as its reciprocal: the substitutions multiply (a division's latency on every row is most of a
    3 x 3 solve's time)."""
    real, zero, one, prefix = w.real, literal(0, w.real), literal(1, w.real), w.prefix
    tolerance = literal(1e-12 if real == "double" else 1e-6, real)
    fabs = "fabsf" if real == "float" else "fabs"
    size = max(w.n_dependent, len(w.system.reactions), len(w.system.dependent_coordinates))
    factor = [f"{real} product = {one};", "int i, j, k;",
              "for (i = 0; i < n * n; ++i) {",
              f"    if ({fabs}(A[i]) > scale) scale = {fabs}(A[i]);",
              "}",
              f"if (!(scale > {zero}) || !isfinite(scale)) return 0;",
              "for (k = 0; k < n; ++k) {",
              "    int pivot = k;",
              "    for (i = k + 1; i < n; ++i) {",
              f"        if ({fabs}(A[i * n + k]) > {fabs}(A[pivot * n + k])) pivot = i;",
              "    }",
              "    ipiv[k] = pivot;",
              f"    if (!({fabs}(A[pivot * n + k]) > {tolerance} * scale)) return 0;",
              "    if (pivot != k) {",
              "        product = -product;",
              "        for (j = 0; j < n; ++j) {",
              f"            const {real} swap = A[k * n + j];",
              "            A[k * n + j] = A[pivot * n + j];",
              "            A[pivot * n + j] = swap;",
              "        }",
              "    }",
              "    product *= A[k * n + k];",
              f"    A[k * n + k] = {one} / A[k * n + k];",
              "    for (i = k + 1; i < n; ++i) {",
              f"        const {real} multiplier = A[i * n + k] * A[k * n + k];",
              "        A[i * n + k] = multiplier;",
              "        for (j = k + 1; j < n; ++j) A[i * n + j] -= multiplier * A[k * n + j];",
              "    }",
              "}",
              "if (det) *det = product;",
              "return 1;"]
    substitute = ["int i, k, c;",
                  "for (k = 0; k < n; ++k) {  /* the row exchanges of the factorization, in its order */",
                  "    if (ipiv[k] != k) {",
                  "        for (c = 0; c < cols; ++c) {",
                  f"            const {real} swap = B[k * cols + c];",
                  "            B[k * cols + c] = B[ipiv[k] * cols + c];",
                  "            B[ipiv[k] * cols + c] = swap;",
                  "        }",
                  "    }",
                  "}",
                  "for (k = 0; k < n; ++k) {",
                  "    for (i = k + 1; i < n; ++i) {",
                  "        for (c = 0; c < cols; ++c) B[i * cols + c] -= LU[i * n + k] * B[k * cols + c];",
                  "    }",
                  "}",
                  "for (k = n - 1; k >= 0; --k) {",
                  "    for (c = 0; c < cols; ++c) {",
                  f"        {real} acc = B[k * cols + c];",
                  "        for (i = k + 1; i < n; ++i) acc -= LU[k * n + i] * B[i * cols + c];",
                  "        B[k * cols + c] = acc * LU[k * n + k];",
                  "    }",
                  "}"]
    solve = [f"int ipiv[{size}];",
             f"if (!{prefix}_dense_factor(A, ipiv, n, scale, det)) return 0;",
             f"{prefix}_dense_substitute(A, ipiv, B, n, cols);",
             "return 1;"]
    return [record("int", f"{prefix}_dense_factor", f"{real} *A, int *ipiv, int n, {real} scale, {real} *det",
                   "LU of A in place (partial pivoting, the row exchanges in ipiv, U's diagonal as its "
                   "reciprocal); 0 when A is singular to rank_tolerance relative to the larger of scale and "
                   "A's largest |entry|; det (or NULL) receives det(A).", factor, hot=True),
            record("void", f"{prefix}_dense_substitute",
                   f"const {real} *LU, const int *ipiv, {real} *B, int n, int cols",
                   f"Solve A X = B in place (B row-major n x cols) with the factors from {prefix}_dense_factor.",
                   substitute, hot=True),
            record("int", f"{prefix}_dense_solve",
                   f"{real} *A, {real} *B, int n, int cols, {real} scale, {real} *det",
                   f"Solve A X = B in place (n <= {size}): {prefix}_dense_factor, then "
                   f"{prefix}_dense_substitute; 0 when A is singular (A then holds part of its factors).",
                   solve, hot=True)]


def _finite_result_function(w: KernelWriter) -> dict:
    """A finite state can still give NaN or infinite derivatives (F overflowing for a huge
    parameter, 0 * inf): the public kernels report that instead of LCG_OK. The drivers' own
    steps are checked on the new state, so the steppers do not pay for this."""
    return record("int", f"{w.prefix}_finite_result", f"int status, const {w.real} *values, int count",
                  "status, or LCG_NONFINITE_STATE when status is LCG_OK but a value is NaN or infinite.",
                  ["int i;", "if (status != LCG_OK) return status;",
                   "for (i = 0; i < count; ++i) {", "    if (!isfinite(values[i])) return LCG_NONFINITE_STATE;",
                   "}", "return LCG_OK;"], static=True)


def _dynamics_functions(w: KernelWriter) -> list:
    """Static kernel behind accel and rhs: K, M, F with joint CSE, then an unrolled LDL^T solve
    (with an always-inlined copy for the explicit steppers when it is small, `hot_dynamics`)."""
    system, real, prefix, n = w.system, w.real, w.prefix, w.n_m
    kernel = system.kernel("dynamics")
    if system.recursive:
        return _recursive_dynamics_functions(w, kernel)
    M = results(kernel, "M")

    def mass_lines():
        lines = ["/* Mass matrix, lower triangle */"]
        for (j, k), expr in M.items():
            if expr != 0 or j == k:  # structural zeros are skipped by the factorization too
                lines.append(f"const {real} M_{j}_{k} = {w.expr(expr, f'M[{j}][{k}]')};")
        return lines

    # eliminated dependent speeds: M and its reduction come before the terms that read them
    reduced = _eliminated_head_lines(w, kernel, M, mass_lines()) if w.n_dependent else None
    body = w.head(kernel, touches_state=system.kinematics_identity, reads_inputs=True,
                  on_singular="return dep_status;", dependent_solve=reduced and reduced[0])
    if not w.n_dependent:
        body += mass_lines()
    body.append("/* Forcing */")
    for (j, _), expr in results(kernel, "F").items():
        body.append(f"const {real} F_{j} = {w.expr(expr, f'F[{j}]')};")
    body.append("/* Kinematics qd = K(q, u, t) */")
    if system.kinematics_identity:
        body += [f"qd[{j}] = x[{w.n_q + j}];" for j in range(w.n_q)]
    else:
        body += [f"qd[{j}] = {w.expr(expr, f'qd[{j}]')};" for (j, _), expr in results(kernel, "K").items()]
    nonzero = {jk for jk, e in M.items() if e != 0}
    failure = f"{prefix}_pivot_failure(x)"
    m = system.n_constraints
    arguments = f"{w.driven_arguments}, {real} *qd, {real} *ud"
    linkage = {"shared": True} if shared_dynamics(system) else {"static": True}
    if w.n_dependent:
        return [record("int", f"{prefix}_dynamics", f"{arguments}, {real} *gauge",
                       "K, M, F, A and gamma of every speed with shared temporaries: A_D factored once, the "
                       "dependent speeds and Kane's reduced M = C^T M C (factored while the terms that read the "
                       f"dependent speeds are computed), then ud of the {w.n_u} independent speeds from the "
                       "reduced equations; gauge (or NULL) receives the pivots of the reduced M and det(A_D) "
                       "(the singularity monitor of the drivers).",
                       body + _eliminated_tail_lines(w, kernel, M, reduced[1]), **linkage)]
    if not m:
        factor, LD = ldlt_factor_lines(n, nonzero, real, failure)
        body += factor + _gauge_lines(n) + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}",
                                                                    lambda i: f"ud[{i}]")
        body.append("return LCG_OK;")
        arguments += f", {real} *gauge"
        doc = ("K, M and F with shared temporaries, then M ud = F by LDL^T; gauge (or NULL) receives the "
               f"{n} pivots of M (the singularity monitor of the drivers).")
        if not hot_dynamics(system):
            return [record("int", f"{prefix}_dynamics", arguments, doc, body, **linkage)]
        return [record("int", f"{prefix}_dynamics_hot", arguments,
                       doc[:-1] + "; inlined into every explicit Runge-Kutta stage.", body, hot=True),
                record("int", f"{prefix}_dynamics", arguments, "The same, as one function for the other callers.",
                       [f"return {prefix}_dynamics_hot(t, x, {w.rp}, qd, ud, gauge);"], static=True)]
    body += _constrained_solve_lines(w, kernel, nonzero, failure)
    return [record("int", f"{prefix}_dynamics_constrained",
                   f"{arguments}, {real} *lam, {real} *Q, {real} *gauge",
                   "K, M, F, A = dphi/dq and gamma with shared temporaries; M ud + A^T lam = F, A ud = gamma "
                   "by the range-space method (LDL^T of M, Cholesky of A M^-1 A^T); Q = A^T lam if not NULL; "
                   f"gauge (or NULL) receives the {n} pivots of M, the {m} of A M^-1 A^T and A "
                   "(the singularity monitor of the drivers).",
                   body, **linkage)]


def _recursive_dynamics_functions(w: KernelWriter, kernel) -> list:
    """The tree's articulated-body algorithm as straight-line code (`symbolic.trees`); its pivots
    D_i = S_i^T I^A_i S_i are those of M's LDL^T in joint variables: each must be positive."""
    real, prefix, n = w.real, w.prefix, w.n_u
    parts, body = kernel_parts(w, kernel, "dynamics", driven=True)
    pivots, scales = results(kernel, "D"), results(kernel, "DS")
    floor = literal(PIVOT_ROUNDING if real == "double" else 1e-6, real)
    body.append("/* Pivots of the articulated inertias: above rounding of the trace of the inertia block each")
    body.append(" * reads unless the tree is singular here (a mass on a joint's axis from runtime parameters) */")
    body += [f"const {real} pivot_{j} = {w.expr(e, f'D[{j}]')};" for (j, _), e in pivots.items()]
    tests = []
    for j in range(n):
        scale = scales.get((j, 0), 0)
        tests.append(f"pivot_{j} > 0" if scale == 0 else f"pivot_{j} > {floor} * ({w.expr(scale, f'trace[{j}]')})")
    body.append(f"if (!({' && '.join(tests)})) return {prefix}_pivot_failure(x);")
    body.append("if (gauge) {  /* pivots, for the drivers' singularity monitor */")
    body += [f"    gauge[{j}] = pivot_{j};" for j in range(n)]
    body.append("}")
    body += [f"qd[{j}] = x[{w.n_q + j}];" for j in range(w.n_q)]
    body += [f"ud[{j}] = {w.expr(e, f'ud[{j}]')};" for (j, _), e in results(kernel, "UD").items()]
    body.append("return LCG_OK;")
    arguments = f"{w.driven_arguments}, {real} *qd, {real} *ud, {real} *gauge"
    doc = ("qd and ud of the tree by the articulated-body algorithm (three passes over the links, written "
           f"out); gauge (or NULL) receives the {n} articulated pivots (the singularity monitor of the drivers).")
    if parts or not hot_dynamics(w.system):
        return parts + [record("int", f"{prefix}_dynamics", arguments, doc, body, static=True)]
    return [record("int", f"{prefix}_dynamics_hot", arguments, doc[:-1] + "; inlined into every explicit "
                   "Runge-Kutta stage.", body, hot=True),
            record("int", f"{prefix}_dynamics", arguments, "The same, as one function for the other callers.",
                   [f"return {prefix}_dynamics_hot(t, x, {w.rp}, qd, ud, gauge);"], static=True)]


def _eliminated_head_lines(w: KernelWriter, kernel, M: dict, mass_lines: list) -> tuple[list, set]:
    """Kane's minimal equations from the unreduced ones, first half: with A = [A_I A_D] (independent,
    dependent columns), u = C u_I + c, C = [I; -A_D^-1 A_I]. A_D is factored once (LU), and
    A_D [C_D | u_dep] = [-A_I | -(A_I u_I + b)] gives C's lower rows and the dependent speeds (the
    rank test's scale is the largest |entry| of A_I: A_D's own would make a 1 x 1 A_D, cos(theta) of a
    sleigh, regular until it is exactly 0); then M and the reduced M_r = C^T M C, factored by LDL^T
    (positive definite when M is on the null space of A; Kane and Levinson, Dynamics: Theory and
    Applications, sec. 6.1). None of this reads the dependent speeds' terms, so it runs where the
    kernel's temporaries that do not read them are done. Returns the lines and the factor's L
    pattern."""
    m, p, n, real, prefix = w.n_dependent, w.n_u, w.n_m, w.real, w.prefix
    fabs = "fabsf" if real == "float" else "fabs"
    zero = literal(0, real)
    width = p + 1
    A = results(kernel, "A")
    unrolled = m <= UNROLLED_LU_MAX
    lines = [f"{real} X[{m * width}], u_dep[{m}], det, scale = {zero};"]
    if not unrolled:
        lines += [f"{real} LU[{m * m}];", f"int ipiv[{m}];"]
    lines += ["/* A_D [C_D | u_dep] = [-A_I | -(A_I u_I + b)], A_D factored once (its LU serves the accelerations",
              " * too); the rank test's scale is the largest |entry| of the independent columns of A */"]
    lines += [(f"{real} LU_{i}_{j} = " if unrolled else f"LU[{i * m + j}] = ")
              + f"{w.expr(A.get((i, p + j), 0), f'A_D[{i}][{j}]')};" for i in range(m) for j in range(m)]
    for i in range(m):
        for k in range(p):
            entry = A.get((i, k), 0)
            # an atom negated by sympy (found by review: a constraint y' - x' printed "X[0] = --1;"), a sum whole
            negated = (zero if entry == 0 else w.expr(-entry, f'A[{i}][{k}]') if entry.is_Atom else
                       f"-({w.expr(entry, f'A[{i}][{k}]')})")
            lines.append(f"X[{i * width + k}] = {negated};")
    lines += [f"X[{i * width + p}] = -({w.expr(e, f'row {i}')});" for (i, _), e in results(kernel, "BI").items()]
    for i in range(m):
        for k in range(p):
            entry = A.get((i, k), 0)
            if entry != 0:
                value = w.expr(entry, f'A[{i}][{k}]')  # a comparison, not fmax: gcc calls libm's fmax
                lines.append(f"if ({fabs}({value}) > scale) scale = {fabs}({value});")
    if unrolled:
        lines += lu_factor_lines(m, real, "LCG_SINGULAR_CONSTRAINTS", what="A_D")
        for c in range(width):
            lines += lu_substitute_lines(m, real, [f"X[{i * width + c}]" for i in range(m)])
    else:
        lines += [f"if (!{prefix}_dense_factor(LU, ipiv, {m}, scale, &det)) return LCG_SINGULAR_CONSTRAINTS;",
                  f"{prefix}_dense_substitute(LU, ipiv, X, {m}, {width});"]
    lines += [f"u_dep[{i}] = X[{i * width + p}];" for i in range(m)]
    lines += mass_lines

    def mass(i, j):  # M's entry (i, j) from its lower triangle, None for a structural zero
        a, b = max(i, j), min(i, j)
        return f"M_{a}_{b}" if M.get((a, b), 0) != 0 or a == b else None

    def total(terms):
        return " + ".join(terms) if terms else zero

    lines.append("/* M C, then Kane's reduced mass matrix C^T M C (X's first p columns are C_D) */")
    for i in range(n):
        for j in range(p if i >= p else i + 1):  # the reduced M's lower triangle reads these
            terms = [mass(i, j)] if mass(i, j) else []
            terms += [f"{mass(i, p + k)}*X[{k * width + j}]" for k in range(m) if mass(i, p + k)]
            lines.append(f"const {real} MC_{i}_{j} = {total(terms)};")
    for i in range(p):
        for j in range(i + 1):
            terms = [f"MC_{i}_{j}"] + [f"X[{k * width + i}]*MC_{p + k}_{j}" for k in range(m)]
            lines.append(f"const {real} Mr_{i}_{j} = {total(terms)};")
    factor, LD = ldlt_factor_lines(p, {(i, j) for i in range(p) for j in range(i)}, real,
                                   "LCG_SINGULAR_MASS_MATRIX", matrix="Mr")
    lines += factor
    lines.append("if (gauge) {  /* pivots of the reduced M and det(A_D), for the drivers' singularity monitor */")
    lines += [f"    gauge[{j}] = D_{j};" for j in range(p)] + [f"    gauge[{p}] = det;", "}"]
    return lines, LD


def _eliminated_tail_lines(w: KernelWriter, kernel, M: dict, LD: set) -> list:
    """Kane's minimal equations, second half (after F and gamma, which read the dependent speeds):
    ud = C ud_I + g, g = [0; A_D^-1 gamma] from A ud = gamma, with A_D's factors; then
    (C^T M C) ud_I = C^T (F - M g) with the reduced M's factors."""
    m, p, n, real, prefix = w.n_dependent, w.n_u, w.n_m, w.real, w.prefix
    width = p + 1
    if not p:  # every speed fixed by the constraints: no acceleration to solve for, M and F unread (found by
        # review: they failed -Wall -Wextra -Werror)
        unread = [f"M_{j}_{k}" for (j, k), e in M.items() if e != 0 or j == k] + [f"F_{j}" for j in range(n)]
        return [f"(void){name};" for name in unread] + ["(void)ud;", "return LCG_OK;"]
    lines = [f"{real} gD[{m}];", "/* g_D = A_D^-1 gamma: the dependent accelerations' part that ud_I does not give */"]
    lines += [f"gD[{i}] = {w.expr(e, f'gamma[{i}]')};" for (i, _), e in results(kernel, "C").items()]
    if m <= UNROLLED_LU_MAX:
        lines += lu_substitute_lines(m, real, [f"gD[{i}]" for i in range(m)])
    else:
        lines.append(f"{prefix}_dense_substitute(LU, ipiv, gD, {m}, 1);")
    lines.append("/* the reduced forcing C^T (F - M g) */")
    for i in range(n):
        terms = [f"F_{i}"]
        for k in range(m):
            a, b = max(i, p + k), min(i, p + k)
            if M.get((a, b), 0) != 0 or a == b:
                terms.append(f"M_{a}_{b}*gD[{k}]")
        lines.append(f"const {real} rest_{i} = {' - '.join(terms)};")
    for i in range(p):
        terms = [f"rest_{i}"] + [f"X[{k * width + i}]*rest_{p + k}" for k in range(m)]
        lines.append(f"const {real} Fr_{i} = {' + '.join(terms)};")
    lines += ldlt_substitution_lines(p, LD, real, lambda i: f"Fr_{i}", lambda i: f"ud[{i}]")
    lines.append("return LCG_OK;")
    return lines


def _gauge_lines(n: int, indent: bool = True) -> list:
    """Store the LDL^T pivots D_j of M into gauge[j] (when gauge is not NULL): the drivers' singularity
    monitor compares them between accepted states (`steppers.gauge_context`)."""
    stores = [f"gauge[{j}] = D_{j};" for j in range(n)]
    if not indent:
        return stores
    return ["if (gauge) {  /* pivots of M, for the drivers' singularity monitor */"] + \
        ["    " + line for line in stores] + ["}"]


def _constrained_solve_lines(w: KernelWriter, kernel, nonzero, failure) -> list:
    real, n, m, prefix = w.real, w.n_u, w.system.n_constraints, w.prefix
    body = [f"{real} A[{m * n}], C[{m}], z[{n}], Y[{n * m}];", "int c, i;", "/* A = dphi/dq, gamma */"]
    for (i, j), expr in results(kernel, "A").items():
        body.append(f"A[{i * n + j}] = {w.expr(expr, f'dphi[{i}]/dq[{j}]')};")
    for (i, _), expr in results(kernel, "C").items():
        body.append(f"C[{i}] = {w.expr(expr, f'gamma[{i}]')};")
    factor, LD = ldlt_factor_lines(n, nonzero, real, failure)
    body += factor + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}", lambda i: f"z[{i}]")
    body.append(f"for (c = 0; c < {m}; ++c) {{  /* Y = M^-1 A^T */")
    body += ["    " + line for line in ldlt_substitution_lines(
        n, LD, real, lambda i: f"A[c * {n} + {i}]", lambda i: f"Y[{i * m} + c]", names=("yc", "wc"))]
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
