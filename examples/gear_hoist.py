"""A geared hoist lifting a load: equation and the load's acceleration.

Run: python examples/gear_hoist.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations


def main() -> None:
    eom = derive_equations(catalog.gear_hoist())
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")
    p = {s.name: s for s in eom.parameters}
    # the load rises r r1/r2 phi, so its acceleration is phidd r r1 / r2 (a single entry)
    acceleration = sp.simplify(eom.forcing[0] / eom.mass_matrix[0, 0] * p["r"] * p["r1"] / p["r2"])
    print("\nacceleration of the load:", sp.pretty(acceleration), sep="\n")
    print(f"at the defaults: {float(acceleration.subs(eom.parameter_values)):.6f} m/s^2")


if __name__ == "__main__":
    main()
