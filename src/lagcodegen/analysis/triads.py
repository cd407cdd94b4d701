"""Stage: Model + Trajectory -> triads: the rigid bodies' frames along a run, as numbers.

For every RigidBody of a model on the bodies route, its frame's unit vectors x, y, z expressed
in the model's inertial frame (the columns of ``model.frame.dcm(body.frame)``) and its mass
centre's position from ``model.origin``, both lambdified once in (t, q) with the parameters'
values substituted, then evaluated at every sample of the trajectory (its coordinate columns
found by name). `scenes.compose_scene` projects them like the named points.
"""
from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import sympy as sp


class AnimationError(ValueError):
    """An animation cannot be made as asked; the message names the culprit."""


#: the default triad length, as a fraction of the largest extent of the drawn positions
FRAME_FRACTION = 0.15


def body_frames(model, trajectory, params: Mapping | None = None) -> tuple[tuple, np.ndarray, np.ndarray]:
    """The rigid bodies' mass centres and axes at every sample of ``trajectory``.

    Parameters
    ----------
    model : Model
        On the bodies route, with at least one RigidBody (Particles have no frame).
    trajectory : Trajectory
        A run of ``model``: its coordinates are the columns of ``x`` named like ``model.coordinates``.
    params : mapping of str or Symbol -> float, optional
        Parameter values over ``model.parameter_values`` (the run's free parameters, if it was
        run with others than the model's).

    Returns
    -------
    (tuple of str, ndarray (n_samples, n_bodies, 3), ndarray (n_samples, n_bodies, 3, 3))
        The bodies' names, their mass centres, and their axes: ``axes[s, b, i]`` is unit vector i
        (x, y, z) of body b in the model's frame.
    """
    import sympy.physics.mechanics as me

    from ..model import TIME, Model

    if not isinstance(model, Model):
        raise AnimationError(f"frames= must be a lagcodegen Model with rigid bodies, got {type(model).__name__}")
    bodies = [body for body in model.bodies if isinstance(body, me.RigidBody)]
    if not bodies:
        raise AnimationError(f"frames=: model {model.name!r} has no rigid bodies whose frames could be drawn "
                             "(it needs Model(bodies=[RigidBody(...)]) with frame= and origin=)")
    values = _parameter_values(model, params)
    q = tuple(model.coordinates)
    symbols = sp.symbols(f"_q0:{len(q)}")
    columns = _coordinate_columns(model, trajectory)
    entries = []
    for body in bodies:
        try:
            axes = model.frame.dcm(body.frame)  # columns: the body's unit vectors in model.frame
            centre = body.masscenter.pos_from(model.origin).to_matrix(model.frame)
        except ValueError as error:
            raise AnimationError(f"frames=: body {body.name!r} (its frame {body.frame}) cannot be expressed in the "
                                 f"model's frame {model.frame} from origin {model.origin.name}: {error}") from None
        entries.append(sp.Matrix.hstack(centre, axes))
    block = sp.Matrix.vstack(*entries).subs(values).subs(dict(zip(q, symbols)))
    _check_symbols(block, bodies, entries, values, q, symbols, TIME)
    # every entry over all samples at once (found by review: a call per sample took 1.0 s of 30001 samples,
    # 20x the run); a constant entry comes back as a number and is broadcast
    function = sp.lambdify((TIME, *symbols), list(block), modules="numpy")
    t = np.asarray(trajectory.t, dtype=np.float64)
    x = np.asarray(trajectory.x, dtype=np.float64)
    entries = function(t, *(x[:, c] for c in columns))
    out = np.stack([np.broadcast_to(np.asarray(e, dtype=np.float64), t.shape) for e in entries], axis=-1)
    out = out.reshape(len(t), len(bodies), 3, 4)
    return tuple(body.name for body in bodies), out[..., 0], np.swapaxes(out[..., 1:], -1, -2)


def _parameter_values(model, params: Mapping | None) -> dict:
    values = dict(model.parameter_values)
    by_name = {p.name: p for p in model.parameters}
    for key, value in dict(params or {}).items():
        name = key.name if isinstance(key, sp.Symbol) else str(key)
        if name not in by_name:
            raise AnimationError(f"params: {name!r} is no parameter of model {model.name!r} "
                                 f"(parameters: {', '.join(by_name) or 'none'})")
        values[by_name[name]] = float(value)
    return values


def _coordinate_columns(model, trajectory) -> list:
    names = list(trajectory.names)
    columns = []
    for qi in model.coordinates:
        name = qi.func.__name__
        if name not in names:
            raise AnimationError(f"frames=: model {model.name!r}'s coordinate {name!r} is not a column of the "
                                 f"trajectory (columns: {', '.join(names)}); is it a run of this model?")
        columns.append(names.index(name))
    return columns


def _check_symbols(block, bodies, entries, values, q, symbols, time) -> None:
    allowed = set(symbols) | {time}
    for body, entry in zip(bodies, entries):
        stray = entry.subs(values).subs(dict(zip(q, symbols))).free_symbols - allowed
        if stray or entry.atoms(sp.Derivative):
            missing = ", ".join(sorted(map(str, stray))) or "derivatives of the coordinates"
            raise AnimationError(f"frames=: body {body.name!r}'s frame or mass centre depends on {missing}, "
                                 "which have no values (give params=, or Model(parameter_values=...))")


def frame_size(positions: np.ndarray) -> float:
    """`FRAME_FRACTION` of the largest extent (over x, y, z) of ``positions (..., 3)``; 1 when they all coincide."""
    xyz = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    xyz = xyz[np.all(np.isfinite(xyz), axis=1)]
    extent = float(np.max(xyz.max(axis=0) - xyz.min(axis=0))) if len(xyz) else 0.0
    return FRAME_FRACTION * extent if extent > 0 else 1.0
