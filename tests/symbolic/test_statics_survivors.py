"""Equilibria at the edges the other statics tests do not reach. No C is compiled.

"""
from __future__ import annotations

import math

import pytest
import sympy as sp
import sympy.physics.mechanics as me

from lagcodegen import Model, catalog, derive_equations
from lagcodegen.statics.equilibria import find_equilibria

m, g, l = sp.symbols("m g l", positive=True)
th = me.dynamicsymbols("theta")


def _pendulum(name="pendulum_s", mass=1.0, **extra):
    """m l^2 thd^2 / 2, V = -m g l cos(th); m g l = 2 m at the defaults."""
    return derive_equations(Model(name, [th], [m, g, l], kinetic_energy=m * l ** 2 * th.diff() ** 2 / 2,
                                  potential_energy=-m * g * l * sp.cos(th),
                                  parameter_values={"m": mass, "g": 2.0, "l": 1.0}, **extra))


@pytest.fixture(scope="module")
def pendulum():
    return _pendulum()


def _values(found):
    return [[float(v) for v in root.values()] for root in found]


# -- find_equilibria ------------------------------------------------------------------------------
def test_roots_given_back_as_guesses_are_found_again(pendulum):
    """A guess that is already a root has |F| ~ 1e-16 there; the tolerance must not shrink to
    it (before, the standing pendulum from guesses=[[pi]] gave [] and the double pendulum
    lost three of its four equilibria when its own roots were passed back)."""
    assert _values(find_equilibria(pendulum, {}, guesses=[[math.pi]])) == [[math.pi]]
    assert _values(find_equilibria(pendulum, {}, guesses=[[-math.pi]])) == [[math.pi]]
    double = derive_equations(catalog.double_pendulum())
    found = find_equilibria(double, {})
    assert len(found) == 4
    assert find_equilibria(double, {}, guesses=_values(found)) == found
