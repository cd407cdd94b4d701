"""Stage: CompiledSystem -> SweepResult: many runs of one kernel over parameters and initial states.

One compiled kernel serves every member (free parameters are runtime inputs); the loop over
members and steps runs in C (`lcg_<model>_sweep`), one call per chunk of members. Chunks run
on local threads (cffi releases the GIL and the C has no global state, so threads scale and the
results do not depend on the thread count) or, given a ``dask.distributed`` Client, as tasks on
a cluster whose workers build the kernel from its C sources or load it from their cache.

Two C kernels: ``lcg_<model>_sweep_lanes`` runs members in lane groups (several members per
vector, see `lanes.py`) and serves explicit Runge-Kutta methods of unconstrained models without
projection; ``lcg_<model>_sweep`` runs members one after another and serves everything.
``SweepResult.kernel`` says which ran. Both give the same per-member results, up to the last bits
of sin/cos (the lane kernel's branch-free polynomials against libm).

Memory: per member 2n (final state) + n (max |q|) + 3 numbers; trajectories, n_out * 2n per
member, only when asked for. Members whose mass matrix loses definiteness (a negative mass,
say) are not refused up front: they run and report SINGULAR_MASS_MATRIX in ``status``.
"""
from __future__ import annotations

import itertools
import math
import os
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass
from typing import Mapping, Sequence

import numpy as np

from .build import CompiledSystem
from .simulate import (Status, _dtype, _pointer, _work_size, initial_state, parameter_vector, positive_int,
                       step_count)

#: status of members a sweep did not reach (interrupted)
NOT_RUN = -1


@dataclass(frozen=True)
class SweepResult:
    """Per-member results of a sweep; row m of every array is member m.

    Attributes
    ----------
    columns : tuple of str
        Names varied across members (free parameters and/or state variables).
    values : ndarray (n_members, n_columns)
        Each member's values of ``columns``.
    grid : tuple of ndarray or None
        For a Cartesian grid, the axis values per column; members are in C order over them.
    x_final : ndarray (n_members, 2n)
        Final state (the last finite state when a member failed).
    q_max : ndarray (n_members, n)
        max |q_i| over every step.
    energy_error : ndarray (n_members,) or None
        max |E - E0| over every step, when the kernel has the energy output.
    status : ndarray (n_members,) of int
        `Status` codes; NOT_RUN (-1) for members an interruption skipped.
    steps_done : ndarray (n_members,)
    blowup_time : ndarray (n_members,)
        Time at which the failing step started; NaN for members that completed.
    t, trajectories : ndarray (n_out,), (n_members, n_out, 2n), or None
        Every stride-th state, only when requested (NaN after a failure).
    state_names, coordinate_names : tuple of str
    completed : bool
        False when the sweep was interrupted (Ctrl-C); finished members are kept.
    kernel : str
        ``"lanes"`` (the lane-group kernel) or ``"scalar"`` (members one after another).
    """

    columns: tuple
    values: np.ndarray
    grid: tuple | None
    x_final: np.ndarray
    q_max: np.ndarray
    energy_error: np.ndarray | None
    status: np.ndarray
    steps_done: np.ndarray
    blowup_time: np.ndarray
    t: np.ndarray | None
    trajectories: np.ndarray | None
    state_names: tuple
    coordinate_names: tuple
    completed: bool
    kernel: str = "scalar"

    @property
    def n_members(self) -> int:
        return len(self.status)

    def on_grid(self, field) -> np.ndarray:
        """``field`` (an attribute name or an (n_members,) array) reshaped to the grid's shape."""
        if self.grid is None:
            raise ValueError("this sweep was not a Cartesian grid")
        data = getattr(self, field) if isinstance(field, str) else np.asarray(field)
        return data.reshape(tuple(len(axis) for axis in self.grid) + data.shape[1:])


def cartesian_members(grid: Mapping[str, Sequence[float]]) -> tuple[tuple, np.ndarray, tuple]:
    """(columns, values (n_members, n_columns), axes) of the Cartesian product of ``grid``."""
    if not grid:
        raise ValueError("the grid is empty: give at least one name with values")
    columns = tuple(str(name) for name in grid)
    axes = []
    for name, axis in zip(columns, grid.values()):
        axis = np.asarray(axis, dtype=float).ravel()
        if axis.size == 0:
            raise ValueError(f"grid axis {name!r} has no values")
        axes.append(axis)
    values = np.array(list(itertools.product(*axes)), dtype=float).reshape(-1, len(columns))
    return columns, values, tuple(axes)


def table_members(members: Mapping[str, Sequence[float]]) -> tuple[tuple, np.ndarray]:
    """(columns, values) of an explicit member table: equal-length columns by name."""
    if not members:
        raise ValueError("the member table is empty")
    columns = tuple(str(name) for name in members)
    arrays = [np.asarray(v, dtype=float).ravel() for v in members.values()]
    lengths = {a.size for a in arrays}
    if len(lengths) != 1 or 0 in lengths:
        raise ValueError(f"member table columns must be non-empty and equally long, got lengths "
                         f"{dict(zip(columns, (a.size for a in arrays)))}")
    return columns, np.column_stack(arrays)


def member_arrays(system: CompiledSystem, columns, values, x0, params):
    """Per-member x0 (n_members, 2n) and p (n_members, n_p) for the columns varied."""
    layout = system.layout
    state_names = layout.coordinates + layout.speeds
    fixed = {name for name, _ in layout.fixed}
    for name in columns:
        if name in fixed:
            raise ValueError(f"{name!r} is fixed at build time and cannot be swept; free parameters: "
                             f"{', '.join(layout.parameters) or 'none'}")
        if name not in layout.parameters and name not in state_names:
            raise ValueError(f"cannot sweep {name!r}: not a free parameter ({', '.join(layout.parameters) or 'none'})"
                             f" nor a state variable ({', '.join(state_names)})")
    bad = [name for j, name in enumerate(columns) if not np.all(np.isfinite(values[:, j]))]
    if bad:
        raise ValueError(f"swept values of {', '.join(bad)} are not all finite")
    dtype = _dtype(system)
    if isinstance(x0, Mapping):  # swept state variables need no base value
        x0 = {**{name: 0.0 for name in columns if name in state_names}, **x0}
    base_x = initial_state(system, x0)
    base_p = parameter_vector(system, params)
    xs = np.repeat(base_x[None, :], len(values), axis=0)
    ps = np.repeat(base_p[None, :], len(values), axis=0) if base_p.size else np.zeros((len(values), 1), dtype)
    for j, name in enumerate(columns):
        if name in layout.parameters:
            ps[:, layout.parameters.index(name)] = values[:, j]
        else:
            xs[:, state_names.index(name)] = values[:, j]
    return np.ascontiguousarray(xs, dtype=dtype), np.ascontiguousarray(ps, dtype=dtype)


def sweep(system: CompiledSystem, grid: Mapping | None = None, *, members: Mapping | None = None, x0,
          t_end: float, h: float, method: str = "rk4", params: Mapping | None = None, t0: float = 0.0,
          trajectories: bool = False, stride: int = 1, threads: int | None = None,
          chunk_size: int | None = None, progress: bool | None = None, client=None,
          track_energy: bool = True, project: bool = False, kernel: str = "auto") -> SweepResult:
    """Run one compiled model for every member of a grid or table.

    Parameters
    ----------
    system : CompiledSystem
    grid : mapping name -> values, optional
        Cartesian product over free parameters and/or state variables (``"k"``, ``"q1"``).
    members : mapping name -> values, optional
        An explicit table instead of a grid (equal-length columns).
    x0 : sequence or mapping
        Base initial state; swept state variables override it.
    t_end, h, t0, method, params
        As in `simulate.simulate`; ``params`` are the base values of the free parameters.
    trajectories : bool
        Keep every ``stride``-th state of every member (memory n_members * n_out * 2n).
    threads : int, optional
        Local worker threads (default: all cores). Results do not depend on it.
    chunk_size : int, optional
        Members per C call / Dask task (default: about 4 chunks per thread, at most 4096, rounded
        up to whole lane groups).
    progress : bool, optional
        tqdm bar; default: shown when the sweep runs longer than about a second.
    client : dask.distributed.Client, optional
        Run chunks as tasks on this cluster instead of local threads.
    track_energy : bool
        Record max |E - E0| per member (one energy evaluation per step).
    project : bool
        Constrained models: project every member back onto the constraints after each step.
    kernel : {"auto", "lanes", "scalar"}
        C kernel: ``"auto"`` takes the lane-group kernel where it applies (explicit method, no
        projection, built with lanes), else the scalar one; ``"lanes"`` insists on it.
    """
    if (grid is None) == (members is None):
        raise ValueError("give exactly one of grid= (Cartesian) or members= (explicit table)")
    if grid is not None:
        columns, values, axes = cartesian_members(grid)
    else:
        (columns, values), axes = table_members(members), None
    layout = system.layout
    method = str(method).lower()
    if method not in layout.methods:
        raise ValueError(f"method {method!r} is not compiled into {layout.model!r}; compiled: {', '.join(layout.methods)}")
    stride = positive_int(stride, "stride")
    n_steps = step_count(t0, t_end, h)
    track_energy = track_energy and f"{layout.prefix}_energy" in layout.functions
    xs, ps = member_arrays(system, columns, values, x0, params)
    if project and not layout.n_constraints:
        raise ValueError(f"project needs holonomic constraints; model {layout.model!r} has none")
    if kernel != "scalar" and system.lane_build is not None and _lanes(system, method, project, "auto") == 0:
        lane_system = system.lane_variant()  # compiled on the first sweep that can use it
        if _lanes(lane_system, method, project, "auto"):
            system = lane_system
    lanes = _lanes(system, method, project, kernel)
    job = _Job(system, layout.methods.index(method), t0, h, n_steps, stride, track_energy, trajectories, project,
               lanes)
    out = _allocate(job, len(values))
    threads = threads or os.cpu_count() or 1
    if chunk_size is None:  # whole lane groups per chunk: only the sweep's last group has empty lanes
        chunk_size = max(1, min(4096, math.ceil(len(values) / (4 * threads))))
        chunk_size = -(-chunk_size // lanes) * lanes if lanes else chunk_size
    chunks = [(start, min(start + chunk_size, len(values))) for start in range(0, len(values), chunk_size)]
    run = _run_dask if client is not None else _run_threads
    completed = run(job, xs, ps, out, chunks, threads if client is None else client, progress)
    return _result(job, columns, values, axes, out, completed)


KERNELS = ("auto", "lanes", "scalar")


def _lanes(system: CompiledSystem, method: str, project: bool, kernel: str) -> int:
    """Lanes per group of the lane kernel for this sweep, or 0 for the scalar kernel."""
    from .schemes import KIND_EXPLICIT, get_scheme, scheme_kind

    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    layout = system.layout
    reason = None
    if scheme_kind(get_scheme(method)) != KIND_EXPLICIT:
        reason = f"method {method!r} is not an explicit Runge-Kutta method"
    elif project:
        reason = "projection onto the constraints runs on the scalar kernel only"
    elif f"{layout.prefix}_sweep_lanes" not in layout.functions:
        reason = f"model {layout.model!r} was built without the lane kernel (compile_model(lanes=0), or constrained)"
    if reason is None and kernel != "scalar":
        return int(getattr(system.lib, f"{layout.prefix.upper()}_LANES"))
    if kernel == "lanes":
        raise ValueError(f"kernel='lanes' does not apply: {reason}")
    return 0


@dataclass(frozen=True)
class _Job:
    system: CompiledSystem
    method_id: int
    t0: float
    h: float
    n_steps: int
    stride: int
    track_energy: bool
    trajectories: bool
    project: bool = False
    lanes: int = 0  # members per group of the lane kernel; 0: the scalar kernel

    @property
    def n_out(self) -> int:
        return self.n_steps // self.stride + 1


def _allocate(job: _Job, n_members: int) -> dict:
    layout, dtype = job.system.layout, _dtype(job.system)
    size = 2 * layout.n
    return {
        "x_final": np.full((n_members, size), np.nan, dtype),
        "q_max": np.full((n_members, layout.n), np.nan, dtype),
        "energy_error": np.full(n_members, np.nan, dtype),
        "status": np.full(n_members, NOT_RUN, np.intc),
        "steps_done": np.zeros(n_members, np.int_),
        "traj": np.full((n_members, job.n_out, size), np.nan, dtype) if job.trajectories else None,
    }


def run_chunk(job: _Job, xs: np.ndarray, ps: np.ndarray) -> dict:
    """One C call over the members in xs, ps; returns the chunk's output arrays."""
    out = _allocate(job, len(xs))
    _call(job, xs, ps, out)
    return out


def _call(job: _Job, xs, ps, out) -> None:
    system = job.system
    ffi, layout = system.ffi, system.layout
    traj = out["traj"]
    if job.lanes:
        lanes_c = getattr(system.lib, f"{layout.prefix}_sweep_lanes")
        code = lanes_c(job.method_id, len(xs), _pointer(system, xs), _pointer(system, ps), job.t0, job.h,
                       job.n_steps, job.stride, int(job.track_energy), _pointer(system, out["x_final"]),
                       _pointer(system, out["q_max"]), _pointer(system, out["energy_error"]),
                       ffi.from_buffer("int[]", out["status"]), ffi.from_buffer("long[]", out["steps_done"]),
                       ffi.NULL if traj is None else _pointer(system, traj))
        if code != Status.OK:
            raise RuntimeError(f"{layout.prefix}_sweep_lanes refused method number {job.method_id} ({code})")
        return
    work = np.empty(_work_size(system), dtype=_dtype(system))
    sweep_c = getattr(system.lib, f"{layout.prefix}_sweep")
    sweep_c(job.method_id, len(xs), _pointer(system, xs), _pointer(system, ps), job.t0, job.h, job.n_steps,
            job.stride, int(job.project), int(job.track_energy), _pointer(system, out["x_final"]), _pointer(system, out["q_max"]),
            _pointer(system, out["energy_error"]), ffi.from_buffer("int[]", out["status"]),
            ffi.from_buffer("long[]", out["steps_done"]),
            ffi.NULL if traj is None else _pointer(system, traj), _pointer(system, work))


def _progress_bar(total: int, progress: bool | None):
    if progress is False:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, unit="member", delay=0.0 if progress else 1.0, leave=False)


def _run_threads(job, xs, ps, out, chunks, threads, progress) -> bool:
    bar = _progress_bar(len(xs), progress)

    def task(bounds):
        start, stop = bounds
        view = {k: (None if v is None else v[start:stop]) for k, v in out.items()}
        _call(job, xs[start:stop], ps[start:stop], view)
        return stop - start

    pool = ThreadPoolExecutor(max_workers=threads)
    pending = {pool.submit(task, bounds) for bounds in chunks}
    try:
        while pending:
            done, pending = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for future in done:
                count = future.result()
                if bar is not None:
                    bar.update(count)
        return True
    except KeyboardInterrupt:
        for future in pending:
            future.cancel()
        return False
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        if bar is not None:
            bar.close()


def _run_dask(job, xs, ps, out, chunks, client, progress) -> bool:
    from dask.distributed import as_completed

    bar = _progress_bar(len(xs), progress)
    futures = {client.submit(run_chunk, job, xs[a:b], ps[a:b], pure=False): (a, b) for a, b in chunks}
    try:
        for future in as_completed(futures):
            a, b = futures[future]
            part = future.result()
            for key, array in out.items():
                if array is not None:
                    array[a:b] = part[key]
            if bar is not None:
                bar.update(b - a)
        return True
    except KeyboardInterrupt:
        client.cancel(list(futures))
        return False
    finally:
        if bar is not None:
            bar.close()


def _result(job: _Job, columns, values, axes, out, completed: bool) -> SweepResult:
    layout = job.system.layout
    failed = (out["status"] != Status.OK) & (out["status"] != NOT_RUN)
    blowup = np.where(failed, job.t0 + out["steps_done"] * job.h, np.nan)
    t = job.t0 + job.h * job.stride * np.arange(job.n_out) if job.trajectories else None
    return SweepResult(
        columns=columns, values=values, grid=axes, x_final=out["x_final"], q_max=out["q_max"],
        energy_error=out["energy_error"] if job.track_energy else None, status=out["status"],
        steps_done=out["steps_done"], blowup_time=blowup, t=t, trajectories=out["traj"],
        state_names=layout.coordinates + layout.speeds, coordinate_names=layout.coordinates,
        completed=completed, kernel="lanes" if job.lanes else "scalar")
