"""Suite `rolling`: the thin disc rolling without slipping in 3D (two velocity constraints with
multipliers, tests/constraints/test_rolling_disc.py's model) in a sweep over its initial spin rate.

In one fresh worker (derivation and compilation never timed): the cold ``compile_model`` time, ns
per RK4 step of ``simulate`` (h = 1e-3, 1e5 steps; with and without projection onto the
constraints after every step) and member-steps per CPU-second of ``sweep`` over 64 initial spin
rates (each member's rolling speed x' = r phi' consistent with it), threads = 1, projection on;
best of ``--rolling-repeat`` runs (default 3).

Goal (issue 14): stated as member-steps per second per core; no peer figure exists in this
suite yet (PyDy's Cython code for the same model is the issue's bicycle comparison, not built
here), so the line reports the figure as UNDECIDED.

Run through the suite runner: ``python benchmarks/run.py rolling [--quick]``.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import emit, format_table, progress, run_worker  # noqa: E402

DESCRIPTION = "rolling disc (velocity constraints, multipliers): compile, ns/step, sweep over the spin rate"
HERE = Path(__file__).resolve().parent
STEPS = {False: 100_000, True: 10_000}


def add_arguments(group) -> None:
    group.add_argument("--rolling-repeat", type=int, default=3, metavar="R", help="best of R runs (default 3)")


def worker_measure(quick: str, repeat: str) -> None:
    import importlib.util
    import tempfile

    import numpy as np
    from _common import best_seconds

    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate
    from lagcodegen.run.sweep import sweep

    spec = importlib.util.spec_from_file_location("rolling", HERE.parent / "tests" / "constraints" / "test_rolling_disc.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    quick, repeat = quick == "1", int(repeat)
    steps = STEPS[quick]
    start = time.perf_counter()
    with tempfile.TemporaryDirectory() as cache:
        system = compile_model(module.rolling_disc(), methods=("rk4",), cache_dir=cache)
        emit(compile_s=time.perf_counter() - start)
        spin = 1.5 * module.CRITICAL
        x0 = [0, 0, 0, 0, 0, spin, 0, 0, 1e-3, spin]
        ns = {}
        for project in (False, True):
            seconds = best_seconds(lambda: simulate(system, x0, t_end=steps * 1e-3, h=1e-3, project=project,
                                                    stride=1000, check_stability=False), repeat)
            ns["projection" if project else "no projection"] = seconds / steps * 1e9
        emit(ns_per_step=ns)
        spins = np.linspace(0.5, 2.0, 64)
        members = {"phi_d": spins, "x_d": spins, "theta_d": np.full(64, 1e-3)}  # r = 1: x' = r phi'
        sweep_steps = steps // 10
        best = float("inf")
        for _ in range(repeat):
            begin = time.process_time()
            result = sweep(system, members=members, x0=[0] * 10, t_end=sweep_steps * 1e-3, h=1e-3, threads=1,
                           project=True, track_energy=False, progress=False)
            best = min(best, time.process_time() - begin)
        # found by review: the rate counted every member's steps whatever their statuses; a member that
        # stops early did less work, so a sweep with failures has no rate
        failed = int(np.count_nonzero((result.status != 0) | (result.steps_done != sweep_steps)))
        emit(sweep_rate=None if failed else 64 * sweep_steps / best, failed=failed,
             statuses=sorted({int(s) for s in result.status}))
    progress("rolling: done")


def run(options) -> dict:
    data = run_worker(__file__, ["measure", int(options.quick), options.rolling_repeat], [options.timeout or 600.0] * 3)
    ns = data.get("ns_per_step", {})
    lines = [f"thin rolling disc, 5 coordinates, 2 velocity constraints; RK4, h = 1e-3; worker status: {data['status']}",
             f"cold compile_model: {data.get('compile_s', float('nan')):.2f} s",
             format_table(["simulate", "ns/step"], [[k, f"{v:.1f}"] for k, v in ns.items()])]
    rate = data.get("sweep_rate")
    if data.get("failed"):
        lines.append(f"sweep over 64 spin rates: {data['failed']} members failed (statuses {data.get('statuses')}): "
                     "no rate")
    if rate:
        lines.append(f"sweep over 64 spin rates, threads = 1, projection on: {rate / 1e6:.2f} M member-steps per "
                     f"CPU-second (statuses {data.get('statuses')})")
    rows = [{"measure": "ns_per_step", "case": k, "ns": v} for k, v in ns.items()]
    rows.append({"measure": "sweep", "member_steps_per_cpu_s": rate, "compile_s": data.get("compile_s")})
    goals = [{"goal": "rolling disc sweep: member-steps per second per core (no peer measured yet)",
              "status": "UNDECIDED" if rate else "NOT RUN",
              "detail": f"{rate / 1e6:.2f} M" if rate else ""}]
    return {"table": "\n".join(lines), "rows": rows, "goals": goals}


WORKERS = {"measure": worker_measure}

if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker" and sys.argv[2] in WORKERS:
        WORKERS[sys.argv[2]](*sys.argv[3:])
    else:
        sys.exit("bench_rolling.py is a suite module; run: python benchmarks/run.py rolling")
