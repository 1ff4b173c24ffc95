"""Wheel odometry: body velocity from wheel rates and a pose integrated from wheel encoders."""

from __future__ import annotations

import math

import numpy as np
from gymnasium import spaces

from bulletnav.config import OdometryConfig
from bulletnav.sensors.base import VectorSensor, float32_list
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot


class Odometry(VectorSensor):
    """Reads ``[x, y, yaw, v, w]`` (m, m, rad, m/s, rad/s).

    ``v = r (wl + wr) / 2`` and ``w = r (wr - wl) / L`` come from the wheel joint rates
    sampled at the last :meth:`update` (every control step).

    The pose starts at the true pose at reset and is integrated in :meth:`update`, once per
    control step, from the wheel *angle* increments over that step (as real encoders count
    them, plus ``encoder_noise_std`` noise per wheel and step): the midpoint rule
    ``x += ds cos(yaw + dyaw / 2)``, which is exact for an arc of constant curvature. Within
    a control step the robot need not drive such an arc (the motors accelerate), so the
    estimate drifts from ground truth by that integration error plus wheel slip.
    """

    name = "odometry"

    def __init__(self, robot: Robot, clock: Clock, config: OdometryConfig = OdometryConfig()) -> None:
        super().__init__(robot, clock, config.rate_hz)
        self.config = config
        self.state: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Integrated pose estimate (x, y, yaw) in m, m, rad."""
        self._prev_angles = (0.0, 0.0)
        self._rates = (0.0, 0.0)
        self.distance = 0.0
        """Path length driven according to the encoders (m)."""
        self.model_scale = (1.0, 1.0)
        """The odometry model's wheel radius and wheelbase over the true ones (1.0: calibrated)."""

    def space(self) -> spaces.Box:
        high = np.array([np.inf, np.inf, np.pi, np.inf, np.inf], dtype=np.float32)
        return spaces.Box(-high, high, dtype=np.float32)

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        truth = self.robot.state  # taken when the robot was placed for this episode
        self.state = (truth.x, truth.y, truth.yaw)
        self._prev_angles, self._rates = truth.wheel_angles, truth.wheel_rates
        self.distance = 0.0

    def update(self) -> None:
        state = self.robot.state  # taken by the simulation after this control step
        angles, self._rates = state.wheel_angles, state.wheel_rates
        d_left, d_right = angles[0] - self._prev_angles[0], angles[1] - self._prev_angles[1]
        self._prev_angles = angles
        if self.config.encoder_noise_std > 0:
            noise = self.rng.normal(0.0, self.config.encoder_noise_std, 2)
            d_left, d_right = d_left + float(noise[0]), d_right + float(noise[1])
        r, base = self.robot.wheel_radius * self.model_scale[0], self.robot.wheelbase * self.model_scale[1]
        ds = r * (d_left + d_right) / 2
        dyaw = r * (d_right - d_left) / base
        x, y, yaw = self.state
        mid = yaw + dyaw / 2
        self.state = (x + ds * math.cos(mid), y + ds * math.sin(mid), math.remainder(yaw + dyaw, 2 * math.pi))
        self.distance += abs(ds)

    def measure_floats(self) -> list[float]:
        rates = self._rates  # sampled with the angles in the last update
        r, base = self.robot.wheel_radius * self.model_scale[0], self.robot.wheelbase * self.model_scale[1]
        v = r * (rates[0] + rates[1]) / 2
        w = r * (rates[1] - rates[0]) / base
        x, y, yaw = self.state
        return float32_list((x, y, yaw, v, w))
