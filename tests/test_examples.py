"""Every script in examples/ runs to completion (exit code 0) as ``python examples/<file>.py``.

Scripts named ``sweep_*`` or ``bench_*`` belong to the sweep and benchmark work and are skipped.
"""
import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parents[1] / "examples"
SKIPPED_PREFIXES = ("sweep_", "bench_")
SCRIPTS = sorted(p for p in EXAMPLES.glob("*.py") if not p.name.startswith(SKIPPED_PREFIXES))


@pytest.mark.parametrize("script", SCRIPTS, ids=[p.name for p in SCRIPTS])
def test_example_runs(script, tmp_path):
    # sympy.pretty prints unicode; what a script writes to a new temporary directory (animations.py's
    # GIFs, 0.5 MB a run) goes under tmp_path, not /tmp for good (found in session 21: 19 left there)
    env = {**os.environ, "PYTHONIOENCODING": "utf-8", "TMPDIR": str(tmp_path)}
    result = subprocess.run([sys.executable, str(script)], cwd=EXAMPLES.parent, env=env,
                            capture_output=True, text=True, encoding="utf-8", timeout=120)
    assert result.returncode == 0, f"{script.name} failed:\n{result.stdout[-2000:]}\n{result.stderr[-4000:]}"
    assert result.stdout.strip(), f"{script.name} printed nothing"


def test_examples_are_found():
    assert {"centrifugal_governor.py", "pendulum_chain.py"} <= {p.name for p in SCRIPTS}
