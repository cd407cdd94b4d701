"""A bar on two rollers going down an incline, with rolling friction: equation and acceleration.

Run: python examples/bar_on_rollers.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations


def main() -> None:
    eom = derive_equations(catalog.bar_on_rollers())
    xd = eom.u[0]
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")
    # moving down the incline (xd > 0) the friction term sign(xd) is +1
    acceleration = sp.simplify((eom.forcing[0] / eom.mass_matrix[0, 0]).subs(sp.sign(xd), 1))
    print(f"\nacceleration of the rollers while moving down ({xd} > 0):")
    print(sp.pretty(acceleration))
    value = acceleration.subs(eom.parameter_values)
    print(f"at the defaults: {float(value):.6f} m/s^2 (the bar accelerates twice as fast)")


if __name__ == "__main__":
    main()
