"""Two wheels and a rod rolling down an incline: equations by both routes, and the acceleration.

Run: python examples/rolling_wheels.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations


def main() -> None:
    for route in catalog.ROUTES:
        eom = derive_equations(catalog.rolling_wheels(route))
        print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
        print("M(q) ud = F(q, u) with")
        print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
        print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")
        # one coordinate: ud = F / M, a single entry, so simplifying it is cheap
        sdd = sp.simplify(eom.forcing[0] / eom.mass_matrix[0, 0])
        print("acceleration of the axles, sdd =", sp.pretty(sdd), sep="\n")
        print()


if __name__ == "__main__":
    main()
