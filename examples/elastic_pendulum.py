"""The elastic (spring) pendulum: equations, static stretch and small-oscillation frequencies.

Run: python examples/elastic_pendulum.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.statics.equilibria import find_equilibria, linearize


def main() -> None:
    eom = derive_equations(catalog.elastic_pendulum())
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")

    r, phi = eom.q
    print("\nequilibria (symbolic):")
    for solution in find_equilibria(eom):
        print(f"  {r} = {solution[r]},  {phi} = {solution[phi]}")

    defaults = {p.name: v for p, v in eom.parameter_values.items()}
    hanging = [s for s in find_equilibria(eom, values={}) if abs(s[phi]) < 1e-9][0]
    linear = linearize(eom, hanging, values={})
    print(f"\nat the defaults {defaults}:")
    print(f"  static stretch r0 = {hanging[r]:.6f}")
    print("  natural frequencies [rad/s]:", ", ".join(f"{w:.6f}" for w in linear.natural_frequencies()))
    print(f"  (swing sqrt(g/r0) = {(defaults['g'] / hanging[r]) ** 0.5:.6f}, "
          f"spring sqrt(k/m) = {(defaults['k'] / defaults['m']) ** 0.5:.6f})")


if __name__ == "__main__":
    main()
