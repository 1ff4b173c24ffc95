"""Multi-goal missions: visit ``goals`` points, in the given order (``fixed``) or any (``free``).

The navigation task's observation, reward and rules, applied to the current target, plus:

- **Target.** ``fixed``: the first goal not yet reached. ``free``: the nearest goal not yet
  reached (straight-line distance from the pose the task observes with), re-chosen every
  step, so the progress term is measured toward the nearest remaining goal. With
  ``guidance="floorplan"`` it is instead the next goal of the shortest tour on the floor plan's
  path costs, fixed at reset (:mod:`bulletnav.tasks.guidance`). A goal counts as reached inside
  ``goal_radius``, like the single goal.
- **Reward.** Every term of :class:`NavigationTask` toward the target, and ``subgoal``
  (``reward_subgoal``, +10) once for each goal reached before the last one; the last one earns
  ``goal`` (+50) and ends the episode with success.
- **Observation.** The navigation vector (43 floats), then the target in the robot frame and
  the share of goals left: ``distance / distance_scale`` (clipped to [0, 3]), ``sin`` and
  ``cos`` of its bearing, ``goals left / K``; in ``free`` order then a block of K slots in the
  episode's goal order, each ``(distance / distance_scale, sin, cos, 1)`` for a goal still to
  visit and ``(0, 0, 0, 0)`` for one reached (the last entry is the mask).
- **Episode length.** Truncated after ``steps_per_goal * K`` control steps (1,200 per goal).
- **Goals** come from ``reset(options={"goals": [[x, y], ...]})`` or a YAML layout's ``goals:``
  list (as many as the env's ``goals``, 1 to 8 unless ``BULLETNAV_MAX_GOALS`` raises it), or are
  sampled connected, at least ``min_goal_separation`` (1.5 m) from each other and the start,
  each leg ``min_goal_distance``-``max_goal_distance`` long (:func:`~bulletnav.sim.sampler.sample_mission`).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from bulletnav import limits
from bulletnav.config import EnvConfig
from bulletnav.planning.tour import tour
from bulletnav.sim.sampler import sample_mission
from bulletnav.tasks.base import pose_option
from bulletnav.tasks.navigation import NavigationTask

if TYPE_CHECKING:
    from bulletnav.tasks.view import TaskScene


class MissionTask(NavigationTask):
    """Visit several goals (see the module docstring)."""

    reward_terms = (*NavigationTask.reward_terms, "subgoal")

    def __init__(self, config: EnvConfig, scene: TaskScene) -> None:
        super().__init__(config, scene)
        t = config.task
        self.k = t.goals
        self.order = t.goal_order
        self.max_steps = t.steps_per_goal * t.goals
        self._w_subgoal = float(t.reward.subgoal)
        self._separation = t.min_goal_separation
        block = 4 + (4 * self.k if self.order == "free" else 0)
        low = [0.0, -1.0, -1.0, 0.0] + [0.0, -1.0, -1.0, 0.0] * (self.k if self.order == "free" else 0)
        high = [3.0, 1.0, 1.0, 1.0] * (block // 4)
        self.mission_offset = len(self.obs_low)
        """Index of the first mission entry in the observation."""
        self.obs_low = np.concatenate([self.obs_low, np.array(low, dtype=np.float32)])
        self.obs_high = np.concatenate([self.obs_high, np.array(high, dtype=np.float32)])
        self.reached: list[bool] = []
        self.reached_at: list[int | None] = []
        """Control step at which each goal was reached (None: not yet)."""
        self._target = 0
        self._steps = 0

    @property
    def goal(self) -> tuple[float, float] | None:
        return self.goals[self._target] if self.goals else None

    @property
    def goals_reached(self) -> int:
        return sum(self.reached)

    # ------------------------------------------------------------------ episode
    def _choose_episode(self, scene: TaskScene, rng: np.random.Generator, options: dict[str, Any]):
        layout = scene.layout
        assert layout is not None
        start = pose_option(options["start"], 3, "start") if "start" in options else layout.start
        if "goals" in options or layout.goals:
            goals = self._goal_option(options.get("goals", layout.goals), scene)
            if start is None:
                start, _ = sample_mission(scene.free_space, rng, self.config.sampler, 0, self._separation)
            return start, goals
        start, goals = sample_mission(scene.free_space, rng, self.config.sampler, self.k, self._separation, start=start)
        return start, goals

    def _goal_option(self, value: Any, scene: TaskScene) -> tuple[tuple[float, float], ...]:
        try:
            goals = [pose_option(g, 2, "goals") for g in value]
        except TypeError:
            raise ValueError(f"options['goals'] must be a list of [x, y] points, got {value!r}") from None
        if not goals:
            raise ValueError("options['goals'] must hold at least one goal, got none")
        limits.check("goals", len(goals), "options['goals'] (entries)")
        if len(goals) != self.k:
            raise ValueError(f"options['goals'] has {len(goals)} goals but the env was made with goals={self.k}")
        layout = scene.layout
        x0, y0, x1, y1 = layout.bounds
        for g in goals:
            if not layout.on_floor(g[0], g[1]):
                raise ValueError(f"options['goals']: {list(g)} lies outside the floor (x in [{x0}, {x1}], y in [{y0}, {y1}])")
            for i, o in enumerate(layout.obstacles):
                if float(o.distance(np.array(g[0]), np.array(g[1]))) <= 0.0:
                    raise ValueError(f"options['goals']: {list(g)} lies inside obstacle {i} ({o.label or o.kind})")
        return tuple((float(g[0]), float(g[1])) for g in goals)

    def _begin(self, scene: TaskScene, start: tuple[float, float, float], rng: np.random.Generator) -> None:
        self.reached = [False] * len(self.goals)
        self.reached_at = [None] * len(self.goals)
        self._steps = 0
        self._target = 0
        self.plan = tuple(range(len(self.goals)))
        super()._begin(scene, start, rng)

    def _choose_target(self, start: tuple[float, float, float]) -> None:
        if self.order != "free":
            return
        if self.guide is None:
            self._target = self._nearest(start[0], start[1])
            return
        # guided: the shortest tour on the path-cost fields, followed goal by goal
        points = [(start[0], start[1]), *self.goals]
        dist = [[0.0 if i == j else self._leg(points[i], j - 1) for j in range(len(points))]
                for i in range(len(points))]
        _, seq = tour(dist, "free")
        self.plan = tuple(j - 1 for j in seq)
        self._target = self.plan[0]

    def _leg(self, point: tuple[float, float], goal: int) -> float:
        cost = self.guide.query(goal, point[0], point[1])[0] if goal >= 0 else 0.0
        if cost == math.inf:
            gx, gy = self.goals[goal]
            cost = math.hypot(gx - point[0], gy - point[1])
        return cost

    def _next_target(self) -> int:
        if self.order == "free" and self.guide is None:
            return self._nearest(self._x, self._y)
        return next(i for i in self.plan if not self.reached[i])

    def _nearest(self, x: float, y: float) -> int:
        left = [i for i, done in enumerate(self.reached) if not done]
        return min(left, key=lambda i: math.hypot(self.goals[i][0] - x, self.goals[i][1] - y))

    # ------------------------------------------------------------------ step
    def after_step(self, scene: TaskScene) -> None:
        self._steps += 1
        if self.order == "free" and self.guide is None:
            target = self._nearest(self._x, self._y)
            if target != self._target:  # a nearer goal now: measure progress toward it from here
                self._target = target
                super().after_step(scene)
                self._prev_distance = self._potential()
                return
        super().after_step(scene)

    def reward(self, scene: TaskScene) -> dict[str, float]:
        terms = super().reward(scene)
        terms["subgoal"] = 0.0
        if self._success:  # inside the radius of the current target
            self.reached[self._target] = True
            self.reached_at[self._target] = self._steps
            if not all(self.reached):
                terms["goal"] = 0.0
                terms["subgoal"] = self._w_subgoal
                self._success = False
                self._target = self._next_target()
                self._measure(scene)
                self._prev_distance = self._potential()
                self._progress.clear()
        return terms

    def end(self, scene: TaskScene) -> tuple[bool, bool, str | None]:
        terminated, truncated, reason = super().end(scene)
        if not (terminated or truncated) and self._steps >= self.max_steps:
            return False, True, "time_limit"
        return terminated, truncated, reason

    def observe(self, scene: TaskScene) -> np.ndarray:
        base = super().observe(scene)
        scale, x, y, yaw = self._distance_scale, self._x, self._y, self._yaw_now()
        left = len(self.reached) - sum(self.reached)
        values = [min(self.distance / scale, 3.0), math.sin(self._heading), math.cos(self._heading),
                  left / max(len(self.reached), 1)]
        if self.order == "free":
            for (gx, gy), done in zip(self.goals, self.reached):
                if done:
                    values += [0.0, 0.0, 0.0, 0.0]
                else:
                    bearing = math.atan2(gy - y, gx - x) - yaw
                    values += [min(math.hypot(gx - x, gy - y) / scale, 3.0), math.sin(bearing), math.cos(bearing), 1.0]
        return np.concatenate([base, np.array(values, dtype=np.float32)])

    def _yaw_now(self) -> float:
        if self._odometry_pose:
            return float(self._odometry[2])
        return self._robot.state.yaw

    def info(self, scene: TaskScene) -> dict[str, Any]:
        out = super().info(scene)
        out.update(goals=self.goals, goals_reached=self.goals_reached, goals_total=len(self.goals),
                   reached=tuple(self.reached), reached_at=tuple(self.reached_at), goal_order=self.order)
        return out
