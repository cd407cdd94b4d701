"""Helper: where compiled modules live on disk, their keys, and atomic installation.

Used by ``build.py``; imports no pipeline stage.

An *entry* is a directory ``<cache dir>/<module name>/`` holding the extension module
(``.so``), the C sources it was built from, and the marker file :data:`MARKER`, whose
first line is the source key and whose second line is the sha256 of the ``.so``. Entries
are built in a private temporary directory inside the cache dir and installed with one
``os.replace``, so a reader sees either no entry or a complete one (numba's
``_open_for_write`` in ``numba/core/caching.py`` does the same for its index files).
"""
from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

__all__ = [
    "ENV_VAR", "MARKER", "cache_dir", "source_key", "new_build_dir", "write_marker",
    "entry_problem", "install_entry", "evict_entry", "keep_failed", "file_sha256",
]

ENV_VAR = "LAGCODEGEN_CACHE_DIR"
MARKER = "lcg-entry.txt"
_TMP_PREFIX = ".tmp-"


def cache_dir(override: str | os.PathLike | None = None) -> Path:
    """The cache directory, created if missing.

    Order: ``override``, ``$LAGCODEGEN_CACHE_DIR``, ``$XDG_CACHE_HOME/lagcodegen``,
    ``%LOCALAPPDATA%/lagcodegen`` on Windows, ``~/.cache/lagcodegen``.
    """
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
    """Write :data:`MARKER` into a not yet installed entry: key, then the ``.so`` checksum."""
    text = f"{key}\n{file_sha256(entry / so_name)}\n"
    (entry / MARKER).write_text(text, encoding="ascii")


def entry_problem(entry: Path, key: str, so_name: str) -> str | None:
    """``None`` if ``entry`` is complete and matches ``key``, else what is wrong with it.

    Checks that the entry exists, that its marker names ``key`` and that the ``.so`` exists
    and has the recorded checksum (a truncated or overwritten file fails here, before any
    attempt to load it).
    """
    if not entry.is_dir():
        return "missing"
    try:
        lines = (entry / MARKER).read_text(encoding="ascii").split()
    except (OSError, UnicodeDecodeError):
        return f"marker {MARKER} missing or unreadable"
    if len(lines) != 2 or lines[0] != key:
        return f"marker {MARKER} does not match key {key}"
    so_path = entry / so_name
    if not so_path.is_file():
        return f"{so_name} missing"
    if file_sha256(so_path) != lines[1]:
        return f"{so_name} does not match its recorded checksum (truncated or overwritten)"
    return None


def evict_entry(entry: Path) -> None:
    """Move a corrupt entry out of the way (atomically), then delete it.

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
    ``entry`` first; then ``built`` is deleted and the caller uses the existing entry.
    """
    try:
        os.replace(built, entry)
        return True
    except OSError:
        # Linux: ENOTEMPTY/EEXIST, Windows: access denied. Only a lost race gets here with an
        # existing entry; anything else (e.g. permissions) surfaces when the entry is checked.
        if not entry.is_dir():
            raise
        shutil.rmtree(built, ignore_errors=True)
        return False


def keep_failed(built: Path, root: Path, name: str) -> Path:
    """Move a failed build directory to ``<root>/failed/<name>`` for inspection; return it."""
    kept = root / "failed" / name
    kept.parent.mkdir(parents=True, exist_ok=True)
    evict_entry(kept)
    try:
        os.replace(built, kept)
    except OSError:  # a concurrent failure kept its copy first; keep ours where it is
        return built
    return kept
