"""Suite `sweep`: member-steps per second of parameter sweeps, lagcodegen against named peers.

A *member* is one independent run of a model (one point of a parameter grid or one initial
state); a *member-step* is one RK4 step (h = 1e-3) of one member. Models: the double pendulum
(``catalog.double_pendulum()``) and the 10-link chain (``catalog.pendulum_chain(10)``).
Contenders, each measured in its own fresh process (imports, derivation and compilation are
never timed; the first, calibrating runs are the warm-up)::

    lagcodegen sweep   ``sweep(system, {"m1": 16 values, "m<n>": 16 values}, method="rk4")``:
                       256 members, threads = 1 and 2, track_energy False and True; the lane-group
                       kernel (``kernel="lanes"``, what ``sweep`` picks for RK4) and, energy off,
                       the scalar kernel (``kernel="scalar"``, members one after another)
    hand C loop        double pendulum only: a C loop over the same 256 members calling
                       ``hand_dp_rk4_run`` of ``peers/hand_double_pendulum.c`` (closed-form
                       accelerations, RK4 stages in registers), compiled with lagcodegen's flags
    MuJoCo rollout     ``mujoco.rollout.Rollout(nthread=0 or 2).rollout`` of an MJCF of the same
                       chain (`mjcf_chain`: point masses as explicit inertials, massless capsules,
                       hinges about -y, integrator RK4, timestep 1e-3, contacts off): 256 members
                       with varying initial q1, in calls of at most `MUJOCO_CHUNK` steps
    scipy solve_ivp    a Python loop over 4 members (m1 varied) of ``solve_ivp(method="RK45",
                       rtol=1e-6, atol=1e-9)`` on ``simulate.make_rhs``; adaptive, so its rate
                       is *equivalent* member-steps/s = members * integrated time / h / wall s

Each contender's step count is calibrated so one batch lasts about ``--sweep-target`` seconds
(default 2, ``--quick`` 0.3), then the batch runs ``--sweep-repeat`` times (default 3) and the
best is reported. Two clocks: wall (``time.perf_counter``) and CPU (``time.process_time``, all
threads of the worker). The machine is shared: when other jobs run, wall rates understate what
a core does, so the per-core goal and the MuJoCo ratios use member-steps per CPU-second of
single-thread runs. The 2-vs-1-thread speed-up fails when the 2-thread run had the cores for
it (CPU/wall >= 1.9) and still missed, or when threading itself costs too much (twice the
per-CPU-s efficiency below 1.9); when the machine gave it fewer cores, it is undecided.

Checks, in a separate worker per model: lagcodegen's RK4 trajectory (distinct masses, 3 initial
states, 1000 steps) against MuJoCo's at every step (absolute angles from MuJoCo's relative joint
angles by cumulative sums), against the hand C's final state and against the RK45 final state.

Vectorization: the double pendulum's generated C (``CompiledSystem.sources``, the output of
``render_sources`` that the build compiles) is compiled with lagcodegen's flags plus
``-fopt-info-vec-optimized``; every report is mapped from its line to the C function containing
it. The lane kernel's loops over lanes (``for (lcg_lane = 0; ...`` in ``_lanes_dynamics`` and
``_lanes_energy``, the stage sums of ``_lanes_rk4_step``) must be reported as vectorized loops;
those that are not are looked up in ``-fopt-info-vec-missed``. A probe (``y[i] = sin(x[i])``)
shows what a libm call does to loop vectorization (why the lane loops use their own sin/cos).

Goals (from the issue): >= 10 million member-steps/s per core on the double pendulum; >= 1.9x
on 2 cores vs 1; >= 20x MuJoCo on the double pendulum and >= 5x on the 10-link chain.

Run through the suite runner: ``python benchmarks/run.py sweep [--quick] [--timeout S]``.
"""
from __future__ import annotations

import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import (  # noqa: E402
    DP,
    DP_STATE,
    emit,
    fmt,
    format_table,
    label,
    links,
    model_of,
    parse_tag,
    progress,
    run_worker,
    sample_state,
)

DESCRIPTION = "parameter sweeps, member-steps/s with RK4: sweep() 1/2 threads vs hand C, MuJoCo rollout, solve_ivp"
TAGS = (DP, 10)
H = 1e-3
GRID = {False: 16, True: 4}            # points per grid axis (members = GRID**2); key: --quick
TARGET_SECONDS = {False: 2.0, True: 0.3}
REPEAT = 3
SCIPY_MEMBERS = 4
RK45_RTOL, RK45_ATOL = 1e-6, 1e-9
MUJOCO_CHUNK = 250                      # steps per rollout call: bounds its state output array
CHECK_STEPS = 1000
DEFAULT_TIMEOUT = 300.0
IMPORT_TIMEOUT = 240.0                  # imports + derive + compile (10-link chain: ~10 s)
PER_CORE_GOAL = 10e6
SPEEDUP_GOAL = 1.9
MUJOCO_GOALS = {DP: 20.0, 10: 5.0}
TOOLS = {"lcg": "lagcodegen sweep, lanes", "lcg_scalar": "lagcodegen sweep, scalar", "hand": "hand C loop",
         "mujoco": "MuJoCo rollout", "scipy": "scipy RK45 loop"}


# -- models shared by workers --------------------------------------------------------------------
def _compiled(tag):
    from lagcodegen.pipeline import compile_model

    system = compile_model(model_of(tag))
    system.lane_variant()  # compiled here, untimed: sweep() builds it on its first lane run
    return system


def _x0(tag):
    """Base initial state (2n,): absolute angles, then speeds."""
    return list(DP_STATE) if tag == DP else [float(v) for v in sample_state(links(tag))]


def _mass_grid(tag, quick: bool) -> dict:
    import numpy as np

    axis = np.linspace(0.5, 2.0, GRID[quick])
    return {"m1": axis, f"m{links(tag)}": axis}


def mjcf_chain(masses, lengths, g: float = 9.81, h: float = H) -> str:
    """MJCF of lagcodegen's planar chain: point masses m_i at distance l_i from the previous bob.

    Bodies hang along -z (gravity -z); hinges about -y, so a positive joint angle moves the bob
    toward +x: bob i sits at x = sum l_j sin(q_j), z = -sum l_j cos(q_j) with absolute angles
    q_j = theta_1 + ... + theta_j of MuJoCo's relative joint angles theta. Masses are explicit
    inertials with inertia 1e-12 (MuJoCo needs > 0; 1e-12 relative to m l^2 = 1); capsules and
    spheres are visual only (density 0, no contacts). Zero damping, armature, friction.
    """
    opened = []
    for i, (m, l) in enumerate(zip(masses, lengths)):
        z = 0.0 if i == 0 else -float(lengths[i - 1])
        opened.append(
            f'<body name="link{i + 1}" pos="0 0 {z!r}">'
            f'<joint name="theta{i + 1}" type="hinge" axis="0 -1 0" damping="0" armature="0" frictionloss="0"/>'
            f'<inertial pos="0 0 {-float(l)!r}" mass="{float(m)!r}" diaginertia="1e-12 1e-12 1e-12"/>'
            f'<geom type="capsule" fromto="0 0 0 0 0 {-float(l)!r}" size="0.01" density="0" contype="0" conaffinity="0"/>'
            f'<geom type="sphere" pos="0 0 {-float(l)!r}" size="0.03" density="0" contype="0" conaffinity="0"/>')
    return (f'<mujoco model="chain{len(masses)}"><compiler angle="radian"/>'
            f'<option timestep="{h!r}" integrator="RK4" gravity="0 0 {-g!r}"><flag contact="disable"/></option>'
            f'<worldbody>{"".join(opened)}{"</body>" * len(masses)}</worldbody></mujoco>')


def _mujoco_states(mujoco, model, x_abs):
    """MuJoCo full-physics states (k, nstate) for absolute states x_abs (k, 2n)."""
    import numpy as np

    spec = mujoco.mjtState.mjSTATE_FULLPHYSICS
    data, n = mujoco.MjData(model), model.nq
    states = np.empty((len(x_abs), mujoco.mj_stateSize(model, spec)))
    for row, x in zip(states, np.asarray(x_abs, dtype=float)):
        data.qpos[:] = np.diff(x[:n], prepend=0.0)   # relative joint angles
        data.qvel[:] = np.diff(x[n:], prepend=0.0)
        mujoco.mj_getState(model, data, row, spec)
    return states


def _absolute(states, n: int):
    """(..., 2n) absolute angles and speeds from MuJoCo full-physics states (time, qpos, qvel)."""
    import numpy as np

    return np.concatenate([np.cumsum(states[..., 1:1 + n], axis=-1),
                           np.cumsum(states[..., 1 + n:1 + 2 * n], axis=-1)], axis=-1)


# -- timing --------------------------------------------------------------------------------------
def _timed(fn) -> tuple:
    wall, cpu = time.perf_counter(), time.process_time()
    fn()
    return time.perf_counter() - wall, time.process_time() - cpu


def sized_best(run, target: float, repeat: int) -> dict:
    """Grow ``run(n_steps)`` until it lasts a quarter of ``target`` (the warm-up), size n_steps
    for ``target`` seconds, then time ``repeat`` runs: best wall, best CPU, and the CPU/wall of
    the fastest run."""
    steps = 4
    while True:
        wall, _ = _timed(lambda: run(steps))
        if wall >= min(0.25, target / 4) or steps >= 1 << 40:
            break
        steps *= 4
    n_steps = max(1, math.ceil(steps * target / max(wall, 1e-9)))
    load = os.getloadavg()[0]
    times = [_timed(lambda: run(n_steps)) for _ in range(repeat)]
    fastest = min(times)
    return {"n_steps": n_steps, "wall": fastest[0], "cpu": min(c for _, c in times),
            "util": fastest[1] / fastest[0], "all_wall": [w for w, _ in times], "load": load}


# -- workers (fresh process each) ----------------------------------------------------------------
def worker_lcg(tag, threads: int, energy: bool, target: float, quick: bool, kernel: str = "lanes") -> None:
    import numpy as np

    from lagcodegen.run.sweep import sweep

    system = _compiled(tag)
    grid, x0 = _mass_grid(tag, quick), _x0(tag)
    members = int(np.prod([len(v) for v in grid.values()]))
    emit(phase="ready")
    bad = []

    def run(n_steps):
        result = sweep(system, grid, x0=x0, t_end=n_steps * H, h=H, method="rk4", threads=threads,
                       track_energy=energy, progress=False, kernel=kernel)
        bad.append(int(np.count_nonzero((result.status != 0) | (result.steps_done != n_steps))))
    timing = sized_best(run, target, REPEAT)
    emit(phase="done", members=members, failed=max(bad), **timing)


_HAND_LOOP = """\
void bench_hand_dp_members(long n_members, const double *x0s, const double *ps, double h, long n_steps,
                           double *x_final)
{
    long m;
    for (m = 0; m < n_members; ++m) hand_dp_rk4_run(x0s + 4 * m, ps + 5 * m, h, n_steps, x_final + 4 * m);
}
"""
_HAND_LOOP_CDEF = ("void bench_hand_dp_members(long n_members, const double *x0s, const double *ps, "
                   "double h, long n_steps, double *x_final);\n")


def hand_members():
    """cffi module with ``bench_hand_dp_members``: a C loop over members calling the peer's
    ``hand_dp_rk4_run`` (separate translation unit, lagcodegen's flags, as `_common.rhs_harness`)."""
    from peers import HAND_DP_CDEF, HAND_DP_SOURCE, build_cffi

    return build_cffi("_lcg_bench_hand_members", HAND_DP_CDEF + _HAND_LOOP_CDEF, HAND_DP_CDEF + _HAND_LOOP,
                      sources=[HAND_DP_SOURCE])


def _hand_params(grid, lengths=(1.0, 1.0), g=9.81):
    """(members, 5) rows (m1, m2, l1, l2, g) over the C-order product of grid's m1, m2 axes."""
    import numpy as np

    m1, m2 = np.meshgrid(grid["m1"], grid["m2"], indexing="ij")
    rows = np.column_stack([m1.ravel(), m2.ravel()])
    return np.ascontiguousarray(np.column_stack([rows, np.tile([*lengths, g], (len(rows), 1))]))


def worker_hand(target: float, quick: bool) -> None:
    import numpy as np

    module = hand_members()
    ffi, lib = module.ffi, module.lib
    ps = _hand_params(_mass_grid(DP, quick))
    x0s = np.ascontiguousarray(np.tile(DP_STATE, (len(ps), 1)), dtype=float)
    out = np.empty_like(x0s)
    pointers = [ffi.from_buffer("double[]", a) for a in (x0s, ps, out)]
    emit(phase="ready")

    def run(n_steps):
        lib.bench_hand_dp_members(len(ps), pointers[0], pointers[1], H, n_steps, pointers[2])
    timing = sized_best(run, target, REPEAT)
    emit(phase="done", members=len(ps), failed=int(np.count_nonzero(~np.isfinite(out).all(axis=1))), **timing)


def worker_mujoco(tag, threads: int, target: float, quick: bool) -> None:
    import mujoco
    import numpy as np
    from mujoco import rollout

    n = links(tag)
    model = mujoco.MjModel.from_xml_string(mjcf_chain([1.0] * n, [1.0] * n))
    datas = [mujoco.MjData(model) for _ in range(threads)]
    members = GRID[quick] ** 2
    x0s = np.tile(_x0(tag), (members, 1))
    x0s[:, 0] += np.linspace(-0.3, 0.3, members)
    initial = _mujoco_states(mujoco, model, x0s)
    buffers = {}
    emit(phase="ready", nstate=initial.shape[1])
    with rollout.Rollout(nthread=0 if threads == 1 else threads) as pool:
        def run(n_steps):
            start, left = initial, n_steps
            while left > 0:
                k = min(left, MUJOCO_CHUNK)
                if k not in buffers:
                    buffers[k] = (np.empty((members, k, initial.shape[1])), np.empty((members, k, 0)))
                state, sensors = buffers[k]
                pool.rollout(model, datas, start, nstep=k, state=state, sensordata=sensors)
                start, left = np.ascontiguousarray(state[:, -1]), left - k
            buffers["last"] = start
        timing = sized_best(run, target, REPEAT)
    failed = int(np.count_nonzero(~np.isfinite(buffers["last"]).all(axis=1)))
    emit(phase="done", members=members, failed=failed, version=mujoco.__version__, **timing)


def worker_scipy(tag, target: float) -> None:
    import numpy as np
    from scipy.integrate import solve_ivp

    from lagcodegen.run.simulate import make_rhs

    system = _compiled(tag)
    rhss = [make_rhs(system, {"m1": float(m)}) for m in np.linspace(0.5, 2.0, SCIPY_MEMBERS)]
    x0 = np.array(_x0(tag))
    emit(phase="ready")
    stats = {}

    def run(n_steps):
        steps = nfev = failed = 0
        for f in rhss:
            sol = solve_ivp(f, (0.0, n_steps * H), x0, method="RK45", rtol=RK45_RTOL, atol=RK45_ATOL)
            steps, nfev, failed = steps + len(sol.t) - 1, nfev + sol.nfev, failed + (not sol.success)
        stats.update(rk45_steps=steps, nfev=nfev, failed=failed)
    timing = sized_best(run, target, REPEAT)
    emit(phase="done", members=len(rhss), **stats, **timing)


def worker_check(tag) -> None:
    """Max abs differences from lagcodegen's sweep (RK4, h = 1e-3, CHECK_STEPS steps)."""
    import mujoco
    import numpy as np
    from mujoco import rollout
    from scipy.integrate import solve_ivp

    from lagcodegen.run.simulate import make_rhs
    from lagcodegen.run.sweep import sweep

    n = links(tag)
    system = _compiled(tag)
    masses = [1.0 + 0.1 * i for i in range(n)]
    params = {f"m{i + 1}": m for i, m in enumerate(masses)}
    x0 = np.array(_x0(tag))
    q1s = x0[0] + np.array([-0.2, 0.0, 0.2])
    emit(phase="ready")
    ours = sweep(system, members={"q1": q1s}, x0=x0, params=params, t_end=CHECK_STEPS * H, h=H,
                 trajectories=True, threads=1, track_energy=False, progress=False)
    x0s = np.tile(x0, (len(q1s), 1))
    x0s[:, 0] = q1s
    model = mujoco.MjModel.from_xml_string(mjcf_chain(masses, [1.0] * n))
    states, _ = rollout.rollout(model, mujoco.MjData(model), _mujoco_states(mujoco, model, x0s), nstep=CHECK_STEPS)
    result = {"mujoco_diff": float(np.abs(_absolute(states, n) - ours.trajectories[:, 1:]).max()),
              "ours_ok": bool((ours.status == 0).all())}
    rhs = make_rhs(system, params)
    finals = [solve_ivp(rhs, (0.0, CHECK_STEPS * H), x, method="RK45", rtol=RK45_RTOL, atol=RK45_ATOL).y[:, -1]
              for x in x0s]
    result["scipy_diff"] = float(np.abs(np.array(finals) - ours.x_final).max())
    if tag == DP:
        module = hand_members()
        ps = np.ascontiguousarray(np.tile([*masses, 1.0, 1.0, 9.81], (len(q1s), 1)))
        out, xs = np.empty_like(x0s), np.ascontiguousarray(x0s)
        buf = lambda a: module.ffi.from_buffer("double[]", a)  # noqa: E731
        module.lib.bench_hand_dp_members(len(q1s), buf(xs), buf(ps), H, CHECK_STEPS, buf(out))
        result["hand_diff"] = float(np.abs(out - ours.x_final).max())
    emit(phase="done", **result)


# -- vectorization evidence ----------------------------------------------------------------------
_REPORT = re.compile(r"^(?P<file>[^:]+):(?P<line>\d+):(?P<col>\d+): (?P<kind>optimized|missed): ?(?P<text>.*)$")
_SIGNATURE = re.compile(r"^(?:static\s+|inline\s+)*[A-Za-z_][\w \*]*?\b(?P<name>[A-Za-z_]\w*)\s*\(")
_PROBE = "#include <math.h>\nvoid probe(long n, const double *restrict x, double *restrict y)\n" \
         "{\n    long i;\n    for (i = 0; i < n; ++i) y[i] = sin(x[i]);\n}\n"


def function_spans(source: str) -> list:
    """[(first line, last line, name)] of the C function definitions in ``source`` (1-based;
    definitions open with ``{`` and close with ``}`` alone at column 0, as the templates write)."""
    spans, pending, start = [], None, None
    for number, line in enumerate(source.splitlines(), 1):
        match = _SIGNATURE.match(line)
        if match and not line.rstrip().endswith(";") and start is None:
            pending = match.group("name")
        elif line == "{" and pending is not None:
            start = number
        elif line == "}" and start is not None:
            spans.append((start, number, pending))
            pending = start = None
    return spans


def _function_at(spans, line: int) -> str:
    return next((name for first, last, name in spans if first <= line <= last), "(file scope)")


def _gcc(command, flags, c_file: Path) -> list:
    """gcc's -fopt-info lines for ``c_file`` as dicts (line, col, kind, text)."""
    done = subprocess.run([*command, *flags, "-c", str(c_file), "-o", os.devnull], capture_output=True,
                          text=True, timeout=300)
    if done.returncode != 0:
        raise RuntimeError(f"{' '.join(command + list(flags))} failed: {done.stderr.strip()[-400:]}")
    found = []
    for line in done.stderr.splitlines():
        match = _REPORT.match(line)
        if match and Path(match["file"]).name == c_file.name:
            found.append({"line": int(match["line"]), "col": int(match["col"]), "kind": match["kind"],
                          "text": match["text"].strip()})
    return found


def _compiler_command() -> list:
    import shlex
    import sysconfig

    return shlex.split(os.environ.get("CC") or sysconfig.get_config_var("CC") or "gcc")[:1]


def worker_vector() -> None:
    from peers import default_flags

    sources = _compiled(DP).lane_variant().sources  # the build sweep() runs: with the lane kernel
    emit(phase="ready")
    tmp = Path(tempfile.mkdtemp(prefix="lcg-bench-vec-"))
    try:
        (tmp / sources.header_name).write_text(sources.header)
        c_file = tmp / sources.source_name
        c_file.write_text(sources.source)
        command, flags = _compiler_command(), list(default_flags())
        lines = sources.source.splitlines()
        spans = function_spans(sources.source)
        optimized = _gcc(command, flags + ["-fopt-info-vec-optimized"], c_file)
        for report in optimized:
            report["function"] = _function_at(spans, report["line"])
            report["code"] = lines[report["line"] - 1].strip()
        lane_loops = _lane_loops(lines, spans, sources.layout.prefix)
        missed_reports = _gcc(command, flags + ["-fopt-info-vec-missed"], c_file)
        for loop in lane_loops:
            loop["vectorized"] = any(r["line"] == loop["line"] and "loop vectorized" in r["text"] for r in optimized)
            loop["missed"] = list(dict.fromkeys(r["text"] for r in missed_reports if r["line"] == loop["line"]))
        probe = tmp / "probe.c"
        probe.write_text(_PROBE)
        probe_plain = any("loop vectorized" in r["text"] for r in _gcc(command, flags + ["-fopt-info-vec-optimized"], probe))
        probe_fast = any("loop vectorized" in r["text"]
                         for r in _gcc(command, flags + ["-ffast-math", "-fopt-info-vec-optimized"], probe))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    emit(phase="done", compiler=" ".join(command), flags=flags, file=sources.source_name, reports=optimized,
         lane_loops=lane_loops, probe_plain=probe_plain, probe_fast=probe_fast)


def _lane_loops(lines, spans, prefix: str) -> list:
    """The loops that must vectorize across members: [{function, line, code}] of every
    ``for (lcg_lane = 0; ...`` in the lane dynamics and energy and every stage loop of the RK4 lane step."""
    wanted = {f"{prefix}_lanes_dynamics": "for (lcg_lane = 0;", f"{prefix}_lanes_energy": "for (lcg_lane = 0;",
              f"{prefix}_lanes_rk4_step": "for (m = 0;"}
    loops = []
    for first, last, name in spans:
        if name not in wanted:
            continue
        for number in range(first, last + 1):
            code = lines[number - 1].strip()
            after = lines[number] if number < len(lines) else ""
            if code.startswith(wanted[name]) and "lcg_redo[lcg_lane] !=" not in after:  # not the scalar fallback loop
                loops.append({"function": name, "line": number, "code": code})
    return loops


# -- parent side ---------------------------------------------------------------------------------
def _measure(args: list, timeout: float, env: dict) -> dict:
    return run_worker(__file__, [str(a) for a in args], [IMPORT_TIMEOUT, timeout], env)


def _row(result: dict, tag, tool: str, threads, energy) -> dict:
    row = {"model": label(tag), "tag": str(tag), "tool": tool, "threads": threads, "energy": energy, **result}
    if result.get("status") == "ok" and result.get("failed"):
        # found by review: 256 members stopped at step 0 counted as 256 x n_steps (2214 M member-steps/CPU-s)
        row["status"] = f"{result['failed']} of {result['members']} members failed: no rate"
    elif result.get("status") == "ok":
        # scipy: equivalent member-steps, members * integrated time (n_steps * h) / h
        done = row["members"] * row["n_steps"]
        row["member_steps"] = done
        row["rate_wall"] = done / row["wall"]
        row["rate_cpu"] = done / row["cpu"] if row["cpu"] > 0 else None
    return row


def measure(options) -> tuple:
    quick = bool(options.quick)
    timeout = options.timeout or DEFAULT_TIMEOUT
    target = getattr(options, "sweep_target", None) or TARGET_SECONDS[quick]
    mode = "quick" if quick else "full"
    cache = Path(tempfile.mkdtemp(prefix="lcg-bench-sweep-cache-"))
    env = {"LAGCODEGEN_CACHE_DIR": str(cache)}
    rows, checks = [], {}
    try:
        for tag in TAGS:
            for threads in (1, 2):
                for energy in (False, True):
                    result = _measure(["lcg", tag, threads, int(energy), target, mode], timeout, env)
                    rows.append(_row(result, tag, "lcg", threads, "on" if energy else "off"))
                    progress(f"sweep: {label(tag)} lagcodegen threads={threads} energy={energy}: {_progress(rows[-1])}")
                result = _measure(["lcg", tag, threads, 0, target, mode, "scalar"], timeout, env)
                rows.append(_row(result, tag, "lcg_scalar", threads, "off"))
                progress(f"sweep: {label(tag)} lagcodegen scalar kernel threads={threads}: {_progress(rows[-1])}")
            if tag == DP:
                rows.append(_row(_measure(["hand", tag, target, mode], timeout, env), tag, "hand", 1, "-"))
                progress(f"sweep: {label(tag)} hand C loop: {_progress(rows[-1])}")
            for threads in (1, 2):
                result = _measure(["mujoco", tag, threads, target, mode], timeout, env)
                rows.append(_row(result, tag, "mujoco", threads, "-"))
                progress(f"sweep: {label(tag)} MuJoCo threads={threads}: {_progress(rows[-1])}")
            rows.append(_row(_measure(["scipy", tag, target], timeout, env), tag, "scipy", 1, "-"))
            progress(f"sweep: {label(tag)} scipy RK45: {_progress(rows[-1])}")
            checks[str(tag)] = _measure(["check", tag], timeout, env)
            progress(f"sweep: {label(tag)} checks: {checks[str(tag)]['status']}")
        vector = _measure(["vector", DP], timeout, env)
        progress(f"sweep: vectorization report: {vector['status']}")
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    return rows, checks, vector, target, timeout


def _progress(row: dict) -> str:
    return f"{row['rate_wall'] / 1e6:.3f} M member-steps/s wall" if "rate_wall" in row else row["status"]


def _find(rows, tag, tool, threads=1, energy=None) -> dict | None:
    return next((r for r in rows if r["tag"] == str(tag) and r["tool"] == tool and r["threads"] == threads
                 and (energy is None or r["energy"] == energy)), None)


def _rate(row, key="rate_cpu"):
    return None if row is None else row.get(key)


def _ratio(a, b):
    return None if a is None or b is None or b == 0 else a / b


# -- report --------------------------------------------------------------------------------------
def _mega(value) -> str:
    return fmt(None if value is None else value / 1e6, ".3f")


def _main_table(rows) -> str:
    body = []
    for r in rows:
        ours = _rate(_find(rows, r["tag"], "lcg", 1, "off"))
        versus = "" if r["tool"] == "lcg" else fmt(_ratio(ours, _rate(r)), ".1f") + "x"
        if r.get("status") != "ok":
            body.append([r["model"], TOOLS[r["tool"]], r["threads"], r["energy"], r["status"][:40]] + [""] * 7)
            continue
        body.append([r["model"], TOOLS[r["tool"]], r["threads"], r["energy"], f"{r['members']} x {r['n_steps']}",
                     f"{r['wall']:.3f}", _mega(r["rate_wall"]), _mega(r["rate_cpu"]), f"{r['util']:.2f}",
                     f"{r['load']:.1f}", versus, r.get("failed", "")])
    header = ["model", "tool", "thr", "energy", "members x steps", "best wall [s]", "M/s wall", "M/CPU-s",
              "CPU/wall", "load", "ours/this", "failed"]
    return format_table(header, body, left=2)


def _speedups(rows) -> list:
    """[(model tag, tool, energy, wall speed-up, CPU/wall of the 2-thread run, per-CPU-s efficiency,
    CPU/wall of the 1-thread run)]."""
    found = []
    for r2 in rows:
        if r2["threads"] != 2 or "rate_wall" not in r2:
            continue
        r1 = _find(rows, r2["tag"], r2["tool"], 1, r2["energy"])
        if r1 is not None and "rate_wall" in r1:
            found.append((r2["tag"], r2["tool"], r2["energy"], r2["rate_wall"] / r1["rate_wall"], r2["util"],
                          _ratio(r2["rate_cpu"], r1["rate_cpu"]), r1["util"]))
    return found


def _speedup_lines(rows) -> str:
    lines = ["2 threads vs 1: speed-up = wall rate ratio; cores = CPU/wall of the 2-thread run (2.0 = two "
             "full cores); efficiency = per-CPU-s rate ratio (1.0 = threading costs nothing per member-step)"]
    for tag, tool, energy, speedup, cores, efficiency, _ in _speedups(rows):
        energy_text = f", energy {energy}" if energy != "-" else ""
        lines.append(f"    {label(parse_tag(tag))}, {TOOLS[tool]}{energy_text}: {speedup:.2f}x, cores {cores:.2f}, "
                     f"efficiency {fmt(efficiency, '.2f')}")
    return "\n".join(lines)


def _peer_notes(rows) -> str:
    lines = []
    for r in rows:
        if r["tool"] == "scipy" and r.get("status") == "ok":
            span = r["n_steps"] * H
            lines.append(f"    scipy RK45, {r['model']}: {r['members']} members x {span:g} s integrated; "
                         f"{r['rk45_steps']} accepted RK45 steps (mean step {r['members'] * span / max(r['rk45_steps'], 1):.2e} s), "
                         f"{r['nfev']} rhs calls, {r['failed']} failed; members/s (wall) "
                         f"{r['members'] / r['wall']:.2f}")
    return "\n".join(lines)


def _check_lines(checks) -> str:
    lines = [f"checks (masses m_i = 1 + 0.1 (i - 1), l_i = 1, g = 9.81; 3 initial states, {CHECK_STEPS} RK4 steps "
             f"of {H:g} s): max abs difference from lagcodegen sweep's states"]
    for tag, c in checks.items():
        if c["status"] != "ok":
            lines.append(f"    {label(parse_tag(tag))}: {c['status']}")
            continue
        parts = [f"MuJoCo RK4 trajectory (every step) {c['mujoco_diff']:.1e}"]
        if "hand_diff" in c:
            parts.append(f"hand C final state {c['hand_diff']:.1e}")
        parts.append(f"scipy RK45 rtol {RK45_RTOL:g} final state {c['scipy_diff']:.1e} (its own error)")
        lines.append(f"    {label(parse_tag(tag))}: " + "; ".join(parts) + ("" if c["ours_ok"] else "; OURS FAILED"))
    return "\n".join(lines)


def _vector_groups(reports) -> list:
    """[(function, line, kind, count, versioned, code)] of the optimized reports, in line order."""
    groups = {}
    for r in reports:
        if "loop versioned" in r["text"]:
            key = (r["function"], r["line"], "loop")
            entry = groups.setdefault(key, {"count": 0, "versioned": 0, "code": r["code"]})
            entry["versioned"] += 1
            continue
        kind = "loop" if "loop vectorized" in r["text"] else "block" if "basic block" in r["text"] else "other"
        entry = groups.setdefault((r["function"], r["line"], kind), {"count": 0, "versioned": 0, "code": r["code"]})
        entry["count"] += 1
    return [(f, line, kind, e["count"], e["versioned"], e["code"]) for (f, line, kind), e in
            sorted(groups.items(), key=lambda item: item[0][1])]


def _vector_section(v: dict) -> str:
    if v.get("status") != "ok":
        return f"vectorization: not measured ({v.get('status')})"
    groups = _vector_groups(v["reports"])
    loops = [g for g in groups if g[2] == "loop"]
    blocks = [g for g in groups if g[2] == "block"]
    widths = sorted({m.group(0) for r in v["reports"] for m in [re.search(r"\d+ byte vectors", r["text"])] if m})
    head = [f"vectorization: {v['compiler']} {' '.join(v['flags'])} -fopt-info-vec-optimized -c {v['file']} "
            f"(the double pendulum's generated C, render_sources as built)",
            f"    {sum(g[3] for g in loops)} loop vectorizations at {len(loops)} source loops, "
            f"{sum(g[3] for g in blocks)} basic-block (SLP) vectorizations at {len(blocks)} source lines; "
            f"vectors: {', '.join(widths) or 'none'}; count > 1 = the same source line vectorized in several "
            f"inlined or cloned copies; versioned = a runtime aliasing check guards the vector loop", ""]
    width = max((len(g[5][:60]) for g in groups), default=0)  # padded: format_table right-aligns
    body = [[f, line, kind, count, versioned or "", code[:60].ljust(width)] for f, line, kind, count, versioned, code in groups]
    table = format_table(["function (source)", "line", "kind", "count", "versioned", "code"], body, left=1)
    lane_lines = [""]
    for loop in v["lane_loops"]:
        why = "; ".join(loop["missed"][:2]) or "no report for this line (fully unrolled and SLP-vectorized, or removed)"
        lane_lines.append(f"    lane loop: line {loop['line']} of {loop['function']} `{loop['code'][:60]}`: "
                          + ("VECTORIZED (loop)" if loop["vectorized"] else f"not loop-vectorized; gcc: \"{why[:160]}\""))
    core = [loop for loop in v["lane_loops"] if "_lanes_dynamics" in loop["function"] or "_lanes_energy" in loop["function"]]
    across = bool(core) and all(loop["vectorized"] for loop in core)
    verdict = lane_lines + [
        "    verdict: " + ("gcc vectorizes the lane kernel's dynamics and energy loops across members (lanes "
                          "innermost); the scalar _sweep still runs members one after another." if across else
                          "the lane kernel's dynamics or energy loop is NOT vectorized across members."),
        f"    probe `y[i] = sin(x[i])` with the same flags: loop "
        f"{'vectorized' if v['probe_plain'] else 'NOT vectorized'}; adding -ffast-math (glibc libmvec "
        f"declarations): {'vectorized' if v['probe_fast'] else 'NOT vectorized'}. Hence the lane loops call their own "
        f"branch-free sin/cos (templates/trig.c.j2) and hand lanes beyond its range to libm afterwards.",
    ]
    return "\n".join(head) + table + "\n" + "\n".join(verdict)


def format_report(rows, checks, vector, target, timeout, start_load) -> str:
    import platform

    from _common import compiler_version, peer_versions
    from peers import default_flags

    import lagcodegen

    members = next((r["members"] for r in rows if r["tool"] == "lcg" and "members" in r), None)
    grid = "?" if members is None else f"{math.isqrt(members)} x {math.isqrt(members)} = {members}"
    head = [
        f"sweep suite: lagcodegen {lagcodegen.__version__}, {peer_versions('mujoco', 'scipy', 'numpy')}, "
        f"Python {platform.python_version()}, {compiler_version()}, flags {' '.join(default_flags())}",
        f"unit: member-steps per second (one RK4 step, h = {H:g} s, of one member); M = 1e6",
        "timer: wall = time.perf_counter around one whole batch (all members x steps, Python call included: "
        "sweep() with its result arrays; MuJoCo's Rollout.rollout in calls of "
        f"{MUJOCO_CHUNK} steps, writing the full state after every step as its API does); CPU = "
        "time.process_time of the worker (all its threads)",
        f"best of {REPEAT} runs after calibration runs (the warm-up) sized the batch to ~{target:g} s wall; one "
        f"fresh process per row; time-out {timeout:g} s per phase, imports + derive + compile "
        f"{IMPORT_TIMEOUT:g} s (never timed)",
        f"threads: thr 1 = sweep(threads=1) / Rollout(nthread=0, the calling thread) / the C or Python loop; "
        f"thr 2 = sweep(threads=2) / Rollout(nthread=2); machine: {os.cpu_count()} logical CPUs",
        f"MACHINE LOAD CAVEAT: shared machine, 1-min load average {start_load:.2f} at the start (column load: at "
        f"each row's timed runs); CPU/wall below thr means the worker waited for a core, so wall rates understate "
        f"a core's speed. The per-core goal and the MuJoCo ratios therefore use M/CPU-s of thr 1 rows.",
        f"lagcodegen: sweep(system, grid, method='rk4', track_energy=off|on, kernel='lanes'|'scalar') over a {grid} "
        f"member grid of m1 x m_n "
        f"(0.5..2 kg each); x0 = {DP_STATE} (double pendulum), sample_state(10) (chain); per step also a "
        f"finiteness check, max |q_i| tracking and a state backup; energy on = one energy evaluation per step",
        "hand C loop: C loop over the same members calling peers' hand_dp_rk4_run (no per-step checks), "
        "separate translation unit, same flags (the issue quotes ~6.8 M steps/s on one core for hand C)",
        "MuJoCo rollout: mjcf_chain (point masses, hinges, RK4, timestep 1e-3, contacts off), members vary "
        "initial q1 by -0.3..0.3 rad; no energy",
        f"scipy RK45 loop: Python loop over {SCIPY_MEMBERS} members, solve_ivp(RK45, rtol {RK45_RTOL:g}, atol "
        f"{RK45_ATOL:g}) on simulate.make_rhs; adaptive steps, so 'member-steps' = members x integrated time "
        f"/ {H:g} (the work RK4 at h = {H:g} would do), see the notes below",
        "ours/this = lagcodegen sweep (thr 1, energy off) M/CPU-s / this row's M/CPU-s; failed = members not "
        "finishing all steps with status OK (or non-finite)",
    ]
    notes = _peer_notes(rows)
    return "\n".join(head) + "\n\n" + _main_table(rows) + "\n\n" + _speedup_lines(rows) + \
        ("\n" + notes if notes else "") + "\n\n" + _check_lines(checks) + "\n\n" + _vector_section(vector)


# -- goals ---------------------------------------------------------------------------------------
def _per_core_goal(rows) -> dict:
    goal = f"lagcodegen sweep >= {PER_CORE_GOAL / 1e6:g} million member-steps/s per core, double pendulum"
    off, on = _find(rows, DP, "lcg", 1, "off"), _find(rows, DP, "lcg", 1, "on")
    rate = _rate(off)
    if rate is None:
        return {"goal": goal, "status": "FAIL", "detail": f"not measured ({off and off['status']})"}
    hand = _find(rows, DP, "hand")
    detail = (f"{rate / 1e6:.2f} M/CPU-s with 1 thread, energy off (wall {off['rate_wall'] / 1e6:.2f} M/s at "
              f"CPU/wall {off['util']:.2f}); energy on {_mega(_rate(on))} M/CPU-s; hand C loop "
              f"{_mega(_rate(hand))} M/CPU-s")
    return {"goal": goal, "status": "PASS" if rate >= PER_CORE_GOAL else "FAIL", "detail": detail}


#: CPU/wall the 1-thread run must have had for a speed-up against it to count (a starved baseline
#: inflates the ratio)
BASELINE_CORE = 0.9


def _speedup_goal(rows) -> dict:
    goal = f"lagcodegen sweep >= {SPEEDUP_GOAL:g}x on 2 threads vs 1 (energy off)"
    found = [s for s in _speedups(rows) if s[1] == "lcg" and s[2] == "off"]
    if len(found) < len(TAGS):
        return {"goal": goal, "status": "FAIL", "detail": "a 1- or 2-thread run failed"}
    statuses, parts = [], []
    for tag, _, _, speedup, cores, efficiency, baseline in found:
        if baseline < BASELINE_CORE:  # found by review: a starved 1-thread run made 2.66x from 0.99 cores
            status = "UNDECIDED"
        else:
            hopeless = efficiency is not None and 2 * efficiency < SPEEDUP_GOAL  # even with two free cores
            status = "PASS" if speedup >= SPEEDUP_GOAL else \
                "FAIL" if cores >= SPEEDUP_GOAL or hopeless else "UNDECIDED"
        statuses.append(status)
        parts.append(f"{label(parse_tag(tag))} {speedup:.2f}x with {cores:.2f} cores available, the 1-thread run "
                     f"{baseline:.2f} (per-CPU-s efficiency {fmt(efficiency, '.2f')})"
                     f"{'' if status != 'UNDECIDED' else ': undecided'}")
    status = "FAIL" if "FAIL" in statuses else "UNDECIDED" if "UNDECIDED" in statuses else "PASS"
    note = "" if status != "UNDECIDED" else \
        (f"; the machine gave the 2-thread run fewer than the {SPEEDUP_GOAL:g} cores the goal needs, or the "
         f"1-thread run less than {BASELINE_CORE:g} of one")
    return {"goal": goal, "status": status, "detail": "; ".join(parts) + note}


#: largest difference of MuJoCo's trajectory from ours that still counts as the same equations
#: (recorded: 1.3e-11 double pendulum, 7.2e-11 chain n=10, rounding over CHECK_STEPS steps)
SAME_EQUATIONS = 1e-9


def _mujoco_goal(rows, tag, checks) -> dict:
    need = MUJOCO_GOALS[tag]
    goal = f"lagcodegen sweep >= {need:g}x MuJoCo rollout, {label(tag)} (1 thread, energy off, per CPU-s)"
    check = checks.get(str(tag), {})
    if check.get("status") != "ok" or not check.get("ours_ok") or not check.get("mujoco_diff", math.inf) <= SAME_EQUATIONS:
        # found by review: PASS at 92x when MuJoCo's chain fell under 0.9 g (its trajectory 0.8 off ours)
        return {"goal": goal, "status": "UNDECIDED",
                "detail": f"no check that both integrate the same equations (check {check.get('status')}, "
                          f"MuJoCo vs ours {check.get('mujoco_diff', math.nan):.1e} > {SAME_EQUATIONS:g})"}
    ours, theirs = _find(rows, tag, "lcg", 1, "off"), _find(rows, tag, "mujoco", 1)
    ratio = _ratio(_rate(ours), _rate(theirs))
    if ratio is None:
        return {"goal": goal, "status": "FAIL" if _rate(ours) is None else "UNDECIDED",
                "detail": f"ours {ours and ours['status']}, MuJoCo {theirs and theirs['status']}"}
    on = _ratio(_rate(_find(rows, tag, "lcg", 1, "on")), _rate(theirs))
    wall = _ratio(_rate(ours, "rate_wall"), _rate(theirs, "rate_wall"))
    detail = (f"{ratio:.1f}x ({_mega(_rate(ours))} vs {_mega(_rate(theirs))} M/CPU-s; wall ratio "
              f"{fmt(wall, '.1f')}x; energy on {fmt(on, '.1f')}x)")
    return {"goal": goal, "status": "PASS" if ratio >= need else "FAIL", "detail": detail}


def goals(rows, checks) -> list:
    return [_per_core_goal(rows), _speedup_goal(rows)] + [_mujoco_goal(rows, tag, checks) for tag in TAGS]


# -- suite protocol ------------------------------------------------------------------------------
def add_arguments(group) -> None:
    group.add_argument("--sweep-target", type=float, default=None, metavar="SECONDS",
                       help=f"wall seconds per timed batch (default {TARGET_SECONDS[False]:g}, "
                            f"--quick {TARGET_SECONDS[True]:g})")


def run(options) -> dict:
    """Measure every contender side by side; return {"table", "rows", "goals"} (see run.py)."""
    start_load = os.getloadavg()[0]
    rows, checks, vector, target, timeout = measure(options)
    table = format_report(rows, checks, vector, target, timeout, start_load)
    extra = [{"check": tag, **c} for tag, c in checks.items()]
    vector_row = {"vectorization": {k: v for k, v in vector.items() if k != "reports"},
                  "vector_groups": _vector_groups(vector.get("reports", []))}
    return {"table": table, "rows": rows + extra + [vector_row], "goals": goals(rows, checks)}


def _worker(kind: str, args: list) -> None:
    quick = lambda text: text == "quick"  # noqa: E731
    if kind == "lcg":
        worker_lcg(parse_tag(args[0]), int(args[1]), bool(int(args[2])), float(args[3]), quick(args[4]), *args[5:])
    elif kind == "hand":
        worker_hand(float(args[1]), quick(args[2]))
    elif kind == "mujoco":
        worker_mujoco(parse_tag(args[0]), int(args[1]), float(args[2]), quick(args[3]))
    elif kind == "scipy":
        worker_scipy(parse_tag(args[0]), float(args[1]))
    elif kind == "check":
        worker_check(parse_tag(args[0]))
    elif kind == "vector":
        worker_vector()
    else:
        raise SystemExit(f"unknown worker {kind!r}")


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker":
        _worker(sys.argv[2], sys.argv[3:])
    else:
        sys.exit("bench_sweep.py is a suite module; run: python benchmarks/run.py sweep")
