"""Multi-goal missions: goal order, rewards, observation block, options and bad input."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
import shapely

import bulletnav  # noqa: F401
from bulletnav.config import asset_path
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.sim.layout import layout_to_dict
from test_layout import _reachable_independent, _shapely_clearance

EMPTY = str(asset_path("worlds", "empty.yaml"))
HALL = str(asset_path("worlds", "hall.yaml"))


def _mission(order="free", k=3, **kw):
    return gym.make("bulletnav/Warehouse-v0", world=EMPTY, task_name="mission", goals=k, goal_order=order,
                    collision_terminates=True, **kw)


def test_a_drive_through_three_goals_earns_two_subgoals_then_the_goal():
    env = _mission("fixed")
    goals = [[2.0, 0.0], [2.0, 2.5], [-1.0, 2.5]]
    obs, info = env.reset(seed=0, options={"start": [0.0, 0.0, 0.0], "goals": goals})
    nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="none"))
    nav.reset(info)
    subgoals = goal_terms = 0
    order = []
    for _ in range(3000):
        obs, reward, terminated, truncated, info = env.step(nav.act(obs, info))
        subgoals += info["reward_subgoal"] == 10.0
        goal_terms += info["reward_goal"] == 50.0
        order += [i for i, t in enumerate(info["reached_at"]) if t is not None and i not in order]
        assert reward == pytest.approx(sum(v for k, v in info.items() if k.startswith("reward_")))
        if terminated or truncated:
            break
    assert info["end_reason"] == "success" and info["is_success"]
    assert (subgoals, goal_terms) == (2, 1) and order == [0, 1, 2] and info["goals_reached"] == 3
    env.close()


def test_free_order_heads_for_the_nearest_goal_and_fixed_for_the_first():
    goals = [[4.0, 0.0], [1.0, 0.0], [2.5, 2.0]]
    for order, first in (("fixed", (4.0, 0.0)), ("free", (1.0, 0.0))):
        env = _mission(order)
        _, info = env.reset(seed=0, options={"start": [0.0, 0.0, 0.0], "goals": goals})
        assert info["goal"] == first
        env.close()


def test_the_navigator_visits_free_goals_in_the_optimal_order():
    """Start at 0; goals at x = 4, 1, 2.5 on a line: the best order is 1, 2.5, 4 (indices 1, 2, 0)."""
    env = _mission("free")
    obs, info = env.reset(seed=0, options={"start": [-1.0, 0.0, 0.0], "goals": [[4.0, 0.0], [1.0, 0.0], [2.5, 0.0]]})
    nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar"))
    nav.reset(info)
    assert nav.order == (1, 2, 0)
    for _ in range(2000):
        obs, _, terminated, truncated, info = env.step(nav.act(obs, info))
        if terminated or truncated:
            break
    assert info["is_success"]
    at = info["reached_at"]
    assert at[1] < at[2] < at[0]
    env.close()


def test_observation_mission_block_matches_geometry():
    env = _mission("free")
    goals = [[3.0, 0.0], [0.0, 2.0], [-2.0, -2.0]]
    obs, info = env.reset(seed=0, options={"start": [0.0, 0.0, 0.0], "goals": goals})
    task = env.unwrapped.task
    i = task.mission_offset
    assert env.observation_space.shape == (43 + 4 + 4 * 3,)
    x, y, yaw = info["pose"]
    # the target is the nearest goal, (0, 2): 2 m away, bearing +90 deg
    np.testing.assert_allclose(obs[i:i + 4], [2.0 / 10.0, 1.0, 0.0, 1.0], atol=2e-3)
    for slot, (gx, gy) in enumerate(goals):
        bearing = math.atan2(gy - y, gx - x) - yaw
        expected = [math.hypot(gx - x, gy - y) / 10.0, math.sin(bearing), math.cos(bearing), 1.0]
        np.testing.assert_allclose(obs[i + 4 + 4 * slot:i + 8 + 4 * slot], expected, atol=1e-5)
    env.close()


def test_mission_step_limit_scales_with_the_goals():
    env = _mission("fixed", k=2, steps_per_goal=5)
    env.reset(seed=0, options={"start": [0.0, 0.0, 0.0], "goals": [[3.0, 0.0], [3.0, 3.0]]})
    steps = 0
    while True:
        _, _, terminated, truncated, info = env.step(np.zeros(2, dtype=np.float32))
        steps += 1
        if terminated or truncated or steps >= 20:
            break
    assert (steps, truncated, info["end_reason"]) == (10, True, "time_limit")
    env.close()


def test_sampled_missions_are_connected_and_apart():
    env = gym.make("bulletnav/WarehouseMission-v0")
    for seed in range(5):
        _, info = env.reset(seed=seed)
        pts = [tuple(info["pose"][:2]), *info["goals"]]
        assert len(info["goals"]) == 3
        assert all(math.dist(a, b) >= 1.5 for k, a in enumerate(pts) for b in pts[k + 1:])
        free = env.unwrapped._scene.free_space
        assert all(free.reachable(pts[0], g) for g in info["goals"])
        # Against outside references: SciPy's connected components of the free grid join the
        # start to every goal, and Shapely puts each goal clear of every footprint and wall.
        layout, cfg = env.unwrapped.scene.layout, env.unwrapped.config.sampler
        assert all(_reachable_independent(layout, pts[0], g, cfg) for g in info["goals"])
        assert _shapely_clearance(layout_to_dict(layout), np.array(pts)).min() >= cfg.clearance - 0.04  # up to the grid
    env.close()


def test_bad_mission_input_is_refused_with_the_value():
    env = gym.make("bulletnav/Warehouse-v0", world=HALL, task_name="mission", goals=2)
    with pytest.raises(ValueError, match=r"\[-2.0, 0.0\] lies inside obstacle"):
        env.reset(seed=0, options={"goals": [[-2.0, 0.0], [3.0, 1.0]]})
    with pytest.raises(ValueError, match=r"\[9.0, 0.0\] lies outside the floor"):
        env.reset(seed=0, options={"goals": [[9.0, 0.0], [3.0, 1.0]]})
    with pytest.raises(ValueError, match="has 1 goals but the env was made with goals=2"):
        env.reset(seed=0, options={"goals": [[3.0, 1.0]]})
    # The refusals agree with Shapely on the hall's own geometry: (-2, 0) inside a footprint,
    # (9, 0) off the floor; two goals Shapely puts clear of everything are taken as given.
    data = layout_to_dict(env.unwrapped.scene.layout)
    hx, hy = data["size"][0] / 2, data["size"][1] / 2
    assert _shapely_clearance(data, np.array([[-2.0, 0.0]]))[0] == 0.0
    assert not shapely.box(-hx, -hy, hx, hy).contains(shapely.Point(9.0, 0.0))
    good = [[3.0, 1.0], [-3.0, -2.0]]
    assert _shapely_clearance(data, np.array(good)).min() > 0.5
    _, info = env.reset(seed=0, options={"goals": good})
    assert [list(g) for g in info["goals"]] == good
    env.close()
    with pytest.raises(ValueError, match=r"task goals = 9 exceeds the limit 8 \(raise it with BULLETNAV_MAX_GOALS\)"):
        gym.make("bulletnav/Warehouse-v0", task_name="mission", goals=9)
    with pytest.raises(ValueError, match="goal_order must be 'fixed' or 'free', got 'shortest'"):
        gym.make("bulletnav/Warehouse-v0", task_name="mission", goal_order="shortest")


def test_mission_env_passes_the_checkers():
    from gymnasium.utils.env_checker import check_env

    env = gym.make("bulletnav/WarehouseMission-v0")
    check_env(env.unwrapped, skip_render_check=True)
    env.close()


def test_yaml_goals_are_the_missions_goals_and_bad_ones_are_refused(tmp_path):
    import yaml

    from bulletnav.errors import LayoutError
    from bulletnav.sim.layout import load_layout

    path = tmp_path / "m.yaml"
    path.write_text(yaml.safe_dump({"size": [10.0, 10.0], "obstacles": [], "start": [0.0, 0.0, 0.0],
                                    "goals": [[3.0, 0.0], [0.0, 3.0]]}))
    env = gym.make("bulletnav/Warehouse-v0", world=str(path), task_name="mission", goals=2, goal_order="fixed")
    _, info = env.reset(seed=0)
    assert info["goals"] == ((3.0, 0.0), (0.0, 3.0)) and info["goal"] == (3.0, 0.0)
    env.close()
    path.write_text(yaml.safe_dump({"size": [10.0, 10.0], "obstacles": [], "goals": [[3.0, 0.0], [7.0, 0.0]]}))
    with pytest.raises(LayoutError, match=r"m.yaml: field 'goals\[1\]' \[7.0, 0.0\] lies outside the floor"):
        load_layout(path)
