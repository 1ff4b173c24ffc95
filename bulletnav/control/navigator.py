"""Classical navigation: PID go-to-goal with lidar avoidance, optionally following A* or RRT
plans made on an occupancy grid built from the lidar as the robot drives."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from bulletnav.control.pid import PID
from bulletnav.planning import OccupancyGrid, astar, rrt
from bulletnav.planning.mapping import LidarMapper


@dataclass(frozen=True)
class ControllerConfig:
    """The article's simple controller: steer at the target, blend in avoidance when close."""

    max_speed: float = 0.5
    """Top forward speed (m/s)."""
    max_turn_rate: float = 1.5
    """Top yaw rate (rad/s)."""
    kp: float = 2.0
    """Heading gain (rad/s per rad)."""
    ki: float = 0.1
    """Heading integral gain (rad/s per rad*s)."""
    kd: float = 0.05
    """Heading derivative gain (rad/s per rad/s)."""
    safety_distance: float = 0.5
    """Front clearance (m) below which the avoidance heading is blended in with weight 1 - d/safety."""
    stop_distance: float = 0.05
    """Front clearance (m) at which forward speed reaches zero."""
    front_half_angle: float = 35.0
    """Half-width of the front sector (deg) whose closest range counts as 'ahead'."""
    goal_slowdown: float = 0.8
    """Distance to the goal (m) inside which the speed ramps down."""
    side_margin: float = 0.2
    """Clearance (m) beside the robot under which the heading is blended toward the obstacle's tangent."""
    footprint_radius: float = 0.2
    """Robot footprint radius (m) around the body centre; clearances are measured beyond it."""
    lidar_offset: float = 0.1
    """Lidar position ahead of the body centre (m)."""


@dataclass(frozen=True)
class NavigatorConfig:
    """Planning and replanning on the lidar map."""

    planner: str = "astar"
    """'none' (PID straight at the goal), 'astar' or 'rrt'."""
    resolution: float = 0.2
    """Occupancy-grid cell size (m)."""
    inflation: float = 0.2
    """Obstacles grow by this (m) before planning: the robot's radius."""
    preferred_margin: float = 0.1
    """Plans are first tried with this much extra inflation (m), falling back to ``inflation``
    alone when that leaves no path: a wide berth where there is room, tight gaps where not."""
    lookahead: float = 0.6
    """The controller steers at the first path point at least this far away (m)."""
    replan_every: int = 24
    """Replan at least every this many control steps (1 s at 24 Hz)."""
    pose_source: str = "truth"
    """Robot pose used for mapping and steering: 'truth' or 'odometry'."""
    rrt_step: float = 0.5
    """RRT extension step (m)."""
    rrt_time_budget: float = 0.05
    """RRT budget per plan (s)."""
    controller: ControllerConfig = field(default_factory=ControllerConfig)

    def __post_init__(self) -> None:
        if self.planner not in ("none", "astar", "rrt"):
            raise ValueError(f"planner must be 'none', 'astar' or 'rrt', got {self.planner!r}")
        if self.pose_source not in ("truth", "odometry"):
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {self.pose_source!r}")


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2 * math.pi)


class GoToGoal:
    """Heading PID toward a target point plus forward speed, with the article's lidar
    avoidance: when the closest clearance ahead is under ``safety_distance``, the desired
    heading is blended toward the side with more room with weight ``1 - d / safety``.

    Clearances are ranges minus the distance from the lidar to the edge of the robot's
    footprint along each ray, so a box 5 cm beside the wheel reads 5 cm, not 21. The same
    blend keeps the sides clear: an obstacle closer than ``side_margin`` beside the robot
    pulls the heading toward its tangent (parallel to it) with weight ``1 - c / margin``.
    """

    def __init__(self, config: ControllerConfig, angles: np.ndarray) -> None:
        self.config = config
        self.angles = np.asarray(angles, dtype=np.float64)
        half = math.radians(config.front_half_angle)
        self.front = np.abs(self.angles) <= half
        self.sides = (np.abs(self.angles) > half) & (np.abs(self.angles) < math.radians(135))
        self.left = (self.angles > math.radians(15)) & (self.angles < math.radians(110))
        self.right = (self.angles < -math.radians(15)) & (self.angles > -math.radians(110))
        # distance from the lidar to the footprint circle along each ray
        along = config.lidar_offset * np.cos(self.angles)
        self.body = -along + np.sqrt(along**2 - config.lidar_offset**2 + config.footprint_radius**2)
        self.pid = PID(config.kp, config.ki, config.kd, -config.max_turn_rate, config.max_turn_rate, integral_limit=0.5)

    def reset(self) -> None:
        self.pid.reset()

    def command(self, pose: tuple[float, float, float], target: tuple[float, float], ranges: np.ndarray,
                dt: float, goal_distance: float) -> tuple[float, float]:
        cfg = self.config
        x, y, yaw = pose
        error = _wrap(math.atan2(target[1] - y, target[0] - x) - yaw)
        clear = ranges - self.body
        ahead = float(clear[self.front].min())
        desired = error
        if ahead < cfg.safety_distance:
            weight = 1.0 - max(ahead, 0.0) / cfg.safety_distance
            side = math.pi / 2 if float(ranges[self.left].mean()) >= float(ranges[self.right].mean()) else -math.pi / 2
            desired = (1.0 - weight) * error + weight * side
        side_clear = clear[self.sides]
        i = int(np.argmin(side_clear))
        if side_clear[i] < cfg.side_margin:
            bearing = float(self.angles[self.sides][i])
            weight = 1.0 - max(float(side_clear[i]), 0.0) / cfg.side_margin
            # from the obstacle's tangent (weight 0) to 45 deg past it, away from it (weight 1)
            away = bearing - math.copysign(math.pi / 2 + weight * math.pi / 4, bearing)
            desired = (1.0 - weight) * desired + weight * away
        w = self.pid.update(desired, dt)
        clearance = min(1.0, max(0.0, (ahead - cfg.stop_distance) / (cfg.safety_distance - cfg.stop_distance)))
        align = max(0.0, math.cos(desired)) ** 2
        v = cfg.max_speed * align * clearance
        v = min(v, cfg.max_speed * max(0.3, goal_distance / cfg.goal_slowdown))
        if v < 0.05 and abs(w) < 0.5:  # blocked with the blends cancelling: turn toward more room
            w = 0.8 if float(ranges[self.left].mean()) >= float(ranges[self.right].mean()) else -0.8
        return v, w


class Navigator:
    """Drives ``bulletnav/Warehouse-v0`` from observations: maps with the lidar, plans with
    A* or RRT on the inflated map, replans every ``replan_every`` steps or when new
    obstacles block the path, and follows the path with :class:`GoToGoal`."""

    def __init__(self, config: NavigatorConfig = NavigatorConfig()) -> None:
        self.config = config
        self.plan_times: list[float] = []
        """Seconds spent in each planner call this episode."""
        self.replans = 0
        self.path: list[tuple[float, float]] | None = None

    # ------------------------------------------------------------------ episode
    def reset(self, env, rng: np.random.Generator | None = None) -> None:
        """Prepare for the episode just reset in ``env`` (a made or unwrapped env)."""
        u = env.unwrapped
        self.env = u
        self.rng = rng if rng is not None else np.random.default_rng(0)
        lidar = u.sensors["lidar"]
        self.angles = lidar.angles
        self.max_range = lidar.config.max_range
        self.n_rays = lidar.config.num_rays
        self.dt = u.config.physics.control_dt
        hx, hy = u.layout.half_extents
        self.mapper = LidarMapper((-hx, -hy, hx, hy), self.config.resolution)
        self.controller = GoToGoal(self.config.controller, self.angles)
        self.goal = tuple(u.goal)
        self.path = None
        self.plan_times = []
        self.replans = 0
        self._since_plan = 0
        self._inflated: list[OccupancyGrid] = []

    def _pose(self) -> tuple[float, float, float]:
        if self.config.pose_source == "odometry":
            x, y, yaw = (float(v) for v in self.env.sensors["odometry"].read()[:3])
            return x, y, yaw
        return self.env.robot.planar_pose()

    def act(self, obs: np.ndarray) -> np.ndarray:
        cfg = self.config
        pose = self._pose()
        ranges = np.asarray(obs[: self.n_rays], dtype=np.float64) * self.max_range
        new_cells = self.mapper.integrate(pose, self.angles, ranges, self.max_range, sensor_offset=0.1)
        goal_distance = math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
        target = self.goal
        if cfg.planner != "none":
            if new_cells or not self._inflated:
                raw = self.mapper.grid()
                self._inflated = [raw.inflate(cfg.inflation + cfg.preferred_margin), raw.inflate(cfg.inflation)]
            self._since_plan += 1
            blocked = bool(new_cells) and self.path is not None and not self._path_free(pose)
            if self.path is None or blocked or self._since_plan >= cfg.replan_every:
                self._plan(pose)
            if self.path:
                target = self._lookahead(pose)
        v, w = self.controller.command(pose, target, ranges, self.dt, goal_distance)
        return np.array([v, w], dtype=np.float32)

    # ------------------------------------------------------------------ planning
    def _plan(self, pose) -> None:
        start = (pose[0], pose[1])
        t0 = time.perf_counter()
        path = None
        for inflated in self._inflated:  # wide berth first, then the robot radius alone
            grid = self._clear_around(inflated, [start, self.goal])
            if self.config.planner == "astar":
                path = astar(grid, start, self.goal)
            else:
                path = rrt(grid, start, self.goal, self.rng, step=self.config.rrt_step,
                           time_budget_s=self.config.rrt_time_budget)
            if path is not None:
                break
        self.plan_times.append(time.perf_counter() - t0)
        if self.path is not None:
            self.replans += 1
        self.path = path
        self._since_plan = 0

    def _clear_around(self, grid: OccupancyGrid, points) -> OccupancyGrid:
        """Inflation can swallow a robot standing close to an obstacle (or the goal), which
        would make every plan fail: clear the inflated-only cells around those points, and
        their own cells unconditionally (the robot is there, so it is passable)."""
        occ = grid.occupied.copy()
        raw = self.mapper.grid().occupied
        r = int(math.ceil(self.config.inflation / grid.resolution))
        for px, py in points:
            ix, iy = grid.world_to_cell((px, py))
            sx, sy = slice(max(ix - r, 0), ix + r + 1), slice(max(iy - r, 0), iy + r + 1)
            occ[sx, sy] = raw[sx, sy]
            if grid.in_bounds(ix, iy):
                occ[ix, iy] = False
        return OccupancyGrid(occ, grid.resolution, grid.origin)

    def _path_free(self, pose) -> bool:
        grid = self._clear_around(self._inflated[-1], [(pose[0], pose[1]), self.goal])
        pts = [(pose[0], pose[1]), *self.path[self._nearest_index(pose):]]
        return all(grid.segment_free(a, b) for a, b in zip(pts[:-1], pts[1:]))

    def _nearest_index(self, pose) -> int:
        d = [math.hypot(px - pose[0], py - pose[1]) for px, py in self.path]
        return int(np.argmin(d))

    def _lookahead(self, pose) -> tuple[float, float]:
        i = self._nearest_index(pose)
        for px, py in self.path[i:]:
            if math.hypot(px - pose[0], py - pose[1]) >= self.config.lookahead:
                return px, py
        return self.path[-1]
