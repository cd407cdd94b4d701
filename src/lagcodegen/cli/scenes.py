"""Stage: cli -> files. The animate subcommand: compile, simulate recording the named points,
write a GIF or MP4 (`lagcodegen.analysis.animation`)."""
from __future__ import annotations

import argparse

from .arguments import (
    EXIT_FAILED,
    EXIT_OK,
    UsageError,
    add_run_arguments,
    load_model,
    positive_float,
)
from .runs import check_steps, compile_for, interruptible, prepare_run, run_inputs

#: the step of an animation run unless --h says otherwise (a frame every 40 samples at 25 fps)
ANIMATE_H = 1e-3

ANIMATE_EPILOG = """examples:
  lagcodegen animate double_pendulum --x0 q1=1,q2=0.5 --t-end 5 --trace bob2 --out scene.gif
  lagcodegen animate elastic_pendulum --x0 r=1.3,phi=0.5 --t-end 5 --trace ball --out spring.gif
  lagcodegen animate centrifugal_governor --x0 alpha=0.6 --t-end 3 --projection 20,30 --out governor.gif
  lagcodegen animate slider_crank --x0 theta=0.3,theta_d=2 --t-end 2 --project --out slider_crank.gif
  lagcodegen animate four_bar --x0 theta1=0.3 --t-end 2 --project --speed 0.5 --out four_bar.mp4

The points are the model's named points (Model(points=...)); segments join the model's links
(Model(links=...)), else the chain from the origin through the points in their declared order.
Playback is real time (--speed 1): a GIF's frame delay is a whole number of hundredths of a second,
so --fps is rounded to match. MP4 needs ffmpeg. The overlay shows t and (E - E0)/|E0| when the model
has energies (for a driven or rheonomic model that is the work done on it, not an error).
Rigid bodies' frames are drawn as small triads at their mass centres (--no-frames to leave them out).
Exit code 0, 1 when the run stopped early (what ran is still animated), 2 for a bad command line.
"""


def parse_links(text: str | None):
    """``"origin-A,A-B"`` -> (("origin", "A"), ("A", "B")); None when not given."""
    if text is None:
        return None
    links = []
    for item in text.split(","):
        ends = tuple(name.strip() for name in item.split("-"))
        if len(ends) != 2 or not all(ends):
            raise UsageError(f"--links {item.strip()!r} must look like a-b (two point names; comma-separated pairs)")
        links.append(ends)
    return tuple(links)


def parse_projection(text: str | None):
    """``"xz"`` as it is, ``"20,30"`` -> (20.0, 30.0) (elevation, azimuth in degrees)."""
    if text is None or "," not in text:
        return text
    try:
        elevation, azimuth = (float(v) for v in text.split(","))
    except ValueError:
        raise UsageError(f"--projection {text!r} must be two axes (xy, xz, ...) or ELEVATION,AZIMUTH "
                         "in degrees") from None
    return elevation, azimuth


def animation_request(args) -> tuple:
    """(model, out path, animate's keyword arguments) of ``lagcodegen animate``, every name and
    value checked before anything is compiled."""
    import numpy as np

    from ..analysis.animation import check_output
    from ..analysis.scenes import AnimationError, frame_interval, frame_samples, project, scene_names

    try:
        target = check_output(args.out, "--out")
    except AnimationError as error:
        raise UsageError(str(error)) from None
    model = load_model(args.model)
    names = (*model.points, *model.tree_points())  # found by review: a tree's Link points were not seen
    if not names:
        raise UsageError(f"model {model.name!r} has no named points to animate; give it some, "
                         "Model(..., points={name: position}) or Link(..., points=...)")
    request = {"points": None if args.points is None else [name.strip() for name in args.points.split(",")],
               "links": parse_links(args.links) or model.links or None,
               "trace": [] if args.trace is None else [name.strip() for name in args.trace.split(",")],
               "projection": parse_projection(args.projection), "fps": args.fps, "speed": args.speed,
               "frames": model if draws_frames(model, getattr(args, "frames", None)) else None}
    try:
        scene_names(names, request["points"], request["links"], request["trace"], prefix="--")
        project(np.zeros(3), request["projection"])
        interval = frame_interval(args.fps, target.suffix.lower() == ".gif")  # before anything runs
    except AnimationError as error:
        message = str(error)
        raise UsageError(message if message.startswith("--") else f"--{message}") from None
    try:  # the frame count too (found by review: --speed 1e-4 was refused after the simulation)
        frame_samples(np.array([0.0, float(args.t_end)]), interval, args.speed)
    except AnimationError as error:
        raise UsageError(f"--speed: {error}") from None
    return model, target, request


def draws_frames(model, option: bool | None) -> bool:
    """Whether ``lagcodegen animate`` draws the bodies' frames: ``--frames``/``--no-frames``, by
    default when the model has rigid bodies; ``--frames`` on a model without them is a UsageError."""
    import sympy.physics.mechanics as me

    rigid = any(isinstance(body, me.RigidBody) for body in model.bodies)
    if option and not rigid:
        raise UsageError(f"--frames: model {model.name!r} has no rigid bodies whose frames could be drawn")
    return rigid if option is None else option


def cmd_animate(args) -> int:
    from ..analysis.animation import animate
    from ..run.inputs import InputError
    from ..run.simulate import simulate

    model, target, request = animation_request(args)
    eom, fixed, params, x0 = prepare_run(args, "animate", model=model)
    check_steps(args, 2 * eom.n + 1 + 3 * len(eom.points))
    energy = eom.energy is not None
    inputs = run_inputs(args)  # a table that cannot be read or is short, before the compile
    system = compile_for(eom, args.method, fixed, energy=energy, points=True)
    try:
        run = interruptible(lambda: simulate(
            system, x0, args.t_end, args.h, args.method, params=params, stride=args.stride, energy=energy,
            points=True, project=args.project, inputs=inputs, hold=args.hold))
    except InputError as error:
        raise UsageError(f"--input: {error}") from None
    print(f"{eom.name}, {run.method}, h = {args.h:g} to t = {args.t_end:g}: {run.message}")
    animate(run, target, title=f"{eom.name} ({run.method}, h = {args.h:g})", params={**fixed, **params},
            **request)
    print(f"wrote {target} ({run.t[-1] - run.t[0]:g} s simulated, {args.speed:g}x real time)")
    return EXIT_OK if run.ok else EXIT_FAILED


def add_animate_parser(commands) -> None:
    animate = commands.add_parser(
        "animate", help="simulate and write an animation of the named points (GIF or MP4)",
        description="Compile MODEL, run it from x0 to t = T recording its named points, and write an\n"
                    "animation of them: links drawn, traces of chosen points, the time and energy change.",
        epilog=ANIMATE_EPILOG, formatter_class=argparse.RawDescriptionHelpFormatter)
    add_run_arguments(animate, default_h=ANIMATE_H)
    animate.add_argument("--out", required=True, metavar="FILE.gif|FILE.mp4", help="the animation to write")
    animate.add_argument("--points", metavar="NAMES", help="comma-separated points to draw (default: all)")
    animate.add_argument("--links", metavar="A-B,...",
                         help="segments to draw, pairs of point names ('origin': the fixed origin; "
                              "default: the model's links, else the chain from the origin)")
    animate.add_argument("--trace", metavar="NAMES", help="comma-separated points whose path is drawn")
    animate.add_argument("--fps", type=positive_float, default=25.0, help="frames per second (default: 25)")
    animate.add_argument("--speed", type=positive_float, default=1.0,
                         help="simulated seconds per second of playback (default: 1, real time)")
    animate.add_argument("--projection", metavar="xy|xz|zy|ELEV,AZIM",
                         help="screen plane of 3-D models: two axes, or a view by elevation and azimuth in "
                              "degrees (default: xy; a negative elevation as --projection=-20,30)")
    animate.add_argument("--frames", action=argparse.BooleanOptionalAction, default=None,
                         help="draw each rigid body's frame (x red, y green, z blue) at its mass centre "
                              "(default: on when the model has rigid bodies)")
    animate.set_defaults(run=cmd_animate)
