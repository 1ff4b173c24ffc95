"""Multi-goal missions in the pictures: numbered goals and visit order in trajectory plots,
numbered / ticked goals and progress in videos, every goal and progress in the GUI dashboard."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.config import asset_path
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.viz import Dashboard, DashboardConfig, EpisodeRecorder, TrajectoryLog, plot_trajectories, trajectory_figure
from bulletnav.viz.mission import progress_text, visit_order, visit_text
from bulletnav.viz.plots import GOAL_GID

ENV_ID = "bulletnav/Warehouse-v0"
EMPTY = str(asset_path("worlds", "empty.yaml"))
MISSION = {"start": [0.0, 0.0, 0.0], "goals": [[2.0, 0.0], [2.0, 2.5], [-1.0, 2.5]]}
SHORT_MISSION = {"start": [0.0, 0.0, 0.0], "goals": [[1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]}
"""About 3 m to drive: the GUI test steps slowly under Xvfb."""


def mission_env(**kwargs):
    return gym.make(ENV_ID, world=EMPTY, task_name="mission", goals=3, goal_order="fixed", **kwargs)


def drive(env, options, steps, hooks=(), seed=0):
    """Run the PID navigator (no planner) for up to ``steps`` steps; hooks get (env, info)."""
    obs, info = env.reset(seed=seed, options=options)
    nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="none"))
    nav.reset(info)
    for on_reset, _ in hooks:
        on_reset(env, info)
    for _ in range(steps):
        obs, _, terminated, truncated, info = env.step(nav.act(obs, info))
        for _, on_step in hooks:
            on_step(env, info)
        if terminated or truncated:
            break
    return info


def texts(fig, gid):
    return [t.get_text() for ax in fig.axes for t in ax.texts if t.get_gid() == gid]


def test_visit_order_ranks_by_step():
    assert visit_order([None, None, None]) == [None, None, None]
    assert visit_order([40, 12, None]) == [2, 1, None]
    assert visit_order([5, 5, 3]) == [2, 3, 1]
    assert visit_text(2, 756, 1 / 24) == "#2 @ 31.5 s"
    assert progress_text(1, 3) == "goals 1/3"


@pytest.fixture(scope="module")
def mission_log():
    """A fixed-order mission stopped after two of its three goals (the third never visited)."""
    env = mission_env()
    log = TrajectoryLog()
    seen = []

    def on_step(env, info):
        log.on_step(env, info)
        seen.append(info)

    try:
        info = drive(env, MISSION, 2000, hooks=[(log.on_reset, on_step)])
        # keep driving until exactly two goals are reached, then stop: rebuild with a cut-off
        if info["goals_reached"] != 3:
            pytest.fail(f"the scripted mission should finish, got {info['goals_reached']}/3")
        steps_to_second = info["reached_at"][1]
        log2 = TrajectoryLog()
        info2 = drive(env, MISSION, steps_to_second + 5, hooks=[(log2.on_reset, log2.on_step)])
        dt = env.unwrapped.scene.control_dt
    finally:
        env.close()
    return log, info, log2, info2, dt


def test_mission_plot_numbers_goals_and_visit_order(mission_log, tmp_path):
    log, info, _, _, dt = mission_log
    (ep,) = log.episodes
    assert ep.mission and ep.goals == tuple(tuple(g) for g in MISSION["goals"])
    assert ep.reached_at == tuple(info["reached_at"]) and all(s is not None for s in ep.reached_at)
    assert ep.goal_order == "fixed" and ep.control_dt == dt
    fig = trajectory_figure(log)
    assert texts(fig, GOAL_GID["number"]) == ["1", "2", "3"]
    want = [visit_text(rank, info["reached_at"][i], dt) for i, rank in enumerate(visit_order(info["reached_at"]))]
    assert want[0].startswith("#1 @ ") and want[2].startswith("#3 @ ")
    assert texts(fig, GOAL_GID["visit"]) == want
    assert texts(fig, GOAL_GID["unvisited"]) == []
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert any("numbered" in t for t in legend) and "visit order @ time" in legend
    assert plot_trajectories(log, tmp_path / "mission.png").stat().st_size > 0


def test_mission_plot_marks_unvisited_goals(mission_log):
    _, _, log2, info2, dt = mission_log
    assert info2["goals_reached"] == 2 and info2["reached_at"][2] is None
    fig = trajectory_figure(log2)
    assert texts(fig, GOAL_GID["number"]) == ["1", "2", "3"]
    assert texts(fig, GOAL_GID["visit"]) == [visit_text(r, s, dt) for r, s in zip((1, 2), info2["reached_at"][:2])]
    assert texts(fig, GOAL_GID["unvisited"]) == ["not visited"]
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "goal not visited" in legend


def test_single_goal_plot_has_no_mission_artists(tmp_path):
    env = gym.make(ENV_ID, world=EMPTY, max_episode_steps=60)
    log = TrajectoryLog()
    try:
        info = drive(env, {"start": [-2.0, 0.0, 0.0], "goal": [0.0, 0.5]}, 60, hooks=[(log.on_reset, log.on_step)])
    finally:
        env.close()
    assert "goals" not in info
    (ep,) = log.episodes
    assert not ep.mission and ep.goals == () and ep.reached_at == ()
    fig = trajectory_figure(log)
    (ax,) = fig.axes
    assert len(ax.texts) == 0  # no numbers, no visit labels
    assert all(a.get_gid() not in GOAL_GID.values() for a in ax.get_children())
    assert len(ax.patches) == 2 + 2  # floor + walls, the goal zone's fill + outline (empty world)
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend == ["success", "collision", "timeout", "start", "goal zone"]


def test_mission_video_numbers_goals_and_shows_progress(tmp_path):
    env = mission_env()
    rec = EpisodeRecorder(tmp_path / "mission.gif", stride=50)
    strips = []
    frames = {}

    def on_step(env, info):
        rec.on_step(env, info)
        if info["goals_reached"] not in frames:
            frames[info["goals_reached"]] = rec.compose(env)
        strips.append(rec.mission_text)

    try:
        info = drive(env, MISSION, 2000, hooks=[(lambda e, i: rec.on_reset(e, i), on_step)])
    finally:
        rec.close()
        env.close()
    assert info["goals_reached"] == 3
    assert rec.frames_written > 2
    assert strips[0].startswith("goals 0/3") and strips[-1].startswith("goals 3/3")
    assert any(s.startswith("goals 1/3") for s in strips)
    # the map changes when a goal is reached: its zone filled and ticked
    assert not np.array_equal(frames[0], frames[1])


@pytest.mark.gui
@pytest.mark.slow
def test_dashboard_marks_every_goal_and_progress(display, drawn_texts):
    env = mission_env(render_mode="human")
    try:
        obs, info = env.reset(seed=0, options=SHORT_MISSION)
        dash = Dashboard(env, DashboardConfig(camera_every=10_000))  # no camera renders: slow under Xvfb
        # 3 lines per goal, a number per goal, one progress text
        assert dash.debug_items == 3 * 3 + 3 + 1
        assert "goals 0/3" in drawn_texts and {"1", "2", "3"} <= set(drawn_texts)
        nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="none"))
        nav.reset(info)
        items = set()
        for _ in range(2000):
            obs, _, terminated, truncated, info = env.step(nav.act(obs, info))
            dash.on_step(nav.path, info)
            items.add(dash.debug_items)
            if terminated or truncated:
                break
        assert info["goals_reached"] == 3
        assert dash.goals_shown == 3
        for k in (1, 2, 3):
            assert f"goals {k}/3" in drawn_texts
        # items are replaced, never piled up: 9 goal lines, 3 numbers, 1 progress text, the rays
        # (the rays from the first lidar_every-th step on)
        assert items == {3 * 3 + 3 + 1, 3 * 3 + 3 + 1 + len(range(0, 36, dash.config.lidar_ray_stride))}

        # Without info (as `bulletnav navigate --gui` calls it), a reset that keeps the scene:
        # the progress still follows the goals reached, from the pose in the target's zone.
        drawn_texts.clear()
        obs, info = env.reset(options=SHORT_MISSION)
        nav.reset(info)
        dash.on_reset()
        assert dash.goals_shown == 0 and "goals 0/3" in drawn_texts
        for _ in range(2000):
            obs, _, terminated, truncated, info = env.step(nav.act(obs, info))
            dash.on_step(nav.path)
            assert dash.goals_shown == info["goals_reached"]
            if terminated or truncated:
                break
        assert dash.goals_shown == 3 and dash.debug_items == 3 * 3 + 3 + 1 + 4
    finally:
        env.close()
