"""The Cartesian pendulum (x, y and x^2 + y^2 - l^2 = 0, Lagrange I) against the same pendulum in
its one angle (`catalog.pendulum_chain(1)`, Lagrange II), and its multiplier against the rod
tension.

References:
- motion: the one-coordinate pendulum integrated by scipy DOP853 at rtol = atol = 1e-12
  (`simulate.solve_reference`); theta = atan2(x, -y).
- tension: Newton's second law along the rod for the bob on its circle, T - m g cos(theta) =
  m l thetad^2 (centripetal), with the reference's theta and thetad; with phi = x^2 + y^2 - l^2,
  A = (2x, 2y) and the constraint force -A^T lambda = -2 lambda (x, y), the tension is 2 l lambda.
- kernels: the augmented system written out by hand here (M = m I, F = (0, -m g), A = (2x, 2y),
  gamma = -2 (xd^2 + yd^2) - 2 alpha w - beta^2 phi with w = 2 (x xd + y yd), from differentiating
  phi twice along the motion), solved at 30 digits by mpmath (the ``augmented_solve`` fixture).
"""
from __future__ import annotations

import math

import numpy as np
import pytest

from lagcodegen import catalog
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import parameter_vector, simulate, solve_reference

THETA0, THETA0_D = 1.0, 0.5   # rad, rad/s: a large swing (57 degrees), not a small-angle case
T_END, H = 3.0, 1e-3
#: rk4 at h = 1e-3 over 3 s: observed 1.1e-10 (no projection) and 1.4e-11 (projection) in theta,
#: 2.4e-9 and 1.7e-10 in the tension; the DOP853 reference itself is good to ~5e-12
TOL = 1e-8


def initial_state(l: float = 1.0) -> list:
    """(x, y, xd, yd) of the pendulum at THETA0, THETA0_D (theta from the downward vertical)."""
    s, c = math.sin(THETA0), math.cos(THETA0)
    return [l * s, -l * c, l * c * THETA0_D, l * s * THETA0_D]


@pytest.fixture(scope="module")
def cartesian(compiled_system):
    return compiled_system("cartesian_pendulum")


@pytest.fixture(scope="module")
def reference(kernel_cache_dir):
    """(t, theta, thetad) of the one-angle pendulum, DOP853 at 1e-12, every 0.01 s."""
    angle = compile_model(catalog.pendulum_chain(1), methods=("rk4",))
    t_eval = np.linspace(0.0, T_END, 301)
    t, x = solve_reference(angle, [THETA0, THETA0_D], t_eval)
    return t, x[:, 0], x[:, 1]


@pytest.mark.parametrize("project", [False, True])
def test_same_motion_as_the_one_angle_pendulum(cartesian, reference, project):
    t_ref, theta_ref, _ = reference
    run = simulate(cartesian, initial_state(), T_END, H, "rk4", stride=10, project=project).check()
    np.testing.assert_allclose(run.t, t_ref, atol=1e-12)
    theta = np.arctan2(run["x"], -run["y"])
    error = np.abs(theta - theta_ref).max()
    print(f"\nproject={project}: max |theta - theta_ref| over {T_END} s = {error:.3g}")
    assert error < TOL


@pytest.mark.parametrize("project", [False, True])
def test_multiplier_is_the_rod_tension(cartesian, reference, project):
    _, theta_ref, thetad_ref = reference
    m, l, g = 1.0, 1.0, 9.81  # the catalog defaults
    run = simulate(cartesian, initial_state(), T_END, H, "rk4", stride=10, project=project,
                   multipliers=True).check()
    tension = m * (g * np.cos(theta_ref) + l * thetad_ref ** 2)
    error = np.abs(2 * l * run.multipliers[:, 0] - tension).max()
    print(f"\nproject={project}: max |2 l lambda - tension| = {error:.3g} (tension {tension.min():.3f} "
          f"to {tension.max():.3f} N)")
    assert error < TOL
    # the generalized constraint force A^T lambda = (2 x lambda, 2 y lambda)
    np.testing.assert_allclose(run.constraint_forces,
                               2 * run.x[:, :2] * run.multipliers[:, :1], rtol=1e-13, atol=1e-13)


def test_tension_scales_with_mass_and_length(cartesian):
    """The same swing with m = 2.5, l = 0.4 (free parameters, same build): at the release point
    (thetad = THETA0_D) the tension is m (g cos(theta0) + l thetad0^2) exactly."""
    m, l, g = 2.5, 0.4, 9.81
    run = simulate(cartesian, initial_state(l), 0.01, 1e-3, "rk4", params={"m": m, "l": l},
                   multipliers=True, residuals=True).check()
    expected = m * (g * math.cos(THETA0) + l * THETA0_D ** 2)
    assert 2 * l * run.multipliers[0, 0] == pytest.approx(expected, rel=1e-13)
    assert np.abs(run.residuals).max() < 1e-12


def test_augmented_system_at_random_states(cartesian, call_kernel, augmented_solve, rng):
    """rhs (ud) and multipliers (lambda, A^T lambda) against the hand-written first-kind system,
    at seeded random states off the constraint (the kernels do not assume phi = 0), with random
    m, l, g and Baumgarte parameters."""
    names = cartesian.layout.parameters
    assert names == ("m", "l", "g", "baumgarte_alpha", "baumgarte_beta")
    worst = 0.0
    for _ in range(8):
        x, y, xd, yd = rng.uniform(-1.5, 1.5, 4)
        m, l, g = rng.uniform(0.5, 2.0), rng.uniform(0.5, 1.5), rng.uniform(5.0, 15.0)
        alpha, beta = rng.uniform(0.0, 20.0, 2)
        phi, w = x * x + y * y - l * l, 2 * (x * xd + y * yd)
        gamma = -2 * (xd * xd + yd * yd) - 2 * alpha * w - beta * beta * phi
        ud_ref, lam_ref = augmented_solve([[m, 0], [0, m]], [0, -m * g], [[2 * x, 2 * y]], [gamma])
        state, p = [x, y, xd, yd], [m, l, g, alpha, beta]
        status, (xdot,) = call_kernel(cartesian, "rhs", state, p, 4)
        assert status == 0
        status, (lam, Q) = call_kernel(cartesian, "multipliers", state, p, 1, 2)
        assert status == 0
        np.testing.assert_allclose(xdot[:2], [xd, yd], rtol=0, atol=0)
        scale = max(1.0, np.abs(ud_ref).max(), abs(lam_ref[0]))
        Q_ref = [2 * x * lam_ref[0], 2 * y * lam_ref[0]]
        errors = [np.abs(xdot[2:] - ud_ref).max(), abs(lam[0] - lam_ref[0]), np.abs(Q - Q_ref).max()]
        worst = max(worst, max(errors) / scale)
        # M ud = F - A^T lambda, the sign convention of the API
        np.testing.assert_allclose(m * xdot[2:], np.array([0, -m * g]) - Q, rtol=1e-12, atol=1e-12 * scale)
    print(f"\nworst relative error of ud, lambda, A^T lambda over 8 random states: {worst:.3g}")
    assert worst < 1e-13


def test_projection_keeps_the_constraint(cartesian):
    """10 s at h = 1e-3 (1e4 rk4 steps): the residual drifts without projection and stays at the
    projection's tolerance (1e-12 in the generated C) with it."""
    free, projected = (simulate(cartesian, initial_state(), 10.0, 1e-3, "rk4", stride=100, project=p,
                                residuals=True).check() for p in (False, True))
    drift = np.abs(free.residuals).max(axis=0)
    kept = np.abs(projected.residuals).max(axis=0)
    print(f"\nmax |phi|, |A u|: no projection {drift[0]:.3g}, {drift[1]:.3g}; projection {kept[0]:.3g}, {kept[1]:.3g}")
    assert kept.max() < 1e-11
    assert drift[0] > 10 * kept[0]


def test_parameter_order_is_the_model_order(cartesian):
    assert list(parameter_vector(cartesian)) == [1.0, 1.0, 9.81, 0.0, 0.0]


@pytest.mark.parametrize("precision, length, relative", [("double", 1000.0, 1e-15), ("float", 10.0, 1e-6)])
def test_projection_of_a_long_rod_converges_at_rounding(compiled_system, precision, length, relative):
    """Found by review: the projection asked max |phi| <= 1e-12 (float 1e-6) absolutely, while
    phi = x^2 + y^2 - l^2 cannot be evaluated closer than about eps l^2: projected runs of an l = 100
    rod (double) or an l = 3 one (float) stopped with NEWTON_FAILED, on the constraint to rounding.
    Now a Newton step at the rounding level of q ends the projection: the runs go on, |phi| stays
    at rounding relative to l^2, and the angle follows DOP853 on theta'' = -(g/l) sin(theta)."""
    from scipy.integrate import solve_ivp

    system = compiled_system("cartesian_pendulum", precision=precision)
    g = 9.81
    period = 2 * math.pi * math.sqrt(length / g)
    run = simulate(system, initial_state(length), 3 * period, period / 2000, "rk4",
                   params={"l": length, "m": 1.0, "g": g}, project=True, residuals=True, stride=100)
    assert run.ok, run.message
    assert np.abs(run.residuals[:, 0]).max() <= 8 * relative * length ** 2
    reference = solve_ivp(lambda _, y: [y[1], -g / length * math.sin(y[0])], (0.0, run.t[-1]), [THETA0, THETA0_D],
                          method="DOP853", rtol=1e-12, atol=1e-12, t_eval=run.t)
    theta = np.arctan2(run.x[:, 0].astype(float), -run.x[:, 1].astype(float))
    wrapped = np.angle(np.exp(1j * (theta - reference.y[0])))  # the long rod turns over the top
    assert np.max(np.abs(wrapped)) < (1e-6 if precision == "double" else 1e-3)  # rk4 truncation: 7e-8
