"""Helper: the vector instruction set of the machine that builds the kernels, which is also the
machine that runs them (a module in the cache is keyed by its flags, and a pickled module
checks on unpickling that it can run where it lands).

On x86-64 a kernel built with ``-mavx2`` (or ``-mavx``) writes its scalar arithmetic in the
three-operand VEX forms, which saves the register copies of the two-operand SSE2 forms, and its
lane loops in 256-bit vectors. Measured on the Whipple bicycle's RK4 step (a 2-core AMD EPYC,
2026-11-27, best of 300 runs of 2000 steps per round; docs/benchmarks.txt): most rounds 2630-2770
ns with the baseline flags, 2060-2180 ns with -mavx2, the same state to the last bit. The results
do not change: -mavx2 does not imply -mfma, so no multiply-add is fused, and without -ffast-math
nothing is reassociated.

``LAGCODEGEN_PORTABLE`` set to anything but empty or 0 builds for the baseline instruction set
(for modules that other machines of the same cache should share). The FMU export never uses these
flags: its binaries are handed on.
"""
from __future__ import annotations

import functools
import os
import platform
import subprocess
from pathlib import Path

__all__ = ["host_flags", "missing_features", "selects_instructions", "this_cpu", "VECTOR_EXTENSIONS"]

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


#: a loop the compiler turns into 256-bit instructions under the flag, so that the assembler is
#: asked too (found by review: an assembler older than the compiler passed a preprocessor-only probe)
_PROBE = "void lcg_probe(double *a) { int i; for (i = 0; i < 64; ++i) a[i] = a[i] * 2.0 + 1.0; }\n"


@functools.cache
def _compiler_accepts(command: tuple[str, ...], flag: str) -> bool:
    try:
        run = subprocess.run([*command, flag, "-O3", "-x", "c", "-c", "-", "-o", os.devnull], input=_PROBE.encode(),
                             capture_output=True, timeout=60)
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


def selects_instructions(flags) -> bool:
    """True if ``flags`` (a caller's extra compile flags) choose the instructions beyond what
    `host_flags` does: -march=, -mcpu=, or an -m flag of an instruction-set extension (-mfma,
    -mavx512f, ...); the module then runs only on a CPU with the building machine's features."""
    return any(f.startswith(("-march=", "-mcpu=")) or
               (f.startswith("-m") and f[2:].split("=")[0] in _EXTENSION_FLAGS) for f in flags)


def missing_features(flags, features: frozenset | None = None, built_on: frozenset = frozenset()) -> list[str]:
    """The CPU features that a module built with ``flags`` needs and this CPU (``features``,
    default this machine's) lacks: those of its vector flag, and all of ``built_on`` (the building
    machine's, recorded when the caller's flags chose instructions: `selects_instructions`)."""
    features = _this_cpu() if features is None else features
    lacking = [feature for feature, flag in VECTOR_EXTENSIONS if flag in flags and feature not in features]
    return lacking + sorted(f for f in built_on - features if f not in lacking)


def this_cpu() -> frozenset:
    """This machine's CPU features (`cpu_features`), read once per process."""
    return _this_cpu()


#: -m<name> flags of gcc and clang that enable an x86 instruction-set extension
_EXTENSION_FLAGS = frozenset(
    "sse3 ssse3 sse4 sse4.1 sse4.2 sse4a avx avx2 fma fma4 f16c bmi bmi2 lzcnt popcnt movbe aes pclmul "
    "sha xop avx512f avx512cd avx512bw avx512dq avx512vl avx512vnni avx512ifma avx512vbmi avxvnni "
    "amx-tile amx-int8 amx-bf16 avx512fp16 avx512bf16".split())
