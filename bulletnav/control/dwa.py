"""move_base with navfn and TrajectoryPlannerROS in DWA mode, as BARN runs it: a Policy.

:class:`MoveBaseDWA` is ROS 1's ``move_base`` (ros-planning/navigation ``noetic-devel``,
``move_base/src/move_base.cpp``) with ``navfn/NavfnROS`` as the global planner
(:mod:`bulletnav.planning.navfn`), ``base_local_planner/TrajectoryPlannerROS`` as the local one
(:mod:`bulletnav.control.trajectory_planner`), a global and a rolling local costmap
(:mod:`bulletnav.planning.costmap`) fed by the lidar, and move_base's default recoveries; its
parameters are BARN's files (:mod:`bulletnav.control.dwa_params`), which a user's YAML may
override. It drives any bulletnav env through ``obs``, ``info`` and ``env.unwrapped.scene``.

Timing. move_base's threads run on the simulated clock: the local costmap updates at its
``update_frequency`` (BARN: 20 Hz), the global one at its own (10 Hz), the planner at
``planner_frequency`` (20 Hz), the control cycle at ``controller_frequency`` (20 Hz), each on the
first env step at or after its due time, and the command holds between cycles as a robot's
base holds its last ``cmd_vel`` (until the Jackal's ``cmd_vel_timeout``, :data:`CMD_VEL_TIMEOUT`).
At bulletnav's 24 Hz control rate that is 20 cycles in 24 steps, and the dynamic window's
``sim_period`` is 1 / ``controller_frequency`` as in ROS. (The alternative, a cycle every env step
with the env's period as ``sim_period``, would change every rate move_base's parameters set.)

Frames. BARN's costmaps and goal are in the odometry frame, which starts at the robot's start
aligned with the world (BARN's ``run.py`` sends the goal (0, 10) in ``odom``, and its Jackal's
odometry fuses the IMU's absolute yaw): here the world frame, with the global costmap's window
(``origin_x``, ``origin_y``, ``width``, ``height``) placed relative to the episode's start and cut
to the world's floor where the world is smaller (its cells stay where ROS's would be). The goal's
yaw is 0, as BARN's goal quaternion (0, 0, 0, 1) has it; BARN's episode ends 1 m from the goal,
before ``xy_goal_tolerance`` matters.

Footprint. The costmaps and the trajectory checks use the parameters' ``footprint`` padded by
``footprint_padding`` (BARN: 0.42 x 0.33 m padded to 0.62 x 0.53 m), as move_base does, not the
simulated robot's outline (the Jackal preset's is 0.508 x 0.430 m).
"""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.control.dwa_params import CostmapParams, DWAParams, load_dwa_params
from bulletnav.control.trajectory_planner import (
    TrajectoryPlanner,
    TrajectoryPlannerROS,
    footprint_cost,
    shortest_angular_distance,
)
from bulletnav.control.trajectory_planner import warmup as planner_warmup
from bulletnav.planning.costmap import LayeredCostmap, footprint_from_radius, pad_footprint
from bulletnav.planning.costmap import warmup as costmap_warmup
from bulletnav.planning.navfn import make_plan
from bulletnav.planning.navfn import warmup as navfn_warmup

log = logging.getLogger(__name__)

__all__ = ["MoveBaseDWA", "DWAParams", "load_dwa_params", "dwa_env_kwargs", "CMD_VEL_TIMEOUT", "warmup"]

CMD_VEL_TIMEOUT = 0.25
"""Seconds a base keeps driving its last command without a new one: the Jackal's
``diff_drive_controller`` ``cmd_vel_timeout`` (jackal/jackal, ``jackal_control/config/control.yaml``)."""

PLANNING, CONTROLLING, CLEARING = "PLANNING", "CONTROLLING", "CLEARING"
"""move_base's states (``MoveBaseState``)."""
PLANNING_R, CONTROLLING_R, OSCILLATION_R = "PLANNING_R", "CONTROLLING_R", "OSCILLATION_R"
"""What started the recoveries (``RecoveryTrigger``)."""
ABORT_MESSAGES = {
    CONTROLLING_R: "Failed to find a valid control. Even after executing recovery behaviors.",
    PLANNING_R: "Failed to find a valid plan. Even after executing recovery behaviors.",
    OSCILLATION_R: "Robot is oscillating. Even after executing recovery behaviors.",
}
"""move_base's abort messages, by trigger."""


def dwa_env_kwargs(params: DWAParams, given: dict[str, Any] | None = None) -> dict[str, Any]:
    """The env keywords a DWA run adds to ``given``: ``min_speed`` = ``escape_vel`` (so the robot
    can back up when the planner escapes) unless ``given`` sets it or ``escape_vel`` is not negative."""
    escape = params.trajectory_planner.escape_vel
    return {} if "min_speed" in (given or {}) or escape >= 0.0 else {"min_speed": escape}


def warmup() -> None:
    """Compile (or load from numba's disk cache) every kernel the controller uses."""
    costmap_warmup()
    navfn_warmup()
    planner_warmup()


@dataclass
class _Rotation:
    """A running ``RotateRecovery``: one loop iteration per its ``frequency``."""

    start_angle: float
    current_angle: float
    got_180: bool = False


def _grid_size(length: float, resolution: float) -> int:
    """``Costmap2DROS``: ``(unsigned int)(length / resolution)``."""
    return max(1, int(length / resolution))


class MoveBaseDWA:
    """ROS 1 move_base + navfn + TrajectoryPlannerROS (DWA), as BARN runs it, for any env.

    A :class:`~bulletnav.policy.Policy`: it reads the lidar scan from ``obs`` (the first
    ``num_rays`` entries times the range), the goal from ``info["goal"]``, the pose from
    ``info["pose"]`` (``pose_source="truth"``) or the odometry estimate, the velocity from the
    odometry (as move_base reads ``odom``), and the lidar's layout, the robot's command limits and
    the floor from the scene view.

    After an abort (every recovery tried) it commands (0, 0) for the rest of the episode, as
    move_base leaves a BARN robot standing until the 100 s time-out; :attr:`stop_reason` says why.

    Args:
        scene: ``env.unwrapped.scene`` of the env it will drive.
        params: move_base's parameters, a shipped name (``"barn"``, ``"barn-2ms"``) or an override
            YAML laid over BARN's files (:func:`~bulletnav.control.dwa_params.load_dwa_params`);
            None: BARN's.
        pose_source: ``"truth"`` or ``"odometry"``.
    """

    def __init__(self, scene: Any, params: DWAParams | str | Path | None = None, pose_source: str = "truth") -> None:
        if pose_source not in ("truth", "odometry"):
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {pose_source!r}")
        self.scene = scene
        self.params = params if isinstance(params, DWAParams) else load_dwa_params(params)
        self.pose_source = pose_source
        self.plan_times: list[float] = []
        """Seconds of each navfn plan this episode."""
        self.replans = 0
        """Plans after the first this episode."""
        self.path: list[tuple[float, float]] | None = None
        """The global plan being followed (world points, m), for drawing."""
        self.stop_reason: str | None = None
        """Why the robot stopped for good: ``"aborted: <move_base's message>"`` or ``"goal reached"``; None while it drives."""
        self.events: list[tuple[float, str]] = []
        """(simulated s, what) for every state change and recovery this episode."""
        self.act_times: list[float] = []
        """Wall-clock seconds of each :meth:`act` this episode."""
        self._warned: set[str] = set()
        warmup()

    # ------------------------------------------------------------------ episode
    def reset(self, info: dict[str, Any]) -> None:
        """Start move_base on the episode that ``info`` (from ``env.reset``) begins: fresh
        costmaps, the goal sent, PLANNING."""
        scene, p = self.scene, self.params
        lidar = scene.sensors.lidar
        self.angles = np.asarray(lidar.angles, dtype=np.float64)
        self.n_rays = lidar.config.num_rays
        self.max_range = float(lidar.config.max_range)
        self.min_range = float(lidar.config.min_range)
        mount = scene.geometry.lidar_mount
        self.mount = (float(mount[0]), float(mount[1]))
        self.dt = float(scene.control_dt)
        (v_lo, v_hi), (w_lo, w_hi) = scene.command_limits
        escape = v_lo < 0.0
        self._check_limits(v_lo, v_hi, w_hi)
        pose = self._pose(info)
        self.goal = (math.nan, math.nan, 0.0)
        self.goal = (*self._goal_of(info, pose), 0.0)
        self.local = self._costmap(p.local_costmap, pose, rolling=True)
        self.global_ = self._costmap(p.global_costmap, pose, rolling=False)
        planner = TrajectoryPlanner(p.trajectory_planner, self.local.master, self.local.footprint, p.sim_period, escape)
        self.tc = TrajectoryPlannerROS(planner)
        mb = p.move_base
        self.now = 0.0
        self._steps = 0
        self.state = PLANNING
        self.run_planner = True
        self.recovery_trigger = PLANNING_R
        self.recovery_index = 0
        self.planning_retries = 0
        self.last_valid_plan = self.last_valid_control = self.last_oscillation_reset = 0.0
        self.oscillation_pose = pose
        self.new_global_plan = False
        self.latest_plan: np.ndarray | None = None
        self.cmd, self.cmd_time = (0.0, 0.0), 0.0
        self._rotation: _Rotation | None = None
        self._next = {"local": 0.0, "global": 0.0, "plan": 0.0, "control": 0.0, "rotate": 0.0}
        self._periods = {"local": _period(p.local_costmap.update_frequency), "global": _period(p.global_costmap.update_frequency),
                         "plan": _period(mb.planner_frequency), "control": _period(mb.controller_frequency),
                         "rotate": _period(p.rotate_recovery.frequency)}
        self.recoveries = self._recoveries()
        self.path, self.stop_reason, self.done = None, None, False
        self.plan_times, self.replans, self.events, self.act_times = [], 0, [], []

    def _check_limits(self, v_lo: float, v_hi: float, w_hi: float) -> None:
        tp = self.params.trajectory_planner
        if v_lo >= 0.0:
            self._warn_once("escape", "the env's robot cannot back up (its command limits start at v = %g m/s): the DWA "
                                      "skips its escape trajectory (escape_vel %g m/s); open the env with min_speed=%g to "
                                      "allow it", v_lo, tp.escape_vel, tp.escape_vel)
        elif v_lo > tp.escape_vel:
            self._warn_once("escape_clip", "escape_vel %g m/s is below the env's lowest speed %g m/s: escapes are clipped",
                            tp.escape_vel, v_lo)
        if tp.max_vel_x > v_hi + 1e-9 or max(tp.max_vel_theta, -tp.min_vel_theta) > w_hi + 1e-9:
            self._warn_once("limits", "the DWA samples up to %g m/s and %g rad/s, the env allows %g m/s and %g rad/s: "
                                      "its commands are clipped", tp.max_vel_x, max(tp.max_vel_theta, -tp.min_vel_theta),
                            v_hi, w_hi)

    def _warn_once(self, key: str, message: str, *args: Any) -> None:
        if key not in self._warned:
            self._warned.add(key)
            log.warning(message, *args)

    def _costmap(self, c: CostmapParams, pose: tuple[float, float, float], rolling: bool) -> LayeredCostmap:
        """A costmap as ``Costmap2DROS`` makes it from ``c``; the global one's window placed from
        the start (the odometry frame's origin) and cut to the floor."""
        res = c.resolution
        size_x, size_y = _grid_size(c.width, res), _grid_size(c.height, res)
        if rolling:
            ox, oy = pose[0] - size_x * res / 2, pose[1] - size_y * res / 2
        else:
            start = self.scene.start
            ox, oy = start[0] + c.origin_x, start[1] + c.origin_y
            fx0, fy0, fx1, fy1 = self.scene.layout.bounds
            x0, y0 = max(0, math.floor((fx0 - ox) / res)), max(0, math.floor((fy0 - oy) / res))
            x1, y1 = min(size_x, math.ceil((fx1 - ox) / res)), min(size_y, math.ceil((fy1 - oy) / res))
            if x1 > x0 and y1 > y0:  # the floor inside the window: keep only those cells (ROS's grid)
                ox, oy, size_x, size_y = ox + x0 * res, oy + y0 * res, x1 - x0, y1 - y0
        footprint = np.asarray(c.footprint, dtype=np.float64) if c.footprint else footprint_from_radius(c.robot_radius)
        layer, source = c.obstacle_layer, c.obstacle_layer.source
        obstacle_range = next(v for v in (source.obstacle_range, layer.obstacle_range, c.obstacle_range, 2.5) if v is not None)
        raytrace_range = next(v for v in (source.raytrace_range, layer.raytrace_range, c.raytrace_range, 3.0) if v is not None)
        track = c.track_unknown_space if layer.track_unknown_space is None else layer.track_unknown_space
        inflation = c.inflation_layer
        cm = LayeredCostmap.make(size_x, size_y, res, ox, oy, pad_footprint(footprint, c.footprint_padding),
                                 inflation.inflation_radius, inflation.cost_scaling_factor, obstacle_range, raytrace_range,
                                 rolling, track, layer.name, inflation.name, layer.footprint_clearing_enabled,
                                 inflation.inflate_unknown, source.marking, source.clearing, layer.combination_method)
        cm.obstacles.enabled, cm.inflation.enabled = layer.enabled, inflation.enabled
        return cm

    def _recoveries(self) -> list[str]:
        """``loadDefaultRecoveryBehaviors``: conservative reset, rotation, aggressive reset, rotation
        (the rotations only with ``clearing_rotation_allowed``)."""
        rotate = ["rotate_recovery"] if self.params.move_base.clearing_rotation_allowed else []
        return ["conservative_reset", *rotate, "aggressive_reset", *rotate]

    # ------------------------------------------------------------------ sensing
    def _pose(self, info: dict[str, Any]) -> tuple[float, float, float]:
        if self.pose_source == "odometry":
            x, y, yaw = (float(v) for v in self.scene.sensors.odometry.read()[:3])
            return x, y, yaw
        x, y, yaw = (float(v) for v in info["pose"])
        return x, y, yaw

    def _scan(self, obs: Any, pose: tuple[float, float, float]) -> tuple[tuple[float, float], np.ndarray]:
        """The lidar's position and its hits (N, 2), world frame; rays that read the maximum range
        (nothing hit) are left out, as laser_geometry's projection leaves them out."""
        state = obs["state"] if isinstance(obs, dict) else obs
        ranges = np.asarray(state[: self.n_rays], dtype=np.float64) * self.max_range
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        ox, oy = x + c * self.mount[0] - s * self.mount[1], y + s * self.mount[0] + c * self.mount[1]
        keep = (ranges < self.max_range * (1.0 - 1e-6)) & (ranges >= self.min_range)
        r, a = ranges[keep], self.angles[keep] + yaw
        return (ox, oy), np.stack([ox + r * np.cos(a), oy + r * np.sin(a)], axis=1)

    def _due(self, name: str) -> bool:
        """Whether the ``name`` loop's next run is due now; if so, its next time is set."""
        period = self._periods[name]
        if self.now + 1e-9 < self._next[name]:
            return False
        self._next[name] = (math.floor((self.now + 1e-9) / period) + 1) * period if period > 0 else self.now
        return True

    # ------------------------------------------------------------------ the loop
    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """One env step of move_base: the costmaps, the planner and the control cycle that are due."""
        t0 = time.perf_counter()
        self.now = self._steps * self.dt
        self._steps += 1
        pose = self._pose(info)
        goal = self._goal_of(info, pose)
        if goal != self.goal[:2]:
            self._new_goal((goal[0], goal[1], 0.0))
        odom = self.scene.sensors.odometry.read()
        vel = (float(odom[3]), float(odom[4]))
        origin, hits = self._scan(obs, pose)
        if self._due("local"):
            self.local.update_map(pose[0], pose[1], pose[2], origin, hits)
        if self._due("global"):
            self.global_.update_map(pose[0], pose[1], pose[2], origin, hits)
        if not self.done:
            if self.run_planner and self._due("plan"):
                self._plan(pose)
            if self._rotation is not None:
                if self._due("rotate"):
                    self._rotate_step(pose)
            elif self._due("control"):
                self._execute_cycle(pose, vel)
        if self.now - self.cmd_time > CMD_VEL_TIMEOUT + 1e-9:
            self.cmd = (0.0, 0.0)
        self.act_times.append(time.perf_counter() - t0)
        return self.scene.action_for(*self.cmd)

    def _goal_of(self, info: dict[str, Any], pose: tuple[float, float, float]) -> tuple[float, float]:
        """The goal to send: ``info["goal"]``; in a mission (``info["goals"]`` and ``"reached"``)
        the current goal while it is not reached, else the first one left (``goal_order`` fixed)
        or the nearest one left (free), so that move_base gets one goal at a time, as a mission
        executive would send them."""
        goals, reached = info.get("goals"), info.get("reached")
        if goals is None or reached is None or len(goals) < 2:
            return float(info["goal"][0]), float(info["goal"][1])
        left = [(float(g[0]), float(g[1])) for g, done in zip(goals, reached) if not done]
        if not left or self.goal[:2] in left:
            return self.goal[:2] if left else (float(info["goal"][0]), float(info["goal"][1]))
        if info.get("goal_order") == "fixed":
            return left[0]
        return min(left, key=lambda g: math.hypot(g[0] - pose[0], g[1] - pose[1]))

    def _new_goal(self, goal: tuple[float, float, float]) -> None:
        """A new goal preempts the current one (``executeCb``'s ``acceptNewGoal``; missions hand
        out their next goal this way): PLANNING from the first recovery, the patience clocks
        restarted."""
        self.goal = goal
        self.events.append((round(self.now, 3), f"new goal ({goal[0]:.2f}, {goal[1]:.2f})"))
        self.recovery_index = 0
        self._set_state(PLANNING, "new goal")
        self.run_planner = True
        self.last_valid_control = self.last_valid_plan = self.last_oscillation_reset = self.now
        self.planning_retries = 0
        self.stop_reason, self.done = None, False

    def _publish(self, v: float, w: float) -> None:
        self.cmd, self.cmd_time = (float(v), float(w)), self.now

    def _set_state(self, state: str, why: str = "") -> None:
        if state != self.state:
            self.events.append((round(self.now, 3), f"{self.state} -> {state}{': ' + why if why else ''}"))
        self.state = state

    def _plan(self, pose: tuple[float, float, float]) -> None:
        """The planner thread's pass (``planThread``): navfn on the global costmap; a plan hands
        itself to the controller, a failure while PLANNING counts against ``planner_patience``."""
        mb = self.params.move_base
        t0 = time.perf_counter()
        plan = make_plan(self.global_.master, (pose[0], pose[1]), (self.goal[0], self.goal[1]), self.params.navfn.allow_unknown)
        self.plan_times.append(time.perf_counter() - t0)
        if plan.found:
            poses = np.zeros((len(plan.path), 3))
            poses[:, :2] = plan.path
            poses[-1, 2] = self.goal[2]  # navfn's poses have yaw 0 (w = 1); the last is the goal pose itself
            self.latest_plan = poses
            if self.path is not None:
                self.replans += 1
            self.path = [(float(x), float(y)) for x, y in plan.path]
            self.last_valid_plan = self.now
            self.planning_retries = 0
            self.new_global_plan = True
            if self.run_planner:
                self._set_state(CONTROLLING)
            if mb.planner_frequency <= 0:
                self.run_planner = False
        elif self.state == PLANNING:
            self.planning_retries += 1
            retries = mb.max_planning_retries if mb.max_planning_retries >= 0 else 2**32 - 1
            if self.run_planner and (self.now > self.last_valid_plan + mb.planner_patience or self.planning_retries > retries):
                self._set_state(CLEARING, "no plan within planner_patience")
                self.run_planner = False
                self._publish(0.0, 0.0)
                self.recovery_trigger = PLANNING_R

    def _execute_cycle(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> None:
        """``MoveBase::executeCycle``."""
        mb = self.params.move_base
        if math.hypot(pose[0] - self.oscillation_pose[0], pose[1] - self.oscillation_pose[1]) >= mb.oscillation_distance:
            self.last_oscillation_reset = self.now
            self.oscillation_pose = pose
            if self.recovery_trigger == OSCILLATION_R:
                self.recovery_index = 0
        if self.new_global_plan:
            self.new_global_plan = False
            self.tc.set_plan(self.latest_plan)
            if self.recovery_trigger == PLANNING_R:
                self.recovery_index = 0
        if self.state == PLANNING:
            self.run_planner = True
        elif self.state == CONTROLLING:
            self._control(pose, vel)
        elif self.state == CLEARING:
            self._clearing(pose)

    def _control(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> None:
        mb = self.params.move_base
        if self.tc.reached_goal:
            self._finish("goal reached")
            return
        if mb.oscillation_timeout > 0.0 and self.last_oscillation_reset + mb.oscillation_timeout < self.now:
            self._publish(0.0, 0.0)
            self._set_state(CLEARING, "oscillation_timeout")
            self.recovery_trigger = OSCILLATION_R
        ok, (v, w) = self.tc.compute_velocity_commands(pose, vel)
        if ok:
            self.last_valid_control = self.now
            self._publish(v, w)
            if self.recovery_trigger == CONTROLLING_R:
                self.recovery_index = 0
        elif self.now > self.last_valid_control + mb.controller_patience:
            self._publish(0.0, 0.0)
            self._set_state(CLEARING, "no valid control within controller_patience")
            self.recovery_trigger = CONTROLLING_R
        else:
            self.last_valid_plan = self.now
            self.planning_retries = 0
            self._set_state(PLANNING, "no valid control")
            self._publish(0.0, 0.0)
            self.run_planner = True

    def _clearing(self, pose: tuple[float, float, float]) -> None:
        """The CLEARING state: the next recovery, or the abort when they are spent."""
        mb = self.params.move_base
        if mb.recovery_behavior_enabled and self.recovery_index < len(self.recoveries):
            name = self.recoveries[self.recovery_index]
            self.events.append((round(self.now, 3), f"recovery {self.recovery_index + 1}/{len(self.recoveries)}: {name}"))
            if name == "rotate_recovery":
                self._rotation = _Rotation(pose[2], pose[2])
                self._next["rotate"] = self.now
                if self._due("rotate"):
                    self._rotate_step(pose)
                return
            self._clear_costmaps(pose, name)
            self._after_recovery()
            return
        self.run_planner = False
        self._finish("aborted: " + ABORT_MESSAGES[self.recovery_trigger])

    def _after_recovery(self) -> None:
        """What executeCycle does once a recovery returns."""
        self.last_oscillation_reset = self.now
        self.last_valid_plan = self.now
        self.planning_retries = 0
        self._set_state(PLANNING, "after a recovery")
        self.recovery_index += 1

    def _clear_costmaps(self, pose: tuple[float, float, float], name: str) -> None:
        """``ClearCostmapRecovery::runBehavior``: the named layers of the affected costmaps cleared
        outside (or inside) a square of ``reset_distance`` around the robot."""
        p = self.params
        cfg = p.conservative_reset if name == "conservative_reset" else p.aggressive_reset
        distance = p.move_base.conservative_reset_dist if name == "conservative_reset" else 4 * p.local_costmap.circumscribed_radius
        maps = {"local": [self.local], "global": [self.global_], "both": [self.global_, self.local]}[cfg.affected_maps]
        cleared = [cm.clear_layers(pose[0], pose[1], distance, cfg.layer_names, cfg.invert_area_to_clear) for cm in maps]
        if not any(cleared):
            self.events.append((round(self.now, 3), f"{name} cleared nothing: its layer_names {list(cfg.layer_names)} "
                                                    f"name no layer (the obstacle layer is {self.local.obstacles.name!r})"))

    def _rotate_step(self, pose: tuple[float, float, float]) -> None:
        """One iteration of ``RotateRecovery::runBehavior``'s loop: turn left toward 180 degrees
        and back to the start, at a rate that can stop in time within ``min_in_place_vel_theta`` ..
        ``max_vel_theta``, ending early when the rotation left would bring the footprint onto a
        lethal cell of the local costmap."""
        rot, tp, rr = self._rotation, self.params.trajectory_planner, self.params.rotate_recovery
        tolerance = tp.yaw_goal_tolerance
        if rot.got_180 and abs(shortest_angular_distance(rot.current_angle, rot.start_angle)) <= tolerance:
            self._end_rotation()
            return
        rot.current_angle = pose[2]
        if not rot.got_180:
            to_180 = abs(shortest_angular_distance(rot.current_angle, rot.start_angle + math.pi))
            dist_left = math.pi + to_180
            rot.got_180 = to_180 < tolerance
        else:
            dist_left = abs(shortest_angular_distance(rot.current_angle, rot.start_angle))
        cm = self.local.master
        costs = cm.costs.reshape(-1)
        sim_angle = 0.0
        while sim_angle < dist_left:
            if footprint_cost(pose[0], pose[1], rot.current_angle + sim_angle, self.local.footprint, costs, cm.size_x,
                              cm.size_y, cm.origin_x, cm.origin_y, cm.resolution) < 0.0:
                self.events.append((round(self.now, 3), "rotate_recovery: a collision ahead, stopped"))
                self._end_rotation()
                return
            sim_angle += rr.sim_granularity
        vel = min(max(math.sqrt(2 * tp.acc_lim_theta * dist_left), tp.min_in_place_vel_theta), tp.max_vel_theta)
        self._publish(0.0, vel)

    def _end_rotation(self) -> None:
        self._rotation = None
        self._next["control"] = self.now  # ros::Rate, behind after the blocking recovery, does not sleep
        self._after_recovery()

    def _finish(self, reason: str) -> None:
        """``resetState`` and the action's end: the planner stopped, zero velocity from now on."""
        self.run_planner = False
        self._set_state(PLANNING, reason)
        self.recovery_index = 0
        self.recovery_trigger = PLANNING_R
        self._publish(0.0, 0.0)
        self.stop_reason = reason
        self.done = True


def _period(frequency: float) -> float:
    """Seconds between runs of a loop at ``frequency`` Hz (0: whenever asked)."""
    return 1.0 / frequency if frequency > 0 else 0.0
