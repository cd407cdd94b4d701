"""Stage: Trajectory -> Scene: the numbers of an animation (frames, projected points, links).

What every frame of an animation shows, before anything is drawn (`animation` draws it): the
sample each frame shows, the named points projected onto the screen, the links between them,
the traced points and the relative energy change. Playback is real time by default: consecutive
frames are ``speed * interval`` apart in simulated time, shown ``interval`` ms apart; a GIF
stores frame delays in hundredths of a second, so for a GIF the interval is rounded to 10 ms
(at least 20 ms, the shortest delay browsers honour) and the frame times follow it.
"""
from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from .triads import AnimationError, body_frames, frame_size

if TYPE_CHECKING:
    from ..run.simulate import Trajectory

#: the fixed origin every point position is measured from, as a name in ``links``
ORIGIN = "origin"
#: default frames per second: 40 ms, a whole number of a GIF's hundredths of a second
DEFAULT_FPS = 25.0
_AXES = "xyz"


@dataclass(frozen=True)
class Scene:
    """What every frame of an animation shows, as numbers (`compose_scene` builds it).

    Attributes
    ----------
    names : tuple of str, (n_names,)
        ``ORIGIN`` first, then the drawn points.
    xy : ndarray, (n_samples, n_names, 2)
        Projected positions of ``names`` at every sample of the trajectory.
    t : ndarray, (n_samples,)
    samples : ndarray of int, (n_frames,)
        The sample frame k shows: the one nearest ``t[0] + k * speed * interval / 1000``.
    links : tuple of (int, int)
        Index pairs into ``names`` joined by a segment.
    trace : tuple of int
        Indices into ``names`` of the points whose path so far is drawn.
    energy_change : ndarray (n_samples,) or None
        (E - E0) / |E0| (E - E0 when E0 = 0), None without energy samples.
    relative : bool
        Whether ``energy_change`` is divided by |E0|.
    interval : float
        Milliseconds between frames.
    speed : float
        Simulated seconds per second of playback.
    axis_labels : (str, str)
        The screen axes' names ("x", "y", or "view" ones for a projection by angles).
    triads : ndarray (n_samples, n_bodies, 3, 2, 2) or None
        The rigid bodies' frames (``frames=``): ``triads[s, b, i]`` is the projected segment
        (start, end) of body b's axis i (x, y, z), from its mass centre ``frame_size`` long.
    triad_names : tuple of str, (n_bodies,)
        The bodies whose frames ``triads`` holds.
    """

    names: tuple
    xy: np.ndarray
    t: np.ndarray
    samples: np.ndarray
    links: tuple
    trace: tuple
    energy_change: np.ndarray | None
    relative: bool
    interval: float
    speed: float
    axis_labels: tuple
    triads: np.ndarray | None = None
    triad_names: tuple = ()

    @property
    def n_frames(self) -> int:
        return len(self.samples)

    @property
    def uses_origin(self) -> bool:
        return any(0 in link for link in self.links)


def project(positions: np.ndarray, projection=None) -> tuple[np.ndarray, tuple]:
    """Orthographic projection of 3-D positions onto the screen.

    Parameters
    ----------
    positions : ndarray, (..., 3)
    projection : None, str or (float, float)
        ``None`` or ``"xy"``: drop z (the catalog's planar models live in the xy plane, y up).
        Two letters of ``"xyz"`` (``"xz"``, ``"zy"``, ...): the screen's horizontal and vertical
        axes. ``(elevation, azimuth)`` in degrees: the view from direction
        d = (sin a cos e, sin e, cos a cos e) with y up; screen axes
        u = (cos a, 0, -sin a) and v = (-sin e sin a, cos e, -sin e cos a), so (0, 0) is ``"xy"``.

    Returns
    -------
    (ndarray (..., 2), (str, str))
        Screen coordinates and the axes' labels.
    """
    positions = np.asarray(positions, dtype=np.float64)
    if projection is None:
        projection = "xy"
    if isinstance(projection, str):
        if len(projection) != 2 or not set(projection) <= set(_AXES) or projection[0] == projection[1]:
            raise AnimationError(f"projection {projection!r} must be two different letters of 'xyz' "
                                 "(e.g. 'xy', 'xz') or (elevation, azimuth) in degrees")
        columns = [_AXES.index(c) for c in projection]
        return positions[..., columns], tuple(projection)
    try:
        elevation, azimuth = (math.radians(float(v)) for v in projection)
    except (TypeError, ValueError):
        raise AnimationError(f"projection {projection!r} must be two letters of 'xyz' or (elevation, azimuth) "
                             "in degrees") from None
    if not (math.isfinite(elevation) and math.isfinite(azimuth)):
        raise AnimationError(f"projection {projection!r}: the angles must be finite")
    se, ce, sa, ca = math.sin(elevation), math.cos(elevation), math.sin(azimuth), math.cos(azimuth)
    screen = np.array([[ca, 0.0, -sa], [-se * sa, ce, -se * ca]])
    view = f"elevation {math.degrees(elevation):g} deg, azimuth {math.degrees(azimuth):g} deg"
    return positions @ screen.T, (f"u (view from {view})", "v")


#: frames an animation may have: 10 minutes at 30 fps, far beyond what anyone watches, and a
#: bound on the time a slip of ``speed`` (1e-5 for 1e-1) would take; a GIF's memory is checked
#: apart (`animation.GIF_BYTES_PER_PIXEL`)
MAX_FRAMES = 18_000


def frame_samples(t: np.ndarray, interval: float, speed: float) -> np.ndarray:
    """Indices into ``t`` (n_samples,) of the frames: the sample nearest each frame time
    ``t[0] + k * speed * interval / 1000`` up to ``t[-1]``, then the last sample when no frame
    fell on it; shape (n_frames,). More than
    `MAX_FRAMES` frames raise `AnimationError`, naming the speed."""
    t = np.asarray(t, dtype=np.float64)
    step = speed * interval / 1000.0
    span = float(t[-1] - t[0])
    frames = span / step * (1 + 1e-12)
    if not frames < MAX_FRAMES:
        raise AnimationError(f"{span:g} s of motion at speed {speed:g} and {1000.0 / interval:g} frames per second "
                             f"would take {frames:.3g} frames, more than {MAX_FRAMES}: raise the speed, lower the "
                             "fps or animate a shorter run")
    n_frames = int(math.floor(frames)) + 1
    targets = t[0] + step * np.arange(n_frames)
    right = np.clip(np.searchsorted(t, targets), 1, max(len(t) - 1, 1))
    left = right - 1
    nearer_right = np.abs(t[np.minimum(right, len(t) - 1)] - targets) < np.abs(t[left] - targets)
    samples = np.where(nearer_right, np.minimum(right, len(t) - 1), left)
    if samples[-1] != len(t) - 1:  # the run's last state ends it, a shorter last interval (found by
        samples = np.append(samples, len(t) - 1)  # review: t_end = 1.039 at 25 fps ended at t = 1)
    return samples


#: the longest frame a GIF holds: its delay is a 16-bit count of hundredths of a second
GIF_LONGEST_FRAME_MS = 655_350.0


def frame_interval(fps: float, gif: bool) -> float:
    """Milliseconds between frames: 1000 / fps, rounded to 10 ms (at least 20) for a GIF."""
    fps = _positive(fps, "fps")
    interval = 1000.0 / fps
    if gif and interval > GIF_LONGEST_FRAME_MS:  # found by review: Pillow's OverflowError, the old file truncated
        raise AnimationError(f"fps {fps:g}: a GIF frame lasts at most {GIF_LONGEST_FRAME_MS / 1000:g} s (a 16-bit "
                             f"count of 10 ms), so fps must be at least {1000 / GIF_LONGEST_FRAME_MS:.3g}")
    return max(20.0, 10.0 * round(interval / 10.0)) if gif else interval



def compose_scene(trajectory: Trajectory, *, points: Sequence[str] | None = None,
                  links: Sequence[tuple[str, str]] | None = None, trace: Sequence[str] = (),
                  fps: float = DEFAULT_FPS, speed: float = 1.0, projection=None, gif: bool = False,
                  frames=None, frame_size: float | None = None, params=None) -> Scene:
    """The frames of an animation of ``trajectory``, as numbers (see `animate` for the arguments)."""
    if trajectory.point_names and trajectory.points is None:
        raise AnimationError(f"the trajectory holds no positions of its points ({', '.join(trajectory.point_names)}): "
                             "simulate it with points=True")
    names, pairs, traced = scene_names(trajectory.point_names, points, links, trace)
    if len(trajectory.t) == 0:
        raise AnimationError("the trajectory has no samples to animate")
    rows = [trajectory.point_names.index(name) for name in names[1:]]
    positions = np.asarray(trajectory.points, dtype=np.float64)[:, rows]
    origin = np.zeros((len(positions), 1, 3))
    xy, labels = project(np.concatenate([origin, positions], axis=1), projection)
    interval = frame_interval(fps, gif)
    speed = _positive(speed, "speed")
    change, relative = energy_change(trajectory)
    t = np.asarray(trajectory.t, dtype=np.float64)
    triads, triad_names = (None, ()) if frames is None else \
        project_triads(trajectory, frames, positions, projection, frame_size, params)
    return Scene(names=names, xy=xy, t=t, samples=frame_samples(t, interval, speed), links=pairs, trace=traced,
                 energy_change=change, relative=relative, interval=interval, speed=speed, axis_labels=labels,
                 triads=triads, triad_names=triad_names)


def project_triads(trajectory: Trajectory, model, positions: np.ndarray, projection=None,
                   size: float | None = None, params=None) -> tuple[np.ndarray, tuple]:
    """The projected frames of ``model``'s rigid bodies (`triads.body_frames`), each axis a segment
    ``size`` long from the mass centre (default: `triads.frame_size` of ``positions (n_samples,
    n_points, 3)`` and the mass centres); (ndarray (n_samples, n_bodies, 3, 2, 2), body names)."""
    names, centres, axes = body_frames(model, trajectory, params)
    if size is None:
        size = frame_size(np.concatenate([positions.reshape(-1, 3), centres.reshape(-1, 3), np.zeros((1, 3))]))
    size = _positive(size, "frame_size")
    starts = np.broadcast_to(centres[:, :, None, :], axes.shape)
    segments = np.stack([starts, starts + size * axes], axis=-2)  # (n_samples, n_bodies, 3, 2, 3)
    return project(segments, projection)[0], names


def scene_names(point_names: Sequence[str], points: Sequence[str] | None = None,
                links: Sequence[tuple[str, str]] | None = None, trace: Sequence[str] = (),
                prefix: str = "") -> tuple:
    """(names, links, trace) of a scene: ``ORIGIN`` and the drawn points, the links and traced
    points as indices into them; every name checked against ``point_names`` (the model's).

    ``points=None`` draws every point; ``links=None`` the chain from the origin through the
    drawn points in the order the model declares them (a pendulum chain, a slider-crank).
    Errors name the argument with ``prefix`` in front (``"--"`` on the command line).
    """
    if not point_names:
        raise AnimationError("the model has no named points to animate; give it some, "
                             "Model(..., points={name: position})")
    drawn = tuple(point_names)
    if points is not None:
        chosen = _name_list(points, f"{prefix}points")
        if not chosen:
            raise AnimationError(f"{prefix}points is empty; choose from {', '.join(point_names)}")
        known = dict(zip(drawn, drawn))
        picked = set(_known(name, known, f"{prefix}points", point_names) for name in chosen)
        # in the model's order, as the default chain promises (found by review: points=bob2,bob1 drew a
        # rod from the hinge to bob2)
        drawn = tuple(name for name in point_names if name in picked)
    index = {ORIGIN: 0} | {name: i for i, name in enumerate(drawn, start=1)}
    if links is None:
        pairs = tuple(zip((ORIGIN,) + drawn[:-1], drawn))
    else:
        pairs = tuple(_checked_link(link, index, f"{prefix}links") for link in links)
    traced = tuple(_known(name, index, f"{prefix}trace", drawn) for name in _name_list(trace, f"{prefix}trace"))
    return (ORIGIN,) + drawn, tuple((index[a], index[b]) for a, b in pairs), traced


def energy_change(trajectory: Trajectory) -> tuple[np.ndarray | None, bool]:
    """((E - E0) / |E0| (n_samples,), True), or (E - E0, False) when E0 = 0; (None, False) without energy."""
    if trajectory.energy is None or len(trajectory.energy) == 0:
        return None, False
    energy = np.asarray(trajectory.energy, dtype=np.float64)
    e0 = float(energy[0])
    return ((energy - e0) / abs(e0), True) if e0 != 0 else (energy - e0, False)


def _name_list(names, what: str) -> list:
    if isinstance(names, str):
        names = [names]
    if not isinstance(names, Sequence) or not all(isinstance(name, str) for name in names):
        raise AnimationError(f"{what} must be point names (strings), got {names!r}")
    return list(names)


def _known(name: str, index: dict, what: str, known) -> int | str:
    if name not in index:
        raise AnimationError(f"{what}: no point {name!r}; points: {', '.join(known)}")
    return index[name]


def _checked_link(link, index: dict, what: str) -> tuple:
    if not (isinstance(link, Sequence) and not isinstance(link, str) and len(link) == 2):
        raise AnimationError(f"{what}: {link!r} must be a pair of point names (name, name)")
    for name in link:
        _known(name, index, f"{what}: {tuple(link)!r}", index)
    return tuple(link)


def _positive(value, what: str) -> float:
    try:
        number = float(value)
    except (TypeError, ValueError):
        raise AnimationError(f"{what} must be a positive number, got {value!r}") from None
    if isinstance(value, bool) or not (math.isfinite(number) and number > 0):
        raise AnimationError(f"{what} must be a positive finite number, got {value!r}")
    return number


def clock_text(scene: Scene, sample: int) -> str:
    """The overlay of a frame showing ``sample``: the time, and the energy change when recorded."""
    text = f"t = {scene.t[sample]:.3f} s" + (f"  ({scene.speed:g}x)" if scene.speed != 1 else "")
    if scene.energy_change is not None:
        label = "(E - E0)/|E0|" if scene.relative else "E - E0"
        text += f"\n{label} = {scene.energy_change[sample]:+.2e}"
    return text
