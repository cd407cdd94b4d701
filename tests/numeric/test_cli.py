"""``lagcodegen simulate`` and ``lagcodegen sweep``: files written, values, and errors; and the
`lagcodegen.analysis.heatmaps` helpers behind ``--heatmap`` on synthetic sweeps with known answers.

The commands run in-process through ``lagcodegen.cli.commands.main`` on tiny problems (the kernels
build into the session's private cache). Independent sources for the numbers:

- final states: scipy's DOP853 at rtol = atol = 1e-12 on the same model (`solve_reference`);
  rk4 with h = 1e-3 over 0.5 s is within ~1e-12 of it, 1e-8 is the margin;
- grid order and axes: ``numpy.linspace`` / ``numpy.geomspace`` and the C order of
  ``itertools.product`` (first --grid slowest), as the help text promises;
- blow-ups: rk4's real stability limit h*omega = 2.785 (Hairer & Wanner, Solving ODEs II,
  Sec. IV.2, Fig. 2.1): the stiff chain's fast mode, omega = sqrt(K (1/m2 + 1/m3)) = sqrt(2 K),
  is unstable at h = 1e-3 for K = 1e8 (h omega = 14) and stable for K = 100 (0.014).
"""
from __future__ import annotations

import dataclasses
import itertools
import re
import subprocess

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog
from lagcodegen.analysis.heatmaps import first_crossing_time, plot_heatmap
from lagcodegen.cli.arguments import EXIT_FAILED, EXIT_USAGE, parse_axis
from lagcodegen.cli.commands import main
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import Status, solve_reference
from lagcodegen.run.sweep import CHUNK_FAILED, NOT_RUN, SweepResult

pytestmark = pytest.mark.compiler

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"
DP_RUN = ["--t-end", "0.5", "--h", "1e-3"]


def run_cli(argv, capsys) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    return code, capsys.readouterr().out


def cli_error(argv, capsys) -> str:
    """The one error line a bad command line prints (exit code 2, nothing on stdout)."""
    code = main([str(a) for a in argv])
    captured = capsys.readouterr()
    assert code == EXIT_USAGE, (code, captured.err)
    assert captured.err.startswith(f"lagcodegen {argv[0]}: error: ") and captured.err.count("\n") == 1, captured.err
    return captured.err


@pytest.fixture(autouse=True)
def _private_cache(kernel_cache_dir):
    """Every command here builds into the session's private cache, never the user's."""
    return kernel_cache_dir


@pytest.fixture(scope="module")
def reference_pendulum(kernel_cache_dir):
    """The double pendulum for scipy's reference solutions (its own compile, rhs only)."""
    return compile_model(catalog.double_pendulum(), outputs=("rhs",), methods=())


def assert_png(path):
    assert path.is_file(), f"{path} was not written"
    assert path.read_bytes()[:8] == PNG_MAGIC


# -- grid syntax ------------------------------------------------------------------------------
@pytest.mark.parametrize("item, name, expected", [
    ("k=10:1000:5", "k", np.linspace(10, 1000, 5)),
    ("k=10:1000:5:log", "k", np.geomspace(10, 1000, 5)),
    ("m2=0.5,1,2", "m2", np.array([0.5, 1.0, 2.0])),
    ("q1=-1:1:1", "q1", np.array([-1.0])),
])
def test_parse_axis(item, name, expected):
    got_name, values = parse_axis(item)
    assert got_name == name
    np.testing.assert_allclose(values, expected, rtol=1e-15)


@pytest.mark.parametrize("item, culprit", [
    ("k", "k"), ("k=", "k="), ("=1,2", "=1,2"), ("k=1:2", "1:2"), ("k=1:2:x", "1:2:x"),
    ("k=1:2:3:4", "1:2:3:4"), ("k=1:2:0", "count"), ("k=0:2:5:log", "positive"), ("k=a,b", "a,b"),
    ("k=1:2:100000000000", "100000000000 values alone would need"),  # was: allocated, then "out of memory"
])
def test_bad_grid_syntax_names_the_item(item, culprit, capsys):
    message = cli_error(["sweep", "double_pendulum", "--grid", item, *DP_RUN, "--x0", "q1=1,q2=0"], capsys)
    assert culprit in message and "--grid" in message


@pytest.mark.parametrize("argv, words", [
    (["--grid", "kk=1,2"], ["unknown name 'kk'", "m2"]),                       # lists the free ones
    (["--grid", "m2=1,2", "--fixed", "m2=1"], ["'m2'", "fixed"]),
    (["--grid", "m2=1,2", "--grid", "m2=3"], ["'m2'", "twice"]),
    (["--grid", "m2=,"], ["'m2'", "no values"]),
    ([], ["--grid", "--table"]),
    (["--grid", "m2=1,2", "--param", "zz=1"], ["unknown name 'zz'", "--param"]),
    (["--grid", "m2=1,2", "--field", "q_max:r"], ["--field", "q1, q2"]),
    (["--grid", "m2=1,2", "--heatmap", "x.png"], ["--heatmap", "two"]),
    # found by review (session 16): the swept values won silently, and the .npz recorded --param's
    (["--grid", "m2=1,2", "--param", "m2=3"], ["--param 'm2'", "swept by --grid/--table"]),
    (["--grid", "q1=0.5,1"], ["--x0 'q1'", "swept by --grid/--table"]),
])
def test_bad_sweep_arguments_name_the_culprit(argv, words, capsys):
    message = cli_error(["sweep", "double_pendulum", *DP_RUN, "--x0", "q1=1,q2=0", *argv], capsys)
    for word in words:
        assert word in message, message


def test_missing_coordinate_and_step_mismatch_fail_before_compiling(capsys):
    assert "q2" in cli_error(["simulate", "double_pendulum", *DP_RUN, "--x0", "q1=1"], capsys)
    assert "whole number of steps" in cli_error(
        ["simulate", "double_pendulum", "--t-end", "1", "--h", "0.3", "--x0", "q1=1,q2=0"], capsys)


def test_help_documents_grid_syntax_and_examples(capsys):
    with pytest.raises(SystemExit) as info:
        main(["sweep", "--help"])
    assert info.value.code == 0
    text = capsys.readouterr().out
    for word in ("--grid", "start:stop:count:log", "name=v1,v2,v3", "--scheduler", "--table", "--field",
                 "--trajectories", "examples:", "lagcodegen sweep "):
        assert word in text, word
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    assert "--energy" in capsys.readouterr().out




# -- simulate ---------------------------------------------------------------------------------
def test_simulate_writes_npz_and_png(tmp_path, capsys, reference_pendulum):
    out, plot = tmp_path / "run.npz", tmp_path / "run.png"
    code, text = run_cli(["simulate", "double_pendulum", *DP_RUN, "--x0", "q1=1,q2=0.5", "--param", "m2=0.5",
                          "--stride", "10", "--energy", "--out", out, "--plot", plot], capsys)
    assert code == 0
    assert "ok" in text and "max |E - E0|" in text and "wall time" in text
    data = np.load(out)
    assert list(data["names"]) == ["q1", "q2", "q1_d", "q2_d"]
    assert data["t"].shape == (51,) and data["x"].shape == (51, 4) and data["energy"].shape == (51,)
    assert int(data["status"]) == Status.OK and str(data["status_name"]) == "OK"
    assert dict(zip(data["parameters"], data["p"]))["m2"] == 0.5
    _, want = solve_reference(reference_pendulum, [1.0, 0.5, 0.0, 0.0], [0.0, 0.5], params={"m2": 0.5})
    np.testing.assert_allclose(data["x"][-1], want[-1], rtol=0, atol=1e-8)
    assert np.max(np.abs(data["energy"] - data["energy"][0])) < 1e-8  # rk4, h = 1e-3: ~1e-12
    assert_png(plot)


def test_simulate_failed_run_exits_1_and_keeps_samples(tmp_path, capsys):
    out = tmp_path / "stiff.npz"
    code = main(["simulate", "stiff_chain", "--t-end", "1", "--h", "1e-3", "--param", "K=1e8",
                 "--x0", "x1=0.1,x2=0,x3=0", "--out", str(out)])
    captured = capsys.readouterr()
    assert code == 1 and "NaN or infinite" in captured.out
    # the stability pre-check's warning (h w = 14 for K = 1e8, outside RK4's 2.83; it runs without the
    # jacobian output since review), then the RuntimeWarning at the failure, one line each
    stability, line = captured.err.splitlines()
    assert stability.startswith("lagcodegen simulate: warning: step h = 0.001 with the largest frequency")
    assert re.fullmatch(r"lagcodegen simulate: warning: rk4 stopped at step \d+ \(t = [\d.]+\): the state or its "
                        r"derivatives became NaN or infinite \(the run diverged\)", line), line
    data = np.load(out)
    assert int(data["status"]) == Status.NONFINITE_STATE
    assert 1 < len(data["t"]) < 1001 and np.all(np.isfinite(data["x"]))


# -- sweep ------------------------------------------------------------------------------------
def test_sweep_grid_writes_every_array_and_heatmap(tmp_path, capsys, reference_pendulum):
    out, png = tmp_path / "sweep.npz", tmp_path / "sweep.png"
    code, text = run_cli(["sweep", "double_pendulum", "--grid", "m2=0.5,1", "--grid", "q1=0.1:0.3:3", *DP_RUN,
                          "--x0", "q2=0.2", "--threads", "2", "--trajectories", "--stride", "10",
                          "--out", out, "--heatmap", png, "--field", "q_max:q2"], capsys)
    assert code == 0 and "6 members" in text and "status: ok 6" in text
    data = np.load(out)
    assert list(data["columns"]) == ["m2", "q1"] and bool(data["is_grid"]) and bool(data["completed"])
    np.testing.assert_array_equal(data["grid_q1"], np.linspace(0.1, 0.3, 3))
    np.testing.assert_array_equal(data["values"], list(itertools.product([0.5, 1.0], np.linspace(0.1, 0.3, 3))))
    shapes = {"x_final": (6, 4), "q_max": (6, 2), "energy_error": (6,), "status": (6,), "steps_done": (6,),
              "blowup_time": (6,), "t": (51,), "trajectories": (6, 51, 4)}
    assert {name: data[name].shape for name in shapes} == shapes
    assert list(data["state_names"]) == ["q1", "q2", "q1_d", "q2_d"]
    # the base state holds what --x0 gave, not the swept q1's first value (found by review)
    assert list(data["x0_names"]) == ["q2"] and list(data["x0_values"]) == [0.2]
    member = 4  # m2 = 1, q1 = 0.2 in C order
    _, want = solve_reference(reference_pendulum, [0.2, 0.2, 0.0, 0.0], [0.0, 0.5], params={"m2": 1.0})
    np.testing.assert_allclose(data["x_final"][member], want[-1], rtol=0, atol=1e-8)
    np.testing.assert_allclose(data["trajectories"][member, -1], want[-1], rtol=0, atol=1e-8)
    assert_png(png)


def test_sweep_table_and_failures(tmp_path, capsys):
    table = tmp_path / "members.csv"
    table.write_text("k,K\n1,100\n2,100\n1,1e8\n2,1e8\n")
    out, png = tmp_path / "stiff.npz", tmp_path / "status.png"
    code, text = run_cli(["sweep", "stiff_chain", "--table", table, "--t-end", "1", "--h", "1e-3",
                          "--x0", "x1=0.1,x2=0,x3=0", "--field", "blowup_time", "--out", out, "--heatmap", png],
                         capsys)
    assert code == 0 and "nonfinite_state 2" in text
    data = np.load(out)
    assert not bool(data["is_grid"]) and "grid_k" not in data.files
    np.testing.assert_array_equal(data["values"], [[1, 100], [2, 100], [1, 1e8], [2, 1e8]])
    np.testing.assert_array_equal(data["status"], [Status.OK, Status.OK, Status.NONFINITE_STATE,
                                                   Status.NONFINITE_STATE])
    assert np.all(np.isnan(data["blowup_time"][:2])) and np.all(data["blowup_time"][2:] < 1.0)
    assert_png(png)


def test_a_table_saved_with_a_byte_order_mark_reads(tmp_path, capsys):
    # found by review: a spreadsheet's UTF-8 byte-order mark made the first name '\ufeffm2', unknown
    table = tmp_path / "members.csv"
    table.write_bytes("m2,l2\n1,2\n3,4\n".encode("utf-8-sig"))
    out = tmp_path / "bom.npz"
    code, _ = run_cli(["sweep", "double_pendulum", "--table", table, "--t-end", "0.01", "--h", "1e-3",
                       "--x0", "q1=1,q2=0.5", "--out", out], capsys)
    assert code == 0
    np.testing.assert_array_equal(np.load(out)["values"], [[1, 2], [3, 4]])


def test_a_table_cell_that_is_not_finite_names_its_line(tmp_path, capsys):
    # found by review: "nan" read as a number, then "swept values of m2 are not all finite", no line
    table = tmp_path / "members.csv"
    table.write_text("m2,l2\n1,2\n3,4\nnan,1\n")
    message = cli_error(["sweep", "double_pendulum", "--table", table, "--t-end", "0.01", "--h", "1e-3",
                         "--x0", "q1=1,q2=0.5"], capsys)
    assert f"--table {table} line 4: m2 = 'nan' is not finite" in message, message


def test_a_table_that_is_not_utf8_is_named(tmp_path, capsys):
    # found by review: "'utf-8' codec can't decode byte 0xff in position 0", naming neither
    table = tmp_path / "members.csv"
    table.write_bytes(b"\xffm2,l2\n1,2\n")
    message = cli_error(["sweep", "double_pendulum", "--table", table, "--t-end", "0.01", "--h", "1e-3",
                         "--x0", "q1=1,q2=0.5"], capsys)
    assert f"--table {table}: not a UTF-8 text file (byte 0" in message, message


def test_sweep_reports_a_failed_chunk_and_exits_non_zero(tmp_path, capsys, monkeypatch):
    """A chunk that raises (a lost worker, a bug) used to be summed up as an interruption: now the
    command names the members and the error, counts them apart from members not run, and exits 1."""
    import lagcodegen.run.sweep as sweep_module

    def failing_call(job, xs, ps, out):
        raise MemoryError("out of memory in chunk")

    monkeypatch.setattr(sweep_module, "_call", failing_call)
    table = tmp_path / "members.csv"
    table.write_text("k\n1\n2\n")
    code = main(["sweep", "stiff_chain", "--table", str(table), "--t-end", "0.01", "--h", "1e-3",
                 "--x0", "x1=0.1,x2=0,x3=0"])
    captured = capsys.readouterr()
    assert code == EXIT_FAILED
    assert "chunk failed: members 0..1 (2 marked chunk_failed): MemoryError: out of memory in chunk" in captured.err
    assert "2 of 2 members lost in 1 failed chunk(s)" in captured.err
    assert "chunk_failed 2" in captured.out and "not run" not in captured.out


def test_sweep_state_variable_needs_no_x0_entry(tmp_path, capsys):
    out = tmp_path / "q.npz"
    code, _ = run_cli(["sweep", "double_pendulum", "--grid", "q1=0,0.5", *DP_RUN, "--x0", "q2=0",
                       "--out", out], capsys)
    assert code == 0
    data = np.load(out)
    assert data["q_max"][0, 0] == 0.0  # the pendulum at rest stays at rest
    # energy: released at rest from (q1, q2) = (0.5, 0), V <= V(0) needs cos q2 >= 1 + 2 (cos 0.5 -
    # cos q1), so |q1| <= 0.5 throughout, the max attained at t = 0 (rk4's energy error ~1e-12)
    assert data["q_max"][1, 0] == pytest.approx(0.5, abs=1e-8)


def test_sweep_on_a_dask_scheduler(tmp_path, capsys):
    distributed = pytest.importorskip("dask.distributed")
    out = tmp_path / "dask.npz"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False,
                                  dashboard_address=None) as cluster:
        code, _ = run_cli(["sweep", "double_pendulum", "--grid", "m2=0.5,1", "--grid", "q1=0.1,0.2", *DP_RUN,
                           "--x0", "q2=0", "--scheduler", cluster.scheduler_address, "--out", out], capsys)
    assert code == 0
    local = tmp_path / "local.npz"
    run_cli(["sweep", "double_pendulum", "--grid", "m2=0.5,1", "--grid", "q1=0.1,0.2", *DP_RUN, "--x0", "q2=0",
             "--out", local], capsys)
    # same C function on the same inputs: bitwise equal to the local-thread run
    np.testing.assert_array_equal(np.load(out)["x_final"], np.load(local)["x_final"])


# -- the heatmap helpers behind --heatmap -----------------------------------------------------
def synthetic_sweep(status, q_max, trajectories=None, t=None) -> SweepResult:
    """A 2 x 3 grid over (a, b) with given per-member status and q_max; one coordinate q."""
    n = len(status)
    return SweepResult(
        columns=("a", "b"), values=np.array(list(itertools.product([1.0, 2.0], [10.0, 20.0, 30.0]))),
        grid=(np.array([1.0, 2.0]), np.array([10.0, 20.0, 30.0])), x_final=np.zeros((n, 2)),
        q_max=np.asarray(q_max, dtype=float).reshape(n, 1), energy_error=np.zeros(n),
        status=np.asarray(status), steps_done=np.zeros(n, int), blowup_time=np.full(n, np.nan), t=t,
        trajectories=trajectories, state_names=("q", "q_d"), coordinate_names=("q",), completed=True)


def test_first_crossing_time_interpolates_and_flags_missed_excursions():
    # q(t) = c t on t = 0, 0.1, ..., 1: crossing pi exactly at t = pi / c (linear, so the
    # interpolation is exact); c = 1 never crosses; the last member's q_max says it crossed
    # between samples, which the samples cannot time
    t = np.linspace(0.0, 1.0, 11)
    slopes = np.array([1.0, 4.0, 10.0, 2 * np.pi, 5.0, 1.0])
    traj = np.zeros((6, 11, 2))
    traj[:, :, 0] = -slopes[:, None] * t  # sign does not matter: |q|
    q_max = slopes.copy()
    q_max[-1] = 4.0
    result = synthetic_sweep([0] * 6, q_max, traj, t)
    with pytest.warns(RuntimeWarning, match="1 member"):
        got = first_crossing_time(result, ("q",), np.pi)
    want = np.array([np.nan, np.pi / 4, np.pi / 10, 0.5, np.pi / 5, np.nan])
    np.testing.assert_allclose(got, want, rtol=1e-12)


def test_heatmap_greys_and_counts_failed_members():
    status = [0, 2, 0, 0, 1, 0]
    fig = plot_heatmap(synthetic_sweep(status, np.arange(6.0)), "q_max")
    ax = fig.axes[0]
    assert "2 of 6 members failed" in ax.get_title()
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("b", "a")  # x = second column, y = first
    values = ax.collections[0].get_array()  # C order over (a, b) = the members' order
    np.testing.assert_array_equal(np.ma.getmaskarray(values).ravel(), np.array(status) != 0)
    np.testing.assert_array_equal(values.compressed(), [0.0, 2.0, 3.0, 5.0])
    assert fig.axes[1].get_ylabel() == "max |q| over the run"  # the colorbar
    assert any("failed (status != ok): 2" in text.get_text() for text in fig.legends[0].get_texts())



def test_heatmap_of_a_failure_field_greys_members_not_run_or_lost():
    """Found by review: blowup_time drew members lost with their chunk (CHUNK_FAILED) or not run
    (NOT_RUN, an interrupted sweep) white and counted them as "completed (no failure)", and
    steps_done drew them as 0 steps. They have no value of any field: grey, in the legend. A run
    that failed by itself (status 1) keeps its value, the point of a failure field."""
    status = [0, 1, CHUNK_FAILED, CHUNK_FAILED, NOT_RUN, 0]
    result = dataclasses.replace(synthetic_sweep(status, np.zeros(6)), steps_done=np.array([9, 4, 0, 0, 0, 9]),
                                 blowup_time=np.array([np.nan, 0.4, np.nan, np.nan, np.nan, np.nan]))
    lost = np.array([False, False, True, True, True, False])
    for field in ("blowup_time", "steps_done"):
        fig = plot_heatmap(result, field)
        values = fig.axes[0].collections[0].get_array()  # not drawn by value: lost, or NaN (white)
        np.testing.assert_array_equal(np.ma.getmaskarray(values).ravel(), lost | np.isnan(getattr(result, field)))
        legend = [text.get_text() for text in fig.legends[0].get_texts()]
        assert "lost (their chunk raised): 2" in legend and "not run: 1" in legend, (field, legend)
        if field == "blowup_time":
            assert "completed (no failure): 2" in legend, legend


# -- derive, emit, demo -----------------------------------------------------------------------
# The double pendulum in absolute angles q1, q2 from the downward vertical, hand-derived from
# the Lagrangian of Landau & Lifshitz, Mechanics, Sec. 5, Problem 1:
#   L = (m1 + m2)/2 l1^2 q1d^2 + m2/2 l2^2 q2d^2 + m2 l1 l2 q1d q2d cos(q1 - q2)
#       + (m1 + m2) g l1 cos q1 + m2 g l2 cos q2,
# whose Lagrange equations are M(q) qdd = F(q, qd) with M, F below.
def landau_double_pendulum():
    q1, q2, u1, u2, m1, m2, l1, l2, g = sp.symbols("q1 q2 q1_d q2_d m1 m2 l1 l2 g")
    c, s = sp.cos(q1 - q2), sp.sin(q1 - q2)
    M = sp.Matrix([[(m1 + m2) * l1**2, m2 * l1 * l2 * c], [m2 * l1 * l2 * c, m2 * l2**2]])
    F = sp.Matrix([-m2 * l1 * l2 * u2**2 * s - (m1 + m2) * g * l1 * sp.sin(q1),
                   m2 * l1 * l2 * u1**2 * s - m2 * g * l2 * sp.sin(q2)])
    return M, F, (q1, q2, u1, u2), (m1, m2, l1, l2, g)


def landau_reference(x0, t_end, p):
    """The Landau-Lifshitz equations above, solved by scipy's DOP853 at rtol = atol = 1e-12."""
    from scipy.integrate import solve_ivp

    M, F, state, params = landau_double_pendulum()
    accel = sp.lambdify([state, params], M.LUsolve(F), "numpy")

    def rhs(t, x):
        return np.concatenate([x[2:], np.ravel(accel(x, p))])
    return solve_ivp(rhs, (0.0, t_end), x0, method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]


def test_derive_prints_the_textbook_double_pendulum(capsys):
    code, text = run_cli(["derive", "double_pendulum"], capsys)
    assert code == 0
    M, F, state, params = landau_double_pendulum()
    names = {str(s): s for s in (*state, *params)}
    printed = dict(line.split(" = ", 1) for line in text.splitlines() if line.startswith(("M[", "F[")))
    assert len(printed) == 6, text
    for i in range(2):
        assert sp.simplify(sp.sympify(printed[f"F[{i}]"], locals=names) - F[i]) == 0, printed[f"F[{i}]"]
        for j in range(2):
            got = sp.sympify(printed[f"M[{i}, {j}]"], locals=names)
            assert sp.simplify(got - M[i, j]) == 0, (i, j, got)


def test_derive_pretty_prints_pictures(capsys):
    code, text = run_cli(["derive", "double_pendulum", "--pretty"], capsys)
    assert code == 0 and "M =" in text and "F =" in text and "M[0, 0]" not in text


def test_emit_header_declares_the_requested_methods_and_compiles(tmp_path, capsys, require_tool):
    gcc = require_tool("gcc")
    code, text = run_cli(["emit", "double_pendulum", "--precision", "float", "--methods",
                          "rk4,symplectic_euler,implicit_midpoint", "--out", tmp_path / "fw"], capsys)
    assert code == 0 and "wrote" in text
    header = (tmp_path / "fw" / "lcg_double_pendulum.h").read_text()
    for function in ("step_rk4", "step_symplectic_euler", "step_implicit_midpoint", "momentum", "jacobian"):
        # the methods' own outputs (momentum, jacobian) were added without being asked for
        assert f" lcg_double_pendulum_{function}(float " in header, function
    assert "step_heun" not in header
    subprocess.run([gcc, "-std=c99", "-Wall", "-Wextra", "-Wpedantic", "-Werror", "-c",
                    str(tmp_path / "fw" / "lcg_double_pendulum.c"), "-o", str(tmp_path / "fw.o")],
                   check=True, capture_output=True, text=True)


DRIVER = """#include <stdio.h>
#include "lcg_double_pendulum.h"
int main(void) {
    double t = 0.0, x[4] = {1.0, 0.5, 0.0, 0.0}, p[5] = {1.0, 0.5, 1.0, 1.0, 9.81};
    double work[LCG_DOUBLE_PENDULUM_WORK_SIZE];
    for (int k = 0; k < 500; ++k)
        if (lcg_double_pendulum_step_rk4(&t, x, p, 1e-3, work) != 0) return 1;
    printf("%.17g %.17g %.17g %.17g %.17g\\n", t, x[0], x[1], x[2], x[3]);
    return 0;
}
"""


def test_emitted_rk4_step_matches_the_textbook_equations(tmp_path, capsys, require_tool):
    gcc = require_tool("gcc")
    assert run_cli(["emit", "double_pendulum", "--methods", "rk4", "--out", tmp_path], capsys)[0] == 0
    header = (tmp_path / "lcg_double_pendulum.h").read_text()
    assert re.search(r"p\[0\]\s*=?\s*m1\b.*p\[1\]\s*=?\s*m2\b", header, re.DOTALL), "parameter order changed"
    (tmp_path / "main.c").write_text(DRIVER)
    exe = tmp_path / "dp"
    subprocess.run([gcc, "-std=c99", "-O2", "-Wall", "-Werror", f"-I{tmp_path}", str(tmp_path / "main.c"),
                    str(tmp_path / "lcg_double_pendulum.c"), "-lm", "-o", str(exe)],
                   check=True, capture_output=True, text=True)
    t, *x = map(float, subprocess.run([str(exe)], check=True, capture_output=True, text=True).stdout.split())
    assert t == pytest.approx(0.5, abs=1e-12)
    want = landau_reference([1.0, 0.5, 0.0, 0.0], 0.5, (1.0, 0.5, 1.0, 1.0, 9.81))
    np.testing.assert_allclose(x, want, rtol=0, atol=1e-9)  # rk4, h = 1e-3 over 0.5 s: ~1e-12


def test_demo_final_state_error_against_dop853_is_small(capsys):
    code, text = run_cli(["demo"], capsys)
    assert code == 0
    line = next(line for line in text.splitlines() if "final-state error against scipy DOP853" in line)
    # rk4 at h = 1e-3 over 10 s of the double pendulum: global error C h^4 with C ~ 1e3..1e4
    assert float(line.rsplit(":", 1)[1]) < 1e-6, line


def test_examples_lists_every_model_with_full_description_coordinates_and_parameters(capsys):
    from lagcodegen.catalog import EXAMPLES

    code, text = run_cli(["examples"], capsys)
    assert code == 0
    entries = {entry.splitlines()[0]: entry for entry in text.strip().split("\n\n")}
    assert list(entries) == list(EXAMPLES)
    for name, entry in entries.items():
        lines = entry.splitlines()[1:]
        described = lines[:next(i for i, line in enumerate(lines) if line.strip().startswith("coordinates:"))]
        description = " ".join(line.strip() for line in described)
        # whole sentences, not a first line cut mid-sentence; no RST markup
        assert len(description) > 30 and description.endswith("."), (name, description)
        assert "`" not in entry, entry
    # the double pendulum's coordinates and default parameters (catalog.pendulum_chain: unit
    # masses and lengths, g = 9.81)
    assert "coordinates: q1, q2\n" in entries["double_pendulum"]
    assert "parameters: m1 = 1, m2 = 1, l1 = 1, l2 = 1, g = 9.81" in entries["double_pendulum"]
    assert "coordinates: q1, q2, q3, q4, q5" in entries["pendulum_chain_5"]


def test_top_level_help_is_plain_text(capsys):
    with pytest.raises(SystemExit) as info:
        main(["--help"])
    text = capsys.readouterr().out
    assert info.value.code == 0 and "``" not in text and "`" not in text
    for word in ("examples", "derive", "emit", "simulate", "sweep", "demo", "--traceback", "Exit codes"):
        assert word in text, word


DRIVEN_OSCILLATOR = '''
import sympy as sp, sympy.physics.mechanics as me
from lagcodegen import Model
x, F = me.dynamicsymbols("x F")
m, c, k = sp.symbols("m c k", positive=True)
model = Model("driven", [x], [m, c, k], kinetic_energy=m * x.diff()**2 / 2, potential_energy=k * x**2 / 2,
              generalized_forces={x: F - c * x.diff()}, inputs=[F], parameter_values={"m": 2, "c": 0.4, "k": 8})
'''


def test_linearize_prints_a_b_and_the_modes(tmp_path, capsys):
    """m x'' + c x' + k x = F by hand: A = [[0, 1], [-k/m, -c/m]], B = [[0], [1/m]];
    w_n = sqrt(k/m) = 2, zeta = c / (2 sqrt(k m)) = 0.05."""
    path = tmp_path / "driven.py"
    path.write_text(DRIVEN_OSCILLATOR)
    code, out = run_cli(["linearize", str(path), "--inputs", "F=1"], capsys)
    assert code == 0
    assert "r = (F)" in out and "[[ 0.   1. ]\n [-4.  -0.2]]" in out and "[[0. ]\n [0.5]]" in out
    assert out.count("  2  0.05") == 2
    assert "'G' is not an input" in cli_error(["linearize", str(path), "--inputs", "G=1"], capsys)
    assert "'y' is not a state" in cli_error(["linearize", str(path), "--at", "y=1"], capsys)


def test_ctrl_c_stops_a_long_simulate_at_once(tmp_path):
    """Found by review: simulate made one blocking C call, so Ctrl-C stopped it only when the whole
    loop had run (a run of 1e8 steps, 20 s after the signal; one of 3e15 steps never). Now the
    call runs in a thread and the command exits 130 promptly. The run here takes minutes (1e9
    steps), so an exit within 60 s of the signal is the interruption, not the end of the run."""
    import os
    import signal
    import sys
    import time

    env = dict(os.environ, LAGCODEGEN_CACHE_DIR=str(tmp_path / "cache"))
    command = [sys.executable, "-m", "lagcodegen.cli.commands", "simulate", "double_pendulum", "--h", "1e-3",
               "--x0", "q1=1,q2=0"]
    subprocess.run(command + ["--t-end", "0.01"], env=env, capture_output=True, check=True, timeout=300)  # compiled
    process = subprocess.Popen(command + ["--t-end", "1e6", "--stride", "1000000"], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.PIPE, text=True)
    time.sleep(6)  # imports and the cached build: then it is in the C loop
    process.send_signal(signal.SIGINT)
    try:
        _, err = process.communicate(timeout=60)
    except subprocess.TimeoutExpired:
        process.kill()
        pytest.fail("simulate did not stop within 60 s of Ctrl-C")
    assert process.returncode == 130 and "interrupted" in err, err


def test_flags_prefixes_and_warnings_are_one_line_each(capsys):
    """Found by review: --traceback after the command gave a traceback of argparse's refusal and
    exit 1; an unknown option of a command was reported as "lagcodegen: error"; warnings came as
    Python's file:line: Category: text and the source line. A run that stops early (m2 = 0: a
    singular mass matrix) warns."""
    assert main(["derive", "double_pendulum", "--traceback"]) == 0
    capsys.readouterr()
    assert main(["derive", "double_pendulum", "--bogus"]) == EXIT_USAGE
    assert capsys.readouterr().err.startswith("lagcodegen derive: error: unrecognized arguments: --bogus")
    code = main(["simulate", "double_pendulum", "--t-end", "0.1", "--h", "1e-3", "--x0", "q1=1,q2=0",
                 "--param", "m2=0"])
    err = capsys.readouterr().err
    assert code == EXIT_FAILED
    lines = [line for line in err.splitlines() if line]
    assert lines and all(line.startswith("lagcodegen simulate: warning: ") for line in lines), err


def test_emit_writes_both_files_or_neither(tmp_path, capsys):
    """Found by review: with the source's name taken by a directory, emit wrote the new header and
    failed on the source, leaving a header beside whatever source was there. Now nothing is
    written; and a write that fails leaves no partial file behind."""
    out = tmp_path / "out"
    (out / "lcg_double_pendulum.c").mkdir(parents=True)
    message = cli_error(["emit", "double_pendulum", "--out", out], capsys)
    assert "lcg_double_pendulum.c exists and is not a file; nothing was written" in message
    assert sorted(p.name for p in out.iterdir()) == ["lcg_double_pendulum.c"]
    (out / "lcg_double_pendulum.c").rmdir()
    code, _ = run_cli(["emit", "double_pendulum", "--out", out], capsys)
    assert code == 0 and sorted(p.name for p in out.iterdir()) == ["lcg_double_pendulum.c", "lcg_double_pendulum.h"]


def test_param_and_params_are_one_option(capsys):
    """Found by review: simulate took --param and linearize --params, and each refused the other's
    spelling ("unrecognized arguments"). Both take both, with the same effect (the linearization at
    m2 = 2 differs from the default m2's)."""
    base = ["double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "0.01", "--h", "1e-3"]
    assert main(["simulate", *base, "--params", "m2=2"]) == 0
    capsys.readouterr()
    printed = {}
    for option in ("--param", "--params", None):
        assert main(["linearize", "double_pendulum", *([option, "m2=2"] if option else [])]) == 0
        printed[option] = capsys.readouterr().out
    assert printed["--param"] == printed["--params"] != printed[None]
