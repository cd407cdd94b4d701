"""The output registry (codegen/outputs.py) is the one place an output is defined (issue 12).

- Every entry names a kernel with rows, and the defaults are the registry's own.
- The layout's exported names are carried by the function records, not parsed: checked here
  against the definitions found in the C source text by a regular expression of this test.
- A new output lands in one place: a test-only entry (its rows and its C writer) registered
  here is reduced, rendered, compiled and called, and gives sum(u_i^2) computed by numpy.
"""
from __future__ import annotations

import re

import numpy as np
import pytest
import sympy as sp

from lagcodegen import catalog
from lagcodegen.codegen import outputs
from lagcodegen.codegen.csyntax import record
from lagcodegen.codegen.kernel_text import results
from lagcodegen.codegen.outputs import DEFAULT_OUTPUTS, KERNEL_ROWS, OUTPUTS, KernelError, applicable_outputs
from lagcodegen.codegen.reduce import reduce_expressions
from lagcodegen.codegen.render import render_sources
from lagcodegen.native.build import build_module
from lagcodegen.symbolic.derive import derive_equations


def test_every_output_names_a_kernel_with_rows():
    assert set(DEFAULT_OUTPUTS) <= set(OUTPUTS)
    for name, output in OUTPUTS.items():
        assert output.name == name
        assert output.kernel in KERNEL_ROWS, name


def test_constrained_models_get_their_outputs_and_lose_the_jacobian():
    eom = derive_equations(catalog.cartesian_pendulum())
    chosen = applicable_outputs(eom, DEFAULT_OUTPUTS)
    assert "jacobian" not in chosen and chosen[-2:] == ["constraints", "multipliers"]
    with pytest.raises(KernelError, match="jacobian"):
        reduce_expressions(eom, ["rhs", "jacobian"])
    free = derive_equations(catalog.double_pendulum())
    assert applicable_outputs(free, DEFAULT_OUTPUTS) == list(DEFAULT_OUTPUTS)
    with pytest.raises(KernelError, match=r"'multipliers' needs constraints \(holonomic or on the velocities\)"):
        reduce_expressions(free, ["rhs", "multipliers"])


@pytest.mark.parametrize("model", ["double_pendulum", "cartesian_pendulum"])
def test_layout_names_are_the_exported_definitions_of_the_source(model):
    eom = derive_equations(getattr(catalog, model)())
    system = reduce_expressions(eom, applicable_outputs(eom, DEFAULT_OUTPUTS))
    sources = render_sources(system, methods=("rk4",))
    defined = re.findall(r"^(?!static)[a-z][\w ]*?\b(lcg_\w+)\(", sources.source, flags=re.M)
    assert set(sources.layout.functions) == set(defined)
    assert f"{sources.layout.prefix}_rhs" in defined and f"{sources.layout.prefix}_simulate" in defined


def _speed_square_c(w, kernel):
    body = w.head(kernel) + [f"return {w.expr(results(kernel, 'S')[(0, 0)], 'sum of u^2')};"]
    return record(w.real, f"{w.prefix}_speed_square", w.arguments, "Sum of the squared speeds.", body)


@pytest.mark.compiler
def test_a_new_output_is_one_registry_entry(monkeypatch, tmp_path):
    monkeypatch.setitem(KERNEL_ROWS, "speed_square", lambda eom, a: [(("S", 0, 0), sp.Add(*[u**2 for u in eom.u]))])
    monkeypatch.setitem(OUTPUTS, "speed_square", outputs.Output("speed_square", "speed_square", _speed_square_c))
    eom = derive_equations(catalog.double_pendulum())
    sources = render_sources(reduce_expressions(eom, ["rhs", "speed_square"]), model_name="registry_probe")
    assert "lcg_registry_probe_speed_square" in sources.layout.functions
    system = build_module(sources, cache_dir=tmp_path)
    x = np.array([0.3, -0.2, 1.5, -2.5])
    p = np.array([1.0, 1.0, 1.0, 1.0, 9.81])
    ffi = system.ffi
    value = system.lib.lcg_registry_probe_speed_square(0.0, ffi.from_buffer("double[]", x),
                                                       ffi.from_buffer("double[]", p))
    assert value == pytest.approx(1.5**2 + 2.5**2, rel=1e-15)  # numpy-free arithmetic: 2.25 + 6.25
