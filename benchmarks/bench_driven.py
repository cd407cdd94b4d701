"""Suite `driven`: what inputs cost. A double pendulum driven by two joint torques (tau1, tau2).

Three measurements, in one fresh worker process (derivation and compilation never timed; every
figure is the best of ``--driven-repeat`` runs, default 5, on a shared machine):

    inputs vs none     ns per RK4 step of ``simulate`` (2e6 steps, h = 1e-3, one sample kept per
                       1e4 steps) of the same equations twice: the torques as constant parameters
                       (no inputs), and as inputs r: a constant (zero-order hold), a 101-knot table
                       interpolated in C (ZOH, and first-order hold: the stages on a ramp)
    step Jacobian      one ``step_jacobian_rk4`` call (x+, dx+/dx 4x4 and dx+/dr 4x2, exact)
                       against the floor of central finite differences of the compiled step: 12 RK4
                       steps (2 per column of [x, r]) at the ns/step measured above, with no Python
                       overhead; the Jacobian is timed through cffi, so the comparison favours the
                       finite differences. Also the largest difference between the two
    driven sweep       member-steps per CPU-second of ``sweep`` over 16 tau1 amplitudes x 16 masses
                       m1, threads = 1: driven (inputs constant per member, which the lane kernel
                       takes as parameters; and the scalar kernel, which reads input tables) and the
                       undriven model (torques as parameters) on the scalar and the lane kernel

Goals (from issue 13): a step with inputs within 1.05x of the step without (ZOH); the step
Jacobian faster than finite differences (and exact); the driven sweep (lane kernel) >= 10
million member-steps/s per core, the per-core goal of the sweep suite.

Run through the suite runner: ``python benchmarks/run.py driven [--quick]``.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import emit, fmt, format_table, progress, run_worker  # noqa: E402

DESCRIPTION = "driven double pendulum: ns/step with inputs vs without, step Jacobian vs finite differences, sweep"
STEPS = {False: 2_000_000, True: 200_000}
H = 1e-3


def add_arguments(group) -> None:
    group.add_argument("--driven-repeat", type=int, default=5, metavar="R", help="best of R runs (default 5)")


def double_pendulum(driven: bool):
    """The catalog double pendulum (bodies route) with joint torques tau1 (on q1) and tau2 (the
    relative joint): inputs when ``driven``, else parameters (the same arithmetic, read from p)."""
    import dataclasses

    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import catalog

    base = catalog.double_pendulum()
    q1, q2 = base.coordinates
    if driven:
        tau1, tau2 = me.dynamicsymbols("tau1 tau2")
        extra = {"inputs": [tau1, tau2]}
    else:
        tau1, tau2 = sp.symbols("tau1 tau2")
        extra = {"parameters": tuple(base.parameters) + (tau1, tau2),
                 "parameter_values": dict(base.parameter_values) | {tau1: 0.3, tau2: -0.2}}
    return dataclasses.replace(base, name="driven_dp" if driven else "torqued_dp",
                               generalized_forces={q1: tau1 - tau2, q2: tau2}, **extra)


def worker_measure(quick: str, repeat: str) -> None:
    import numpy as np
    from _common import best_seconds

    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate, step_jacobians
    from lagcodegen.run.sweep import sweep

    quick, repeat = quick == "1", int(repeat)
    steps = STEPS[quick]
    driven = compile_model(double_pendulum(True), methods=("rk4",), outputs=("rhs", "step_jacobian"))
    torqued = compile_model(double_pendulum(False), methods=("rk4",), lanes=4)
    x0 = [1.0, 0.5, 0.0, 0.0]
    t_end = steps * H
    knots = np.linspace(0.0, t_end, 101)
    table = (knots, np.column_stack([0.3 * np.cos(knots), -0.2 * np.ones_like(knots)]))
    runs = {
        "no inputs (torques as parameters)": (torqued, {}),
        "inputs: constant, ZOH": (driven, {"inputs": [0.3, -0.2]}),
        "inputs: 101-knot table, ZOH": (driven, {"inputs": table}),
        "inputs: 101-knot table, FOH": (driven, {"inputs": table, "hold": "foh"}),
    }
    ns = {}
    for name, (system, kw) in runs.items():
        call = lambda: simulate(system, x0, t_end=t_end, h=H, stride=10_000, check_stability=False, **kw)  # noqa: E731
        ns[name] = best_seconds(call, repeat) / steps * 1e9
        progress(f"{name}: {ns[name]:.1f} ns/step")
    emit(ns_per_step=ns)
    # the same two runs give the same state when the inputs equal the parameters
    a = simulate(torqued, x0, t_end=1.0, h=H).x[-1]
    b = simulate(driven, x0, t_end=1.0, h=H, inputs=[0.3, -0.2]).x[-1]
    emit(same_state=float(np.abs(a - b).max()))

    p = np.array([dict(driven.layout.defaults)[k] for k in driven.layout.parameters])
    x, r = np.array([0.4, -0.3, 0.2, 0.1]), np.array([0.3, -0.2])
    n_calls = 20_000 if quick else 200_000
    ffi, lib, prefix = driven.ffi, driven.lib, driven.layout.prefix
    c_jacobian = getattr(lib, f"{prefix}_step_jacobian_rk4")
    t_c, x_c, r_c, p_c = ffi.new("double *"), ffi.new("double[]", list(x)), ffi.new("double[]", list(r)), \
        ffi.new("double[]", list(p))
    Fx_c, Fr_c = ffi.new("double[]", 16), ffi.new("double[]", 8)
    work_c = ffi.new("double[]", int(getattr(lib, f"{prefix.upper()}_WORK_JACOBIAN_RK4")))

    def jacobians():
        for _ in range(n_calls):
            c_jacobian(t_c, x_c, r_c, p_c, H, Fx_c, Fr_c, work_c)
    jac_us = best_seconds(jacobians, repeat) / n_calls * 1e6
    _, Fx, Fr = step_jacobians(driven, x, p, H, r=r)
    eps = 1e-6
    step = lambda xx, rr: step_jacobians(driven, xx, p, H, r=rr)[0]  # noqa: E731
    fd_x = np.column_stack([(step(x + eps * e, r) - step(x - eps * e, r)) / (2 * eps) for e in np.eye(4)])
    fd_r = np.column_stack([(step(x, r + eps * e) - step(x, r - eps * e)) / (2 * eps) for e in np.eye(2)])
    floor_us = 12 * ns["inputs: constant, ZOH"] / 1e3
    emit(jacobian_us=jac_us, fd_floor_us=floor_us,
         fd_difference=float(max(np.abs(Fx - fd_x).max(), np.abs(Fr - fd_r).max())))
    progress(f"step Jacobian {jac_us:.2f} us per call; finite-difference floor {floor_us:.2f} us")

    amplitudes, masses = np.linspace(0.1, 1.0, 16), np.linspace(0.5, 2.0, 16)
    sweep_steps = 2_000 if quick else 20_000
    rates = {}
    held = {"inputs": {"tau1": 1.0, "tau2": -0.2}}
    cases = {"driven, lane kernel": (driven, {"tau1": amplitudes}, held, "lanes"),
             "driven, scalar kernel": (driven, {"tau1": amplitudes}, held, "scalar"),
             "no inputs, scalar kernel": (torqued, {"tau1": amplitudes}, {}, "scalar"),
             "no inputs, lane kernel": (torqued, {"tau1": amplitudes}, {}, "lanes")}
    for name, (system, grid, kw, kernel) in cases.items():
        def go():
            return sweep(system, grid | {"m1": masses}, x0={"q1": 1.0, "q2": 0.5}, t_end=sweep_steps * H, h=H,
                         threads=1, track_energy=False, kernel=kernel, progress=False, **kw)
        best = float("inf")
        for _ in range(repeat):
            start = time.process_time()
            result = go()
            best = min(best, time.process_time() - start)
        assert (result.status == 0).all()
        rates[name] = 256 * sweep_steps / best
        progress(f"sweep {name}: {rates[name] / 1e6:.2f} M member-steps per CPU-s")
    emit(sweep_rates=rates)


def run(options) -> dict:
    timeout = options.timeout or 900.0
    progress("driven: one worker (compile, then measure)")
    data = run_worker(__file__, ["measure", int(options.quick), options.driven_repeat], [timeout] * 4)
    rows, goals = [], []
    ns = data.get("ns_per_step", {})
    base = ns.get("no inputs (torques as parameters)")
    lines = [f"RK4 steps of simulate, h = {H:g}, {STEPS[options.quick]:.0e} steps, best of {options.driven_repeat} "
             f"(wall clock); worker status: {data['status']}"]
    body = []
    for name, value in ns.items():
        ratio = value / base if base else None
        rows.append({"measure": "ns_per_step", "case": name, "ns": value, "ratio": ratio})
        body.append([name, fmt(value, ".1f"), fmt(ratio, ".3f")])
    lines.append(format_table(["case", "ns/step", "vs none"], body))
    if "same_state" in data:
        lines.append(f"the same motion with inputs and with parameters: max state difference {data['same_state']:.1e}")
    zoh = ns.get("inputs: constant, ZOH")
    goals.append(_goal("a step with inputs (ZOH) within 1.05x of one without",
                       None if not (zoh and base) else zoh / base <= 1.05, f"{zoh / base:.3f}x" if zoh and base else ""))
    if "jacobian_us" in data:
        lines.append(f"\nstep_jacobian_rk4 (through cffi): {data['jacobian_us']:.2f} us per call; finite differences "
                     f"need 12 steps = {data['fd_floor_us']:.2f} us at the C step's speed (no Python); largest "
                     f"difference between them {data['fd_difference']:.1e}")
        rows.append({"measure": "step_jacobian", "us": data["jacobian_us"], "fd_floor_us": data["fd_floor_us"],
                     "fd_difference": data["fd_difference"]})
        goals.append(_goal("the step Jacobian faster than finite differences of the step",
                           data["jacobian_us"] < data["fd_floor_us"],
                           f"{data['jacobian_us']:.2f} us vs {data['fd_floor_us']:.2f} us"))
    else:
        goals.append(_goal("the step Jacobian faster than finite differences of the step", None, "not measured"))
    rates = data.get("sweep_rates", {})
    if rates:
        lines.append("\nsweep, 256 members (16 tau1 amplitudes x 16 m1), threads = 1, member-steps per CPU-second:")
        lines.append(format_table(["case", "M member-steps/CPU-s"], [[k, f"{v / 1e6:.2f}"] for k, v in rates.items()]))
        rows += [{"measure": "sweep", "case": k, "member_steps_per_cpu_s": v} for k, v in rates.items()]
    driven_rate = rates.get("driven, lane kernel")
    goals.append(_goal(">= 10 M member-steps/s per core for the driven double pendulum sweep",
                       None if driven_rate is None else driven_rate >= 1e7,
                       "" if driven_rate is None else f"{driven_rate / 1e6:.2f} M"))
    return {"table": "\n".join(lines), "rows": rows, "goals": goals}


def _goal(text: str, passed, detail: str) -> dict:
    status = "NOT RUN" if passed is None else ("PASS" if passed else "FAIL")
    return {"goal": text, "status": status, "detail": detail}


WORKERS = {"measure": worker_measure}

if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker" and sys.argv[2] in WORKERS:
        WORKERS[sys.argv[2]](*sys.argv[3:])
    else:
        sys.exit("bench_driven.py is a suite module; run: python benchmarks/run.py driven")
