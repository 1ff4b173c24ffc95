"""Domain randomization: draws inside the declared ranges, reproducible under the seed, the same
episodes as a nominal env, applied through the same physics as the named shifts, clear errors."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pytest
from scipy import stats

import bulletnav  # noqa: F401
from bulletnav.config import asset_path
from bulletnav.envs.randomization import PARAMETERS, parse_randomize
from bulletnav.errors import ConfigError
from bulletnav.rl.hyperparams import load_hyperparams

EMPTY = str(asset_path("worlds", "empty.yaml"))
SPEC = {
    "floor_friction": [0.2, 1.0],
    "mass_scale": {"loguniform": [0.8, 1.5]},
    "motor_force_scale": {"normal": [1.0, 0.2], "clip": [0.6, 1.3]},
    "action_latency": [0, 2],
    "lidar_dropout": {"choice": [0.0, 0.05, 0.1]},
    "imu_accel_bias": [-0.1, 0.1],
    "odometry_wheelbase_scale": [0.95, 1.05],
}


def test_draws_stay_inside_the_declared_ranges_and_cover_them():
    env = gym.make("bulletnav/Warehouse-v0", randomize=SPEC)
    seen: dict[str, list] = {k: [] for k in SPEC}
    for seed in range(40):
        _, info = env.reset(seed=seed)
        for k, v in info["dr"].items():
            seen[k].append(v)
    env.close()
    assert 0.2 <= min(seen["floor_friction"]) and max(seen["floor_friction"]) <= 1.0
    assert 0.8 <= min(seen["mass_scale"]) and max(seen["mass_scale"]) <= 1.5
    assert 0.6 <= min(seen["motor_force_scale"]) and max(seen["motor_force_scale"]) <= 1.3
    assert set(seen["action_latency"]) == {0, 1, 2}
    assert set(seen["lidar_dropout"]) <= {0.0, 0.05, 0.1} and len(set(seen["lidar_dropout"])) == 3
    biases = np.array(seen["imu_accel_bias"])
    assert biases.shape == (40, 3) and np.abs(biases).max() <= 0.1 and biases.std() > 0.03
    assert max(seen["floor_friction"]) - min(seen["floor_friction"]) > 0.5  # spread, not a constant


def test_draws_are_reproducible_under_the_seed_and_keep_the_episode():
    a = gym.make("bulletnav/Warehouse-v0", randomize=SPEC)
    b = gym.make("bulletnav/Warehouse-v0", randomize=SPEC)
    plain = gym.make("bulletnav/Warehouse-v0")
    draws = []
    for seed in (11, 12):
        _, ia = a.reset(seed=seed)
        _, ib = b.reset(seed=seed)
        _, ip = plain.reset(seed=seed)
        assert ia["dr"] == ib["dr"]
        assert ia["goal"] == ip["goal"] and np.array_equal(ia["pose"], ip["pose"])
        draws.append(ia["dr"])
        _, ia2 = a.reset()  # unseeded resets continue the stream, in step in both envs
        _, ib2 = b.reset()
        assert ia2["dr"] == ib2["dr"] != ia["dr"]
    assert draws[0] != draws[1]
    for env in (a, b, plain):
        env.close()
    # The declared distributions' moments against their closed forms, N = 20,000 draws each
    # (the same draws twice from one seed): the mean within 5 standard errors, the variance
    # within 5 %.
    n = 20_000
    lo, hi = math.log(0.8), math.log(1.5)
    clipped = stats.norm(1.0, 0.2)  # clip to [0.6, 1.3]: the tails pile up on the bounds
    body = stats.truncnorm(-2.0, 1.5, 1.0, 0.2)
    p_lo, p_hi, p_in = clipped.cdf(0.6), clipped.sf(1.3), clipped.cdf(1.3) - clipped.cdf(0.6)
    clip_mean = 0.6 * p_lo + 1.3 * p_hi + p_in * body.mean()
    clip_var = 0.36 * p_lo + 1.69 * p_hi + p_in * (body.var() + body.mean() ** 2) - clip_mean**2
    closed = {  # name: (mean, variance)
        "floor_friction": (0.6, 0.8**2 / 12),
        "mass_scale": ((1.5 - 0.8) / (hi - lo), (1.5**2 - 0.8**2) / (2 * (hi - lo)) - ((1.5 - 0.8) / (hi - lo)) ** 2),
        "motor_force_scale": (clip_mean, clip_var),
        "action_latency": (1.0, 2 / 3),  # 0, 1, 2 equally likely
        "lidar_dropout": (0.05, (0.05**2 + 0.1**2) / 3 - 0.05**2),
        "imu_accel_bias": (0.0, 0.2**2 / 12),
        "odometry_wheelbase_scale": (1.0, 0.1**2 / 12),
    }
    for dist in parse_randomize(SPEC):
        values = [np.array([dist.sample(rng) for _ in range(n)], dtype=float) for rng in
                  (np.random.default_rng(7), np.random.default_rng(7))]
        np.testing.assert_array_equal(values[0], values[1])
        mean, var = closed[dist.name]
        sample = values[0].ravel()
        assert abs(sample.mean() - mean) < 5 * math.sqrt(var / sample.size), dist.name
        assert sample.var() == pytest.approx(var, rel=0.05), dist.name


def test_a_drawn_value_drives_the_same_physics_as_the_shift_itself():
    trajectories = []
    for kw in ({"randomize": {"mass_scale": [2.0, 2.0], "action_latency": {"choice": [1]}}},
               {"shift_mass_scale": 2.0, "shift_action_latency": 1}, {}):
        env = gym.make("bulletnav/Warehouse-v0", world=EMPTY, **kw)
        env.reset(seed=0, options={"start": [-3.0, 0.0, 0.0], "goal": [4.0, 4.0]})
        poses = []
        for _ in range(20):
            env.step(np.array([0.5, 0.3]))
            poses.append(env.unwrapped.scene.pose)
        trajectories.append(np.array(poses))
        env.close()
    np.testing.assert_array_equal(trajectories[0], trajectories[1])
    assert np.abs(trajectories[0] - trajectories[2]).max() > 0.01
    # A latency of one step: the first command reaches the wheels a step late, so after one
    # step the robot still stands at its start, where the nominal robot has already moved.
    np.testing.assert_allclose(trajectories[0][0], [-3.0, 0.0, 0.0], atol=1e-4)
    assert trajectories[2][0][0] > -3.0 + 1e-3


def test_world_parameters_reach_the_layout_and_mover_speeds_the_movers():
    env = gym.make("bulletnav/Warehouse-v0", randomize={"num_obstacles": {"choice": [5]}})
    _, info = env.reset(seed=3)
    assert len(env.unwrapped.scene.layout.obstacles) == 5 and info["dr"] == {"num_obstacles": 5}
    env.close()
    speeds = []
    for kw in ({}, {"randomize": {"mover_speed_scale": [2.0, 2.0]}}):
        env = gym.make("bulletnav/WarehouseDynamic-v0", yield_to_robot=False, **kw)
        env.reset(seed=4)
        speeds.append([m.speed for m in env.unwrapped.scene.movers])
        env.close()
    nominal, fast = np.array(speeds[0]), np.array(speeds[1])
    assert len(nominal) > 0 and (nominal > 0).any()
    np.testing.assert_allclose(fast, 2.0 * nominal)


@pytest.mark.parametrize("spec, message", [
    ({"frction": [0, 1]}, "unknown parameter 'frction'; known: action_latency"),
    ({"mass_scale": {"loguniform": [0.0, 2.0]}}, "randomize.mass_scale: loguniform needs low > 0, got 0.0"),
    ({"mass_scale": [-1.0, 2.0]}, "randomize.mass_scale: the range reaches -1.0"),
    ({"action_latency": [0.5, 2]}, "action_latency takes whole numbers"),
    ({"floor_friction": [1.0, 0.2]}, "need low <= high"),
    ({"lidar_noise_std": {"normal": [0.02, 0.01]}}, "give a normal distribution a clip range"),
    ({"floor_friction": "slippery"}, "expected [low, high], a fixed number or a mapping"),
])
def test_bad_specifications_are_refused_by_name(spec, message):
    with pytest.raises(ValueError, match=message.replace("[", r"\[").replace("]", r"\]").replace(".", r"\.")):
        gym.make("bulletnav/Warehouse-v0", randomize=spec)


def test_every_shift_field_and_world_parameter_is_randomizable():
    spec = {name: ([0, 1] if kind is int else [1.0, 1.0]) for name, kind in PARAMETERS.items()}
    spec.update(lidar_noise_std=[0.0, 0.01], lidar_dropout=[0.0, 0.1], depth_noise_std=[0.0, 0.01],
                imu_accel_bias=[-0.1, 0.1], imu_gyro_bias=[-0.01, 0.01], num_obstacles=[20, 30],
                clutter_per_metre=[0.1, 0.2])
    assert {d.name for d in parse_randomize(spec)} == set(PARAMETERS)


def test_a_hyperparameter_file_with_a_bad_randomize_block_names_file_and_key(tmp_path):
    path = tmp_path / "ppo.yml"
    path.write_text("bulletnav/Warehouse-v0:\n  policy: MlpPolicy\n  randomize: {mass_scale: [0.0, 2.0]}\n")
    with pytest.raises(ConfigError, match=r"ppo\.yml: bulletnav/Warehouse-v0\.randomize\.mass_scale: the range reaches 0\.0"):
        load_hyperparams("ppo", path=path)


def test_the_ablation_files_differ_from_the_shipped_settings_only_in_their_arm():
    base = load_hyperparams("ppo", "bulletnav/WarehouseDynamic-v0")
    arms = {}
    for arm in ("curriculum", "randomize", "both"):
        path = asset_path("..", "rl", "hyperparams", f"ppo_dynamic_{arm}.yml")
        hp = load_hyperparams("ppo", "bulletnav/WarehouseDynamic-v0", path)
        arms[arm] = hp
        assert {k: v for k, v in hp.items() if k not in ("curriculum", "randomize")} == base
    assert set(arms["curriculum"]) - set(base) == {"curriculum"}
    assert set(arms["randomize"]) - set(base) == {"randomize"}
    assert arms["both"]["curriculum"] == arms["curriculum"]["curriculum"]
    assert arms["both"]["randomize"] == arms["randomize"]["randomize"]
    env = gym.make("bulletnav/WarehouseDynamic-v0", randomize=arms["randomize"]["randomize"])
    for seed in range(3):  # every drawn world and shift builds and runs
        env.reset(seed=seed)
        for _ in range(5):
            env.step(env.action_space.sample())
    env.close()
