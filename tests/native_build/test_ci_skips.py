"""Under ``CI`` a toolchain test cannot pass by not running: ``require_tool`` fails instead of
skipping, and a toolchain test (marked ``compiler``, or in ``tests/native_build/``) skipped any
other way fails the session (``ToolchainSkipGuard`` in tests/conftest.py).

Each test runs a small inner pytest session whose conftest is tests/conftest.py itself, so
removing the guard or the CI branch of ``require_tool`` there makes these tests fail.
"""
from __future__ import annotations

import pytest

INNER_TESTS = {
    # a test in the toolchain folder, not marked: skipped by a bare pytest.skip
    "native_build/test_folder.py": "import pytest\n\n"
                                   "def test_in_folder():\n    pytest.skip('no tool here')\n",
    # a marked test elsewhere, skipped by skipif
    "numeric/test_marked.py": "import pytest\n\n"
                              "@pytest.mark.compiler\n@pytest.mark.skipif(True, reason='no compiler')\n"
                              "def test_marked():\n    pass\n",
    # neither: its skip is nobody's business
    "numeric/test_unrelated.py": "import pytest\n\n"
                                 "def test_unrelated():\n    pytest.skip('optional dependency missing')\n",
    # an expected failure in the toolchain folder is not a skip
    "native_build/test_xfail.py": "import pytest\n\n"
                                  "@pytest.mark.xfail(reason='known', strict=True)\n"
                                  "def test_known_bug():\n    assert False\n",
    "numeric/test_passes.py": "def test_passes():\n    assert True\n",
}


@pytest.fixture
def inner(pytester, repo_root):
    """A pytester folder with tests/conftest.py as its conftest; run(*names, ci=...) runs the
    named inner test files (keys of INNER_TESTS) with or without CI set."""
    pytester.makeconftest((repo_root / "tests" / "conftest.py").read_text())
    pytester.makeini("[pytest]\nmarkers =\n    compiler: needs a C toolchain\n")
    for path, text in INNER_TESTS.items():
        target = pytester.path / path
        target.parent.mkdir(exist_ok=True)
        target.write_text(text)

    def run(*names, ci: bool):
        with pytest.MonkeyPatch.context() as patch:
            if ci:
                patch.setenv("CI", "true")
            else:
                patch.delenv("CI", raising=False)
            # a subprocess: an in-process inner session crashed the outer one (SIGSEGV) after
            # many cffi modules were loaded
            return pytester.runpytest_subprocess("-p", "no:cacheprovider", "-rs", *names)

    return run


@pytest.mark.parametrize("skipped", ["native_build/test_folder.py", "numeric/test_marked.py"])
def test_a_skipped_toolchain_test_fails_the_session_under_ci(inner, skipped):
    result = inner(skipped, "numeric/test_passes.py", "numeric/test_unrelated.py", ci=True)
    assert result.ret == pytest.ExitCode.TESTS_FAILED, result.stdout.str()
    lines = result.stdout.lines
    start = next(i for i, line in enumerate(lines) if "toolchain tests skipped under CI" in line) + 1
    section = lines[start:next(i for i in range(start, len(lines)) if lines[i].startswith("="))]
    listed = [line for line in section if line.startswith("SKIPPED")]
    assert len(listed) == 1 and f"{skipped}::" in listed[0], section  # and not test_unrelated


@pytest.mark.parametrize("ci", [False, True])
def test_other_skips_and_expected_failures_pass(inner, ci):
    result = inner("numeric/test_passes.py", "numeric/test_unrelated.py", "native_build/test_xfail.py", ci=ci)
    result.assert_outcomes(passed=1, skipped=1, xfailed=1)
    assert result.ret == pytest.ExitCode.OK, result.stdout.str()


def test_toolchain_skips_pass_without_ci(inner):
    result = inner("native_build/test_folder.py", "numeric/test_marked.py", ci=False)
    result.assert_outcomes(skipped=2)
    assert result.ret == pytest.ExitCode.OK, result.stdout.str()


def test_require_tool_fails_under_ci_and_skips_otherwise(inner, pytester):
    pytester.makepyfile(test_tool="def test_tool(require_tool):\n    require_tool('lcg-no-such-tool-4f2a')\n")
    under_ci = inner("test_tool.py", ci=True)
    under_ci.assert_outcomes(failed=1)
    under_ci.stdout.fnmatch_lines(["*'lcg-no-such-tool-4f2a' not found on PATH (CI is set*"])
    inner("test_tool.py", ci=False).assert_outcomes(skipped=1)
