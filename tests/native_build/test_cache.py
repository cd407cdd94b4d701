"""Build stage and on-disk cache: hit, miss on a flag change, rebuild after corruption (any
byte of any file of an entry, paths of the wrong kind, a tampered .so that would kill the
process if it were opened), clear errors (bad C, no compiler), concurrent builders, pickling
across processes.

Every test uses a fresh ``LAGCODEGEN_CACHE_DIR`` under ``tmp_path`` and hand-written C (a
``tag`` in a comment makes each test's key, and so its module name, unique, so the
in-process memo of one test never serves another).
"""
from __future__ import annotations

import dataclasses
import json
import multiprocessing
import os
import pickle
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

from lagcodegen.codegen.render import CSources, KernelLayout
from lagcodegen.native import build, cache
from lagcodegen.native.build import BuildError, CompiledSystem, build_module, compiler_available

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")

CDEF = "int lcg_tiny_add(double *out, const double *in, int n);"


def _rewrite(path, data: bytes) -> None:
    """Write ``data`` as a new file (new inode): rewriting a .so in place that this process has
    loaded changes its mapped pages and crashes the test process (SIGSEGV), not the code under test."""
    path.unlink()
    path.write_bytes(data)


def _replace_with(source, path) -> None:
    """Copy ``source`` over ``path`` as a new inode, for the same reason as `_rewrite`."""
    Path(path).unlink()
    shutil.copy(source, path)


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
    return CSources(layout, "tiny.h", header, "tiny.c", source, CDEF, source_key=f"tiny-{tag}")


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
    _rewrite(so, data[: len(data) // 2])
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
    _rewrite(so, b"this is not an ELF file")
    cache.write_marker(so.parent, json.loads(so.parent.joinpath(cache.MARKER).read_text())["key"], so.name)
    assert cache.entry_problem(so.parent, json.loads(so.parent.joinpath(cache.MARKER).read_text())["key"],
                               so.name) is None  # the checksums really match: this is the import path
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


# --- every byte of an entry is covered by a checksum ------------------------------------------

def _entry_files(entry: Path) -> list[Path]:
    return sorted(p for p in entry.iterdir() if p.is_file())


def _flip(path: Path, rng, data: bytes | None = None) -> tuple[int, int]:
    """Replace one byte of ``path`` (seeded position, a different value); return (offset, old)."""
    data = path.read_bytes() if data is None else data
    offset = int(rng.integers(len(data)))
    new = (data[offset] + int(rng.integers(1, 256))) % 256
    _rewrite(path, data[:offset] + bytes([new]) + data[offset + 1:])
    return offset, data[offset]


@pytest.mark.compiler
@needs_cc
def test_every_sampled_one_byte_corruption_of_an_entry_is_seen(cache_root):
    # 80 seeded single-byte corruptions of each file of a real entry (.so, .c, .h, cffi's
    # wrapper .c, the marker): the check that runs before any dlopen must flag every one.
    import numpy as np

    # Built by another process: rewriting a .so this process has mapped would crash it.
    path, _, _ = _in_subprocess(_worker_build, "every-byte", str(cache_root))
    entry, so = Path(path).parent, Path(path).name
    key = json.loads((entry / cache.MARKER).read_text())["key"]
    files = _entry_files(entry)
    assert {p.suffix for p in files} >= {".so", ".c", ".h", ".json"} and len(files) == 5, files
    rng = np.random.default_rng(20240611)
    for path in files:
        data = path.read_bytes()
        for _ in range(80):
            offset, _old = _flip(path, rng, data)
            problem = cache.entry_problem(entry, key, so)
            assert problem not in (None, "missing"), f"{path.name}: byte {offset} changed, not seen"
        _rewrite(path, data)
        assert cache.entry_problem(entry, key, so) is None


@pytest.mark.compiler
@needs_cc
@pytest.mark.parametrize("kind", [".so", "tiny.c", cache.MARKER])
def test_corrupt_entry_file_rebuilds_with_same_numbers(cache_root, compile_counter, kind):
    import numpy as np

    path, _, _ = _in_subprocess(_worker_build, f"corrupt-{kind}", str(cache_root))  # never mapped here
    entry = Path(path).parent
    target = Path(path) if kind == ".so" else entry / kind
    original = target.read_bytes()
    _flip(target, np.random.default_rng(7))
    system = build_module(tiny_sources(f"corrupt-{kind}"))
    assert len(compile_counter) == 1 and system.path == Path(path)
    assert call_add(system, [41.0, -1.5]) == [42.0, -0.5]  # out = in + 1 (the C above)
    assert cache.entry_problem(entry, system.key, system.path.name) is None  # replaced, valid
    if kind == "tiny.c":  # our own text: the rebuilt file is the original one again
        assert target.read_bytes() == original


@pytest.mark.compiler
@needs_cc
@pytest.mark.parametrize("damage", ["entry is a file", "so is a directory", "marker is a directory",
                                    "so is a symlink"])
def test_paths_of_the_wrong_kind_rebuild(cache_root, compile_counter, damage):
    path, _, _ = _in_subprocess(_worker_build, f"kind-{damage}", str(cache_root))
    so = Path(path)
    entry = so.parent
    if damage == "entry is a file":
        shutil.rmtree(entry)
        entry.write_text("not a directory")
    elif damage == "so is a directory":
        so.unlink()
        so.mkdir()
        (so / "inner").write_text("x")
    elif damage == "marker is a directory":
        (entry / cache.MARKER).unlink()
        (entry / cache.MARKER).mkdir()
    else:  # same bytes, but through a link the entry does not own
        elsewhere = cache_root / "elsewhere.so"
        shutil.copy(so, elsewhere)
        so.unlink()
        so.symlink_to(elsewhere)
    system = build_module(tiny_sources(f"kind-{damage}"))
    assert len(compile_counter) == 1 and system.path == so
    assert entry.is_dir() and so.is_file() and not so.is_symlink()
    assert call_add(system, [2.0]) == [3.0]


_BOMB = """\
#include <stdlib.h>
__attribute__((constructor)) static void lcg_test_bomb(void) { abort(); }
int lcg_test_bomb_symbol;
"""


def _unpickle_and_call(blob: bytes) -> tuple[str, list[float]]:
    system = pickle.loads(blob)
    return str(system.path), call_add(system, [1.0])


@pytest.mark.compiler
@needs_cc
def test_so_that_kills_on_load_is_never_opened(cache_root, tmp_path):
    # A shared library whose constructor aborts: if any load path dlopened it, the worker
    # process would die (SIGABRT). The checksum check must reject it first, on the build path
    # and on the unpickling path, and rebuild from the sources.
    gcc = shutil.which("gcc") or shutil.which("cc")
    (tmp_path / "bomb.c").write_text(_BOMB)
    bomb = tmp_path / "bomb.so"
    subprocess.run([gcc, "-shared", "-fPIC", str(tmp_path / "bomb.c"), "-o", str(bomb)], check=True)
    crash = subprocess.run([sys.executable, "-c", f"import ctypes; ctypes.CDLL({str(bomb)!r})"],
                           capture_output=True)
    assert crash.returncode != 0  # the bomb really kills a process that opens it

    system = build_module(tiny_sources("bomb"))
    blob = pickle.dumps(system)
    _replace_with(bomb, system.path)  # tampered after the build: its checksum no longer matches
    path, values = _in_subprocess(_unpickle_and_call, blob)
    assert (Path(path), values) == (system.path, [2.0])
    assert cache.entry_problem(system.path.parent, system.key, system.path.name) is None

    _replace_with(bomb, system.path)
    path, values, compiled = _in_subprocess(_worker_build, "bomb", str(cache_root))
    assert (Path(path), values, compiled) == (system.path, [2.0, 3.0], 1)

    _replace_with(bomb, system.path)  # no sources to rebuild from: a clear error, not a crash
    bare = pickle.dumps(dataclasses.replace(system, sources=None))
    with pytest.raises(BuildError, match="checksum") as info:
        _in_subprocess(_unpickle_and_call, bare)
    assert str(system.path) in str(info.value)


def test_an_edited_measurement_under_the_same_name_is_not_served_stale(tmp_path):
    """Regression: the sources' cache key once left out measurements, so y = 2 x recompiled under
    the same model name and cache returned y = x with status OK. Reference: y(0) = 2 x(0) by hand."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    for factor in (1, 2):
        model = Model("oscillator_y", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                      parameter_values={"m": 1.0, "k": 1.0}, measurements={"y": factor * x})
        run = simulate(compile_model(model, methods=("rk4",), cache_dir=tmp_path), [1.5, 0.0], 0.01, 0.01)
        assert run.measurements[0, 0] == factor * 1.5


@pytest.mark.parametrize("route", ["model", "equations"])
def test_an_edited_user_function_class_is_not_served_stale(tmp_path, route):
    """Found by review (session 16): pickle keys a class by its name, so a user's sympy Function
    whose body changed (a notebook cell run again) loaded the kernel of its old body: cos(2) for a
    stiffness changed from 4 to 9, status OK. Reference: V' = K x gives x = cos(sqrt(K) t) from
    x = 1 at rest (exact); the model entry and the equations' digest are both keyed."""
    import math

    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model, derive_equations
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    x = me.dynamicsymbols("x")
    m = sp.symbols("m", positive=True)
    for stiffness in (4.0, 9.0):
        namespace = {"sp": sp}
        exec(f"class spring(sp.Function):\n    def fdiff(self, argindex=1):\n        return {stiffness} * self.args[0]\n",
             namespace)
        model = Model("user_spring", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2,
                      potential_energy=namespace["spring"](x), parameter_values={"m": 1.0})
        source = model if route == "model" else derive_equations(model)
        run = simulate(compile_model(source, methods=("rk4",), outputs="rhs", cache_dir=tmp_path), {"x": 1.0}, 1.0, 1e-3)
        assert run.ok and run["x"][-1] == pytest.approx(math.cos(math.sqrt(stiffness)), abs=1e-9)


@needs_cc
def test_two_models_of_one_prefix_under_rtld_global_keep_their_own_kernels(tmp_path):
    """Found by review (session 16): with sys.setdlopenflags(RTLD_GLOBAL) (MPI and C++ extension
    stacks set it) the second of two models named alike ran the first's exported kernels, status OK.
    References: x = cos(2 t) for V = 2 x^2 (exact), DOP853 at 1e-12 on x'' = -4 x^3 written here."""
    from scipy.integrate import solve_ivp

    script = textwrap.dedent(f"""
        import os, sys
        sys.setdlopenflags(os.RTLD_GLOBAL | os.RTLD_NOW)
        import sympy as sp, sympy.physics.mechanics as me
        from lagcodegen import Model
        from lagcodegen.pipeline import compile_model
        from lagcodegen.run.simulate import simulate
        x = me.dynamicsymbols("x")
        m, k = sp.symbols("m k", positive=True)
        for V in (k * x**2 / 2, k * x**4 / 4):
            model = Model("osc", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2, potential_energy=V,
                          parameter_values={{"m": 1.0, "k": 4.0}})
            system = compile_model(model, methods=("rk4",), cache_dir={str(tmp_path)!r})
            print(repr(float(simulate(system, {{"x": 1.0}}, 1.0, 1e-3)["x"][-1])))
    """)
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr
    harmonic, quartic = (float(v) for v in out.stdout.split())
    reference = solve_ivp(lambda t, y: [y[1], -4 * y[0] ** 3], (0, 1), [1, 0], method="DOP853", rtol=1e-12,
                          atol=1e-12).y[0, -1]
    assert harmonic == pytest.approx(-0.4161468365471424, abs=1e-9)  # cos(2)
    assert quartic == pytest.approx(reference, abs=1e-9)


def test_methods_and_outputs_given_as_generators(tmp_path):
    """Found by review (session 16): a generator keyed the model entry, was then empty for the build,
    and the cache kept a kernel of no methods under the list: a later methods=["rk4"] in the same
    cache compiled none. Reference: x = cos(2 t) (exact) for k = 4, m = 1."""
    import math

    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    model = Model("osc_generators", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                  parameter_values={"m": 1.0, "k": 4.0})
    first = compile_model(model, methods=(name for name in ["rk4"]), outputs=(o for o in ["rhs"]), cache_dir=tmp_path)
    second = compile_model(model, methods=["rk4"], outputs=["rhs"], cache_dir=tmp_path)
    assert first.layout.methods == second.layout.methods == ("rk4",)
    assert simulate(second, {"x": 1.0}, 1.0, 1e-3)["x"][-1] == pytest.approx(math.cos(2.0), abs=1e-9)


def test_an_interrupted_build_stops_its_compilers(tmp_path, monkeypatch):
    """Found by review (session 16): a KeyboardInterrupt (a Jupyter interrupt) while the compilers
    ran left them running to the end: minutes of cc1 for a big model. Here the kernel's and the
    wrapper's "compilers" sleep for 60 s; after the interrupt both must be gone."""
    from lagcodegen.native import compiler

    command = [sys.executable, "-c", "import time; time.sleep(60)"]  # the flags after it land in sys.argv
    sleeper = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    kernels = [(command, sleeper, tmp_path / "kernels0.o")]
    started = []
    real_popen, real_communicate = subprocess.Popen, subprocess.Popen.communicate

    def popen(*args, **kwargs):
        started.append(real_popen(*args, **kwargs))
        return started[-1]

    interrupted = []

    def communicate(self, *args, **kwargs):
        if not interrupted:
            interrupted.append(self)
            raise KeyboardInterrupt
        return real_communicate(self, *args, **kwargs)

    class Builder:
        def emit_c_code(self, path):
            Path(path).write_text("int placeholder;\n")

    monkeypatch.setattr(compiler.subprocess, "Popen", popen)
    monkeypatch.setattr(real_popen, "communicate", communicate)
    with pytest.raises(KeyboardInterrupt):
        compiler.compile_in_parallel(Builder(), tmp_path, kernels, "module", ["-O3"], command, "module.so")
    for process in [sleeper, *started]:
        assert process.wait(timeout=10) is not None  # killed, not left to sleep 60 s


@needs_cc
def test_a_compiler_out_of_disk_falls_back_to_a_temporary_cache(cache_root, tmp_path, monkeypatch):
    """Found by review (session 16): when the sources fit on a nearly full disk but gcc's object file
    did not, the build died with a compiler dump, where the cache's docstring promises the temporary
    directory and a CacheDirWarning (as when Python's own write fails). The compiler here runs out of
    disk for every file under the cache root (as a full device would) and works elsewhere."""
    gcc = shutil.which("gcc") or shutil.which("cc")
    wrapper = tmp_path / "fullcc"
    wrapper.write_text(f"#!/bin/sh\ncase \"$*\" in *{cache_root}*) echo 'fatal error: error writing to "
                       f"kernels1.o: No space left on device' >&2; exit 1;; esac\nexec {gcc} \"$@\"\n")
    wrapper.chmod(0o755)
    monkeypatch.setattr(cache, "_WARNED", set())
    with pytest.warns(cache.CacheDirWarning, match=str(cache_root)):
        system = build_module(tiny_sources("full-disk"), compiler=str(wrapper))
    assert call_add(system, [0.5]) == [1.5]
    assert not system.path.is_relative_to(cache_root)


def test_a_compiler_that_writes_nothing_is_named(cache_root):
    """Found by review (session 16): CC=true (exit 0, no output) ended in a bare FileNotFoundError
    naming a temporary path, which the CLI reported as a bad command line (exit 2)."""
    with pytest.raises(BuildError, match=r"the C compiler \S*true reported success for model .* but wrote no "
                                         r".*; set CC to a working C compiler"):
        build_module(tiny_sources("writes-nothing"), compiler=shutil.which("true"))


@pytest.mark.parametrize("how", ["closure", "global list", "helper function"])
def test_what_a_user_function_class_reads_is_keyed(tmp_path, how):
    """Found by review (session 16, of the fix above): a stiffness held in a closure, a global list or
    a helper function the method calls keyed as before when changed: cos(2) for k = 9, status OK.
    Reference: x = cos(sqrt(k) t) from x = 1 at rest (exact)."""
    import math

    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    x = me.dynamicsymbols("x")
    m = sp.symbols("m", positive=True)
    for stiffness in (4.0, 9.0):
        if how == "closure":
            def make(k):
                class Spring(sp.Function):
                    def fdiff(self, argindex=1):
                        return k * self.args[0]
                return Spring
            spring = make(stiffness)
        else:
            namespace = {"sp": sp, "__name__": "user_cell"}
            source = ("COEFFS = [%r]\nclass spring(sp.Function):\n    def fdiff(self, argindex=1):\n"
                      "        return COEFFS[0] * self.args[0]\n" if how == "global list" else
                      "def stiffness():\n    return %r\nclass spring(sp.Function):\n"
                      "    def fdiff(self, argindex=1):\n        return stiffness() * self.args[0]\n") % stiffness
            exec(source, namespace)
            spring = namespace["spring"]
        model = Model("read_spring", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=spring(x),
                      parameter_values={"m": 1.0})
        run = simulate(compile_model(model, methods=("rk4",), outputs="rhs", cache_dir=tmp_path), {"x": 1.0}, 1.0, 1e-3)
        assert run.ok and run["x"][-1] == pytest.approx(math.cos(math.sqrt(stiffness)), abs=1e-9)


def test_a_model_with_a_user_function_class_keys_alike_in_two_processes(tmp_path):
    """Found by review (session 16): sympy's metaclass gives every subclass a dict of functions whose
    repr holds memory addresses, so each process keyed the same model apart (no hit, another entry).
    A module named sympy_<something> is the user's, not sympy's."""
    module = tmp_path / "sympy_helpers.py"
    module.write_text("import sympy as sp\nclass spring(sp.Function):\n    def fdiff(self, argindex=1):\n"
                      "        return 4.0 * self.args[0]\n")
    script = textwrap.dedent(f"""
        import sys
        sys.path.insert(0, {str(tmp_path)!r})
        import sympy as sp, sympy.physics.mechanics as me
        from sympy_helpers import spring
        from lagcodegen import Model
        from lagcodegen.pipeline import _model_entry
        x = me.dynamicsymbols("x")
        m = sp.symbols("m", positive=True)
        model = Model("keyed_spring", [x], [m], kinetic_energy=m * x.diff()**2 / 2, potential_energy=spring(x),
                      parameter_values={{"m": 1.0}})
        print(_model_entry(model, None, None, ("rk4",), "double", ("libm", 0, "fast"), {str(tmp_path)!r}).name)
    """)
    keys = [subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300) for _ in range(2)]
    assert all(k.returncode == 0 for k in keys), [k.stderr for k in keys]
    assert keys[0].stdout == keys[1].stdout and keys[0].stdout.startswith("model-")
    module.write_text(module.read_text().replace("4.0", "9.0"))
    edited = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert edited.returncode == 0 and edited.stdout != keys[0].stdout


def test_two_user_function_classes_that_read_each_other_are_keyed(tmp_path):
    """Found reading the change over: a method of A reading the class B, whose method reads A, recursed
    without end in the key (each class described afresh). By hand V' = 4 x: x = cos(2 t) from x = 1."""
    import math

    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import simulate

    namespace = {"sp": sp, "__name__": "user_cell"}
    exec("class A(sp.Function):\n    def fdiff(self, argindex=1):\n        return 0 * B(self.args[0]) + 4.0 * self.args[0]\n"
         "class B(sp.Function):\n    def fdiff(self, argindex=1):\n        return A(self.args[0])\n", namespace)
    x = me.dynamicsymbols("x")
    m = sp.symbols("m", positive=True)
    model = Model("mutual_spring", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=namespace["A"](x),
                  parameter_values={"m": 1.0})
    run = simulate(compile_model(model, methods=("rk4",), outputs="rhs", cache_dir=tmp_path), {"x": 1.0}, 1.0, 1e-3)
    assert run.ok and run["x"][-1] == pytest.approx(math.cos(2.0), abs=1e-9)
