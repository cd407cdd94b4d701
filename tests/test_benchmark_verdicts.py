"""The benchmark suites' verdicts, on rows shaped like their workers' (no timing here: the numbers are
made up, and the expected verdict follows from each goal's rule by hand). Found by review (helper-47):
PASS against a peer that never ran, that integrated other equations, or from runs whose members failed."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "benchmarks"))

import bench_integrators  # noqa: E402
import bench_scale  # noqa: E402
import bench_sweep  # noqa: E402


def test_a_peer_that_did_not_run_decides_nothing():
    rows = [{"level": level, "ours_seconds": 1e-3, **{key: None for key in bench_integrators.CONTENDERS}}
            for level in bench_integrators.LEVELS]
    found = {g["goal"]: g for g in bench_integrators.goals(rows, {"ours": "ok", "hand": "ok", "pydy": "ok",
                                                                  "jitcode": "error: ImportError"})}
    jitcode = [g for goal, g in found.items() if "JiTCODE" in goal]
    assert jitcode and all(g["status"] == "UNDECIDED" for g in jitcode)
    # a peer that ran but reaches no level is beaten at every level (its worker finished)
    assert found["ours faster than hand RK4 (C) at every level 1e-3..1e-10"]["status"] == "PASS"


def _sweep_rows(ratio: float, failed: int = 0, baseline_util: float = 1.0):
    rows = []
    for tag in bench_sweep.TAGS:
        for threads, util in ((1, baseline_util), (2, 1.95)):
            result = {"status": "ok", "members": 256, "n_steps": 1000, "wall": 1.0 / threads, "cpu": 1.0,
                      "util": util, "failed": failed}
            rows.append(bench_sweep._row(result, tag, "lcg", threads, "off"))
        rows.append(bench_sweep._row({"status": "ok", "members": 256, "n_steps": 1000, "wall": ratio, "cpu": ratio,
                                      "util": 1.0, "failed": 0}, tag, "mujoco", 1, "-"))
    return rows


def test_mujoco_goals_need_the_same_equations():
    checks_same = {str(tag): {"status": "ok", "ours_ok": True, "mujoco_diff": 1e-11} for tag in bench_sweep.TAGS}
    checks_other = {str(tag): {"status": "ok", "ours_ok": True, "mujoco_diff": 0.8} for tag in bench_sweep.TAGS}
    rows = _sweep_rows(ratio=100.0)  # MuJoCo 100x slower per member-step: past both goals
    assert [bench_sweep._mujoco_goal(rows, tag, checks_same)["status"] for tag in bench_sweep.TAGS] == ["PASS"] * 2
    assert [bench_sweep._mujoco_goal(rows, tag, checks_other)["status"] for tag in bench_sweep.TAGS] == \
        ["UNDECIDED"] * 2


def test_a_timed_sweep_with_failed_members_has_no_rate():
    row = _sweep_rows(ratio=100.0, failed=256)[0]
    assert "rate_cpu" not in row and row["status"] == "256 of 256 members failed: no rate"
    assert bench_sweep._per_core_goal(_sweep_rows(100.0, failed=3))["status"] == "FAIL"


@pytest.mark.parametrize("baseline_util, expected", [(1.0, "PASS"), (0.5, "UNDECIDED")])
def test_a_starved_one_thread_run_decides_no_speed_up(baseline_util, expected):
    # 2 threads at wall 0.5 s against 1 thread at 1.0 s: 2.0x, PASS only when the 1-thread run had its core
    assert bench_sweep._speedup_goal(_sweep_rows(100.0, baseline_util=baseline_util))["status"] == expected


def _scale_row(n, warm_final, rk4_final, rk4_runs_ok=True):
    def ok(ns, final, runs=True):
        return {"status": "ok", "ns_cpu": ns, "final": final, "runs_ok": runs, "check_ok": True}
    row = {"n": n, "warm": ok(2000.0, warm_final), "cold_rk4": ok(1500.0, rk4_final, rk4_runs_ok),
           "mujoco": ok(20000.0, [0.0, 1.0]), "pin_zero": ok(20000.0, [0.0, 1.0]), "cold": {"status": "ok"}}
    row |= {f"pin_{v}": ok(20000.0, [0.0, 1.0]) for v in bench_scale.PIN_RUNS}
    return row


def test_the_scale_goal_times_only_the_build_it_checked():
    sizes = bench_scale.STEP_GOAL_SIZES
    # the faster rk4-only build failed its runs: the default build (2000 ns, 10x) is the one timed
    rows = [_scale_row(n, [0.0, 1.0], [0.0, 1.0], rk4_runs_ok=False) for n in sizes]
    goal = bench_scale._step_goal(rows, "MuJoCo", 3.0)
    assert goal["status"] == "PASS" and "(2000 vs 20000 ns)" in goal["detail"]
    # the timed build's state is 0.5 off MuJoCo's: not the same equations
    rows = [_scale_row(n, [0.0, 1.0], [0.5, 1.0]) for n in sizes]
    assert bench_scale._step_goal(rows, "MuJoCo", 3.0)["status"] == "UNDECIDED"
