"""A rolling disk held by a spring, with a rod hinged at its centre: equations and frequencies.

Run: python examples/disk_spring_rod.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.statics.equilibria import linearize


def main() -> None:
    eom = derive_equations(catalog.disk_spring_rod("bodies"))
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")

    linear = linearize(eom, {"x": 0, "phi": 0})
    print("\nabout x = 0, phi = 0 (rod hanging): M0 dqdd + K0 dq = 0 with")
    print("M0 =", sp.pretty(linear.M0), sep="\n")
    print("K0 =", sp.pretty(linear.K0), sep="\n")
    numeric = linearize(eom, {"x": 0, "phi": 0}, values={})
    print("natural frequencies at the defaults [rad/s]:",
          ", ".join(f"{w:.6f}" for w in numeric.natural_frequencies()))


if __name__ == "__main__":
    main()
