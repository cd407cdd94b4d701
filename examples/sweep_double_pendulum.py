"""Double pendulum over mass ratio m2/m1 and length ratio l2/l1: time until the first flip.

Both links start at rest at q1 = q2 = 1.4 rad (80 degrees from the downward vertical). A *flip*
is the first time either link passes the upward vertical, |q1| > pi or |q2| > pi. With
m1 = 1 kg, l1 = 1 m and g = 9.81 m/s^2 fixed at build time, the one compiled kernel is swept
over m2 (= m2/m1) and l2 (= l2/l1) as runtime parameters.

Energy bound (the overlay): with mu = m2/m1, lambda = l2/l1 and c_i = cos(q_i(0)), the
initial energy E0 = -(1 + mu) c1 - mu lambda c2 (in m1 g l1) must reach the least potential
energy with a link upright, -|1 + mu - mu lambda| (outer link up over a hanging inner one, or
inner link up with the outer hanging). Inside the hatched band

    |1 + mu - mu lambda| < (1 + mu) c1 + mu lambda c2

no flip can ever happen; the script checks that no member there flips. Outside the band a flip
is allowed but not forced: the map shows where and how soon chaos delivers one within t_end.

Flip times come from trajectories kept every `stride`-th step (interpolated between samples;
`lagcodegen.analysis.heatmaps.first_crossing_time`). To bound memory the grid runs in batches of m2 rows
(at most MAX_TRAJECTORY_BYTES of trajectories at a time); only the flip times are kept.

Run: python examples/sweep_double_pendulum.py [--quick] [--out PATH] [--threads N]
"""
import argparse
import dataclasses
import math
import time
from pathlib import Path

import numpy as np
from matplotlib.patches import Patch
from tqdm.auto import tqdm

from lagcodegen import catalog
from lagcodegen.analysis.heatmaps import add_legend_entries, first_crossing_time, plot_heatmap
from lagcodegen.pipeline import compile_model
from lagcodegen.run.sweep import sweep

M1, L1, G = 1.0, 1.0, 9.81  # kg, m, m/s^2 (fixed at build time)
Q0 = {"q1": 1.4, "q2": 1.4}  # rad, both links at rest
MAX_TRAJECTORY_BYTES = 64 * 2 ** 20
DEFAULT_OUT = Path(__file__).resolve().parents[1] / "docs" / "sweep_double_pendulum.png"
#: (n_m2, n_l2, t_end [s], h [s], stride): full size runs in ~30-50 s on 2 cores
FULL, QUICK = (56, 56, 50.0, 0.002, 10), (6, 5, 4.0, 0.005, 4)


def flip_margin(mu, lam):
    """|1 + mu - mu lam| - E0-part: negative where no flip is energetically possible (docstring)."""
    c1, c2 = math.cos(Q0["q1"]), math.cos(Q0["q2"])
    return np.abs(1 + mu - mu * lam) - ((1 + mu) * c1 + mu * lam * c2)


def stack(parts, axes):
    """One SweepResult of the whole grid from row batches (C order is kept by concatenation)."""
    cat = lambda name: np.concatenate([getattr(part, name) for part in parts])  # noqa: E731
    return dataclasses.replace(
        parts[0], values=cat("values"), grid=axes, x_final=cat("x_final"), q_max=cat("q_max"),
        energy_error=cat("energy_error"), status=cat("status"), steps_done=cat("steps_done"),
        blowup_time=cat("blowup_time"), t=None, trajectories=None, completed=all(p.completed for p in parts))


def run(system, masses, lengths, t_end, h, stride, threads):
    """(SweepResult over m2 x l2, flip time per member), in batches of m2 rows."""
    n_out = round(t_end / h) // stride + 1
    rows = max(1, MAX_TRAJECTORY_BYTES // (len(lengths) * n_out * 2 * system.layout.n * 8))
    parts, flips = [], []
    with tqdm(total=len(masses) * len(lengths), unit="member", leave=False, delay=1.0) as bar:
        for start in range(0, len(masses), rows):
            part = sweep(system, {"m2": masses[start:start + rows], "l2": lengths}, x0=Q0, t_end=t_end, h=h,
                         method="rk4", trajectories=True, stride=stride, threads=threads, progress=False)
            flips.append(first_crossing_time(part, ("q1", "q2"), math.pi))
            parts.append(part)
            bar.update(part.n_members)
    return stack(parts, (masses, lengths)), np.concatenate(flips)


def report(result, flip, t_end) -> None:
    mu, lam = result.values[:, 0], result.values[:, 1]
    forbidden = flip_margin(mu, lam) < 0
    flipped = np.isfinite(flip)
    energy_scale = (M1 + mu) * G * L1 + mu * G * lam  # potential-energy range of the system
    print(f"flipped within {t_end:g} s: {flipped.sum()} of {result.n_members} members; flip time min "
          f"{np.nanmin(flip):.2f} s, median {np.nanmedian(flip):.2f} s, max {np.nanmax(flip):.2f} s "
          f"(time unit sqrt(l1/g) = {math.sqrt(L1 / G):.3f} s)")
    print(f"energetically forbidden band: {forbidden.sum()} members, of which flipped: "
          f"{(flipped & forbidden).sum()} (must be 0); allowed but no flip within t_end: "
          f"{(~flipped & ~forbidden).sum()}")
    print(f"max |E - E0| / ((m1 + m2) g l1 + m2 g l2): median {np.median(result.energy_error / energy_scale):.1e}, "
          f"max {np.max(result.energy_error / energy_scale):.1e}; failed members: {int(np.sum(result.status != 0))}")
    if (flipped & forbidden).any():
        raise SystemExit("a member flipped although its energy forbids it: the integration is wrong")


def draw_bound(ax, masses, lengths) -> None:
    """Hatch the band where the energy forbids any flip; outline it."""
    lam, mu = np.meshgrid(np.geomspace(lengths[0], lengths[-1], 400), np.geomspace(masses[0], masses[-1], 400))
    margin = flip_margin(mu, lam)
    ax.contourf(lam, mu, margin, levels=[margin.min() - 1, 0], colors="none", hatches=["///"])
    ax.contour(lam, mu, margin, levels=[0], colors="red", linewidths=1.0)
    band = Patch(facecolor="none", edgecolor="red", hatch="///",
                 label="energy forbids a flip: |1 + mu - mu lam| < (1 + mu) cos q1(0) + mu lam cos q2(0)")
    add_legend_entries(ax.figure, [band])


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="tiny grid and short run (tests)")
    parser.add_argument("--out", type=Path, default=DEFAULT_OUT, help=f"PNG path (default {DEFAULT_OUT})")
    parser.add_argument("--threads", type=int, default=None, help="worker threads (default: all cores)")
    args = parser.parse_args(argv)
    n_m, n_l, t_end, h, stride = QUICK if args.quick else FULL

    start = time.perf_counter()
    system = compile_model(catalog.double_pendulum(), outputs=("rhs", "energy"), methods=("rk4",),
                           fixed={"m1": M1, "l1": L1, "g": G})
    print(f"compiled {system.module_name} (free parameters {', '.join(system.layout.parameters)}) "
          f"in {time.perf_counter() - start:.1f} s")
    masses, lengths = np.geomspace(0.1, 10.0, n_m), np.geomspace(0.2, 5.0, n_l)
    start = time.perf_counter()
    result, flip = run(system, masses, lengths, t_end, h, stride, args.threads)
    elapsed = time.perf_counter() - start
    print(f"{result.n_members} members x {round(t_end / h)} rk4 steps in {elapsed:.1f} s "
          f"(trajectories every {stride * h:g} s, batches of <= {MAX_TRAJECTORY_BYTES >> 20} MiB)")
    report(result, flip, t_end)

    fig = plot_heatmap(result, flip, log=True, label="time until the first flip [s]",
                       nan_label=f"no flip within {t_end:g} s",
                       title=f"Double pendulum from rest at q1 = q2 = {Q0['q1']:g} rad: first |q1| or |q2| > pi\n"
                             f"m1 = {M1:g} kg, l1 = {L1:g} m (rk4, h = {h:g} s, t_end = {t_end:g} s)")
    ax = fig.axes[0]
    draw_bound(ax, masses, lengths)
    ax.set_xlabel("l2 / l1: length ratio")
    ax.set_ylabel("m2 / m1: mass ratio")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(args.out, dpi=110)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
