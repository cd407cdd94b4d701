"""Stage: CompiledSystem -> Trajectory (the whole fixed-step loop runs in C).

Also `solve_reference`: scipy's ``solve_ivp`` (DOP853, Radau, ...) on the same compiled
right-hand side, for measuring the error of the fixed-step methods.
"""
from __future__ import annotations

import math
import numbers
import warnings
from collections.abc import Mapping
from dataclasses import dataclass, replace

import numpy as np

from ..codegen.steppers import SWEEP_WARN
from ..integrators.schemes import KIND_SYMPLECTIC_EULER, get_scheme
from ..model import SIGN_ASSUMPTIONS, sign_error
from ..native.build import CompiledSystem
from ..status import Status
from .arguments import (  # noqa: F401
    check_output_size,
    check_time_resolution,
    flag,
    keyed_by_name,
    method_name,
    missing_constraints,
    output_bytes,
    positive_int,
    real_number,
    real_values,
    step_count,
    stride_within,
)
from .drift import (  # noqa: F401
    DRIFT_TOLERANCE,
    ConstraintDriftWarning,
    resolve_drift_tolerance,
    warn_if_configuration_drifted,
    warn_if_drifted,
)
from .inputs import CallableInputs, InputTable, check_float_range, hold_code, is_sampled, resolve_inputs


class SimulationError(RuntimeError):
    """A run stopped early; ``trajectory`` holds the samples up to the failure."""

    def __init__(self, message: str, trajectory: Trajectory):
        super().__init__(message)
        self.trajectory = trajectory


class StabilityWarning(UserWarning):
    """The step lies outside the method's linear stability region at the initial state."""


class UndefinedOutputWarning(UserWarning):
    """A recorded output (a point, a measurement, the energy) is NaN or infinite at a finite state:
    its expression is undefined there (sqrt or log of a negative number, a division by zero)."""


@dataclass(frozen=True)
class Trajectory:
    """Samples of one run.

    Attributes
    ----------
    t : ndarray, (n_out,)
    x : ndarray, (n_out, 2n); columns named by ``names`` (coordinates, then speeds)
    names : tuple of str, (2n,)
    energy : ndarray (n_out,) or None
    points : ndarray (n_out, n_points, 3) or None; rows named by ``point_names``
    point_names : tuple of str
    status : Status
    failed_step, failed_time : int or None, float or None
        The step that failed (1-based) and the time it started from, when status is not OK.
    method : str
    h : float
    residuals : ndarray (n_out, 2m) or None
        Constrained models: phi (m) then A u + dphi/dt (m) at each kept sample.
    multipliers, constraint_forces : ndarray (n_out, m), (n_out, n) or None
        Constrained models: lambda and the generalized constraint forces A^T lambda, with
        M ud = F - A^T lambda (so the force the constraints exert is -A^T lambda).
    inputs : ndarray (n_out, n_r) or None
        Driven models: the inputs r read at each kept sample (held over the step that starts
        there), columns named by ``input_names``; NaN where reading them failed.
    measurements : ndarray (n_out, n_y) or None
        The model's output expressions y = h(q, u, r, t) at each kept sample, columns named by
        ``measurement_names`` (also ``traj["name"]``).
    detail : str or None
        What failed, when the run's inputs stopped it (which input, which value, what the callable raised).
    """

    t: np.ndarray
    x: np.ndarray
    names: tuple
    energy: np.ndarray | None
    points: np.ndarray | None
    point_names: tuple
    status: Status
    failed_step: int | None
    failed_time: float | None
    method: str
    h: float
    residuals: np.ndarray | None = None
    multipliers: np.ndarray | None = None
    constraint_forces: np.ndarray | None = None
    inputs: np.ndarray | None = None
    input_names: tuple = ()
    detail: str | None = None
    measurements: np.ndarray | None = None
    measurement_names: tuple = ()

    @property
    def ok(self) -> bool:
        return self.status == Status.OK

    @property
    def message(self) -> str:
        if self.ok:
            return "ok"
        detail = f" ({self.detail})" if self.detail else ""
        return (f"{self.method} stopped at step {self.failed_step} (t = {self.failed_time:.6g}): "
                f"{self.status.message}{detail}")

    def check(self) -> Trajectory:
        """Return self, or raise `SimulationError` when the run stopped early."""
        if not self.ok:
            raise SimulationError(self.message, self)
        return self

    def __repr__(self) -> str:
        where = "" if self.ok else f" at step {self.failed_step} (t = {self.failed_time:.6g})"
        span = f"t = {self.t[0]:.6g} .. {self.t[-1]:.6g}" if len(self.t) else "no samples"
        return (f"Trajectory(method={self.method!r}, h={self.h:g}, {len(self.t)} samples, {span}, "
                f"state=({', '.join(self.names)}), status={self.status.name}{where})")

    def __getitem__(self, name: str) -> np.ndarray:
        """The column of state variable or input ``name`` (e.g. ``traj["q1"]``), shape (n_out,)."""
        if name in self.names:
            return self.x[:, self.names.index(name)]
        if name in self.input_names and self.inputs is not None:
            return self.inputs[:, self.input_names.index(name)]
        if name in self.measurement_names and self.measurements is not None:
            return self.measurements[:, self.measurement_names.index(name)]
        known = self.names + self.input_names + self.measurement_names
        raise KeyError(f"no state variable or input {name!r}; names: {', '.join(known)}")


def parameter_vector(system: CompiledSystem, params: Mapping | None = None) -> np.ndarray:
    """Free-parameter values in ``p[]`` order: ``params`` by name, else the model's defaults."""
    layout = system.layout
    if params is not None and not isinstance(params, Mapping):
        raise TypeError(f"params must be a mapping name -> value, got {type(params).__name__}")
    given = keyed_by_name(params or {}, "params")
    fixed = {name for name, _ in layout.fixed}
    for name in given:
        if name in fixed:
            raise ValueError(f"parameter {name!r} is fixed at build time; free parameters: "
                             f"{', '.join(layout.parameters) or 'none'}")
        if name in layout.inputs:  # found by review: "unknown parameter 'F'" for the model's own input
            raise ValueError(f"{name!r} is an input of model {layout.model!r}, not a parameter: pass it in inputs=")
        if name not in layout.parameters:
            raise ValueError(f"unknown parameter {name!r}; free parameters: {', '.join(layout.parameters) or 'none'}")
    given = dict(zip(given, real_values(given.values(), given, "parameter")))
    values = dict(layout.defaults) | given
    missing = [name for name in layout.parameters if name not in values]
    if missing:
        raise ValueError(f"no value for parameter(s) {', '.join(missing)} of model {layout.model!r}")
    p = np.array([values[name] for name in layout.parameters], dtype=real_dtype(system))
    bad = [name for name, v in zip(layout.parameters, p) if not np.isfinite(v)]
    if bad:
        raise ValueError(f"parameter(s) {', '.join(bad)} are not finite")
    check_signs(layout, p[None, :], lambda name, member: f"parameter {name!r}")
    return p


class ParameterSignWarning(UserWarning):
    """A parameter's value has the sign its declared assumption excludes (positive=True and a
    negative value): the equations need not hold for it. The run goes on (a sweep's member with a
    negative mass fails alone), and this names the parameter where the failure would not."""


def check_signs(layout, ps: np.ndarray, what, names=None) -> None:
    """A `ParameterSignWarning` for the first value (rows of ``ps``: members) of the sign a free
    parameter's assumption excludes, with how many rows have one; ``what(name, member)`` names it.
    ``names``: only these parameters (a sweep's swept ones: the others were checked as the base)."""
    for name, assumption in layout.signs:
        if names is not None and name not in names:
            continue
        column = ps[:, layout.parameters.index(name)]
        wrong = np.flatnonzero(~SIGN_ASSUMPTIONS[assumption](column))
        if wrong.size:
            others = f" ({wrong.size} of {len(column)} members)" if len(column) > 1 else ""
            warnings.warn(sign_error(name, float(column[wrong[0]]), assumption, what(name, int(wrong[0]))) + others,
                          ParameterSignWarning, stacklevel=4)


def kernel_vector(system: CompiledSystem, values, names, what: str) -> np.ndarray:
    """``values``, one finite real per name, as the kernel's array (the low-level calls that take x,
    p or r as the C function does); a wrong length, a non-number or NaN raises naming ``what``."""
    if type(values) is np.ndarray and values.dtype == np.float64 and values.shape == (len(names),):
        array = values.astype(real_dtype(system))  # a copy; the float64 array a filter loop passes, checked at once
        if np.isfinite(array).all():  # (found by review: the checks per entry took 29 us of a 0.3 us jacobian)
            return array
    if isinstance(values, (str, bytes, Mapping)) or not np.iterable(values) or np.ndim(values) != 1:
        raise ValueError(f"{what} must be a sequence of {len(names)} number(s) ({', '.join(names)}), got {values!r}")
    if len(values) != len(names):
        raise ValueError(f"{what} needs {len(names)} value(s) ({', '.join(names)}), got {len(values)}")
    array = np.array(real_values(list(values), names, what), dtype=real_dtype(system))
    bad = [name for name, value in zip(names, array) if not np.isfinite(value)]
    if bad:
        raise ValueError(f"{what} is not finite in {', '.join(bad)}: {list(values)}")
    return array


def kernel_parameters(system: CompiledSystem, p) -> np.ndarray:
    """``p`` as a mapping name -> value (`parameter_vector`; None: the defaults) or one value per
    free parameter."""
    if p is None or isinstance(p, Mapping):
        return parameter_vector(system, p)
    return kernel_vector(system, p, system.layout.parameters, "p")


def initial_state(system: CompiledSystem, x0) -> np.ndarray:
    """x0 as a C-contiguous array of 2n values; accepts a sequence or a mapping name -> value
    (unnamed speeds default to 0, unnamed coordinates are an error)."""
    layout = system.layout
    names = layout.coordinates + layout.speeds
    if isinstance(x0, Mapping):
        x0 = keyed_by_name(x0, "x0")
        unknown = [k for k in x0 if k not in names]
        dependent = [k for k in unknown if k in layout.dependent_speeds]
        if dependent:
            raise ValueError(f"{', '.join(dependent)}: dependent speed(s), computed from the velocity constraints "
                             f"at every evaluation, not in the state; state: {', '.join(names)}")
        inputs = [k for k in unknown if k in layout.inputs]
        if inputs:
            raise ValueError(f"{', '.join(map(repr, inputs))}: input(s) of model {layout.model!r}, not in the state: "
                             "pass them in inputs=")
        if unknown:
            raise ValueError(f"unknown state variable(s) {unknown}; state: {', '.join(names)}")
        missing = [c for c in layout.coordinates if c not in x0]
        if missing:
            raise ValueError(f"initial state lacks coordinate(s) {', '.join(missing)}")
        x0 = [x0.get(name, 0.0) for name in names]
    elif isinstance(x0, (str, bytes)) or not np.iterable(x0):
        raise TypeError(f"x0 must be a sequence of {len(names)} numbers ({', '.join(names)}) or a mapping "
                        f"name -> value, got {x0!r}")
    values = list(np.asarray(x0, dtype=object).ravel()) if np.ndim(x0) > 1 else list(x0)
    if len(values) != len(names) or np.ndim(x0) > 1:
        raise ValueError(f"initial state needs {len(names)} values ({', '.join(names)}), got "
                         f"{len(values)}{' in shape ' + str(np.shape(x0)) if np.ndim(x0) > 1 else ''}")
    bad = [name for name, value in zip(names, values) if isinstance(value, numbers.Real)
           and not isinstance(value, bool) and not math.isfinite(float(value))]
    if bad:
        raise ValueError(f"initial state is not finite in {', '.join(bad)}: {values}")
    x = np.array(real_values(values, names, "initial state variable"), dtype=real_dtype(system))
    bad = [name for name, value in zip(names, x) if not np.isfinite(value)]
    if bad:  # finite doubles beyond the float range
        raise ValueError(f"initial state is not finite in {', '.join(bad)} at {layout.precision} precision")
    return x


def real_dtype(system: CompiledSystem):
    return np.float32 if system.layout.precision == "float" else np.float64


def c_pointer(system: CompiledSystem, array: np.ndarray):
    ctype = "float[]" if system.layout.precision == "float" else "double[]"
    return system.ffi.from_buffer(ctype, array, require_writable=array.flags.writeable)


def simulate(system: CompiledSystem, x0, t_end: float, h: float, method: str = "rk4", *,
             params: Mapping | None = None, t0: float = 0.0, stride: int = 1, energy: bool = False,
             points: bool = False, check_stability: bool = True, project: bool = False,
             residuals: bool = False, multipliers: bool = False, drift_tolerance: float | None = None,
             max_output_bytes: int | None = None, inputs=None, hold: str = "zoh") -> Trajectory:
    """Integrate with a fixed step, the whole loop in C.

    Parameters
    ----------
    system : CompiledSystem
        From `pipeline.compile_model` (or `build.build_module`), with ``method`` compiled in.
    x0 : sequence (2n,) or mapping name -> value
    t_end, h, t0 : float
        ``t_end - t0`` must be a whole number of steps, at most 2^63 - 1 of them.
    method : str
        A name from ``system.layout.methods``.
    params : mapping name -> float, optional
        Free parameter values; the model's defaults fill the rest.
    stride : int
        Keep every stride-th sample: ``n_steps // stride + 1`` samples (memory bounded by that);
        at most the number of steps.
    energy, points : bool
        Also record T + V and the named point positions at each kept sample.
    check_stability : bool
        Warn (`StabilityWarning`) when h times an eigenvalue of the Jacobian at x0 lies outside
        the method's linear stability region (inputs from a callable taken as 0 there: it is not
        called before the run).
    project : bool
        Constrained models: after every step, project the state back onto phi = 0 and
        A u + dphi/dt = 0 (Gauss-Newton, then linear). Baumgarte stabilization instead is set by
        the parameters ``baumgarte_alpha`` and ``baumgarte_beta``.
    residuals, multipliers : bool
        Constrained models: record the constraint residuals, and the multipliers with the
        generalized constraint forces, at each kept sample.
    drift_tolerance : float, optional
        Constrained models: warn (`ConstraintDriftWarning`) when max |phi| over the kept samples
        exceeds it; default `DRIFT_TOLERANCE` of the kernel's precision, ``math.inf`` switches
        the check off.
    max_output_bytes : int, optional
        Refuse (`arguments.OutputTooLargeError`) runs keeping more; default half the
        physical memory.
    inputs : optional
        Driven models (``Model(..., inputs=[...])``) only, and for them required: a constant
        (a number, or one per input), a mapping name -> constant or table, an array with a row
        per step (``n_steps`` or ``n_steps + 1`` rows) or per stride, a table ``(t, r)`` with
        increasing times covering the run (linear interpolation in C), or a callable
        ``f(t, x) -> r`` for feedback (a Python call per step, at its start: slower; the last sample
        records the inputs held over the last step). See `inputs.resolve_inputs`.
    hold : {"zoh", "foh"}
        ``"zoh"``: the inputs read at a step's start are held over the step (the embedded
        convention); ``"foh"``: the stages take them on the line to the value at the step's end
        (first-order hold; not for a callable, whose inputs depend on the state). An array of rows
        per step or per stride is a step function under "zoh" (row k over its step or stride) and
        the line through the rows under "foh". The inputs are read at the steps' ends only, so
        with an input that varies over a step every method is first order under "zoh" and at
        most second order under "foh" (measured: RK4 on a pendulum driven by 2 sin 3t, orders 1.0
        and 2.0 against DOP853); a table fine enough, or a step small enough, keeps that error
        below the method's own. symplectic_euler reads them at the step's start: "zoh" only.

    Returns
    -------
    Trajectory
        ``status`` says whether the run completed; a failed run keeps the samples before the
        failure and also emits a RuntimeWarning naming the reason, time and step. A singular
        status (``SINGULAR_MASS_MATRIX``, ``SINGULAR_CONSTRAINTS``) means the run landed on a
        singular configuration (or a step crossed a singular configuration: a pivot of M or of
        A M^-1 A^T that jumps 100x in one step or falls below 1e-8 of its value at t0, 1e-4 in
        float, or a sign change of det(A_prev A^T)).

    Examples
    --------
    The mass on a spring from x = 1 at rest: x(t) = cos(2 t) (omega = sqrt(k/m) = 2), so
    x(1) = cos 2 = -0.416147 (RK4 at h = 1e-3 is 1e-12 off):

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0})
    >>> from lagcodegen.pipeline import compile_model
    >>> from lagcodegen.run.simulate import simulate
    >>> run = simulate(compile_model(model, methods=("rk4",)), {"x": 1.0}, t_end=1.0, h=1e-3)
    >>> run.status, round(float(run["x"][-1]), 6)
    (<Status.OK: 0>, -0.416147)
    """
    method = compiled_method(system, method)
    n_steps = step_count(t0, t_end, h)
    t0, h = float(t0), float(h)
    check_time_resolution(system.layout, t0, t0 + n_steps * h, h)
    stride = stride_within(stride, n_steps)
    x = initial_state(system, x0)
    p = parameter_vector(system, params)
    check_start(system, x, p, t0)
    ramp = hold_code(hold)
    check_hold(method, ramp)
    signal = resolve_inputs(system.layout, inputs, t0, h, n_steps, stride, hold)
    if isinstance(signal, InputTable):
        check_float_range(system.layout, signal.values)
    if ramp and callable(signal):
        raise ValueError("hold='foh' needs the inputs at the step's end before the step: not for a callable of "
                         "the state; use hold='zoh' or a table")
    outputs = _outputs(system, energy=energy, points=points, project=project, residuals=residuals,
                       multipliers=multipliers)
    tolerance = resolve_drift_tolerance(system.layout, drift_tolerance)
    track = bool(tolerance is not None or outputs["residuals"])

    def size_of(every: int) -> int:
        return output_bytes(system.layout, n_steps, every, energy=outputs["energy"], points=outputs["points"],
                            residuals=track, multipliers=outputs["multipliers"])

    check_output_size(size_of(stride), n_steps, stride, "the run", max_output_bytes, size_of)
    if flag(check_stability, "check_stability"):
        # a callable is not called here (a controller with state would advance): its inputs are taken
        # as 0 for the Jacobian (found by review: the check was skipped, and a run blew up to 3e129 with OK)
        r0 = None if signal is None else np.zeros(len(system.layout.inputs)) if callable(signal) else signal.at(t0)
        warn_if_unstable(system, x, p, h, method, t0, n_steps, r=r0)
    trajectory = _run(system, x, p, t0, h, n_steps, stride, method, outputs, track, signal, ramp)
    warn_if_outputs_undefined(trajectory)
    if tolerance is not None:
        warn_if_drifted(trajectory, tolerance, system.layout.n_constraints, system.layout.n_holonomic)
    if not outputs["project"]:
        warn_if_configuration_drifted(system.layout, trajectory,
                                      lambda times, states: projected_rows(system, times, states, p), drift_tolerance)
    if not outputs["residuals"] and trajectory.residuals is not None:  # kept for the drift check only
        trajectory = replace(trajectory, residuals=None)
    return trajectory


def warn_if_outputs_undefined(trajectory: Trajectory) -> bool:
    """Warn (`UndefinedOutputWarning`, and return True) for each recorded output that is not finite
    at a sample whose state (and inputs) are: the run's status speaks of the state only (found by review: a
    point at (sqrt(x), 0) and a measurement log(x) were NaN at 60 % of a run's samples, status OK,
    no word, and the animation silently left the point out)."""
    finite = np.all(np.isfinite(trajectory.x), axis=1)
    if trajectory.inputs is not None:  # an input that failed is the run's status, not the expression's (review)
        finite &= np.all(np.isfinite(trajectory.inputs), axis=1)
    columns = []
    if trajectory.points is not None:
        columns += [(f"point {name!r}", np.all(np.isfinite(trajectory.points[:, j, :]), axis=1))
                    for j, name in enumerate(trajectory.point_names)]
    if trajectory.measurements is not None:
        columns += [(f"measurement {name!r}", np.isfinite(trajectory.measurements[:, j]))
                    for j, name in enumerate(trajectory.measurement_names)]
    if trajectory.energy is not None:
        columns.append(("the energy", np.isfinite(trajectory.energy)))
    warned = False
    for what, defined in columns:
        undefined = np.flatnonzero(finite & ~defined)
        if len(undefined):
            first = int(undefined[0])
            state = np.array2string(np.asarray(trajectory.x[first], dtype=float), precision=4)
            warnings.warn(f"{what} is NaN or infinite at {len(undefined)} of the {len(finite)} samples whose state is "
                          f"finite, first at t = {trajectory.t[first]:.6g} (state {state}): its expression is "
                          "undefined there", UndefinedOutputWarning, stacklevel=3)
            warned = True
    return warned


def check_hold(method: str, ramp: int) -> None:
    """symplectic_euler takes the inputs at the step's start: hold='foh' would be ignored (found by
    review: its runs were bit for bit those of 'zoh')."""
    if ramp and method == "symplectic_euler":
        raise ValueError("hold='foh' does not apply to symplectic_euler, which reads the inputs once, at the "
                         "step's start: use hold='zoh' or another method")


def check_start(system: CompiledSystem, x: np.ndarray, p: np.ndarray, t0: float) -> None:
    """A ValueError naming the culprit when x at t0 cannot start a run: the eliminated dependent
    speeds not solvable (a singular constraint Jacobian in them), or x off Kane's configuration
    constraints."""
    if system.layout.dependent_speeds:
        _per_state(system, "dependent_speeds", system.layout.dependent_speeds, x, p, t0, None)
    _check_configuration(system, x, p, t0)


def start_offsets(system: CompiledSystem, x: np.ndarray, p: np.ndarray, t0: float) -> float | None:
    """max |phi| and |A u + dphi/dt| of the constraints with multipliers at x (None without them)."""
    layout = system.layout
    m = layout.n_constraints
    if not m or f"{layout.prefix}_residuals" not in layout.functions:
        return None
    out = np.empty(2 * m, dtype=real_dtype(system))
    residuals = getattr(system.lib, f"{layout.prefix}_residuals")
    residuals(t0, c_pointer(system, np.ascontiguousarray(x)), c_pointer(system, np.ascontiguousarray(p)),
              c_pointer(system, out))
    return float(np.max(np.abs(out)))


def projected_rows(system: CompiledSystem, times, states, ps) -> tuple[np.ndarray, np.ndarray]:
    """Kane's configuration projection (``<prefix>_project``, in C) of a copy of each row of ``states``
    at ``times``; ``ps``: one parameter vector, or one per row. Through one buffer per array (found by
    review: a buffer per state took 15 us each, 3 ms of a short simulate). Returns (the statuses, the
    projected copies)."""
    dtype = real_dtype(system)
    out = np.array(states, dtype=dtype)
    ps = np.ascontiguousarray(ps, dtype=dtype)
    project = getattr(system.lib, f"{system.layout.prefix}_project")
    x_at, p_at = c_pointer(system, out), c_pointer(system, ps)
    n_x, n_p, per_row = out.shape[1], ps.shape[-1], ps.ndim == 2
    codes = np.array([project(float(t), x_at + i * n_x, p_at + i * n_p if per_row else p_at)
                      for i, t in enumerate(times)], dtype=int)
    return codes, out


def member_offsets(system: CompiledSystem, xs: np.ndarray, ps: np.ndarray, t: float) -> np.ndarray | None:
    """`start_offsets` of every row of ``xs`` (parameters: the rows of ``ps``), through one buffer per
    array (a sweep's loop over `start_offsets` took 30 us per member; found by review). None without
    constraints with multipliers."""
    layout = system.layout
    m = layout.n_constraints
    if not m or f"{layout.prefix}_residuals" not in layout.functions:
        return None
    dtype = real_dtype(system)
    xs, ps = np.ascontiguousarray(xs, dtype=dtype), np.ascontiguousarray(ps, dtype=dtype)
    out = np.empty((len(xs), 2 * m), dtype=dtype)
    residuals = getattr(system.lib, f"{layout.prefix}_residuals")
    x_at, p_at, out_at = c_pointer(system, xs), c_pointer(system, ps), c_pointer(system, out)
    n_x, n_p = xs.shape[1], ps.shape[1]
    for i in range(len(xs)):
        residuals(t, x_at + i * n_x, p_at + i * n_p, out_at + i * 2 * m)
    return np.max(np.abs(out), axis=1)


def _check_configuration(system: CompiledSystem, x: np.ndarray, p: np.ndarray, t0: float) -> None:
    """x0 on Kane's configuration constraints (a model whose <prefix>_project solves them for its
    dependent coordinates): else a ValueError naming each coordinate off and the value that fits."""
    layout = system.layout
    if layout.n_constraints or f"{layout.prefix}_project" not in layout.functions:
        return
    projected = np.array(x, dtype=real_dtype(system))
    code = getattr(system.lib, f"{layout.prefix}_project")(t0, c_pointer(system, projected), c_pointer(system, p))
    names = layout.coordinates
    if code != Status.OK:
        raise ValueError(f"x0 is on no configuration of model {layout.model!r} near it (Kane's configuration "
                         f"constraints, solved for its dependent coordinates: {Status(code).message})")
    tolerance = 1e-9 if projected.dtype == np.float64 else 1e-4
    off = [i for i in range(layout.n_q) if abs(projected[i] - x[i]) > tolerance * (1 + abs(x[i]))]
    if off:
        fits = ", ".join(f"{names[i]} = {float(x[i])!r} (fits: {float(projected[i])!r})" for i in off)
        raise ValueError(f"x0 violates the configuration constraints of model {layout.model!r}: {fits}; start "
                         "from the values that fit")


def compiled_method(system: CompiledSystem, method) -> str:
    """``method`` lower-cased, checked to be a string compiled into ``system``."""
    layout = system.layout
    method = method_name(method)
    if method not in layout.methods:
        raise ValueError(f"method {method!r} is not compiled into {layout.model!r}; compiled: "
                         f"{', '.join(layout.methods) or 'none'}")
    return method


def _outputs(system: CompiledSystem, **requested) -> dict:
    """The optional outputs as checked bools; ValueError when the kernel lacks the C function one
    needs (the C driver skips a missing output, which would leave its array unwritten)."""
    layout = system.layout
    outputs = {name: flag(value, name) for name, value in requested.items()}
    projects = f"{layout.prefix}_project" in layout.functions  # Kane's configuration constraints too
    asked = [name for name in ("project", "residuals", "multipliers") if outputs[name]
             and not (name == "project" and projects)]
    if asked and not layout.n_constraints:
        raise ValueError(missing_constraints(layout, asked))
    for name, output in NEEDED_OUTPUT.items():
        if outputs.get(name) and f"{layout.prefix}_{name}" not in layout.functions:
            raise ValueError(f"{name}=True: model {layout.model!r} was compiled without the {output!r} output "
                             f"(compile_model(..., outputs=(..., {output!r})))")
    return outputs


#: option -> the compile output that brings its C function lcg_<model>_<option>
NEEDED_OUTPUT = {"energy": "energy", "points": "points", "project": "constraints", "residuals": "constraints",
                 "multipliers": "multipliers"}


def _run(system, x, p, t0, h, n_steps, stride, method, outputs, track_residuals, signal=None,
         ramp: int = 0) -> Trajectory:
    layout, dtype = system.layout, real_dtype(system)
    n_out = n_steps // stride + 1
    t_out = np.empty(n_out, dtype=dtype)
    x_out = np.empty((n_out, layout.n_state), dtype=dtype)
    e_out = np.empty(n_out, dtype=dtype) if outputs["energy"] else None
    p_out = np.empty((n_out, len(layout.points), 3), dtype=dtype) if outputs["points"] else None
    m = layout.n_constraints
    r_out = np.full((n_out, 2 * m), np.nan, dtype=dtype) if m and track_residuals else None
    m_out = np.full((n_out, m + layout.n_u), np.nan, dtype=dtype) if m and outputs["multipliers"] else None
    work = np.empty(work_size(system), dtype=dtype)
    steps_done = system.ffi.new("long *")
    ptr = lambda a: system.ffi.NULL if a is None else c_pointer(system, a)  # noqa: E731
    simulate_c = getattr(system.lib, f"{layout.prefix}_simulate")
    driven, in_out, source = (), None, None
    if layout.inputs:
        in_out = np.full((n_out, len(layout.inputs)), np.nan, dtype=dtype)
        driven, source = _input_arguments(system, signal, ramp, t0 + n_steps * h, h)
        driven += (ptr(in_out),)
    y_out = None
    if layout.measurements:
        y_out = np.full((n_out, len(layout.measurements)), np.nan, dtype=dtype)
        driven += (ptr(y_out),)
    code = simulate_c(layout.methods.index(method), t0, c_pointer(system, x), c_pointer(system, p), h,
                      n_steps, stride, int(outputs["project"]), *driven, ptr(t_out), ptr(x_out), ptr(e_out),
                      ptr(p_out), ptr(r_out), ptr(m_out), ptr(work), steps_done)
    if isinstance(source, CallableInputs):
        source.reraise()
    status = Status(code)
    kept = n_out if status == Status.OK else steps_done[0] // stride + 1
    failed_step = None if status == Status.OK else steps_done[0] + 1
    failed_time = None if status == Status.OK else t0 + steps_done[0] * h
    trajectory = Trajectory(
        t=t_out[:kept], x=x_out[:kept], names=layout.coordinates + layout.speeds,
        energy=None if e_out is None else e_out[:kept], points=None if p_out is None else p_out[:kept],
        residuals=None if r_out is None else r_out[:kept],
        multipliers=None if m_out is None else m_out[:kept, :m],
        constraint_forces=None if m_out is None else m_out[:kept, m:],
        point_names=layout.points, status=status, failed_step=failed_step, failed_time=failed_time,
        method=method, h=h, inputs=None if in_out is None else in_out[:kept], input_names=layout.inputs,
        detail=_input_detail(source, status), measurements=None if y_out is None else y_out[:kept],
        measurement_names=layout.measurements)
    if not trajectory.ok:
        warnings.warn(trajectory.message, RuntimeWarning, stacklevel=3)
    return trajectory


def _input_arguments(system: CompiledSystem, signal, ramp: int, t_end: float, h: float) -> tuple:
    """The driver's (input function, context, hold) for a table or a callable, and what keeps
    the cffi objects alive for the call (the table's arrays, the callback)."""
    ffi, prefix = system.ffi, system.layout.prefix
    if callable(signal) and not isinstance(signal, InputTable):
        source = CallableInputs(system, signal, final_time=t_end, h=abs(h))
        return (source.callback, ffi.NULL, ramp), source
    dtype = real_dtype(system)
    times = np.ascontiguousarray(signal.times, dtype=dtype)
    values = np.ascontiguousarray(signal.values, dtype=dtype)
    table = ffi.new(f"{prefix}_input_table *")
    table.t, table.r = c_pointer(system, times), c_pointer(system, values)
    table.n, table.cursor = len(times), 0
    source = (table, times, values)
    function = ffi.addressof(system.lib, f"{prefix}_table_inputs")
    return (function, table, ramp), source


def _input_detail(source, status: Status) -> str | None:
    if isinstance(source, CallableInputs) and status != Status.OK:
        return source.detail
    return None


def work_size(system: CompiledSystem) -> int:
    return int(getattr(system.lib, f"{system.layout.prefix.upper()}_WORK_SIZE"))


def jacobian(system: CompiledSystem, x, p, t: float = 0.0, r=None, with_inputs: bool = False):
    """df/dx (2n, 2n) of the compiled first-order right-hand side (the analytic Jacobian); for a
    driven model at the inputs ``r``, and with ``with_inputs`` the pair (df/dx, df/dr (2n, n_r))."""
    layout = system.layout
    name = f"{layout.prefix}_jacobian"
    if name not in layout.functions:
        raise ValueError(f"model {layout.model!r} was compiled without the 'jacobian' output")
    size = layout.n_state
    J = np.empty((size, size), dtype=real_dtype(system))
    x = kernel_vector(system, x, layout.coordinates + layout.speeds, "x")
    p = kernel_parameters(system, p)
    driven, Jr = (), None
    if layout.inputs:
        if r is None:
            raise ValueError(f"model {layout.model!r} is driven by {', '.join(layout.inputs)}: pass r=")
        r = kernel_vector(system, np.reshape(r, -1), layout.inputs, "r")
        Jr = np.empty((size, len(layout.inputs)), dtype=real_dtype(system))
        driven = (c_pointer(system, r),)
    arguments = (t, c_pointer(system, x), *driven, c_pointer(system, p), c_pointer(system, J))
    if layout.inputs:
        arguments += (c_pointer(system, Jr) if with_inputs else system.ffi.NULL,)
    code = getattr(system.lib, name)(*arguments)
    if code == Status.NONFINITE_STATE:
        raise JacobianOverflow(f"jacobian at x = {x} is not finite: {Status(code).message}")
    if code != Status.OK:
        raise ValueError(f"jacobian failed at x = {x}: {Status(code).message}")
    if with_inputs:
        return J, (Jr if Jr is not None else np.empty((size, 0), dtype=J.dtype))
    return J


class JacobianOverflow(ValueError):
    """The Jacobian kernel met NaN or infinite values at a finite state (e.g. a parameter near overflow)."""


def warn_if_unstable(system: CompiledSystem, x, p, h: float, method: str, t: float = 0.0,
                     n_steps: int = 1, r=None) -> bool:
    """Warn (and return True) when the step is outside the method's linear stability region.

    The Jacobian's eigenvalues lambda at x are the local frequencies. Modes with Re(lambda) > 0
    grow in the exact solution too and are ignored; for the others the amplification
    |R(h lambda)| per step (R the method's stability function) must not exceed 1 by so much that
    the run, n_steps long, amplifies them more than tenfold.
    """
    scheme = get_scheme(method)
    try:
        if f"{system.layout.prefix}_jacobian" in system.layout.functions:
            J = jacobian(system, x, p, t, r=r)
        else:  # found by review: an RK4-only build (every CLI run) blew up to 1e74 with no warning
            J = _difference_jacobian(system, x, p, t, r)
    except JacobianOverflow:
        J = None
    except (ValueError, FloatingPointError):  # e.g. a singular mass matrix at x: the run itself reports it
        return False
    if J is None or not np.all(np.isfinite(J)):  # e.g. a parameter of 1e308: the run reports its status
        warnings.warn(f"stability pre-check skipped: the Jacobian at the initial state is not finite "
                      f"(parameters or state near overflow); {method} runs unchecked", StabilityWarning,
                      stacklevel=3)
        return False
    try:
        eigenvalues = np.linalg.eigvals(J.astype(np.float64))
    except np.linalg.LinAlgError:  # eigenvalue iteration did not converge: never fatal for a pre-check
        return False
    understated = _warn_if_growth_lost(scheme, h, eigenvalues, method)
    if scheme.implicit:  # A-stable or close to it: the non-growing modes need no check
        return understated
    if scheme.stepper == KIND_SYMPLECTIC_EULER and _warn_if_sweeps_diverge(system, J, h):
        return True
    settled = eigenvalues[eigenvalues.real <= 1e-9 * np.abs(eigenvalues)]
    if settled.size == 0:
        return False
    w = float(np.max(np.abs(settled)))
    unstable, limit = scheme.unstable_step(h, settled, n_steps)
    if unstable:
        warnings.warn(
            f"step h = {h:g} with the largest frequency w = {w:.6g} rad/s of the Jacobian at the "
            f"initial state gives h*w = {h * w:.4g}, outside {method}'s stability region ({limit}); "
            f"the run will likely blow up: reduce h or use an implicit method", StabilityWarning, stacklevel=3)
    return unstable


def _warn_if_sweeps_diverge(system: CompiledSystem, J: np.ndarray, h: float) -> bool:
    """Symplectic Euler solves for its new speeds by sweeps that contract by about h |d ud/du| (the
    speeds' block of the Jacobian): warn (and return True) when that reaches `SWEEP_WARN`, past
    which the sweeps outrun their budget and the step fails with NEWTON_FAILED (found by review:
    damping with h c/m = 0.4 failed at step 1, unwarned; it now converges)."""
    n_q = system.layout.n_q
    try:
        rho = float(np.max(np.abs(np.linalg.eigvals(J[n_q:, n_q:].astype(np.float64)))))
    except (np.linalg.LinAlgError, ValueError):
        return False
    if not h * rho >= SWEEP_WARN:
        return False
    warnings.warn(f"step h = {h:g} with |d ud/du| = {rho:.4g} 1/s (damping, or speed-dependent forces) at the "
                  f"initial state: symplectic_euler's velocity iteration contracts by h*|d ud/du| = {h * rho:.3g} "
                  f"per sweep and may not converge from {SWEEP_WARN:g} on; reduce h below "
                  f"{SWEEP_WARN / rho:.3g} or use an implicit method", StabilityWarning, stacklevel=4)
    return True


def _warn_if_growth_lost(scheme, h: float, eigenvalues: np.ndarray, method: str) -> bool:
    """Warn (and return True) when a growing mode (Re(lambda) > 0) changes by a step h of ``method``
    far less than the exact e^(h Re(lambda)): |R(h lambda)| below e^(h Re(lambda) / 2) for
    h Re(lambda) > 1/2 (found by review: backward Euler at h lambda = 10 has R = -0.11, and an unstable
    plant decayed to 0 with status OK; implicit midpoint's 1.5 per step against e^10)."""
    amplification = getattr(scheme, "amplification", None)
    growing = eigenvalues[(eigenvalues.real > 1e-9 * np.abs(eigenvalues)) & (h * eigenvalues.real > 0.5)]
    if amplification is None or growing.size == 0:
        return False
    rate = h * growing.real
    with np.errstate(divide="ignore"):
        lost = np.log(amplification(h * growing)) < rate / 2
    if not lost.any():
        return False
    worst = int(np.argmax(np.where(lost, rate, -np.inf)))
    lam = complex(growing[worst])
    warnings.warn(f"the Jacobian at the initial state has a growing mode lambda = {lam.real:.4g}"
                  f"{lam.imag:+.4g}j 1/s: with h = {h:g}, h*Re(lambda) = {rate[worst]:.4g}, {method} changes it "
                  f"by a factor {float(amplification(np.array([h * lam]))[0]):.3g} per step where it grows by "
                  f"{math.exp(min(rate[worst], 700.0)):.3g}; the run would understate or reverse its growth: reduce h",
                  StabilityWarning, stacklevel=4)
    return True


def solve_reference(system: CompiledSystem, x0, t_eval, *, params: Mapping | None = None, t0: float = 0.0,
                    method: str = "DOP853", rtol: float = 1e-12, atol: float = 1e-12, inputs=None,
                    h: float | None = None):
    """scipy ``solve_ivp`` on the compiled right-hand side; returns (t (k,), x (k, 2n)).

    The reference for error measurements (DOP853 or Radau at rtol = atol = 1e-12). A driven
    model takes ``inputs`` as `simulate` does, read continuously: a table interpolated at every
    time scipy asks for, a callable at (t, x) (an array per step is a step function of t). An
    array per step needs the run's step: ``h``, or ``t_eval`` the run's own grid t0, t0 + h, ...
    """
    from scipy.integrate import solve_ivp

    layout = system.layout
    if layout.precision != "double":
        raise ValueError("reference solutions need a double-precision kernel")
    t_eval = np.asarray(t_eval, dtype=float)
    signal = None
    if layout.inputs or inputs is not None:
        t_last = float(t_eval[-1])
        if h is None:
            h = _grid_step(t_eval, t0)
            if h is None and is_sampled(layout, inputs):  # found by review: the rows were silently re-timed
                raise ValueError(f"an array of inputs per step needs the run's step: pass h= (t_eval is not the "
                                 f"run's grid t0 = {t0:g}, t0 + h, ...)")
            h = h or (t_last - t0)  # tables and callables do not depend on it
        signal = resolve_inputs(layout, inputs, t0, h, step_count(t0, t_last, h), 1, exact_jumps=True)

    def rhs_until(end):  # a segment's right-hand side: a table's inputs at its end are those before a jump there
        if not isinstance(signal, InputTable):
            return make_rhs(system, params, inputs=signal)
        return make_rhs(system, params, inputs=lambda t, _: signal.before(t) if t >= end else signal.at(t))
    x = initial_state(system, x0)
    kwargs = {}
    if method in ("Radau", "BDF", "LSODA") and f"{layout.prefix}_jacobian" in layout.functions:
        p = parameter_vector(system, params)
        kwargs["jac"] = lambda t, y: jacobian(system, y, p, t, r=_signal_at(signal, t, y))
    breaks = signal.times if isinstance(signal, InputTable) and signal.times.size > 1 else ()
    solution = _solve_between(solve_ivp, rhs_until, t0, float(t_eval[-1]), x, method, t_eval, rtol, atol, breaks,
                              kwargs)
    return solution


def _grid_step(t_eval: np.ndarray, t0: float) -> float | None:
    """The spacing of ``t_eval`` when it is a uniform grid starting at t0, else None."""
    if len(t_eval) < 2 or t_eval[0] != t0:
        return None
    steps = np.diff(t_eval)
    return float(steps[0]) if steps[0] > 0 and np.allclose(steps, steps[0], rtol=1e-9, atol=0) else None


def _signal_at(signal, t, x):
    if signal is None:
        return None
    if isinstance(signal, InputTable):
        return signal.at(t)
    return np.asarray(signal(t, np.asarray(x)), dtype=float).reshape(-1)


def _solve_between(solve_ivp, rhs_until, t0, t_end, x, method, t_eval, rtol, atol, breaks, kwargs):
    """solve_ivp from knot to knot of the input table, so no step straddles a kink or jump of the
    inputs (a step across one would lose the method's order there); ``rhs_until(b)`` is the
    right-hand side of the segment that ends at b."""
    edges = [t0] + sorted({float(b) for b in breaks if t0 < b < t_end}) + [t_end]
    times, states = [], []
    for k, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        last = k == len(edges) - 2
        inside = t_eval[(t_eval >= a) & ((t_eval <= b) if last else (t_eval < b))]
        points = np.union1d(inside, [b])
        solution = solve_ivp(rhs_until(b), (a, b), x, method=method, t_eval=points, rtol=rtol, atol=atol, **kwargs)
        if not solution.success:
            raise RuntimeError(f"reference solution ({method}) failed: {solution.message}")
        keep = np.isin(solution.t, inside)
        times.append(solution.t[keep])
        states.append(solution.y.T[keep])
        x = solution.y[:, -1]
    return np.concatenate(times), np.concatenate(states)


def _difference_jacobian(system: CompiledSystem, x, p, t: float, r=None) -> np.ndarray:
    """df/dx by central differences of the compiled rhs (steps eps^(1/3) (1 + |x_j|)): enough for
    the stability pre-check's eigenvalues where the kernel has no analytic Jacobian."""
    layout = system.layout
    dtype = real_dtype(system)
    rhs_c = getattr(system.lib, f"{layout.prefix}_rhs")
    p = np.ascontiguousarray(p, dtype=dtype)
    driven = ()
    if layout.inputs:
        if r is None:
            raise ValueError(f"model {layout.model!r} is driven by {', '.join(layout.inputs)}: pass r=")
        driven = (c_pointer(system, np.ascontiguousarray(np.reshape(r, -1), dtype=dtype)),)

    def f(state: np.ndarray) -> np.ndarray:
        state = np.ascontiguousarray(state, dtype=dtype)
        out = np.empty_like(state)
        code = rhs_c(t, c_pointer(system, state), *driven, c_pointer(system, p), c_pointer(system, out))
        if code != Status.OK:
            raise FloatingPointError(f"rhs failed near x = {state}: {Status(code).message}")
        return out.astype(np.float64)

    x = np.asarray(x, dtype=np.float64)
    J = np.empty((x.size, x.size))
    for j in range(x.size):
        step = np.cbrt(np.finfo(dtype).eps) * (1.0 + abs(x[j]))
        plus, minus = x.copy(), x.copy()
        plus[j] += step
        minus[j] -= step
        J[:, j] = (f(plus) - f(minus)) / (2.0 * step)
    return J


def make_rhs(system: CompiledSystem, params: Mapping | None = None, inputs=None):
    """``f(t, x) -> xdot`` (numpy) calling the compiled rhs; raises on a non-OK status. A driven
    model reads ``inputs`` (an `InputTable` or a callable f(t, x)) at every call."""
    layout = system.layout
    p = parameter_vector(system, params)
    p_ptr = c_pointer(system, p)
    rhs_c = getattr(system.lib, f"{layout.prefix}_rhs")
    dtype = real_dtype(system)
    if layout.inputs and inputs is None:
        raise ValueError(f"model {layout.model!r} is driven by {', '.join(layout.inputs)}: pass inputs=")

    names = layout.coordinates + layout.speeds

    def f(t, x):
        # found by review: a short x, or short inputs, were read and written past their ends by the C
        x = np.ascontiguousarray(x, dtype=dtype)
        if x.shape != (layout.n_state,):
            raise ValueError(f"x must hold the {layout.n_state} values {', '.join(names)} of one state, "
                             f"got shape {x.shape}")
        out = np.empty_like(x)
        if layout.inputs:
            r = np.ascontiguousarray(_signal_at(inputs, t, x), dtype=dtype)
            if r.shape != (len(layout.inputs),):
                raise ValueError(f"the inputs at t = {t} must be {len(layout.inputs)} values "
                                 f"({', '.join(layout.inputs)}), got shape {r.shape}")
            code = rhs_c(t, c_pointer(system, x), c_pointer(system, r), p_ptr, c_pointer(system, out))
        else:
            code = rhs_c(t, c_pointer(system, x), p_ptr, c_pointer(system, out))
        if code != Status.OK:
            raise FloatingPointError(f"rhs failed at t = {t}: {Status(code).message}")
        return out
    return f


def dependent_speeds(system: CompiledSystem, x, params: Mapping | None = None, t=0.0) -> np.ndarray:
    """The eliminated dependent speeds (``layout.dependent_speeds``) at states ``x`` ((N,) or
    (k, N), e.g. ``trajectory.x``) and times ``t`` (a number or k of them, e.g. ``trajectory.t``),
    from the compiled ``<prefix>_dependent_speeds``: (m,) or (k, m). A singular constraint
    Jacobian in them raises ValueError naming the state."""
    names = system.layout.dependent_speeds
    if not names:
        raise ValueError(f"model {system.layout.model!r} eliminates no dependent speeds")
    return _per_state(system, "dependent_speeds", names, x, params, t, None)


def reactions(system: CompiledSystem, x, params: Mapping | None = None, t=0.0, r=None) -> np.ndarray:
    """The constraint forces Kane's auxiliary speeds expose (``layout.reactions``, e.g. a contact's
    normal and friction forces) at states ``x`` and times ``t`` as `dependent_speeds` takes them,
    with the inputs ``r`` ((n_r,) or (k, n_r)) of a driven model: (n_R,) or (k, n_R)."""
    names = system.layout.reactions
    if not names:
        raise ValueError(f"model {system.layout.model!r} was compiled without reactions: they need the 'reactions' "
                         "output (compile_model(..., outputs=(..., 'reactions'))) and a KanesMethod with auxiliary "
                         "speeds, the unknown forces applied where they act")
    return _per_state(system, "reactions", names, x, params, t, r)


def _per_state(system: CompiledSystem, function: str, names: tuple, x, params, t, r) -> np.ndarray:
    """``<prefix>_<function>(t, x, [r,] p, out)`` at every state of ``x``; a status raises ValueError."""
    layout = system.layout
    dtype = real_dtype(system)
    try:
        states = np.atleast_2d(np.asarray(x, dtype=dtype))
    except (TypeError, ValueError) as error:
        raise ValueError(f"x must be numbers, {layout.n_state} per state: {error}") from None
    if states.ndim != 2 or states.shape[1] != layout.n_state:
        raise ValueError(f"x must hold {layout.n_state} values per state "
                         f"({', '.join(layout.coordinates + layout.speeds)}), got shape {np.shape(x)}")
    times = np.broadcast_to(np.asarray(t, dtype=float), (len(states),))
    p = kernel_parameters(system, params)
    call = getattr(system.lib, f"{layout.prefix}_{function}")
    driven = function == "reactions" and layout.inputs
    if driven:
        if r is None:
            raise ValueError(f"model {layout.model!r} is driven by {', '.join(layout.inputs)}: pass r=")
        held = np.broadcast_to(np.asarray(r, dtype=dtype), (len(states), len(layout.inputs)))
    out = np.empty((len(states), len(names)), dtype=dtype)
    # one buffer per array, rows by pointer offsets (found by review: buffers per state took 3.7 us of each)
    states = np.ascontiguousarray(states)
    x_at, p_at, out_at = c_pointer(system, states), c_pointer(system, p), c_pointer(system, out)
    r_at = c_pointer(system, np.ascontiguousarray(held)) if driven else None
    n_x, n_out, n_r = layout.n_state, len(names), len(layout.inputs)
    for i, time in enumerate(times.tolist()):
        if driven:
            code = call(time, x_at + i * n_x, r_at + i * n_r, p_at, out_at + i * n_out)
        else:
            code = call(time, x_at + i * n_x, p_at, out_at + i * n_out)
        if code != Status.OK:
            raise ValueError(f"{function.replace('_', ' ')} {', '.join(names)} at t = {time}, x = {states[i]}: "
                             f"{Status(code).message}")
    return out if np.ndim(x) == 2 else out[0]


def step_jacobians(system: CompiledSystem, x, p, h: float, method: str = "rk4", r=None, t: float = 0.0):
    """One compiled explicit step from (t, x) with inputs ``r`` held, and its exact Jacobians.

    Returns (x_next (N,), Fx = dx+/dx (N, N), Fr = dx+/dr (N, n_r)), N = n_q + n_u: the discrete plant's
    linearization for an extended Kalman filter, MPC or a discrete LQR. Needs the kernel built
    with the ``step_jacobian`` output and ``method`` (an explicit Runge-Kutta method) compiled in.
    """
    layout = system.layout
    method = compiled_method(system, method)
    name = f"{layout.prefix}_step_jacobian_{method}"
    if name not in layout.functions:
        raise ValueError(f"model {layout.model!r} has no step Jacobian for {method!r}: compile it with "
                         "outputs=(..., 'step_jacobian') and an explicit Runge-Kutta method (rk4, dopri5, ...; "
                         "symplectic_euler has none)")
    dtype, size, n_r = real_dtype(system), layout.n_state, len(layout.inputs)
    state = np.array(initial_state(system, x), dtype=dtype)
    p = kernel_parameters(system, p)
    h = real_number(h, "h")
    Fx = np.empty((size, size), dtype=dtype)
    Fr = np.empty((size, n_r), dtype=dtype)
    work = np.empty(int(getattr(system.lib, f"{layout.prefix.upper()}_WORK_JACOBIAN_{method.upper()}")), dtype=dtype)
    time = system.ffi.new("float *" if dtype == np.float32 else "double *", t)
    arguments = [time, c_pointer(system, state)]
    if n_r:
        if r is None:
            raise ValueError(f"model {layout.model!r} is driven by {', '.join(layout.inputs)}: pass r=")
        r = kernel_vector(system, np.reshape(r, -1), layout.inputs, "r")
        arguments.append(c_pointer(system, r))
    arguments += [c_pointer(system, p), h, c_pointer(system, Fx)]
    if n_r:
        arguments.append(c_pointer(system, Fr))
    code = getattr(system.lib, name)(*arguments, c_pointer(system, work))
    if code != Status.OK:
        raise ValueError(f"step Jacobian of {method} failed at x = {state}: {Status(code).message}")
    return state, Fx, Fr
