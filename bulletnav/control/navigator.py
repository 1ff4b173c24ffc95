"""Classical navigation: PID go-to-goal with lidar avoidance, optionally following A* or RRT
plans made on an occupancy grid built from the lidar as the robot drives."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np

from bulletnav.config import TaskConfig
from bulletnav.control.pid import PID
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.planning import OccupancyGrid, astar, rrt, warmup
from bulletnav.planning.mapping import LidarMapper
from bulletnav.planning.rrt import DEFAULT_MAX_ITERS
from bulletnav.planning.tour import tour_through


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
    outline_clearance: bool = False
    """Measure clearances to the robot's collision outline (its rectangles) instead of its disc
    (``RobotGeometry.radius``): for a robot much longer than wide, whose disc overstates its
    width by a lot (the Jackal: 0.215 m half width, 0.35 m disc). A slow turn whose corners would
    swing into a lidar hit then turns the other way, crawls straight on, or stops."""
    brake_decel: float | None = None
    """With a value (m/s^2), forward speed is set by braking instead of the linear ramp between
    ``stop_distance`` and ``safety_distance``: at most ``sqrt(2 a d)``, where ``d`` is the free
    length of the corridor the robot's width (plus ``corridor_margin``) sweeps straight ahead
    less ``stop_distance`` (that length is also what counts as ahead for the avoidance blend), and
    at most ``max_speed * c / near_range`` where ``c`` is the nearest clearance around the front
    half (at least ``crawl_speed``). None: the ramp (the article robot's controller)."""
    near_range: float = 0.6
    """With ``brake_decel``: clearance (m) to anything ahead or beside at which full speed is allowed."""
    crawl_speed: float = 0.2
    """With ``brake_decel``: the speed (m/s) the nearness cap never goes under (braking still can)."""
    corridor_margin: float = 0.02
    """With ``brake_decel``: the corridor ahead is the robot's width plus this much (m) each side;
    what is in it counts as ahead (the avoidance blend and the braking), what is beside it does not."""
    avoid_side: str = "room"
    """Which way the avoidance blend turns from what is ahead: 'room', toward the side whose rays
    (15-110 deg) read farther on average (the article robot's rule); 'away', away from the
    nearest hit in the corridor ahead (``brake_decel`` only), toward the target's side where that
    hit lies within :data:`CENTRE_BAND` of the centre line. The mean of the ranges can point at the
    very obstacle being avoided, and flips with every scan beside a cylinder."""

    def __post_init__(self) -> None:
        if self.avoid_side not in ("room", "away"):
            raise ValueError(f"avoid_side must be 'room' or 'away', got {self.avoid_side!r}")


@dataclass(frozen=True)
class NavigatorConfig:
    """Planning and replanning on the lidar map."""

    planner: str = "astar"
    """'none' (PID straight at the goal), 'astar' or 'rrt'."""
    resolution: float = 0.2
    """Occupancy-grid cell size (m)."""
    inflation: float | None = None
    """Obstacles grow by this (m) before planning; None takes the robot's disc radius
    (``RobotGeometry.radius``, 0.2 m)."""
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
    rrt_max_iters: int = DEFAULT_MAX_ITERS
    """RRT iteration budget per plan (no wall-clock budget: the same map gives the same plan on any machine)."""
    seed: int = 0
    """RRT's random numbers come from ``(seed, episode start pose, goal)``: the same episode
    gets the same plans whatever ran before it."""
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    wait_for_movers: bool = True
    """Among movers (``scene.movers``): stop while a moving one is in the corridor ahead."""
    wait_distance: float = 1.0
    """Length (m) of that corridor beyond the robot's disc."""
    max_wait: float = 4.0
    """Seconds to wait for a mover before planning around it (a stopped or yielding mover is
    planned around at once: it is an obstacle in the lidar map)."""
    fit_robot: bool = True
    """Fit the settings to a robot other than the article's (:func:`fit_to_robot`): its top
    speed and turn rate, braking-limited speed, clearances to its outline, a narrow-gap plan.
    The article robot (the shipped URDF with Warehouse-v0's action bounds, which these defaults
    were tuned for) always gets the settings as given."""
    back_up: bool = True
    """Where the env lets the robot back up (``TaskConfig.min_speed`` < 0): a robot that has made
    no headway for ``stuck_time`` backs along the way it came (:meth:`Navigator.act`) until its
    turning circle is clear of what the lidar sees, then replans: the way out of a pocket too
    tight to turn in. A forward-only env never backs up."""
    stuck_time: float = 1.0
    """Seconds without headway (under 3 cm and 0.2 rad net) after which the robot backs up."""
    back_speed: float = 0.3
    """Speed (m/s) of backing up."""
    back_max: float = 1.0
    """The farthest (m) one backing up goes."""
    narrow_inflation: float | None = None
    """A last plan is tried with this inflation (m) when none is found with ``inflation``
    (None: no such plan). :func:`fit_to_robot` sets it to a long, narrow robot's half width
    plus 3 cm: driven along the plan it fits where its disc does not."""

    def __post_init__(self) -> None:
        if self.planner not in ("none", "astar", "rrt"):
            raise ValueError(f"planner must be 'none', 'astar' or 'rrt', got {self.planner!r}")
        if self.pose_source not in ("truth", "odometry"):
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {self.pose_source!r}")


def _wrap(angle: float) -> float:
    return math.remainder(angle, 2 * math.pi)


TRAIL_STEP = 0.05
"""Spacing (m) of the points of the robot's trail, the way it backs out along."""
STUCK_DISTANCE = 0.03
"""Net motion (m) under which ``stuck_time`` without headway counts as stuck."""
STUCK_TURN = 0.2
"""Net turn (rad) under which ``stuck_time`` without headway counts as stuck."""
BACK_CLEARANCE = 0.06
"""Backing up ends when no lidar hit lies within the outline's reach plus this (m): room to turn."""
TURN_FIRST_RAD = 1.0
"""A robot that can back up turns in place toward its target first when facing more than this
(rad) away from it with something in the corridor ahead (:meth:`GoToGoal.turn_first`)..."""
TURN_FIRST_DONE_RAD = 0.3
"""... until it faces within this (rad) of it."""
TABU_RADIUS = 0.2
"""Plans keep this far (m, plus their inflation) from the places the robot had to back out of."""
BACK_LOOKAHEAD = 0.3
"""Backing up steers the rear at the trail point this far (m) behind."""
BACK_GAIN = 2.0
"""Yaw rate (rad/s) per rad of heading error of the rear while backing up."""
FIT_BRAKE_DECEL = 2.5
"""The deceleration (m/s^2) a fitted robot's speed is limited by (:func:`fit_to_robot`): the
Jackal's motors brake at about 3.5. It was 1.5 (the shield's assumed deceleration) until the
BARN navigator was tuned for speed on 40 non-test BARN worlds x 2 runs (the ``barn-tune`` suite),
backing up allowed: behind the shield the metric went from 0.478 to 0.493 there in development
runs, every run succeeding before and after."""
FIT_NEAR_RANGE = 0.4
"""The clearance (m) at which a fitted robot may drive at full speed (``near_range``; 0.6 before,
as above)."""
NARROW_MARGIN = 0.03
"""What :func:`fit_to_robot`'s narrow-gap plan adds to the robot's half width (m)."""
TURN_GUARD_RAD = 0.35
"""With ``outline_clearance``, a slow turn is checked this far ahead (rad, two control steps at
4 rad/s) for corners swinging into what the lidar sees."""
TURN_GUARD_MARGIN = 0.02
"""The outline grows by this much (m) for that check."""
TURN_ROLL_SPEED = 0.2
"""A fitted robot rolling faster than this (m/s) checks a guarded turn along the roll too
(:meth:`GoToGoal._rolls_into`) and stops straight instead where the turn made while rolling would
bring a corner onto a hit: the turn guard checks turns in place, and a hard turn asked at
0.3-0.5 m/s swung a front corner into a cylinder the roll carried it onto (BARN training worlds
271 and 283, seed 7100001)."""
TURN_GUARD_RATE = 1.5
"""Top yaw rate (rad/s) of such a turn with something within the corners' reach: at 4 rad/s the
robot's own spin carries the corners past a reversal (0.35 rad is 2 control steps at 4 rad/s, 5.6 at 1.5)."""


CENTRE_BAND = 0.05
"""With ``avoid_side='away'``: a corridor hit this close (m) to the centre line has no side; the
blend turns toward the target's."""


def is_article_robot(scene: Any) -> bool:
    """Whether ``scene`` drives the robot the navigator's defaults were tuned for: the shipped
    URDF's geometry and Warehouse-v0's action bounds (0.5 m/s, 1.5 rad/s)."""
    task = TaskConfig()
    return (scene.geometry == robot_geometry()
            and tuple(scene.command_limits) == ((0.0, task.max_speed), (-task.max_turn_rate, task.max_turn_rate)))


def fit_to_robot(config: NavigatorConfig, scene: Any) -> NavigatorConfig:
    """``config`` for the robot of ``scene``: itself for the article robot (:func:`is_article_robot`)
    or with ``fit_robot`` off; for another robot the controller takes the env's top speed and
    turn rate (``scene.command_limits``), speed limited by braking (``brake_decel``
    :data:`FIT_BRAKE_DECEL`) and by nearness (full speed from :data:`FIT_NEAR_RANGE` of anything
    ahead or beside) instead of the article's ramp,
    clearances to the collision outline, a 0.3 m avoidance blend and a 0.1 m side margin (to the
    outline, so tight clutter does not push it off its plan); the planner a 0.1 m grid and, for
    a robot narrower than its disc, a last plan at its half width (``narrow_inflation``)."""
    if not config.fit_robot or is_article_robot(scene):
        return config
    geometry = scene.geometry
    (_, v_max), (_, w_max) = scene.command_limits
    controller = replace(config.controller, max_speed=float(v_max), max_turn_rate=float(w_max), outline_clearance=True,
                         brake_decel=FIT_BRAKE_DECEL, near_range=FIT_NEAR_RANGE, safety_distance=0.3, side_margin=0.1,
                         avoid_side="away")
    narrow = geometry.half_width + NARROW_MARGIN
    inflation = geometry.radius if config.inflation is None else config.inflation
    return replace(config, controller=controller, resolution=min(config.resolution, 0.1),
                   narrow_inflation=narrow if narrow < inflation and config.narrow_inflation is None
                   else config.narrow_inflation)


def outline_reach(geometry: RobotGeometry, angles: np.ndarray, step: float = 0.002) -> np.ndarray:
    """Distance (m) from the lidar to the edge of the robot's collision outline along each ray
    (its rectangles' union, which the lidar lies in or near), in ``step`` m."""
    lx, ly = geometry.lidar_mount[0], geometry.lidar_mount[1]
    s = np.arange(0.0, 2.0 * geometry.outline_radius + step, step)
    x = lx + s[None, :] * np.cos(angles)[:, None]
    y = ly + s[None, :] * np.sin(angles)[:, None]
    inside = np.zeros(x.shape, dtype=bool)
    for r in geometry.rectangles:
        inside |= (np.abs(x - r.cx) <= r.half_x) & (np.abs(y - r.cy) <= r.half_y)
    last = np.where(inside.any(axis=1), inside.shape[1] - 1 - np.argmax(inside[:, ::-1], axis=1), 0)
    return s[last]


class GoToGoal:
    """Heading PID toward a target point plus forward speed, with the article's lidar
    avoidance: when the closest clearance ahead is under ``safety_distance``, the desired
    heading is blended toward the side with more room with weight ``1 - d / safety``.

    Clearances are ranges minus the distance from the lidar to the edge of the robot's
    disc (``geometry.radius`` around the body centre) along each ray, so a box 5 cm beside
    the wheel reads about 5 cm, not 21. The same blend keeps the sides clear: an obstacle
    closer than ``side_margin`` beside the robot pulls the heading toward its tangent
    (parallel to it) with weight ``1 - c / margin``.
    """

    def __init__(self, config: ControllerConfig, angles: np.ndarray, geometry: RobotGeometry) -> None:
        self.config = config
        self.angles = np.asarray(angles, dtype=np.float64)
        half = math.radians(config.front_half_angle)
        self.front = np.abs(self.angles) <= half
        self.sides = (np.abs(self.angles) > half) & (np.abs(self.angles) < math.radians(135))
        self.left = (self.angles > math.radians(15)) & (self.angles < math.radians(110))
        self.right = (self.angles < -math.radians(15)) & (self.angles > -math.radians(110))
        offset = geometry.lidar_offset
        if config.outline_clearance:  # distance from the lidar to the collision outline along each ray
            self.body = outline_reach(geometry, self.angles)
        else:  # distance from the lidar to the footprint circle along each ray
            along = offset * np.cos(self.angles)
            self.body = -along + np.sqrt(along**2 - offset**2 + geometry.radius**2)
        self.cos, self.sin = np.cos(self.angles), np.sin(self.angles)
        self.offset = offset
        self.half_width = geometry.half_width
        self.nose = geometry.nose
        self.front_half = np.abs(self.angles) <= math.pi / 2
        self.rectangles = np.array([(r.cx, r.cy, r.half_x, r.half_y) for r in geometry.rectangles])
        self.reach = geometry.outline_radius
        self.pid = PID(config.kp, config.ki, config.kd, -config.max_turn_rate, config.max_turn_rate, integral_limit=0.5)
        self._turning = 0.0  # the way turn_first is turning (0: not)

    def reset(self) -> None:
        self.pid.reset()
        self._turning = 0.0

    def turn_first(self, pose: tuple[float, float, float], target: tuple[float, float], ranges: np.ndarray,
                   v_now: float = 0.0, dt: float = 0.0) -> tuple[float, float] | None:
        """For a robot that can back up, beside obstacles and facing well away from its target:
        turn in place toward it before driving, where the outline's corners stay clear
        (:data:`TURN_FIRST_RAD`; the avoidance blends, left alone there, swing the heading from
        side to side). The command of that turn, ``(0, 0)`` when neither way is clear (back up),
        or None to drive as :meth:`command` does."""
        cfg = self.config
        x, y, yaw = pose
        error = _wrap(math.atan2(target[1] - y, target[0] - x) - yaw)
        if self._turning and abs(error) < TURN_FIRST_DONE_RAD:
            self._turning = 0.0
        if not self._turning:
            if abs(error) < TURN_FIRST_RAD or self._corridor(ranges) >= cfg.safety_distance:
                return None
            self._turning = math.copysign(1.0, error)
        points = self._near_points(ranges)
        for sign in (self._turning, -self._turning):
            if not self._turn_hits(points, sign):
                self._turning = sign
                rate = min(cfg.max_turn_rate, TURN_GUARD_RATE if len(points) else cfg.max_turn_rate, max(0.8, 2.0 * abs(error)))
                if self._rolls_into(ranges, sign * rate, v_now, dt):
                    return 0.0, 0.0  # the turn, made while the robot still rolls on, would hit: stop straight first
                return 0.0, sign * rate
        self._turning = 0.0
        return 0.0, 0.0

    def command(self, pose: tuple[float, float, float], target: tuple[float, float], ranges: np.ndarray,
                dt: float, goal_distance: float, v_now: float = 0.0) -> tuple[float, float]:
        """The command toward ``target``; ``v_now``: the robot's forward speed now (m/s), along
        which a guarded turn is checked too (:data:`TURN_ROLL_SPEED`)."""
        cfg = self.config
        x, y, yaw = pose
        error = _wrap(math.atan2(target[1] - y, target[0] - x) - yaw)
        clear = ranges - self.body
        # what lies ahead: the closest clearance in the front sector, or (braking) the free length
        # of the corridor the robot's width sweeps straight ahead
        ahead = float(clear[self.front].min()) if cfg.brake_decel is None else self._corridor(ranges)
        desired = error
        if ahead < cfg.safety_distance:
            weight = 1.0 - max(ahead, 0.0) / cfg.safety_distance
            side = self._avoid_side(ranges, error)
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
        align = max(0.0, math.cos(desired)) ** 2
        if cfg.brake_decel is None:
            clearance = min(1.0, max(0.0, (ahead - cfg.stop_distance) / (cfg.safety_distance - cfg.stop_distance)))
            v = cfg.max_speed * align * clearance
        else:
            v = align * self._braking_speed(ahead, clear)
        v = min(v, cfg.max_speed * max(0.3, goal_distance / cfg.goal_slowdown))
        if v < 0.05 and abs(w) < 0.5:  # blocked with the blends cancelling: turn toward more room
            w = 0.8 * self._roomier(ranges)
        if cfg.outline_clearance and v < cfg.crawl_speed and w != 0.0:
            v, w = self._guard_turn(ranges, v, w, ahead, error)
            if w != 0.0 and self._rolls_into(ranges, w, v_now, dt):
                return 0.0, 0.0  # the turn, made while the robot still rolls on, would hit: stop straight first
        return v, w

    def _rolls_into(self, ranges: np.ndarray, w: float, v_now: float, dt: float) -> bool:
        """Whether a turn at ``w`` rad/s, made while the robot rolls on from ``v_now`` m/s (faster
        than :data:`TURN_ROLL_SPEED`), brings a corner onto a lidar hit within ``TURN_GUARD_RAD``:
        the roll is one control period ``dt`` plus the time the turn takes to sweep
        ``TURN_GUARD_RAD``, braking at ``brake_decel``."""
        if v_now <= TURN_ROLL_SPEED:
            return False
        decel = self.config.brake_decel or FIT_BRAKE_DECEL
        t = min(TURN_GUARD_RAD / max(abs(w), 0.1), v_now / decel)  # the roll while the guard's turn is made
        roll = v_now * dt + v_now * t - 0.5 * decel * t * t
        return self._turn_hits(self._near_points(ranges, roll), math.copysign(1.0, w), roll)

    def _guard_turn(self, ranges: np.ndarray, v: float, w: float, ahead: float, error: float = 0.0
                    ) -> tuple[float, float]:
        """A slow turn with lidar hits within its corners' reach turns at most ``TURN_GUARD_RATE``;
        one whose corners would swing into a hit within ``TURN_GUARD_RAD`` becomes the turn the
        other way, else a crawl straight ahead (room permitting), else a stop. A turn the other
        way with the target ``error`` rad off, at least :data:`TURN_FIRST_RAD`, goes on as
        :meth:`turn_first`'s turn until the robot faces the target: turned back at each step as
        the corners clear, it rocked in place (BARN training world 271, seed 7100000)."""
        points = self._near_points(ranges)
        if len(points):  # something within the corners' reach: turn no faster than TURN_GUARD_RATE
            w = max(-TURN_GUARD_RATE, min(TURN_GUARD_RATE, w))
        if not self._turn_hits(points, math.copysign(1.0, w)):
            return v, w
        if not self._turn_hits(points, -math.copysign(1.0, w)):
            if abs(error) >= TURN_FIRST_RAD:
                self._turning = -math.copysign(1.0, w)
            return v, -w
        if ahead > self.config.stop_distance + 0.05:
            return self.config.crawl_speed / 2, 0.0
        return 0.0, 0.0

    def _near_points(self, ranges: np.ndarray, more: float = 0.0) -> np.ndarray:
        """Lidar hits (body frame, (N, 2)) within reach of the outline's corners as it turns (and ``more`` m)."""
        x = self.offset + ranges * self.cos
        y = ranges * self.sin
        near = x * x + y * y <= (self.reach + TURN_GUARD_MARGIN + more) ** 2
        return np.stack([x[near], y[near]], axis=1)

    def _turn_hits(self, points: np.ndarray, sign: float, roll: float = 0.0) -> bool:
        """Whether turning by up to ``TURN_GUARD_RAD`` the ``sign`` way (while rolling ``roll`` m
        forward, evenly over the turn, along its mean heading) brings the outline, grown by
        ``TURN_GUARD_MARGIN``, onto a point not already on it."""
        if not len(points):
            return False
        m = TURN_GUARD_MARGIN
        rects = self.rectangles

        def inside(px: np.ndarray, py: np.ndarray) -> np.ndarray:
            return ((np.abs(px[:, None] - rects[:, 0]) <= rects[:, 2] + m)
                    & (np.abs(py[:, None] - rects[:, 1]) <= rects[:, 3] + m)).any(axis=1)

        free = ~inside(points[:, 0], points[:, 1])
        px, py = points[free, 0], points[free, 1]
        for k, theta in enumerate(np.linspace(0.0, TURN_GUARD_RAD, 7)[1:] * sign, start=1):
            d = roll * k / 6  # the points as the body sees them there: moved back, turned back
            qx, qy = px - d * math.cos(theta / 2), py - d * math.sin(theta / 2)
            c, s = math.cos(theta), math.sin(theta)
            if inside(c * qx + s * qy, -s * qx + c * qy).any():
                return True
        return False


    def _avoid_side(self, ranges: np.ndarray, error: float) -> float:
        """The heading (rad, +-pi/2) the avoidance blend turns toward (``avoid_side``)."""
        if self.config.avoid_side == "away" and self.config.brake_decel is not None:
            hit = self._corridor_hit(ranges)
            if hit is not None:
                lateral = hit[1] if abs(hit[1]) > CENTRE_BAND else -error
                return -math.copysign(math.pi / 2, lateral)
        return math.pi / 2 * self._roomier(ranges)

    def _roomier(self, ranges: np.ndarray) -> float:
        """+1 where the rays on the left (15-110 deg) read at least as far on average as those on the right, else -1."""
        return 1.0 if float(ranges[self.left].mean()) >= float(ranges[self.right].mean()) else -1.0

    def _corridor_hit(self, ranges: np.ndarray) -> tuple[float, float] | None:
        """The nearest lidar hit (body frame, m) in the corridor :meth:`_corridor` measures, or None."""
        x = self.offset + ranges * self.cos
        y = ranges * self.sin
        inside = (np.abs(y) <= self.half_width + self.config.corridor_margin) & (x > 0.0)
        if not inside.any():
            return None
        i = int(np.flatnonzero(inside)[np.argmin(x[inside])])
        return float(x[i]), float(y[i])

    def _corridor(self, ranges: np.ndarray) -> float:
        """Free length (m) ahead of the robot's nose of the corridor its width plus
        ``corridor_margin`` each side sweeps straight ahead (inf when nothing is in it)."""
        hit = self._corridor_hit(ranges)
        return math.inf if hit is None else hit[0] - self.nose

    def _braking_speed(self, ahead: float, clear: np.ndarray) -> float:
        """Top speed that can still stop ``stop_distance`` short of what is ``ahead`` in the
        corridor (``brake_decel``), capped by the nearest clearance around the front half
        (``near_range``, ``crawl_speed``)."""
        cfg = self.config
        v = math.sqrt(2.0 * cfg.brake_decel * max(ahead - cfg.stop_distance, 0.0))
        near = max(float(clear[self.front_half].min()), 0.0)
        cap = max(cfg.crawl_speed, cfg.max_speed * near / cfg.near_range)
        return min(cfg.max_speed, v, cap)


class Navigator:
    """PID + A*/RRT for any env with the navigation observation: maps with the lidar, plans
    on the inflated map, replans every ``replan_every`` steps or when new obstacles block
    the path, and follows the path with :class:`GoToGoal`.

    Among movers the lidar map forgets: cells a mover left are cleared by later rays passing
    through them (log-odds free evidence), and the inflated map is rebuilt when cells empty
    as well as when they fill. While a moving mover is in the corridor ahead (the scene's
    mover list, as a fleet manager would broadcast it) the robot waits, up to ``max_wait``
    seconds; then, or at once for a stopped one, it plans around it like any obstacle.

    A :class:`~bulletnav.policy.Policy`: it reads the lidar from ``obs``, the goal and the
    true pose from ``info``, and the map bounds, lidar layout, robot geometry and (with
    ``pose_source="odometry"``) the odometry estimate from the read-only scene view.

    Args:
        scene: ``env.unwrapped.scene`` of the env it will drive.
        config: planner and controller settings.
    """

    def __init__(self, scene: Any, config: NavigatorConfig = NavigatorConfig()) -> None:
        self.scene = scene
        self.given = config
        """The settings as given; :attr:`config` is them fitted to the robot at each reset (:func:`fit_to_robot`)."""
        self.config = config
        self.plan_times: list[float] = []
        """Seconds spent in each planner call this episode."""
        self.replans = 0
        self.path: list[tuple[float, float]] | None = None
        """The plan being followed (world points, m), for drawing."""
        if config.planner != "none":
            warmup()  # numba kernels compiled (or loaded from the disk cache) before any plan

    # ------------------------------------------------------------------ episode
    def reset(self, info: dict[str, Any]) -> None:
        """Prepare for the episode that ``info`` (from ``env.reset``) starts."""
        scene = self.scene
        self.config = fit_to_robot(self.given, scene)
        lidar = scene.sensors.lidar
        geometry = scene.geometry
        self.angles = lidar.angles
        self.max_range = lidar.config.max_range
        self.n_rays = lidar.config.num_rays
        self.lidar_offset = geometry.lidar_offset
        self.inflation = geometry.radius if self.config.inflation is None else self.config.inflation
        self.dt = scene.control_dt
        self._last_pose: tuple[float, float, float] | None = None
        self.mapper = LidarMapper(scene.layout.bounds, self.config.resolution)
        self.controller = GoToGoal(self.config.controller, self.angles, geometry)
        self.goal = (float(info["goal"][0]), float(info["goal"][1]))
        x, y, yaw = (float(v) for v in info["pose"])
        # the episode's own stream: same start and goal -> same RRT samples, on any machine
        words = np.frombuffer(np.array([x, y, yaw, *self.goal]).tobytes(), dtype=np.uint32)
        self.rng = np.random.default_rng([self.config.seed, *words.tolist()])
        self.path = None
        self.plan_times = []
        self.replans = 0
        self._since_plan = 0
        self._inflated: list[OccupancyGrid] = []
        self._waited = 0
        (v_min, _), _ = scene.command_limits
        self._can_back = self.config.back_up and v_min < 0.0
        self._back_speed = min(self.config.back_speed, -v_min) if self._can_back else 0.0
        self._turn_clear = geometry.outline_radius + BACK_CLEARANCE
        self._trail: list[tuple[float, float]] = [(x, y)]
        self._recent: list[tuple[float, float, float]] = []
        self._backing = False
        self._stuck_now = False
        self._tabu: list[tuple[float, float]] = []
        self._backed = 0.0
        self._back_steps = 0
        self.backups = 0
        """Times this episode the robot backed out of a place it could not turn in."""
        # missions: visit the goals in the best order on the true static map (free order), or as given
        self.order: tuple[int, ...] | None = None
        """Mission goal indices in the order this navigator visits them (None: one goal)."""
        goals = info.get("goals")
        if goals is not None and len(goals) > 1:
            self._goals = [(float(g[0]), float(g[1])) for g in goals]
            if info.get("goal_order") == "free":
                self.order = self._best_order((x, y), self._goals)
            else:
                self.order = tuple(range(len(self._goals)))
            self.goal = self._goals[self.order[0]]

    def _pose(self, info: dict[str, Any]) -> tuple[float, float, float]:
        if self.config.pose_source == "odometry":
            x, y, yaw = (float(v) for v in self.scene.sensors.odometry.read()[:3])
            return x, y, yaw
        x, y, yaw = info["pose"]
        return float(x), float(y), float(yaw)

    def _best_order(self, start: tuple[float, float], goals: list[tuple[float, float]]) -> tuple[int, ...]:
        """The shortest visiting order: A* lengths between all pairs on the scene's static map
        inflated by the robot's radius, then the exact tour (:func:`bulletnav.planning.tour`)."""
        grid = self.scene.occupancy(0.1, self.inflation)

        def length(a: tuple[float, float], b: tuple[float, float]) -> float:
            path = astar(grid, a, b)
            return math.inf if path is None else sum(math.dist(p, q) for p, q in zip(path, path[1:]))

        _, seq = tour_through([start, *goals], length, "free")
        return tuple(i - 1 for i in seq)

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        cfg = self.config
        pose = self._pose(info)
        v_now = self._speed(pose)
        if self.order is not None and "reached" in info:  # missions: on to the next goal of our order
            left = [i for i in self.order if not info["reached"][i]]
            goal = self._goals[left[0]] if left else self.goal
            if goal != self.goal:
                self.goal, self.path = goal, None
        state = obs["state"] if isinstance(obs, dict) else obs
        ranges = np.asarray(state[: self.n_rays], dtype=np.float64) * self.max_range
        new_cells = self.mapper.integrate(pose, self.angles, ranges, self.max_range, sensor_offset=self.lidar_offset)
        goal_distance = math.hypot(self.goal[0] - pose[0], self.goal[1] - pose[1])
        if self._can_back and not (self.scene.dynamic and cfg.wait_for_movers and self._mover_ahead(pose)):
            # (waiting for a mover to pass is no reason to back up)
            backing = self._back_up(pose, ranges, goal_distance)
            if backing is not None:
                return self._action(*backing)
        target = self.goal
        dynamic = self.scene.dynamic
        if dynamic and cfg.wait_for_movers:
            if self._mover_ahead(pose):
                if self._waited < cfg.max_wait / self.dt:
                    self._waited += 1
                    return self._action(0.0, 0.0)
                if self._waited == int(math.ceil(cfg.max_wait / self.dt)) and cfg.planner != "none":
                    self.path = None  # waited long enough: plan around it
                self._waited += 1
            else:
                self._waited = 0
        if cfg.planner != "none":
            if new_cells or not self._inflated or (dynamic and self.mapper.freed):
                raw = self.mapper.grid()
                radii = [self.inflation + cfg.preferred_margin, self.inflation]
                if cfg.narrow_inflation is not None:  # a long, narrow robot: the gaps it fits through aligned
                    radii.append(cfg.narrow_inflation)
                self._inflated = raw.inflate_many(radii)
            self._since_plan += 1
            blocked = bool(new_cells) and self.path is not None and not self._path_free(pose)
            if self.path is None or blocked or self._since_plan >= cfg.replan_every:
                self._plan(pose)
            if self.path:
                target = self._lookahead(pose)
        if self._can_back and self.config.controller.outline_clearance:
            turn = self.controller.turn_first(pose, target, ranges, v_now, self.dt)
            if turn is not None:
                if turn == (0.0, 0.0):  # boxed in: back out now rather than wait to be stuck
                    self._stuck_now = True
                return self._action(*turn)
        v, w = self.controller.command(pose, target, ranges, self.dt, goal_distance, v_now)
        return self._action(v, w)

    def _speed(self, pose: tuple[float, float, float]) -> float:
        """The robot's forward speed (m/s) over the last control period, from the poses the
        navigator steers by (0 at the first step)."""
        last, self._last_pose = self._last_pose, pose
        if last is None:
            return 0.0
        return ((pose[0] - last[0]) * math.cos(pose[2]) + (pose[1] - last[1]) * math.sin(pose[2])) / self.dt

    def _action(self, v: float, w: float) -> np.ndarray:
        return self.scene.action_for(v, w)

    # ------------------------------------------------------------------ backing out
    def _back_up(self, pose: tuple[float, float, float], ranges: np.ndarray, goal_distance: float
                 ) -> tuple[float, float] | None:
        """The command that backs the robot along its trail, or None to drive on as usual.

        The trail is the robot's own path (a point every :data:`TRAIL_STEP` m): free space it
        came through. After ``stuck_time`` without headway away from the goal, the robot backs
        along it, steering its rear at the trail point :data:`BACK_LOOKAHEAD` m behind, until
        no lidar hit lies within its turning circle (the outline's reach plus
        :data:`BACK_CLEARANCE`), it has backed ``back_max`` m, or the trail runs out; then it
        replans from there."""
        cfg = self.config
        x, y, yaw = pose
        tx, ty = self._trail[-1]
        if not self._backing and math.hypot(x - tx, y - ty) >= TRAIL_STEP:
            self._trail.append((x, y))
        self._recent.append(pose)
        window = max(1, int(round(cfg.stuck_time / self.dt)))
        if len(self._recent) > window:
            del self._recent[0]
        if not self._backing:
            x0, y0, yaw0 = self._recent[0]
            stuck = ((self._stuck_now or (len(self._recent) == window and math.hypot(x - x0, y - y0) < STUCK_DISTANCE
                                          and abs(_wrap(yaw - yaw0)) < STUCK_TURN))
                     and goal_distance > 2.0 * self.scene.goal_radius and len(self._trail) > 1)
            self._stuck_now = False
            if not stuck:
                return None
            self._backing, self._backed, self._back_steps = True, 0.0, 0
            self.backups += 1
            self._tabu.append((x, y))  # plans go around this place from now on, where they can
        # drop the trail points the robot has backed past; steer the rear at the one BACK_LOOKAHEAD behind
        while len(self._trail) > 1 and math.hypot(self._trail[-1][0] - x, self._trail[-1][1] - y) < TRAIL_STEP:
            self._trail.pop()
        hx = self.lidar_offset + ranges * np.cos(self.angles)
        hy = ranges * np.sin(self.angles)
        hits = ranges < self.max_range * 0.999
        roomy = not np.any(hits & (hx * hx + hy * hy < self._turn_clear ** 2))
        self._back_steps += 1
        ended = (roomy or self._backed >= cfg.back_max or len(self._trail) <= 1
                 or self._back_steps * self.dt > 2.0 * cfg.back_max / max(self._back_speed, 1e-6))
        if ended:
            self._backing = False
            self._recent = []
            self._trail.append((x, y))
            self.path = None  # replan from here
            return None
        target = self._trail[-1]
        for px, py in reversed(self._trail):
            target = (px, py)
            if math.hypot(px - x, py - y) >= BACK_LOOKAHEAD:
                break
        error = _wrap(math.atan2(target[1] - y, target[0] - x) - (yaw + math.pi))
        (_, _), (_, w_max) = self.scene.command_limits
        w = max(-w_max, min(w_max, BACK_GAIN * error))
        v = -self._back_speed * max(0.0, math.cos(error))
        self._backed += -v * self.dt
        return v, w

    def _mover_ahead(self, pose) -> bool:
        """A moving mover overlaps the corridor ahead: the robot's disc swept ``wait_distance``
        forward (1.1 disc radii wide each side)."""
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        radius = self.scene.geometry.radius
        for m in self.scene.movers:
            if m.speed <= 0.0:
                continue
            mx, my = m.pose[0] - x, m.pose[1] - y
            lx, ly = c * mx + s * my, -s * mx + c * my
            extent = 0.5 * math.hypot(m.size[0], m.size[1])
            if -radius < lx - extent < radius + self.config.wait_distance and abs(ly) < extent + 1.1 * radius:
                return True
        return False

    # ------------------------------------------------------------------ planning
    def _plan(self, pose) -> None:
        start = (pose[0], pose[1])
        t0 = time.perf_counter()
        path = None
        grids = self._inflated
        if self._tabu:  # around the places it had to back out of first, then through them as a last resort
            grids = [self._blocked_at(g, self._tabu) for g in self._inflated] + list(self._inflated)
        for inflated in grids:  # wide berth first, then the robot radius alone
            grid = self._clear_around(inflated, [start, self.goal])
            if self.config.planner == "astar":
                path = astar(grid, start, self.goal)
            else:
                path = rrt(grid, start, self.goal, self.rng, step=self.config.rrt_step,
                           max_iters=self.config.rrt_max_iters)
            if path is not None:
                break
        self.plan_times.append(time.perf_counter() - t0)
        if self.path is not None:
            self.replans += 1
        self.path = path
        self._since_plan = 0

    def _blocked_at(self, grid: OccupancyGrid, points: list[tuple[float, float]]) -> OccupancyGrid:
        """``grid`` with the cells within :data:`TABU_RADIUS` of ``points`` occupied."""
        occ = grid.occupied.copy()
        r = TABU_RADIUS / grid.resolution
        n = int(math.ceil(r))
        for px, py in points:
            ix, iy = grid.world_to_cell((px, py))
            for dx in range(-n, n + 1):
                for dy in range(-n, n + 1):
                    if dx * dx + dy * dy <= r * r and grid.in_bounds(ix + dx, iy + dy):
                        occ[ix + dx, iy + dy] = True
        return OccupancyGrid(occ, grid.resolution, grid.origin)

    def _clear_around(self, grid: OccupancyGrid, points) -> OccupancyGrid:
        """Inflation can swallow a robot standing close to an obstacle (or the goal), which
        would make every plan fail: clear the inflated-only cells around those points, and
        their own cells unconditionally (the robot is there, so it is passable)."""
        occ = grid.occupied.copy()
        raw = self.mapper.grid().occupied
        r = int(math.ceil(self.inflation / grid.resolution))
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
