"""Helper: the vector instruction set of the machine that builds the kernels, which is also the
machine that runs them (a module in the cache is keyed by its flags, and a pickled module
checks on unpickling that it can run where it lands).

On x86-64 a kernel built with ``-mavx2`` (or ``-mavx``) writes its scalar arithmetic in the
three-operand VEX forms, which saves the register copies of the two-operand SSE2 forms, and its
lane loops in 256-bit vectors. Measured on the Whipple bicycle's RK4 step (a 2-core AMD EPYC,
2026-11-27, best of 300 runs of 2000 steps): 2630-2720 ns with the baseline flags, 2080-2180 ns
with -mavx2, the same state to the last bit. The results do not change: -mavx2 does not imply
-mfma, so no multiply-add is fused, and without -ffast-math nothing is reassociated.

``LAGCODEGEN_PORTABLE=1`` builds for the baseline instruction set (for a cache copied to older
machines). The FMU export never uses these flags: its binaries are handed on.
"""
from __future__ import annotations

import functools
import os
import platform
import subprocess
from pathlib import Path

__all__ = ["host_flags", "missing_features", "VECTOR_EXTENSIONS"]

#: (CPU feature as /proc/cpuinfo names it, compiler flag), best first
VECTOR_EXTENSIONS = (("avx2", "-mavx2"), ("avx", "-mavx"))
PORTABLE_ENV = "LAGCODEGEN_PORTABLE"
_X86_64 = ("x86_64", "amd64")


def cpu_features(cpuinfo: str | None = None) -> frozenset:
    """The feature names of this machine's CPU (Linux: the flags of /proc/cpuinfo, which lists AVX
    only where the kernel saves its registers); empty where they cannot be read."""
    if cpuinfo is None:
        try:
            cpuinfo = Path("/proc/cpuinfo").read_text(encoding="ascii", errors="replace")
        except OSError:
            return frozenset()
    for line in cpuinfo.splitlines():
        name, _, value = line.partition(":")
        if name.strip() == "flags":
            return frozenset(value.split())
    return frozenset()


@functools.cache
def _this_cpu() -> frozenset:
    return cpu_features()


def _portable() -> bool:
    return os.environ.get(PORTABLE_ENV, "").strip() not in ("", "0")


@functools.cache
def _compiler_accepts(command: tuple[str, ...], flag: str) -> bool:
    try:
        run = subprocess.run([*command, flag, "-E", "-x", "c", os.devnull], capture_output=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired):
        return False
    return run.returncode == 0


def host_flags(command: tuple[str, ...], features: frozenset | None = None) -> tuple[str, ...]:
    """The flag of the best vector extension this CPU has (``features``, default this machine's)
    and the compiler ``command`` accepts; () on other architectures, where the CPU cannot be read,
    or with ``LAGCODEGEN_PORTABLE`` set."""
    if _portable() or platform.machine().lower() not in _X86_64:
        return ()
    features = _this_cpu() if features is None else features
    for feature, flag in VECTOR_EXTENSIONS:
        if feature in features and _compiler_accepts(tuple(command), flag):
            return (flag,)
    return ()


def missing_features(flags, features: frozenset | None = None) -> list[str]:
    """The CPU features that ``flags`` (a module's build flags) need and this CPU (``features``,
    default this machine's) lacks."""
    features = _this_cpu() if features is None else features
    return [feature for feature, flag in VECTOR_EXTENSIONS if flag in flags and feature not in features]
