"""sympy.physics.mechanics' own test systems, fed to lagcodegen unchanged (tools/sympy_peer_survey.py).

Every KanesMethod, LagrangesMethod, System and JointsMethod that the installed sympy's test files
form is either compiled (at -O0, as the fuzz: the derivation and the generated C are checked here, the
optimizer elsewhere) and its rhs equals sympy's ``mass_matrix_full \\ forcing_full`` (the
independent reference) at random states, parameters and inputs to 1e-10, or refused with one of
the documented reasons below; 1 s of the compiled RK4 also follows scipy's DOP853 on sympy's rhs.
test_kane3's bicycle runs on its own (sympy's test function stopped once its KanesMethod is formed:
its own linearization checks take minutes).
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, ModelError, derive_equations

TOOL = Path(__file__).resolve().parents[2] / "tools" / "sympy_peer_survey.py"
FILES = ("test_kane", "test_kane2", "test_kane4", "test_kane5", "test_lagrange", "test_lagrange2",
         "test_jointsmethod", "test_linearize", "test_models")
#: what lagcodegen refuses, each for a stated reason: sympy's own mass matrix is singular
#: (test_issue_24887, test_sub_qdot2); dependent coordinates and speeds, auxiliary speeds and
#: more or fewer speeds than coordinates were refused until issue 14
REASONS = ("has no inertia",)


@pytest.fixture(scope="module")
def rows(tmp_path_factory):
    spec = importlib.util.spec_from_file_location("sympy_peer_survey", TOOL)
    survey = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = survey  # its dataclass looks itself up there
    spec.loader.exec_module(survey)
    return survey.survey(FILES, cache_dir=tmp_path_factory.mktemp("peers"), extra_compile_args=("-O0",))


def test_every_system_matches_or_is_refused_for_a_stated_reason(rows):
    assert len(rows) >= 50
    for row in rows:
        if row["status"] == "refused":
            assert any(reason in row["reason"] for reason in REASONS), row
        else:
            assert row["status"] == "matches", row
    matching = [row for row in rows if row["status"] == "matches"]
    assert len(matching) >= len(rows) - 3  # all but the three singular ones on sympy 1.14 (2026-11-25)
    # and 1 s of our RK4 (h = 1e-3) agrees with scipy's DOP853 at 1e-12 on sympy's own rhs, for every
    # matching system without constraints (a constrained one would need a consistent random state)
    followed = [row for row in matching if "trajectory_error" in row]
    assert len(followed) >= 36 and all(row["trajectory_error"] < 1e-8 for row in followed)


def test_driven_and_joints_systems_match(rows):
    """The systems driven by specified functions of t (cart force, joint torques, external forces)
    and the JointsMethod objects: refused before issue 13 and this change, matching now."""
    driven = [row for row in rows if row.get("inputs")]
    assert len(driven) >= 7 and all(row["status"] == "matches" for row in driven), driven
    joints = [row for row in rows if row["kind"] == "JointsMethod"]
    assert len(joints) >= 6 and all(row["status"] == "matches" for row in joints), joints


def test_kane_dependent_and_auxiliary_speeds_match(rows):
    """Kane's velocity constraints (dependent speeds), dependent coordinates, auxiliary speeds and a
    massless contact speed (the unreduced M singular): refused before issue 14, matching sympy now."""
    by_source = {}
    for row in rows:
        by_source.setdefault(row["source"], []).append(row)
    for source in ("test_kane2.test_aux_dep", "test_kane2.test_non_central_inertia", "test_kane2.test_sub_qdot",
                   "test_kane.test_aux", "test_kane5.test_kane_rolling_disc_lu",
                   "test_linearize.test_linearize_rolling_disc_kane",
                   "test_linearize.test_linearize_pendulum_kane_nonminimal"):
        assert by_source[source] and all(row["status"] == "matches" for row in by_source[source]), by_source[source]


def nonminimal_pendulum(constraint: str):
    """sympy's test_nonminimal_pendulum: a particle at (q1, q2) on q1^2 + q2^2 = L^2 (``"holonomic"``),
    or sliding with q1' = q2' (``"nonholonomic"``), gravity m g along x."""
    q1, q2 = me.dynamicsymbols("q1:3")
    L, m, g = sp.symbols("L m g", positive=True)
    constraints = {"hol_coneqs": [q1 ** 2 + q2 ** 2 - L ** 2]} if constraint == "holonomic" else \
        {"nonhol_coneqs": [q1.diff() - q2.diff()]}
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    P = O.locatenew("P", q1 * N.x + q2 * N.y)
    P.set_vel(N, P.pos_from(O).dt(N))
    method = me.LagrangesMethod(me.Lagrangian(N, me.Particle("p", P, m)), [q1, q2], forcelist=[(P, m * g * N.x)],
                                frame=N, **constraints)
    method.form_lagranges_equations()
    return method, (q1, q2), (L, m, g)


def test_lagranges_method_with_hol_coneqs_is_lagrange_i():
    """Second route: the same pendulum stated with Model(constraints=...) by its energies."""
    method, (q1, q2), (L, m, g) = nonminimal_pendulum("holonomic")
    ours = derive_equations(Model("sympy_pendulum", parameters=[L, m, g], sympy_model=method))
    t = me.dynamicsymbols._t
    energies = derive_equations(Model("pendulum", [q1, q2], [L, m, g],
                                      kinetic_energy=m * (q1.diff(t) ** 2 + q2.diff(t) ** 2) / 2,
                                      potential_energy=-m * g * q1, constraints=[q1 ** 2 + q2 ** 2 - L ** 2]))
    assert ours.m == 1 and "Lagrange I" in ours.route
    for name in ("mass_matrix", "forcing", "constraint_jacobian", "constraint_bias"):
        assert sp.simplify(getattr(ours, name) - getattr(energies, name)) == sp.zeros(*getattr(ours, name).shape)


def test_lagranges_method_constraints_by_kind():
    method, _, (L, m, g) = nonminimal_pendulum("holonomic")
    with pytest.raises(ModelError, match="constraint 0 uses symbols not declared as parameters: L"):
        derive_equations(Model("undeclared", parameters=[m, g], sympy_model=method))
    sliding, _, (L, m, g) = nonminimal_pendulum("nonholonomic")  # q1' = q2': a velocity constraint
    eom = derive_equations(Model("sliding", parameters=[m, g], sympy_model=sliding))
    assert "velocity constraints" in eom.route and eom.m == 1 and eom.n_holonomic == 0


@pytest.mark.slow
def test_the_whipple_bicycle_of_test_kane3_matches(tmp_path):
    """The field's benchmark as sympy's test_kane3 builds it (Kane, CRAMER solver, 4 coordinates,
    3 independent and 3 dependent speeds, the pitch dependent): sympy's rhs to 1e-10 at random
    consistent states, 1 s of RK4 follows DOP853 on sympy's rhs from a consistent start, and the
    weave, capsize and castor eigenvalues at 5 m/s are the benchmark's to 1e-8."""
    spec = importlib.util.spec_from_file_location("sympy_peer_survey", TOOL)
    survey = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = survey
    spec.loader.exec_module(survey)
    bicycle = survey.first_kane("test_kane3", "test_bicycle")
    row = survey.check(survey.Recorded("test_kane3.test_bicycle", bicycle, "KanesMethod"), 0, tmp_path)
    assert row["status"] == "matches", row
    assert row["eliminated"] == 3 and row["max_error"] < 1e-10 and row["trajectory_error"] < 1e-8
    # and its linearization at upright running, 5 m/s, against the benchmark's published matrix
    # (``Res`` in test_kane3, the parameter values converted as that test converts them)
    import numpy as np
    from scipy.optimize import brentq

    from lagcodegen.statics.state_space import linearize_state

    spec = importlib.util.spec_from_file_location("whipple_bicycle", TOOL.parents[1] / "tests" / "constraints"
                                                  / "test_whipple_bicycle.py")
    whipple = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(whipple)
    t = me.dynamicsymbols._t
    constants = sorted((bicycle.mass_matrix_full.free_symbols | bicycle.forcing_full.free_symbols) - {t}, key=str)
    values = {c: whipple.benchmark_values()[c.name] for c in constants}
    eom = derive_equations(Model("kane_bicycle", parameters=constants, sympy_model=bicycle, parameter_values=values))
    assert (eom.n_q, eom.n_u, eom.n_dependent) == (4, 6, 3)
    q, dependent = list(bicycle.q), list(bicycle._qdep)
    pitch = brentq(sp.lambdify(dependent, bicycle._f_h[0].xreplace(values | {c: 0 for c in q if c not in dependent})),
                   -1.0, 1.0)  # upright: the pitch that keeps the front wheel on the ground
    state = {s.name: 0.0 for s in eom.q + eom.u} | {"q4": pitch, "u3": 5.0 / values[sp.Symbol("WRrad")]}
    A = np.array(eom.constraint_jacobian.xreplace({s: state[s.name] for s in eom.q} | values).evalf(), dtype=float)
    speeds = np.array([state[s.name] for s in eom.u])
    speeds[3:] = np.linalg.solve(A[:, 3:], -A[:, :3] @ speeds[:3])  # the dependent speeds u1, u4, u6
    ours = linearize_state(eom, [state[s.name] for s in eom.q] + list(speeds), values={}).eigenvalues()
    for value in np.linalg.eigvals(whipple.benchmark_matrix(5.0)):
        assert np.abs(ours - value).min() < 1e-8 * max(1.0, abs(value)), (value, ours)
