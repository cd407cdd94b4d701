"""Energy behaviour over long fixed-step runs (1e5 steps here, 1e6 steps marked ``slow``).

The double pendulum (catalog defaults m1 = m2 = l1 = l2 = 1, g = 9.81) starts at rest from
q = (0.5, 0.3) rad: moderate amplitude, regular (quasi-periodic) motion. Its energy at rest at the
bottom is -(m1 + m2) g l1 - m2 g l2 = -3 g (hand computation), so the oscillation energy is
E0 + 3 g ~ 2.84 J; errors are reported relative to it. Only 1001 samples are kept (``stride``).

"No secular growth" means: the largest |E - E0| in the last tenth of the run is comparable to the
one in the first tenth, and the least-squares trend of |E - E0| against t explains only a small
part of the largest error. "Secular" is the opposite: the error grows about linearly in t.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pytest
import scipy.linalg

from lagcodegen.integrators import schemes
from lagcodegen.run.simulate import simulate

LONG = [100_000, pytest.param(1_000_000, marks=pytest.mark.slow, id="1e6")]
SAMPLES = 1000
G = 9.81
DP_X0 = (0.5, 0.3, 0.0, 0.0)
DP_REST_ENERGY = -3 * G  # -(m1 + m2) g l1 - m2 g l2 with unit masses and lengths


@dataclass(frozen=True)
class Drift:
    """Energy error statistics of one run (dE = E - E0)."""

    duration: float
    first: float  # max |dE| over the first tenth
    last: float  # max |dE| over the last tenth
    largest: float  # max |dE|
    trend: float  # least-squares slope of |dE| against t
    rate: float  # least-squares slope of dE against t (signed drift per unit time)
    tenth_means: np.ndarray  # mean dE over each tenth of the run, (10,)

    @classmethod
    def of(cls, traj) -> Drift:
        dE = traj.energy - traj.energy[0]
        tenths = np.array_split(dE, 10)
        return cls(duration=float(traj.t[-1] - traj.t[0]), first=float(np.max(np.abs(tenths[0]))),
                   last=float(np.max(np.abs(tenths[-1]))), largest=float(np.max(np.abs(dE))),
                   trend=float(np.polyfit(traj.t, np.abs(dE), 1)[0]),
                   rate=float(np.polyfit(traj.t, dE, 1)[0]),
                   tenth_means=np.array([t.mean() for t in tenths]))

    def line(self, label: str, scale: float, scale_name: str = "E_osc") -> str:
        return (f"{label}: T = {self.duration:g} s, max|dE|/{scale_name} first tenth {self.first / scale:.3e}, "
                f"last tenth {self.last / scale:.3e}, overall {self.largest / scale:.3e}; "
                f"drift rate dE/dt = {self.rate:.4e} J/s, trend of |dE| x T / max|dE| = "
                f"{self.trend * self.duration / self.largest:+.3f}")

    @property
    def secular_share(self) -> float:
        """|trend| x duration / largest: ~1 for linear growth, ~0 for a bounded oscillation."""
        return abs(self.trend) * self.duration / self.largest


@pytest.fixture(scope="module")
def double_pendulum(compiled_example):
    return compiled_example("double_pendulum", methods=schemes.DEFAULT_METHODS)


@pytest.fixture(scope="module")
def chain(compiled_example):
    return compiled_example("stiff_chain", methods=schemes.DEFAULT_METHODS)


def long_run(system, x0, h, n_steps, method):
    return simulate(system, x0, n_steps * h, h, method, stride=n_steps // SAMPLES, energy=True).check()


def oscillation_energy(traj) -> float:
    return float(traj.energy[0] - DP_REST_ENERGY)


@pytest.mark.parametrize("n_steps", LONG)
def test_implicit_midpoint_energy_error_is_bounded(double_pendulum, n_steps):
    h = 5e-3
    traj = long_run(double_pendulum, DP_X0, h, n_steps, "implicit_midpoint")
    drift = Drift.of(traj)
    print("\n" + drift.line(f"implicit_midpoint, double pendulum, h = {h}, {n_steps} steps",
                            oscillation_energy(traj)))
    # Expected (symplectic, GNI Thm. IX.8.1): energy error O(h^2) without drift.
    assert oscillation_energy(traj) == pytest.approx(2.84, abs=0.01)  # 3g - g(2cos0.5 + cos0.3)
    assert drift.last <= 1.5 * drift.first
    assert drift.secular_share < 0.2
    assert drift.largest < 1e-4 * oscillation_energy(traj)


@pytest.mark.parametrize("n_steps", LONG)
def test_symplectic_euler_energy_bounded_when_the_mass_matrix_depends_on_q(double_pendulum, n_steps):
    """Symplectic Euler in momentum form (p = M(q) u; schemes.py, steppers.c.j2) is symplectic for
    any M(q) (GNI Thm. VI.3.3), so on the double pendulum its energy error stays O(h) with no
    drift (GNI Thm. IX.8.1) over 1e6 steps: bounded, like implicit midpoint but first order."""
    h = 1e-3
    traj = long_run(double_pendulum, DP_X0, h, n_steps, "symplectic_euler")
    drift = Drift.of(traj)
    print("\n" + drift.line(f"symplectic_euler, double pendulum, h = {h}, {n_steps} steps",
                            oscillation_energy(traj)))
    assert drift.last <= 1.5 * drift.first
    assert drift.secular_share < 0.2
    assert drift.largest < 1e-2 * oscillation_energy(traj)  # O(h) with h = 1e-3


@pytest.mark.parametrize("n_steps", LONG)
def test_symplectic_euler_energy_bounded_on_the_stiff_chain(chain, n_steps):
    """Constant M: symplectic Euler is symplectic and keeps a modified energy (GNI Thm. VI.3.3)."""
    m, k, K = 1.0, 1.0, 1.0e4  # catalog.stiff_chain defaults (m1 = m2 = m3)
    stiffness = np.array([[2 * k, -k, 0], [-k, k + K, -K], [0, -K, K + k]])
    w = math.sqrt(np.max(np.linalg.eigvalsh(stiffness / m)))  # numpy, independent of the kernel
    y = 0.5
    traj = long_run(chain, (0.1, 0.05, -0.05, 0.0, 0.0, 0.0), y / w, n_steps, "symplectic_euler")
    drift = Drift.of(traj)
    print("\n" + drift.line(f"symplectic_euler, stiff chain, h w = {y}, {n_steps} steps", traj.energy[0], "E0"))
    # Expected: per mode v^2 + w^2 x^2 - h w^2 x v is invariant, so E / E0 stays within
    # [(1 - y/2) / (1 + y/2), (1 + y/2) / (1 - y/2)] (see tests/stability/test_stability.py).
    bound = (1 + y / 2) / (1 - y / 2)
    assert np.all(traj.energy <= bound * traj.energy[0])
    assert np.all(traj.energy >= traj.energy[0] / bound)
    assert 0.5 * drift.first <= drift.last <= 2 * drift.first
    assert drift.secular_share < 0.1


def linearized_rk4_energy_rate(x0, h) -> float:
    """RK4 dissipation predicted by the linearized double pendulum (small-angle M and K by hand).

    |R(iy)|^2 = 1 - y^6 / 72 + O(y^8) for RK4 (tableau theory), so mode i loses
    E_i w_i^6 h^5 / 72 per unit time; frequencies from scipy eigh(K, M)."""
    M = np.array([[2.0, 1.0], [1.0, 1.0]])  # [[(m1 + m2) l1^2, m2 l1 l2], [m2 l1 l2, m2 l2^2]]
    K = np.array([[2 * G, 0.0], [0.0, G]])  # [[(m1 + m2) g l1, 0], [0, m2 g l2]]
    w2, phi = scipy.linalg.eigh(K, M)
    eta = phi.T @ M @ np.asarray(x0[:2])
    return float(-np.sum(w2 * eta ** 2 / 2 * w2 ** 3 * h ** 5 / 72))


@pytest.mark.parametrize("n_steps", LONG)
def test_rk4_energy_drifts_secularly(double_pendulum, n_steps):
    h = 5e-3
    traj = long_run(double_pendulum, DP_X0, h, n_steps, "rk4")
    drift = Drift.of(traj)
    predicted = linearized_rk4_energy_rate(DP_X0, h)
    print("\n" + drift.line(f"rk4, double pendulum, h = {h}, {n_steps} steps", oscillation_energy(traj))
          + f"; linearized prediction {predicted:.4e} J/s (ratio {drift.rate / predicted:.3f})")
    assert drift.secular_share > 0.9
    assert drift.last > 5 * drift.first
    assert np.all(np.diff(drift.tenth_means) < 0)  # loses energy monotonically (|R(iy)| < 1)
    # The linearization ignores the amplitude's lowering of the frequencies (~w^6): within 30%.
    assert drift.rate == pytest.approx(predicted, rel=0.3)


def test_rk4_drift_rate_scales_as_h5(double_pendulum):
    """|R(iy)|^2 = 1 - y^6/72 + ...: the energy lost per unit time is O(h^5) (tableau theory)."""
    n_steps = 100_000
    rates = {h: Drift.of(long_run(double_pendulum, DP_X0, h, n_steps, "rk4")).rate for h in (1e-2, 5e-3)}
    ratio = rates[1e-2] / rates[5e-3]
    print(f"\nrk4 drift rates {rates}, ratio {ratio:.3f} (2^5 = 32)")
    assert ratio == pytest.approx(2 ** 5, rel=0.1)
