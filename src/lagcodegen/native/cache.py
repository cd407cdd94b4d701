"""Helper: where compiled modules live on disk, their keys, and atomic installation.

Used by ``build.py`` and ``pipeline.py``; imports no pipeline stage.

An *entry* is a directory ``<cache dir>/<module name>/`` holding the extension module
(``.so``), the C sources it was built from, and the marker file :data:`MARKER`, a JSON
object with the source key and the sha256 of every other file in the entry. Nothing is
loaded before all of them match (:func:`entry_problem`): a truncated, edited or replaced
file, or a path of the wrong kind, makes the entry rebuild instead of reaching ``dlopen``.
Entries are built in a private temporary directory inside the cache dir and installed with
one ``os.replace``, so a reader sees either no entry or a complete one (numba's
``_open_for_write`` in ``numba/core/caching.py`` does the same for its index files).

A cache dir that cannot be used (not creatable, not a directory, read-only, full) is
replaced by one temporary directory per process with a :class:`CacheDirWarning` naming it
(:func:`cache_dir`, :func:`fallback_dir`); only a ``cache_dir`` argument given explicitly
raises :class:`CacheDirError` instead.
"""
from __future__ import annotations

import atexit
import errno
import hashlib
import json
import os
import shutil
import sys
import tempfile
import warnings
from pathlib import Path

__all__ = [
    "ENV_VAR", "MARKER", "CacheDirError", "CacheDirWarning", "cache_dir", "fallback_dir",
    "unwritable", "subdir", "source_key", "new_build_dir", "write_marker", "entry_problem",
    "install_entry", "evict_entry", "keep_failed", "file_sha256", "user_stacklevel",
]

ENV_VAR = "LAGCODEGEN_CACHE_DIR"
MARKER = "lcg-entry.json"
_TMP_PREFIX = ".tmp-"
#: errors that mean "this directory cannot take our files", as opposed to a bug or a bad build
_UNWRITABLE = frozenset({errno.EACCES, errno.EPERM, errno.EROFS, errno.ENOSPC, errno.EDQUOT,
                         errno.ENOTDIR, errno.ENAMETOOLONG})
_WRITABLE: set = set()  # directories that passed the write probe in this process
_FALLBACK: dict = {}  # "dir" -> this process's temporary cache dir, once created
_WARNED: set = set()


class CacheDirError(OSError):
    """The cache directory cannot be used; the message names it and says what to do."""


class CacheDirWarning(UserWarning):
    """The cache directory cannot be used; a temporary one serves this process instead."""


def cache_dir(override: str | os.PathLike | None = None) -> Path:
    """The cache directory, created if missing, writable.

    Order: ``override``, ``$LAGCODEGEN_CACHE_DIR``, ``$XDG_CACHE_HOME/lagcodegen``,
    ``%LOCALAPPDATA%/lagcodegen`` on Windows, ``~/.cache/lagcodegen``.

    Raises
    ------
    CacheDirError
        ``override`` is given and cannot be used. Any other directory that cannot be used is
        replaced by :func:`fallback_dir` (with a :class:`CacheDirWarning`).
    """
    explicit = override is not None
    if override is None:
        override = os.environ.get(ENV_VAR) or None
    if override is not None:
        path = Path(override)
    elif os.environ.get("XDG_CACHE_HOME"):
        path = Path(os.environ["XDG_CACHE_HOME"]) / "lagcodegen"
    elif os.name == "nt" and os.environ.get("LOCALAPPDATA"):
        path = Path(os.environ["LOCALAPPDATA"]) / "lagcodegen"
    else:
        path = Path.home() / ".cache" / "lagcodegen"
    path = path.expanduser().resolve()
    problem = _dir_problem(path)
    if problem is None:
        return path
    if explicit:
        raise CacheDirError(f"cache directory {path} (the cache_dir argument) {problem}; "
                            "pass a writable directory")
    return fallback_dir(path, problem)


def _dir_problem(path: Path) -> str | None:
    """``None`` if ``path`` is (now) a writable directory, else what is wrong with it."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return "exists but is not a directory"
    except OSError as exc:
        return f"cannot be created ({exc.strerror or exc})"
    if path in _WRITABLE:
        return None
    try:  # as root, permission bits do not stop writes: only trying tells
        os.rmdir(tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}probe-", dir=path))
    except OSError as exc:
        return f"is not writable ({exc.strerror or exc})"
    _WRITABLE.add(path)
    return None


def unwritable(exc: BaseException) -> bool:
    """True if ``exc`` says a directory cannot take files (read-only, full, wrong kind)."""
    return isinstance(exc, OSError) and exc.errno in _UNWRITABLE


def fallback_dir(failed: Path, problem: str) -> Path:
    """This process's temporary cache dir (created once, deleted at exit), after a warning
    that names ``failed`` and ``problem``.

    Raises
    ------
    CacheDirError
        The temporary directory cannot be created either.
    """
    if failed not in _WARNED:
        _WARNED.add(failed)
        warnings.warn(CacheDirWarning(
            f"cache directory {failed} {problem}; set {ENV_VAR} to a writable directory. "
            f"Using a temporary directory for this process instead: builds will not be reused"),
            stacklevel=user_stacklevel())
    if "dir" not in _FALLBACK:
        try:
            _FALLBACK["dir"] = Path(tempfile.mkdtemp(prefix="lagcodegen-cache-")).resolve()
        except OSError as exc:
            raise CacheDirError(f"cache directory {failed} {problem}, and no temporary directory "
                                f"could be created in {tempfile.gettempdir()} ({exc.strerror or exc}); "
                                f"set {ENV_VAR} to a writable directory") from None
        atexit.register(shutil.rmtree, _FALLBACK["dir"], True)
    return _FALLBACK["dir"]


def user_stacklevel() -> int:
    """``stacklevel`` for ``warnings.warn`` called right here that points at the first frame
    outside lagcodegen (the user's call of ``compile_model`` or ``build_module``)."""
    package = str(Path(__file__).resolve().parents[1])  # lagcodegen/, above this subpackage
    frame, level = sys._getframe(1), 1
    while frame is not None and str(Path(frame.f_code.co_filename).resolve()).startswith(package):
        frame, level = frame.f_back, level + 1
    return level


def subdir(root: Path, name: str) -> Path:
    """``root / name`` as a directory; a file of that name (a damaged cache) is removed first."""
    path = root / name
    if path.exists() and not path.is_dir():
        evict_entry(path)
    path.mkdir(parents=True, exist_ok=True)
    return path


def source_key(parts: dict[str, str]) -> str:
    """sha256 hex digest of ``parts`` serialized canonically (sorted keys, JSON, UTF-8).

    Every value must be a ``str``: callers decide how flags or versions are spelled, and a
    silent ``str()`` of a list or a float could change between Python versions.
    """
    for name, value in parts.items():
        if not isinstance(name, str) or not isinstance(value, str):
            raise TypeError(f"source_key part {name!r} must map str to str, got {type(value).__name__}")
    text = json.dumps(parts, sort_keys=True, ensure_ascii=False, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def file_sha256(path: str | os.PathLike) -> str:
    """sha256 hex digest of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as fh:
        for block in iter(lambda: fh.read(1 << 20), b""):
            digest.update(block)
    return digest.hexdigest()


def new_build_dir(root: Path, name: str) -> Path:
    """A fresh private directory inside ``root`` (same filesystem, so ``os.replace`` is atomic)."""
    return Path(tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}{name}-", dir=root))


def write_marker(entry: Path, key: str, so_name: str) -> None:
    """Write :data:`MARKER` into a not yet installed entry: the key and the sha256 of every
    file in it (``so_name`` first among equals: it must be there)."""
    if not (entry / so_name).is_file():
        raise FileNotFoundError(f"{entry / so_name} was not built")
    files = {item.name: file_sha256(item) for item in sorted(entry.iterdir())
             if item.is_file() and item.name != MARKER}
    text = json.dumps({"key": key, "files": files}, sort_keys=True, separators=(",", ":"))
    (entry / MARKER).write_text(text, encoding="ascii")


def entry_problem(entry: Path, key: str, so_name: str) -> str | None:
    """``None`` if ``entry`` is complete and matches ``key``, else what is wrong with it.

    Checks, without loading anything, that the entry is a directory, that its marker names
    ``key`` and lists ``so_name``, and that every listed file is a regular file with its
    recorded sha256. A truncated, edited or swapped file, or a marker damaged in any byte,
    fails here, before any attempt to ``dlopen`` the ``.so``. Any other return than ``None``
    and ``"missing"`` means the entry must be evicted.
    """
    if not entry.exists():
        return "missing"
    if not entry.is_dir():
        return "is not a directory"
    try:
        marker = json.loads((entry / MARKER).read_bytes().decode("ascii"))
        recorded, files = marker["key"], marker["files"]
    except (OSError, ValueError, KeyError, TypeError) as exc:  # ValueError: bad ASCII or JSON
        return f"marker {MARKER} missing or unreadable ({type(exc).__name__})"
    if recorded != key:
        return f"marker {MARKER} does not match key {key}"
    if not isinstance(files, dict) or so_name not in files:
        return f"marker {MARKER} does not list {so_name}"
    for name, digest in files.items():
        path = entry / str(name)
        if path.name != name or path.is_symlink() or not path.is_file():
            return f"{name!r} is missing or not a regular file"
        if file_sha256(path) != digest:
            return f"{name} does not match its recorded checksum (truncated or overwritten)"
    return None


def evict_entry(entry: Path) -> None:
    """Move a corrupt entry (a directory, or a file where one belongs) out of the way
    atomically, then delete it.

    A concurrent process may evict the same entry first; that is not an error.
    """
    trash = Path(tempfile.mkdtemp(prefix=f"{_TMP_PREFIX}evicted-", dir=entry.parent))
    try:
        os.replace(entry, trash / entry.name)
    except FileNotFoundError:
        pass
    shutil.rmtree(trash, ignore_errors=True)


def install_entry(built: Path, entry: Path) -> bool:
    """Atomically rename the complete directory ``built`` to ``entry``.

    Returns ``True`` if ``built`` became the entry, ``False`` if another process installed
    ``entry`` first; then ``built`` is deleted and the caller uses the existing entry. A
    file where the entry belongs (a damaged cache) is evicted first.
    """
    for attempt in range(2):
        try:
            os.replace(built, entry)
            return True
        except OSError:
            # Linux: ENOTEMPTY/EEXIST, Windows: access denied. Only a lost race gets here with an
            # existing entry; anything else (e.g. permissions) is raised.
            if entry.is_dir():
                shutil.rmtree(built, ignore_errors=True)
                return False
            if attempt == 1 or not entry.exists():
                raise
            evict_entry(entry)
    raise AssertionError("unreachable")


def keep_failed(built: Path, root: Path, name: str) -> Path:
    """Move a failed build directory to ``<root>/failed/<name>`` for inspection; return it."""
    try:
        kept = subdir(root, "failed") / name
        evict_entry(kept)
        os.replace(built, kept)
    except OSError:  # a concurrent failure kept its copy first, or no room: keep ours where it is
        return built
    return kept
