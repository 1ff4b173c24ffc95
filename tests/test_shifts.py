"""Named evaluation shifts and the shift parameters: each changes the physics or the sensor
it names, by the amount physics predicts, and nothing else about the episode."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import bulletnav  # noqa: F401
from bulletnav.cli import main
from bulletnav.config import asset_path
from bulletnav.envs.shifts import PERTURBATIONS

EMPTY = str(asset_path("worlds", "empty.yaml"))
START = [-3.0, 0.0, 0.0]
G = 9.81


def _env(**kw):
    env = gym.make("bulletnav/Warehouse-v0", world=EMPTY, **kw)
    env.reset(seed=0, options={"start": START, "goal": [4.0, 4.0]})
    return env


def _drive(env, action, steps):
    xs = []
    for _ in range(steps):
        env.step(np.array(action))
        xs.append(env.unwrapped.scene.pose[0])
    return xs


def _braking_distance(**kw):
    env = _env(**kw)
    _drive(env, [0.5, 0.0], 48)
    x0 = env.unwrapped.scene.pose[0]
    x1 = _drive(env, [0.0, 0.0], 48)[-1]
    env.close()
    return x1 - x0


def test_a_slippery_floor_brakes_no_harder_than_coulomb_friction_allows():
    nominal = _braking_distance()
    slippery = _braking_distance(perturb="slippery")
    mu = PERTURBATIONS["slippery"].floor_friction * 1.0  # PyBullet multiplies floor and wheel friction
    coulomb = 0.5**2 / (2 * mu * G)  # the shortest stop friction mu allows from 0.5 m/s
    assert nominal < coulomb <= slippery + 0.005
    assert slippery > 1.5 * nominal


def _initial_acceleration(**kw):
    env = _env(**kw)
    xs = _drive(env, [0.5, 0.0], 3)  # 0.125 s, well before the 0.5 m/s target
    env.close()
    return 2 * (xs[-1] - START[0]) / (3 / 24) ** 2


def _total_mass(env):
    scene = env.unwrapped.scene
    body, cid = scene.robot_body, scene.client
    return sum(p.getDynamicsInfo(body, link, physicsClientId=cid)[0] for link in range(-1, p.getNumJoints(body, physicsClientId=cid)))


def test_mass_and_motor_force_change_the_acceleration_as_newton_says():
    nominal = _initial_acceleration()
    heavy_env = _env(shift_mass_scale=2.0)
    nominal_env = _env()
    predicted = _total_mass(heavy_env) / _total_mass(nominal_env)
    heavy_env.close()
    nominal_env.close()
    assert predicted > 1.5
    heavy = _initial_acceleration(shift_mass_scale=2.0)
    assert nominal / heavy == pytest.approx(predicted, rel=0.15)
    weak = _initial_acceleration(shift_motor_force_scale=0.5)
    assert nominal / weak == pytest.approx(2.0, rel=0.15)


def test_a_miscalibrated_odometry_model_drifts_by_its_error():
    env = _env(shift_odometry_wheel_radius_scale=1.05, shift_odometry_wheelbase_scale=0.95)
    odo = env.unwrapped.scene.sensors.odometry
    _drive(env, [0.4, 0.0], 72)
    true_dx = env.unwrapped.scene.pose[0] - START[0]
    assert (odo.read()[0] - START[0]) / true_dx == pytest.approx(1.05, rel=0.01)
    yaw0, odo_yaw0 = env.unwrapped.scene.pose[2], odo.read()[2]
    _drive(env, [0.0, 1.0], 24)  # about 1 rad in place
    true_turn = math.remainder(env.unwrapped.scene.pose[2] - yaw0, 2 * math.pi)
    odo_turn = math.remainder(odo.read()[2] - odo_yaw0, 2 * math.pi)
    assert odo_turn / true_turn == pytest.approx(1.05 / 0.95, rel=0.02)
    env.close()


def test_latency_delays_the_motion_by_whole_control_steps():
    rng = np.random.default_rng(3)
    actions = [np.array([rng.uniform(0.0, 0.5), rng.uniform(-1.5, 1.5)]) for _ in range(30)]
    runs = {}
    for lag in (0, 2):
        env = _env(shift_action_latency=lag)
        poses = []
        for a in actions:
            env.step(a)
            poses.append(env.unwrapped.scene.pose)
        runs[lag] = np.array(poses)
        env.close()
    np.testing.assert_allclose(runs[2][:2, :2], [START[:2]] * 2, atol=1e-3)  # nothing moves at first
    assert np.abs(runs[2][10:, :2] - runs[0][10:, :2]).max() > 0.01  # then it lags behind


def test_lidar_dropout_and_imu_noise_scale_as_declared():
    dropped, seen = 0, 0
    env = _env(shift_lidar_dropout=0.3, shift_imu_noise_scale=3.0)
    nominal = _env()
    gyro = []
    for _ in range(40):
        obs, *_ = env.step(np.array([0.0, 0.0]))
        ref, *_ = nominal.step(np.array([0.0, 0.0]))
        hit = ref[:36] < 1.0
        seen += int(hit.sum())
        dropped += int((obs[:36][hit] == 1.0).sum())
        gyro.append(env.unwrapped.scene.sensors.imu.read()[5])
    assert dropped / seen == pytest.approx(0.3, abs=0.06)
    assert np.std(gyro) == pytest.approx(3 * 0.01, rel=0.3)
    env.close()
    nominal.close()


def test_a_shift_keeps_the_episode_and_reports_itself():
    plain = gym.make("bulletnav/WarehouseAisles-v0")
    shifted = gym.make("bulletnav/WarehouseAisles-v0", perturb="heavy")
    for seed in (5, 6):
        _, a = plain.reset(seed=seed)
        _, b = shifted.reset(seed=seed)
        assert a["goal"] == b["goal"] and np.array_equal(a["pose"], b["pose"])
        assert plain.unwrapped.scene.layout == shifted.unwrapped.scene.layout
        assert "shift" not in a and b["shift"] == {"mass_scale": 1.5, "motor_force_scale": 0.6}
    plain.close()
    shifted.close()


def test_unknown_names_and_bad_values_are_refused_clearly(capsys):
    with pytest.raises(ValueError, match="unknown perturbation 'wobbly'; choose one of slippery, heavy, noisy"):
        gym.make("bulletnav/Warehouse-v0", perturb="wobbly")
    with pytest.raises(ValueError, match="shift mass_scale must be a finite number > 0, got -1"):
        gym.make("bulletnav/Warehouse-v0", shift_mass_scale=-1)
    with pytest.raises(SystemExit):
        main(["navigate", "--perturb", "wobbly", "--episodes", "1"])
    err = capsys.readouterr().err
    assert "invalid choice: 'wobbly'" in err and all(name in err for name in PERTURBATIONS)


@pytest.mark.parametrize("name", list(PERTURBATIONS))
def test_every_named_shift_runs_a_controller(name):
    from bulletnav.control.navigator import Navigator
    from bulletnav.evaluation import run_episodes

    env = gym.make("bulletnav/Warehouse-v0", perturb=name)
    poses = []
    results = run_episodes(env, Navigator(env.unwrapped.scene), episodes=1, seed=1000,
                           on_reset=lambda e, info: poses.append(info["pose"][:2].copy()),
                           on_step=lambda e, info: poses.append(info["pose"][:2].copy()))
    assert results[0].steps > 0
    env.close()
    # against values worked out here: one pose per 1/24 s step, the driven length their sum of
    # segment lengths, and at least the straight line from the start to where the robot ended
    r = results[0]
    assert len(poses) == r.steps + 1 and r.sim_time == pytest.approx(r.steps / 24)
    driven = sum(math.dist(a, b) for a, b in zip(poses, poses[1:]))
    assert r.path_length == pytest.approx(driven, rel=1e-6, abs=1e-9)
    assert r.path_length >= math.dist(poses[0], poses[-1]) - 1e-9 and r.path_length > 0.5
