"""Command line: ``lagcodegen <command>``; ``lagcodegen --help`` lists the commands.

A MODEL argument is a catalog example name (``lagcodegen examples``) or a Python file that
defines ``model`` (a `Model`) or a function ``build_model()`` returning one.
"""
from __future__ import annotations

import argparse
import runpy
import sys
import time
from pathlib import Path

import sympy as sp

from .cli_runs import add_run_commands


def load_model(spec: str):
    """A catalog example by name, or the ``model`` / ``build_model()`` of a Python file."""
    from .catalog import EXAMPLES
    from .model import Model

    if spec in EXAMPLES:
        return EXAMPLES[spec]()
    path = Path(spec)
    if not path.is_file():
        raise SystemExit(f"lagcodegen: {spec!r} is neither an example ({', '.join(EXAMPLES)}) nor a file")
    namespace = runpy.run_path(str(path))
    model = namespace.get("model")
    if model is None and callable(namespace.get("build_model")):
        model = namespace["build_model"]()
    if not isinstance(model, Model):
        raise SystemExit(f"lagcodegen: {path} must define `model` (a lagcodegen.Model) or `build_model()`")
    return model


def parse_assignments(items, what: str) -> dict:
    """``["k=10", "m=2"]`` or ``["k=10,m=2"]`` -> {"k": 10.0, "m": 2.0}."""
    values = {}
    for item in items or []:
        for part in filter(None, item.split(",")):
            name, sep, value = part.partition("=")
            if not sep:
                raise SystemExit(f"lagcodegen: {what} {part!r} must look like name=value")
            try:
                values[name.strip()] = float(value)
            except ValueError:
                raise SystemExit(f"lagcodegen: {what} {name!r} has a non-numeric value {value!r}") from None
    return values


def cmd_examples(args) -> int:
    from .catalog import EXAMPLES

    for name, builder in EXAMPLES.items():
        doc = (builder.__doc__ or "").strip().splitlines()
        print(f"{name:22s} {doc[0] if doc else ''}")
    return 0


def cmd_derive(args) -> int:
    from .derive import derive_equations

    model = load_model(args.model)
    start = time.perf_counter()
    eom = derive_equations(model)
    elapsed = time.perf_counter() - start
    print(f"{eom.name}: {eom.route}, n = {eom.n}, derived in {elapsed:.3f} s")
    print(f"coordinates q = {list(eom.q)}; speeds u = {list(eom.u)}")
    print(f"M(q, t) ud = F(q, u, t) with\nM =")
    sp.pprint(eom.mass_matrix, use_unicode=False, wrap_line=False)
    print("F =")
    sp.pprint(eom.forcing, use_unicode=False, wrap_line=False)
    if eom.energy is not None:
        print("T + V =")
        sp.pprint(eom.energy, use_unicode=False, wrap_line=False)
    return 0


def cmd_emit(args) -> int:
    from .cse import DEFAULT_OUTPUTS, reduce_expressions
    from .derive import derive_equations
    from .emit import render_sources

    eom = derive_equations(load_model(args.model))
    outputs = args.outputs.split(",") if args.outputs else [
        o for o in DEFAULT_OUTPUTS if not (o == "energy" and eom.energy is None)]
    methods = args.methods.split(",") if args.methods else ()
    system = reduce_expressions(eom, outputs, parse_assignments(args.fixed, "fixed parameter"))
    sources = render_sources(system, args.precision, methods=methods, trig=args.trig)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / sources.header_name).write_text(sources.header)
    (out / sources.source_name).write_text(sources.source)
    for kernel in system.kernels:
        print(f"{kernel.name:12s} ops {kernel.ops_before:6d} before CSE, {kernel.ops_after:6d} after")
    if system.fixed_parameters:
        print(f"folding {len(system.fixed_parameters)} fixed parameter(s) saved {system.ops_saved_by_fixing} ops")
    print(f"wrote {out / sources.header_name} and {out / sources.source_name}")
    return 0


def cmd_demo(args) -> int:
    """Derive, compile and simulate the double pendulum; compare with scipy's DOP853."""
    import numpy as np

    from .catalog import double_pendulum
    from .derive import derive_equations
    from .pipeline import compile_model
    from .simulate import simulate, solve_reference

    start = time.perf_counter()
    eom = derive_equations(double_pendulum())
    print(f"double pendulum ({eom.route}), M(q) ud = F(q, u):")
    sp.pprint(eom.mass_matrix, use_unicode=False, wrap_line=False)
    sp.pprint(eom.forcing, use_unicode=False, wrap_line=False)
    system = compile_model(eom, methods=("rk4", "implicit_midpoint"))
    print(f"compiled {system.module_name} in {time.perf_counter() - start:.2f} s (cache: {system.path.parent})")
    x0 = {"q1": 1.0, "q2": 0.5}
    for method, h in (("rk4", 1e-3), ("implicit_midpoint", 1e-3)):
        simulate(system, x0, 10.0, h, method).check()  # checks h against the stability limit
        start = time.perf_counter()
        run = simulate(system, x0, 10.0, h, method, energy=True, stride=100, check_stability=False)
        elapsed = time.perf_counter() - start
        drift = float(np.max(np.abs(run.energy - run.energy[0])))
        print(f"{method:18s} h = {h:g}: 10 s in {elapsed * 1e3:.2f} ms, |dE| <= {drift:.2e}, "
              f"final q = {run.x[-1, :2]}")
    _, reference = solve_reference(system, [1.0, 0.5, 0.0, 0.0], [0.0, 10.0])
    final = simulate(system, x0, 10.0, 1e-3, "rk4").x[-1]
    print(f"rk4 final-state error against scipy DOP853 (rtol = atol = 1e-12): "
          f"{float(np.max(np.abs(final - reference[-1]))):.2e}")
    return 0


def make_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="lagcodegen", description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    commands = parser.add_subparsers(dest="command", required=True)
    commands.add_parser("examples", help="list the built-in textbook models").set_defaults(run=cmd_examples)
    commands.add_parser("demo", help="derive, compile and simulate the double pendulum").set_defaults(run=cmd_demo)
    derive = commands.add_parser("derive", help="derive and print M(q,t) ud = F(q,u,t)")
    derive.add_argument("model", help="example name or model file")
    derive.set_defaults(run=cmd_derive)
    emit = commands.add_parser("emit", help="write the standalone C header and source of a model")
    emit.add_argument("model", help="example name or model file")
    emit.add_argument("--out", default=".", help="output directory (default: .)")
    emit.add_argument("--precision", choices=("double", "float"), default="double")
    emit.add_argument("--trig", choices=("libm", "inline"), default="libm",
                      help="sin/cos as libm calls (default) or inline polynomials (below 1 ulp, templates/trig.c.j2)")
    emit.add_argument("--outputs", help="comma-separated subset of mass_matrix,forcing,accel,rhs,energy,"
                      "points,jacobian (default: all)")
    emit.add_argument("--methods", help="comma-separated integrators to include as step functions, "
                      "e.g. rk4,symplectic_euler,implicit_midpoint (implicit ones need the jacobian output)")
    emit.add_argument("--fixed", action="append", metavar="NAME=VALUE",
                      help="fold a parameter into the code (repeatable, or comma-separated)")
    emit.set_defaults(run=cmd_emit)
    add_run_commands(commands)
    return parser


def main(argv=None) -> int:
    args = make_parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
