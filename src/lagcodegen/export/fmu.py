"""Stage: Model / CompiledSystem -> an FMI 2.0 or 3.0 FMU (Model Exchange and Co-Simulation in one).

The FMU holds the model's generated C kernel (the same text `render_sources` emits and
`compile_model` builds), a wrapper rendered from ``templates/fmi2.c.j2`` or ``fmi3.c.j2`` that
implements the FMI functions on it, ``modelDescription.xml`` (`description.py`, from the variable
table of `variables.py`) and a binary for the host platform built from those sources. The binary
is built by the project's C compiler and flags (`build.DEFAULT_FLAGS`); the sources build it again
with any other toolchain (FMI 2.0 lists them in the model description, FMI 3.0 in
``sources/buildDescription.xml``; FMPy's ``build_platform_binary`` reads either).
"""
from __future__ import annotations

import hashlib
import math
import numbers
import os
import platform
import re
import secrets
import shlex
import subprocess
import sys
import tempfile
import uuid
import zipfile
from collections.abc import Mapping
from pathlib import Path

from .. import __version__
from ..codegen.csyntax import comment_text
from ..codegen.outputs import applicable_outputs
from ..codegen.reduce import reduce_expressions
from ..codegen.render import CSources, render_sources, template_environment
from ..integrators.schemes import get_scheme, required_outputs
from ..model import Model
from ..native.build import DEFAULT_FLAGS, BuildError, CompiledSystem, _compiler_command
from ..run.arguments import keyed_by_name
from ..status import STATUS_TABLE
from ..symbolic.derive import EquationsOfMotion, derive_equations
from .description import build_description, model_description, model_description_fmi3
from .variables import fmi_variables

#: outputs the FMU exposes, when the model has them
FMU_OUTPUTS = ("rhs", "energy", "points", "measurements")
FMI_VERSIONS = ("2.0", "3.0")
#: (sys.platform prefix, machine) -> (FMI 2.0 binaries folder, FMI 3.0 binaries folder, library suffix)
PLATFORMS = {("linux", "x86_64"): ("linux64", "x86_64-linux", ".so"),
             ("linux", "aarch64"): (None, "aarch64-linux", ".so"),
             ("darwin", "x86_64"): ("darwin64", "x86_64-darwin", ".dylib"),
             ("darwin", "arm64"): ("darwin64", "aarch64-darwin", ".dylib"),
             ("win32", "AMD64"): ("win64", "x86_64-windows", ".dll")}
#: the FMI 3.0 functions the wrapper defines from one pattern each (templates/fmi3.c.j2)
FMI3_OTHER_TYPES = ("Float32", "Int8", "UInt8", "Int16", "UInt16", "Int32", "UInt32", "Int64", "UInt64",
                    "Boolean", "String")
FMI3_DERIVATIVE_FUNCTIONS = ("GetDirectionalDerivative", "GetAdjointDerivative")
FMI3_CONFIGURATION_FUNCTIONS = ("EnterConfigurationMode", "ExitConfigurationMode")
#: a zip entry's time stamp: fixed, so that the same model gives the same archive listing
ZIP_TIME = (1980, 1, 1, 0, 0, 0)


class FmuError(ValueError):
    """An FMU cannot be made from these arguments; the message names the culprit."""


#: characters XML 1.0 does not allow (ElementTree writes them through, and every importer's parser
#: then fails naming only a line and column: found by review)
_NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def _check_xml_text(model_name: str, table) -> None:
    """An FmuError naming the model or variable whose name or description XML cannot hold."""
    texts = [("the model name", model_name)]
    texts += [(f"the name of FMI variable {v.name!r}", v.name) for v in table.variables]
    texts += [(f"the description of FMI variable {v.name!r}", v.description) for v in table.variables]
    for what, text in texts:
        found = _NOT_XML.search(text or "")
        if found:
            raise FmuError(f"{what} holds the character {found.group()!r} (U+{ord(found.group()):04X}), which "
                           "modelDescription.xml cannot hold: rename it")


def export_fmu(model, path, *, method: str = "rk4", step: float = 1e-3, x0=None, params: Mapping | None = None,
               fixed: Mapping | None = None, fmi_version: str = "2.0", binary: bool = True,
               compiler: str | None = None) -> Path:
    """Write an FMI 2.0 or 3.0 FMU (Model Exchange and Co-Simulation) of ``model`` to ``path``.

    Parameters
    ----------
    model : Model, EquationsOfMotion or CompiledSystem
        A CompiledSystem (`pipeline.compile_model`) lends its C sources unchanged, so the FMU
        steps exactly as its `simulate` does; it must be double precision and have ``method``.
    path : str or Path
        The ``.fmu`` file to write (replaced if it exists; its folder must exist).
    method : str
        The Co-Simulation integrator (`schemes.SCHEMES`); Model Exchange leaves integration to
        the importer.
    step : float
        Start value of the FMU's ``step_size`` parameter: the fixed step of ``method`` inside
        ``fmi2DoStep``. An interval that is not a whole number of steps ends with one shorter step.
    x0 : sequence (2n,) or mapping name -> value, optional
        Start values of the states (coordinates, then speeds); unnamed ones are 0.
    params : mapping name -> float, optional
        Start values of the free parameters (tunable in the FMU); default: the model's values.
        A free parameter with neither has no FMI start value: `FmuError` naming it.
    fixed : mapping name -> float, optional
        Parameters folded into the C as constants (Model or EquationsOfMotion only); the FMU
        shows them as read-only constants.
    fmi_version : {"2.0", "3.0"}
    binary : bool
        Build ``binaries/<platform>/<identifier>`` for this host (else sources only).
    compiler : str, optional
        The C compiler command; default ``$CC``, else Python's, else ``cc``.

    Returns
    -------
    Path of the written FMU.

    Examples
    --------
    The double pendulum's FMU, sources only (``binary=True``, the default, adds this host's):

    >>> import pathlib, tempfile, zipfile
    >>> from lagcodegen.catalog import double_pendulum
    >>> from lagcodegen.export import export_fmu
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> fmu = export_fmu(double_pendulum(), folder / "pendulum.fmu", x0={"q1": 1.0}, binary=False)
    >>> sorted(zipfile.ZipFile(fmu).namelist())  # doctest: +NORMALIZE_WHITESPACE
    ['modelDescription.xml', 'sources/lcg_double_pendulum.c', 'sources/lcg_double_pendulum.h',
     'sources/lcg_double_pendulum_fmi2.c']
    """
    target = _checked_path(path)
    if fmi_version not in FMI_VERSIONS:
        raise FmuError(f"fmi_version must be one of {', '.join(FMI_VERSIONS)}, got {fmi_version!r}")
    get_scheme(method)  # a KeyError naming the method and the known ones
    step = _positive_step(step)
    folder = _platform_folder(fmi_version) if binary else None
    sources = _kernel_sources(model, method, fixed)
    layout = sources.layout
    table = fmi_variables(layout, _state_start(layout, x0), _parameter_start(layout, params), step, method=method,
                          has_energy=f"{layout.prefix}_energy" in layout.functions, fmi_version=fmi_version)
    _check_xml_text(layout.model, table)
    guid = _guid(sources, table, method)
    wrapper_name = f"{layout.prefix}_fmi{fmi_version[0]}.c"
    wrapper = _wrapper_source(sources, table, guid, method, step, wrapper_name, fmi_version)
    files = {f"sources/{sources.header_name}": sources.header, f"sources/{sources.source_name}": sources.source,
             f"sources/{wrapper_name}": wrapper}
    about = dict(model_name=layout.model, identifier=layout.prefix, tool=f"lagcodegen {__version__}", step=step,
                 constrained=bool(layout.n_constraints),
                 description=f"{layout.model}: Lagrange's equations, {method} at step_size in Co-Simulation")
    if fmi_version == "2.0":
        description = model_description(table, guid=guid, sources=(sources.source_name, wrapper_name), **about)
    else:
        description = model_description_fmi3(table, token=guid, **about)
    members = {"modelDescription.xml": description.encode("utf-8")}
    members |= {name: text.encode("utf-8") for name, text in files.items()}
    if fmi_version == "3.0":
        members["sources/buildDescription.xml"] = build_description(
            layout.prefix, (sources.source_name, wrapper_name)).encode("utf-8")
    if folder is not None:
        name, suffix = folder
        members[f"binaries/{name}/{layout.prefix}{suffix}"] = _build_binary(files, layout.prefix + suffix, compiler)
    _write_zip(target, members)
    return target


def _checked_path(path) -> Path:
    if not isinstance(path, (str, os.PathLike)) or not str(path).strip():
        raise FmuError(f"the FMU path must be a file name, got {path!r}")
    target = Path(path)
    if target.is_dir():
        raise FmuError(f"FMU path {str(path)!r} is a directory; give a file name such as {str(target / 'model.fmu')!r}")
    if not target.parent.is_dir():
        raise FmuError(f"FMU path {str(path)!r}: its folder {str(target.parent)!r} does not exist")
    if target.exists() and not target.is_file():  # a device or a FIFO (/dev/null) would be replaced by a file
        raise FmuError(f"FMU path {str(path)!r} exists and is not a regular file; give a file name")
    if target.suffix.lower() != ".fmu":  # the standard's extension; found by review: the model's own .py was replaced
        raise FmuError(f"FMU path {str(path)!r}: give a file name ending in .fmu")
    return target


def _positive_step(step) -> float:
    if isinstance(step, bool) or not isinstance(step, numbers.Real) or not math.isfinite(step) or step <= 0:
        raise FmuError(f"step must be a positive finite number, got {step!r}")
    return float(step)


def _kernel_sources(model, method: str, fixed) -> CSources:
    """The kernel's C: a CompiledSystem's own, or rendered for ``method`` with the FMU's outputs."""
    if isinstance(model, CompiledSystem):
        layout = model.layout
        if fixed:
            raise FmuError(f"fixed= applies when the FMU renders the model; {layout.model!r} is already compiled "
                           f"(with fixed parameters {dict(layout.fixed) or 'none'})")
        if layout.precision != "double":
            raise FmuError(f"model {layout.model!r} is compiled in {layout.precision} precision; FMI Reals are "
                           f"double: compile it with precision='double'")
        if method not in layout.methods:
            raise FmuError(f"method {method!r} is not compiled into {layout.model!r} (methods: "
                           f"{', '.join(layout.methods) or 'none'})")
        if f"{layout.prefix}_rhs" not in layout.functions:
            raise FmuError(f"model {layout.model!r} is compiled without its rhs, which Model Exchange needs")
        for output, present in (("points", layout.points), ("measurements", layout.measurements)):
            if present and f"{layout.prefix}_{output}" not in layout.functions:
                raise FmuError(f"model {layout.model!r} is compiled without its {output!r} output, which the FMU's "
                               f"outputs read: compile it with outputs=(..., {output!r}), or export the Model")
        return model.sources
    if isinstance(model, Model):
        model = derive_equations(model)
    if not isinstance(model, EquationsOfMotion):
        raise FmuError(f"export_fmu needs a Model, EquationsOfMotion or CompiledSystem, got {type(model).__name__}")
    outputs = applicable_outputs(model, FMU_OUTPUTS)
    outputs += [o for o in required_outputs((method,)) if o not in outputs]
    fixed_values = keyed_by_name(fixed or {}, "fixed")
    return render_sources(reduce_expressions(model, outputs, fixed_values), "double", methods=(method,))


def _state_start(layout, x0) -> list:
    names = layout.coordinates + layout.speeds
    if x0 is None:
        return [0.0] * len(names)
    if isinstance(x0, Mapping):
        x0 = keyed_by_name(x0, "x0")
        unknown = [k for k in x0 if k not in names]
        if unknown:
            raise FmuError(f"x0: {unknown[0]!r} is not a state of {layout.model!r}; states: {', '.join(names)}")
        values = [x0.get(name, 0.0) for name in names]
    else:
        values = list(x0)
        if len(values) != len(names):
            raise FmuError(f"x0 needs {len(names)} values ({', '.join(names)}), got {len(values)}")
    return [_real(value, f"x0[{name!r}]") for name, value in zip(names, values)]


def _parameter_start(layout, params) -> list:
    given = keyed_by_name(params or {}, "params")
    fixed = dict(layout.fixed)
    for name in given:
        if name in fixed:
            raise FmuError(f"parameter {name!r} is folded into the C as {fixed[name]!r}; it cannot be given a start "
                           f"value (free parameters: {', '.join(layout.parameters) or 'none'})")
        if name not in layout.parameters:
            raise FmuError(f"{name!r} is not a free parameter of {layout.model!r} (free parameters: "
                           f"{', '.join(layout.parameters) or 'none'})")
    values = dict(layout.defaults) | given
    missing = [name for name in layout.parameters if name not in values]
    if missing:
        raise FmuError(f"parameter(s) {', '.join(map(repr, missing))} of {layout.model!r} have no value, and an FMI "
                       f"parameter needs a constant start value: give params={{{missing[0]!r}: ...}} or a value "
                       f"in the model's parameter_values")
    return [_real(values[name], f"parameter {name!r}") for name in layout.parameters]


def _real(value, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
        raise FmuError(f"{what} must be a finite real number (an FMI start value), got {value!r}")
    return float(value)


def _guid(sources: CSources, table, method: str) -> str:
    digest = hashlib.sha256(repr((sources.header, sources.source, table, method, __version__)).encode())
    return "{" + str(uuid.UUID(bytes=digest.digest()[:16])) + "}"


def _wrapper_source(sources: CSources, table, guid: str, method: str, step: float, source_name: str,
                    fmi_version: str) -> str:
    layout = sources.layout
    numbers_of = lambda kind: ", ".join(repr(float(v.start)) for v in table.of_kind(kind)) or "0.0"  # noqa: E731
    context = {
        "version": __version__, "model": comment_text(layout.model), "prefix": layout.prefix,
        "macro": layout.prefix.upper(), "header_name": sources.header_name, "source_name": source_name,
        "key": sources.source_key, "guid": guid, "method": method, "n_state": layout.n_state,
        "p_size": max(1, len(layout.parameters)), "r_size": max(1, len(layout.inputs)),
        "point_size": max(1, 3 * len(layout.points)), "y_size": max(1, len(layout.measurements)),
        "fixed_size": max(1, len(layout.fixed)), "has_fixed": bool(layout.fixed),
        "x_start": numbers_of("state"), "p_start": numbers_of("parameter"), "fixed_values": numbers_of("fixed"),
        "h_start": repr(float(step)), "vr": table.ranges,
        "r_argument": "c->r, " if layout.inputs else "",
        "method_macro": f"{layout.prefix.upper()}_METHOD_{method.upper()}",
        "has_energy": bool(table.of_kind("energy")), "has_points": bool(layout.points),
        "has_measurements": bool(layout.measurements),
        "n_constraints": layout.n_constraints if f"{layout.prefix}_residuals" in layout.functions else 0,
        "status_codes": [{"value": row.code, "doc": row.message} for row in STATUS_TABLE],
        "other_types": FMI3_OTHER_TYPES, "derivative_functions": FMI3_DERIVATIVE_FUNCTIONS,
        "configuration_functions": FMI3_CONFIGURATION_FUNCTIONS,
    }
    template = "fmi2.c.j2" if fmi_version == "2.0" else "fmi3.c.j2"
    return template_environment().get_template(template).render(context)


def _platform_folder(fmi_version: str) -> tuple:
    """(binaries folder, library suffix) of this host in ``fmi_version``."""
    machine = platform.machine()
    for (system, arch), (fmi2, fmi3, suffix) in PLATFORMS.items():
        folder = fmi2 if fmi_version == "2.0" else fmi3
        if sys.platform.startswith(system) and machine == arch and folder:
            return folder, suffix
    raise FmuError(f"FMI {fmi_version} names no binaries folder for {sys.platform} on {machine}; export with "
                   f"binary=False and build the FMU from its sources on the importing side")


def _build_binary(files: dict, so_name: str, compiler: str | None) -> bytes:
    """Compile the FMU's sources into one shared library; `BuildError` with the compiler's output."""
    command = _compiler_command(compiler)  # the project's compiler ($CC, Python's, cc), as build_module's
    with tempfile.TemporaryDirectory(prefix="lagcodegen_fmu_") as tmp:
        folder = Path(tmp)
        for name, text in files.items():
            (folder / Path(name).name).write_text(text)
        c_files = [str(folder / Path(name).name) for name in files if name.endswith(".c")]
        # hidden: only the fmi* functions are exported (FMI2_Export / FMI3_Export), so the kernel's own calls
        # bind to this FMU's kernel, never to a same-named one another FMU or the host exports first
        argv = [*command, *DEFAULT_FLAGS, "-fPIC", "-shared", "-fvisibility=hidden", "-I", str(folder), *c_files,
                "-o", str(folder / so_name), "-lm"]
        try:
            run = subprocess.run(argv, capture_output=True, text=True)
        except OSError as error:
            raise BuildError(f"cannot run the C compiler {shlex.join(command)!r}: {error}",
                             command=shlex.join(argv)) from None
        if run.returncode != 0:
            raise BuildError(f"building the FMU binary failed\ncommand: {shlex.join(argv)}\n{run.stderr.rstrip()}",
                             command=shlex.join(argv), stderr=run.stderr)
        return (folder / so_name).read_bytes()


def _write_zip(target: Path, members: dict) -> None:
    """Write the archive beside ``target``, then move it there (a reader never sees half an FMU), with
    the mode a new file gets under the umask (mkstemp's would be 0600). An OSError is an FmuError naming
    ``target``, not the temporary file."""
    temporary = None
    try:
        candidate = target.parent / f".{target.name}.{secrets.token_hex(8)}.tmp"
        os.close(os.open(candidate, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))  # the umask applies
        temporary = str(candidate)
        with zipfile.ZipFile(temporary, "w", zipfile.ZIP_DEFLATED) as archive:
            for name, data in members.items():
                info = zipfile.ZipInfo(name, ZIP_TIME)
                info.compress_type = zipfile.ZIP_DEFLATED
                info.external_attr = 0o644 << 16
                archive.writestr(info, data)
        os.replace(temporary, target)
    except OSError as error:
        raise FmuError(f"cannot write the FMU {str(target)!r}: {error.strerror or error}") from None
    finally:
        if temporary is not None and os.path.exists(temporary):
            os.unlink(temporary)
