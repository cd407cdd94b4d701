"""generated/ is exactly what the pipeline writes today, byte for byte, and deterministic.

Golden files prove "unchanged", never "correct" (correctness: tests/numeric and the C tests
that ctest runs). On a difference the test prints a unified diff and the hint to rewrite
generated/ with ``python -m pytest tests/golden --update-golden``, as ``compare_or_update`` in
symforce's ``test_util/test_case_mixin.py`` does. The committed files depend on sympy's printer
and CSE output, so the test extras pin sympy (pyproject ``test`` extra).
"""
from __future__ import annotations

import difflib
import hashlib
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest
from regenerate import example_files, write_generated

from lagcodegen.catalog import EXAMPLES

HINT = "python -m pytest tests/golden --update-golden"
NAMES = sorted(EXAMPLES)
#: a calendar date or a clock time: output must not depend on when it was generated
DATE = re.compile(r"\b(19|20)\d\d[-/.](0[1-9]|1[0-2])[-/.](0[1-9]|[12]\d|3[01])\b|\b\d\d:\d\d:\d\d\b")


def unified_diff(expected: str, got: str, name: str) -> str:
    lines = difflib.unified_diff(expected.splitlines(keepends=True), got.splitlines(keepends=True),
                                 fromfile=f"generated/{name} (committed)", tofile=f"{name} (regenerated)")
    return "".join(lines)


@pytest.fixture(scope="module")
def regenerated(tmp_path_factory, update_golden, repo_root):
    """Every example written by `write_generated` into a fresh directory (or into generated/
    itself under --update-golden, which then rewrites only files whose content changed)."""
    if update_golden:
        changed = write_generated(repo_root / "generated")
        print(f"--update-golden rewrote {len(changed)} file(s):", *map(str, changed), sep="\n  ")
        return repo_root / "generated"
    root = tmp_path_factory.mktemp("generated")
    write_generated(root)
    return root


@pytest.mark.parametrize("name", NAMES)
def test_generated_matches_committed(name, regenerated, repo_root):
    committed_dir, fresh_dir = repo_root / "generated" / name, regenerated / name
    fresh = {p.name: p.read_bytes() for p in sorted(fresh_dir.iterdir())}
    committed = {p.name: p.read_bytes() for p in sorted(committed_dir.glob("*"))} if committed_dir.is_dir() else {}
    problems = []
    for missing in sorted(set(fresh) - set(committed)):
        problems.append(f"generated/{name}/{missing} is missing")
    for stale in sorted(set(committed) - set(fresh)):
        problems.append(f"generated/{name}/{stale} is no longer generated")
    for filename in sorted(set(fresh) & set(committed)):
        if fresh[filename] != committed[filename]:
            problems.append(unified_diff(committed[filename].decode(), fresh[filename].decode(),
                                         f"{name}/{filename}"))
    if problems:
        pytest.fail("\n".join(problems) + f"\n\ngenerated/{name} is stale; if the change is intended, run\n"
                    f"    {HINT}\nand commit the result.", pytrace=False)


def test_no_stray_example_directories(repo_root):
    on_disk = {p.name for p in (repo_root / "generated").iterdir() if p.is_dir()}
    assert on_disk == set(NAMES), f"generated/ holds {sorted(on_disk - set(NAMES))} not in the catalog"


@pytest.mark.parametrize("name", NAMES)
def test_no_timestamps_or_paths(name, regenerated, repo_root):
    home = str(Path.home())
    for path in sorted((regenerated / name).iterdir()):
        text = path.read_text()
        for forbidden in {str(repo_root), str(regenerated), home, "/tmp/"}:
            assert forbidden not in text, f"{path.name} contains the path {forbidden}"
        match = DATE.search(text)
        assert match is None, f"{path.name} contains a date or time: {match.group(0)!r}"


_CHILD = """
import hashlib, sys
from regenerate import example_files
files = example_files(sys.argv[1])
for name in sorted(files):
    print(name, hashlib.sha256(files[name].encode()).hexdigest())
"""


def fresh_process_digest(name: str, hash_seed: str) -> str:
    tools = str(Path(__file__).resolve().parents[2] / "tools")
    env = {**os.environ, "PYTHONHASHSEED": hash_seed,
           "PYTHONPATH": os.pathsep.join(filter(None, [tools, os.environ.get("PYTHONPATH")]))}
    run = subprocess.run([sys.executable, "-c", _CHILD, name], capture_output=True, text=True, env=env,
                         timeout=300, check=False)
    assert run.returncode == 0, run.stderr
    return run.stdout


@pytest.mark.parametrize("name", ["double_pendulum"])
def test_deterministic_across_hash_seeds(name):
    """Set and dict order of symbols must not leak into the C: two fresh interpreters with
    different string hashing write identical bytes (and the same as this process)."""
    first, second = fresh_process_digest(name, "1"), fresh_process_digest(name, "4242")
    assert first == second, f"PYTHONHASHSEED changes the output:\n{first}\n{second}"
    here = "".join(f"{f} {hashlib.sha256(t.encode()).hexdigest()}\n" for f, t in sorted(example_files(name).items()))
    assert first == here
