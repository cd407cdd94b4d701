"""Equilibria, linear models and constrained equilibria at the edges the other statics tests do
not reach: mutation survivors in `statics/equilibria.py` and `statics/constrained.py`
(docs/mutation.md). No C is compiled.

Hand derivations (each test repeats the one it uses):
- pendulum driven by a constant torque tau: F = -m g l sin(th) + tau = 0 gives
  sin(th) = tau / (m g l); for tau = m g l / 2 the roots in (-pi, pi] are pi/6 and 5 pi/6.
- double well V = k (x^2 - a^2)^2 / 4: F = -k x (x^2 - a^2), roots -a, 0, a.
- a mass on a spring k in a frame whose mass grows as m (2 + cos t): at t = 0, M0 = 3 m, K0 = k.
- bob on a rod phi = x^2 + y^2 - l^2 under gravity: at (0, -l) lambda = m g / (2 l)
  (tests/constraints/test_consistent_and_statics.py); phi = x^2 + y^2 + l^2 has no real zero.
"""
from __future__ import annotations

import math

import numpy as np
import pytest
import scipy.optimize
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations
from lagcodegen.statics import constrained, equilibria
from lagcodegen.statics.constrained import constrained_equilibrium
from lagcodegen.statics.equilibria import LinearModel, angle_like, find_equilibria, linearize

m, g, l, k, c = sp.symbols("m g l k c", positive=True)
th, x, y = me.dynamicsymbols("theta x y")
t = me.dynamicsymbols._t


def _pendulum(name="pendulum_s", mass=1.0, **extra):
    """m l^2 thd^2 / 2, V = -m g l cos(th); m g l = 2 m at the defaults."""
    return derive_equations(Model(name, [th], [m, g, l], kinetic_energy=m * l ** 2 * th.diff() ** 2 / 2,
                                  potential_energy=-m * g * l * sp.cos(th),
                                  parameter_values={"m": mass, "g": 2.0, "l": 1.0}, **extra))


@pytest.fixture(scope="module")
def pendulum():
    return _pendulum()


@pytest.fixture(scope="module")
def driven():
    tau = me.dynamicsymbols("tau")
    return _pendulum("driven_pendulum_s", generalized_forces={th: tau}, inputs=[tau])


def _values(found):
    return [[float(v) for v in root.values()] for root in found]


# -- find_equilibria ------------------------------------------------------------------------------
def test_roots_given_back_as_guesses_are_found_again(pendulum):
    """A guess that is already a root has |F| ~ 1e-16 there; the tolerance must not shrink to
    it (before, the standing pendulum from guesses=[[pi]] gave [] and the double pendulum
    lost three of its four equilibria when its own roots were passed back)."""
    assert _values(find_equilibria(pendulum, {}, guesses=[[math.pi]])) == [[math.pi]]
    assert _values(find_equilibria(pendulum, {}, guesses=[[-math.pi]])) == [[math.pi]]
    double = derive_equations(catalog.double_pendulum())
    found = find_equilibria(double, {})
    assert len(found) == 4
    assert find_equilibria(double, {}, guesses=_values(found)) == found


@pytest.mark.parametrize("tau, expected", [
    (1.0, [math.pi / 6, 5 * math.pi / 6]),          # sin(th) = tau / (m g l) = 1/2
    (-1.0, [-5 * math.pi / 6, -math.pi / 6]),       # sin(th) = -1/2: both roots below 0
])
def test_driven_pendulum_roots_are_not_mirrored(driven, tau, expected):
    found = find_equilibria(driven, {}, inputs={"tau": tau})
    np.testing.assert_allclose(_values(found), [[e] for e in expected], rtol=1e-12)


def test_inputs_are_held_and_refused_where_there_are_none(pendulum, driven):
    with pytest.raises(ValueError, match="has no inputs"):
        find_equilibria(pendulum, {}, inputs=[1.0])
    with pytest.raises(ValueError, match="has inputs tau"):
        find_equilibria(driven, {})


@pytest.mark.parametrize("guess", [-3.0, -math.pi + 1e-3, 3.2])
def test_a_root_near_minus_pi_is_reported_as_pi(pendulum, guess):
    # (-pi, pi]: the standing pendulum is +pi whichever side the search came from
    assert _values(find_equilibria(pendulum, {}, guesses=[[guess]])) == [[math.pi]]


@pytest.mark.parametrize("raw", [-math.pi + 1e-13, 2126.85822648029, math.pi + 1e-13])
def test_reduction_modulo_two_pi_folds_minus_pi_onto_pi(raw):
    # A far root (hybr from th = -7.85, where the Jacobian -m g l cos(th) vanishes, lands on
    # 2126.858... = 677 pi + 7e-14) reduces to -pi + 7e-14 in floating point: it is pi.
    (reduced,) = equilibria._canonical(np.array([raw]), (True,))
    assert reduced == pytest.approx(math.pi, abs=1e-12)


@pytest.mark.parametrize("guess", [0.3, -0.3, 1e-9])
def test_a_root_at_zero_is_exactly_zero(pendulum, guess):
    (root,) = _values(find_equilibria(pendulum, {}, guesses=[[guess]]))
    assert root == [0.0] and math.copysign(1.0, root[0]) == 1.0


def test_a_single_mapping_is_one_guess(pendulum):
    assert _values(find_equilibria(pendulum, {}, guesses={"theta": 0.2})) == [[0.0]]
    assert _values(find_equilibria(pendulum, {}, guesses={th: 3.0})) == [[math.pi]]


def test_integer_and_sympy_guesses(pendulum):
    assert _values(find_equilibria(pendulum, {}, guesses=[[3], [1]])) == [[0.0], [math.pi]]
    assert _values(find_equilibria(pendulum, {}, guesses=[{"theta": sp.Integer(3)}, {"theta": sp.pi / 8}])) == [[0.0], [math.pi]]


def test_guesses_of_the_wrong_shape_are_refused():
    double = derive_equations(catalog.double_pendulum())
    for bad in ([[0.1, 0.2, 0.3]], [[0.1], [0.1, 0.2]], [0.1, 0.2, 0.3]):
        with pytest.raises(ValueError, match=r"guesses must have shape \(k, 2\)"):
            find_equilibria(double, {}, guesses=bad)


def _double_well(a):
    return derive_equations(Model("double_well_s", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                  potential_energy=k * (x ** 2 - a ** 2) ** 2 / 4,
                                  parameter_values={"m": 1.0, "k": 1.0}))


def test_double_well_roots_beyond_one_are_kept_apart():
    # F = -k x (x^2 - 4): -2, 0, 2 (x is a length: no reduction modulo 2 pi)
    assert _values(find_equilibria(_double_well(2), {})) == [[-2.0], [0.0], [2.0]]


def test_roots_are_sorted_whatever_order_they_are_found_in():
    # F = -k x (x^2 - 1/4): from 0.6 the search finds 0.5 first, from 0.05 then 0
    assert _values(find_equilibria(_double_well(sp.Rational(1, 2)), {}, guesses=[[0.6], [0.05]])) == [[0.0], [0.5]]


def test_large_forces_scale_the_tolerance():
    # m g l = 2e12: the residual at a root is ~1e-4 in absolute terms, 1e-16 relative
    heavy = _pendulum("heavy_pendulum_s", mass=1e12)
    assert _values(find_equilibria(heavy, {})) == [[0.0], [math.pi]]


def test_non_finite_forces_at_every_start_give_no_roots():
    # F = k / x^2 is infinite at the only guess, x = 0 (and has no root anywhere)
    model = derive_equations(Model("inverse_square_s", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                   potential_energy=k / x, parameter_values={"m": 1.0, "k": 1.0}))
    assert find_equilibria(model, {}, guesses=[[0.0]]) == []


def test_symbolic_search_without_forces_and_with_more_than_six_coordinates():
    free = derive_equations(Model("free_s", [x], [m], kinetic_energy=m * x.diff() ** 2 / 2))
    assert find_equilibria(free) == [{}]  # every configuration
    q = me.dynamicsymbols("q1:8")  # n = 7 > SIMPLIFY_MAX_N: conditions passed unsimplified
    springs = derive_equations(Model("springs7_s", q, [m, k], kinetic_energy=sum(m * qi.diff() ** 2 for qi in q) / 2,
                                     potential_energy=sum(k * qi ** 2 for qi in q) / 2))
    assert find_equilibria(springs) == [dict.fromkeys(springs.q, 0)]


def test_values_by_symbol_and_unknown_names_listed(pendulum):
    # K0 = m g l = 8 with g = 8 given by its Symbol
    assert linearize(pendulum, [0.0], {g: 8.0}).K0.tolist() == [[8.0]]
    with pytest.raises(ValueError, match=r"unknown parameter 'gee' for model 'pendulum_s' \(parameters: m, g, l\)"):
        linearize(pendulum, [0.0], {"gee": 8.0})
    free = derive_equations(Model("no_parameters_s", [x], [], kinetic_energy=x.diff() ** 2 / 2))
    with pytest.raises(ValueError, match=r"\(parameters: none\)$"):
        find_equilibria(free, {"gee": 8.0})


def test_a_force_that_is_nowhere_finite_is_not_taken_as_steady():
    # F = sqrt(x - 5) cos(t) at rest: NaN at every sampled x in [0.5, 2], so the numeric check
    # sees no value at all; that is no evidence of independence from t
    model = derive_equations(Model("nowhere_finite_s", [x], [], kinetic_energy=x.diff() ** 2 / 2,
                                   generalized_forces={x: sp.sqrt(x - 5) * sp.cos(t)}))
    with pytest.raises(ValueError, match=r"F\[0\] \(coordinate x\).*depends on t"):
        find_equilibria(model)


def test_missing_parameters_name_the_quantity_being_built():
    model = derive_equations(Model("msd_s", [x], [m, c, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                   potential_energy=k * x ** 2 / 2, dissipation=c * x.diff() ** 2 / 2))
    with pytest.raises(ValueError, match="^equilibrium conditions of model 'msd_s': no value for parameter.*k"):
        find_equilibria(model, {"m": 1.0, "c": 0.1})
    for given, which in (({}, "M0"), ({"m": 1.0}, "C0"), ({"m": 1.0, "c": 0.1}, "K0")):
        with pytest.raises(ValueError, match=f"^linear model {which} of model 'msd_s'"):
            linearize(model, [0.0], given)


# -- angle_like, points ---------------------------------------------------------------------------
def test_angle_like_needs_the_coordinate_only_inside_sin_and_cos():
    # a length that enters nowhere (the free cart) and an angle that also has a torsion spring
    # th^2 / 20 are not angles: their equations are not 2 pi-periodic in them
    T = (2 * m) * x.diff() ** 2 / 2 + m * l * sp.cos(th) * x.diff() * th.diff() + m * l ** 2 * th.diff() ** 2 / 2
    cart = derive_equations(Model("cart_s", [x, th], [m, g, l], kinetic_energy=T,
                                  potential_energy=-m * g * l * sp.cos(th)))
    assert angle_like(cart) == (False, True)
    sprung = _pendulum("sprung_pendulum_s", generalized_forces={th: -th / 10})
    assert angle_like(sprung) == (False,)


@pytest.mark.parametrize("bad", [sp.nan, sp.zoo, sp.oo, -sp.oo])
def test_non_finite_sympy_q0_is_refused(pendulum, bad):
    with pytest.raises(ValueError, match="q0 entry for theta must be finite"):
        linearize(pendulum, [bad])


# -- linearize, LinearModel -----------------------------------------------------------------------
def test_linearize_refuses_a_time_varying_linear_model():
    # T = m (2 + cos t) xd^2 / 2: x = 0 is at rest at every t, but M0 = m (2 + cos t) varies in time, so
    # the model frozen at t = 0 (3 m, which this test once pinned) says nothing of its stability
    # (found by review, session 16: "stable" inside a vibrating pivot's resonance tongue)
    model = derive_equations(Model("growing_mass_s", [x], [m, k], kinetic_energy=m * (2 + sp.cos(t)) * x.diff() ** 2 / 2,
                                   potential_energy=k * x ** 2 / 2))
    with pytest.raises(ValueError, match=r"model 'growing_mass_s' depends on t at q0: M\[0,0\] = m\*cos\(t\) \+ 2\*m"):
        linearize(model, [0])


def test_linearize_takes_a_time_that_cancels():
    # T = m (sin^2 t + cos^2 t) xd^2 / 2 = m xd^2 / 2 by hand: M0 = m, C0 = 0, K0 = k
    model = derive_equations(Model("unit_mass_s", [x], [m, k],
                                   kinetic_energy=m * (sp.sin(t) ** 2 + sp.cos(t) ** 2) * x.diff() ** 2 / 2,
                                   potential_energy=k * x ** 2 / 2))
    lin = linearize(model, [0])
    assert lin.q == tuple(model.q) and lin.q0 == (0,)
    assert (sp.simplify(lin.M0 - sp.Matrix([[m]])), lin.C0, lin.K0) == (sp.zeros(1, 1), sp.Matrix([[0]]), sp.Matrix([[k]]))


@pytest.mark.parametrize("step", [sp.sign, sp.Heaviside])
def test_a_force_not_differentiable_in_q_is_named(step):
    # Q = -k sign(x) (sympy keeps d sign(x)/dx unevaluated) or -k Heaviside(x) (derivative
    # -k DiracDelta(x)): no stiffness at rest
    model = derive_equations(Model("step_spring_s", [x], [m, k], kinetic_energy=m * x.diff() ** 2 / 2,
                                   generalized_forces={x: -k * step(x)}))
    with pytest.raises(ValueError, match=r"F\[0\] of model 'step_spring_s' is not differentiable in x"):
        linearize(model, [0.0])


def _linear(K0, M0=None):
    K0 = np.array(K0, dtype=float)
    return LinearModel((), (), np.eye(len(K0)) if M0 is None else np.array(M0, dtype=float), np.zeros_like(K0), K0)


def test_frequencies_below_one_and_neutral_modes_stay_real():
    lin = _linear(np.diag([0.0, 0.25]))  # w^2 = 0 (neutral) and 1/4
    w = lin.natural_frequencies()
    assert np.isrealobj(w) and w.tolist() == [0.0, 0.5]
    assert _linear(np.diag([-4.0, 1.0])).natural_frequencies().tolist() == [2j, 1.0]


def test_round_off_zero_modes_are_zeroed_and_soft_modes_kept():
    """A free-free pair of masses (m1 = 1, m2 = 1e-3, k = 1e6) has a rigid mode, w^2 = 0 exactly (by
    hand: K (1, 1) = 0), which eigh returns as round-off; it must read 0. Exact small eigenvalues are
    data: diag(1e4, 1e-8) has w^2 = 1e-8 (was zeroed as 'relative 1e-10'), and a stiff chain's soft
    modes stay (see test_statics_review2)."""
    k = 1e6
    free = _linear(k * np.array([[1.0, -1.0], [-1.0, 1.0]]), np.diag([1.0, 1e-3])).eigenvalues()
    assert free[0] == 0.0
    assert free[1] == pytest.approx(k * (1.0 + 1e3), rel=1e-12)  # by hand: k (1/m1 + 1/m2)
    np.testing.assert_allclose(_linear(np.diag([1e4, 1e-8])).eigenvalues(), [1e-8, 1e4], rtol=1e-12)
    np.testing.assert_allclose(_linear(np.diag([1e-8, 1e-12])).eigenvalues(), [1e-12, 1e-8], rtol=1e-12)


@pytest.mark.parametrize("scale", [1e-12, 1.0, 1e6])
def test_circulatory_stiffness_is_refused_at_any_scale(scale):
    with pytest.raises(ValueError, match=r"K0 is not symmetric \(K0\[0,1\] != K0\[1,0\]"):
        _linear(scale * np.array([[2.0, 1.0], [0.0, 2.0]])).eigenvalues()


def test_round_off_asymmetry_is_accepted():
    # relative asymmetry 1e-13 at entries of 1e6 (the symmetric part is used)
    lin = _linear([[2e6, 1e6 + 2e-7], [1e6, 2e6]])
    np.testing.assert_allclose(lin.eigenvalues(), [1e6, 3e6], rtol=1e-12)


def test_mode_shapes_are_mass_normalized_with_a_positive_largest_entry():
    # the documented normalization, checked on seeded random M0, K0 (symmetric positive definite)
    rng = np.random.default_rng(3)
    for n in (2, 3, 4, 5):
        for _ in range(5):
            B, C = rng.normal(size=(n, n)), rng.normal(size=(n, n))
            M0, K0 = B @ B.T + n * np.eye(n), C @ C.T + np.eye(n)
            V = _linear(K0, M0).mode_shapes()
            np.testing.assert_allclose(V.T @ M0 @ V, np.eye(n), atol=1e-12)
            assert np.all(V[np.argmax(np.abs(V), axis=0), np.arange(n)] > 0)


def test_frequencies_name_the_matrix_that_still_has_symbols():
    lin = LinearModel((), (), np.eye(1), np.zeros((1, 1)), sp.Matrix([[k]]))
    with pytest.raises(ValueError, match="^K0 still contains k"):
        lin.natural_frequencies()


# -- constrained_equilibrium ----------------------------------------------------------------------
def _bob(name="bob_s", mass=2.0, phi=None, **names):
    """Bob of mass m at (x, y) on a rod of length l: phi = x^2 + y^2 - l^2 (tension 2 l lambda)."""
    X, Y = (me.dynamicsymbols(names.get(s, s)) for s in ("x", "y"))
    return derive_equations(Model(
        name, [X, Y], [m, g, l], kinetic_energy=m * (X.diff() ** 2 + Y.diff() ** 2) / 2, potential_energy=m * g * Y,
        constraints=[X ** 2 + Y ** 2 - l ** 2 if phi is None else phi(X, Y)],
        parameter_values={"m": mass, "g": 9.81, "l": 1.3}))


def test_hanging_bob_multiplier_by_hand_with_heavy_mass():
    # lambda = m g / (2 l); with m = 1e9 the residual ~1e-6 is 1e-16 of the forces
    for mass in (2.0, 1e9):
        q, lam = constrained_equilibrium(_bob(mass=mass), {"x": 0.1, "y": -0.9})
        np.testing.assert_allclose(q, [0.0, -1.3], atol=1e-12)
        np.testing.assert_allclose(lam, [mass * 9.81 / 2.6], rtol=1e-12)


@pytest.mark.parametrize("guess", [[0, -1], [sp.Integer(0), sp.Rational(-1)], {"x": 0, "y": -1}])
def test_an_integer_or_sympy_guess_gives_a_float_solution(guess):
    q, lam = constrained_equilibrium(_bob(), guess)
    np.testing.assert_allclose(q, [0.0, -1.3], atol=1e-12)
    np.testing.assert_allclose(lam, [2.0 * 9.81 / 2.6], rtol=1e-12)


def test_coordinates_named_like_the_multipliers():
    # the multipliers are Dummies: a coordinate called lambda_0 is a different unknown
    q, lam = constrained_equilibrium(_bob("bob_lambda_s", x="lambda_0", y="lambda_1"), [0.1, -0.9])
    np.testing.assert_allclose(q, [0.0, -1.3], atol=1e-12)
    np.testing.assert_allclose(lam, [2.0 * 9.81 / 2.6], rtol=1e-12)


def test_no_equilibrium_raises_naming_the_constraint():
    # phi = x^2 + y^2 + l^2 >= l^2 > 0: no admissible point; the best residual is l^2 = 1.69
    # (less than the size of the terms, so a tolerance near 1 would pass it)
    eom = _bob("no_circle_s", phi=lambda X, Y: X ** 2 + Y ** 2 + l ** 2)
    with pytest.raises(ValueError, match=r"no constrained equilibrium of model 'no_circle_s'.*constraint 0: .* has residual 1\.69"):
        constrained_equilibrium(eom, [0.1, -0.9])


def test_a_coordinate_symbol_can_be_held():
    eom = _bob()
    for fix in (eom.q[0], [eom.q[0]], {eom.q[0]: 0.0}):
        q, lam = constrained_equilibrium(eom, [0.0, -1.0], fix=fix)
        np.testing.assert_allclose(q, [0.0, -1.3], atol=1e-12)
        np.testing.assert_allclose(lam, [9.81 * 2.0 / 2.6, 0.0], atol=1e-10)  # x needs no holding force


_ROOT = scipy.optimize.root


def _spy_root(monkeypatch):
    """scipy.optimize.root (both modules call it through the scipy package) recording its calls."""
    calls = []

    def root(fun, x0, **kwargs):
        calls.append((fun, np.array(x0, dtype=float), kwargs))
        return _ROOT(fun, x0, **kwargs)
    monkeypatch.setattr(scipy.optimize, "root", root)
    return calls


def _check_jacobians(calls):
    assert calls
    for fun, x0, kwargs in calls:
        jac = kwargs.get("jac")
        assert callable(jac), "the analytic Jacobian is passed"
        numeric = np.column_stack([(fun(x0 + h) - fun(x0 - h)) / 2e-6 for h in 1e-6 * np.eye(len(x0))])
        np.testing.assert_allclose(jac(x0), numeric, rtol=1e-6, atol=1e-6)


def test_the_solvers_get_the_jacobian_of_the_equations(monkeypatch):
    # against central differences of the same residual function at the starting points
    assert constrained.scipy.optimize is equilibria.scipy.optimize is scipy.optimize
    calls = _spy_root(monkeypatch)
    constrained_equilibrium(_bob(), [0.1, -0.9])
    constrained_equilibrium(_bob(), [0.3, -0.9], fix=["x"])
    _check_jacobians(calls)
    calls.clear()
    find_equilibria(derive_equations(catalog.double_pendulum()), {}, guesses=[[0.3, -0.2], [2.9, 0.4]])
    _check_jacobians(calls)
