"""``robot="jackal"``: a Clearpath Jackal-sized robot on every id, BARN-v0's default.

References: Clearpath's public numbers (github.com/jackal/jackal: track 0.37559 m, wheel radius
0.098 m, 2.0 m/s, 4.0 rad/s; spec sheet 0.508 x 0.430 m; the UST-10's 270 degrees and 30 m)
written here by hand, against what PyBullet loads and how the robot drives."""

from __future__ import annotations

import math
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import bulletnav  # noqa: F401  (registers the ids)


def test_geometry_wheels_and_rest_height_are_the_jackals():
    env = gym.make("bulletnav/BARN-v0", world_idx=93)
    try:
        env.reset(seed=0)
        scene = env.unwrapped.scene
        rects = scene.geometry.rectangles
        length = 2 * max(abs(r.cx) + r.half_x for r in rects)
        width = 2 * max(abs(r.cy) + r.half_y for r in rects)
        assert (length, width) == pytest.approx((0.508, 0.430), abs=1e-9)
        cid, body = scene.client, scene.robot_body
        joints = {p.getJointInfo(body, j, physicsClientId=cid)[1].decode(): j
                  for j in range(p.getNumJoints(body, physicsClientId=cid))}
        left, right = (p.getJointInfo(body, joints[n], physicsClientId=cid)[14] for n in ("left_wheel_joint", "right_wheel_joint"))
        assert left[1] - right[1] == pytest.approx(0.37559, abs=1e-6)
        assert p.getCollisionShapeData(body, joints["left_wheel_joint"], physicsClientId=cid)[0][3][0] == pytest.approx(0.098)
        for _ in range(24):  # a second standing still: it rests where it was put, on its wheels
            env.step(np.zeros(2, dtype=np.float32))
        com_z = p.getBasePositionAndOrientation(body, physicsClientId=cid)[0][2]
        assert com_z == pytest.approx(0.098 + 0.03, abs=1e-3)  # axle 0.098 m up, centre of mass 0.03 m above it
    finally:
        env.close()


def test_top_speed_turn_rate_and_straight_driving():
    env = gym.make("bulletnav/BARN-v0", world_idx=93)
    try:
        assert env.action_space.high.tolist() == [2.0, 4.0] and env.action_space.low.tolist() == [0.0, -4.0]
        _, info = env.reset(seed=0)
        dt = env.unwrapped.config.physics.control_dt
        poses = [info["pose"].copy()]
        for _ in range(48):  # 2 s at full speed north along world 93's open lane
            _, _, terminated, truncated, info = env.step(np.array([2.0, 0.0], dtype=np.float32))
            poses.append(info["pose"].copy())
            assert not (terminated or truncated)
        xy = np.array(poses)[:, :2]
        speed = np.linalg.norm(xy[-1] - xy[-13]) / (12 * dt)  # over the last half second
        assert speed == pytest.approx(2.0, rel=0.02)
        assert abs(poses[-1][2] - 1.57) < 0.01 and abs(poses[-1][0] + 2.25) < 0.02
    finally:
        env.close()


def test_lidar_is_the_ust10s_270_degrees_and_30_m():
    env = gym.make("bulletnav/BARN-v0", world_idx=0)
    full = gym.make("bulletnav/BARN-v0", world_idx=0, lidar_rays=720)
    try:
        lidar = env.unwrapped.config.sensors.lidar
        assert (lidar.fov, lidar.max_range, lidar.min_range, lidar.num_rays) == (270.0, 30.0, 0.1, 72)
        angles = env.unwrapped.scene.sensors.lidar.angles
        assert (angles[0], angles[-1]) == pytest.approx((-3 * math.pi / 4, 3 * math.pi / 4))
        assert env.observation_space.shape == (79,) and full.observation_space.shape == (727,)
        assert full.unwrapped.config.sensors.lidar.fov == 270.0  # lidar_rays after robot keeps its fov
    finally:
        env.close()
        full.close()


def test_robot_keyword_on_every_id_and_bad_names():
    ids = sorted(e for e in gym.registry if e.startswith("bulletnav/"))
    for env_id in ids:
        env = gym.make(env_id, robot="jackal")
        try:
            assert env.unwrapped.config.task.max_speed == 2.0
            # the farthest corner of the body with bumpers (0.508 x 0.31 m) or of a wheel guard (0.458 m long, to y = 0.215)
            corner = max(math.hypot(0.254, 0.155), math.hypot(0.229, 0.215))
            assert env.unwrapped.scene.geometry.outline_radius == pytest.approx(corner)
        finally:
            env.close()
    article = gym.make("bulletnav/BARN-v0", robot="article")
    warehouse = gym.make("bulletnav/Warehouse-v0")
    try:
        assert article.unwrapped.config.robot == warehouse.unwrapped.config.robot
        # the same sensors, but BARN-v0 casts its lidar in closed form against BARN's cylinders
        assert article.unwrapped.config.sensors.lidar.caster == "exact"
        sensors = article.unwrapped.config.sensors
        assert replace(sensors, lidar=replace(sensors.lidar, caster="bullet")) == warehouse.unwrapped.config.sensors
    finally:
        article.close()
        warehouse.close()
    with pytest.raises(ValueError, match="robot='husky'.*unknown robot 'husky'; known: article, jackal"):
        gym.make("bulletnav/Warehouse-v0", robot="husky")
