"""The command line as a hostile user meets it: every bad argument ends in ONE line on stderr,
``lagcodegen <command>: error: <message>``, naming the culprit, and exit code 2; nothing is
compiled first. (Named test_cli_input.py, not test_cli.py: pytest's default import mode refuses
two test modules of the same base name in folders without __init__.py, and tests/numeric has
test_cli.py.)

Expected values come from the command line itself (the option and value given must be named)
and from the documented exit codes (`lagcodegen --help`).
"""
from __future__ import annotations

import os
import subprocess
import sys

import pytest

from lagcodegen.cli.arguments import UsageError, join_negative_numbers
from lagcodegen.cli.commands import main

RUN = ["--t-end", "0.5", "--h", "1e-3"]
DP = ["double_pendulum", *RUN, "--x0", "q1=1,q2=0.5"]
COMMANDS = ("examples", "demo", "derive", "emit", "simulate", "sweep", "animate")


@pytest.fixture(autouse=True)
def _private_cache(kernel_cache_dir):
    return kernel_cache_dir


def one_line_error(argv, capsys) -> str:
    """Run ``lagcodegen argv`` in-process; assert exit code 2 and one error line; return it."""
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    prog = f"lagcodegen {argv[0]}" if argv[0] in COMMANDS else "lagcodegen"  # unknown: the top level's error
    assert code == 2, (code, captured.err)
    assert captured.err.count("\n") == 1 and "Traceback" not in captured.err, captured.err
    assert captured.err.startswith(f"{prog}: error: "), captured.err
    assert "compiled" not in captured.out and "wrote" not in captured.out
    return captured.err


@pytest.mark.parametrize("argv, culprits", [
    # unknown or empty model names and broken model files (files written by the test below)
    (["derive", "nosuch"], ["'nosuch'", "double_pendulum"]),
    (["derive", ""], ["''"]),
    (["simulate", "nosuch", *RUN], ["'nosuch'"]),
    # unknown command, method, coordinates and names
    (["bogus"], ["'bogus'"]),
    (["simulate", *DP, "--method", "rk5"], ["--method", "'rk5'"]),
    (["simulate", "double_pendulum", *RUN, "--x0", "q1=1,q3=0"], ["'q3'", "--x0", "q1, q2"]),
    (["simulate", "double_pendulum", *RUN, "--x0", "q1"], ["--x0", "'q1'", "name=value"]),
    (["simulate", "double_pendulum", *RUN, "--x0", "q1=abc,q2=0"], ["--x0", "'q1'", "'abc'"]),
    (["simulate", "double_pendulum", *RUN, "--x0", "q1=nan,q2=0"], ["--x0", "'q1'", "finite"]),
    (["simulate", "double_pendulum", *RUN, "--x0", ""], ["--x0", "empty"]),
    (["simulate", "double_pendulum", *RUN, "--x0", "=1"], ["--x0", "'=1'"]),
    (["simulate", *DP, "--param", "zz=1"], ["--param", "'zz'"]),
    (["simulate", *DP, "--fixed", "g=1", "--param", "g=2"], ["'g'", "fixed"]),
    # step sizes, end times and strides: negative numbers are values, then checked
    (["simulate", "double_pendulum", "--t-end", "1", "--h", "-1e-3", "--x0", "q1=1,q2=0"], ["--h", "> 0", "-1e-3"]),
    (["simulate", "double_pendulum", "--t-end", "1", "--h", "-.5", "--x0", "q1=1,q2=0"], ["--h", "> 0"]),
    (["simulate", "double_pendulum", "--t-end", "1", "--h", "0", "--x0", "q1=1,q2=0"], ["--h", "> 0"]),
    (["simulate", "double_pendulum", "--t-end", "1", "--h", "abc", "--x0", "q1=1,q2=0"], ["--h", "'abc'"]),
    (["simulate", "double_pendulum", "--t-end", "inf", "--h", "1e-3", "--x0", "q1=1,q2=0"], ["--t-end", "finite"]),
    (["simulate", "double_pendulum", "--t-end", "nan", "--h", "1e-3", "--x0", "q1=1,q2=0"], ["--t-end", "finite"]),
    (["simulate", "double_pendulum", "--t-end", "-1", "--h", "1e-3", "--x0", "q1=1,q2=0"], ["--t-end", "> 0"]),
    (["simulate", "double_pendulum", "--t-end", "1", "--h", "0.3", "--x0", "q1=1,q2=0"], ["--t-end", "--h", "whole"]),
    (["simulate", *DP, "--stride", "0"], ["--stride", "0"]),
    (["simulate", *DP, "--energy", "-1"], ["--energy"]),
    # output far beyond memory: says so and names --stride (estimated before any allocation)
    (["simulate", "double_pendulum", "--t-end", "1e9", "--h", "1e-3", "--x0", "q1=1,q2=0"], ["--stride", "TiB"]),
    (["sweep", "double_pendulum", "--t-end", "1e6", "--h", "1e-3", "--x0", "q1=1,q2=0", "--grid", "m2=1:2:100",
      "--trajectories"], ["--stride", "TiB"]),
    # malformed grids and tables
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2=1:2"], ["--grid", "'m2'", "1:2"]),
    # found by review: an empty value was dropped silently (a member fewer)
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2=1,,2"], ["--grid", "'m2'", "empty value"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2"], ["--grid", "'m2'"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", ""], ["--grid", "''"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "zz=1,2"], ["'zz'", "--grid"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--table", "/nonexistent/m.csv"],
     ["--table", "/nonexistent/m.csv"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2=1,2", "--threads", "-2"], ["--threads"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2=1,2", "--scheduler", ""],
     ["--scheduler", "empty"]),
    (["sweep", "double_pendulum", *RUN, "--x0", "q1=1,q2=0", "--grid", "m2=1,2", "--field", ""], ["--field"]),
    # emit: outputs, methods and fixed parameters by name
    (["emit", "double_pendulum", "--methods", "rk5"], ["--methods", "'rk5'", "rk4"]),
    (["emit", "double_pendulum", "--methods", ""], ["--methods", "empty"]),
    (["emit", "double_pendulum", "--methods", "rk4,,heun"], ["--methods", "empty"]),
    (["emit", "double_pendulum", "--outputs", "forcing,foo"], ["--outputs", "'foo'", "mass_matrix"]),
    (["emit", "double_pendulum", "--fixed", "zz=1"], ["--fixed", "'zz'", "m1"]),
    (["emit", "double_pendulum", "--fixed", "g"], ["--fixed", "'g'", "name=value"]),
    (["emit", "cartesian_pendulum", "--methods", "symplectic_euler"], ["cartesian_pendulum", "momentum"]),
    (["emit", "double_pendulum", "--precision", "half"], ["--precision", "'half'"]),
])
def test_bad_argument_is_one_line_naming_the_culprit(argv, culprits, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # emit's default --out is the working directory
    message = one_line_error(argv, capsys)
    for culprit in culprits:
        assert culprit in message, (culprit, message)


@pytest.mark.parametrize("content, culprits", [
    ("raise RuntimeError('boom in the model')", ["bad_model.py", "RuntimeError", "boom in the model"]),
    ("x = 1", ["bad_model.py", "must define"]),
    ("model = 42", ["bad_model.py", "must define"]),
    ("def build_model(:\n", ["bad_model.py", "SyntaxError"]),
    # found by review: the command exited with the file's code (0: success, nothing done)
    ("import sys\nsys.exit(0)", ["bad_model.py", "sys.exit(0)"]),
    ("import sys\nsys.exit(7)", ["bad_model.py", "sys.exit(7)"]),
])
def test_broken_model_file_is_named(content, culprits, tmp_path, capsys):
    path = tmp_path / "bad_model.py"
    path.write_text(content)
    message = one_line_error(["derive", path], capsys)
    for culprit in culprits:
        assert culprit in message, (culprit, message)


def test_unusable_output_paths_are_refused_before_running(tmp_path, capsys):
    a_file = tmp_path / "file.txt"
    a_file.write_text("")
    cases = [
        (["--out", tmp_path], ["--out", str(tmp_path), "directory"]),
        (["--out", tmp_path / "missing" / "run.npz"], ["--out", "missing", "not an existing directory"]),
        (["--out", a_file / "run.npz"], ["--out", "file.txt"]),
        (["--out", ""], ["--out", "empty"]),
        (["--plot", tmp_path], ["--plot", "directory"]),
        (["--out", "/proc/lagcodegen_test.npz"], ["--out", "/proc/lagcodegen_test.npz", "cannot write"]),
        # found by review: numpy wrote run.dat.npz while the CLI said "wrote run.dat"; a figure format
        # matplotlib lacks failed only after the run, its error naming no option
        (["--out", tmp_path / "run.dat"], ["--out", "run.dat", "ending in .npz", "run.dat.npz"]),
        (["--plot", tmp_path / "run.xyz"], ["--plot", "run.xyz", "'xyz' is not one matplotlib writes", "png"]),
        (["--plot", tmp_path / "run"], ["--plot", "'(none)'"]),
        # found by review (session 16): numpy appends .npz to run.NPZ (its test is case-sensitive)
        (["--out", tmp_path / "run.NPZ"], ["--out", "run.NPZ", "ending in .npz", "run.NPZ.npz"]),
    ]
    for extra, culprits in cases:
        message = one_line_error(["simulate", *DP, *extra], capsys)
        for culprit in culprits:
            assert culprit in message, (culprit, message)
    assert a_file.read_text() == "" and not (tmp_path / "missing").exists()


def test_a_pgf_figure_without_its_tex_is_refused_before_running(tmp_path, capsys, monkeypatch):
    # found by review (session 16): the whole run, then a 98-line traceback ("'xelatex' not found")
    import shutil

    import matplotlib

    which = shutil.which
    monkeypatch.setattr(shutil, "which", lambda name, *args, **kwargs: None if name.endswith("latex")
                        else which(name, *args, **kwargs))
    message = one_line_error(["simulate", *DP, "--plot", tmp_path / "run.pgf"], capsys)
    tex = matplotlib.rcParams["pgf.texsystem"]
    assert "--plot" in message and f"{tex}, which is not installed" in message, message


def test_read_only_directory_is_refused(tmp_path, capsys):
    if os.geteuid() == 0:
        pytest.skip("root may write into a read-only directory")
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    message = one_line_error(["simulate", *DP, "--out", locked / "run.npz"], capsys)
    assert "--out" in message and "locked" in message


def test_emit_out_that_is_a_file_is_refused(tmp_path, capsys):
    a_file = tmp_path / "not_a_dir"
    a_file.write_text("keep me")
    message = one_line_error(["emit", "double_pendulum", "--out", a_file], capsys)
    assert "--out" in message and "not_a_dir" in message and a_file.read_text() == "keep me"


def test_negative_numbers_are_option_values():
    # argparse (Python <= 3.12) reads '-1e-3' as an option; the CLI hands it over as the value
    assert join_negative_numbers(["x", "--h", "-1e-3", "--t-end", "-inf"]) == ["x", "--h=-1e-3", "--t-end=-inf"]
    assert join_negative_numbers(["--h", "-x"]) == ["--h", "-x"]     # not a number: left to argparse
    assert join_negative_numbers(["--", "--h", "-1"]) == ["--", "--h", "-1"]  # after --: positional


def test_traceback_switch_shows_the_exception(monkeypatch):
    with pytest.raises(UsageError, match="'nosuch'"):
        main(["--traceback", "derive", "nosuch"])
    monkeypatch.setenv("LAGCODEGEN_DEBUG", "1")
    from lagcodegen.codegen.reduce import KernelError

    with pytest.raises(KernelError, match="cartesian_pendulum"):  # the library's own exception, unchanged
        main(["emit", "cartesian_pendulum", "--methods", "symplectic_euler"])


def test_closed_stdout_exits_quietly(tmp_path):
    """``lagcodegen derive X | head``: the reader goes away; no BrokenPipeError traceback, exit
    code 141 (128 + SIGPIPE, what a shell reports for a process killed by SIGPIPE)."""
    code = "import sys; from lagcodegen.cli.commands import main; sys.exit(main())"
    process = subprocess.Popen([sys.executable, "-c", code, "derive", "double_pendulum"], cwd=tmp_path,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    process.stdout.close()  # before the first line is written: every write meets a closed pipe
    _, stderr = process.communicate(timeout=120)
    assert process.returncode == 141, stderr.decode()
    assert stderr.decode().strip() == ""


def test_failed_build_is_one_line_with_exit_code_1(monkeypatch, capsys):
    # a build failure is not the command line's fault: exit code 1 (documented in --help), not 2
    from lagcodegen import pipeline
    from lagcodegen.native.build import BuildError

    def failing_build(*args, **kwargs):
        raise BuildError("gcc exited with status 1 (kept /tmp/x.c)", command="gcc", stderr="boom")

    monkeypatch.setattr(pipeline, "compile_model", failing_build)
    code = main(["simulate", *DP])
    error = capsys.readouterr().err
    assert code == 1 and error.count("\n") == 1, error
    assert error.startswith("lagcodegen simulate: error: building double_pendulum with rk4 failed: gcc"), error


def test_interrupt_exits_130_quietly(monkeypatch, capsys):
    from lagcodegen.cli import commands

    def interrupted(args):
        raise KeyboardInterrupt

    monkeypatch.setattr(commands, "cmd_derive", interrupted)
    assert main(["derive", "double_pendulum"]) == 130
    assert "Traceback" not in capsys.readouterr().err


def test_late_found_arguments_are_refused_before_compiling(tmp_path, capsys, monkeypatch):
    """Found by review: a repeated --grid value with --heatmap was refused after the whole sweep ran,
    an --speed too small for the frame limit after the simulation, and an --input table that
    cannot be read after the compile. Now each is one line before anything is compiled: the
    compiler is replaced by one that fails the test if called."""
    import lagcodegen.cli.runs as runs
    import lagcodegen.cli.scenes as scenes

    def no_compile(*args, **kwargs):
        raise AssertionError("compiled before the bad argument was refused")

    monkeypatch.setattr(runs, "compile_for", no_compile)
    monkeypatch.setattr(scenes, "compile_for", no_compile)
    model_file = tmp_path / "driven.py"
    model_file.write_text(
        "import sympy as sp, sympy.physics.mechanics as me\nfrom lagcodegen import Model\n"
        "x, F = me.dynamicsymbols('x F'); m, k = sp.symbols('m k', positive=True)\n"
        "model = Model('driven', [x], [m, k], kinetic_energy=m * x.diff()**2 / 2, potential_energy=k * x**2 / 2,\n"
        "              generalized_forces={x: F}, inputs=[F], parameter_values={'m': 1.0, 'k': 4.0})\n")
    short, with_nan = tmp_path / "short.csv", tmp_path / "with_nan.csv"
    short.write_text("t,F\n0,0\n1,1\n2,0\n")
    with_nan.write_text("t,F\n0,0\n1,nan\n2,0\n")
    cases = [
        (["sweep", "double_pendulum", "--grid", "m2=0.5,1,0.5", "--grid", "l2=1,2", "--x0", "q1=1,q2=0",
          "--t-end", "0.5", "--h", "1e-3", "--heatmap", tmp_path / "map.png"], ["--heatmap", "'m2'", "repeats 0.5"]),
        (["animate", "double_pendulum", "--x0", "q1=1,q2=0.5", "--t-end", "1", "--speed", "1e-4",
          "--out", tmp_path / "scene.gif"], ["speed 0.0001", "frames"]),
        (["simulate", model_file, "--x0", "x=0", "--t-end", "1", "--h", "1e-3", "--input",
          f"F={tmp_path / 'no_such_table.csv'}"], ["--input F", "no_such_table.csv"]),
        # found by review (session 17): these three were refused only after the compile
        (["simulate", "double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "1", "--h", "1e-3", "--stride", "2000"],
         ["--stride 2000", "1000 steps"]),
        (["simulate", model_file, "--x0", "x=0", "--t-end", "3", "--h", "1e-3", "--input", f"F={short}"],
         ["--input F", "covers t = 0 .. 2", "t = 0 .. 3"]),
        (["simulate", model_file, "--x0", "x=0", "--t-end", "2", "--h", "1e-3", "--input", f"F={with_nan}"],
         ["--input F", "row 2", "nan", "not finite"]),
        (["sweep", "double_pendulum", "--grid", "m2=0.5:inf:3", "--x0", "q1=1,q2=0", "--t-end", "1", "--h", "1e-3"],
         ["--grid 'm2'", "finite", "0.5:inf"]),
    ]
    for argv, culprits in cases:
        message = one_line_error(argv, capsys)
        for culprit in culprits:
            assert culprit in message, (culprit, message)


def test_sweep_members_off_their_constraints_are_refused(capsys):
    """Found by review: `sweep cartesian_pendulum --grid x=0.1,0.5 --x0 y=-1` ran both members with
    exit 0, each holding its offset (phi = x^2 + y^2 - 1 = 0.01 and 0.25, by hand: rods of 1.005 and
    1.118), where `simulate --x0 x=0.5,y=-1` refuses the start. Now the sweep refuses it too, naming
    the worst member."""
    message = one_line_error(["sweep", "cartesian_pendulum", "--grid", "x=0.1,0.5", "--x0", "y=-1", "--t-end",
                              "0.01", "--h", "1e-3"], capsys)
    assert "2 member(s) start off the constraints" in message and "member 1 (x = 0.5) with 0.25" in message
