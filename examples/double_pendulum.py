"""The double pendulum: equations and natural frequencies at the hanging equilibrium.

Run: python examples/double_pendulum.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.statics.equilibria import linearize


def main() -> None:
    eom = derive_equations(catalog.double_pendulum())
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")

    hanging = {"q1": 0, "q2": 0}
    linear = linearize(eom, hanging)
    print("\nabout the hanging equilibrium: M0 dqdd + K0 dq = 0 with")
    print("M0 =", sp.pretty(linear.M0), sep="\n")
    print("K0 =", sp.pretty(linear.K0), sep="\n")
    numeric = linearize(eom, hanging, values={})
    defaults = {p.name: v for p, v in eom.parameter_values.items()}
    g, l = defaults["g"], defaults["l1"]
    print(f"natural frequencies at the defaults {defaults} [rad/s]:",
          ", ".join(f"{w:.6f}" for w in numeric.natural_frequencies()))
    print(f"(equal m, l: sqrt((g/l)(2 -+ sqrt 2)) = {((g / l) * (2 - 2 ** 0.5)) ** 0.5:.6f}, "
          f"{((g / l) * (2 + 2 ** 0.5)) ** 0.5:.6f})")
    print("mode shapes (columns, M0-normalized):", numeric.mode_shapes(), sep="\n")


if __name__ == "__main__":
    main()
