"""Animations of a run (analysis/scenes.py, analysis/animation.py, ``lagcodegen animate``): the drawn points are where
the trajectory says, playback is real time, files are written, bad input is named.

Independent sources of the expected values:
- the double pendulum's positions by the hand formula bob1 = l1 (sin q1, -cos q1),
  bob2 = bob1 + l2 (sin q2, -cos q2) (q from the downward vertical; catalog.pendulum_chain's
  docstring) applied to the recorded q, and its energy T + V written out by hand;
- real time by its definition: frames ``speed * interval`` of simulated time apart, an interval
  of 1000 / fps ms (25 fps: 40 ms, a GIF's 4 hundredths of a second); frame k shows the sample
  at t = k * 0.04 s, index k * 0.04 / h, computed here;
- the written GIF as Pillow reads it back (frame count, per-frame duration, size);
- orthographic views worked out by hand: seen from +x with y up, the screen's right is -z;
  seen from above (elevation 90), the screen's up is -z;
- for the five example models of the issue, the trajectory's own recorded points.
"""
from __future__ import annotations

import dataclasses
import inspect
import math
from pathlib import Path

import numpy as np
import pytest

from lagcodegen import catalog
from lagcodegen.analysis import scenes
from lagcodegen.analysis.animation import animate, draw_scene
from lagcodegen.analysis.scenes import AnimationError, compose_scene, project
from lagcodegen.cli.commands import main
from lagcodegen.model import Model, ModelError
from lagcodegen.native.build import compiler_available
from lagcodegen.run.simulate import Status, Trajectory, simulate

needs_cc = pytest.mark.skipif(not compiler_available(), reason="no C compiler / Python headers")

H, T_END = 1e-3, 0.2  # 200 steps; at 25 fps: frames at t = 0, 0.04, ..., 0.2 (6 of them)


@pytest.fixture(scope="module")
def pendulum_run():
    if not compiler_available():
        pytest.skip("no C compiler / Python headers")
    from lagcodegen.pipeline import compile_model

    model = catalog.double_pendulum()
    system = compile_model(model, outputs=("rhs", "energy", "points"), methods=("rk4",))
    run = simulate(system, {"q1": 1.0, "q2": 0.5, "q1_d": 0.3}, T_END, H, energy=True, points=True)
    return model, run.check()


def by_label(artists) -> dict:
    return {artist.get_label(): artist for artist in artists}


def hand_positions(run, values: dict) -> np.ndarray:
    """(n_samples, 2, 2): bob1, bob2 from the recorded q by the textbook formula."""
    q1, q2 = run["q1"].astype(float), run["q2"].astype(float)
    l1, l2 = values["l1"], values["l2"]
    bob1 = np.stack([l1 * np.sin(q1), -l1 * np.cos(q1)], axis=1)
    bob2 = bob1 + np.stack([l2 * np.sin(q2), -l2 * np.cos(q2)], axis=1)
    return np.stack([bob1, bob2], axis=1)


def hand_energy(run, v: dict) -> np.ndarray:
    q1, q2, u1, u2 = (run[name].astype(float) for name in ("q1", "q2", "q1_d", "q2_d"))
    T = ((v["m1"] + v["m2"]) * v["l1"] ** 2 * u1 ** 2 / 2 + v["m2"] * v["l2"] ** 2 * u2 ** 2 / 2
         + v["m2"] * v["l1"] * v["l2"] * u1 * u2 * np.cos(q1 - q2))
    V = -(v["m1"] + v["m2"]) * v["g"] * v["l1"] * np.cos(q1) - v["m2"] * v["g"] * v["l2"] * np.cos(q2)
    return T + V


@needs_cc
@pytest.mark.parametrize("k", [0, 2, 5])
def test_drawn_points_links_and_trace_are_the_hand_formula(pendulum_run, k):
    model, run = pendulum_run
    values = {p.name: v for p, v in model.parameter_values.items()}
    expected = hand_positions(run, values)
    sample = round(k * 0.04 / H)  # frame k at t = k * 40 ms (real time at 25 fps)
    scene = compose_scene(run, trace=["bob2"])
    fig, update = draw_scene(scene)
    drawn = by_label(update(k))
    bob1, bob2 = expected[sample]
    np.testing.assert_allclose(np.column_stack(drawn["points"].get_data()), [bob1, bob2], rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.column_stack(drawn["link origin-bob1"].get_data()), [[0, 0], bob1], atol=1e-12)
    np.testing.assert_allclose(np.column_stack(drawn["link bob1-bob2"].get_data()), [bob1, bob2], atol=1e-12)
    np.testing.assert_allclose(np.column_stack(drawn["trace bob2"].get_data()), expected[:sample + 1, 1],
                               atol=1e-12)
    text = drawn["clock"].get_text()
    assert text.startswith(f"t = {k * 0.04:.3f} s")
    energy = hand_energy(run, values)
    shown = float(text.split("(E - E0)/|E0| = ")[1])
    assert shown == pytest.approx((energy[sample] - energy[0]) / abs(energy[0]), abs=1e-12)


@needs_cc
@pytest.mark.parametrize("speed, fps, n_frames, interval", [(1.0, 25, 6, 40.0), (0.5, 25, 11, 40.0),
                                                            (2.0, 50, 6, 20.0)])
def test_playback_is_real_time_times_speed(pendulum_run, speed, fps, n_frames, interval):
    _, run = pendulum_run
    scene = compose_scene(run, fps=fps, speed=speed)
    assert (scene.n_frames, scene.interval) == (n_frames, interval)
    shown = scene.t[scene.samples]
    # simulated time per second of playback, frame to frame and over the whole animation
    np.testing.assert_allclose(np.diff(shown) / (scene.interval / 1000), speed, rtol=1e-9)
    assert T_END / ((scene.n_frames - 1) * scene.interval / 1000) == pytest.approx(speed, rel=1e-12)


def test_gif_interval_is_whole_hundredths():
    # a GIF stores delays in 1/100 s: 30 fps (33.3 ms) becomes 30 ms, and 200 fps the 20 ms floor
    assert scenes.frame_interval(30, gif=True) == 30.0
    assert scenes.frame_interval(200, gif=True) == 20.0
    assert scenes.frame_interval(30, gif=False) == pytest.approx(1000 / 30)


@needs_cc
def test_gif_is_written_with_its_frames_and_delays(pendulum_run, tmp_path):
    from PIL import Image

    _, run = pendulum_run
    out = tmp_path / "scene.gif"
    animate(run, out, trace=["bob2"], size=(3.0, 3.0), dpi=50)
    with Image.open(out) as gif:
        assert gif.size == (150, 150)
        durations = []
        for frame in range(gif.n_frames):
            gif.seek(frame)
            durations.append(gif.info["duration"])
    assert len(durations) == 6 and set(durations) == {40}  # 6 frames x 40 ms = 0.24 s for 0.2 s + one frame


@needs_cc
def test_gif_at_30_fps_keeps_real_time(pendulum_run, tmp_path):
    from PIL import Image

    _, run = pendulum_run
    out = tmp_path / "scene30.gif"
    animate(run, out, fps=30, size=(2.0, 2.0), dpi=40)
    with Image.open(out) as gif:
        n_frames, duration = gif.n_frames, gif.info["duration"]
    # 30 ms apart: t = 0, 0.03, ..., 0.18, then the run's end t = 0.2 (no frame fell on it)
    assert (n_frames, duration) == (8, 30)


@needs_cc
def test_mp4_without_ffmpeg_is_refused_before_drawing(pendulum_run, tmp_path, monkeypatch):
    from matplotlib.animation import FFMpegWriter

    monkeypatch.setattr(FFMpegWriter, "isAvailable", classmethod(lambda cls: False))
    out = tmp_path / "scene.mp4"
    with pytest.raises(AnimationError, match=r"scene\.mp4.*needs ffmpeg.*\.gif"):
        animate(pendulum_run[1], out)
    assert not out.exists()


@needs_cc
def test_mp4_with_ffmpeg(pendulum_run, tmp_path):
    from matplotlib.animation import FFMpegWriter

    if not FFMpegWriter.isAvailable():
        pytest.skip("ffmpeg is not installed")
    out = tmp_path / "scene.mp4"
    animate(pendulum_run[1], out, size=(2.0, 2.0), dpi=40)
    assert out.stat().st_size > 0


def test_energy_overlay_is_the_change_relative_to_e0():
    # E = -2, -1, -3: (E - E0)/|E0| = 0, +0.5, -0.5 by hand; E0 = 0 leaves E - E0 unscaled
    run = synthetic()
    run = dataclasses.replace(run, energy=np.r_[-2.0, -1.0, -3.0, np.full(18, -2.0)])
    scene = compose_scene(run)
    np.testing.assert_allclose(scene.energy_change[:3], [0.0, 0.5, -0.5], rtol=0, atol=1e-15)
    assert scenes.clock_text(scene, 1) == "t = 0.010 s\n(E - E0)/|E0| = +5.00e-01"
    scene = compose_scene(dataclasses.replace(run, energy=np.r_[0.0, 0.25, np.zeros(19)]), speed=0.5)
    assert scenes.clock_text(scene, 1) == "t = 0.010 s  (0.5x)\nE - E0 = +2.50e-01"
    assert scenes.clock_text(compose_scene(synthetic()), 2) == "t = 0.020 s"  # no energy recorded


# -- projections ------------------------------------------------------------------------------
def test_projections_by_hand():
    p = np.array([[1.0, 2.0, 3.0]])
    np.testing.assert_array_equal(project(p)[0], [[1.0, 2.0]])
    np.testing.assert_array_equal(project(p, "zy")[0], [[3.0, 2.0]])
    np.testing.assert_allclose(project(p, (0, 0))[0], [[1.0, 2.0]], atol=1e-15)
    np.testing.assert_allclose(project(p, (0, 90))[0], [[-3.0, 2.0]], atol=1e-15)  # from +x: right is -z
    np.testing.assert_allclose(project(p, (90, 0))[0], [[1.0, -3.0]], atol=1e-15)  # from above: up is -z
    for bad in ("xx", "xyz", "ab", (1.0,), (math.inf, 0)):
        with pytest.raises(AnimationError, match="projection"):
            project(p, bad)


# -- the five models of the issue -------------------------------------------------------------
FIVE = {
    "double_pendulum": (catalog.double_pendulum, {"q1": 1.0, "q2": 0.5}, "xy"),
    "elastic_pendulum": (catalog.elastic_pendulum, {"r": 1.3, "phi": 0.5}, "xy"),
    "centrifugal_governor": (catalog.centrifugal_governor, {"alpha": 0.6}, (20.0, 30.0)),
    "slider_crank": (catalog.slider_crank, catalog.slider_crank_state(0.3, 2.0), "xy"),
    "four_bar": (catalog.four_bar, catalog.four_bar_state(0.3, 2.0), "xy"),
}


@needs_cc
@pytest.mark.parametrize("name", FIVE)
def test_five_models_draw_their_recorded_points(name):
    from lagcodegen.pipeline import compile_model

    build, x0, projection = FIVE[name]
    model = build()
    outputs = ("rhs", "energy", "points") + ("constraints",) * bool(model.constraints)
    system = compile_model(model, outputs=outputs, methods=("rk4",))
    run = simulate(system, x0, 0.1, H, energy=True, points=True, project=bool(model.constraints)).check()
    scene = compose_scene(run, links=model.links or None, trace=[run.point_names[-1]], projection=projection)
    _, update = draw_scene(scene, title=name)
    screen = project(np.asarray(run.points, dtype=float), projection)[0]  # the recorded points, projected
    for k in (1, scene.n_frames - 2, scene.n_frames - 1):
        drawn = by_label(update(k))
        # frames 0.04 s apart (25 fps), then the run's last sample, t = 0.1, which none fell on
        sample = round(k * 0.04 / H) if k < scene.n_frames - 1 else len(run.t) - 1
        np.testing.assert_allclose(np.column_stack(drawn["points"].get_data()), screen[sample], atol=1e-12)
        at = dict(zip(run.point_names, screen[sample])) | {"origin": np.zeros(2)}
        links = model.links or tuple(zip(("origin",) + run.point_names[:-1], run.point_names))
        for a, b in links:
            np.testing.assert_allclose(np.column_stack(drawn[f"link {a}-{b}"].get_data()), [at[a], at[b]], atol=1e-12)


# -- bad input --------------------------------------------------------------------------------
def synthetic(point_names=("bob1", "bob2"), points=True) -> Trajectory:
    t = np.linspace(0.0, 0.2, 21)
    positions = np.zeros((t.size, len(point_names), 3)) if points else None
    return Trajectory(t=t, x=np.zeros((t.size, 2)), names=("q", "q_d"), energy=None, points=positions,
                      point_names=tuple(point_names), status=Status.OK, failed_step=None, failed_time=None,
                      method="rk4", h=0.01)


def test_model_without_named_points_is_named():
    with pytest.raises(AnimationError, match=r"no named points.*Model\(\.\.\., points="):
        compose_scene(synthetic(point_names=()))


def test_run_without_recorded_points_says_points_true():
    with pytest.raises(AnimationError, match=r"bob1, bob2.*points=True"):
        compose_scene(synthetic(points=False))


@pytest.mark.parametrize("kwargs, culprit", [
    ({"points": ["bob3"]}, r"points: no point 'bob3'; points: bob1, bob2"),
    ({"trace": ["tip"]}, r"trace: no point 'tip'; points: bob1, bob2"),
    ({"links": [("bob1", "bob9")]}, r"links: \('bob1', 'bob9'\): no point 'bob9'; points: origin, bob1, bob2"),
    ({"links": [("bob1",)]}, r"links: \('bob1',\) must be a pair"),
    ({"points": []}, r"points is empty; choose from bob1, bob2"),
    ({"speed": 0}, r"speed must be a positive"),
    ({"fps": -25}, r"fps must be a positive"),
])
def test_unknown_names_and_bad_numbers_are_named(kwargs, culprit):
    with pytest.raises(AnimationError, match=culprit):
        compose_scene(synthetic(), **kwargs)


def test_trace_of_an_undrawn_point_lists_the_drawn_ones():
    with pytest.raises(AnimationError, match=r"trace: no point 'bob2'; points: bob1$"):
        compose_scene(synthetic(), points=["bob1"], trace=["bob2"])


@pytest.mark.parametrize("name, culprit", [
    ("", r"must be a file name ending in \.gif or \.mp4"),
    ("scene.png", r"scene\.png.*cannot write \.png"),
    ("missing/scene.gif", r"missing.*not an existing directory"),
])
def test_bad_output_paths_are_named(tmp_path, name, culprit):
    out = str(tmp_path / name) if name else name
    with pytest.raises(AnimationError, match=culprit):
        animate(synthetic(), out)


def test_an_unwritable_output_is_named_before_drawing(monkeypatch, capsys):
    """Found by review: animate to a place that cannot be written (here /proc, where no file can be
    created, even by root) drew every frame first and then failed without naming --out."""
    import lagcodegen.analysis.animation as animation_module

    def never(*args, **kwargs):
        raise AssertionError("drew frames for an output it cannot write")

    monkeypatch.setattr(animation_module, "write_animation", never)
    with pytest.raises(AnimationError, match=r"out '/proc/lagcodegen_scene.gif': cannot write there"):
        animate(synthetic(), "/proc/lagcodegen_scene.gif")
    code = main(["animate", "double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "0.1", "--out",
                 "/proc/lagcodegen_scene.gif"])
    err = capsys.readouterr().err
    assert code == 2 and "--out '/proc/lagcodegen_scene.gif': cannot write there" in err, err


def test_the_last_frame_is_the_run_s_end():
    """Found by review: frames fell every 0.04 s (25 fps) up to t_end and a run ending between two
    of them (t_end = 1.039) was never shown at its end. By hand: samples every 1 ms, frames at
    samples 0, 40, ..., 1000 (t = 1.0), then the last sample, 1039."""
    t = np.arange(1040) * 1e-3
    samples = scenes.frame_samples(t, 40.0, 1.0)
    assert list(samples[:-1]) == list(range(0, 1001, 40)) and samples[-1] == 1039
    exact = scenes.frame_samples(t[:1001], 40.0, 1.0)  # a run that ends on a frame gets no extra one
    assert list(exact) == list(range(0, 1001, 40))


def test_a_gif_too_large_for_memory_is_refused_before_drawing(monkeypatch, tmp_path):
    """Found by review: a GIF's writer keeps every frame (0.83-0.92 MB each at the default 400 x
    400 pixels), so the 18,000 frames allowed would take about 15 GB. The estimate, 6 bytes per
    pixel, is checked against the run limit before any frame is drawn: 6 frames of 800 x 800 px
    take 6 x 640,000 x 6 B = 22 MiB, refused under a 16 MiB limit."""
    import lagcodegen.analysis.animation as animation_module
    import lagcodegen.run.arguments as arguments
    from lagcodegen.run.arguments import OutputTooLargeError

    monkeypatch.setattr(arguments, "output_limit", lambda: 16 * 2**20)
    monkeypatch.setattr(animation_module, "draw_scene", lambda *a, **k: pytest.fail("drew frames"))
    run = synthetic()  # 0.2 s at speed 1, 25 fps (40 ms): frames at 0, ..., 0.2, 6 of them
    with pytest.raises(OutputTooLargeError, match=r"a GIF of 6 frames of 800 x 800 pixels"):
        animate(run, tmp_path / "scene.gif", size=(10.0, 10.0), dpi=80)


def test_a_gif_frame_too_long_is_refused_and_a_failed_write_keeps_the_old_file(tmp_path, monkeypatch, capsys):
    """Found by review: --fps 0.001 (a frame of 1000 s) gave Pillow's OverflowError as a traceback
    and truncated the existing GIF to 800 bytes. A GIF's frame delay is a 16-bit count of 10 ms, at
    most 655.35 s. Now that fps is refused before anything runs, and a write that fails for any
    reason leaves the old file as it was."""
    out = tmp_path / "keep.gif"
    out.write_bytes(b"old animation")
    code = main(["animate", "double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "0.1", "--fps", "0.001",
                 "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2 and "--fps 0.001: a GIF frame lasts at most 655.35 s" in err, err
    from matplotlib.animation import FuncAnimation

    def broken(self, *args, **kwargs):
        Path(args[0]).write_bytes(b"half")
        raise OSError("disk full")

    monkeypatch.setattr(FuncAnimation, "save", broken)
    with pytest.raises(OSError, match="disk full"):
        animate(synthetic(), out)
    assert out.read_bytes() == b"old animation" and sorted(p.name for p in tmp_path.iterdir()) == ["keep.gif"]


def test_output_path_that_is_a_directory_is_named(tmp_path):
    with pytest.raises(AnimationError, match=rf"out '{tmp_path}' is a directory; give a file name"):
        animate(synthetic(), tmp_path)


def test_model_links_name_known_points():
    model = catalog.elastic_pendulum()
    base = dict(kinetic_energy=model.kinetic_energy, potential_energy=model.potential_energy, points=model.points)
    with pytest.raises(ModelError, match=r"link \('origin', 'bal'\) names 'bal'.*points: ball, origin"):
        Model("spring", model.coordinates, model.parameters, links=[("origin", "bal")], **base)
    with pytest.raises(ModelError, match=r"joins point 'ball' to itself"):
        Model("spring", model.coordinates, model.parameters, links=[("ball", "ball")], **base)
    assert Model("spring", model.coordinates, model.parameters, links=[["origin", "ball"]], **base).links == (
        ("origin", "ball"),)


# -- the command line -------------------------------------------------------------------------
@needs_cc
def test_cli_writes_a_gif(tmp_path, capsys):
    from PIL import Image

    out = tmp_path / "scene.gif"
    code = main(["animate", "double_pendulum", "--x0", "q1=1,q2=0.5", "--t-end", str(T_END), "--trace", "bob2",
                 "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    with Image.open(out) as gif:
        assert (gif.n_frames, gif.info["duration"]) == (6, 40)
    assert f"wrote {out}" in capsys.readouterr().out


@pytest.mark.parametrize("argv, culprit", [
    (["stiff_chain", "--x0", "x1=1,x2=0,x3=0"], "model 'stiff_chain' has no named points"),
    (["double_pendulum", "--x0", "q1=1,q2=0", "--trace", "bob3"], "--trace: no point 'bob3'; points: bob1, bob2"),
    (["double_pendulum", "--x0", "q1=1,q2=0", "--links", "bob1"], "--links 'bob1' must look like a-b"),
    (["double_pendulum", "--x0", "q1=1,q2=0", "--projection", "1,b"], "--projection '1,b'"),
    (["double_pendulum", "--x0", "q1=1,q2=0", "--projection", "xq"], "--projection 'xq' must be two different"),
])
def test_cli_bad_input_is_one_line_naming_it(argv, culprit, tmp_path, capsys):
    code = main(["animate", *argv, "--t-end", "0.1", "--out", str(tmp_path / "s.gif")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and culprit in err, err


def test_cli_out_directory_is_named(tmp_path, capsys):
    code = main(["animate", "double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "0.1", "--out", str(tmp_path)])
    err = capsys.readouterr().err
    assert code == 2 and f"--out '{tmp_path}' is a directory" in err, err


# -- the rigid bodies' frames (frames=) ---------------------------------------------------------
# Independent sources: the compound pendulum's geometry by hand (a rod of length l hinged at the
# origin, at angle q from the downward vertical: mass centre l/2 (sin q, -cos q), its x axis the
# inertial x rotated by q about z, (cos q, sin q)); the 3-D body's rotation matrix by hand,
# Rz(a) Rx(b), whose columns are the body's axes in the inertial frame.
def compound_pendulum(extra_body=None) -> Model:
    import sympy as sp
    import sympy.physics.mechanics as me

    q = me.dynamicsymbols("q")
    m, l, g = sp.symbols("m l g", positive=True)
    N, O, B = me.ReferenceFrame("N"), me.Point("O"), me.ReferenceFrame("B")
    B.orient_axis(N, N.z, q)
    G = O.locatenew("G", -l / 2 * B.y)
    rod = me.RigidBody("rod", G, B, m, (m * l ** 2 / 12 * me.outer(B.z, B.z), G))
    tip = O.locatenew("tip", -l * B.y)
    return Model("compound_pendulum", [q], (m, l, g), bodies=[rod], gravity=-g * N.y, frame=N, origin=O,
                 points={"tip": tip}, parameter_values={m: 1.0, l: 0.8, g: 9.81})


def run_of(names, columns, point_names=("tip",)) -> Trajectory:
    t = np.linspace(0.0, 0.2, 21)
    x = np.zeros((t.size, len(names)))
    for i, column in enumerate(columns):
        x[:, i] = column(t)
    return Trajectory(t=t, x=x, names=tuple(names), energy=None, points=np.zeros((t.size, len(point_names), 3)),
                      point_names=tuple(point_names), status=Status.OK, failed_step=None, failed_time=None,
                      method="rk4", h=0.01)


@pytest.mark.parametrize("k", [0, 3, 5])
def test_compound_pendulum_triad_is_the_hand_rotation(k):
    run = run_of(("q", "q_d"), [lambda t: 0.4 + 5 * t, lambda t: 5 + 0 * t])
    scene = compose_scene(run, frames=compound_pendulum(), frame_size=0.25)
    fig, update = draw_scene(scene)
    artists = by_label(update(k))
    sample = int(scene.samples[k])
    q, l = 0.4 + 5 * run.t[sample], 0.8
    centre = np.array([l / 2 * math.sin(q), -l / 2 * math.cos(q)])  # by hand
    x_end = centre + 0.25 * np.array([math.cos(q), math.sin(q)])
    y_end = centre + 0.25 * np.array([-math.sin(q), math.cos(q)])
    np.testing.assert_allclose(np.column_stack(artists["frame rod x"].get_data()), [centre, x_end], atol=1e-12)
    np.testing.assert_allclose(np.column_stack(artists["frame rod y"].get_data()), [centre, y_end], atol=1e-12)
    # z is along the line of sight in "xy": a zero-length segment at the mass centre
    np.testing.assert_allclose(np.column_stack(artists["frame rod z"].get_data()), [centre, centre], atol=1e-12)
    assert artists["frame rod x"].get_color() == "tab:red"
    assert scene.triad_names == ("rod",)


def test_params_override_the_model_values():
    run = run_of(("q", "q_d"), [lambda t: 0.0 * t, lambda t: 0.0 * t])
    scene = compose_scene(run, frames=compound_pendulum(), frame_size=0.1, params={"l": 2.0})
    np.testing.assert_allclose(scene.triads[0, 0, 0], [[0.0, -1.0], [0.1, -1.0]], atol=1e-12)  # l/2 below O


def test_default_frame_size_is_a_fraction_of_the_extent():
    run = run_of(("q", "q_d"), [lambda t: 0.0 * t, lambda t: 0.0 * t])
    scene = compose_scene(run, frames=compound_pendulum())
    # points at 0 (tip not moving here: zeros) and the mass centre at (0, -0.4): extent 0.4
    np.testing.assert_allclose(scene.triads[0, 0, 0, 1] - scene.triads[0, 0, 0, 0], [0.15 * 0.4, 0.0], atol=1e-12)


def test_3d_body_triad_is_the_hand_rotation_matrix_projected():
    import sympy as sp
    import sympy.physics.mechanics as me

    a, b = me.dynamicsymbols("a b")
    m, d = sp.symbols("m d", positive=True)
    N, O, A, B = (me.ReferenceFrame("N"), me.Point("O"), me.ReferenceFrame("A"), me.ReferenceFrame("B"))
    A.orient_axis(N, N.z, a)
    B.orient_axis(A, A.x, b)
    G = O.locatenew("G", d * B.z)
    body = me.RigidBody("top", G, B, m, (me.inertia(B, 1, 2, 3), G))
    model = Model("top", [a, b], (m, d), bodies=[body], frame=N, origin=O, points={"G": G},
                  parameter_values={m: 1.0, d: 0.5})
    run = run_of(("a", "b", "a_d", "b_d"), [lambda t: 0.3 + 2 * t, lambda t: -0.7 + 3 * t,
                                            lambda t: 2 + 0 * t, lambda t: 3 + 0 * t], point_names=("G",))
    scene = compose_scene(run, frames=model, frame_size=0.2, projection="xy")
    for s in (0, 10, 20):
        ca, sa = math.cos(run.x[s, 0]), math.sin(run.x[s, 0])
        cb, sb = math.cos(run.x[s, 1]), math.sin(run.x[s, 1])
        R = np.array([[ca, -sa, 0], [sa, ca, 0], [0, 0, 1]]) @ np.array([[1, 0, 0], [0, cb, -sb], [0, sb, cb]])
        centre = 0.5 * R[:, 2]
        for i in range(3):
            np.testing.assert_allclose(scene.triads[s, 0, i], [centre[:2], (centre + 0.2 * R[:, i])[:2]],
                                       atol=1e-12)


def test_frames_of_a_model_without_rigid_bodies_names_it():
    run = run_of(("q1", "q2", "q1_d", "q2_d"), [lambda t: 0 * t] * 4, point_names=("bob1", "bob2"))
    with pytest.raises(AnimationError, match=r"model 'double_pendulum' has no rigid bodies"):
        compose_scene(run, frames=catalog.double_pendulum())


def test_body_frame_not_expressible_names_the_body():
    import sympy as sp
    import sympy.physics.mechanics as me

    model = compound_pendulum()
    # Model validates its bodies, so a stray body is put in afterwards: a frame oriented to nothing
    loose_frame, loose_centre = me.ReferenceFrame("L"), me.Point("L0")
    loose_centre.set_pos(model.origin, 0)
    loose = me.RigidBody("loose", loose_centre, loose_frame, sp.S.One, (me.inertia(loose_frame, 1, 1, 1), loose_centre))
    object.__setattr__(model, "bodies", (*model.bodies, loose))
    run = run_of(("q", "q_d"), [lambda t: 0 * t] * 2)
    with pytest.raises(AnimationError, match=r"body 'loose' \(its frame L\) cannot be expressed in the model's frame N"):
        compose_scene(run, frames=model)




@needs_cc
@pytest.mark.parametrize("option, drawn", [((), True), (("--no-frames",), False)])
def test_cli_draws_frames_of_a_bodies_model(tmp_path, capsys, monkeypatch, option, drawn):
    from PIL import Image

    from lagcodegen.analysis import animation

    seen = []
    original = animation.draw_scene
    monkeypatch.setattr(animation, "draw_scene", lambda scene, **kw: seen.append(scene) or original(scene, **kw))
    path = tmp_path / "rod.py"
    path.write_text("from lagcodegen.model import Model\n\n" + inspect.getsource(compound_pendulum)
                    + "\n\nmodel = compound_pendulum()\n")
    out = tmp_path / "rod.gif"
    code = main(["animate", str(path), "--x0", "q=1", "--t-end", "0.08", *option, "--out", str(out)])
    assert code == 0, capsys.readouterr().err
    with Image.open(out) as gif:
        assert gif.n_frames == 3
    assert (seen[0].triad_names == ("rod",)) is drawn


def test_cli_frames_on_a_model_without_rigid_bodies_is_named(tmp_path, capsys):
    code = main(["animate", "double_pendulum", "--x0", "q1=1,q2=0", "--t-end", "0.1", "--frames",
                 "--out", str(tmp_path / "s.gif")])
    assert code == 2
    assert "--frames: model 'double_pendulum' has no rigid bodies" in capsys.readouterr().err


def test_a_speed_that_asks_for_too_many_frames_is_refused(pendulum_run):
    # found by review: --speed 1e-5 started rendering 750000 GIF frames (1e-9: out of memory)
    _, run = pendulum_run
    span = float(run.t[-1] - run.t[0])
    with pytest.raises(AnimationError, match=r"at speed 1e-05 and 25 frames per second would take .* frames, more "
                                             r"than 18000: raise the speed"):
        compose_scene(run, fps=25, speed=1e-5)
    assert compose_scene(run, fps=25, speed=span * 25 / 17_000).n_frames > 16_000  # just under the bound


def test_chosen_points_are_chained_in_the_models_order():
    """Found by review: points=["bob2", "bob1"] drew the rods origin-bob2 and bob2-bob1, a rod from the
    hinge straight to the lower bob; the docs promise the chain in the order the model declares the
    points (origin-bob1, bob1-bob2: the double pendulum's rods)."""
    names, links, _ = scenes.scene_names(("bob1", "bob2"), points=["bob2", "bob1"])
    assert [(names[a], names[b]) for a, b in links] == [(scenes.ORIGIN, "bob1"), ("bob1", "bob2")]
