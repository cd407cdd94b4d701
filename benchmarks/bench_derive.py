"""Suite `derive`: time, op counts and memory of deriving the planar n-link pendulum chain.

For each n (2, 5, 10, 15, 20, 30; ``--quick``: 2, 5, 10) and each tool, one fresh Python
process (so sympy's global cache never favours a later measurement) runs::

    ready     imports done (not timed); peak RSS so far recorded
    derived   wall time (time.perf_counter) of building the model and forming M and F
    counted   sympy.count_ops of M and F, and M, F at a fixed sample state (not timed)

Tools, all for the same chain (point masses m_i, rods l_i, gravity g, absolute angles q_i
from the downward vertical; target form M(q) qdd = F(q, qd))::

    lagcodegen bodies     derive_equations(pendulum_chain(n, route="bodies"))
    lagcodegen energies   derive_equations(pendulum_chain(n, route="energies"))
    LagrangesMethod       sympy.physics.mechanics, L = Lagrangian(N, *particles),
                          form_lagranges_equations(), .mass_matrix, .forcing
    KanesMethod           sympy.physics.mechanics, u_i = qd_i, kanes_equations(particles,
                          gravity loads), .mass_matrix, .forcing

The peers build the chain here, independently of lagcodegen's catalog, the way their own
documentation does (a frame per link, ``v2pt_theory``). A "check" column compares every tool's
M and F with lagcodegen's bodies route at the sample state, so a wrong peer model shows.

Each phase has a hard time-out (``--timeout``, default 120 s; imports get `IMPORT_TIMEOUT`).
A tool that times out at some n is skipped at every larger n. Goal lines (>= 5x faster than
KanesMethod at every n, n = 30 under 5 s) are computed from the measured numbers.

Run through the suite runner: ``python benchmarks/run.py derive [--quick] [--timeout S]``.
"""
from __future__ import annotations

import json
import queue
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

DESCRIPTION = "derivation time, op counts of M and F, peak RSS: n-link chain vs sympy Lagrange/Kane"
NS_FULL = (2, 5, 10, 15, 20, 30)
NS_QUICK = (2, 5, 10)
DEFAULT_TIMEOUT = 120.0
IMPORT_TIMEOUT = 120.0
KANE_GOAL_RATIO = 5.0
N30_GOAL_SECONDS = 5.0
TOOLS = {  # key -> label; the first entry is the reference of the check column
    "lcg-bodies": "lagcodegen bodies",
    "lcg-energies": "lagcodegen energies",
    "lagrange": "sympy LagrangesMethod",
    "kane": "sympy KanesMethod",
}
LCG_TOOLS = ("lcg-bodies", "lcg-energies")
MESSAGE_PREFIX = "@@bench "


# -- worker side: runs in a fresh process --------------------------------------------------------
def _peak_rss_mib() -> float:
    """Peak resident set size of this process so far (ru_maxrss: KiB on Linux, bytes on macOS)."""
    import resource

    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / (1024.0 * 1024.0) if sys.platform == "darwin" else peak / 1024.0


def _emit(**message) -> None:
    print(MESSAGE_PREFIX + json.dumps(message), flush=True)


def _sympy_chain(n: int, kane: bool):
    """The n-link chain by sympy.physics.mechanics alone. Returns (M, F, q, speeds, params)."""
    import sympy as sp
    import sympy.physics.mechanics as me

    q = me.dynamicsymbols(f"q1:{n + 1}")
    u = me.dynamicsymbols(f"u1:{n + 1}")
    m = sp.symbols(f"m1:{n + 1}", positive=True)
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    g = sp.Symbol("g", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    particles, loads, previous = [], [], O
    for i in range(n):
        link = N.orientnew(f"A{i + 1}", "Axis", (q[i], N.z))
        if kane:
            link.set_ang_vel(N, u[i] * N.z)
        bob = previous.locatenew(f"P{i + 1}", -l[i] * link.y)
        bob.v2pt_theory(previous, N, link)
        particle = me.Particle(f"bob{i + 1}", bob, m[i])
        if kane:  # each method gets gravity in its own idiom, and only that one
            loads.append((bob, -m[i] * g * N.y))
        else:
            particle.potential_energy = m[i] * g * bob.pos_from(O).dot(N.y)
        particles.append(particle)
        previous = bob
    params = tuple(m) + tuple(l) + (g,)
    if kane:
        kd = [qi.diff(me.dynamicsymbols._t) - ui for qi, ui in zip(q, u)]
        method = me.KanesMethod(N, q_ind=q, u_ind=u, kd_eqs=kd)
        method.kanes_equations(particles, loads)
        return method.mass_matrix, method.forcing, q, u, params
    method = me.LagrangesMethod(me.Lagrangian(N, *particles), q)
    method.form_lagranges_equations()
    qd = [qi.diff(me.dynamicsymbols._t) for qi in q]
    return method.mass_matrix, method.forcing, q, qd, params


def _lagcodegen_chain(n: int, route: str):
    from lagcodegen import derive_equations
    from lagcodegen.catalog import pendulum_chain

    eom = derive_equations(pendulum_chain(n, route=route))
    return eom.mass_matrix, eom.forcing, eom.q, eom.u, eom.parameters


def _sample_state(q, speeds, params) -> dict:
    """Fixed, distinct values: q_i = 0.3 + 0.1 i, qd_i = 0.7 - 0.05 i, m_i = 1 + 0.1 i,
    l_i = 0.5 + 0.02 i, g = 9.81 (parameters matched by name, so each tool's own symbols work)."""
    values = {}
    for i, (qi, si) in enumerate(zip(q, speeds)):
        values[qi], values[si] = 0.3 + 0.1 * i, 0.7 - 0.05 * i
    for p in params:
        kind, index = p.name[0], int(p.name[1:] or 1) - 1
        values[p] = {"m": 1.0 + 0.1 * index, "l": 0.5 + 0.02 * index, "g": 9.81}[kind]
    return values


def worker(tool: str, n: int) -> None:
    """Measure one (tool, n) in this process, emitting one message per phase."""
    import sympy as sp

    # import cost is not derivation cost: every tool's modules are loaded before the clock starts
    import sympy.physics.mechanics  # noqa: F401

    import lagcodegen  # noqa: F401
    import lagcodegen.catalog  # noqa: F401

    build = {"lcg-bodies": lambda: _lagcodegen_chain(n, "bodies"),
             "lcg-energies": lambda: _lagcodegen_chain(n, "energies"),
             "lagrange": lambda: _sympy_chain(n, kane=False),
             "kane": lambda: _sympy_chain(n, kane=True)}[tool]
    rss_before = _peak_rss_mib()
    _emit(phase="ready", rss_before_mib=rss_before)
    start = time.perf_counter()
    M, F, q, speeds, params = build()
    seconds = time.perf_counter() - start
    rss_after = _peak_rss_mib()
    _emit(phase="derived", seconds=seconds, peak_rss_mib=rss_after, delta_rss_mib=rss_after - rss_before)
    state = _sample_state(q, speeds, params)
    _emit(phase="counted",
          ops_M=sum(sp.count_ops(e) for e in M), ops_F=sum(sp.count_ops(e) for e in F),
          M_sample=[float(sp.sympify(e).xreplace(state)) for e in M],
          F_sample=[float(sp.sympify(e).xreplace(state)) for e in F])


# -- parent side ---------------------------------------------------------------------------------
def _pump(stream, lines: queue.Queue) -> None:
    for line in stream:
        if line.startswith(MESSAGE_PREFIX):
            lines.put(json.loads(line[len(MESSAGE_PREFIX):]))
    lines.put(None)  # end of output


def run_in_subprocess(argv: list, timeouts: list) -> tuple[list, str]:
    """Run ``argv``, which emits one prefixed JSON message per phase; ``timeouts[i]`` (s) limits
    phase i. Returns (messages, status), status "ok", "timeout" or "error: <stderr tail>"."""
    with tempfile.TemporaryFile(mode="w+") as stderr:
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=stderr, text=True)
        lines: queue.Queue = queue.Queue()
        threading.Thread(target=_pump, args=(proc.stdout, lines), daemon=True).start()
        messages = []
        try:
            for limit in timeouts:
                message = lines.get(timeout=limit)
                if message is None:
                    break
                messages.append(message)
        except queue.Empty:
            proc.kill()
            proc.wait()
            return messages, "timeout"
        proc.wait()
        if proc.returncode == 0 and len(messages) == len(timeouts):
            return messages, "ok"
        stderr.seek(0)
        tail = stderr.read().strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
        return messages, "error: " + tail[0]


def measure(tool: str, n: int, timeout: float) -> dict:
    """One row: status, seconds, ops_M, ops_F, peak_rss_mib, delta_rss_mib (+ samples)."""
    argv = [sys.executable, str(Path(__file__).resolve()), "--worker", tool, str(n)]
    messages, status = run_in_subprocess(argv, [IMPORT_TIMEOUT, timeout, timeout])
    row = {"n": n, "tool": tool, "label": TOOLS[tool], "status": status}
    for message in messages:
        row.update({k: v for k, v in message.items() if k != "phase"})
    if "seconds" in row and status != "ok":  # derived in time; counting or sampling failed
        row["status"] = "ok"
        row["count_status"] = status
    return row


def measure_best(tool: str, n: int, timeout: float, repeat: int) -> dict:
    """The fastest of ``repeat`` fresh-process runs (all times kept in ``all_seconds``); the
    first run that does not finish in time decides the row."""
    best, times = None, []
    for _ in range(repeat):
        row = measure(tool, n, timeout)
        if row["status"] != "ok":
            return row
        times.append(row["seconds"])
        best = row if best is None or row["seconds"] < best["seconds"] else best
    best["all_seconds"] = times
    return best


def _max_rel_diff(a: list, b: list) -> float:
    scale = max(max(abs(x) for x in b), 1e-300)
    return max(abs(x - y) for x, y in zip(a, b)) / scale


def _add_checks(rows: list) -> None:
    """check = max relative difference of M and F from the reference tool's, at the sample."""
    reference = {r["n"]: r for r in rows if r["tool"] == next(iter(TOOLS)) and "M_sample" in r}
    for row in rows:
        ref = reference.get(row["n"])
        if ref is not None and "M_sample" in row:
            row["check"] = max(_max_rel_diff(row["M_sample"], ref["M_sample"]),
                               _max_rel_diff(row["F_sample"], ref["F_sample"]))


# -- report --------------------------------------------------------------------------------------
def _time_cell(row: dict, timeout: float) -> str:
    if row["status"] == "ok":
        return f"{row['seconds']:.3f}"
    if row["status"] == "timeout":
        return f"timeout >{timeout:g}s"
    return row["status"] if row["status"] == "skipped" else "error"


def _ratio(peer: dict, own: dict, timeout: float) -> tuple[float | None, bool]:
    """(peer time / own time, is_lower_bound); None when it cannot be stated."""
    if own["status"] != "ok":
        return None, False
    if peer["status"] == "ok":
        return peer["seconds"] / own["seconds"], False
    if peer["status"] in ("timeout", "skipped"):  # skipped: timed out at a smaller n
        return timeout / own["seconds"], True
    return None, False


def _ratio_cell(ratio: float | None, bound: bool) -> str:
    return "" if ratio is None else (">" if bound else "") + f"{ratio:.1f}x"


def _format(header: list, body: list) -> str:
    widths = [max(len(str(r[i])) for r in [header] + body) for i in range(len(header))]
    line = lambda cells: "  ".join(str(c).rjust(w) if i != 1 else str(c).ljust(w)  # noqa: E731
                                   for i, (c, w) in enumerate(zip(cells, widths)))
    return "\n".join([line(header), line(["-" * w for w in widths])] + [line(r) for r in body])


def format_table(rows: list, timeout: float, repeat: int) -> str:
    import platform

    import sympy

    import lagcodegen

    by_key = {(r["n"], r["tool"]): r for r in rows}
    body = []
    for row in rows:
        kane, lagrange = by_key[(row["n"], "kane")], by_key[(row["n"], "lagrange")]
        ratios = (_ratio(kane, row, timeout), _ratio(lagrange, row, timeout)) \
            if row["tool"] in LCG_TOOLS else ((None, False), (None, False))
        ok = row["status"] == "ok" and "ops_M" in row
        body.append([row["n"], row["label"], _time_cell(row, timeout),
                     _ratio_cell(*ratios[0]), _ratio_cell(*ratios[1]),
                     row["ops_M"] if ok else "", row["ops_F"] if ok else "",
                     f"{row['peak_rss_mib']:.0f}" if "peak_rss_mib" in row else "",
                     f"{row['delta_rss_mib']:.0f}" if "delta_rss_mib" in row else "",
                     f"{row['check']:.0e}" if "check" in row else ""])
    header = ["n", "tool", "time [s]", "Kane/t", "Lagr/t", "ops(M)", "ops(F)",
              "peak RSS [MiB]", "+RSS [MiB]", "check"]
    notes = [
        f"derive suite: n-link pendulum chain; lagcodegen {lagcodegen.__version__}, sympy "
        f"{sympy.__version__}, Python {platform.python_version()}; one fresh process per cell",
        "time: wall clock (perf_counter) of building the model and forming M and F; imports excluded"
        + (f"; fastest of {repeat} runs" if repeat > 1 else "; one run"),
        f"time-out {timeout:g} s per cell; a tool that times out is skipped at larger n",
        "Kane/t, Lagr/t: peer time / this row's time ('>': peer timed out, so a lower bound)",
        "ops: sympy.count_ops summed over all n*n entries of M and n entries of F, as returned",
        "memory: peak RSS = ru_maxrss of the worker after deriving (interpreter and sympy "
        "included); +RSS = growth of that peak during the derivation",
        "check: max relative difference of M and F from lagcodegen bodies at a fixed sample state",
    ]
    return "\n".join(notes) + "\n\n" + _format(header, body)


# -- goals ---------------------------------------------------------------------------------------
def _kane_goal(rows: list, tool: str, timeout: float) -> dict:
    by_key = {(r["n"], r["tool"]): r for r in rows}
    ns = sorted({r["n"] for r in rows})
    ratios = {n: _ratio(by_key[(n, "kane")], by_key[(n, tool)], timeout) for n in ns}
    below = {n for n, (ratio, _) in ratios.items() if ratio is not None and ratio < KANE_GOAL_RATIO}
    failing = [n for n in below if not ratios[n][1]]
    unknown = [n for n, (ratio, bound) in ratios.items() if ratio is None or (bound and n in below)]
    status = "FAIL" if failing or any(by_key[(n, tool)]["status"] != "ok" for n in ns) \
        else "UNDECIDED" if unknown else "PASS"
    detail = ", ".join(f"n={n}: {_ratio_cell(*ratios[n]) or by_key[(n, tool)]['status']}" for n in ns)
    return {"goal": f"{TOOLS[tool]} >= {KANE_GOAL_RATIO:g}x faster than KanesMethod at every n",
            "status": status, "detail": detail}


def _n30_goal(rows: list, tool: str) -> dict:
    goal = f"{TOOLS[tool]} derives n = 30 in under {N30_GOAL_SECONDS:g} s"
    row = next((r for r in rows if r["n"] == 30 and r["tool"] == tool), None)
    if row is None:
        return {"goal": goal, "status": "NOT RUN", "detail": "n = 30 not measured (drop --quick)"}
    if row["status"] != "ok":
        return {"goal": goal, "status": "FAIL", "detail": row["status"]}
    status = "PASS" if row["seconds"] < N30_GOAL_SECONDS else "FAIL"
    return {"goal": goal, "status": status, "detail": f"{row['seconds']:.2f} s"}


def goals(rows: list, timeout: float) -> list:
    """The issue's goals, for both lagcodegen routes, from measured rows."""
    return [_kane_goal(rows, tool, timeout) for tool in LCG_TOOLS] + \
        [_n30_goal(rows, tool) for tool in LCG_TOOLS]


# -- suite protocol ------------------------------------------------------------------------------
def add_arguments(group) -> None:
    group.add_argument("--derive-repeat", type=int, default=1, metavar="R",
                       help="fresh-process runs per cell, the fastest is reported (default 1)")


def run(options) -> dict:
    """Measure every (n, tool) side by side; return {"table", "rows", "goals"} (see run.py)."""
    ns = NS_QUICK if options.quick else NS_FULL
    timeout = options.timeout or DEFAULT_TIMEOUT
    repeat = max(1, getattr(options, "derive_repeat", 1))
    rows, gave_up = [], {}
    for n in ns:
        for tool in TOOLS:
            if tool in gave_up:
                row = {"n": n, "tool": tool, "label": TOOLS[tool], "status": "skipped"}
            else:
                row = measure_best(tool, n, timeout, repeat)
                if row["status"] == "timeout":
                    gave_up[tool] = n
            print(f"  derive: n={n:<3} {TOOLS[tool]:<22} {_time_cell(row, timeout)}",
                  file=sys.stderr, flush=True)
            rows.append(row)
    _add_checks(rows)
    table = format_table(rows, timeout, repeat)
    for row in rows:  # samples served the check column; keep the JSON small
        row.pop("M_sample", None)
        row.pop("F_sample", None)
    return {"table": table, "rows": rows, "goals": goals(rows, timeout)}


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--worker":
        worker(sys.argv[2], int(sys.argv[3]))
    else:
        sys.exit("bench_derive.py is a suite module; run: python benchmarks/run.py derive")
