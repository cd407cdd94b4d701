"""Property-based fuzz: random small models, derived and compiled by lagcodegen, against sympy.

Each example is a model with 1-3 coordinates:
    T = 1/2 u^T (L L^T + D) u + b(q)^T u      L lower triangular, D a positive diagonal: M is
                                              positive definite at every q by construction
    V(q), Q(q, u)                             from a small grammar of sin, cos, powers, products
It is derived by the energies route, compiled to C (rhs only, -O0: the fuzz checks the generated
C, not the optimizer), and its rhs at random states is compared with the reference: sympy's own
`LagrangesMethod` on L = T - V, whose equations M_ref qdd = F_ref we complete with the generalized
forces by the definition of Lagrange's equations, d/dt dL/dqd - dL/dq = Q, evaluated by
`lambdify` and `numpy.linalg.solve`. Tolerance 1e-10, relative to the size of the accelerations
(with a floor of 1: accelerations of order one carry an absolute error of the same size).

CI (`CI=true`) runs a fixed, derandomized set of `FUZZ_EXAMPLES` models (at least 200, issue 11);
locally set `LAGCODEGEN_FUZZ_EXAMPLES` for more. A failure prints the model and hypothesis'
reproduction blob (`@reproduce_failure`).
"""
from __future__ import annotations

import itertools
import os
import time

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import HealthCheck, assume, given, note, settings
from hypothesis import strategies as st

from lagcodegen import Model
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import make_rhs

pytestmark = [pytest.mark.fuzz, pytest.mark.compiler]

FUZZ_EXAMPLES = int(os.environ.get("LAGCODEGEN_FUZZ_EXAMPLES", "200"))
TOLERANCE = 1e-10
MAX_CONDITION = 1e4  # numpy's LU and our LDL^T each lose cond(M) * eps; keep that below 1e-12

t = me.dynamicsymbols._t
COORDINATES = me.dynamicsymbols("q1 q2 q3")
PARAMETERS = sp.symbols("p1 p2 p3", positive=True)
_model_numbers = itertools.count()
_models_checked = []


def _leaves(coordinates):
    # t makes some models rheonomic: M(q, t), b(q, t) and V(q, t) bring the dM/dt and db/dt terms
    return st.sampled_from(list(coordinates) + list(PARAMETERS) + [t, sp.Integer(1), sp.Integer(2), sp.Rational(1, 2)])


def expressions(coordinates, depth: int = 2):
    """A small grammar: leaves (coordinates, parameters, small numbers), sin, cos, powers 2-3,
    sums and products."""
    leaf = _leaves(coordinates)
    if depth == 0:
        return leaf
    inner = expressions(coordinates, depth - 1)
    return st.one_of(
        leaf,
        inner.map(sp.sin),
        inner.map(sp.cos),
        st.tuples(inner, st.sampled_from([2, 3])).map(lambda pair: pair[0] ** pair[1]),
        st.tuples(inner, inner).map(lambda pair: pair[0] + pair[1]),
        st.tuples(inner, inner).map(lambda pair: pair[0] * pair[1]),
    )


@st.composite
def random_models(draw):
    n = draw(st.integers(1, 3))
    q = COORDINATES[:n]
    qd = [c.diff(t) for c in q]
    expr = expressions(q)
    L = sp.zeros(n, n)
    for i in range(n):
        for j in range(i + 1):
            L[i, j] = draw(expr) if draw(st.booleans()) else sp.S.Zero
    diagonal = sp.diag(*[draw(st.sampled_from(PARAMETERS)) for _ in range(n)])
    M = L * L.T + diagonal
    u = sp.Matrix(qd)
    T = (u.T * M * u)[0] / 2
    if draw(st.booleans()):  # gyroscopic / moving-frame term b(q)^T u
        T += sum(draw(expr) * qd[i] for i in range(n) if draw(st.booleans()))
    V = draw(expr)
    forces = {}
    for i in range(n):
        if draw(st.booleans()):
            speed = draw(st.sampled_from(qd))
            forces[q[i]] = -draw(st.sampled_from(PARAMETERS)) * speed * draw(expr) + draw(expr)
    values = {p: draw(st.floats(0.5, 2.0)) for p in PARAMETERS}
    return q, T, V, forces, values


def reference_accelerations(q, T, V, forces, values):
    """qdd(x) from sympy's LagrangesMethod (plus Q), evaluated by lambdify."""
    method = me.LagrangesMethod(T - V, list(q))
    method.form_lagranges_equations()
    n = len(q)
    Q = sp.Matrix([forces.get(c, 0) for c in q])
    plain_q = sp.symbols(f"x0:{n}")
    plain_u = sp.symbols(f"v0:{n}")
    table = {c.diff(t): s for c, s in zip(q, plain_u)}
    table.update({c: s for c, s in zip(q, plain_q)})
    M = method.mass_matrix.subs(values).xreplace(table)
    F = (method.forcing + Q).subs(values).xreplace(table)
    M_f = sp.lambdify([t, plain_q, plain_u], M, "numpy")
    F_f = sp.lambdify([t, plain_q, plain_u], F, "numpy")

    def accelerations(at, state):
        positions, speeds = state[:n], state[n:]
        M_value = np.array(M_f(at, positions, speeds), dtype=float)
        forcing = np.array(F_f(at, positions, speeds), dtype=float).ravel()
        return np.linalg.solve(M_value, forcing), np.linalg.cond(M_value)
    return accelerations


@settings(max_examples=FUZZ_EXAMPLES, deadline=None, derandomize=os.environ.get("CI") == "true",
          print_blob=True, suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                                  HealthCheck.data_too_large])
@given(model=random_models(), states=st.lists(st.lists(st.floats(-2.0, 2.0), min_size=7, max_size=7),
                                              min_size=3, max_size=3))
def test_compiled_rhs_matches_sympy_lagranges_method(model, states):
    q, T, V, forces, values = model
    n = len(q)
    note(f"T = {T}\nV = {V}\nQ = {forces}\nvalues = {values}")
    reference = reference_accelerations(q, T, V, forces, values)
    checked = []
    for raw in states:
        at, state = raw[6], np.array(raw[:2 * n])
        expected, condition = reference(at, state)
        if condition < MAX_CONDITION and np.all(np.isfinite(expected)):
            checked.append((at, state, expected))
    assume(checked)
    number = next(_model_numbers)
    started = time.perf_counter()
    system = compile_model(
        Model(f"fuzz_{number}", list(q), list(PARAMETERS), kinetic_energy=T, potential_energy=V,
              generalized_forces=forces, parameter_values=values),
        outputs=("rhs",), methods=(), extra_compile_args=("-O0",))
    rhs = make_rhs(system)
    for at, state, expected in checked:
        derivative = rhs(at, state)
        np.testing.assert_array_equal(derivative[:n], state[n:])  # qd = u
        scale = max(1.0, float(np.max(np.abs(expected))))
        np.testing.assert_allclose(derivative[n:], expected, rtol=0, atol=TOLERANCE * scale,
                                   err_msg=f"model fuzz_{number} at t = {at}, state {state.tolist()}:\n"
                                           f"T = {T}\nV = {V}\nQ = {forces}\nvalues = {values}")
    _models_checked.append(time.perf_counter() - started)


def test_fuzz_checked_enough_models():
    """Issue 11 asks for at least 200 random models per CI run: count the ones really compared
    (hypothesis discards examples with no well-conditioned state)."""
    if not _models_checked:
        pytest.skip("the fuzz test did not run in this session (deselected)")
    assert len(_models_checked) >= min(200, FUZZ_EXAMPLES), (
        f"only {len(_models_checked)} random models were compiled and compared")
