"""Suite `kernels`: from equations to C -- operation counts, pipeline time, cost per evaluation.

Models: the double pendulum (``catalog.double_pendulum()``) and the planar n-link chain
(``catalog.pendulum_chain(n)``), n = 5, 10, 20 (``--quick``: 5); op counts also at n = 15, the
size the issue quotes. Every measurement runs in a fresh Python process under a hard time-out
(`bench_derive.run_in_subprocess`); imports are never timed.

1. Operations after CSE, four counts side by side:

   ours           ``reduce_expressions(eom, ("rhs",)).kernel("dynamics").ops_after``: sympy
                  ``count_ops`` of the temporaries and results (M lower triangle and F; qd = u
                  is a copy) -- the LDL^T solve is not a sympy expression and is not included;
   ours C         the same kernel counted in the emitted C (`_common.count_c_ops`: every
                  ``+ - * /``, unary minus and call), M, F part and, separately, the unrolled
                  LDL^T factorization and substitution;
   closed form    a hand-structured chain written here: M_jk = mu_max(j,k) l_j l_k cos(q_j - q_k),
                  F_j = -l_j sum_k mu_max(j,k) l_k sin(q_j - q_k) u_k^2 - g mu_j l_j sin q_j with
                  mu_j = m_j + mu_(j+1) (n - 1 additions), CSE'd by sympy, count_ops (checked
                  against lagcodegen's M and F at a sample state);
   Kane + cse     ``sympy.cse`` of KanesMethod's M (all n*n entries) and F for the same chain
                  (bench_derive's peer model, u = qd, dynamicsymbols replaced by symbols), count_ops;
   PyDy C         PyDy's ``CMatrixGenerator([q, u, p], [M, F])`` (its own sympy CSE and C99
                  printer, the code behind its Cython backend), counted in its C text like ours C.

2. Pipeline time (wall clock, the Model is built before the timer starts): *cold* =
   ``compile_model(model)`` with its defaults (all `schemes.DEFAULT_METHODS` and the outputs they
   need) into an empty ``LAGCODEGEN_CACHE_DIR``: derive + reduce + render + build, each stage's
   share shown; *warm* = the same call in a fresh process on that populated cache (a hit:
   checked that nothing new appears in the cache). Peer: PyDy's Cython backend, ``generate_ode_function(..., generator="cython")``
   from KanesMethod's M, F (its generate + compile, the Kane derivation shown apart).

3. Cost of one right-hand-side evaluation (q, u) -> (qd, ud), i.e. one solve for qdd:
   in C, through `_common.rhs_harness`: a C loop calling ``lcg_<model>_rhs`` (and the hand-written
   ``hand_dp_rhs`` of ``peers/hand_double_pendulum.c``, double pendulum only) compiled as separate
   translation units with lagcodegen's own flags; *independent* = 256 different states in turn
   (throughput), *chained* = explicit Euler steps, each evaluation waiting for the previous one
   (latency). The hand C is checked against lagcodegen's rhs at random states and parameters
   to 1e-12 (relative to max(1, |value|)) before timing. From Python, as users call them: ours
   through ``simulate.make_rhs`` and PyDy's Cython rhs ``f(x, t, p)`` (its numpy solve included).

Goals (from the issue): ops at n = 15 within 1.1x of the hand-structured closed form's ~1,270;
qdd evaluation within 1.1x of hand C (double pendulum, both loops); cold pipeline of the double
pendulum under 1 s; warm under 50 ms.

Run through the suite runner: ``python benchmarks/run.py kernels [--quick] [--timeout S]``.
"""
from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import DP, count_c_ops, emit, fmt, format_table, label, links, model_of, parse_tag, progress, run_worker  # noqa: E402

DESCRIPTION = "equations to C: ops after CSE, cold/warm pipeline, ns per qdd vs hand C, PyDy Cython"
TAGS_FULL = (DP, 5, 10, 20)
TAGS_QUICK = (DP, 5)
OPS_EXTRA = 15  # op counts only: the issue's reference size
ISSUE_OPS_N15 = 1270
DEFAULT_TIMEOUT = 300.0
IMPORT_TIMEOUT = 120.0
OPS_GOAL_RATIO = 1.1
QDD_GOAL_RATIO = 1.1
COLD_GOAL_SECONDS = 1.0
WARM_GOAL_SECONDS = 0.050
N_STATES = 256
SPEED_REPEAT = 7  # at least this many timing runs (each >= 50 ms) per evaluation cost


# -- workers (fresh process each) ----------------------------------------------------------------
def _closed_form(eom):
    """(M lower + F) of the hand-structured chain in eom's symbols, and the mu definitions."""
    import sympy as sp

    n = eom.n
    by_name = {p.name: p for p in eom.parameters}
    m = [by_name[f"m{i + 1}"] for i in range(n)]
    l = [by_name[f"l{i + 1}"] for i in range(n)]
    g, q, u = by_name["g"], eom.q, eom.u
    mu = sp.symbols(f"mu1:{n + 1}")
    M = [mu[j] * l[j] ** 2 if j == k else mu[j] * l[j] * l[k] * sp.cos(q[j] - q[k])
         for j in range(n) for k in range(j + 1)]
    F = [-l[j] * sp.Add(*[mu[max(j, k)] * l[k] * sp.sin(q[j] - q[k]) * u[k] ** 2 for k in range(n) if k != j])
         - g * mu[j] * l[j] * sp.sin(q[j]) for j in range(n)]
    mu_values = {}
    for j in reversed(range(n)):
        mu_values[mu[j]] = m[j] + (mu_values[mu[j + 1]] if j + 1 < n else 0)
    return M, F, mu_values


def worker_ops(tag) -> None:
    import numpy as np
    import sympy as sp

    from lagcodegen import derive_equations
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources

    emit(phase="ready")
    eom = derive_equations(model_of(tag))
    system = reduce_expressions(eom, ("rhs",))
    kernel = system.kernel("dynamics")
    source = render_sources(system).source
    # the equations are in _dynamics_hot where the kernel has one (found by review: the one-line
    # _dynamics wrapper around it was searched, and the count failed)
    head = "_dynamics_hot(double t" if "_dynamics_hot(double t" in source else "_dynamics(double t"
    body = source[source.index(head):]
    body = body[:body.index("\n}\n")]
    M, F, mu = _closed_form(eom)
    replacements, reduced = sp.cse(M + F, order="canonical")
    closed = (eom.n - 1) + sum(sp.count_ops(v) for _, v in replacements) + sp.count_ops(reduced)
    state = dict(zip(eom.q + eom.u, np.random.default_rng(3).uniform(-1, 1, 2 * eom.n)))
    state |= {p: float(v) for p, v in zip(eom.parameters, np.random.default_rng(4).uniform(0.5, 2, len(eom.parameters)))}
    got = [float(e.xreplace(mu).xreplace(state)) for e in M + F]
    ref = [float(eom.mass_matrix[j, k].xreplace(state)) for j in range(eom.n) for k in range(j + 1)] + \
        [float(e.xreplace(state)) for e in eom.forcing]
    emit(phase="counted", ops_before=kernel.ops_before, ops_after=kernel.ops_after,
         temporaries=len(kernel.temporaries),
         c_ops_mf=count_c_ops(body[body.index("/* Intermediate terms"):body.index("/* Kinematics")]),
         c_ops_solve=count_c_ops(body[body.index("/* Factor M"):]), closed_ops=int(closed),
         closed_check=max(abs(a - b) / max(1.0, abs(b)) for a, b in zip(got, ref)))


def worker_kane_ops(tag) -> None:
    import sympy as sp
    import sympy.physics.mechanics as me
    from bench_derive import _sympy_chain
    from pydy.codegen.c_code import CMatrixGenerator

    emit(phase="ready")
    M, F, q, u, params = _sympy_chain(links(tag), kane=True)
    emit(phase="derived")
    plain = {f: sp.Symbol(f.func.__name__) for f in list(q) + list(u)}
    plain |= {f.diff(me.dynamicsymbols._t): sp.Symbol(f"{f.func.__name__}_d") for f in q}
    replacements, reduced = sp.cse([sp.sympify(e).xreplace(plain) for e in list(M) + list(F)])
    kane_cse = sum(sp.count_ops(v) for _, v in replacements) + sp.count_ops(reduced)
    generator = CMatrixGenerator([q, u, params], [M, F])
    _, source = generator.doprint()
    emit(phase="counted", kane_cse_ops=int(kane_cse), pydy_c_ops=count_c_ops(source),
         pydy_subexpressions=len(generator.subexprs))


def worker_pipeline(tag, mode: str) -> None:
    """``compile_model(model)`` timed whole, in the cache dir from the environment: "cold" (the
    dir is empty) with each stage's share, "warm" (populated) checking that nothing was built.

    The stage shares come from wrapping the stage functions that `lagcodegen.pipeline` calls
    (in this process only), so the timed call stays exactly ``compile_model``."""
    import functools
    import os

    from lagcodegen import pipeline

    model = model_of(tag)
    cache = Path(os.environ["LAGCODEGEN_CACHE_DIR"])
    before = sorted(p.name for p in cache.iterdir())
    stages = {"derive": "derive_equations", "reduce": "reduce_expressions", "render": "render_sources",
              "build": "build_module"}
    shares = dict.fromkeys(stages, 0.0)

    def timed(stage, fn):
        @functools.wraps(fn)
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return fn(*args, **kwargs)
            finally:
                shares[stage] += time.perf_counter() - start
        return wrapper
    for stage, name in stages.items():
        if hasattr(pipeline, name):
            setattr(pipeline, name, timed(stage, getattr(pipeline, name)))
    emit(phase="ready", entries_before=len(before))
    start = time.perf_counter()
    system = pipeline.compile_model(model)
    seconds = time.perf_counter() - start
    built = sorted(p.name for p in cache.iterdir()) != before
    emit(phase="timed", seconds=seconds, cache_hit=not built, key=system.key, **shares)


def worker_speed(tag, repeat: int) -> None:
    import numpy as np
    from _common import c_ns_per_eval, c_ns_per_eval_interleaved, per_call_seconds, rhs_harness, sample_state

    from lagcodegen import derive_equations
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources
    from lagcodegen.native.build import build_module
    from lagcodegen.run.simulate import make_rhs, parameter_vector

    emit(phase="ready")
    repeat = max(SPEED_REPEAT, repeat)
    eom = derive_equations(model_of(tag))
    sources = render_sources(reduce_expressions(eom, ("rhs",)))
    harness = rhs_harness(sources, with_hand=tag == DP)
    compiled = build_module(sources)
    emit(phase="built")
    n, p = eom.n, parameter_vector(compiled)
    rng = np.random.default_rng(7)
    X = np.hstack([rng.uniform(-np.pi, np.pi, (N_STATES, n)), rng.uniform(-5, 5, (N_STATES, n))])
    result = {}
    if tag == DP:
        result["hand_check"] = _hand_check(harness, X, p, rng)
        timed = c_ns_per_eval_interleaved(harness, ("hand", "lcg"), X, p, repeat)
        result["hand_ns"], result["lcg_ns"] = timed["hand"], timed["lcg"]
    else:
        result["lcg_ns"] = c_ns_per_eval(harness, "lcg", X, p, repeat)
    f = make_rhs(compiled)
    x = sample_state(n)
    result["lcg_python_us"] = 1e6 * per_call_seconds(lambda k: [f(0.0, x) for _ in range(k)], repeat)
    result["sample"] = f(0.0, x).tolist()
    emit(phase="timed", **result)


def _hand_check(harness, X, p, rng) -> float:
    """Max |hand - ours| / max(1, |ours|) over the states X at the default and 3 random p."""
    import numpy as np

    ffi, lib = harness.ffi, harness.lib
    worst = 0.0
    for pv in [p] + [p * rng.uniform(0.5, 2.0, p.size) for _ in range(3)]:
        pv = np.ascontiguousarray(pv, dtype=float)
        out = {who: np.empty_like(X) for who in ("lcg", "hand")}
        for who, o in out.items():
            getattr(lib, f"bench_{who}_independent")(ffi.from_buffer("double[]", X), X.shape[0],
                                                     ffi.from_buffer("double[]", pv), 1, ffi.from_buffer("double[]", o))
        worst = max(worst, float(np.max(np.abs(out["hand"] - out["lcg"]) / np.maximum(1.0, np.abs(out["lcg"])))))
    return worst


def worker_pydy(tag, repeat: int) -> None:
    import numpy as np
    from _common import per_call_seconds, pydy_chain_rhs, sample_state

    emit(phase="ready")
    f, kane_seconds, generate_seconds = pydy_chain_rhs(links(tag))
    emit(phase="compiled", kane_seconds=kane_seconds, generate_seconds=generate_seconds)
    n = links(tag)
    p = np.array([1.0] * (2 * n) + [9.81])  # m_i = l_i = 1, g = 9.81: lagcodegen's catalog defaults
    x = sample_state(n)
    per_call = per_call_seconds(lambda k: [f(x, 0.0, p) for _ in range(k)], max(SPEED_REPEAT, repeat))
    emit(phase="timed", pydy_python_us=1e6 * per_call, sample=np.asarray(f(x, 0.0, p)).tolist())


WORKERS = {"ops": worker_ops, "kane-ops": worker_kane_ops, "pipeline": worker_pipeline,
           "speed": worker_speed, "pydy": worker_pydy}


# -- parent side ---------------------------------------------------------------------------------
def _measure_ops(tags, timeout) -> list:
    rows = []
    for tag in tags:
        ours = run_worker(__file__, ["ops", tag], [IMPORT_TIMEOUT, timeout])
        kane = run_worker(__file__, ["kane-ops", tag], [IMPORT_TIMEOUT, timeout, timeout])
        row = {"table": "ops", "model": label(tag), "n": links(tag), "status": ours.pop("status"),
               "kane_status": kane.pop("status"), **ours, **kane}
        progress(f"kernels ops: {label(tag):<16} ours {row.get('ops_after', row['status'])}, "
                 f"Kane+cse {row.get('kane_cse_ops', row['kane_status'])}")
        rows.append(row)
    return rows


def _measure_pipeline(tag, timeout, repeat) -> dict:
    colds, warms = [], []
    for _ in range(repeat):
        cache = Path(tempfile.mkdtemp(prefix="lcg-bench-cache-"))
        try:
            env = {"LAGCODEGEN_CACHE_DIR": str(cache)}
            cold = run_worker(__file__, ["pipeline", tag, "cold"], [IMPORT_TIMEOUT, timeout], env)
            colds.append(cold)
            if cold["status"] == "ok":
                warms.append(run_worker(__file__, ["pipeline", tag, "warm"], [IMPORT_TIMEOUT, timeout], env))
        finally:
            shutil.rmtree(cache, ignore_errors=True)
        if cold["status"] != "ok":
            break
    ok_cold = [c for c in colds if c["status"] == "ok"]
    ok_warm = [w for w in warms if w["status"] == "ok"]
    best_cold = min(ok_cold, key=lambda c: c["seconds"]) if ok_cold else colds[-1]
    row = {"table": "pipeline", "model": label(tag), "n": links(tag), "cold_status": best_cold["status"],
           "cold_all": [c["seconds"] for c in ok_cold], "warm_all": [w["seconds"] for w in ok_warm],
           "cold_built": all(not c.get("cache_hit") for c in ok_cold) if ok_cold else None,
           "warm_cache_hit": all(w.get("cache_hit") for w in ok_warm) if ok_warm else None}
    if ok_cold:
        row.update({k: best_cold[k] for k in ("derive", "reduce", "render", "build")})
        row["cold_seconds"] = best_cold["seconds"]
    if ok_warm:
        best_warm = min(ok_warm, key=lambda w: w["seconds"])
        row["warm_seconds"] = best_warm["seconds"]
        row["warm_shares"] = {k: best_warm[k] for k in ("derive", "reduce", "render", "build")}
    row["warm_status"] = "ok" if ok_warm else (warms[-1]["status"] if warms else "not run")
    return row


def _measure_pydy(tag, timeout, repeat) -> dict:
    runs = [run_worker(__file__, ["pydy", tag, repeat], [IMPORT_TIMEOUT, timeout, timeout]) for _ in range(repeat)]
    ok = [r for r in runs if r["status"] == "ok"]
    if not ok:
        return {"pydy_status": runs[-1]["status"]}
    return {"pydy_status": "ok", "kane_seconds": min(r["kane_seconds"] for r in ok),
            "pydy_generate_seconds": min(r["generate_seconds"] for r in ok),
            "pydy_generate_all": [r["generate_seconds"] for r in ok],
            "pydy_python_us": min(r["pydy_python_us"] for r in ok), "pydy_sample": ok[0]["sample"]}


def _measure_speed(tag, timeout, repeat) -> dict:
    speed = run_worker(__file__, ["speed", tag, repeat], [IMPORT_TIMEOUT, timeout, timeout])
    row = {"speed_status": speed.pop("status"), **speed}
    return row


def _max_rel_diff(a, b) -> float:
    scale = max(max(abs(y) for y in b), 1e-300)
    return max(abs(x - y) for x, y in zip(a, b)) / scale


def _measure_timings(tags, timeout, repeat) -> list:
    rows = []
    for tag in tags:
        row = _measure_pipeline(tag, timeout, repeat)
        progress(f"kernels pipeline: {label(tag):<16} cold {fmt(row.get('cold_seconds'), '.3f', row['cold_status'])} s, "
                 f"warm {fmt(row.get('warm_seconds'), '.4f', row['warm_status'])} s")
        row.update(_measure_speed(tag, timeout, repeat))
        row.update(_measure_pydy(tag, timeout, repeat))
        if "sample" in row and "pydy_sample" in row:
            row["pydy_check"] = _max_rel_diff(row["pydy_sample"], row["sample"])
        progress(f"kernels speed: {label(tag):<16} ours {fmt(row.get('lcg_ns', {}).get('independent'), '.1f', row['speed_status'])} ns, "
                 f"PyDy {fmt(row.get('pydy_python_us'), '.2f', row['pydy_status'])} us/call")
        rows.append(row)
    return rows


# -- report --------------------------------------------------------------------------------------
def _ops_table(rows) -> str:
    body = []
    for r in rows:
        ok, kok = r["status"] == "ok", r["kane_status"] == "ok"
        body.append([r["model"], r["n"],
                     f"{r['ops_before']} -> {r['ops_after']}" if ok else _short(r["status"]),
                     f"{r['c_ops_mf']} + {r['c_ops_solve']}" if ok else "",
                     r["closed_ops"] if ok else "", f"{r['ops_after'] / r['closed_ops']:.2f}x" if ok else "",
                     r["kane_cse_ops"] if kok else _short(r["kane_status"]), r["pydy_c_ops"] if kok else "",
                     f"{r['kane_cse_ops'] / r['ops_after']:.2f}x" if ok and kok else "",
                     f"{r['pydy_c_ops'] / r['c_ops_mf']:.2f}x" if ok and kok else "",
                     f"{r['closed_check']:.0e}" if ok else ""])
    header = ["model", "n", "ours ops", "ours C (M,F + LDLT)", "closed", "ours/closed", "Kane+cse",
              "PyDy C", "Kane/ours", "PyDy C/ours C", "closed check"]
    return format_table(header, body) + _failures(rows, ("status", "kane_status"))


def _short(status: str) -> str:
    """A table cell for a failed measurement: "error" or "timeout" (details below the table)."""
    return "error" if status.startswith("error") else status


def _failures(rows, keys) -> str:
    lines = [f"{r['model']} {key.replace('_status', '') or 'ours'}: {r[key]}"
             for r in rows for key in keys if r.get(key, "ok") not in ("ok", "not run")]
    return "".join("\n  failed: " + line for line in lines)


def _timing_table(rows) -> str:
    body = []
    for r in rows:
        cold = fmt(r.get("cold_seconds"), ".3f", _short(r["cold_status"]))
        parts = "/".join(f"{r[k]:.2f}" for k in ("derive", "reduce", "render", "build")) if "derive" in r else ""
        warm = fmt(None if r.get("warm_seconds") is None else 1e3 * r["warm_seconds"], ".1f", _short(r["warm_status"]))
        warm_parts = "/".join(f"{1e3 * v:.0f}" for v in r["warm_shares"].values()) if "warm_shares" in r else ""
        ok = r["pydy_status"] == "ok"
        body.append([r["model"], cold, parts, warm, warm_parts, fmt(r.get("kane_seconds"), ".2f", _short(r["pydy_status"])),
                     fmt(r.get("pydy_generate_seconds"), ".2f", "") if ok else "",
                     f"{(r['kane_seconds'] + r['pydy_generate_seconds']) / r['cold_seconds']:.1f}x"
                     if ok and "cold_seconds" in r else ""])
    header = ["model", "ours cold [s]", "derive/reduce/render/build [s]", "ours warm [ms]", "warm shares [ms]",
              "Kane derive [s]", "PyDy gen+compile [s]", "(Kane + PyDy) / ours cold"]
    return format_table(header, body) + _failures(rows, ("cold_status", "warm_status", "pydy_status"))


def _speed_table(rows) -> str:
    body = []
    for r in rows:
        lcg, hand = r.get("lcg_ns", {}), r.get("hand_ns", {})
        ratio = lambda k: f"{lcg[k] / hand[k]:.2f}x" if k in lcg and k in hand else "-"  # noqa: E731
        body.append([r["model"],
                     fmt(lcg.get("independent"), ".1f", _short(r["speed_status"])), fmt(lcg.get("chained"), ".1f"),
                     fmt(hand.get("independent"), ".1f"), fmt(hand.get("chained"), ".1f"),
                     ratio("independent"), ratio("chained"), fmt(r.get("hand_check"), ".0e"),
                     fmt(r.get("lcg_python_us"), ".2f"), fmt(r.get("pydy_python_us"), ".2f", _short(r["pydy_status"])),
                     f"{r['pydy_python_us'] / r['lcg_python_us']:.1f}x"
                     if "pydy_python_us" in r and "lcg_python_us" in r else "-",
                     fmt(r.get("pydy_check"), ".0e")])
    header = ["model", "ours indep", "ours chain", "hand indep", "hand chain", "ours/hand indep",
              "ours/hand chain", "hand check", "ours py [us]", "PyDy py [us]", "PyDy/ours py", "PyDy check"]
    return format_table(header, body) + _failures(rows, ("speed_status",))


def format_report(ops_rows, timing_rows, timeout, repeat) -> str:
    import platform

    import sympy
    from _common import compiler_version, peer_versions
    from peers import default_flags

    import lagcodegen

    head = [
        f"kernels suite: lagcodegen {lagcodegen.__version__}, sympy {sympy.__version__}, "
        f"{peer_versions('pydy', 'Cython', 'numpy', 'cffi')}, Python {platform.python_version()}, "
        f"{compiler_version()}; flags {' '.join(default_flags())} for ours and hand C",
        f"every cell from fresh processes under a hard time-out of {timeout:g} s per phase "
        f"(imports {IMPORT_TIMEOUT:g} s, never timed); shared 2-core machine, so every time is the "
        f"minimum (best) of repeats: pipeline and PyDy",
        f"generate+compile: {repeat} fresh processes each; per-evaluation costs: "
        f"{max(SPEED_REPEAT, repeat)} timing runs of >= 50 ms each",
    ]
    ops_notes = [
        "",
        "(1) operations after CSE. ours ops: sympy count_ops of the rhs 'dynamics' kernel (M lower "
        "triangle + F), before -> after CSE;",
        "    ours C: operators + calls in the emitted C, M,F part + unrolled LDL^T solve; closed: the "
        "hand-structured chain (mu_j partial mass sums, cos/sin(q_j - q_k)), sympy cse, count_ops;",
        "    Kane+cse: sympy.cse of KanesMethod M (n*n) and F, count_ops; PyDy C: operators + calls in "
        "PyDy CMatrixGenerator's C for M, F (same counter as ours C);",
        f"    closed check: max relative difference of the closed form from lagcodegen's M, F at a "
        f"random state. The issue's closed form at n = 15: ~{ISSUE_OPS_N15} ops.",
    ]
    time_notes = [
        "",
        "(2) pipeline wall time, the Model built before the timer. ours cold: compile_model(model) with "
        "its defaults (all DEFAULT_METHODS and the outputs they need) into an empty",
        "    LAGCODEGEN_CACHE_DIR, stage shares derive/reduce/render/build (gcc); ours warm: the same "
        "call in a fresh process, cache hit (shares likewise); PyDy: generate_ode_function(generator='cython')",
        "    from KanesMethod M, F (sympy cse, C + Cython, setuptools build), Kane derivation apart.",
    ]
    speed_notes = [
        "",
        "(3) ns per rhs evaluation (q,u) -> (qd, qdd), measured in C by a harness calling the "
        "compiled function in a loop (separate translation units, no inlining);",
        f"    indep: {N_STATES} different states in turn (throughput); chain: explicit Euler steps, "
        "each evaluation waits for the previous (latency). hand: peers/hand_double_pendulum.c;",
        "    hand check: max |hand - ours| / max(1, |ours|) at 256 random states x 4 parameter sets, "
        "required <= 1e-12. py [us]: per call from Python, as users call them:",
        "    ours via simulate.make_rhs (cffi, numpy output), PyDy's Cython rhs f(x, t, p) (numpy "
        "linalg.solve in Python); PyDy check: max relative difference from ours at a sample state.",
    ]
    return "\n".join(head + ops_notes) + "\n\n" + _ops_table(ops_rows) + "\n" + \
        "\n".join(time_notes) + "\n\n" + _timing_table(timing_rows) + "\n" + \
        "\n".join(speed_notes) + "\n\n" + _speed_table(timing_rows)


# -- goals ---------------------------------------------------------------------------------------
def goals(ops_rows, timing_rows) -> list:
    found = []
    row15 = next((r for r in ops_rows if r["n"] == OPS_EXTRA and r["model"] != label(DP)), None)
    goal = f"ops after CSE at n = {OPS_EXTRA} within {OPS_GOAL_RATIO}x of the closed form's ~{ISSUE_OPS_N15}"
    if row15 is None:
        found.append({"goal": goal, "status": "NOT RUN", "detail": f"n = {OPS_EXTRA} not measured (drop --quick)"})
    elif row15["status"] != "ok":
        found.append({"goal": goal, "status": "FAIL", "detail": row15["status"]})
    else:
        ratio = row15["ops_after"] / ISSUE_OPS_N15
        found.append({"goal": goal, "status": "PASS" if ratio <= OPS_GOAL_RATIO else "FAIL",
                      "detail": f"{row15['ops_after']} ops = {ratio:.2f}x of {ISSUE_OPS_N15} "
                                f"({row15['ops_after'] / row15['closed_ops']:.2f}x of this suite's closed "
                                f"form, {row15['closed_ops']} ops)"})
    dp = next((r for r in timing_rows if r["model"] == label(DP)), None)
    found.append(_qdd_goal(dp))
    for key, limit, name in (("cold_seconds", COLD_GOAL_SECONDS, "cold"), ("warm_seconds", WARM_GOAL_SECONDS, "warm")):
        goal = f"{name} pipeline of the double pendulum under " + \
            (f"{limit:g} s" if limit >= 1 else f"{limit * 1e3:g} ms")
        if dp is None or dp.get(key) is None:
            found.append({"goal": goal, "status": "FAIL" if dp else "NOT RUN",
                          "detail": dp[f"{name}_status"] if dp else "not measured"})
        else:
            found.append({"goal": goal, "status": "PASS" if dp[key] < limit else "FAIL",
                          "detail": f"{dp[key] * 1e3:.1f} ms"})
    return found


def _qdd_goal(dp) -> dict:
    goal = f"qdd evaluation within {QDD_GOAL_RATIO}x of hand C (double pendulum, indep and chain)"
    if dp is None:
        return {"goal": goal, "status": "NOT RUN", "detail": "not measured"}
    lcg, hand = dp.get("lcg_ns"), dp.get("hand_ns")
    if not lcg or not hand:
        return {"goal": goal, "status": "FAIL", "detail": dp["speed_status"]}
    if dp["hand_check"] > 1e-12:
        return {"goal": goal, "status": "UNDECIDED", "detail": f"hand C disagrees with ours: {dp['hand_check']:.1e}"}
    ratios = {k: lcg[k] / hand[k] for k in ("independent", "chained")}
    status = "PASS" if all(r <= QDD_GOAL_RATIO for r in ratios.values()) else "FAIL"
    return {"goal": goal, "status": status,
            "detail": ", ".join(f"{k} {lcg[k]:.1f} vs {hand[k]:.1f} ns = {r:.2f}x" for k, r in ratios.items())}


# -- suite protocol ------------------------------------------------------------------------------
def add_arguments(group) -> None:
    group.add_argument("--kernels-repeat", type=int, default=3, metavar="R",
                       help="repeats per timing (fresh processes for pipeline times), best reported (default 3)")


def run(options) -> dict:
    """Measure op counts, pipeline times and evaluation costs; {"table", "rows", "goals"}."""
    tags = TAGS_QUICK if options.quick else TAGS_FULL
    timeout = options.timeout or DEFAULT_TIMEOUT
    repeat = max(1, getattr(options, "kernels_repeat", 3))
    ops_tags = tags if options.quick else (DP,) + tuple(sorted({t for t in tags if t != DP} | {OPS_EXTRA}))
    ops_rows = _measure_ops(ops_tags, timeout)
    timing_rows = _measure_timings(tags, timeout, repeat)
    table = format_report(ops_rows, timing_rows, timeout, repeat)
    for row in timing_rows:  # samples served the check column; keep the JSON small
        row.pop("sample", None)
        row.pop("pydy_sample", None)
    return {"table": table, "rows": ops_rows + timing_rows, "goals": goals(ops_rows, timing_rows)}


if __name__ == "__main__":
    if len(sys.argv) >= 4 and sys.argv[1] == "--worker":
        name, tag, extra = sys.argv[2], parse_tag(sys.argv[3]), sys.argv[4:]
        if name == "pipeline":
            WORKERS[name](tag, extra[0])
        elif name in ("speed", "pydy"):
            WORKERS[name](tag, int(extra[0]))
        else:
            WORKERS[name](tag)
    else:
        sys.exit("bench_kernels.py is a suite module; run: python benchmarks/run.py kernels")
