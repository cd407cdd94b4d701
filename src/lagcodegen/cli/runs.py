"""Stage: cli -> files, text. The simulate and sweep subcommands (their options in `arguments`)."""
from __future__ import annotations

import argparse
import math
import os
import sys
import time
import warnings
from pathlib import Path

from ..run.inputs import InputError
from .arguments import (
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    SIMULATE_EPILOG,
    SWEEP_EPILOG,
    RunFailed,
    UsageError,
    add_run_arguments,
    load_model,
    parse_assignments,
    parse_grid,
    parse_inputs,
    positive_int,
    read_table,
)

#: a trajectory may take at most this share of the machine's physical memory
MEMORY_SHARE = 0.5


def prepare_run(args, command: str, swept=(), model=None) -> tuple:
    """Derive the model (``model``, else loaded from ``args.model``) and check every name given
    on the command line before compiling.

    Returns (eom, fixed, params, x0) with plain ``{name: float}`` dicts.
    """
    if model is None:
        eom = derive_equations_of(args.model)
    else:
        from ..symbolic.derive import derive_equations

        eom = derive_equations(model)
    fixed = parse_assignments(args.fixed, "--fixed")
    params = parse_assignments(args.param, "--param")
    x0 = parse_assignments(args.x0, "--x0")
    parameters = [p.name for p in eom.parameters]
    states = [q.name for q in eom.q] + [u.name for u in eom.u]
    free = [name for name in parameters if name not in fixed]
    where = (f"free parameters of {eom.name}: {', '.join(free) or 'none'}; "
             f"state variables: {', '.join(states)}")
    inputs = [r.name for r in eom.inputs]
    for option, names, allowed in (("--fixed", fixed, parameters), ("--param", params, parameters),
                                   ("--x0", x0, states), ("--grid/--table", swept, free + states + inputs)):
        for name in names:
            if name in fixed and option != "--fixed":
                raise UsageError(f"{name!r} in {option} is fixed by --fixed; {where}")
            if name not in allowed:
                raise UsageError(f"unknown name {name!r} in {option}; {where}")
    missing = [q.name for q in eom.q if q.name not in x0 and q.name not in swept]
    if missing and eom.m and not swept:
        x0 = consistent_x0(eom, x0, {**fixed, **params}, command)
    elif eom.m and not eom.n_dependent and not swept and not missing:
        check_consistent_x0(eom, x0, {**fixed, **params})
    elif missing:
        raise UsageError(f"--x0 lacks coordinate(s) {', '.join(missing)} "
                         f"(every coordinate needs a value; speeds default to 0)")
    return eom, fixed, params, x0


def check_steps(args, n_state: int, members: int = 1, keep: bool = True) -> int:
    """The number of steps, after checking that ``--t-end`` is a whole number of ``--h`` and that
    the kept samples (``members`` trajectories of ``n_state`` values plus t, when ``keep``) fit in
    `MEMORY_SHARE` of physical memory; the error says which ``--stride`` would fit."""
    from ..run.simulate import step_count

    try:
        steps = step_count(0.0, args.t_end, args.h)
    except ValueError as error:
        raise UsageError(f"--t-end {args.t_end:g} / --h {args.h:g}: {error}") from None
    if keep and getattr(args, "stride", 1) > steps:  # before the compile (found by review: refused after it)
        raise UsageError(f"--stride {args.stride} exceeds the {steps} steps of --t-end {args.t_end:g} / --h "
                         f"{args.h:g}: only the initial state would be kept; use --stride <= {steps}")
    budget = physical_memory() * MEMORY_SHARE
    row = members * (n_state + 1) * 8  # float64 state and time of every member per sample
    n_out = steps // args.stride + 1
    if keep and budget and n_out * row > budget:
        stride = math.ceil(steps / max(budget // row - 1, 1))
        raise UsageError(f"--t-end {args.t_end:g} / --h {args.h:g} is {steps} steps; with --stride {args.stride} "
                         f"the {n_out} kept samples need {format_bytes(n_out * row)}, more than half this "
                         f"machine's memory ({format_bytes(budget / MEMORY_SHARE)}): raise --stride "
                         f"to at least {stride}")
    return steps


def run_inputs(args) -> dict | None:
    """``--input`` values (`parse_inputs`), every table checked to cover the run 0 .. --t-end before
    anything is compiled (found by review: a short table was refused only after the compile)."""
    from ..run.inputs import InputError, check_cover

    inputs = parse_inputs(args.input)
    for name, value in (inputs or {}).items():
        if isinstance(value, tuple):
            try:
                check_cover(value[0], 0.0, args.t_end, args.h, repr(name))
            except InputError as error:
                raise UsageError(f"--input {name}: {error}") from None
    return inputs


def physical_memory() -> float:
    """Bytes of physical memory, or 0 when the platform does not say (then nothing is checked)."""
    try:
        return float(os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES"))
    except (AttributeError, ValueError, OSError):  # no sysconf (Windows) or no such name
        return 0.0


def format_bytes(size: float) -> str:
    for unit in ("B", "KiB", "MiB", "GiB", "TiB"):
        if size < 1024 or unit == "TiB":
            return f"{size:.3g} {unit}"
        size /= 1024
    return f"{size:.3g} TiB"


def check_output_file(path: str | None, option: str, kind: str = "npz") -> None:
    """Fail before any work when ``path`` (a file to write) is empty, a directory, in a missing
    directory, cannot be opened for writing (tried: os.access says yes to root everywhere), or
    does not end as its ``kind`` must: ``"npz"`` (numpy appends .npz to any other name) or
    ``"figure"`` (a format matplotlib writes)."""
    if path is None:
        return
    if not path.strip():
        raise UsageError(f"{option} is given an empty file name")
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{option} {path}: is a directory; give a file name")
    if not target.parent.is_dir():
        raise UsageError(f"{option} {path}: {target.parent} is not an existing directory")
    suffix = target.suffix.lower().lstrip(".")
    if kind == "npz" and target.suffix != ".npz":  # numpy's test is case-sensitive (found by review: run.NPZ)
        raise UsageError(f"{option} {path}: give a file name ending in .npz (numpy would write {path}.npz)")
    if kind == "figure":
        import shutil

        import matplotlib
        from matplotlib.figure import Figure

        formats = Figure().canvas.get_supported_filetypes()
        if suffix not in formats:
            raise UsageError(f"{option} {path}: the figure format {suffix or '(none)'!r} is not one matplotlib "
                             f"writes ({', '.join(sorted(formats))})")
        tex = matplotlib.rcParams["pgf.texsystem"]
        if suffix == "pgf" and shutil.which(tex) is None:  # found by review: a traceback after the whole run
            raise UsageError(f"{option} {path}: matplotlib writes .pgf with {tex}, which is not installed")
    from ..run.arguments import unwritable

    reason = unwritable(target)
    if reason is not None:
        raise UsageError(f"{option} {path}: cannot write there ({reason})")


def derive_equations_of(spec: str):
    from ..symbolic.derive import derive_equations

    return derive_equations(load_model(spec))


def consistent_x0(eom, x0: dict, values: dict, command: str, option: str = "--x0") -> dict:
    """Complete a partial --x0 (or ``option``) of a constrained model: the missing coordinates and
    speeds solve the constraints (consistent.consistent_state), the given ones are held."""
    from ..statics.consistent import consistent_state

    q_given = {q.name: x0[q.name] for q in eom.q if q.name in x0}
    u_given = {u.name: x0[u.name] for u in eom.u if u.name in x0}
    try:
        q, u = consistent_state(eom, q_given, u_given, values=values or None)
    except ValueError as error:
        raise UsageError(f"{option} is inconsistent with the constraints: {error}") from None
    state = dict(zip([s.name for s in eom.q], map(float, q))) | dict(zip([s.name for s in eom.u], map(float, u)))
    print("consistent initial state: " + ", ".join(f"{k} = {v:.9g}" for k, v in state.items()))
    return state


def interruptible(call):
    """``call()`` (one long C call) in a daemon thread, the main thread waiting in short joins, so
    that Ctrl-C stops the command at once (found by review: simulate stopped only when its whole
    C loop had run, 20 s after the signal; one of 3e15 steps could not be stopped). The abandoned
    thread ends with the process."""
    import threading

    outcome: dict = {}

    def target():
        try:
            outcome["value"] = call()
        except BaseException as error:  # noqa: BLE001 - re-raised in the main thread
            outcome["error"] = error

    thread = threading.Thread(target=target, daemon=True)
    thread.start()
    while thread.is_alive():
        thread.join(0.05)
    if "error" in outcome:
        raise outcome["error"]
    return outcome["value"]


def check_consistent_x0(eom, x0: dict, values: dict) -> None:
    """A complete --x0 of a model with constraints with multipliers must satisfy them: a run holds
    the offset it starts with (found by review: a rod of 1 started at 0.6 ran as a rod of 0.6, exit 0,
    the warning blaming drift). `linearize` refuses the same start."""
    import numpy as np

    from ..run.drift import DRIFT_TOLERANCE
    from ..statics.consistent import constraint_residuals, constraint_scales

    q = {s.name: x0[s.name] for s in eom.q}
    u = {s.name: x0.get(s.name, 0.0) for s in eom.u}
    residual = constraint_residuals(eom, q, u, values=values or None)
    # relative to each row's terms, no absolute floor (found by review: l = 1e-3 started at y = -l/2 ran)
    excess = np.abs(residual) - DRIFT_TOLERANCE["double"] * constraint_scales(eom, q, u, values=values or None)
    m = eom.m
    worst = int(np.argmax(excess))
    if excess[worst] > 0:
        level = "positions, phi" if worst < m else "velocities, A u + dphi/dt"
        raise UsageError(f"--x0 is off constraint row {worst % m} of {eom.name} on the {level} = "
                         f"{residual[worst]:.3g}; give only some coordinates (the others are solved) or a "
                         "consistent state")


def _has_energy(eom) -> bool:
    """An energy expression, or a recursive tree's own (found by review: the command line said a
    tree "has no energy expression", where the API records it)."""
    return eom.energy is not None or (eom.tree is not None and eom.tree.energy is not None)


def compile_for(eom, method: str, fixed: dict, *, energy: bool, points: bool):
    """The model compiled with one integrator and only the outputs the run records (the outputs
    the method needs, such as the Jacobian, are added by `compile_model`)."""
    from ..codegen.outputs import applicable_outputs
    from ..native.build import BuildError
    from ..pipeline import compile_model

    outputs = ["rhs"] + ["energy"] * (energy and _has_energy(eom)) + ["points"] * (points and bool(eom.points))
    outputs += ["measurements"] * bool(eom.measurements)
    # residuals, multipliers, --project: for constraints with multipliers only (found by review: a
    # model with eliminated dependent speeds was refused, "output 'constraints' needs multipliers")
    outputs = applicable_outputs(eom, outputs)
    try:
        return compile_model(eom, outputs=outputs, fixed=fixed or None, methods=(method,))
    except BuildError as error:
        raise RunFailed(f"building {eom.name} with {method} failed: {error}") from None


def plot_coordinates(trajectory, title: str, n_q: int):
    """Figure of the ``n_q`` coordinates against t (a dotted line where a failed run stopped)."""
    from matplotlib.figure import Figure  # Agg canvas via savefig; no pyplot

    fig = Figure(figsize=(8.0, 4.5), dpi=100, layout="constrained")
    ax = fig.add_subplot()
    # n_q, not half the state: found by review, a model with fewer speeds than coordinates lost some
    for j, name in enumerate(trajectory.names[:n_q]):
        ax.plot(trajectory.t, trajectory.x[:, j], linewidth=0.9, label=name)
    if not trajectory.ok:
        ax.axvline(trajectory.failed_time, color="red", linestyle=":", label=f"stopped: {trajectory.status.name}")
    ax.set_xlabel("t")
    ax.set_ylabel("coordinates")
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(loc="best", fontsize="small")
    return fig


def cmd_simulate(args) -> int:
    import numpy as np

    from ..run.simulate import parameter_vector, simulate

    check_output_file(args.out, "--out")
    check_output_file(args.plot, "--plot", "figure")
    eom, fixed, params, x0 = prepare_run(args, "simulate")
    steps = check_steps(args, eom.n_state + bool(args.energy))
    if args.energy and not _has_energy(eom):
        raise UsageError(f"--energy: model {eom.name!r} has no energy expression")
    inputs = run_inputs(args)  # found by review: a table that cannot be read was found after the compile
    start = time.perf_counter()
    system = compile_for(eom, args.method, fixed, energy=args.energy, points=True)
    compile_time, start = time.perf_counter() - start, time.perf_counter()
    constrained = bool(system.layout.n_constraints)
    try:
        run = interruptible(lambda: simulate(
            system, x0, args.t_end, args.h, args.method, params=params, stride=args.stride, energy=args.energy,
            points=bool(system.layout.points), project=args.project, residuals=constrained,
            multipliers=constrained, inputs=inputs, hold=args.hold))
    except InputError as error:
        raise UsageError(f"--input: {error}") from None
    elapsed = time.perf_counter() - start
    print(f"{eom.name}, {run.method}, h = {args.h:g}, {steps} steps to t = {args.t_end:g}: {run.message}")
    print(f"state at t = {run.t[-1]:.9g} (last kept sample): "
          + ", ".join(f"{n} = {v:.9g}" for n, v in zip(run.names, run.x[-1])))
    if run.measurements is not None:
        print("measurements at the last kept sample: "
              + ", ".join(f"{n} = {v:.9g}" for n, v in zip(run.measurement_names, run.measurements[-1])))
    if run.energy is not None:
        drift = float(np.max(np.abs(run.energy - run.energy[0])))
        relative = drift / abs(float(run.energy[0])) if run.energy[0] else float("inf")
        print(f"energy: E0 = {float(run.energy[0]):.9g}, max |E - E0| = {drift:.3e} (relative {relative:.3e})")
    else:
        print("energy: not recorded (add --energy)")
    if run.residuals is not None:
        m = run.residuals.shape[1] // 2
        print(f"constraints: max |phi| = {np.nanmax(np.abs(run.residuals[:, :m])):.3e}, "
              f"max |A u + dphi/dt| = {np.nanmax(np.abs(run.residuals[:, m:])):.3e}"
              f"{' (projected every step)' if args.project else ' (add --project to hold them)'}")
    # the whole call, not a rate of the C loop (found by review: its stability pre-check, sympy root
    # finding on the first call, was most of it; `lagcodegen demo` times the loop alone)
    print(f"wall time: compile {compile_time:.2f} s, simulate {elapsed * 1e3:.2f} ms (the whole call: stability "
          "pre-check, stepping loop in C, checks after it)")
    if args.out:
        layout = system.layout
        extra = {} if run.energy is None else {"energy": run.energy}
        if run.points is not None:
            extra |= {"points": run.points, "point_names": np.array(run.point_names)}
        if run.inputs is not None:
            extra |= {"inputs": run.inputs, "input_names": np.array(run.input_names), "hold": args.hold}
        if run.measurements is not None:
            extra |= {"measurements": run.measurements, "measurement_names": np.array(run.measurement_names)}
        for name in ("residuals", "multipliers"):
            if getattr(run, name) is not None:
                extra[name] = getattr(run, name)
        np.savez(args.out, t=run.t, x=run.x, names=np.array(run.names), status=int(run.status),
                 status_name=run.status.name, message=run.message, model=eom.name, method=run.method,
                 h=args.h, t_end=args.t_end, stride=args.stride, x0=run.x[0],
                 parameters=np.array(layout.parameters), p=parameter_vector(system, params),
                 fixed_names=np.array([n for n, _ in layout.fixed]),
                 fixed_values=np.array([float(v) for _, v in layout.fixed]), **extra)
        print(f"wrote {args.out}")
    if args.plot:
        title = f"{eom.name}: {run.method}, h = {args.h:g} ({run.message})"
        plot_coordinates(run, title, eom.n_q).savefig(args.plot, dpi=110)
        print(f"wrote {args.plot}")
    return EXIT_OK if run.ok else EXIT_FAILED


def check_sweep_outputs(args, members: dict, eom) -> str:
    """Fail before compiling when --field or --heatmap cannot work; returns the field name."""
    from ..analysis.heatmaps import product_axes, resolve_field

    coordinates = [q.name for q in eom.q]
    field = args.field if args.field is not None else f"q_max:{coordinates[0]}"
    try:
        resolve_field(field, coordinates, coordinates + [u.name for u in eom.u],
                      [name for name, _ in eom.measurements])
    except ValueError as error:
        raise UsageError(f"--field: {error}") from None
    if field == "energy_error" and not _has_energy(eom):
        raise UsageError(f"--field energy_error: model {eom.name!r} has no energy expression")
    if args.heatmap:
        if len(members) != 2:
            raise UsageError(f"--heatmap needs exactly two swept names, got {', '.join(members)}")
        import numpy as np
        if args.table:
            try:
                product_axes(np.column_stack(list(members.values())), list(members))
            except ValueError as error:
                raise UsageError(f"--heatmap: {error}") from None
        else:  # found by review: a repeated grid value was refused only after the whole sweep ran
            for name, axis in members.items():
                values, counts = np.unique(np.asarray(axis, dtype=float), return_counts=True)
                if (counts > 1).any():
                    raise UsageError(f"--heatmap: grid axis {name!r} repeats {float(values[counts > 1][0])!r}: a "
                                     "heatmap cell per value; drop the repeat")
    return field


def connect(address: str):
    """A ``dask.distributed.Client`` connected to the scheduler at ``address``."""
    try:
        from dask.distributed import Client
    except ImportError:
        raise UsageError("--scheduler needs dask.distributed "
                         "(pip install 'lagcodegen[dask]')") from None
    try:
        return Client(address, timeout="10s")
    except (OSError, TimeoutError) as error:
        raise UsageError(f"cannot connect to the Dask scheduler at {address}: {error}") from None


def save_sweep(path, result, system, eom, args, params, x0) -> None:
    """Every SweepResult array, the column and state names, and the run's settings, as .npz."""
    import numpy as np

    from ..run.simulate import parameter_vector

    arrays = {name: getattr(result, name) for name in ("values", "x_final", "q_max", "status", "steps_done",
                                                      "blowup_time", "energy_error", "t", "trajectories",
                                                      "y_final", "y_min", "y_max")}
    arrays = {name: value for name, value in arrays.items() if value is not None}
    if result.y_final is not None:  # found by review: the measurements' summaries were computed, then dropped
        arrays["measurement_names"] = np.array(result.measurement_names)
    if result.grid is not None:
        arrays |= {f"grid_{name}": axis for name, axis in zip(result.columns, result.grid)}
    layout = system.layout
    # the base state: a swept coordinate's placeholder (its first value) is not part of it (found by review)
    x0 = {name: value for name, value in x0.items() if name not in result.columns}
    np.savez(path, **arrays, columns=np.array(result.columns), state_names=np.array(result.state_names),
             coordinate_names=np.array(result.coordinate_names), completed=result.completed,
             is_grid=result.grid is not None, model=eom.name, method=args.method, h=args.h,
             t_end=args.t_end, stride=args.stride, parameters=np.array(layout.parameters),
             p=parameter_vector(system, params), x0_names=np.array(list(x0)), x0_values=np.array(list(x0.values())),
             fixed_names=np.array([n for n, _ in layout.fixed]),
             fixed_values=np.array([float(v) for _, v in layout.fixed]))


def print_sweep_summary(result, field: str, elapsed: float, compile_time: float, steps: int, method: str) -> None:
    import numpy as np

    from ..analysis.heatmaps import field_values
    from ..run.simulate import Status
    from ..run.sweep import SWEEP_STATUS_NAMES

    axes = ", ".join(f"{name} ({len(axis)} values {axis.min():g}..{axis.max():g})"
                     for name, axis in zip(result.columns, result.grid or ())) or ", ".join(result.columns)
    print(f"swept {axes}: {result.n_members} members x {steps} {method} steps in {elapsed:.2f} s "
          f"({result.n_members * steps / max(elapsed, 1e-12) / 1e6:.2f} M member-steps/s; "
          f"compile {compile_time:.2f} s)")
    codes, counts = np.unique(result.status, return_counts=True)
    names = {**SWEEP_STATUS_NAMES, **{int(s): s.name.lower() for s in Status}}
    print("status: " + ", ".join(f"{names.get(int(c), c)} {n}" for c, n in zip(codes, counts)))
    if np.isfinite(result.blowup_time).any():
        first = int(np.nanargmin(result.blowup_time))
        where = ", ".join(f"{c} = {v:g}" for c, v in zip(result.columns, result.values[first]))
        print(f"earliest failure at t = {result.blowup_time[first]:.6g} (member {first}: {where})")
    ok = result.status == Status.OK
    values, label = field_values(result, field)
    finite = values[np.isfinite(values) & (ok | (field in ("blowup_time", "steps_done")))]
    if finite.size and field != "status":
        print(f"{field} ({label}): min {finite.min():.6g}, median {np.median(finite):.6g}, max {finite.max():.6g}")
    if result.energy_error is not None and ok.any():
        print(f"energy error max |E - E0| of completed members: median {np.median(result.energy_error[ok]):.3e}, "
              f"max {np.max(result.energy_error[ok]):.3e}")


def cmd_sweep(args) -> int:
    from ..analysis.heatmaps import plot_heatmap
    from ..run.drift import StartOffConstraintsWarning
    from ..run.sweep import CHUNK_FAILED, NOT_RUN, sweep

    if bool(args.grid) == bool(args.table):
        raise UsageError("give the members either with --grid (repeatable) or with --table")
    check_output_file(args.out, "--out")
    check_output_file(args.heatmap, "--heatmap", "figure")
    if args.scheduler is not None and not args.scheduler.strip():  # Client("") would start a local cluster
        raise UsageError("--scheduler is given an empty address; give one like tcp://host:8786")
    members = parse_grid(args.grid) if args.grid else read_table(args.table)
    eom, fixed, params, x0 = prepare_run(args, "sweep", swept=members)
    for option, given in (("--param", params), ("--x0", x0)):
        both = sorted(set(given) & set(members))
        if both:  # found by review: the swept values won, and the .npz recorded the dropped --param value
            raise UsageError(f"{option} {both[0]!r} is swept by --grid/--table too; drop one of them")
    n_members = math.prod(len(v) for v in members.values()) if args.grid else len(next(iter(members.values())))
    steps = check_steps(args, eom.n_state, n_members, keep=args.trajectories)
    for name in members:  # a swept coordinate needs no base value in --x0
        if name in [q.name for q in eom.q]:
            x0.setdefault(name, float(members[name][0]))
    field = check_sweep_outputs(args, members, eom)
    inputs = run_inputs(args)
    both = sorted(set(inputs or ()) & set(members))
    if both:  # found by review: the swept values won and --input was silently ignored
        raise UsageError(f"--input {both[0]!r} is swept by --grid/--table too; drop one of them")
    start = time.perf_counter()
    system = compile_for(eom, args.method, fixed, energy=True, points=False)
    compile_time = time.perf_counter() - start
    client = connect(args.scheduler) if args.scheduler is not None else None
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():  # as simulate refuses such a start (found by review: exit 0)
            warnings.simplefilter("error", StartOffConstraintsWarning)
            result = sweep(system, **({"grid": members} if args.grid else {"members": members}), x0=x0,
                           t_end=args.t_end, h=args.h, method=args.method, params=params,
                           trajectories=args.trajectories, stride=args.stride, threads=args.threads, client=client,
                           project=args.project, inputs=inputs, hold=args.hold)
    except InputError as error:
        raise UsageError(f"--input: {error}") from None
    except StartOffConstraintsWarning as error:
        raise UsageError(f"{error}; give --x0 on the constraints for every swept value") from None
    finally:
        if client is not None:
            client.close()
    print_sweep_summary(result, field, time.perf_counter() - start, compile_time, steps, args.method)
    for error in result.errors:
        print(f"chunk failed: members {error.start}..{error.stop - 1} ({error.stop - error.start} marked "
              f"chunk_failed): {error.error}", file=sys.stderr)
    not_run = int((result.status == NOT_RUN).sum())
    if not_run:
        print(f"interrupted: {not_run} of {result.n_members} members not run; the finished ones are kept")
    if result.errors:
        failed = int((result.status == CHUNK_FAILED).sum())
        print(f"{failed} of {result.n_members} members lost in {len(result.errors)} failed chunk(s); "
              "the other members are kept", file=sys.stderr)
    if args.out:
        save_sweep(args.out, result, system, eom, args, params, x0)
        print(f"wrote {args.out}")
    if args.heatmap:
        title = f"{eom.name}: {field} ({args.method}, h = {args.h:g}, t_end = {args.t_end:g})"
        plot_heatmap(result, field, title=title).savefig(args.heatmap, dpi=110)
        print(f"wrote {args.heatmap}")
    if result.errors:
        return EXIT_FAILED
    return EXIT_OK if result.completed else EXIT_INTERRUPTED


def add_simulate_parser(commands) -> None:
    simulate = commands.add_parser(
        "simulate", help="compile and run one simulation, write .npz and a plot",
        description="Compile MODEL with one integrator and run it from x0 to t = T in fixed steps;\n"
                    "print the status, final state, energy drift and wall time.",
        epilog=SIMULATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(simulate)
    simulate.add_argument("--energy", action="store_true", help="record T + V at each kept sample")
    simulate.add_argument("--out", metavar="FILE.npz", help="write the trajectory here")
    simulate.add_argument("--plot", metavar="FILE.png", help="plot the coordinates against t here")
    simulate.set_defaults(run=cmd_simulate)


def add_sweep_parser(commands) -> None:
    sweep = commands.add_parser(
        "sweep", help="run one compiled model over a grid or table of parameters and initial states",
        description="Compile MODEL once and run it for every member of a grid (--grid) or table (--table)\n"
                    "of free parameters and initial-state values; print a summary, write .npz and a heatmap.",
        epilog=SWEEP_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(sweep)
    sweep.add_argument("--grid", action="append", metavar="NAME=SPEC",
                       help="one grid axis: name=start:stop:count[:log] or name=v1,v2,... (repeatable)")
    sweep.add_argument("--table", metavar="FILE.csv", help="explicit members: header of names, one row each")
    sweep.add_argument("--threads", type=positive_int, metavar="N", help="local worker threads (default: all cores)")
    sweep.add_argument("--scheduler", metavar="ADDRESS",
                       help="run on a Dask cluster, e.g. tcp://host:8786 (dask.distributed.Client)")
    sweep.add_argument("--trajectories", action="store_true",
                       help="keep every --stride-th state of every member (memory n_members x n_out x 2n)")
    sweep.add_argument("--field", metavar="FIELD",
                       help="value summarized and drawn in the heatmap (default: q_max:<first coordinate>)")
    sweep.add_argument("--out", metavar="FILE.npz", help="write all results here")
    sweep.add_argument("--heatmap", metavar="FILE.png", help="draw --field over a 2-D grid here")
    sweep.set_defaults(run=cmd_sweep)


def add_run_commands(commands) -> None:
    """Register the simulate and sweep subcommands on ``commands`` (argparse subparsers)."""
    add_simulate_parser(commands)
    add_sweep_parser(commands)
