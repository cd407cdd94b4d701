"""The pendulum in Cartesian coordinates: x, y with x^2 + y^2 - l^2 = 0 (Lagrange I).

Prints M ud + A^T lambda = F, A ud = gamma, then simulates 10 s with and without projection
onto the constraint and prints the residuals and the multiplier, whose 2 l lambda is the rod
tension m (g cos(theta) + l thetad^2).

Run: python examples/cartesian_pendulum.py
"""
import math

import numpy as np
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate


def main() -> None:
    eom = derive_equations(catalog.cartesian_pendulum())
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, {eom.m} constraint")
    print("M ud + A^T lambda = F, A ud = gamma with")
    for label, matrix in (("M", eom.mass_matrix), ("F", eom.forcing), ("phi", eom.constraints),
                          ("A", eom.constraint_jacobian), ("gamma", eom.constraint_bias)):
        print(f"{label} =", sp.pretty(matrix, wrap_line=False), sep="\n")

    system = compile_model(eom, methods=("rk4",))
    theta0, m, l, g = 1.0, 1.0, 1.0, 9.81  # released from rest at 57 degrees; catalog defaults
    x0 = [l * math.sin(theta0), -l * math.cos(theta0), 0.0, 0.0]
    print("\nrk4, h = 1e-3, 10 s:")
    for project in (False, True):
        run = simulate(system, x0, 10.0, 1e-3, "rk4", stride=100, project=project, residuals=True,
                       multipliers=True).check()
        phi, w = np.abs(run.residuals).max(axis=0)
        theta = np.arctan2(run["x"], -run["y"])
        thetad = (run["x"] * run["y_d"] - run["y"] * run["x_d"]) / l ** 2
        tension = m * (g * np.cos(theta) + l * thetad ** 2)
        print(f"  project={project!s:5}: max |phi| = {phi:.2e}, max |A u| = {w:.2e}, "
              f"max |2 l lambda - tension| = {np.abs(2 * l * run.multipliers[:, 0] - tension).max():.2e}")
    print(f"  lambda at t = 0: {run.multipliers[0, 0]:.6f} (m g cos(theta0) / (2 l) = "
          f"{m * g * math.cos(theta0) / (2 * l):.6f})")


if __name__ == "__main__":
    main()
