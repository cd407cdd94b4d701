"""Stage: CSources -> CompiledSystem (cffi API mode, out of line, cached on disk).

``build_module`` writes the generated ``.h``/``.c`` into a private directory inside the
cache dir, compiles them with ``ffibuilder.compile`` together with cffi's wrapper, and
installs the directory with one ``os.replace`` (see ``cache.py``). The key covers
everything that changes the binary: C text, cdef, flags, compiler, Python, cffi and
lagcodegen versions, like cffi's ``Verifier`` and numba's index key. Every load of an entry,
in this process or in a worker that unpickles a `CompiledSystem`, first checks the entry's
recorded sha256 sums (``cache.entry_problem``): a tampered ``.so`` is rebuilt, never opened.
A cache dir that cannot take the build (read-only, full) gives way to a temporary one with a
warning (``cache.fallback_dir``); a build estimated to be expensive warns first (``build_cost``).
"""
from __future__ import annotations

import contextlib
import functools
import importlib.util
import os
import re
import shlex
import shutil
import subprocess
import sys
import sysconfig
import threading
import time
import types
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import cffi

from .. import __version__
from ..codegen.printer import mangle
from ..codegen.render import CSources, KernelLayout
from . import cache
from .build_cost import BuildCost, warn_if_expensive
from .compiler import (
    KERNEL_FLAGS,
    BuildError,
    check_python_headers,
    compile_error,
    compile_in_parallel,
    start_kernel_compile,
    stop,
)
from .instruction_set import host_flags, missing_features, selects_instructions, this_cpu

__all__ = ["BuildError", "CompiledSystem", "build_module", "compiler_available", "host_instruction_set",
           "DEFAULT_FLAGS"]

# A cdef naming a function the header does not declare fails to compile (with gcc's message)
# instead of producing a module that cannot be imported.
# -O3 unrolls the stage loops; -fno-math-errno lets gcc fuse sin and cos of one angle into sincos
# (the kernels never read errno, and IEEE results are unchanged)
# -ffp-contract=off: no multiply-add is fused where the target has FMA (clang's default is "on", gcc's
# is off in ISO C mode), so -march=native or a later -mfma leaves the numbers as they are
DEFAULT_FLAGS = ("-O3", "-std=c99", "-fno-math-errno", "-ffp-contract=off", "-Werror=implicit-function-declaration")
#: after the caller's flags: the statuses rest on isfinite() and x != x, which -ffinite-math-only
#: (part of -ffast-math) compiles away, and a NaN state would then end a run with status OK
IEEE_FLAGS = ("-fno-finite-math-only",)
_INSTALL_HINT = ("install gcc, e.g. apt-get install gcc / build-essential, "
                 "or set CC to a working C compiler")
_EXT_SUFFIX = sysconfig.get_config_var("EXT_SUFFIX") or ".so"
_FILE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
_LOCK = threading.RLock()  # one build at a time per process: cffi chdirs while compiling
_MEMO: dict[tuple[str, str], tuple[Any, Any, Path, float | None]] = {}  # (cache dir, key) -> (ffi, lib, .so, build s)
_LOADED: dict[str, types.ModuleType] = {}  # .so path -> module: checked and imported once per process


@dataclass(frozen=True)
class CompiledSystem:
    """A loaded kernel module: cffi ``ffi`` and ``lib``, and where it came from.

    Pickles as (key, path, module name, layout); unpickling re-imports the ``.so`` from
    ``path`` (once per process), so worker processes get a usable ``lib``.
    """

    ffi: Any = field(repr=False, compare=False)
    lib: Any = field(repr=False, compare=False)
    key: str
    path: Path
    module_name: str
    layout: KernelLayout
    sources: CSources | None = field(default=None, repr=False, compare=False)
    #: (sources, cache_dir, extra_compile_args) of the same model with the lane sweep kernel,
    #: built on first use by `lane_variant` (it doubles the compile time, and only sweeps need it)
    lane_build: tuple | None = field(default=None, repr=False, compare=False)
    #: seconds this process spent compiling the module (None: loaded from the cache) and the
    #: estimate made before (``build_cost.estimate_build_cost``; None when not given)
    build_seconds: float | None = field(default=None, repr=False, compare=False)
    cost: BuildCost | None = field(default=None, repr=False, compare=False)
    #: the flags of the building machine's vector instruction set (`instruction_set.host_flags`)
    instruction_set: tuple = field(default=(), repr=False, compare=False)
    #: the building machine's CPU features when the caller's flags chose instructions (-march=native,
    #: -mfma, ...): a process on a CPU without all of them builds the module again instead of opening it
    built_on: frozenset = field(default=frozenset(), repr=False, compare=False)

    def report(self) -> str:
        """What was built and how: the formulation (trees: which one and the operation estimate
        that chose it), the C source size, the estimated and the measured compile time."""
        layout = self.layout
        lines = [f"model {layout.model!r}: {len(layout.coordinates)} coordinates, "
                 f"{len(layout.functions)} C functions, methods {', '.join(layout.methods) or 'none'}"]
        if layout.formulation:
            lines.append(f"formulation: {layout.formulation}")
        if self.sources is not None:
            lines.append(f"C source: {len(self.sources.source)} bytes ({self.sources.source_name})")
        if self.built_on:
            lines.append("built for the CPU of the machine that built it (its compile flags chose the instructions)")
        else:
            lines.append(f"built for {' '.join(self.instruction_set)}" if self.instruction_set
                         else "built for the baseline instruction set")
        if self.cost is not None:
            ops = sum(count for _, count in self.cost.ops)
            lines.append(f"estimated build: {self.cost.seconds:.1f} s, {self.cost.megabytes:.0f} MB of compiler "
                         f"memory ({ops} operations after CSE)")
        lines.append(f"compiled in {self.build_seconds:.2f} s" if self.build_seconds is not None
                     else f"loaded from the cache ({self.path})")
        return "\n".join(lines)

    def __reduce__(self):
        return (_restore, (self.key, str(self.path), self.module_name, self.layout, self.sources, self.lane_build,
                           self.instruction_set, self.built_on))

    def lane_variant(self) -> CompiledSystem | None:
        """The same model built with the lane sweep kernel (compiled once, then cached), or None;
        for the instruction set this module was built for (found by review: it followed
        ``LAGCODEGEN_PORTABLE`` at the first sweep instead)."""
        if self.lane_build is None:
            return None
        # kept on this object (found by review: keying the lane source again took 0.6-0.9 ms per sweep); not
        # by the module's key, which two lane_trig choices of one scalar module share; the pickle drops it
        variant = self.__dict__.get("_lane_variant")
        if variant is None:
            sources, cache_dir, extra_compile_args = self.lane_build
            variant = build_module(sources, cache_dir=cache_dir, extra_compile_args=extra_compile_args,
                                   instruction_set=self.instruction_set)
            self.__dict__["_lane_variant"] = variant  # frozen dataclass: as functools.cached_property stores
        return variant


def _restore(key: str, path: str, module_name: str, layout: KernelLayout,
             sources: CSources | None = None, lane_build: tuple | None = None,
             instruction_set: tuple = (), built_on: frozenset = frozenset()) -> CompiledSystem:
    so = Path(path)
    problem = None if path in _LOADED else cache.entry_problem(so.parent, key, so.name)
    lacking = missing_features(instruction_set, built_on=built_on)
    if lacking and problem is None:
        # a worker whose CPU lacks what the module was built for (a shared cache on a mixed cluster):
        # opening it would end the process on an illegal instruction
        built_for = " ".join(instruction_set) or "the instructions its compile flags chose"
        problem = f"built for {built_for}, and this CPU has no {', '.join(lacking)}"
    if problem is not None:
        # another machine (a Dask worker), or a damaged entry: build again (with the default
        # flags: the pickle does not carry extra ones) or say why not
        if sources is not None:
            return replace(build_module(sources), lane_build=lane_build)
        state = "no longer exists" if problem == "missing" else f"cannot be loaded (entry: {problem})"
        raise BuildError(f"compiled module {path} of model {layout.model!r} {state}; call build_module again")
    module = _import(path, module_name)
    return CompiledSystem(module.ffi, module.lib, key, so, module_name, layout, sources, lane_build,
                          instruction_set=instruction_set, built_on=built_on)


def _import(path: str, module_name: str) -> types.ModuleType:
    """Import the extension at ``path`` (never via sys.path or the current directory), once per
    process. Callers check the entry (``cache.entry_problem``) before the first import."""
    if path not in _LOADED:
        spec = importlib.util.spec_from_file_location(module_name, path)
        if spec is None or spec.loader is None:
            raise ImportError(f"{path} is not an importable extension module")
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        _LOADED[path] = module
    return _LOADED[path]


def _compiler_command(compiler: str | None) -> list[str]:
    text = compiler or os.environ.get("CC") or sysconfig.get_config_var("CC") or "cc"
    return shlex.split(text)


@functools.cache
def _compiler_identity(command: tuple[str, ...]) -> str:
    """``<command>: <first line of --version>``; BuildError with an install hint if it cannot run."""
    shown = shlex.join(command)
    try:
        run = subprocess.run([*command, "--version"], capture_output=True, text=True, timeout=60)
    except (OSError, subprocess.TimeoutExpired) as exc:
        raise BuildError(f"no working C compiler: `{shown}` could not be run ({exc}); "
                         f"{_INSTALL_HINT}", command=shown) from None
    lines = (run.stdout or run.stderr).strip().splitlines()
    if run.returncode != 0 or not lines:
        raise BuildError(f"no working C compiler: `{shown} --version` failed; {_INSTALL_HINT}",
                         command=shown, stderr=run.stderr)
    return f"{shown}: {lines[0]}"


def host_instruction_set(compiler: str | None = None) -> tuple[str, ...]:
    """The vector instruction-set flags `build_module` adds on this machine for ``compiler``
    (default ``$CC``, else Python's): ``instruction_set.host_flags``."""
    return host_flags(tuple(_compiler_command(compiler)))


def compiler_available(compiler: str | None = None) -> bool:
    """True if the C compiler runs and Python's headers (``Python.h``) are installed."""
    try:
        _compiler_identity(tuple(_compiler_command(compiler)))
    except BuildError:
        return False
    return (Path(sysconfig.get_paths()["include"]) / "Python.h").is_file()


@contextlib.contextmanager
def _compiler_env(compiler: str | None):
    """distutils reads the compiler from ``$CC``; set it for the duration of one build."""
    if compiler is None:
        yield
        return
    saved = os.environ.get("CC")
    os.environ["CC"] = compiler
    try:
        yield
    finally:
        if saved is None:
            os.environ.pop("CC", None)
        else:
            os.environ["CC"] = saved


def _check_names(sources: CSources, module_name: str) -> None:
    for attr, ext in (("header_name", ".h"), ("source_name", ".c")):
        name = getattr(sources, attr)
        if not _FILE_NAME.fullmatch(name) or not name.endswith(ext) or name == module_name + ".c":
            raise BuildError(f"CSources.{attr} {name!r} must be a plain file name ending in {ext}")


def _key(sources: CSources, flags: list[str], identity: str, built_on: frozenset = frozenset()) -> str:
    return cache.source_key({
        **({"cpu": " ".join(sorted(built_on))} if built_on else {}),
        "header_name": sources.header_name, "header": sources.header,
        "source_name": sources.source_name, "source": sources.source, "cdef": sources.cdef,
        "flags": shlex.join(flags), "kernel_flags": shlex.join(KERNEL_FLAGS), "compiler": identity,
        "python": f"{sys.implementation.cache_tag}-{sysconfig.get_platform()}{_EXT_SUFFIX}",
        "cffi": cffi.__version__, "lagcodegen": __version__,
    })


@dataclass(frozen=True)
class _Job:
    """One build request: what `_fetch` and `_compile_entry` need besides the cache root."""

    sources: CSources
    key: str
    module_name: str
    flags: tuple
    command: tuple
    compiler: str | None
    cost: BuildCost | None

    @property
    def so_name(self) -> str:
        return self.module_name + _EXT_SUFFIX


def build_module(sources: CSources, *, cache_dir=None, extra_compile_args=(), compiler=None,
                 cost: BuildCost | None = None, instruction_set: tuple | None = None) -> CompiledSystem:
    """Compile (or fetch from the cache) and load the C kernels of one model.

    Parameters
    ----------
    sources : CSources
        Output of ``render.render_sources``.
    cache_dir : path, optional
        Overrides ``$LAGCODEGEN_CACHE_DIR`` and the user cache dir.
    extra_compile_args : sequence of str
        Appended to :data:`DEFAULT_FLAGS` and the flag of this machine's vector instruction set
        (``instruction_set.host_flags``: -mavx2 where the CPU has AVX2; none with
        ``LAGCODEGEN_PORTABLE=1``), then :data:`IEEE_FLAGS` (so -ffast-math keeps the non-finite
        checks); all part of the key.
    compiler : str, optional
        Compiler command (default ``$CC``, else Python's configured compiler); part of the key.
    cost : BuildCost, optional
        Estimated compile cost (``build_cost.estimate_build_cost``); when the module has to be
        compiled and the estimate is high, a ``BuildCostWarning`` says so first.
    instruction_set : tuple of str, optional
        The vector instruction-set flags (default: this machine's, ``host_instruction_set``); a
        flag this CPU cannot run is dropped for this machine's.

    Raises
    ------
    BuildError
        No compiler, no Python headers, or the C does not compile: the message holds the
        compiler's errors and the path of the kept ``.c``.
    cache.CacheDirError
        ``cache_dir`` was given and cannot be used. Without it, an unusable cache dir gives way
        to a temporary one, with a ``cache.CacheDirWarning``.
    """
    command = tuple(_compiler_command(compiler))
    if instruction_set is None or missing_features(instruction_set):
        instruction_set = host_flags(command)
    instruction_set = tuple(instruction_set)
    flags = (*DEFAULT_FLAGS, *instruction_set, *extra_compile_args, *IEEE_FLAGS)
    # -march=native and the like: what the module runs on is the building machine's CPU, so it is
    # part of the key (a shared cache), and of the pickle (`_restore`)
    built_on = this_cpu() if selects_instructions(extra_compile_args) else frozenset()
    key = _key(sources, list(flags), _compiler_identity(command), built_on)
    # bounded: the module name is also a file name and a C identifier (PyInit_<name>)
    module_name = f"_lcg_{mangle(sources.layout.model, max_len=40)}_{key[:16]}"
    _check_names(sources, module_name)
    job = _Job(sources, key, module_name, flags, command, compiler, cost)
    with _LOCK:
        root = cache.cache_dir(cache_dir)
        if (str(root), key) not in _MEMO:
            try:
                _MEMO[str(root), key] = _fetch(job, root)
            except OSError as exc:
                if not cache.unwritable(exc):
                    raise
                root = _fallback(root, exc, cache_dir, module_name)
                if (str(root), key) not in _MEMO:
                    _MEMO[str(root), key] = _fetch(job, root)
        ffi, lib, so_path, seconds = _MEMO[str(root), key]
    return CompiledSystem(ffi, lib, key, so_path, module_name, sources.layout, sources,
                          build_seconds=seconds, cost=cost, instruction_set=instruction_set, built_on=built_on)


def _fallback(root: Path, exc: OSError, explicit, module_name: str) -> Path:
    """The temporary cache dir after ``root`` could not take a build (``exc``)."""
    problem = f"cannot take the build of {module_name} ({exc.strerror or exc}: {exc.filename})"
    if explicit is not None:
        raise cache.CacheDirError(f"cache directory {root} (the cache_dir argument) {problem}; "
                                  "pass a writable directory") from exc
    return cache.fallback_dir(root, problem)


def _fetch(job: _Job, root: Path):
    """Load the entry for ``job.key``, building it if missing or corrupt; (ffi, lib, .so path,
    seconds spent compiling or None)."""
    entry, so_name = root / job.module_name, job.so_name
    seconds = None
    for attempt in range(2):
        problem = None if str(entry / so_name) in _LOADED else cache.entry_problem(entry, job.key, so_name)
        if problem is not None:
            if problem != "missing":
                cache.evict_entry(entry)
            if job.cost is not None:
                warn_if_expensive(job.cost)
            start = time.perf_counter()
            _compile_entry(job, root, entry)
            seconds = time.perf_counter() - start
        try:
            module = _import(str(entry / so_name), job.module_name)
            return module.ffi, module.lib, entry / so_name, seconds
        except ImportError as exc:  # e.g. a corrupt .so whose checksum was rewritten
            if attempt == 1 or problem is not None:
                kept = cache.keep_failed(entry, root, job.module_name)
                raise BuildError(f"built module {job.module_name} cannot be imported: {exc}\n"
                                 f"kept sources: {kept / job.sources.source_name}",
                                 c_path=kept / job.sources.source_name) from None
            cache.evict_entry(entry)
    raise AssertionError("unreachable")


def _compile_entry(job: _Job, root: Path, entry: Path) -> None:
    """Build in a private directory, then install it as ``entry`` (or keep it on failure)."""
    sources, module_name, so_name = job.sources, job.module_name, job.so_name
    check_python_headers(sources)
    tmp, kept = cache.new_build_dir(root, module_name), None
    try:
        (tmp / sources.header_name).write_text(sources.header, encoding="utf-8")
        (tmp / sources.source_name).write_text(sources.source, encoding="utf-8")
        kernels = start_kernel_compile(tmp, sources, job.flags, job.command) if os.name == "posix" else None
        try:
            ffibuilder = cffi.FFI()
            ffibuilder.cdef(sources.cdef)
            ffibuilder.set_source(module_name, f'#include "{sources.header_name}"',
                                  sources=[str(tmp / sources.source_name)], include_dirs=[str(tmp)],
                                  extra_compile_args=list(job.flags))
        except BaseException:
            if kernels is not None:
                stop(kernels)
            raise
        if kernels is not None:
            built = compile_in_parallel(ffibuilder, tmp, kernels, module_name, job.flags, job.command, so_name)
        else:
            with _compiler_env(job.compiler):
                built = Path(ffibuilder.compile(tmpdir=str(tmp), verbose=False))
        if not built.is_file():  # found by review: CC=true "built" nothing, then a bare FileNotFoundError
            raise BuildError(f"the C compiler {shlex.join(job.command)} reported success for model "
                             f"{sources.layout.model!r} but wrote no {built.name}; set CC to a working C compiler")
        if built != tmp / so_name:
            os.replace(built, tmp / so_name)
        for item in tmp.iterdir():  # drop object files and distutils' build tree
            if item.is_dir():
                shutil.rmtree(item)
            elif item.suffix in (".o", ".obj"):
                item.unlink()
        cache.write_marker(tmp, job.key, so_name)
        cache.install_entry(tmp, entry)
    except (cffi.CDefError, cffi.FFIError, cffi.VerificationError) as exc:
        kept = cache.keep_failed(tmp, root, module_name)
        raise compile_error(sources, kept, module_name, job.flags, job.command, exc) from None
    finally:
        if kept is None and tmp.exists():
            shutil.rmtree(tmp, ignore_errors=True)
