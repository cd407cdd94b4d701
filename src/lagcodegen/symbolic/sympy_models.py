"""Stage: sympy LagrangesMethod / KanesMethod / System / JointsMethod model -> EquationsOfMotion.

sympy has already derived ``M ud = F`` for these objects; this route renames their
dynamicsymbols to plain symbols and takes the kinematic equations from Kane's
``kindiffdict`` (qd = K(q, u, t)), so Kane's generalized speeds pass through unchanged, in any
number (a quaternion's four rates from three body rates).

Kane's dependent speeds: the unreduced equations of every speed (`_every_speed_independent`) and
the velocity constraints A u + b = 0, eliminated in C at every evaluation (the default,
``n_dependent``) or kept with multipliers (Model.formulation). Dependent coordinates are integrated
with the others and projected onto the configuration constraints when asked (``configuration``).
Auxiliary speeds are zero and stay out of the state, as in sympy's ``rhs``; the unknown forces of
its ``auxiliary_eqs`` become the ``reactions``.
"""
from __future__ import annotations

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

from ..model import TIME, Model, ModelError, check_symbols_declared, check_well_defined, input_name
from .equations import assemble, check_mass_matrix, input_symbols, make_substitution, plain_symbols, without_baumgarte
from .holonomic import BAUMGARTE_ALPHA, BAUMGARTE_BETA
from .kane_terms import dyadic_frames, kane_terms


def derive_from_sympy(model: Model):
    method = _formed_method(model.sympy_model)
    coords = tuple(method.q)
    auxiliary = tuple(getattr(method, "_uaux", ()))  # private: sympy 1.14 keeps Kane's auxiliary speeds there
    if isinstance(method, me.LagrangesMethod):
        _check_joint_speeds_are_rates(model.sympy_model, method)
        # private: sympy 1.14 keeps the Lagrangian only in _L
        check_well_defined("the sympy model's Lagrangian", sp.sympify(method._L))
        held = list(method._hol_coneqs)  # private: sympy 1.14 keeps the holonomic constraints only there
        for i, phi in enumerate(held):  # found by review: x - y' was taken as phi(q) with A missing y'
            rates = sorted(sp.sympify(phi).atoms(sp.Derivative), key=str)
            if rates:
                raise ModelError(f"holonomic constraint {i} of the LagrangesMethod ({phi}) contains speeds "
                                 f"{', '.join(map(str, rates))}: hol_coneqs are phi(q, t) = 0; a constraint on "
                                 "the velocities belongs in nonhol_coneqs")
        motion = list(method.coneqs)[len(held):]  # coneqs = (d/dt hol_coneqs, nonhol_coneqs)
        speeds = tuple(c.diff(TIME) for c in coords)
        kin_dynamic = sp.Matrix(speeds)
        route = "sympy LagrangesMethod"
        n_dependent, auxiliary_equations, dependent_coordinates, motion_rates, configuration = 0, None, (), None, None
    else:
        speeds = tuple(method.u)
        kindiff = method.kindiffdict()
        kin_dynamic = sp.Matrix([kindiff[c.diff(TIME)] for c in coords])
        route = "sympy KanesMethod (Kane)"
        motion = []
        auxiliary_equations = method.auxiliary_eqs if auxiliary else None
        dependent_coordinates = tuple(method._qdep)  # private: sympy 1.14 keeps them only there
        configuration = sp.Matrix(method._f_h) if dependent_coordinates else None
        n_dependent = len(method._udep)  # private: sympy 1.14 keeps the split of the speeds only there
        motion_rates = None
        if n_dependent:
            motion = list(method._k_nh * sp.Matrix(method.u) + method._f_nh)
            if method._k_dnh == method._k_nh:  # sympy's acceleration constraints A ud + f_dnh = 0: its own d/dt
                motion_rates = method._f_dnh
    _check_inputs_outside_constraints(model, [("holonomic constraint", held if isinstance(method, me.LagrangesMethod)
                                               else ()),
                                              ("velocity constraint", motion),
                                              ("configuration constraint",
                                               list(configuration) if configuration is not None else [])])
    q, u = plain_symbols(coords, speeds, model.parameters)
    exposed = ()
    if auxiliary:  # the unknown forces of the auxiliary equations, named if they reach the equations of motion
        known = set(coords) | set(speeds) | set(auxiliary) | {s.diff(TIME) for s in tuple(speeds) + auxiliary}
        exposed = tuple(me.find_dynamicsymbols(sp.Matrix(method.auxiliary_eqs)) - known - set(model.inputs))
        _check_reaction_names(model, exposed)
    renamed = make_substitution(coords, speeds, q, u, "sympy model", inputs=model.inputs, reactions=exposed)
    zero = {a: 0 for a in auxiliary} | {a.diff(TIME): 0 for a in auxiliary}
    if exposed and n_dependent:  # contact forces along the velocity constraints: the constraints hold them
        zero |= {f: 0 for f in _absorbed_reactions(method, exposed, kindiff)}

    rates = {} if isinstance(method, me.LagrangesMethod) else {c.diff(TIME): k for c, k in zip(coords, kin_dynamic)}

    def to_plain(expr, what):  # auxiliary speeds are zero in the equations of motion
        if what.startswith("measurement") and rates:  # a measurement may read q' (Kane's qd = K(q, u))
            expr = sp.sympify(expr).xreplace(rates)
        return renamed(sp.sympify(expr).xreplace(zero) if zero and expr is not None else expr, what)
    terms = None
    if isinstance(method, me.KanesMethod):
        inertias = _check_symmetric_inertias(method, model)
        plain_inputs = input_symbols(model.inputs)
        known = set(model.parameters) | set(plain_inputs) | set(q) | set(u) | {TIME}
        terms = kane_terms(method, kindiff, to_plain, motion, inputs=plain_inputs, known=known, inertias=inertias)
        if terms is None and n_dependent:
            method = _every_speed_independent(method, kindiff)
    qdot_table = rates
    n_u = len(speeds)
    if terms is not None:
        M, F = terms.mass_matrix, terms.forcing
        motion_rates = terms.motion_rates if motion else None
    else:  # Lagrange I: without lambda's columns
        M = to_plain(method.mass_matrix[:, :n_u].xreplace(qdot_table), "mass matrix")
        F = to_plain(method.forcing.xreplace(qdot_table), "forcing")
    K = to_plain(kin_dynamic, "kinematic equations")
    for what, matrix in (("mass matrix", M), ("forcing", F), ("kinematic equations", K)):
        for (i, j), entry in sorted(matrix.todok().items()):
            check_well_defined(f"the sympy model's {what}, entry ({i}, {j})", entry)
    T, V = _energies(method, model, to_plain)
    constraints = held if isinstance(method, me.LagrangesMethod) else ()
    if not motion:
        check_mass_matrix(M, coords, u, speeds)
    eom = assemble(model, coords, speeds, q, u, M, F, K, T, V, to_plain, constraints=constraints, motion=motion,
                   motion_rates=motion_rates)
    if motion:
        eom = _massless_speeds_regularized(eom)
        check_mass_matrix(eom.mass_matrix, coords, u, speeds)
        eom = _with_formulation(eom, model, n_dependent)
    if eom.m:  # assemble's " with ... constraints (Lagrange I)"
        route += eom.route[eom.route.index(" with "):]
    elif isinstance(method, me.LagrangesMethod):
        route += " (Lagrange II)"
    if auxiliary_equations is not None:
        eom = _with_reactions(eom, model, auxiliary_equations, coords, speeds, auxiliary, to_plain)
    if dependent_coordinates and eom.m and not eom.n_dependent:
        # found by review: a Kane four-bar with multipliers started 2 units off its loop closure and
        # drifted 0.04 in 200 s, status OK, no warning: its multipliers hold A u + b = 0 alone
        raise ModelError(f"model {model.name!r}: the configuration constraints of the KanesMethod (q_dependent: "
                         f"{', '.join(map(str, dependent_coordinates))}) are held only with the dependent speeds "
                         "eliminated (formulation='elimination', the default; it needs u_dependent= naming one "
                         "speed per velocity constraint, and velocity constraints free of inputs): its projection "
                         "and start check solve them; with multipliers nothing would hold f(q) = 0")
    if dependent_coordinates:
        from dataclasses import replace

        rows = sp.ImmutableMatrix(to_plain(configuration, "configuration constraints"))
        for i, row in enumerate(rows):  # a symbol only here reached the C printer unnamed
            check_symbols_declared(f"model {model.name!r}: the sympy model's configuration constraint {i}",
                                   row.free_symbols - set(model.parameters) - set(eom.q) - {TIME}, model.parameters)
        eom = replace(eom, configuration=rows,
                      dependent_coordinates=tuple(coords.index(c) for c in dependent_coordinates))
    return _with_route(eom, route)


def _absorbed_reactions(method, exposed, kindiff) -> list:
    """The unknown forces whose generalized forces on the model's speeds are a combination of the
    velocity constraints' rows, c = A^T mu (a contact force at a point that rolls or slides without
    sideslip): the elimination removes them (C^T A^T = 0) and the multipliers take them in, so the
    equations of motion may leave them out, as sympy's reduced forcing does (found by review: a
    Chaplygin sleigh and a rolling disc with dependent speeds and auxiliary contact forces were
    refused). Tested in numbers at random configurations and parameter values; a force that fails
    at any of them stays, and the route refuses it by name."""
    import random

    frame, speeds = method._inertial, list(method.u)  # private: sympy 1.14 keeps the inertial frame only there
    A = sp.Matrix(method._k_nh)  # private: the velocity constraints' A in A u + b = 0, only there
    coefficients = {f: [sp.S.Zero] * len(speeds) for f in exposed}
    for load in method.loads or ():
        where, vector = load[0], load[1]
        velocity = where.ang_vel_in(frame) if isinstance(where, me.ReferenceFrame) else where.vel(frame)
        partials = me.partial_velocity([velocity.subs(kindiff)], speeds, frame)[0]
        for f in exposed:
            direction = vector.diff(f, frame, var_in_dcm=False)
            for r, partial in enumerate(partials):
                coefficients[f][r] += partial.dot(direction)
    rows = [sp.Matrix(c) for c in coefficients.values()]
    if any(m.has(*_NOT_ANALYTIC) for m in [A, *rows]):
        # samples in a box prove an identity only for analytic functions (found by review: a drag
        # -mu f Heaviside(x - 2) B.x looked held by the blade at every sample and was dropped for x > 2)
        return []
    unknowns = set().union(A.free_symbols, *(c.free_symbols for c in rows), me.find_dynamicsymbols(A),
                           *(me.find_dynamicsymbols(c) for c in rows))
    generator = random.Random(0)
    absorbed = []
    for f, c in zip(coefficients, rows):
        held, tested = True, 0
        for _ in range(40):  # 4 samples where every entry is a finite real number
            sample = {v: sp.Float(generator.uniform(-2.0, 2.0)) for v in unknowns}
            try:
                A_n = np.array(A.xreplace(sample).evalf(), dtype=float)
                c_n = np.array(c.xreplace(sample).evalf(), dtype=float).ravel()
            except (TypeError, ValueError):  # complex there (found by review: sqrt(R**2 - x**2) at x > R)
                continue
            if not (np.all(np.isfinite(A_n)) and np.all(np.isfinite(c_n))):
                continue
            mu = np.linalg.lstsq(A_n.T, c_n, rcond=None)[0]
            if not np.linalg.norm(A_n.T @ mu - c_n) <= 1e-10 * max(np.linalg.norm(c_n), 1e-300):
                held = False
                break
            tested += 1
            if tested == 4:
                break
        if held and tested == 4:
            absorbed.append(f)
    return absorbed


#: functions that are not analytic: a coefficient that holds one is never taken as identically held
_NOT_ANALYTIC = (sp.Piecewise, sp.Heaviside, sp.Abs, sp.sign, sp.Max, sp.Min, sp.floor, sp.ceiling, sp.frac,
                 sp.Mod, sp.DiracDelta, sp.re, sp.im)


def _check_reaction_names(model: Model, exposed) -> None:
    """A ModelError when an unknown force of the auxiliary equations bears a parameter's or an
    input's name: renamed to a plain symbol it became that parameter, and the reactions were
    dropped without a word (found by review: a tension T(t) beside a damping constant T)."""
    taken = {p.name: "a parameter" for p in model.parameters} | {input_name(r): "an input" for r in model.inputs}
    for force in sorted(exposed, key=str):
        name = force.func.__name__ if hasattr(force, "func") else str(force)
        if name in taken:
            raise ModelError(f"model {model.name!r}: name {name!r} is used by {taken[name]} and by the reaction "
                             f"{force} that Kane's auxiliary equations expose; rename one of them")


def _check_inputs_outside_constraints(model: Model, groups) -> None:
    """A ModelError naming the first input in a constraint: its rate would enter the constraint's
    derivatives, which are formed with the input held constant (an input in a LagrangesMethod's
    hol_coneqs was taken as a constant there, and the C then failed to compile)."""
    inputs = set(model.inputs)
    for what, rows in groups:
        for i, row in enumerate(rows):
            found = sorted(inputs & (me.find_dynamicsymbols(sp.sympify(row)) | sp.sympify(row).free_symbols), key=str)
            if found:
                raise ModelError(f"input {input_name(found[0])!r} appears in the sympy model's {what} {i}: inputs "
                                 "may drive the loads only, not constraints (the constraint's derivatives would "
                                 "hold the input's rate)")


def _with_reactions(eom, model: Model, equations, coords, speeds, auxiliary, to_plain):
    """The unknown forces of Kane's auxiliary equations (Fr + Fr* of the auxiliary speeds = 0, linear
    in them): every symbol there that is not a parameter, input, coordinate, speed or acceleration."""
    from dataclasses import replace

    accelerations = tuple(sp.Symbol(f"{u.name}_dot") for u in eom.u)
    known = set(coords) | set(speeds) | set(auxiliary) | {s.diff(TIME) for s in speeds + tuple(auxiliary)}
    unknown_functions = sorted(me.find_dynamicsymbols(equations) - known - set(model.inputs), key=str)
    plain = {f: sp.Symbol(f.func.__name__) for f in unknown_functions}
    rates = dict(zip((s.diff(TIME) for s in speeds), accelerations))
    rows = to_plain(sp.Matrix(equations).xreplace(rates).xreplace(plain), "auxiliary equations")
    declared = set(eom.parameters) | set(eom.inputs) | set(eom.q) | set(eom.u) | set(accelerations) | {eom.t}
    unknowns = tuple(sorted(rows.free_symbols - declared, key=str))
    if not unknowns:
        return eom
    if len(unknowns) != rows.rows:
        raise ModelError(f"model {model.name!r}: Kane's {rows.rows} auxiliary equations hold {len(unknowns)} unknown "
                         f"forces ({', '.join(map(str, unknowns))}): every symbol there that is not a declared "
                         "parameter, input, coordinate or speed is taken for one (declare a parameter that is among "
                         "them in Model(..., parameters=[...])); the reactions need as many equations as unknowns "
                         "(one auxiliary speed per force component)")
    for i, row in enumerate(rows):
        for force in unknowns:
            if row.diff(force).has(*unknowns):
                raise ModelError(f"model {model.name!r}: auxiliary equation {i} is not linear in the unknown "
                                 f"force {force}")
    return replace(eom, reactions=unknowns, reaction_equations=sp.ImmutableMatrix(rows),
                   reaction_accelerations=accelerations)


def _check_symmetric_inertias(method, model: Model) -> dict:
    """A rigid body's inertia dyadic with a product of inertia written on one side only
    (``Ixz*(B.x|B.z)`` without ``B.z|B.x``) gives Kane's equations a mass matrix that is not
    symmetric, which no factorization of M reads as written. Returns {body: (frame, its central
    inertia's matrix in that frame)}, which `kane_terms` takes instead of forming them again."""
    matrices = {}
    for body in method.bodies or ():
        if not isinstance(body, me.RigidBody):
            continue
        frames = dyadic_frames(body.central_inertia) or [body.frame]
        try:
            I = body.central_inertia.to_matrix(frames[0])
        except ValueError:  # terms in frames with no orientation between them: sympy's own equations tell
            continue
        matrices[body] = (frames[0], I)
        for i in range(3):
            for j in range(i + 1, 3):
                if sp.expand(I[i, j] - I[j, i]) != 0:
                    raise ModelError(f"model {model.name!r}: the inertia of rigid body {body} is not symmetric: in "
                                     f"frame {frames[0]}, entry ({i}, {j}) is {I[i, j]} and entry ({j}, {i}) is "
                                     f"{I[j, i]}; write each product of inertia on both sides, as "
                                     "sympy.physics.mechanics.inertia() does")
    return matrices


def _every_speed_independent(method, kindiff):
    """The KanesMethod of the same bodies, loads and kinematic equations with every speed
    independent: its M (n_u x n_u, symmetric) and F are the unreduced Kane equations, to which the
    velocity constraints A u + b = 0 return as multipliers, M ud = F - A^T lam (the reduced
    equations sympy forms are their projection onto the independent speeds, so both agree)."""
    kd = [c.diff(TIME) - kindiff[c.diff(TIME)] for c in method.q]
    unreduced = me.KanesMethod(method._inertial, q_ind=list(method.q), u_ind=list(method.u), kd_eqs=kd,
                               bodies=method.bodies, forcelist=method.loads)
    unreduced.kanes_equations(method.bodies, method.loads)
    return unreduced


def _with_formulation(eom, model: Model, n_dependent: int):
    """Kane's dependent speeds eliminated (the default) or kept with multipliers (Model.formulation)."""
    from dataclasses import replace

    if model.formulation == "multipliers":
        return eom
    held = sorted({str(r) for r in eom.inputs if eom.constraint_jacobian.has(r) or eom.constraint_rate.has(r)})
    obstacle = None
    if n_dependent != eom.m or eom.n_holonomic:
        obstacle = "it has no dependent speeds (KanesMethod u_dependent=) for its velocity constraints"
    elif held:
        obstacle = f"its velocity constraints read the input(s) {', '.join(held)}"
    if obstacle is None:  # no Baumgarte terms (see without_baumgarte): M + A^T A regularized F holds gamma too
        baumgarte = {BAUMGARTE_ALPHA, BAUMGARTE_BETA}
        return replace(eom, n_dependent=n_dependent, forcing=without_baumgarte(eom.forcing),
                       constraint_bias=without_baumgarte(eom.constraint_bias),
                       parameters=tuple(p for p in eom.parameters if p not in baumgarte),
                       parameter_values={p: v for p, v in eom.parameter_values.items() if p not in baumgarte},
                       route=eom.route.replace("(Lagrange I)", "(dependent speeds eliminated, Kane)"))
    if model.formulation == "elimination":
        raise ModelError(f"model {model.name!r}: formulation 'elimination' is not possible: {obstacle}; "
                         "use formulation='multipliers'")
    return eom


def _massless_speeds_regularized(eom):
    """Unreduced Kane equations whose M is singular because a dependent speed carries no mass (a
    contact point's velocity): M + A^T A and F + A^T gamma in their place. The constrained solution
    is the same, since A ud = gamma gives A^T A ud = A^T gamma, and M + A^T A is positive definite
    whenever M is on the null space of A (the reduced mass matrix sympy inverts)."""
    from dataclasses import replace

    M, A = eom.mass_matrix, eom.constraint_jacobian
    massless = [j for j in range(M.rows) if M[j, j] == 0 and any(A[i, j] != 0 for i in range(A.rows))]
    if not massless:
        return eom
    return replace(eom, mass_matrix=sp.ImmutableMatrix(M + A.T * A),
                   forcing=sp.ImmutableMatrix(eom.forcing + A.T * eom.constraint_bias),
                   route=eom.route + f" (massless dependent speeds {', '.join(str(eom.u[j]) for j in massless)}: "
                                     "M + A^T A, F + A^T gamma)")


def _check_joint_speeds_are_rates(obj, method) -> None:
    """A ModelError when joints (of a JointsMethod or System formed with LagrangesMethod) have speeds
    other than their coordinates' rates: LagrangesMethod writes its equations in the rates and leaves
    the joints' speeds in them, undefined (found by review: b1(t) was called a specified function of
    time, to be listed in inputs=, which would have compiled a different model)."""
    joints = getattr(obj, "joints", None) or ()
    rates = {c.diff(TIME) for c in method.q}
    left = me.find_dynamicsymbols(sp.Matrix(method.forcing)) | me.find_dynamicsymbols(sp.Matrix(method.mass_matrix))
    stray = sorted((s for joint in joints for s in joint.speeds if s not in rates and s in left), key=str)
    if stray:
        raise ModelError(f"the joints' speeds {', '.join(map(str, stray))} are not the rates of their coordinates, "
                         "and a LagrangesMethod leaves them in its equations undefined; form the equations with "
                         "KanesMethod (form_eoms() without an argument), or give each joint speeds equal to its "
                         "coordinates' rates (the joints' default)")


def _formed_method(obj):
    """The LagrangesMethod or KanesMethod behind ``obj``, with its equations formed."""
    if isinstance(obj, me.JointsMethod):
        if obj.method is None:
            obj.form_eoms()
        obj = obj.method
    if isinstance(obj, me.System):
        if obj.eom_method is None:
            obj.form_eoms()
        obj = obj.eom_method
    if isinstance(obj, me.LagrangesMethod):
        if obj.eom is None:
            obj.form_lagranges_equations()
        return obj
    if isinstance(obj, me.KanesMethod):
        if obj._fr is None:
            if not obj.bodies:
                raise ModelError("KanesMethod has no bodies: call kanes_equations(bodies, loads) "
                                 "or pass bodies= to KanesMethod")
            obj.kanes_equations(obj.bodies, obj.loads)
        return obj
    raise ModelError(f"sympy_model must be a LagrangesMethod, KanesMethod, System or JointsMethod, got "
                     f"{type(obj).__name__}")


def _energies(method, model: Model, to_plain):
    """(T, V): a LagrangesMethod's from its bodies, else from L = T - V split at u = 0 where that
    split is T and -V, or Kane's from its bodies; (None, None) when they cannot be told apart."""
    if isinstance(method, me.LagrangesMethod):
        lagrangian = method._L[0] if isinstance(method._L, sp.MatrixBase) else method._L
        L = to_plain(lagrangian, "Lagrangian")
        extra = to_plain(model.potential_energy, "potential energy")
        frame = getattr(method, "inertial", None) or model.frame
        bodies = getattr(method, "_bodies", None) or ()
        rest = to_plain(sp.Matrix([c.diff(TIME) for c in method.q]), "speeds")
        if bodies and frame is not None:
            T = to_plain(me.kinetic_energy(frame, *bodies), "kinetic energy")
            # V = T - L only when L's kinetic energy is the bodies' (found by review: a rotor inertia
            # written into L, or bodies= listing some of the bodies, put a speed into V, status OK)
            if not _reads_speeds(T - L, list(rest)):
                return T, T - L + extra
        at_rest = L.xreplace({s: 0 for s in rest})
        # a moving frame or support gives T terms of degree 1 and 0 in the speeds; the split at u = 0
        # would move the latter into V with the wrong sign (found by review: a particle seen from a
        # turning frame had T = -1.5, V = -1.5 for 0.5 and 0.5): no energy then
        zero = {s: 0 for s in rest}
        if any(L.diff(s).xreplace(zero) != 0 for s in rest) or TIME in at_rest.free_symbols:
            return None, None
        return L - at_rest, -at_rest + extra
    bodies = method.bodies or ()
    if not bodies or model.frame is None:
        return None, None
    T = to_plain(me.kinetic_energy(model.frame, *bodies).xreplace(method.kindiffdict()), "kinetic energy")
    V = to_plain(sum((b.potential_energy for b in bodies), sp.S.Zero) + model.potential_energy,
                 "potential energy")
    return T, V


def _reads_speeds(expr, speeds: list) -> bool:
    """Does ``expr`` change with the speeds? Numerically, at seeded random values of everything else
    (the difference T - L of sympy's expressions need not simplify to a speed-free form)."""
    import numpy as np

    others = sorted(sp.sympify(expr).free_symbols - set(speeds), key=str)
    rng = np.random.default_rng(20261126)
    try:
        f = sp.lambdify(others + speeds, expr, "numpy")
        for _ in range(3):
            point = list(rng.uniform(0.3, 1.3, len(others)))
            with np.errstate(all="ignore"):
                a, b = (complex(f(*point, *rng.uniform(-2.0, 2.0, len(speeds)))) for _ in range(2))
            if abs(a - b) > 1e-9 * (1.0 + abs(a) + abs(b)):
                return True
    except (TypeError, ValueError, ArithmeticError, NameError):  # not evaluable there: take it as reading them
        return True
    return False


def _with_route(eom, route: str):
    from dataclasses import replace
    return replace(eom, route=route)
