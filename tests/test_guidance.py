"""Floor-plan path guidance: costs against geometry and an independent shortest path, the
lookahead point, the progress term along the path, guided mission order, and bad input."""

from __future__ import annotations

import itertools
import math

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import bulletnav  # noqa: F401
from bulletnav.config import SamplerConfig, asset_path
from bulletnav.sim.sampler import FreeSpace

EMPTY = str(asset_path("worlds", "empty.yaml"))


@pytest.fixture
def wall_world(tmp_path):
    """A 10 x 10 m room split by a 6 m rack across its middle (x in [-3, 3], y in [-0.3, 0.3])."""
    path = tmp_path / "wall.yaml"
    path.write_text("name: wall\nsize: [10.0, 10.0]\nobstacles:\n"
                    "  - {type: box, center: [0.0, 0.0], size: [6.0, 0.6, 2.0], yaw: 0.0, label: rack}\n")
    return str(path)


def _guided(world, **kw):
    return gym.make("bulletnav/Warehouse-v0", world=world, guidance="floorplan", **kw)


@pytest.mark.parametrize("start, goal", [((-2.0, 0.0, 0.0), (2.0, 0.0)), ((-2.0, -2.0, 0.0), (2.0, 2.0))])
def test_in_open_floor_the_path_cost_is_the_straight_distance(start, goal):
    env = _guided(EMPTY)
    obs, _ = env.reset(seed=0, options={"start": list(start), "goal": list(goal)})
    task = env.unwrapped.task
    straight = math.dist(start[:2], goal)
    # octile steps are exact along axes and diagonals; the ends sit within half a cell of centres
    assert straight <= task.path_cost + 1e-9 <= straight + 0.15
    # the lookahead point lies on the segment toward the goal, 0.8 m (8 cells) ahead
    lx, ly = task.lookahead
    ahead = math.dist(start[:2], (lx, ly))
    assert 0.6 <= ahead <= 1.25
    bearing = math.atan2(goal[1] - start[1], goal[0] - start[0])
    assert abs(math.remainder(math.atan2(ly - start[1], lx - start[0]) - bearing, 2 * math.pi)) < 0.1
    # observation: the guidance block is the last three entries
    assert obs.shape == (46,)
    np.testing.assert_allclose(obs[-3:], [task.path_cost / 10.0, math.sin(bearing), math.cos(bearing)], atol=0.1)
    env.close()


def test_behind_a_rack_the_path_goes_around_it(wall_world):
    env = _guided(wall_world)
    _, info = env.reset(seed=0, options={"start": [0.0, -2.0, math.pi / 2], "goal": [0.0, 2.0]})
    task, scene = env.unwrapped.task, env.unwrapped.scene
    r = scene.geometry.radius
    # any path for the robot's disc passes a point with |x| >= 3 + r on the rack's line
    lower = 2.0 * math.hypot(3.0 + r, 2.0)
    assert task.path_cost >= lower
    # and is no shorter than the unweighted shortest path on the same free space (scipy Dijkstra)
    free = FreeSpace.build(scene.layout, SamplerConfig(), r)
    unweighted = free.path_lengths(free.cell((0.0, 2.0)))[free.cell((0.0, -2.0))]
    assert task.path_cost >= unweighted - 0.15
    assert task.path_cost <= 1.6 * unweighted  # wall costs bend the path, they do not double it
    # the lookahead point leads sideways along the rack, not through it
    lx, ly = task.lookahead
    assert ly < -0.3 - r and abs(lx) > 0.4
    env.close()


def test_progress_term_telescopes_to_the_drop_in_path_cost(wall_world):
    env = _guided(wall_world)
    _, info = env.reset(seed=0, options={"start": [-1.0, -2.0, 0.0], "goal": [0.0, 2.0]})
    task = env.unwrapped.task
    first = task.path_cost
    # by geometry: a path for the robot's disc from (-1, -2) to (0, 2) passes one end of the rack
    # (|x| >= 3 + r on its line), so it is no shorter than the two legs via the nearer end
    r = env.unwrapped.scene.geometry.radius
    lower = min(math.dist((-1.0, -2.0), (e, 0.0)) + math.dist((e, 0.0), (0.0, 2.0)) for e in (-3.0 - r, 3.0 + r))
    assert lower <= first <= 1.6 * lower
    weight = task.reward_weights.progress
    total = 0.0
    rng = np.random.default_rng(0)
    for _ in range(120):
        _, _, terminated, truncated, info = env.step(np.array([0.4, rng.uniform(-1.0, 1.0)]))
        total += info["reward_progress"]
        if terminated or truncated:
            break
    assert total / weight == pytest.approx(first - task.path_cost, abs=1e-9)
    assert first - task.path_cost != 0.0
    # the remaining cost is never below the straight line from where the robot ended up
    x, y, _ = info["pose"]
    assert task.path_cost >= math.dist((x, y), (0.0, 2.0)) - 0.15
    env.close()


def _follow(obs):
    """Steer to the lookahead point (the last three observation entries), slowing to turn."""
    bearing = math.atan2(obs[-2], obs[-1])
    return np.array([0.5 * max(0.0, math.cos(bearing)) ** 4, float(np.clip(2.0 * bearing, -1.5, 1.5))])


@pytest.mark.slow
def test_a_blind_guide_follower_completes_aisle_missions():
    """Nothing but the guidance entries (no lidar): the path keeps clear of the racks by itself."""
    from shapely import affinity
    from shapely.geometry import box
    from shapely.ops import unary_union

    env = gym.make("bulletnav/WarehouseMission-v0", guidance="floorplan")
    rects = env.unwrapped.scene.geometry.rectangles
    body = unary_union([box(r.cx - r.half_x, r.cy - r.half_y, r.cx + r.half_x, r.cy + r.half_y) for r in rects])
    done = 0
    for seed in range(4):
        obs, info = env.reset(seed=7000 + seed)
        layout = env.unwrapped.scene.layout
        racks = unary_union([affinity.rotate(box(o.center[0] - o.size[0] / 2, o.center[1] - o.size[1] / 2,
                                                 o.center[0] + o.size[0] / 2, o.center[1] + o.size[1] / 2),
                                             o.yaw, origin=tuple(o.center), use_radians=True)
                             for o in layout.obstacles if o.kind == "box"])
        closest = math.inf
        while True:
            obs, _, terminated, truncated, info = env.step(_follow(obs[:46]))
            # Shapely: the robot's outline, placed at its true pose, against the racks' footprints
            x, y, yaw = info["pose"]
            outline = affinity.translate(affinity.rotate(body, yaw, origin=(0, 0), use_radians=True), x, y)
            closest = min(closest, outline.distance(racks))
            if terminated or truncated:
                break
        done += info["goals_reached"] == 3
        if info["goals_reached"] == 3:  # a completed mission never touched a rack
            assert closest > 0.0 and not info["collision"], (seed, closest)
    assert done >= 3
    env.close()


def test_guided_free_missions_follow_the_exact_tour_on_the_path_costs():
    env = gym.make("bulletnav/WarehouseMission-v0", guidance="floorplan", goals=4)
    for seed in range(3):
        _, info = env.reset(seed=seed)
        task, scene = env.unwrapped.task, env.unwrapped.scene
        start, goals = scene.start[:2], task.goals
        points = [start, *goals]

        cost = [[task.guide.query(j, *points[a])[0] for j in range(4)] for a in range(5)]
        best = min(itertools.permutations(range(4)),
                   key=lambda p, c=cost: c[0][p[0]] + sum(c[p[i] + 1][p[i + 1]] for i in range(3)))
        assert task.plan == best
        assert info["goal"] == goals[best[0]]
    env.close()


def test_guidance_off_keeps_the_observation_and_checkers_pass_with_it_on():
    plain = gym.make("bulletnav/Warehouse-v0", normalize_actions=True)
    guided = gym.make("bulletnav/Warehouse-v0", guidance="floorplan", normalize_actions=True)
    a, _ = plain.reset(seed=3)
    b, _ = guided.reset(seed=3)
    assert a.shape == (43,) and b.shape == (46,)
    np.testing.assert_array_equal(a, b[:43])
    check_env(guided.unwrapped, skip_render_check=True)
    sb3_check_env(gym.make("bulletnav/WarehouseMission-v0", guidance="floorplan", normalize_actions=True))
    plain.close()
    guided.close()


def test_an_unknown_guidance_is_refused_by_name():
    with pytest.raises(ValueError, match="guidance must be 'none' or 'floorplan', got 'map'"):
        gym.make("bulletnav/Warehouse-v0", guidance="map")
