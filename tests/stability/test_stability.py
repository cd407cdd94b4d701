"""Linear stability of the compiled fixed-step methods, measured through the whole pipeline.

Expected values come from two independent places:

* the tableau's theory: one step of any Runge-Kutta method multiplies a mode of ``y' = lambda y``
  by ``R(h lambda)`` (Hairer-Wanner II, Sec. IV.2-IV.3), with ``R`` from
  ``ButcherTableau.stability_polynomial()`` and the limits from ``real_stability_limit()`` /
  ``imag_stability_limit()``; symplectic Euler on ``x'' = -w^2 x`` keeps
  ``v^2 + w^2 x^2 - h w^2 x v`` exactly (checked symbolically, see `_symplectic_euler_bound`) and
  is stable for ``h w < 2`` (trace ``2 - (h w)^2`` of its map);
* numpy / scipy linear algebra on the hand-written matrices of the stiff chain (masses m_i,
  stiffness matrix from the springs k, k, K, k between the walls): the frequencies ``w_i`` and the
  modal energies, never the generated code.

For an undamped linear chain a Runge-Kutta step maps the complex modal amplitude
``w_i eta_i + i eta_i'`` to ``R(-i h w_i)`` times itself, so the energy of mode i is multiplied
by ``|R(i h w_i)|^2`` per step, exactly (up to rounding).
"""
from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model
from lagcodegen.integrators import schemes
from lagcodegen.integrators.tableaux import Z
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import StabilityWarning, Status, simulate

EXPLICIT_RK = tuple(m for m in schemes.DEFAULT_METHODS
                    if schemes.get_scheme(m).stepper == schemes.KIND_EXPLICIT)
L_STABLE = ("backward_euler", "sdirk2", "radau_iia3")
RK4_IMAG_LIMIT = 2 * math.sqrt(2)  # |R(iy)| = 1 at y = 2 sqrt(2) for RK4 (HW II, Sec. IV.2)

# stiff_chain defaults (catalog.stiff_chain): m1 = m2 = m3 = 1, k = 1, K = 1e4
CHAIN = {"m1": 1.0, "m2": 1.0, "m3": 1.0, "k": 1.0, "K": 1.0e4}


# -- independent linear algebra of the stiff chain ----------------------------------------
def chain_matrices(m1, m2, m3, k, K):
    """Mass and stiffness matrices written from the springs: wall-k-m1-k-m2-K-m3-k-wall."""
    mass = np.diag([m1, m2, m3])
    stiffness = np.array([[2 * k, -k, 0.0],
                          [-k, k + K, -K],
                          [0.0, -K, K + k]])
    return mass, stiffness


def chain_modes():
    """(w (3,), Phi (3, 3)) with K Phi = M Phi diag(w^2), Phi^T M Phi = I (scipy eigh)."""
    mass, stiffness = chain_matrices(**CHAIN)
    w2, phi = scipy.linalg.eigh(stiffness, mass)
    return np.sqrt(w2), phi


def largest_frequency() -> float:
    """sqrt of the largest eigenvalue of M^-1 K, from numpy (an independent route)."""
    mass, stiffness = chain_matrices(**CHAIN)
    return float(np.sqrt(np.max(np.linalg.eigvals(np.linalg.solve(mass, stiffness)).real)))


def modal_energies(x) -> np.ndarray:
    """Energy (w_i^2 eta_i^2 + eta_i'^2) / 2 of each mode of the state x = (q, u) (6,)."""
    w, phi = chain_modes()
    mass, _ = chain_matrices(**CHAIN)
    eta, eta_d = phi.T @ mass @ x[:3], phi.T @ mass @ x[3:]
    return (w ** 2 * eta ** 2 + eta_d ** 2) / 2


def stability_function(method: str):
    """R(z) of the method's tableau as a numpy function."""
    return sp.lambdify(Z, schemes.get_scheme(method).stability_polynomial(), "numpy")


def predicted_energy(method: str, x0, h: float, n_steps: int) -> float:
    """Sum over modes of E_i(0) |R(i h w_i)|^(2 n): the exact energy after n RK steps."""
    w, _ = chain_modes()
    growth = np.abs(stability_function(method)(1j * h * w)) ** 2
    return float(np.sum(modal_energies(np.asarray(x0)) * growth ** n_steps))


def _symplectic_euler_bound(y: float) -> float:
    """Largest E_n / E_0 of symplectic Euler on one mode with h w = y < 2.

    Its invariant Q = v^2 + w^2 x^2 - h w^2 x v (sympy: Q(step(x, v)) - Q(x, v) == 0) lies
    between 2E (1 - y/2) and 2E (1 + y/2) because |w x v| <= E.
    """
    x, v, h, w = sp.symbols("x v h w")
    Q = lambda x, v: v ** 2 + w ** 2 * x ** 2 - h * w ** 2 * x * v  # noqa: E731
    v1 = v - h * w ** 2 * x
    assert sp.simplify(Q(x + h * v1, v1) - Q(x, v)) == 0
    return (1 + y / 2) / (1 - y / 2)


X0_CHAIN = (0.1, 0.05, -0.05, 0.0, 0.0, 0.0)  # excites all three modes


@pytest.fixture(scope="module")
def chain(compiled_example):
    return compiled_example("stiff_chain", methods=schemes.DEFAULT_METHODS)


@pytest.fixture(scope="module")
def damped_particle(kernel_cache_dir):
    """T = m xd^2 / 2, Q = -c xd: Jacobian eigenvalues 0 and -c/m (c/m = 1.5)."""
    m, c = sp.symbols("m c", positive=True)
    x = me.dynamicsymbols("x")
    model = Model("damped_particle", [x], (m, c), kinetic_energy=m * x.diff() ** 2 / 2,
                  generalized_forces={x: -c * x.diff()}, parameter_values={m: 2.0, c: 3.0})
    return compile_model(model, methods=schemes.DEFAULT_METHODS)


def run_quietly(system, x0, n_steps, h, method, **kwargs):
    """simulate over n_steps without the stability check (its warning is tested separately)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        return simulate(system, x0, n_steps * h, h, method, check_stability=False, **kwargs)


# -- negative real axis: the damped particle -----------------------------------------------
@pytest.mark.parametrize("method", EXPLICIT_RK)
@pytest.mark.parametrize("factor", [0.98, 1.02])
def test_real_axis_limit_on_the_damped_particle(damped_particle, method, factor):
    lam = 3.0 / 2.0  # c / m: the Jacobian's eigenvalue is -lam (u' = -(c/m) u)
    limit = schemes.get_scheme(method).real_stability_limit()
    h, n_steps, u0 = factor * limit / lam, 2000, 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)  # no warning inside the limit
        if factor > 1:
            with pytest.warns(StabilityWarning, match=method):
                traj = simulate(damped_particle, (0.3, u0), n_steps * h, h, method)
        else:
            traj = simulate(damped_particle, (0.3, u0), n_steps * h, h, method)
    u = traj["x_d"]
    # Expected: u_n = R(-h lam)^n u0 exactly (tableau theory), |R| < 1 inside, > 1 outside.
    R = float(stability_function(method)(-h * lam))
    assert (abs(R) < 1) == (factor < 1)
    if factor < 1:
        assert traj.ok
        assert np.all(np.abs(u) <= u0)  # decays, never exceeds the start
        assert abs(u[-1]) < 1e-20 * u0
        assert np.all(np.abs(traj["x"]) < 10)  # x' = u, so x stays bounded
    else:
        assert traj.status == Status.NONFINITE_STATE or abs(u[-1]) > 1e6 * u0
    if traj.ok:
        assert u[-1] == pytest.approx(R ** n_steps * u0, rel=1e-9)


# -- imaginary axis: the stiff chain --------------------------------------------------------
def test_largest_frequency_independent_routes_agree():
    w, _ = chain_modes()
    assert largest_frequency() == pytest.approx(w.max(), rel=1e-12)
    assert largest_frequency() == pytest.approx(math.sqrt(2e4), rel=1e-3)  # ~ sqrt(2K/m) for K >> k


def test_rk4_bounded_just_inside_the_imaginary_limit(chain):
    w = largest_frequency()
    h, n_steps = 0.95 * RK4_IMAG_LIMIT / w, 20000
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        traj = simulate(chain, X0_CHAIN, n_steps * h, h, "rk4", stride=100, energy=True)
    assert traj.ok
    e0 = float(np.sum(modal_energies(np.array(X0_CHAIN))))
    assert traj.energy[0] == pytest.approx(e0, rel=1e-12)
    assert np.all(traj.energy <= e0 * (1 + 1e-12))  # |R| <= 1 on every mode
    assert traj.energy[-1] == pytest.approx(predicted_energy("rk4", X0_CHAIN, h, n_steps), rel=1e-8)


def test_rk4_blows_up_just_outside_the_imaginary_limit(chain):
    w = largest_frequency()
    h, n_steps, t0 = 1.05 * RK4_IMAG_LIMIT / w, 20000, 0.25
    with pytest.warns(StabilityWarning, match="rk4"), pytest.warns(RuntimeWarning, match="NaN or infinite"):
        traj = simulate(chain, X0_CHAIN, t0 + n_steps * h, h, "rk4", t0=t0)
    assert traj.status == Status.NONFINITE_STATE
    assert traj.failed_step is not None and traj.failed_time is not None
    assert traj.failed_time == pytest.approx(t0 + (traj.failed_step - 1) * h, rel=1e-12)
    assert len(traj.t) == traj.failed_step  # samples 0 .. failed_step - 1 (stride 1)
    assert np.all(np.isfinite(traj.x)) and traj.t[-1] == pytest.approx(traj.failed_time)
    # Expected: the stiff mode grows by |R(i y)| per step until it overflows DBL_MAX (~1.8e308);
    # the stage arithmetic (w^2 x ~ 2e4 x) overflows a few percent of the steps earlier.
    growth = abs(stability_function("rk4")(1j * h * w))
    amplitude0 = math.sqrt(2 * modal_energies(np.array(X0_CHAIN))[-1]) / w
    overflow = (math.log(np.finfo(float).max) - math.log(amplitude0)) / math.log(growth)
    assert 0.95 * overflow < traj.failed_step <= 1.01 * overflow
    assert len(traj.t) > 1000


def test_explicit_euler_energy_grows_at_any_step(chain):
    w = largest_frequency()
    for y in (0.1, 0.01, 0.001):
        h, n_steps = y / w, 10000
        traj = run_quietly(chain, X0_CHAIN, n_steps, h, "euler", stride=n_steps, energy=True)
        assert traj.ok
        assert traj.energy[-1] > traj.energy[0]
        # Expected: |R(iy)|^2 = 1 + y^2 > 1 for every y > 0, per mode (tableau theory).
        assert traj.energy[-1] == pytest.approx(predicted_energy("euler", X0_CHAIN, h, n_steps), rel=1e-6)


def test_symplectic_euler_bounded_below_hw_2(chain):
    w, y, n_steps = largest_frequency(), 1.9, 5000
    h = y / w
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        traj = simulate(chain, X0_CHAIN, n_steps * h, h, "symplectic_euler", energy=True)
    assert traj.ok
    assert np.max(traj.energy) <= traj.energy[0] * _symplectic_euler_bound(y)
    assert np.min(traj.energy) >= traj.energy[0] / _symplectic_euler_bound(y)


def test_symplectic_euler_grows_above_hw_2(chain):
    w, y, n_steps = largest_frequency(), 2.1, 5000
    h = y / w
    with pytest.warns(StabilityWarning, match="symplectic_euler"), pytest.warns(RuntimeWarning):
        traj = simulate(chain, X0_CHAIN, n_steps * h, h, "symplectic_euler", energy=True)
    # Expected: trace 2 - y^2 = -2.41 < -2, an eigenvalue of modulus 1.88 per step: overflow.
    assert traj.status == Status.NONFINITE_STATE
    assert traj.energy[-1] > 1e100 * traj.energy[0]


def test_implicit_midpoint_conserves_energy_far_beyond_the_explicit_limits(chain):
    w, n_steps = largest_frequency(), 1000
    h = 10 * RK4_IMAG_LIMIT / w
    traj = simulate(chain, X0_CHAIN, n_steps * h, h, "implicit_midpoint", energy=True).check()
    # Expected: |R(iy)| = 1 for Gauss methods: a quadratic invariant is kept exactly (GNI, Thm. IV.2.1).
    assert np.max(np.abs(traj.energy / traj.energy[0] - 1)) < 1e-10


@pytest.mark.parametrize("method", L_STABLE)
def test_l_stable_methods_damp_the_stiff_mode(chain, method):
    w, n_steps = largest_frequency(), 50
    h = 100 / w
    traj = simulate(chain, X0_CHAIN, n_steps * h, h, method, energy=True).check()
    assert np.all(np.diff(traj.energy) <= 1e-12 * traj.energy[0])  # A-stable: never gains energy
    assert traj.energy[-1] < traj.energy[0]
    # Expected: each mode's energy times |R(i h w_i)|^(2n); R(i 100) is small (L-stable).
    assert abs(stability_function(method)(100j)) < 0.05
    expected = predicted_energy(method, X0_CHAIN, h, n_steps)
    assert traj.energy[-1] == pytest.approx(expected, rel=1e-6)
    # The stiff mode itself is gone down to rounding (its theory value is below 1e-60 of the start).
    assert modal_energies(traj.x[-1])[-1] < 1e-20 * modal_energies(np.array(X0_CHAIN))[-1]


def test_stability_warning_at_105_not_at_095(chain):
    w = largest_frequency()
    for factor, expect in ((0.95, False), (1.05, True)):
        h = factor * RK4_IMAG_LIMIT / w
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            simulate(chain, X0_CHAIN, 100 * h, h, "rk4")
        assert any(issubclass(c.category, StabilityWarning) for c in caught) == expect, factor


# -- measured limits ------------------------------------------------------------------------
MEASURE_STEPS = 100_000
MEASURED_METHODS = EXPLICIT_RK + ("symplectic_euler",)


def _stiff_mode_start():
    """The stiff mode alone (scipy eigenvector), amplitude 0.01, at rest."""
    _, phi = chain_modes()
    return tuple(0.01 * phi[:, -1] / np.max(np.abs(phi[:, -1]))) + (0.0, 0.0, 0.0)


def is_bounded(chain, method: str, y: float, n_steps: int = MEASURE_STEPS) -> bool:
    """Whether n_steps of size h = y / w keep the stiff mode's energy bounded.

    Bounded: the run completes and E_n <= G E_0, with G = 2 for Runge-Kutta methods (their mode
    energy never grows when |R(iy)| <= 1) and G = 1e6 for symplectic Euler (its energy oscillates
    by up to (1 + y/2) / (1 - y/2) inside the limit).
    """
    h = y / largest_frequency()
    traj = run_quietly(chain, _stiff_mode_start(), n_steps, h, method, stride=n_steps, energy=True)
    allowed = 1e6 if method == "symplectic_euler" else 2.0
    return traj.ok and bool(traj.energy[-1] <= allowed * traj.energy[0])


def measured_stability_limit(chain, method: str, low: float, high: float, rtol: float = 1e-3) -> float:
    """Bisection on h w between a bounded `low` and an unbounded `high` (geometric midpoints)."""
    assert is_bounded(chain, method, low) and not is_bounded(chain, method, high), (method, low, high)
    while high / low > 1 + rtol:
        middle = math.sqrt(low * high)
        low, high = (middle, high) if is_bounded(chain, method, middle) else (low, middle)
    return math.sqrt(low * high)


def doubling_point(method: str, n_steps: int = MEASURE_STEPS) -> float:
    """For methods unstable on the whole imaginary axis: the y with |R(iy)|^(2n) = 2 (theory)."""
    if method == "euler":  # |R(iy)|^2 = 1 + y^2
        return math.sqrt(2 ** (1 / n_steps) - 1)
    if method == "heun":  # |R(iy)|^2 = (1 - y^2/2)^2 + y^2 = 1 + y^4 / 4
        return (4 * (2 ** (1 / n_steps) - 1)) ** 0.25
    raise ValueError(method)


@pytest.fixture(scope="module")
def measured_limits(chain):
    """method -> (theoretical imag limit, measured h w limit over MEASURE_STEPS steps)."""
    table = {}
    for method in MEASURED_METHODS:
        theory = schemes.get_scheme(method).imag_stability_limit()
        if theory > 0:
            table[method] = (theory, measured_stability_limit(chain, method, 0.5 * theory, 1.5 * theory))
        else:
            table[method] = (theory, measured_stability_limit(chain, method, 1e-4, 1.0))
    return table


@pytest.mark.parametrize("method", MEASURED_METHODS)
def test_measured_limit_matches_the_tableau(measured_limits, method):
    theory, measured = measured_limits[method]
    if theory > 0:
        # Expected: imag_stability_limit() (rk4 2 sqrt 2, kutta3 sqrt 3, dopri5 0.997, symplectic
        # Euler 2); growth just above it is slow for dopri5, so the measurement errs on the high side.
        assert measured == pytest.approx(theory, rel=0.02)
        assert measured >= theory * (1 - 1e-3)
    else:
        # Unstable for every h w > 0: the only threshold is where n steps double the energy.
        assert measured == pytest.approx(doubling_point(method), rel=0.02)


def test_print_measured_limits(measured_limits):
    lines = [f"\nImaginary-axis stability limits (h w, stiff chain, bounded over {MEASURE_STEPS} steps)",
             f"{'method':<18} {'tableau':>9} {'measured':>9}  note"]
    for method, (theory, measured) in measured_limits.items():
        note = f"doubling point {doubling_point(method):.4g}" if theory == 0 else \
            f"{100 * (measured / theory - 1):+.2f}%"
        lines.append(f"{method:<18} {theory:>9.4f} {measured:>9.4f}  {note}")
    print("\n".join(lines))
    assert set(measured_limits) == set(MEASURED_METHODS)


@pytest.mark.parametrize("K", [1e7, 1e8, 1e9])
def test_implicit_methods_hold_a_very_stiff_spring(tmp_path_factory, K):
    """Found by review: on two unit masses, a soft spring (k = 1) to the wall and a stiff one (K)
    between them, from x = (1, 1) at rest, sdirk2 and radau_iia3 stopped with NEWTON_FAILED from
    K = 1e7 and the implicit midpoint rule from 1e8: the Newton increments stalled at the rounding of
    the stiff force, eps K h |x| (2e-12 at 1e7), above the 1e-13 tolerance. Started together, the
    masses move as one of mass 2 on k = 1: x1 = x2 = cos(t / sqrt 2) (by hand)."""
    x1, x2 = me.dynamicsymbols("x1 x2")
    m, k, stiff = sp.symbols("m k K", positive=True)
    model = Model("stiff_pair", [x1, x2], [m, k, stiff],
                  kinetic_energy=m / 2 * (x1.diff() ** 2 + x2.diff() ** 2),
                  potential_energy=k / 2 * x1 ** 2 + stiff / 2 * (x2 - x1) ** 2,
                  parameter_values={m: 1.0, k: 1.0, stiff: 1e8})
    methods = {"backward_euler": 1e-3, "implicit_midpoint": 1e-7, "sdirk2": 1e-6, "radau_iia3": 1e-7}
    system = compile_model(model, methods=tuple(methods), cache_dir=tmp_path_factory.mktemp("stiff_pair"))
    for method, tolerance in methods.items():
        run = simulate(system, [1.0, 1.0, 0.0, 0.0], t_end=1.0, h=1e-3, method=method, params={"K": K},
                       check_stability=False)
        assert run.status == Status.OK, (method, run.message)
        exact = np.cos(run.t / math.sqrt(2.0))
        assert np.abs(run["x1"] - exact).max() < tolerance and np.abs(run["x2"] - exact).max() < tolerance, method


def test_float_implicit_steps_are_not_accepted_before_they_converge(tmp_path):
    """Found by review: in float, an implicit-midpoint step of the double pendulum at h = 0.3137
    accepted a Newton iterate 3e-3 from the root (the stall rule took slow convergence below 1e-4
    for rounding). The root, by scipy's fsolve on the double kernel's rhs (x1 = x0 + h f((x0 + x1)
    / 2), 1e-14): the float step must land within its tolerance of it, or fail."""
    from scipy.optimize import fsolve

    from lagcodegen import catalog
    from lagcodegen.run.simulate import make_rhs

    x0 = np.array([-1.41396164894104, -1.2700320482254028, -7.24111795425415, 4.337000370025635])
    h = 0.3137231767177582
    rhs = make_rhs(compile_model(catalog.double_pendulum(), methods=("rk4",), cache_dir=tmp_path))
    root = fsolve(lambda x1: x1 - x0 - h * rhs(0.0, (x0 + x1) / 2), x0, xtol=1e-14)
    assert np.abs(root - x0 - h * rhs(0.0, (x0 + root) / 2)).max() < 1e-11
    single = compile_model(catalog.double_pendulum(), methods=("implicit_midpoint",), precision="float",
                           cache_dir=tmp_path)
    run = simulate(single, x0, t_end=h, h=h, method="implicit_midpoint", check_stability=False)
    if run.ok:
        assert np.abs(run.x[-1] - root).max() < 1e-4 * (1 + np.abs(root).max()), (run.x[-1], root)
    else:
        assert run.status == Status.NEWTON_FAILED


def test_a_slowly_converging_newton_iteration_is_not_taken_for_a_stalled_one(tmp_path):
    """Found by review: on a saturating spring (V = x^2/2 + K (sqrt(1 + x^4) - 1)/2, K = 1e6: soft
    near 0, stiff beyond |x| = 1), one backward Euler step from x = -64.6 with h = 5.29 returned OK
    1e-2 from the step's root: the Jacobian, frozen where the spring is 1e5 times stiffer than at
    the root, made the iteration creep with tiny increments, which the stall rule took for the
    rounding of f. Now a stall is accepted only when the stage residual is at that rounding. The
    root by mpmath at 50 digits: x + h^2 g(x) = x0 + h v0, g = dV/dx, unique (monotone)."""
    import mpmath as mp

    x = me.dynamicsymbols("x")
    stiff = sp.Symbol("K", positive=True)
    model = Model("saturating_spring", [x], [stiff], kinetic_energy=x.diff() ** 2 / 2,
                  potential_energy=x ** 2 / 2 + stiff * (sp.sqrt(1 + x ** 4) - 1) / 2, parameter_values={stiff: 1e6})
    system = compile_model(model, methods=("backward_euler",), cache_dir=tmp_path)
    x0, v0, h = -64.55876219, 12.33505363, 5.29
    run = simulate(system, [x0, v0], t_end=h, h=h, method="backward_euler", check_stability=False)
    with mp.workdps(50):
        K = mp.mpf(10) ** 6
        g = lambda y: y + K * y ** 3 / mp.sqrt(1 + y ** 4)  # noqa: E731
        c = mp.mpf(x0) + mp.mpf(h) * mp.mpf(v0)
        root = mp.findroot(lambda y: y + mp.mpf(h) ** 2 * g(y) - c, (-abs(c) - 1, abs(c) + 1), solver="anderson")
        exact = np.array([float(root), float(mp.mpf(v0) - mp.mpf(h) * g(root))])
    if run.ok:
        assert np.abs(run.x[-1] - exact).max() <= 1e-10 * (1 + np.abs([x0, v0]).max()), (run.x[-1], exact)
    else:
        assert run.status == Status.NEWTON_FAILED, run.message


def test_failures_are_named_by_what_failed(tmp_path):
    """Found by review: symplectic Euler on a linear spring (constant M, no iteration needed) far
    past its stability limit (h w = 0.01 * 1e4 = 100 > 2) overflowed and was reported as a Newton
    failure; radau_iia3 from a regular state (M = diag(a - q2^2, 1), pivot 0.75 at q2 = 0.5) with a
    step too large for its Newton iteration reported a singular mass matrix where an iterate had
    wandered past |q2| = 1, while backward Euler and the implicit midpoint rule report the
    iteration's failure."""
    x = me.dynamicsymbols("x")
    m, k = sp.symbols("m k", positive=True)
    spring = compile_model(Model("se_spring", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                 potential_energy=k * x ** 2 / 2, parameter_values={m: 1.0, k: 1e8}),
                           methods=("symplectic_euler",), cache_dir=tmp_path)
    run = simulate(spring, [1.0, 0.0], t_end=1.0, h=0.01, method="symplectic_euler", check_stability=False)
    assert run.status == Status.NONFINITE_STATE, run.message
    q1, q2 = me.dynamicsymbols("q1 q2")
    a = sp.Symbol("a", positive=True)
    degenerate = compile_model(Model("degenerate", [q1, q2], [a], parameter_values={a: 1.0},
                                     kinetic_energy=((a - q2 ** 2) * q1.diff() ** 2 + q2.diff() ** 2) / 2),
                               methods=("backward_euler", "implicit_midpoint", "radau_iia3"), cache_dir=tmp_path)
    for method in ("backward_euler", "implicit_midpoint", "radau_iia3"):
        run = simulate(degenerate, [0.0, 0.5, 2.0, 0.3], t_end=3.0, h=3.0, method=method, check_stability=False)
        assert run.status == Status.NEWTON_FAILED, (method, run.message)


def test_a_growing_mode_an_implicit_step_would_damp_is_warned(tmp_path):
    """Found by review: q'' = (K/m) q with K/m = 1e6 grows like cosh(1000 t) (by hand), but at h = 0.01
    (h lambda = 10) backward Euler multiplies the mode by R(10) = 1/(1 - 10) = -0.11 per step, and the
    run decayed to 1.6e-16 with status OK and no warning; implicit midpoint's R(10) = (1 + 5)/(1 - 5),
    |R| = 1.5 against e^10. Now each warns. At h = 1e-4 (h lambda = 0.1) no method warns: the
    growth is resolved (backward Euler 1/0.9 = 1.11 against e^0.1 = 1.105)."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import StabilityWarning, simulate

    q = me.dynamicsymbols("q")
    m, K = sp.symbols("m K", positive=True)
    system = compile_model(Model("unstable", [q], [m, K], kinetic_energy=m * q.diff() ** 2 / 2,
                                 potential_energy=-K * q ** 2 / 2, parameter_values={"m": 1.0, "K": 1e6}),
                           methods=("backward_euler", "implicit_midpoint", "rk4"), cache_dir=tmp_path)
    for method, factor in (("backward_euler", "0.111"), ("implicit_midpoint", "1.5")):  # |R(10)|
        with pytest.warns(StabilityWarning, match=rf"growing mode lambda = 1000\+0j .* h\*Re\(lambda\) = 10, "
                                                  rf"{method} changes it by a factor {factor} per step"):
            simulate(system, [1e-6, 0.0], 0.1, 1e-2, method)
    with warnings.catch_warnings():
        warnings.simplefilter("error", StabilityWarning)
        for method in system.layout.methods:
            simulate(system, [1e-6, 0.0], 1e-3, 1e-4, method)


def test_symplectic_euler_converges_on_damping_it_can_and_warns_where_it_cannot(tmp_path):
    """Found by review: a critically damped oscillator (m = 1, k = 625, c = 50) stopped with
    NEWTON_FAILED at step 1 for h = 8e-3 (h c/m = 0.4): the velocity solve's sweeps contract by
    h c/m, and 30 sweeps were not enough for 1e-13. Now they go on while contracting. Expected, by
    hand, the scheme itself on this linear model: m v+ = m v + h (-k q - c v+), i.e.
    v+ = (v - h k q)/(1 + h c), then q+ = q + h v+. At h c/m = 0.9 the pre-check warns before the
    step fails."""
    import sympy as sp
    import sympy.physics.mechanics as me

    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import StabilityWarning, Status, simulate

    x = me.dynamicsymbols("x")
    m, k, c = sp.symbols("m k c", positive=True)
    system = compile_model(Model("damped", [x], [m, k, c], kinetic_energy=m * x.diff() ** 2 / 2,
                                 potential_energy=k * x ** 2 / 2, dissipation=c * x.diff() ** 2 / 2,
                                 parameter_values={"m": 1.0, "k": 625.0, "c": 50.0}),
                           methods=("symplectic_euler",), cache_dir=tmp_path)
    for h in (8e-3, 0.015):
        with warnings.catch_warnings():
            warnings.simplefilter("error", StabilityWarning)
            run = simulate(system, [1.0, 0.0], 0.24, h, "symplectic_euler")
        q, v = 1.0, 0.0
        for _ in range(round(0.24 / h)):
            v = (v - h * 625.0 * q) / (1 + h * 50.0)
            q = q + h * v
        assert run.status is Status.OK
        np.testing.assert_allclose(run.x[-1], [q, v], rtol=1e-9, atol=1e-12)
    with pytest.warns(StabilityWarning, match=r"velocity iteration contracts by h\*\|d ud/du\| = 0.9"):
        run = simulate(system, [1.0, 0.0], 0.252, 0.018, "symplectic_euler")
    assert run.status is Status.NEWTON_FAILED


def test_the_stability_limits_are_isolated_once_per_method(compiled_example, monkeypatch):
    """simulate's stability pre-check names the method's limits; their exact root isolation is cached
    on the tableau (found 2026-11-27: every simulate call redid it, 17 ms of a 1-step double pendulum
    run that takes 0.3 ms). A second run, and a third with another step, isolates no roots."""
    from lagcodegen.integrators import tableaux

    system = compiled_example("double_pendulum", methods=("rk4",))
    isolated = []
    original = tableaux._stable_interval_end
    monkeypatch.setattr(tableaux, "_stable_interval_end", lambda g: isolated.append(g) or original(g))
    simulate(system, [0.5, 0.2, 0.0, 0.0], t_end=1e-3, h=1e-3)
    first = len(isolated)
    assert first <= 2  # the real and the imaginary limit, if no earlier run asked for them
    simulate(system, [0.5, 0.2, 0.0, 0.0], t_end=1e-3, h=1e-3)
    simulate(system, [0.1, 0.0, 0.0, 0.0], t_end=2e-3, h=2e-4)
    assert len(isolated) == first
