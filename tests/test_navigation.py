"""Whole episodes with the classical navigator, scored like the RL agents, and the CLI."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import pytest

import bulletnav  # noqa: F401
from bulletnav.cli import main
from bulletnav.config import asset_path
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.evaluation import run_episodes, shortest_path_length, summarize
from bulletnav.sim.layout import Layout, Obstacle


def test_shortest_path_matches_geometry():
    empty = Layout((10.0, 10.0))
    assert shortest_path_length(empty, (-3.0, 0.0), (3.0, 0.0)) == pytest.approx(6.0, abs=0.05)
    # A 4 m wall across the direct line: the detour around its end, for a 0.2 m disc, is
    # two straight legs past the corner (plus the disc's clearance at the corner).
    wall = Layout((10.0, 10.0), (Obstacle("box", (0.0, 0.0), size=(0.2, 4.0, 1.0)),))
    corner = (0.1 + 0.2, 2.0 + 0.2)
    expected = math.dist((-3.0, 0.0), (-0.3, 2.2)) + 0.6 + math.dist(corner, (3.0, 0.0))
    assert shortest_path_length(wall, (-3.0, 0.0), (3.0, 0.0)) == pytest.approx(expected, rel=0.03)


def test_pid_astar_navigates_procedural_warehouses(report):
    env = gym.make("bulletnav/Warehouse-v0")
    results = run_episodes(env, Navigator(NavigatorConfig(planner="astar")), episodes=6, seed=1000)
    env.close()
    summary = summarize(results)
    report("PID+A* on 6 episodes: success / collisions / SPL",
           f"{summary['success_rate']:.2f} / {summary['collision_rate']:.2f} / {summary['spl']:.3f}")
    assert summary["success_rate"] == 1.0 and summary["collision_rate"] == 0.0
    for r in results:
        # nobody beats the shortest path to the success disc (0.5 m around the goal)
        assert r.shortest_path - 0.5 <= r.path_length + 0.05
        assert 0.0 < r.spl <= 1.0
        assert r.plan_ms and max(r.plan_ms) < 50


@pytest.mark.parametrize("planner", ["none", "rrt"])
def test_other_planners_run_episodes(planner):
    env = gym.make("bulletnav/Warehouse-v0", world=str(asset_path("worlds", "hall.yaml")))
    results = run_episodes(env, Navigator(NavigatorConfig(planner=planner)), episodes=2, seed=0)
    env.close()
    assert len(results) == 2
    assert all(r.steps > 0 for r in results)
    assert (len(results[0].plan_ms) > 0) == (planner != "none")


def test_odometry_pose_source_navigates_an_empty_room():
    env = gym.make("bulletnav/Warehouse-v0", world=str(asset_path("worlds", "empty.yaml")))
    results = run_episodes(env, Navigator(NavigatorConfig(planner="astar", pose_source="odometry")), 2, seed=3)
    env.close()
    assert all(r.success for r in results)


def test_navigate_cli_json(capsys):
    assert main(["navigate", "--planner", "astar", "--episodes", "2", "--seed", "1000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("episodes", "success_rate", "collision_rate", "mean_length", "spl", "plan_ms_median",
                "plan_ms_p95", "per_episode"):
        assert key in out
    assert out["episodes"] == 2 and len(out["per_episode"]) == 2
    assert main(["navigate", "--planner", "none", "--episodes", "1", "--world",
                 str(asset_path("worlds", "aisles.yaml"))]) == 0
    text = capsys.readouterr().out
    assert "episode   1/1 seed 0" in text and "success rate" in text


def test_navigate_cli_bad_world(tmp_path, capsys):
    bad = tmp_path / "bad.yaml"
    bad.write_text("size: [10, 10]\nobstacles:\n  - {type: box, center: [0, 0]}\n")
    assert main(["navigate", "--world", str(bad), "--episodes", "1"]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "obstacles[0].size" in err
