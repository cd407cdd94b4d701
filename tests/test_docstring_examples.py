"""The examples in the public entry points' docstrings run and print what they say (issue 12).

Their expected values are worked out by hand in each docstring (x(t) = cos(2 t) of the mass on a
spring, the pendulum's sqrt(g / l)); this test runs them with doctest.
"""
from __future__ import annotations

import doctest

import pytest

from lagcodegen import Model, derive_equations
from lagcodegen.analysis.animation import animate
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate
from lagcodegen.run.sweep import sweep
from lagcodegen.statics.equilibria import find_equilibria, linearize

ENTRY_POINTS = [Model, derive_equations, compile_model, simulate, sweep, find_equilibria, linearize, animate]


@pytest.mark.parametrize("entry", ENTRY_POINTS, ids=lambda e: e.__name__)
def test_docstring_example_runs(entry):
    tests = [t for t in doctest.DocTestFinder(recurse=False).find(entry, entry.__name__) if t.examples]
    assert tests, f"{entry.__name__} has no example in its docstring"
    runner = doctest.DocTestRunner(optionflags=doctest.NORMALIZE_WHITESPACE)
    for test in tests:
        runner.run(test)
    assert runner.failures == 0, f"{runner.failures} of {runner.tries} examples of {entry.__name__} failed (see above)"
