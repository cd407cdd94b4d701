"""A chain of n pendulums: derivation time and operation counts of M and F.

Run: python examples/pendulum_chain.py [n]     (n defaults to 5)
"""
import sys
import time

import sympy as sp

from lagcodegen import catalog, derive_equations


def main(argv: list[str]) -> None:
    n = int(argv[1]) if len(argv) > 1 else 5
    model = catalog.pendulum_chain(n)
    start = time.perf_counter()
    eom = derive_equations(model)
    elapsed = time.perf_counter() - start
    print(f"{eom.name}, route: {eom.route}; {eom.n} coordinates q = {eom.q}")
    print(f"derivation time: {elapsed:.3f} s")
    ops_M = [sp.count_ops(e) for e in eom.mass_matrix]
    ops_F = [sp.count_ops(e) for e in eom.forcing]
    print(f"operation counts (sympy.count_ops): M {sum(ops_M)} (largest entry {max(ops_M)}), "
          f"F {sum(ops_F)} (largest entry {max(ops_F)})")
    print("\nfirst row of M ud = F, plain text:")
    for k in range(eom.n):
        print(f"  M[0,{k}] = {eom.mass_matrix[0, k]}")
    print(f"  F[0] = {eom.forcing[0]}")


if __name__ == "__main__":
    main(sys.argv)
