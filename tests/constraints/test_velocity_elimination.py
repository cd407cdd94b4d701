"""Velocity constraints eliminated on the energies and bodies routes (issue 14, item 2):
``Model(..., motion_constraints=[...], dependent_speeds=[...])``.

The named coordinates' rates are the dependent speeds: the state holds q and the other rates,
the dependent ones are solved from A u + b = 0 at every evaluation and the unreduced M, F are
reduced by C^T M C in C, as for Kane's u_dependent (tests/numeric/test_kane_speeds.py). The
models are those of test_chaplygin_sleigh.py and test_rolling_disc.py; references, each stated
at its test:
- the sleigh's closed form (Neimark and Fufaev; Bloch), in ``test_chaplygin_sleigh.closed_form``;
- sympy's own upright linearization of the rolling disc (``test_rolling_disc.sympy_upright_a``);
- the multipliers formulation of the same model (Lagrange I; a second derivation of its motion).
"""
from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import trapezoid
from test_chaplygin_sleigh import VALUES, closed_form, sleigh
from test_rolling_disc import CRITICAL, lean_period, rolling_disc, sympy_upright_a

from lagcodegen import Model, ModelError, derive_equations
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import c_pointer, dependent_speeds, make_rhs, parameter_vector, simulate
from lagcodegen.status import Status

pytestmark = pytest.mark.compiler

t = me.dynamicsymbols._t
X, Y, THETA = me.dynamicsymbols("x y theta")


@pytest.fixture(scope="module")
def sleighs(tmp_path_factory):
    """The sleigh with y' (``"y"``) or x' (``"x"``) dependent, compiled with the energy output."""
    cache = tmp_path_factory.mktemp("sleighs")
    return {name: compile_model(sleigh(dependent_speeds=[coordinate]), methods=("rk4",), cache_dir=cache)
            for name, coordinate in (("y", Y), ("x", X))}


def test_the_dependent_rate_goes_last_and_is_eliminated():
    """Second route: the multipliers equations of the same sleigh, rows and columns permuted."""
    kept = derive_equations(sleigh())
    eom = derive_equations(sleigh(dependent_speeds=[Y]))
    x_d, y_d, theta_d = kept.u
    assert eom.u == (x_d, theta_d, y_d) and eom.n_dependent == 1 and eom.m == 1
    assert list(eom.kinematics) == [x_d, y_d, theta_d]  # qd = K stays in coordinate order: a permutation of u
    assert "(dependent speeds y_d eliminated)" in eom.route
    order = [0, 2, 1]
    assert sp.simplify(eom.mass_matrix - kept.mass_matrix.extract(order, order)) == sp.zeros(3, 3)
    assert sp.simplify(eom.forcing - kept.forcing.extract(order, [0])) == sp.zeros(3, 1)
    assert sp.simplify(eom.constraint_jacobian - kept.constraint_jacobian.extract([0], order)) == sp.zeros(1, 3)
    again = derive_equations(sleigh(dependent_speeds=[Y], formulation="multipliers"))
    assert again.u == kept.u and again.n_dependent == 0 and "(Lagrange I)" in again.route


# (v0, w0, theta0): the heading turns by +1.60 and -2.66 rad over the 6 s (the closed form integrated),
# so theta stays 0.77 and 0.24 rad away from where the dependent block (cos theta for y', -sin theta
# for x') vanishes
CASES = {"y": [(0.5, 2.0, -0.8), (-0.3, -1.5, 1.3)], "x": [(0.5, 2.0, 0.77), (-0.3, -1.5, 2.9)]}


@pytest.mark.parametrize("dependent, v0, w0, theta0", [(d, *case) for d, cases in CASES.items() for case in cases])
def test_the_eliminated_sleigh_follows_the_closed_form(sleighs, dependent, v0, w0, theta0):
    """Closed form (test_chaplygin_sleigh.closed_form) for v (the speed along the blade) and w, and
    its conserved energy E = (m v0^2 + J w0^2) / 2 from the energy kernel, which reads the dependent
    rate; the blade constraint holds to round-off without projection, and the dependent speed is the
    constraint solved by hand (y' = x' tan(theta), x' = y' / tan(theta))."""
    system = sleighs[dependent]
    independent = "x_d" if dependent == "y" else "y_d"
    assert system.layout.speeds == (independent, "theta_d") and system.layout.dependent_speeds == (f"{dependent}_d",)
    start = v0 * (np.cos(theta0) if dependent == "y" else np.sin(theta0))
    run = simulate(system, {"x": 0.0, "y": 0.0, "theta": theta0, independent: start, "theta_d": w0},
                   t_end=6.0, h=1e-3, energy=True)
    assert run.ok and run.x.shape == (6001, 5)
    theta, solved = run["theta"], dependent_speeds(system, run.x)[:, 0]
    xd, yd = (run["x_d"], solved) if dependent == "y" else (solved, run["y_d"])
    by_hand = run["x_d"] * np.tan(theta) if dependent == "y" else run["y_d"] / np.tan(theta)
    np.testing.assert_allclose(solved, by_hand, rtol=1e-12, atol=1e-15)
    v_exact, w_exact = closed_form(run.t, v0, w0)
    np.testing.assert_allclose(xd * np.cos(theta) + yd * np.sin(theta), v_exact, atol=1e-9)
    np.testing.assert_allclose(run["theta_d"], w_exact, atol=1e-9)
    assert np.abs(-xd * np.sin(theta) + yd * np.cos(theta)).max() < 1e-15  # no sideways slip, by construction
    m, I, a = VALUES["m"], VALUES["I"], VALUES["a"]
    np.testing.assert_allclose(run.energy, (m * v0 ** 2 + (I + m * a ** 2) * w0 ** 2) / 2, rtol=1e-10)


def test_a_singular_dependent_block_at_the_start_is_named(sleighs):
    """x' dependent: A_D = -sin(theta) is exactly 0 at theta = 0 (the blade along x fixes x', not y')."""
    with pytest.raises(ValueError, match=r"dependent speeds x_d at t = 0\.0, .*lost rank"):
        simulate(sleighs["x"], {"x": 0.0, "y": 0.0, "theta": 0.0, "y_d": 0.0, "theta_d": 1.0}, t_end=1.0, h=1e-3)
    with pytest.raises(ValueError, match="lost rank"):
        dependent_speeds(sleighs["x"], [0.0, 0.0, 0.0, 0.0, 1.0])


def test_a_start_on_the_singular_heading_is_named(sleighs):
    """y' dependent at theta = pi/2: cos(pi/2) is 6e-17 in binary, not exactly 0, but 6e-17 of the
    constraint row's largest entry (sin(pi/2) = 1): singular to the rank tolerance, so the start is
    refused by name as for an exactly singular block, instead of running on a reduced mass matrix
    ~1e32 times its usual size."""
    with pytest.raises(ValueError, match=r"dependent speeds y_d at t = 0\.0, .*lost rank"):
        simulate(sleighs["y"], {"x": 0.0, "y": 0.0, "theta": np.pi / 2, "x_d": 0.0, "theta_d": 1.0},
                 t_end=1.0, h=1e-3)
    from lagcodegen.statics.state_space import linearize_state

    with pytest.raises(ValueError, match=r"do not fix the dependent speeds y_d at x0 = .*lost rank"):
        linearize_state(derive_equations(sleigh(dependent_speeds=[Y])), [0.0, 0.0, np.pi / 2, 0.0, 1.0], values={})


def test_a_nearly_singular_dependent_block_is_judged_against_the_whole_constraint_row(sleighs):
    """y' dependent, A = [-sin(theta), cos(theta)] (x', y'): at theta = pi/2 - 1e-14 the block
    A_D = cos(theta) is 1e-14 of the row's largest entry, below the rank tolerance 1e-12; measured
    against A_D alone (a 1 x 1 block is its own largest entry) it passed, and y' = x' tan(theta)
    came out as 1e14 x'. One step further from the pole it is regular and equals the hand formula."""
    near = np.pi / 2 - 1e-14
    with pytest.raises(ValueError, match="lost rank"):
        dependent_speeds(sleighs["y"], [0.0, 0.0, near, 1.0, 0.0])
    theta = np.pi / 2 - 1e-6
    solved = dependent_speeds(sleighs["y"], [0.0, 0.0, theta, 1.0, 0.0])[0]
    np.testing.assert_allclose(solved, np.tan(theta), rtol=1e-9)


@pytest.mark.parametrize("theta0, w0, h", [(1.40, 5.0, 0.05), (1.46, 10.0, 0.05), (1.50, 20.0, 0.02)])
def test_a_step_across_the_singular_heading_is_not_ok(sleighs, theta0, w0, h):
    """y' dependent: cos(theta) = 0 at theta = pi/2. Started spinning (v0 = 0), the heading passes
    pi/2 inside the first step by the closed form (test_chaplygin_sleigh.closed_form, w integrated),
    and no stage lands near it: before the monitor watched det(A_D), these runs went on with status
    OK and w wrong by 0.8-21 rad/s. The first step stops with LCG_SINGULAR_CONSTRAINTS: a later
    stage's det(A_D) = cos(theta) has the other sign than the start's, or differs from it by more
    than 2x (before the stages were judged, the sign change between the two states stopped the
    run at the second step's judgment)."""
    grid = np.linspace(0.0, h, 2001)
    _, w_exact = closed_form(grid, 0.0, w0)
    theta_h = theta0 + trapezoid(w_exact, grid)
    assert theta0 < np.pi / 2 < theta_h  # the first step crosses the singular heading
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        run = simulate(sleighs["y"], {"x": 0.0, "y": 0.0, "theta": theta0, "x_d": 0.0, "theta_d": w0},
                       t_end=1.0, h=h)
    assert run.status == Status.SINGULAR_CONSTRAINTS, run.status
    assert run.failed_step == 1


def test_a_dependent_speed_is_not_a_state_variable(sleighs):
    with pytest.raises(ValueError, match=r"y_d: dependent speed\(s\), computed from the velocity constraints"):
        simulate(sleighs["y"], {"x": 0.0, "y": 0.0, "theta": 0.0, "x_d": 1.0, "y_d": 0.0}, t_end=0.1, h=1e-3)


def test_what_elimination_does_not_offer_is_refused_by_name(sleighs):
    """As for Kane's eliminated models: no implicit method (jacobian), no multipliers or projection."""
    from lagcodegen.codegen.outputs import KernelError

    with pytest.raises(KernelError, match="dependent speeds are eliminated"):
        compile_model(sleigh(dependent_speeds=[Y]), outputs=("rhs", "jacobian"), methods=("rk4",))
    with pytest.raises(KernelError, match="eliminates its dependent speeds"):
        compile_model(sleigh(dependent_speeds=[Y]), outputs=("rhs", "multipliers"), methods=("rk4",))
    with pytest.raises(ValueError, match=r"project=True needs constraints kept with multipliers; model .* eliminates "
                       r"its velocity constraints \(dependent speeds y_d\)"):
        simulate(sleighs["y"], {"x": 0.0, "y": 0.0, "theta": 0.0}, t_end=0.1, h=1e-3, project=True)


# -- the rolling disc: x' and y' of the contact point dependent ---------------------------------------
@pytest.fixture(scope="module")
def discs(tmp_path_factory):
    """The rolling disc eliminated (x', y' dependent) and with multipliers, compiled with energy and points."""
    cache = tmp_path_factory.mktemp("discs")
    x, y = rolling_disc().coordinates[:2]
    return {formulation: compile_model(rolling_disc(dependent_speeds=[x, y], formulation=formulation),
                                       methods=("rk4",), cache_dir=cache)
            for formulation in ("elimination", "multipliers")}


def test_the_eliminated_disc_keeps_three_speeds(discs):
    layout = discs["elimination"].layout
    assert layout.speeds == ("psi_d", "theta_d", "phi_d") and layout.dependent_speeds == ("x_d", "y_d")
    assert layout.n_state == 8 and discs["multipliers"].layout.n_state == 10


def _assert_same_disc_bits(built, reference, seed: int) -> None:
    """The rhs and the dependent speeds at five random states, and a 500-step run, equal to the last
    bit in two builds of the eliminated disc."""
    rng = np.random.default_rng(seed)
    for state in rng.uniform(-1.0, 1.0, (5, 8)) + [0, 0, 0, 0.4, 0, 0, 0, 0]:  # theta near 0.4: off the singular set
        np.testing.assert_array_equal(make_rhs(built)(0.0, state), make_rhs(reference)(0.0, state))
        np.testing.assert_array_equal(dependent_speeds(built, state), dependent_speeds(reference, state))
    start = [0.0, 0.0, 0.0, 0.1, 0.0, 0.2, 0.0, 8.0]
    np.testing.assert_array_equal(simulate(built, start, t_end=0.5, h=1e-3).x,
                                  simulate(reference, start, t_end=0.5, h=1e-3).x)


@pytest.mark.parametrize("limit,marker,seed", [
    ("outputs.UNROLLED_LU_MAX", "_dense_factor(LU, ipiv", 3),
    ("steppers.SHARED_DYNAMICS_MIN_OPS", "LCG_SHARED int lcg_rolling_disc_dynamics(", 5),
], ids=["looped_lu", "shared_kernel"])
def test_another_kernel_layout_gives_the_same_bits(discs, tmp_path, monkeypatch, limit, marker, seed):
    """Second routes to the same numbers, each with a size limit lowered to 0 so that the disc takes it.
    A_D larger than codegen.lu.UNROLLED_LU_MAX keeps the looped dense_factor / dense_substitute: the
    same operations in the same order as the unrolled LU. A dynamics kernel of
    steppers.SHARED_DYNAMICS_MIN_OPS or more is compiled once in the two-part build (defined in part
    2, called by part 1's steppers): the same C function in another translation unit. Either way the
    rhs, the dependent speeds and a simulated run agree to the last bit with the usual build's."""
    from lagcodegen.codegen import outputs, steppers

    module, name = limit.split(".")
    monkeypatch.setattr({"outputs": outputs, "steppers": steppers}[module], name, 0)
    x, y = rolling_disc().coordinates[:2]
    other = compile_model(rolling_disc(dependent_speeds=[x, y]), methods=("rk4",), cache_dir=tmp_path)
    assert marker in other.sources.source
    assert marker not in discs["elimination"].sources.source
    _assert_same_disc_bits(other, discs["elimination"], seed=seed)


def test_only_the_multipliers_take_baumgarte_parameters(discs):
    # found by review: an FMU of an eliminated model offered baumgarte_alpha and _beta, which did nothing
    # (the dependent speeds are solved from the constraints, so w = A u + b = 0 at every evaluation)
    assert not any(name.startswith("baumgarte") for name in discs["elimination"].layout.parameters)
    assert {"baumgarte_alpha", "baumgarte_beta"} <= set(discs["multipliers"].layout.parameters)


def test_upright_rolling_wobbles_at_sympys_frequency(discs):
    """As test_rolling_disc's multipliers test: the lean oscillates at sympy's w_lean (A_sol) at 1.5 times
    the critical spin; here without projection, the rolling held by construction."""
    spin = 1.5 * CRITICAL
    w_lean = np.abs(np.linalg.eigvals(sympy_upright_a(spin)).imag).max()
    lean_rate = 1e-4
    system = discs["elimination"]
    run = simulate(system, [0, 0, 0, 0, 0, 0, lean_rate, spin], t_end=40.0, h=1e-3)
    assert run.ok
    np.testing.assert_allclose(lean_period(run), 2 * np.pi / w_lean, rtol=1e-6)
    np.testing.assert_allclose(np.abs(run["theta"]).max(), lean_rate / w_lean, rtol=1e-3)
    x_d, y_d = dependent_speeds(system, run.x).T  # x' = r cos(psi) phi', y' = r sin(psi) phi' (r = 1, by hand)
    np.testing.assert_allclose(x_d, np.cos(run["psi"]) * run["phi_d"], rtol=0, atol=1e-15)
    np.testing.assert_allclose(y_d, np.sin(run["psi"]) * run["phi_d"], rtol=0, atol=1e-15)


def _rhs_jacobian(system, x, eps=1e-6) -> np.ndarray:
    """Central differences of the compiled <prefix>_rhs (the eliminated 8-state ODE) at t = 0."""
    p = parameter_vector(system, {})
    rhs = getattr(system.lib, f"{system.layout.prefix}_rhs")

    def f(state):
        state = np.array(state, dtype=float)
        xdot = np.empty_like(state)
        assert rhs(0.0, c_pointer(system, state), c_pointer(system, p), c_pointer(system, xdot)) == 0
        return xdot

    columns = []
    for c in range(len(x)):
        step = np.zeros(len(x))
        step[c] = eps
        columns.append((f(x + step) - f(x - step)) / (2 * eps))
    return np.column_stack(columns)


@pytest.mark.parametrize("factor", [1.5, 0.5])
def test_the_linearization_about_upright_rolling_matches_sympys(discs, factor):
    """sympy's A_sol (Kane, its dependent speeds eliminated; 5 coordinates and 3 speeds, like ours) against
    (1) the Jacobian of the compiled eliminated right-hand side, by central differences, and (2)
    linearize_state of the eliminated equations (every speed, in their order: psi', theta', phi', x', y').
    The zeros form Jordan blocks: compared by count only, as test_rolling_disc does."""
    from lagcodegen.statics.state_space import linearize_state

    spin = factor * CRITICAL
    theirs = np.linalg.eigvals(sympy_upright_a(spin))
    significant = lambda lam: np.sort_complex(lam[np.abs(lam) > 1e-3])  # noqa: E731
    compiled = np.linalg.eigvals(_rhs_jacobian(discs["elimination"], np.array([0, 0, 0, 0, 0, 0, 0, spin])))
    np.testing.assert_allclose(significant(compiled), significant(theirs), atol=1e-7)
    assert (np.abs(compiled) <= 1e-3).sum() == 6
    x, y = rolling_disc().coordinates[:2]
    eom = derive_equations(rolling_disc(dependent_speeds=[x, y]))
    state = dict.fromkeys(("x", "y", "psi", "theta", "phi", "psi_d", "theta_d"), 0.0) | {"phi_d": spin, "x_d": spin,
                                                                                          "y_d": 0.0}
    linear = linearize_state(eom, state, values={})
    assert linear.basis.shape == (10, 8)
    np.testing.assert_allclose(significant(linear.eigenvalues()), significant(theirs), atol=1e-8)
    # the state as simulate takes it, (q, independent speeds): the constraints complete x', y'
    reduced = {k: v for k, v in state.items() if k not in ("x_d", "y_d")}
    in_order = [reduced[name] for name in ("x", "y", "psi", "theta", "phi", "psi_d", "theta_d", "phi_d")]
    for given in (reduced, in_order):
        again = linearize_state(eom, given, values={})
        np.testing.assert_allclose(again.x0, linear.x0, atol=1e-15)
        np.testing.assert_allclose(again.A, linear.A, atol=1e-12)
    with pytest.raises(ValueError, match="gives the dependent speed.* x_d .*but not y_d"):
        linearize_state(eom, reduced | {"x_d": spin}, values={})
    with pytest.raises(ValueError, match="x0 entry for theta_d"):
        linearize_state(eom, in_order[:6] + [float("nan"), spin], values={})


def test_the_eliminated_disc_moves_as_the_multipliers_disc(discs):
    """Second derivation route: the same model with multipliers (every speed in the state), from the
    same consistent state, 1 s of RK4 at h = 1e-3: coordinates, speeds (the dependent ones from the
    constraints), energy and the centre point agree to 1e-9."""
    q0, speeds = [0.0, 0.0, 0.3, 0.1, 0.0], {"psi_d": 0.2, "theta_d": 0.01, "phi_d": 2.0}
    full = q0 + [2.0 * np.cos(0.3), 2.0 * np.sin(0.3), 0.2, 0.01, 2.0]  # x' = r cos(psi) phi', y' = r sin(psi) phi'
    kept = simulate(discs["multipliers"], full, t_end=1.0, h=1e-3, energy=True, points=True)
    system = discs["elimination"]
    ours = simulate(system, q0 + list(speeds.values()), t_end=1.0, h=1e-3, energy=True, points=True)
    assert ours.ok and kept.ok
    names = discs["multipliers"].layout.coordinates + discs["multipliers"].layout.speeds
    dependent = dependent_speeds(system, ours.x)
    for name in names:
        mine = dependent[:, ("x_d", "y_d").index(name)] if name in ("x_d", "y_d") else ours[name]
        np.testing.assert_allclose(mine, kept[name], rtol=0, atol=1e-9, err_msg=name)
    np.testing.assert_allclose(ours.energy, kept.energy, rtol=0, atol=1e-9)
    np.testing.assert_allclose(ours.points, kept.points, rtol=0, atol=1e-9)


# -- bad input -------------------------------------------------------------------------------------------
@pytest.mark.parametrize("options, match", [
    ({"dependent_speeds": [me.dynamicsymbols("z")]}, r"dependent speed z\(t\) is not a coordinate of model "
                                                     r"'chaplygin_sleigh' \(coordinates: x, y, theta\)"),
    ({"dependent_speeds": [Y.diff(t)]}, r"is not a coordinate .*\(name the coordinate y\(t\), not its rate\)"),
    ({"dependent_speeds": [X, Y]}, r"dependent_speeds names 2 coordinate\(s\) \(x, y\) for 1 motion constraint"),
    ({"dependent_speeds": [Y, Y]}, "dependent speed 'y' is listed twice"),
    ({"dependent_speeds": [Y], "constraints": [X - Y]}, "dependent_speeds with holonomic constraints= are not"),
    ({"dependent_speeds": Y}, "dependent_speeds must be a list or tuple"),
    ({"formulation": "elimination"}, r"formulation 'elimination' needs named dependent speeds: .*dependent_speeds="),
    ({"dependent_speeds": [THETA]}, "dependent speed theta_d appears in no motion constraint"),
])
def test_bad_dependent_speeds_are_named(options, match):
    with pytest.raises(ModelError, match=match):
        derive_equations(sleigh(**options))


def test_dependent_speeds_need_motion_constraints_and_no_sympy_model():
    x = me.dynamicsymbols("x")
    with pytest.raises(ModelError, match=r"names 1 coordinate\(s\) \(x\) for 0 motion constraint"):
        Model("free", [x], [], kinetic_energy=x.diff(t) ** 2 / 2, dependent_speeds=[x])
    N = me.ReferenceFrame("N")
    P = me.Point("P")
    P.set_vel(N, x.diff(t) * N.x)
    kane = me.KanesMethod(N, q_ind=[x], u_ind=[me.dynamicsymbols("u")], kd_eqs=[x.diff(t) - me.dynamicsymbols("u")])
    with pytest.raises(ModelError, match="a KanesMethod brings its own"):
        Model("kane", sympy_model=kane, dependent_speeds=[x])


def test_a_steady_turn_of_the_eliminated_disc_is_the_multipliers_ones_and_is_held(discs):
    """steady_motion and steady_eigenvalues on the eliminated equations (every speed, in their order)
    against the multipliers equations of the same disc (whose turn test_rolling_disc checks against
    sympy's textbook disc): the same spin and stability; the compiled eliminated disc holds the turn."""
    from lagcodegen.statics.steady import steady_eigenvalues, steady_motion

    x, y = rolling_disc().coordinates[:2]
    found = {}
    for name, model in (("elimination", rolling_disc(dependent_speeds=[x, y])), ("multipliers", rolling_disc())):
        eom = derive_equations(model)
        turn = steady_motion(eom, {"theta": 0.3, "psi_d": 0.5, "phi_d": 1.0}, unknowns=["phi_d", "x_d", "y_d"],
                             steady=["theta_d"])
        modes = steady_eigenvalues(eom, turn, cyclic=["x", "y", "psi", "phi"], speeds=["psi_d", "theta_d", "phi_d"])
        found[name] = (eom, turn, np.sort_complex(modes[np.abs(modes) > 1e-9]))
    (eom, turn, modes), (_, kept, kept_modes) = found["elimination"], found["multipliers"]
    assert abs(turn.values["phi_d"] - kept.values["phi_d"]) < 1e-12
    np.testing.assert_allclose(modes, kept_modes, atol=1e-12)
    system = discs["elimination"]
    every = [str(s) for s in eom.q + eom.u]
    state = [turn.state[every.index(name)] for name in system.layout.coordinates + system.layout.speeds]
    run = simulate(system, state, t_end=2.0, h=1e-3)
    assert run.ok and np.abs(run["theta"] - 0.3).max() < 1e-9 and np.abs(run["psi_d"] - 0.5).max() < 1e-9


def test_the_dynamics_kernel_solves_the_dependent_speeds_from_its_own_constraint_jacobian():
    """One evaluation of A and one LU of A_D per right-hand side: the dynamics kernel solves
    A_D u_dep = -(A_I u_I + b) from the A it forms anyway, between its temporaries that do not read
    u_dep and those that do (a call of the public dependent_speeds function would form A a second
    time), and the accelerations' A_D^-1 gamma substitutes with the same factors. Its values are
    checked against the disc's sympy model by the tests above."""
    from lagcodegen.codegen.reduce import reduce_expressions
    from lagcodegen.codegen.render import render_sources

    x, y = rolling_disc().coordinates[:2]
    eom = derive_equations(rolling_disc(dependent_speeds=[x, y]))
    source = render_sources(reduce_expressions(eom, ["rhs"], {}), methods=("rk4",)).source
    start = source.index("_dynamics(double t")
    body = source[start:source.index("\n}\n", start)]
    assert "_dependent_speeds(" not in body
    solve, first_reader = body.index("/* LU of A_D"), body.index("= u_dep[0];")
    assert solve < first_reader
    assert body.count("/* LU of A_D") == 1 and "_dense_solve(" not in body and "_dense_factor(" not in body
    assert body.index("double b_0 = gD[0]") > first_reader
    for name in eom.u[eom.n_u - eom.n_dependent:]:  # no temporary reads a dependent speed before the solve
        assert f"*{name}" not in body[:solve] and f"{name}*" not in body[:solve]


@pytest.mark.parametrize("name", ("AD_dep", "scale_dep", "u_dep", "LU", "ipiv", "X", "gD", "Mr_1_0", "MC_2_0",
                                  "rest_2", "Fr_1", "D_0", "LU_0_0", "pivot_0", "largest_0", "b_0", "top"))
def test_a_symbol_named_like_the_kernels_own_locals_is_renamed(sleighs, tmp_path, name):
    """The inline solve's locals (u_dep, LU, the reduced M's Mr_i_j, ...) are reserved: a sleigh whose lever arm
    is called so compiles, and its rhs equals the sleigh's with the usual name (second route: the
    same model; a BuildError 'conflicting type qualifiers' before the names were reserved)."""
    renamed = sleigh(arm=name, dependent_speeds=[Y])
    system = compile_model(renamed, methods=("rk4",), cache_dir=tmp_path)
    state = np.array([0.1, -0.2, 0.7, 0.4, 1.3])  # x, y, theta, x', theta'
    # the names order the CSE's terms, so rounding may differ in the last place
    np.testing.assert_allclose(make_rhs(system)(0.0, state), make_rhs(sleighs["y"])(0.0, state), rtol=1e-13, atol=1e-15)


def test_a_sweep_member_on_the_singular_heading_gets_its_own_status(sleighs):
    """Found by review: one member of three starting at theta = pi/2 (y' dependent: A_D = cos(theta), by
    hand singular there) refused the whole sweep; as any other singular start it is now that member's
    SINGULAR_CONSTRAINTS, and the others equal their own simulate runs."""
    from lagcodegen.run.simulate import Status
    from lagcodegen.run.sweep import sweep

    system = sleighs["y"]
    base = {"x": 0.0, "y": 0.0, "theta": 0.0, "x_d": 0.5}
    result = sweep(system, members={"theta": [0.2, np.pi / 2, 1.0], "theta_d": [0.5, 0.0, -0.5]}, x0=base,
                   t_end=0.5, h=1e-2)
    assert result.status.tolist() == [Status.OK, Status.SINGULAR_CONSTRAINTS, Status.OK]
    for i, (theta, rate) in enumerate([(0.2, 0.5), (1.0, -0.5)]):
        alone = simulate(system, base | {"theta": theta, "theta_d": rate}, t_end=0.5, h=1e-2).x[-1]
        np.testing.assert_array_equal(result.x_final[2 * i], alone)


@pytest.mark.parametrize("name, ratio", [("minus_one", 1), ("minus_half", sp.Rational(1, 2)), ("folded", None)])
def test_a_constraint_with_a_negative_number_in_the_independent_columns(name, ratio):
    """Found by review (session 16): A_I = -1 printed "X[0] = --1;" and the build failed. By hand, with
    L = m x'^2/2 + y'^2/2 - x^2/2 and y' = c x': (m + c^2) x'' = -x; at x = 0.3, x' = 0.5, m = 1 the
    state's rate is (x', c x', -0.3 / (1 + c^2)). "folded": c = r with r fixed to 1.0 (A_I = -1.0)."""
    x, y = me.dynamicsymbols("x y")
    m, r = sp.symbols("m r", positive=True)
    c = r if ratio is None else ratio
    model = Model(f"negative_{name}", [x, y], [m, r], kinetic_energy=m * x.diff() ** 2 / 2 + y.diff() ** 2 / 2,
                  potential_energy=x ** 2 / 2, motion_constraints=[y.diff() - c * x.diff()], dependent_speeds=[y],
                  parameter_values={m: 1, r: 1})
    system = compile_model(model, methods=("rk4",), fixed={"r": 1.0} if ratio is None else None)
    c = 1.0 if ratio is None else float(ratio)
    np.testing.assert_allclose(make_rhs(system)(0.0, np.array([0.3, 0.2, 0.5])), [0.5, c * 0.5, -0.3 / (1 + c * c)],
                               rtol=1e-14)


def test_every_speed_fixed_by_the_constraints_builds_strictly(tmp_path):
    """Found by review (session 16): with no independent speed (x' = sin(w t)) the exported C failed
    -Wall -Wextra -Werror (unused rest_0, M_0_0, F_0, ud). By hand x(1) = (1 - cos 2) / 2 for w = 2."""
    import subprocess

    t = me.dynamicsymbols._t
    x = me.dynamicsymbols("x")
    m, w = sp.symbols("m omega", positive=True)
    model = Model("driven_only", [x], [m, w], kinetic_energy=m * x.diff() ** 2 / 2, potential_energy=m * x ** 2 / 2,
                  motion_constraints=[x.diff() - sp.sin(w * t)], dependent_speeds=[x], parameter_values={m: 1, w: 2})
    system = compile_model(model, methods=("rk4",), cache_dir=tmp_path / "cache")
    run = simulate(system, {"x": 0.0}, t_end=1.0, h=1e-3)
    assert run.ok and run.x[-1][0] == pytest.approx((1 - np.cos(2.0)) / 2, abs=1e-12)
    for name, text in ((system.sources.header_name, system.sources.header),
                       (system.sources.source_name, system.sources.source)):
        (tmp_path / name).write_text(text)
    build = subprocess.run(["gcc", "-std=c99", "-Wall", "-Wextra", "-Werror", "-c", system.sources.source_name,
                            "-o", "out.o"], cwd=tmp_path, capture_output=True, text=True)
    assert build.returncode == 0, build.stderr
