"""The generated C of every catalog model runs clean under AddressSanitizer and
UndefinedBehaviorSanitizer (``-fsanitize=address,undefined -fno-sanitize-recover=all``, -O1),
built once per compiler (gcc and clang) by CMakeLists.txt with ``-DLCG_SANITIZE=ON``:

- the C tests in generated/ (kernels at a sample state, against sympy at 30 digits);
- one driver per library (``tests/native_build/c/drive_model.c``) that steps every compiled
  method (rk4, symplectic_euler, implicit_midpoint; projection for the constrained models)
  300 times, runs simulate and sweep with every output, and checks statuses and finiteness;
- a canary (``tests/native_build/c/sanitizer_canary.c``) that calls a generated rhs with a
  too-short output buffer and with a misaligned state, and must be stopped by the sanitizers:
  without it a build that silently lost the flags would pass everything above.

The drivers' values (``<library>_drive.h``) come from the catalog: default parameters and the
regeneration's sample state (`regenerate.sample_state`), made consistent with the constraints
by `consistent.consistent_state` for the constrained models.
"""
from __future__ import annotations

import os
import re
import subprocess

import pytest

pytestmark = pytest.mark.compiler

#: CMake's CMAKE_C_COMPILER_ID of each compiler
COMPILER_IDS = {"gcc": "GNU", "clang": "Clang"}
STEP = 1e-3  # stiffest example: stiff_chain, h * omega = 0.1
#: leaks are errors too; a report names the generated file and line
SANITIZER_ENV = {"ASAN_OPTIONS": "detect_leaks=1:abort_on_error=0", "UBSAN_OPTIONS": "print_stacktrace=1"}


def run(argv, **kwargs) -> subprocess.CompletedProcess:
    result = subprocess.run([str(a) for a in argv], capture_output=True, text=True, timeout=900, **kwargs)
    assert result.returncode == 0, f"{' '.join(map(str, argv))} failed:\n{result.stdout[-4000:]}\n{result.stderr[-4000:]}"
    return result


def _rendered_sources(name: str) -> list:
    """The `CSources` regeneration renders for generated/<name>/ (their layouts name the methods
    and the functions), caught on their way through `regenerate.example_files`."""
    import regenerate

    caught = []
    render = regenerate.render_sources

    def catch(*args, **kwargs):
        sources = render(*args, **kwargs)
        caught.append(sources)
        return sources

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(regenerate, "render_sources", catch)
        regenerate.example_files(name)
    return caught


def _initial_state(eom) -> tuple:
    """(x0, p): the regeneration's sample state, on the constraints if there are any."""
    from regenerate import sample_state

    from lagcodegen.statics.consistent import consistent_state

    sample = sample_state(eom)
    x = [float(v) for v in sample.x]
    if eom.m:  # projected as a whole (no coordinate held): the sample is not on the constraints
        q, u = consistent_state(eom, x[:eom.n], x[eom.n:], fix=(), fix_u=())
        x = [float(v) for v in (*q, *u)]
    return x, [float(v) for v in sample.p]


def _values_header(sources, eom) -> str:
    layout = sources.layout
    x0, p = _initial_state(eom)
    assert layout.coordinates == tuple(s.name for s in eom.q), "state order differs from the equations'"
    assert layout.parameters == tuple(s.name for s in eom.parameters), "parameter order differs from the equations'"
    suffix = "F" if layout.precision == "float" else ""
    numbers = lambda values: "{" + ", ".join(f"{v!r}{suffix}" for v in values) + "}"
    methods = " ".join(f"X({m}, {m.upper()})" for m in layout.methods)
    return "\n".join([
        f"/* {layout.prefix}_drive.h: written by tests/native_build/test_sanitize.py for drive_model.c */",
        f'#include "{sources.header_name}"',
        f'#define LCG_DRIVE_NAME "{layout.prefix}"',
        f"#define LCG_DRIVE_PREFIX {layout.prefix}",
        f"#define LCG_DRIVE_MACRO {layout.prefix.upper()}",
        f"#define LCG_DRIVE_REAL {layout.precision}",
        f"#define LCG_DRIVE_N_CONSTRAINTS {layout.n_constraints}",
        f"#define LCG_DRIVE_HAS_ENERGY {int(f'{layout.prefix}_energy' in layout.functions)}",
        f"#define LCG_DRIVE_METHODS(X) {methods}",
        f"#define LCG_DRIVE_X0 {numbers(x0)}",
        f"#define LCG_DRIVE_P {numbers(p)}",
        f"#define LCG_DRIVE_H {STEP!r}{suffix}",
        ""])


@pytest.fixture(scope="module")
def libraries(repo_root) -> list:
    names = sorted(p.stem for p in (repo_root / "generated").glob("*/lcg_*.c"))
    assert names, "no generated libraries found"
    return names


@pytest.fixture(scope="module")
def drive_values(repo_root, libraries, tmp_path_factory):
    """A folder with ``<library>_drive.h`` for every library in generated/."""
    from lagcodegen import catalog, derive_equations

    folder = tmp_path_factory.mktemp("drive_values")
    written = []
    for name in sorted(p.name for p in (repo_root / "generated").iterdir() if p.is_dir()):
        eom = derive_equations(catalog.example(name))
        for sources in _rendered_sources(name):
            committed = repo_root / "generated" / name / sources.source_name
            if not committed.is_file() or committed.read_text() != sources.source:
                pytest.fail(f"{committed} is not what regeneration writes: run pytest tests/golden --update-golden")
            (folder / f"{sources.layout.prefix}_drive.h").write_text(_values_header(sources, eom))
            written.append(sources.layout.prefix)
    assert sorted(written) == libraries, f"drivers for {sorted(written)}, libraries {libraries}"
    return folder


@pytest.fixture(scope="module", params=sorted(COMPILER_IDS))
def sanitized_build(request, repo_root, drive_values, tmp_path_factory, require_tool):
    """generated/ built by CMake with LCG_SANITIZE=ON and the drivers, once per compiler."""
    cmake, compiler = require_tool("cmake"), require_tool(request.param)
    build = tmp_path_factory.mktemp(f"sanitize_{request.param}")
    run([cmake, "-S", repo_root, "-B", build, f"-DCMAKE_C_COMPILER={compiler}", "-DLCG_SANITIZE=ON",
         f"-DLCG_DRIVE_VALUES={drive_values}"])
    identified = "".join(p.read_text() for p in build.glob("CMakeFiles/*/CMakeCCompiler.cmake"))
    assert f'set(CMAKE_C_COMPILER_ID "{COMPILER_IDS[request.param]}")' in identified, identified[:500]
    run([cmake, "--build", build, "-j2"])
    return build


def test_tests_and_drivers_pass_under_sanitizers(sanitized_build, libraries, require_tool, ctest_summary):
    tested = run([require_tool("ctest"), "--test-dir", sanitized_build, "-j2", "--output-on-failure"],
                 env=os.environ | SANITIZER_ENV)
    print(tested.stdout)
    expected = sorted(libraries + [f"drive_{name}" for name in libraries])
    ran = sorted(re.findall(r"Test +#\d+: (\S+) \.+\s+Passed", tested.stdout))
    assert ran == expected, f"ctest ran {ran}, expected a C test and a driver per library {expected}"
    assert ctest_summary(tested.stdout) == ("100", "0", str(len(expected))), tested.stdout[-2000:]


@pytest.mark.parametrize("mode, report", [
    ("heap", r"ERROR: AddressSanitizer: heap-buffer-overflow"),
    ("align", r"lcg_\w+\.c:\d+:\d+: runtime error: load of misaligned address"),
])
def test_sanitizers_stop_a_broken_call(sanitized_build, mode, report):
    """The canary's broken call into generated code aborts with the sanitizer's report (for
    UBSan, at a line of the generated file: the library itself is instrumented), while the same
    call done right exits 0."""
    canary = sanitized_build / "lcg_sanitizer_canary"
    run([canary, "none"], env=os.environ | SANITIZER_ENV)
    broken = subprocess.run([str(canary), mode], capture_output=True, text=True, timeout=60,
                            env=os.environ | SANITIZER_ENV)
    assert broken.returncode != 0, f"canary {mode} exited 0: the sanitizer did not stop it\n{broken.stderr[-2000:]}"
    assert re.search(report, broken.stderr), f"no {report!r} in the canary's report:\n{broken.stderr[-3000:]}"
