"""Visualisation: episode videos, recording side effects, GUI dashboard throttling, trajectory plots."""

from __future__ import annotations

import math

import gymnasium as gym
import imageio.v2 as imageio
import numpy as np
import pybullet
import pytest
from PIL import Image

import bulletnav  # noqa: F401  (registers the env)
from bulletnav.config import asset_path
from bulletnav.evaluation import run_episodes
from bulletnav.viz import (
    FRAME_SIZE,
    Dashboard,
    DashboardConfig,
    EpisodeRecorder,
    TrajectoryLog,
    figure_size,
    plot_trajectories,
    simplify_path,
    trajectory_figure,
)
from bulletnav.viz.video import GOAL, MAP_PX

ENV_ID = "bulletnav/Warehouse-v0"
EMPTY = str(asset_path("worlds", "empty.yaml"))
# Episode 1 reaches the goal (~1 m to drive) before the 60-step limit; episode 2 times out.
EPISODES = [
    {"start": (-2.0, 0.0, 0.0), "goal": (-0.5, 0.0)},
    {"start": (0.0, -2.0, math.pi / 2), "goal": (3.0, 3.0)},
]


def scripted(obs: np.ndarray) -> np.ndarray:
    """Steer at the goal from the observation alone (heading error at 36, distance at 42)."""
    heading = float(obs[36]) * math.pi
    v = 0.5 * max(math.cos(heading), 0.0)
    return np.array([v, float(np.clip(2.0 * heading, -1.5, 1.5))], dtype=np.float32)


def expected_frames(steps: int, stride: int) -> int:
    """The documented count: reset frame + every stride-th step + the final step when off the stride."""
    return 1 + steps // stride + (1 if steps % stride else 0)


@pytest.mark.slow
def test_video_frames_are_composed_and_counted(tmp_path):
    env = gym.make(ENV_ID, world=EMPTY, max_episode_steps=60)
    mp4, gif = tmp_path / "episodes.mp4", tmp_path / "episodes.gif"
    steps, outcomes = [], []
    try:
        with EpisodeRecorder(mp4, stride=1) as rec_mp4, EpisodeRecorder(gif, stride=7, fps=12) as rec_gif:
            for options in EPISODES:
                obs, info = env.reset(seed=0, options=options)
                rec_mp4.on_reset(env)
                rec_gif.on_reset(env)
                n = 0
                while True:
                    obs, reward, terminated, truncated, info = env.step(scripted(obs))
                    n += 1
                    path = [options["start"][:2], options["goal"]]
                    rec_mp4.on_step(env, info, path)
                    rec_gif.on_step(env, info, path)
                    if terminated or truncated:
                        break
                steps.append(n)
                outcomes.append("success" if info["is_success"] else "timeout" if n == 60 else "other")
            frame = rec_mp4.last_frame
    finally:
        env.close()
    assert outcomes == ["success", "timeout"] and steps[0] % 7 != 0  # both counting rules exercised
    assert rec_mp4.frame_size == FRAME_SIZE == (960, 528)
    assert FRAME_SIZE[0] % 16 == 0 and FRAME_SIZE[1] % 16 == 0

    want_mp4 = sum(expected_frames(n, 1) for n in steps)
    want_gif = sum(expected_frames(n, 7) for n in steps)
    assert rec_mp4.frames_written == want_mp4 and rec_gif.frames_written == want_gif
    with imageio.get_reader(mp4) as reader:
        video = [f for f in reader]
    gif_frames = imageio.mimread(gif, memtest=False)
    assert len(video) == want_mp4 and len(gif_frames) == want_gif
    w, h = FRAME_SIZE
    assert video[0].shape == (h, w, 3)
    assert gif_frames[0].shape[:2] == (h, w)

    # The panels are really composed (checked on the exact last frame and on decoded video).
    assert frame.shape == (h, w, 3) and frame.dtype == np.uint8
    for img, tol in ((frame, 0), (video[-1], 40)):
        img = img.astype(int)
        rgb_panel = img[0:240, 480:800]
        depth_panel = img[240:480, 480:800]
        map_panel = img[0:MAP_PX, 0:MAP_PX]
        assert rgb_panel.std() > 10  # a camera image, not a flat fill
        goal_px = np.all(np.abs(map_panel - np.array(GOAL)) <= tol, axis=-1).sum()
        assert goal_px > 50  # the goal ring and centre dot
        colours = {tuple(c) for c in (depth_panel[::8, ::8] // 32).reshape(-1, 3)}
        assert len(colours) >= 4  # the depth colour map spans several colours


def _run(env, recorders, seeds, steps_per_episode):
    """Scripted episodes; returns everything the env handed back."""
    trace = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        trace.append(("reset", obs, info))
        for rec in recorders:
            if isinstance(rec, TrajectoryLog):
                rec.on_reset(env, info)
            else:  # EpisodeRecorder.on_reset(env, path=None)
                rec.on_reset(env)
        for _ in range(steps_per_episode):
            obs, reward, terminated, truncated, info = env.step(scripted(obs))
            trace.append(("step", obs, reward, terminated, truncated, info))
            for rec in recorders:
                rec.on_step(env, info)
            if terminated or truncated:
                break
    return trace


def _assert_identical(a, b):
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert x[0] == y[0]
        for u, v in zip(x[1:], y[1:]):
            if isinstance(u, dict):
                assert u.keys() == v.keys()
                for k in u:
                    np.testing.assert_array_equal(np.asarray(u[k]), np.asarray(v[k]), err_msg=k)
            else:
                np.testing.assert_array_equal(np.asarray(u), np.asarray(v))


def test_recording_leaves_the_episode_unchanged(tmp_path):
    # procedural warehouse with IMU noise: any extra random draw or physics step would show
    traces = []
    for record in (False, True):
        env = gym.make(ENV_ID)
        try:
            recorders = [EpisodeRecorder(tmp_path / "side.mp4", stride=1), TrajectoryLog()] if record else []
            traces.append(_run(env, recorders, seeds=(3, 4), steps_per_episode=25))
            for rec in recorders:
                if isinstance(rec, EpisodeRecorder):
                    rec.close()
                    assert rec.frames_written >= 2
        finally:
            env.close()
    _assert_identical(traces[0], traces[1])
    # the side video, decoded by imageio: the documented count (a reset frame and every step,
    # stride 1) of each episode the trace holds
    lengths, n = [], 0
    for entry in traces[1]:
        if entry[0] == "reset" and n:
            lengths.append(n)
            n = 0
        n += entry[0] == "step"
    lengths.append(n)
    with imageio.get_reader(tmp_path / "side.mp4") as reader:
        decoded = sum(1 for _ in reader)
    assert len(lengths) == 2 and decoded == sum(expected_frames(k, 1) for k in lengths)


def test_dashboard_needs_the_gui():
    env = gym.make(ENV_ID, world=EMPTY)
    try:
        env.reset(seed=0)
        with pytest.raises(ValueError, match="render_mode='human'"):
            Dashboard(env)
    finally:
        env.close()
    with pytest.raises(ValueError, match="camera_every"):
        DashboardConfig(camera_every=0)


def test_simplify_path_keeps_corners_and_caps_segments():
    straight = [(0.1 * i, 0.0) for i in range(11)] + [(1.0, 0.1 * j) for j in range(1, 6)]
    assert simplify_path(straight, 40) == [(0.0, 0.0), (1.0, 0.0), (1.0, 0.5)]
    zigzag = [(i, i % 2) for i in range(100)]
    assert len(simplify_path(zigzag, 10)) == 11


@pytest.mark.gui
@pytest.mark.slow
def test_dashboard_throttles_and_replaces_in_place(display, monkeypatch):
    calls = {"new": [], "replace": [], "camera": 0}
    real_line, real_camera = pybullet.addUserDebugLine, pybullet.getCameraImage

    def counting_line(*args, **kwargs):
        item = real_line(*args, **kwargs)
        if "replaceItemUniqueId" in kwargs:
            calls["replace"].append((kwargs["replaceItemUniqueId"], item))
        else:
            calls["new"].append(item)
        return item

    def counting_camera(*args, **kwargs):
        calls["camera"] += 1
        return real_camera(*args, **kwargs)

    monkeypatch.setattr(pybullet, "addUserDebugLine", counting_line)
    monkeypatch.setattr(pybullet, "getCameraImage", counting_camera)
    cfg = DashboardConfig()  # every 10 steps; rays 0, 10, 20, 30 of 36
    rays = len(range(0, 36, cfg.lidar_ray_stride))
    path = [(-2.0, 0.0), (-1.0, 0.0), (0.0, 1.0)]  # 2 segments (no straight-through points)
    env = gym.make(ENV_ID, render_mode="human", world=EMPTY)  # one GUI per process: closed below
    try:
        obs, _ = env.reset(seed=0, options={"start": (-2.0, 0.0, 0.0), "goal": (3.0, 3.0)})
        dash = Dashboard(env, cfg)  # the env is reset: draws the goal marker (3 lines) now
        assert dash.debug_items == 3 and dash.debug_draw_calls == 3
        items = []
        for _ in range(100):
            obs, _, terminated, truncated, _ = env.step([0.25, 0.4])  # a 0.6 m circle: no collision
            assert not (terminated or truncated)
            dash.on_step(path)
            items.append(dash.debug_items)
        # no render at reset: one every camera_every steps
        assert dash.camera_renders == calls["camera"] == 100 // cfg.camera_every == 10
        want = 3 + (100 // cfg.lidar_every) * rays + (100 // cfg.path_every) * 2
        assert dash.debug_draw_calls == len(calls["new"]) + len(calls["replace"]) == want == 63
        # items exist from the first update on and are only moved after that
        assert items[cfg.lidar_every - 1:] == [3 + rays + 2] * (100 - cfg.lidar_every + 1)
        assert len(calls["new"]) == len(set(calls["new"])) == 3 + rays + 2
        assert all(old == new >= 0 for old, new in calls["replace"])

        # A seeded reset rebuilds the scene, which deletes all debug items: they are re-created once.
        env.reset(seed=1, options={"start": (-2.0, 0.0, 0.0), "goal": (3.0, 3.0)})
        dash.on_reset()
        for _ in range(cfg.lidar_every):
            env.step([0.25, 0.4])
            dash.on_step(path)
        assert dash.debug_items == 3 + rays + 2
        assert len(calls["new"]) == 2 * (3 + rays + 2)
        assert all(old == new >= 0 for old, new in calls["replace"])
    finally:
        env.close()


def test_trajectory_log_and_plots(tmp_path):
    env = gym.make(ENV_ID, world=EMPTY, max_episode_steps=40)

    class Scripted:
        def reset(self, info):
            pass

        def act(self, obs, info):
            return scripted(obs)

    try:
        log = TrajectoryLog()
        finals = []
        # the pose after each step straight from PyBullet (the scene's robot), not from info
        results = run_episodes(env, Scripted(), 2, seed=5, on_reset=log.on_reset,
                               on_step=lambda e, i: (log.on_step(e, i),
                                                     finals.append(e.unwrapped._scene.robot.planar_pose())),
                               on_episode=log.on_episode)
        # and one without the reset hook: the log starts the episode itself
        log2 = TrajectoryLog()
        run_episodes(env, Scripted(), 1, seed=5, on_step=log2.on_step, on_episode=log2.on_episode)
    finally:
        env.close()
    assert len(log) == 2
    for ep, res in zip(log.episodes, results):
        assert ep.result is res
        assert len(ep.points) == res.steps + 1
        assert ep.outcome == ("success" if res.success else "collision" if res.collision else "timeout")
        np.testing.assert_allclose(ep.points[0], ep.start[:2], atol=1e-6)
    assert log.episodes[-1].points[-1] == finals[-1][:2]
    assert log2.episodes[0].points == log.episodes[0].points

    out = plot_trajectories(log, tmp_path / "plots" / "one_map.png", title="scripted")
    with Image.open(out) as img:
        assert img.size == figure_size(log) == (700, 700)
    assert not list(out.parent.glob(".*tmp"))  # the temp file was renamed, not left behind

    # different layouts: small multiples, one panel per episode
    env = gym.make(ENV_ID, max_episode_steps=15)
    try:
        multi = TrajectoryLog()
        run_episodes(env, Scripted(), 3, seed=7, on_reset=multi.on_reset, on_step=multi.on_step,
                     on_episode=multi.on_episode)
    finally:
        env.close()
    out = plot_trajectories(multi, tmp_path / "multi.png")
    with Image.open(out) as img:
        assert img.size == figure_size(multi) == (2 * 300, 2 * 300 + 50)
    # every panel to scale in metres: its own ticks, the axis names on the outer panels
    panels = [ax for ax in trajectory_figure(multi).axes if ax.get_title()]
    assert len(panels) == 3 and all(len(ax.get_xticks()) > 1 and len(ax.get_yticks()) > 1 for ax in panels)
    assert panels[0].get_ylabel() == "y (m)" and {ax.get_xlabel() for ax in panels[1:]} == {"x (m)"}


@pytest.mark.gui
@pytest.mark.slow
def test_bench_gui_reports_frame_rates(display, monkeypatch, report):
    from bulletnav.bench.gui_bench import bench_gui

    renders = []
    real_camera = pybullet.getCameraImage

    def counting_camera(*args, **kwargs):
        renders.append(args[:2])
        return real_camera(*args, **kwargs)

    monkeypatch.setattr(pybullet, "getCameraImage", counting_camera)
    result = bench_gui(steps=3, repeats=1)
    report("GUI FPS throttled / unthrottled / no dashboard",
           f"{result['fps_throttled']} / {result['fps_unthrottled']} / {result['fps_no_dashboard']}")
    assert result["benchmark"] == "gui" and result["steps"] == 3 and result["repeats"] == 1
    assert result["throttles"]["camera_every"] == 10 and result["throttles"]["lidar_ray_stride"] == 10
    # Each setting drove 10 warm-up + 3 timed steps of one episode (2 m or more from its goal:
    # it cannot end in 13 steps), so the dashboards did exactly their documented work: the
    # throttled one rendered the camera once (every 10 steps), the unthrottled one every
    # step, none without a dashboard. A figure from a run that skipped its drawing would be
    # no frame rate of the dashboard at all.
    assert len(renders) == 13 // 10 + 13 // 1 + 0
    # the ratio is the two figures' (the bench rounds each figure and the ratio to 0.01, so
    # the quotient of the rounded figures differs by up to ratio * 0.005 * (1/fps_t + 1/fps_u) + 0.005)
    ft, fu = result["fps_throttled"], result["fps_unthrottled"]
    assert result["throttled_vs_unthrottled"] == pytest.approx(ft / fu, abs=ft / fu * 0.005 * (1 / ft + 1 / fu) + 0.006)


def test_the_legend_names_the_robots_own_parts_the_camera_sees(tmp_path):
    """The red cylinder and the blue block at the bottom of the camera image are the robot's own
    lidar and base: the legend lists both in the colours diff_drive.urdf gives them (read here
    from the URDF's materials), only when a camera is drawn; without one there is no depth bar."""
    import xml.etree.ElementTree as ET

    from bulletnav.viz.video import OWN_BODY, OWN_LIDAR, SIDE_X

    robot = ET.parse(asset_path("diff_drive.urdf")).getroot()
    materials = {m.get("name"): m.find("color").get("rgba") for m in robot.findall("material")}
    links = {link.get("name"): link.find("visual/material").get("name") for link in robot.findall("link")
             if link.find("visual/material") is not None}
    urdf_rgb = {part: tuple(round(float(v) * 255) for v in materials[links[link]].split()[:3])
                for part, link in (("body", "base_link"), ("lidar", "lidar_link"))}
    assert urdf_rgb == {"body": OWN_BODY, "lidar": OWN_LIDAR}
    rec = EpisodeRecorder(tmp_path / "x.mp4")
    try:
        with_camera, without = rec._render_base(camera=True), rec._render_base(camera=False)
    finally:
        rec.abort()
    legend = (slice(0, MAP_PX), slice(SIDE_X, FRAME_SIZE[0]))
    for colour in (OWN_BODY, OWN_LIDAR):
        assert np.all(np.asarray(with_camera)[legend] == colour, axis=-1).sum() >= 100  # a 12 x 10 px swatch
        assert not np.all(np.asarray(without)[legend] == colour, axis=-1).any()
    # the depth bar's turbo colours: dozens of distinct ones with a camera, none without
    count = lambda img: len({tuple(c) for c in np.asarray(img)[legend].reshape(-1, 3)})  # noqa: E731
    assert count(with_camera) > count(without) + 50
