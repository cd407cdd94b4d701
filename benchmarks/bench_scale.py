"""Suite `scale`: how lagcodegen's costs grow with the size of the model, against named peers.

Model: the planar n-link pendulum chain of ``catalog.pendulum_chain(n, route="tree")`` (point
masses m_i = 1 on massless rods l_i = 1, hinged at the origin, gravity 9.81; coordinates: absolute
angles from the downward vertical; stated as a kinematic tree, so that compile_model's cost model
picks the closed form or the recursive one and the report names it), n = 2, 5, 10, 20, 50, 100
(``--scale-sizes``; ``--quick``: 2, 5, 10, 20).
lagcodegen's side is `lagcodegen_chain` with `COMPILE_OPTIONS` / `DERIVE_OPTIONS` (or
``--scale-compile-options JSON``), e.g. ``{"formulation": "recursive"}`` to force one formulation.

Per n, each measurement in its own fresh process (imports and model construction untimed), under
a hard time-out per phase (``--timeout``, default 120 s) and a memory cap on its process tree
(``--scale-memory-cap``, default 12 GiB), both reported as results (``> 120 s``), not errors::

    derive          derive_equations(lagcodegen_chain(n))
    cold            compile_model(lagcodegen_chain(n), cache_dir=<new empty dir>), every default method
    warm            the same call in a new process on the same cache dir (a cache hit), then RK4:
                    simulate(system, x0, t_end=k h, h=1e-3, method="rk4", stride=k) per step
    cold rk4        compile_model(..., methods=("rk4",)) into another empty dir, then RK4 the same way
    MuJoCo RK4      mujoco.rollout of bench_sweep.mjcf_chain (same chain, integrator RK4, timestep 1e-3,
                    contacts off): one trajectory, Rollout(nthread=0), calls of MUJOCO_CHUNK steps
    Pinocchio RK4   peers/pinocchio_chain.cpp: classic RK4 whose 4 stages call pinocchio::aba (tau = 0),
                    g++ -O3 -DNDEBUG; two builds: "inline" (header only, -march=native, every template
                    instantiated in the program) and "lib" (the wheel's precompiled aba from
                    libpinocchio_default; no -march=native, which would change Eigen's alignment ABI:
                    free() of a misaligned pointer), each run with aba's Convention::LOCAL (default)
                    and ::WORLD; the goals use the fastest of the four

Peak memory: the parent samples the worker's whole process tree (the worker and every descendant,
gcc included) every SAMPLE_SECONDS with psutil and sums their RSS; the column is the largest sum:
a lower bound of the true peak (sampling can miss a spike). A compile stopped by the time-out
shows the peak seen until then (``>=``). The worker's ru_maxrss (RUSAGE_SELF, RUSAGE_CHILDREN) go
to the JSON only: Linux carries a process's high-water RSS across exec, so a child's figure starts
at the RSS of the process that forked it (the run.py parent for the worker, the ~90 MiB Python
worker for each gcc), not at the child's own use.

Step times: ns per RK4 step of one trajectory (h = 1e-3) from x0 = `_common.sample_state(n)`,
per CPU second of the (single-threaded) worker: the step count is grown until one run lasts a
quarter of ``--scale-target`` seconds (the warm-up), sized for the target, best of REPEAT runs.
Growth exponents: least-squares slope of log(cost) against log(n) over the measured sizes n >= 5.

Checks: after CHECK_STEPS RK4 steps from the same x0, the absolute states (MuJoCo's and
Pinocchio's relative joint angles summed) of MuJoCo, both Pinocchio builds and lagcodegen, and
of the inline Pinocchio build run with rotational inertia exactly 0 (lagcodegen's point masses;
MuJoCo needs > 0, so the peers' timed models carry 1e-12 kg m^2, as bench_sweep's).
Sweep row at n = SWEEP_N (else the largest measured n below it, as a smoke run, goal not run):
lagcodegen ``sweep(system, {m1, m_n grid}, method="rk4", threads=1, track_energy=False)`` of a
``compile_model(..., methods=("rk4",))`` build with its lane kernel (compiled untimed)
member-steps per CPU second against bench_sweep's MuJoCo rollout worker (same member count).

Goals (issue 15): cold compile_model with every default method at n = 20 <= 3 s, n = 50 <= 10 s,
n = 100 <= 30 s; peak memory (gcc included) <= 1 GiB at n = 100; warm <= 100 ms at every n; RK4
step >= 3x faster than MuJoCo's RK4 and >= 2x faster than Pinocchio's ABA-based RK4 (its fastest
run) at n = 10, 20, 50, 100; sweep throughput at n = 50 >= 3x MuJoCo rollout per core;
derivation at n = 100 <= 5 s.

Run through the suite runner: ``python benchmarks/run.py scale [--quick] [--timeout S]``.
"""
from __future__ import annotations

import json
import math
import os
import queue
import shutil
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import emit, fmt, format_table, progress, sample_state  # noqa: E402

DESCRIPTION = "n-link chain n=2..100: cold/warm compile, peak memory, RK4 step vs MuJoCo and Pinocchio ABA, growth"
HERE = Path(__file__).resolve().parent
SIZES = {False: (2, 5, 10, 20, 50, 100), True: (2, 5, 10, 20)}  # key: --quick
H = 1e-3
CHECK_STEPS = 1000
DEFAULT_TIMEOUT = 120.0          # per phase of a measurement (a lagcodegen compile, a derivation)
IMPORT_TIMEOUT = 120.0           # imports and model construction, never timed
PIN_BUILD_TIMEOUT = 1800.0       # g++ of the header-only Pinocchio peer: ~3 min on a free core
TARGET_SECONDS = {False: 1.0, True: 0.3}
REPEAT = 3
MEMORY_CAP_GIB = 12.0
SAMPLE_SECONDS = 0.05
MUJOCO_CHUNK = 1000
SWEEP_N = 50
PIN_VARIANTS = ("inline", "lib")    # builds of peers/pinocchio_chain.cpp
PIN_CONVENTIONS = ("local", "world")  # aba's Convention, chosen at run time
PIN_RUNS = tuple(f"{v}_{c}" for v in PIN_VARIANTS for c in PIN_CONVENTIONS)

COLD_GOALS = {20: 3.0, 50: 10.0, 100: 30.0}        # n -> seconds
MEMORY_GOAL = (100, 1024.0)                         # n, MiB
WARM_GOAL = 0.1                                     # seconds, every n
STEP_GOAL_SIZES = (10, 20, 50, 100)
MUJOCO_STEP_RATIO, PINOCCHIO_STEP_RATIO = 3.0, 2.0
SWEEP_RATIO = 3.0
DERIVE_GOAL = (100, 5.0)                            # n, seconds

# -- lagcodegen's side: one place to change the model or the options ----------------------------
COMPILE_OPTIONS: dict = {}   # extra compile_model keywords, e.g. {"formulation": "recursive"}
DERIVE_OPTIONS: dict = {}    # extra derive_equations keywords


def lagcodegen_chain(n: int):
    """The Model lagcodegen compiles for the n-link chain."""
    from lagcodegen.catalog import pendulum_chain

    return pendulum_chain(n, route="tree")


# -- worker side (fresh process each) ------------------------------------------------------------
def _rusage() -> dict:
    import resource

    return {"maxrss_self_mib": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
            "maxrss_children_mib": resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss / 1024.0}


def _x0(n: int):
    """Initial state (2n,): absolute angles, then absolute angular speeds."""
    return sample_state(n)


def _relative(x0, n: int):
    """Relative joint angles and speeds (MuJoCo's and Pinocchio's coordinates) of absolute ones."""
    import numpy as np

    x0 = np.asarray(x0, dtype=float)
    return np.concatenate([np.diff(x0[:n], prepend=0.0), np.diff(x0[n:], prepend=0.0)])


def _absolute_of_relative(x, n: int):
    import numpy as np

    x = np.asarray(x, dtype=float)
    return np.concatenate([np.cumsum(x[:n]), np.cumsum(x[n:])])


def worker_derive(n: int, options: dict) -> None:
    from lagcodegen.symbolic.derive import derive_equations

    model = lagcodegen_chain(n)
    emit(phase="ready")
    start = time.perf_counter()
    derive_equations(model, **{**DERIVE_OPTIONS, **options})
    emit(phase="done", seconds=time.perf_counter() - start, **_rusage())


def worker_compile(n: int, cache_dir: str, options: dict, measure: bool, target: float) -> None:
    """Time compile_model; with ``measure``, then the RK4 step time and the check's final state."""
    import warnings

    import numpy as np
    from bench_sweep import sized_best

    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    model = lagcodegen_chain(n)
    emit(phase="ready")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        start = time.perf_counter()
        system = compile_model(model, cache_dir=cache_dir, **{**COMPILE_OPTIONS, **options})
        seconds = time.perf_counter() - start
    emit(phase="compiled", seconds=seconds, methods=list(system.layout.methods),
         formulation=system.layout.formulation,
         warnings=sorted({f"{type(w.message).__name__}: {str(w.message)[:200]}" for w in caught}), **_rusage())
    if not measure:
        return
    x0 = _x0(n)
    check = simulate(system, x0, t_end=CHECK_STEPS * H, h=H, method="rk4", stride=CHECK_STEPS, check_stability=False)
    statuses = []

    def run(n_steps):
        result = simulate(system, x0, t_end=n_steps * H, h=H, method="rk4", stride=n_steps, check_stability=False)
        statuses.append(bool(result.ok and np.isfinite(result.x[-1]).all()))
    timing = sized_best(run, target, REPEAT)
    emit(phase="done", final=[float(v) for v in check.x[-1]], check_ok=bool(check.ok), runs_ok=all(statuses),
         **_step_times(timing))


def _step_times(timing: dict) -> dict:
    return {"n_steps": timing["n_steps"], "ns_cpu": 1e9 * timing["cpu"] / timing["n_steps"],
            "ns_wall": 1e9 * timing["wall"] / timing["n_steps"], "util": timing["util"], "load": timing["load"]}


def worker_mujoco(n: int, target: float) -> None:
    """ns per RK4 step of one MuJoCo trajectory (rollout, calling thread) and the check's state."""
    import mujoco
    import numpy as np
    from bench_sweep import _absolute, _mujoco_states, mjcf_chain, sized_best
    from mujoco import rollout

    model = mujoco.MjModel.from_xml_string(mjcf_chain([1.0] * n, [1.0] * n, h=H))
    data = mujoco.MjData(model)
    initial = _mujoco_states(mujoco, model, [_x0(n)])
    nstate = initial.shape[1]
    buffers = {}

    def buffer(k):
        if k not in buffers:
            buffers[k] = (np.empty((1, k, nstate)), np.empty((1, k, 0)))
        return buffers[k]
    emit(phase="ready", nstate=nstate)
    with rollout.Rollout(nthread=0) as pool:
        state, sensors = buffer(CHECK_STEPS)
        pool.rollout(model, [data], initial, nstep=CHECK_STEPS, state=state, sensordata=sensors)
        final = _absolute(state[0, -1], n)
        finite = []

        def run(n_steps):
            start, left = initial, n_steps
            while left > 0:
                k = min(left, MUJOCO_CHUNK)
                state, sensors = buffer(k)
                pool.rollout(model, [data], start, nstep=k, state=state, sensordata=sensors)
                start, left = np.ascontiguousarray(state[:, -1]), left - k
            finite.append(bool(np.isfinite(start).all()))
        timing = sized_best(run, target, REPEAT)
    emit(phase="done", final=[float(v) for v in final], runs_ok=all(finite), version=mujoco.__version__,
         **_step_times(timing))


def worker_sweep_lcg(n: int, cache_dir: str, options: dict, target: float, quick: bool) -> None:
    """Member-steps of lagcodegen's sweep (RK4, 1 thread, energy off) over bench_sweep's m1 x m_n grid."""
    import numpy as np
    from bench_sweep import _mass_grid, sized_best

    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.sweep import sweep

    options = {**COMPILE_OPTIONS, "methods": ("rk4",), **options}  # RK4 only: the sweep needs no other
    system = compile_model(lagcodegen_chain(n), cache_dir=cache_dir, **options)
    system.lane_variant()  # compiled here, untimed: sweep() builds it on its first lane run
    grid, x0 = _mass_grid(n, quick), _x0(n)
    members = int(np.prod([len(v) for v in grid.values()]))
    emit(phase="ready")
    bad = []

    def run(n_steps):
        result = sweep(system, grid, x0=x0, t_end=n_steps * H, h=H, method="rk4", threads=1,
                       track_energy=False, progress=False)
        bad.append(int(np.count_nonzero((result.status != 0) | (result.steps_done != n_steps))))
    timing = sized_best(run, target, REPEAT)
    emit(phase="done", members=members, failed=max(bad), **timing)


# -- Pinocchio peer: build and run ---------------------------------------------------------------
PIN_SOURCE = HERE / "peers" / "pinocchio_chain.cpp"


def cmeel_prefix() -> Path:
    """``cmeel.prefix`` of the pin wheel (headers under include/, libraries under lib/):
    ``$PINOCCHIO_PREFIX`` if set, else the one beside the installed packages."""
    import sysconfig

    if os.environ.get("PINOCCHIO_PREFIX"):
        return Path(os.environ["PINOCCHIO_PREFIX"])
    for key in ("purelib", "platlib"):
        path = Path(sysconfig.get_paths()[key]) / "cmeel.prefix"
        if (path / "include" / "pinocchio").is_dir():
            return path
    raise FileNotFoundError("no cmeel.prefix/include/pinocchio beside the installed packages: pip install pin")


def eigen_include(prefix: Path) -> Path:
    """Eigen's headers: the cmeel-eigen wheel's, else Debian's libeigen3-dev."""
    for path in (prefix / "include" / "eigen3", Path("/usr/include/eigen3")):
        if (path / "Eigen" / "Core").is_file():
            return path
    raise FileNotFoundError("no Eigen headers (pip install cmeel-eigen, or apt-get install libeigen3-dev)")


def _pinocchio_defines(prefix: Path) -> list:
    """-D flags of the pinocchio::pinocchio_headers target of the wheel's CMake config."""
    import re

    targets = prefix / "lib" / "cmake" / "pinocchio" / "pinocchioTargets.cmake"
    block = re.search(r"set_target_properties\(pinocchio::pinocchio_headers PROPERTIES(.*?)\n\)",
                      targets.read_text(), re.S) if targets.is_file() else None
    found = re.search(r'INTERFACE_COMPILE_DEFINITIONS "([^"]*)"', block.group(1)) if block else None
    defines = found.group(1).split(";") if found else [
        "BOOST_MPL_LIMIT_LIST_SIZE=30", "BOOST_MPL_LIMIT_VECTOR_SIZE=30", "BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS",
        "BOOST_FUSION_INVOKE_MAX_ARITY=12"]
    return [f"-D{d}" for d in defines if d and "$<" not in d]


def pinocchio_command(variant: str, output: Path) -> list:
    """g++ command line of the peer: ``inline`` (header only, -march=native) or ``lib`` (the
    wheel's libpinocchio_default for aba; rpath set so the program finds it)."""
    prefix = cmeel_prefix()
    cxx = os.environ.get("CXX", "g++")
    common = [cxx, "-std=c++17", "-O3", "-DNDEBUG", f"-I{prefix / 'include'}", f"-I{eigen_include(prefix)}",
              *_pinocchio_defines(prefix)]
    if variant == "inline":
        return [*common, "-march=native", str(PIN_SOURCE), "-o", str(output)]
    lib = prefix / "lib"
    return [*common, "-DPINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION", str(PIN_SOURCE), "-o", str(output),
            f"-L{lib}", "-lpinocchio_default", f"-Wl,-rpath,{lib}"]


def build_pinocchio_chain(variant: str, timeout: float = PIN_BUILD_TIMEOUT) -> tuple:
    """(path of the compiled peer, seconds spent building: 0 when it was cached). Cached in
    `peers.peer_cache_dir()` under the sha256 of the command, the source, pin's version and the
    compiler's."""
    import hashlib
    from importlib.metadata import version

    from peers import peer_cache_dir

    probe = pinocchio_command(variant, Path("OUT"))
    compiler = subprocess.run([probe[0], "--version"], capture_output=True, text=True, timeout=60).stdout
    key = hashlib.sha256(json.dumps([probe, PIN_SOURCE.read_text(), version("pin"), compiler]).encode()).hexdigest()
    target = peer_cache_dir() / f"pinocchio_chain_{variant}_{key[:16]}"
    if target.is_file():
        return target, 0.0
    with tempfile.TemporaryDirectory(prefix="lcg-pin-", dir=peer_cache_dir()) as tmp:
        built = Path(tmp) / target.name
        start = time.perf_counter()
        done = subprocess.run(pinocchio_command(variant, built), capture_output=True, text=True, timeout=timeout)
        if done.returncode != 0:
            raise RuntimeError(f"g++ failed: {done.stderr.strip()[-600:]}")
        os.replace(built, target)
        return target, time.perf_counter() - start


def run_pinocchio(binary: Path, n: int, target: float, timeout: float, inertia: float = 1e-12,
                  convention: str = "local") -> dict:
    """Run the peer for n links from `_x0` (rotational inertia ``inertia`` about each mass, aba's
    ``convention``); its JSON plus ``final`` as absolute state."""
    state = " ".join(repr(float(v)) for v in _relative(_x0(n), n))
    try:
        done = subprocess.run([str(binary), str(n), str(CHECK_STEPS), repr(target), str(REPEAT), repr(inertia), convention],
                              input=state,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return {"status": "timeout"}
    if done.returncode != 0:
        return {"status": f"error: {(done.stderr.strip().splitlines() or ['exit ' + str(done.returncode)])[-1]}"}
    result = json.loads(done.stdout)
    result["final"] = [float(v) for v in _absolute_of_relative(result["final"], n)]
    return {"status": "ok" if result["finite"] else "error: non-finite state", "ns_cpu": result["cpu_ns_per_step"],
            "ns_wall": result["wall_ns_per_step"], **result}


# -- parent side: a fresh process, its tree watched ----------------------------------------------
def _pump(stream, lines: queue.Queue) -> None:
    from bench_derive import MESSAGE_PREFIX

    for line in stream:
        if line.startswith(MESSAGE_PREFIX):
            lines.put(json.loads(line[len(MESSAGE_PREFIX):]))
    lines.put(None)


def _tree_rss(root) -> int:
    """Summed RSS (bytes) of ``root`` and all its descendants; vanished processes count 0."""
    import psutil

    total = 0
    try:
        processes = [root, *root.children(recursive=True)]
    except psutil.Error:
        return 0
    for process in processes:
        try:
            total += process.memory_info().rss
        except psutil.Error:
            pass
    return total


def run_tree(argv: list, timeouts: list, memory_cap: float) -> tuple:
    """Run ``argv`` (it emits one prefixed JSON message per phase) in its own session; phase i
    limited to ``timeouts[i]`` s; the summed RSS of its process tree sampled every SAMPLE_SECONDS
    and capped at ``memory_cap`` bytes. On a time-out or the cap the whole process group (gcc
    children included) is killed. Returns (messages, status, peak tree RSS per phase in MiB);
    status "ok", "timeout", "memory" or "error: <stderr tail>"."""
    import psutil

    with tempfile.TemporaryFile(mode="w+") as stderr:
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=stderr, text=True, start_new_session=True)
        lines: queue.Queue = queue.Queue()
        threading.Thread(target=_pump, args=(proc.stdout, lines), daemon=True).start()
        root = psutil.Process(proc.pid)
        messages, peaks, status = [], [], None
        try:
            for limit in timeouts:
                deadline, peak, message = time.monotonic() + limit, 0, None
                while True:
                    peak = max(peak, _tree_rss(root))
                    if peak > memory_cap:
                        status = "memory"
                        break
                    try:
                        message = lines.get(timeout=SAMPLE_SECONDS)
                        break
                    except queue.Empty:
                        if time.monotonic() > deadline:
                            status = "timeout"
                            break
                peaks.append(peak / 2**20)
                if status is not None or message is None:
                    break
                messages.append(message)
        finally:
            if proc.poll() is None and status is not None:
                os.killpg(proc.pid, signal.SIGKILL)  # the worker's session: it and its gcc children
            proc.wait()
        if status is not None:
            return messages, status, peaks
        if proc.returncode == 0 and len(messages) == len(timeouts):
            return messages, "ok", peaks
        stderr.seek(0)
        tail = stderr.read().strip().splitlines()[-1:] or [f"exit code {proc.returncode}"]
        return messages, "error: " + tail[0], peaks


def measure_worker(kind: str, args: list, timeouts: list, memory_cap: float) -> dict:
    """One fresh worker; its messages merged, plus status and per-phase tree peaks."""
    argv = [sys.executable, str(Path(__file__).resolve()), "--worker", kind, *map(str, args)]
    messages, status, peaks = run_tree(argv, timeouts, memory_cap)
    merged = {"status": status, "tree_peaks_mib": peaks}
    for message in messages:
        merged.update({k: v for k, v in message.items() if k != "phase"})
    return merged


def _peak(result: dict, phase: int) -> float | None:
    """Peak summed RSS of the process tree in phase ``phase`` (MiB), from the parent's samples."""
    peaks = result.get("tree_peaks_mib", [])
    return peaks[phase] if len(peaks) > phase else None


# -- measuring everything ------------------------------------------------------------------------
def _sizes(options) -> tuple:
    text = getattr(options, "scale_sizes", None)
    if text:
        return tuple(sorted({int(v) for v in text.split(",") if v.strip()}))
    return SIZES[bool(options.quick)]


def measure(options) -> dict:
    quick = bool(options.quick)
    sizes = _sizes(options)
    timeout = options.timeout or DEFAULT_TIMEOUT
    target = getattr(options, "scale_target", None) or TARGET_SECONDS[quick]
    cap = (getattr(options, "scale_memory_cap", None) or MEMORY_CAP_GIB) * 2**30
    compile_options = json.loads(getattr(options, "scale_compile_options", None) or "{}")
    derive_options = json.loads(getattr(options, "scale_derive_options", None) or "{}")
    rows, pin_builds = [], {}
    for variant in PIN_VARIANTS:
        try:
            progress(f"scale: building the Pinocchio peer ({variant}"
                     f"{'; header only: minutes the first time' if variant == 'inline' else ''})")
            path, seconds = build_pinocchio_chain(variant)
            pin_builds[variant] = {"status": "ok", "path": str(path), "build_seconds": seconds,
                                   "command": " ".join(pinocchio_command(variant, Path("<out>")))}
        except (OSError, RuntimeError, subprocess.TimeoutExpired, ValueError) as exc:
            pin_builds[variant] = {"status": f"error: {exc}"[:300]}
        progress(f"scale: Pinocchio {variant}: {pin_builds[variant]['status']} "
                 f"(build {pin_builds[variant].get('build_seconds', 0):.0f} s, 0 = cached)")
    caches = []
    try:
        for n in sizes:
            row = {"n": n}
            row["derive"] = measure_worker("derive", [n, json.dumps(derive_options)], [IMPORT_TIMEOUT, timeout], cap)
            progress(f"scale n={n}: derive {_brief(row['derive'], 'seconds')}")
            cold_dir = tempfile.mkdtemp(prefix=f"lcg-bench-scale-{n}-")
            caches.append(cold_dir)
            args = [n, cold_dir, json.dumps(compile_options)]
            row["cold"] = measure_worker("compile", args + [0, target], [IMPORT_TIMEOUT, timeout], cap)
            progress(f"scale n={n}: cold compile {_brief(row['cold'], 'seconds')}")
            if row["cold"]["status"] == "ok":
                row["warm"] = measure_worker("compile", args + [1, target], [IMPORT_TIMEOUT, timeout, timeout], cap)
            else:
                row["warm"] = {"status": "not run (cold compile did not finish)"}
            progress(f"scale n={n}: warm compile {_brief(row['warm'], 'seconds')}, RK4 {_brief(row['warm'], 'ns_cpu')} ns")
            rk4_dir = tempfile.mkdtemp(prefix=f"lcg-bench-scale-rk4-{n}-")
            caches.append(rk4_dir)
            rk4_options = json.dumps({**compile_options, "methods": ["rk4"]})
            row["cold_rk4"] = measure_worker("compile", [n, rk4_dir, rk4_options, 1, target],
                                             [IMPORT_TIMEOUT, timeout, timeout], cap)
            progress(f"scale n={n}: cold compile rk4 only {_brief(row['cold_rk4'], 'seconds')}, "
                     f"RK4 {_brief(row['cold_rk4'], 'ns_cpu')} ns")
            row["mujoco"] = measure_worker("mujoco", [n, target], [IMPORT_TIMEOUT, timeout], cap)
            progress(f"scale n={n}: MuJoCo RK4 {_brief(row['mujoco'], 'ns_cpu')} ns")
            for run_name in PIN_RUNS:
                variant, convention = run_name.split("_")
                build = pin_builds[variant]
                row[f"pin_{run_name}"] = run_pinocchio(Path(build["path"]), n, target, timeout, convention=convention) \
                    if build["status"] == "ok" else {"status": "not built"}
                progress(f"scale n={n}: Pinocchio {variant} {convention} RK4 {_brief(row[f'pin_{run_name}'], 'ns_cpu')} ns")
            if pin_builds["inline"]["status"] == "ok":  # the check only: lagcodegen's masses have no inertia
                row["pin_zero"] = run_pinocchio(Path(pin_builds["inline"]["path"]), n, 0.01, timeout, inertia=0.0)
            rows.append(row)
        sweep = _measure_sweep(rows, sizes, quick, target, timeout, cap, compile_options)
    finally:
        for path in caches:
            shutil.rmtree(path, ignore_errors=True)
    return {"sizes": sizes, "rows": rows, "sweep": sweep, "pin_builds": pin_builds, "timeout": timeout,
            "target": target, "memory_cap_gib": cap / 2**30, "compile_options": compile_options,
            "derive_options": derive_options}


def _measure_sweep(rows, sizes, quick, target, timeout, cap, compile_options) -> dict:
    below = [n for n in sizes if n <= SWEEP_N]
    if not below:
        return {"status": f"not run (no size <= {SWEEP_N})"}
    n = max(below)
    cache = tempfile.mkdtemp(prefix=f"lcg-bench-scale-sweep-{n}-")
    try:
        # first phase: imports, compile_model (cold) and the lane kernel's build, untimed
        lcg = measure_worker("sweep_lcg", [n, cache, json.dumps(compile_options), target, int(quick)],
                             [IMPORT_TIMEOUT + 2 * timeout, timeout], cap)
    finally:
        shutil.rmtree(cache, ignore_errors=True)
    progress(f"scale: sweep n={n} lagcodegen {_brief(lcg, 'cpu')}")
    mujoco = measure_worker("sweep_mujoco", [n, target, int(quick)], [IMPORT_TIMEOUT, timeout], cap)
    progress(f"scale: sweep n={n} MuJoCo {_brief(mujoco, 'cpu')}")
    for result in (lcg, mujoco):
        if result["status"] == "ok":
            result["rate_cpu"] = result["members"] * result["n_steps"] / result["cpu"]
            result["rate_wall"] = result["members"] * result["n_steps"] / result["wall"]
    return {"status": "ok", "n": n, "lcg": lcg, "mujoco": mujoco}


def _brief(result: dict, key: str) -> str:
    return f"{result[key]:.4g}" if result.get("status") == "ok" and key in result else result.get("status", "?")


# -- report --------------------------------------------------------------------------------------
def _ok(result: dict | None, key: str):
    """result[key] when the measurement finished, else None."""
    return result[key] if result and result.get("status") == "ok" and key in result else None


def _seconds_cell(result: dict, timeout: float, cap_gib: float) -> str:
    status = result.get("status", "?")
    if status == "ok":
        return f"{result['seconds']:.3f}"
    if status == "timeout":
        return f"> {timeout:g} s"
    if status == "memory":
        return f"mem > {cap_gib:g} GiB"
    return "error" if status.startswith("error") else status.split(" (")[0]


def _memory_cell(result: dict, phase: int) -> str:
    peak = _peak(result, phase)
    if peak is None:
        return "-"
    return f"{peak:.0f}" if result.get("status") == "ok" else f">= {peak:.0f}"


#: the two lagcodegen builds timed at each n: the default one (warm) and the RK4-only one
LCG_BUILDS = {"warm": "lagcodegen default build", "cold_rk4": "lagcodegen rk4-only build"}


def _ran_right(result: dict | None) -> bool:
    """Its timed runs all ended OK and its check run too (found by review: a build whose runs failed,
    its state 1.0 off, still gave the goal's step time)."""
    return bool(_ok(result, "ns_cpu") is not None and result.get("runs_ok") and result.get("check_ok"))


def lcg_build(row: dict) -> str | None:
    """The key of lagcodegen's faster build at this n among those that ran right (the same RK4
    kernel text)."""
    found = [(row[key]["ns_cpu"], key) for key in LCG_BUILDS if _ran_right(row.get(key))]
    return min(found)[1] if found else None


def lcg_step(row: dict) -> float | None:
    """lagcodegen's RK4 ns/step at this n: that of `lcg_build`."""
    key = lcg_build(row)
    return None if key is None else row[key]["ns_cpu"]


def pin_step(row: dict) -> tuple:
    """(ns/step, build_convention) of the fastest Pinocchio run at this n."""
    found = [(_ok(row.get(f"pin_{v}"), "ns_cpu"), v) for v in PIN_RUNS]
    found = [f for f in found if f[0] is not None]
    return min(found) if found else (None, None)


def _ratio(a, b):
    return None if a is None or b is None or b == 0 else a / b


def _ns(value) -> str:
    return fmt(value, ".0f")


def growth(points: list) -> tuple:
    """(slope of log cost against log n, number of points) over n >= 5; slope None below 2 points."""
    points = [(n, c) for n, c in points if n >= 5 and c is not None and c > 0]
    if len(points) < 2:
        return None, len(points)
    xs, ys = [math.log(n) for n, _ in points], [math.log(c) for _, c in points]
    mx, my = sum(xs) / len(xs), sum(ys) / len(ys)
    sxx = sum((x - mx) ** 2 for x in xs)
    return (sum((x - mx) * (y - my) for x, y in zip(xs, ys)) / sxx if sxx > 0 else None), len(points)


def cost_series(rows) -> dict:
    """label -> [(n, cost)] of every cost with a growth exponent."""
    series = {
        "lagcodegen derive [s]": [(r["n"], _ok(r["derive"], "seconds")) for r in rows],
        "lagcodegen cold compile, default methods [s]": [(r["n"], _ok(r["cold"], "seconds")) for r in rows],
        "lagcodegen cold compile, rk4 only [s]": [(r["n"], _ok(r["cold_rk4"], "seconds")) for r in rows],
        "lagcodegen warm compile [s]": [(r["n"], _ok(r["warm"], "seconds")) for r in rows],
        "lagcodegen peak memory, default methods [MiB]": [
            (r["n"], _peak(r["cold"], 1) if r["cold"]["status"] == "ok" else None) for r in rows],
        "lagcodegen RK4 step [ns]": [(r["n"], lcg_step(r)) for r in rows],
        "MuJoCo RK4 step [ns]": [(r["n"], _ok(r["mujoco"], "ns_cpu")) for r in rows],
    }
    for run_name in PIN_RUNS:
        series[f"Pinocchio ABA RK4 step, {run_name.replace('_', ' ')} [ns]"] = [
            (r["n"], _ok(r[f"pin_{run_name}"], "ns_cpu")) for r in rows]
    return series


def _max_diff(a, b):
    import numpy as np

    if a is None or b is None:
        return None
    return float(np.abs(np.asarray(a) - np.asarray(b)).max())


def check_diffs(row: dict) -> dict:
    """Max abs differences between the contenders' states after CHECK_STEPS steps."""
    finals = {**{label: _ok(row.get(key), "final") for key, label in LCG_BUILDS.items()},
              "MuJoCo": _ok(row["mujoco"], "final"),
              **{f"Pinocchio {v.replace('_', ' ')}": _ok(row[f"pin_{v}"], "final") for v in PIN_RUNS},
              "Pinocchio inertia 0": _ok(row.get("pin_zero"), "final")}
    pin = [f"Pinocchio {v.replace('_', ' ')}" for v in PIN_RUNS]
    # each lagcodegen build against the peers: the step goal times one, which must be the one checked
    # (found by review: the RK4-only build was timed, the default one compared)
    pairs = [*[("MuJoCo", p) for p in pin], *[(pin[0], p) for p in pin[1:]],
             *[(build, peer) for build in LCG_BUILDS.values() for peer in ("MuJoCo", pin[0], "Pinocchio inertia 0")]]
    return {f"{a} vs {b}": _max_diff(finals[a], finals[b]) for a, b in pairs}


def format_report(result: dict, start_load: float) -> str:
    import platform

    from _common import compiler_version, peer_versions

    import lagcodegen

    rows, timeout, cap = result["rows"], result["timeout"], result["memory_cap_gib"]
    builds = result["pin_builds"]
    head = [
        f"scale suite: lagcodegen {lagcodegen.__version__}, {peer_versions('mujoco', 'pin', 'cmeel-eigen', 'psutil')}, "
        f"Python {platform.python_version()}, {compiler_version()}; {os.cpu_count()} logical CPUs, 1-min load "
        f"{start_load:.2f} at the start",
        "model: planar n-link chain, point masses m_i = 1 on massless rods l_i = 1, g = 9.81 "
        "(catalog.pendulum_chain(n, route='tree')); "
        f"lagcodegen options: compile_model {result['compile_options'] or 'defaults'}, derive_equations "
        f"{result['derive_options'] or 'defaults'}",
        f"each cell a fresh process; time-out {timeout:g} s per phase (imports {IMPORT_TIMEOUT:g} s, untimed); "
        f"memory cap {cap:g} GiB on the process tree; a stopped compile shows '> {timeout:g} s' and the peak "
        "seen until then ('>=')",
        "times: wall clock (perf_counter) of derive_equations / compile_model alone (imports and the Model's "
        "construction excluded); cold = empty cache dir, warm = second call in a new process, same dir",
        f"peak MiB: largest summed RSS of the worker and all its descendants during the compile (gcc included; "
        f"psutil samples every {SAMPLE_SECONDS * 1000:g} ms: a lower bound); interpreter and sympy included",
        f"RK4 ns/step: one trajectory, h = {H:g}, x0 = sample_state(n), per CPU second of the worker; runs sized to "
        f"~{result['target']:g} s after a warm-up, best of {REPEAT}. lagcodegen: simulate(method='rk4', "
        "stride=steps) (the faster of its two builds); MuJoCo: Rollout(nthread=0).rollout of mjcf_chain "
        f"in calls of {MUJOCO_CHUNK} steps (state written every step, as its API does); Pinocchio: "
        "peers/pinocchio_chain.cpp, RK4 with 4 pinocchio::aba per step, timed in C++ (CLOCK_PROCESS_CPUTIME_ID)",
        *[f"    Pinocchio {v}: {b.get('command', b['status'])}" for v, b in builds.items()],
        "Pin <build> <convention>: aba(..., Convention::LOCAL (its default) or ::WORLD), chosen at run time",
        "MuJoCo/lcg, Pin/lcg: peer ns / lagcodegen ns (> 1: lagcodegen faster); Pin = the fastest of the four "
        "Pinocchio runs",
    ]
    compile_body = []
    for r in rows:
        compile_body.append([r["n"], r["cold"].get("formulation", "-").split(" (")[0],
                             _seconds_cell(r["derive"], timeout, cap), _seconds_cell(r["cold"], timeout, cap),
                             _memory_cell(r["cold"], 1), _seconds_cell(r["warm"], timeout, cap),
                             _seconds_cell(r["cold_rk4"], timeout, cap), _memory_cell(r["cold_rk4"], 1)])
    compile_table = format_table(["n", "formulation", "derive [s]", "cold [s]", "cold peak [MiB]", "warm [s]", "cold rk4-only [s]",
                                  "rk4-only peak [MiB]"], compile_body)
    step_body = []
    for r in rows:
        ours, mujoco, pin = lcg_step(r), _ok(r["mujoco"], "ns_cpu"), pin_step(r)[0]
        step_body.append([r["n"], _ns(_ok(r["warm"], "ns_cpu")), _ns(_ok(r["cold_rk4"], "ns_cpu")), _ns(mujoco),
                          *[_ns(_ok(r[f"pin_{v}"], "ns_cpu")) for v in PIN_RUNS],
                          fmt(_ratio(mujoco, ours), ".2f"), fmt(_ratio(pin, ours), ".2f")])
    step_table = format_table(["n", "lcg default", "lcg rk4-only", "MuJoCo",
                               *[f"Pin {v.replace('_', ' ')}" for v in PIN_RUNS], "MuJoCo/lcg", "Pin/lcg"], step_body)
    choices = [f"    n={r['n']}: {r['cold']['formulation']}" for r in rows if "formulation" in r["cold"]]
    compile_table += "\nformulation chosen by compile_model (its report line):\n" + "\n".join(choices)
    growth_body = []
    for name, points in cost_series(rows).items():
        slope, count = growth(points)
        growth_body.append([name, fmt(slope, ".2f"), count])
    growth_table = format_table(["cost", "slope d log(cost) / d log(n), n >= 5", "points"], growth_body)
    check_lines = [f"checks: max abs difference of the absolute states after {CHECK_STEPS} RK4 steps of {H:g} s from "
                   "sample_state(n) ('-': a side not measured); MuJoCo and Pinocchio give each mass a rotational "
                   "inertia of 1e-12 kg m^2, lagcodegen's have none: 'Pinocchio inertia 0' is the inline build "
                   "run with exactly 0"]
    for r in rows:
        diffs = check_diffs(r)
        check_lines.append(f"    n={r['n']}: " + "; ".join(f"{k} {fmt(v, '.1e')}" for k, v in diffs.items()))
    return "\n".join(head) + "\n\ncompile (seconds, MiB)\n" + compile_table + "\n\nRK4 step (ns per step, CPU)\n" + \
        step_table + "\n\ngrowth exponents (measured sizes only; a timed-out size is left out)\n" + growth_table + \
        "\n\n" + "\n".join(check_lines) + "\n\n" + _sweep_lines(result["sweep"])


def _sweep_lines(sweep: dict) -> str:
    if sweep.get("status") != "ok":
        return f"sweep: {sweep.get('status')}"
    n, lcg, mujoco = sweep["n"], sweep["lcg"], sweep["mujoco"]

    def part(name, r):
        if r["status"] != "ok":
            return f"{name}: {r['status'][:80]}"
        return (f"{name}: {r['rate_cpu'] / 1e6:.4f} M member-steps/CPU-s ({r['members']} members x {r['n_steps']} "
                f"steps, wall {r['wall']:.3f} s, CPU/wall {r['util']:.2f}, failed {r.get('failed', 0)})")
    ratio = _ratio(_ok(lcg, "rate_cpu"), _ok(mujoco, "rate_cpu"))
    return (f"sweep n={n} (RK4, h = {H:g}, 1 thread, energy off, lagcodegen built with methods=('rk4',) and its "
            f"lane kernel; members: m1 x m{n} grid of bench_sweep; MuJoCo: "
            f"bench_sweep's rollout worker, members vary q1):\n    {part('lagcodegen sweep', lcg)}\n    "
            f"{part('MuJoCo rollout', mujoco)}\n    lagcodegen / MuJoCo per CPU-s: {fmt(ratio, '.2f')}")


# -- goals ---------------------------------------------------------------------------------------
def _row(rows, n):
    return next((r for r in rows if r["n"] == n), None)


def _seconds_goal(goal: str, rows, n, phase: str, limit: float, timeout: float) -> dict:
    """PASS when the ``phase`` measurement at n finished within ``limit`` seconds."""
    row = _row(rows, n)
    if row is None:
        return {"goal": goal, "status": "NOT RUN", "detail": f"n={n} not among the sizes"}
    seconds = _ok(row[phase], "seconds")
    if seconds is None:
        return {"goal": goal, "status": "FAIL", "detail": f"did not finish: {row[phase]['status']} "
                f"(time-out {timeout:g} s)"}
    return {"goal": goal, "status": "PASS" if seconds <= limit else "FAIL", "detail": f"{seconds:.3f} s"}


def _cold_goal(rows, n, limit, timeout) -> dict:
    return _seconds_goal(f"cold compile_model, every default method, n={n} <= {limit:g} s", rows, n, "cold",
                         limit, timeout)


def _memory_goal(rows) -> dict:
    n, limit = MEMORY_GOAL
    goal = f"peak memory of the cold compile (gcc included) at n={n} <= {limit / 1024:g} GiB"
    row = _row(rows, n)
    if row is None:
        return {"goal": goal, "status": "NOT RUN", "detail": f"n={n} not among the sizes"}
    peak = _peak(row["cold"], 1)
    if row["cold"]["status"] == "ok":
        return {"goal": goal, "status": "PASS" if peak <= limit else "FAIL", "detail": f"{peak:.0f} MiB"}
    if peak is not None and peak > limit:
        return {"goal": goal, "status": "FAIL", "detail": f">= {peak:.0f} MiB before it was stopped "
                f"({row['cold']['status']})"}
    return {"goal": goal, "status": "UNDECIDED", "detail": f"compile stopped ({row['cold']['status']}) at "
            f"{fmt(peak, '.0f')} MiB"}


def _warm_goal(rows) -> dict:
    goal = f"warm compile_model (cache hit) <= {WARM_GOAL * 1000:g} ms at every n"
    if not rows:
        return {"goal": goal, "status": "NOT RUN", "detail": "no sizes"}
    parts, failed, missing = [], False, False
    for r in rows:
        seconds = _ok(r["warm"], "seconds")
        if seconds is None:
            missing = True
            parts.append(f"n={r['n']} {r['warm']['status']}")
        else:
            failed |= seconds > WARM_GOAL
            parts.append(f"n={r['n']} {seconds * 1000:.0f} ms")
    status = "FAIL" if failed else "UNDECIDED" if missing else "PASS"
    return {"goal": goal, "status": status, "detail": "; ".join(parts)}


#: largest difference of the states after CHECK_STEPS steps that counts as the same equations
#: (recorded lagcodegen vs MuJoCo: 5.4e-11 at n = 10 up to 3.8e-9 at n = 100, rounding)
SAME_EQUATIONS = 1e-7


def _step_goal(rows, peer: str, need: float) -> dict:
    goal = f"RK4 step >= {need:g}x faster than {peer} at n = {', '.join(map(str, STEP_GOAL_SIZES))}"
    parts, failed, missing = [], False, False
    for n in STEP_GOAL_SIZES:
        row = _row(rows, n)
        if row is None:
            missing = True
            parts.append(f"n={n} not run")
            continue
        ours = lcg_step(row)
        theirs = _ok(row["mujoco"], "ns_cpu") if peer == "MuJoCo" else pin_step(row)[0]
        build, diffs = lcg_build(row), check_diffs(row)
        first = f"Pinocchio {PIN_RUNS[0].replace('_', ' ')}"  # ours is compared with it, it with the others
        compared = "MuJoCo" if peer == "MuJoCo" else first
        chain = [diffs.get(f"{LCG_BUILDS[build]} vs {compared}")] if build else [None]
        if peer != "MuJoCo" and pin_step(row)[1] not in (None, PIN_RUNS[0]):
            chain.append(diffs.get(f"{first} vs Pinocchio {pin_step(row)[1].replace('_', ' ')}"))
        difference = None if None in chain else max(chain)
        if theirs is None:
            missing = True
            parts.append(f"n={n} {peer} not measured")
        elif ours is None:
            failed = True
            parts.append(f"n={n} lagcodegen did not compile or run right ({row['cold_rk4']['status']})")
        elif difference is None or not difference <= SAME_EQUATIONS:
            missing = True
            parts.append(f"n={n}: the timed build's state differs from {compared}'s by {fmt(difference, '.1e')} "
                         f"(> {SAME_EQUATIONS:g}): not the same equations, no ratio")
        else:
            ratio = theirs / ours
            failed |= ratio < need
            parts.append(f"n={n} {ratio:.2f}x ({ours:.0f} vs {theirs:.0f} ns)")
    status = "FAIL" if failed else "UNDECIDED" if missing else "PASS"
    return {"goal": goal, "status": status, "detail": "; ".join(parts)}


def _sweep_goal(sweep: dict) -> dict:
    goal = f"sweep throughput at n={SWEEP_N} >= {SWEEP_RATIO:g}x MuJoCo rollout per core"
    if sweep.get("status") != "ok" or sweep["n"] != SWEEP_N:
        where = f"measured at n={sweep['n']} only" if sweep.get("status") == "ok" else sweep.get("status")
        return {"goal": goal, "status": "NOT RUN", "detail": f"n={SWEEP_N} not among the sizes ({where})"}
    ours, theirs = _ok(sweep["lcg"], "rate_cpu"), _ok(sweep["mujoco"], "rate_cpu")
    if ours is not None and sweep["lcg"].get("failed"):  # a member that stops early did less work
        return {"goal": goal, "status": "FAIL", "detail": f"lagcodegen: {sweep['lcg']['failed']} members failed"}
    if ours is None:
        return {"goal": goal, "status": "FAIL", "detail": f"lagcodegen: {sweep['lcg']['status']}"}
    if theirs is None:
        return {"goal": goal, "status": "UNDECIDED", "detail": f"MuJoCo: {sweep['mujoco']['status']}"}
    ratio = ours / theirs
    return {"goal": goal, "status": "PASS" if ratio >= SWEEP_RATIO else "FAIL",
            "detail": f"{ratio:.2f}x ({ours / 1e6:.4f} vs {theirs / 1e6:.4f} M member-steps/CPU-s)"}


def _derive_goal(rows, timeout) -> dict:
    n, limit = DERIVE_GOAL
    return _seconds_goal(f"derive_equations at n={n} <= {limit:g} s", rows, n, "derive", limit, timeout)


def goals(result: dict) -> list:
    rows, timeout = result["rows"], result["timeout"]
    return [*[_cold_goal(rows, n, limit, timeout) for n, limit in COLD_GOALS.items()], _memory_goal(rows),
            _warm_goal(rows), _step_goal(rows, "MuJoCo", MUJOCO_STEP_RATIO),
            _step_goal(rows, "Pinocchio", PINOCCHIO_STEP_RATIO), _sweep_goal(result["sweep"]),
            _derive_goal(rows, timeout)]


# -- suite protocol ------------------------------------------------------------------------------
def add_arguments(group) -> None:
    group.add_argument("--scale-sizes", default=None, metavar="N,N,...",
                       help=f"chain sizes (default {','.join(map(str, SIZES[False]))}; --quick "
                            f"{','.join(map(str, SIZES[True]))})")
    group.add_argument("--scale-target", type=float, default=None, metavar="SECONDS",
                       help=f"seconds per timed RK4 run (default {TARGET_SECONDS[False]:g}, --quick {TARGET_SECONDS[True]:g})")
    group.add_argument("--scale-memory-cap", type=float, default=None, metavar="GIB",
                       help=f"kill a measurement whose process tree exceeds this (default {MEMORY_CAP_GIB:g} GiB)")
    group.add_argument("--scale-compile-options", default=None, metavar="JSON",
                       help="extra compile_model keywords for lagcodegen, e.g. '{\"formulation\": \"recursive\"}'")
    group.add_argument("--scale-derive-options", default=None, metavar="JSON",
                       help="extra derive_equations keywords for lagcodegen")


def run(options) -> dict:
    """Measure every contender side by side; return {"table", "rows", "goals"} (see run.py)."""
    start_load = os.getloadavg()[0]
    result = measure(options)
    table = format_report(result, start_load)
    rows = [{"n": r["n"], **{k: v for k, v in r.items() if k != "n"}, "checks": check_diffs(r)} for r in result["rows"]]
    growth_rows = [{"growth": name, "slope": growth(points)[0], "points": points}
                   for name, points in cost_series(result["rows"]).items()]
    extra = [{"sweep": result["sweep"]}, {"pinocchio_builds": result["pin_builds"]}]
    return {"table": table, "rows": rows + growth_rows + extra, "goals": goals(result)}


def _worker(kind: str, args: list) -> None:
    if kind == "derive":
        worker_derive(int(args[0]), json.loads(args[1]))
    elif kind == "compile":
        worker_compile(int(args[0]), args[1], json.loads(args[2]), bool(int(args[3])), float(args[4]))
    elif kind == "mujoco":
        worker_mujoco(int(args[0]), float(args[1]))
    elif kind == "sweep_lcg":
        worker_sweep_lcg(int(args[0]), args[1], json.loads(args[2]), float(args[3]), bool(int(args[4])))
    elif kind == "sweep_mujoco":
        from bench_sweep import worker_mujoco as sweep_mujoco

        sweep_mujoco(int(args[0]), 1, float(args[1]), bool(int(args[2])))
    else:
        raise SystemExit(f"unknown worker {kind!r}")


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker":
        _worker(sys.argv[2], sys.argv[3:])
    else:
        sys.exit("bench_scale.py is a suite module; run: python benchmarks/run.py scale")
