"""Helper: the estimated compile time and memory of a model's kernels, and the warning.

Used by ``pipeline.py`` (which knows the operation counts after CSE) and ``build.py`` (which
knows whether anything has to be compiled); imports no pipeline stage.

gcc at -O3 spends time and memory superlinearly in the size of one straight-line function, and
the large kernels of a big model are exactly that: the Jacobian (implicit methods) and the
momentum map (symplectic Euler) grow like n^2 in operations for an n-link chain. A 40-link
chain with the default methods once took 6 minutes and 2.6 GB in gcc without a word; now
`compile_model` warns (:class:`BuildCostWarning`) before such a build and names the cheaper
options.
"""
from __future__ import annotations

import warnings
from collections.abc import Mapping
from dataclasses import dataclass

from .cache import user_stacklevel

__all__ = ["BuildCost", "BuildCostWarning", "estimate_build_cost", "warn_if_expensive",
           "MAX_SECONDS", "MAX_MEGABYTES"]

#: a build estimated above either limit warns (module constants: tests and users may lower them)
MAX_SECONDS = 30.0
MAX_MEGABYTES = 1000.0

# Calibration (cold `compile_model` builds of `catalog.pendulum_chain(n)`, bodies route, gcc 12
# at -O3 on 2 cores shared with other work, 2026-11-24; ops after CSE of the kernels dynamics /
# jacobian / momentum (energy and points are small); default = the 11 default methods, 4 of
# them implicit; seconds of build_module, peak gcc RSS):
#   n=5  rk4   156 /     - /    -   0.34 s   81 MB   default   156 /   618 /  304    1.08 s   83 MB
#   n=10 rk4   416 /     - /    -   0.47 s   82 MB   default   416 /  2217 / 1105    2.08 s   88 MB
#   n=15 rk4   776 /     - /    -   0.91 s   83 MB   default   776 /  4719 / 2445    5.47 s  161 MB
#   n=20 rk4  1236 /     - /    -   1.10 s   84 MB   default  1236 /  8207 / 4258   13.35 s  345 MB
#   n=25                                             default  1796 / 12677 / 6538   27.07 s  595 MB
#   n=30 rk4  2456 /     - /    -   3.01 s  136 MB   default  2456 / 18125 / 9291   64.24 s  936 MB
# Least squares in log space over these 12 rows gives (ops_k in thousands, over all kernels)
#   seconds = 0.32 + 0.027 * methods + 0.436 * sum_k ops_k ** 1.50
#   MB      = 80 + 4.95 * sum_k ops_k ** 1.69
# within about a third of every row. For n = 40 (ops ~ 4300 / 32200 / 16500) they give ~2 min
# and ~2.5 GB, against the 6 min and 2.6 GB once reported there: time grows faster than the fit
# beyond n = 30, so the estimate errs low there; the warning (30 s) already fires from n = 26.
_SECONDS = (0.32, 0.027, 0.436, 1.504)
_MEGABYTES = (80.0, 4.95, 1.69)


class BuildCostWarning(UserWarning):
    """A model's C build is estimated to take long or need much memory."""


@dataclass(frozen=True)
class BuildCost:
    """Estimated cost of compiling one model's kernels.

    Attributes
    ----------
    model : str
    seconds, megabytes : float
        Estimated wall time of the build and peak compiler memory.
    ops : tuple of (str, int)
        Operations after CSE per kernel, largest first: the inputs of the estimate.
    methods : tuple of str
        Integration schemes compiled in.
    cheaper_seconds, cheaper_megabytes : float
        The same estimate with ``methods=("rk4",)`` and only the kernels RK4 needs.
    """

    model: str
    seconds: float
    megabytes: float
    ops: tuple
    methods: tuple
    cheaper_seconds: float
    cheaper_megabytes: float

    def message(self) -> str:
        kernels = ", ".join(f"{name} {count} ops" for name, count in self.ops)
        return (f"building model {self.model!r} is estimated to take ~{_duration(self.seconds)} and "
                f"~{_size(self.megabytes)} of compiler memory ({len(self.methods)} methods; kernels "
                f"after CSE: {kernels}). Cheaper: fewer methods, e.g. methods=('rk4',) "
                f"(~{_duration(self.cheaper_seconds)}, ~{_size(self.cheaper_megabytes)}), or fewer "
                f"outputs (the jacobian is needed only by implicit methods, the momentum only by "
                f"symplectic_euler)")


#: kernels an explicit method with the default outputs needs (the cheap alternative we suggest)
_EXPLICIT_KERNELS = ("dynamics", "energy", "points")


def estimate_build_cost(model: str, ops: Mapping[str, int], methods) -> BuildCost:
    """Estimate the compile cost from the operation counts after CSE (see the calibration above).

    Parameters
    ----------
    model : str
    ops : mapping kernel name -> int
        ``ReducedKernel.ops_after`` of every kernel in the build.
    methods : sequence of str
        Integration schemes compiled in.

    Examples
    --------
    >>> small = estimate_build_cost("chain", {"dynamics": 416, "energy": 182}, ("rk4",))
    >>> small.seconds < MAX_SECONDS and small.megabytes < MAX_MEGABYTES
    True
    """
    methods = tuple(methods)
    counts = tuple(sorted(((str(k), int(v)) for k, v in ops.items()), key=lambda kv: -kv[1]))
    cheap = {k: v for k, v in counts if k.split(" part ")[0] in _EXPLICIT_KERNELS}
    seconds, megabytes = _estimate(dict(counts), len(methods))
    cheaper_seconds, cheaper_megabytes = _estimate(cheap, 1)
    return BuildCost(model, seconds, megabytes, counts, methods, cheaper_seconds, cheaper_megabytes)


def _estimate(ops: Mapping[str, int], n_methods: int) -> tuple:
    t0, per_method, scale, power = _SECONDS
    m0, m_scale, m_power = _MEGABYTES
    seconds = t0 + per_method * n_methods + scale * sum((v / 1000) ** power for v in ops.values())
    megabytes = m0 + m_scale * sum((v / 1000) ** m_power for v in ops.values())
    return seconds, megabytes


def warn_if_expensive(cost: BuildCost, max_seconds: float | None = None,
                      max_megabytes: float | None = None) -> bool:
    """Warn (:class:`BuildCostWarning`) if ``cost`` passes either limit; return whether it did.

    The limits default to :data:`MAX_SECONDS` and :data:`MAX_MEGABYTES`, read at call time.
    """
    max_seconds = MAX_SECONDS if max_seconds is None else max_seconds
    max_megabytes = MAX_MEGABYTES if max_megabytes is None else max_megabytes
    if cost.seconds <= max_seconds and cost.megabytes <= max_megabytes:
        return False
    warnings.warn(BuildCostWarning(cost.message()), stacklevel=user_stacklevel())
    return True


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 120 else f"{seconds / 60:.0f} min"


def _size(megabytes: float) -> str:
    return f"{megabytes:.0f} MB" if megabytes < 1000 else f"{megabytes / 1000:.1f} GB"
