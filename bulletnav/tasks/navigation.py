"""Point-goal navigation (the article's task): drive to one goal point without touching anything.

Observation (``lidar_rays + 7`` float32, see the env docstring for the table), the article's
seven named reward terms, success inside ``goal_radius``, a collision truncating (or, with
``collision_terminates``, terminating) the episode.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import fields, replace
from typing import TYPE_CHECKING, Any

import numpy as np
from gymnasium import spaces

from bulletnav.config import EnvConfig
from bulletnav.sim.sampler import sample_start_goal
from bulletnav.tasks.base import Task, pose_option
from bulletnav.tasks.guidance import PathGuide

if TYPE_CHECKING:
    from bulletnav.tasks.view import TaskScene


class NavigationTask(Task):
    """Go to a goal point: observation, reward and termination.

    The start and goal come, in this order of precedence, from ``reset`` options
    (``start`` = (x, y, yaw), ``goal`` = (x, y)), the YAML layout's ``start``/``goal``, or
    :func:`~bulletnav.sim.sampler.sample_start_goal`.
    """

    reward_terms = ("progress", "goal", "collision", "time", "heading", "stuck", "proximity")

    def __init__(self, config: EnvConfig, scene: TaskScene) -> None:
        super().__init__(config, scene)
        scene.sensors.require("lidar", "imu", "odometry", by="the navigation task")
        t = config.task
        self.task = t
        # weights as floats, so every term (and info entry) is a float whatever the config holds
        self.reward_weights = w = replace(t.reward, **{f.name: float(getattr(t.reward, f.name))
                                                       for f in fields(t.reward) if f.name != "stuck_window"})
        self._max_speed, self._max_turn_rate, self._distance_scale = t.max_speed, t.max_turn_rate, t.distance_scale
        self._mover_weight = (w.mover_proximity, w.mover_proximity_distance) if w.mover_proximity else None
        if self._mover_weight is not None:  # an optional term: listed only when it is on
            names = type(self).reward_terms  # right after "proximity", where reward() puts it
            at = names.index("proximity") + 1
            self.reward_terms = (*names[:at], "mover_proximity", *names[at:])
        self._goal_radius = t.goal_radius
        self.lidar_range = config.sensors.lidar.max_range
        self.num_rays = n = config.sensors.lidar.num_rays
        self.gravity = config.physics.gravity
        self.goals = ((0.0, 0.0),)
        self.initial_distance = 0.0
        """Straight-line start-goal distance this episode (m)."""
        self.path_length = 0.0
        """Metres driven this episode (ground truth)."""
        self.distance = 0.0
        """Distance to the goal after the last step (m), from the pose the task observes with."""
        self.collision = False
        self._prev_distance = 0.0
        self._prev_xy = (0.0, 0.0)
        self._progress: deque[float] = deque(maxlen=w.stuck_window)
        self.obs_low = np.array([0.0] * n + [-1.0, -2.0, -2.0, -3.0, -3.0, -3.0, 0.0], dtype=np.float32)
        self.obs_high = np.array([1.0] * n + [1.0, 2.0, 2.0, 3.0, 3.0, 3.0, 3.0], dtype=np.float32)
        self._scalar_bounds = list(zip(self.obs_low[n:].tolist(), self.obs_high[n:].tolist()))
        self._history_len = t.lidar_history - 1
        if self._history_len:  # earlier scans, appended after the scalars
            self.obs_low = np.concatenate([self.obs_low, np.zeros(n * self._history_len, dtype=np.float32)])
            self.obs_high = np.concatenate([self.obs_high, np.ones(n * self._history_len, dtype=np.float32)])
        self._history: deque[list[float]] = deque(maxlen=max(self._history_len, 1))
        self._guided = t.guidance == "floorplan"
        if self._guided:  # path cost / distance_scale, sin and cos of the lookahead point's bearing
            self.obs_low = np.concatenate([self.obs_low, np.array([0.0, -1.0, -1.0], dtype=np.float32)])
            self.obs_high = np.concatenate([self.obs_high, np.array([3.0, 1.0, 1.0], dtype=np.float32)])
        self.guide: PathGuide | None = None
        """The floor-plan path guide (``guidance="floorplan"``; :mod:`bulletnav.tasks.guidance`)."""
        self.path_cost = 0.0
        """Guided tasks: the path cost (m) from the robot to the target after the last step."""
        self.lookahead = (0.0, 0.0)
        """Guided tasks: the lookahead point on the path (world x, y; m)."""
        self._guide_heading = 0.0
        self._target = 0
        self._odometry_pose = t.pose_source == "odometry"
        # the per-step code reads these directly: fewer lookups on a path that runs every step
        self._lidar, self._imu_sensor, self._odometry_sensor = scene.sensors.lidar, scene.sensors.imu, scene.sensors.odometry
        self._robot = scene.robot
        self._weights = (w.progress, w.goal, w.collision, w.time, w.heading, w.heading_distance, w.stuck,
                         w.stuck_window, w.stuck_progress, w.proximity, w.proximity_distance)
        # per-step measurement, taken once in after_step
        self._x = self._y = self._yaw = self._heading = 0.0
        self._range_list: list[float] = [0.0] * n
        self._odometry: list[float] = [0.0] * 5
        self._imu: list[float] = [0.0] * 6
        self._success = False

    def observation_space(self) -> spaces.Box:
        return spaces.Box(self.obs_low, self.obs_high, dtype=np.float32)

    # ------------------------------------------------------------------ episode
    def initialize_episode(self, scene: TaskScene, rng: np.random.Generator, options: dict[str, Any]) -> None:
        start, self.goals = self._choose_episode(scene, rng, options)
        self._begin(scene, start, rng)

    def _choose_episode(self, scene: TaskScene, rng: np.random.Generator, options: dict[str, Any]
                        ) -> tuple[tuple[float, float, float], tuple[tuple[float, float], ...]]:
        """The episode's start pose and goal(s), from options, the layout or the sampler."""
        layout = scene.layout
        assert layout is not None  # the env chose it before calling this
        start: tuple[float, float, float] | None = layout.start
        goal: tuple[float, float] | None = layout.goal
        if start is None or goal is None:
            sampled_start, sampled_goal = sample_start_goal(scene.free_space, rng, self.config.sampler)
            start = start or sampled_start
            goal = goal or sampled_goal
        if "start" in options:
            start = pose_option(options["start"], 3, "start")  # type: ignore[assignment]
        if "goal" in options:
            goal = pose_option(options["goal"], 2, "goal")  # type: ignore[assignment]
        return start, ((float(goal[0]), float(goal[1])),)

    def _begin(self, scene: TaskScene, start: tuple[float, float, float], rng: np.random.Generator) -> None:
        """Place the robot at ``start`` and reset the per-episode state (goals already chosen)."""
        scene.place_robot(start, rng, self.goals)
        if self._guided:
            if self.guide is None or self.guide.free is not scene.free_space:  # once per layout
                self.guide = PathGuide(scene.free_space, scene.geometry.radius)
            self.guide.set_goals(self.goals)
        self._choose_target(start)
        self._measure(scene)
        self.collision = self._success = False
        self.initial_distance = self.distance
        self._prev_distance = self._potential()
        state = scene.robot.state
        self._prev_xy = (state.x, state.y)
        self.path_length = 0.0
        self._progress.clear()
        if self._history_len:  # before the first step, the earlier scans are the first one
            self._history.clear()
            self._history.extend([self._range_list] * self._history_len)

    def _head_for(self, scene: TaskScene, goal: tuple[float, float]) -> None:
        """Head for ``goal`` (x, y m) from now on, mid-episode: the guide, the distance, the
        heading error and the progress term are measured to it from this moment."""
        self.goals = ((float(goal[0]), float(goal[1])),)
        if self.guide is not None:
            self.guide.set_goals(self.goals)
        self._measure(scene)
        self.initial_distance = self.distance
        self._prev_distance = self._potential()
        self._progress.clear()

    def _choose_target(self, start: tuple[float, float, float]) -> None:
        """Which goal the episode heads for first (the only one here)."""

    def _potential(self) -> float:
        """What the progress term measures: the path cost with guidance, else the straight distance."""
        return self.path_cost if self._guided else self.distance

    def after_step(self, scene: TaskScene) -> None:
        if self._history_len:
            self._history.appendleft(self._range_list)  # the scan of the step before, newest first
        self.collision = scene.in_collision()
        self._measure(scene)

    def _measure(self, scene: TaskScene) -> None:
        odometry = self._odometry = self._odometry_sensor.floats()
        if self._odometry_pose:
            x, y, yaw = odometry[0], odometry[1], odometry[2]
        else:
            state = self._robot.state
            x, y, yaw = state.x, state.y, state.yaw
        goal = self.goal  # the goal headed for now (the only one here)
        dx, dy = goal[0] - x, goal[1] - y
        self._x, self._y = x, y
        self._heading = math.remainder(math.atan2(dy, dx) - yaw, 2 * math.pi)
        self._range_list = self._lidar.floats()  # float32 values, exactly, as Python floats
        self._imu = self._imu_sensor.floats()
        self.distance = math.hypot(dx, dy)
        if self._guided:
            cost, lx, ly = self.guide.query(self._target, x, y)
            if cost == math.inf:  # nothing passable near: the straight line
                cost, lx, ly = self.distance, goal[0], goal[1]
            self.path_cost, self.lookahead = cost, (lx, ly)
            self._guide_heading = math.atan2(ly - y, lx - x) - yaw

    # ------------------------------------------------------------------ step
    def observe(self, scene: TaskScene) -> np.ndarray:
        """The observation vector (see the env docstring for the table).

        Built as one list of Python floats and rounded to float32 once: each lidar entry is
        the float32 range divided by ``lidar_range`` in double precision and then rounded,
        which equals float32 division (double has more than twice float32's precision), and
        it costs one NumPy call instead of four on a path that runs every step.
        """
        scale = self.lidar_range
        values = [r / scale for r in self._range_list]
        _, _, _, v, w = self._odometry
        ax, ay, _, _, _, gz = self._imu
        g, max_turn = self.gravity, self._max_turn_rate
        scalars = (self._heading / math.pi, v / self._max_speed, w / max_turn, ax / g, ay / g, gz / max_turn,
                   self.distance / self._distance_scale)
        values += [lo if x < lo else hi if x > hi else x for x, (lo, hi) in zip(scalars, self._scalar_bounds)]
        for earlier in self._history if self._history_len else ():
            values += [r / scale for r in earlier]
        if self._guided:
            values += [min(self.path_cost / self._distance_scale, 3.0), math.sin(self._guide_heading),
                       math.cos(self._guide_heading)]
        return np.array(values, dtype=np.float32)

    def reward(self, scene: TaskScene) -> dict[str, float]:
        wp, wg, wc, wt, wh, far_from, ws, window, stuck_progress, wx, near = self._weights
        if self._odometry_pose:  # path length is always measured on the true path
            state = self._robot.state
            x, y = state.x, state.y
        else:
            x, y = self._x, self._y
        px, py = self._prev_xy
        self.path_length += math.hypot(x - px, y - py)
        self._prev_xy = (x, y)
        distance = self.distance
        potential = self.path_cost if self._guided else distance
        progress = self._prev_distance - potential
        self._prev_distance = potential
        recent = self._progress
        recent.append(progress)
        success = self._success = distance < self._goal_radius
        far = distance > far_from
        closest = min(self._range_list)
        heading = math.remainder(self._guide_heading, 2 * math.pi) if self._guided else self._heading
        stuck = len(recent) == window and sum(recent) < stuck_progress and far
        terms = {
            "progress": wp * progress,
            "goal": wg if success else 0.0,
            "collision": wc if self.collision else 0.0,
            "time": wt,
            "heading": wh * (1.0 - abs(heading) / math.pi) if far else 0.0,
            "stuck": ws if stuck else 0.0,
            "proximity": wx * (near - closest) if closest < near else 0.0,
        }
        if self._mover_weight is not None:
            weight, within = self._mover_weight
            gap = scene.nearest_mover()
            terms["mover_proximity"] = weight * (within - gap) if gap < within else 0.0
        return terms

    def end(self, scene: TaskScene) -> tuple[bool, bool, str | None]:
        if self._success:
            return True, False, "success"
        if self.collision:
            return (True, False, "collision") if self.task.collision_terminates else (False, True, "collision")
        return False, False, None

    def info(self, scene: TaskScene) -> dict[str, Any]:
        state = scene.robot.state
        out = {
            "distance_to_goal": self.distance, "collision": self.collision, "is_success": self._success,
            "path_length": self.path_length, "initial_distance": self.initial_distance, "goal": self.goal,
            "pose": np.array((state.x, state.y, state.yaw)),
        }
        if self._guided:
            out["path_cost"] = self.path_cost
        return out
