"""Stage: Trajectory -> numbers.

Pure functions over trajectories and compiled systems: energy drift, observed order of
convergence, work-precision records (fixed-step methods and scipy's adaptive ones on the same
compiled right-hand side) and measured linear stability limits. `lagcodegen.analysis.figures` draws them.

References: Hairer, Norsett, Wanner, Solving ODEs I (work-precision diagrams, Sec. II.10) and
II (stability domains, Sec. IV.2); Hairer, Lubich, Wanner, Geometric Numerical Integration
(energy behaviour of symplectic methods, Ch. IX).
"""
from __future__ import annotations

import math
import time
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from ..integrators.schemes import get_scheme
from ..native.build import CompiledSystem
from ..run.arguments import positive_int
from ..run.simulate import Trajectory, initial_state, jacobian, make_rhs, parameter_vector, simulate, solve_reference

#: Growth of the energy (or scaled state norm) over a run that counts as "unbounded".
GROWTH_LIMIT = 10.0


# -- energy -----------------------------------------------------------------------------------
def energy_drift(trajectory: Trajectory) -> dict:
    """Energy error of a run: largest deviation, relative deviation and linear drift rate.

    Parameters
    ----------
    trajectory : Trajectory
        Simulated with ``energy=True``; ``t (n_out,)``, ``energy (n_out,)``.

    Returns
    -------
    dict
        ``max_abs``: max |E - E0|; ``max_rel``: max_abs / |E0| (inf when E0 = 0);
        ``rate``: slope dE/dt of the least-squares line through (t, E - E0) (0 for one sample);
        ``final``: E(t_end) - E0; ``e0``: E0.
    """
    if trajectory.energy is None:
        raise ValueError("trajectory has no energy samples; simulate with energy=True")
    if len(trajectory.energy) == 0:
        raise ValueError("trajectory has no samples (an empty slice?): there is no energy drift to measure")
    t = np.asarray(trajectory.t, dtype=np.float64)
    dE = np.asarray(trajectory.energy, dtype=np.float64) - float(trajectory.energy[0])
    e0 = float(trajectory.energy[0])
    max_abs = float(np.max(np.abs(dE)))
    rate = float(np.polyfit(t, dE, 1)[0]) if t.size > 1 else 0.0
    return {"max_abs": max_abs, "max_rel": max_abs / abs(e0) if e0 != 0 else math.inf,
            "rate": rate, "final": float(dE[-1]), "e0": e0}


# -- convergence order ------------------------------------------------------------------------
def observed_order(hs, errors, *, window: tuple[float, float] | None = None) -> float:
    """Slope p of log(error) against log(h) by least squares (error ~ C h^p).

    Parameters
    ----------
    hs, errors : array_like, (k,)
        Step sizes and the matching errors. Non-finite or non-positive errors are skipped.
    window : (lo, hi), optional
        Use only points with ``lo <= error <= hi``: leaves out the pre-asymptotic range (large
        errors) and the round-off / reference floor (tiny errors).

    Returns
    -------
    float
        The slope; nan when fewer than two points remain.
    """
    h, e = np.asarray(hs, dtype=np.float64).ravel(), np.asarray(errors, dtype=np.float64).ravel()
    if h.shape != e.shape:
        raise ValueError(f"hs and errors need the same length, got {h.size} and {e.size}")
    keep = np.isfinite(e) & (e > 0) & np.isfinite(h) & (h > 0)
    if window is not None:
        lo, hi = window
        keep &= (e >= lo) & (e <= hi)
    if np.count_nonzero(keep) < 2 or np.unique(h[keep]).size < 2:
        return math.nan
    return float(np.polyfit(np.log(h[keep]), np.log(e[keep]), 1)[0])


# -- work-precision ---------------------------------------------------------------------------
@dataclass(frozen=True)
class WorkRecord:
    """One point of a work-precision diagram.

    Attributes
    ----------
    method : str
        A lagcodegen scheme name, or ``"scipy:<method>"`` for ``solve_ivp``.
    h : float or None
        Fixed step (None for adaptive scipy runs).
    tolerance : float or None
        ``rtol = atol`` of an adaptive scipy run (None for fixed-step runs).
    n_steps : int or None
        Fixed steps taken (None for scipy runs).
    nfev : int or None
        Right-hand-side calls of a scipy run (None for fixed-step runs).
    error : float
        Max-norm of x(t_end) - reference over the 2n state entries; inf when the run failed.
    seconds : float
        Wall time, best of the repeats (`time.perf_counter` around the whole call; found by review:
        this was called CPU time).
    ok : bool
        The run completed (status OK / scipy success).
    """

    method: str
    h: float | None
    tolerance: float | None
    n_steps: int | None
    nfev: int | None
    error: float
    seconds: float
    ok: bool


def reference_state(system: CompiledSystem, x0, t_end: float, *, params: Mapping | None = None) -> np.ndarray:
    """x(t_end), (2n,), by DOP853 at rtol = atol = 1e-12 (`simulate.solve_reference`)."""
    _, x = solve_reference(system, x0, [float(t_end)], params=params, rtol=1e-12, atol=1e-12)
    return x[-1]


def _best_time(call, repeats: int, min_seconds: float = 0.02):
    """Fastest of at least ``repeats`` calls, repeated (up to 1000 times) until ``min_seconds``
    have been spent, so that runs of tens of microseconds get enough samples to beat the noise."""
    best, result, spent, count = math.inf, None, 0.0, 0
    while count < max(1, int(repeats)) or (spent < min_seconds and count < 1000):
        start = time.perf_counter()
        result = call()
        elapsed = time.perf_counter() - start
        best, spent, count = min(best, elapsed), spent + elapsed, count + 1
    return best, result


def work_precision(system: CompiledSystem, x0, t_end: float, methods: Sequence[str], steps: Sequence[int], *,
                   params: Mapping | None = None, reference=None, repeats: int = 3) -> list[WorkRecord]:
    """Final error and wall time of fixed-step runs, one record per (method, step count).

    Parameters
    ----------
    system : CompiledSystem
        Double precision, with ``methods`` compiled in.
    x0 : sequence (2n,) or mapping
    t_end : float
        Runs go from t = 0 to t_end.
    methods : sequence of str
    steps : sequence of int
        Numbers of steps n; the step is h = t_end / n.
    params : mapping, optional
        Free parameter values (model defaults otherwise).
    reference : array_like (2n,), optional
        x(t_end); default `reference_state` (DOP853, rtol = atol = 1e-12).
    repeats : int
        Each run is timed at least ``repeats`` times (more while under 20 ms in total); the
        fastest counts (least disturbed by the OS).

    Returns
    -------
    list of WorkRecord
        In the order methods x steps. A diverged run has ``ok=False`` and ``error=inf``.
    """
    steps = [positive_int(n, f"steps[{i}]") for i, n in enumerate(steps)]
    x_ref = reference_state(system, x0, t_end, params=params) if reference is None else np.asarray(reference)
    x = initial_state(system, x0)
    records = []
    for method in methods:
        for n in steps:
            h = float(t_end) / n
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", RuntimeWarning)  # a diverged run is a data point
                seconds, traj = _best_time(lambda: simulate(system, x, t_end, h, method, params=params,
                                                            stride=n, check_stability=False), repeats)
            error = float(np.max(np.abs(traj.x[-1] - x_ref))) if traj.ok else math.inf
            records.append(WorkRecord(method, h, None, n, None, error if math.isfinite(error) else math.inf,
                                      seconds, traj.ok and math.isfinite(error)))
    return records


def scipy_work_precision(system: CompiledSystem, x0, t_end: float, methods=("RK45", "DOP853", "Radau"),
                         tolerances=(1e-3, 1e-5, 1e-7, 1e-9, 1e-11), *, params: Mapping | None = None,
                         reference=None, repeats: int = 3) -> list[WorkRecord]:
    """Reference curves: scipy ``solve_ivp`` (adaptive) on the same compiled rhs.

    ``make_rhs`` wraps the compiled C rhs; Radau, BDF and LSODA also get the compiled analytic
    Jacobian (`simulate.jacobian`). Each call asks only for x(t_end) (``t_eval=[t_end]``), so
    the time is stepping plus scipy's per-step Python overhead, which dominates for small systems.

    Parameters
    ----------
    tolerances : sequence of float
        ``rtol = atol`` per run.
    Others as in `work_precision`.

    Returns
    -------
    list of WorkRecord
        ``method = "scipy:<name>"``, ``h = None``, ``tolerance`` set.
    """
    from scipy.integrate import solve_ivp

    x_ref = reference_state(system, x0, t_end, params=params) if reference is None else np.asarray(reference)
    x = initial_state(system, x0)
    rhs = make_rhs(system, params)
    p = parameter_vector(system, params)
    records = []
    for method in methods:
        kwargs = {}
        if method in ("Radau", "BDF", "LSODA"):
            kwargs["jac"] = lambda t, y: jacobian(system, y, p, t)
        for tol in tolerances:
            call = lambda: solve_ivp(rhs, (0.0, float(t_end)), x, method=method, t_eval=[float(t_end)],  # noqa: E731
                                     rtol=tol, atol=tol, **kwargs)
            seconds, sol = _best_time(call, repeats)
            error = float(np.max(np.abs(sol.y[:, -1] - x_ref))) if sol.success else math.inf
            records.append(WorkRecord(f"scipy:{method}", None, float(tol), None, int(sol.nfev), error,
                                      seconds, bool(sol.success)))
    return records


# -- stability --------------------------------------------------------------------------------
def theoretical_stability_limit(method: str) -> float:
    """Largest h*w on the imaginary axis with |R(i h w)| <= 1 (undamped oscillator bound).

    From the tableau's stability polynomial (`ButcherTableau.imag_stability_limit`); symplectic
    Euler 2; inf for the implicit (A-stable) methods. Explicit Euler and Heun: 0.
    """
    return float(get_scheme(method).imag_stability_limit())


def _growth(traj: Trajectory, w: float, n_q: int) -> float:
    """Growth over a run: max over its last quarter / max over its first quarter of the energy,
    else (no energy kernel, or E0 <= 0) of the scaled state norm |(w q, u)|.

    Comparing the two ends, rather than the maximum with E0, separates growth from a bounded
    oscillation of the energy: symplectic Euler's energy swings by (2 + h w) / (2 - h w) on
    an oscillator although the run is stable for h w < 2.
    """
    if traj.energy is not None and traj.energy[0] > 0:
        size = np.abs(np.asarray(traj.energy, dtype=np.float64))
    else:
        x = np.asarray(traj.x, dtype=np.float64)
        size = np.linalg.norm(np.hstack([w * x[:, :n_q], x[:, n_q:]]), axis=1)  # constant for one mode
    quarter = max(1, size.size // 4)
    start = float(np.max(size[:quarter]))
    return float(np.max(size[-quarter:]) / start) if start > 0 else math.inf


def _is_bounded(system, method, x, w, hw, params, steps) -> bool:
    h = hw / w
    with_energy = f"{system.layout.prefix}_energy" in system.layout.functions
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # divergence is what we are looking for
        traj = simulate(system, x, steps * h, h, method, params=params, energy=with_energy,
                        check_stability=False)
    return traj.ok and _growth(traj, w, system.layout.n_q) <= GROWTH_LIMIT


def measured_stability_limit(system: CompiledSystem, method: str, x0, w: float, *, params: Mapping | None = None,
                             steps: int = 2000, lo: float = 1e-3, hi: float = 1e3, grid: int = 49,
                             rtol: float = 1e-4) -> float:
    """Largest h*w for which a run stays bounded, found by a scan and bisection.

    "Bounded": the run of ``steps`` steps completes (status OK) and its energy does not grow
    more than `GROWTH_LIMIT` (10) times (largest value over the last quarter of the run against
    the first quarter); without an energy kernel (or E0 <= 0), the scaled state norm
    |(w q, u)| is used instead. Meant for an undamped system excited in its fastest mode
    (the stiff chain: `catalog.stiff_chain`, x0 stretching the stiff spring), where it measures
    the imaginary-axis limit of the method's stability region. It is a finite-time test: a
    method whose |R(i h w)| exceeds 1 only slightly (Euler, Heun, dopri5 just past its limit)
    passes until the growth over ``steps`` steps reaches 10x, so its measured limit lies above
    the theoretical one and falls towards it as ``steps`` grows.

    Parameters
    ----------
    system : CompiledSystem
    method : str
    x0 : sequence (2n,) or mapping
    w : float
        The fastest angular frequency (rad/s) of the system, e.g. the largest |eigenvalue| of
        the Jacobian; h = (h w) / w.
    params : mapping, optional
    steps : int
        Steps per trial run.
    lo, hi : float
        Search range of h*w. The scan walks a geometric grid of ``grid`` points from lo to hi
        and stops at the first unbounded run; bisection (geometric) then narrows the edge to a
        relative width ``rtol``. The first instability is reported, so the limit is that of
        the interval [0, limit] of stable h*w.

    Returns
    -------
    float
        The largest h*w found bounded; ``inf`` when bounded even at ``hi`` (no limit found up to
        hi: implicit A-stable methods); ``0.0`` when unbounded already at ``lo``.
    """
    if not (w > 0 and math.isfinite(w)):
        raise ValueError(f"frequency w must be positive and finite, got {w}")
    if not 0 < lo < hi:
        raise ValueError(f"need 0 < lo < hi, got lo = {lo}, hi = {hi}")
    x = initial_state(system, x0)
    bounded = lambda hw: _is_bounded(system, method, x, w, hw, params, steps)  # noqa: E731
    trials = np.geomspace(lo, hi, grid)
    first_bad = next((i for i, hw in enumerate(trials) if not bounded(hw)), None)
    if first_bad is None:
        return math.inf
    if first_bad == 0:
        return 0.0
    good, bad = float(trials[first_bad - 1]), float(trials[first_bad])
    while bad / good > 1 + rtol:
        mid = math.sqrt(good * bad)
        good, bad = (mid, bad) if bounded(mid) else (good, mid)
    return good
