"""Command line: lagcodegen <command>; lagcodegen --help lists the commands.

A MODEL argument is a catalog example name (lagcodegen examples) or a Python file that
defines model (a lagcodegen.Model) or a function build_model() returning one.

Errors print one line, "lagcodegen <command>: error: <message>", naming the culprit.
Exit codes: 0 done, 1 the work failed (a run stopped early, a build failed), 2 a bad
command line, 130 interrupted. --traceback (or LAGCODEGEN_DEBUG=1) shows the Python
traceback instead, for developers.
"""
from __future__ import annotations

import argparse
import os
import sys
import textwrap
import time
import warnings
from pathlib import Path

import sympy as sp

from .arguments import (
    EXIT_BROKEN_PIPE,
    EXIT_FAILED,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    Parser,
    RunFailed,
    UsageError,
    join_negative_numbers,
    load_model,
    parse_assignments,
    parse_names,
)
from .fmu import add_fmu_command
from .runs import add_run_commands
from .scenes import add_animate_parser


def describe_example(name: str, builder, width: int = 88) -> str:
    """One catalog example for ``lagcodegen examples``: name, the builder's whole description
    (wrapped), its coordinates, and its parameters with their default values."""
    model = builder()
    doc = " ".join((builder.__doc__ or "").split()).replace("`", "")
    values = {p.name: v for p, v in model.parameter_values.items()}
    coordinates = ", ".join(str(q.func) if hasattr(q, "func") and q.args else str(q) for q in model.coordinates)
    parameters = ", ".join(f"{p.name} = {values[p.name]:g}" if p.name in values else p.name
                           for p in model.parameters)
    indent = " " * 4
    lines = [name, textwrap.fill(doc, width, initial_indent=indent, subsequent_indent=indent)]
    lines += [textwrap.fill(f"{label}: {text or 'none'}", width, initial_indent=indent,
                            subsequent_indent=indent * 2)
              for label, text in (("coordinates", coordinates), ("parameters", parameters))]
    return "\n".join(lines)


def cmd_examples(args) -> int:
    from ..catalog import EXAMPLES

    print("\n\n".join(describe_example(name, builder) for name, builder in EXAMPLES.items()))
    return EXIT_OK


def cmd_derive(args) -> int:
    """Print M and F one element a line (``M[i, j] = <expr>``, sympy syntax: sympify reads it
    back), or as 2-D pictures with --pretty."""
    from ..symbolic.derive import derive_equations

    model = load_model(args.model)
    start = time.perf_counter()
    eom = derive_equations(model)
    elapsed = time.perf_counter() - start
    speeds = f", {eom.n_u} speeds" if eom.n_u != eom.n_q else ""
    print(f"{eom.name}: {eom.route}, n = {eom.n_q}{speeds}, derived in {elapsed:.3f} s")
    print(f"coordinates q = {list(eom.q)}; speeds u = {list(eom.u)}; parameters {list(eom.parameters)}")
    if eom.tree is not None:  # found by review: it printed "M = None" and "F = None"
        from ..statics.equilibria import require_closed_form

        try:
            require_closed_form(eom, "derive")
        except ValueError as error:
            raise UsageError(str(error)) from None
    if args.latex:
        from ..symbolic.display import latex_equations

        print(latex_equations(eom))
        return EXIT_OK
    print("M(q, t) ud = F(q, u, t) with" + (" (textbook display form)" if args.display else ""))
    M, F = eom.display() if args.display else (eom.mass_matrix, eom.forcing)
    energy = eom.energy
    if args.display and energy is not None:
        from ..symbolic.display import display_form

        energy = display_form(energy)
    blocks = [("M", M), ("F", F)] + [("T + V", energy)] * (energy is not None)
    for label, value in blocks:
        if args.pretty:
            print(f"{label} =")
            sp.pprint(value, use_unicode=False, wrap_line=False)
        elif isinstance(value, sp.MatrixBase) and value.shape[1] == 1:
            print("\n".join(f"{label}[{i}] = {sp.sstr(value[i])}" for i in range(value.shape[0])))
        elif isinstance(value, sp.MatrixBase):
            print("\n".join(f"{label}[{i}, {j}] = {sp.sstr(value[i, j])}"
                            for i in range(value.shape[0]) for j in range(value.shape[1])))
        else:
            print(f"{label} = {sp.sstr(value)}")
    return EXIT_OK


def cmd_linearize(args) -> int:
    """Print A = df/dx and B = df/dr of xd = f(x, r) about a state (any state: states not named
    in --at are 0; of a model with constraints, solved from them, as simulate's --x0) with the
    eigenvalues, their frequencies and damping ratios."""
    import numpy as np

    from ..statics.state_space import linearize_state
    from ..symbolic.derive import derive_equations
    from .runs import consistent_x0

    eom = derive_equations(load_model(args.model))
    at = parse_assignments(args.at, "--at")
    states = [s.name for s in eom.q + eom.u]
    unknown = [name for name in at if name not in states]
    if unknown:
        raise UsageError(f"--at: {unknown[0]!r} is not a state of {eom.name}; states: {', '.join(states)}")
    given = parse_assignments(args.inputs, "--inputs")
    names = [r.name for r in eom.inputs]
    unknown = [name for name in given if name not in names]
    if unknown:
        raise UsageError(f"--inputs: {unknown[0]!r} is not an input of {eom.name}; "
                         f"inputs: {', '.join(names) or 'none'}")
    values = parse_assignments(args.params, "--params")
    if eom.m:  # found by review: the state simulate completes was refused, pointing at a Python function
        at = consistent_x0(eom, at, values, "linearize", "--at")
    linear = linearize_state(eom, [at.get(name, 0.0) for name in states],
                             [given.get(name, 0.0) for name in names] if names else None, values=values)
    print(f"{eom.name}: x = ({', '.join(states)}), r = ({', '.join(names)}), about x0 = {list(linear.x0)}"
          + (f", r0 = {list(linear.r0)}" if names else ""))
    show = lambda matrix: np.array2string(matrix, precision=6, max_line_width=160)  # noqa: E731
    print("A = df/dx =")
    print(show(linear.A))
    if names:
        print("B = df/dr =")
        print(show(linear.B))
    print("eigenvalue, frequency (rad/s), damping ratio:")
    for lam, w, zeta in zip(linear.eigenvalues(), linear.frequencies(), linear.damping_ratios()):
        print(f"  {lam.real:+.6g} {lam.imag:+.6g}j  {w:.6g}  {zeta:.6g}")
    return EXIT_OK


def emit_request(args, eom) -> tuple[list, list, dict]:
    """(outputs, methods, fixed) of ``lagcodegen emit``, every name checked."""
    from ..codegen.outputs import DEFAULT_OUTPUTS, OUTPUTS, applicable_outputs
    from ..integrators.schemes import SCHEMES, required_outputs

    methods = parse_names(args.methods, "--methods", tuple(SCHEMES))
    if args.outputs is not None:
        outputs = parse_names(args.outputs, "--outputs", tuple(OUTPUTS))
    else:
        outputs = applicable_outputs(eom, DEFAULT_OUTPUTS)
    outputs += [o for o in required_outputs(methods) if o not in outputs]
    fixed = parse_assignments(args.fixed, "--fixed")
    parameters = [p.name for p in eom.parameters]
    for name in fixed:
        if name not in parameters:
            raise UsageError(f"--fixed: {name!r} is not a parameter of {eom.name}; "
                             f"parameters: {', '.join(parameters) or 'none'}")
    return outputs, methods, fixed


def cmd_emit(args) -> int:
    from ..codegen.reduce import reduce_expressions
    from ..codegen.render import render_sources
    from ..symbolic.derive import derive_equations

    out = Path(args.out)
    if not args.out.strip() or (out.exists() and not out.is_dir()):
        raise UsageError(f"--out {args.out!r} must be a directory (it is created if missing)")
    eom = derive_equations(load_model(args.model))
    outputs, methods, fixed = emit_request(args, eom)
    system = reduce_expressions(eom, outputs, fixed)
    sources = render_sources(system, args.precision, methods=methods, trig=args.trig)
    # both files written beside their targets first, then moved there: a failure leaves no new header
    # next to an old source (found by review)
    for name in (sources.header_name, sources.source_name):
        if (out / name).exists() and not (out / name).is_file():
            raise UsageError(f"--out {args.out}: {out / name} exists and is not a file; nothing was written")
    written = []
    try:
        out.mkdir(parents=True, exist_ok=True)
        for name, text in ((sources.header_name, sources.header), (sources.source_name, sources.source)):
            partial = out / f".{name}.{os.getpid()}.partial"
            written.append((partial, out / name))
            partial.write_text(text)
        for partial, target in written:
            os.replace(partial, target)
    except OSError as error:
        raise UsageError(f"--out {args.out}: cannot write {error.filename}: {error.strerror}") from None
    finally:
        for partial, _ in written:
            if partial.exists():
                partial.unlink()
    if system.formulation:
        print(f"formulation {system.formulation}; C source {len(sources.source)} bytes")
    for kernel in system.kernels:
        print(f"{kernel.name:12s} ops {kernel.ops_before:6d} before CSE, {kernel.ops_after:6d} after")
    if system.fixed_parameters:
        print(f"folding {len(system.fixed_parameters)} fixed parameter(s) saved {system.ops_saved_by_fixing} ops")
    print(f"wrote {out / sources.header_name} and {out / sources.source_name}")
    return EXIT_OK


def cmd_demo(args) -> int:
    """Derive, compile and simulate the double pendulum; compare with scipy's DOP853."""
    import numpy as np

    from ..catalog import double_pendulum
    from ..pipeline import compile_model
    from ..run.simulate import simulate, solve_reference
    from ..symbolic.derive import derive_equations

    start = time.perf_counter()
    eom = derive_equations(double_pendulum())
    print(f"double pendulum ({eom.route}), M(q) ud = F(q, u), as a textbook prints them:")
    M, F = eom.display()
    sp.pprint(M, use_unicode=False, wrap_line=False)
    sp.pprint(F, use_unicode=False, wrap_line=False)
    system = compile_model(eom, methods=("rk4", "implicit_midpoint"))
    print(f"compiled {system.module_name} in {time.perf_counter() - start:.2f} s (cache: {system.path.parent})")
    x0 = {"q1": 1.0, "q2": 0.5}
    for method, h in (("rk4", 1e-3), ("implicit_midpoint", 1e-3)):
        simulate(system, x0, 10.0, h, method).check()  # checks h against the stability limit
        start = time.perf_counter()
        run = simulate(system, x0, 10.0, h, method, energy=True, stride=100, check_stability=False)
        elapsed = time.perf_counter() - start
        drift = float(np.max(np.abs(run.energy - run.energy[0])))
        # over the kept samples (every 100th step), not a bound over every step (found by review)
        print(f"{method:18s} h = {h:g}: 10 s in {elapsed * 1e3:.2f} ms, max |dE| every 100 steps {drift:.2e}, "
              f"final q = {run.x[-1, :2]}")
    _, reference = solve_reference(system, [1.0, 0.5, 0.0, 0.0], [0.0, 10.0])
    final = simulate(system, x0, 10.0, 1e-3, "rk4").x[-1]
    print(f"rk4 final-state error against scipy DOP853 (rtol = atol = 1e-12): "
          f"{float(np.max(np.abs(final - reference[-1]))):.2e}")
    return EXIT_OK


def make_parser() -> Parser:
    parser = Parser(prog="lagcodegen", description=__doc__,
                    formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--traceback", action="store_true",
                        help="on an error, show the Python traceback (also: LAGCODEGEN_DEBUG=1)")
    commands = parser.add_subparsers(dest="command", required=True, metavar="command")
    parser.command_names = commands.choices  # the commands' names, for the error prefix before parsing
    commands.add_parser("examples", help="list the built-in textbook models").set_defaults(run=cmd_examples)
    commands.add_parser("demo", help="derive, compile and simulate the double pendulum").set_defaults(run=cmd_demo)
    derive = commands.add_parser("derive", help="derive and print M(q,t) ud = F(q,u,t)")
    derive.add_argument("model", help="example name or model file")
    derive.add_argument("--pretty", action="store_true",
                        help="2-D pictures instead of one sympy expression per element")
    derive.add_argument("--display", action="store_true",
                        help="the textbook form (angle differences combined, factors pulled out) instead of "
                             "the emitted one")
    derive.add_argument("--latex", action="store_true", help="print M qdd = F as LaTeX, in the textbook form")
    derive.set_defaults(run=cmd_derive)
    linear = commands.add_parser("linearize", help="print A, B of xd = f(x, r) about a state, with eigenvalues")
    linear.add_argument("model", help="example name or model file")
    linear.add_argument("--at", action="append", metavar="STATE=VALUE",
                        help="the operating state (coordinates and speeds; unnamed ones are 0)")
    linear.add_argument("--inputs", action="append", metavar="INPUT=VALUE", help="the inputs there (default 0)")
    linear.add_argument("--params", "--param", dest="params", action="append", metavar="NAME=VALUE",
                        help="parameter values (default: the model's)")
    linear.set_defaults(run=cmd_linearize)
    emit = commands.add_parser("emit", help="write the standalone C header and source of a model")
    emit.add_argument("model", help="example name or model file")
    emit.add_argument("--out", default=".", help="output directory, created if missing (default: .)")
    emit.add_argument("--precision", choices=("double", "float"), default="double")
    emit.add_argument("--trig", choices=("libm", "inline"), default="inline",
                      help="sin/cos as inline polynomials (default; below 1 ulp, templates/trig.c.j2) or libm calls")
    emit.add_argument("--outputs", help="comma-separated subset of mass_matrix,forcing,accel,rhs,energy,"
                      "points,jacobian,momentum (default: all that apply)")
    emit.add_argument("--methods", help="comma-separated integrators to include as step functions, "
                      "e.g. rk4,symplectic_euler,implicit_midpoint (the outputs they need are added)")
    emit.add_argument("--fixed", action="append", metavar="NAME=VALUE",
                      help="fold a parameter into the code (repeatable, or comma-separated)")
    emit.set_defaults(run=cmd_emit)
    add_run_commands(commands)
    add_animate_parser(commands)
    add_fmu_command(commands)
    return parser


def classify(error: Exception) -> tuple[int, str] | None:
    """(exit code, one-line message) of an error the command line reports, or None for the rest
    (bugs keep their traceback)."""
    from ..native.build import BuildError
    from ..run.simulate import SimulationError

    if isinstance(error, UsageError):
        return EXIT_USAGE, str(error)
    if isinstance(error, KeyError):  # str() of a KeyError adds quotes around its message
        return EXIT_USAGE, str(error.args[0] if error.args else error)
    if isinstance(error, ValueError):  # the library's checks (ModelError, KernelError, ...) name the culprit
        return EXIT_USAGE, str(error)
    if isinstance(error, OSError) and not isinstance(error, BrokenPipeError):  # a file the user named
        return EXIT_USAGE, f"{error.filename}: {error.strerror}" if error.filename else str(error)
    if isinstance(error, MemoryError):
        return EXIT_FAILED, f"out of memory: {error or 'MemoryError'}"
    if isinstance(error, (RunFailed, BuildError, SimulationError)):
        return EXIT_FAILED, str(error)
    return None


def run_command(argv) -> int:
    """Parse and run; every reported error becomes one line on stderr, ``lagcodegen <command>:
    error: <message>``, and an exit code (see the module doc)."""
    argv = join_negative_numbers(argv)
    debug = "--traceback" in argv or os.environ.get("LAGCODEGEN_DEBUG", "").strip() not in ("", "0")
    # a flag of the whole command line, wherever it stands (found by review: after the command,
    # argparse refused it with a traceback and exit 1)
    argv = [a for a in argv if a != "--traceback"]
    parser = make_parser()
    named = next((a for a in argv if not a.startswith("-")), None)
    prog = f"lagcodegen {named}" if named in parser.command_names else "lagcodegen"
    try:
        with warnings.catch_warnings():
            warnings.showwarning = _one_line_warning(prog)
            args = parser.parse_args(argv)
            prog = f"lagcodegen {args.command}"
            return args.run(args)
    except Exception as error:  # re-raised below unless classify() knows it as a reported error
        verdict = classify(error)
        if verdict is None or debug:
            raise
        code, message = verdict
        named = getattr(error, "prog", None)  # the top-level parser reports a command's unknown options too
        print(f"{prog if named in (None, 'lagcodegen') else named}: error: {message}", file=sys.stderr)
        return code


def _one_line_warning(prog: str):
    """Warnings as the errors are printed, one line naming the command (found by review: they
    came as Python's file:line: Category: text, then the source line)."""
    def show(message, category, filename, lineno, file=None, line=None):
        print(f"{prog}: warning: {message}", file=sys.stderr if file is None else file)
    return show


def main(argv=None) -> int:
    """Entry point of ``lagcodegen``: returns the exit code (see the module doc)."""
    try:
        return run_command(sys.argv[1:] if argv is None else list(argv))
    except KeyboardInterrupt:
        print("\ninterrupted", file=sys.stderr)
        return EXIT_INTERRUPTED
    except BrokenPipeError:
        # The reader closed stdout (`lagcodegen derive X | head`): exit quietly. Point stdout at
        # devnull so the flush at interpreter exit does not raise again (Python docs, "Note on SIGPIPE").
        try:
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        except (OSError, ValueError, AttributeError):  # stdout is not a real file (e.g. captured in tests)
            pass
        return EXIT_BROKEN_PIPE


if __name__ == "__main__":
    sys.exit(main())
