"""Stage: CompiledSystem -> SweepResult: many runs of one kernel over parameters and initial states.

One compiled kernel serves every member (free parameters are runtime inputs); the loop over
members and steps runs in C (`lcg_<model>_sweep`), one call per chunk of members. Chunks run
on local threads (cffi releases the GIL and the C has no global state, so threads scale and the
results do not depend on the thread count) or, given a ``dask.distributed`` Client, as tasks on
a cluster whose workers build the kernel from its C sources or load it from their cache.

Two C kernels: ``lcg_<model>_sweep_lanes`` runs members in lane groups (several members per
vector, see `lane_kernel.py`) and serves explicit Runge-Kutta methods of unconstrained models without
projection; ``lcg_<model>_sweep`` runs members one after another and serves everything.
``SweepResult.kernel`` says which ran. Both give the same per-member results, up to the last bits
of sin/cos (the lane kernel's branch-free polynomials against libm).

Memory: per member 2n (final state) + n (max |q|) + 3 numbers; trajectories, n_out * 2n per
member, only when asked for. Members whose mass matrix loses definiteness (a negative mass,
say) are not refused up front: they run and report SINGULAR_MASS_MATRIX in ``status``.
"""
from __future__ import annotations

import math
import os
import warnings
from collections.abc import Mapping
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait
from dataclasses import dataclass

import numpy as np

from ..native.build import CompiledSystem
from ..status import CHUNK_FAILED, NOT_RUN, SWEEP_STATUS_NAMES, Status  # noqa: F401 (re-exported)
from .arguments import (
    check_memory,
    check_output_size,
    check_time_resolution,
    flag,
    missing_constraints,
    output_bytes,
    positive_int,
    step_count,
    stride_within,
)
from .inputs import hold_code
from .simulate import c_pointer, check_hold, compiled_method, real_dtype, work_size
from .sweep_members import (  # noqa: F401
    cartesian_members,
    cartesian_product,
    check_member_ends,
    check_member_starts,
    column_values,
    grid_axes,
    member_arrays,
    member_input_tables,
    table_members,
)


class SweepWarning(RuntimeWarning):
    """A chunk of the sweep failed; its members have status CHUNK_FAILED, the others are kept."""


@dataclass(frozen=True)
class ChunkError:
    """A chunk that raised: members ``start`` to ``stop - 1`` and the exception's text."""

    start: int
    stop: int
    error: str


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
        max |E - E0| over every step, when the kernel has the energy output; NaN when an energy
        was not finite (E - E0 NaN).
    status : ndarray (n_members,) of int
        `Status` codes; NOT_RUN (-1) for members an interruption skipped, CHUNK_FAILED (-2) for
        members of a chunk that raised (listed in ``errors``).
    steps_done : ndarray (n_members,)
    blowup_time : ndarray (n_members,)
        Time at which the failing step started; NaN for members that completed.
    t, trajectories : ndarray (n_out,), (n_members, n_out, 2n), or None
        Every stride-th state, only when requested (NaN after a failure).
    state_names, coordinate_names : tuple of str
    completed : bool
        False when the sweep was interrupted (Ctrl-C) or a chunk failed; finished members are kept.
    kernel : str
        ``"lanes"`` (the lane-group kernel) or ``"scalar"`` (members one after another).
    errors : tuple of ChunkError
        The chunks that raised, with the exception (also emitted as a `SweepWarning`).
    y_final, y_min, y_max : ndarray (n_members, n_y) or None
        The model's measurements at the end, and their least and greatest value over every step,
        columns named by ``measurement_names``; NaN where any step's value was NaN (as
        ``energy_error`` where an energy was).
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
    errors: tuple = ()
    y_final: np.ndarray | None = None
    y_min: np.ndarray | None = None
    y_max: np.ndarray | None = None
    measurement_names: tuple = ()

    @property
    def n_members(self) -> int:
        return len(self.status)

    def on_grid(self, field) -> np.ndarray:
        """``field`` (an attribute name or an (n_members,) array) reshaped to the grid's shape."""
        if self.grid is None:
            raise ValueError("this sweep was not a Cartesian grid")
        data = getattr(self, field) if isinstance(field, str) else np.asarray(field)
        return data.reshape(tuple(len(axis) for axis in self.grid) + data.shape[1:])


def sweep(system: CompiledSystem, grid: Mapping | None = None, *, members: Mapping | None = None, x0,
          t_end: float, h: float, method: str = "rk4", params: Mapping | None = None, t0: float = 0.0,
          trajectories: bool = False, stride: int = 1, threads: int | None = None,
          chunk_size: int | None = None, progress: bool | None = None, client=None,
          track_energy: bool = True, project: bool = False, kernel: str = "auto",
          max_output_bytes: int | None = None, inputs=None, member_inputs=None, hold: str = "zoh") -> SweepResult:
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
        Members per C call / Dask task (default: about 4 chunks per thread, the cluster's worker
        threads with ``client``; at most 4096, rounded up to whole lane groups).
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
    max_output_bytes : int, optional
        Refuse (`arguments.OutputTooLargeError`) sweeps whose arrays would take more;
        default half the physical memory.
    inputs, member_inputs, hold
        Driven models: the base inputs as `simulate` takes them (no callable); a grid or table
        column named like an input is its amplitude, multiplying the base signal (constant 1
        where ``inputs`` gives none). ``member_inputs``: instead, one input spec per member.
        Members whose inputs change in time run on the scalar kernel; inputs held constant per
        member ride the lane kernel as parameters.

    Every argument is checked before any member runs; errors name the argument. A chunk that
    raises (a Dask worker lost, say) does not lose the others: its members get status
    CHUNK_FAILED, the sweep returns with ``completed=False`` and ``errors``, and warns.

    Examples
    --------
    Three stiffnesses at once: x(1) = cos(sqrt(k)), that is cos 1, cos 2 and cos 3:

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0})
    >>> from lagcodegen.pipeline import compile_model
    >>> from lagcodegen.run.sweep import sweep
    >>> system = compile_model(model, methods=("rk4",))
    >>> result = sweep(system, {"k": [1.0, 4.0, 9.0]}, x0={"x": 1.0}, t_end=1.0, h=1e-3)
    >>> [round(float(v), 6) for v in result.x_final[:, 0]]
    [0.540302, -0.416147, -0.989992]
    """
    if (grid is None) == (members is None):
        raise ValueError("give exactly one of grid= (Cartesian) or members= (explicit table)")
    layout = system.layout
    method = compiled_method(system, method)
    n_steps = step_count(t0, t_end, h)
    t0, h = float(t0), float(h)
    check_time_resolution(layout, t0, t0 + n_steps * h, h)
    trajectories, track_energy, project = (flag(v, name) for name, v in (
        ("trajectories", trajectories), ("track_energy", track_energy), ("project", project)))
    # stride spaces the kept trajectories alone (found by review: without them a stride of 1000 for 98
    # steps was refused, and one that did not divide the steps warned of samples never kept)
    if trajectories:
        stride = input_stride = stride_within(stride, n_steps)
    else:  # the kernel keeps no samples, but an input array given per stride reads it (as simulate's);
        # found by review: the kernel's stride of n_steps read a 2-row array as samples at t0 and t_end
        input_stride = positive_int(stride, "stride")
        stride = max(1, n_steps)
    threads, chunk_size = _optional_positive(threads, "threads"), _optional_positive(chunk_size, "chunk_size")
    _check_runner(progress, client, kernel)
    if project and not layout.n_constraints and f"{layout.prefix}_project" not in layout.functions:
        raise ValueError(missing_constraints(layout, ["project"]))
    track_energy = track_energy and f"{layout.prefix}_energy" in layout.functions
    if grid is not None:
        columns, axes = grid_axes(grid)
        _check_sweep_size(layout, math.prod(len(axis) for axis in axes), len(columns), n_steps, stride,
                          trajectories, max_output_bytes)
        values = cartesian_product(axes)
    else:
        (columns, values), axes = table_members(members), None
        _check_sweep_size(layout, len(values), len(columns), n_steps, stride, trajectories, max_output_bytes)
    xs, ps = member_arrays(system, columns, values, x0, params)
    check_member_starts(system, xs, ps, t0, columns, values)
    checked, member_parameters = system, ps
    ramp = hold_code(hold)
    check_hold(method, ramp)
    tables = member_input_tables(system, columns, values, inputs, member_inputs, t0, h, n_steps, input_stride, hold,
                                 max_output_bytes)
    held = tables is not None and tables[0].shape[1] == 1  # every member's inputs constant in time
    system = _kernel_system(system, method, project, kernel, tables is None or held)
    lanes = _lanes(system, method, project, kernel, tables is None or held)
    job = _Job(system, layout.methods.index(method), t0, h, n_steps, stride, track_energy, trajectories, project,
               lanes, ramp)
    dtype = real_dtype(system)
    if tables is not None and lanes:  # inputs held per member: the lane kernel reads them after the parameters
        free = ps[:, :len(layout.parameters)]
        ps = np.ascontiguousarray(np.hstack([free, tables[1][:, 0, :]]), dtype=dtype)
    elif tables is not None:  # the tables travel with the members, chunk by chunk
        xs = _DrivenStates(xs, np.ascontiguousarray(tables[0], dtype=dtype),
                           np.ascontiguousarray(tables[1], dtype=dtype))
    out = _allocate(job, len(values))
    threads = threads or os.cpu_count() or 1
    workers = threads if client is None else _cluster_threads(client, threads)
    if chunk_size is None:  # whole lane groups per chunk: only the sweep's last group has empty lanes
        chunk_size = max(1, min(4096, math.ceil(len(values) / (4 * workers))))
        chunk_size = -(-chunk_size // lanes) * lanes if lanes else chunk_size
    chunks = [(start, min(start + chunk_size, len(values))) for start in range(0, len(values), chunk_size)]
    run = _run_dask if client is not None else _run_threads
    completed, errors = run(job, xs, ps, out, chunks, threads if client is None else client, progress)
    _mark_failed(out, errors)
    if not project:
        check_member_ends(checked, out["x_final"], member_parameters, t0 + n_steps * h, out["status"], columns,
                          values)
    return _result(job, columns, values, axes, out, completed and not errors, errors)


def _cluster_threads(client, fallback: int) -> int:
    """The cluster's worker threads, for the chunking (found by review: the client's own core count cut
    1000 members into 8 tasks on a 12-worker cluster); ``fallback`` when it cannot say."""
    try:
        total = sum(client.nthreads().values())
    except Exception:  # noqa: BLE001 - any client without that answer keeps the local count
        return fallback
    return total if isinstance(total, int) and total > 0 else fallback


def _optional_positive(value, what: str) -> int | None:
    return None if value is None else positive_int(value, what)


def _check_runner(progress, client, kernel) -> None:
    """progress, client and kernel: the arguments that choose how the sweep runs."""
    if progress is not None:
        flag(progress, "progress")
    if client is not None and not callable(getattr(client, "submit", None)):
        raise TypeError(f"client must be a dask.distributed Client (with .submit), got {type(client).__name__}")
    if not isinstance(kernel, str) or kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")


def _check_sweep_size(layout, n_members: int, n_columns: int, n_steps: int, stride: int, trajectories: bool,
                      limit: int | None) -> None:
    """Refuse sweeps whose per-member arrays (inputs, results and kept trajectories) do not fit."""
    itemsize = 4 if layout.precision == "float" else 8
    # values (n_columns doubles), x0 and x_final (2n each), q_max (n), p, energy error, status, steps
    per_member = 8 * n_columns + itemsize * (2 * layout.n_state + layout.n_q + len(layout.parameters) + 2) + 4 + 8
    def size_of(every: int) -> int:  # no t per member
        kept = output_bytes(layout, n_steps, every, n_members=n_members, trajectory=trajectories)
        return kept - itemsize * n_members * (n_steps // every + 1) + n_members * per_member

    if trajectories:
        check_output_size(size_of(stride), n_steps, stride, f"the sweep of {n_members} members", limit, size_of)
    check_memory(n_members * per_member, f"the sweep of {n_members} members would need",
                 "sweep fewer members (a coarser grid)", limit)


def _kernel_system(system: CompiledSystem, method: str, project: bool, kernel: str,
                   held: bool = True) -> CompiledSystem:
    """``system``, or its lane variant (compiled on the first sweep that can use it)."""
    if kernel != "scalar" and system.lane_build is not None and _lanes(system, method, project, "auto", held) == 0:
        lane_system = system.lane_variant()
        if _lanes(lane_system, method, project, "auto", held):
            return lane_system
    return system


KERNELS = ("auto", "lanes", "scalar")


def _lanes(system: CompiledSystem, method: str, project: bool, kernel: str, held: bool = True) -> int:
    """Lanes per group of the lane kernel for this sweep, or 0 for the scalar kernel (``held``:
    the members' inputs, if any, are constant in time)."""
    from ..integrators.schemes import get_scheme

    if kernel not in KERNELS:
        raise ValueError(f"kernel must be one of {KERNELS}, got {kernel!r}")
    layout = system.layout
    reason = None
    if not get_scheme(method).lane_capable:
        reason = f"method {method!r} is not an explicit Runge-Kutta method"
    elif project:
        reason = "projection onto the constraints runs on the scalar kernel only"
    elif not held:
        reason = "inputs that vary in time run on the scalar kernel only"
    elif layout.measurements:
        reason = "the measurements' summaries are kept by the scalar kernel only"
    elif f"{layout.prefix}_sweep_lanes" not in layout.functions:
        reason = (f"model {layout.model!r} was built without the lane kernel (compile_model(lanes=0), a "
                  "constrained model, or a tree in the recursive formulation)")
    if reason is None and kernel != "scalar":
        return int(getattr(system.lib, f"{layout.prefix.upper()}_LANES"))
    if kernel == "lanes":
        raise ValueError(f"kernel='lanes' does not apply: {reason}")
    return 0


@dataclass(frozen=True)
class _DrivenStates:
    """Members' initial states with their input tables (times (k,) and values (k, n_r) each),
    sliced together into chunks."""

    x: np.ndarray
    times: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return len(self.x)

    def __getitem__(self, rows) -> _DrivenStates:
        return _DrivenStates(self.x[rows], self.times[rows], self.values[rows])


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
    hold: int = 0  # driven models: 0 zero-order hold, 1 first-order hold

    @property
    def n_out(self) -> int:
        return self.n_steps // self.stride + 1


def _allocate(job: _Job, n_members: int) -> dict:
    layout, dtype = job.system.layout, real_dtype(job.system)
    size = layout.n_state
    return {
        "x_final": np.full((n_members, size), np.nan, dtype),
        "q_max": np.full((n_members, layout.n_q), np.nan, dtype),
        "energy_error": np.full(n_members, np.nan, dtype),
        "status": np.full(n_members, NOT_RUN, np.intc),
        "steps_done": np.zeros(n_members, np.int_),
        "traj": np.full((n_members, job.n_out, size), np.nan, dtype) if job.trajectories else None,
        **{key: np.full((n_members, len(layout.measurements)), np.nan, dtype) if layout.measurements else None
           for key in ("y_final", "y_min", "y_max")},
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
        code = lanes_c(job.method_id, len(xs), c_pointer(system, xs), c_pointer(system, ps), job.t0, job.h,
                       job.n_steps, job.stride, int(job.track_energy), c_pointer(system, out["x_final"]),
                       c_pointer(system, out["q_max"]), c_pointer(system, out["energy_error"]),
                       ffi.from_buffer("int[]", out["status"]), ffi.from_buffer("long[]", out["steps_done"]),
                       ffi.NULL if traj is None else c_pointer(system, traj))
        if code != Status.OK:
            raise RuntimeError(f"{layout.prefix}_sweep_lanes refused method number {job.method_id} ({code})")
        return
    work = np.empty(work_size(system), dtype=real_dtype(system))
    sweep_c = getattr(system.lib, f"{layout.prefix}_sweep")
    driven, summaries = (), ()
    if layout.inputs:
        xs, times, table_values = xs.x, xs.times, xs.values
        driven = (c_pointer(system, times), c_pointer(system, table_values), times.shape[1], job.hold)
    if layout.measurements:
        summaries = tuple(c_pointer(system, out[key]) for key in ("y_final", "y_min", "y_max"))
    sweep_c(job.method_id, len(xs), c_pointer(system, xs), c_pointer(system, ps), *driven, job.t0, job.h,
            job.n_steps, job.stride, int(job.project), int(job.track_energy), *summaries,
            c_pointer(system, out["x_final"]),
            c_pointer(system, out["q_max"]),
            c_pointer(system, out["energy_error"]), ffi.from_buffer("int[]", out["status"]),
            ffi.from_buffer("long[]", out["steps_done"]),
            ffi.NULL if traj is None else c_pointer(system, traj), c_pointer(system, work))


def _progress_bar(total: int, progress: bool | None):
    if progress is False:
        return None
    from tqdm.auto import tqdm
    return tqdm(total=total, unit="member", delay=0.0 if progress else 1.0, leave=False)


def _run_threads(job, xs, ps, out, chunks, threads, progress) -> tuple[bool, list]:
    """Chunks on a local thread pool; returns (not interrupted, [ChunkError of chunks that raised])."""
    bar = _progress_bar(len(xs), progress)

    def task(bounds):
        start, stop = bounds
        view = {k: (None if v is None else v[start:stop]) for k, v in out.items()}
        _call(job, xs[start:stop], ps[start:stop], view)
        return stop - start

    pool = ThreadPoolExecutor(max_workers=threads)
    pending = {pool.submit(task, bounds): bounds for bounds in chunks}
    errors = []
    try:
        while pending:
            done, _ = wait(pending, timeout=0.2, return_when=FIRST_COMPLETED)
            for future in done:
                bounds = pending.pop(future)
                if _collect(future, bounds, errors):
                    _advance(bar, bounds)
        return True, errors
    except KeyboardInterrupt:
        for future in pending:
            future.cancel()
        return False, errors
    finally:
        pool.shutdown(wait=True, cancel_futures=True)
        if bar is not None:
            bar.close()


def _run_dask(job, xs, ps, out, chunks, client, progress) -> tuple[bool, list]:
    """Chunks as tasks on a Dask cluster; returns (not interrupted, [ChunkError ...])."""
    from dask.distributed import as_completed

    _check_workers(client)
    bar = _progress_bar(len(xs), progress)
    futures = {client.submit(run_chunk, job, xs[a:b], ps[a:b], pure=False): (a, b) for a, b in chunks}
    errors = []
    try:
        for future in as_completed(futures):
            a, b = futures[future]
            part = _collect(future, (a, b), errors)
            if part is None:
                continue
            for key, array in out.items():
                if array is not None:
                    array[a:b] = part[key]
            _advance(bar, (a, b))
        return True, errors
    except KeyboardInterrupt:
        client.cancel(list(futures))
        return False, errors
    finally:
        if bar is not None:
            bar.close()


#: seconds a sweep waits for the first worker of a Dask cluster that has none
WORKER_WAIT = 30.0


def _check_workers(client) -> None:
    """Every worker of ``client`` imports this lagcodegen. A worker that cannot unpickle a chunk
    (lagcodegen missing from its environment) dies on it, its nanny restarts it, and the sweep
    would wait for the chunk for ever; a worker with another version could run other kernels.
    Checked with a stdlib function (pkgutil.resolve_name), which every worker can unpickle."""
    from pkgutil import resolve_name

    from .. import __version__

    try:  # found by review: with no worker, client.run answered {} and the sweep waited for ever
        client.wait_for_workers(1, timeout=WORKER_WAIT)
    except TimeoutError:
        raise RuntimeError(f"the dask cluster of {client!r} has no worker (none joined within {WORKER_WAIT:g} s): "
                           "start workers, or sweep without client=; nothing was run") from None
    for target, what in (("lagcodegen.run.sweep:__name__", "cannot import lagcodegen.run.sweep"),
                         ("lagcodegen:__version__", "has another lagcodegen")):
        answers = client.run(resolve_name, target, on_error="return")
        for worker, answer in sorted(answers.items()):
            if isinstance(answer, BaseException):
                raise RuntimeError(f"dask worker {worker} {what} ({_describe(answer)}): install lagcodegen "
                                   f"{__version__} in the workers' environment; nothing was run")
            if target.endswith("__version__") and answer != __version__:
                raise RuntimeError(f"dask worker {worker} {what} ({answer}) than this process ({__version__}): "
                                   f"install the same version on every worker; nothing was run")


def _collect(future, bounds, errors: list):
    """The chunk's result, or None after recording its exception in ``errors`` (any exception:
    a chunk that raises must not lose the chunks that finished)."""
    try:
        return future.result()
    except Exception as error:  # noqa: BLE001 - KilledWorker, MemoryError, a bug in a chunk: all recorded
        errors.append(ChunkError(bounds[0], bounds[1], _describe(error)))
        return None


def _describe(error: BaseException) -> str:
    """``"Type: message"``; an exception whose str() fails itself still gets its type named."""
    try:
        text = str(error)
    except Exception:  # noqa: BLE001 - e.g. a KilledWorker built without its WorkerState
        text = "(no message)"
    return f"{type(error).__name__}: {text}"


def _advance(bar, bounds) -> None:
    if bar is not None:
        bar.update(bounds[1] - bounds[0])


def _mark_failed(out: dict, errors: list) -> None:
    """Members of failed chunks: status CHUNK_FAILED, results NaN (a half-written chunk is not
    trusted), one warning per chunk naming the members and the exception."""
    for error in errors:
        rows = slice(error.start, error.stop)
        for key, array in out.items():
            if array is not None and key not in ("status", "steps_done"):
                array[rows] = np.nan
        out["status"][rows], out["steps_done"][rows] = CHUNK_FAILED, 0
        warnings.warn(f"sweep chunk of members {error.start} to {error.stop - 1} failed ({error.error}); "
                      f"their status is CHUNK_FAILED, the other members are kept", SweepWarning, stacklevel=3)


def _result(job: _Job, columns, values, axes, out, completed: bool, errors=()) -> SweepResult:
    layout = job.system.layout
    failed = out["status"] > Status.OK  # the C kernel's failures; not NOT_RUN, CHUNK_FAILED
    blowup = np.where(failed, job.t0 + out["steps_done"] * job.h, np.nan)
    t = job.t0 + job.h * job.stride * np.arange(job.n_out) if job.trajectories else None
    return SweepResult(
        columns=columns, values=values, grid=axes, x_final=out["x_final"], q_max=out["q_max"],
        energy_error=out["energy_error"] if job.track_energy else None, status=out["status"],
        steps_done=out["steps_done"], blowup_time=blowup, t=t, trajectories=out["traj"],
        state_names=layout.coordinates + layout.speeds, coordinate_names=layout.coordinates,
        completed=completed, kernel="lanes" if job.lanes else "scalar", errors=tuple(errors),
        y_final=out["y_final"], y_min=out["y_min"], y_max=out["y_max"], measurement_names=layout.measurements)
