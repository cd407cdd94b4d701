"""Helper: the whole pipeline in one call, Model -> CompiledSystem.

``compile_model`` chains the stages (derive, reduce, render, build) with their defaults; each
stage stays callable on its own for users who want to inspect or change what passes between.
The rendered sources are cached on disk beside the built modules, keyed by the derived equations
and every option, so loading an unchanged model again skips CSE and rendering as well as gcc.
A sources entry is plain JSON (nothing runs on load) after a line with its sha256: any damaged
byte makes it render again and replace the entry, never compile stale or edited C. A model
stated in plain expressions (a tree, or the energies route) is also keyed before it is derived:
a model entry names its sources entry, so loading it again skips the derivation too.
"""
from __future__ import annotations

import dataclasses
import functools
import hashlib
import io
import json
import math
import numbers
import os
import pickle
import tempfile
import types
import warnings
from collections.abc import Mapping
from dataclasses import replace
from pathlib import Path

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef, UndefinedFunction

from . import __version__
from .codegen.kernel_text import PART_ASSIGNMENTS
from .codegen.lane_kernel import DEFAULT_LANES, lanes_apply
from .codegen.outputs import KernelError, applicable_methods, applicable_outputs
from .codegen.printer import DEFAULT_TRIG
from .codegen.reduce import reduce_expressions
from .codegen.render import CSources, KernelLayout, render_sources, template_dir
from .integrators.schemes import DEFAULT_METHODS, required_outputs
from .model import ROUTE_TREE, Model, sign_assumption, sign_error
from .native import cache
from .native.build import CompiledSystem, build_module
from .native.build_cost import estimate_build_cost
from .symbolic.derive import EquationsOfMotion, check_derived, derive_equations
from .symbolic.trees import derive_from_tree

SIMULATION_OUTPUTS = ("rhs", "energy", "points", "jacobian", "measurements", "reactions", "configuration")


def compile_model(model: Model | EquationsOfMotion, *, outputs=None, fixed: Mapping | None = None,
                  methods=DEFAULT_METHODS, precision: str = "double", trig: str = DEFAULT_TRIG,
                  cache_dir=None, extra_compile_args=(), lanes: int = DEFAULT_LANES,
                  lane_trig: str = "fast") -> CompiledSystem:
    """Derive (if given a Model), CSE, emit and compile the kernels of one model.

    Parameters
    ----------
    model : Model or EquationsOfMotion
    outputs : str or sequence of str, optional
        Kernel outputs (one name: that output alone); default ``SIMULATION_OUTPUTS`` (without
        ``energy`` when the model has no energies, without ``jacobian`` when no implicit method
        is requested). The outputs the
        methods need (``rhs``; ``jacobian`` for implicit ones; ``momentum`` for symplectic Euler)
        are always added, and those simulate checks a constrained run with (``constraints``,
        ``configuration``) where they apply.
    fixed : mapping parameter (Symbol or name) -> real number, optional
        Parameters folded into the code; the rest stay runtime inputs. A value that is not a
        finite real number, or a name that is not a parameter, raises ``KernelError`` naming it.
    methods : str or sequence of str
        Integration schemes to compile in (`schemes.SCHEMES`; one name: that scheme alone).
    precision : {"double", "float"}
    trig : {"inline", "libm"}
        How sine and cosine are computed (`render.render_sources`): the inline polynomials of
        ``templates/trig.c.j2`` (default) or libm calls.
    lanes : int
        Members per vector group of the lane sweep kernel (``sweep`` uses it for explicit methods
        of unconstrained models); 0: none. Its sources are rendered here, but compiled only when a
        sweep first needs them (`CompiledSystem.lane_variant`): it doubles the compile time.
    lane_trig : {"fast", "libm"}
        sin/cos in the lane kernel: vectorizable polynomials, or the scalar kernel's own (``trig``;
        bitwise equal to its scalar sweep, slower); see `render_sources`.

    Warns
    -----
    BuildCostWarning
        The module has to be compiled and the estimated compile time or memory is high
        (`build_cost.estimate_build_cost`); the message names cheaper options.

    Examples
    --------
    The mass on a spring, with only RK4 compiled in (a short build):

    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from lagcodegen import Model
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0})
    >>> from lagcodegen.pipeline import compile_model
    >>> system = compile_model(model, methods=("rk4",))
    >>> system.layout.parameters, system.layout.methods
    (('m', 'k'), ('rk4',))
    """
    # one name is that one (a str is a sequence too: "rhs" read as the outputs 'r', 'h', 's')
    outputs = (outputs,) if isinstance(outputs, str) else outputs
    methods = (methods,) if isinstance(methods, str) else methods
    # once: a generator keyed the entry and was then empty for the build, which the cache kept under
    # the full list (found by review: "compiled: none" for a later list in the same cache)
    outputs = None if outputs is None else tuple(outputs)
    methods = tuple(methods)
    alias = _model_entry(model, outputs, fixed, methods, precision, (trig, lanes, lane_trig), cache_dir)
    stored = _load_sources(*_aliased_sources(alias, cache_dir)) if alias is not None else None
    if stored is not None:
        sources, with_lanes, ops = stored
        return _build(model.name, sources, with_lanes, ops, cache_dir, extra_compile_args)
    eom = model if isinstance(model, EquationsOfMotion) else _derive(model, methods, outputs)
    methods = tuple(methods)
    if methods == DEFAULT_METHODS:  # the defaults that apply; a method asked for by name is checked instead
        methods = applicable_methods(eom, methods)
    if outputs is None:
        outputs = applicable_outputs(eom, [o for o in SIMULATION_OUTPUTS
                                           if o != "jacobian" or o in required_outputs(methods)])

    outputs = list(outputs)
    outputs += [o for o in required_outputs(methods) if o not in outputs]  # the integrators' needs
    # and simulate's checks of the constraints: their drift and the start (found by review: with
    # outputs=("rhs",) a pendulum in x, y drifted 9e-3 off its rod, no warning, drift_tolerance ignored)
    outputs += [o for o in applicable_outputs(eom, ["constraints", "configuration"]) if o not in outputs]
    fixed = _checked_fixed(eom, fixed)
    key = _sources_key(eom, outputs, fixed, methods, precision, (trig, lanes, lane_trig))
    entry = cache.cache_dir(cache_dir) / "sources" / f"{key[:32]}.json"
    stored = _load_sources(entry, key)
    if stored is None:
        system = reduce_expressions(eom, outputs, fixed)
        sources = render_sources(system, precision, methods=methods, trig=trig)
        with_lanes = render_sources(system, precision, methods=methods, trig=trig, lanes=lanes,
                                    lane_trig=lane_trig) if lanes and lanes_apply(system, methods) else None
        if with_lanes is not None and f"{with_lanes.layout.prefix}_sweep_lanes" not in with_lanes.layout.functions:
            with_lanes = None
        stored = (sources, with_lanes, _function_ops(system))
        _store_sources(entry, stored, key)
    if alias is not None:
        _store_alias(alias, key)
    sources, with_lanes, ops = stored
    return _build(eom.name, sources, with_lanes, ops, cache_dir, extra_compile_args)


def _derive(model: Model, methods, outputs) -> EquationsOfMotion:
    """derive_equations, except that a tree learns whether its kernels need the Jacobian (implicit
    methods or the jacobian output): its formulation choice weighs that cost only then."""
    if model.route != ROUTE_TREE:
        return derive_equations(model)
    implicit = "jacobian" in required_outputs(tuple(methods)) or "jacobian" in (outputs or ())
    eom = derive_from_tree(model, implicit=implicit)
    check_derived(model, eom)  # as derive_equations does (found by review: a tree skipped it)
    return eom


def _function_ops(system) -> dict:
    """Operations per C function for the build-cost estimate: a kernel, or the parts a long
    recursive kernel is split into (`kernel_text.kernel_parts`), whose cost adds up linearly."""
    ops = {}
    for kernel in system.kernels:
        parts = math.ceil(len(kernel.temporaries) / PART_ASSIGNMENTS) if system.recursive else 1
        if parts <= 1:
            ops[kernel.name] = kernel.ops_after
        else:
            ops.update({f"{kernel.name} part {k}": kernel.ops_after // parts for k in range(parts)})
    return ops


def _build(name: str, sources: CSources, with_lanes, ops: dict, cache_dir, extra_compile_args) -> CompiledSystem:
    cost = estimate_build_cost(name, ops, sources.layout.methods)
    compiled = build_module(sources, cache_dir=cache_dir, extra_compile_args=extra_compile_args, cost=cost)
    if with_lanes is None:
        return compiled
    return replace(compiled, lane_build=(with_lanes, cache_dir, tuple(extra_compile_args)))


#: routes whose models hold only sympy expressions and plain data, so that their pickled bytes key
#: them (bodies and sympy models hold frames and points, whose pickles carry identities)
_KEYED_ROUTES = ("tree", "energies")


def _model_entry(model, outputs, fixed, methods, precision, code_options, cache_dir) -> Path | None:
    """Where the model entry of ``model`` with these options lives, or None when the model is
    not keyed before derivation (an EquationsOfMotion, a route with frames and points, or a
    model that does not pickle)."""
    if not isinstance(model, Model) or model.route not in _KEYED_ROUTES:
        return None
    fields = tuple((f.name, getattr(model, f.name)) for f in dataclasses.fields(model))
    try:
        digest = _values_digest((fields, None if outputs is None else list(outputs),
                                 sorted((str(k), _fixed_key(v)) for k, v in (fixed or {}).items()), list(methods)))
    except (pickle.PicklingError, TypeError, AttributeError, ValueError, RecursionError):
        return None
    key = cache.source_key({"lagcodegen": __version__, "sympy": sp.__version__,
                            "model": digest,
                            "options": repr((precision, code_options)), "code": _package_digest()})
    return cache.cache_dir(cache_dir) / "sources" / f"model-{key[:32]}.txt"


def _fixed_key(value) -> str:
    """A fixed value as the kernel will fold it (float.hex: exact), for the model entry's key; repr
    of sp.Float(1.4, 2) is '1.4' while it folds as 1.400390625. A value that is no number keys by
    repr (the derivation then refuses it)."""
    try:
        return _fixed_value("", value).hex()
    except KernelError:
        return repr(value)


def _aliased_sources(alias: Path, cache_dir) -> tuple[Path, str]:
    """(the sources entry a model entry names, its key); a missing or damaged one names none, and
    so does one written under another name: its body names the entry it was stored as (found by
    review: an intact entry copied over another model's file loaded that model's kernel, status OK)."""
    try:
        head, _, body = alias.read_bytes().partition(b"\n")
    except OSError:
        return alias.with_suffix(".missing"), ""
    name, _, key = body.partition(b" ")
    if head != f"{_SOURCES_MAGIC} {hashlib.sha256(body).hexdigest()}".encode("ascii") or len(key) != 64 or \
            not all(c in b"0123456789abcdef" for c in key) or name != alias.name.encode("utf-8"):
        return alias.with_suffix(".missing"), ""
    key = key.decode("ascii")
    return cache.cache_dir(cache_dir) / "sources" / f"{key[:32]}.json", key


def _store_alias(alias: Path, key: str) -> None:
    body = f"{alias.name} {key}".encode()
    _write_atomically(alias, f"{_SOURCES_MAGIC} {hashlib.sha256(body).hexdigest()}\n".encode("ascii") + body)


def _checked_fixed(eom: EquationsOfMotion, fixed: Mapping | None) -> dict:
    """``fixed`` as {parameter name: float}; KernelError naming the entry that is not a parameter
    or not a finite real number (before anything is keyed, reduced or compiled)."""
    if fixed is None:
        return {}
    if not isinstance(fixed, Mapping):
        raise KernelError(f"fixed must be a mapping parameter -> value, got {type(fixed).__name__}")
    parameters = {p.name for p in eom.parameters}
    coordinates = {q.name for q in eom.q}
    checked = {}
    for key, value in fixed.items():
        if isinstance(key, sp.Symbol):
            name = key.name
        elif isinstance(key, AppliedUndef):  # a coordinate given as q(t)
            name = key.func.__name__
        else:
            name = str(key)
        if name not in parameters:
            what = "a coordinate, not a parameter," if name in coordinates else "not a parameter"
            raise KernelError(f"cannot fix {name!r}: {what} of model {eom.name!r} "
                              f"(parameters: {', '.join(sorted(parameters)) or 'none'})")
        checked[name] = _fixed_value(name, value)
        symbol = next(p for p in eom.parameters if p.name == name)
        wrong = sign_error(name, checked[name], sign_assumption(symbol), f"fixed parameter {name!r}")
        if wrong:
            raise KernelError(wrong)
    return checked


def _fixed_value(name: str, value) -> float:
    """float(value) for a real number (Python, numpy or a sympy number), else KernelError."""
    if isinstance(value, (bool, str, bytes)) or value is None:
        number = None  # float("1.5") and float(True) work, but neither is a number given as one
    elif isinstance(value, sp.Basic):
        number = float(value) if value.is_number and value.is_real else None
    elif isinstance(value, numbers.Real):
        try:
            number = float(value)
        except OverflowError:  # an int beyond the double range (found by review: a bare OverflowError)
            number = math.inf
    else:
        number = None
    if number is None:
        raise KernelError(f"fixed parameter {name!r} must be a real number, got "
                          f"{type(value).__name__} {value!r}")
    if not math.isfinite(number):
        integral = isinstance(value, numbers.Integral)
        shown = f"an integer of {len(str(abs(int(value))))} digits" if integral else repr(value)
        raise KernelError(f"fixed parameter {name!r} must be finite, got {shown}")
    return number


def _sources_key(eom: EquationsOfMotion, outputs, fixed, methods, precision,
                 code_options=(DEFAULT_TRIG, 0, "fast")) -> str:
    """sha256 of everything render_sources' output depends on (equations, options, templates and
    the code that reduces and renders them)."""
    templates = sorted(template_dir().glob("*.j2"))
    return cache.source_key({
        "lagcodegen": __version__, "sympy": sp.__version__, "name": eom.name, "route": eom.route,
        "equations": equations_digest(eom),
        "parameters": repr(sorted((str(k), v) for k, v in eom.parameter_values.items())),
        "options": repr((list(outputs), sorted((str(k), float(v)) for k, v in (fixed or {}).items()),
                         list(methods), precision, code_options)),
        "templates": "".join(path.name + path.read_text() for path in templates),
        "code": _package_digest(),
    })


def equations_digest(eom: EquationsOfMotion) -> str:
    """sha256 of every field of ``eom`` (but the parameter values, keyed apart), by `_values_digest`:
    two equal equations give the same digest however sympy's cache shared their subexpressions,
    and in every process (sympy orders the arguments of Add and Mul canonically)."""
    fields = tuple((f.name, getattr(eom, f.name)) for f in dataclasses.fields(eom) if f.name != "parameter_values")
    return _values_digest(fields)


class _DigestPickler(pickle.Pickler):
    """Pickles without a memo (the bytes follow the values, not the identities of shared parts) and
    notes the user-defined sympy classes it meets: pickle stores a class by its name, so an edited
    ``class spring(sp.Function)`` (a notebook cell run again) keyed as before and loaded the old
    kernel (found by review: cos(2) for a stiffness changed to 9, status OK)."""

    def __init__(self, buffer, nodes: _NodeDigests | None = None):
        super().__init__(buffer, protocol=4)
        self.fast = True
        self.classes: dict = {}
        self.nodes = nodes

    def persistent_id(self, obj):
        """A sympy object as its digest (`_NodeDigests`), when this pickler has them."""
        if self.nodes is not None and isinstance(obj, sp.Basic):
            return self.nodes.digest(obj)
        return None

    def reducer_override(self, obj):
        if (isinstance(obj, type) and issubclass(obj, sp.Basic) and not isinstance(obj, UndefinedFunction)
                and not _from_sympy(obj)):
            name = f"{obj.__module__}.{obj.__qualname__}"
            self.classes[id(obj)] = (name, obj)  # two classes of one name (two exec'd cells) both count
            return str, (name,)  # by its name here, its code apart: a class defined in a function pickles too
        return NotImplemented


class _NodeDigests:
    """sha256 of sympy objects, as a Merkle tree: a node that pickles as its class and its arguments
    (Basic's own ``__reduce_ex__``: ``__getnewargs__`` is ``args``, no state) is the digest of its
    class pickled and of its arguments' digests; any other node (a Symbol, a number, a class
    with state of its own) is the digest of its whole pickle. The same information as pickling
    the tree, but each distinct subexpression is digested once: the Whipple bicycle's equations
    hold 40000 nodes as trees and 1300 distinct ones (pickling them whole took 0.15-0.25 s).
    Memoized by identity, as equal values of different types (Float(1.0) == 1) must differ."""

    def __init__(self, classes: dict):
        self.classes = classes  # the user-defined sympy classes met, as _DigestPickler notes them
        self.known: dict = {}  # id(node) -> digest
        self.alive: list = []  # the nodes of those ids
        self.class_keys: dict = {}

    def digest(self, root) -> str:
        stack = [root]
        while stack:  # iterative: an expression can be deeper than the recursion limit
            node = stack[-1]
            if id(node) in self.known:
                stack.pop()
                continue
            if not _by_arguments(node):
                stack.pop()
                self._note(node, hashlib.sha256(b"whole" + self._pickled(node)).digest())
                continue
            missing = [a for a in node.args if id(a) not in self.known]
            if missing:
                stack.extend(missing)
                continue
            stack.pop()
            digest = hashlib.sha256(self._class_key(type(node)))
            for argument in node.args:
                digest.update(self.known[id(argument)])
            self._note(node, digest.digest())
        return self.known[id(root)].hex()

    def _note(self, node, digest: bytes) -> None:
        self.known[id(node)] = digest
        self.alive.append(node)

    def _class_key(self, cls: type) -> bytes:
        key = self.class_keys.get(cls)
        if key is None:
            key = self.class_keys[cls] = hashlib.sha256(b"class" + self._pickled(cls)).digest()
        return key

    def _pickled(self, value) -> bytes:
        buffer = io.BytesIO()
        pickler = _DigestPickler(buffer)
        pickler.dump(value)
        self.classes.update(pickler.classes)
        return buffer.getvalue()


def _by_arguments(node) -> bool:
    """Whether ``node`` pickles as its class and its (sympy) arguments alone."""
    cls = type(node)
    return (bool(node.args) and cls.__reduce_ex__ is sp.Basic.__reduce_ex__
            and cls.__getnewargs__ is sp.Basic.__getnewargs__ and cls.__getstate__ is sp.Basic.__getstate__
            and getattr(cls, "__getnewargs_ex__", None) is None and cls.__reduce__ is object.__reduce__
            and all(isinstance(a, sp.Basic) for a in node.args))


def _values_digest(values) -> str:
    """sha256 of ``values`` pickled (their sympy objects by `_NodeDigests`), and of the code of the
    user-defined sympy classes they hold."""
    buffer = io.BytesIO()
    classes: dict = {}
    pickler = _DigestPickler(buffer, _NodeDigests(classes))
    pickler.dump(values)
    classes.update(pickler.classes)
    digest = hashlib.sha256(buffer.getvalue())
    for entry in sorted(name.encode() + b"\0" + _class_code(cls) for name, cls in classes.values()):
        digest.update(entry)
    return digest.hexdigest()


def _class_code(cls: type, seen: frozenset = frozenset(), depth: int = 0) -> bytes:
    """What decides the behaviour of ``cls`` and of its bases outside sympy: its methods (their code,
    defaults, closures and the globals they read) and its other attributes, by content (no memory
    addresses, file names or line numbers: the key must be the same in every process). ``seen``:
    the objects being described around it (two classes whose methods read each other)."""
    parts, seen = [], seen | {id(cls)}
    for klass in cls.__mro__:
        if klass is object or _from_sympy(klass):
            continue
        for name, value in sorted(vars(klass).items()):
            if name.startswith("__") and name.endswith("__") and not callable(value):
                continue  # __module__, __doc__, __dict__, ...
            parts.append(name.encode() + b"=" + _value_bytes(value, seen, depth + 1))
    return b"\0".join(parts)


def _from_sympy(obj) -> bool:
    module = getattr(obj, "__module__", None) or ""
    return module == "sympy" or module.startswith("sympy.")


def _value_bytes(value, seen: frozenset, depth: int) -> bytes:
    """Deterministic bytes of ``value`` as a method sees it (found by review: a closure variable, a
    list or a helper function read through the globals keyed as before when edited)."""
    if depth > 8 or id(value) in seen and not isinstance(value, (numbers.Number, str, bytes)):
        return b"..."
    if value is None or isinstance(value, (bool, numbers.Number, str, bytes)):
        return repr(value).encode()
    if isinstance(value, sp.Basic):
        return sp.srepr(value).encode()
    seen = seen | {id(value)}
    if isinstance(value, (list, tuple)):
        return b"[" + b",".join(_value_bytes(v, seen, depth + 1) for v in value) + b"]"
    if isinstance(value, (set, frozenset)):
        return b"{" + b",".join(sorted(_value_bytes(v, seen, depth + 1) for v in value)) + b"}"
    if isinstance(value, dict):
        return b"{" + b",".join(sorted(_value_bytes(k, seen, depth + 1) + b":" + _value_bytes(v, seen, depth + 1)
                                       for k, v in value.items())) + b"}"
    if isinstance(value, (staticmethod, classmethod)):
        return _value_bytes(value.__func__, seen, depth + 1)
    if isinstance(value, property):
        return b"property" + b",".join(_value_bytes(f, seen, depth + 1) for f in (value.fget, value.fset, value.fdel))
    if isinstance(value, type):
        if _from_sympy(value) or value.__module__ == "builtins":
            return f"{value.__module__}.{value.__qualname__}".encode()
        return f"{value.__module__}.{value.__qualname__}".encode() + b":" + _class_code(value, seen, depth + 1)
    if isinstance(value, types.ModuleType):
        return b"module " + value.__name__.encode()
    code = getattr(getattr(value, "__func__", value), "__code__", None)
    if code is not None:
        function = getattr(value, "__func__", value)
        if _from_sympy(function):
            return f"{function.__module__}.{function.__qualname__}".encode()
        read = {n: function.__globals__[n] for n in _names(code) if n in function.__globals__}
        closure = [cell.cell_contents for cell in function.__closure__ or ()]
        return b"function:" + _code_bytes(code) + b"|" + _value_bytes(
            (function.__defaults__, function.__kwdefaults__, closure, sorted(read.items())), seen, depth + 1)
    if isinstance(value, np.ndarray):
        return f"array{value.dtype}{value.shape}".encode() + value.tobytes()
    try:
        return pickle.dumps(value, protocol=4)
    except Exception:  # noqa: BLE001 - an object that does not pickle keys by its type alone
        return f"{type(value).__module__}.{type(value).__qualname__}".encode()


def _names(code) -> set:
    """The global names ``code`` and the code objects nested in it read."""
    names = set(code.co_names)
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            names |= _names(const)
    return names


def _code_bytes(code) -> bytes:
    """The instructions, names and constants of ``code`` (nested code too), not its file or lines."""
    consts = b",".join(_code_bytes(c) if isinstance(c, types.CodeType) else repr(c).encode() for c in code.co_consts)
    return code.co_code + b"|" + repr((code.co_names, code.co_varnames)).encode() + b"|" + consts


@functools.lru_cache(maxsize=1)
def _package_digest() -> str:
    """sha256 over every module of the package, subpackages included, and the templates: an
    edited emitter or template must not be served stale sources from the cache under an
    unchanged version number."""
    from .codegen.render import template_dir

    return code_digest(Path(__file__).resolve().parent, template_dir())


def code_digest(package: Path, templates: Path) -> str:
    """sha256 over the ``.py`` files under ``package`` (recursively, by relative path) and the
    ``.j2`` files in ``templates``."""
    digest = hashlib.sha256()
    for path in sorted(package.rglob("*.py")):
        digest.update(path.relative_to(package).as_posix().encode() + b"\0" + path.read_bytes())
    for path in sorted(templates.glob("*.j2")):
        digest.update(b"templates/" + path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


_SOURCES_MAGIC = "lagcodegen-sources-v2"


def _load_sources(entry: Path, key: str) -> tuple | None:
    """(sources, sources with the lane kernel or None, {kernel: ops after CSE}), or None when the
    entry is missing or fails any check (then the caller renders again and replaces it). The body
    names its own key: an intact entry copied over another's file is another model's."""
    try:
        data = entry.read_bytes()
        head, _, body = data.partition(b"\n")
        if head != f"{_SOURCES_MAGIC} {hashlib.sha256(body).hexdigest()}".encode("ascii"):
            return None  # damaged (or written by another format): any byte counts
        stored = json.loads(body.decode("utf-8"))
        if stored["key"] != key:
            return None
        lanes = stored["lanes"]
        ops = {str(k): int(v) for k, v in stored["ops"].items()}
        return (_csources(stored["sources"]), None if lanes is None else _csources(lanes), ops)
    except (OSError, ValueError, KeyError, TypeError, AttributeError):  # ValueError: bad UTF-8 or JSON
        return None


def _csources(fields: dict) -> CSources:
    """CSources from its JSON form (lists back to tuples, as KernelLayout holds them)."""
    def tuples(value):
        return tuple(tuples(v) for v in value) if isinstance(value, list) else value
    layout = KernelLayout(**{k: tuples(v) for k, v in fields["layout"].items()})
    return CSources(layout=layout, **{k: v for k, v in fields.items() if k != "layout"})


def _store_sources(entry: Path, stored: tuple, key: str) -> None:
    """Write the entry atomically; a cache dir that cannot take it only costs a warning."""
    sources, lanes, ops = stored
    body = json.dumps({"key": key, "sources": dataclasses.asdict(sources),
                       "lanes": None if lanes is None else dataclasses.asdict(lanes), "ops": ops},
                      sort_keys=True, ensure_ascii=False).encode("utf-8")
    _write_atomically(entry, f"{_SOURCES_MAGIC} {hashlib.sha256(body).hexdigest()}\n".encode("ascii") + body)


def _write_atomically(entry: Path, text: bytes) -> None:
    """Write the entry atomically; a cache dir that cannot take it only costs a warning."""
    try:
        cache.subdir(entry.parent.parent, entry.parent.name)
        if entry.is_dir() and not entry.is_symlink():  # a damaged cache: the entry must be a file
            cache.evict_entry(entry)
        handle, temporary = tempfile.mkstemp(dir=entry.parent, suffix=".tmp")
        try:
            with os.fdopen(handle, "wb") as out:
                out.write(text)
            os.replace(temporary, entry)  # atomic: concurrent builders see the old file or the new one
        finally:
            if os.path.exists(temporary):
                os.unlink(temporary)
    except OSError as exc:
        warnings.warn(cache.CacheDirWarning(
            f"could not store the rendered sources in {entry} ({exc.strerror or exc}); they will be "
            f"rendered again next time. Set {cache.ENV_VAR} to a writable directory"),
            stacklevel=cache.user_stacklevel())
