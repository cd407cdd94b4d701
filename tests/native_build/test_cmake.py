"""The top-level CMakeLists.txt configures, builds generated/ warning-free (-std=c99 -Wall -Wextra
-Wpedantic -Werror) with gcc and with clang, whose warnings differ (clang rejects an unused static
inline function, gcc does not), and ctest runs one C test per generated library, each checking
M, F and ud against sympy at 30 digits."""
from __future__ import annotations

import re
import subprocess

import pytest

pytestmark = pytest.mark.compiler

#: CMake's CMAKE_C_COMPILER_ID of each compiler
COMPILER_IDS = {"gcc": "GNU", "clang": "Clang"}


def run(argv, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=600, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stdout[-4000:]}\n{result.stderr[-4000:]}"
    return result


@pytest.mark.parametrize("compiler", sorted(COMPILER_IDS))
def test_cmake_builds_and_ctest_passes(compiler, repo_root, tmp_path, require_tool, ctest_summary):
    cmake, ctest, cc = require_tool("cmake"), require_tool("ctest"), require_tool(compiler)
    build = tmp_path / "build"
    # default build type: no -O, half the build time
    run([cmake, "-S", repo_root, "-B", build, f"-DCMAKE_C_COMPILER={cc}"])
    # the compiler CMake identified (a "gcc" that is clang in disguise would test nothing new)
    identified = "".join(p.read_text() for p in build.glob("CMakeFiles/*/CMakeCCompiler.cmake"))
    assert f'set(CMAKE_C_COMPILER_ID "{COMPILER_IDS[compiler]}")' in identified, identified[:500]
    run([cmake, "--build", build, "-j2"])
    tested = run([ctest, "--test-dir", build, "-j2", "--output-on-failure"])
    print(tested.stdout)
    libraries = sorted(p.stem for p in (repo_root / "generated").glob("*/lcg_*.c"))
    assert libraries, "no generated libraries found"
    assert ctest_summary(tested.stdout) == ("100", "0", str(len(libraries))), tested.stdout[-2000:]
    ran = sorted(re.findall(r"Test +#\d+: (\S+) \.+\s+Passed", tested.stdout))
    assert ran == libraries, f"ctest ran {ran}, expected one test per library {libraries}"
