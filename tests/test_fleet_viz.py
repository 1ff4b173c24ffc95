"""Fleet pictures: the top-down video, the still frame and the path plot of a fleet episode
(every robot in its colour with its errand), the CLI's --video/--plot/--frame, the world
arguments of ``fleet``, and ``view --robots`` in the PyBullet GUI."""

from __future__ import annotations

import json
import math

import imageio.v2 as imageio
import numpy as np
import pytest
from PIL import Image

from bulletnav.cli import main
from bulletnav.fleet.controllers import make_controller
from bulletnav.fleet.metrics import run_fleet_episodes
from bulletnav.viz.fleet import FleetVisuals
from bulletnav.viz.fleet_frames import FLEET_FRAME_SIZE
from bulletnav.viz.fleet_robots import ROBOT_PALETTE, robot_colour

ROBOTS = 3
DURATION = 2.0  # s: 48 control steps at 24 Hz
STEPS = 48


def _independent(env):
    return make_controller("independent", env)


def _rows(result: dict) -> list[dict]:
    """Episode rows without their wall-clock time (the only entry that may differ between runs)."""
    return [{k: v for k, v in row.items() if k != "wall_s"} for row in result["episodes"]]


def _video(path) -> list[np.ndarray]:
    with imageio.get_reader(path) as reader:  # not list(reader): its length hint is infinite
        return [frame for frame in reader]


def _disc(frame: np.ndarray, centre: tuple[float, float], radius: float) -> np.ndarray:
    """The pixels (K, 3) of ``frame`` within ``radius`` px of ``centre`` (x right, y down)."""
    h, w, _ = frame.shape
    yy, xx = np.mgrid[0:h, 0:w]
    inside = np.hypot(xx - centre[0], yy - centre[1]) <= radius
    return frame[inside].astype(int)


def _hand_px(layout, xy: tuple[float, float]) -> tuple[float, float]:
    """World (m) -> frame pixel, written out here from the documented frame: a 720 px square map at
    the frame's top left, the floor plus its 0.2 m walls fitted inside an 8 px margin, x right and
    y up (so pixel y runs down from the centre)."""
    hx, hy = layout.half_extents
    scale = (720 - 2 * 8) / (2 * max(hx + 0.2, hy + 0.2))  # px per m
    return 360 + scale * xy[0], 360 - scale * xy[1]


@pytest.fixture(scope="module")
def recorded(tmp_path_factory):
    """Two 2 s episodes of 3 robots, the first recorded (video, frame at 1 s, plot), and the
    same episodes run again without pictures."""
    out = tmp_path_factory.mktemp("fleet_viz")
    visuals = FleetVisuals(video=out / "fleet.mp4", frame=out / "frame.png", frame_at_s=1.0, plot=out / "paths.png",
                           title="independent")
    kwargs = dict(num_robots=ROBOTS, duration_s=DURATION)
    with_pictures = run_fleet_episodes(kwargs, _independent, episodes=2, seed=11, on_step=visuals)
    written = visuals.close()
    without = run_fleet_episodes(kwargs, _independent, episodes=2, seed=11)
    return out, visuals, written, with_pictures, without


def test_pictures_leave_the_episodes_unchanged(recorded):
    _, _, _, with_pictures, without = recorded
    assert _rows(with_pictures) == _rows(without)
    # each row against its documented definition, worked out here: episode k has seed 11 + k,
    # the throughput is errands per simulated hour of the 2 s episode, the errand count the legs' halves at most
    for k, row in enumerate(with_pictures["episodes"]):
        assert row["episode"] == k and row["seed"] == 11 + k and row["robots"] == ROBOTS
        assert row["throughput_per_hour"] == pytest.approx(row["errands"] * 3600.0 / DURATION, rel=1e-12)
        assert 2 * row["errands"] <= row["legs"]


def test_video_of_episode_0_decodes_with_one_frame_per_step(recorded):
    out, visuals, written, _, _ = recorded
    assert (out / "fleet.mp4").is_file() and not list(out.glob(".fleet.mp4.*"))  # renamed into place
    frames = _video(out / "fleet.mp4")
    assert len(frames) == 1 + STEPS == visuals.frames_written  # the reset frame, then every step of episode 0 only
    assert all(f.shape == (FLEET_FRAME_SIZE[1], FLEET_FRAME_SIZE[0], 3) for f in frames)
    # the last video frame is the last composed one, up to H.264's losses
    assert np.abs(frames[-1].astype(int) - visuals.frames.last_frame.astype(int)).mean() < 6.0
    assert any("fleet.mp4" in w and f"{1 + STEPS} frames" in w for w in written)


def test_each_robot_is_drawn_in_its_colour_where_it_is(recorded):
    out, visuals, _, _, _ = recorded
    frames = visuals.frames
    exact = frames.last_frame
    video = _video(out / "fleet.mp4")[-1]
    r = frames.robot_radius_px()
    track = visuals.log.track
    for i in range(ROBOTS):
        # where robot i is, by the transform written in the test from its last recorded position
        centre = _hand_px(track.layout, track.paths[i][-1])
        colour = np.array(robot_colour(i))
        disc = _disc(exact, centre, r)
        # the composed frame: most of the disc is exactly the robot's colour (the rest: outline, heading line)
        assert (disc == colour).all(axis=1).mean() > 0.5, f"robot {i}"
        # the decoded video: the disc is nearer this robot's colour than any other robot's
        seen = np.median(_disc(video, centre, r * 0.8), axis=0)
        nearest = min(range(ROBOTS), key=lambda j: np.abs(seen - np.array(robot_colour(j))).sum())
        assert nearest == i and np.abs(seen - colour).max() < 60, f"robot {i}: {seen} vs {colour}"
    assert len(set(ROBOT_PALETTE)) == len(ROBOT_PALETTE) == 16  # 16 robots, 16 distinct colours


def test_still_frame_and_plot(recorded):
    out, visuals, written, _, _ = recorded
    frame = np.asarray(Image.open(out / "frame.png").convert("RGB"))
    assert frame.shape == (FLEET_FRAME_SIZE[1], FLEET_FRAME_SIZE[0], 3)
    assert visuals.frame_written_at == pytest.approx(1.0, abs=1e-6)
    for i in range(ROBOTS):  # each robot's colour is in the frame
        assert (frame.reshape(-1, 3) == np.array(robot_colour(i))).all(axis=1).sum() > 20
    track = visuals.log.track
    r = visuals.frames.robot_radius_px()
    for i in range(ROBOTS):  # ... and most of its disc is, where the robot stood at 1 s (after step 24)
        disc = _disc(frame, _hand_px(track.layout, track.paths[i][24]), r)
        assert (disc == np.array(robot_colour(i))).all(axis=1).mean() > 0.5, f"robot {i}"
    plot = Image.open(out / "paths.png")
    assert plot.size == (900, 700)
    assert any("frame.png" in w and "at 1.0 s" in w for w in written) and any("paths.png" in w for w in written)
    track = visuals.log.track
    assert len(track.paths) == ROBOTS and all(len(p) == 1 + STEPS for p in track.paths)
    assert track.pick and track.drop


def test_plot_draws_every_robot_path_in_its_colour(recorded):
    from matplotlib.colors import to_rgb

    from bulletnav.viz.fleet_paths import fleet_figure

    _, visuals, _, with_pictures, _ = recorded
    fig = fleet_figure(visuals.log.track)
    ax = fig.axes[0]
    drawn = []
    for i in range(ROBOTS):
        (line,) = [a for a in ax.lines if a.get_gid() == f"robot_{i}_path"]
        assert np.allclose(to_rgb(line.get_color()), np.array(robot_colour(i)) / 255)
        xs, ys = line.get_data()
        assert len(xs) == 1 + STEPS
        assert math.isclose(xs[0], visuals.log.track.starts[i][0]) and math.isclose(ys[0], visuals.log.track.starts[i][1])
        drawn.append(np.column_stack([xs, ys]))
    # the drawn paths are the episode's: the smallest centre distance between two of them, step
    # by step (brute force over pairs here), is episode 0's min_separation_m
    closest = min(math.dist(drawn[i][k], drawn[j][k]) for k in range(1 + STEPS)
                  for i in range(ROBOTS) for j in range(i))
    assert closest == pytest.approx(with_pictures["episodes"][0]["min_separation_m"], abs=1e-9)
    assert [a for a in ax.lines if a.get_gid() == "pick_station"] and [a for a in ax.lines if a.get_gid() == "drop_station"]


def test_cli_pictures_do_not_change_the_json(tmp_path, capsys):
    argv = ["fleet", "--robots", "2", "--duration", "1", "--seed", "4", "--json"]
    assert main(argv) == 0
    plain = json.loads(capsys.readouterr().out)
    video, plot, frame = tmp_path / "f.mp4", tmp_path / "p.png", tmp_path / "f.png"
    assert main([*argv, "--video", str(video), "--plot", str(plot), "--frame", str(frame), "--frame-at", "0.5"]) == 0
    captured = capsys.readouterr()
    pictured = json.loads(captured.out)
    for out in (plain, pictured):
        for row in out["rows"]:
            row.pop("wall_s")
    assert plain == pictured
    assert video.is_file() and plot.is_file() and frame.is_file()
    assert "episode 0, 25 frames" in captured.err
    # decoded by imageio/ffmpeg: the reset frame and 24 steps (1 s at 24 Hz), at the documented size
    decoded = _video(video)
    assert len(decoded) == 1 + 24 and decoded[0].shape == (768, 1024, 3)
    assert Image.open(frame).size == (1024, 768)
    # an existing file is refused without --overwrite, before anything runs
    assert main([*argv, "--video", str(video)]) == 2
    assert "--video" in capsys.readouterr().err
    assert main([*argv, "--frame", str(tmp_path / "g.png"), "--frame-at", "3"]) == 2
    assert "after the episode's end" in capsys.readouterr().err
    assert main([*argv, "--frame-at", "0.5"]) == 2
    assert "--frame" in capsys.readouterr().err


def test_fleet_takes_the_world_arguments(capsys):
    world = "bulletnav/assets/worlds/aisles.yaml"
    assert main(["fleet", "--robots", "2", "--duration", "0.5", "--world", world, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["world"] == world and out["rows"][0]["robots"] == 2
    assert main(["fleet", "--robots", "2", "--duration", "0.5", "--layout-style", "scattered", "--obstacles", "12",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["layout_style"] == "scattered" and out["obstacles"] == 12
    # a world without racks has no pick stations: one clear error
    assert main(["fleet", "--robots", "2", "--duration", "0.5", "--world", "bulletnav/assets/worlds/empty.yaml"]) == 2
    assert "no pick stations" in capsys.readouterr().err
    assert main(["fleet", "--robots", "2", "--duration", "0.5", "--env", "bulletnav/Nope-v0"]) == 2
    assert "unknown env id" in capsys.readouterr().err


@pytest.mark.gui
def test_view_robots_opens_the_gui_and_tints_every_robot(display, capsys, monkeypatch):
    import pybullet as p

    from bulletnav.fleet.view import FleetView
    from bulletnav.viz.fleet_gui import FleetDashboard

    seen = {}
    on_reset, on_step = FleetDashboard.on_reset, FleetDashboard.on_step

    def checking_reset(self, infos):
        on_reset(self, infos)
        fleet = FleetView(self.env)
        seen["rgba"] = [p.getVisualShapeData(fleet.robot_body(i), physicsClientId=fleet.client)[0][7]
                        for i in range(fleet.num_robots)]
        seen["calls"] = self.debug_draw_calls

    def counting_step(self, infos):
        on_step(self, infos)
        seen["steps"] = self.steps
        seen["step_calls"] = self.debug_draw_calls

    monkeypatch.setattr(FleetDashboard, "on_reset", checking_reset)
    monkeypatch.setattr(FleetDashboard, "on_step", counting_step)
    assert main(["view", "--robots", "2", "--seconds", "0.5"]) == 0
    assert "viewed a fleet of 2 robots" in capsys.readouterr().out
    assert len(seen["rgba"]) == 2
    for i, rgba in enumerate(seen["rgba"]):  # each robot's body in its colour
        assert np.allclose(rgba[:3], np.array(robot_colour(i)) / 255, atol=1e-3)
    assert seen["calls"] == 2 * 2  # a goal post and a robot-to-goal line per robot
    if seen.get("steps", 0) < 12:  # no goal changed so soon: no line redrawn before step 12
        assert seen.get("step_calls", seen["calls"]) == seen["calls"]


def test_marks_are_told_apart_and_the_legend_shows_each(recorded):
    """No robot's colour is near the collision mark's (white: the channels together off by at least
    100 of 765); red, the old robot 0 that looked like the old red collision ring, is left to a
    16th robot; the legend draws the octagon, and the strip's words are spaced (a gap of at least
    3 px between ``4`` and ``robots``)."""
    from PIL import ImageDraw

    from bulletnav.viz.fleet_frames import STOPPED_RGB
    from bulletnav.viz.video import draw_text, text_length, ui_font

    assert STOPPED_RGB == (255, 255, 255)
    assert all(sum(abs(a - b) for a, b in zip(rgb, STOPPED_RGB)) >= 100 for rgb in ROBOT_PALETTE)
    assert ROBOT_PALETTE.index((230, 25, 75)) == 15 and robot_colour(0) == (60, 180, 75)  # robot 0 green
    _, visuals, _, _, _ = recorded
    base = np.asarray(visuals.frames._render_base(ROBOTS))
    legend = base[:720, 730:]
    assert (legend == np.array(STOPPED_RGB)).all(axis=-1).sum() > 20  # the octagon sample
    # the spaced text: "4 robots" as drawn is wider by the gap than "4robots", and the gap is blank
    font = ui_font(11)
    assert text_length("4 robots", font) - text_length("4robots", font) >= 3.0
    img = Image.new("RGB", (80, 20), (0, 0, 0))
    draw_text(ImageDraw.Draw(img), (2, 2), "4 robots", font, (255, 255, 255))
    ink = np.asarray(img).max(axis=(0, 2)) > 60  # columns with any ink
    four_end = 2 + int(ImageDraw.Draw(img).textlength("4", font=font))
    assert not ink[four_end + 1:four_end + 3].any() and ink[four_end + 3:].any()


def test_fleet_table_leaves_out_the_rate_of_a_run_too_short(capsys):
    """errands/h is shown for runs of at least one typical errand (70 s), '-' and a reason below."""
    import argparse

    from bulletnav.cli.fleet import _print_fleet_table
    from bulletnav.fleet.metrics import TYPICAL_ERRAND_S

    row = {"episode": 0, "seed": 7, "errands": 4, "collisions_robot_robot": 0, "collisions_static": 0,
           "collisions_mover": 0, "collisions_person": 0, "deadlocks": 0, "min_separation_m": 0.5, "errand_time_s": 50.0}
    summary = {"errands": 4, "collisions_robot_robot": 0, "collisions_static": 0, "collisions_mover": 0,
               "collisions_person": 0, "deadlocks": 0, "min_separation_m": 0.5, "errand_time_s": 50.0}
    assert TYPICAL_ERRAND_S == 70.0
    for duration, robots, shown in ((120.0, 4, "120.0 errands/h (30.0 per robot)"),  # 4 errands in 1/30 h, by hand
                                    (60.0, 8, "errands/h: run too short (60 s; an errand takes ~70 s), 4 errands")):
        rate = 4 * 3600.0 / duration
        args = argparse.Namespace(robots=robots, controller="independent", shield=False, episodes=1, duration=duration,
                                  dynamic=True, seed=7)
        _print_fleet_table(args, {"summary": {**summary, "throughput_per_hour": rate,
                                              "throughput_per_robot_per_hour": rate / robots},
                                  "episodes": [{**row, "throughput_per_hour": rate}]})
        out = capsys.readouterr().out
        assert f"all: {shown}, collisions" in out
        assert ("  120.0 " in out) == (duration >= 70) and (" - " in out.splitlines()[2]) == (duration < 70)


def test_comparison_table_leaves_out_the_rate_of_a_run_too_short():
    """fleet-compare's table follows the fleet table's rule: no errands/h for episodes shorter
    than a typical errand, and one line that says why; the numbers stay for longer runs."""
    from bulletnav.fleet.compare import comparison_markdown

    cell = {"robots": 8, "entry": "independent", "throughput_per_hour": 48.0, "throughput_se": 6.0,
            "throughput_per_robot_per_hour": 6.0, "collisions_robot_robot": 0, "collisions_static": 1,
            "collisions_mover": 0, "collisions_person": 0, "deadlocks": 0, "min_separation_m": 0.4,
            "errand_time_s": 55.0, "near_misses": 2, "shield_rate": float("nan"), "episodes": 4}
    for duration, shown in ((120.0, True), (60.0, False)):
        md = comparison_markdown({"settings": {"episodes": 4, "seed": 9000, "robots": [8],
                                               "env_kwargs": {"duration_s": duration, "dynamic": False}},
                                  "cells": [cell], "provenance": {}})
        row = next(line for line in md.splitlines() if line.startswith("| independent |"))
        assert row.startswith("| independent | 48.0 ± 6.0 | 6.0 | 0 | 1 |") == shown
        assert row.startswith("| independent | - | - | 0 | 1 |") == (not shown)
        assert ("episodes of 60 s end before a robot can be expected to finish one errand" in md) == (not shown)
