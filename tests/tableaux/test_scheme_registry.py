"""The scheme protocol: every registered scheme declares what the pipeline, the steppers and
the sweep ask of it, and `required_outputs` is the one method/output policy.

Expected outputs follow from how each stepper works (HNW I and HW II): explicit Runge-Kutta
stages call the right-hand side only; implicit ones solve their stages by Newton's method with
the Jacobian df/dx; symplectic Euler in momentum form needs the momentum map p = M(q) u.
"""
from __future__ import annotations

import itertools

import numpy as np
import pytest

from lagcodegen.integrators import schemes
from lagcodegen.integrators.schemes import SCHEMES, get_scheme, required_outputs

EXPLICIT = ("euler", "heun", "midpoint", "kutta3", "rk4", "rk38", "dopri5")
IMPLICIT = ("backward_euler", "implicit_midpoint", "sdirk2", "radau_iia3")


def test_every_scheme_is_registered_once_and_classified():
    assert set(SCHEMES) == set(EXPLICIT) | set(IMPLICIT) | {"symplectic_euler"}


@pytest.mark.parametrize("name", sorted(SCHEMES))
def test_every_scheme_declares_the_protocol(name):
    scheme = get_scheme(name)
    assert scheme.name == name and isinstance(scheme.order, int) and scheme.order >= 1
    assert scheme.stepper in (schemes.KIND_EXPLICIT, schemes.KIND_IMPLICIT, schemes.KIND_SYMPLECTIC_EULER)
    assert "rhs" in scheme.outputs
    assert scheme.lane_capable == (name in EXPLICIT)
    assert scheme.implicit == (name in IMPLICIT)
    assert scheme.imag_stability_limit() >= 0


@pytest.mark.parametrize("methods, expected", [
    ((), ()),
    (("rk4",), ("rhs",)),
    (EXPLICIT, ("rhs",)),
    (("backward_euler",), ("rhs", "jacobian")),
    (("symplectic_euler",), ("rhs", "momentum")),
    (("symplectic_euler", "radau_iia3", "rk4"), ("rhs", "jacobian", "momentum")),
])
def test_required_outputs(methods, expected):
    assert required_outputs(methods) == expected


def test_required_outputs_do_not_depend_on_the_order_of_the_methods():
    # the sources key hashes the output list: the same methods in another order must give the same key
    methods = ("symplectic_euler", "sdirk2", "heun")
    assert len({required_outputs(p) for p in itertools.permutations(methods)}) == 1


def test_unknown_method_is_named():
    with pytest.raises(KeyError, match="rk5"):
        required_outputs(("rk4", "rk5"))


@pytest.mark.parametrize("name, limit", [("rk4", 2 * 2 ** 0.5), ("symplectic_euler", 2.0)])
def test_each_scheme_judges_its_own_step(name, limit):
    """The stability verdict lives in the scheme: an undamped mode w = 1 (eigenvalues +-i) is kept
    just inside the imaginary-axis limit (RK4: 2 sqrt 2, Hairer-Wanner II, Sec. IV.2; symplectic
    Euler: h w < 2, trace of its map 2 - (h w)^2) and flagged just outside, over a long run."""
    scheme = schemes.get_scheme(name)
    eigenvalues = np.array([1j, -1j])
    assert scheme.unstable_step(0.99 * limit, eigenvalues, 10**6)[0] is False
    assert scheme.unstable_step(1.01 * limit, eigenvalues, 10**6)[0] is True
