"""Helper: LU with partial pivoting of a small dense A and its substitutions, unrolled into C lines
over locals (A's entries in ``LU_i_j``, the row exchanges in ``pivot_k``).

The operations are those of the looped ``<prefix>_dense_factor`` and ``<prefix>_dense_substitute``
(``outputs._dense_lu_functions``), in the same order, so the two give the same bits; only the row
exchanges are selects on locals instead of swaps in an array. The loops indexed their arrays by
the pivots, which kept every entry in memory: the Whipple bicycle's 3 x 3 A_D (4 right-hand
columns, then 1) took 14 % of its dynamics' time that way, and its RK4 step 17 % less time
unrolled (docs/benchmarks.txt, session 20).
"""
from __future__ import annotations

from .csyntax import literal as _literal

UNROLLED_LU_MAX = 6
"""The largest A unrolled; the lines grow as n^3 (the selects of the row exchanges)."""


def lu_factor_lines(n: int, real: str, failure: str, matrix: str = "LU", what: str = "A") -> list:
    """Factor the locals ``{matrix}_i_j`` (non-const, n x n) in place: L's multipliers below the
    diagonal, U above it and U's diagonal as its reciprocal; ``pivot_k`` (int locals, declared
    here) the row exchanged with row k. Reads and updates ``scale`` (a local: the rank test is
    relative to the larger of it and A's largest |entry|) and sets ``det`` (a declared local) to
    det(A). A pivot not above the rank tolerance times the scale returns ``failure``. ``what`` names
    A in the lines' comment."""
    zero, one = _literal(0, real), _literal(1, real)
    tolerance = _literal(1e-12 if real == "double" else 1e-6, real)
    fabs = "fabsf" if real == "float" else "fabs"

    def a(i, j):
        return f"{matrix}_{i}_{j}"

    lines = [f"/* LU of {what} ({n} x {n}) in {matrix}_i_j, partial pivoting, unrolled (row exchanges: selects) */"]
    lines += [f"if ({fabs}({a(i, j)}) > scale) scale = {fabs}({a(i, j)});" for i in range(n) for j in range(n)]
    lines += [f"if (!(scale > {zero}) || !isfinite(scale)) return {failure};", f"det = {one};"]
    for k in range(n):
        if k < n - 1:
            lines += [f"int pivot_{k} = {k};", f"{real} largest_{k} = {fabs}({a(k, k)});"]
            lines += [f"if ({fabs}({a(i, k)}) > largest_{k}) {{ largest_{k} = {fabs}({a(i, k)}); pivot_{k} = {i}; }}"
                      for i in range(k + 1, n)]
            lines.append(f"if (!(largest_{k} > {tolerance} * scale)) return {failure};")
            for j in range(n):
                chosen = a(k, j)
                for i in reversed(range(k + 1, n)):
                    chosen = f"pivot_{k} == {i} ? {a(i, j)} : {chosen}" if chosen == a(k, j) else \
                        f"pivot_{k} == {i} ? {a(i, j)} : ({chosen})"
                below = " ".join(f"{a(i, j)} = pivot_{k} == {i} ? top : {a(i, j)};" for i in range(k + 1, n))
                lines.append(f"{{ const {real} top = {a(k, j)}; {a(k, j)} = {chosen}; {below} }}")
            lines.append(f"det = pivot_{k} != {k} ? -det : det;")
        else:
            lines.append(f"if (!({fabs}({a(k, k)}) > {tolerance} * scale)) return {failure};")
        lines += [f"det *= {a(k, k)};", f"{a(k, k)} = {one} / {a(k, k)};"]
        for i in range(k + 1, n):
            lines.append(f"{a(i, k)} = {a(i, k)} * {a(k, k)};")
            lines += [f"{a(i, j)} -= {a(i, k)} * {a(k, j)};" for j in range(k + 1, n)]
    return lines


def lu_substitute_lines(n: int, real: str, column: list, matrix: str = "LU") -> list:
    """Solve A x = b in place for one column, with the factors of `lu_factor_lines`: ``column``
    names the n C lvalues that hold b and receive x. One block of lines (its locals scoped)."""
    def a(i, j):
        return f"{matrix}_{i}_{j}"

    b = [f"b_{i}" for i in range(n)]
    lines = ["{", f"    {real} " + ", ".join(f"{b[i]} = {column[i]}" for i in range(n)) + ", top;"]
    for k in range(n - 1):  # the row exchanges of the factorization, in its order
        chosen = b[k]
        for i in reversed(range(k + 1, n)):
            chosen = f"pivot_{k} == {i} ? {b[i]} : {chosen}" if chosen == b[k] else \
                f"pivot_{k} == {i} ? {b[i]} : ({chosen})"
        below = " ".join(f"{b[i]} = pivot_{k} == {i} ? top : {b[i]};" for i in range(k + 1, n))
        lines.append(f"    top = {b[k]}; {b[k]} = {chosen}; {below}")
    for k in range(n):
        lines += [f"    {b[i]} -= {a(i, k)} * {b[k]};" for i in range(k + 1, n)]
    for k in reversed(range(n)):
        acc = b[k]
        for i in range(k + 1, n):
            acc = f"({acc} - {a(k, i)} * {b[i]})"
        lines.append(f"    {b[k]} = {acc} * {a(k, k)};")
    lines += [f"    {column[i]} = {b[i]};" for i in range(n)]
    if n == 1:
        lines[1] = f"    {real} {b[0]} = {column[0]};"
    lines.append("}")
    return lines
