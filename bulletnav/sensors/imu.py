"""Inertial measurement unit: accelerometer (specific force) and gyroscope in the body frame."""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from bulletnav.config import ImuConfig
from bulletnav.sensors.base import VectorSensor, float32_list
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot


class Imu(VectorSensor):
    """Reads ``[ax, ay, az, gx, gy, gz]``: body-frame specific force (m/s^2, gravity included,
    so +g on z at rest) and angular rate (rad/s), with white noise and constant bias.

    Acceleration is the change of the body-centre velocity over the last control step,
    sampled in :meth:`update` from the robot's ground-truth snapshot (``robot.state``, taken
    by the simulation after each control step); noise is drawn there, once per step.
    """

    name = "imu"

    def __init__(self, robot: Robot, clock: Clock, config: ImuConfig = ImuConfig(), gravity: float = 9.81) -> None:
        super().__init__(robot, clock, config.rate_hz)
        self.config = config
        self._gravity = (0.0, 0.0, -gravity)
        self.shift(1.0, (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
        self._prev_velocity: tuple[float, ...] = (0.0, 0.0, 0.0)
        self._prev_time = 0.0
        self._latest = [0.0] * 6
        self._offsets: list[list[float]] = []

    def space(self) -> spaces.Box:
        return spaces.Box(-np.inf, np.inf, (6,), dtype=np.float32)

    def shift(self, noise_scale: float, accel_bias: tuple[float, float, float], gyro_bias: tuple[float, float, float]
              ) -> None:
        """Noise standard deviations times ``noise_scale`` and biases plus the given ones, from
        the next :meth:`reset` on (the config's values with 1.0 and zeros)."""
        cfg = self.config
        self._noise_std = np.repeat([cfg.accel_noise_std, cfg.gyro_noise_std], 3) * noise_scale
        self._bias = np.concatenate([cfg.accel_bias, cfg.gyro_bias]) + np.concatenate([accel_bias, gyro_bias])

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._offsets = []
        state = self.robot.state  # taken when the robot was placed for this episode
        self._prev_velocity = state.linear_velocity
        self._prev_time = self.clock.time
        self._latest = self._sample((0.0, 0.0, 0.0), state.angular_velocity, state.rotation)

    def update(self) -> None:
        state = self.robot.state
        velocity = state.linear_velocity
        now = self.clock.time
        dt = now - self._prev_time
        prev = self._prev_velocity
        if dt > 0:
            accel = ((velocity[0] - prev[0]) / dt, (velocity[1] - prev[1]) / dt, (velocity[2] - prev[2]) / dt)
        else:
            accel = (0.0, 0.0, 0.0)
        self._prev_velocity, self._prev_time = velocity, now
        self._latest = self._sample(accel, state.angular_velocity, state.rotation)

    def _sample(self, accel_world: tuple[float, ...], omega: tuple[float, ...], m: tuple[float, ...]) -> list[float]:
        """Body-frame reading of world-frame ``accel_world`` and ``omega`` (``m``: row-major
        body-to-world rotation), plus this step's noise and bias."""
        g = self._gravity
        fx, fy, fz = accel_world[0] - g[0], accel_world[1] - g[1], accel_world[2] - g[2]
        wx, wy, wz = omega
        if not self._offsets:  # noise + bias drawn in blocks: one Generator call per 256 steps
            block = self.rng.normal(0.0, 1.0, (256, 6)) * self._noise_std + self._bias
            self._offsets = block.tolist()[::-1]
        e = self._offsets.pop()
        # body frame = R^T @ world vector (m is row-major R)
        return float32_list((
            m[0] * fx + m[3] * fy + m[6] * fz + e[0], m[1] * fx + m[4] * fy + m[7] * fz + e[1],
            m[2] * fx + m[5] * fy + m[8] * fz + e[2], m[0] * wx + m[3] * wy + m[6] * wz + e[3],
            m[1] * wx + m[4] * wy + m[7] * wz + e[4], m[2] * wx + m[5] * wy + m[8] * wz + e[5],
        ))

    def measure_floats(self) -> list[float]:
        return self._latest
