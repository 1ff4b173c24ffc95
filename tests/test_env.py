"""The Gymnasium env: API checks, determinism, reward bookkeeping and episode rules."""

from __future__ import annotations

import json
import math
import re
import warnings

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import bulletnav  # noqa: F401  (registers the env)
from bulletnav.cli import main
from bulletnav.config import asset_path
from bulletnav.envs.task import REWARD_TERMS
from bulletnav.errors import DisplayError

ENV_ID = "bulletnav/Warehouse-v0"
ACTION_SPACE_ADVICE = ("symmetric and normalized", "symmetric and normalized Box action space")
WRAPPED_ADVICE = "using the raw environment for `check_env`"


def _all_warnings(fn) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn()
    return [str(w.message) for w in caught]


@pytest.fixture
def make_env():
    envs = []

    def _make(**kwargs):
        env = gym.make(ENV_ID, **kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()


def test_spaces_match_the_article(make_env):
    env = make_env()
    assert env.observation_space.shape == (43,) and env.observation_space.dtype == np.float32
    np.testing.assert_array_equal(env.action_space.low, [0.0, -1.5])
    np.testing.assert_array_equal(env.action_space.high, [0.5, 1.5])
    assert env.spec.max_episode_steps == 1000
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert len(env.unwrapped.world.obstacle_ids) == 31
    assert set(env.unwrapped.sensors) == {"lidar", "camera", "imu", "odometry"}
    for name in REWARD_TERMS:
        assert info[f"reward_{name}"] == 0.0
    # Observation entries against their sources.
    u = env.unwrapped
    x, y, yaw = u.robot.pose()
    gx, gy = info["goal"]
    assert obs[42] == pytest.approx(math.hypot(gx - x, gy - y) / 10, abs=1e-6)
    assert obs[36] * math.pi == pytest.approx(math.remainder(math.atan2(gy - y, gx - x) - yaw, 2 * math.pi), abs=1e-5)
    np.testing.assert_allclose(obs[:36], u.sensors["lidar"].read() / 5.0, atol=1e-6)


@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_checkers_pass_without_warnings_with_normalized_actions(make_env, display, render_mode):
    env = make_env(normalize_actions=True, render_mode=render_mode)
    # Gymnasium's render check also builds a "human" env (hence the display).
    assert _all_warnings(lambda: gym_check_env(env.unwrapped)) == []
    assert _all_warnings(lambda: sb3_check_env(env)) == []
    assert _all_warnings(lambda: sb3_check_env(env.unwrapped)) == []
    # On the made env Gymnasium adds only its advice to check the raw env instead.
    assert all(WRAPPED_ADVICE in w for w in _all_warnings(lambda: gym_check_env(env, skip_render_check=True)))


def test_checkers_pass_in_human_mode(make_env, display):
    env = make_env(normalize_actions=True, render_mode="human")
    # PyBullet allows one GUI connection per process, and Gymnasium's render and close
    # checks open a second env from the spec; the render check of "human" ran above.
    assert _all_warnings(lambda: gym_check_env(env.unwrapped, skip_render_check=True, skip_close_check=True)) == []
    assert _all_warnings(lambda: sb3_check_env(env)) == []


def test_physical_action_space_draws_only_the_normalisation_advice(make_env):
    """The article's action box exceeds [-1, 1], which both checkers advise against; nothing else."""
    env = make_env()
    caught = _all_warnings(lambda: (gym_check_env(env.unwrapped, skip_render_check=True), sb3_check_env(env)))
    assert len(caught) == 2
    assert all(any(a in w for a in ACTION_SPACE_ADVICE) for w in caught)


def test_rgb_array_render(make_env):
    env = make_env(render_mode="rgb_array")
    env.reset(seed=1)
    frame = env.render()
    assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8 and frame.std() > 5


def test_human_mode_without_display_raises_clearly(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(DisplayError, match="needs an X display.*xvfb-run"):
        gym.make(ENV_ID, render_mode="human")
    monkeypatch.setenv("DISPLAY", ":987")  # nothing listens there
    with pytest.raises(DisplayError, match="does not answer"):
        gym.make(ENV_ID, render_mode="human")


def _rollout(seed: int, steps: int = 300):
    env = gym.make(ENV_ID, lidar_noise=0.02)
    env.action_space.seed(seed)
    trace = []
    obs, info = env.reset(seed=seed)
    resets = 0
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            obs, info = env.reset()
            resets += 1
            trace.append((obs, info))
    layout = env.unwrapped.layout
    env.close()
    return trace, resets, layout


def _equal(a, b) -> bool:
    if isinstance(a, dict):
        return a.keys() == b.keys() and all(_equal(a[k], b[k]) for k in a)
    if isinstance(a, (tuple, list)):
        return len(a) == len(b) and all(_equal(x, y) for x, y in zip(a, b))
    if isinstance(a, np.ndarray):
        return a.dtype == b.dtype and np.array_equal(a, b)
    return a == b and type(a) is type(b)


def test_same_seed_is_bit_identical_across_resets():
    a, resets_a, layout_a = _rollout(seed=3)
    b, resets_b, layout_b = _rollout(seed=3)
    assert resets_a >= 2, "the rollout should span several episodes"
    assert resets_a == resets_b and layout_a == layout_b
    assert _equal(a, b)
    _, _, layout_c = _rollout(seed=4, steps=1)
    assert layout_c != layout_a


def test_seeded_reset_is_independent_of_history(make_env):
    env = make_env()
    first, _ = env.reset(seed=11)
    for _ in range(30):
        env.step(env.action_space.sample())
    again, _ = env.reset(seed=11)
    np.testing.assert_array_equal(first, again)
    step_a = env.step(np.array([0.3, 0.2], dtype=np.float32))[0]
    env.reset(seed=11)
    step_b = env.step(np.array([0.3, 0.2], dtype=np.float32))[0]
    np.testing.assert_array_equal(step_a, step_b)


def test_reward_terms_sum_to_the_reward(make_env):
    env = make_env()
    env.action_space.seed(0)
    env.reset(seed=5)
    seen = set()
    for _ in range(400):
        _, reward, terminated, truncated, info = env.step(env.action_space.sample())
        terms = [info[f"reward_{name}"] for name in REWARD_TERMS]
        assert sum(terms) == pytest.approx(reward, abs=1e-12)
        seen |= {name for name, t in zip(REWARD_TERMS, terms) if t != 0.0}
        if terminated or truncated:
            env.reset()
    assert {"progress", "time", "heading"} <= seen


EMPTY = str(asset_path("worlds", "empty.yaml"))


def test_scripted_drive_to_a_nearby_goal_terminates_with_the_goal_term(make_env):
    env = make_env(world=EMPTY)
    obs, _ = env.reset(seed=0, options={"start": (-2.0, 0.0, 0.0), "goal": (0.0, 0.3)})
    total, steps = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(np.array([0.5, 2.0 * obs[36] * math.pi]))
        total += reward
        steps += 1
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["is_success"] and info["reward_goal"] == 50.0 and info["distance_to_goal"] < 0.5
    assert info["initial_distance"] == pytest.approx(math.hypot(2.0, 0.3), abs=1e-6)
    assert info["path_length"] == pytest.approx(info["initial_distance"] - info["distance_to_goal"], abs=0.1)
    assert total > 50.0


def test_driving_into_a_wall_truncates_with_the_collision_term(make_env):
    env = make_env(world=EMPTY)
    env.reset(seed=0, options={"start": (3.5, 0.0, 0.0), "goal": (-3.0, 0.0)})
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.array([0.5, 0.0]))
        if terminated or truncated:
            break
    assert truncated and not terminated
    assert info["collision"] and info["reward_collision"] == -10.0 and not info["is_success"]
    assert env.unwrapped.robot.pose()[0] == pytest.approx(5.0 - 0.15, abs=0.06)  # front face at the wall


def test_top_speed_into_a_wall_never_passes_through(make_env):
    env = make_env(world=EMPTY)
    env.reset(seed=0, options={"start": (3.0, 1.0, 0.1), "goal": (-3.0, 0.0)})
    xs = []
    for _ in range(24 * 20):  # keep pushing for 20 s after the contact, ignoring truncation
        env.unwrapped.step(np.array([0.5, 0.0]))
        xs.append(env.unwrapped.robot.pose()[0])
    assert max(xs) < 5.0  # the wall's inner face is at x = 5 m


def test_bad_actions_and_options(make_env):
    env = make_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="non-finite entries: v"):
        env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="non-finite entries: w"):
        env.step(np.array([0.1, np.inf]))
    assert env.unwrapped.command(np.array([9.0, -9.0])) == (0.5, -1.5)  # clipped
    assert env.unwrapped.command(np.array([-1.0, 0.7])) == (0.0, 0.7)
    with pytest.raises(ValueError, match="options\\['start'\\]"):
        env.reset(options={"start": (1.0, 2.0)})
    with pytest.raises(TypeError, match="unknown keyword argument 'num_obstacle'"):
        gym.make(ENV_ID, num_obstacle=3)


def test_normalized_actions_map_onto_the_physical_range(make_env):
    env = make_env(normalize_actions=True)
    u = env.unwrapped
    assert u.command(np.array([-1.0, -1.0])) == (0.0, -1.5)
    assert u.command(np.array([1.0, 1.0])) == (0.5, 1.5)
    assert u.command(np.array([0.0, 0.0])) == (0.25, 0.0)


def test_options_place_start_and_goal_exactly(make_env):
    env = make_env(layouts_every=100)  # keep the warehouse across resets
    obs, info = env.reset(seed=2)
    layout = env.unwrapped.layout
    free = env.unwrapped.free_space
    (sx, sy, _), goal = info["pose"], info["goal"]
    _, info2 = env.reset(options={"start": (float(sx), float(sy), 0.5), "goal": goal})
    assert env.unwrapped.layout is layout and free is env.unwrapped.free_space
    np.testing.assert_allclose(info2["pose"], [sx, sy, 0.5], atol=1e-9)
    assert info2["goal"] == goal


def test_kwargs_reach_the_configs(make_env):
    env = make_env(num_obstacles=12, lidar_rays=72, physics_hz=240, control_hz=12, reward_collision=-20.0,
                   min_goal_distance=3.0, max_goal_distance=4.0)
    u = env.unwrapped
    assert env.observation_space.shape == (79,)
    _, info = env.reset(seed=0)
    assert len(u.world.obstacle_ids) == 12
    assert u.config.physics.substeps == 20
    assert u.config.task.reward.collision == -20.0
    assert 3.0 <= info["initial_distance"] <= 4.0
    with pytest.raises(ValueError, match="must divide"):
        gym.make(ENV_ID, control_hz=7)


def test_camera_observations(make_env):
    env = make_env(camera_obs=True, normalize_actions=True)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state", "rgb", "depth"}
    assert obs["rgb"].shape == (240, 320, 3) and obs["depth"].shape == (240, 320, 1)
    assert env.observation_space.contains(obs)
    assert _all_warnings(lambda: gym_check_env(env.unwrapped, skip_render_check=True)) == []


def test_yaml_world_uses_its_start_and_goal(make_env):
    env = make_env(world=str(asset_path("worlds", "aisles.yaml")))
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(info["pose"], [-5.0, -4.0, 0.0], atol=1e-6)
    assert info["goal"] == (4.5, 4.2)
    assert len(env.unwrapped.world.obstacle_ids) == 10


def test_bench_env_cli_prints_the_ratio_with_its_provenance(capsys):
    """``bulletnav bench env --json``: both loops' rates, their ratio, and where the figures
    came from (no timing is asserted: these machines are noisy)."""
    assert main(["bench", "env", "--steps", "200", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["benchmark"] == "env" and result["steps"] == 200
    assert result["env_steps_per_s"] > 0 and result["raw_steps_per_s"] > 0
    assert result["ratio"] > 0 and result["env_overhead_us_per_step"] == pytest.approx(
        (1 / result["env_steps_per_s"] - 1 / result["raw_steps_per_s"]) * 1e6, abs=0.5)
    assert re.fullmatch(r"([0-9a-f]{40}(-dirty)?|unknown)", result["git_commit"])
    assert "cores, python" in result["machine"] and result["command"]
