"""Helper: runs the C compiler for one build of ``build.py`` and explains its failures.

The kernels compile while cffi writes its wrapper, and the wrapper at -O0 beside them
(`start_kernel_compile`, `compile_in_parallel`); a failure is re-run with captured output so
that the `BuildError` shows the compiler's own errors, the command and the kept ``.c``
(`compile_error`). Imports no pipeline stage: the sources are duck-typed ``CSources``.
"""
from __future__ import annotations

import contextlib
import errno
import io
import os
import shlex
import subprocess
import sysconfig
from pathlib import Path

import cffi

__all__ = ["BuildError", "check_python_headers", "start_kernel_compile", "stop",
           "compile_in_parallel", "compile_error"]


class BuildError(RuntimeError):
    """A C build failed. ``command``, ``stderr`` and ``c_path`` (the kept ``.c``) say why and where."""

    def __init__(self, message: str, *, command: str = "", stderr: str = "", c_path: Path | None = None):
        super().__init__(message)
        self.command, self.stderr, self.c_path = command, stderr, c_path


def check_python_headers(sources) -> None:
    """cffi's wrapper includes Python.h: without the headers every build fails, so say so first."""
    include = Path(sysconfig.get_paths()["include"])
    if not (include / "Python.h").is_file():
        raise BuildError(f"cannot build model {sources.layout.model!r}: the Python development headers "
                         f"are not installed (no Python.h in {include}); install them, e.g. "
                         f"apt-get install python3-dev (Debian/Ubuntu) or dnf install python3-devel")


#: the kernels stay inside the module: exported, two models of one C prefix loaded with RTLD_GLOBAL
#: (MPI and C++ extension stacks set it) called each other's, status OK (found by review)
KERNEL_FLAGS = ("-fvisibility=hidden",)


def start_kernel_compile(tmp: Path, sources, flags, command) -> list:
    """Start compiling the kernels (POSIX) before cffi parses the cdef and writes its wrapper, so
    that the longest jobs start first. A source with integrators is compiled as two translation
    units at once (``LCG_BUILD_PART`` 1: the explicit steppers and the drivers, 2: everything
    else; see model.c.j2), which keeps the second core busy. Returns [(argv, process, object)]."""
    shared = shlex.split(sysconfig.get_config_var("CCSHARED") or "-fPIC")
    parts = (1, 2) if sources.layout.methods else (0,)
    jobs = []
    for part in parts:
        obj = tmp / f"kernels{part}.o"
        argv = [*command, *flags, *shared, *KERNEL_FLAGS, f"-DLCG_BUILD_PART={part}", "-I", str(tmp), "-c",
                str(tmp / sources.source_name), "-o", str(obj)]
        jobs.append((argv, subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True), obj))
    return jobs


def stop(kernels: list) -> None:
    for _, process, _ in kernels:
        process.kill()
        process.communicate()


def compile_in_parallel(ffibuilder, tmp: Path, kernels: list, module_name, flags, command, so_name) -> Path:
    """Compile cffi's wrapper while the kernels compile (``kernels`` from `start_kernel_compile`),
    then link them all (POSIX).

    The translation units are independent: the kernels get ``flags``, the wrapper (glue that
    includes Python.h) -O0. Running them at once and skipping setuptools roughly halves a
    cold build on two cores. A failure raises cffi.VerificationError like cffi's own build.
    """
    wrapper = tmp / f"{module_name}.c"
    try:
        with contextlib.redirect_stdout(io.StringIO()):  # cffi announces "generating <file>"
            ffibuilder.emit_c_code(str(wrapper))
    except BaseException:
        stop(kernels)
        raise
    shared = shlex.split(sysconfig.get_config_var("CCSHARED") or "-fPIC")
    include = sysconfig.get_paths()["include"]
    # the glue converts arguments once per call from Python; at -O0 it compiles in half the time
    # of -O1 (0.16 against 0.33 s for the double pendulum), which is most of a cold build's slack
    wrapper_flags = [f for f in flags if not f.startswith("-O")] + ["-O0"]
    argv = [*command, *wrapper_flags, *shared, "-I", str(tmp), "-I", include, "-c", str(wrapper),
            "-o", str(tmp / "wrapper.o")]
    try:
        jobs = [*kernels, (argv, subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True),
                           tmp / "wrapper.o")]
    except BaseException:
        stop(kernels)
        raise
    try:
        outputs = [process.communicate()[0] for _, process, _ in jobs]
    except BaseException:  # found by review: after a Ctrl-C the compilers ran on to the end
        stop(jobs)
        raise
    for (argv, process, _), output in zip(jobs, outputs):
        if process.returncode != 0:
            _raise_if_full(output, tmp)
            raise cffi.VerificationError(f"{shlex.join(argv)}\n{output}")
    link_flags = shlex.split(sysconfig.get_config_var("LDSHARED") or "cc -shared")[1:]
    link = [*command, *link_flags, *[str(obj) for _, _, obj in jobs], "-o", str(tmp / so_name), "-lm"]
    run = subprocess.run(link, capture_output=True, text=True)
    if run.returncode != 0:
        _raise_if_full(run.stderr, tmp)
        raise cffi.VerificationError(f"{shlex.join(link)}\n{run.stderr}")
    return tmp / so_name


def _raise_if_full(output: str, tmp: Path) -> None:
    """A compiler or linker that ran out of disk: the OSError the cache's fallback to a temporary
    directory answers, as it does when Python's own writes fail (found by review: a compiler dump)."""
    if "No space left on device" in output:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(tmp))


def compile_error(sources, kept: Path, module_name, flags, command, exc) -> BuildError:
    """Re-run the failing compile with captured output, so the message shows gcc's own errors."""
    c_path = kept / sources.source_name
    if isinstance(exc, (cffi.CDefError, cffi.FFIError)):
        return BuildError(f"cdef of model {sources.layout.model!r} is invalid: {exc}\n"
                          f"kept sources: {c_path}", c_path=c_path)
    include = sysconfig.get_paths()["include"]
    attempts = [[*command, *flags, "-I", str(kept), "-c", str(c_path), "-o", os.devnull],
                [*command, *flags, "-fPIC", "-I", str(kept), "-I", include,
                 "-c", str(kept / (module_name + ".c")), "-o", os.devnull]]
    shown, stderr = "", str(exc)
    for argv in attempts:
        if not Path(argv[-3]).is_file():
            continue
        run = subprocess.run(argv, capture_output=True, text=True)
        if run.returncode != 0:
            shown, stderr = shlex.join(argv), (run.stderr or run.stdout)
            break
    hint = ("\nhint: install the Python development headers (e.g. apt-get install python3-dev)"
            if "Python.h" in stderr else "")
    return BuildError(f"C compilation of model {sources.layout.model!r} failed\n"
                      f"command: {shown or 'cffi build_ext'}\n{stderr.rstrip()}\n"
                      f"kept sources: {c_path}{hint}",
                      command=shown, stderr=stderr, c_path=c_path)
