"""Every command and code block of README.md runs, so a README that breaks fails here.

What is extracted: fenced code blocks (```python ... ```) and indented (4-space) command lines,
with backslash continuations joined. How each kind runs:

- python blocks: exec'd in order in ONE namespace, as a reader pasting them into one session
  would (the sweep block uses the ``system`` compiled two blocks earlier), in a temporary working
  directory, building into the test session's private kernel cache (``kernel_cache_dir``).
- ``lagcodegen ...``: a subprocess in a temporary directory (the console script of the running
  Python's environment); exit code 0 and every file it was told to write (--out, --heatmap,
  --plot) exists.
- the install lines: the test command is exactly what ``.ci/run`` runs (checked character for
  character, and not run here: it is this test suite); the main-job line sets up the same venv
  and pip the same way (checked), then its ``lagcodegen demo`` runs.
- ``cmake ...``: run when cmake is present (``require_tool``: skipped locally, an error in CI),
  with the one documented substitution: the build directory ``build`` becomes a temporary one.
- ``pip install -e ".[bench]" && python benchmarks/run.py``: the extras are not installed here
  (no network in tests); ``benchmarks/run.py --list`` runs (imports every suite, lists them).
- ``python docs/make_charts.py``: ``--help`` runs (the charts take about a minute).

A command that matches none of these rules fails the test: a new README command needs a rule.
"""
from __future__ import annotations

import itertools
import os
import re
import shlex
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
README = REPO / "README.md"
#: the setup every install line of the README shares with .ci/run
VENV_SETUP = "python3 -m venv .venv && . .venv/bin/activate && pip install -q "
OUTPUT_OPTIONS = ("--out", "--heatmap", "--plot")


@dataclass(frozen=True)
class Block:
    kind: str   # "python", "command", or a fenced block's other language
    text: str
    line: int   # 1-based line in README.md


def readme_blocks(text: str) -> list[Block]:
    """Fenced blocks and indented command lines of ``text``, in order."""
    lines, blocks, i = text.splitlines(), [], 0
    while i < len(lines):
        if lines[i].startswith("```"):
            end = next(j for j in range(i + 1, len(lines)) if lines[j].startswith("```"))
            blocks.append(Block(lines[i][3:].strip() or "text", "\n".join(lines[i + 1:end]), i + 1))
            i = end + 1
        elif lines[i].startswith("    ") and lines[i].strip() and (i == 0 or not lines[i - 1].strip()):
            start, command = i, ""
            while i < len(lines) and lines[i].startswith("    "):
                command += lines[i].strip()
                if not command.endswith("\\"):
                    blocks.append(Block("command", command, start + 1))
                    command, start = "", i + 1
                else:
                    command = command[:-1].rstrip() + " "
                i += 1
        else:
            i += 1
    return blocks


def ci_command() -> str:
    """The command .ci/run runs (its last line that is not a comment)."""
    lines = [line for line in (REPO / ".ci" / "run").read_text().splitlines()
             if line.strip() and not line.lstrip().startswith("#")]
    return lines[-1].strip()


BLOCKS = readme_blocks(README.read_text())
COMMANDS = [b for b in BLOCKS if b.kind == "command"]
PYTHON = [b for b in BLOCKS if b.kind == "python"]


def run_shell(command: str, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess:
    """``command`` in bash, with the running interpreter's bin dir first on PATH (its python and
    lagcodegen console script) and the test session's environment (cache dir, PYTHONPATH)."""
    env = {**os.environ, "PATH": f"{Path(sys.executable).parent}{os.pathsep}{os.environ.get('PATH', '')}",
           "PYTHONIOENCODING": "utf-8", "MPLBACKEND": "Agg"}
    result = subprocess.run(["bash", "-c", command], cwd=cwd, env=env, capture_output=True, text=True, check=False,
                            timeout=timeout)
    assert result.returncode == 0, (f"README command failed ({result.returncode}): {command}\n"
                                    f"{result.stdout[-3000:]}\n{result.stderr[-3000:]}")
    return result


def run_lagcodegen(command: str, cwd: Path) -> None:
    run_shell(command, cwd)
    words = shlex.split(command)
    for option, value in itertools.pairwise(words):
        if option in OUTPUT_OPTIONS:
            assert (cwd / value).exists(), f"{command!r} did not write {value}"


def test_readme_has_blocks():
    # the parser still finds what it is meant to test (a README without blocks would pass vacuously)
    assert len(PYTHON) >= 4 and any(b.text.startswith("lagcodegen emit ") for b in COMMANDS)
    assert not [b for b in BLOCKS if b.kind not in ("python", "command")], "a fenced block no rule runs"


def test_readme_test_command_is_what_ci_runs():
    # The README says "Tests (what `.ci/run` runs)": the two must be the same command, character
    # for character. It is not run here: it is this very test suite, run by .ci/run.
    assert ci_command() in [b.text for b in COMMANDS]
    assert ci_command().startswith(VENV_SETUP)


@pytest.mark.compiler
@pytest.mark.parametrize("block", COMMANDS, ids=[f"line{b.line}" for b in COMMANDS])
def test_readme_command_runs(block, tmp_path, kernel_cache_dir, require_tool):
    command = block.text
    if command == ci_command():
        return  # .ci/run itself runs it; test_readme_test_command_is_what_ci_runs checks the text (a skip would trip the CI skip guard)
    elif command.startswith(VENV_SETUP):
        # the main-job line: the same venv and pip as .ci/run (checked above), installed here
        # already; what follows the install runs
        install, _, rest = command[len(VENV_SETUP):].partition(" && ")
        assert install == "." and rest.startswith("lagcodegen "), command
        run_lagcodegen(rest, tmp_path)
    elif command.startswith("lagcodegen "):
        run_lagcodegen(command, tmp_path)
    elif command.startswith("cmake "):
        require_tool("cmake")
        build = tmp_path / "build"  # the one substitution: the build dir is a temporary one
        run_shell(re.sub(r"(?<=\s)build\b", str(build), command), REPO)
    elif command == 'pip install -e ".[bench]" && python benchmarks/run.py':
        run_shell("python benchmarks/run.py --list", REPO)  # extras not installed in tests
    elif command == "python docs/make_charts.py":
        run_shell("python docs/make_charts.py --help", REPO)  # the charts take about a minute
    else:
        pytest.fail(f"README.md line {block.line}: no rule runs {command!r}; add one to {__file__}")


@pytest.mark.compiler
def test_readme_python_blocks_run(tmp_path, monkeypatch, kernel_cache_dir):
    monkeypatch.chdir(tmp_path)
    namespace: dict = {"__name__": "__readme__"}
    for block in PYTHON:
        exec(compile(block.text, f"README.md:{block.line}", "exec"), namespace)  # noqa: S102 (our README)
    # the blocks did what they say: a complete trajectory and a complete (Dask) sweep
    assert namespace["run"].ok and namespace["result"].completed
