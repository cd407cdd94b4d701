"""The centrifugal governor (rheonomic: a frame spun at omega): equation, relative equilibria
and the small-oscillation frequency about the deflected one.

Run: python examples/centrifugal_governor.py
"""
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.statics.equilibria import find_equilibria, linearize


def main() -> None:
    eom = derive_equations(catalog.centrifugal_governor())
    alpha = eom.q[0]
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, u = {eom.u}")
    print("M(q) ud = F(q, u) with")
    print("M =", sp.pretty(eom.mass_matrix, wrap_line=False), sep="\n")
    print("F =", sp.pretty(eom.forcing, wrap_line=False), sep="\n")

    print("\nrelative equilibria (at rest in the spinning frame):")
    solutions = find_equilibria(eom)
    for solution in solutions:
        print(f"  {alpha} = {solution[alpha]}")
    deflected = next(s for s in solutions if s[alpha].has(sp.acos) and not s[alpha].has(sp.pi))
    print("deflected branch: cos(alpha) =", sp.pretty(sp.cos(deflected[alpha])), sep="\n")
    linear = linearize(eom, deflected)
    w2 = sp.simplify(linear.K0[0, 0] / linear.M0[0, 0])  # one entry: cheap to simplify
    print("small oscillations about it: w^2 =", sp.pretty(w2), sep="\n")

    defaults = {p.name: v for p, v in eom.parameter_values.items()}
    print(f"\nat the defaults {defaults}:")
    for solution in find_equilibria(eom, values={}):
        numeric = linearize(eom, solution, values={})
        w = numeric.natural_frequencies()[0]
        if numeric.stable:
            print(f"  {alpha} = {solution[alpha]: .6f} rad: stable, w = {w.real:.6f} rad/s")
        else:
            print(f"  {alpha} = {solution[alpha]: .6f} rad: unstable, growth rate {w.imag:.6f} 1/s")


if __name__ == "__main__":
    main()
