"""The top-level CMakeLists.txt configures, builds generated/ warning-free (-Werror) and ctest runs
one C test per generated library, each checking M, F and ud against sympy at 30 digits."""
from __future__ import annotations

import re
import subprocess

import pytest

pytestmark = pytest.mark.compiler


def run(argv, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=600, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stdout[-4000:]}\n{result.stderr[-4000:]}"
    return result


def test_cmake_builds_and_ctest_passes(repo_root, tmp_path, require_tool):
    cmake, ctest = require_tool("cmake"), require_tool("ctest")
    require_tool("cc")  # CMake's default C compiler
    build = tmp_path / "build"
    run([cmake, "-S", repo_root, "-B", build])  # default build type: no -O, half the build time
    run([cmake, "--build", build, "-j2"])
    tested = run([ctest, "--test-dir", build, "--output-on-failure"])
    print(tested.stdout)
    libraries = sorted(p.stem for p in (repo_root / "generated").glob("*/lcg_*.c"))
    assert libraries, "no generated libraries found"
    summary = re.search(r"(\d+)% tests passed, (\d+) tests failed out of (\d+)", tested.stdout)
    assert summary, tested.stdout
    assert summary.groups() == ("100", "0", str(len(libraries))), summary.group(0)
    ran = sorted(re.findall(r"Test +#\d+: (\S+) \.+\s+Passed", tested.stdout))
    assert ran == libraries, f"ctest ran {ran}, expected one test per library {libraries}"
