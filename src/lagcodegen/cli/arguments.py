"""Stage: cli (arguments). The parser class, number types, exit codes, the options of simulate
and sweep, and the parsers of ``NAME=VALUE`` lists, ``--grid`` axes and ``--table`` files.
No command runs here.

Every user error is a `UsageError` whose message names the culprit (the option and the value);
`lagcodegen.cli.commands.main` prints it as the one line ``lagcodegen <command>: error: <message>`` and
exits with `EXIT_USAGE`, the code and format argparse uses for its own errors.
"""
from __future__ import annotations

import argparse
import math
import re
import runpy
from pathlib import Path

#: exit codes of every subcommand
EXIT_OK = 0
EXIT_FAILED = 1       # the command line was fine, the work failed (a run stopped early, a build failed)
EXIT_USAGE = 2        # a bad command line, model name, file or value (argparse's code for its own errors)
EXIT_INTERRUPTED = 130  # Ctrl-C (128 + SIGINT, the shell convention)
EXIT_BROKEN_PIPE = 141  # stdout closed by the reader, e.g. `| head` (128 + SIGPIPE, the shell convention)

# A negative number as argparse's own `_negative_number_matcher` should see it (Python <= 3.12
# misses exponents: '-1e-3' is taken for an option), plus -inf / -nan so they reach the type check.
NEGATIVE_NUMBER = re.compile(r"-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?|-(inf|infinity|nan)", re.IGNORECASE)


class UsageError(Exception):
    """A bad command line: printed as one line naming the culprit, exit code `EXIT_USAGE`.

    ``prog`` is the command the message belongs to (``lagcodegen simulate``), when known.
    """

    def __init__(self, message: str, prog: str | None = None):
        super().__init__(message)
        self.prog = prog


class RunFailed(Exception):
    """The command line was fine but the work failed (e.g. a build): exit code `EXIT_FAILED`."""


class Parser(argparse.ArgumentParser):
    """`argparse.ArgumentParser` whose errors are `UsageError` (one line, no usage dump), so that
    argparse's errors and the commands' own print the same way (`lagcodegen.cli.commands.main`)."""

    def error(self, message: str):
        raise UsageError(f"{message} (see {self.prog} --help)", prog=self.prog)


def join_negative_numbers(argv) -> list[str]:
    """``["--h", "-1e-3"]`` -> ``["--h=-1e-3"]``: a long option followed by a negative number
    takes it as its value, which argparse reads as another option otherwise.

    A flag given a number this way still fails, with argparse's "ignored explicit argument".
    Tokens after a bare ``--`` are left alone.
    """
    argv, out, i = list(argv), [], 0
    while i < len(argv):
        token = argv[i]
        if token == "--":
            return out + argv[i:]
        if (token.startswith("--") and "=" not in token and i + 1 < len(argv)
                and NEGATIVE_NUMBER.fullmatch(argv[i + 1])):
            out.append(f"{token}={argv[i + 1]}")
            i += 2
        else:
            out.append(token)
            i += 1
    return out


def finite_float(text: str) -> float:
    """argparse type: a finite float (``inf`` and ``nan`` are refused with the text given)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
    return value


def positive_float(text: str) -> float:
    """argparse type: a finite float > 0."""
    value = finite_float(text)
    if not value > 0:
        raise argparse.ArgumentTypeError(f"must be > 0, got {text}")
    return value


def positive_int(text: str) -> int:
    """argparse type: an integer >= 1."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {text}")
    return value


def parse_names(text: str | None, option: str, known) -> list[str]:
    """``"rk4,heun"`` -> ``["rk4", "heun"]``, each checked against ``known`` (in order, no repeats)."""
    if text is None:
        return []
    names = [name.strip() for name in text.split(",")]
    for name in names:
        if not name:
            raise UsageError(f"{option} {text!r} has an empty name; give a comma-separated list of "
                             f"{', '.join(known)}")
        if name not in known:
            raise UsageError(f"{option}: unknown name {name!r}; choose from {', '.join(known)}")
    return list(dict.fromkeys(names))


def parse_assignments(items, option: str) -> dict:
    """``["k=10", "m=2"]`` or ``["k=10,m=2"]`` -> {"k": 10.0, "m": 2.0}; ``option`` names the
    flag in messages."""
    values = {}
    for item in items or []:
        if not item.strip():
            raise UsageError(f"{option} is given an empty value; it takes name=value[,name=value...]")
        for part in filter(str.strip, item.split(",")):
            name, sep, value = (s.strip() for s in part.partition("="))
            if not sep or not name:
                raise UsageError(f"{option} {part!r} must look like name=value")
            try:
                number = float(value)
            except ValueError:
                raise UsageError(f"{option} {name!r} has a non-numeric value {value!r}") from None
            if not math.isfinite(number):
                raise UsageError(f"{option} {name!r} must be finite, got {value!r}")
            if name in values:
                raise UsageError(f"{option} {name!r} is given twice")
            values[name] = number
    return values


def parse_inputs(items) -> dict | None:
    """``--input`` values: name -> a constant, or (times, values) from a CSV file of two columns
    (a header row is skipped); None when no --input was given."""
    if not items:
        return None
    inputs = {}
    for item in items:
        name, sep, value = (part.strip() for part in item.partition("="))
        if not sep or not name or not value:
            raise UsageError(f"--input {item!r} must look like name=value or name=table.csv")
        if name in inputs:
            raise UsageError(f"--input {name!r} is given twice")
        try:
            number = float(value)
        except ValueError:
            inputs[name] = _input_table(name, Path(value))
            continue
        if not math.isfinite(number):
            raise UsageError(f"--input {name!r} must be finite, got {value!r}")
        inputs[name] = number
    return inputs


def _input_table(name: str, path: Path) -> tuple:
    import numpy as np

    if not path.is_file():
        raise UsageError(f"--input {name}: {str(path)!r} is neither a number nor a file")
    try:
        rows = [line for line in path.read_text(encoding="utf-8-sig").splitlines() if line.strip()]
        if rows and not _numeric_row(rows[0]):
            rows = rows[1:]  # a header (found by review: a first row "-0.5,1" or ".5,1" was taken for one)
        table = np.array([[float(v) for v in row.split(",")] for row in rows], dtype=float)
    except (OSError, UnicodeDecodeError, ValueError) as error:
        raise UsageError(f"--input {name}: cannot read {path} as a CSV table of numbers ({error})") from None
    if table.ndim != 2 or table.shape[0] < 1 or table.shape[1] != 2:
        raise UsageError(f"--input {name}: {path} must have two columns (time, value), got shape {table.shape}")
    bad = np.flatnonzero(~np.isfinite(table).all(axis=1))
    if bad.size:  # before the compile (found by review: refused only after it)
        raise UsageError(f"--input {name}: {path} row {int(bad[0]) + 1} of its numbers, "
                         f"{', '.join(f'{v:g}' for v in table[bad[0]])}, is not finite")
    return table[:, 0], table[:, 1]


def _numeric_row(row: str) -> bool:
    try:
        [float(v) for v in row.split(",")]
    except ValueError:
        return False
    return True


def parse_axis(item: str) -> tuple:
    """``name=start:stop:count`` (linspace), ``name=start:stop:count:log`` (geomspace) or
    ``name=v1,v2,...`` (explicit values) -> (name, values)."""
    import numpy as np

    name, sep, spec = item.partition("=")
    name = name.strip()
    if not sep or not name or not spec.strip():
        raise UsageError(f"--grid {item!r} must look like name=start:stop:count[:log] or name=v1,v2,...")
    if ":" not in spec:
        values = spec.split(",")
        if not any(v.strip() for v in values):
            return name, np.array([], dtype=float)  # "has no values" (parse_grid)
        if any(not v.strip() for v in values):
            raise UsageError(f"--grid {name!r}: {spec!r} has an empty value (two commas, or one at an end)")
        try:
            return name, np.array([float(v) for v in values], dtype=float)
        except ValueError:
            raise UsageError(f"--grid {name!r}: {spec!r} is not a comma-separated list "
                             "of numbers") from None
    parts = [part.strip() for part in spec.split(":")]
    log = parts[-1].lower() == "log"
    numbers = parts[:-1] if log else parts
    try:
        start, stop, count = float(numbers[0]), float(numbers[1]), int(numbers[2])
        if len(numbers) != 3:
            raise ValueError
    except (ValueError, IndexError):
        raise UsageError(f"--grid {name!r}: {spec!r} must be start:stop:count or start:stop:count:log "
                         "(numbers start and stop, an integer count)") from None
    if count < 1:
        raise UsageError(f"--grid {name!r}: count must be at least 1, got {count}")
    if not (math.isfinite(start) and math.isfinite(stop)):  # found by review: inf reached numpy as nan
        raise UsageError(f"--grid {name!r}: start and stop must be finite, got {start:g}:{stop:g}")
    from ..run.arguments import output_limit

    if 8 * count > output_limit():  # found by review: 1e9 values were allocated, then "out of memory"
        raise UsageError(f"--grid {name!r}: {count} values alone would need {8 * count / 2 ** 30:.3g} GiB, more "
                         f"than the {output_limit() / 2 ** 30:.3g} GiB a run may take; give fewer")
    if log and not (start > 0 and stop > 0):
        raise UsageError(f"--grid {name!r}: a log axis needs positive start and stop, "
                         f"got {start:g}:{stop:g}")
    return name, (np.geomspace if log else np.linspace)(start, stop, count)


def parse_grid(items) -> dict:
    """Repeated ``--grid`` options -> {name: values}, in the given order (C order of members)."""
    grid = {}
    for item in items or []:
        name, values = parse_axis(item)
        if name in grid:
            raise UsageError(f"--grid {name!r} is given twice")
        if values.size == 0:
            raise UsageError(f"--grid {name!r} has no values")
        grid[name] = values
    return grid


def read_table(path: str) -> dict:
    """A CSV member table (header row of names, one member per row) -> {name: values}."""
    import csv

    import numpy as np

    try:
        with open(path, newline="", encoding="utf-8-sig") as handle:  # -sig: a spreadsheet's byte-order mark
            rows = [row for row in csv.reader(handle) if any(cell.strip() for cell in row)]
    except OSError as error:
        raise UsageError(f"--table {path}: {error.strerror}") from None
    except UnicodeDecodeError as error:  # found by review: the message named neither the file nor the option
        raise UsageError(f"--table {path}: not a UTF-8 text file (byte {error.start}: {error.reason})") from None
    if len(rows) < 2:
        raise UsageError(f"--table {path} needs a header row of names and at least one member row")
    header = [cell.strip() for cell in rows[0]]
    if len(set(header)) != len(header) or not all(header):
        raise UsageError(f"--table {path}: the header {header} must name each column once")
    table = {name: [] for name in header}
    for line, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise UsageError(f"--table {path} line {line} has {len(row)} values, the header {len(header)}")
        for name, cell in zip(header, row):
            try:
                value = float(cell)
            except ValueError:
                raise UsageError(f"--table {path} line {line}: {name} = {cell!r} is not a number") from None
            if not math.isfinite(value):  # found by review: "nan" passed here, to an error naming no line
                raise UsageError(f"--table {path} line {line}: {name} = {cell!r} is not finite")
            table[name].append(value)
    return {name: np.array(values) for name, values in table.items()}


SIMULATE_EPILOG = """examples:
  lagcodegen simulate double_pendulum --t-end 10 --h 1e-3 --x0 q1=1,q2=0.5 --energy --out run.npz --plot run.png
  lagcodegen simulate elastic_pendulum --t-end 20 --h 1e-3 --x0 r=1.3,phi=0.3 --param k=60 --fixed g=9.81
  lagcodegen simulate stiff_chain --t-end 1 --h 1e-4 --method implicit_midpoint --x0 x1=0.1,x2=0,x3=0

The .npz holds t (n_out,), x (n_out, 2n), names, energy (with --energy), points and point_names
(models with named points), inputs, input_names and hold (driven models), measurements and
measurement_names (models with measurements), residuals and multipliers (constrained models),
status, status_name, message, model, method, h, t_end, stride, x0, parameters and p (free parameter
values used), fixed_names and fixed_values.
Exit code 0 when the run completed, 1 when it stopped early (singular mass matrix, divergence) or the
build failed, 2 for a bad command line (one line on stderr naming the culprit).
"""

SWEEP_EPILOG = """grid syntax (--grid, repeatable; members are the Cartesian product, the first axis slowest):
  name=start:stop:count        count values, evenly spaced (numpy.linspace)
  name=start:stop:count:log    count values, geometrically spaced (numpy.geomspace; start, stop > 0)
  name=v1,v2,v3                these values
A name is a free parameter (not one given with --fixed) or a state variable (q1, q1_d, ...).
--table FILE.csv instead gives one member per row under a header row of names.

fields (--field, for the summary and the heatmap):
  q_max:<coordinate>   max |q| over the run      x_final:<state>   final value
  energy_error         max |E - E0| over the run blowup_time       time a failed member stopped
  steps_done           steps completed           status            the member's status code (below)
  y_final:<measurement>, y_min:<measurement>, y_max:<measurement>: a measurement's final, least, greatest value

status codes of members:
{status_codes}

examples:
  lagcodegen sweep elastic_pendulum --grid phi=0.05:1:20 --grid k=15:60:46 --x0 r=1.3 --t-end 60 \\
      --h 5e-3 --field q_max:r --out sweep.npz --heatmap sweep.png
  lagcodegen sweep double_pendulum --grid m2=0.5,1,2 --grid q1=0:3:31 --x0 q2=0 --t-end 10 \\
      --h 1e-3 --trajectories --stride 100 --out dp.npz
  lagcodegen sweep stiff_chain --grid k=0.5,1,2 --grid K=1e2:1e8:61:log --t-end 1 --h 1e-3 \\
      --x0 x1=0.1,x2=0,x3=0 --field status --heatmap stability.png
  lagcodegen sweep double_pendulum --table members.csv --x0 q1=1,q2=0 --t-end 5 --h 1e-3 \\
      --scheduler tcp://127.0.0.1:8786

The .npz holds every SweepResult array (values (n_members, n_columns), x_final, q_max, status,
steps_done, blowup_time, energy_error, and t, trajectories with --trajectories), grid_<name> axes
for a grid, columns, state_names, coordinate_names, completed, and the run's settings.
Exit code 0 when every member ran (members that stopped early say so in their status), 1 when the
build or a chunk of members failed, 2 for a bad command line (one line on stderr naming the culprit),
130 when interrupted (Ctrl-C; the finished members are still written).
"""


def _status_codes() -> str:
    """The members' status codes, from the status table (found by review: a hand-written list stopped
    at 5, without the inputs', the arguments' and the sweep's own codes)."""
    import textwrap

    from ..status import STATUS_TABLE, SWEEP_STATUS_TABLE

    text = ", ".join(f"{row.code} {row.name.lower().replace('_', ' ')}" for row in STATUS_TABLE + SWEEP_STATUS_TABLE
                     if row.name != "UNKNOWN_METHOD")
    return textwrap.fill(text, 100, initial_indent="  ", subsequent_indent="  ")


SWEEP_EPILOG = SWEEP_EPILOG.format(status_codes=_status_codes())


def add_run_arguments(parser, default_h: float | None = None) -> None:
    """Options shared by simulate, sweep and animate (``--h`` is required unless ``default_h``)."""
    from ..integrators.schemes import SCHEMES

    parser.add_argument("model", help="example name (list: lagcodegen examples) or model file")
    parser.add_argument("--t-end", type=positive_float, required=True, metavar="T",
                        help="end time (t starts at 0; T must be a whole number of steps H)")
    parser.add_argument("--h", type=positive_float, required=default_h is None, default=default_h, metavar="H",
                        help="fixed step size" + (f" (default: {default_h:g})" if default_h is not None else ""))
    parser.add_argument("--method", default="rk4", choices=tuple(SCHEMES),
                        help="integrator, compiled in alone (default: rk4)")
    parser.add_argument("--x0", action="append", metavar="NAME=VALUE",
                        help="initial state, e.g. --x0 q1=1,q2=0.5; every coordinate needs a value "
                             "(speeds default to 0)")
    parser.add_argument("--param", "--params", dest="param", action="append", metavar="NAME=VALUE",
                        help="value of a free parameter (repeatable or comma-separated; "
                             "others keep the model's defaults)")
    parser.add_argument("--fixed", action="append", metavar="NAME=VALUE",
                        help="fold a parameter into the C code as a constant (repeatable or comma-separated)")
    parser.add_argument("--stride", type=positive_int, default=1, metavar="K",
                        help="keep every K-th state of a trajectory (default: 1)")
    parser.add_argument("--input", action="append", metavar="NAME=VALUE|NAME=FILE.csv",
                        help="driven models: an input held constant (--input tau=0.5) or read from a CSV "
                             "table of time and value columns, interpolated linearly (--input tau=torque.csv); "
                             "repeatable")
    parser.add_argument("--hold", choices=("zoh", "foh"), default="zoh",
                        help="inputs over a step: held at the step's start (zoh, default) or on a line to its "
                             "end (foh)")
    parser.add_argument("--project", action="store_true",
                        help="models with holonomic constraints: project the state back onto them after every "
                             "step (Baumgarte instead: --param baumgarte_alpha=10,baumgarte_beta=10)")


def load_model(spec: str):
    """A catalog example by name, or the ``model`` / ``build_model()`` of a Python file."""
    from ..catalog import EXAMPLES
    from ..model import Model

    if spec in EXAMPLES:
        return EXAMPLES[spec]()
    path = Path(spec)
    if not spec.strip() or not path.is_file():
        raise UsageError(f"model {spec!r} is neither an example ({', '.join(EXAMPLES)}) nor a file")
    try:
        namespace = runpy.run_path(str(path))
        model = namespace.get("model")
        if model is None and callable(namespace.get("build_model")):
            model = namespace["build_model"]()
    except SystemExit as error:  # found by review: sys.exit(0) in the file ended the command, exit 0, nothing done
        raise UsageError(f"model file {path} called sys.exit({error.code!r}) instead of defining `model` or "
                         "`build_model()`") from error
    except Exception as error:  # the user's own code, whatever it raises: name the file and the error
        raise UsageError(f"model file {path} failed: {type(error).__name__}: {error}") from error
    if not isinstance(model, Model):
        raise UsageError(f"model file {path} must define `model` (a lagcodegen.Model) or `build_model()`")
    return model
