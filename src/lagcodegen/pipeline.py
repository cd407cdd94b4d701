"""Helper: the whole pipeline in one call, Model -> CompiledSystem.

``compile_model`` chains the stages (derive, reduce, render, build) with their defaults; each
stage stays callable on its own for users who want to inspect or change what passes between.
The rendered sources are cached on disk beside the built modules, keyed by the derived equations
and every option, so loading an unchanged model again skips CSE and rendering as well as gcc.
"""
from __future__ import annotations

import functools
import hashlib
import os
import pickle
import tempfile
from dataclasses import replace
from pathlib import Path
from typing import Mapping

import sympy as sp

from . import __version__, cache
from .build import CompiledSystem, build_module
from .cse import momentum_obstacle, reduce_expressions
from .derive import EquationsOfMotion, derive_equations
from .emit import CSources, render_sources, template_dir
from .lanes import DEFAULT_LANES
from .printer import DEFAULT_TRIG
from .model import Model
from .schemes import DEFAULT_METHODS, needs_jacobian

SIMULATION_OUTPUTS = ("rhs", "energy", "points", "jacobian")


def compile_model(model: Model | EquationsOfMotion, *, outputs=None, fixed: Mapping | None = None,
                  methods=DEFAULT_METHODS, precision: str = "double", trig: str = DEFAULT_TRIG,
                  cache_dir=None, extra_compile_args=(), lanes: int = DEFAULT_LANES,
                  lane_trig: str = "fast") -> CompiledSystem:
    """Derive (if given a Model), CSE, emit and compile the kernels of one model.

    Parameters
    ----------
    model : Model or EquationsOfMotion
    outputs : sequence of str, optional
        Kernel outputs; default ``SIMULATION_OUTPUTS`` (without ``energy`` when the model has no
        energies, without ``jacobian`` when no implicit method is requested). The outputs the
        methods need (``rhs``; ``jacobian`` for implicit ones; ``momentum`` for symplectic Euler)
        are always added.
    fixed : mapping parameter -> float, optional
        Parameters folded into the code; the rest stay runtime inputs.
    methods : sequence of str
        Integration schemes to compile in (`schemes.SCHEMES`).
    precision : {"double", "float"}
    trig : {"libm", "inline"}
        How sine and cosine are computed (`emit.render_sources`): libm calls (default) or the
        inline polynomials of ``templates/trig.c.j2``.
    lanes : int
        Members per vector group of the lane sweep kernel (``sweep`` uses it for explicit methods
        of unconstrained models); 0: none. Its sources are rendered here, but compiled only when a
        sweep first needs them (`CompiledSystem.lane_variant`): it doubles the compile time.
    lane_trig : {"fast", "libm"}
        sin/cos in the lane kernel: vectorizable polynomials, or libm (bitwise equal to the
        scalar sweep, slower); see `render_sources`.
    """
    eom = model if isinstance(model, EquationsOfMotion) else derive_equations(model)
    methods = tuple(methods)
    defaulted = methods == DEFAULT_METHODS
    if defaulted and momentum_obstacle(eom) is not None:
        methods = tuple(m for m in methods if m != "symplectic_euler")  # not applicable: see momentum_obstacle
    if defaulted and eom.m:
        methods = tuple(m for m in methods if not needs_jacobian([m]))  # no constrained Jacobian yet
    if outputs is None:
        outputs = [o for o in SIMULATION_OUTPUTS
                   if not (o == "energy" and eom.energy is None)
                   and not (o == "jacobian" and (not needs_jacobian(methods) or eom.m))]
        outputs += ["constraints", "multipliers"] if eom.m else []

    outputs = list(outputs)
    needed = ["rhs"] if methods else []  # the integrators' own needs come with them
    needed += ["jacobian"] if needs_jacobian(methods) else []
    needed += ["momentum"] if "symplectic_euler" in methods else []
    outputs += [o for o in needed if o not in outputs]
    key = _sources_key(eom, outputs, fixed, methods, precision, (trig, lanes, lane_trig))
    entry = cache.cache_dir(cache_dir) / "sources" / f"{key[:32]}.pickle"
    stored = _load_sources(entry)
    if stored is None:
        system = reduce_expressions(eom, outputs, fixed)
        sources = render_sources(system, precision, methods=methods, trig=trig)
        with_lanes = render_sources(system, precision, methods=methods, trig=trig, lanes=lanes,
                                    lane_trig=lane_trig) if lanes else None
        stored = (sources, with_lanes if with_lanes is not None and f"{with_lanes.layout.prefix}_sweep_lanes" in with_lanes.layout.functions else None)
        _store_sources(entry, stored)
    sources, with_lanes = stored
    compiled = build_module(sources, cache_dir=cache_dir, extra_compile_args=extra_compile_args)
    if with_lanes is None:
        return compiled
    return replace(compiled, lane_build=(with_lanes, cache_dir, tuple(extra_compile_args)))


def _sources_key(eom: EquationsOfMotion, outputs, fixed, methods, precision,
                 code_options=(DEFAULT_TRIG, 0, "fast")) -> str:
    """sha256 of everything render_sources' output depends on (equations, options, templates and
    the code that reduces and renders them)."""
    templates = sorted(template_dir().glob("*.j2"))
    expressions = (eom.mass_matrix, eom.forcing, eom.kinematics, eom.energy, eom.points, eom.constraints,
                   eom.constraint_jacobian, eom.constraint_rate, eom.constraint_bias, eom.q, eom.u)
    return cache.source_key({
        "lagcodegen": __version__, "sympy": sp.__version__, "name": eom.name, "route": eom.route,
        "expressions": sp.srepr(expressions),
        "parameters": sp.srepr(tuple(eom.parameters)) + repr(sorted((str(k), v) for k, v in eom.parameter_values.items())),
        "options": repr((list(outputs), sorted((str(k), float(v)) for k, v in (fixed or {}).items()),
                         list(methods), precision, code_options)),
        "templates": "".join(path.name + path.read_text() for path in templates),
        "code": _package_digest(),
    })


@functools.lru_cache(maxsize=1)
def _package_digest() -> str:
    """sha256 over this package's modules: an edited emitter must not be served stale sources
    from the cache under an unchanged version number."""
    digest = hashlib.sha256()
    for path in sorted(Path(__file__).parent.glob("*.py")):
        digest.update(path.name.encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


def _load_sources(entry: Path) -> tuple | None:
    """(sources, sources with the lane kernel or None), or None when missing or unreadable."""
    try:
        with open(entry, "rb") as handle:
            stored = pickle.load(handle)
    except FileNotFoundError:
        return None
    except (OSError, pickle.UnpicklingError, EOFError, AttributeError, TypeError):  # corrupt: rebuild
        return None
    if (isinstance(stored, tuple) and len(stored) == 2 and isinstance(stored[0], CSources)
            and (stored[1] is None or isinstance(stored[1], CSources))):
        return stored
    return None


def _store_sources(entry: Path, sources: tuple) -> None:
    entry.parent.mkdir(parents=True, exist_ok=True)
    handle, temporary = tempfile.mkstemp(dir=entry.parent, suffix=".tmp")
    with os.fdopen(handle, "wb") as out:
        pickle.dump(sources, out, protocol=pickle.HIGHEST_PROTOCOL)
    os.replace(temporary, entry)  # atomic: concurrent builders see the old file or the new one
