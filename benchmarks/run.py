"""The one benchmark command: speed and memory of lagcodegen against named peers, same run.

    python benchmarks/run.py [suite ...] [--quick] [--timeout SECONDS] [--out FILE] [--list]

With no suite named, every suite runs. Each suite prints a plain-text table and its goal lines
(PASS / FAIL / UNDECIDED / NOT RUN, computed from the numbers just measured); ``--out`` also
writes everything as JSON. Goal failures are results, not errors: the exit code is 0 whenever
the suites ran.

Suite protocol
--------------
A suite is a file ``benchmarks/bench_<name>.py``; ``<name>`` is what you type. `SUITES`
(name -> module name) is built from those file names, so adding a suite touches no other file.
A suite module

1. imports only the standard library at module level; peers, sympy and lagcodegen are imported
   inside functions, so ``--help`` and ``--list`` never need them;
2. defines ``DESCRIPTION``, one line for ``--list``;
3. may define ``add_arguments(group)``, adding its own options to an argparse group, spelled
   ``--<name>-<option>`` so suites never clash;
4. defines ``run(options) -> dict`` with

   - ``"table"``: str, printed verbatim; its header lines state the units, what the timer
     covers, how memory is measured, the peers' versions and the time-out;
   - ``"rows"``: list of JSON-serialisable dicts, one per measurement;
   - ``"goals"``: list of ``{"goal": str, "status": "PASS"|"FAIL"|"UNDECIDED"|"NOT RUN",
     "detail": str}``, computed from ``rows``;

   ``options`` is the parsed namespace: ``quick`` (bool), ``timeout`` (float, or None for the
   suite's own default) and the suite's own options;
5. measures lagcodegen and its peers side by side in the same run, each measurement in a fresh
   process under a hard time-out (`bench_derive.run_in_subprocess` does this), and reports
   progress on stderr; the report goes to stdout.
"""
from __future__ import annotations

import argparse
import importlib
import json
import os
import platform
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
SUITES = {path.stem[len("bench_"):]: path.stem for path in sorted(HERE.glob("bench_*.py"))}


def load_suite(name: str):
    """The module of suite ``name``."""
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    return importlib.import_module(SUITES[name])


def make_parser(modules: dict) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        description="Benchmarks of lagcodegen against named peers, measured side by side.")
    parser.add_argument("suites", nargs="*", metavar="suite",
                        help=f"suites to run (default: all): {', '.join(SUITES)}")
    parser.add_argument("--quick", action="store_true", help="small sizes only, for a smoke run")
    parser.add_argument("--timeout", type=float, default=None, metavar="SECONDS",
                        help="hard time-out per measurement (default: each suite's own)")
    parser.add_argument("--out", type=Path, default=None, metavar="FILE",
                        help="also write environment, tables, rows and goals as JSON")
    parser.add_argument("--list", action="store_true", help="list the suites and exit")
    for name, module in modules.items():
        if hasattr(module, "add_arguments"):
            module.add_arguments(parser.add_argument_group(f"suite {name}"))
    return parser


def environment() -> dict:
    """What the numbers depend on: interpreter, machine, lagcodegen version and commit."""
    from lagcodegen import __version__

    cpu = platform.processor() or platform.machine()
    cpuinfo = Path("/proc/cpuinfo")
    if cpuinfo.exists():
        models = [line.split(":", 1)[1].strip() for line in cpuinfo.read_text().splitlines()
                  if line.startswith("model name")]
        cpu = models[0] if models else cpu
    try:
        commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=HERE, text=True,
                                capture_output=True, check=True).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "unknown"
    return {"python": platform.python_version(), "platform": platform.platform(), "cpu": cpu,
            "cpu_count": os.cpu_count(), "lagcodegen": __version__, "commit": commit}


def format_goals(goals: list) -> str:
    return "\n".join(f"{g['status']:<9} {g['goal']}: {g['detail']}" for g in goals)


def main(argv: list | None = None) -> int:
    modules = {name: load_suite(name) for name in SUITES}
    parser = make_parser(modules)
    options = parser.parse_args(argv)
    if options.list:
        print("\n".join(f"{name:<12} {module.DESCRIPTION}" for name, module in modules.items()))
        return 0
    unknown = [s for s in options.suites if s not in SUITES]
    if unknown:
        parser.error(f"unknown suite(s) {', '.join(unknown)}; suites: {', '.join(SUITES)}")
    env = environment()
    print("environment: " + ", ".join(f"{k} {v}" for k, v in env.items()), flush=True)
    report = {"environment": env, "suites": {}}
    for name in options.suites or list(SUITES):
        result = modules[name].run(options)
        print(f"\n== {name} ==\n{result['table']}\n\n{format_goals(result['goals'])}", flush=True)
        report["suites"][name] = result
    if options.out is not None:
        options.out.write_text(json.dumps(report, indent=2) + "\n")
        print(f"\nwrote {options.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
