"""Stage: ReducedKernel -> CSources (C header, C source and cffi cdef text).

The printer writes the maths; Jinja2 templates in ``templates/`` write the layout.
"""
from __future__ import annotations

import functools
import hashlib
from dataclasses import dataclass
from pathlib import Path

import jinja2
import sympy as sp

from ..model import sign_assumption
from ..status import STATUS_TABLE
from .csyntax import PROJECTION_STALL, UNIT_ROUNDOFF, EmitError, comment_text, literal
from .kernel_text import KernelWriter, Names, names_for
from .lane_kernel import lane_context
from .outputs import OUTPUTS, support_functions
from .printer import DEFAULT_TRIG, TRIG_MODES, CPrinter
from .reduce import ReducedSystem
from .steppers import stepper_context

__all__ = ["CSources", "EmitError", "KernelLayout", "render_sources", "template_dir", "comment_text",
           "trig_source"]


@dataclass(frozen=True)
class KernelLayout:
    """What the generated C expects and exports, index by index.

    Attributes
    ----------
    model : str
        The model's own name.
    prefix : str
        C identifier prefix of every exported name, ``lcg_<mangled model name>``.
    precision : str
        ``"double"`` or ``"float"``: the scalar type of every array.
    coordinates, speeds : tuple of str, (n,)
        ``x[i]`` = coordinates[i], ``x[n + i]`` = speeds[i].
    parameters : tuple of str
        Free parameters in ``p[]`` order.
    fixed : tuple of (str, float)
        Parameters folded into the code.
    points : tuple of str
        Named points whose positions the ``points`` function writes (3 values each).
    functions : tuple of str
        Exported C function names.
    methods : tuple of str
        Integration schemes compiled in; a method's number in ``simulate`` is its index here.
    defaults : tuple of (str, float)
        Default values of free parameters that have one.
    inputs : tuple of str
        Inputs in ``r[]`` order (empty: the functions take no ``r``).
    measurements : tuple of str
        Output expressions in ``y[]`` order.
    n_constraints, n_holonomic : int
        Constraints with multipliers (rows of ``<prefix>_residuals``), and how many of them, first,
        are holonomic (phi(q, t) = 0; the others are on the velocities alone).
    dependent_speeds : tuple of str
        Speeds eliminated by the velocity constraints (``<prefix>_dependent_speeds``), not in x.
    reactions : tuple of str
        Constraint forces from Kane's auxiliary speeds (``<prefix>_reactions``), in its ``out[]`` order.
    formulation : str
        A tree's formulation (closed form or recursive), why, and the estimated operations of
        both (`symbolic.trees.choose_formulation`); "" for other models.
    """

    model: str
    prefix: str
    precision: str
    coordinates: tuple
    speeds: tuple
    parameters: tuple
    fixed: tuple
    points: tuple
    functions: tuple
    methods: tuple = ()
    defaults: tuple = ()
    n_constraints: int = 0
    n_holonomic: int = 0
    inputs: tuple = ()
    measurements: tuple = ()
    dependent_speeds: tuple = ()
    reactions: tuple = ()
    formulation: str = ""
    signs: tuple = ()  # (name, "positive" ...): free parameters' sign assumptions (model.sign_assumption)

    @property
    def n_q(self) -> int:
        return len(self.coordinates)

    @property
    def n_u(self) -> int:
        return len(self.speeds)

    @property
    def n_state(self) -> int:
        return len(self.coordinates) + len(self.speeds)

    @property
    def n(self) -> int:
        """The common count of coordinates and speeds; an error when they differ (use n_q, n_u)."""
        if len(self.coordinates) != len(self.speeds):
            raise ValueError(f"model {self.model!r} has {len(self.coordinates)} coordinates and "
                             f"{len(self.speeds)} speeds: this step needs one speed per coordinate")
        return len(self.coordinates)


@dataclass(frozen=True)
class CSources:
    """Generated C text for one model: ``header`` (``header_name``), ``source`` and the cffi cdef;
    ``source_key`` is the digest of the layout and function bodies printed in their comments."""

    layout: KernelLayout
    header_name: str
    header: str
    source_name: str
    source: str
    cdef: str
    source_key: str



PRECISIONS = ("double", "float")


def template_dir() -> Path:
    """Where the Jinja2 templates live: inside the installed package (the wheel puts them at
    ``lagcodegen/templates``), else at the top of the source tree that holds the package."""
    import lagcodegen

    package = Path(lagcodegen.__file__).resolve().parent
    for candidate in (package / "templates", package.parent.parent / "templates"):
        if (candidate / "model.c.j2").is_file():
            return candidate
    raise FileNotFoundError(f"lagcodegen's templates (model.c.j2, ...) are neither in {package / 'templates'} "
                            f"nor in {package.parent.parent / 'templates'}: reinstall the package")


@functools.lru_cache(maxsize=1)
def template_environment() -> jinja2.Environment:
    """One environment per process: it keeps the compiled templates, which cost more than a
    render (the lane variant and every later model reuse them)."""
    return jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir())), undefined=jinja2.StrictUndefined,
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True, autoescape=False)


def render_sources(system: ReducedSystem, precision: str = "double", model_name: str | None = None,
                   methods=(), trig: str = DEFAULT_TRIG, lanes: int = 0, lane_trig: str = "fast") -> CSources:
    """Render the C header, source and cffi cdef of ``system``.

    Parameters
    ----------
    system : ReducedSystem
    precision : {"double", "float"}
        Scalar type of every array and literal (float: ``sinf``, ``1.0F``, no promotion).
    model_name : str, optional
        Name used for the C prefix; defaults to the model's name.
    methods : sequence of str
        Integration schemes (`schemes.SCHEMES`) to compile as ``step_<name>`` functions and into
        the ``simulate`` driver; needs the ``rhs`` output, implicit ones also ``jacobian``.
    trig : {"inline", "libm"}
        ``"inline"`` (default, `printer.DEFAULT_TRIG`): the inline functions of
        ``templates/trig.c.j2`` (below 1 ulp, sin and cos of one angle share the reduction);
        ``"libm"``: plain ``sin``/``cos`` calls.
        The source defines only the functions of that template it calls.
    lanes : int
        0: no lane kernel. Else also ``<prefix>_sweep_lanes``, which runs ``lanes`` members side by
        side for the explicit methods (see `lane_kernel.py`); host use, it is never in ``generated/``.
    lane_trig : {"fast", "libm"}
        sin/cos inside the lane loops: branch-free polynomials (vectorizable), or the scalar
        kernel's own (``trig``: libm calls or the inline forms; then the lane kernel equals the
        scalar sweep bit for bit, for tests; the name is from when the scalar default was libm).
    """
    if precision not in PRECISIONS:
        raise EmitError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    if trig not in TRIG_MODES:
        raise EmitError(f"trig must be one of {TRIG_MODES}, got {trig!r}")
    model_name = model_name or system.name
    names = names_for(system, model_name)
    printer = _KernelPrinter(precision=precision, names=names.symbols, trig=trig)
    real = precision
    writer = KernelWriter(system, names, printer, real)
    functions = support_functions(writer)
    written = [OUTPUTS[out].write(writer, system.kernel(OUTPUTS[out].kernel)) for out in system.outputs]
    functions += [f for f in written if f is not None]
    has_dynamics = any(OUTPUTS[out].kernel == "dynamics" for out in system.outputs)
    steppers = stepper_context(system, names, real, list(methods))
    steppers |= lane_context(system, names, real, list(methods), lanes, lane_trig, scalar_trig=trig)
    stepper_prototypes = [f for out in system.outputs for f in OUTPUTS[out].template_functions(writer)]
    stepper_prototypes += steppers.pop("exported")
    if steppers["has_lanes"]:
        stepper_prototypes.append(steppers["lane_prototype"])
    layout = _layout(system, names, real, model_name, functions + stepper_prototypes,
                     tuple(m["name"] for m in steppers["methods"]))
    context = _context(system, names, layout, functions, real, has_dynamics) | steppers
    context["prototypes"] = context["prototypes"] + stepper_prototypes
    context |= _trig_context(printer, steppers)
    # defined only where called (found by review: an eliminated model's dynamics never calls it, and
    # the unused static function failed the README's -Wall -Wextra -Werror build)
    failure_call = f"{names.prefix}_pivot_failure("
    context["uses_pivot_failure"] = has_dynamics and (context["has_symplectic_euler"] or any(
        failure_call in line for f in functions for line in f["body"]))
    context["needs_spd"] = bool((context["has_constraints"] and (context["has_dynamics"]
                                                                 or context["has_constraint_terms"]))
                                or context["has_symplectic_euler"])
    env = template_environment()
    header_name = f"{names.prefix}.h"
    source_name = f"{names.prefix}.c"
    context["header_name"] = header_name
    header = env.get_template("model.h.j2").render(context, template="model.h.j2")
    source = env.get_template("model.c.j2").render(context, template="model.c.j2")
    cdef = env.get_template("model.cdef.j2").render(context)
    return CSources(layout=layout, header_name=header_name, header=header, source_name=source_name,
                    source=source, cdef=cdef, source_key=context["key"])


class _KernelPrinter(CPrinter):
    """A `CPrinter` that also records which of sin and cos it printed (``trig_calls``), so the
    source defines exactly the inline functions it calls (`_trig_context`)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.trig_calls = set()

    def _print_trig(self, expr, name: str) -> str:
        self.trig_calls.add(name)
        return super()._print_trig(expr, name)


def _trig_context(printer: _KernelPrinter, steppers: dict) -> dict:
    """Which functions of templates/trig.c.j2 the source calls; it defines those and no others,
    since clang rejects an unused static function under -Wall -Werror (gcc does not warn for
    static inline ones). The kernels call lcg_sin/lcg_cos (float: lcg_sinf/lcg_cosf) only with
    trig="inline", and those call the branch-free _fast forms, as do the lane kernel's sin and
    cos wrappers (templates/lanes.c.j2, lane_trig="fast"). Nothing else does: with trig="libm"
    and no lanes (the committed generated/ files) the template is left out."""
    calls = printer.trig_calls if printer.trig == "inline" else set()
    emit = {f"emit_{name}": name in calls for name in ("sin", "cos")}
    emit |= {f"emit_{name}_fast": name in calls or steppers.get(f"lane_uses_{name}", False)
             for name in ("sin", "cos")}
    return {"has_trig": any(emit.values())} | emit | _trig_template_context(printer.precision)


def _trig_template_context(precision: str) -> dict:
    suffix = "f" if precision == "float" else ""
    return {"is_float": precision == "float", "trig_sin": f"lcg_sin{suffix}", "trig_cos": f"lcg_cos{suffix}",
            "mantissa_bits": 23 if precision == "float" else 52}


def trig_source(precision: str = "double") -> str:
    """The C text of ``templates/trig.c.j2`` alone, every function in it (needs ``<math.h>``),
    e.g. to test it."""
    if precision not in PRECISIONS:
        raise EmitError(f"precision must be one of {PRECISIONS}, got {precision!r}")
    every = {"emit_sin": True, "emit_cos": True, "emit_sin_fast": True, "emit_cos_fast": True}
    return template_environment().get_template("trig.c.j2").render(every | _trig_template_context(precision))


def _layout(system: ReducedSystem, names: Names, real: str, model_name: str, functions: list,
            methods: tuple) -> KernelLayout:
    exported = tuple(f["name"] for f in functions if not f["static"])
    return KernelLayout(
        model=model_name, prefix=names.prefix, precision=real,
        coordinates=tuple(s.name for s in system.q), speeds=tuple(s.name for s in system.u),
        parameters=tuple(s.name for s in system.free_parameters),
        fixed=tuple((s.name, v) for s, v in system.fixed_parameters),
        points=system.point_names, functions=exported, methods=methods, n_constraints=system.n_constraints,
        n_holonomic=system.n_holonomic,
        inputs=tuple(s.name for s in system.inputs), measurements=tuple(system.measurements),
        dependent_speeds=tuple(s.name for s in system.u_dependent), reactions=tuple(s.name for s in system.reactions),
        formulation=system.formulation,
        signs=tuple((p.name, sign_assumption(p)) for p in system.free_parameters if sign_assumption(p)),
        defaults=tuple((p.name, system.parameter_values[p]) for p in system.free_parameters
                       if p in system.parameter_values))


def _context(system: ReducedSystem, names: Names, layout: KernelLayout, functions: list, real: str,
             has_dynamics: bool) -> dict:
    from .. import __version__

    n_q, n = len(system.q), len(system.u)
    state_rows = [{"index": i, "name": comment_text(s.name), "c_name": names.symbols[s],
                   "kind": "coordinate" if i < n_q else "speed"}
                  for i, s in enumerate(system.q + system.u)]
    dependent_rows = [{"index": i, "name": comment_text(s.name)} for i, s in enumerate(system.u_dependent)]
    param_rows = [{"index": i, "name": comment_text(s.name), "c_name": names.symbols[s]}
                  for i, s in enumerate(system.free_parameters)]
    fixed_rows = [{"name": comment_text(s.name), "value": repr(v)} for s, v in system.fixed_parameters]
    point_rows = [{"index": 3 * i, "name": comment_text(name)} for i, name in enumerate(system.point_names)]
    key_text = repr((layout, [(f["decl"], f["body"]) for f in functions]))
    upper = names.prefix.upper()
    return {
        "version": __version__, "sympy_version": sp.__version__, "model": comment_text(layout.model),
        "route": system.route, "formulation": comment_text(system.formulation),
        "key": hashlib.sha256(key_text.encode()).hexdigest()[:16],
        "prefix": names.prefix, "guard": f"{upper}_H", "macro": upper, "real": real,
        "n_q": n_q, "n_u": n, "n_state": n_q + n, "n_params": len(param_rows), "n_points": len(point_rows),
        "state_rows": state_rows, "dependent_rows": dependent_rows, "param_rows": param_rows, "fixed_rows": fixed_rows,
        "point_rows": point_rows, "has_fixed": bool(fixed_rows),
        "status_codes": [{"name": row.c_name, "value": row.code, "doc": row.message} for row in STATUS_TABLE],
        "prototypes": [f for f in functions if not f["static"]], "functions": functions,
        "has_dynamics": has_dynamics,
        "has_hot": any(f["hot"] for f in functions), "has_shared": any(f["shared"] for f in functions),
        "has_constraints": system.n_constraints > 0, "n_constraints": system.n_constraints,
        "n_constraint_matrix": system.n_constraints * n, "n_constraints_squared": system.n_constraints ** 2,
        "has_constraint_terms": "constraints" in system.outputs,
        "constraint_tolerance": literal(1e-12 if real == "double" else 1e-6, real),
        "projection_stall": literal(PROJECTION_STALL * UNIT_ROUNDOFF[real], real),
        "projection_stall_text": f"{PROJECTION_STALL:g}",
        "projection_iterations": 10, "n_residuals": 2 * system.n_constraints,
        "n_multiplier_values": system.n_constraints + n,
        "rank_tolerance": literal(1e-12 if real == "double" else 1e-6, real),
    }


