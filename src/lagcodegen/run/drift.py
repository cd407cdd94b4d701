"""Stage helper for run: the constraint-drift check of `simulate.simulate`.

A constrained run without projection (or with too weak Baumgarte terms) drifts off phi = 0 while
its status stays OK; the check reads the residuals the C driver records at each kept sample
(``lcg_<model>_residuals``, phi then A u + dphi/dt) and warns once max |phi| passes the tolerance.
"""
from __future__ import annotations

import math
import numbers
import warnings

import numpy as np

from .arguments import real_number


class ConstraintDriftWarning(UserWarning):
    """A constrained run without projection drifted off the constraints by more than the
    tolerance (``simulate(..., drift_tolerance=...)``)."""


class StartOffConstraintsWarning(ConstraintDriftWarning):
    """Sweep members start off their constraints with multipliers: a run holds the offset it starts
    with (the command line's sweep refuses them, as its simulate refuses such a start)."""


#: default ``drift_tolerance`` on max |phi| per precision: well above the rounding of a run
DRIFT_TOLERANCE = {"double": 1e-6, "float": 1e-3}


def resolve_drift_tolerance(layout, tolerance) -> float | None:
    """The max |phi| tolerance of the drift check for a kernel of ``layout`` (None: the
    precision's `DRIFT_TOLERANCE`; ``math.inf``: off), or None when there is nothing to check."""
    tolerance = _tolerance(layout, tolerance)
    if tolerance is None or not layout.n_constraints or f"{layout.prefix}_residuals" not in layout.functions:
        return None
    return tolerance


def _tolerance(layout, tolerance) -> float | None:
    if tolerance is None:
        tolerance = DRIFT_TOLERANCE[layout.precision]
    elif isinstance(tolerance, numbers.Real) and not isinstance(tolerance, bool) and math.isinf(tolerance) \
            and tolerance > 0:
        return None
    else:
        tolerance = real_number(tolerance, "drift_tolerance")
        if not tolerance > 0:
            raise ValueError(f"drift_tolerance must be positive, got {tolerance}")
    return tolerance


#: kept samples at most at which a run's configuration is checked (each a Newton solve in C)
CONFIGURATION_SAMPLES = 200


def warn_if_configuration_drifted(layout, trajectory, project_rows, tolerance) -> bool:
    """Warn (`ConstraintDriftWarning`, and return True) when a run of a model with Kane's
    configuration constraints (an eliminated build, whose C ``_project`` solves them for the
    dependent coordinates; ``project_rows(times, states)`` projects copies of the rows of ``states``
    and returns (their statuses, the copies), as `simulate.projected_rows`) ends up, at a kept
    sample, more than ``tolerance`` (as ``drift_tolerance``) from where they put the dependent
    coordinates. Found by review: a Kane four-bar run without projection opened its loop by 4e-6
    with status OK and no word; the eliminated speeds keep A u + b = 0 exactly, but nothing held
    f(q) = 0."""
    tolerance = _tolerance(layout, tolerance)
    if tolerance is None or layout.n_constraints or f"{layout.prefix}_project" not in layout.functions \
            or not len(trajectory.t):
        return False
    samples = np.unique(np.linspace(0, len(trajectory.t) - 1, CONFIGURATION_SAMPLES).astype(int))
    states = np.asarray(trajectory.x)[samples]
    finite = np.all(np.isfinite(states), axis=1)
    if not finite.all():  # the samples up to the first state that is not finite (the run's status speaks of it)
        samples, states = samples[:int(np.argmin(finite))], states[:int(np.argmin(finite))]
    times = np.asarray(trajectory.t)[samples]
    codes, projected = project_rows(times, states)
    off = np.abs(projected[:, :layout.n_q] - states[:, :layout.n_q]).astype(np.float64)
    failing = np.flatnonzero((codes != 0) | ~(off.max(axis=1, initial=0.0) <= tolerance))
    if not failing.size:
        return False
    k = int(failing[0])
    detail = "no configuration near it" if codes[k] != 0 else \
        f"{layout.coordinates[int(np.argmax(off[k]))]} is {off[k].max():.3g} from where they put it"
    warnings.warn(
        f"the run drifted off the configuration constraints: {detail} at t = {times[k]:.6g} "
        f"(drift_tolerance = {tolerance:g}); use project=True (or a smaller h)", ConstraintDriftWarning,
        stacklevel=3)
    return True


def warn_if_drifted(trajectory, tolerance: float, m: int, holonomic: int | None = None) -> bool:
    """Warn (`ConstraintDriftWarning`, and return True) when max |phi| over the kept samples of
    ``trajectory`` (its residuals, phi in the first m columns, A u + dphi/dt in the next m; of
    the rows after the first ``holonomic``, velocity constraints) exceeds ``tolerance``, or when the
    start is off the constraints, |phi| or |A u + dphi/dt| (the next m columns; a velocity
    constraint has no phi, and a run never corrects a start off it: a review found a Chaplygin
    sleigh started with a sideways slip of 0.3 keeping it all run, status OK, no word)."""
    if trajectory.residuals is None or not len(trajectory.t) or not m:
        return False

    def largest(values) -> float:
        values = np.abs(values.astype(np.float64))
        return float(np.where(np.isfinite(values), values, -np.inf).max(initial=-np.inf))

    # the start first: a run started off phi = 0 was blamed on drift (found by review: a pendulum rod
    # of 1 started at 0.6 ran as a rod of 0.6, and the advice was a smaller h)
    position, start = largest(trajectory.residuals[0, :m]), largest(trajectory.residuals[0, m:2 * m])
    if start > tolerance or position > tolerance:
        where = [f"on the positions, max |phi| = {position:.3g}"] * (position > tolerance) + \
            [f"on the velocities, max |A u + dphi/dt| = {start:.3g}"] * (start > tolerance)
        warnings.warn(
            f"the run started off the constraints {' and '.join(where)} at t = {trajectory.t[0]:.6g} "
            f"(drift_tolerance = {tolerance:g}), and held that offset; start from "
            "statics.consistent.consistent_state", ConstraintDriftWarning, stacklevel=3)
        return True
    # then the run: phi, and A u + b of the rows that are velocity constraints (the first ``holonomic``
    # rows are phi's, watched by phi), which alone measures their drift (found by review: a rolling
    # disc with multipliers reached |A u + b| = 7e-6 with no word)
    holonomic = m if holonomic is None else holonomic
    for columns, what in ((slice(0, m), "max |phi|"), (slice(m + holonomic, 2 * m), "max |A u + b|")):
        if columns.start >= columns.stop:
            continue
        values = np.abs(trajectory.residuals[:, columns].astype(np.float64))
        size = np.where(np.isfinite(values), values, -np.inf).max(axis=1)
        k = int(np.argmax(size))
        if size[k] > tolerance:
            warnings.warn(
                f"the run drifted off the constraints: {what} = {size[k]:.3g} at t = {trajectory.t[k]:.6g} "
                f"(drift_tolerance = {tolerance:g}); use project=True, Baumgarte stabilization "
                f"(baumgarte_alpha, baumgarte_beta) or a smaller h", ConstraintDriftWarning, stacklevel=3)
            return True
    return False
