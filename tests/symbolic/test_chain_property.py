"""Property: for random planar pendulum chains, qdd = M^-1 F of lagcodegen equals sympy's.

Independent source: sympy's ``LagrangesMethod``, built here from points and frames with the joint
damping given as torques on the link frames (sympy computes their generalized forces itself),
while lagcodegen gets the catalog chain plus the damping as hand-written generalized forces
Q_j = -c_j (u_j - u_{j-1}) + c_{j+1} (u_{j+1} - u_j). Chains of n = 1..4 links, masses and
lengths random positive rationals or floats, random states; compared at 30 digits, relative 1e-10.
"""
from __future__ import annotations

import dataclasses
from fractions import Fraction
from functools import cache

import pytest
import sympy as sp
import sympy.physics.mechanics as me
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from lagcodegen import catalog, derive_equations

t = me.dynamicsymbols._t
DIGITS = 30
RTOL = sp.Float("1e-10", DIGITS)


def chain_symbols(n: int):
    m = sp.symbols(f"m1:{n + 1}", positive=True)
    l = sp.symbols(f"l1:{n + 1}", positive=True)
    c = sp.symbols(f"c1:{n + 1}", nonnegative=True)
    return m, l, sp.Symbol("g", positive=True), c


def ours(n: int, route: str, damped: bool):
    """lagcodegen's equations of the catalog chain, with joint damping as generalized forces."""
    model = catalog.pendulum_chain(n, route)
    if damped:
        _, _, _, c = chain_symbols(n)
        qd = [q.diff(t) for q in model.coordinates]
        rel = [qd[0]] + [qd[j] - qd[j - 1] for j in range(1, n)]  # joint j's relative rate
        forces = {q: -c[j] * rel[j] + (c[j + 1] * rel[j + 1] if j + 1 < n else 0)
                  for j, q in enumerate(model.coordinates)}
        model = dataclasses.replace(model, parameters=tuple(model.parameters) + tuple(c),
                                    generalized_forces=forces)
    return derive_equations(model)


@cache
def sympys(n: int, damped: bool):
    """sympy's LagrangesMethod for the same chain, built independently: (M, F, q, qd)."""
    m, l, g, c = chain_symbols(n)
    q = me.dynamicsymbols(f"q1:{n + 1}")
    N = me.ReferenceFrame("N")
    O = me.Point("O")
    O.set_vel(N, 0)
    frames, particles, previous = [], [], O
    for i in range(n):
        frame = N.orientnew(f"L{i + 1}", "Axis", (q[i], N.z))
        bob = previous.locatenew(f"P{i + 1}", -l[i] * frame.y)  # l_i (sin q_i, -cos q_i)
        bob.v2pt_theory(previous, N, frame)
        particle = me.Particle(f"bob{i + 1}", bob, m[i])
        particle.potential_energy = m[i] * g * bob.pos_from(O).dot(N.y)
        frames.append(frame)
        particles.append(particle)
        previous = bob
    loads = []
    if damped:
        for j in range(n):  # joint j between link j-1 (ground for j = 0) and link j
            outer = frames[j]
            w_rel = outer.ang_vel_in(N) - (frames[j - 1].ang_vel_in(N) if j else 0 * N.z)
            loads.append((outer, -c[j] * w_rel))
            if j:
                loads.append((frames[j - 1], c[j] * w_rel))
    lm = me.LagrangesMethod(me.Lagrangian(N, *particles), q, forcelist=loads or None, frame=N)
    lm.form_lagranges_equations()
    qd = [qi.diff(t) for qi in q]
    return lm.mass_matrix, lm.forcing, q, qd


def exact(value) -> sp.Expr:
    return sp.Rational(value.numerator, value.denominator) if isinstance(value, Fraction) else sp.Float(value, 17)


positives = st.one_of(st.fractions(min_value=Fraction(1, 10), max_value=10, max_denominator=50),
                      st.floats(min_value=0.1, max_value=10.0, allow_nan=False, allow_infinity=False))


@st.composite
def chains(draw):
    n = draw(st.integers(1, 4))
    return dict(
        n=n,
        route=draw(st.sampled_from(["energies", "bodies"])),
        masses=draw(st.lists(positives, min_size=n, max_size=n)),
        lengths=draw(st.lists(positives, min_size=n, max_size=n)),
        damping=draw(st.one_of(st.none(), st.lists(st.floats(0.0, 5.0), min_size=n, max_size=n))),
        g=draw(st.floats(0.5, 20.0)),
        angles=draw(st.lists(st.floats(-3.2, 3.2), min_size=n, max_size=n)),
        rates=draw(st.lists(st.floats(-5.0, 5.0), min_size=n, max_size=n)),
    )


def solve(M, F, table) -> sp.Matrix:
    Mx = M.xreplace(table).evalf(DIGITS)
    Fx = F.xreplace(table).evalf(DIGITS)
    return Mx.LUsolve(Fx).evalf(DIGITS)


@pytest.fixture(scope="module")
def derived():
    """`ours`, cached per test session (not per process: a mutation run forks its test runs from
    one process, and a cache filled before the fork would hide every mutant of the derivation)."""
    return cache(ours)


@settings(max_examples=15, deadline=None, database=None, suppress_health_check=[HealthCheck.too_slow])
@given(chain=chains())
def test_chain_accelerations_match_sympy_lagranges_method(chain, derived):
    n, damped = chain["n"], chain["damping"] is not None
    m, l, g, c = chain_symbols(n)
    values = {**dict(zip(m, map(exact, chain["masses"]))), **dict(zip(l, map(exact, chain["lengths"]))),
              g: exact(chain["g"])}
    if damped:
        values.update(zip(c, map(exact, chain["damping"])))
    angles, rates = list(map(exact, chain["angles"])), list(map(exact, chain["rates"]))

    eom = derived(n, chain["route"], damped)
    got = solve(eom.mass_matrix, eom.forcing,
                {**values, **dict(zip(eom.q, angles)), **dict(zip(eom.u, rates))})

    M, F, q, qd = sympys(n, damped)
    # qd before q: xreplace of q(t) inside Derivative(q(t), t) would otherwise break the speeds.
    expected = solve(M.xreplace(dict(zip(qd, rates))), F.xreplace(dict(zip(qd, rates))),
                     {**values, **dict(zip(q, angles))})

    scale = max(sp.Float(1, DIGITS), *[abs(e) for e in expected])
    for a, b in zip(got, expected):
        assert abs(a - b) <= RTOL * scale, (chain, list(got), list(expected))
