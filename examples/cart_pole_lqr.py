"""A cart-pole balanced by LQR, in Python and in an embedded C loop.

The model (by its energies, cart position x, pole angle theta from upright, point mass at the
pole's end) is driven by the cart force F. We linearize at upright (A, B), take the plant's
exact one-step Jacobians at h = 10 ms (dx+/dx, dx+/dF) for a discrete LQR gain (scipy's
solve_discrete_are), then close the loop twice from a 0.2 rad tilt:
- in Python, ``simulate(inputs=callable)`` calls the controller every step;
- in C, ``--emit DIR`` writes the plant's header and source (double, or float with --float)
  and ``cart_pole_plant.h`` beside examples/cart_pole_lqr/balance.c, a C99 control loop for
  firmware (no malloc, no globals) that tests/native_build/test_cart_pole_lqr.py builds with gcc,
  clang and arm-none-eabi-gcc.

Run: python examples/cart_pole_lqr.py [--emit DIR] [--float]
"""
from __future__ import annotations

import argparse
import shutil
from pathlib import Path

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me
from scipy.linalg import solve_discrete_are

from lagcodegen import Model
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate, step_jacobians
from lagcodegen.statics.state_space import linearize_state
from lagcodegen.symbolic.derive import derive_equations

H = 0.01
STEPS = 800  # 8 s
TILT = 0.2
SETTLED = 1e-3
#: LQR weights on (x, theta, x', theta') and the force
STATE_WEIGHTS = (10.0, 100.0, 1.0, 1.0)
FORCE_WEIGHT = 0.1
PARAMETERS = {"m_cart": 1.0, "m_pole": 0.1, "l": 0.5, "g": 9.81}


def cart_pole() -> Model:
    x, theta, F = me.dynamicsymbols("x theta F")
    m_cart, m_pole, l, g = sp.symbols("m_cart m_pole l g", positive=True)
    xd, thetad = x.diff(), theta.diff()
    T = (m_cart + m_pole) * xd ** 2 / 2 + m_pole * l * sp.cos(theta) * xd * thetad + m_pole * l ** 2 * thetad ** 2 / 2
    V = m_pole * g * l * sp.cos(theta)
    return Model("cart_pole", [x, theta], [m_cart, m_pole, l, g], kinetic_energy=T, potential_energy=V,
                 generalized_forces={x: F}, inputs=[F], parameter_values=PARAMETERS,
                 measurements={"pole_tip_x": x + l * sp.sin(theta), "pole_tip_y": l * sp.cos(theta)})


def discrete_lqr(Fx: np.ndarray, Fr: np.ndarray) -> np.ndarray:
    Q, R = np.diag(STATE_WEIGHTS), np.array([[FORCE_WEIGHT]])
    P = solve_discrete_are(Fx, Fr, Q, R)
    return np.linalg.solve(R + Fr.T @ P @ Fr, Fr.T @ P @ Fx).ravel()


def plant_header(prefix: str, real: str, gain: np.ndarray) -> str:
    literal = (lambda v: f"{float(v)!r}F") if real == "float" else (lambda v: repr(float(v)))
    values = lambda vs: "{ " + ", ".join(literal(v) for v in vs) + " }"  # noqa: E731
    upper = prefix.upper()
    return "\n".join([
        "/* cart_pole_plant.h: the plant and the controller of balance.c, written by examples/cart_pole_lqr.py. */",
        "#ifndef CART_POLE_PLANT_H", "#define CART_POLE_PLANT_H",
        f'#include "{prefix}.h"',
        f"typedef {real} plant_real;",
        f"#define PLANT_N_STATE {upper}_N_STATE",
        f"#define PLANT_N_PARAMS {upper}_N_PARAMS",
        f"#define PLANT_WORK {upper}_WORK_RK4",
        f"#define PLANT_STEP {prefix}_step_rk4",
        f"#define PLANT_H {literal(H)}",
        f"#define PLANT_STEPS {STEPS}L",
        f"#define PLANT_SETTLED {SETTLED!r}",
        f"#define PLANT_GAIN {values(gain)}",
        f"#define PLANT_PARAMS {values(PARAMETERS.values())}",
        f"#define PLANT_X0 {values([0.0, TILT, 0.0, 0.0])}",
        "#endif", ""])


def emit(directory: Path, gain: np.ndarray, precision: str = "double") -> Path:
    """Write the plant's C (RK4 step with the force held), cart_pole_plant.h and balance.c."""
    directory.mkdir(parents=True, exist_ok=True)
    eom = derive_equations(cart_pole())
    system = reduce_expressions(eom, ("mass_matrix", "forcing", "rhs", "measurements"))
    name = "cart_pole" if precision == "double" else "cart_pole_f32"
    sources = render_sources(system, precision=precision, model_name=name, methods=("rk4",))
    (directory / sources.header_name).write_text(sources.header)
    (directory / sources.source_name).write_text(sources.source)
    (directory / "cart_pole_plant.h").write_text(plant_header(sources.layout.prefix, precision, gain))
    shutil.copy(Path(__file__).with_name("cart_pole_lqr") / "balance.c", directory / "balance.c")
    return directory


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--emit", metavar="DIR", help="also write the C plant and control loop here")
    parser.add_argument("--float", action="store_true", help="emit single-precision C")
    args = parser.parse_args()

    eom = derive_equations(cart_pole())
    upright = linearize_state(eom, [0, 0, 0, 0], [0], values=PARAMETERS)
    print("A =", upright.A, "B =", upright.B.ravel(), sep="\n")
    print("open-loop eigenvalues:", np.round(upright.eigenvalues(), 4))

    plant = compile_model(cart_pole(), methods=("rk4",), outputs=("rhs", "step_jacobian", "measurements"))
    p = [PARAMETERS[name] for name in plant.layout.parameters]
    _, Fx, Fr = step_jacobians(plant, [0, 0, 0, 0], p, H, r=[0.0])
    gain = discrete_lqr(Fx, Fr)
    closed = np.linalg.eigvals(Fx - Fr @ gain[None, :])
    print("discrete LQR gain K =", np.round(gain, 4), "; closed-loop |eigenvalues| =", np.round(abs(closed), 4))

    run = simulate(plant, {"x": 0.0, "theta": TILT}, t_end=STEPS * H, h=H, inputs=lambda t, x: [-gain @ x])
    final = run.x[-1]
    print(f"Python loop (simulate with a callable): {run.status}, after {run.t[-1]:.1f} s: cart {final[0]:.2e} m, "
          f"pole {final[1]:.2e} rad, peak force {np.abs(run['F']).max():.2f} N")
    if not (run.ok and abs(final[1]) < SETTLED and abs(final[0]) < SETTLED):
        raise SystemExit("the pole did not settle")
    if args.emit:
        out = emit(Path(args.emit), gain, "float" if args.float else "double")
        print(f"wrote the plant and balance.c to {out}; build: cc -std=c99 -O2 -I {out} {out}/*.c -lm")


if __name__ == "__main__":
    main()
