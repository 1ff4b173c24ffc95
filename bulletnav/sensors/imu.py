"""Inertial measurement unit: accelerometer (specific force) and gyroscope in the body frame."""

from __future__ import annotations

import numpy as np
import pybullet as p

from bulletnav.config import ImuConfig
from bulletnav.sensors.base import Sensor
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot


class Imu(Sensor):
    """Reads ``[ax, ay, az, gx, gy, gz]``: body-frame specific force (m/s^2, gravity included,
    so +g on z at rest) and angular rate (rad/s), with white noise and constant bias.

    Acceleration is the change of the body-centre velocity over the last control step,
    sampled in :meth:`update`; noise is drawn there, once per step.
    """

    name = "imu"

    def __init__(self, robot: Robot, clock: Clock, config: ImuConfig = ImuConfig(), gravity: float = 9.81) -> None:
        super().__init__(robot, clock)
        self.config = config
        self.gravity = np.array([0.0, 0.0, -gravity])
        self._prev_velocity = np.zeros(3)
        self._prev_time = 0.0
        self._latest = np.zeros(6, dtype=np.float32)

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._prev_velocity, _ = self.robot.world_velocity()
        self._prev_time = self.clock.time
        self._latest = self._sample(np.zeros(3))

    def update(self) -> None:
        velocity, _ = self.robot.world_velocity()
        dt = self.clock.time - self._prev_time
        accel = (velocity - self._prev_velocity) / dt if dt > 0 else np.zeros(3)
        self._prev_velocity, self._prev_time = velocity, self.clock.time
        self._latest = self._sample(accel)

    def _sample(self, accel_world: np.ndarray) -> np.ndarray:
        cfg = self.config
        _, orn = self.robot.pose3d()
        rot = np.reshape(p.getMatrixFromQuaternion(orn), (3, 3))
        _, omega = self.robot.world_velocity()
        specific_force = rot.T @ (accel_world - self.gravity)
        rate = rot.T @ omega
        noise = self.rng.normal(0.0, 1.0, 6) * np.repeat([cfg.accel_noise_std, cfg.gyro_noise_std], 3)
        bias = np.concatenate([cfg.accel_bias, cfg.gyro_bias])
        return (np.concatenate([specific_force, rate]) + bias + noise).astype(np.float32)

    def measure(self) -> np.ndarray:
        return self._latest
