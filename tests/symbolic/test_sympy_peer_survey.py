"""sympy.physics.mechanics' own test systems, fed to lagcodegen unchanged (tools/sympy_peer_survey.py).

Every KanesMethod, LagrangesMethod, System and JointsMethod that the installed sympy's test files
form is either compiled and its rhs equals sympy's ``mass_matrix_full \\ forcing_full`` (the
independent reference) at random states, parameters and inputs to 1e-10, or refused with one of
the documented reasons below. The bicycle (test_kane3, two minutes of sympy) is left to the tool.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest

TOOL = Path(__file__).resolve().parents[2] / "tools" / "sympy_peer_survey.py"
FILES = ("test_kane", "test_kane2", "test_kane4", "test_kane5", "test_lagrange", "test_lagrange2",
         "test_jointsmethod", "test_linearize", "test_models")
#: what lagcodegen refuses today, each for a stated reason (issue 14 lifts the first five)
REASONS = ("has dependent coordinates", "has dependent speeds", "has auxiliary speeds",
           "independent speeds (", "LagrangesMethod with constraint multipliers",
           "has no inertia")  # the last: sympy's own mass matrix is singular (test_issue_24887)


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("sympy_peer_survey", TOOL)
    survey = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = survey  # its dataclass looks itself up there
    spec.loader.exec_module(survey)
    return survey.survey(FILES, cache_dir=tmp_path_factory.mktemp("peers"))


def test_every_system_matches_or_is_refused_for_a_stated_reason(rows):
    assert len(rows) >= 50
    for row in rows:
        if row["status"] == "refused":
            assert any(reason in row["reason"] for reason in REASONS), row
        else:
            assert row["status"] == "matches", row
    matching = [row for row in rows if row["status"] == "matches"]
    assert len(matching) >= 37  # 37 of 51 on sympy 1.14 (2026-11-25)


def test_driven_and_joints_systems_match(rows):
    """The systems driven by specified functions of t (cart force, joint torques, external forces)
    and the JointsMethod objects: refused before issue 13 and this change, matching now."""
    driven = [row for row in rows if row.get("inputs") and "dependent" not in row.get("reason", "")
              and "auxiliary" not in row.get("reason", "") and "independent speeds" not in row.get("reason", "")]
    assert len(driven) >= 7 and all(row["status"] == "matches" for row in driven), driven
    joints = [row for row in rows if row["kind"] == "JointsMethod"]
    assert len(joints) >= 6 and all(row["status"] == "matches" for row in joints), joints
