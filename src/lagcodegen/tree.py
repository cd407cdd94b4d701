"""Model stage: a kinematic tree stated link by link (`Link`), for ``Model(tree=...)``.

Each link hangs from its parent (or the ground) by one joint with one degree of freedom: a
revolute joint turns the link about a fixed axis of the parent's frame, a prismatic joint slides
it along one. A spherical joint is three revolute links about independent axes (the first two
massless), a free joint three prismatic and three revolute ones. The joint variable is a
generalized coordinate or a linear combination of them with constant coefficients (absolute
angles: ``q2 - q1`` is the second joint's angle when q1, q2 are the links' angles from the
vertical). The links, their masses and their points are all the model needs: the kinetic and
potential energy follow; springs, dampers and drives enter as the model's potential energy,
dissipation function and generalized forces.
"""
from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

TIME = me.dynamicsymbols._t

#: joint kinds of `Link`, one degree of freedom each
JOINTS = ("revolute", "prismatic")


class TreeError(ValueError):
    """A link that does not describe a joint; the message names the link and the field."""


@dataclass(frozen=True)
class Link:
    """One body of a kinematic tree and the joint that carries it.

    Parameters
    ----------
    name : str
        Unique among the tree's links.
    parent : str or None
        The link this one hangs from; None: the ground (the model's fixed frame). A parent is
        listed before its children.
    joint : {"revolute", "prismatic"}
    axis : 3 numbers
        The joint axis in the parent's frame (normalized here); the right-hand rule gives the
        positive sense of the joint variable.
    variable : Expr
        The joint variable: a coordinate q_i(t) or a linear combination of coordinates with
        constant coefficients. At variable = 0 the link's frame is the parent's, moved to ``offset``.
    offset : 3 expressions
        Where the joint sits, from the parent's frame origin, in the parent's frame.
    mass : expression
        0 for a massless link (an intermediate axis of a spherical joint).
    center : 3 expressions
        The centre of mass in the link's frame.
    inertia : 6 expressions
        ``(Ixx, Iyy, Izz, Ixy, Iyz, Izx)`` about the centre of mass in the link's frame; zero for a
        point mass.
    points : mapping name -> 3 expressions
        Named points of the link, in its frame (recorded in trajectories and animations).
    """

    name: str
    parent: str | None
    joint: str
    axis: tuple
    variable: Any
    offset: tuple = (0, 0, 0)
    mass: Any = 0
    center: tuple = (0, 0, 0)
    inertia: tuple = (0, 0, 0, 0, 0, 0)
    points: Mapping = field(default_factory=dict)

    def __post_init__(self) -> None:
        set_ = lambda attr, value: object.__setattr__(self, attr, value)  # noqa: E731 (frozen)
        if not isinstance(self.name, str) or not self.name.isidentifier():
            raise TreeError(f"link name must be an identifier string, got {self.name!r}")
        if self.parent is not None and not isinstance(self.parent, str):
            raise TreeError(f"link {self.name!r}: parent must be a link name or None, got {self.parent!r}")
        if self.joint not in JOINTS:
            raise TreeError(f"link {self.name!r}: joint must be one of {', '.join(JOINTS)}, got {self.joint!r}")
        axis = self._vector("axis", self.axis)
        if any(not a.is_number or not a.is_real for a in axis):
            raise TreeError(f"link {self.name!r}: the axis must be 3 real numbers, got {self.axis!r}")
        norm = sp.sqrt(sum(a ** 2 for a in axis))
        if norm == 0:
            raise TreeError(f"link {self.name!r}: the axis is the zero vector")
        # exact only when every component is (found by review: (3, 0.001, 0) has a float norm, and
        # nsimplify of 3/norm = 0.99999994 gave 1, an axis 5.6e-8 off unit length)
        # an exact irrational axis (sqrt(2)/2, cos(pi/6)) stays exact (found by review: Float() of
        # sqrt(2)/2 raised a bare TypeError, and a tree's recursive form normalizes its axes again)
        if all(a.is_Rational for a in axis):
            unit = tuple(sp.nsimplify(a / norm) for a in axis)
        elif not any(a.has(sp.Float) for a in axis):
            unit = tuple(sp.simplify(a / norm) for a in axis)
        else:
            unit = tuple(sp.Float(sp.N(a / norm, 15)) for a in axis)
        set_("axis", unit)
        set_("offset", self._vector("offset", self.offset))
        set_("center", self._vector("center", self.center))
        set_("variable", self._expr("variable", self.variable))
        set_("mass", self._expr("mass", self.mass))
        inertia = self.inertia
        if not isinstance(inertia, (list, tuple)) or len(inertia) != 6:
            raise TreeError(f"link {self.name!r}: inertia must be 6 entries (Ixx, Iyy, Izz, Ixy, Iyz, Izx), "
                            f"got {inertia!r}")
        set_("inertia", tuple(self._expr("inertia", i) for i in inertia))
        if not isinstance(self.points, Mapping):
            raise TreeError(f"link {self.name!r}: points must be a mapping name -> (x, y, z)")
        points = {}
        for point, where in self.points.items():
            if not isinstance(point, str) or not point.isidentifier():
                raise TreeError(f"link {self.name!r}: point name {point!r} must be an identifier string")
            points[point] = self._vector(f"point {point!r}", where)
        set_("points", points)

    def _expr(self, what: str, value):
        try:
            expr = sp.sympify(value, strict=True)
        except (sp.SympifyError, TypeError):
            raise TreeError(f"link {self.name!r}: {what} must be a sympy expression or number, got "
                            f"{type(value).__name__} {value!r}") from None
        if not isinstance(expr, sp.Expr):
            raise TreeError(f"link {self.name!r}: {what} must be an expression, got {value!r}")
        moving = expr.atoms(AppliedUndef, sp.Derivative) | (expr.free_symbols & {TIME})
        if moving and what != "variable":
            raise TreeError(f"link {self.name!r}: {what} {expr} depends on {sorted(map(str, moving))[0]}; the "
                            "geometry and inertia of a link are constants of its own frame (the joint "
                            "variable is what moves it)")
        return expr

    def _vector(self, what: str, value) -> tuple:
        entries = three_entries(value)
        if entries is None:
            raise TreeError(f"link {self.name!r}: {what} must be 3 entries (x, y, z) in a list, tuple, 1-D "
                            f"array or sympy Matrix, got {value!r}")
        return tuple(self._expr(what, v) for v in entries)


def three_entries(value) -> tuple | None:
    """The 3 entries of a list, tuple, 1-D numpy array or 3-entry sympy Matrix, else None (found by
    review: numpy arrays were refused as "must be 3 entries", which they had)."""
    if isinstance(value, np.ndarray):
        return tuple(value.tolist()) if value.shape == (3,) else None
    if isinstance(value, sp.MatrixBase):
        return tuple(value) if sorted(value.shape) == [1, 3] else None
    if isinstance(value, (list, tuple)) and len(value) == 3:
        return tuple(value)
    return None


def checked_tree(links, coordinates) -> tuple:
    """``links`` as a tuple of `Link`, checked as a tree over ``coordinates``: unique names,
    parents listed first, joint variables linear in the coordinates with constant coefficients,
    and as many links as coordinates with an invertible map from coordinates to joint variables."""
    if not isinstance(links, (list, tuple)):
        raise TreeError(f"tree must be a list or tuple of Link, got {type(links).__name__}")
    seen: set = set()
    points: set = set()
    for link in links:
        if not isinstance(link, Link):
            raise TreeError(f"tree entries must be lagcodegen.Link, got {type(link).__name__} {link!r}")
        if link.name in seen:
            raise TreeError(f"link name {link.name!r} is used twice")
        if link.parent is not None and link.parent not in seen:
            raise TreeError(f"link {link.name!r} hangs from {link.parent!r}, which is not a link listed before it")
        for point in link.points:
            if point in points:
                raise TreeError(f"point name {point!r} is used twice (link {link.name!r})")
            points.add(point)
        seen.add(link.name)
    if links:
        joint_map(links, coordinates)
    return tuple(links)


def joint_map(links, coordinates) -> sp.Matrix:
    """P with joint variables = P q (rows: links, columns: coordinates), constant and invertible."""
    coordinates = tuple(coordinates)
    if len(links) != len(coordinates):
        raise TreeError(f"the tree has {len(links)} links (one joint variable each) but the model has "
                        f"{len(coordinates)} coordinates; every coordinate must move one joint")
    P = sp.zeros(len(links), len(coordinates))
    column = {c: j for j, c in enumerate(coordinates)}
    for i, link in enumerate(links):
        rest = link.variable
        for c in link.variable.atoms(sp.Function):
            if c not in column:
                continue
            coefficient = link.variable.diff(c)
            if coefficient.free_symbols or coefficient.atoms(sp.Function):
                raise TreeError(f"link {link.name!r}: the joint variable {link.variable} is not linear in "
                                f"{c.func.__name__} with a constant coefficient")
            if not coefficient.is_extended_real:
                raise TreeError(f"link {link.name!r}: the joint variable {link.variable} has the coefficient "
                                f"{coefficient} of {c.func.__name__}, which is not a real number")
            P[i, column[c]] = coefficient
            rest = rest - coefficient * c
        rest = sp.expand(rest)
        if rest != 0:
            raise TreeError(f"link {link.name!r}: the joint variable {link.variable} has a part {rest} that is "
                            "not a coordinate; joint variables are constant-coefficient sums of coordinates")
        if not any(P[i, j] != 0 for j in range(len(coordinates))):
            raise TreeError(f"link {link.name!r}: the joint variable {link.variable} involves no coordinate")
    if np.linalg.matrix_rank(np.array(P.evalf(), dtype=float)) < len(links):
        raise TreeError("the joint variables do not determine the coordinates (their map is singular): "
                        "two links move with the same combination of coordinates")
    return P
