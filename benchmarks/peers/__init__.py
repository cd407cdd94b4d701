"""Hand-written peers of the benchmarks, compiled on demand with cffi (API mode, out of line).

`load_hand_double_pendulum` builds ``hand_double_pendulum.c`` (exports `HAND_DP_CDEF`) with
lagcodegen's own default flags, so the comparison with generated code is flag for flag;
`build_cffi` is the small cached builder behind it, also used by the benchmark harnesses.
Modules are keyed by the sha256 of everything that changes the binary and kept in
`peer_cache_dir()` (``$LAGCODEGEN_BENCH_CACHE_DIR``, else ``<tmp>/lagcodegen-bench-<uid>``);
each is built in a private temporary directory and installed with ``os.replace``.
"""
from __future__ import annotations

import hashlib
import importlib.util
import os
import shutil
import sys
import sysconfig
import tempfile
from pathlib import Path

HAND_DP_SOURCE = Path(__file__).resolve().with_name("hand_double_pendulum.c")
HAND_DP_CDEF = """\
void hand_dp_rhs(double t, const double *x, const double *p, double *xdot);
void hand_dp_rk4_run(const double *x0, const double *p, double h, long n_steps, double *x_out_final);
"""


def peer_cache_dir() -> Path:
    """Where compiled peers and harnesses are kept (created if missing)."""
    root = os.environ.get("LAGCODEGEN_BENCH_CACHE_DIR")
    uid = os.getuid() if hasattr(os, "getuid") else "user"
    path = Path(root) if root else Path(tempfile.gettempdir()) / f"lagcodegen-bench-{uid}"
    path.mkdir(parents=True, exist_ok=True)
    return path


def default_flags() -> tuple:
    """lagcodegen's compile flags on this machine (``build.DEFAULT_FLAGS`` and the vector
    instruction set's, ``build.host_instruction_set``): peers get exactly the same."""
    from lagcodegen.native.build import DEFAULT_FLAGS, host_instruction_set

    return (*DEFAULT_FLAGS, *host_instruction_set())


def build_cffi(stem: str, cdef: str, source: str, sources=(), include_dirs=(), flags=None):
    """Compile (or fetch) a cffi extension and return its module (``.ffi``, ``.lib``).

    Parameters
    ----------
    stem : str
        Module name prefix; the module is ``<stem>_<key16>``.
    cdef : str
        Declarations visible from Python.
    source : str
        The C text cffi puts in front of its wrapper (``ffibuilder.set_source``).
    sources : sequence of path
        Further C files compiled as separate translation units (no inlining across them).
    include_dirs : sequence of path
    flags : sequence of str, optional
        Default `default_flags()`.
    """
    import cffi

    flags = list(default_flags() if flags is None else flags)
    sources = [Path(s).resolve() for s in sources]
    digest = hashlib.sha256()
    headers = sorted(h for d in include_dirs for h in Path(d).glob("*.h"))
    for part in [cdef, source, " ".join(flags), cffi.__version__, sys.implementation.cache_tag,
                 sysconfig.get_platform(), os.environ.get("CC", "")] + \
            [p.read_text() for p in sources] + [h.read_text() for h in headers]:
        digest.update(part.encode() + b"\0")
    name = f"{stem}_{digest.hexdigest()[:16]}"
    suffix = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
    target = peer_cache_dir() / (name + suffix)
    if not target.is_file():
        tmp = Path(tempfile.mkdtemp(prefix=name + ".", dir=peer_cache_dir()))
        try:
            builder = cffi.FFI()
            builder.cdef(cdef)
            builder.set_source(name, source, sources=[str(s) for s in sources],
                               include_dirs=[str(d) for d in include_dirs], extra_compile_args=flags)
            built = builder.compile(tmpdir=str(tmp), verbose=False)
            os.replace(built, target)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)
    spec = importlib.util.spec_from_file_location(name, target)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_hand_double_pendulum():
    """The hand-written double pendulum as a cffi module: ``lib.hand_dp_rhs(t, x, p, xdot)`` and
    ``lib.hand_dp_rk4_run(x0, p, h, n_steps, x_out_final)`` (x = (q1, q2, u1, u2),
    p = (m1, m2, l1, l2, g))."""
    return build_cffi("_hand_double_pendulum", HAND_DP_CDEF, HAND_DP_CDEF, sources=[HAND_DP_SOURCE])
