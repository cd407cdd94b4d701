"""Regenerate the accuracy, cost and stability charts in docs/ and print the numbers behind them.

Usage::

    python docs/make_charts.py            # full run (~1 min)
    python docs/make_charts.py --quick    # fewer steps, one timing repeat (~15 s)
    python docs/make_charts.py --out DIR  # write the PNGs and charts.md elsewhere

Writes ``work_precision_double_pendulum.png``, ``work_precision_stiff_chain.png``,
``stability.png``, ``energy_error.png`` and ``charts.md`` (the tables, for the README), and
prints the same tables to stdout. Times are CPU seconds of this machine (best of the repeats),
so they change from run to run; errors and stability limits are reproducible.

Cases
-----
* Double pendulum (m = l = 1, g = 9.81), x0 = (q1, q2, q1_d, q2_d) = (1.0, 0.5, 0, 0), 10 s;
  reference DOP853 at rtol = atol = 1e-12 (checked against Radau at the same tolerance).
* Stiff chain (m = k = 1, K = 1e4, fastest frequency w = 141.4 rad/s), x0 = (0.1, 0.01,
  -0.01, 0, 0, 0): mass 1 displaced 10 cm and the stiff spring stretched 2 cm, so the stiff
  mode carries most of the energy; 1 s; reference: the exact solution expm(J t) x0 (the chain is
  linear), checked against DOP853 at 1e-12.
* Stability: the stiff chain with that x0; largest h*w whose 2000-step run keeps its energy
  from growing 10x (`measures.measured_stability_limit`).
* Energy: double pendulum, 1e6 steps of h = 0.01 s (1e5 with --quick).
"""
from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from pathlib import Path

import numpy as np

from lagcodegen import catalog
from lagcodegen.analysis import figures, measures
from lagcodegen.integrators.schemes import DEFAULT_METHODS, get_scheme
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import jacobian, parameter_vector, simulate, solve_reference

DOCS = Path(__file__).resolve().parent
PENDULUM_X0 = (1.0, 0.5, 0.0, 0.0)
CHAIN_X0 = (0.1, 0.01, -0.01, 0.0, 0.0, 0.0)
ENERGY_METHODS = ("rk4", "dopri5", "implicit_midpoint", "symplectic_euler")
SCIPY_METHODS = ("RK45", "DOP853", "Radau")
ORDER_WINDOW = (1e-10, 1e-1)  # above the reference floor (~1e-11), below errors of order one
ORDER_POINTS = 4  # the finest runs inside the window: the asymptotic range
STABILITY_STEPS = 2000
STABILITY_HI = 1e3


def settings(quick: bool) -> dict:
    """Step counts, tolerances and repeats of a full or a quick run."""
    if quick:
        return {"pendulum_steps": [125 * 4 ** k for k in range(6)], "chain_steps": [25 * 4 ** k for k in range(6)],
                "tolerances": (1e-3, 1e-6, 1e-9), "repeats": 1, "energy_steps": 10 ** 5}
    return {"pendulum_steps": [125 * 2 ** k for k in range(11)], "chain_steps": [25 * 2 ** k for k in range(13)],
            "tolerances": (1e-3, 1e-5, 1e-7, 1e-9, 1e-11), "repeats": 3, "energy_steps": 10 ** 6}


# -- tables -----------------------------------------------------------------------------------
def markdown_table(header, rows) -> str:
    lines = ["| " + " | ".join(header) + " |", "|" + "|".join("---" for _ in header) + "|"]
    lines += ["| " + " | ".join(str(c) for c in row) + " |" for row in rows]
    return "\n".join(lines)


def fmt(value: float, spec: str = ".2e") -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    if math.isinf(value):
        return "inf"
    return format(value, spec)


def error_and_time_tables(records, steps) -> tuple[str, str]:
    """Two method x n tables from fixed-step records: error of x(t_end), wall time [ms]."""
    methods = list(dict.fromkeys(r.method for r in records))
    cell = {(r.method, r.n_steps): r for r in records}
    errors = [[m] + [fmt(cell[m, n].error) if cell[m, n].ok else "diverged" for n in steps] for m in methods]
    times = [[m] + [fmt(cell[m, n].seconds * 1e3, ".3g") for n in steps] for m in methods]
    header = ["method \\ n steps"] + [str(n) for n in steps]
    return markdown_table(header, errors), markdown_table(header, times)


def scipy_table(records) -> str:
    rows = [[r.method, fmt(r.tolerance, ".0e"), r.nfev, fmt(r.error), fmt(r.seconds * 1e3, ".3g")] for r in records]
    return markdown_table(["method", "rtol = atol", "rhs calls", "error", "wall time [ms]"], rows)


def orders(records, window=ORDER_WINDOW, points=ORDER_POINTS) -> dict:
    """Observed order per fixed-step method from its ``points`` finest runs with error in ``window``."""
    out = {}
    for method in dict.fromkeys(r.method for r in records):
        rows = sorted((r for r in records if r.method == method and r.ok and window[0] <= r.error <= window[1]),
                      key=lambda r: r.h)[:points]
        out[method] = measures.observed_order([r.h for r in rows], [r.error for r in rows])
    return out


# -- cases ------------------------------------------------------------------------------------
def pendulum_case(system, cfg) -> dict:
    t_end = 10.0
    _, x_ref = solve_reference(system, PENDULUM_X0, [t_end])
    _, x_radau = solve_reference(system, PENDULUM_X0, [t_end], method="Radau")
    records = measures.work_precision(system, PENDULUM_X0, t_end, DEFAULT_METHODS, cfg["pendulum_steps"],
                                     reference=x_ref[-1], repeats=cfg["repeats"])
    scipy_records = measures.scipy_work_precision(system, PENDULUM_X0, t_end, SCIPY_METHODS, cfg["tolerances"],
                                                 reference=x_ref[-1], repeats=cfg["repeats"])
    difference = float(np.max(np.abs(x_ref - x_radau)))
    check = f"reference DOP853 (1e-12) vs Radau (1e-12) at t = {t_end:g} s: {difference:.1e}"
    return {"records": records, "scipy": scipy_records, "check": check, "steps": cfg["pendulum_steps"],
            "reference_error": difference}


def chain_case(system, cfg) -> dict:
    t_end = 1.0
    from scipy.linalg import expm

    J = jacobian(system, np.asarray(CHAIN_X0), parameter_vector(system))
    x_exact = expm(J * t_end) @ np.asarray(CHAIN_X0)  # linear system: x(t) = exp(J t) x0
    _, x_dop = solve_reference(system, CHAIN_X0, [t_end])
    records = measures.work_precision(system, CHAIN_X0, t_end, DEFAULT_METHODS, cfg["chain_steps"],
                                     reference=x_exact, repeats=cfg["repeats"])
    scipy_records = measures.scipy_work_precision(system, CHAIN_X0, t_end, SCIPY_METHODS, cfg["tolerances"],
                                                 reference=x_exact, repeats=cfg["repeats"])
    difference = float(np.max(np.abs(x_exact - x_dop[-1])))
    check = f"reference exact expm(J t) x0 vs DOP853 (1e-12) at t = {t_end:g} s: {difference:.1e}"
    return {"records": records, "scipy": scipy_records, "check": check, "steps": cfg["chain_steps"]}


def finite_time_limit(method: str, steps: int, growth: float = measures.GROWTH_LIMIT) -> float:
    """Smallest h*w at which |R(i h w)|^(2 m) exceeds ``growth`` with m = 3/4 ``steps`` (the gap
    between the quarters `measures.measured_stability_limit` compares): the limit a finite run
    can see. Explicit RK only (symplectic Euler: its strict limit 2; implicit: inf)."""
    scheme = get_scheme(method)
    if not getattr(scheme, "explicit", False):
        return measures.theoretical_stability_limit(method)
    import sympy as sp

    from lagcodegen.integrators.tableaux import Z

    R = sp.lambdify(Z, scheme.stability_polynomial(), "numpy")
    y = np.geomspace(1e-3, 10.0, 200001)
    too_big = 2 * 0.75 * steps * np.log(np.abs(R(1j * y))) > math.log(growth)
    return float(y[np.argmax(too_big)])


def stability_case(system) -> dict:
    p = parameter_vector(system)
    w = float(np.max(np.abs(np.linalg.eigvals(jacobian(system, np.asarray(CHAIN_X0), p)))))
    measured = {m: measures.measured_stability_limit(system, m, CHAIN_X0, w, steps=STABILITY_STEPS, hi=STABILITY_HI)
                for m in DEFAULT_METHODS}
    theory = {m: measures.theoretical_stability_limit(m) for m in DEFAULT_METHODS}
    finite = {m: finite_time_limit(m, STABILITY_STEPS) for m in DEFAULT_METHODS}
    return {"w": w, "measured": measured, "theory": theory, "finite": finite}


def energy_case(system, cfg, h: float = 0.01) -> dict:
    n = cfg["energy_steps"]
    trajectories, seconds = {}, {}
    for method in ENERGY_METHODS:
        start = time.perf_counter()
        trajectories[method] = simulate(system, PENDULUM_X0, n * h, h, method, energy=True,
                                        stride=max(1, n // 4000)).check()
        seconds[method] = time.perf_counter() - start
    return {"h": h, "n": n, "trajectories": trajectories, "seconds": seconds}


# -- report -----------------------------------------------------------------------------------
def work_precision_section(title: str, image: str, case: dict, unit: str) -> str:
    errors, times = error_and_time_tables(case["records"], case["steps"])
    return "\n\n".join([
        f"### {title}", f"![{title}](docs/{image})",
        "Each point is one run; down and to the left is better. lagcodegen's fixed-step methods: solid "
        "(explicit) and dash-dot (implicit) lines, one point per step count; scipy `solve_ivp` on the same "
        "compiled rhs: dashed grey, one point per tolerance (its time includes scipy's per-step Python "
        "overhead, which is what a user of scipy with a compiled rhs pays). rk4 and rk38 lie on top of "
        "each other. Runs with an error above 10 are left out of the figure.",
        case["check"] + ".",
        f"Max-norm error of x(t_end) [{unit}] (\"diverged\": the run overflowed):", errors,
        "wall time per run [ms] (best of at least three calls; includes ~10-20 us of Python call overhead):",
        times, "scipy `solve_ivp` on the same compiled rhs (Radau with the compiled analytic Jacobian):",
        scipy_table(case["scipy"])])


def orders_section(pendulum: dict, chain: dict) -> str:
    op, oc = orders(pendulum["records"]), orders(chain["records"])
    rows = [[m, get_scheme(m).order, fmt(op[m], ".2f"), fmt(oc[m], ".2f")] for m in DEFAULT_METHODS]
    return "\n\n".join([
        "### Observed order of convergence",
        f"Least-squares slope of log(error) against log(h) (`measures.observed_order`) over the "
        f"{ORDER_POINTS} smallest steps whose error lies in [{ORDER_WINDOW[0]:.0e}, {ORDER_WINDOW[1]:.0e}] "
        "(above the reference floor, below errors of order one; \"-\": fewer than two such runs). "
        "The max-norm mixes position and speed errors, so a slope can sit between two orders while "
        "one term still dominates: on the chain symplectic Euler's speed error is second order in this "
        "range (its position error is first order), and dopri5 on the linear chain is still approaching "
        "its asymptotic order 5 from above.",
        markdown_table(["method", "declared order", "double pendulum", "stiff chain"], rows)])


def stability_section(stab: dict) -> str:
    w = stab["w"]
    rows = []
    for m in DEFAULT_METHODS:
        measured = stab["measured"][m]
        shown = f"no limit found up to {STABILITY_HI:g}" if math.isinf(measured) else fmt(measured, ".4g")
        h_max = "-" if math.isinf(measured) else fmt(measured / w, ".3g")
        rows.append([m, fmt(stab["theory"][m], ".4g"), fmt(stab["finite"][m], ".4g"), shown, h_max])
    return "\n\n".join([
        "### Linear stability on the stiff chain", "![Stability limits](docs/stability.png)",
        "Largest step (as h*w) that keeps an undamped oscillation bounded: measured on the stiff chain "
        "excited in its stiff mode, beside the limit on the imaginary axis of each method's stability "
        "region. Hatched bars: no limit (the implicit methods are A-stable).",
        f"Fastest frequency w = {w:.6g} rad/s (largest |eigenvalue| of the Jacobian). \"theory\": "
        f"largest h*w with |R(i h w)| <= 1 (from the tableau's stability polynomial; symplectic Euler 2; "
        f"implicit A-stable methods: no limit). \"finite-time theory\": the h*w at which |R|^2 per step "
        f"grows the energy 10x over the 1500 steps between the run's first and last quarter. "
        f"\"measured\": `measures.measured_stability_limit`, {STABILITY_STEPS} steps per trial.",
        markdown_table(["method", "theory h*w", "finite-time theory h*w", "measured h*w", "largest stable h [s]"],
                       rows)])


def energy_section(energy: dict) -> str:
    rows = []
    for m, traj in energy["trajectories"].items():
        d = measures.energy_drift(traj)
        rows.append([m, fmt(energy["seconds"][m], ".3g"), fmt(d["max_abs"]), fmt(d["max_rel"]), fmt(d["rate"]),
                     fmt(d["final"])])
    t_end = energy["n"] * energy["h"]
    return "\n\n".join([
        "### Energy error of the double pendulum", "![Energy error](docs/energy_error.png)",
        "The symplectic methods keep the energy error bounded with no drift: the implicit midpoint rule "
        "(second order) and symplectic Euler in momentum form (p = M(q) u; first order, so its bounded "
        "error is larger); rk4 and dopri5 drift linearly.",
        f"{energy['n']:.0e} steps of h = {energy['h']:g} s (t = 0 .. {t_end:g} s), E0 = "
        f"{measures.energy_drift(next(iter(energy['trajectories'].values())))['e0']:.6g} J. "
        "drift rate: slope of a least-squares line through E(t) - E0.",
        markdown_table(["method", "wall time [s]", "max abs(E - E0) [J]", "relative", "drift rate [J/s]",
                        "E(t_end) - E0 [J]"], rows)])


# -- figures ----------------------------------------------------------------------------------
def save(fig, path: Path) -> None:
    fig.savefig(path, dpi=100)
    print(f"wrote {path}", file=sys.stderr)


def write_figures(out: Path, pendulum, chain, stab, energy) -> None:
    fig = figures.plot_work_precision(
        pendulum["records"] + pendulum["scipy"],
        "Double pendulum, 10 s from q = (1.0, 0.5) rad, at rest: error vs cost",
        max_error=10.0, error_label="max-norm error of x(10 s)  [rad, rad/s]")
    ax = fig.axes[0]
    ax.axhline(pendulum["reference_error"], color="grey", linewidth=0.8, linestyle=":",
               label="reference accuracy\n(DOP853 vs Radau)")
    ax.legend(loc="center left", bbox_to_anchor=(1.01, 0.5), fontsize="small")
    save(fig, out / "work_precision_double_pendulum.png")
    save(figures.plot_work_precision(
        chain["records"] + chain["scipy"],
        "Stiff chain (K = 1e4, w = 141 rad/s), 1 s, stiff mode excited: error vs cost",
        max_error=10.0, error_label="max-norm error of x(1 s)  [m, m/s]  (reference: exact)"),
        out / "work_precision_stiff_chain.png")
    save(figures.plot_stability(
        stab["measured"], stab["theory"], searched_up_to=STABILITY_HI,
        title=f"Largest stable step on the stiff chain (undamped, w = {stab['w']:.1f} rad/s)",
        note=(f"measured: largest h*w at which a {STABILITY_STEPS}-step run's energy does not grow 10x. "
              "A finite run cannot see a very slow growth, so Euler, Heun and dopri5 (|R| just above 1) "
              "measure above their theoretical limit.")),
        out / "stability.png")
    labels = {"symplectic_euler": "symplectic_euler (momentum form)"}
    order = ("implicit_midpoint", "symplectic_euler", "rk4", "dopri5")  # the dense band first, below
    trajectories = {labels.get(m, m): energy["trajectories"][m] for m in order}
    save(figures.plot_energy_error(
        trajectories, f"Double pendulum energy error, {energy['n']:,} steps of h = {energy['h']:g} s, "
        f"E(0) = {measures.energy_drift(trajectories['rk4'])['e0']:.4g} J"), out / "energy_error.png")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps and one timing repeat (~15 s)")
    parser.add_argument("--out", type=Path, default=DOCS, help="directory for the PNGs and charts.md")
    args = parser.parse_args(argv)
    cfg = settings(args.quick)
    args.out.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()
    pendulum_system = compile_model(catalog.double_pendulum())
    chain_system = compile_model(catalog.stiff_chain())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # diverged runs are expected data points
        pendulum, chain = pendulum_case(pendulum_system, cfg), chain_case(chain_system, cfg)
        stab = stability_case(chain_system)
    energy = energy_case(pendulum_system, cfg)
    write_figures(args.out, pendulum, chain, stab, energy)
    text = "\n\n".join([
        "<!-- generated by `python docs/make_charts.py" + (" --quick" if args.quick else "") + "`; do not edit -->",
        "## Accuracy, cost and stability",
        "Image paths are relative to the repository root. Errors and stability limits are reproducible; "
        "times are wall seconds (best of repeats) on the machine that ran the script and vary by some tens of percent from "
        "run to run.", orders_section(pendulum, chain), stability_section(stab),
        energy_section(energy),
        work_precision_section("Work-precision: double pendulum, 10 s", "work_precision_double_pendulum.png",
                               pendulum, "rad, rad/s"),
        work_precision_section("Work-precision: stiff chain, 1 s", "work_precision_stiff_chain.png", chain,
                               "m, m/s")]) + "\n"
    (args.out / "charts.md").write_text(text, encoding="utf-8")
    print(text)
    print(f"total {time.perf_counter() - start:.1f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
