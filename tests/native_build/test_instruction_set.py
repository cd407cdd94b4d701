"""The building machine's vector instruction set (`native/instruction_set.py`): which flag a CPU
gets, that a kernel built with it gives the baseline build's numbers to the last bit, and that a
pickled module built for AVX2 is never opened on a CPU without it.

The reference for the numbers is the same model built with ``LAGCODEGEN_PORTABLE=1`` (the
baseline instruction set): IEEE arithmetic without fused multiply-adds or reassociation gives the
same bits whichever encoding the instructions have.
"""
from __future__ import annotations

import pickle
import platform
import shutil
import subprocess

import numpy as np
import pytest

from lagcodegen import catalog
from lagcodegen.native import build, instruction_set
from lagcodegen.native.build import BuildError, compiler_available
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import sweep

X86_64 = platform.machine().lower() in ("x86_64", "amd64")
needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")
needs_x86 = pytest.mark.skipif(not X86_64, reason="the vector flags are chosen on x86-64 only")
HAS_AVX2 = "avx2" in instruction_set.cpu_features()

# two lines of a real /proc/cpuinfo (an AMD EPYC's, shortened)
CPUINFO = ("processor\t: 0\nvendor_id\t: AuthenticAMD\n"
           "flags\t\t: fpu vme de pse tsc msr pae mce cx8 apic sep sse sse2 ht syscall nx mmx fxsr_opt "
           "pdpe1gb rdtscp lm pni pclmulqdq ssse3 fma cx16 sse4_1 sse4_2 movbe popcnt aes xsave avx f16c "
           "rdrand hypervisor lahf_lm abm sse4a misalignsse bmi1 avx2 smep bmi2\n"
           "bugs\t\t: sysret_ss_attrs\n")
GCC = ("gcc",) if shutil.which("gcc") else None


def needs_avx2_build(test):
    """A test that compiles kernels for AVX2: a C compiler, x86-64 and a CPU with AVX2."""
    for mark in (pytest.mark.skipif(not HAS_AVX2, reason="this CPU has no AVX2"), needs_x86, needs_cc,
                 pytest.mark.compiler):
        test = mark(test)
    return test


def test_cpu_features_are_read_from_the_flags_line():
    features = instruction_set.cpu_features(CPUINFO)
    assert {"avx", "avx2", "sse2", "fma"} <= features
    assert "sysret_ss_attrs" not in features  # the bugs line is not a feature
    assert instruction_set.cpu_features("processor\t: 0\n") == frozenset()


@needs_x86
@pytest.mark.skipif(GCC is None, reason="gcc not installed")
def test_the_best_extension_the_cpu_has_is_chosen(monkeypatch):
    monkeypatch.delenv(instruction_set.PORTABLE_ENV, raising=False)
    assert instruction_set.host_flags(GCC, instruction_set.cpu_features(CPUINFO)) == ("-mavx2",)
    assert instruction_set.host_flags(GCC, frozenset({"sse2", "avx"})) == ("-mavx",)
    assert instruction_set.host_flags(GCC, frozenset({"sse2", "sse4_2"})) == ()
    monkeypatch.setenv(instruction_set.PORTABLE_ENV, "1")
    assert instruction_set.host_flags(GCC, frozenset({"avx", "avx2"})) == ()
    monkeypatch.setenv(instruction_set.PORTABLE_ENV, "0")  # "0" is not set
    assert instruction_set.host_flags(GCC, frozenset({"avx", "avx2"})) == ("-mavx2",)


def test_a_compiler_that_refuses_the_flag_gets_none(monkeypatch):
    monkeypatch.delenv(instruction_set.PORTABLE_ENV, raising=False)
    assert instruction_set.host_flags(("false",), frozenset({"avx", "avx2"})) == ()
    assert instruction_set.host_flags(("/no/such/compiler",), frozenset({"avx", "avx2"})) == ()


def test_missing_features_name_what_the_flags_need():
    assert instruction_set.missing_features(("-O3", "-mavx2"), frozenset({"avx"})) == ["avx2"]
    assert instruction_set.missing_features(("-O3", "-mavx2"), frozenset({"avx", "avx2"})) == []
    assert instruction_set.missing_features(("-O3",), frozenset()) == []


@needs_avx2_build
def test_host_build_gives_the_baseline_numbers_to_the_last_bit(tmp_path, monkeypatch):
    monkeypatch.delenv(instruction_set.PORTABLE_ENV, raising=False)
    model = catalog.double_pendulum()
    host = compile_model(model, methods=("rk4",), lanes=4, cache_dir=tmp_path / "host")
    monkeypatch.setenv(instruction_set.PORTABLE_ENV, "1")
    portable = compile_model(model, methods=("rk4",), lanes=4, cache_dir=tmp_path / "portable")
    assert host.instruction_set == ("-mavx2",) and portable.instruction_set == ()
    assert host.key != portable.key
    assert "built for -mavx2" in host.report()
    if shutil.which("objdump"):  # the flag reached the compiler: VEX-encoded arithmetic in the module
        text = subprocess.run(["objdump", "-d", str(host.path)], capture_output=True, text=True).stdout
        assert "vmulsd" in text
        baseline = subprocess.run(["objdump", "-d", str(portable.path)], capture_output=True, text=True).stdout
        assert "vmulsd" not in baseline
    x0 = {"q1": 2.0, "q2": -1.0, "q1_d": 0.3, "q2_d": 0.0}
    a = simulate(host, x0, t_end=4.0, h=1e-3)
    b = simulate(portable, x0, t_end=4.0, h=1e-3)
    assert a.ok and b.ok
    np.testing.assert_array_equal(a.x, b.x)
    # the lane sweep (vectorized across members: four doubles per vector with AVX2, two without),
    # each lane module for its system's instruction set whatever the environment says by then
    # (found by review: the host system's lane module followed LAGCODEGEN_PORTABLE=1 here)
    assert host.lane_variant().instruction_set == ("-mavx2",)
    assert portable.lane_variant().instruction_set == ()
    grid = {"q1": np.linspace(0.1, 3.0, 11)}
    sa = sweep(host, grid, x0=x0, t_end=2.0, h=1e-3, threads=1)
    sb = sweep(portable, grid, x0=x0, t_end=2.0, h=1e-3, threads=1)
    np.testing.assert_array_equal(sa.x_final, sb.x_final)


@needs_avx2_build
def test_a_module_built_for_avx2_is_not_opened_on_a_cpu_without_it(tmp_path, monkeypatch):
    monkeypatch.delenv(instruction_set.PORTABLE_ENV, raising=False)
    monkeypatch.setenv("LAGCODEGEN_CACHE_DIR", str(tmp_path))
    system = compile_model(catalog.double_pendulum(), methods=("rk4",), lanes=0, cache_dir=tmp_path)
    assert system.instruction_set == ("-mavx2",)
    blob = pickle.dumps(system)
    # the worker of a mixed cluster: its CPU has SSE2 only
    monkeypatch.setattr(instruction_set, "_this_cpu", lambda: frozenset({"sse2"}))
    there = pickle.loads(blob)
    assert there.instruction_set == () and there.path != system.path  # built again, for the baseline
    x0 = {"q1": 1.0, "q2": 0.5, "q1_d": 0.0, "q2_d": 0.0}
    np.testing.assert_array_equal(simulate(there, x0, t_end=1.0, h=1e-3).x,
                                  simulate(system, x0, t_end=1.0, h=1e-3).x)
    bare = pickle.dumps(build.CompiledSystem(None, None, system.key, system.path, system.module_name,
                                             system.layout, None, instruction_set=system.instruction_set))
    with pytest.raises(BuildError, match="built for -mavx2, and this CPU has no avx2"):
        pickle.loads(bare)


@pytest.mark.compiler
@needs_cc
@needs_x86
def test_a_module_whose_flags_chose_instructions_is_rebuilt_on_another_cpu(tmp_path, monkeypatch):
    """Found by review: with extra_compile_args=("-mavx2",) (or -march=native) and LAGCODEGEN_PORTABLE=1
    the module recorded no instruction set, and a worker without AVX2 opened it."""
    monkeypatch.setenv(instruction_set.PORTABLE_ENV, "1")
    monkeypatch.setenv("LAGCODEGEN_CACHE_DIR", str(tmp_path))
    system = compile_model(catalog.double_pendulum(), methods=("rk4",), lanes=0, cache_dir=tmp_path,
                           extra_compile_args=("-march=native",))
    assert system.instruction_set == () and system.built_on == instruction_set.this_cpu()
    assert "built for the CPU of the machine that built it" in system.report()
    blob = pickle.dumps(system)
    assert pickle.loads(blob).path == system.path  # this CPU: the same module
    monkeypatch.setattr(instruction_set, "_this_cpu", lambda: frozenset({"sse2"}))
    there = pickle.loads(blob)
    assert there.path != system.path and there.built_on == frozenset()
    x0 = {"q1": 1.0, "q2": 0.5, "q1_d": 0.0, "q2_d": 0.0}
    np.testing.assert_array_equal(simulate(there, x0, t_end=1.0, h=1e-3).x, simulate(system, x0, t_end=1.0, h=1e-3).x)


def test_flags_that_choose_instructions_are_recognized():
    assert instruction_set.selects_instructions(["-O2", "-march=native"])
    assert instruction_set.selects_instructions(["-mfma"]) and instruction_set.selects_instructions(["-mavx512f"])
    assert instruction_set.selects_instructions(["-mcpu=native"])
    assert not instruction_set.selects_instructions(["-O2", "-ffast-math", "-mfpmath=sse", "-m64"])
    assert instruction_set.missing_features((), frozenset({"sse2"}), built_on=frozenset({"sse2", "fma"})) == ["fma"]
