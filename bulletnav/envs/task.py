"""The navigation task: observation vector, named reward terms and episode end rules.

Kept apart from the simulation so a user can change the reward or the observation without
touching physics or sensors (dm_control's Task).
"""

from __future__ import annotations

import math
from collections import deque
from typing import NamedTuple

import numpy as np

from bulletnav.config import TaskConfig
from bulletnav.sim.simulation import Simulation

REWARD_TERMS = ("progress", "goal", "collision", "time", "heading", "stuck", "proximity")
"""Names of the reward terms; ``info`` carries each as ``reward_<name>``."""


class Measurement(NamedTuple):
    """What the task reads from the simulation once per control step."""

    x: float
    y: float
    yaw: float
    ranges: np.ndarray
    odometry: np.ndarray
    imu: np.ndarray
    distance: float
    heading_error: float
    """Goal bearing relative to the heading (rad, in [-pi, pi], counter-clockwise positive)."""


class NavigationTask:
    """Go to a goal point in the warehouse: observation, reward and termination."""

    def __init__(self, config: TaskConfig, lidar_range: float, num_rays: int, gravity: float) -> None:
        self.config = config
        self.lidar_range = lidar_range
        self.num_rays = num_rays
        self.gravity = gravity
        self.goal = (0.0, 0.0)
        self.initial_distance = 0.0
        self.path_length = 0.0
        self._prev_distance = 0.0
        self._prev_xy = (0.0, 0.0)
        self._progress: deque[float] = deque(maxlen=config.reward.stuck_window)
        n = num_rays
        self.obs_low = np.array([0.0] * n + [-1.0, -2.0, -2.0, -3.0, -3.0, -3.0, 0.0], dtype=np.float32)
        self.obs_high = np.array([1.0] * n + [1.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0], dtype=np.float32)
        self._scalar_low = self.obs_low[n:].tolist()
        self._scalar_high = self.obs_high[n:].tolist()

    @property
    def obs_size(self) -> int:
        return self.num_rays + 7

    # ------------------------------------------------------------------ episode
    def reset(self, sim: Simulation, goal: tuple[float, float]) -> Measurement:
        self.goal = (float(goal[0]), float(goal[1]))
        m = self.measure(sim)
        self.initial_distance = self._prev_distance = m.distance
        state = sim.robot.state
        self._prev_xy = (state.x, state.y)
        self.path_length = 0.0
        self._progress.clear()
        return m

    def measure(self, sim: Simulation) -> Measurement:
        odometry = sim.sensors["odometry"].read()
        if self.config.pose_source == "odometry":
            x, y, yaw = (float(v) for v in odometry[:3])
        else:
            state = sim.robot.state
            x, y, yaw = state.x, state.y, state.yaw
        dx, dy = self.goal[0] - x, self.goal[1] - y
        heading = math.remainder(math.atan2(dy, dx) - yaw, 2 * math.pi)
        return Measurement(x, y, yaw, sim.sensors["lidar"].read(), odometry, sim.sensors["imu"].read(),
                           math.hypot(dx, dy), heading)

    def observation(self, m: Measurement) -> np.ndarray:
        """The observation vector (see the env docstring for the table)."""
        cfg = self.config
        n = self.num_rays
        obs = np.empty(self.obs_size, dtype=np.float32)
        np.divide(m.ranges, self.lidar_range, out=obs[:n])  # lidar ranges are within [0, max]
        lo, hi = self._scalar_low, self._scalar_high
        values = (
            m.heading_error / math.pi,
            float(m.odometry[3]) / cfg.max_speed,
            float(m.odometry[4]) / cfg.max_turn_rate,
            float(m.imu[0]) / self.gravity,
            float(m.imu[1]) / self.gravity,
            float(m.imu[5]) / cfg.max_turn_rate,
            m.distance / cfg.distance_scale,
        )
        obs[n:] = [min(max(v, a), b) for v, a, b in zip(values, lo, hi)]
        return obs

    def evaluate(self, sim: Simulation, m: Measurement, collision: bool) -> tuple[dict[str, float], bool, bool]:
        """Reward terms for the step that led to ``m``, and (terminated, truncated)."""
        w = self.config.reward
        x, y = m.x, m.y
        if self.config.pose_source == "odometry":  # path length is always measured on the true path
            x, y = sim.robot.state.x, sim.robot.state.y
        self.path_length += math.hypot(x - self._prev_xy[0], y - self._prev_xy[1])
        self._prev_xy = (x, y)
        progress = self._prev_distance - m.distance
        self._prev_distance = m.distance
        self._progress.append(progress)
        success = m.distance < self.config.goal_radius
        far = m.distance > w.heading_distance
        closest = float(m.ranges.min())
        stuck = (len(self._progress) == w.stuck_window and sum(self._progress) < w.stuck_progress and far)
        terms = {
            "progress": w.progress * progress,
            "goal": w.goal if success else 0.0,
            "collision": w.collision if collision else 0.0,
            "time": w.time,
            "heading": w.heading * (1.0 - abs(m.heading_error) / math.pi) if far else 0.0,
            "stuck": w.stuck if stuck else 0.0,
            "proximity": w.proximity * (w.proximity_distance - closest) if closest < w.proximity_distance else 0.0,
        }
        return terms, success, collision and not success
