"""The lint configuration in pyproject.toml ([tool.ruff]) holds for the whole repository."""
from __future__ import annotations

import shutil
import subprocess

import pytest


def test_ruff_is_clean(repo_root):
    ruff = shutil.which("ruff")
    if ruff is None:  # the test extra installs it; a bare checkout without it cannot lint
        pytest.skip("ruff is not installed (pip install -e '.[test]')")
    result = subprocess.run([ruff, "check", "src", "tests", "tools", "benchmarks", "examples"], cwd=repo_root,
                            capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stdout + result.stderr
