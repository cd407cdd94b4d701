"""Helper: the template context of the integrators (coefficient tables, step functions, driver).

Explicit Runge-Kutta methods run one generic stepper, implicit ones one simplified-Newton
stepper, both reading the Butcher coefficients emitted as ``static const`` arrays; symplectic
Euler has its own template code. See ``templates/steppers.c.j2``.
"""
from __future__ import annotations

from .csyntax import EmitError
from .csyntax import literal as _literal
from .csyntax import record as _record

#: simplified-Newton stopping rule of the implicit steppers: max |dW| / (1 + |x|) per precision
NEWTON_TOLERANCE = {"double": 1e-13, "float": 1e-5}
#: a Newton increment that no longer shrinks (ratio >= NEWTON_STALL to the previous one) and is below
#: NEWTON_FLOOR has reached the rounding of f: accepted (a stiff spring's stays above the tolerance).
#: Not in float, whose tolerance is already 84 eps: there a stall above it was as often an iteration
#: that converges slowly or not at all (a review found errors of 3e-3 accepted at a floor of 1e-4)
NEWTON_STALL = 0.9
NEWTON_FLOOR = {"double": 1e-9, "float": NEWTON_TOLERANCE["float"]}
NEWTON_MAX_ITERATIONS = 30
#: symplectic Euler's velocity solve is a fixed-point iteration v <- M^-1 (p + h G(q, v)), contracting
#: by about h |d ud/du| per sweep: it may take this many sweeps while each shrinks the change below
#: SWEEP_CONTRACTION of the previous one (found by review: damping with h c/m = 0.4 needs 33 sweeps,
#: and 30 failed it at step 1)
SWEEP_MAX_ITERATIONS = 300
SWEEP_CONTRACTION = 0.95
#: the contraction h |d ud/du| from which the drivers' pre-check warns: 0.8^140 is 1e-14, near the budget
SWEEP_WARN = 0.8
#: ... and a stalled iteration is accepted only when the stage equations' residual is within this
#: many units of rounding of the terms of f at the stages (h sum |a_ij| sum |J_ml| |X_jl| + |W_im|)
NEWTON_NOISE = {"double": 1e3 * 2.0 ** -52, "float": 1e3 * 2.0 ** -23}

#: The drivers' singularity monitor (``<prefix>_gauge_check`` in templates/steppers.c.j2) reads the
#: pivots the solves already produce at each accepted state: the LDL^T pivots of M and, with
#: constraints, the Cholesky pivots of A M^-1 A^T. A pivot that changes by more than PIVOT_JUMP
#: (either way) between two accepted states means the step jumped across, or onto, a singular
#: configuration it did not resolve: in normal runs of the catalog models a pivot changes by at most
#: 1.7x per step (slider_crank_minimal spinning up at h = 1e-3; tests/numeric/test_singular_crossing.py).
PIVOT_JUMP = 1e2
#: ... and a pivot below PIVOT_COLLAPSE times its value at the run's first state is a singular
#: configuration approached slowly (the landing check of the solves only asks for pivots > 0).
PIVOT_COLLAPSE = {"double": 1e-8, "float": 1e-4}
#: ... and (dependent speeds eliminated) a det(A_D) that changes by more than DEPENDENT_JUMP in one
#: step is a singular A_D the step does not resolve: the dependent speeds scale with 1/det(A_D), and
#: a fixed step near det(A_D) = 0 can turn back short of it (no sign change) with a wrong answer.
#: sympy's non-minimal Kane pendulum (u1 = -u2 q2/q1) at h = 1e-2 from 300 random starts: a
#: relative energy error above 1e-4 with status OK in 49 runs; with a 2x test 1 (error 3e-4),
#: with 4x 3. The explicit steps apply it to every later stage against x too (`_explicit_stage_lines`):
#: a step can come back from the singular A_D to x's side (tests/constraints/test_dependent_singularity.py).
DEPENDENT_JUMP = 2.0


#: a dynamics kernel this small (ops after CSE) is inlined into every explicit Runge-Kutta stage,
#: so that gcc keeps the stage values in registers: with the steppers' local parameter copy, the
#: double pendulum's RK4 step took 126 ns instead of 139 (dopri5 192 instead of 216; C harness).
#: Larger kernels stay calls: every inlined copy costs compile time, and there are ~20 call sites.
HOT_DYNAMICS_MAX_OPS = 100

#: a dynamics kernel this large (ops after CSE) is compiled once in the two-part build (in part 2;
#: part 1's steppers call it), not once in each part: its compile is most of a cold build. The
#: Whipple bicycle (about 1300 operations): part 1 took 0.36 s of CPU instead of 0.9, part 2 0.95
#: instead of 0.75 (the kernel no longer inlined into rhs with gauge NULL), the build 1.37 s
#: instead of 1.44 (medians of 8 in turn) on two cores; the RK4 step the same (C harness, best of
#: 20 rounds: 1573 against 1584 ns) and the results the same bits (tests).
SHARED_DYNAMICS_MIN_OPS = 500


def shared_dynamics(system) -> bool:
    """True when the dynamics kernel is defined once for both parts of the build (LCG_SHARED); a
    kernel small enough to be inlined (`hot_dynamics`) never is."""
    return not system.recursive and not hot_dynamics(system) and \
        system.kernel("dynamics").ops_after >= SHARED_DYNAMICS_MIN_OPS


def hot_dynamics(system) -> bool:
    """True when the explicit steppers call an always-inlined copy of the dynamics kernel."""
    return not system.n_constraints and not system.u_dependent and \
        system.kernel("dynamics").ops_after <= HOT_DYNAMICS_MAX_OPS


def stepper_context(system, names, real: str, methods: list) -> dict:
    """Template context of the integrators: coefficient tables, step functions, the driver."""
    from ..integrators.schemes import KIND_EXPLICIT, KIND_IMPLICIT, get_scheme

    n, prefix = len(system.u), names.prefix  # n: speeds, the size of M
    N, G = len(system.q) + n, gauge_size(system)
    points = len(system.point_names) if "points" in system.outputs else 0
    context = {"has_steppers": bool(methods), "tableaux": [], "methods": [], "exported": [],
               "explicit_steppers": [],
               "has_explicit": False, "has_implicit": False, "has_symplectic_euler": False,
               "identity_kinematics": system.kinematics_identity, "zero": _literal(0, real),
               "one": _literal(1, real), "fsuffix": "f" if real == "float" else "",
               "newton_tolerance": _literal(NEWTON_TOLERANCE[real], real), "newton_max": NEWTON_MAX_ITERATIONS,
               "sweep_max": SWEEP_MAX_ITERATIONS, "sweep_contraction": _literal(SWEEP_CONTRACTION, real),
               "newton_stall": _literal(NEWTON_STALL, real), "newton_floor": _literal(NEWTON_FLOOR[real], real),
               "newton_noise": _literal(NEWTON_NOISE[real], real),
               "n_state_squared": N * N, "n_squared": n * n, "se_work": 3 * n * n + 5 * n + N,
               "has_energy": "energy" in system.outputs, "has_points": points > 0,
               "n_point_values": 3 * points, "work_size": N, "method_rows": [], "gauge_size": G,
               "pivot_jump": _literal(PIVOT_JUMP, real), "pivot_collapse": _literal(PIVOT_COLLAPSE[real], real),
               "pivot_jump_text": f"{PIVOT_JUMP:g}",
               "dependent_jump": _literal(DEPENDENT_JUMP, real), "dependent_jump_text": f"{DEPENDENT_JUMP:g}",
               "pivot_collapse_text": f"{PIVOT_COLLAPSE[real]:.0e}".replace("e-0", "e-"),
               "n_pivots": n + system.n_constraints, "has_dependent": bool(system.u_dependent),
               "step_jacobians": []} | input_context(system, names, real)
    if "step_jacobian" in system.outputs and not any(get_scheme(m).stepper == KIND_EXPLICIT for m in methods):
        # found by review: emitted without one, the output was silently left out
        raise EmitError("output 'step_jacobian' is the Jacobian of an explicit step: add an explicit method "
                        f"(e.g. rk4) to methods ({', '.join(methods) if methods else 'none given'})")
    if not methods:
        return context
    if "rhs" not in system.outputs and "accel" not in system.outputs:
        raise EmitError("integrators need the 'rhs' output; add it to outputs")
    held, ramped = ("r, 0, ", "r, dr, ") if system.inputs else ("", "")
    foh = []
    for number, name in enumerate(dict.fromkeys(methods)):
        scheme = get_scheme(name)
        kind = scheme.stepper
        for output in scheme.outputs:
            if output not in system.outputs:
                raise EmitError(f"method {name!r} needs the {output!r} output; add it to outputs")
        # part (LCG_BUILD_PART): explicit steppers compile beside the drivers, the others apart
        record = {"name": scheme.name, "id": number, "title": scheme.title or scheme.name, "order": scheme.order,
                  "part": 1 if kind == KIND_EXPLICIT else 2, "explicit": kind == KIND_EXPLICIT}
        if kind == KIND_EXPLICIT:
            context["tableaux"].append(_tableau_record(scheme, real))
            record["work"] = (scheme.stages + 1) * N + G
            tail = record["gauge_offset"] = record["work"] - G
            record["call"] = f"{prefix}_{scheme.name}_step(*t, x, {held}p, h, work, work + {tail})"
            record["call_in_driver"] = f"{prefix}_{scheme.name}_step(t, x, {ramped}p, h, scratch, scratch + {tail})"
            dynamics = f"{prefix}_dynamics_hot" if hot_dynamics(system) else f"{prefix}_dynamics"
            context["explicit_steppers"].append(
                {"name": scheme.name, "title": scheme.title or scheme.name, "order": scheme.order,
                 "stages": scheme.stages,
                 "lines": _explicit_stage_lines(scheme, prefix, len(system.q), N, dynamics, bool(system.inputs),
                                                G - 1 if system.u_dependent else None)})
        elif kind == KIND_IMPLICIT:
            context["tableaux"].append(_tableau_record(scheme, real))
            s = scheme.stages
            arrays = f"{prefix}_{scheme.name}_a, {prefix}_{scheme.name}_b, {prefix}_{scheme.name}_c"
            record["work"] = 3 * s * N + (s * N) ** 2 + N * N + N + G
            tail = record["gauge_offset"] = record["work"] - G
            record["call"] = f"{prefix}_irk_step({s}, {arrays}, *t, x, {held}p, h, work, work + {tail})"
            record["call_in_driver"] = _exported_call(prefix, scheme.name, bool(system.inputs))
            context["has_implicit"] = True
        else:
            record["work"] = 3 * n * n + 5 * n + N + G
            tail = record["gauge_offset"] = record["work"] - G
            record["call"] = f"{prefix}_symplectic_euler_step(*t, x, {held}p, h, work, work + {tail})"
            record["call_in_driver"] = _exported_call(prefix, scheme.name, bool(system.inputs))
            context["has_symplectic_euler"] = True
        context["methods"].append(record)
        context["method_rows"].append({"macro": f"{prefix.upper()}_METHOD_{scheme.name.upper()}", "id": number,
                                       "work_macro": f"{prefix.upper()}_WORK_{scheme.name.upper()}",
                                       "work": record["work"]})
        held_doc = " with the inputs r held over the step (zero-order hold)" if system.inputs else ""
        context["exported"].append(_record(
            "int", f"{prefix}_step_{scheme.name}",
            f"{real} *t, {real} *x, {context['r_param']}const {real} *p, {real} h, {real} *work",
            f"One step of {record['title']} (order {scheme.order}){held_doc}; work holds {record['work']} values, "
            f"the last {G} receive the pivots (gauge) of the state x it started from.", []))
        if system.inputs:
            held_stages = "each stage at its own time" if kind in (KIND_EXPLICIT, KIND_IMPLICIT) else \
                "symplectic Euler holds r0"
            foh.append(_record(
                "int", f"{prefix}_step_{scheme.name}_foh",
                f"{real} *t, {real} *x, const {real} *r0, const {real} *r1, const {real} *p, {real} h, {real} *work",
                f"One step of {record['title']} with the inputs on the line from r0 at t to r1 at t + h "
                f"(first-order hold; {held_stages}); "
                f"work as for {prefix}_step_{scheme.name}.", []))
    context["work_size"] = N + 2 * G + max(m["work"] for m in context["methods"])
    driven = ""
    if system.inputs:
        driven = (f"{prefix}_input_fn inputs, void *context, int hold, {real} *r_out, ")
    if system.measurements:
        driven += f"{real} *y_out, "
    driver = _record("int", f"{prefix}_simulate",
                     f"int method, {real} t0, const {real} *x0, const {real} *p, {real} h, "
                     f"long n_steps, long stride, int project, {driven}{real} *t_out, {real} *x_out, "
                     f"{real} *energy_out, {real} *points_out, {real} *residuals_out, {real} *multipliers_out, "
                     f"{real} *work, long *steps_done",
                     "Fixed-step integration loop from (t0, x0), n_steps steps of size h, keeping every "
                     f"stride-th state: n_steps / stride + 1 samples of t_out (1), x_out ({N}), energy_out (1), "
                     f"points_out ({3 * points}), "
                     + (f"residuals_out ({2 * system.n_constraints}: phi, then A u + dphi/dt) and multipliers_out "
                        f"({system.n_constraints + n}: lam, then Q = A^T lam) each, any of the last four"
                        if system.n_constraints else "residuals_out and multipliers_out (none: no constraints "
                        "with multipliers) each, any of the last four")
                     + " NULL to skip (written only where the kernel has them); work: "
                     f"{prefix.upper()}_WORK_SIZE values; returns a status code (*steps_done: the steps "
                     "completed)." + _driven_driver_doc(system, prefix), [])
    context["exported"] += foh
    context |= _step_jacobian_context(system, context, prefix, real, methods)
    if system.inputs:
        context["exported"].append(_record(
            "int", f"{prefix}_table_inputs", f"void *context, {real} t, const {real} *x, {real} *r",
            f"An input function ({prefix}_input_fn) interpolating linearly in the {prefix}_input_table "
            "that context points to.", []))
    context["explicit_ids"] = [m["id"] for m in context["methods"] if m["explicit"]]
    context["simulate_decl"] = driver["decl"]
    context["exported"].append(driver)
    held = f"const {real} *r, const {real} *r1, " if system.inputs else ""
    monitored = _record("int", f"{prefix}_step_monitored",
                        f"int method, {real} t, {real} *x, {held}const {real} *p, {real} h, {real} *work, int first, "
                        "int judge_only",
                        "One step of the method numbered `method` under the singularity monitor of "
                        f"{prefix}_simulate, for a caller's own loop (work: {prefix.upper()}_WORK_SIZE values, "
                        "kept between calls; first: 1 after the state or parameters were set; a failed step leaves "
                        "x as it was; judge_only: judge x, the last state reached, and leave it as it is)"
                        + ("; r1 NULL holds r over the step" if system.inputs else "") + "; returns a status code.",
                        [])
    context["step_monitored_decl"] = monitored["decl"]
    context["exported"].append(monitored)
    tables = summaries = ""
    if system.inputs:
        tables = f"const {real} *input_t, const {real} *input_r, long n_knots, int hold, "
    if system.measurements:
        summaries = f"{real} *y_final, {real} *y_min, {real} *y_max, "
    sweep = _record("void", f"{prefix}_sweep",
                    f"int method, long n_members, const {real} *x0s, const {real} *ps, {tables}{real} t0, "
                    f"{real} h, long n_steps, long stride, int project, int track_energy, {summaries}{real} *x_final, "
                    f"{real} *q_max, {real} *energy_error, int *status, long *steps_done, {real} *traj, {real} *work",
                    "Many independent members, one after another: member m from x0s + m * "
                    f"{N} with ps + m * {max(1, len(system.free_parameters))}, its results at x_final + m * {N}, "
                    f"q_max + m * {len(system.q)}, energy_error[m], status[m], steps_done[m] and (traj not NULL) "
                    f"traj + m * (n_steps / stride + 1) * {N}; work: {prefix.upper()}_WORK_SIZE values."
                    + _driven_sweep_doc(system), [])
    context["sweep_decl"] = sweep["decl"]
    context["n_params_or_one"] = max(1, len(system.free_parameters))
    context["can_project"] = "constraints" in system.outputs or "configuration" in system.outputs
    context["records_constraints"] = "constraints" in system.outputs
    context["records_multipliers"] = "multipliers" in system.outputs
    context["exported"].append(sweep)
    return context


def _driven_driver_doc(system, prefix: str) -> str:
    """The simulate prototype's words on its inputs and measurements (found by review: the header
    left inputs, context, hold, r_out and y_out undocumented)."""
    text = ""
    if system.inputs:
        text += (f" The {len(system.inputs)} inputs come from inputs(context, t, x, r) (not NULL; "
                 f"{prefix}_table_inputs with context a {prefix}_input_table interpolates a table), read at each "
                 "step's start and held over the step (hold = 0), or with hold = 1 also at the step's end, the "
                 "stages taking them on the line between (first-order hold, for inputs of t only); r_out (or "
                 f"NULL) receives them at each kept sample, {len(system.inputs)} each.")
    if system.measurements:
        text += (f" y_out (or NULL) receives the {len(system.measurements)} measurements at each kept sample.")
    return text


def _driven_sweep_doc(system) -> str:
    """The sweep prototype's words on its input tables and measurement summaries."""
    text = ""
    n_r, n_y = len(system.inputs), len(system.measurements)
    if n_r:
        text += (" Member m's inputs interpolate its own table of n_knots knots (times input_t + m * n_knots, "
                 f"values input_r + m * n_knots * {n_r}), hold as in simulate.")
    if n_y:
        text += (f" y_final, y_min and y_max + m * {n_y} (required) receive member m's {n_y} measurements at "
                 "its end and their least and largest values over its samples (a NaN sample sticks).")
    return text


def _step_jacobian_context(system, context: dict, prefix: str, real: str, methods) -> dict:
    """The step Jacobians dx+/dx (and dx+/dr) of the explicit methods, when the step_jacobian
    output is asked for: one exported function per method over one generic C routine."""
    from ..integrators.schemes import KIND_EXPLICIT, get_scheme

    if "step_jacobian" not in system.outputs:
        return {"step_jacobians": []}
    n_r = len(system.inputs)
    N = len(system.q) + len(system.u)
    rows = []
    for name in dict.fromkeys(methods):
        scheme = get_scheme(name)
        if scheme.stepper != KIND_EXPLICIT:
            continue
        s = scheme.stages
        work = s * N + N + s * N * (N + n_r) + N * N + N * n_r + N * (N + n_r)
        inputs = f"const {real} *r, " if n_r else ""
        matrices = f"{real} *Fx, {real} *Fr" if n_r else f"{real} *Fx"
        record = _record(
            "int", f"{prefix}_step_jacobian_{scheme.name}",
            f"{real} *t, {real} *x, {inputs}const {real} *p, {real} h, {matrices}, {real} *work",
            f"One step of {scheme.title or scheme.name} as {prefix}_step_{scheme.name}, also writing its exact "
            f"Jacobians Fx = dx+/dx (row-major {N} x {N})"
            + (f" and Fr = dx+/dr ({N} x {n_r}, the inputs held)" if n_r else "")
            + f"; work holds {work} values. As the step, LCG_BAD_ARGUMENT for a t or h that is not finite and "
            "LCG_NONFINITE_STATE for a new state or Jacobian that is not finite; a failed step leaves t and x as "
            "they were.", [])
        context["exported"].append(record)
        rows.append({"name": scheme.name, "stages": s, "work": work,
                     "work_macro": f"{prefix.upper()}_WORK_JACOBIAN_{scheme.name.upper()}"})
    return {"step_jacobians": rows, "n_jacobian_columns": N + n_r}


def _exported_call(prefix: str, name: str, driven: bool) -> str:
    """The driver's call of a step compiled apart from it (implicit, symplectic Euler), through its
    exported function (the first-order-hold one when the driver passes r1)."""
    if not driven:
        return f"{prefix}_step_{name}(&step_t, x, p, h, scratch)"
    return (f"r1 ? {prefix}_step_{name}_foh(&step_t, x, r, r1, p, h, scratch) "
            f": {prefix}_step_{name}(&step_t, x, r, p, h, scratch)")


def gauge_size(system) -> int:
    """Values of one singularity gauge: the n pivots of M (n speeds), then (constrained) the m pivots
    of A M^-1 A^T and the m x n constraint Jacobian A (its orientation between steps), or (dependent
    speeds eliminated) det(A_D), whose sign changes where the step crossed a singular A_D."""
    n, m = len(system.u), system.n_constraints
    return n + m + m * n + (1 if system.u_dependent else 0)


def _tableau_record(scheme, real: str) -> dict:
    s = scheme.stages
    value = (lambda v: _literal(float(v), real))
    rows = [{"entries": ", ".join(value(v) for v in row), "comment": ", ".join(str(v) for v in row)}
            for row in scheme.a]
    return {"name": scheme.name, "title": scheme.title or scheme.name, "order": scheme.order, "stages": s,
            "stages_squared": s * s, "a_rows": rows,
            "b_values": ", ".join(value(v) for v in scheme.b), "b_comment": ", ".join(map(str, scheme.b)),
            "c_values": ", ".join(value(v) for v in scheme.c), "c_comment": ", ".join(map(str, scheme.c))}


def _explicit_stage_lines(scheme, prefix: str, n_q: int, N: int, dynamics: str, driven: bool = False,
                          determinant: int | None = None) -> list:
    """Straight-line stages of one explicit tableau: only its nonzero a_ij and b_i, read from the
    method's coefficient arrays (constant indices, so the compiler folds them). ``driven``: the
    stages read the inputs r (held, or r + c_i dr on a ramp; `input_context`). ``determinant``
    (dependent speeds eliminated): the index of det(A_D) in the gauge; every later stage writes its
    own gauge, and a stage whose det(A_D) has the other sign than x's, or differs from it by more
    than DEPENDENT_JUMP (``<prefix>_determinant_near``), stops the step with
    LCG_SINGULAR_CONSTRAINTS, as the monitor does between accepted states: the step reaches a
    singular A_D, which the accepted states alone miss when the step comes back to x's side
    (found by review: heun at h = 2e-2, whose predictor stage came within 0.0018 L of the
    horizontal, and dopri5 at 5e-2 turned sympy's non-minimal pendulum back there with status OK)."""
    name = f"{prefix}_{scheme.name}"

    def evaluate(i, state):
        gauge = "gauge" if i == 0 else "stage_gauge" if determinant is not None else "0"  # stage 0 is at x
        inputs = ""
        if driven:
            inputs = "r, " if scheme.c[i] == 0 else f"{prefix}_stage_inputs(r, dr, {name}_c[{i}], rs), "
        lines = [f"status = {dynamics}(t + {name}_c[{i}] * h, {state}, {inputs}p, k + {i * N}, k + {i * N + n_q}, "
                 f"{gauge});",
                 "if (status != LCG_OK) return status;"]
        if i > 0 and determinant is not None:
            near = f"{prefix}_determinant_near(stage_gauge[{determinant}], gauge[{determinant}])"
            lines.append(f"if (!{near}) return LCG_SINGULAR_CONSTRAINTS;")
        return lines

    if not needed_stages(scheme)[0]:
        raise EmitError(f"method {scheme.name!r}: its first stage is never used, so no stage reads the pivots of x")

    lines = [f"(void){name}_a;  /* all zero for one-stage methods */"] if not any(any(r) for r in scheme.a) else []
    return lines + tableau_stage_lines(scheme, prefix, N, evaluate, "x[m] += h * ") + ["return LCG_OK;"]


def tableau_stage_lines(scheme, prefix: str, size: int, evaluate, update: str) -> list:
    """Stage loops of an explicit tableau over ``size`` values: xs = x + h sum_j a_ij k_j, then
    ``evaluate(i, state)`` (lines that fill k_i), and finally ``update`` + h sum_i b_i k_i.
    Shared by the scalar steppers and the lane kernel, so both round alike."""
    s, name = scheme.stages, f"{prefix}_{scheme.name}"

    def combination(weights, array) -> str:
        return " + ".join(f"{name}_{array}[{index}] * k[{j * size} + m]" for index, j in weights)

    lines = []
    needed = needed_stages(scheme)
    for i in range(s):
        if not needed[i]:
            continue
        state = "x"
        weights = [(i * s + j, j) for j in range(i) if scheme.a[i][j] != 0]
        if weights:
            lines.append(f"for (m = 0; m < {size}; ++m) xs[m] = x[m] + h * ({combination(weights, 'a')});")
            state = "xs"
        lines += evaluate(i, state)
    final = [(i, i) for i in range(s) if scheme.b[i] != 0]
    lines.append(f"for (m = 0; m < {size}; ++m) {update}({combination(final, 'b')});")
    return lines


def needed_stages(scheme) -> list:
    """needed[i]: stage i's derivative reaches the step's result, through b_i or through a later
    needed stage's a_ji. An explicit step computes only these: a first-same-as-last stage that
    exists for an embedded error estimate (Dormand-Prince's 7th, b_7 = 0) is never evaluated."""
    s = scheme.stages
    needed = [scheme.b[i] != 0 for i in range(s)]
    for i in reversed(range(s)):
        needed[i] = needed[i] or any(needed[j] and scheme.a[j][i] != 0 for j in range(i + 1, s))
    return needed


def input_context(system, names, real: str) -> dict:
    """Template context of the inputs r: their rows for the header, the C argument text, and the
    types of the drivers' input function and table (models without inputs: none of it)."""
    n_r, prefix = len(system.inputs), names.prefix
    rows = [{"index": i, "name": s.name, "c_name": names.symbols[s]} for i, s in enumerate(system.inputs)]
    return {"has_measurements": bool(system.measurements), "n_measurements": len(system.measurements),
            "has_inputs": n_r > 0, "n_inputs": n_r, "n_inputs_or_one": max(1, n_r), "input_rows": rows,
            "r_param": f"const {real} *r, " if n_r else "", "rp": "r, p" if n_r else "p",
            "input_fn": f"{prefix}_input_fn", "input_table": f"{prefix}_input_table"}
