"""A Grashof crank-rocker four-bar in redundant coordinates (three link angles, two loop-closure
constraints, Lagrange I), and the folded-flat configuration of a change-point linkage.

Prints the equations, simulates 1 s from rest under the crank torque with and without
projection (residuals, crank turns, rocker range, multipliers), then starts the change-point
linkage flat on the x axis, where the constraint Jacobian loses rank: the run reports it.

Run: python examples/four_bar.py
"""
import math
import warnings

import numpy as np
import sympy as sp

from lagcodegen import catalog, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate


def main() -> None:
    eom = derive_equations(catalog.four_bar())
    print(f"{eom.name}, route: {eom.route}; q = {eom.q}, {eom.m} constraints, lengths "
          f"(l1, l2, l3, d) = {catalog.FOUR_BAR_GRASHOF}")
    for label, matrix in (("M", eom.mass_matrix), ("F", eom.forcing), ("phi", eom.constraints),
                          ("A", eom.constraint_jacobian)):
        print(f"{label} =", sp.pretty(matrix, wrap_line=False), sep="\n")

    system = compile_model(eom, methods=("rk4",))
    x0 = catalog.four_bar_state(0.0, 0.0)
    print("\nrk4, h = 1e-4, 1 s from rest:")
    for project in (False, True):
        run = simulate(system, x0, 1.0, 1e-4, "rk4", stride=10, project=project, residuals=True,
                       multipliers=True).check()
        turns = (run["theta1"][-1] - run["theta1"][0]) / (2 * math.pi)
        print(f"  project={project!s:5}: max residual {np.abs(run.residuals).max():.2e}; crank turns {turns:.2f}; "
              f"rocker {math.degrees(run['theta3'].min()):.3f} to {math.degrees(run['theta3'].max()):.3f} deg; "
              f"max |lambda| {np.abs(run.multipliers).max(axis=0).round(1)}")

    folding = dict(zip(("l1", "l2", "l3", "d"), catalog.FOUR_BAR_FOLDING))
    print(f"\nchange-point lengths {catalog.FOUR_BAR_FOLDING}, all links flat on the x axis:")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # the run warns; we print its message
        # crank rate 1, rocker rate l1 / l3 = 0.5: on the velocity constraint l1 w1 + l2 w2 - l3 w3 = 0
        run = simulate(system, [0.0, 0.0, 0.0, 1.0, 0.0, 0.5], 0.1, 1e-4, "rk4", params=folding)
    print(f"  status {run.status.name} at step {run.failed_step}: {run.message}")


if __name__ == "__main__":
    main()
