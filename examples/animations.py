"""Animations of five catalog models (issue 16): the double pendulum, the elastic pendulum, the
centrifugal governor (3-D, seen from 20 degrees above), the slider-crank and the four-bar.

Each is compiled with RK4, run for a second from a consistent state, and written as a
GIF in real time: the links of the model, a trace of its last point, the frames of its rigid
bodies as small x/y/z triads (slider-crank, four-bar), the time and the relative energy change
(for the driven slider-crank and four-bar and the spun governor that is the work done on them,
not an error).

Run: python examples/animations.py [OUT_DIR]     (default: a new temporary directory)
The same from the command line: lagcodegen animate --help.
"""
import sys
import tempfile
import time
from pathlib import Path

import sympy.physics.mechanics as me

from lagcodegen import catalog
from lagcodegen.analysis.animation import animate
from lagcodegen.pipeline import compile_model
from lagcodegen.run.simulate import simulate

T_END, H = 1.0, 1e-3

#: name -> (model, initial state, projection onto the screen)
SCENES = {
    "double_pendulum": (catalog.double_pendulum(), {"q1": 1.0, "q2": 0.5}, "xy"),
    "elastic_pendulum": (catalog.elastic_pendulum(), {"r": 1.3, "phi": 0.5}, "xy"),
    "centrifugal_governor": (catalog.centrifugal_governor(), {"alpha": 0.6}, (20.0, 30.0)),
    "slider_crank": (catalog.slider_crank(), catalog.slider_crank_state(0.3, 2.0), "xy"),
    "four_bar": (catalog.four_bar(), catalog.four_bar_state(0.3, 2.0), "xy"),
}


def main(out_dir: Path) -> None:
    for name, (model, x0, projection) in SCENES.items():
        start = time.perf_counter()
        system = compile_model(model, methods=("rk4",))
        constrained = bool(model.constraints)  # closed loops: projected back onto phi = 0 every step
        run = simulate(system, x0, T_END, H, energy=True, points=True, project=constrained).check()
        out = out_dir / f"{name}.gif"
        rigid = any(isinstance(body, me.RigidBody) for body in model.bodies)
        animate(run, out, links=model.links or None, trace=[run.point_names[-1]], projection=projection,
                title=f"{name} (rk4, h = {H:g})", size=(4.0, 4.0), dpi=60, frames=model if rigid else None)
        print(f"{name:22s} points {', '.join(run.point_names)}: wrote {out} "
              f"({out.stat().st_size / 1024:.0f} KiB, {time.perf_counter() - start:.1f} s)")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(tempfile.mkdtemp(prefix="lagcodegen_animations_")))
