"""Helper: the unrolled LDL^T factorization and solve of M ud = F, written as C lines.

M arrives in locals ``M_j_k`` (j >= k); structural zeros are skipped, so a diagonal M costs
n divisions. A pivot that is not positive returns a status instead of producing NaNs.
"""
from __future__ import annotations

from .csyntax import literal as _literal


def ldlt_solve_lines(n: int, nonzero: set, real: str, failure: str = "LCG_SINGULAR_MASS_MATRIX") -> list:
    """Unrolled LDL^T factorization of M (locals M_j_k) and solve of M ud = F (locals F_j)."""
    factor, LD = ldlt_factor_lines(n, nonzero, real, failure)
    return factor + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}", lambda i: f"ud[{i}]")


def _minus_terms(pairs) -> str:
    return "".join(f" - {a}*{b}" for a, b in pairs)


def ldlt_factor_lines(n: int, nonzero: set, real: str, failure: str = "LCG_SINGULAR_MASS_MATRIX",
                      flag: str | None = None, matrix: str = "M") -> tuple[list, set]:
    """Unrolled LDL^T factorization of the symmetric M held in locals M_j_k (j >= k; ``matrix``
    names another stem, Mr_j_k for Kane's reduced mass matrix).

    Structural zeros of M are skipped. A pivot that is not positive (or NaN) returns
    ``failure`` (default LCG_SINGULAR_MASS_MATRIX), so a singular M never produces NaNs
    silently; with ``flag`` (the name of a local of type ``real``) it sets that flag to 1 instead
    and goes on, branch-free, as the lane kernels need (a flag of the scalar type keeps their
    loops vectorizable: gcc does not mix int and double lanes there). Returns the lines and the set
    of (i, k) whose L_i_k
    is nonzero.
    """
    zero, one = _literal(0, real), _literal(1, real)
    lines = [f"/* Factor {matrix} = L D L^T: unrolled ({n} x {n}) */"]
    LD: set = set()  # (i, k) with LD_i_k = L_i_k * D_k nonzero
    for j in range(n):
        pivot = _minus_terms((f"L_{j}_{k}", f"LD_{j}_{k}") for k in range(j) if (j, k) in LD)
        lines.append(f"const {real} D_{j} = {matrix}_{j}_{j}{pivot};")
        lines.append(f"if (!(D_{j} > {zero})) return {failure};" if flag is None
                     else f"{flag} = D_{j} > {zero} ? {flag} : {one};")
        lines.append(f"const {real} Dinv_{j} = {one} / D_{j};")
        for i in range(j + 1, n):
            pairs = [(f"LD_{i}_{k}", f"L_{j}_{k}") for k in range(j) if (i, k) in LD and (j, k) in LD]
            if (i, j) not in nonzero and not pairs:
                continue
            head = f"{matrix}_{i}_{j}" if (i, j) in nonzero else zero
            lines.append(f"const {real} LD_{i}_{j} = {head}{_minus_terms(pairs)};")
            lines.append(f"const {real} L_{i}_{j} = LD_{i}_{j} * Dinv_{j};")
            LD.add((i, j))
    return lines, LD


def ldlt_substitution_lines(n: int, LD: set, real: str, rhs, out, names: tuple = ("y", "w")) -> list:
    """Forward, diagonal and backward substitution with the factors; rhs(i), out(i) name C lvalues;
    ``names`` the stems of the locals (another pair for a solve inside the scope of a first one:
    found by review, the constrained dynamics' second solve shadowed the first's y_i, -Wshadow)."""
    y, w = names
    lines = [f"/* Substitute: L {y} = b, D z = {y}, L^T {w} = z */"]
    for i in range(n):
        lower = _minus_terms((f"L_{i}_{k}", f"{y}_{k}") for k in range(i) if (i, k) in LD)
        lines.append(f"const {real} {y}_{i} = {rhs(i)}{lower};")
    for i in reversed(range(n)):
        back = _minus_terms((f"L_{k}_{i}", f"{w}_{k}") for k in range(i + 1, n) if (k, i) in LD)
        lines.append(f"const {real} {w}_{i} = {y}_{i} * Dinv_{i}{back};")
        lines.append(f"{out(i)} = {w}_{i};")
    return lines
