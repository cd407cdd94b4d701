"""Helper: the terms of holonomic constraints phi(q, t) = 0 for Lagrange's equations of the first kind.

With A = dphi/dq (m, n) and the velocity constraint w = A u + dphi/dt = 0, differentiating once
more along the motion gives A ud = gamma with (Haug, Computer-Aided Kinematics and Dynamics of
Mechanical Systems, sec. 6.3; Nikravesh, Computer-Aided Analysis of Mechanical Systems, ch. 6)::

    gamma = -(A u)_q u - 2 A_t u - phi_tt  =  -(w_q u + w_t)

and Baumgarte's stabilization (Comput. Methods Appl. Mech. Eng. 1, 1972) replaces phi'' = 0 by
phi'' + 2 alpha phi' + beta^2 phi = 0, i.e. gamma - 2 alpha w - beta^2 phi. The first-kind system is

    [M  A^T] [ud    ]   [F    ]
    [A  0  ] [lambda] = [gamma]

so the generalized constraint forces acting on the system are -A^T lambda.
"""
from __future__ import annotations

import sympy as sp

from ..walk import with_zeros

BAUMGARTE_ALPHA = sp.Symbol("baumgarte_alpha")
BAUMGARTE_BETA = sp.Symbol("baumgarte_beta")


def holonomic_terms(phi: sp.Matrix, q, u, t) -> dict:
    """A (m, n), phi_t (m, 1), w = A u + phi_t and the stabilized gamma (m, 1) of phi(q, t)."""
    q_vec, u_vec = sp.Matrix(q), sp.Matrix(u)
    A = phi.jacobian(q_vec)
    phi_t = phi.diff(t)
    w = A * u_vec + phi_t
    gamma = -(w.jacobian(q_vec) * u_vec + w.diff(t)) - 2 * BAUMGARTE_ALPHA * w - BAUMGARTE_BETA ** 2 * phi
    return {"A": sp.ImmutableMatrix(A), "phi_t": sp.ImmutableMatrix(phi_t), "w": sp.ImmutableMatrix(w),
            "gamma": sp.ImmutableMatrix(gamma)}


def motion_terms(w: sp.Matrix, q, u, t, qd=None, rates=None, A=None) -> dict:
    """The rows of velocity constraints w = A(q, t) u + b(q, t) = 0 in the layout of
    `holonomic_terms`: no position-level phi (0), A = dw/du, b in the place of dphi/dt, and
    gamma = -(w_q qd + w_t) - 2 alpha w (Baumgarte's velocity term; no position term), with
    qd = K(q, u, t) the kinematic equations (``qd``, default u). ``rates``, when given, is
    w_q qd + w_t already formed (Kane's ``f_dnh``: sympy differentiated its constraints itself);
    ``A``, when given, is dw/du already formed."""
    q_vec, u_vec = sp.Matrix(q), sp.Matrix(u)
    A = w.jacobian(u_vec) if A is None else A
    memo: dict = {}
    b = w.applyfunc(lambda entry: with_zeros(entry, u, memo))
    if rates is None:
        rates = w.jacobian(q_vec) * (u_vec if qd is None else sp.Matrix(qd)) + w.diff(t)
    gamma = -rates - 2 * BAUMGARTE_ALPHA * w
    return {"A": sp.ImmutableMatrix(A), "phi_t": sp.ImmutableMatrix(b), "w": sp.ImmutableMatrix(w),
            "gamma": sp.ImmutableMatrix(gamma), "phi": sp.ImmutableMatrix.zeros(w.rows, 1)}
