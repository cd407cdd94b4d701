"""Elastic pendulum over spring stiffness k and natural length l0: the 2:1 internal resonance.

A ball (m = 1 kg) on a spring swings in a vertical plane. Its two small-oscillation modes are
the spring mode, omega_r = sqrt(k/m), and the swing mode, omega_s = sqrt(g/r0), with the
static length r0 = l0 + m g / k. Started with a 10 % stretch of r0 and a tiny swing
(phi0 = 0.01 rad), the run stays a spring oscillation, except where omega_r = 2 omega_s: there
the bouncing pumps the swing parametrically and energy flows from the spring into the swing
and back. Solving omega_r = 2 omega_s for k gives the resonance curve

    k l0 = 3 m g        (k/m = 4 g / r0  with  r0 = l0 + m g / k),

which the map of max |phi| over the run shows as a ridge. (A 1:1 resonance cannot occur:
omega_r^2 = k/m > g/r0 = omega_s^2 for every k, l0.) Why k and l0 and not k and m: the
equations depend on k and m only through k/m, so a (k, m) map would be constant along every
ray k/m = const, whereas (k, l0) is a genuine 2-D family.

Every member starts from its own r = 1.1 r0(k, l0), so the sweep is an explicit member table
(columns l0, k and the initial r) whose members form a complete k x l0 grid. m and g are fixed
at build time (folded into the C); k and l0 are runtime inputs of the one compiled kernel.

Run: python examples/sweep_elastic_pendulum.py [--quick] [--out PATH] [--threads N]
"""
import argparse
import time
from pathlib import Path

import numpy as np

from lagcodegen import catalog
from lagcodegen.analysis.heatmaps import add_legend_entries, gridded, plot_heatmap
from lagcodegen.pipeline import compile_model
from lagcodegen.run.sweep import sweep

M, G = 1.0, 9.81          # kg, m/s^2 (fixed at build time)
PHI0 = 0.01               # rad, initial swing
STRETCH = 0.10            # initial r = (1 + STRETCH) r0
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "docs" / "sweep_elastic_pendulum.png"
#: (n_k, n_l0, t_end [s], h [s]): full size runs in ~20 s on 2 cores
FULL, QUICK = (72, 48, 120.0, 0.005), (10, 6, 10.0, 0.01)


def resonant_k(l0):
    """Spring stiffness of the 2:1 resonance sqrt(k/m) = 2 sqrt(g/r0): k = 3 m g / l0."""
    return 3 * M * G / np.asarray(l0)


def members(n_k: int, n_l0: int) -> dict:
    """Member table: every (l0, k) pair, each with its own initial r = (1 + STRETCH) r0."""
    ks, l0s = np.geomspace(5.0, 300.0, n_k), np.geomspace(0.25, 2.0, n_l0)
    l0, k = (a.ravel() for a in np.meshgrid(l0s, ks, indexing="ij"))
    return {"l0": l0, "k": k, "r": (1 + STRETCH) * (l0 + M * G / k)}


def ridge_report(result) -> None:
    """Per l0 row: the k of the largest max|phi| against the resonance curve."""
    (_, _), (l0s, ks), phi, _ = gridded(result, result.q_max[:, 1], x="k", y="l0")
    peak_k = ks[np.nanargmax(phi, axis=1)]
    ratio = peak_k / resonant_k(l0s)
    print(f"max|phi| over the map: {np.nanmax(phi):.3f} rad on the ridge, median {np.nanmedian(phi):.4f} rad "
          f"(phi0 = {PHI0} rad); all of the spring's energy k (STRETCH r0)^2 / 2 moved into the swing "
          f"m g r0 phi^2 / 2 at k/m = 4 g / r0 would give phi = 2 STRETCH = {2 * STRETCH:.2f} rad")
    for i in np.linspace(0, len(l0s) - 1, min(5, len(l0s))).astype(int):
        print(f"  l0 = {l0s[i]:.3f} m: ridge at k = {peak_k[i]:7.2f} N/m, theory 3 m g / l0 = "
              f"{resonant_k(l0s[i]):7.2f} N/m")
    print(f"ridge k / theory k over all {len(l0s)} rows: median {np.median(ratio):.3f}, "
          f"range {ratio.min():.3f} .. {ratio.max():.3f} (grid step in k: x{ks[1] / ks[0]:.3f})")


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny grid and short run (tests)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"PNG path (default {DEFAULT_OUT})")
    parser.add_argument("--threads", type=int, default=None, help="worker threads (default: all cores)")
    args = parser.parse_args(argv)
    n_k, n_l0, t_end, h = QUICK if args.quick else FULL

    start = time.perf_counter()
    system = compile_model(catalog.elastic_pendulum(), outputs=("rhs", "energy"), methods=("rk4",),
                           fixed={"m": M, "g": G})
    print(f"compiled {system.module_name} (free parameters {', '.join(system.layout.parameters)}) "
          f"in {time.perf_counter() - start:.1f} s")
    table = members(n_k, n_l0)
    start = time.perf_counter()
    result = sweep(system, members=table, x0={"r": 1.0, "phi": PHI0}, t_end=t_end, h=h, method="rk4",
                   threads=args.threads)
    elapsed = time.perf_counter() - start
    n_steps = round(t_end / h)
    print(f"{result.n_members} members x {n_steps} rk4 steps in {elapsed:.1f} s "
          f"({result.n_members * n_steps / elapsed / 1e6:.1f} M steps/s); "
          f"{int(np.sum(result.status != 0))} failed")
    r0 = table["l0"] + M * G / table["k"]
    energy0 = table["k"] * (STRETCH * r0) ** 2 / 2 + M * G * table["r"] * (1 - np.cos(PHI0))
    print(f"max |E - E0| / (energy above the rest state): {np.nanmax(result.energy_error / energy0):.1e}")
    ridge_report(result)

    fig = plot_heatmap(result, "q_max:phi", x="k", y="l0", log=True, label="max |phi| over the run [rad]",
                       title=f"Elastic pendulum (m = {M:g} kg): swing amplitude reached in {t_end:g} s\n"
                             f"from r = {1 + STRETCH:g} r0, phi = {PHI0:g} rad (rk4, h = {h:g} s)")
    ax = fig.axes[0]
    l0_line = np.geomspace(0.25, 2.0, 200)
    line, = ax.plot(resonant_k(l0_line), l0_line, "r--", linewidth=1.0,
                    label="2:1 resonance sqrt(k/m) = 2 sqrt(g/r0), i.e. k l0 = 3 m g (theory)")
    add_legend_entries(fig, [line])
    ax.set_xlabel("k: spring stiffness [N/m]")
    ax.set_ylabel("l0: natural length [m]")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
