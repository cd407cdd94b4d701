"""Shared fixtures: the ``--update-golden`` option, the repository root, fixed seeds, tool
checks and the catalog examples compiled once per session.

- ``require_tool(name)`` skips a test when an external program (cmake, arm-none-eabi-gcc, ...)
  is missing, but FAILS it when the environment variable ``CI`` is set: on CI a missing
  toolchain is a broken image, not a reason to go green.
- Under ``CI`` a session in which a toolchain test (marked ``compiler``, or in
  ``tests/native_build/``) was skipped anyway, by any other route (a ``skipif``, a bare
  ``pytest.skip``), fails: the summary lists those tests and the exit status is 1.
- ``compiled_example(name, precision="double", ...)`` compiles a catalog example through
  ``lagcodegen.pipeline.compile_model`` once per session (cached by name, precision, outputs,
  fixed parameters and methods) into an isolated cache dir under ``tmp_path_factory``,
  exported as ``LAGCODEGEN_CACHE_DIR`` for the session and restored afterwards.
"""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

#: pytester runs the inner sessions that test the CI hooks below (tests/native_build/test_ci_skips.py)
pytest_plugins = ("pytester",)

#: every random number in the tests derives from this seed
SEED = 20240611
REPO_ROOT = Path(__file__).resolve().parents[1]
#: tools/ holds maintenance scripts the tests import (regenerate.py); they are not in the package
sys.path.insert(0, str(REPO_ROOT / "tools"))
#: every output the pipeline can generate (kernel tests compare all of them)
ALL_OUTPUTS = ("mass_matrix", "forcing", "accel", "rhs", "energy", "points", "jacobian")


def pytest_addoption(parser):
    parser.addoption("--update-golden", action="store_true", default=False,
                     help="rewrite generated/ (tools/regenerate.py, write_generated) instead of "
                          "failing when the regenerated C differs from it")


@pytest.fixture(scope="session")
def update_golden(request) -> bool:
    """True when pytest runs with ``--update-golden``."""
    return bool(request.config.getoption("--update-golden"))


@pytest.fixture(scope="session")
def repo_root() -> Path:
    """The lagcodegen checkout (holds ``generated/``, ``CMakeLists.txt``, ``templates/``)."""
    return REPO_ROOT


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh generator with the fixed seed: every test sees the same numbers."""
    return np.random.default_rng(SEED)


def in_ci() -> bool:
    """True when the environment variable ``CI`` is set to anything but "", 0, false or no."""
    return os.environ.get("CI", "").strip().lower() not in ("", "0", "false", "no")


def require_tool(name: str) -> str:
    """Full path of the program ``name``; skip if missing, or fail when ``$CI`` is set."""
    path = shutil.which(name)
    if path is None:
        message = f"required tool {name!r} not found on PATH"
        if in_ci():
            pytest.fail(f"{message} (CI is set: a missing tool is an error, not a skip)")
        pytest.skip(message)
    return path


# --- under CI, a skipped toolchain test fails the session ----------------------------------
#: the folder of the toolchain tests: every test in it counts, marked ``compiler`` or not
TOOLCHAIN_FOLDER = "native_build"


class ToolchainSkipGuard:
    """Under ``CI``, fails the session when a toolchain test was skipped.

    ``require_tool`` already fails instead of skipping on CI, but a ``skipif`` or a bare
    ``pytest.skip`` in a toolchain test would still turn a broken CI image green.
    """

    def __init__(self):
        self.skipped = []  # "nodeid: reason"

    @staticmethod
    def is_toolchain_test(report) -> bool:
        return "compiler" in report.keywords or TOOLCHAIN_FOLDER in Path(report.nodeid.split("::")[0]).parts

    def pytest_runtest_logreport(self, report):
        # an expected failure (xfail) is reported as skipped too: it is not a skip here
        if report.skipped and not hasattr(report, "wasxfail") and self.is_toolchain_test(report):
            reason = report.longrepr[2] if isinstance(report.longrepr, tuple) else str(report.longrepr)
            self.skipped.append(f"{report.nodeid}: {reason}")

    def pytest_sessionfinish(self, session, exitstatus):
        if in_ci() and self.skipped and exitstatus == pytest.ExitCode.OK:
            session.exitstatus = pytest.ExitCode.TESTS_FAILED

    def pytest_terminal_summary(self, terminalreporter):
        if in_ci() and self.skipped:
            terminalreporter.section("toolchain tests skipped under CI", sep="=", red=True, bold=True)
            for line in self.skipped:
                terminalreporter.line(f"SKIPPED (fails the session: CI is set) {line}", red=True)


@pytest.fixture(scope="session")
def ctest_summary():
    """(percent passed, failed, total) from ctest's output, or None: ctest 3.x prints "100% tests
    passed, 0 tests failed out of N", 4.x (the cmake wheel FMPy pulls in) leaves out a zero count."""
    import re

    def parse(stdout: str):
        found = re.search(r"(\d+)% tests passed(?:, (\d+) tests failed)? out of (\d+)", stdout)
        return None if found is None else (found.group(1), found.group(2) or "0", found.group(3))
    return parse


def pytest_configure(config):
    config.pluginmanager.register(ToolchainSkipGuard(), "lagcodegen-toolchain-skip-guard")


@pytest.fixture(name="require_tool", scope="session")
def _require_tool_fixture():
    """``require_tool`` as a fixture, for test modules (conftest is not importable by name)."""
    return require_tool


@pytest.fixture(scope="session", autouse=True)
def kernel_cache_dir(tmp_path_factory):
    """A private lagcodegen cache dir, exported as ``LAGCODEGEN_CACHE_DIR`` for the session.

    Autouse: no test, fixture or module-level compile writes into the user's own cache.

    Session scope cannot use ``monkeypatch``, so the old value is saved and restored by hand.
    """
    path = tmp_path_factory.mktemp("lagcodegen_cache")
    saved = os.environ.get("LAGCODEGEN_CACHE_DIR")
    os.environ["LAGCODEGEN_CACHE_DIR"] = str(path)
    try:
        yield path
    finally:
        if saved is None:
            os.environ.pop("LAGCODEGEN_CACHE_DIR", None)
        else:
            os.environ["LAGCODEGEN_CACHE_DIR"] = saved


@pytest.fixture(scope="session")
def example_eom():
    """``example_eom(name)``: derived equations of a catalog example, derived once per session."""
    from lagcodegen import catalog, derive_equations

    memo: dict = {}

    def get(name: str):
        if name not in memo:
            memo[name] = derive_equations(catalog.example(name))
        return memo[name]

    return get


@pytest.fixture(scope="session")
def compiled_example(kernel_cache_dir, example_eom):
    """``compiled_example(name, precision="double", outputs=None, fixed=None, methods=(), **lane_options)``.

    Compiles a catalog example once per session through ``compile_model``. ``outputs=None``
    means every output the model has (``ALL_OUTPUTS`` minus energy when it has no energies);
    ``methods=()`` compiles no integrators, which keeps the build fast for kernel tests.
    ``lane_options`` (``lanes``, ``lane_trig``) go to ``compile_model``.
    """
    from lagcodegen.pipeline import compile_model

    memo: dict = {}

    def get(name: str, precision: str = "double", outputs=None, fixed=None, methods=(), **lane_options):
        eom = example_eom(name)
        if outputs is None:
            outputs = tuple(o for o in ALL_OUTPUTS if not (o == "energy" and eom.energy is None))
        fixed_key = tuple(sorted((str(k), float(v)) for k, v in (fixed or {}).items()))
        key = (name, precision, tuple(outputs), fixed_key, tuple(methods), tuple(sorted(lane_options.items())))
        if key not in memo:
            memo[key] = compile_model(eom, outputs=outputs, fixed=fixed, methods=tuple(methods),
                                      precision=precision, **lane_options)
        return memo[key]

    return get


@pytest.fixture(scope="session")
def cart_pole_example():
    """examples/cart_pole_lqr.py as a module: its cart-pole model, gains and C emitter."""
    import importlib.util

    spec = importlib.util.spec_from_file_location("cart_pole_lqr", REPO_ROOT / "examples" / "cart_pole_lqr.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def driven_oscillator_model(name: str = "driven_oscillator", **extra):
    """m x'' + c x' + k x = F with the input F (m, k, c = 1, 4, 0.5): the driven tests' plant."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model

    x, F = me.dynamicsymbols("x F")
    m, k, c = sp.symbols("m k c", positive=True)
    measurements = {key: build(x, F, m, k, c) for key, build in extra.pop("measurements", {}).items()}
    return Model(name, [x], [m, k, c], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=k * x ** 2 / 2,
                 generalized_forces={x: F - c * x.diff()}, inputs=[F], parameter_values={"m": 1.0, "k": 4.0, "c": 0.5},
                 measurements=measurements, **extra)


@pytest.fixture(scope="session")
def driven_oscillator():
    """`driven_oscillator_model`, the builder."""
    return driven_oscillator_model
