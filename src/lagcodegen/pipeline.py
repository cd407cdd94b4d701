"""Helper: the whole pipeline in one call, Model -> CompiledSystem.

``compile_model`` chains the stages (derive, reduce, render, build) with their defaults; each
stage stays callable on its own for users who want to inspect or change what passes between.
"""
from __future__ import annotations

from typing import Mapping

from .build import CompiledSystem, build_module
from .cse import momentum_obstacle, reduce_expressions
from .derive import EquationsOfMotion, derive_equations
from .emit import render_sources
from .model import Model
from .schemes import DEFAULT_METHODS, needs_jacobian

SIMULATION_OUTPUTS = ("rhs", "energy", "points", "jacobian")


def compile_model(model: Model | EquationsOfMotion, *, outputs=None, fixed: Mapping | None = None,
                  methods=DEFAULT_METHODS, precision: str = "double", cache_dir=None,
                  extra_compile_args=()) -> CompiledSystem:
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
    system = reduce_expressions(eom, outputs, fixed)
    sources = render_sources(system, precision, methods=methods)
    return build_module(sources, cache_dir=cache_dir, extra_compile_args=extra_compile_args)
