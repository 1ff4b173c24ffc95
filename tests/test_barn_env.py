"""``bulletnav/BARN-v0``: BARN's worlds, start, goal, clock, end rules and score in PyBullet.

References: BARN's world files and path files (tests/data/barn/, read here with the test's own
regex and numpy.load), the numbers of BARN's run.py (start, goal, 0.1 m, 1 m, 100 s, 2 m/s,
clip 2-8 t_opt) written here by hand, and PyBullet's own reports of bodies and contacts."""

from __future__ import annotations

import gzip
import math
import re
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from gymnasium.utils.env_checker import check_env

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.errors import LayoutError

DATA = Path(__file__).resolve().parent / "data" / "barn"
POSE = re.compile(r"<model name='unit_cylinder_\d+'>\s*<static>1</static>\s*<pose frame=''>([-\d.]+) ([-\d.]+) ")
START, GOAL = (-2.25, 3.0, 1.57), (-2.25, 13.0)  # run.py lines 46-47 (goal = start + (0, 10))


def _centres(i: int) -> np.ndarray:
    text = gzip.decompress((DATA / f"world_{i}.world.gz").read_bytes()).decode()
    return np.array([[float(x), float(y)] for x, y in POSE.findall(text)])


def _t_opt(i: int) -> float:
    # run.py lines 19-27 and 172-185, written out again here
    cells = np.load(DATA / f"path_{i}.npy", allow_pickle=False).astype(float)
    pts = np.vstack([START[:2], np.column_stack([cells[:, 0] * 0.15 - 4.575, cells[:, 1] * 0.15 + 5.075]), GOAL])
    return float(np.sum(np.hypot(*np.diff(pts, axis=0).T))) / 2.0


def _cylinders(env) -> dict[int, tuple[float, float, float]]:
    """Every body whose one shape is a cylinder of BARN's size: id -> position (the rays and contacts
    of the tests show the collision shapes are there too). Bodies
    made in a batch are missing from PyBullet's getNumBodies, so every id below the robot's (loaded
    last) is asked."""
    cid, out = env.unwrapped.scene.client, {}
    for body in range(env.unwrapped.scene.robot_body):
        shapes = p.getVisualShapeData(body, physicsClientId=cid)  # (static rigid bodies report no collision shape data)
        if len(shapes) == 1 and shapes[0][2] == p.GEOM_CYLINDER and shapes[0][3][:2] == pytest.approx((1.0, 0.075)):
            out[body] = p.getBasePositionAndOrientation(body, physicsClientId=cid)[0]
    return out


@pytest.fixture
def env():
    e = gym.make("bulletnav/BARN-v0", world_idx=0)
    yield e
    e.close()


def test_cylinders_stand_where_the_world_file_puts_them(env):
    env.reset(seed=0)
    cid = env.unwrapped.scene.client
    cylinders = _cylinders(env)
    got = np.array(list(cylinders.values()))
    assert got.shape == (209, 3)
    np.testing.assert_allclose(np.sort(got[:, :2], axis=0), np.sort(_centres(0), axis=0), atol=1e-9)
    np.testing.assert_allclose(got[:, 2], 0.5)  # 1 m tall, standing on the floor
    # a ray along a row of cylinders stops at the first one's surface, 0.075 m from its centre
    x0, y0 = _centres(0)[0]
    hit = p.rayTest([x0 + 1.0, y0, 0.3], [x0 - 1.0, y0, 0.3], physicsClientId=cid)[0]
    assert hit[0] in cylinders and hit[3][0] == pytest.approx(x0 + 0.075, abs=1e-6)


def test_start_goal_clock_success_and_score_follow_run_py(env):
    # world 93: no cylinder within 1.05 m of the line x = -2.25 north of the start (a scan of all 300 worlds)
    obs, info = env.reset(seed=1, options={"world_idx": 93})
    assert tuple(info["pose"]) == pytest.approx(START, abs=1e-9) and info["goal"] == GOAL
    assert info["barn_time_s"] == 0.0 and "barn_metric" not in info
    dt = env.unwrapped.config.physics.control_dt
    steps, started_at, poses = 0, None, []
    while True:  # full speed north
        obs, r, terminated, truncated, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
        steps += 1
        poses.append(info["pose"][:2].copy())
        if started_at is None and math.dist(poses[-1], START[:2]) >= 0.1:
            started_at = steps * dt
        if terminated or truncated:
            break
    assert (terminated, truncated, info["end_reason"], info["is_success"]) == (True, False, "success", True)
    assert math.dist(poses[-1], GOAL) <= 1.0 < math.dist(poses[-2], GOAL)
    assert info["barn_time_s"] == pytest.approx(steps * dt - started_at, abs=1e-9)
    t, t_opt = info["barn_time_s"], _t_opt(93)
    assert info["barn_metric"] == pytest.approx(t_opt / min(max(t, 2 * t_opt), 8 * t_opt), rel=1e-12)


def test_any_contact_ends_in_a_collision_with_no_score(env):
    # facing the bottom row of cylinders (y = 0.075) from 0.6 m above it
    env.reset(seed=2, options={"start": (-2.25, 0.6, -1.57)})
    for _ in range(200):
        obs, r, terminated, truncated, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
        if terminated or truncated:
            break
    cid, u = env.unwrapped.scene.client, env.unwrapped
    cylinders = _cylinders(env)
    contacts = [c for c in p.getContactPoints(bodyA=u.scene.robot_body, physicsClientId=cid) if c[2] in cylinders]
    assert (terminated, info["end_reason"], info["is_success"], info["barn_metric"]) == (True, "collision", False, 0.0)
    assert contacts and info["pose"][1] < 0.6


def test_time_limit_counts_from_the_first_tenth_of_a_metre():
    # 100 s simulated at 8 control steps a second and 96 Hz physics: the rule, not the driving, is checked
    env = gym.make("bulletnav/BARN-v0", world_idx=0, physics="fast", control_hz=8)
    env.reset(seed=3)
    dt = env.unwrapped.config.physics.control_dt
    steps = 0
    while True:  # creep until BARN's clock runs, then stand still
        moving = env.unwrapped.task.clock_start_s is None
        obs, r, terminated, truncated, info = env.step(np.array([0.2 if moving else 0.0, 0.0], dtype=np.float32))
        steps += 1
        if terminated or truncated:
            break
    start_s = env.unwrapped.task.clock_start_s
    assert (terminated, truncated, info["end_reason"], info["barn_metric"]) == (False, True, "timeout", 0.0)
    assert info["barn_time_s"] >= 100.0 > info["barn_time_s"] - dt
    assert steps * dt == pytest.approx(start_s + info["barn_time_s"], abs=1e-9)
    assert start_s > 0.1 / 0.2 - dt  # 0.1 m at <= 0.2 m/s cannot take less
    env.close()


def test_world_index_by_make_and_by_reset_and_bad_ones_named(env):
    _, info = env.reset(options={"world_idx": 299})
    assert info["world_idx"] == 299 and env.unwrapped.world_idx == 299
    assert len(env.unwrapped.scene.layout.obstacles) == len(_centres(299))
    assert env.unwrapped.task.t_opt == pytest.approx(_t_opt(299), rel=1e-12)
    for bad in (300, -1, "7"):
        with pytest.raises(LayoutError, match=re.escape(repr(bad))):
            env.reset(options={"world_idx": bad})
        with pytest.raises(LayoutError, match=re.escape(repr(bad))):
            gym.make("bulletnav/BARN-v0", world_idx=bad)
    assert env.unwrapped.world_idx == 299  # a refused index leaves the world as it was
    for kwargs in ({"world": "x.yaml"}, {"task_name": "navigation"}):
        with pytest.raises(TypeError, match=f"not {next(iter(kwargs))}="):
            gym.make("bulletnav/BARN-v0", **kwargs)


def test_barn_refuses_keywords_that_change_its_rules_and_defaults_to_a_training_world():
    """A 0.5 m goal radius let an episode end at BARN's 1 m and 'succeed' without the goal bonus;
    now every keyword that would change BARN's rules is refused unless it says BARN's value, and
    those that draw a warehouse are refused; the default world is 1, not test world 0."""
    from bulletnav.barn.data import TEST_WORLDS

    for key, value in (("goal_radius", 0.5), ("collision_terminates", False), ("goals", 3), ("forklifts", (1, 2)),
                       ("workers", [0, 1]), ("pallet_events_per_min", 2.0), ("goal_order", "fixed")):
        with pytest.raises(TypeError, match=f"keeps BARN's rules: {key}="):
            gym.make("bulletnav/BARN-v0", **{key: value})
    for key, value in (("num_obstacles", 10), ("world_size", 12.0), ("steps_per_goal", 100)):
        with pytest.raises(TypeError, match=f"runs BARN's worlds, start and goal: {key}="):
            gym.make("bulletnav/BARN-v0", **{key: value})
    from bulletnav.envs.warehouse import make_config

    for config in (make_config(None, goals=3), make_config(None, forklifts=(1, 2))):  # a whole config keeps the rules too
        with pytest.raises(TypeError, match="keeps BARN's rules"):
            gym.make("bulletnav/BARN-v0", config=config)
    same = gym.make("bulletnav/BARN-v0", goal_radius=1, collision_terminates=True, forklifts=0, workers=[0, 0])
    default = gym.make("bulletnav/BARN-v0")
    try:
        assert same.unwrapped.config.task.goal_radius == 1.0
        assert default.unwrapped.world_idx == 1 and 1 not in TEST_WORLDS
    finally:
        same.close()
        default.close()


def test_check_env_passes():
    e = gym.make("bulletnav/BARN-v0", world_idx=6).unwrapped
    try:
        check_env(e, skip_render_check=True)
    finally:
        e.close()


def test_world_pools_draw_their_own_worlds_and_repeat_with_the_seed():
    """BARN's report_test.py scores the test worlds idx * 6 for idx in 0-49 (written out here); a
    pool draws only its own worlds, the same seed gives the same worlds, and the world built is the
    one drawn (cylinder count from the world file)."""
    from bulletnav.barn.data import TEST_WORLDS, TRAIN_WORLDS

    test = {6 * k for k in range(50)}
    assert set(TEST_WORLDS) == test and len(TEST_WORLDS) == 50 and max(TEST_WORLDS) == 294
    assert set(TRAIN_WORLDS) == set(range(300)) - test and len(TRAIN_WORLDS) == 250

    def draws(env, seed: int, n: int = 3) -> list[int]:
        out = [env.reset(seed=seed)[1]["world_idx"]]
        return out + [env.reset()[1]["world_idx"] for _ in range(n - 1)]

    e = gym.make("bulletnav/BARN-v0", world_idx="train")
    try:
        a, b, c = draws(e, 5), draws(e, 5), draws(e, 6)
        assert a == b and a != c
        assert not set(a + c) & test
        _, info = e.reset(options={"world_idx": 0})  # an explicit world, even a test world
        assert info["world_idx"] == 0 and len(e.unwrapped.scene.layout.obstacles) == len(_centres(0))
    finally:
        e.close()
    e = gym.make("bulletnav/BARN-v0", world_idx=[1, 299])
    try:
        seen = draws(e, 0, 4)
        assert set(seen) == {1, 299}  # (seed 0 draws both: the resets below switch worlds)
        e.reset(seed=0)
        for world in seen[1:]:  # the same draws again: the built world is the drawn one
            _, info = e.reset()
            assert info["world_idx"] == world
            assert len(e.unwrapped.scene.layout.obstacles) == len(_centres(world))
        _, _, _, _, info = e.step(e.action_space.sample())
        assert info["world_idx"] == world
    finally:
        e.close()
    for bad, match in (("train2", "'train2' is neither"), ([], "empty list"), ([3, 3], r"world\(s\) \[3\] more than once"),
                       ([5, 300], "300 is not"), (2.0, "2.0 is neither")):
        with pytest.raises(LayoutError, match=match):
            gym.make("bulletnav/BARN-v0", world_idx=bad)
