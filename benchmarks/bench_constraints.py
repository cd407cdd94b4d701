"""Suite `constraints`: the price of Lagrange's equations of the first kind on the slider-crank.

Models: ``catalog.slider_crank()`` (redundant coordinates q = (theta, xc, yc, phi, s), n = 5,
closed by m = 4 holonomic constraints; first kind, multipliers solved at every rhs evaluation)
and ``catalog.slider_crank_minimal()`` (the same mechanism in the crank angle theta alone;
second kind). Both are compiled with ``pipeline.compile_model(..., methods=("rk4",))`` into a
temporary cache, so the build is real (its time is reported, never charged to a step).

Scenarios (the catalog's default parameters unless said):

swing   theta0 = 0.3 rad, theta_d0 = 0 (tau = 1 N m, g = 9.81): the crank swings between
        about -1.6 and 0.3 rad; bounded motion.
spin    theta0 = 0, theta_d0 = 20 rad/s, tau = 0: the crank keeps turning at 19..21 rad/s
        (about 190 turns in 100 s), through every configuration of the mechanism.

The redundant initial state is ``catalog.slider_crank_state(theta0, theta_d0)`` (consistent to
round-off). Variants of the redundant model:

redundant      no stabilization (baumgarte_alpha = baumgarte_beta = 0, no projection);
baumgarte 10   parameters baumgarte_alpha = baumgarte_beta = 10;
baumgarte 50   parameters baumgarte_alpha = baumgarte_beta = 50;
projection     ``simulate(..., project=True)``: after every step Gauss-Newton on phi, then the
               linear velocity projection (alpha = beta = 0).

1. Cost. ``simulate.simulate`` of each variant and of the minimal model over N = 1e5 steps
   (``--quick`` 1e4) of rk4 with h = 1e-4, stride N (two samples kept), check_stability=False;
   wall clock of the whole call (argument checks, output allocation and one cffi call into
   the generated C loop: the Python part is microseconds against tens of ms), best of
   ``--constraints-repeat`` (default 5) calls in one process, after one untimed warm-up call
   each, the variants timed round robin. Reported as ns per step and the ratio to the minimal
   model (and to the unstabilized redundant model).
2. Drift. One run per variant of up to ``--constraints-max-steps`` (default 1e6, ``--quick``
   1e5) rk4 steps with h = 1e-4, stride 1, ``residuals=True``: max over every step so far and
   over the 4 constraints of |phi| (m) and of |A u + dphi/dt| (m/s), read after 1e3, 1e4, 1e5
   (1e6) steps (one run, read at each checkpoint: the same numbers as separate shorter runs).
3. Accuracy. The crank angle theta of those runs at each checkpoint against the minimal
   model's rk4 run with the same h (|theta_redundant - theta_minimal|, rad). To tell truncation
   error from round-off, the minimal model and every variant are also run at h / 2 (twice the
   steps, same times, stride 2, no residuals): |minimal(h) - minimal(h/2)| estimates the minimal
   run's own error (15/16 of rk4's truncation error, plus round-off), and a variant's difference
   from the minimal model at h / 2 that is 16x smaller than at h is rk4 truncation error of the
   variant's formulation (it vanishes as h^4), while one that stays put is round-off. The
   minimal model is also compared with scipy DOP853 at rtol = atol = 1e-13 on its compiled rhs
   (``simulate.solve_reference``), with how far that reference moves at 1e-12 (where the shift
   exceeds the difference, the reference does not resolve rk4's error).

Every measurement (cost, drift, reference; per scenario) runs in a fresh process under a hard
time-out (``--timeout``, default 300 s per phase; import + derive + build get 240 s more).
No goal thresholds were set by the issue: the goal lines are UNDECIDED and state the measured
price.

Run through the suite runner: ``python benchmarks/run.py constraints [--quick]``.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import emit, fmt, format_table, progress, run_worker  # noqa: E402

DESCRIPTION = "slider-crank, Lagrange I vs minimal coordinates: ns/step, drift and accuracy against steps"
H = 1e-4
COST_STEPS = {False: 100_000, True: 10_000}      # key: --quick
MAX_STEPS = {False: 1_000_000, True: 100_000}
DEFAULT_REPEAT = 5
DEFAULT_TIMEOUT = 300.0
IMPORT_TIMEOUT = 240.0    # imports + derive + compile of both models
SCENARIOS = {  # name -> (theta0, theta_d0, parameter overrides, description)
    "swing": (0.3, 0.0, {}, "theta0 = 0.3 rad, theta_d0 = 0, defaults (tau = 1 N m, g = 9.81)"),
    "spin": (0.0, 20.0, {"tau": 0.0}, "theta0 = 0, theta_d0 = 20 rad/s, tau = 0 (g = 9.81)"),
}
VARIANTS = {  # name -> (simulate keyword arguments, parameter overrides); "minimal" is the other model
    "redundant": ({}, {}),
    "baumgarte 10": ({}, {"baumgarte_alpha": 10.0, "baumgarte_beta": 10.0}),
    "baumgarte 50": ({}, {"baumgarte_alpha": 50.0, "baumgarte_beta": 50.0}),
    "projection": ({"project": True}, {}),
}
MINIMAL = "minimal"


def halved(name: str) -> str:
    """The drift worker's name of run ``name`` repeated at h / 2."""
    return f"{name} h/2"


HALF = halved(MINIMAL)


# -- workers (fresh process each) ----------------------------------------------------------------
def _compile_both():
    """(redundant system, minimal system, seconds to derive + build each)."""
    from lagcodegen import catalog
    from lagcodegen.pipeline import compile_model

    start = time.perf_counter()
    redundant = compile_model(catalog.slider_crank(), methods=("rk4",))
    middle = time.perf_counter()
    minimal = compile_model(catalog.slider_crank_minimal(), methods=("rk4",))
    return redundant, minimal, {"redundant": middle - start, "minimal": time.perf_counter() - middle}


def _runs(scenario: str):
    """variant -> (system, x0, simulate kwargs) for one scenario, minimal model first."""
    from lagcodegen import catalog

    redundant, minimal, build_seconds = _compile_both()
    theta0, omega0, params, _ = SCENARIOS[scenario]
    runs = {MINIMAL: (minimal, (theta0, omega0), {"params": dict(params)})}
    x0 = catalog.slider_crank_state(theta0, omega0)
    for name, (kwargs, extra) in VARIANTS.items():
        runs[name] = (redundant, x0, {**kwargs, "params": {**params, **extra}})
    return runs, build_seconds


def worker_cost(scenario: str, steps: str, repeat: str) -> None:
    from lagcodegen.run.simulate import simulate

    steps, repeat = int(steps), int(repeat)
    runs, build_seconds = _runs(scenario)
    emit(phase="ready", build_seconds=build_seconds)

    def call(name):
        system, x0, kwargs = runs[name]
        start = time.perf_counter()
        trajectory = simulate(system, x0, steps * H, H, "rk4", stride=steps, check_stability=False, **kwargs)
        return time.perf_counter() - start, trajectory

    last = {name: call(name)[1] for name in runs}  # one untimed warm-up call each
    times = {name: [] for name in runs}
    for _ in range(repeat):  # round robin, so a disturbance of the shared machine hits every variant alike
        for name in runs:
            seconds, last[name] = call(name)
            times[name].append(seconds)
    for name in runs:
        emit(phase="variant", variant=name, seconds=min(times[name]), all_seconds=times[name], steps=steps,
             status=int(last[name].status), theta_final=float(last[name].x[-1, 0]))


def _checkpoints(max_steps: int) -> list:
    return [10 ** k for k in range(3, 7) if 10 ** k <= max_steps]


def worker_drift(scenario: str, max_steps: str) -> None:
    import warnings

    import numpy as np

    from lagcodegen.run.simulate import simulate

    max_steps = int(max_steps)
    checkpoints = _checkpoints(max_steps)
    runs, build_seconds = _runs(scenario)
    emit(phase="ready", build_seconds=build_seconds)
    for name, (system, x0, kwargs) in runs.items():
        residuals = name != MINIMAL
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)  # a failed run is reported by its status
            trajectory = simulate(system, x0, max_steps * H, H, "rk4", stride=1, check_stability=False,
                                  residuals=residuals, **kwargs)
        seconds = time.perf_counter() - start
        kept = len(trajectory.t)  # samples 0 .. kept - 1 (all of them when the run completed)
        points = []
        if residuals:
            m = trajectory.residuals.shape[1] // 2
            phi = np.maximum.accumulate(np.abs(trajectory.residuals[:, :m]).max(axis=1))
            rate = np.maximum.accumulate(np.abs(trajectory.residuals[:, m:]).max(axis=1))
        for k in checkpoints:
            if k >= kept:
                points.append({"steps": k, "reached": False})
                continue
            point = {"steps": k, "reached": True, "theta": float(trajectory.x[k, 0])}
            if residuals:
                point.update(max_phi=float(phi[k]), max_rate=float(rate[k]))
            points.append(point)
        emit(phase="variant", variant=name, seconds=seconds, status=int(trajectory.status),
             failed_step=trajectory.failed_step, points=points)
        del trajectory
    # every run again at h / 2 (rk4 truncation error 16x smaller), sampled at the same times
    for name, (system, x0, kwargs) in runs.items():
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", RuntimeWarning)
            half = simulate(system, x0, max_steps * H, H / 2, "rk4", stride=2, check_stability=False,
                            **kwargs)
        kept = len(half.t)
        emit(phase="variant", variant=halved(name), seconds=time.perf_counter() - start,
             status=int(half.status), failed_step=half.failed_step,
             points=[{"steps": k, "reached": k < kept, "theta": float(half.x[k, 0]) if k < kept else None}
                     for k in checkpoints])
        del half


def worker_reference(scenario: str, max_steps: str) -> None:
    from lagcodegen import catalog
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import solve_reference

    theta0, omega0, params, _ = SCENARIOS[scenario]
    system = compile_model(catalog.slider_crank_minimal(), methods=("rk4",))
    emit(phase="ready")
    checkpoints = _checkpoints(int(max_steps))
    t_eval = [0.0] + [k * H for k in checkpoints]
    found = {}
    for tol in (1e-13, 1e-12):
        start = time.perf_counter()
        _, x = solve_reference(system, (theta0, omega0), t_eval, params=params, rtol=tol, atol=tol)
        found[f"{tol:g}"] = ([float(v) for v in x[1:, 0]], time.perf_counter() - start)
    emit(phase="done", checkpoints=checkpoints, theta=found["1e-13"][0], theta_loose=found["1e-12"][0],
         seconds=found["1e-13"][1] + found["1e-12"][1])


# -- parent side ---------------------------------------------------------------------------------
def _collect(args: list, timeouts: list, env: dict) -> dict:
    """Run a worker; ``variants`` maps variant -> its message, the rest merged."""
    from _common import run_messages

    messages, status = run_messages(__file__, args, timeouts, env)
    merged = {"status": status, "variants": {}}
    for message in messages:
        if message.get("phase") == "variant":
            merged["variants"][message["variant"]] = message
        else:
            merged.update({k: v for k, v in message.items() if k != "phase"})
    return merged


def measure(options) -> dict:
    timeout = options.timeout or DEFAULT_TIMEOUT
    quick = bool(options.quick)
    repeat = max(1, getattr(options, "constraints_repeat", None) or DEFAULT_REPEAT)
    max_steps = getattr(options, "constraints_max_steps", None) or MAX_STEPS[quick]
    steps = COST_STEPS[quick]
    n_runs = 1 + len(VARIANTS)
    cache = Path(tempfile.mkdtemp(prefix="lcg-bench-cache-"))
    env = {"LAGCODEGEN_CACHE_DIR": str(cache)}
    data = {"timeout": timeout, "repeat": repeat, "cost_steps": steps, "max_steps": int(max_steps),
            "checkpoints": _checkpoints(int(max_steps)), "scenarios": {}}
    try:
        for scenario in SCENARIOS:
            part = {}
            part["cost"] = _collect(["cost", scenario, steps, repeat],
                                    [IMPORT_TIMEOUT + timeout] + [timeout] * n_runs, env)
            progress(f"constraints: {scenario} cost {part['cost']['status']}")
            part["drift"] = _collect(["drift", scenario, int(max_steps)],
                                     [IMPORT_TIMEOUT + timeout] + [timeout] * (2 * n_runs), env)
            progress(f"constraints: {scenario} drift {part['drift']['status']}")
            part["reference"] = run_worker(__file__, ["reference", scenario, int(max_steps)],
                                           [IMPORT_TIMEOUT + timeout, timeout], env)
            progress(f"constraints: {scenario} reference {part['reference']['status']}")
            data["scenarios"][scenario] = part
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return data


def analyse(data: dict) -> list:
    """One JSON row per measurement: cost rows, drift rows (variant x checkpoint), reference rows."""
    rows = []
    for scenario, part in data["scenarios"].items():
        cost = part["cost"]["variants"]
        base = cost.get(MINIMAL)
        plain = cost.get("redundant")
        for name, message in cost.items():
            ns = 1e9 * message["seconds"] / message["steps"]
            rows.append({"kind": "cost", "scenario": scenario, "variant": name, "steps": message["steps"],
                         "h": H, "seconds": message["seconds"], "all_seconds": message["all_seconds"],
                         "ns_per_step": ns, "status": message["status"],
                         "ratio_minimal": message["seconds"] / base["seconds"] if base else None,
                         "ratio_redundant": message["seconds"] / plain["seconds"] if plain else None})
        drift = part["drift"]["variants"]
        theta_of = {name: {p["steps"]: p.get("theta") for p in message["points"]}
                    for name, message in drift.items()}
        ref = part["reference"]
        ref_theta = dict(zip(ref.get("checkpoints", []), ref.get("theta", [])))
        ref_loose = dict(zip(ref.get("checkpoints", []), ref.get("theta_loose", [])))
        for name, message in drift.items():
            for point in message["points"]:
                k = point["steps"]
                row = {"kind": "drift", "scenario": scenario, "variant": name, "steps": k, "h": H,
                       "reached": point["reached"], "status": message["status"],
                       "failed_step": message["failed_step"], "run_seconds": message["seconds"],
                       "max_phi": point.get("max_phi"), "max_rate": point.get("max_rate"),
                       "theta": point.get("theta"), "theta_minus_minimal": None,
                       "theta_minus_reference": None}
                # a variant against the minimal model at the same h; the minimal model at h/2 against h
                base = MINIMAL if name in (MINIMAL, HALF) or not name.endswith(" h/2") else HALF
                if point["reached"] and name != MINIMAL and theta_of.get(base, {}).get(k) is not None:
                    row["theta_minus_minimal"] = point["theta"] - theta_of[base][k]
                if point["reached"] and k in ref_theta:
                    row["theta_minus_reference"] = point["theta"] - ref_theta[k]
                rows.append(row)
        for k in ref_theta:
            rows.append({"kind": "reference", "scenario": scenario, "steps": k, "t": k * H,
                         "theta": ref_theta[k], "shift_at_1e-12": ref_loose[k] - ref_theta[k]})
    return rows


# -- report --------------------------------------------------------------------------------------
def _pick(rows, **match):
    return [r for r in rows if all(r.get(k) == v for k, v in match.items())]


def _one(rows, **match):
    found = _pick(rows, **match)
    return found[0] if found else None


def _steps_label(k: int) -> str:
    return f"1e{len(str(k)) - 1}"


def _cost_table(rows, scenarios) -> str:
    header = ["variant"]
    for s in scenarios:
        header += [f"{s} ns/step", "/ minimal", "/ redundant"]
    body = []
    for name in [MINIMAL, *VARIANTS]:
        cells = [name]
        for s in scenarios:
            r = _one(rows, kind="cost", scenario=s, variant=name)
            if r is None:
                cells += ["-", "-", "-"]
                continue
            flag = "" if r["status"] == 0 else f" (status {r['status']})"
            cells += [f"{r['ns_per_step']:.0f}{flag}", fmt(r["ratio_minimal"], ".2f"),
                      fmt(r["ratio_redundant"], ".2f") if name != MINIMAL else "-"]
        body.append(cells)
    return format_table(header, body, left=1)


def _drift_cell(r, field) -> str:
    if r is None:
        return "-"
    if not r["reached"]:
        return f"failed@{r['failed_step']}"
    return fmt(r[field], ".1e")


def _drift_table(rows, scenarios, checkpoints, field, variants) -> str:
    header = ["scenario", "variant"] + [f"{_steps_label(k)} steps" for k in checkpoints]
    body = []
    for s in scenarios:
        for name in variants:
            body.append([s, name] + [_drift_cell(_one(rows, kind="drift", scenario=s, variant=name, steps=k),
                                                  field) for k in checkpoints])
    return format_table(header, body, left=2)


def _abs_cell(r, field, missing: str = "-") -> str:
    """|r[field]| as .1e; ``failed@<step>`` when the run stopped before this checkpoint."""
    if r is None:
        return missing
    if not r["reached"]:
        return f"failed@{r['failed_step']}"
    return fmt(None if r[field] is None else abs(r[field]), ".1e", missing)


def _accuracy_table(rows, scenarios, checkpoints) -> str:
    header = ["scenario", "run"] + [f"{_steps_label(k)} steps" for k in checkpoints]
    lines = [("minimal - reference", MINIMAL, "theta_minus_reference"),
             ("minimal(h/2) - minimal", HALF, "theta_minus_minimal")]
    lines += [(f"{name} - minimal", name, "theta_minus_minimal") for name in VARIANTS]
    lines += [(f"{name} - minimal, at h/2", halved(name), "theta_minus_minimal") for name in VARIANTS]
    body = []
    for s in scenarios:
        ref = {r["steps"]: r for r in _pick(rows, kind="reference", scenario=s)}
        body.append([s, "reference theta [rad]"] + [fmt(ref[k]["theta"], ".6f") if k in ref else "-"
                                                     for k in checkpoints])
        body.append([s, "reference shift at 1e-12"]
                    + [fmt(abs(ref[k]["shift_at_1e-12"]), ".1e") if k in ref else "-" for k in checkpoints])
        for label, variant, field in lines:
            found = [_one(rows, kind="drift", scenario=s, variant=variant, steps=k) for k in checkpoints]
            body.append([s, label] + [_abs_cell(r, field) for r in found])
    return format_table(header, body, left=2)


def format_report(data: dict, rows: list) -> str:
    import platform

    from _common import compiler_version, peer_versions
    from peers import default_flags

    import lagcodegen

    scenarios = list(data["scenarios"])
    checkpoints = data["checkpoints"]
    builds = {s: part["cost"].get("build_seconds") for s, part in data["scenarios"].items()}
    first_build = next((b for b in builds.values() if b), None)
    statuses = {f"{s} {kind}": part[kind]["status"] for s, part in data["scenarios"].items()
                for kind in ("cost", "drift", "reference")}
    bad = {k: v for k, v in statuses.items() if v != "ok"}
    drift_seconds = {s: [sum(m["seconds"] for name, m in part["drift"]["variants"].items()
                             if name.endswith(" h/2") == half) for half in (False, True)]
                     for s, part in data["scenarios"].items()}
    ref_seconds = {s: part["reference"].get("seconds") for s, part in data["scenarios"].items()}
    head = [
        f"constraints suite: lagcodegen {lagcodegen.__version__}, "
        f"{peer_versions('numpy', 'scipy', 'cffi', 'sympy')}, "
        f"Python {platform.python_version()}, {compiler_version()}, flags {' '.join(default_flags())}",
        "models: catalog.slider_crank() (n = 5 redundant coordinates, m = 4 holonomic constraints, "
        "Lagrange I) and catalog.slider_crank_minimal() (theta only, Lagrange II); both "
        "compile_model(methods=('rk4',))"
        + (f", derive + build {first_build['redundant']:.1f} s / {first_build['minimal']:.1f} s (not charged)"
           if first_build else ""),
        "scenarios: " + "; ".join(f"{s}: {SCENARIOS[s][3]}" for s in scenarios)
        + "; redundant x0 = catalog.slider_crank_state(theta0, theta_d0)",
        "variants: redundant = no stabilization; baumgarte A = params baumgarte_alpha = baumgarte_beta = A; "
        "projection = simulate(project=True) (Gauss-Newton on phi, then velocity projection, every step)",
        f"cost: rk4, h = {H:g}, {data['cost_steps']:.0e} steps, stride = all steps (2 samples kept), "
        f"check_stability=False; time = wall clock of the whole simulate() call (one cffi call into the "
        f"generated C loop), best of {data['repeat']} (after a warm-up call, variants round robin) in "
        f"one fresh process per scenario; "
        f"ns/step = time / steps",
        f"drift: one stride-1 run per variant, rk4 h = {H:g}, up to {data['max_steps']:.0e} steps, "
        f"residuals=True; max over all steps so far and over the 4 constraints; all runs took "
        + ", ".join(f"{s} {drift_seconds[s][0]:.1f} s (at h/2: {drift_seconds[s][1]:.1f} s)"
                    for s in scenarios)
        + " (memory not measured: stride 1 "
        f"keeps {data['max_steps'] + 1:.0e} x 18 doubles per run)",
        "accuracy: |theta| differences [rad] at each checkpoint; 'at h/2' = both runs repeated with rk4 at "
        "h/2 and sampled at the same times (truncation error shrinks 16x, round-off does not); "
        "minimal(h/2) - minimal estimates the minimal run's own error; reference = scipy DOP853 rtol = "
        "atol = 1e-13 on the minimal model's compiled rhs ("
        + ", ".join(f"{s} {fmt(ref_seconds[s], '.1f')} s" for s in scenarios) + " for both tolerances)",
        f"time-out: {data['timeout']:g} s per phase (+{IMPORT_TIMEOUT:g} s for import, derive and build); "
        f"a run that stopped early shows failed@<step>"
        + (f"; worker status: {bad}" if bad else ""),
    ]
    parts = [
        "\n".join(head),
        "cost per rk4 step (ns); / minimal = variant time / minimal-coordinates time\n\n"
        + _cost_table(rows, scenarios),
        "drift: max |phi| [m] over all steps up to N\n\n"
        + _drift_table(rows, scenarios, checkpoints, "max_phi", list(VARIANTS)),
        "drift: max |A u + dphi/dt| [m/s] over all steps up to N\n\n"
        + _drift_table(rows, scenarios, checkpoints, "max_rate", list(VARIANTS)),
        "accuracy: crank angle theta after N steps (rk4, same h); differences in rad\n\n"
        + _accuracy_table(rows, scenarios, checkpoints),
    ]
    return "\n\n".join(parts)


def goals(rows: list, data: dict) -> list:
    result = []
    scenarios = list(data["scenarios"])
    last = data["checkpoints"][-1] if data["checkpoints"] else None

    def cost_detail(name):
        parts = []
        for s in scenarios:
            r, base = (_one(rows, kind="cost", scenario=s, variant=v) for v in (name, MINIMAL))
            if r is None or base is None or r["ratio_minimal"] is None:
                parts.append(f"{s}: not measured")
            else:
                parts.append(f"{s} {r['ratio_minimal']:.1f}x "
                             f"({r['ns_per_step']:.0f} vs {base['ns_per_step']:.0f} ns)")
        return ", ".join(parts)

    for name, what in (("redundant", "redundant coordinates without stabilization cost"),
                       ("projection", "projection costs"),
                       ("baumgarte 10", "Baumgarte (alpha = beta = 10) costs")):
        detail = cost_detail(name)
        ok = "not measured" not in detail
        result.append({"goal": f"price of the first kind: {name} vs minimal per rk4 step",
                      "status": "UNDECIDED" if ok else "NOT RUN",
                      "detail": f"{what} the minimal model per step: {detail}; "
                                f"no threshold set by the issue"})

    def drift_at(s, name, field, k):
        r = _one(rows, kind="drift", scenario=s, variant=name, steps=k)
        if r is None:
            return "not measured"
        return f"failed@{r['failed_step']}" if not r["reached"] else f"{r[field]:.1e}"

    if last is not None:
        first = data["checkpoints"][0]
        parts = []
        for s in scenarios:
            parts.append(f"{s}: no stabilization {drift_at(s, 'redundant', 'max_phi', first)} -> "
                         f"{drift_at(s, 'redundant', 'max_phi', last)} ({_steps_label(first)} -> "
                         f"{_steps_label(last)} steps); "
                         f"with projection {drift_at(s, 'projection', 'max_phi', last)}, "
                         f"Baumgarte 10 {drift_at(s, 'baumgarte 10', 'max_phi', last)}, "
                         f"Baumgarte 50 {drift_at(s, 'baumgarte 50', 'max_phi', last)}")
        ok = all("not measured" not in p for p in parts)
        result.append({"goal": "constraint drift max |phi| [m] against steps",
                      "status": "UNDECIDED" if ok else "NOT RUN",
                      "detail": "; ".join(parts) + "; no threshold set by the issue"})
        parts = []
        for s in scenarios:
            diffs = []
            for name in VARIANTS:
                pair = [_one(rows, kind="drift", scenario=s, variant=v, steps=last)
                        for v in (name, halved(name))]
                at_h, at_half = (_abs_cell(r, "theta_minus_minimal", "not measured") for r in pair)
                diffs.append(f"{name} {at_h} ({at_half} at h/2)")
            minimal_half = _one(rows, kind="drift", scenario=s, variant=HALF, steps=last)
            own = _abs_cell(minimal_half, "theta_minus_minimal")
            parts.append(f"{s}: |theta - theta_minimal| after {_steps_label(last)} steps: " + ", ".join(diffs)
                         + f"; the minimal run's own error |theta(h/2) - theta(h)|: {own}")
        ok = all("not measured" not in p for p in parts)
        result.append({"goal": "stabilization does not spoil accuracy (final crank angle vs minimal model)",
                      "status": "UNDECIDED" if ok else "NOT RUN",
                      "detail": "; ".join(parts) + "; no threshold set by the issue"})
    return result


# -- suite protocol ------------------------------------------------------------------------------
def add_arguments(group) -> None:
    group.add_argument("--constraints-repeat", type=int, default=None, metavar="R",
                       help=f"timed simulate calls per cost cell, best reported (default {DEFAULT_REPEAT})")
    group.add_argument("--constraints-max-steps", type=int, default=None, metavar="N",
                       help=f"longest drift run in steps, checkpoints 1e3, 1e4, ... up to N (default "
                            f"{MAX_STEPS[False]:.0e}, --quick {MAX_STEPS[True]:.0e})")


def run(options) -> dict:
    """Measure cost, drift and accuracy side by side; {"table", "rows", "goals"} (see run.py)."""
    data = measure(options)
    rows = analyse(data)
    return {"table": format_report(data, rows), "rows": rows, "goals": goals(rows, data)}


WORKERS = {"cost": worker_cost, "drift": worker_drift, "reference": worker_reference}

if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker" and sys.argv[2] in WORKERS:
        WORKERS[sys.argv[2]](*sys.argv[3:])
    else:
        sys.exit("bench_constraints.py is a suite module; run: python benchmarks/run.py constraints")
