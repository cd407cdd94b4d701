"""Stage: cli -> files. The ``fmu`` subcommand: write an FMI 2.0 or 3.0 FMU of a model (`export.export_fmu`)."""
from __future__ import annotations

import argparse

from .arguments import EXIT_OK, RunFailed, UsageError, load_model, parse_assignments, positive_float

FMU_EPILOG = """examples:
  lagcodegen fmu double_pendulum --out double_pendulum.fmu --x0 q1=1,q2=0.5
  lagcodegen fmu my_model.py --out plant.fmu --method symplectic_euler --h 1e-4 --param k=20
  lagcodegen fmu double_pendulum --out double_pendulum.fmu --fmi-version 3.0

The FMU holds Model Exchange (states, derivatives) and Co-Simulation (METHOD at the fixed step
H, the FMU's step_size parameter) in one modelDescription.xml, the C sources and a binary for
this platform. Free parameters are tunable FMI parameters; --fixed folds some into the C."""


def cmd_fmu(args) -> int:
    from ..export.fmu import export_fmu
    from ..native.build import BuildError

    if not args.out.strip():
        raise UsageError("--out is given an empty file name")
    model = load_model(args.model)
    try:
        path = export_fmu(model, args.out, method=args.method, step=args.h,
                          x0=parse_assignments(args.x0, "--x0"), params=parse_assignments(args.param, "--param"),
                          fixed=parse_assignments(args.fixed, "--fixed") or None, fmi_version=args.fmi_version,
                          binary=not args.no_binary)
    except BuildError as error:
        raise RunFailed(f"building the FMU of {model.name} failed: {error}") from None
    print(f"wrote {path} (FMI {args.fmi_version}, Model Exchange and Co-Simulation with {args.method} at "
          f"step_size {args.h:g})")
    return EXIT_OK


def add_fmu_command(commands) -> None:
    """Register ``lagcodegen fmu`` on ``commands`` (argparse subparsers)."""
    from ..integrators.schemes import SCHEMES

    fmu = commands.add_parser(
        "fmu", help="write an FMI 2.0 or 3.0 FMU (Model Exchange and Co-Simulation) with sources and a binary",
        description="Write an FMI 2.0 (or 3.0) FMU of MODEL: Model Exchange and Co-Simulation in one file.",
        epilog=FMU_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    fmu.add_argument("model", help="example name (list: lagcodegen examples) or model file")
    fmu.add_argument("--out", required=True, metavar="FILE.fmu", help="the FMU to write (replaced if it exists)")
    fmu.add_argument("--method", default="rk4", choices=tuple(SCHEMES), help="Co-Simulation integrator (default: rk4)")
    fmu.add_argument("--h", type=positive_float, default=1e-3, metavar="H",
                     help="start value of the step_size parameter, the Co-Simulation fixed step (default: 1e-3)")
    fmu.add_argument("--x0", action="append", metavar="NAME=VALUE",
                     help="start values of the states (unnamed ones: 0)")
    fmu.add_argument("--param", "--params", dest="param", action="append", metavar="NAME=VALUE",
                     help="start values of free parameters (default: the model's)")
    fmu.add_argument("--fixed", action="append", metavar="NAME=VALUE",
                     help="fold a parameter into the C code as a constant (repeatable or comma-separated)")
    fmu.add_argument("--fmi-version", choices=("2.0", "3.0"), default="2.0", help="FMI version (default: 2.0)")
    fmu.add_argument("--no-binary", action="store_true", help="sources only, no binary for this platform")
    fmu.set_defaults(run=cmd_fmu)
