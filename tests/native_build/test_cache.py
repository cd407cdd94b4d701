"""Build stage and on-disk cache: hit, miss on a flag change, rebuild after corruption,
clear errors (bad C, no compiler), concurrent builders, pickling across processes.

Every test uses a fresh ``LAGCODEGEN_CACHE_DIR`` under ``tmp_path`` and hand-written C (a
``tag`` in a comment makes each test's key, and so its module name, unique, so the
in-process memo of one test never serves another).
"""
from __future__ import annotations

import dataclasses
import multiprocessing
import os
import pickle
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import cffi
import pytest

from lagcodegen import build, cache
from lagcodegen.build import BuildError, CompiledSystem, build_module, compiler_available
from lagcodegen.emit import CSources, KernelLayout

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")

CDEF = "int lcg_tiny_add(double *out, const double *in, int n);"


def tiny_sources(tag: str, body: str = "out[i] = in[i] + 1.0;") -> CSources:
    """A one-function kernel: out[i] = in[i] + 1, returns n."""
    layout = KernelLayout(model="tiny", prefix="lcg_tiny", precision="double",
                          coordinates=("x",), speeds=("xd",), parameters=(), fixed=(),
                          points=(), functions=("lcg_tiny_add",))
    header = f"#ifndef LCG_TINY_H\n#define LCG_TINY_H\n{CDEF}\n#endif\n"
    source = textwrap.dedent(f"""\
        /* test tag: {tag} */
        #include "tiny.h"
        int lcg_tiny_add(double *out, const double *in, int n)
        {{
            int i;
            for (i = 0; i < n; ++i) {{
                {body}
            }}
            return n;
        }}
        """)
    return CSources(layout, "tiny.h", header, "tiny.c", source, CDEF)


def call_add(system: CompiledSystem, values) -> list[float]:
    ffi, n = system.ffi, len(values)
    out = ffi.new("double[]", n)
    assert system.lib.lcg_tiny_add(out, ffi.new("double[]", list(values)), n) == n
    return list(out)


@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    return root


@pytest.fixture
def compile_counter(monkeypatch):
    """Counts calls of build._compile_entry (the only place C gets compiled: cffi's compile step
    or, on POSIX, the parallel compile of kernels and wrapper)."""
    calls = []
    original = build._compile_entry

    def spy(*args, **kwargs):
        calls.append(args[2])
        return original(*args, **kwargs)

    monkeypatch.setattr(build, "_compile_entry", spy)
    return calls


# --- workers for spawned processes (module level so ``spawn`` can import them) -------------

def _worker_build(tag: str, root: str, barrier=None) -> tuple[str, list[float], int]:
    os.environ[cache.ENV_VAR] = root
    calls = []
    original = build._compile_entry

    def spy(*args, **kwargs):
        calls.append(1)
        return original(*args, **kwargs)

    build._compile_entry = spy
    if barrier is not None:
        barrier.wait()
    system = build_module(tiny_sources(tag))
    return str(system.path), call_add(system, [1.0, 2.0]), len(calls)


def _worker_main(tag, root, barrier, queue):
    try:
        queue.put(("ok", _worker_build(tag, root, barrier)))
    except BuildError as exc:
        queue.put(("error", str(exc)))


def _in_subprocess(func, *args):
    with multiprocessing.get_context("spawn").Pool(1) as pool:
        return pool.apply(func, args)


# --- cache helpers (no compiler needed) ----------------------------------------------------

def test_source_key_is_canonical_and_sensitive():
    a = cache.source_key({"source": "int x;", "flags": "-O2"})
    assert a == cache.source_key({"flags": "-O2", "source": "int x;"})  # order-free
    assert len(a) == 64 and int(a, 16) >= 0
    assert a != cache.source_key({"source": "int x;", "flags": "-O3"})
    assert a != cache.source_key({"source": "int x; ", "flags": "-O2"})
    with pytest.raises(TypeError, match="flags"):
        cache.source_key({"flags": ["-O2"]})


def test_cache_dir_resolution(tmp_path, monkeypatch):
    monkeypatch.setenv(cache.ENV_VAR, str(tmp_path / "env"))
    assert cache.cache_dir() == (tmp_path / "env").resolve()
    assert cache.cache_dir(tmp_path / "arg") == (tmp_path / "arg").resolve()
    monkeypatch.delenv(cache.ENV_VAR)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert cache.cache_dir() == (tmp_path / "xdg" / "lagcodegen").resolve()
    monkeypatch.delenv("XDG_CACHE_HOME")
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert cache.cache_dir() == (tmp_path / "home" / ".cache" / "lagcodegen").resolve()


def test_entry_problem_and_install_race(tmp_path):
    key, so = "k" * 64, "m.so"
    entry = tmp_path / "m"
    assert cache.entry_problem(entry, key, so) == "missing"
    first = cache.new_build_dir(tmp_path, "m")
    (first / so).write_bytes(b"binary")
    cache.write_marker(first, key, so)
    assert cache.install_entry(first, entry) is True
    assert cache.entry_problem(entry, key, so) is None
    assert "does not match key" in cache.entry_problem(entry, "x" * 64, so)
    second = cache.new_build_dir(tmp_path, "m")
    (second / so).write_bytes(b"other")
    assert cache.install_entry(second, entry) is False  # lost the race: keep the winner
    assert not second.exists() and (entry / so).read_bytes() == b"binary"
    (entry / so).write_bytes(b"bin")  # truncated
    assert "checksum" in cache.entry_problem(entry, key, so)
    cache.evict_entry(entry)
    assert not entry.exists() and sorted(tmp_path.iterdir()) == []


def test_no_compiler_gives_install_hint(cache_root, tmp_path, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "no-such-cc"))
    assert compiler_available() is False
    with pytest.raises(BuildError) as info:
        build_module(tiny_sources("no-compiler"))
    message = str(info.value)
    assert "no-such-cc" in message
    assert "install gcc" in message and "apt-get install gcc" in message and "set CC" in message


# --- compiling tests -----------------------------------------------------------------------

@pytest.mark.compiler
@needs_cc
def test_cache_hit_compiles_nothing(cache_root, compile_counter, monkeypatch):
    sources = tiny_sources("hit")
    first = build_module(sources)
    assert len(compile_counter) == 1
    assert call_add(first, [1.0, 2.5]) == [2.0, 3.5]
    assert first.module_name == f"_lcg_tiny_{first.key[:16]}"
    assert first.path.parent.parent == cache_root.resolve()
    mtime = first.path.stat().st_mtime_ns

    again = build_module(sources)  # in-process memo
    assert len(compile_counter) == 1 and again.lib is first.lib

    monkeypatch.setattr(build, "_MEMO", {})  # forget the memo: the disk entry must serve
    from_disk = build_module(sources)
    assert len(compile_counter) == 1
    assert from_disk.path == first.path and from_disk.path.stat().st_mtime_ns == mtime
    assert call_add(from_disk, [0.0]) == [1.0]

    path, values, compiled = _in_subprocess(_worker_build, "hit", str(cache_root))
    assert (Path(path), values, compiled) == (first.path, [2.0, 3.0], 0)  # a new process
    assert [p.name for p in cache_root.iterdir()] == [first.module_name]  # no temp dirs left


@pytest.mark.compiler
@needs_cc
def test_flag_change_misses(cache_root, compile_counter):
    sources = tiny_sources("flags")
    plain = build_module(sources)
    debug = build_module(sources, extra_compile_args=("-O0", "-g"))
    assert len(compile_counter) == 2
    assert debug.key != plain.key and debug.path != plain.path
    assert call_add(debug, [1.0]) == call_add(plain, [1.0]) == [2.0]
    build_module(sources, extra_compile_args=("-O0", "-g"))
    assert len(compile_counter) == 2


@pytest.mark.compiler
@needs_cc
def test_rebuild_after_truncated_so(cache_root, compile_counter):
    # Built by another process, so this one never mapped the file we truncate.
    path, _, _ = _in_subprocess(_worker_build, "truncated", str(cache_root))
    so = Path(path)
    data = so.read_bytes()
    so.write_bytes(data[: len(data) // 2])
    system = build_module(tiny_sources("truncated"))
    assert len(compile_counter) == 1 and system.path == so
    assert so.stat().st_size > len(data) // 2
    assert call_add(system, [41.0]) == [42.0]


@pytest.mark.compiler
@needs_cc
def test_rebuild_after_unloadable_so(cache_root, compile_counter):
    # Garbage with a matching checksum: only the import attempt can tell.
    path, _, _ = _in_subprocess(_worker_build, "garbage", str(cache_root))
    so = Path(path)
    so.write_bytes(b"this is not an ELF file")
    cache.write_marker(so.parent, so.parent.joinpath(cache.MARKER).read_text().split()[0], so.name)
    system = build_module(tiny_sources("garbage"))
    assert len(compile_counter) == 1
    assert call_add(system, [1.0]) == [2.0]


@pytest.mark.compiler
@needs_cc
def test_bad_c_raises_build_error_with_compiler_text(cache_root):
    sources = tiny_sources("bad", body="out[i] = in[i] + undeclared_thing;")
    with pytest.raises(BuildError) as info:
        build_module(sources)
    error = info.value
    message = str(error)
    assert "undeclared_thing" in message and "error" in message  # gcc's own diagnostic
    assert "Traceback" not in message and "VerificationError" not in message
    assert error.c_path is not None and error.c_path.is_file()
    assert str(error.c_path) in message
    assert "undeclared_thing" in error.c_path.read_text()
    assert error.command and "tiny.c" in error.command
    assert not any(p.name.startswith(".tmp") for p in cache_root.iterdir())


@pytest.mark.compiler
@needs_cc
def test_concurrent_builders_all_succeed(cache_root):
    ctx = multiprocessing.get_context("spawn")
    n = 3
    barrier, queue = ctx.Barrier(n), ctx.Queue()
    procs = [ctx.Process(target=_worker_main, args=("race", str(cache_root), barrier, queue))
             for _ in range(n)]
    for p in procs:
        p.start()
    results = [queue.get(timeout=300) for _ in procs]
    for p in procs:
        p.join(timeout=60)
        assert p.exitcode == 0
    assert [status for status, _ in results] == ["ok"] * n, results
    paths = {r[0] for _, r in results}
    assert len(paths) == 1 and all(r[1] == [2.0, 3.0] for _, r in results)
    assert sum(r[2] for _, r in results) >= 1  # usually n: they really raced to install
    entries = sorted(p.name for p in cache_root.iterdir())
    assert entries == [Path(paths.pop()).parent.name]  # one entry, no temp dirs left


@pytest.mark.compiler
@needs_cc
def test_pickled_system_loads_in_another_process(cache_root, tmp_path):
    system = build_module(tiny_sources("pickle"))
    blob = tmp_path / "system.pkl"
    blob.write_bytes(pickle.dumps(system))
    script = textwrap.dedent(f"""\
        import pickle
        system = pickle.loads(open({str(blob)!r}, "rb").read())
        out = system.ffi.new("double[2]")
        system.lib.lcg_tiny_add(out, system.ffi.new("double[]", [3.0, 4.0]), 2)
        again = pickle.loads(open({str(blob)!r}, "rb").read())
        print(system.key, system.layout.model, list(out), again.lib is system.lib)
        """)
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.split() == [system.key, "tiny", "[4.0,", "5.0]", "True"]
    clone = pickle.loads(pickle.dumps(system))
    assert clone == system and clone.lib is system.lib


@pytest.mark.compiler
@needs_cc
def test_cdef_header_mismatch_is_a_build_error(cache_root):
    sources = tiny_sources("mismatch")
    extra = dataclasses.replace(sources, cdef=CDEF + "\nint lcg_tiny_missing(int k);")
    with pytest.raises(BuildError, match="lcg_tiny_missing") as info:
        build_module(extra)
    assert info.value.c_path.is_file()
    broken = dataclasses.replace(sources, cdef="int lcg_tiny_add(double *out, ;")
    with pytest.raises(BuildError, match="cdef of model 'tiny' is invalid"):
        build_module(broken)
    assert [p.name for p in cache_root.iterdir()] == ["failed"]  # nothing half-built installed


@pytest.mark.compiler
@needs_cc
def test_explicit_compiler_is_used_and_env_restored(cache_root, monkeypatch):
    monkeypatch.delenv("CC", raising=False)
    gcc = shutil.which("gcc") or shutil.which("cc")
    system = build_module(tiny_sources("explicit-cc"), compiler=gcc)
    assert call_add(system, [0.5]) == [1.5]
    assert "CC" not in os.environ
