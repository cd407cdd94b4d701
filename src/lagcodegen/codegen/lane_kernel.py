"""Helper: the template context of the lane-group sweep kernel (``templates/lanes.c.j2``).

The scalar ``<prefix>_sweep`` runs members one after another, so the compiler can vectorize
only inside one member. The lane kernel runs ``lanes`` members side by side: every state,
parameter and stage value is stored as ``v[i * lanes + l]`` (component i of lane l), and the
dynamics and energy are one ``for (l = 0; l < lanes; ++l)`` loop each whose body is the same
straight-line code as the scalar kernels (same CSE temporaries, same unrolled LDL^T), so gcc
vectorizes across members, ``lanes`` members per vector group.

Inside that loop nothing may branch or call libm: the pivot test of the LDL^T sets a flag
instead of returning, and sin/cos are branch-free polynomials (``templates/trig.c.j2``) valid
for ``|x| <= LCG_TRIG_LIMIT`` (``LCG_TRIGF_LIMIT`` in float). A lane whose pivot failed or whose
trig argument left that range (or was not finite) is recomputed afterwards by the scalar ``<prefix>_dynamics`` /
``<prefix>_energy`` with libm, which also yields the scalar kernel's status codes. With
``trig="libm"`` the loop calls libm's sin/cos itself (it no longer vectorizes), and every
member's result equals the scalar kernel's bit for bit: the tests use it to prove the lane
driver's semantics.

The first stage of each step also leaves every lane's pivots of M in a gauge, which the group
loop hands lane by lane to the drivers' singularity monitor (``<prefix>_gauge_check``,
``templates/monitor.c.j2``): a lane that steps across a singular configuration stops with the
status and step the scalar sweep reports.

Only explicit Runge-Kutta methods of unconstrained models get a lane stepper; everything else
(implicit methods, symplectic Euler, projection onto constraints) stays on the scalar sweep.
"""
from __future__ import annotations

from .csyntax import EmitError
from .csyntax import literal as _literal
from .csyntax import record as _record
from .ldlt import ldlt_factor_lines, ldlt_substitution_lines
from .printer import CPrinter
from .steppers import tableau_stage_lines

#: members per lane group: 8 doubles = two AVX2 (four SSE2) vectors; 8 measured a little faster than 4
#: with SSE2 and AVX2 (benchmarks/bench_sweep.py)
DEFAULT_LANES = 8
TRIG_MODES = ("fast", "libm")
# per-lane flags, 0 or 1 in the scalar type (int flags would stop gcc vectorizing the loop):
_WIDE = "lcg_wide"          # a trig argument outside the fast range, or not finite
_SINGULAR = "lcg_singular"  # a pivot of M that is not positive
# Locals beside user code start with lcg_ (mangle never gives a user name that prefix); x, p, t
# and xdot are reserved names already.


class LanePrinter(CPrinter):
    """CPrinter whose sin/cos call the branch-free lane versions and flag out-of-range arguments."""

    def __init__(self, precision: str, names: dict, prefix: str):
        super().__init__(precision=precision, names=names)
        self._prefix = prefix
        self.trig_calls = set()  # "sin", "cos": the lane wrappers to define (and no others)

    def _print_sin(self, expr):
        self.trig_calls.add("sin")
        return f"{self._prefix}_lane_sin({self._print(expr.args[0])}, &{_WIDE})"

    def _print_cos(self, expr):
        self.trig_calls.add("cos")
        return f"{self._prefix}_lane_cos({self._print(expr.args[0])}, &{_WIDE})"


def lanes_apply(system, methods) -> bool:
    """True when the lane kernel can serve this system: unconstrained, rhs, an explicit method. A
    driven model's lanes take inputs constant per member, as parameters after the free ones (a
    sweep over input amplitudes); inputs that vary in time run on the scalar sweep. A tree's
    recursive kernel has no lanes: the members of its sweeps run one after another (its kernel
    is long, and lanes would multiply its compile time for little: it is not M ud = F)."""
    from ..integrators.schemes import get_scheme

    return any(get_scheme(m).lane_capable for m in methods) and not system.n_constraints and \
        not system.u_dependent and "rhs" in system.outputs and not system.recursive


def lane_context(system, names, real: str, methods: list, lanes: int, trig: str = "fast",
                 scalar_trig: str = "libm") -> dict:
    """Template context of ``templates/lanes.c.j2``; ``{"has_lanes": False}`` when lanes is 0.
    ``trig`` "fast": the branch-free lane forms; "libm": sin and cos as the scalar kernel prints
    them (``scalar_trig``: libm calls or the inline forms), so the lanes equal its sweep bit for bit."""
    from ..integrators.schemes import get_scheme

    if not lanes:
        return {"has_lanes": False}
    if not isinstance(lanes, int) or isinstance(lanes, bool) or not 1 <= lanes <= 64:
        raise EmitError(f"lanes must be an int in 1..64 (members per vector group), got {lanes!r}")
    if trig not in TRIG_MODES:
        raise EmitError(f"lane trig must be one of {TRIG_MODES}, got {trig!r}")
    if not lanes_apply(system, methods):
        return {"has_lanes": False}
    n, N, prefix = len(system.u), len(system.q) + len(system.u), names.prefix  # n: speeds, the size of M
    printer = LanePrinter(real, names.symbols, prefix) if trig == "fast" else \
        CPrinter(real, names.symbols, trig=scalar_trig)
    steppers = []
    for number, name in enumerate(dict.fromkeys(methods)):
        scheme = get_scheme(name)
        if scheme.lane_capable:
            steppers.append({"name": scheme.name, "id": number, "title": scheme.title or scheme.name,
                             "lines": _stage_lines(scheme, prefix, N * lanes)})
    has_energy = "energy" in system.outputs
    prototype = _record("int", f"{prefix}_sweep_lanes",
                        f"int method, long n_members, const {real} *x0s, const {real} *ps, {real} t0, "
                        f"{real} h, long n_steps, long stride, int track_energy, {real} *x_final, {real} *q_max, "
                        f"{real} *energy_error, int *status, long *steps_done, {real} *traj",
                        f"Many independent members, {lanes} side by side (explicit Runge-Kutta "
                        "methods only; returns LCG_UNKNOWN_METHOD for others)"
                        + (f"; ps holds per member the free parameters, then its {len(system.inputs)} inputs, "
                           "held constant." if system.inputs else "."), [])
    context = {
        "has_lanes": True, "lanes": lanes, "lane_fast_trig": trig == "fast",
        "lane_sin": "lcg_sinf_fast" if real == "float" else "lcg_sin_fast",
        "lane_cos": "lcg_cosf_fast" if real == "float" else "lcg_cos_fast",
        "lane_limit": "LCG_TRIGF_LIMIT" if real == "float" else "LCG_TRIG_LIMIT",
        "lane_steppers": steppers, "lane_max_stages": max(get_scheme(s["name"]).stages for s in steppers),
        "lane_dynamics": _dynamics_lines(system, names, printer, real, lanes), "lane_energy": [],
        "n_state_lanes": N * lanes, "n_lanes": n * lanes, "n_q_lanes": len(system.q) * lanes,
        "n_param_lanes": max(1, len(system.free_parameters) + len(system.inputs)) * lanes,
        "lane_params": max(1, len(system.free_parameters) + len(system.inputs)),
        "lane_inputs": f"p_lane + {len(system.free_parameters)}, " if system.inputs else "",
        "n_params_free": len(system.free_parameters), "sweep_lanes_decl": prototype["decl"],
        "lane_history": 2 * n * lanes, "lane_history_per_lane": 2 * n,  # the monitor: previous, initial pivots
        "lane_prototype": prototype,
    }
    if has_energy:
        kernel = system.kernel("energy")
        energy = {(i, j): e for (b, i, j), e in kernel.results if b == "E"}[(0, 0)]
        context["lane_energy"] = _head(kernel, names, printer, real, lanes) + [
            f"lcg_energy[lcg_lane] = {_print(printer, energy, 'energy')};", f"lcg_redo[lcg_lane] = {_WIDE};"]
    # only the wrappers (and trig.c.j2 forms, see emit._trig_context) the lane code calls: an
    # unused static function fails clang's -Wall -Werror
    calls = printer.trig_calls if trig == "fast" else set()
    context |= {"lane_uses_sin": "sin" in calls, "lane_uses_cos": "cos" in calls}
    return context


def _print(printer, expr, where: str) -> str:
    try:
        return printer.doprint(expr)
    except ValueError as err:
        raise EmitError(f"cannot print {where}: {err}") from err


def _head(kernel, names, printer, real: str, lanes: int) -> list:
    """Lane inputs (``const double q1 = x[0 * lanes + l];``) and the CSE temporaries of lane l."""
    used = kernel.symbols
    lines = [f"{real} {_WIDE} = {_literal(0, real)};"]
    for s, i in names.state_index.items():
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = x[{i * lanes} + lcg_lane];")
    for s, i in names.param_index.items():
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = p[{i * lanes} + lcg_lane];")
    for s, i in (names.input_index or {}).items():  # held per member: after the parameters
        if s in used:
            lines.append(f"const {real} {names.symbols[s]} = p[{(len(names.param_index) + i) * lanes} + lcg_lane];")
    lines.append(f"/* Intermediate terms ({len(kernel.temporaries)}) */")
    for s, expr in kernel.temporaries:
        lines.append(f"const {real} {names.symbols[s]} = {_print(printer, expr, names.symbols[s])};")
    return lines


def _dynamics_lines(system, names, printer, real: str, lanes: int) -> list:
    """Loop body of the lane dynamics: K, M, F, the flagged LDL^T and xdot of lane l."""
    kernel = system.kernel("dynamics")
    n_q, n = len(system.q), len(system.u)
    lines = _head(kernel, names, printer, real, lanes) + [f"{real} {_SINGULAR} = {_literal(0, real)};"]
    blocks = {}
    for (b, i, j), expr in kernel.results:
        blocks.setdefault(b, {})[(i, j)] = expr
    M = blocks.get("M", {})
    for (j, k), expr in M.items():
        if expr != 0 or j == k:
            lines.append(f"const {real} M_{j}_{k} = {_print(printer, expr, f'M[{j}][{k}]')};")
    for (j, _), expr in blocks.get("F", {}).items():
        lines.append(f"const {real} F_{j} = {_print(printer, expr, f'F[{j}]')};")
    if system.kinematics_identity:
        lines += [f"xdot[{j * lanes} + lcg_lane] = x[{(n_q + j) * lanes} + lcg_lane];" for j in range(n_q)]
    else:
        lines += [f"xdot[{j * lanes} + lcg_lane] = {_print(printer, expr, f'qd[{j}]')};"
                  for (j, _), expr in blocks["K"].items()]
    factor, LD = ldlt_factor_lines(n, {jk for jk, e in M.items() if e != 0}, real, flag=_SINGULAR)
    factor += [f"gauge[{j * lanes} + lcg_lane] = D_{j};" for j in range(n)]  # the singularity monitor's pivots
    lines += factor + ldlt_substitution_lines(n, LD, real, lambda i: f"F_{i}",
                                              lambda i: f"xdot[{(n_q + i) * lanes} + lcg_lane]")
    lines.append(f"lcg_redo[lcg_lane] = {_SINGULAR} + {_WIDE};")
    return lines


def _stage_lines(scheme, prefix: str, size: int) -> list:
    """Stages of one explicit tableau over all lanes at once (``size`` = (n_q + n_u) * lanes values), with
    the scalar stepper's coefficient arrays and sums, so each lane rounds as the scalar step does."""
    name = f"{prefix}_{scheme.name}"

    def evaluate(i, state):
        gauge = "gauge" if i == 0 else "spare"  # stage 0 is at x: its pivots are x's
        return [f"{prefix}_lanes_dynamics(t + {name}_c[{i}] * h, {state}, p, k + {i * size}, stage, {gauge});",
                f"{prefix}_lanes_first_failure(code, stage);"]

    return tableau_stage_lines(scheme, prefix, size, evaluate, "xn[m] = x[m] + h * ")
