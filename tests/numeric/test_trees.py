"""Kinematic trees (issue 15): the recursive formulation against independent derivations.

References, per test:
- the planar chain's closed form from the energies route, T and V written by hand in
  `catalog.pendulum_chain` (Lagrange II; no tree code involved);
- sympy's KanesMethod, built in this file from frames and bodies for the spherical chain;
- the same tree in closed form through the points and bodies route (a second derivation route)
  for the branched ragdoll;
- conservation of energy (no damping) for the big trees.
"""
from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Link, Model, ModelError, catalog
from lagcodegen.codegen.outputs import KernelError
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import jacobian, make_rhs, parameter_vector, simulate
from lagcodegen.status import Status
from lagcodegen.symbolic.derive import derive_equations
from lagcodegen.symbolic.trees import choose_formulation, derive_from_tree
from lagcodegen.tree import TreeError


def _states(n_q: int, count: int = 5, seed: int = 0) -> np.ndarray:
    rng = np.random.default_rng(seed)
    return np.hstack([rng.uniform(-1.0, 1.0, (count, n_q)), rng.uniform(-2.0, 2.0, (count, n_q))])


def _compiled(model, tmp_path, **options):
    return compile_model(model, methods=options.pop("methods", ("rk4",)), cache_dir=tmp_path, **options)


@pytest.mark.parametrize("n", [1, 2, 5, 12])
def test_chain_recursive_equals_the_hand_derived_lagrangian(n, tmp_path):
    """pendulum_chain(n, route='tree') in its recursive formulation against the energies route
    (T and V by hand in absolute angles): the right-hand sides at random states to 1e-12."""
    from dataclasses import replace

    tree = _compiled(replace(catalog.pendulum_chain(n, route="tree"), formulation="recursive"), tmp_path)
    hand = _compiled(catalog.pendulum_chain(n, route="energies"), tmp_path)
    assert "recursive" in tree.layout.formulation
    f, g = make_rhs(tree), make_rhs(hand)
    for x in _states(n):
        np.testing.assert_allclose(f(0.0, x), g(0.0, x), rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize("n", [3, 5])
def test_chain_closed_form_of_the_tree_equals_the_hand_derived_lagrangian(n, tmp_path):
    """The tree in closed form goes through the points and bodies route, whose grouping of terms
    once summed two zero coefficients into 0/0 = NaN entries of M for this chain (relative angles)."""
    from dataclasses import replace

    tree = _compiled(replace(catalog.pendulum_chain(n, route="tree"), formulation="closed"), tmp_path)
    hand = _compiled(catalog.pendulum_chain(n, route="energies"), tmp_path)
    f, g = make_rhs(tree), make_rhs(hand)
    for x in _states(n, seed=n):
        np.testing.assert_allclose(f(0.0, x), g(0.0, x), rtol=1e-12, atol=1e-12)


def _kane_spherical_chain(n: int):
    """sympy KanesMethod of `catalog.spherical_chain` from its docstring: rods joined by z, x, y
    turns relative to the rod above, gravity along -z. Returns (q, u, params, M_full, F_full)."""
    m, l, r, g = sp.symbols("m l r g", positive=True)
    N, O = me.ReferenceFrame("N"), me.Point("O")
    O.set_vel(N, 0)
    frame, tip, q, bodies, loads = N, O, [], [], []
    for i in range(1, n + 1):
        a, b, c = me.dynamicsymbols(f"a{i} b{i} c{i}")
        A = me.ReferenceFrame(f"A{i}")
        A.orient_axis(frame, frame.z, a)
        B = me.ReferenceFrame(f"B{i}")
        B.orient_axis(A, A.x, b)
        C = me.ReferenceFrame(f"C{i}")
        C.orient_axis(B, B.y, c)
        center = tip.locatenew(f"G{i}", -l / 2 * C.z)
        center.v2pt_theory(tip, N, C)
        new_tip = tip.locatenew(f"T{i}", -l * C.z)
        new_tip.v2pt_theory(tip, N, C)
        inertia = me.inertia(C, m * l ** 2 / 12, m * l ** 2 / 12, m * r ** 2 / 2)
        bodies.append(me.RigidBody(f"rod{i}", center, C, m, (inertia, center)))
        loads.append((center, -m * g * N.z))
        q += [a, b, c]
        frame, tip = C, new_tip
    u = [qi.diff() for qi in q]
    speeds = me.dynamicsymbols(f"w1:{len(q) + 1}")
    kane = me.KanesMethod(N, q_ind=q, u_ind=speeds, kd_eqs=[qd - w for qd, w in zip(u, speeds)])
    kane.kanes_equations(bodies, loads)
    return q, speeds, (m, l, r, g), kane.mass_matrix_full, kane.forcing_full


@pytest.mark.parametrize("n", [1, 2])
def test_spherical_chain_equals_sympys_kane_model(n, tmp_path):
    """The 3D chain of rods on spherical joints (three revolute axes each): recursive rhs against
    sympy KanesMethod's M_full^-1 F_full at random states, to 1e-10."""
    model = catalog.spherical_chain(n, formulation="recursive")
    system = _compiled(model, tmp_path)
    f = make_rhs(system)
    q, w, params, M, F = _kane_spherical_chain(n)
    values = [model.parameter_values[p] for p in model.parameters]
    assert [p.name for p in model.parameters] == [p.name for p in params]
    M_f = sp.lambdify(list(q) + list(w) + list(params), M, "numpy")
    F_f = sp.lambdify(list(q) + list(w) + list(params), F, "numpy")
    for x in _states(3 * n, seed=n) * 0.6:  # away from the gimbal lock at b = +-pi/2
        args = list(x) + values
        expected = np.linalg.solve(np.array(M_f(*args), dtype=float), np.array(F_f(*args), dtype=float).ravel())
        np.testing.assert_allclose(f(0.0, x), expected, rtol=1e-10, atol=1e-10)


def test_ragdoll_recursive_equals_its_closed_form(tmp_path):
    """The branched ragdoll (floating pelvis, three branches, springs and dampers) with two links
    per branch: recursive against the points-and-bodies route of the same tree, to 1e-11."""
    recursive = _compiled(catalog.ragdoll(2, formulation="recursive"), tmp_path)
    closed = _compiled(catalog.ragdoll(2, formulation="closed"), tmp_path)
    assert "closed" in closed.layout.formulation and "recursive" in recursive.layout.formulation
    f, g = make_rhs(recursive), make_rhs(closed)
    for x in _states(9, seed=3):
        np.testing.assert_allclose(f(0.0, x), g(0.0, x), rtol=1e-11, atol=1e-11)
    x0 = _states(9, count=1, seed=4)[0]
    a = simulate(recursive, x0, t_end=0.5, h=1e-3, energy=True, points=True)
    b = simulate(closed, x0, t_end=0.5, h=1e-3, energy=True, points=True)
    np.testing.assert_allclose(a.energy, b.energy, rtol=1e-11, atol=1e-10)
    np.testing.assert_allclose(a.points, b.points, rtol=0, atol=1e-11)


@pytest.mark.parametrize("build, size", [(lambda: catalog.pendulum_chain(40, route="tree"), 40),
                                          (lambda: catalog.ragdoll(8), 27),
                                          (lambda: catalog.spherical_chain(8), 24)])
def test_big_trees_conserve_energy(build, size, tmp_path):
    """Without damping the energy is a first integral, so its drift under RK4 is the method's
    error alone: it falls by 2^4 = 16 when h halves (measured 16.4 for the ragdoll at h = 1e-3),
    or is at round-off already. A dynamics kernel inconsistent with the energy kernel drifts by
    a part that does not shrink with h."""
    model = build()
    if model.dissipation != 0:
        model = Model(model.name, model.coordinates, model.parameters, tree=model.tree, gravity=model.gravity,
                      potential_energy=model.potential_energy, parameter_values=model.parameter_values)
    system = _compiled(model, tmp_path)
    assert "recursive" in system.layout.formulation
    x0 = _states(size, count=1, seed=5)[0] * 0.3
    drift = []
    for h in (1e-3, 5e-4):
        run = simulate(system, x0, t_end=1.0, h=h, energy=True)
        drift.append(np.abs(run.energy - run.energy[0]).max() / (np.abs(run.energy).max() + 1.0))
    if drift[0] > 1e-10:
        assert 12 < drift[0] / drift[1] < 20, drift
    else:
        assert drift[1] < 1e-10


def test_implicit_methods_use_a_difference_jacobian_close_to_the_exact_one(tmp_path):
    """The recursive tree's Jacobian (central differences in C) against the closed form's
    symbolic Jacobian of the hand-derived chain: agreement to 1e-7 relative; and backward Euler
    runs on it."""
    from dataclasses import replace

    tree = _compiled(replace(catalog.pendulum_chain(4, route="tree"), formulation="recursive"), tmp_path,
                     methods=("rk4", "backward_euler"))
    hand = _compiled(catalog.pendulum_chain(4, route="energies"), tmp_path, methods=("rk4", "backward_euler"))
    for x in _states(4, count=3, seed=6):
        J_tree = jacobian(tree, x, parameter_vector(tree))
        J_hand = jacobian(hand, x, parameter_vector(hand))
        np.testing.assert_allclose(J_tree, J_hand, rtol=1e-7, atol=1e-7 * np.abs(J_hand).max())
    x0 = _states(4, count=1, seed=7)[0] * 0.2
    a = simulate(tree, x0, t_end=0.2, h=1e-3, method="backward_euler")
    b = simulate(hand, x0, t_end=0.2, h=1e-3, method="backward_euler")
    np.testing.assert_allclose(a.x[-1], b.x[-1], rtol=1e-8, atol=1e-8)


def test_a_massless_leaf_is_a_singular_status_not_nan(tmp_path):
    """A tree whose last link's mass is 0 at run time has a zero articulated pivot: the run stops
    with the singular-mass-matrix status, naming no NaN. A leaf massless in the model itself is
    refused when derived, naming the link, as the closed form refuses it (found by review: with
    a spring or a force on its joint, 1 / D printed as zoo and the C printer failed)."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    m, m2, g, k = sp.symbols("m m2 g k", positive=True)
    upper = Link("upper", None, "revolute", (0, 0, 1), q1, mass=m, center=(0, -1, 0))
    model = Model("massless_leaf", [q1, q2], [m, m2, g], gravity=(0, -g, 0), formulation="recursive",
                  tree=[upper, Link("lower", "upper", "revolute", (0, 0, 1), q2, offset=(0, -1, 0), mass=m2,
                                    center=(0, -1, 0))],
                  parameter_values={m: 1.0, m2: 0.0, g: 9.81})
    system = _compiled(model, tmp_path)
    with pytest.raises(FloatingPointError, match="singular"):
        make_rhs(system)(0.0, np.array([0.1, 0.2, 0.0, 0.0]))
    for formulation, match in (("recursive", "link 'lower' \\(joint variable q2\\) has no inertia"),
                               ("closed", "'q2' has no inertia")):
        with pytest.raises(ModelError, match=match):
            derive_equations(Model("massless_leaf", [q1, q2], [m, g, k], potential_energy=k * q2 ** 2 / 2,
                                   gravity=(0, -g, 0), formulation=formulation,
                                   tree=[upper, Link("lower", "upper", "revolute", (0, 0, 1), q2, offset=(0, -1, 0))]))


def test_fixed_parameters_fold_into_the_recursion(tmp_path):
    """Folding m and l (fixed=) changes the code, not the numbers: equal to the free build."""
    model = catalog.pendulum_chain(8, route="tree")
    free = _compiled(model, tmp_path)
    fixed = _compiled(model, tmp_path, fixed={f"m{i}": 1.0 for i in range(1, 9)} | {f"l{i}": 1.0 for i in range(1, 9)})
    assert fixed.layout.parameters == ("g",)
    for x in _states(8, count=3, seed=8):
        np.testing.assert_allclose(make_rhs(free)(0.0, x), make_rhs(fixed)(0.0, x), rtol=1e-13, atol=1e-13)


def test_a_driven_tree_takes_its_inputs_like_the_closed_form(tmp_path):
    """A torque input r on the first joint (a generalized force) and a spring on the second: the
    recursive tree against the same model in closed form, under a sinusoidal input."""
    q1, q2, r = me.dynamicsymbols("q1 q2 r")
    m, g, k = sp.symbols("m g k", positive=True)
    links = [Link("upper", None, "revolute", (0, 0, 1), q1, mass=m, center=(0, -1, 0), inertia=(0, 0, m / 12, 0, 0, 0)),
             Link("lower", "upper", "revolute", (0, 0, 1), q2, offset=(0, -1, 0), mass=m, center=(0, -0.5, 0))]

    def build(formulation):
        return Model("driven_tree", [q1, q2], [m, g, k], tree=links, gravity=(0, -g, 0), inputs=[r],
                     generalized_forces={q1: r}, potential_energy=k * q2 ** 2 / 2, formulation=formulation,
                     parameter_values={m: 1.0, g: 9.81, k: 3.0})
    recursive, closed = _compiled(build("recursive"), tmp_path), _compiled(build("closed"), tmp_path)
    inputs = lambda t, x: np.array([0.5 * np.sin(3 * t)])  # noqa: E731
    for x in _states(2, count=3, seed=9):
        np.testing.assert_allclose(make_rhs(recursive, inputs=inputs)(0.3, x), make_rhs(closed, inputs=inputs)(0.3, x),
                                   rtol=1e-12, atol=1e-12)


def test_the_cost_model_picks_closed_for_small_and_recursive_for_big_trees(tmp_path):
    """The choices the measured costs call for (trees.py's cost-model table): the closed form is the
    faster step up to about 16 planar links, but with implicit methods its symbolic Jacobian makes
    the compile several times slower from 6 links on; a 3D tree's closed form grows much faster."""
    small = derive_equations(catalog.pendulum_chain(2, route="tree"))
    big = derive_equations(catalog.pendulum_chain(30, route="tree"))
    assert small.tree is None and small.formulation.startswith("closed (chosen by cost")
    assert big.tree is not None and big.formulation.startswith("recursive (chosen by cost")
    middle = catalog.pendulum_chain(8, route="tree")
    assert choose_formulation(middle, implicit=False).name == "closed"
    assert choose_formulation(middle).reason.startswith("chosen for 8 links: the closed form's Jacobian")
    assert choose_formulation(catalog.spherical_chain(2), implicit=False).name == "recursive"
    # compile_model knows the methods: RK4 alone keeps the closed form, the defaults do not
    assert _compiled(middle, tmp_path).layout.formulation.startswith("closed (chosen by cost for 8 links")
    assert compile_model(middle, cache_dir=tmp_path).layout.formulation.startswith("recursive (chosen for 8")


def test_the_header_says_which_formulation(tmp_path):
    system = _compiled(catalog.pendulum_chain(20, route="tree"), tmp_path)
    assert "Formulation: recursive (chosen by cost for 20 links" in system.sources.header
    report = system.report()
    assert "formulation: recursive (chosen by cost for 20 links" in report
    assert f"C source: {len(system.sources.source)} bytes" in report and "estimated build:" in report
    assert "compiled in" in report  # a fresh cache dir: this process compiled it


def test_the_report_says_a_cache_hit(tmp_path, monkeypatch):
    from lagcodegen.native import build

    _compiled(catalog.pendulum_chain(3, route="tree"), tmp_path)
    monkeypatch.setattr(build, "_MEMO", {})  # as in a new process: the disk entry serves
    assert "loaded from the cache" in _compiled(catalog.pendulum_chain(3, route="tree"), tmp_path).report()


def test_a_warm_compile_skips_the_derivation_and_a_damaged_model_entry_does_not(tmp_path, monkeypatch):
    """The second compile_model of an unchanged tree hits the model entry (no derivation); a
    damaged model entry is ignored (derived again), never trusted."""
    import lagcodegen.pipeline as pipeline

    model = catalog.pendulum_chain(6, route="tree")
    first = _compiled(model, tmp_path)
    calls = []
    monkeypatch.setattr(pipeline, "derive_from_tree", lambda m, **options: calls.append(m) or derive_from_tree(m, **options))
    again = _compiled(model, tmp_path)
    assert calls == [] and again.key == first.key
    for entry in (tmp_path / "sources").glob("model-*.txt"):
        text = entry.read_bytes()  # the last byte changed (it was "0" for one package digest in 16)
        entry.write_bytes(text[:-1] + (b"1" if text.endswith(b"0") else b"0"))
    third = _compiled(model, tmp_path)
    assert len(calls) == 1 and third.key == first.key


def test_recursive_only_outputs_are_refused_by_name(tmp_path):
    model = catalog.pendulum_chain(20, route="tree")
    with pytest.raises(KernelError, match="'mass_matrix' needs the closed-form M and F.*formulation='closed'"):
        compile_model(model, outputs=["rhs", "mass_matrix"], methods=("rk4",), cache_dir=tmp_path)


def _link(**change):
    q1 = me.dynamicsymbols("q1")
    fields = dict(name="a", parent=None, joint="revolute", axis=(0, 0, 1), variable=q1)
    fields.update(change)
    return Link(**fields)


@pytest.mark.parametrize("change, match", [
    (dict(joint="ball"), "link 'a': joint must be one of revolute, prismatic"),
    (dict(axis=(0, 0, 0)), "link 'a': the axis is the zero vector"),
    (dict(axis=(0, 1)), "link 'a': axis must be 3 entries"),
    (dict(axis=(0, sp.Symbol("k"), 1)), "link 'a': the axis must be 3 real numbers"),
    (dict(offset=(me.dynamicsymbols("q1"), 0, 0)), "link 'a': offset q1.* depends on q1"),
    (dict(name="not a name"), "link name must be an identifier"),
    (dict(inertia=(1, 2, 3)), "link 'a': inertia must be 6 entries"),
])
def test_bad_links_are_named(change, match):
    with pytest.raises(ValueError, match=match):
        _link(**change)


def test_bad_trees_are_named():
    q1, q2 = me.dynamicsymbols("q1 q2")
    k = sp.Symbol("k")
    link = lambda name, parent, variable: Link(name, parent, "revolute", (0, 0, 1), variable, mass=1)  # noqa: E731
    cases = [
        ([link("a", None, q1), link("b", "c", q2)], "link 'b' hangs from 'c', which is not a link listed before it"),
        ([link("a", None, q1), link("a", "a", q2)], "link name 'a' is used twice"),
        ([link("a", None, sp.sin(q1)), link("b", "a", q2)], "joint variable sin\\(q1.*not linear in q1"),
        ([link("a", None, k * q1), link("b", "a", q2)], "joint variable k\\*q1.*not linear in q1 with a constant"),
        ([link("a", None, sp.I * q1), link("b", "a", q2)], "joint variable I\\*q1.* has the coefficient I of q1, "
         "which is not a real number"),
        ([link("a", None, q1), link("b", "a", 2 * q1)], "the joint variables do not determine the coordinates"),
        ([link("a", None, q1)], "the tree has 1 links .* but the model has 2 coordinates"),
    ]
    for tree, match in cases:
        with pytest.raises(ModelError, match=match):
            Model("bad_tree", [q1, q2], [k], tree=tree)
    with pytest.raises(ModelError, match="a tree brings its bodies, frames and points; drop kinetic_energy"):
        Model("bad_tree", [q1, q2], [k], tree=[link("a", None, q1), link("b", "a", q2)], kinetic_energy=q1.diff() ** 2)
    with pytest.raises(ModelError, match="formulation 'recursive' is for a kinematic tree"):
        Model("no_tree", [q1], [k], kinetic_energy=q1.diff() ** 2, formulation="recursive")
    with pytest.raises(ModelError, match="formulation 'elimination' is for velocity constraints"):
        Model("bad_tree", [q1, q2], [k], tree=[link("a", None, q1), link("b", "a", q2)], formulation="elimination")


def test_the_recursive_form_sends_the_statics_to_the_closed_form_and_drops_a_driven_energy(tmp_path):
    """Found by review: linearize_state and find_equilibria on a recursive tree failed with numpy's
    and sympy's own errors (it forms no M and F); and an input in a recursive tree's potential
    energy (a servo spring's setpoint) made the energy kernel read r, which it does not take:
    the C failed to compile. The closed form drops that energy; so does the recursive one now."""
    from lagcodegen.statics.equilibria import find_equilibria, linearize
    from lagcodegen.statics.state_space import linearize_state

    q1, setpoint = me.dynamicsymbols("q1 w")
    k = sp.Symbol("k", positive=True)
    arm = [Link("arm", None, "revolute", (0, 0, 1), q1, mass=1, center=(1, 0, 0))]
    eom = derive_equations(Model("servo", [q1], [k], tree=arm, potential_energy=k * q1 ** 2 / 2,
                                 parameter_values={k: 5.0}, formulation="recursive"))
    for call, name in ((lambda: linearize_state(eom, [0.0, 0.0], values={}), "linearize_state"),
                       (lambda: find_equilibria(eom, {}), "find_equilibria"), (lambda: linearize(eom, [0.0]), "linearize")):
        with pytest.raises(ValueError, match=f"{name} needs the closed-form M and F.*formulation='closed'"):
            call()
    driven = Model("servo_driven", [q1], [k], tree=arm, potential_energy=k * (q1 - setpoint) ** 2 / 2, inputs=[setpoint],
                   parameter_values={k: 5.0}, formulation="recursive")
    system = compile_model(driven, methods=("rk4",), cache_dir=tmp_path)
    assert not any(name.endswith("_energy") for name in system.layout.functions)
    with pytest.raises(KernelError, match="holds the input"):
        compile_model(driven, methods=("rk4",), outputs=("rhs", "energy"), cache_dir=tmp_path)
    # the arm (I = 1 about the joint) held at w = 0.2 by k = 5: q1 = 0.2 (1 - cos(sqrt(5) t)) (by hand)
    run = simulate(system, [0.0, 0.0], t_end=1.0, h=1e-3, inputs=[0.2])
    assert run.x[-1, 0] == pytest.approx(0.2 * (1 - np.cos(np.sqrt(5.0))), rel=1e-10)


def test_the_difference_jacobian_keeps_its_accuracy_at_large_angles(tmp_path):
    """Found by review: the recursive form's central differences stepped eps^(1/3) |q| in an angle,
    and the dynamics vary with an angle on a scale of a radian at any angle: 1.6e-6 relative error
    at 100 rad, 8.5e-5 at 1000 rad, 1.5e-2 at 1e4. The reference is the closed form's symbolic
    Jacobian of the same 4-link chain (the second route)."""
    recursive = compile_model(dataclasses.replace(catalog.pendulum_chain(4, route="tree"), formulation="recursive"),
                              methods=("rk4",), outputs=("rhs", "jacobian"), cache_dir=tmp_path)
    closed = compile_model(catalog.pendulum_chain(4, route="energies"), methods=("rk4",),
                           outputs=("rhs", "jacobian"), cache_dir=tmp_path)
    rng = np.random.default_rng(15)
    for offset, limit in ((1.0, 1e-9), (1000.0, 1e-7)):
        for _ in range(5):
            x = rng.uniform(-1, 1, 8)
            x[:4] += offset * rng.choice([-1, 1], 4)
            J = jacobian(closed, x, None)
            assert np.abs(jacobian(recursive, x, None) - J).max() < limit * np.abs(J).max(), offset


def test_vectors_may_be_numpy_arrays_or_sympy_matrices(tmp_path):
    """Found by review: a 3-entry numpy array for an axis or for gravity was refused as "must be 3
    entries". A point mass 1 at distance 1 on a revolute joint: q'' = -g sin q by hand."""
    q = me.dynamicsymbols("q")
    for axis, center, gravity in ((np.array([0, 0, 1]), np.array([0.0, -1.0, 0.0]), np.array([0, -9.81, 0])),
                                  (sp.Matrix([0, 0, 1]), sp.Matrix([[0, -1, 0]]), sp.Matrix([0, -9.81, 0]))):
        model = Model("numpy_pendulum", [q], [], gravity=gravity,
                      tree=[Link("rod", None, "revolute", axis, q, mass=1, center=center)])
        rate = make_rhs(_compiled(model, tmp_path))(0.0, np.array([0.5, 0.0]))
        np.testing.assert_allclose(rate, [0.0, -9.81 * np.sin(0.5)], rtol=1e-14)
    with pytest.raises(TreeError, match="must be 3 entries"):
        Link("rod", None, "revolute", np.array([0, 1]), q)
    with pytest.raises(ModelError, match="gravity is 3 components"):
        Model("g", [q], [], gravity=np.zeros((3, 3)), tree=[Link("rod", None, "revolute", (0, 0, 1), q, mass=1,
                                                                   center=(0, -1, 0))])


def test_a_joint_whose_carried_mass_lies_on_its_axis_is_named_rightly():
    """Found by review: a massless turntable (axis z) carrying a slider along z with mass 1 was
    said to be "massless and carries no link with mass"; it does carry one, whose mass lies on the
    turntable's axis (no inertia about it, so the turntable's pivot is zero)."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    tree = [Link("turntable", None, "revolute", (0, 0, 1), q1),
            Link("slider", "turntable", "prismatic", (0, 0, 1), q2, mass=1)]
    with pytest.raises(ModelError, match="articulated inertia about its joint's axis is zero .*their mass lies on "
                                         "that axis"):
        derive_equations(Model("turntable", [q1, q2], [], tree=tree, formulation="recursive"))


def test_derive_on_the_command_line_says_a_recursive_tree_forms_no_m_and_f(tmp_path, capsys):
    """Found by review: `lagcodegen derive` printed "M = None" and "F = None" for a recursive tree."""
    from lagcodegen.cli.commands import main

    source = tmp_path / "tree.py"
    source.write_text("import sympy.physics.mechanics as me\nfrom lagcodegen import Link, Model\n"
                      "q = me.dynamicsymbols('q')\n"
                      "model = Model('rod', [q], [], gravity=(0, -9.81, 0), formulation='recursive',\n"
                      "              tree=[Link('rod', None, 'revolute', (0, 0, 1), q, mass=1, center=(0, -1, 0))])\n")
    code = main(["derive", str(source)])
    out, err = capsys.readouterr()
    assert code == 2 and "M = None" not in out
    assert "needs the closed-form M and F" in err and "formulation='closed'" in err


def test_an_axis_with_float_components_is_a_unit_vector():
    """Found by review: (3, 0.001, 0) has a float norm, and the exact-looking 3 / norm =
    0.99999994 was nsimplified to 1, an axis 5.6e-8 off unit length (the recursive kernel, which
    reads the stored axis, then missed Pinocchio's accelerations by 2.4e-8). Expected: numpy's
    a / |a|."""
    q = me.dynamicsymbols("q")
    for axis in ((3, 0.001, 0), (1, 2.5, 0), (0.6, 0.8, 0), (2, 0, 1e-9)):
        stored = np.array([float(a) for a in Link("rod", None, "revolute", axis, q).axis])
        expected = np.array(axis, dtype=float) / np.linalg.norm(axis)
        np.testing.assert_allclose(stored, expected, rtol=1e-15, atol=1e-17)
    exact = Link("rod", None, "revolute", (3, 4, 0), q).axis  # all exact: stays exact
    assert exact == (sp.Rational(3, 5), sp.Rational(4, 5), 0)


def test_a_mass_on_its_joint_axis_given_as_floats_is_refused_like_an_exact_one():
    """Found by review: link b turns about (0.6, 0.8, 0) and carries a point mass at (0.3, 0.4, 0),
    on that axis, so by hand axis x r = 0 and q1 has no inertia. With the same numbers as
    integers (3, 4) the recursive derivation refused it; as floats its pivot came out 1.7e-17 and
    the run went on with status OK, q1 not converging as h shrinks."""
    q0, q1 = me.dynamicsymbols("q0:2")
    links = [Link("a", None, "revolute", (1, 0, 0), q0, mass=1.0, center=(0, 0, -1), inertia=(0.1, 0.1, 0.1, 0, 0, 0)),
             Link("b", "a", "revolute", (0.6, 0.8, 0), q1, offset=(0, 0, -1), mass=2.0, center=(0.3, 0.4, 0))]
    with pytest.raises(ModelError, match=r"link 'b' \(joint variable q1\) has no inertia"):
        derive_equations(Model("on_axis", [q0, q1], [], tree=links, gravity=(0, 0, -9.81), formulation="recursive"))


def test_a_mass_on_its_joint_axis_through_runtime_parameters_is_a_singular_status(tmp_path):
    """The same link b with its point mass at (cx, cy, 0), cx and cy runtime parameters. At (0.3, 0.4),
    (0.9, 1.2), (0.03, 0.04) the mass is on b's axis (0.6, 0.8, 0), by hand, and q1 has no inertia:
    its articulated pivot came out at rounding level and the run went on with status OK (q1's final
    value changing with h). Now the pivot is tested against the trace of the inertia block it reads,
    and the run stops singular. Off the axis, (0.3, 0.41), the recursive kernel agrees with the
    closed form (a second derivation route) to 1e-9 at the initial state."""
    q0, q1 = me.dynamicsymbols("q0:2")
    cx, cy = sp.symbols("cx cy")

    def model(formulation):
        links = [Link("a", None, "revolute", (1, 0, 0), q0, mass=1.0, center=(0, 0, -1),
                      inertia=(0.1, 0.1, 0.1, 0, 0, 0)),
                 Link("b", "a", "revolute", (0.6, 0.8, 0), q1, offset=(0, 0, -1), mass=2.0, center=(cx, cy, 0))]
        return Model("on_axis_runtime", [q0, q1], [cx, cy], tree=links, gravity=(0, 0, -9.81),
                     formulation=formulation, parameter_values={cx: 0.3, cy: 0.4})

    recursive = _compiled(model("recursive"), tmp_path)
    for on_axis in ((0.3, 0.4), (0.9, 1.2), (0.03, 0.04)):
        with pytest.warns(RuntimeWarning, match="singular"):
            run = simulate(recursive, {"q0": 0.2, "q1": 0.1}, t_end=0.01, h=1e-3,
                           params={"cx": on_axis[0], "cy": on_axis[1]})
        assert run.status is Status.SINGULAR_MASS_MATRIX, on_axis
    closed = _compiled(model("closed"), tmp_path)
    x = np.array([0.2, 0.1, 0.3, -0.4])
    off_axis = {"cx": 0.3, "cy": 0.41}
    np.testing.assert_allclose(make_rhs(recursive, off_axis)(0.0, x), make_rhs(closed, off_axis)(0.0, x),
                               rtol=1e-9, atol=1e-9)


def test_the_command_line_records_a_recursive_trees_energy(tmp_path, capsys):
    """Found by review: `simulate --energy` and `sweep --field energy_error` said a recursive tree
    "has no energy expression", where the API records it. Expected E0 by hand: three unit masses
    on unit rods at rest at absolute angles 0.1, V = -g (1 + 2 + 3) cos(0.1)."""
    import dataclasses
    import math

    from lagcodegen.cli.commands import main

    model_file = tmp_path / "tree_model.py"
    model_file.write_text("import dataclasses\nfrom lagcodegen import catalog\n"
                          "model = dataclasses.replace(catalog.pendulum_chain(3, route='tree'), formulation='recursive')\n")
    assert dataclasses.is_dataclass(catalog.pendulum_chain(3, route="tree"))
    x0 = ",".join(f"q{i}=0.1" for i in (1, 2, 3))
    assert main(["simulate", str(model_file), "--x0", x0, "--t-end", "0.1", "--h", "1e-3", "--energy",
                 "--out", str(tmp_path / "run.npz")]) == 0
    printed = capsys.readouterr().out
    e0 = float(printed.split("energy: E0 = ")[1].split(",")[0])
    assert e0 == pytest.approx(-9.81 * 6 * math.cos(0.1), rel=1e-8)  # printed to 9 digits
    assert main(["sweep", str(model_file), "--grid", "m1=1,2", "--x0", x0, "--t-end", "0.1", "--h", "1e-3",
                 "--field", "energy_error"]) == 0
    assert "energy_error" in capsys.readouterr().out


def test_the_command_line_animates_a_tree(tmp_path, capsys):
    """Found by review: `lagcodegen animate` looked at Model.points, which a tree leaves empty (its
    points are its links'), refused every tree, and advised Model(points=...), which a tree refuses."""
    from PIL import Image

    from lagcodegen.cli.commands import main

    model_file = tmp_path / "tree_model.py"
    model_file.write_text("from lagcodegen import catalog\nmodel = catalog.pendulum_chain(3, route='tree')\n")
    out = tmp_path / "chain.gif"
    assert main(["animate", str(model_file), "--x0", "q1=1,q2=0.5,q3=0", "--t-end", "0.4", "--trace", "bob3",
                 "--out", str(out)]) == 0
    assert "wrote" in capsys.readouterr().out
    with Image.open(out) as gif:
        assert gif.n_frames == 11  # 0.4 s at 25 frames per second, both ends


def test_two_joints_about_one_tilted_axis_stop_singular(tmp_path):
    """Found by review: joints a (massless) and b about the same axis (1, 1, 0) through the same
    point: b's pose is Rot(a, q1 + q2) (by hand), so M = [[J, J], [J, J]] is singular at every state.
    About z the derivation refuses it; about the tilted axis a's pivot is an expression in q2 that
    is zero only in exact arithmetic, and the run went on with status OK and an arbitrary split of
    ud1 + ud2. Now the pivot's relative floor stops it at once."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    m, g = sp.symbols("m g", positive=True)
    for mass in (m, 1.0):
        links = [Link("a", None, "revolute", (1.0, 1.0, 0), q1),
                 Link("b", "a", "revolute", (1.0, 1.0, 0), q2, mass=mass, center=(0.3, -0.2, 0.5),
                      inertia=(0.1, 0.2, 0.3, 0.01, 0.02, 0.03))]
        system = _compiled(Model("aligned", [q1, q2], [m, g], tree=links, gravity=(0, -g, 0),
                                 formulation="recursive", parameter_values={m: 1.0, g: 9.81}), tmp_path)
        with pytest.warns(RuntimeWarning, match="singular"):
            run = simulate(system, np.array([0.3, 0.2, 0.1, -0.4]), t_end=0.5, h=1e-3)
        assert run.status is Status.SINGULAR_MASS_MATRIX and len(run.t) == 1, mass


def test_an_exact_irrational_axis_stays_exact_in_both_formulations(tmp_path):
    """Found by review: Link(axis=(sqrt(2)/2, sqrt(2)/2, 0)) and (cos(pi/6), sin(pi/6), 0) raised a
    bare TypeError ("cannot create mpf from sqrt(2)/2"), and (1, 1, 0) did in the recursive form,
    which normalizes the stored axis again. Expected: the unit vectors by hand; the recursive
    right-hand side equal to the closed form's (a second derivation route)."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    half = sp.sqrt(2) / 2
    assert Link("a", None, "revolute", (1, 1, 0), q1).axis == (half, half, 0)
    assert Link("a", None, "revolute", (half, half, 0), q1).axis == (half, half, 0)
    assert Link("a", None, "revolute", (sp.cos(sp.pi / 6), sp.sin(sp.pi / 6), 0), q1).axis == \
        (sp.sqrt(3) / 2, sp.Rational(1, 2), 0)
    links = [Link("a", None, "revolute", (0, 0, 1), q1, mass=1, center=(0, -1, 0)),
             Link("b", "a", "revolute", (1, 1, 0), q2, offset=(0, -1, 0), mass=2, center=(0.2, -1, 0.3),
                  inertia=(0.1, 0.2, 0.3, 0, 0, 0))]
    rhs = {form: make_rhs(_compiled(Model("irrational_axis", [q1, q2], [], tree=links, gravity=(0, -9.81, 0),
                                          formulation=form), tmp_path))
           for form in ("closed", "recursive")}
    x = np.array([0.3, -0.5, 0.7, 0.2])
    np.testing.assert_allclose(rhs["recursive"](0.0, x), rhs["closed"](0.0, x), rtol=1e-12, atol=1e-12)


def test_a_tree_without_mass_is_named_in_the_closed_form():
    """Found by review: the closed form's message blamed Model(bodies=[...]) and the energies route,
    which the user never used; the recursive form named the link."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    links = [Link("a", None, "revolute", (0, 0, 1), q1, center=(0, -1, 0)),
             Link("b", "a", "revolute", (0, 0, 1), q2, offset=(0, -1, 0), center=(0, -1, 0))]
    with pytest.raises(ModelError, match="no link of its tree has a mass or an inertia"):
        derive_equations(Model("massless", [q1, q2], [], tree=links, gravity=(0, -9.81, 0), formulation="closed"))


@pytest.mark.parametrize("formulation", ["closed", "recursive"])
def test_a_jump_in_a_trees_potential_is_refused_where_it_is_compiled(formulation, tmp_path):
    """Found by review: compile_model derives a tree by its own route and skipped the energy-jump
    check derive_equations makes, and a recursive tree has no forcing to check: a wall of height 10
    at q1 = 0.5 (energy 0.5 cannot pass it, by hand) was crossed with status OK. Now both forms refuse
    it where they are derived and where they are compiled."""
    q1 = me.dynamicsymbols("q1")
    links = [Link("slider", None, "prismatic", (1, 0, 0), q1, mass=1.0)]
    model = Model("wall", [q1], [], tree=links, formulation=formulation,
                  potential_energy=sp.Piecewise((0, q1 < 0.5), (10, True)))
    for derive in (derive_equations, lambda m: compile_model(m, methods=("rk4",), cache_dir=tmp_path)):
        with pytest.raises(ModelError, match="potential energy jumps by 10 where q1 = 0.5"):
            derive(model)
