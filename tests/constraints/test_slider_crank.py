"""The slider-crank in redundant coordinates (theta, xc, yc, phi, s; 4 constraints, Lagrange I)
against the same mechanism in its minimal coordinate theta, and the constraint drift with and
without projection and Baumgarte stabilization.

References:
- motion: the minimal model's equation of motion formed by sympy's own ``LagrangesMethod`` from
  `catalog.slider_crank_minimal`'s Lagrangian (closed-form kinematics from the triangle O A B:
  L sin(phi) = r sin(theta), s = r cos(theta) + L cos(phi)),
  lambdified and integrated by scipy DOP853 at rtol = atol = 1e-12. Neither lagcodegen's
  derivation nor its C is involved in the reference.
- kernels: the derived M, F, A, gamma evaluated by sympy at 30 digits and solved as one augmented
  system by mpmath (conftest ``eom_augmented_reference``), a different solve than the C's.
- constraints of swept final states: ``sympy.lambdify`` of ``eom.constraints`` and
  ``eom.constraint_jacobian``.
"""
from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from scipy.integrate import solve_ivp

from lagcodegen import catalog
from lagcodegen.run.simulate import parameter_vector, simulate
from lagcodegen.run.sweep import sweep

THETA0, THETA0_D = 0.3, 5.0     # rad, rad/s
R, L = 0.1, 0.3                  # catalog defaults
H = 1e-4
#: rk4 at h = 1e-4 over 1 s against the DOP853 reference: observed 3.9e-11 in theta, 3.2e-11 in s
MOTION_TOL = 1e-7


@pytest.fixture(scope="module")
def crank(compiled_system):
    return compiled_system("slider_crank")


@pytest.fixture(scope="module")
def minimal_reference():
    """(t, theta, thetad) every 0.01 s over 1 s: sympy LagrangesMethod + DOP853 at 1e-12."""
    model = catalog.slider_crank_minimal()
    theta = model.coordinates[0]
    tau = next(p for p in model.parameters if p.name == "tau")
    lagrangian = model.kinetic_energy - model.potential_energy
    residual = me.LagrangesMethod(lagrangian, [theta]).form_lagranges_equations()[0] - tau
    a, b, c = sp.symbols("a b c")  # theta, thetad, thetadd
    residual = residual.subs(model.parameter_values).subs(theta.diff(me.dynamicsymbols._t, 2), c)
    residual = residual.subs(theta.diff(), b).subs(theta, a)
    thetadd = -residual.subs(c, 0) / residual.diff(c)  # the equation is linear in thetadd
    acceleration = sp.lambdify((a, b), thetadd, "math")
    t_eval = np.linspace(0.0, 1.0, 101)
    sol = solve_ivp(lambda t, y: (y[1], acceleration(y[0], y[1])), (0.0, 1.0), [THETA0, THETA0_D],
                    method="DOP853", rtol=1e-12, atol=1e-12, t_eval=t_eval)
    assert sol.success
    return sol.t, sol.y[0], sol.y[1]


def test_initial_state_is_consistent(constrained_eom):
    """The closed-form initial state satisfies phi = 0 and A u = 0 (sympy lambdify)."""
    eom = constrained_eom("slider_crank")
    x0 = catalog.slider_crank_state(THETA0, THETA0_D)
    phi, w = constraint_functions(eom)
    p = [eom.parameter_values[s] for s in eom.parameters]
    assert np.abs(phi(x0, p)).max() < 1e-15
    assert np.abs(w(x0, p)).max() < 1e-14


@pytest.mark.parametrize("project", [False, True])
def test_positions_match_the_minimal_model(crank, minimal_reference, project):
    t_ref, theta_ref, _ = minimal_reference
    x0 = catalog.slider_crank_state(THETA0, THETA0_D)
    run = simulate(crank, x0, 1.0, H, "rk4", stride=100, project=project).check()
    np.testing.assert_allclose(run.t, t_ref, atol=1e-12)
    phi_ref = np.arcsin(R * np.sin(theta_ref) / L)
    s_ref = R * np.cos(theta_ref) + L * np.cos(phi_ref)
    errors = {name: np.abs(run[name] - want).max()
              for name, want in (("theta", theta_ref), ("s", s_ref), ("phi", phi_ref),
                                 ("xc", R * np.cos(theta_ref) + L / 2 * np.cos(phi_ref)),
                                 ("yc", R * np.sin(theta_ref) / 2))}
    print(f"\nproject={project}: max errors over 1 s (theta advanced {theta_ref[-1] - THETA0:.2f} rad): "
          + ", ".join(f"{k} {v:.2g}" for k, v in errors.items()))
    assert max(errors.values()) < MOTION_TOL


def residual_maxima(run) -> tuple:
    """max |phi| and max |A u + phi_t| over the run."""
    m = run.residuals.shape[1] // 2
    return np.abs(run.residuals[:, :m]).max(), np.abs(run.residuals[:, m:]).max()


def test_projection_holds_the_constraints_and_drift_grows_without(crank):
    """1e5 rk4 steps (h = 1e-4, 10 s; the crank spins up to ~580 rad/s under tau = 1)."""
    x0 = catalog.slider_crank_state(THETA0, THETA0_D)
    runs = {project: simulate(crank, x0, 10.0, H, "rk4", stride=1000, project=project, residuals=True).check()
            for project in (False, True)}
    free, kept = residual_maxima(runs[False]), residual_maxima(runs[True])
    phi_free = np.abs(runs[False].residuals[:, :4]).max(axis=1)  # (101,), one value per 0.1 s
    early, late = phi_free[:11].max(), phi_free[-11:].max()
    print(f"\n1e5 steps: max |phi|, |A u|: projection {kept[0]:.3g}, {kept[1]:.3g}; none {free[0]:.3g}, "
          f"{free[1]:.3g} (none: first 1 s {early:.3g}, last 1 s {late:.3g})")
    assert max(kept) < 1e-10
    assert free[0] > 1e3 * kept[0] and free[1] > 1e3 * kept[1]
    assert late > 1e3 * early  # the drift grows
    assert np.all(np.diff(phi_free[10:]) > 0)  # monotonically, once the crank spins


def test_baumgarte_bounds_the_drift(crank):
    """Baumgarte (alpha = beta = 10 /s; a critically damped phi'' + 2 alpha phi' + beta^2 phi = 0)
    against none, same 1e5 steps, no projection."""
    x0 = catalog.slider_crank_state(THETA0, THETA0_D)
    maxima = {}
    for gain in (0.0, 10.0, 50.0):
        run = simulate(crank, x0, 10.0, H, "rk4", stride=1000, residuals=True,
                       params={"baumgarte_alpha": gain, "baumgarte_beta": gain}).check()
        maxima[gain] = residual_maxima(run)
    print("\n1e5 steps: max |phi|, |A u| by Baumgarte alpha = beta: "
          + "; ".join(f"{g:g}: {a:.3g}, {b:.3g}" for g, (a, b) in maxima.items()))
    assert maxima[10.0][0] < maxima[0.0][0] / 100
    assert maxima[50.0][0] < maxima[10.0][0]
    assert maxima[10.0][1] < maxima[0.0][1] / 100


def test_kernels_match_the_augmented_system(crank, constrained_eom, call_kernel, eom_augmented_reference, rng):
    """ud and lambda of the C at seeded random states (off the constraint manifold too) and
    random parameters, against the 30-digit augmented solve of the derived equations."""
    eom = constrained_eom("slider_crank")
    defaults = parameter_vector(crank)
    worst = 0.0
    for _ in range(5):
        x = np.concatenate([rng.uniform(-1.0, 1.0, 5) * [3, 0.3, 0.1, 0.5, 0.4], rng.uniform(-5, 5, 5)])
        p = defaults * rng.uniform(0.7, 1.3, defaults.size) + np.r_[np.zeros(7), rng.uniform(0, 10, 2)]
        ud_ref, lam_ref = eom_augmented_reference(eom, x, p)
        status, (xdot,) = call_kernel(crank, "rhs", x, p, 10)
        assert status == 0
        status, (lam, _) = call_kernel(crank, "multipliers", x, p, 4, 5)
        assert status == 0
        scale = max(1.0, np.abs(ud_ref).max(), np.abs(lam_ref).max())
        worst = max(worst, np.abs(xdot[5:] - ud_ref).max() / scale, np.abs(lam - lam_ref).max() / scale)
    print(f"\nworst relative error of ud, lambda at 5 random states: {worst:.3g}")
    assert worst < 1e-12


def test_bodies_and_energies_routes_agree(constrained_eom):
    """Second derivation route: T, V and Q_theta = tau written by hand (catalog route
    "energies") give the same M, F, A and gamma as the bodies (d'Alembert-Lagrange) route."""
    from lagcodegen import derive_equations

    bodies = constrained_eom("slider_crank")
    energies = derive_equations(catalog.slider_crank("energies"))
    for field in ("mass_matrix", "forcing", "constraint_jacobian", "constraint_bias"):
        difference = getattr(bodies, field) - getattr(energies, field)
        assert sp.simplify(difference) == sp.zeros(*difference.shape), field


def constraint_functions(eom):
    """phi(x, p) and w(x, p) = A u + phi_t (numpy) lambdified from the derived equations."""
    n = eom.n
    args = (sp.Matrix(eom.q + eom.u), sp.Matrix(eom.parameters))
    phi = sp.lambdify(args, eom.constraints, "numpy")
    w = sp.lambdify(args, eom.constraint_jacobian * sp.Matrix(eom.u) + eom.constraint_rate, "numpy")
    unpack = lambda f: lambda x, p: np.asarray(f(np.asarray(x)[:2 * n], np.asarray(p)), float).ravel()  # noqa: E731
    return unpack(phi), unpack(w)


def test_sweep_with_projection_keeps_every_member_on_the_constraints(crank, constrained_eom):
    """A grid over the torque, then a table over the rod length L (each member with its own
    consistent initial state): with project=True every final state satisfies that member's
    phi = 0 and A u = 0 (sympy lambdify), and a member equals its own `simulate` run."""
    eom = constrained_eom("slider_crank")
    phi, w = constraint_functions(eom)
    x0 = catalog.slider_crank_state(THETA0, THETA0_D)
    by_torque = sweep(crank, {"tau": np.linspace(0.5, 3.0, 6)}, x0=x0, t_end=0.5, h=H, project=True)
    lengths = np.array([0.2, 0.25, 0.3, 0.4, 0.6])
    states = np.array([catalog.slider_crank_state(THETA0, THETA0_D, R, length) for length in lengths])
    state_names = crank.layout.coordinates + crank.layout.speeds
    table = {"L": lengths} | {name: states[:, i] for i, name in enumerate(state_names)}
    by_length = sweep(crank, members=table, x0=x0, t_end=0.5, h=H, project=True)
    worst = 0.0
    for result, column in ((by_torque, "tau"), (by_length, "L")):
        assert np.all(result.status == 0)
        for i in range(result.n_members):
            p = parameter_vector(crank, {column: result.values[i, result.columns.index(column)]})
            worst = max(worst, np.abs(phi(result.x_final[i], p)).max(), np.abs(w(result.x_final[i], p)).max())
    print(f"\nswept final states: max |phi|, |A u| = {worst:.3g}; crank angles "
          f"{np.round(by_length.x_final[:, 0], 3)} for L = {lengths}")
    assert worst < 1e-10
    # a member equals its own run (same C stepper, same projection)
    single = simulate(crank, states[3], 0.5, H, "rk4", params={"L": lengths[3]}, project=True).check()
    np.testing.assert_allclose(by_length.x_final[3], single.x[-1], rtol=1e-13, atol=1e-13)


def test_compiled_minimal_model_matches_sympy(compiled_system, constrained_eom, call_kernel):
    """The minimal model's compiled acceleration against its own sympy F / M at THETA0, THETA0_D,
    to 1e-12 relative (sympy evaluates F / M exactly, then rounds once)."""
    eom = constrained_eom("slider_crank_minimal")
    system = compiled_system("slider_crank_minimal")
    p = parameter_vector(system)
    values = dict(zip(eom.q + eom.u, (THETA0, THETA0_D))) | dict(zip(eom.parameters, p))
    want = float((eom.forcing[0] / eom.mass_matrix[0]).xreplace(values))
    _, (xdot,) = call_kernel(system, "rhs", [THETA0, THETA0_D], p, 2)
    assert xdot[1] == pytest.approx(want, rel=1e-12)
