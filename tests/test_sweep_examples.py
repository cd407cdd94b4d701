"""The ``examples/sweep_*.py`` scripts run with ``--quick`` (tiny grid, short horizon) and write
their figure to ``--out`` in a temp dir, so docs/ is never touched.

`tests/test_examples.py` skips these scripts because their full size takes ~20-40 s each; the
docs figures come from full-size runs. The physics checks inside the scripts still run here:
sweep_double_pendulum exits non-zero if a member flips where its energy forbids it; for
sweep_elastic_pendulum the ridge found on the quick 10 x 6 grid must lie on the 2:1 resonance
curve k l0 = 3 m g (theory: sqrt(k/m) = 2 sqrt(g/r0), r0 = l0 + m g / k) to within two grid
steps in k (x1.58 each).
"""
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SCRIPTS = sorted(EXAMPLES.glob("sweep_*.py"))
PNG_MAGIC = b"\x89PNG\r\n\x1a\n"

pytestmark = pytest.mark.compiler


def run_quick(script: Path, out: Path, cache: Path) -> str:
    env = {**os.environ, "LAGCODEGEN_CACHE_DIR": str(cache), "PYTHONIOENCODING": "utf-8"}
    result = subprocess.run([sys.executable, str(script), "--quick", "--out", str(out), "--threads", "2"],
                            cwd=EXAMPLES.parent, env=env, capture_output=True, text=True, encoding="utf-8",
                            timeout=300)
    assert result.returncode == 0, f"{script.name} failed:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
    assert out.read_bytes()[:8] == PNG_MAGIC, f"{script.name} did not write a PNG to {out}"
    assert f"wrote {out}" in result.stdout
    return result.stdout


def test_sweep_examples_are_found():
    assert {p.name for p in SCRIPTS} >= {"sweep_elastic_pendulum.py", "sweep_double_pendulum.py"}


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_sweep_example_quick(script, tmp_path, kernel_cache_dir):
    out = tmp_path / "figure.png"
    stdout = run_quick(script, out, kernel_cache_dir)
    assert "0 failed" in stdout or "failed members: 0" in stdout
    if script.name == "sweep_elastic_pendulum.py":
        match = re.search(r"ridge k / theory k over all \d+ rows: median ([\d.]+)", stdout)
        assert match, stdout
        assert 1 / 1.58 ** 2 < float(match.group(1)) < 1.58 ** 2
    if script.name == "sweep_double_pendulum.py":
        assert "of which flipped: 0" in stdout
