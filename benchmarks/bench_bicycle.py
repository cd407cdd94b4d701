"""Suite `bicycle`: the Whipple bicycle as sympy's own test_kane3.py builds it (KanesMethod, 4
coordinates, 3 independent and 3 dependent speeds, CRAMER solver), against sympy + PyDy's
Cython code for the same KanesMethod object.

In one fresh worker: sympy forms the KanesMethod (the test function is run until its
``kanes_equations`` returns; not timed for either side). Then, each from that object:

- lagcodegen's cold pipeline: ``Model(sympy_model=...)`` and ``compile_model`` (the RK4 driver
  and the rhs, an empty cache directory), dependent speeds eliminated (the default), built for
  this machine's vector instruction set (-mavx2 where the CPU has AVX2; `instruction_set`);
- PyDy's ``generate_ode_function(forcing, q, u, constants, mass_matrix=mass_matrix,
  coordinate_derivatives=<kindiffdict>, generator="cython")`` (its code generation and Cython
  compile, with the same instruction-set flag in $CFLAGS; Kane's M and F of every speed, the
  dependent ones' rows from the constraints);
- ns per RK4 step (h = 1e-3) from the same consistent state: ours is ``simulate``'s loop in C;
  PyDy has no integrator, so its step is the classic
  RK4 in Python around its compiled rhs (four calls and the numpy updates, what a PyDy user runs),
  and also reported: four bare calls of its rhs, the floor of any Python stepping loop. Each
  contender's time is its best of ``--bicycle-repeat`` runs (default 7), the three runs taken in
  turn, so that the bests come from the same spells of the shared machine;
- the cold pipelines again in ``--bicycle-pipelines`` - 1 more fresh processes (default 2 more,
  PyDy's first every other time): each side's best of them all.

Goals (issue 14): RK4 step >= 50x faster than PyDy's; our cold pipeline faster than PyDy's
generate + compile.

Run through the suite runner: ``python benchmarks/run.py bicycle [--quick]`` (needs the ``bench``
extra: pydy, cython).
"""
from __future__ import annotations

import os
import sys
import time
from pathlib import Path

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent))

from _common import emit, format_table, peer_versions, progress, run_worker  # noqa: E402

DESCRIPTION = "Whipple bicycle (sympy test_kane3's KanesMethod): pipeline and RK4 ns/step against PyDy's Cython"
STEPS = {False: 20_000, True: 2_000}
SPEED = 5.0  # m/s, upright with a small roll rate


def bicycle_kane():
    """The KanesMethod test_kane3.test_bicycle forms (its later linearization checks are skipped),
    by the peer survey tool's `first_kane`."""
    import importlib.util

    path = Path(__file__).resolve().parent.parent / "tools" / "sympy_peer_survey.py"
    spec = importlib.util.spec_from_file_location("sympy_peer_survey", path)
    survey = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = survey  # its dataclass looks itself up there
    spec.loader.exec_module(survey)
    return survey.first_kane("test_kane3", "test_bicycle")


def benchmark_values() -> dict:
    """The benchmark bicycle's parameters under test_kane3's names (the conversion in
    tests/constraints/test_whipple_bicycle.py, which follows that test)."""
    import importlib.util

    path = Path(__file__).resolve().parent.parent / "tests" / "constraints" / "test_whipple_bicycle.py"
    spec = importlib.util.spec_from_file_location("whipple_bicycle", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.benchmark_values()


def upright_state(kane, system, values: dict):
    """(q, independent u) of upright running at SPEED with a roll rate of 0.5 rad/s: zero yaw, roll
    and steer, the pitch (test_kane3's dependent coordinate) from its configuration constraint."""
    import numpy as np
    import sympy as sp
    from scipy.optimize import brentq

    q = list(kane.q)
    dependent = list(kane._qdep)  # private: sympy 1.14 keeps them only there
    closure = sp.lambdify(dependent, kane._f_h[0].xreplace(values | {c: 0 for c in q if c not in dependent}))
    pitch = brentq(closure, -1.0, 1.0)
    x = np.zeros(system.layout.n_state)
    x[q.index(dependent[0])] = pitch
    speeds = {name: 0.0 for name in system.layout.speeds}
    names = list(system.layout.speeds)
    speeds[names[0]] = 0.5  # test_kane3's u_ind = (u2 roll rate, u4 rear wheel rate, u5 steer rate)
    speeds[names[1]] = SPEED / values[next(c for c in values if c.name == "WRrad")]  # forward
    x[len(q):] = [speeds[name] for name in names]
    return x


def add_arguments(group) -> None:
    group.add_argument("--bicycle-repeat", type=int, default=7, metavar="R", help="best of R runs (default 7)")
    group.add_argument("--bicycle-pipelines", type=int, default=3, metavar="P",
                       help="cold pipelines: best of P fresh processes (default 3)")


def ours_pipeline(kane, constants, cache: str):
    """lagcodegen's cold pipeline from the KanesMethod: (CompiledSystem, seconds)."""
    from lagcodegen import Model
    from lagcodegen.pipeline import compile_model

    start = time.perf_counter()
    model = Model("whipple_kane", parameters=constants, sympy_model=kane)
    system = compile_model(model, methods=("rk4",), outputs=("rhs",), cache_dir=cache)
    return system, time.perf_counter() - start


def pydy_pipeline(kane, constants, instruction_set):
    """PyDy's generate + Cython compile of the same KanesMethod: (rhs, seconds). Its build gets the
    flag of the vector instruction set ours was built with (setuptools appends $CFLAGS), so that
    both C codes use the same instructions."""
    import sympy as sp
    from pydy.codegen.ode_function_generators import generate_ode_function

    os.environ["CFLAGS"] = " ".join([os.environ.get("CFLAGS", ""), *instruction_set]).strip()
    start = time.perf_counter()
    rates = kane.kindiffdict()
    # lists, not Matrices: PyDy 0.9.4 adds coordinates + speeds for its docstring (elementwise for Matrices)
    rhs = generate_ode_function(kane.forcing, list(kane.q), list(kane.u), constants,
                                mass_matrix=kane.mass_matrix,
                                coordinate_derivatives=sp.Matrix([rates[c.diff()] for c in kane.q]),
                                generator="cython", constants_arg_type="array")
    return rhs, time.perf_counter() - start


def kane_and_constants():
    """The KanesMethod (formed, not timed) and its constants in a fixed order."""
    import sympy as sp

    kane = bicycle_kane()
    t = sp.Symbol("t")
    return kane, sorted((kane.mass_matrix_full.free_symbols | kane.forcing_full.free_symbols) - {t}, key=str)


def worker_pipelines(order: str) -> None:
    """One more sample of both cold pipelines in a fresh process, in the order given ("ours" or
    "pydy" first): the machine is shared, and one sample each can land in different spells."""
    import tempfile

    kane, constants = kane_and_constants()
    emit(formed=True)
    with tempfile.TemporaryDirectory() as cache:
        if order == "ours":
            system, ours = ours_pipeline(kane, constants, cache)
            _, pydy = pydy_pipeline(kane, constants, system.instruction_set)
        else:
            from lagcodegen.native.build import host_instruction_set

            _, pydy = pydy_pipeline(kane, constants, host_instruction_set())
            system, ours = ours_pipeline(kane, constants, cache)
    emit(ours_pipeline_s=ours, pydy_pipeline_s=pydy)


def worker_measure(quick: str, repeat: str) -> None:
    import tempfile

    import numpy as np
    from _common import best_seconds_interleaved

    from lagcodegen.run.simulate import dependent_speeds, parameter_vector, simulate

    quick, repeat = quick == "1", int(repeat)
    steps = STEPS[quick]
    start = time.perf_counter()
    kane, constants = kane_and_constants()
    emit(sympy_s=time.perf_counter() - start)
    progress(f"bicycle: sympy formed the KanesMethod in {time.perf_counter() - start:.0f} s")
    benchmark = benchmark_values()
    values = {c: benchmark[c.name] for c in constants}

    with tempfile.TemporaryDirectory() as cache:
        system, seconds = ours_pipeline(kane, constants, cache)
        emit(ours_pipeline_s=seconds, instruction_set=" ".join(system.instruction_set) or "baseline")
        progress(f"bicycle: lagcodegen pipeline {seconds:.1f} s")
        pydy_rhs, seconds = pydy_pipeline(kane, constants, system.instruction_set)
        emit(pydy_pipeline_s=seconds)
        progress(f"bicycle: PyDy generate + compile {seconds:.1f} s")

        params = {c.name: v for c, v in values.items()}
        ours_x0 = upright_state(kane, system, values)
        full_x0 = np.concatenate([ours_x0, dependent_speeds(system, ours_x0, params)])
        run = simulate(system, ours_x0, t_end=steps * 1e-3, h=1e-3, params=params, stride=steps)
        if not run.ok:  # a run that stops early would time nothing
            raise RuntimeError(f"the bicycle run stopped: {run.message}")

        p = parameter_vector(system, params)
        p_pydy = np.array([values[c] for c in constants])

        def pydy_rk4(n: int) -> np.ndarray:
            # copies: PyDy's Cython rhs returns the same output buffer at every call
            x, h = full_x0.copy(), 1e-3
            for i in range(n):
                time_i = i * h
                k1 = pydy_rhs(x, time_i, p_pydy).copy()
                k2 = pydy_rhs(x + h / 2 * k1, time_i + h / 2, p_pydy).copy()
                k3 = pydy_rhs(x + h / 2 * k2, time_i + h / 2, p_pydy).copy()
                k4 = pydy_rhs(x + h * k3, time_i + h, p_pydy)
                x = x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
            return x

        pydy_steps = max(200, steps // 10)

        def calls() -> None:
            for _ in range(4 * pydy_steps):
                pydy_rhs(full_x0, 0.0, p_pydy)

        # the bare calls in the same turns (found by review: timed after the others, their "floor"
        # came out above the RK4 loop that makes them)
        ours_s, pydy_s, calls_s = best_seconds_interleaved(
            [lambda: simulate(system, ours_x0, t_end=steps * 1e-3, h=1e-3, params=params, stride=steps,
                              check_stability=False),
             lambda: pydy_rk4(pydy_steps), calls], repeat)
        ours_ns, pydy_ns = ours_s / steps * 1e9, pydy_s / pydy_steps * 1e9
        rhs_ns = calls_s / (4 * pydy_steps) * 1e9
        # the same step both ways, as a check that the two codes integrate the same equations
        ours_one = simulate(system, ours_x0, t_end=0.01, h=1e-3, params=params, check_stability=False).x[-1]
        theirs_one = pydy_rk4(10)[:len(ours_one)]
        if not np.allclose(ours_one, theirs_one, rtol=1e-9, atol=1e-9):  # not the same equations: no ratio
            raise RuntimeError(f"10 RK4 steps differ: ours {ours_one}, PyDy's {theirs_one}")
        emit(ours_ns=ours_ns, pydy_rk4_ns=pydy_ns, pydy_rhs_ns=rhs_ns, steps=steps, pydy_steps=pydy_steps,
             agreement=float(np.max(np.abs(ours_one - theirs_one))), n_params=len(p))
    progress("bicycle: done")


def run(options) -> dict:
    data = run_worker(__file__, ["measure", int(options.quick), options.bicycle_repeat],
                      [options.timeout or 900.0] * 4)
    samples = [(data["ours_pipeline_s"], data["pydy_pipeline_s"])] if "pydy_pipeline_s" in data else []
    for i in range(options.bicycle_pipelines - 1):  # more fresh processes, PyDy first every other time
        progress(f"bicycle: pipelines, fresh process {i + 2} of {options.bicycle_pipelines}")
        more = run_worker(__file__, ["pipelines", "pydy" if i % 2 == 0 else "ours"], [options.timeout or 900.0] * 2)
        if "pydy_pipeline_s" in more:
            samples.append((more["ours_pipeline_s"], more["pydy_pipeline_s"]))
    if samples:
        data["ours_pipeline_s"] = min(ours for ours, _ in samples)
        data["pydy_pipeline_s"] = min(pydy for _, pydy in samples)
        data["pipeline_samples"] = samples
    ours, pydy, floor = data.get("ours_ns"), data.get("pydy_rk4_ns"), data.get("pydy_rhs_ns")
    lines = [f"Whipple bicycle, sympy test_kane3's KanesMethod (4 q, 3 + 3 dependent u); RK4, h = 1e-3; "
             f"{peer_versions('pydy', 'cython', 'sympy')}; worker status: {data['status']}",
             f"sympy's kanes_equations (shared, not timed for either): {data.get('sympy_s', float('nan')):.1f} s",
             f"both C codes built for this machine's instruction set: {data.get('instruction_set', '?')}"]
    body = [[f"cold pipeline [s], best of {len(samples)}", f"{data.get('ours_pipeline_s', float('nan')):.2f}",
             f"{data.get('pydy_pipeline_s', float('nan')):.2f}", ""]]
    if ours and pydy:
        body.append(["RK4 step [ns]", f"{ours:.0f}", f"{pydy:.0f}", f"{pydy / ours:.1f}x"])
        body.append(["4 bare rhs calls [ns]", "", f"{4 * floor:.0f}", f"{4 * floor / ours:.1f}x"])
    lines.append(format_table(["measure", "lagcodegen", "PyDy (Cython)", "ratio"], body))
    if samples:
        lines.append("cold pipelines, each pair from one fresh process (ours, PyDy's) [s]: "
                     + ", ".join(f"({a:.2f}, {b:.2f})" for a, b in samples))
    if "agreement" in data:
        lines.append(f"10 RK4 steps from the same state, ours vs PyDy's: max |difference| {data['agreement']:.1e}")
    rows = [{k: v for k, v in data.items() if k != "status"}]
    goals = []
    if ours and pydy:
        goals.append({"goal": "bicycle RK4 step >= 50x faster than PyDy's Cython rhs in an RK4 loop",
                      "status": "PASS" if pydy / ours >= 50 else "FAIL", "detail": f"{pydy / ours:.1f}x"})
    else:
        goals.append({"goal": "bicycle RK4 step >= 50x PyDy", "status": "NOT RUN", "detail": data["status"]})
    if "ours_pipeline_s" in data and "pydy_pipeline_s" in data:
        goals.append({"goal": "bicycle cold pipeline faster than PyDy's generate + compile",
                      "status": "PASS" if data["ours_pipeline_s"] < data["pydy_pipeline_s"] else "FAIL",
                      "detail": f"{data['ours_pipeline_s']:.1f} s vs {data['pydy_pipeline_s']:.1f} s"})
    return {"table": "\n".join(lines), "rows": rows, "goals": goals}


WORKERS = {"measure": worker_measure, "pipelines": worker_pipelines}

if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "--worker" and sys.argv[2] in WORKERS:
        WORKERS[sys.argv[2]](*sys.argv[3:])
    else:
        sys.exit("bench_bicycle.py is a suite module; run: python benchmarks/run.py bicycle")
