"""BARN's episode rules on top of point-goal navigation (task name ``"barn"``).

As BARN's ``run.py`` (github.com/Daffan/the-barn-challenge, commit bf5a226) defines them, read
from the robot's ground-truth pose after every control step (BARN polls Gazebo's model state):

- BARN's clock starts at the step the robot is first :data:`~bulletnav.barn.metric.CLOCK_START_M`
  (0.1 m) from its start (run.py lines 133-141);
- the episode ends, in run.py's order of precedence (lines 162-169), in a collision (any contact
  with a cylinder or wall; it terminates, or truncates with ``collision_terminates=False``), a
  time-out (clock >= 100 s; truncates) or success (within 1 m of the goal; terminates);
- ``info["barn_time_s"]`` (BARN's clock) and ``info["barn_metric"]`` (BARN's score,
  :func:`bulletnav.barn.metric.barn_metric`, t_opt from run.py's start) come with the last step.

One thing BARN leaves open: run.py waits for the first 0.1 m of motion without a limit; here a
robot that has not moved 0.1 m after 100 s of simulated time ends the episode as a time-out too.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from bulletnav.barn.metric import CLOCK_START_M, GOAL_RADIUS_M, START, TIME_LIMIT_S, barn_metric, optimal_time
from bulletnav.tasks import register_task
from bulletnav.tasks.navigation import NavigationTask

if TYPE_CHECKING:
    from bulletnav.config import EnvConfig
    from bulletnav.tasks.view import TaskScene


class BarnTask(NavigationTask):
    """Point-goal navigation scored and ended by BARN's rules (observation and reward unchanged)."""

    def __init__(self, config: EnvConfig, scene: TaskScene) -> None:
        super().__init__(config, scene)
        self._dt = config.physics.control_dt
        self.t_opt = math.nan
        """BARN's optimal time of this episode's world (s)."""
        self._reset_clock()

    def _reset_clock(self) -> None:
        self.elapsed_s = 0.0
        """Simulated seconds since the episode began."""
        self.clock_start_s: float | None = None
        """Simulated time (s) at which BARN's clock started; None before the first 0.1 m."""
        self.barn_outcome: str | None = None
        """``"success"``, ``"collision"`` or ``"timeout"`` once the episode ended."""
        self._start_xy = (0.0, 0.0)

    def set_reference(self, path_cells: np.ndarray) -> None:
        """The world's reference path (BARN grid cells): t_opt from run.py's start."""
        self.t_opt = optimal_time(path_cells, START[:2])

    def initialize_episode(self, scene: TaskScene, rng: np.random.Generator, options: dict[str, Any]) -> None:
        super().initialize_episode(scene, rng, options)
        self._reset_clock()
        state = scene.robot.state
        self._start_xy = (state.x, state.y)

    def after_step(self, scene: TaskScene) -> None:
        super().after_step(scene)
        self.elapsed_s += self._dt
        if self.clock_start_s is None:
            state = scene.robot.state
            if math.hypot(state.x - self._start_xy[0], state.y - self._start_xy[1]) >= CLOCK_START_M:
                self.clock_start_s = self.elapsed_s

    @property
    def barn_time_s(self) -> float:
        """BARN's clock (s): 0 until the robot has moved 0.1 m from its start."""
        return 0.0 if self.clock_start_s is None else self.elapsed_s - self.clock_start_s

    def end(self, scene: TaskScene) -> tuple[bool, bool, str | None]:
        state = scene.robot.state
        goal = self.goal
        near_goal = math.hypot(goal[0] - state.x, goal[1] - state.y) <= GOAL_RADIUS_M
        started = self.clock_start_s is not None
        if self.collision:
            self.barn_outcome = "collision"
            return (True, False, "collision") if self.task.collision_terminates else (False, True, "collision")
        if (started and self.barn_time_s >= TIME_LIMIT_S) or (not started and self.elapsed_s >= TIME_LIMIT_S):
            self.barn_outcome = "timeout"
            return False, True, "timeout"
        if near_goal and started:
            self.barn_outcome = "success"
            return True, False, "success"
        return False, False, None

    def info(self, scene: TaskScene) -> dict[str, Any]:
        out = super().info(scene)
        out["barn_time_s"] = self.barn_time_s
        if self.barn_outcome is not None:
            out["is_success"] = self.barn_outcome == "success"
            out["barn_metric"] = barn_metric(self.barn_outcome == "success", self.barn_time_s, self.t_opt)
        return out


register_task("barn", BarnTask)
