"""The multi-robot fleet (``bulletnav.fleet``): PettingZoo API, spaces equal to the single-robot
env's, determinism, the lidar seeing other robots, collisions, errands, bad arguments, and a
shipped single-robot policy running zero-shot on every robot."""

from __future__ import annotations

import hashlib
import json
import math
import re
import subprocess
import sys
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import yaml
from pettingzoo.test import api_test, parallel_api_test

import bulletnav  # noqa: F401 (registers the single-robot ids)
from bulletnav.errors import BulletnavError, ConfigError, SamplingError
from bulletnav.fleet import fleet_v0

ROOT = Path(__file__).resolve().parent.parent
EMPTY = str(ROOT / "bulletnav" / "assets" / "worlds" / "empty.yaml")
ROOM_STATIONS = {"pick_stations": [(2.0, 3.0), (-2.0, 3.0)], "drop_stations": [(3.0, -3.5), (-3.0, -3.5)]}
"""Stations for the empty 10 x 10 m room (it has no racks to derive them from)."""


@pytest.fixture
def room(tmp_path):
    """A 10 x 8 m room with one rack and its stations named in the file."""
    path = tmp_path / "room.yaml"
    path.write_text(yaml.safe_dump({
        "name": "room", "size": [10.0, 8.0],
        "obstacles": [{"type": "box", "center": [0.0, 2.0], "size": [4.0, 1.0, 2.0], "label": "rack"}],
        "stations": {"pick": [[0.0, 0.9], [1.5, 3.1]], "drop": [[-4.0, -3.0], [4.0, -3.0]]},
    }))
    return str(path)


def _zero(env):
    return {a: np.zeros(2, dtype=np.float32) for a in env.agents}


def _teleport(env, index, pose):
    env._scene.robots[index].reset_pose(pose)  # test-only reach into the scene


# ------------------------------------------------------------------ PettingZoo API
def test_parallel_api():
    env = fleet_v0.parallel_env(num_robots=2, duration_s=2.0)
    try:
        parallel_api_test(env, num_cycles=60)  # 48 steps: the episode ends inside the test
    finally:
        env.close()


def test_aec_api():
    env = fleet_v0.env(num_robots=2, duration_s=1.0)
    try:
        api_test(env, num_cycles=30)
    finally:
        env.close()


def test_agents_and_truncation_together():
    env = fleet_v0.parallel_env(num_robots=3, duration_s=0.5)
    obs, infos = env.reset(seed=3)
    assert env.agents == ["robot_0", "robot_1", "robot_2"] and set(obs) == set(infos) == set(env.agents)
    steps = 0
    while env.agents:
        obs, rewards, terms, truncs, infos = env.step(_zero(env))
        steps += 1
        assert not any(terms.values())
        assert len(set(truncs.values())) == 1  # all together
    assert steps == 12 and all(truncs.values())  # 0.5 s at 24 Hz
    env.close()


# ------------------------------------------------------------------ spaces
@pytest.mark.parametrize("kwargs, single_id", [
    ({}, "bulletnav/WarehouseAisles-v0"),
    ({"guidance": "floorplan", "normalize_actions": True, "lidar_rays": 24}, "bulletnav/WarehouseAisles-v0"),
])
def test_spaces_equal_single_robot(kwargs, single_id):
    single = gym.make(single_id, **kwargs)
    env = fleet_v0.parallel_env(num_robots=2, duration_s=1.0, **kwargs)
    try:
        for agent in env.possible_agents:
            assert env.observation_space(agent) == single.observation_space
            assert env.action_space(agent) == single.action_space
        obs, infos = env.reset(seed=1)
        assert all(single.observation_space.contains(o) for o in obs.values())
        # against the documented layout (the env's observation table), by hand: lidar_rays + 7
        # entries, 3 more with floor-plan guidance; actions (v m/s, w rad/s) in [0, 0.5] x [-1.5, 1.5]
        # or [-1, 1]^2 normalized
        rays = kwargs.get("lidar_rays", 36)
        extra = 3 if kwargs.get("guidance") == "floorplan" else 0
        space = env.observation_space("robot_0")
        assert space.shape == (rays + 7 + extra,)
        low, high = ([-1.0, -1.0], [1.0, 1.0]) if kwargs.get("normalize_actions") else ([0.0, -1.5], [0.5, 1.5])
        assert np.allclose(env.action_space("robot_0").low, low) and np.allclose(env.action_space("robot_0").high, high)
        for agent, o in obs.items():  # entries 36 and 42 recomputed from the robot's pose and goal
            x, y, yaw = infos[agent]["pose"]
            gx, gy = infos[agent]["goal"]
            heading = math.remainder(math.atan2(gy - y, gx - x) - yaw, 2 * math.pi)
            assert o[rays] == pytest.approx(heading / math.pi, abs=1e-5)
            assert o[rays + 6] == pytest.approx(min(math.hypot(gx - x, gy - y) / 10.0, 3.0), abs=1e-5)
            assert ((o[:rays] >= 0.0) & (o[:rays] <= 1.0)).all()
    finally:
        env.close()
        single.close()



@pytest.mark.parametrize("normalize", [False, True])
def test_each_robot_maps_actions_as_the_single_robot_env_does(normalize):
    """The fleet's action map is the single-robot env's: the same (v, w) for in-range,
    out-of-range and integer actions, and the same error for a bad one."""
    single = gym.make("bulletnav/WarehouseAisles-v0", normalize_actions=normalize).unwrapped
    env = fleet_v0.parallel_env(num_robots=2, duration_s=1.0, normalize_actions=normalize)
    try:
        # hand values: physical actions clipped to v in [0, 0.5] m/s, w in [-1.5, 1.5] rad/s;
        # normalized ones mapped linearly from [-1, 1] onto those ranges first
        expected = ([(0.325, -1.05), (0.5, -1.5), (0.5, 0.0), (0.3125, 1.5)] if normalize else
                    [(0.3, -0.7), (0.5, -1.5), (0.5, 0.0), (0.25, 1.25)])
        for action, want in zip((np.array([0.3, -0.7], np.float32), np.array([9.0, -9.0]), [1, 0], (0.25, 1.25)),
                                expected):
            assert env.command(action) == single.command(action)
            assert env.command(action) == pytest.approx(want, abs=1e-6)
        for bad in (np.array([np.nan, 0.0]), [0.1], {"v": 1}):
            with pytest.raises(ValueError) as theirs:
                single.command(bad)
            with pytest.raises(ValueError, match=re.escape(str(theirs.value))):
                env.command(bad)
    finally:
        env.close()
        single.close()

# ------------------------------------------------------------------ determinism
def rollout_hash(seed: int = 7, steps: int = 48) -> str:
    """SHA-256 of every observation, reward and info of a seeded dynamic 3-robot rollout."""
    env = fleet_v0.parallel_env(num_robots=3, duration_s=steps / 24, dynamic=True)
    actions = np.random.default_rng(seed).uniform([0.0, -1.5], [0.5, 1.5], (steps, 3, 2)).astype(np.float32)
    h = hashlib.sha256()

    def feed(obs, infos, rewards=None):
        for a in sorted(obs):
            h.update(obs[a].tobytes())
            h.update(json.dumps(infos[a], sort_keys=True, default=lambda x: np.asarray(x).tolist()).encode())
            if rewards is not None:
                h.update(repr(rewards[a]).encode())

    obs, infos = env.reset(seed=seed)
    feed(obs, infos)
    for t in range(steps):
        obs, rewards, _, _, infos = env.step({a: actions[t, i] for i, a in enumerate(env.possible_agents)})
        feed(obs, infos, rewards)
    env.close()
    return h.hexdigest()


def test_same_seed_same_episode_here_and_in_a_fresh_process():
    first = rollout_hash()
    assert rollout_hash() == first
    code = f"import sys; sys.path.insert(0, {str(ROOT / 'tests')!r}); from test_fleet import rollout_hash; print(rollout_hash())"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True, cwd=ROOT)
    assert out.stdout.strip().splitlines()[-1] == first
    assert rollout_hash(seed=8) != first


# ------------------------------------------------------------------ lidar
def test_lidar_sees_other_robot_not_itself():
    env = fleet_v0.parallel_env(num_robots=2, world=EMPTY, **ROOM_STATIONS)
    try:
        env.reset(seed=0)
        scene = env._scene
        geometry = scene.geometry
        back = min(r.cx - r.half_x for r in geometry.rectangles)   # rear face of the body (m, body frame)
        front = max(r.cx + r.half_x for r in geometry.rectangles)
        _teleport(env, 0, (-2.0, 0.0, 0.0))
        _teleport(env, 1, (0.0, 0.0, 0.0))
        env.step(_zero(env))
        r0, r1 = scene.robots[0].state, scene.robots[1].state
        lidar0, lidar1 = scene.sensors[0].lidar, scene.sensors[1].lidar
        ahead = float(lidar0.read()[0])  # ray 0: straight ahead
        expected = (r1.x + back) - lidar0.origin()[0]
        assert abs(ahead - expected) < 0.015, (ahead, expected)
        behind = int(np.argmin(np.abs(np.abs(lidar1.angles) - math.pi)))  # robot 1 looks back at robot 0
        expected_back = lidar1.origin()[0] - (r0.x + front)
        assert abs(float(lidar1.read()[behind]) - expected_back) < 0.015
        # alone in the open: no ray of either robot hits its own body
        _teleport(env, 1, (3.0, 3.0, 0.0))
        env.step(_zero(env))
        assert float(scene.sensors[0].lidar.read().min()) > 2.5  # walls >= 3 m away, robot 1 out of the way
    finally:
        env.close()


# ------------------------------------------------------------------ collisions
def test_robot_robot_collision_stops_both_and_episode_goes_on():
    env = fleet_v0.parallel_env(num_robots=2, world=EMPTY, collision_penalty_s=1.0, duration_s=6.0, **ROOM_STATIONS)
    try:
        env.reset(seed=0)
        _teleport(env, 0, (-0.6, -1.0, 0.0))
        _teleport(env, 1, (0.6, -1.0, math.pi))
        forward = {a: np.array([0.5, 0.0], dtype=np.float32) for a in env.possible_agents}
        hit_at = None
        for t in range(72):
            _, rewards, terms, truncs, infos = env.step(forward)
            if infos["robot_0"]["collisions_robot"]:
                hit_at = t
                break
        assert hit_at is not None, "the robots never met"
        for a in env.possible_agents:
            assert infos[a]["collisions_robot"] == 1 and infos[a]["collision_with"] == "robot"
            assert infos[a]["reward_collision"] == env.config.task.reward.collision
            assert infos[a]["collisions_static"] == infos[a]["collisions_mover"] == infos[a]["collisions_person"] == 0
            assert infos[a]["stopped_s"] == pytest.approx(1.0)
        poses = [infos[a]["pose"].copy() for a in env.possible_agents]
        for _ in range(24):  # 1 s of penalty: the actions (full speed ahead) are ignored
            _, _, terms, truncs, infos = env.step(forward)
            assert not any(terms.values()) and not any(truncs.values())
        for a, before in zip(env.possible_agents, poses):
            assert np.hypot(*(infos[a]["pose"][:2] - before[:2])) < 0.02
            assert infos[a]["stopped_s"] == 0.0 and infos[a]["collisions_robot"] == 1  # touching still: not counted again
        turn = {a: np.array([0.0, 1.5], dtype=np.float32) for a in env.possible_agents}
        _, _, _, _, infos = env.step(turn)
        assert env.agents == env.possible_agents  # the episode goes on
    finally:
        env.close()


# ------------------------------------------------------------------ errands
def test_errand_completes_pick_then_drop_and_next_is_assigned(room):
    env = fleet_v0.parallel_env(num_robots=2, world=room)
    try:
        _, infos = env.reset(seed=2)
        assert env.stations.pick == ((0.0, 0.9), (1.5, 3.1)) and env.stations.dock_wall == "named"
        errand = infos["robot_0"]["errand"]
        assert errand["leg"] == "pick" and infos["robot_0"]["goal"] == errand["pick"]
        _teleport(env, 0, (*errand["pick"], 0.0))
        _, rewards, _, _, infos = env.step(_zero(env))
        info = infos["robot_0"]
        assert info["legs_completed"] == 1 and info["errands_completed"] == 0
        assert info["errand"]["leg"] == "drop" and info["errand"]["id"] == errand["id"]
        assert info["goal"] == errand["drop"] and info["reward_goal"] == env.config.task.reward.goal
        _teleport(env, 0, (*errand["drop"], 0.0))
        _, _, _, _, infos = env.step(_zero(env))
        info = infos["robot_0"]
        assert info["errands_completed"] == 1 and info["legs_completed"] == 2
        assert info["errand"]["leg"] == "pick" and info["errand"]["id"] == 2  # errands 0 and 1 went out at reset
        assert info["goal"] == info["errand"]["pick"] and info["goal"] in env.stations.pick
        assert infos["robot_1"]["errands_completed"] == 0
    finally:
        env.close()


def test_stations_derived_from_an_aisle_warehouse():
    env = fleet_v0.parallel_env(num_robots=4, duration_s=1.0)
    try:
        _, infos = env.reset(seed=5)
        st = env.stations
        assert len(st.pick) >= 8 and len(st.drop) >= 3
        free = env._scene.free_space
        layout = env._scene.layout
        for pt in (*st.pick, *st.drop):
            assert free.reachable(st.pick[0], pt)
            assert float(layout.clearance(np.array(pt[0]), np.array(pt[1]))) > env.config.sampler.clearance
            assert _shapely_clearance(layout, pt) > env.config.sampler.clearance  # Shapely's distance, too
        poses = [infos[a]["pose"] for a in env.possible_agents]
        for i in range(4):
            assert free.reachable(tuple(poses[i][:2]), infos[f"robot_{i}"]["goal"])
            for j in range(i):
                assert np.hypot(*(poses[i][:2] - poses[j][:2])) >= 2 * env._scene.geometry.radius + 0.3 - 1e-9
    finally:
        env.close()


def test_dock_moves_in_where_racks_line_every_wall(tmp_path):
    """Racks along all four walls (procedural aisles draw such floors, e.g. seed 1015): no
    station fits 0.55 m from a wall, so the dock is the first free line farther in."""
    path = tmp_path / "lined.yaml"
    rack = {"type": "box", "label": "rack"}
    path.write_text(yaml.safe_dump({"name": "lined", "size": [10.0, 8.0], "obstacles": [
        {**rack, "center": [-4.6, 0.0], "size": [0.8, 8.0, 2.0]}, {**rack, "center": [4.6, 0.0], "size": [0.8, 8.0, 2.0]},
        {**rack, "center": [0.0, -3.6], "size": [10.0, 0.8, 2.0]}, {**rack, "center": [0.0, 3.6], "size": [10.0, 0.8, 2.0]},
        {**rack, "center": [0.0, 0.0], "size": [4.0, 1.0, 2.0]}]}))
    env = fleet_v0.parallel_env(num_robots=2, world=str(path), duration_s=1.0)
    try:
        env.reset(seed=0)
        st = env.stations
        # south and north hold as many; south is first. 0.55 + 3 x 0.25 m in: the first line 0.4 m clear of the rack
        assert st.dock_wall == "south" and len(st.drop) >= 3
        assert all(y == pytest.approx(-4.0 + 1.3) for _, y in st.drop)
        layout, free = env._scene.layout, env._scene.free_space
        for pt in st.drop:
            assert float(layout.clearance(np.array(pt[0]), np.array(pt[1]))) > env.config.sampler.clearance
            assert free.reachable(st.pick[0], pt)
    finally:
        env.close()


def test_procedural_floor_with_racks_on_every_wall_gets_a_dock():
    env = fleet_v0.parallel_env(num_robots=2, duration_s=1.0, dynamic=True)
    try:
        env.reset(seed=1015)  # raised "no drop stations" before the dock could move in
        assert len(env.stations.drop) >= 1
        # the dock is free floor: every drop station clear of every rack and wall by Shapely's distance
        layout = env._scene.layout
        assert sum(o.label == "rack" for o in layout.obstacles) >= 4
        for pt in env.stations.drop:
            assert _shapely_clearance(layout, pt) > env.config.sampler.clearance, pt
    finally:
        env.close()


def _shapely_clearance(layout, point) -> float:
    """Distance (m) from ``point`` to the nearest obstacle footprint or wall, by Shapely from the
    obstacles' documented centre, size and yaw (an independent reference for station clearance)."""
    from shapely import affinity
    from shapely.geometry import Point, box

    shapes = []
    for o in layout.obstacles:
        if o.kind == "cylinder":
            shapes.append(Point(o.center).buffer(o.radius, quad_segs=64))
        else:
            hx, hy = o.size[0] / 2, o.size[1] / 2
            rect = box(o.center[0] - hx, o.center[1] - hy, o.center[0] + hx, o.center[1] + hy)
            shapes.append(affinity.rotate(rect, o.yaw, origin=tuple(o.center), use_radians=True))
    hx, hy = layout.half_extents
    shapes.append(box(-hx, -hy, hx, hy).exterior)  # the walls' inner faces
    pt = Point(point)
    return min(pt.distance(s) for s in shapes)


# ------------------------------------------------------------------ bad arguments
@pytest.mark.parametrize("n", [0, 17, 2.5])
def test_num_robots_out_of_range(n):
    with pytest.raises(ConfigError, match="num_robots"):
        fleet_v0.parallel_env(num_robots=n)


def test_more_robots_than_fit(tmp_path):
    path = tmp_path / "closet.yaml"
    path.write_text(yaml.safe_dump({"size": [3.0, 3.0], "obstacles": []}))
    env = fleet_v0.parallel_env(num_robots=16, world=str(path), pick_stations=[(0.5, 0.5)], drop_stations=[(-0.5, -0.5)])
    try:
        with pytest.raises(SamplingError, match="num_robots=16"):
            env.reset(seed=0)
    finally:
        env.close()


def test_world_without_stations():
    env = fleet_v0.parallel_env(num_robots=2, world=EMPTY)
    try:
        with pytest.raises(ConfigError, match="no pick stations"):
            env.reset(seed=0)
    finally:
        env.close()
    env = fleet_v0.parallel_env(num_robots=2, world=EMPTY, pick_stations=[(0.0, 0.0)], drop_stations=[(0.0, 4.9)])
    try:
        with pytest.raises(ConfigError, match="drop_stations"):  # 0.1 m from the wall: not free floor
            env.reset(seed=0)
    finally:
        env.close()
    with pytest.raises(BulletnavError, match="task_name"):
        fleet_v0.parallel_env(num_robots=2, task_name="mission")


# ------------------------------------------------------------------ zero-shot single-robot policy
def test_shipped_dynamic_policy_runs_on_every_robot():
    from bulletnav.rl.io import load_model
    from bulletnav.rl.policy import SB3Policy

    model, meta, normalizer = load_model(ROOT / "models" / "ppo_dynamic.zip")
    kwargs = {k: v for k, v in meta["env_kwargs"].items() if k not in ("collision_terminates", "layouts_every")}
    env = fleet_v0.parallel_env(num_robots=3, duration_s=1.0, dynamic=True, **kwargs)
    try:
        assert env.observation_space("robot_0") == model.observation_space
        policy = SB3Policy(model, normalizer)
        obs, infos = env.reset(seed=11)
        policy.reset(infos["robot_0"])
        driven = dict.fromkeys(infos, 0.0)
        last = {a: infos[a]["pose"][:2].copy() for a in infos}
        while env.agents:
            actions = {a: policy.act(obs[a], infos[a]) for a in env.agents}
            obs, rewards, _, _, infos = env.step(actions)
            assert all(np.isfinite(r) for r in rewards.values())
            for a, info in infos.items():  # the driven length, summed here from the true poses step by step
                driven[a] += math.dist(last[a], info["pose"][:2])
                last[a] = info["pose"][:2].copy()
        assert all(info["path_length"] > 0.0 for info in infos.values())
        for a, info in infos.items():
            assert info["path_length"] == pytest.approx(driven[a], rel=1e-6, abs=1e-9), a
    finally:
        env.close()


def test_route_distance_follows_the_floor_plan_like_an_independent_a_star():
    """The deadlock metric's progress is measured along the floor plan: RouteDistance against
    the planner's A* (its own search) on the true map inflated by the robot's radius."""
    import math

    from bulletnav.fleet.metrics import RouteDistance
    from bulletnav.fleet.view import FleetView
    from bulletnav.planning.astar import astar_cost

    env = fleet_v0.parallel_env(num_robots=2, duration_s=5.0)
    try:
        _, infos = env.reset(seed=21)
        view = FleetView(env.unwrapped if hasattr(env, "unwrapped") else env)
        route = RouteDistance(view)
        grid = view.occupancy(0.1, view.geometry.radius)
        stations = env.unwrapped.stations if hasattr(env, "unwrapped") else env.stations
        rng = np.random.default_rng(0)
        pairs = 0
        for _ in range(12):
            a = stations.pick[rng.integers(len(stations.pick))]
            b = stations.drop[rng.integers(len(stations.drop))]
            ref = astar_cost(grid, a, b)
            if ref is None or not math.isfinite(ref):
                continue
            got = route((float(b[0]), float(b[1])), float(a[0]), float(a[1]))
            assert got >= math.dist(a, b) - 0.15  # never shorter than the straight line
            assert abs(got - ref) <= 0.05 * ref + 0.3, (a, b, got, ref)
            pairs += 1
        assert pairs >= 6
    finally:
        env.close()
