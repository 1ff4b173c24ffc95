"""Visualisation of dynamic worlds: movers and events in trajectory plots, videos and the GUI dashboard."""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet
import pytest
import yaml
from PIL import Image

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.config import asset_path
from bulletnav.evaluation import run_episodes
from bulletnav.sim.world import COLOURS
from bulletnav.viz import Dashboard, EpisodeRecorder, TrajectoryLog, figure_size, plot_trajectories, trajectory_figure
from bulletnav.viz.movers import EVENT_HEX, EVENT_RGB, FORKLIFT_PALETTE, WORKER_PALETTE, hex_colour
from bulletnav.viz.plots import EVENT_GID, MOVER_GID
from bulletnav.viz.video import MAP_PX, SIDE_X, STRIP_Y, MapView

EMPTY = str(asset_path("worlds", "empty.yaml"))
FORKLIFT_ROUTE = [[-4.5, 0.5], [4.5, 0.5], [4.5, 4.0]]
WORKER_ROUTE = [[-2.0, 4.2], [3.0, 4.2]]
PALLET_XY = (0.5, -2.0)


def dynamic_world(tmp_path: Path) -> str:
    """A 12 x 10 m hall with one forklift (2 route segments), one worker (1 segment) and a
    scripted pallet added at 0.5 s and removed at 1.0 s, clear of the robot, goal and routes."""
    doc = {"name": "viz-dynamic", "size": [12.0, 10.0],
           "obstacles": [{"type": "box", "center": [0.0, 2.5], "size": [4.0, 0.6, 1.8]}],
           "start": [-4.0, -3.0, 0.0], "goal": [4.5, -3.0],
           "dynamic": [{"type": "forklift", "route": FORKLIFT_ROUTE, "speed": 0.6},
                       {"type": "worker", "waypoints": WORKER_ROUTE, "speed": 1.0, "pause": 0.5}],
           "events": [{"at": 0.5, "add": {"type": "box", "center": list(PALLET_XY), "size": [1.2, 0.8, 1.0],
                                          "label": "pallet_a"}},
                      {"at": 1.0, "remove": "pallet_a"}]}
    path = tmp_path / "dynamic.yaml"
    path.write_text(yaml.safe_dump(doc))
    return str(path)


class Creep:
    """Drive slowly straight ahead (normalized action)."""

    def reset(self, info):
        pass

    def act(self, obs, info):
        return np.array([0.3, 0.0], dtype=np.float32)


def gids(fig) -> dict[str, list]:
    out: dict[str, list] = {}
    for artist in fig.findobj():
        gid = artist.get_gid()
        if gid:
            out.setdefault(gid, []).append(artist)
    return out


def legend_labels(fig) -> list[str]:
    return [t.get_text() for legend in fig.legends for t in legend.get_texts()]


def log_episode(env, episodes: int = 1, seed: int = 0, watch=None) -> tuple[TrajectoryLog, list]:
    log = TrajectoryLog()

    def on_step(e, info):
        log.on_step(e, info)
        if watch is not None:
            watch(e, info)

    results = run_episodes(env, Creep(), episodes, seed=seed, on_reset=log.on_reset, on_step=on_step,
                           on_episode=log.on_episode)
    return log, results


def test_plot_draws_one_route_per_mover_with_trail_and_footprint(tmp_path):
    env = gym.make("bulletnav/WarehouseDynamic-v0", max_episode_steps=24)
    last: list = []
    try:
        log, results = log_episode(env, watch=lambda e, i: last.__setitem__(slice(None), e.unwrapped.scene.movers))
    finally:
        env.close()
    (ep,) = log.episodes
    assert len(ep.movers) == len(last) >= 4  # 2-4 forklifts and 2-6 workers
    assert [t.kind for t in ep.movers] == [m.kind for m in last]
    for track, mover in zip(ep.movers, last):
        assert len(track.poses) == results[0].steps + 1  # reset, then every step
        assert track.poses[-1] == mover.pose and track.path == mover.path and track.size == mover.size

    fig = trajectory_figure(log)
    drawn = gids(fig)
    routes = drawn[MOVER_GID["path"]]
    assert len(routes) == len(ep.movers)
    assert len(drawn[MOVER_GID["trail"]]) == len(drawn[MOVER_GID["footprint"]]) == len(ep.movers)
    # forklifts in the yellow-amber family, workers in the blue-violet one, one shade each
    for kind, palette in (("forklift", FORKLIFT_PALETTE), ("worker", WORKER_PALETTE)):
        colours = [line.get_color() for line, t in zip(routes, ep.movers) if t.kind == kind]
        assert colours == [hex_colour(palette[k % len(palette)]) for k in range(len(colours))]
        trails = [line.get_color() for line, t in zip(drawn[MOVER_GID["trail"]], ep.movers) if t.kind == kind]
        assert trails == colours  # the same shade for a mover's route and trail
    for line, track in zip(routes, ep.movers):
        np.testing.assert_allclose(np.column_stack(line.get_data()), np.asarray(track.path))
    # each final footprint against its shape built here with Shapely from the mover's last pose:
    # a forklift a size[0] (along its heading) x size[1] rectangle, a worker a disc of size[0] / 2
    from matplotlib.patches import Circle
    from shapely import affinity
    from shapely.geometry import Polygon, box

    for patch, track in zip(drawn[MOVER_GID["footprint"]], ep.movers):
        x, y, yaw = track.poses[-1]
        if track.kind == "forklift":
            length, width = track.size[0], track.size[1]
            want = affinity.translate(affinity.rotate(box(-length / 2, -width / 2, length / 2, width / 2), yaw,
                                                      origin=(0, 0), use_radians=True), x, y)
            got = Polygon(patch.get_xy())
            assert got.symmetric_difference(want).area < 1e-9 * want.area, (track.kind, got.wkt, want.wkt)
        else:
            assert isinstance(patch, Circle)
            assert patch.center == pytest.approx((x, y)) and patch.radius == pytest.approx(track.size[0] / 2)
    assert {"forklift route", "worker route"} <= set(legend_labels(fig))
    assert "event_add" not in drawn and "event_remove" not in drawn  # no event in these 24 steps

    out = plot_trajectories(log, tmp_path / "dynamic.png")
    with Image.open(out) as img:
        assert img.size == figure_size(log)


def test_scripted_events_are_marked_on_the_plot(tmp_path):
    env = gym.make("bulletnav/Warehouse-v0", world=dynamic_world(tmp_path), max_episode_steps=30)  # 1.25 s
    try:
        log, _ = log_episode(env)
    finally:
        env.close()
    (ep,) = log.episodes
    assert [(e["action"], e["label"], e["time_s"]) for e in ep.events] == [("add", "pallet_a", 0.5),
                                                                            ("remove", "pallet_a", 1.0)]
    assert [t.kind for t in ep.movers] == ["forklift", "worker"]

    fig = trajectory_figure(log)
    drawn = gids(fig)
    assert len(drawn[MOVER_GID["path"]]) == 2
    (added,) = drawn[EVENT_GID["add"]]
    (removed,) = drawn[EVENT_GID["remove"]]
    corners = added.get_xy()[:4]
    np.testing.assert_allclose(corners.min(axis=0), (PALLET_XY[0] - 0.6, PALLET_XY[1] - 0.4))
    np.testing.assert_allclose(corners.max(axis=0), (PALLET_XY[0] + 0.6, PALLET_XY[1] + 0.4))
    assert tuple(np.ravel(removed.get_data())) == PALLET_XY and removed.get_marker() in ("x", "X")
    assert added.get_edgecolor()[:3] == pytest.approx(tuple(int(EVENT_HEX[i:i + 2], 16) / 255 for i in (1, 3, 5)))
    assert {"obstacle added", "obstacle removed", "forklift route", "worker route"} <= set(legend_labels(fig))
    # the last footprint of each mover is where the episode left it
    forklift, worker = drawn[MOVER_GID["footprint"]]
    x, y, _ = ep.movers[1].poses[-1]
    assert worker.center == pytest.approx((x, y)) and worker.radius == pytest.approx(0.25)
    np.testing.assert_allclose(forklift.get_xy()[:4].mean(axis=0), ep.movers[0].poses[-1][:2], atol=1e-9)


def test_static_world_logs_and_plots_no_movers_or_events(tmp_path):
    env = gym.make("bulletnav/Warehouse-v0", world=EMPTY, max_episode_steps=10)
    try:
        log, _ = log_episode(env)
    finally:
        env.close()
    (ep,) = log.episodes
    assert ep.movers == [] and ep.events == [] and not ep.dynamic
    fig = trajectory_figure(log)
    assert not set(gids(fig)) & {*MOVER_GID.values(), *EVENT_GID.values(), "event_time"}
    assert legend_labels(fig) == ["success", "collision", "timeout", "start", "goal zone"]
    fig.draw_without_rendering()
    rows = {round(t.get_window_extent().y0) for t in fig.legends[0].get_texts()}
    assert len(rows) == 1  # one legend row, as before


def _near(pixel, rgb, tol: int = 12) -> bool:
    return all(abs(int(a) - int(b)) <= tol for a, b in zip(pixel, rgb))


def _has_colour(region: np.ndarray, rgb, tol: int = 0) -> bool:
    return bool(np.any(np.all(np.abs(region.astype(int) - np.asarray(rgb)) <= tol, axis=-1)))


def test_video_map_shows_movers_events_and_a_text_line(tmp_path):
    env = gym.make("bulletnav/Warehouse-v0", world=dynamic_world(tmp_path), max_episode_steps=30)
    try:
        with EpisodeRecorder(tmp_path / "dynamic.gif", stride=10) as rec:
            obs, info = env.reset(seed=0)
            rec.on_reset(env, info)
            for _ in range(30):
                obs, _, terminated, truncated, info = env.step(Creep().act(obs, info))
                rec.on_step(env, info)
                if terminated or truncated:
                    break
            scene = env.unwrapped.scene
            frame = rec.compose(env)  # the state now, as a frame would show it
            view = MapView(scene.layout)
            forklift, worker = scene.movers
        static_env = gym.make("bulletnav/Warehouse-v0", world=EMPTY, max_episode_steps=5)
        try:
            with EpisodeRecorder(tmp_path / "static.gif", stride=5) as rec_static:
                obs, info = static_env.reset(seed=0)
                rec_static.on_reset(env=static_env, info=info)
                for _ in range(5):
                    obs, *_, info = static_env.step(Creep().act(obs, info))
                    rec_static.on_step(static_env, info)
                static_frame = rec_static.last_frame
        finally:
            static_env.close()
    finally:
        env.close()

    def px(x, y):
        # the map transform written out here: the floor and its 0.2 m walls fitted into the
        # 480 px map square inside an 8 px margin, x right, y up
        hx, hy = scene.layout.half_extents
        scale = (480 - 2 * 8) / (2 * max(hx + 0.2, hy + 0.2))
        u, v = 240 + scale * x, 240 - scale * y
        assert view.to_px((x, y))[0] == pytest.approx((u, v), abs=1e-9)
        return frame[int(round(v)), int(round(u))]

    x, y, yaw = forklift.pose  # behind its centre: off the heading tick
    assert _near(px(x - 0.3 * math.cos(yaw), y - 0.3 * math.sin(yaw)), FORKLIFT_PALETTE[0])
    assert _near(px(*worker.pose[:2]), WORKER_PALETTE[0])
    # the pallet added at 0.5 s and removed at 1.0 s: filled, outlined and crossed out
    pallet = tuple(int(round(255 * c)) for c in COLOURS["pallet"][:3])
    assert _near(px(PALLET_XY[0] + 0.3, PALLET_XY[1]), pallet, tol=2)
    assert _near(px(PALLET_XY[0] - 0.6, PALLET_XY[1]), EVENT_RGB, tol=2)  # its outline
    assert _near(px(*PALLET_XY), EVENT_RGB, tol=2)  # where the cross's diagonals meet
    # the legend lists the movers and events, the strip has its text line; a static world's frame neither
    for img, dynamic in ((frame, True), (static_frame, False)):
        legend, strip = img[:MAP_PX, SIDE_X:], img[STRIP_Y:, :]
        assert _has_colour(legend, EVENT_RGB) == dynamic
        assert _has_colour(legend, FORKLIFT_PALETTE[0]) == _has_colour(legend, WORKER_PALETTE[0]) == dynamic
        assert _has_colour(strip, EVENT_RGB, tol=30) == dynamic


def test_recording_and_logging_leave_a_dynamic_episode_unchanged(tmp_path):
    traces = []
    for record in (False, True):
        env = gym.make("bulletnav/WarehouseDynamic-v0", pallet_events_per_min=120.0, max_episode_steps=40)
        try:
            log = TrajectoryLog()
            rec = EpisodeRecorder(tmp_path / "side.gif", stride=5) if record else None
            trace = []
            for seed in (3, 4):
                obs, info = env.reset(seed=seed)
                if record:
                    log.on_reset(env, info)
                    rec.on_reset(env, info)
                for _ in range(40):
                    obs, reward, terminated, truncated, info = env.step(Creep().act(obs, info))
                    if record:
                        log.on_step(env, info)
                        rec.on_step(env, info)
                    trace.append((obs.copy(), reward, info["events"], info["nearest_mover_m"],
                                  [m.pose for m in env.unwrapped.scene.movers]))
                    if terminated or truncated:
                        break
            if rec is not None:
                rec.close()
            traces.append(trace)
        finally:
            env.close()
    assert len(traces[0]) == len(traces[1])
    assert any(step[2] for step in traces[0])  # events happened (120 per minute drawn)
    for a, b in zip(*traces):
        np.testing.assert_array_equal(a[0], b[0])
        assert a[1:] == b[1:]


@pytest.mark.gui
@pytest.mark.slow
def test_dashboard_draws_routes_once_and_event_messages(display, monkeypatch, tmp_path):
    calls = {"new": [], "replace": [], "text_new": [], "text_replace": []}
    real_line, real_text = pybullet.addUserDebugLine, pybullet.addUserDebugText

    def counting_line(*args, **kwargs):
        item = real_line(*args, **kwargs)
        calls["replace" if "replaceItemUniqueId" in kwargs else "new"].append(item)
        return item

    def counting_text(text, *args, **kwargs):
        item = real_text(text, *args, **kwargs)
        calls["text_replace" if "replaceItemUniqueId" in kwargs else "text_new"].append((text, item))
        return item

    monkeypatch.setattr(pybullet, "addUserDebugLine", counting_line)
    monkeypatch.setattr(pybullet, "addUserDebugText", counting_text)
    env = gym.make("bulletnav/Warehouse-v0", render_mode="human", world=dynamic_world(tmp_path))
    try:
        env.reset(seed=0)
        scene = env.unwrapped.scene
        routes = (len(FORKLIFT_ROUTE) - 1) + (len(WORKER_ROUTE) - 1)
        dash = Dashboard(env)  # goal marker (3 lines) and the routes, once
        assert dash.debug_draw_calls == len(calls["new"]) == 3 + routes and not calls["replace"]
        for _ in range(30):  # 1.25 s: the pallet comes at 0.5 s and goes at 1.0 s
            env.step([0.0, 0.0])
            dash.on_step()
        hud = [text for text, _ in calls["text_new"] + calls["text_replace"] if text.startswith("nearest mover")]
        events = [(text, item) for text, item in calls["text_new"] if not text.startswith("nearest mover")]
        assert [text for text, _ in events] == ["+ pallet_a (0.5 s)", "- pallet_a (1.0 s)"]
        # the safety line, with every lidar redraw: created once, then replaced
        assert len(hud) == 30 // dash.config.lidar_every and "| min " in hud[-1] and "near misses" in hud[-1]
        assert dash.debug_text_calls == 2 + len(hud)
        assert not [text for text, _ in calls["text_replace"] if not text.startswith("nearest mover")]
        rays = len(range(0, 36, dash.config.lidar_ray_stride))
        assert dash.debug_items == 3 + routes + rays + 2 + 1
        # routes are not redrawn while stepping: only the lidar rays were added / moved
        assert len(calls["new"]) == 3 + routes + rays

        # a reset that keeps the scene: the routes are moved in place, the messages hidden in place
        builds = scene.scene_builds
        env.reset()
        dash.on_reset()
        assert scene.scene_builds == builds
        assert len(calls["new"]) == 3 + routes + rays and len(calls["text_new"]) == 3  # 2 events, 1 safety line
        hidden = [text for text, _ in calls["text_replace"] if not text.startswith("nearest mover")]
        assert hidden == [" ", " ", " "]  # both messages and the safety line hidden in place

        # a seeded reset rebuilds the scene and deletes every debug item: drawn anew, once
        env.reset(seed=1)
        dash.on_reset()
        assert scene.scene_builds != builds
        assert len(calls["new"]) == 2 * (3 + routes) + rays
        assert dash.debug_items == 3 + routes
    finally:
        env.close()
