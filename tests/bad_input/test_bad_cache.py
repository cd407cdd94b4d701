"""Bad cache state: damaged sources entries, cache directories that are files, unwritable or
full, and cache paths of the wrong kind. Each ends in a correct build (the same numbers as a
clean build in a fresh cache dir, the second route) or in an error that names the directory.

Tests run as root on the development machine, where ``chmod 0o500`` does not stop writes.
So an unwritable or full directory is simulated by making the os-level call that would fail
there raise the error the kernel gives (``PermissionError`` / ``ENOSPC``), and a directory
that cannot be created by a path below a regular file.
"""
from __future__ import annotations

import errno
import json
import math
import re
import tempfile
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, pipeline
from lagcodegen.native import build, cache
from lagcodegen.native.build import compiler_available
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")
pytestmark = [pytest.mark.compiler, needs_cc]

STATE = [0.7, -0.4, 0.3, 1.1]  # q1, q2, q1_d, q2_d: a generic state, no symmetry


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    """An empty LAGCODEGEN_CACHE_DIR, no in-process memo, and temporary dirs under tmp_path."""
    root = tmp_path / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(root))
    monkeypatch.setattr(build, "_MEMO", {})
    for name, value in (("_FALLBACK", {}), ("_WARNED", set()), ("_WRITABLE", set())):
        monkeypatch.setattr(cache, name, value)
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    return root


@pytest.fixture(scope="module")
def pendulum(example_eom):
    return example_eom("double_pendulum")


@pytest.fixture(scope="module")
def reference(pendulum, tmp_path_factory):
    """rhs of a clean build in its own cache dir: what every recovered build must give."""
    return rhs(compile_model(pendulum, methods=("rk4",), cache_dir=tmp_path_factory.mktemp("clean")))


def rhs(system) -> np.ndarray:
    ffi, layout = system.ffi, system.layout
    out = ffi.new("double[]", 2 * layout.n)
    p = [dict(layout.defaults)[name] for name in layout.parameters]
    getattr(system.lib, f"{layout.prefix}_rhs")(0.0, ffi.new("double[]", STATE), ffi.new("double[]", p), out)
    return np.array(list(out))


def sources_entry(root: Path) -> Path:
    (entry,) = (root / "sources").iterdir()
    return entry


def own_key(entry: Path) -> str:
    """The key an intact sources entry names in its body."""
    return json.loads(entry.read_bytes().partition(b"\n")[2])["key"]


# --- damaged sources entries ------------------------------------------------------------------

def test_every_sampled_one_byte_corruption_of_the_sources_entry_is_seen(fresh_cache, pendulum):
    # 300 seeded single-byte changes anywhere in the entry: each must read as "no entry" (then
    # compile_model renders again), none may raise. The old pickle format crashed on half of
    # them with UnicodeDecodeError and compiled edited C text silently.
    compile_model(pendulum, methods=("rk4",))
    entry = sources_entry(fresh_cache)
    data, key = entry.read_bytes(), own_key(entry)
    assert pipeline._load_sources(entry, key) is not None
    rng = np.random.default_rng(20240611)
    for _ in range(300):
        offset = int(rng.integers(len(data)))
        changed = bytearray(data)
        changed[offset] = (changed[offset] + int(rng.integers(1, 256))) % 256
        entry.write_bytes(bytes(changed))
        assert pipeline._load_sources(entry, key) is None, f"byte {offset} changed, not seen"
    entry.write_bytes(data)
    assert pipeline._load_sources(entry, key) is not None


def test_sources_entry_is_json_not_pickle(fresh_cache, pendulum):
    system = compile_model(pendulum, methods=("rk4",))
    head, _, body = sources_entry(fresh_cache).read_bytes().partition(b"\n")
    assert re.fullmatch(rb"lagcodegen-sources-v2 [0-9a-f]{64}", head)
    stored = json.loads(body)
    assert stored["sources"]["source"].startswith("/*") and stored["ops"]["dynamics"] > 0
    assert pipeline._csources(stored["sources"]) == system.sources  # lossless round trip


def _oscillator(name: str):
    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    return Model(name, [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                 parameter_values={m: 1.0, k: 1.0})


def test_another_models_intact_entry_copied_over_this_ones_is_not_loaded(fresh_cache):
    """Found by review: an intact sources entry (its checksum right) copied onto another entry's
    file names was loaded as the other model: model 'alias' with k fixed at 1.4, and x(1) = 0.378
    with status OK where cos(1) = 0.5403 (unit mass and stiffness, x(0) = 1, by hand)."""
    compile_model(_oscillator("plain"), methods=("rk4",))
    plain_files = sorted(p for p in (fresh_cache / "sources").iterdir() if p.suffix == ".json")
    compile_model(_oscillator("alias"), methods=("rk4",), fixed={"k": 1.4})
    (alias_file,) = [p for p in (fresh_cache / "sources").iterdir() if p.suffix == ".json" and p not in plain_files]
    for target in plain_files:
        target.write_bytes(alias_file.read_bytes())
    build._MEMO.clear()  # as in a new process: only the disk serves
    again = compile_model(_oscillator("plain"), methods=("rk4",))
    assert again.layout.model == "plain" and again.layout.fixed == ()
    run = simulate(again, [1.0, 0.0], t_end=1.0, h=1e-3)
    assert run.ok and run.x[-1, 0] == pytest.approx(math.cos(1.0), abs=1e-10)


def test_another_models_model_entry_copied_over_this_ones_is_not_followed(fresh_cache):
    """Found by review: a model entry (sources/model-*.txt, which names the sources entry of a
    Model's derivation) copied over another model's was followed, and the run gave the other
    model's answer with status OK. Here the entries of fixed k = 1 and k = 4 are swapped: the
    k = 1 model must still give x(1) = cos(1) (unit mass, x(0) = 1, by hand), not cos(2)."""
    compile_model(_oscillator("swap"), methods=("rk4",), fixed={"k": 1.0})
    first = {p for p in (fresh_cache / "sources").iterdir() if p.name.startswith("model-")}
    compile_model(_oscillator("swap"), methods=("rk4",), fixed={"k": 4.0})
    (second,) = {p for p in (fresh_cache / "sources").iterdir() if p.name.startswith("model-")} - first
    for target in first:
        target.write_bytes(second.read_bytes())
    build._MEMO.clear()  # as in a new process: only the disk serves
    again = compile_model(_oscillator("swap"), methods=("rk4",), fixed={"k": 1.0})
    run = simulate(again, [1.0, 0.0], t_end=1.0, h=1e-3)
    assert run.ok and run.x[-1, 0] == pytest.approx(math.cos(1.0), abs=1e-10)


def test_fixed_values_that_print_alike_are_different_kernels(fresh_cache):
    """Found by review: the model entry keyed a fixed value by repr, and repr(sp.Float(1.4, 2)) is
    '1.4' while it folds as 1.400390625: the plain 1.4 then reused that kernel. x(1) =
    cos(sqrt(1.4)) for unit mass and x(0) = 1 (by hand)."""
    coarse = compile_model(_oscillator("folded"), methods=("rk4",), fixed={"k": sp.Float(1.4, 2)})
    assert coarse.layout.fixed == (("k", 1.400390625),)
    exact = compile_model(_oscillator("folded"), methods=("rk4",), fixed={"k": 1.4})
    assert exact.layout.fixed == (("k", 1.4),)
    run = simulate(exact, [1.0, 0.0], t_end=1.0, h=1e-3)
    assert run.x[-1, 0] == pytest.approx(math.cos(math.sqrt(1.4)), abs=1e-10)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_one_byte_edit_of_the_cached_c_is_detected(fresh_cache, pendulum, reference, seed):
    # A digit of a numeric literal in the cached C is changed: still valid C, wrong numbers if
    # it were compiled. The entry must be rejected, rendered again and replaced, and the
    # module must be the clean one (same key, same numbers as the clean build).
    clean = compile_model(pendulum, methods=("rk4",))
    entry = sources_entry(fresh_cache)
    head, _, body = entry.read_bytes().partition(b"\n")
    literal = [m.start() for m in re.finditer(rb"(?<=[ (*+-])[1-9]\.[0-9]", body)]
    offset = literal[np.random.default_rng(seed).integers(len(literal))]
    edited = bytearray(body)
    edited[offset] = ord("1") if edited[offset] != ord("1") else ord("2")
    entry.write_bytes(head + b"\n" + bytes(edited))
    build._MEMO.clear()  # as in a new process: only the disk serves

    again = compile_model(pendulum, methods=("rk4",))
    assert again.key == clean.key and again.sources == clean.sources
    np.testing.assert_array_equal(rhs(again), reference)
    assert entry.read_bytes() == head + b"\n" + body  # the damaged entry was replaced


def test_sources_entry_of_the_wrong_kind_is_replaced(fresh_cache, pendulum, reference):
    compile_model(pendulum, methods=("rk4",))
    entry = sources_entry(fresh_cache)
    entry.unlink()
    entry.mkdir()  # a directory where the file belongs
    (entry / "junk").write_text("x")
    assert np.array_equal(rhs(compile_model(pendulum, methods=("rk4",))), reference)
    assert entry.is_file() and pipeline._load_sources(entry, own_key(entry)) is not None

    folder = fresh_cache / "sources"
    for item in folder.iterdir():
        item.unlink()
    folder.rmdir()
    folder.write_text("a file where the sources folder belongs")
    build._MEMO.clear()
    assert np.array_equal(rhs(compile_model(pendulum, methods=("rk4",))), reference)
    assert folder.is_dir() and pipeline._load_sources(sources_entry(fresh_cache), own_key(sources_entry(fresh_cache))) \
        is not None


# --- unusable cache directories ---------------------------------------------------------------

def _assert_fallback_warning(record, directory: Path) -> None:
    messages = [str(w.message) for w in record if issubclass(w.category, cache.CacheDirWarning)]
    assert messages, [str(w.message) for w in record]
    assert any(str(directory) in m and cache.ENV_VAR in m and "will not be reused" in m
               for m in messages), messages


@pytest.mark.parametrize("kind", ["is a file", "below a file"])
def test_cache_dir_that_is_a_file_falls_back_with_a_warning(fresh_cache, tmp_path, monkeypatch,
                                                            pendulum, reference, kind):
    blocker = tmp_path / "blocker"
    blocker.write_text("a regular file")
    bad = blocker if kind == "is a file" else blocker / "cache"
    monkeypatch.setenv(cache.ENV_VAR, str(bad))
    with pytest.warns(cache.CacheDirWarning) as record:
        system = compile_model(pendulum, methods=("rk4",))
    _assert_fallback_warning(record, bad)
    assert Path(tempfile.gettempdir()) in system.path.parents  # the temporary directory
    assert np.array_equal(rhs(system), reference)
    assert blocker.read_text() == "a regular file"  # the user's file is untouched


def test_read_only_cache_dir_falls_back_with_a_warning(fresh_cache, monkeypatch, pendulum, reference):
    # As root, chmod 0o500 does not stop writes; so tempfile.mkdtemp (the write probe and every
    # build directory) raises what it raises in a read-only directory.
    fresh_cache.mkdir()
    original = tempfile.mkdtemp

    def read_only(*args, dir=None, **kwargs):
        if dir is not None and Path(dir).resolve() == fresh_cache.resolve():
            raise PermissionError(errno.EACCES, "Permission denied", str(dir))
        return original(*args, dir=dir, **kwargs)

    monkeypatch.setattr(tempfile, "mkdtemp", read_only)
    with pytest.warns(cache.CacheDirWarning) as record:
        system = compile_model(pendulum, methods=("rk4",))
    _assert_fallback_warning(record, fresh_cache)
    assert any("Permission denied" in str(w.message) for w in record)
    assert fresh_cache not in system.path.parents
    assert np.array_equal(rhs(system), reference)


def test_full_cache_dir_during_the_build_falls_back(fresh_cache, monkeypatch, pendulum, reference):
    # The disk fills up after the probe: writing the build directory fails with ENOSPC.
    original = build.cache.new_build_dir

    def full(root, name):
        if root == fresh_cache.resolve():
            raise OSError(errno.ENOSPC, "No space left on device", str(root / name))
        return original(root, name)

    monkeypatch.setattr(cache, "new_build_dir", full)
    with pytest.warns(cache.CacheDirWarning) as record:
        system = compile_model(pendulum, methods=("rk4",))
    _assert_fallback_warning(record, fresh_cache)
    assert any("No space left on device" in str(w.message) for w in record)
    assert np.array_equal(rhs(system), reference)


def test_sources_that_cannot_be_stored_only_warn(fresh_cache, monkeypatch, pendulum, reference):
    def full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tempfile, "mkstemp", full)
    with pytest.warns(cache.CacheDirWarning, match="could not store the rendered sources") as record:
        system = compile_model(pendulum, methods=("rk4",))
    assert any(cache.ENV_VAR in str(w.message) and str(fresh_cache) in str(w.message) for w in record)
    assert np.array_equal(rhs(system), reference)


def test_explicit_cache_dir_that_cannot_be_used_is_an_error(fresh_cache, tmp_path, pendulum):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    with pytest.raises(cache.CacheDirError) as info:
        compile_model(pendulum, methods=("rk4",), cache_dir=blocker)
    assert str(blocker) in str(info.value) and "not a directory" in str(info.value)


def test_no_fallback_either_is_an_error_naming_both(fresh_cache, tmp_path, monkeypatch, pendulum):
    blocker = tmp_path / "blocker"
    blocker.write_text("x")
    monkeypatch.setenv(cache.ENV_VAR, str(blocker))

    def nowhere(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(tempfile, "mkdtemp", nowhere)
    with pytest.warns(cache.CacheDirWarning), pytest.raises(cache.CacheDirError) as info:
        compile_model(pendulum, methods=("rk4",))
    message = str(info.value)
    assert str(blocker) in message and tempfile.gettempdir() in message and cache.ENV_VAR in message
