"""Stage: Scene -> figures and files: animations of a run, written as GIF or MP4.

The named points of a run (``simulate(..., points=True)``) drawn frame by frame: segments for
the links between them, a trace of chosen points, the frames of a model's rigid bodies as small
x/y/z triads (``frames=model``, `triads`), and a clock with the relative energy change
(E - E0) / |E0| when the run recorded the energy (an energy *error* for a conservative model;
for a driven or rheonomic one it is the work done on it). `scenes.compose_scene` picks the
frames and projects the points (numbers), `draw_scene` builds the figure and the function that
draws frame k, and `animate` chains them into a ``FuncAnimation`` and writes it: GIFs with
Pillow, MP4s with ffmpeg (matplotlib's ``FFMpegWriter``). Real-time playback: see `scenes`.
"""
from __future__ import annotations

import math
import os
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .scenes import DEFAULT_FPS, ORIGIN, AnimationError, Scene, clock_text, compose_scene

if TYPE_CHECKING:
    from matplotlib.animation import FuncAnimation
    from matplotlib.figure import Figure

    from ..run.simulate import Trajectory

#: the file types `animate` writes, by suffix
FORMATS = (".gif", ".mp4")
#: colours of a body frame's x, y, z axes
TRIAD_COLOURS = ("tab:red", "tab:green", "tab:blue")


def draw_scene(scene: Scene, *, title: str | None = None, size=(5.0, 5.0),
               dpi: float = 80) -> tuple[Figure, Callable[[int], list]]:
    """The figure of ``scene`` and ``update(k)``, which draws frame k and returns the artists.

    Every artist carries a label: ``"link a-b"`` per link, ``"points"`` (the drawn points, in
    ``scene.names[1:]`` order), ``"trace name"`` per traced point, ``"origin"`` (when a link
    uses it), ``"frame body x"`` (and y, z) per axis of a body's frame when the scene has
    ``triads``, and ``"clock"`` (the time and energy text).
    """
    from matplotlib.figure import Figure  # Agg canvas via savefig; no pyplot, no GUI

    fig = Figure(figsize=size, dpi=dpi)  # fixed margins: a layout engine would redo (and draw) every frame
    fig.subplots_adjust(left=0.15, right=0.96, bottom=0.11, top=0.93)
    ax = fig.add_subplot()
    _frame_axes(ax, scene, title)
    if scene.uses_origin:
        ax.plot(*scene.xy[0, 0], "s", color="black", markersize=6, label=ORIGIN, zorder=4)
    traces = [ax.plot([], [], linewidth=1.0, alpha=0.7, label=f"trace {scene.names[i]}")[0] for i in scene.trace]
    links = [ax.plot([], [], "-", linewidth=2.5, color="dimgray", solid_capstyle="round",
                     label=f"link {scene.names[i]}-{scene.names[j]}")[0] for i, j in scene.links]
    axes = [(b, i, ax.plot([], [], "-", linewidth=1.2, color=TRIAD_COLOURS[i], zorder=5,
                           label=f"frame {name} {'xyz'[i]}")[0])
            for b, name in enumerate(scene.triad_names) for i in range(3)]
    markers = ax.plot([], [], "o", markersize=8, color="tab:blue", label="points", zorder=3)[0]
    clock = ax.text(0.02, 0.98, "", transform=ax.transAxes, va="top", ha="left", family="monospace",
                    fontsize=8, label="clock")

    def update(k: int) -> list:
        sample = int(scene.samples[k])
        frame = scene.xy[sample]
        for line, (i, j) in zip(links, scene.links):
            line.set_data(frame[[i, j], 0], frame[[i, j], 1])
        markers.set_data(frame[1:, 0], frame[1:, 1])
        for line, i in zip(traces, scene.trace):
            line.set_data(scene.xy[:sample + 1, i, 0], scene.xy[:sample + 1, i, 1])
        for b, i, line in axes:
            line.set_data(scene.triads[sample, b, i, :, 0], scene.triads[sample, b, i, :, 1])
        clock.set_text(clock_text(scene, sample))
        return [*traces, *links, markers, *(line for _, _, line in axes), clock]

    update(0)
    return fig, update


def _frame_axes(ax, scene: Scene, title: str | None) -> None:
    """Equal-aspect limits that hold every drawn position of the whole run, with a margin."""
    columns = list(range(0 if scene.uses_origin else 1, len(scene.names)))
    xy = scene.xy[:, columns].reshape(-1, 2)
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    low, high = (xy.min(axis=0), xy.max(axis=0)) if len(xy) else (np.zeros(2), np.zeros(2))
    centre, half = (low + high) / 2, max(float(np.max(high - low)) / 2, 1e-9) * 1.15
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_aspect("equal")
    ax.set_xlabel(scene.axis_labels[0])
    ax.set_ylabel(scene.axis_labels[1])
    ax.grid(True, alpha=0.3)
    if title:
        ax.set_title(title, fontsize=10)


def check_output(out, what: str = "out") -> Path:
    """``out`` as a Path to write, or `AnimationError` naming it (as the argument ``what``):
    empty, a directory, in a missing directory, not ``.gif`` or ``.mp4``, or ``.mp4`` without ffmpeg."""
    text = str(out) if isinstance(out, (str, Path)) else None
    suffixes = " or ".join(FORMATS)
    if text is None or not text.strip():
        raise AnimationError(f"{what} {out!r} must be a file name ending in {suffixes}")
    target = Path(text)
    if target.is_dir():
        raise AnimationError(f"{what} {text!r} is a directory; give a file name ending in {suffixes}")
    if target.suffix.lower() not in FORMATS:
        raise AnimationError(f"{what} {text!r}: cannot write {target.suffix or 'a file without a suffix'}; "
                             f"give a file name ending in {suffixes}")
    if not target.parent.is_dir():
        raise AnimationError(f"{what} {text!r}: {target.parent} is not an existing directory")
    if target.suffix.lower() == ".mp4":
        from matplotlib.animation import FFMpegWriter

        if not FFMpegWriter.isAvailable():
            raise AnimationError(f"{what} {text!r}: writing MP4 needs ffmpeg, which was not found (on PATH, or "
                                 "matplotlib's rcParams['animation.ffmpeg_path']); install ffmpeg or write a .gif")
    # before any frame is drawn (found by review: an unwritable place failed only after the whole run
    # was drawn, naming no argument)
    from ..run.arguments import unwritable

    reason = unwritable(target)
    if reason is not None:
        raise AnimationError(f"{what} {text!r}: cannot write there ({reason})")
    return target


def animate(trajectory: Trajectory, out=None, *, points: Sequence[str] | None = None,
            links: Sequence[tuple[str, str]] | None = None, trace: Sequence[str] = (), fps: float = DEFAULT_FPS,
            speed: float = 1.0, projection=None, title: str | None = None, size=(5.0, 5.0),
            dpi: float = 80, frames=None, frame_size: float | None = None, params=None) -> FuncAnimation:
    """Animate the named points of a run; write it to ``out`` (.gif or .mp4) when given.

    Parameters
    ----------
    trajectory : Trajectory
        Simulated with ``points=True`` (and ``energy=True`` for the energy overlay);
        ``points (n_samples, n_points, 3)`` named by ``point_names``. Each frame shows the sample
        nearest its time, so keep samples at least as often as frames (``stride * h <= speed / fps``)
        for even motion; a run that stopped early is animated up to where it stopped.
    out : str or Path, optional
        ``*.gif`` (Pillow) or ``*.mp4`` (ffmpeg; `AnimationError` when it is missing). Checked
        before anything is drawn.
    points : sequence of str, optional
        The points to draw (default: all).
    links : sequence of (str, str), optional
        Pairs of point names joined by a segment, ``"origin"`` the fixed origin; pass the
        model's ``Model.links or None`` (an empty sequence draws no segment). Default (None): the
        chain origin -> first point -> second -> ...
    trace : sequence of str
        Points whose path up to the current frame is drawn.
    fps : float
        Frames per second of playback (a GIF rounds the interval to 10 ms, see the module doc).
    speed : float
        Simulated seconds per second of playback; 1 is real time.
    projection : None, str or (float, float)
        Onto the screen plane, orthographic (`project`): "xy" (default), "xz", ... or
        (elevation, azimuth) in degrees for a 3-D model seen at an angle.
    title : str, optional
    size, dpi
        Figure size in inches and resolution of the written frames.
    frames : Model, optional
        The model of the run, on the bodies route: each of its RigidBodies' frames is drawn as a
        thin triad (x red, y green, z blue) at its mass centre, from the run's coordinates
        (`triads.body_frames`; `AnimationError` naming the model when it has no rigid body).
    frame_size : float, optional
        The triads' length (default: 0.15 of the largest extent of the points and mass centres).
    params : mapping of str -> float, optional
        Parameter values for the frames over the model's ``parameter_values`` (the run's, if
        it was run with others).

    Returns
    -------
    matplotlib.animation.FuncAnimation
        ``to_jshtml()`` shows it in a notebook; the frames and times are `compose_scene`'s.

    Examples
    --------
    A mass on a spring (omega = 2) for one second in real time at 25 frames per second: 26
    frames, 40 ms apart, at t = 0, 0.04, ..., 1; the last shows x(1) = cos 2 = -0.416147:

    >>> import pathlib, tempfile
    >>> import sympy as sp, sympy.physics.mechanics as me
    >>> from PIL import Image
    >>> from lagcodegen import Model
    >>> from lagcodegen.pipeline import compile_model
    >>> from lagcodegen.run.simulate import simulate
    >>> x = me.dynamicsymbols("x")
    >>> m, k = sp.symbols("m k", positive=True)
    >>> model = Model("oscillator", [x], [m, k], kinetic_energy=m * x.diff()**2 / 2,
    ...               potential_energy=k * x**2 / 2, parameter_values={"m": 1.0, "k": 4.0},
    ...               points={"mass": (x, 0)})
    >>> run = simulate(compile_model(model, methods=("rk4",)), {"x": 1.0}, 1.0, 1e-3, energy=True, points=True)
    >>> out = pathlib.Path(tempfile.mkdtemp()) / "oscillator.gif"
    >>> anim = animate(run, out, trace=["mass"], dpi=40)
    >>> gif = Image.open(out)
    >>> gif.n_frames, gif.info["duration"]
    (26, 40)
    >>> scene = compose_scene(run)
    >>> round(float(scene.xy[scene.samples[-1], 1, 0]), 6)
    -0.416147
    """
    target = None if out is None else check_output(out)
    gif = target is not None and target.suffix.lower() == ".gif"
    scene = compose_scene(trajectory, points=points, links=links, trace=trace, fps=fps, speed=speed,
                          projection=projection, gif=gif, frames=frames, frame_size=frame_size, params=params)
    if gif:
        _check_gif_memory(scene.n_frames, size, dpi)
    fig, update = draw_scene(scene, title=title, size=size, dpi=dpi)
    from matplotlib.animation import FuncAnimation

    animation = FuncAnimation(fig, update, frames=scene.n_frames, interval=scene.interval, blit=False)
    if target is not None:
        write_animation(animation, target, scene.interval, dpi)
    return animation


#: bytes a GIF's frame holds until the file is written, per pixel (matplotlib's PillowWriter keeps
#: every frame; the peak RSS of animate() grew 0.83-0.92 MB per 400 x 400 frame over 251 and 751
#: frames, 5.2-5.8 bytes per pixel, 2026-11-26)
GIF_BYTES_PER_PIXEL = 6


def _check_gif_memory(n_frames: int, size, dpi: float) -> None:
    """`OutputTooLargeError` before drawing when the GIF's frames would not fit in the memory a run
    may keep (half the physical memory; found by review: 18,000 frames at the default size would
    have taken about 15 GB)."""
    from ..run.arguments import check_memory

    width, height = (math.ceil(float(v) * float(dpi)) for v in size)
    check_memory(n_frames * width * height * GIF_BYTES_PER_PIXEL,
                 f"a GIF of {n_frames} frames of {width} x {height} pixels (its writer keeps every frame)",
                 "lower the dpi, the size or the fps, raise the speed, or write an .mp4")


def write_animation(animation: FuncAnimation, target: Path, interval: float, dpi: float) -> Path:
    """Write ``animation`` to ``target`` (checked by `check_output`), ``interval`` ms per frame."""
    from matplotlib.animation import FFMpegWriter, PillowWriter

    if target.suffix.lower() == ".gif":
        # PillowWriter stores int(1000 / fps) ms: nudge fps so that is the interval itself (1000 /
        # (1000 / 30) is 29.999..., which int() would cut to 29 and a GIF to 20 ms)
        writer = PillowWriter(fps=1000.0 / (interval + 1e-6))
    else:
        writer = FFMpegWriter(fps=1000.0 / interval)
    # written beside the target, then moved there: a failed write leaves an existing file as it was
    # (found by review: one was truncated to 800 bytes)
    partial = target.with_name(f".{target.stem}.{os.getpid()}.partial{target.suffix}")
    try:
        animation.save(str(partial), writer=writer, dpi=dpi)
        os.replace(partial, target)
    finally:
        if partial.exists():
            partial.unlink()
    return target
