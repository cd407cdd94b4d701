"""Maintenance tool: feed every system built by sympy.physics.mechanics' own test files to lagcodegen.

Each test function of the installed sympy's ``test_kane*.py``, ``test_lagrange*.py``,
``test_system*.py``, ``test_jointsmethod.py``, ``test_linearize.py`` and ``test_models.py`` runs
with the equation-forming methods (``KanesMethod.kanes_equations``,
``LagrangesMethod.form_lagranges_equations``, ``System.form_eoms``, ``JointsMethod.form_eoms``)
wrapped to record the objects they formed. Each recorded system is then given to lagcodegen
unchanged (``Model(name, parameters=<its free symbols>, sympy_model=obj, inputs=<its specified
functions of t>)``): refused (with the message), or compiled and its rhs compared with sympy's own
``mass_matrix_full \\ forcing_full`` at 3 random states with random parameters and inputs, then
(models without constraints) 1 s of its RK4 against scipy's DOP853 on sympy's rhs.

    python tools/sympy_peer_survey.py            # the table, one line per system
    python tools/sympy_peer_survey.py --json F   # also the rows as JSON

The peer suite of issue 14 grows from this; `tests/symbolic/test_sympy_peer_survey.py` runs the
small files.
"""
from __future__ import annotations

import argparse
import importlib
import json
import random
import sys
import time
import traceback
import warnings
from dataclasses import dataclass, field

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

FILES = ("test_kane", "test_kane2", "test_kane3", "test_kane4", "test_kane5", "test_lagrange", "test_lagrange2",
         "test_system", "test_system_class", "test_jointsmethod", "test_linearize", "test_models")
SEED = 20261125
TOLERANCE = 1e-10
#: 1 s of RK4 at h = 1e-3 against DOP853 at 1e-12, relative to 1 + |x|
TRAJECTORY_TOLERANCE = 1e-8


@dataclass
class Recorded:
    source: str
    system: object
    kind: str
    rows: list = field(default_factory=list)


class _Checking(Exception):
    """Stops a sympy test function at its own linearization once it formed a system: the linearization
    re-derives what it formed (test_linearize_rolling_disc_kane linearized for 15 s; collecting every
    file took 242 s, 50 s without; 2026-11-27). Its ``simplify`` checks run: test_models forms more
    systems after them."""


def collect(files=FILES) -> list:
    """Run the test functions of ``files`` and return every system whose equations they formed; each
    stops at its first linearization after it formed one (`_Checking`). On sympy 1.14 that keeps
    every system the whole functions form (54 of the default files)."""
    recorded, current = [], {"source": "", "formed": False}

    def wrap(cls, name, kind):
        original = getattr(cls, name)

        def formed(self, *args, **kwargs):
            result = original(self, *args, **kwargs)
            if not any(r.system is self for r in recorded):
                recorded.append(Recorded(current["source"], self, kind))
            current["formed"] = True
            return result
        return original, formed

    def checking(original):
        def stop_once_formed(*args, **kwargs):
            if current["formed"]:
                raise _Checking
            return original(*args, **kwargs)
        return stop_once_formed

    patches = [(me.KanesMethod, "kanes_equations", "KanesMethod"),
               (me.LagrangesMethod, "form_lagranges_equations", "LagrangesMethod"),
               (me.System, "form_eoms", "System"), (me.JointsMethod, "form_eoms", "JointsMethod")]
    saved = []
    for cls, name, kind in patches:
        original, formed = wrap(cls, name, kind)
        saved.append((cls, name, original))
        setattr(cls, name, formed)
    saved.append((me.Linearizer, "linearize", me.Linearizer.linearize))
    me.Linearizer.linearize = checking(me.Linearizer.linearize)
    try:
        for file in files:
            module = importlib.import_module(f"sympy.physics.mechanics.tests.{file}")
            for name in sorted(n for n in dir(module) if n.startswith("test_")):
                current["source"], current["formed"] = f"{file}.{name}", False
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore")
                    try:
                        getattr(module, name)()
                    except Exception:  # noqa: BLE001 - a failing sympy test still formed what it formed
                        pass  # (_Checking included)
    finally:
        for cls, name, original in saved:
            setattr(cls, name, original)
    # a System's and a JointsMethod's inner KanesMethod/LagrangesMethod is the same system
    inner = {id(method_of(r.system)) for r in recorded if r.kind in ("System", "JointsMethod")}
    return [r for r in recorded if id(r.system) not in inner]


class _Formed(Exception):
    """Stops a sympy test function once its first KanesMethod has its equations."""


def first_kane(file: str, test: str):
    """The first KanesMethod that sympy's ``<file>.<test>`` forms, its later checks skipped (test_kane3's
    own linearization takes a minute; its KanesMethod forms in a few seconds)."""
    module = importlib.import_module(f"sympy.physics.mechanics.tests.{file}")
    original, formed = me.KanesMethod.kanes_equations, []

    def record(self, *args, **kwargs):
        original(self, *args, **kwargs)
        formed.append(self)
        raise _Formed

    me.KanesMethod.kanes_equations = record
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            getattr(module, test)()
    except _Formed:
        pass
    finally:
        me.KanesMethod.kanes_equations = original
    if not formed:
        raise RuntimeError(f"sympy's {file}.{test} formed no KanesMethod")
    return formed[0]


def method_of(obj):
    """The KanesMethod or LagrangesMethod behind a System or JointsMethod (or obj itself)."""
    if isinstance(obj, me.System):
        return obj.eom_method
    if isinstance(obj, me.JointsMethod):
        return obj.method
    return obj


def specified_functions(method) -> list:
    t = me.dynamicsymbols._t
    q = list(method.q)
    u = list(getattr(method, "u", [])) or [c.diff(t) for c in q]
    known = set(q) | set(u) | {c.diff(t) for c in q} | {s.diff(t) for s in u} | set(auxiliary_zeros(method))
    found = me.find_dynamicsymbols(method.forcing) | me.find_dynamicsymbols(method.mass_matrix)
    return sorted(found - known, key=str)


def auxiliary_zeros(method) -> dict:
    """Kane's auxiliary speeds and their rates, zero in the equations of motion (sympy sets them to
    zero in ``rhs``; they only serve ``auxiliary_eqs``)."""
    t = me.dynamicsymbols._t
    aux = list(getattr(method, "_uaux", []))  # private: sympy 1.14 keeps them only there
    return {a: 0 for a in aux} | {a.diff(t): 0 for a in aux}


def check(record: Recorded, index: int, cache_dir, trajectories: bool = True, extra_compile_args=()) -> dict:
    """Feed one system to lagcodegen; the row says accepted / refused (why) / matching (error).
    ``extra_compile_args``: for `compile_model` (the test passes -O0, as the fuzz does: it checks the
    derivation and the generated C, not the optimizer; 53 systems built in 32 s instead of 46 s)."""
    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model
    from lagcodegen.run.simulate import dependent_speeds, make_rhs

    row = {"source": record.source, "kind": record.kind}
    method = method_of(record.system)
    t = me.dynamicsymbols._t
    try:
        inputs = specified_functions(method)
        held = getattr(method, "_hol_coneqs", sp.Matrix())  # private: a LagrangesMethod's holonomic constraints
        configuration = sp.Matrix(getattr(method, "_f_h", sp.Matrix()))  # private: Kane's configuration constraints
        parameters = sorted((method.mass_matrix.free_symbols | method.forcing.free_symbols | held.free_symbols
                             | configuration.free_symbols) - {t}, key=str)
        row["n_q"], row["n_u"] = len(method.q), len(getattr(method, "u", method.q))
        row["inputs"] = [str(r) for r in inputs]
        start = time.perf_counter()
        model = Model(f"peer_{index}", parameters=parameters, sympy_model=record.system, inputs=inputs)
        system = compile_model(model, methods=("rk4",), outputs=("rhs",), cache_dir=cache_dir,
                               extra_compile_args=tuple(extra_compile_args))
        row["compile_s"] = round(time.perf_counter() - start, 2)
    except Exception as error:  # noqa: BLE001 - the refusal is the result
        row["status"] = "refused"
        row["reason"] = f"{type(error).__name__}: {str(error).splitlines()[0][:300]}"
        return row
    rng = random.Random(SEED + index)
    errors = []
    try:
        full_M, full_F = method.mass_matrix_full, method.forcing_full
        speeds = list(getattr(method, "u", [])) or [c.diff(t) for c in method.q]
        attempts = 0
        while len(errors) < 3:
            attempts += 1
            values = {p: rng.uniform(0.5, 2.0) for p in parameters}
            state = [rng.uniform(-1, 1) for _ in range(len(method.q) + len(speeds))]
            r = [rng.uniform(-1, 1) for _ in inputs]
            eliminated = len(system.layout.dependent_speeds)
            if eliminated:  # our state is (q, independent u); the dependent ones follow from it
                ours_state = state[:len(state) - eliminated]
                state = ours_state + list(dependent_speeds(system, ours_state, {p.name: v for p, v in values.items()},
                                                           t=0.3))
            at = dict(zip(list(method.q) + speeds, state)) | dict(zip(inputs, r)) | values | {t: 0.3} | \
                auxiliary_zeros(method)
            at |= {c.diff(t): v for c, v in zip(method.q, state[len(method.q):])} if not getattr(method, "u", None) \
                else {}
            reference = np.array(full_M.xreplace(at).evalf().LUsolve(full_F.xreplace(at).evalf()).evalf(),
                                 dtype=float).ravel()
            table = (np.array([0.0, 1.0]), np.array([r, r])) if inputs else None
            rhs = make_rhs(system, {p.name: v for p, v in values.items()},
                           inputs=None if table is None else _constant(r))
            try:
                ours = rhs(0.3, np.array(state[:len(state) - eliminated]))
            except FloatingPointError:  # random parameters need not give a positive definite M (nor sympy's)
                if attempts < 20:
                    continue
                raise
            row["draws"] = attempts
            reference = reference[:len(ours)]  # (qd, ud); dependent ud or a Lagrange I model's multipliers follow
            errors.append(float(np.max(np.abs(ours - reference) / (1 + np.abs(reference)))))
    except Exception as error:  # noqa: BLE001
        row["status"] = "compare failed"
        row["reason"] = f"{type(error).__name__}: {str(error).splitlines()[0][:300]}"
        return row
    row["max_error"] = max(errors)
    row["status"] = "matches" if row["max_error"] < TOLERANCE else "differs"
    row["eliminated"] = len(system.layout.dependent_speeds)
    if row["status"] == "matches" and trajectories and not system.layout.n_constraints:
        try:
            row["trajectory_error"] = trajectory_error(system, method, values, inputs, rng)
        except Exception as error:  # noqa: BLE001
            row["status"] = "compare failed"
            row["reason"] = f"trajectory: {type(error).__name__}: {str(error).splitlines()[0][:300]}"
            return row
        if not row["trajectory_error"] < TRAJECTORY_TOLERANCE:
            row["status"] = "differs"
    return row


def trajectory_error(system, method, values, inputs, rng) -> float:
    """1 s of our compiled RK4 (h = 1e-3) against scipy's DOP853 (rtol = atol = 1e-12) on sympy's own
    rhs, ``mass_matrix_full \\ forcing_full`` lambdified, at parameter ``values`` the rhs check accepted,
    from a random state with constant inputs:
    the largest difference relative to 1 + |x|."""
    from scipy.integrate import solve_ivp

    from lagcodegen.run.simulate import dependent_speeds, simulate

    t = me.dynamicsymbols._t
    speeds = list(getattr(method, "u", [])) or [c.diff(t) for c in method.q]
    state = [rng.uniform(-0.5, 0.5) for _ in range(len(method.q) + len(speeds))]
    r = [rng.uniform(-1, 1) for _ in inputs]
    plain = sp.symbols(f"x0:{len(state)}")
    table = dict(zip(list(method.q) + speeds, plain)) | dict(zip(inputs, r)) | values | auxiliary_zeros(method)
    if not getattr(method, "u", None):
        table |= {c.diff(t): s for c, s in zip(method.q, plain[len(method.q):])}
    # cse=True: sympy's own rewriting of its expressions (exact); the bicycle's lambdify took 16 s
    # without it and each evaluation 18 ms, with it 2 s and 0.2 ms (2026-11-27)
    M = sp.lambdify([plain, t], method.mass_matrix_full.xreplace(table), "numpy", cse=True)
    F = sp.lambdify([plain, t], method.forcing_full.xreplace(table), "numpy", cse=True)
    n = len(state)

    def rhs(time, x):
        return np.linalg.solve(np.asarray(M(x, time), dtype=float), np.asarray(F(x, time), dtype=float).ravel())[:n]

    state = consistent_coordinates(method, state, values)
    ours = state[:len(state) - len(system.layout.dependent_speeds)]
    if system.layout.dependent_speeds:  # a consistent start: the dependent speeds from the constraints
        state = ours + list(dependent_speeds(system, ours, {p.name: v for p, v in values.items()}))
    run = simulate(system, ours, t_end=1.0, h=1e-3, params={p.name: v for p, v in values.items()},
                   inputs=r if inputs else None, check_stability=False)
    if not run.ok:
        raise RuntimeError(run.message)
    reference = solve_ivp(rhs, (0.0, 1.0), state, method="DOP853", rtol=1e-12, atol=1e-12, t_eval=[1.0])
    expected = reference.y[:len(ours), -1]
    return float(np.max(np.abs(run.x[-1] - expected) / (1 + np.abs(expected))))


def consistent_coordinates(method, state: list, values: dict) -> list:
    """``state`` with a KanesMethod's dependent coordinates solved from its configuration
    constraints (scipy's fsolve from the random draw), the independent ones kept: a random
    configuration of a closed loop is otherwise no configuration of the mechanism."""
    from scipy.optimize import fsolve

    dependent = list(getattr(method, "_qdep", []))  # private: sympy 1.14 keeps them only there
    if not dependent:
        return state
    q = list(method.q)
    by_name = {p.name: v for p, v in values.items()}
    # a length only the positions hold (a four-bar's ground link, absent from the velocity constraints
    # and the dynamics) is no parameter of the model: any value makes a mechanism
    lengths = {s: by_name.get(s.name, 1.0) for s in method._f_h.free_symbols if s != me.dynamicsymbols._t}
    independent = [c for c in q if c not in dependent]
    residual = sp.lambdify([independent, dependent], list(method._f_h.xreplace(lengths)), "numpy")
    rng = np.random.default_rng(len(state))
    draws = [[state[q.index(c)] for c in independent]] + list(rng.uniform(-np.pi, np.pi, (20, len(independent))))
    for drawn in draws:  # the drawn independent coordinates first; a crank angle the loop cannot reach next
        guesses = [[state[q.index(c)] for c in dependent]] + list(rng.uniform(-np.pi, np.pi, (20, len(dependent))))
        for guess in guesses:
            solved, _, found, _ = fsolve(lambda d, at=drawn: residual(at, d), guess, full_output=True, xtol=1e-14)
            if found == 1 and np.max(np.abs(residual(drawn, solved))) < 1e-10:
                fixed = list(state)
                for c, v in zip(independent, drawn):
                    fixed[q.index(c)] = float(v)
                for c, v in zip(dependent, solved):
                    fixed[q.index(c)] = float(v)
                return fixed
    raise RuntimeError(f"no configuration satisfies {method._f_h.T}")


def _constant(r):
    from lagcodegen.run.inputs import InputTable
    return InputTable(np.zeros(1), np.array([r], dtype=float))


def survey(files=FILES, cache_dir=None, trajectories: bool = True, extra_compile_args=()) -> list:
    rows = []
    for i, record in enumerate(collect(files)):
        try:
            rows.append(check(record, i, cache_dir, trajectories, extra_compile_args))
        except Exception:  # noqa: BLE001
            rows.append({"source": record.source, "kind": record.kind, "status": "crashed",
                         "reason": traceback.format_exc().splitlines()[-1]})
        row = rows[-1]
        if row["status"] != "matches":
            detail = f": {row.get('reason', '')}"
        else:
            detail = f", max error {row['max_error']:.1e}"
            if "trajectory_error" in row:
                detail += f", 1 s RK4 vs DOP853 {row['trajectory_error']:.1e}"
        print(f"{row['status']:>14}  {record.source} ({record.kind}){detail}", file=sys.stderr, flush=True)
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("files", nargs="*", default=FILES)
    parser.add_argument("--json", metavar="FILE")
    args = parser.parse_args()
    rows = survey(tuple(args.files))
    counts = {}
    for row in rows:
        counts[row["status"]] = counts.get(row["status"], 0) + 1
    print(f"{len(rows)} systems: " + ", ".join(f"{v} {k}" for k, v in sorted(counts.items())))
    if args.json:
        with open(args.json, "w") as handle:
            json.dump(rows, handle, indent=1)


if __name__ == "__main__":
    sp.init_printing(pretty_print=False)
    main()
