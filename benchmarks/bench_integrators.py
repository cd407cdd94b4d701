"""Suite `integrators`: time to reach a given accuracy on the double pendulum, ours against peers.

Problem: ``catalog.double_pendulum()`` with its default parameters (m1 = m2 = l1 = l2 = 1,
g = 9.81) from x0 = (q1, q2, u1, u2) = (1, 0.5, 0, 0) over t in [0, 10]. Error = max abs
difference of the final state from a reference: scipy DOP853 at rtol = atol = 1e-12 on
lagcodegen's compiled rhs (``simulate.solve_reference``); the header states how far that
reference moves when tightened to 1e-13.

Contenders, each in its own fresh process under a hard time-out; run times are the minimum of
5 runs (shared machine); compile times are measured once and never included:

ours        ``compile_model(double_pendulum())`` with all `schemes.DEFAULT_METHODS`; every method
            at N = 100 ... 10^6 steps (24 per decade, ``--quick`` 4; h = 10 / N), timed as one direct cffi call
            of the generated C ``lcg_double_pendulum_simulate`` (stride N: the first and last
            states are stored; the driver's per-step finiteness check included), so no Python
            overhead of `simulate.simulate` is counted. A method's scan stops once its error is
            below 1e-11, stops improving below 1e-8, or one run takes over 0.25 s.
hand RK4    ``hand_dp_rk4_run`` of ``peers/hand_double_pendulum.c`` (closed-form accelerations,
            constants hoisted), same N grid and stopping rule, compiled with lagcodegen's flags.
JiTCODE     ``jitcode`` of the same closed-form accelerations (parameters as ``control_pars``),
            compiled with its defaults (-O3 -ffast-math -march=native); scipy's ``ode``
            integrators ``dopri5`` and ``dop853`` through ``set_integrator`` at rtol = atol =
            1e-3 ... 1e-13 (6 per decade, ``--quick`` 1); timed: ``integrate(10.0)`` after
            ``set_initial_value``.
PyDy+DOP853 scipy ``solve_ivp(method="DOP853")`` at the same tolerances on PyDy's Cython rhs
            (``generate_ode_function(..., generator="cython")`` of KanesMethod's M, F). PyDy's rhs
            returns one buffer that it overwrites on every call, so it is wrapped in a copy (without,
            DOP853's reuse of the last derivative goes wrong).

For each error level 1e-3 ... 1e-10 every contender is charged its cheapest measured run with
error <= level (no interpolation); ratios are contender time / ours. Goal (from the issue): ours
faster than each contender at every level.

Run through the suite runner: ``python benchmarks/run.py integrators [--quick] [--timeout S]``.
"""
from __future__ import annotations

import json
import shutil
import sys
import tempfile
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import DP_STATE, emit, fmt, format_table, progress, run_messages, run_worker  # noqa: E402

DESCRIPTION = "double pendulum over 10 s: time to reach 1e-3..1e-10 error, ours vs hand RK4, JiTCODE, PyDy"
T_END = 10.0
LEVELS = tuple(10.0 ** -k for k in range(3, 11))
# grid density of N and of tolerances; key: --quick. 24 per decade (N ratio 1.10): at 8 (ratio 1.33)
# a contender could be charged up to a third more steps than it needs, which decided 1e-3 and 1e-4
PER_DECADE = {False: 24, True: 4}
REPEAT = 5
ERROR_FLOOR = 1e-11      # a scan stops below this: finer runs serve no level
ROUNDOFF_ZONE = 1e-8     # below this, an error that stops shrinking is roundoff
RUN_CAP_SECONDS = 0.25   # a scan stops when one run takes longer
DEFAULT_TIMEOUT = 300.0
IMPORT_TIMEOUT = 120.0
PARAMS = (1.0, 1.0, 1.0, 1.0, 9.81)  # m1 m2 l1 l2 g: the catalog's defaults, in p[] order
JITCODE_METHODS = ("dopri5", "dop853")


# -- workers (fresh process each) ----------------------------------------------------------------
def _compiled():
    from lagcodegen.catalog import double_pendulum
    from lagcodegen.pipeline import compile_model

    return compile_model(double_pendulum())


def worker_reference() -> None:
    from lagcodegen.run.simulate import solve_reference

    system = _compiled()
    emit(phase="ready")
    finals = {}
    for tol in (1e-12, 1e-13):
        _, x = solve_reference(system, DP_STATE, [0.0, T_END], rtol=tol, atol=tol)
        finals[f"{tol:g}"] = x[-1].tolist()
    emit(phase="done", reference=finals["1e-12"], tighter=finals["1e-13"])


def _error(x, reference) -> float:
    return max(abs(a - b) for a, b in zip(x, reference))


def step_counts(quick: bool) -> tuple:
    """N = 100 ... 10^6, PER_DECADE[quick] per decade, geometric."""
    k = PER_DECADE[quick]
    return tuple(sorted({int(round(10 ** (i / k))) for i in range(2 * k, 6 * k + 1)}))


def tolerances(quick: bool) -> tuple:
    """rtol = atol = 1e-3 ... 1e-13, PER_DECADE[quick] / 4 per decade (at least one)."""
    k = max(1, PER_DECADE[quick] // 4)
    return tuple(10.0 ** (-i / k) for i in range(3 * k, 13 * k + 1))


def _scan(run, reference, quick: bool) -> list:
    """[(N, seconds, final state or None, status)] over `step_counts` with the stopping rule;
    ``run(N)`` returns (status, final state) and is timed as the best of REPEAT."""
    import time

    points, best_error, stale = [], float("inf"), 0
    for N in step_counts(quick):
        start = time.perf_counter()
        status, x = run(N)
        first = time.perf_counter() - start
        if status != 0:
            points.append((N, first, None, status))
            continue
        best = first
        for _ in range(REPEAT - 1):
            start = time.perf_counter()
            run(N)
            best = min(best, time.perf_counter() - start)
        error = _error(x, reference)
        points.append((N, best, list(x), 0))
        stale = stale + 1 if error >= best_error else 0
        best_error = min(best_error, error)
        stalled = stale >= max(3, PER_DECADE[quick] // 2)  # half a decade of N without improvement
        if error < ERROR_FLOOR or best > RUN_CAP_SECONDS or (best_error < ROUNDOFF_ZONE and stalled):
            break
    return points


def _simulate_call(system, buffers: dict):
    """``call(method_number, h, N)`` of the generated C ``simulate``, arguments matched by name
    from its prototype in the built header, so a changed signature cannot silently shift them:
    named inputs and outputs from ``buffers``; any other pointer gets NULL, any other int 0."""
    import re

    layout, ffi, lib = system.layout, system.ffi, system.lib
    header = (system.path.parent / f"{layout.prefix}.h").read_text()
    params = re.search(rf"int\s+{layout.prefix}_simulate\(([^)]*)\)", header).group(1)
    names, fixed = [], {}
    for decl in params.split(","):
        name = decl.replace("*", " ").split()[-1]
        names.append(name)
        if name not in buffers and name not in ("method", "h", "n_steps", "stride"):
            if "*" in decl:
                fixed[name] = ffi.NULL
            elif decl.split()[-2] in ("int", "long"):
                fixed[name] = 0
            else:
                raise ValueError(f"simulate argument {decl.strip()!r} has no benchmark value")
    simulate_c = getattr(lib, f"{layout.prefix}_simulate")

    def call(number, h, N):
        values = {**buffers, **fixed, "method": number, "h": h, "n_steps": N, "stride": N}
        return simulate_c(*[values[name] for name in names])
    return call


def worker_ours(reference_json: str, quick: str) -> None:
    import numpy as np

    reference = json.loads(reference_json)
    system = _compiled()
    layout, ffi, lib = system.layout, system.ffi, system.lib
    emit(phase="ready", methods=list(layout.methods))
    work = np.empty(int(getattr(lib, f"{layout.prefix.upper()}_WORK_SIZE")))
    x0, p = np.array(DP_STATE, dtype=float), np.array(PARAMS)
    t_out, x_out = np.empty(2), np.empty((2, 2 * layout.n))
    buf = lambda a: ffi.from_buffer("double[]", a, require_writable=True)  # noqa: E731
    call = _simulate_call(system, {"t0": 0.0, "x0": buf(x0), "p": buf(p), "t_out": buf(t_out),
                                   "x_out": buf(x_out), "work": buf(work), "steps_done": ffi.new("long *")})
    for number, method in enumerate(layout.methods):
        def run(N, number=number):
            return call(number, T_END / N, N), x_out[-1].copy()
        emit(phase="method", method=method, points=_scan(run, reference, quick == "quick"))


def worker_hand(reference_json: str, quick: str) -> None:
    import numpy as np
    from peers import load_hand_double_pendulum

    reference = json.loads(reference_json)
    module = load_hand_double_pendulum()
    ffi, lib = module.ffi, module.lib
    emit(phase="ready")
    x0, p, out = np.array(DP_STATE, dtype=float), np.array(PARAMS), np.empty(4)
    px0, pp, pout = (ffi.from_buffer("double[]", a) for a in (x0, p, out))

    def run(N):
        lib.hand_dp_rk4_run(px0, pp, T_END / N, N, pout)
        return (0 if np.all(np.isfinite(out)) else 2), out.copy()
    emit(phase="method", method="rk4", points=_scan(run, reference, quick == "quick"))


def _closed_form_jitcode():
    """JiTCODE of the double pendulum: the hand C's closed-form accelerations in symengine."""
    import symengine as se
    from jitcode import jitcode, y

    m1, m2, l1, l2, g = se.symbols("m1 m2 l1 l2 g")
    q1, q2, u1, u2 = y(0), y(1), y(2), y(3)
    s, c = se.sin(q1 - q2), se.cos(q1 - q2)
    den = m1 + m2 * s ** 2
    ud1 = (-m2 * s * (l2 * u2 ** 2 + l1 * c * u1 ** 2) - (m1 + m2) * g * se.sin(q1)
           + m2 * g * c * se.sin(q2)) / (l1 * den)
    ud2 = ((m1 + m2) * (l1 * s * u1 ** 2 - g * se.sin(q2))
           + c * (m2 * l2 * s * u2 ** 2 + (m1 + m2) * g * se.sin(q1))) / (l2 * den)
    return jitcode([u1, u2, ud1, ud2], control_pars=[m1, m2, l1, l2, g], verbose=False)


def worker_jitcode(quick: str) -> None:
    import time
    import warnings

    import numpy as np

    ode = _closed_form_jitcode()
    emit(phase="ready")
    start = time.perf_counter()
    ode.compile_C()
    emit(phase="compiled", compile_seconds=time.perf_counter() - start)
    x0 = np.array(DP_STATE, dtype=float)
    for name in JITCODE_METHODS:
        points = []
        for tol in tolerances(quick == "quick"):
            best, x, status = float("inf"), None, 0
            try:
                ode.set_integrator(name, rtol=tol, atol=tol)
                ode.set_parameters(*PARAMS)
                for _ in range(REPEAT):
                    ode.set_initial_value(x0, 0.0)
                    with warnings.catch_warnings():
                        warnings.simplefilter("ignore")
                        start = time.perf_counter()
                        x = ode.integrate(T_END)
                        best = min(best, time.perf_counter() - start)
            except Exception as exc:  # noqa: BLE001  (UnsuccessfulIntegration and scipy's errors)
                status, x = f"failed: {type(exc).__name__}", None
            points.append((tol, best, None if x is None else np.asarray(x).tolist(), status))
        emit(phase="method", method=name, points=points)


def worker_pydy(quick: str) -> None:
    import time

    import numpy as np
    from _common import pydy_chain_rhs
    from scipy.integrate import solve_ivp

    emit(phase="ready")
    f, kane_seconds, generate_seconds = pydy_chain_rhs(2)
    emit(phase="compiled", kane_seconds=kane_seconds, generate_seconds=generate_seconds)
    x0, p = np.array(DP_STATE, dtype=float), np.array(PARAMS)
    # PyDy's argument order is (x, t, p), and its rhs returns one buffer it reuses on every call:
    # solve_ivp keeps the last derivative (FSAL), so without the copy the run goes wrong
    fun = lambda t, x: f(x, t, p).copy()  # noqa: E731
    points = []
    for tol in tolerances(quick == "quick"):
        best, x = float("inf"), None
        for _ in range(REPEAT):
            start = time.perf_counter()
            solution = solve_ivp(fun, (0.0, T_END), x0, method="DOP853", rtol=tol, atol=tol)
            best = min(best, time.perf_counter() - start)
            x = solution.y[:, -1]
        points.append((tol, best, x.tolist() if solution.success else None, 0 if solution.success else "failed"))
    emit(phase="method", method="DOP853", points=points)


# -- parent side ---------------------------------------------------------------------------------
CONTENDERS = {  # key -> label
    "hand": "hand RK4 (C)",
    "jitcode:dopri5": "JiTCODE dopri5",
    "jitcode:dop853": "JiTCODE dop853",
    "pydy:DOP853": "scipy DOP853 + PyDy Cython",
}


def _curves(result: dict, reference) -> dict:
    """method -> [(error, seconds, setting)] of the successful runs in a worker's messages."""
    return {method: [(_error(x, reference), seconds, setting)
                     for setting, seconds, x, status in points if status == 0 and x is not None]
            for method, points in result.get("methods_points", {}).items()}


def _collect(args: list, timeouts: list, env: dict | None = None) -> dict:
    """Run a worker whose messages include one per method; keep every method's points."""
    messages, status = run_messages(__file__, args, timeouts, env)
    merged = {"status": status, "methods_points": {}}
    for message in messages:
        if message.get("phase") == "method":
            merged["methods_points"][message["method"]] = message["points"]
        else:
            merged.update({k: v for k, v in message.items() if k != "phase"})
    return merged


def cheapest(curve: list, level: float):
    """(seconds, setting, error) of the cheapest run with error <= level, or None."""
    good = [(seconds, setting, error) for error, seconds, setting in curve if error <= level]
    return min(good) if good else None


def measure(timeout: float, quick: bool) -> dict:
    from lagcodegen.integrators.schemes import DEFAULT_METHODS

    cache = Path(tempfile.mkdtemp(prefix="lcg-bench-cache-"))
    env = {"LAGCODEGEN_CACHE_DIR": str(cache)}
    try:
        ref = run_worker(__file__, ["reference"], [IMPORT_TIMEOUT + timeout, timeout], env)
        if ref["status"] != "ok":
            return {"reference_status": ref["status"]}
        reference = ref["reference"]
        progress("integrators: reference done")
        ref_json, mode = json.dumps(reference), "quick" if quick else "full"
        ours = _collect(["ours", ref_json, mode], [IMPORT_TIMEOUT + timeout] + [timeout] * len(DEFAULT_METHODS), env)
        progress(f"integrators: ours {ours['status']}")
        hand = _collect(["hand", ref_json, mode], [IMPORT_TIMEOUT + timeout, timeout])
        progress(f"integrators: hand RK4 {hand['status']}")
        jit = _collect(["jitcode", mode], [IMPORT_TIMEOUT, timeout, timeout, timeout])
        progress(f"integrators: JiTCODE {jit['status']}")
        pydy = _collect(["pydy", mode], [IMPORT_TIMEOUT, timeout, timeout])
        progress(f"integrators: PyDy {pydy['status']}")
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return {"reference": reference, "reference_shift": _error(ref["tighter"], reference),
            "ours": ours, "hand": hand, "jitcode": jit, "pydy": pydy}


def analyse(data: dict) -> tuple[list, dict, dict]:
    """rows (one per level), ours' per-method curves, contenders' curves."""
    reference = data["reference"]
    ours = _curves(data["ours"], reference)
    jit = _curves(data["jitcode"], reference)
    others = {"hand": _curves(data["hand"], reference).get("rk4", []),
              "jitcode:dopri5": jit.get("dopri5", []), "jitcode:dop853": jit.get("dop853", []),
              "pydy:DOP853": _curves(data["pydy"], reference).get("DOP853", [])}
    rows = []
    for level in LEVELS:
        per_method = {m: cheapest(curve, level) for m, curve in ours.items()}
        reached = {m: v for m, v in per_method.items() if v is not None}
        best_method = min(reached, key=lambda m: reached[m][0]) if reached else None
        row = {"level": level, "ours_method": best_method,
               "ours_seconds": reached[best_method][0] if best_method else None,
               "ours_steps": reached[best_method][1] if best_method else None,
               "ours_per_method": {m: (v[0] if v else None) for m, v in per_method.items()}}
        for key, curve in others.items():
            found = cheapest(curve, level)
            row[key] = None if found is None else {"seconds": found[0], "setting": found[1], "error": found[2]}
        rows.append(row)
    return rows, ours, others


# -- report --------------------------------------------------------------------------------------
def _ms(seconds) -> str:
    return "-" if seconds is None else f"{1e3 * seconds:.3f}"


def _level_table(rows) -> str:
    body = []
    for r in rows:
        ours = r["ours_seconds"]
        cells = [f"{r['level']:.0e}", _ms(ours),
                 f"{r['ours_method']} N={r['ours_steps']}" if r["ours_method"] else "not reached"]
        for key in CONTENDERS:
            found = r[key]
            if found is None:
                cells.append("not reached")
            else:
                ratio = f" ({found['seconds'] / ours:.2f}x)" if ours else ""
                cells.append(_ms(found["seconds"]) + ratio)
        body.append(cells)
    header = ["level", "ours [ms]", "ours: method, steps"] + [f"{v} [ms] (/ours)" for v in CONTENDERS.values()]
    return format_table(header, body, left=1)


def _method_table(rows, methods) -> str:
    body = [[f"{r['level']:.0e}"] + [_ms(r["ours_per_method"].get(m)) for m in methods] for r in rows]
    return format_table(["level"] + list(methods), body)


def _settings_note(rows) -> str:
    parts = []
    for key, name in CONTENDERS.items():
        chosen = [f"{r['level']:.0e}: {'N=' if key == 'hand' else 'tol '}{r[key]['setting']:g}"
                  for r in rows if r[key] is not None]
        parts.append(f"    {name}: " + (", ".join(chosen) or "none"))
    return "\n".join(parts)


def _rk4_agreement(data) -> float | None:
    ours = {N: x for N, _, x, s in data["ours"]["methods_points"].get("rk4", []) if s == 0}
    hand = {N: x for N, _, x, s in data["hand"]["methods_points"].get("rk4", []) if s == 0}
    common = sorted(set(ours) & set(hand))
    return max(_error(ours[N], hand[N]) for N in common) if common else None


def format_report(data, rows, methods, timeout, quick) -> str:
    import platform

    from _common import compiler_version, peer_versions
    from peers import default_flags

    import lagcodegen

    jit, pydy = data["jitcode"], data["pydy"]
    per_decade = PER_DECADE[quick]
    agreement = _rk4_agreement(data)
    head = [
        f"integrators suite: lagcodegen {lagcodegen.__version__}, "
        f"{peer_versions('jitcode', 'symengine', 'pydy', 'Cython', 'scipy', 'numpy')}, "
        f"Python {platform.python_version()}, {compiler_version()}",
        f"double pendulum (m = l = 1, g = 9.81), x0 = {DP_STATE}, t = 0..{T_END:g} s; error = max abs "
        f"final-state error vs scipy DOP853 rtol = atol = 1e-12 on our rhs (that reference moves "
        f"{data['reference_shift']:.1e} at 1e-13)",
        f"time: wall clock, minimum (best) of {REPEAT} runs on a shared 2-core machine; each "
        f"contender in a fresh process, time-out {timeout:g} s per phase; compile times excluded:",
        f"    ours: direct cffi call of the generated C simulate (no Python in the loop), flags "
        f"{' '.join(default_flags())}; N = 100..1e6 steps, {per_decade} per decade, every DEFAULT_METHOD",
        f"    hand RK4: peers/hand_double_pendulum.c hand_dp_rk4_run, same flags, same N grid "
        f"(agrees with our rk4 at equal N to {fmt(agreement, '.1e')})",
        f"    JiTCODE: compiled rhs (its defaults: -O3 -ffast-math -march=native), scipy ode "
        f"dopri5/dop853, rtol = atol = 1e-3..1e-13, {max(1, per_decade // 4)} per decade; compile "
        f"{fmt(jit.get('compile_seconds'), '.1f', jit['status'])} s, not included",
        f"    scipy DOP853 + PyDy: solve_ivp on PyDy's Cython rhs (its reused output buffer copied), same "
        f"tolerances; PyDy "
        f"generate + compile {fmt(pydy.get('generate_seconds'), '.1f', pydy['status'])} s, not included",
        "each level charges a contender its cheapest measured run with error <= level (no "
        "interpolation); (/ours) = contender time / ours time, > 1 means ours is faster",
    ]
    return "\n".join(head) + "\n\n" + _level_table(rows) + \
        "\n\nsettings chosen per level:\n" + _settings_note(rows) + \
        "\n\nours per method: cheapest run [ms] reaching each level ('-': not reached on the N grid)\n\n" + \
        _method_table(rows, methods)


def goals(rows, statuses: dict | None = None) -> list:
    """PASS/FAIL per contender; UNDECIDED when its worker (or ours) did not finish: a level it did
    not reach then says nothing (found by review: PASS against a JiTCODE that failed to import)."""
    statuses = statuses or {}
    found = []
    for key, name in CONTENDERS.items():
        goal = f"ours faster than {name} at every level 1e-3..1e-10"
        broken = {worker: statuses[worker] for worker in ("ours", key.split(":")[0])
                  if statuses.get(worker, "ok") != "ok"}
        if broken:
            found.append({"goal": goal, "status": "UNDECIDED",
                          "detail": "worker did not finish: " + ", ".join(f"{w}: {s}" for w, s in broken.items())})
            continue
        failing, detail = [], []
        for r in rows:
            ours, other = r["ours_seconds"], r[key]
            if ours is None:
                failing.append(r["level"])
                detail.append(f"{r['level']:.0e}: ours not reached")
            elif other is None:
                detail.append(f"{r['level']:.0e}: peer not reached")
            else:
                ratio = other["seconds"] / ours
                detail.append(f"{r['level']:.0e}: {ratio:.2f}x")
                if ratio <= 1.0:
                    failing.append(r["level"])
        found.append({"goal": goal, "status": "FAIL" if failing else "PASS", "detail": ", ".join(detail)})
    return found


# -- suite protocol ------------------------------------------------------------------------------
def run(options) -> dict:
    """Measure every contender's error-time curve; {"table", "rows", "goals"} (see run.py)."""
    timeout = options.timeout or DEFAULT_TIMEOUT
    data = measure(timeout, options.quick)
    if "reference" not in data:
        detail = f"reference failed: {data['reference_status']}"
        return {"table": f"integrators suite: {detail}", "rows": [],
                "goals": [{"goal": f"ours faster than {n} at every level", "status": "NOT RUN", "detail": detail}
                          for n in CONTENDERS.values()]}
    rows, ours, _ = analyse(data)
    methods = data["ours"].get("methods") or list(ours)
    table = format_report(data, rows, methods, timeout, options.quick)
    statuses = {k: data[k]["status"] for k in ("ours", "hand", "jitcode", "pydy")}
    raw = [{"curve": key, "points": points} for part in ("ours", "hand", "jitcode", "pydy")
           for key, points in data[part]["methods_points"].items()]
    found = goals(rows, statuses)
    for g in found:
        if any(s != "ok" for s in statuses.values()):
            g["detail"] += f" (worker status: {statuses})"
    return {"table": table, "rows": rows + raw, "goals": found}


WORKERS = {"reference": worker_reference, "ours": worker_ours, "hand": worker_hand,
           "jitcode": worker_jitcode, "pydy": worker_pydy}

if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker" and sys.argv[2] in WORKERS:
        WORKERS[sys.argv[2]](*sys.argv[3:])
    else:
        sys.exit("bench_integrators.py is a suite module; run: python benchmarks/run.py integrators")
