"""Maintenance tool: write the C of every catalog example into ``generated/`` (and check it is fresh).

For each example: ``lcg_<name>.{h,c}`` in double, ``lcg_<name>_f32.{h,c}`` in float and a C test
``test_lcg_<name>.c`` (and ``_f32``) whose expected values come from sympy evaluation at 30
digits, an independent route from CSE, printing and compilation. Files are rewritten only
when their content changes.

    python tools/regenerate.py           # rewrite generated/ where it changed
    python tools/regenerate.py --check   # exit 1, listing the stale files, without writing

`tests/golden/test_generated.py` runs the same check (``--update-golden`` rewrites).
"""
from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import sympy as sp

from lagcodegen.catalog import EXAMPLES
from lagcodegen.codegen.outputs import applicable_methods, applicable_outputs
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import comment_text, render_sources, template_environment
from lagcodegen.integrators.schemes import required_outputs
from lagcodegen.symbolic.derive import EquationsOfMotion, derive_equations

#: time of the C tests' sample state (rheonomic models depend on it)
SAMPLE_TIME = 0.25
TOLERANCE = {"double": "1e-12", "float": "2e-4"}
#: outputs of the committed examples besides those their methods need (`schemes.required_outputs`)
EXAMPLE_OUTPUTS = ("mass_matrix", "forcing", "accel", "rhs", "energy", "points")
#: steppers compiled into the committed examples (embedded users get these step functions)
EXAMPLE_METHODS = ("rk4", "symplectic_euler", "implicit_midpoint")


@dataclass(frozen=True)
class SampleState:
    """A deterministic state, parameter values and sympy's 30-digit M, F and ud there."""

    x: tuple
    p: tuple
    M: tuple  # row-major n*n
    F: tuple
    ud: tuple


def sample_state(eom: EquationsOfMotion) -> SampleState:
    """Evaluate M, F and ud = M^-1 F with 30 significant digits at a fixed sample state."""
    n = eom.n
    q = [sp.Float(0.4 + 0.17 * i, 30) for i in range(n)]
    u = [sp.Float(0.3 - 0.11 * i, 30) for i in range(n)]
    p = [sp.Float(eom.parameter_values[s], 30) for s in eom.parameters]
    values = dict(zip(eom.q, q)) | dict(zip(eom.u, u)) | dict(zip(eom.parameters, p))
    values[eom.t] = sp.Float(SAMPLE_TIME, 30)
    M = eom.mass_matrix.xreplace(values).evalf(30)
    F = eom.forcing.xreplace(values).evalf(30)
    if eom.m:  # [M A^T; A 0] [ud; lambda] = [F; gamma]: Lagrange's equations of the first kind
        A = eom.constraint_jacobian.xreplace(values).evalf(30)
        gamma = eom.constraint_bias.xreplace(values).evalf(30)
        augmented = sp.Matrix(sp.BlockMatrix([[M, A.T], [A, sp.zeros(eom.m, eom.m)]]))
        ud = augmented.LUsolve(sp.Matrix.vstack(F, gamma))[:eom.n, 0].evalf(30)
    else:
        ud = M.LUsolve(F).evalf(30)
    return SampleState(x=tuple(q + u), p=tuple(p), M=tuple(M), F=tuple(F), ud=tuple(ud))


def example_files(name: str) -> dict:
    """File name -> text for one catalog example (double and float kernels and their C tests)."""
    eom = derive_equations(EXAMPLES[name]())
    methods = applicable_methods(eom, EXAMPLE_METHODS)  # constrained: rk4, multipliers and projection
    outputs = applicable_outputs(
        eom, EXAMPLE_OUTPUTS + tuple(o for o in required_outputs(methods) if o not in EXAMPLE_OUTPUTS))
    system = reduce_expressions(eom, outputs)
    sample = sample_state(eom)
    files = {}
    for precision, suffix in (("double", ""), ("float", "_f32")):
        sources = render_sources(system, precision, model_name=name + suffix, methods=methods)
        files[sources.header_name] = sources.header
        files[sources.source_name] = sources.source
        files[f"test_{sources.layout.prefix}.c"] = _c_test(sources, sample, precision)
    return files


def _numbers(values) -> str:
    return ", ".join(f"{float(v)!r}" for v in values) or "0.0"


def _c_test(sources, sample: SampleState, precision: str) -> str:
    layout = sources.layout
    literal = (lambda v: f"{float(v)!r}F") if precision == "float" else (lambda v: f"{float(v)!r}")
    context = {
        "version": _version(), "sympy_version": sp.__version__, "model": comment_text(layout.model),
        "key": sources.source_key, "prefix": layout.prefix,
        "header_name": sources.header_name, "real": precision, "n_u": layout.n_u,
        "n_state": layout.n_state, "n_matrix": layout.n_u * layout.n_u, "p_size": max(1, len(sample.p)),
        "state_values": ", ".join(map(literal, sample.x)),
        "param_values": ", ".join(map(literal, sample.p)) or literal(0),
        "mass_values": _numbers(sample.M), "forcing_values": _numbers(sample.F),
        "accel_values": _numbers(sample.ud), "time": literal(SAMPLE_TIME),
        "tolerance": TOLERANCE[precision],
    }
    return template_environment().get_template("test_model.c.j2").render(context, template="test_model.c.j2")


def _version() -> str:
    from lagcodegen import __version__
    return __version__


def write_generated(root: Path, names=None) -> list:
    """Write every example under ``root/<name>/``; return the paths whose content changed."""
    changed = []
    for name in names or EXAMPLES:
        folder = Path(root) / name
        folder.mkdir(parents=True, exist_ok=True)
        for filename, text in example_files(name).items():
            path = folder / filename
            if not path.exists() or path.read_text() != text:
                path.write_text(text)
                changed.append(path)
    return changed


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description="Write (or check) the committed C in generated/.")
    parser.add_argument("--check", action="store_true", help="only report stale files; exit 1 if any")
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parents[1] / "generated")
    args = parser.parse_args(argv)
    if not args.check:
        for path in write_generated(args.root):
            print(f"wrote {path}")
        return 0
    with tempfile.TemporaryDirectory() as fresh:
        write_generated(Path(fresh))
        stale = [str(path.relative_to(fresh)) for path in sorted(Path(fresh).rglob("*"))
                 if path.is_file() and (not (args.root / path.relative_to(fresh)).is_file()
                                        or (args.root / path.relative_to(fresh)).read_text() != path.read_text())]
    for name in stale:
        print(f"stale: generated/{name}")
    return 1 if stale else 0


if __name__ == "__main__":
    sys.exit(main())
