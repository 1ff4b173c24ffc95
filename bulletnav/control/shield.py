"""A safety shield: vetoes a command whose stopping sweep would touch what the lidar sees or
where a mover is headed, and replaces it with the closest safe one. It never drives.

**The sweep.** For a command (v, w) the robot is assumed to run at ``max(v_now, v)`` for one
control period, then to brake at ``decel`` along the same arc; a turn in place slows down at
the same rim deceleration (its yaw rate at ``decel / (wheelbase / 2)``), so it keeps turning a
little after the period. The horizon is one control period plus the longer of the two stops.
The robot's outline (its collision rectangles, grown by a margin that rises with the sweep's
starting speed from ``margin_min`` at rest to ``margin`` at full speed) is placed at
``samples`` poses along that path and tested against:

- the current lidar scan's hits, in the body frame, with the surface between two neighbouring
  rays filled in every 4 cm when the two hits are within ``join`` of each other (36 rays are
  17 cm apart at 1 m: a box corner could hide between two, and a wall seen at a grazing angle
  has hits far apart in range but close in space; a gap narrower than the robot is no
  passage, so closing it costs nothing); where the surfaces either side of a joined gap meet
  in a convex corner pointing at the robot (a rack's end), the corner is rebuilt from the two
  surface lines -- the straight join cuts it off by up to ~4 cm at 0.6 m;
- the movers the scene exposes (``scene.movers``), each moved ahead at its current speed and
  heading to the time of each pose, as points on its footprint.

**The choice.** A command whose sweep is clear passes unchanged, bit for bit. Otherwise the
shield tries a small set of commands -- the commanded speed scaled by 0.75, 0.5, 0.25 and 0,
each with the commanded yaw rate and yaw rates around it, always including a full stop -- and
takes the clear one with the smallest change in wheel speeds. When the robot is already inside
the margin and none is clear, it may still turn in place, but only where the bare outline
grown by 2 cm stays off the scan filled in every 1 cm (a corner pokes at most 5 mm between two
points), so it can turn away from a wall it has come close to, never into it; when no turn
qualifies, it stops. The action space is forward-only, so it never backs into
space the lidar has not seen.

**No deadlock.** A controller that keeps asking for a blocked command would stand still
forever (a deterministic policy sees the same scan and asks again). After ``patience`` steps
held still the shield is *stuck*: turns in place both ways join the set ahead of the stop,
and once it has turned one way it keeps to that way while stuck (no dithering: when that way
is not free it stops, unless already inside the margin, where a turn the other way is still
preferred to standing: standing beside a wall is the last resort; the robot's parking brake,
``RobotConfig.park_brake_rate``, keeps a stopped robot from creeping into it),
until the controller's command, or a forward one near it, is clear again. (A forward-only
robot that has come face-first within the margin of a flat wall has no turn that keeps its
corners off the wall: it stays stopped; only reversing would free it.)

**Beside a mover that waits for it.** A forklift or worker that yields stands still for as
long as the robot is near, so a robot the shield holds beside it would wait forever (a tight
gap between a yielding worker and a rack, say). Stuck there (``patience`` steps held, a
yielding mover in reach), the controller's forward command may also pass at
``creep_speed`` with the yaw rates around it, and turns in place its way, where no pose of
the sweep brings the bare outline closer to the scan filled in every 1 cm or to a mover than
the robot already is: a gap that is there is passed, slowly, instead of given up, and the
clearance never shrinks while it creeps, so it cannot wedge itself in. Creeping counts as
held, so it stays stuck until the command is clear again. Static worlds never creep (no
mover yields).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.control.shield_kernels import (
    blocked_points,
    in_pose_frames,
    pose_gaps,
    scan_points,
    start_speed,
    sweep_profile,
    travel,
    wheel_sweep,
)
from bulletnav.control.shield_memory import ScanMemory
from bulletnav.geometry import RobotGeometry

_BATCH = 8
"""Fallback commands checked first (the nearest in change); the rest are checked together."""
_DISC = np.stack([np.cos(np.arange(12) * math.pi / 6), np.sin(np.arange(12) * math.pi / 6)], axis=1)
"""A worker's footprint: 12 points on its circle (scaled by its radius)."""
_RING = np.stack([np.cos(np.arange(48) * math.pi / 24), np.sin(np.arange(48) * math.pi / 24)], axis=1)
"""Another robot of a fleet (``kind == "robot"``): 48 points on the circle round its outline
(scaled by its half-diagonal plus :data:`_RING_MARGIN`), so its turns in place, which the
constant-velocity forecast does not see, sweep nothing outside it; 48 keep a corner from
slipping more than 6 mm between two."""
_RING_MARGIN = 0.03
"""How far (m) the ring of another robot lies outside its corners: PyBullet reports a contact
(and the fleet counts a collision) from about 2 cm apart, and two robots both stand still only
as long as neither creeps."""
_U = np.linspace(-1.0, 1.0, 5)
_BOX = np.concatenate([np.stack([_U, np.ones(5)], 1), np.stack([_U, -np.ones(5)], 1),
                       np.stack([np.ones(3), _U[1:4]], 1), np.stack([-np.ones(3), _U[1:4]], 1)])
"""A forklift's footprint: 16 points on its rectangle's edges (scaled by its half sizes)."""


@dataclass(frozen=True)
class ShieldConfig:
    """Safety shield settings."""

    margin: float = 0.05
    """Added to every side of the robot's collision rectangles (m) for a sweep at full speed;
    slower sweeps get less, down to ``margin_min`` at rest (the error of a predicted stop grows
    with speed)."""
    margin_min: float = 0.03
    """The margin (m) of a sweep from rest (a turn in place): covers the 4 cm spacing of filled
    surfaces (a corner pokes up to 2 cm between two points) and leaves 1 cm."""
    decel: float = 1.5
    """Braking deceleration assumed for the sweep (m/s^2), for every robot: the article robot's
    motors reach about 2.6, the Jackal's (``robot="jackal"``) about 3.5 (0.57 m from 2.0 m/s, on
    the flat); the rest of the sweep is the env's robot: its outline, wheelbase, lidar and action
    bounds (:func:`shield_for`)."""
    samples: int = 12
    """Poses along each sweep."""
    join: float = 0.25
    """Neighbouring lidar hits closer to each other than this (m) are joined into a surface."""
    speed_scales: tuple[float, ...] = (0.75, 0.5, 0.25, 0.0)
    """Fallback forward speeds, as fractions of the commanded one."""
    turn_offsets: tuple[float, ...] = (0.0, 0.4, -0.4, 0.8, -0.8, 1.5, -1.5)
    """Fallback yaw rates: the commanded one plus these (rad/s), clipped to the action range."""
    patience: int = 12
    """Control steps the shield holds the robot still (stopped or turning in place) while the
    controller keeps asking for a blocked command; then it is *stuck*: turns in place both
    ways come before the stop, so the controller gets a new view instead of a deadlock."""
    escape_rates: tuple[float, ...] = (0.5, 1.0, 1.5)
    """Yaw rates (rad/s, both signs) of the turns in place offered when stuck."""
    close_margin: float = 0.02
    """Inside the margin, a turn in place may pass where the bare outline grown by this much
    (m) stays off the scan filled in every 1 cm (a corner pokes at most 5 mm between points)."""
    creep_speed: float = 0.1
    """Stuck beside a mover that is yielding to the robot, the controller's forward command may
    pass at this speed (m/s, or the commanded one when slower) where no pose of its sweep
    brings the bare outline closer to the finely filled scan or to a mover than it already is:
    the mover waits for as long as the robot stands near it, so standing would be a deadlock.
    0 turns creeping off."""
    creep_floor: float = 0.0
    """Nearer than this (m) to the scan or a mover, a creep must also end at least 5 mm
    farther away than the robot is now (or at this distance). Without it (0, the
    single-robot default, with which the published shielded results were measured) a creep
    only never comes closer than the robot is, and clearances of a few millimetres can
    ratchet down step by step: the filled scan and the sweep's motion model are each off by
    a few millimetres, so a creep that keeps the measured clearance can shrink the true one
    until the robot touches. The fleet's shield sets it to ``close_margin``."""

    wheel_accel: float | None = None
    """How fast (m/s^2) each wheel's rim speed follows a command, for the second sweep of a command
    the wheels cannot reach within one control period (see :meth:`Shield.check`). None: the
    robot's own (``RobotConfig.wheel_accel``: the Jackal's 3.5), and no second sweep for a robot
    without one (the article robot). Without it a big change of yaw rate at speed (the Jackal's
    4 rad/s turns) counts on a turn the robot cannot make in time."""
    gyro: bool | None = None
    """Take the robot's current yaw rate from the IMU's gyroscope instead of the wheel odometry.
    None: where the robot's wheels are measured (``RobotConfig.wheel_accel``: the Jackal), whose
    four-wheel-like skid makes the wheels' rates read a yaw rate of the wrong sign while the body
    turns (measured: odometry -2.3 rad/s, the body +1.5 rad/s); the article robot keeps odometry."""
    memory_radius: float = 1.2
    """The shield remembers what the lidar saw within this distance (m) of the body centre once
    it has left a blind sector (:mod:`bulletnav.control.shield_memory`; the Jackal's lidar sees
    270 degrees), carried forward by dead reckoning (the gyroscope's heading where ``gyro`` is
    on), and checks every sweep against it too. A lidar that sees all the way round has nothing
    to remember. 0 turns the memory off."""
    memory_margin: float = 0.03
    """In the close-range test (turning in place or backing up once inside the margin),
    remembered points count this much closer to the robot (m): each is moved this far toward the
    body centre. The lidar saw a remembered object from where the robot was then, so the side
    nearest the robot now may be one it never saw. Measured in BARN world 68 (random commands
    backing up, seed 8000000): a cylinder seen from behind, its near side never in view, was
    1.8 cm nearer the rear corner than the nearest remembered point, and a turn in place that the
    remembered points passed by 2.2 cm touched it. The other sweeps (with their larger margins)
    and the test of whether the robot is inside the margin take the points as remembered, so
    driving away from a remembered wall is never refused for it."""

    def __post_init__(self) -> None:
        if (not 0 <= self.margin_min <= self.margin or self.decel <= 0 or self.samples < 3 or self.join < 0
                or self.patience < 1 or self.creep_speed < 0 or self.creep_floor < 0 or not self.memory_radius >= 0
                or not self.memory_margin >= 0 or not (self.wheel_accel is None or self.wheel_accel > 0)):
            raise ValueError("shield needs 0 <= margin_min <= margin, decel > 0, samples >= 3, join >= 0, patience >= 1, "
                             f"creep_speed >= 0, creep_floor >= 0, memory_radius >= 0, memory_margin >= 0, wheel_accel > 0; "
                             f"got {self}")


@dataclass(frozen=True)
class ShieldDecision:
    """What the shield did this step."""

    intervened: bool
    v: float
    """Forward speed sent to the motors (m/s)."""
    w: float
    """Yaw rate sent (rad/s)."""
    change: float
    """Change in wheel rim speeds, |dv_left| + |dv_right| (m/s); 0 when it passed the command."""
    safe: bool
    """False when no candidate was clear (the shield stopped)."""
    creep: bool = False
    """True when it let the robot creep past a mover that waits for it (see ``ShieldConfig.creep_speed``)."""

    def as_info(self) -> dict[str, Any]:
        return {"intervened": self.intervened, "v": self.v, "w": self.w, "change": self.change, "safe": self.safe,
                "creep": self.creep}


_CREEP_SLACK = 1e-5
"""How much closer (m) than it already is a creep may bring the robot (the arithmetic's rounding)."""
_CREEP_GAIN = 0.005
"""Nearer than ``ShieldConfig.creep_floor``, a creep must end at least this much (m) farther
from everything than the robot is now (or at the floor), by the sweep's model: a forward creep
sweeps about 7.5 mm (0.1 m/s for one period, then braking), so it can back away from what is
behind; two parallel sides it cannot, and then the robot stands."""
_SIN_CORNER = math.sin(math.radians(15.0))
"""Two surfaces meeting at less than this angle are one surface to :meth:`Shield.points`."""


class Shield:
    """The decision alone: :meth:`check` a command, :meth:`filter` one (see the module docstring).

    Args:
        geometry: the robot's geometry (collision rectangles, lidar mount, wheelbase).
        angles: lidar ray angles (rad, body frame).
        max_range: lidar range (m): readings at it are no hit.
        control_dt: the control period (s).
        v_max, w_max: the action bounds (m/s, rad/s).
        v_min: the lowest speed (m/s): below 0 the robot may back up.
    """

    def __init__(self, geometry: RobotGeometry, angles: np.ndarray, max_range: float, control_dt: float,
                 v_max: float, w_max: float, config: ShieldConfig = ShieldConfig(), v_min: float = 0.0) -> None:
        self.config = config
        self.can_back = v_min < 0.0
        """Whether the robot may back up (the env's lowest speed under 0): only then is a command
        against the way it rolls refused (:data:`REVERSAL_SPEED`)."""
        self.geometry = geometry
        self.angles = np.asarray(angles, dtype=np.float64)
        self.cos, self.sin = np.cos(self.angles), np.sin(self.angles)
        self.max_range = max_range
        self.dt = control_dt
        self.v_max, self.w_max = v_max, w_max
        m = config.margin
        self._outline = np.array([(r.cx, r.cy, r.half_x, r.half_y) for r in geometry.rectangles])
        self._half_base = geometry.wheelbase / 2
        self._reach = geometry.outline_radius + m
        # each rectangle's farthest corner from the centre, less the margin: |c| + half size
        self._outline_abs = np.abs(self._outline[:, :2]) + self._outline[:, 2:]
        self._bare_radius = float(np.hypot(self._outline_abs[:, 0], self._outline_abs[:, 1]).max())
        self._tail = np.linspace(0.0, 1.0, config.samples - 1)[None, 1:]
        # the compiled kernels load (or compile) now, not inside an episode's first decision
        one, grid = np.zeros(1), np.zeros((1, 1))
        blocked_points(one, one, grid, grid, grid, grid, one, self._outline)
        pose_gaps(one, one, grid, grid, grid, grid, self._outline)
        self._next = np.roll(np.arange(len(self.angles)), -1)  # each ray's neighbours
        self._prev = np.roll(np.arange(len(self.angles)), 1)
        self.sweep(0.0, 0.0, 0.0)
        self.sweep(0.0, 0.0, 0.0, 0.0)
        self.points(np.full(len(self.angles), max_range))

    # ------------------------------------------------------------------ geometry
    def points(self, ranges: np.ndarray, within: float = math.inf, fill: float = 0.04) -> np.ndarray:
        """Lidar hits in the body frame, with joined surfaces filled in every ``fill`` m (N, 2);
        with ``within``, only the hits and surfaces that come that close to the body centre.

        A convex corner between two rays (a box or rack corner pointing at the robot) sticks out
        of the straight join of the two hits: where the surfaces on both sides of a joined gap
        are seen by two hits each (within twice ``join`` of each other), the corner is rebuilt as the intersection of the two
        surface lines (when they meet at 15 degrees or more, inside the gap's wedge, in front
        of the straight join and within twice its length of both hits), and the two legs to it
        are filled too."""
        return scan_points(np.asarray(ranges, dtype=np.float64), self.cos, self.sin, self.geometry.lidar_offset,
                            self.max_range, self.config.join, within, fill, _SIN_CORNER)

    def sweep(self, v: float | np.ndarray, w: float | np.ndarray, v_now: float, w_now: float | None = None,
              tighten: bool = False) -> tuple[np.ndarray, np.ndarray]:
        """Poses (C, K, 3) in the current body frame along the stopping sweeps of C commands
        (scalars give C = 1), and their times (C, K). With ``w_now`` the yaw rate moves from it
        to the command's over the first control period (the motors need that long). With
        ``tighten`` the yaw rate holds while the robot brakes (its arc tightens)."""
        cfg = self.config
        v = np.atleast_1d(np.asarray(v, dtype=np.float64))
        w = np.atleast_1d(np.asarray(w, dtype=np.float64))
        out = np.zeros((v.shape[0], cfg.samples, 3))
        t, mid, ds = sweep_profile(v, w, float(v_now), np.nan if w_now is None else float(w_now), self._tail[0],
                                    self.dt, cfg.decel, self._half_base, out, tighten)
        # position by the distance travelled in each interval along the interval's mean heading
        np.cumsum(ds * np.cos(mid), axis=1, out=out[:, 1:, 0])
        np.cumsum(ds * np.sin(mid), axis=1, out=out[:, 1:, 1])
        return out, t

    def margin(self, v1: np.ndarray | float) -> np.ndarray:
        """The margin (m) of a sweep that starts at speed ``v1`` (m/s)."""
        cfg = self.config
        return cfg.margin_min + (cfg.margin - cfg.margin_min) * np.minimum(np.asarray(v1, dtype=np.float64) / self.v_max, 1.0)

    def _blocked(self, poses: np.ndarray, points: np.ndarray, margin: np.ndarray) -> np.ndarray:
        """(C,) True where a point ((N, 2), or per pose (C, K, M, 2)) lies in the outline grown
        by the command's ``margin`` ((C,) m) at one of the poses (C, K, 3)."""
        n_cmd = poses.shape[0]
        if points.shape[-2] == 0:
            return np.zeros(n_cmd, dtype=bool)
        if points.ndim == 2:  # one point set for every pose: the compiled loop, which stops at a command's first hit
            m = np.array(np.broadcast_to(np.asarray(margin, dtype=np.float64), (n_cmd,)))  # a writable copy: one signature
            return blocked_points(np.ascontiguousarray(points[:, 0]), np.ascontiguousarray(points[:, 1]),
                                   np.ascontiguousarray(poses[:, :, 0]), np.ascontiguousarray(poses[:, :, 1]),
                                   np.cos(poses[:, :, 2]), np.sin(poses[:, :, 2]), m, self._outline)
        bx, by = in_pose_frames(poses, points)
        m = np.broadcast_to(np.asarray(margin, dtype=np.float64), (n_cmd,)).reshape((n_cmd,) + (1,) * (bx.ndim - 1))
        hit = np.zeros(bx.shape, dtype=bool)
        for cx, cy, hx, hy in self._outline:
            hit |= (np.abs(bx - cx) <= hx + m) & (np.abs(by - cy) <= hy + m)
        return hit.reshape(n_cmd, -1).any(axis=1)

    def _clearance(self, poses: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(C,) the smallest distance (m) over the poses (C, K, 3) from a point ((N, 2), or per
        pose (C, K, M, 2)) to the bare outline (its collision rectangles); inf without points."""
        return self._pose_clearance(poses, points).min(axis=1)

    def _pose_clearance(self, poses: np.ndarray, points: np.ndarray) -> np.ndarray:
        """(C, K) :meth:`_clearance` at each pose."""
        if points.shape[-2] == 0:
            return np.full(poses.shape[:2], np.inf)
        bx, by = in_pose_frames(poses, points)
        dist = np.full(bx.shape, np.inf)
        for cx, cy, hx, hy in self._outline:
            dx = np.maximum(np.abs(bx - cx) - hx, 0.0)
            dy = np.maximum(np.abs(by - cy) - hy, 0.0)
            dist = np.minimum(dist, np.hypot(dx, dy))
        return dist.min(axis=2)

    def _mover_points(self, movers: list[Any], times: np.ndarray, pose: tuple[float, float, float]) -> np.ndarray:
        """Footprint points of every mover at each time (C, K), in the robot's body frame (C, K, M, 2)."""
        rx, ry, ryaw = pose
        c0, s0 = math.cos(ryaw), math.sin(ryaw)
        out = []
        for m in movers:
            mx, my, myaw = m.pose
            lx, ly = m.size[0] / 2, m.size[1] / 2
            if m.kind == "worker":
                local = _DISC * lx
            elif m.kind == "robot":
                local = _RING * (math.hypot(lx, ly) + _RING_MARGIN)
            else:
                local = _BOX * (lx, ly)
            cm, sm = math.cos(myaw), math.sin(myaw)
            wx = mx + cm * local[:, 0] - sm * local[:, 1]
            wy = my + sm * local[:, 0] + cm * local[:, 1]
            # constant velocity along its heading (a worker's heading is its walking direction)
            dx = (m.speed * cm * times)[..., None] + wx - rx
            dy = (m.speed * sm * times)[..., None] + wy - ry
            out.append(np.stack([c0 * dx + s0 * dy, -s0 * dx + c0 * dy], axis=-1))
        return np.concatenate(out, axis=2)

    # ------------------------------------------------------------------ decisions
    def check(self, v: float | np.ndarray, w: float | np.ndarray, v_now: float, points: np.ndarray,
              movers: list[Any] | None = None, pose: tuple[float, float, float] = (0.0, 0.0, 0.0),
              w_now: float | None = None, back_room: float = math.inf) -> np.ndarray:
        """(C,) True where the sweep of command (v, w) is clear of ``points`` (body frame) and
        ``movers`` for the outline grown by the sweep's margin (see :meth:`margin`); a command
        that backs up (v < 0) must also stay within ``back_room`` m behind the robot."""
        poses, times = self.sweep(v, w, v_now, w_now)
        margin = self.margin(start_speed(np.atleast_1d(np.asarray(v, dtype=np.float64)), v_now))
        if len(points):  # only points within the grown outline's reach of some pose can be hit
            m = float(margin.max())
            far = travel(poses) + float(np.hypot(self._outline_abs[:, 0] + m, self._outline_abs[:, 1] + m).max())
            points = points[points[:, 0] ** 2 + points[:, 1] ** 2 <= far * far]
        blocked = self._blocked(poses, points, margin)
        if movers:
            blocked |= self._blocked(poses, self._mover_points(movers, times, pose), margin)
        vv = np.atleast_1d(np.asarray(v, dtype=np.float64))
        ww = np.broadcast_to(np.atleast_1d(np.asarray(w, dtype=np.float64)), vv.shape)
        if self.config.wheel_accel is not None:
            # a robot whose wheels are measured (the Jackal) keeps turning as it brakes: measured
            # braking from 1.5 m/s at 1.6 rad/s, its yaw rate held 1.6-1.9 rad/s to the stop, and
            # a slow reverse turning at 3.4 rad/s turned on for 0.1 s after its stop; the sweep
            # whose arc tightens so, then spins down, is checked too
            turning = (vv != 0.0) & (ww != 0.0) & ~blocked
            if turning.any():
                idx = np.flatnonzero(turning)
                spiral, spiral_t = self.sweep(vv[idx], ww[idx], v_now, w_now, tighten=True)
                hit = self._blocked(spiral, points, margin[idx])
                if movers:
                    hit |= self._blocked(spiral, self._mover_points(movers, spiral_t, pose), margin[idx])
                blocked[idx] |= hit
        blocked |= self._lag_blocked(vv, ww, v_now, w_now, points, margin, movers, pose, blocked)
        back = vv < 0.0
        if back.any():
            # backing up goes no farther back than the room behind (the way the robot came)
            blocked |= back & (-poses[:, :, 0].min(axis=1) > back_room)
        return ~(blocked | _reversing(v, v_now)) if self.can_back else ~blocked

    def _lag_blocked(self, vv: np.ndarray, ww: np.ndarray, v_now: float, w_now: float | None, points: np.ndarray,
                     margin: np.ndarray, movers: list[Any] | None, pose: tuple[float, float, float],
                     skip: np.ndarray) -> np.ndarray:
        """(C,) True where a command (not in ``skip``) hits ``points`` or a mover along one of its
        sweeps as the wheels follow it (:func:`wheel_sweep`: each rim speed moves at ``wheel_accel``
        for one control period):

        - a command the wheels cannot reach in one period, then braking at ``decel``. Measured on
          the Jackal: turning in place at -1 rad/s and told to back up straight, the body turns on
          at -1 rad/s for two periods and stops turning after five, as this sweep says;
        - a command that moves the robot while it turns (now or commanded), then braking at
          ``wheel_accel``, as the Jackal's rims do: both rims brake alike, so the yaw rate holds
          until the inner one stops and the robot ends pivoting on it. Measured on the Jackal:
          stopped from 1.7 m/s turning at -1.0 rad/s, it rolled 0.46 m and turned 0.53 rad, as
          this sweep says; the sweep braking at ``decel`` rolls twice as far with the same turn,
          a gentler curve that passes beside what the real one turns into (BARN world 231).

        All False for a robot without ``wheel_accel`` or without ``w_now``."""
        out = np.zeros(vv.shape, dtype=bool)
        if w_now is None or self.config.wheel_accel is None:
            return out
        accel = self.config.wheel_accel
        hb, reach = self._half_base, accel * self.dt
        slow = ((np.abs((vv - ww * hb) - (v_now - w_now * hb)) > reach)
                | (np.abs((vv + ww * hb) - (v_now + w_now * hb)) > reach)) & ~skip
        moving = (vv != 0.0) | (v_now != 0.0)
        turning = (ww != 0.0) | (w_now != 0.0)
        hard = moving & turning & ~skip
        for which, decel in ((slow, self.config.decel), (hard, accel)):
            todo = which & ~out
            if not todo.any():
                continue
            idx = np.flatnonzero(todo)
            lag = np.zeros((len(idx), self.config.samples, 3))
            lag_t = np.zeros((len(idx), self.config.samples))
            wheel_sweep(np.ascontiguousarray(vv[idx]), np.ascontiguousarray(ww[idx]), float(v_now), float(w_now),
                        self.dt, accel, decel, hb, lag, lag_t)
            lag_pts = points
            if len(points):
                m = float(np.max(margin))
                far = travel(lag) + float(np.hypot(self._outline_abs[:, 0] + m, self._outline_abs[:, 1] + m).max())
                lag_pts = points[points[:, 0] ** 2 + points[:, 1] ** 2 <= far * far]
            hit = self._blocked(lag, lag_pts, margin[idx])
            if movers:
                hit |= self._blocked(lag, self._mover_points(movers, lag_t, pose), margin[idx])
            out[idx] |= hit
        return out

    def _touch_free(self, v_now: float, points: np.ndarray, movers: list[Any], pose: tuple[float, float, float],
                    w_now: float | None) -> bool:
        """Whether the full stop's sweep keeps the bare outline off every point and mover."""
        poses, times = self.sweep(0.0, 0.0, v_now, w_now)
        gap = float(self._clearance(poses, points)[0])
        if movers:
            gap = min(gap, float(self._clearance(poses, self._mover_points(movers, times, pose))[0]))
        return gap > 0.0

    def _close_clear(self, v: np.ndarray, w: np.ndarray, v_now: float, ranges: np.ndarray, movers: list[Any],
                     pose: tuple[float, float, float], w_now: float | None, memory: np.ndarray | None = None,
                     back_room: float = math.inf) -> np.ndarray:
        """(C,) True where the sweep keeps the bare outline grown by ``close_margin`` off the scan
        filled in every 1 cm and off the movers: the test for turning in place (or backing up,
        within ``back_room``) once inside the margin."""
        cfg = self.config
        if memory is not None:  # the remembered objects' unseen near sides (ShieldConfig.memory_margin)
            memory = nearer(memory, cfg.memory_margin)
        poses, times = self.sweep(v, w, v_now, w_now)
        within = self._bare_radius + cfg.close_margin + travel(poses)
        dense = _joined(self.points(ranges, within=within, fill=0.01), memory, within)
        margin = np.full(poses.shape[0], cfg.close_margin)
        blocked = self._blocked(poses, dense, margin)
        if movers:
            blocked |= self._blocked(poses, self._mover_points(movers, times, pose), margin)
        back = v < 0.0
        blocked |= back & (-poses[:, :, 0].min(axis=1) > back_room)
        if self.can_back:
            blocked |= _reversing(v, v_now)
        if back.any():  # a slow back-up with a fast turn: the turn goes on after the stop (the spiral sweep)
            idx = np.flatnonzero(back)
            spiral, spiral_t = self.sweep(v[idx], w[idx], v_now, w_now, tighten=True)
            wide = self._bare_radius + cfg.close_margin + travel(spiral)
            hit = self._blocked(spiral, _joined(self.points(ranges, within=wide, fill=0.01), memory, wide), margin[idx])
            if movers:
                hit |= self._blocked(spiral, self._mover_points(movers, spiral_t, pose), margin[idx])
            blocked[idx] |= hit
        if self.config.wheel_accel is not None and w_now is not None:
            # the turn the wheels cannot stop in one period goes on (measured on the Jackal): its sweep too
            lag_within = self._bare_radius + cfg.close_margin + self.v_max * self.dt + max(abs(v_now), 0.5) ** 2 / cfg.decel
            lag_pts = _joined(self.points(ranges, within=lag_within, fill=0.01), memory, lag_within)
            blocked |= self._lag_blocked(np.asarray(v, dtype=np.float64), np.asarray(w, dtype=np.float64), v_now, w_now,
                                         lag_pts, margin, movers, pose, blocked)
        return ~blocked

    def _creep_clear(self, v: np.ndarray, w: np.ndarray, v_now: float, ranges: np.ndarray, movers: list[Any],
                     pose: tuple[float, float, float], w_now: float | None, memory: np.ndarray | None = None) -> np.ndarray:
        """(C,) True where no pose of the sweep brings the bare outline closer to the scan
        (filled in every 1 cm) or to a mover than the robot already is: the test for creeping
        past a mover that waits for the robot. The clearance never shrinks while it creeps, so
        a creep can pass a gap that is there but never wedge the robot in tighter."""
        poses, times = self.sweep(v, w, v_now, w_now)
        within = self._reach + travel(poses)
        dense = _joined(self.points(ranges, within=within, fill=0.01), memory, within)  # all within the margin of a pose
        gaps = pose_gaps(np.ascontiguousarray(dense[:, 0]), np.ascontiguousarray(dense[:, 1]),
                          np.ascontiguousarray(poses[:, :, 0]), np.ascontiguousarray(poses[:, :, 1]),
                          np.cos(poses[:, :, 2]), np.sin(poses[:, :, 2]), self._outline)
        if movers:
            gaps = np.minimum(gaps, self._pose_clearance(poses, self._mover_points(movers, times, pose)))
        # every sweep's first pose is where the robot stands: its gap is the clearance now
        now, floor = float(gaps[0, 0]), self.config.creep_floor
        clear = gaps.min(axis=1) >= now - _CREEP_SLACK
        if now < floor:  # nearer than the floor already: away by _CREEP_GAIN too (or to the floor)
            clear &= gaps[:, -1] >= min(floor, now + _CREEP_GAIN)
        robots = [m for m in movers if m.kind == "robot"] if movers else []
        if robots:  # a robot's ring is no body: a robot on it (gap 0) may not creep, nor creep nearer to it
            ring = self._pose_clearance(poses, self._mover_points(robots, times, pose))
            clear &= (ring.min(axis=1) > 0.0) & (ring.min(axis=1) >= ring[0, 0] - _CREEP_SLACK)
        return clear

    def filter(self, v: float, w: float, v_now: float, ranges: np.ndarray, movers: list[Any] | None = None,
               pose: tuple[float, float, float] = (0.0, 0.0, 0.0), w_now: float | None = None,
               stuck: float | None = None, memory: np.ndarray | None = None, back_room: float = math.inf) -> ShieldDecision:
        """The command to send instead of (v, w) (itself when its sweep is clear). ``stuck``
        (see ``ShieldConfig.patience``): 0 adds turns in place both ways and puts the stop
        last; +1 or -1 also puts the turns in place of the other sign after the stop. ``memory``:
        points the lidar no longer sees (body frame; :mod:`~bulletnav.control.shield_memory`),
        checked as the scan's are; ``back_room``: how far (m) a command may back the robot."""
        cfg = self.config
        if v == 0.0 and w == 0.0:  # a stop passes: nothing is safer, and the shield never drives
            return ShieldDecision(False, v, w, 0.0, True)
        coast = self.dt + self.v_max / cfg.decel
        reach = self._reach + max(v_now, self.v_max) * coast  # the farthest any sweep gets
        points = _joined(self.points(ranges, within=reach), memory, reach)
        near = [m for m in (movers or ()) if math.hypot(m.pose[0] - pose[0], m.pose[1] - pose[1])
                < reach + max(m.size[:2]) + m.speed * coast]
        # inside the margin already: every sweep starts here, so none is clear (skip to the fallback)
        here = np.zeros((1, 1, 3))
        m_now = self.margin(max(v_now, 0.0))
        inside = bool(self._blocked(here, points, m_now)[0]) or bool(
            near and self._blocked(here, self._mover_points(near, np.zeros((1, 1)), pose), m_now)[0])
        if not inside and self.check(v, w, v_now, points, near, pose, w_now=w_now, back_room=back_room)[0]:
            return ShieldDecision(False, v, w, 0.0, True)
        hb = self._half_base
        options = [(v * scale, min(max(w + dw, -self.w_max), self.w_max))
                   for scale in (1.0, *cfg.speed_scales) for dw in cfg.turn_offsets if (scale, dw) != (1.0, 0.0)]
        if stuck is not None:
            options += [(0.0, sign * min(rate, self.w_max)) for rate in cfg.escape_rates for sign in (1.0, -1.0)]
        cand = np.array([(0.0, 0.0)] + options)  # a full stop is always among them, first among equals
        change = (np.abs((cand[:, 0] - cand[:, 1] * hb) - (v - w * hb))
                  + np.abs((cand[:, 0] + cand[:, 1] * hb) - (v + w * hb)))
        rank = change.copy()
        if stuck is not None:  # anything that moves comes before the stop; turns the other way after it
            rank[(cand[:, 0] == 0.0) & ((cand[:, 1] == 0.0) | (cand[:, 1] * stuck < 0.0))] = np.inf
        order = np.argsort(rank, kind="stable")
        cand, change, rank = cand[order], change[order], rank[order]
        # stuck beside a mover that waits for the robot: creeping past it (where it comes no
        # closer to anything, see _creep_clear) ranks among the others by its change, ahead of
        # the turns in place and the stop
        creep = (stuck is not None and v > 0.0 and cfg.creep_speed > 0.0
                 and any(getattr(m, "yielding", False) or m.kind == "robot" for m in near))
        if creep:
            slow = min(cfg.creep_speed, v)
            crawl = np.array([(slow, min(max(w + dw, -self.w_max), self.w_max)) for dw in cfg.turn_offsets]
                             + [(0.0, sign * min(rate, self.w_max)) for rate in cfg.escape_rates for sign in (1.0, -1.0)
                                if sign * stuck >= 0.0])  # turns in place: only the way it took, once it took one
            crawl_change = (np.abs((crawl[:, 0] - crawl[:, 1] * hb) - (v - w * hb))
                            + np.abs((crawl[:, 0] + crawl[:, 1] * hb) - (v + w * hb)))
            split = int(np.searchsorted(rank, crawl_change.min(), side="right"))
        else:
            split = len(cand)
        # by increasing change, the nearest few first, then all the rest in one go: the first
        # clear one is the closest safe command
        batches = ((0, min(_BATCH, split)), (min(_BATCH, split), split), (split, len(cand)))
        for i, (lo, hi) in enumerate(batches):
            if i == 2 and creep:
                by = np.argsort(crawl_change, kind="stable")
                clear = self._creep_clear(crawl[by, 0], crawl[by, 1], v_now, ranges, near, pose, w_now, memory)
                if clear.any():
                    best = int(by[np.argmax(clear)])
                    return ShieldDecision(True, float(crawl[best, 0]), float(crawl[best, 1]), float(crawl_change[best]),
                                          True, creep=True)
            if inside or hi <= lo:
                continue
            clear = self.check(cand[lo:hi, 0], cand[lo:hi, 1], v_now, points, near, pose, w_now=w_now, back_room=back_room)
            if clear.any():
                best = lo + int(np.argmax(clear))
                return ShieldDecision(True, float(cand[best, 0]), float(cand[best, 1]), float(change[best]), True)
        # already inside the margin: a turn in place (or the stop) that passes the close-range test
        # (stuck: its own way first, then the other way, then the stop -- the ranks already put
        # the other way after this one; standing beside a wall is the last resort)
        turns = np.flatnonzero(cand[:, 0] <= 0.0)  # turns in place, and backing up where the env allows it
        if stuck:
            turns = np.concatenate([turns[cand[turns, 1] != 0.0], turns[cand[turns, 1] == 0.0]])
        clear = self._close_clear(cand[turns, 0], cand[turns, 1], v_now, ranges, near, pose, w_now, memory, back_room)
        if not clear.any():  # the last resort; safe when even its coasting keeps off the bare outline
            stop = int(np.flatnonzero((cand[:, 0] == 0.0) & (cand[:, 1] == 0.0))[0])
            return ShieldDecision(True, 0.0, 0.0, float(change[stop]), self._touch_free(v_now, points, near, pose, w_now))
        best = int(turns[np.argmax(clear)])
        return ShieldDecision(True, float(cand[best, 0]), float(cand[best, 1]), float(change[best]), True)


REVERSAL_SPEED = 0.05
"""A command against the way the robot still rolls faster than this (m/s) -- backing up while it
rolls forward, or driving on while it rolls back -- is never clear: the robot stops first. (Sent
while rolling, such a command brakes one wheel and reverses the other, and the robot rolls on,
turning, much farther than either sweep says: measured on the Jackal.)"""


def nearer(points: np.ndarray, by: float) -> np.ndarray:
    """``points`` (N, 2; body frame) each moved ``by`` m toward the body centre (a point nearer
    than that to it lands on the centre)."""
    if by <= 0.0 or len(points) == 0:
        return points
    r = np.hypot(points[:, 0], points[:, 1])
    scale = np.where(r > by, (r - by) / np.maximum(r, 1e-12), 0.0)
    return points * scale[:, None]


def _reversing(v: float | np.ndarray, v_now: float) -> np.ndarray:
    """(C,) True where command speed ``v`` is against the roll ``v_now`` (m/s) beyond :data:`REVERSAL_SPEED`."""
    v = np.atleast_1d(np.asarray(v, dtype=np.float64))
    return ((v < 0.0) & (v_now > REVERSAL_SPEED)) | ((v > 0.0) & (v_now < -REVERSAL_SPEED))


def _joined(points: np.ndarray, memory: np.ndarray | None, within: float) -> np.ndarray:
    """``points`` and the remembered ones within ``within`` m of the body centre (body frame)."""
    if memory is None or not len(memory):
        return points
    near = memory[memory[:, 0] ** 2 + memory[:, 1] ** 2 <= within * within]
    return np.concatenate([points, near]) if len(near) else points


NO_DECISION = ShieldDecision(False, 0.0, 0.0, 0.0, True)
"""What ``info["shield"]`` holds after a reset (no command yet)."""


class Veto:
    """The shield on one env, one call per step: ``veto(action) -> (action to send, decision)``.
    It reads the scene's lidar scan, odometry and movers, and maps a replacement command back
    into the env's action space (the inverse of the env's linear ``command`` map).
    :class:`ShieldWrapper` and :class:`SafetyShield` both decide through it."""

    def __init__(self, env: Any, config: ShieldConfig) -> None:
        self.base = env.unwrapped
        self.shield = shield_for(env, config)
        low, high = env.action_space.low.astype(np.float64), env.action_space.high.astype(np.float64)
        (lo_v, lo_w), (hi_v, hi_w) = self.base.command(low), self.base.command(high)
        self._map = (lo_v, lo_w, hi_v, hi_w, low, high)
        self.held = 0
        """Consecutive steps the shield has replaced the command by a stop or a turn in place."""
        self.escape = 0.0
        """The sign of the turn in place it took while stuck (0: none yet)."""
        scene = self.base.scene
        self.memory = ScanMemory(scene.geometry, scene.sensors.lidar.angles, config.memory_radius)
        """What the lidar saw and no longer sees (empty for a lidar that sees all the way round)."""
        self.back_room = 0.0
        """How far (m, by odometry) the robot may back up: the forward distance it has driven,
        less what it has backed since, at most ``config.memory_radius`` (the space it came
        through, whose sides the lidar saw on the way in)."""
        self._dt = scene.control_dt
        gyro = self.shield.config.gyro
        self._gyro = scene.wheel_accel is not None if gyro is None else gyro
        self._pose = (0.0, 0.0, 0.0)
        self._rates: tuple[float, float] | None = None

    def reset(self) -> None:
        """Forget the last episode (call at every env reset)."""
        self.held, self.escape = 0, 0.0
        self.memory.reset()
        self.back_room = 0.0
        self._pose, self._rates = (0.0, 0.0, 0.0), None

    def _memory_pose(self, odometry: np.ndarray, v_now: float, w_now: float) -> tuple[float, float, float]:
        """The pose the memory is carried by. With the gyroscope (the Jackal) the shield dead-reckons
        its own: yaw from the gyroscope's rate, distance from the wheels' speed, both as the mean of
        the rates at the start and end of each period. The wheels' own pose drifts fast while a
        skid-steered robot turns in place (measured on the Jackal: 26 degrees in 30 s of dithering
        turns), and a memory carried by it puts a remembered obstacle beside where it is."""
        if not self._gyro:
            return float(odometry[0]), float(odometry[1]), float(odometry[2])
        if self._rates is not None:
            x, y, yaw = self._pose
            v0, w0 = self._rates
            dyaw = 0.5 * (w0 + w_now) * self._dt
            ds = 0.5 * (v0 + v_now) * self._dt
            mid = yaw + 0.5 * dyaw
            self._pose = (x + ds * math.cos(mid), y + ds * math.sin(mid), yaw + dyaw)
        self._rates = (v_now, w_now)
        return self._pose

    def __call__(self, action: Any) -> tuple[Any, ShieldDecision]:
        """The action to send instead of ``action`` (``action`` itself, the same object, when
        its sweep is clear) and the decision."""
        scene = self.base.scene
        v, w = self.base.command(action)
        ranges = np.asarray(scene.sensors.lidar.read(), dtype=np.float64)
        odometry = scene.sensors.odometry.read()
        movers = list(scene.movers) if scene.dynamic else None
        stuck = self.held >= self.shield.config.patience
        v_now = float(odometry[3])
        w_now = float(scene.sensors.imu.read()[5]) if self._gyro else float(odometry[4])
        memory = None
        if self.memory.active:
            seen = self.shield.points(ranges, within=self.memory.radius, fill=0.01)
            memory = self.memory.update(self._memory_pose(odometry, v_now, w_now), seen)
        self.back_room = min(max(self.back_room + v_now * self._dt, 0.0), self.shield.config.memory_radius)
        d = self.shield.filter(v, w, v_now, ranges, movers, tuple(scene.pose), w_now=w_now,
                               stuck=self.escape if stuck else None, memory=memory,
                               back_room=self.back_room if v < 0.0 else math.inf)
        if d.intervened and (d.v == 0.0 or d.creep):  # creeping past a waiting mover stays stuck
            self.held += 1
            if stuck and d.v == 0.0 and d.w != 0.0 and not self.escape:
                self.escape = math.copysign(1.0, d.w)
        else:
            self.held, self.escape = 0, 0.0
        return (self._action(d.v, d.w) if d.intervened else action), d

    def _action(self, v: float, w: float) -> np.ndarray:
        lo_v, lo_w, hi_v, hi_w, low, high = self._map
        a0 = low[0] + (v - lo_v) / (hi_v - lo_v) * (high[0] - low[0])
        a1 = low[1] + (w - lo_w) / (hi_w - lo_w) * (high[1] - low[1])
        return np.clip(np.array([a0, a1], dtype=np.float32), low.astype(np.float32), high.astype(np.float32))


class SafetyShield:
    """Any :class:`~bulletnav.policy.Policy` behind the shield, itself a Policy: ``act`` asks
    the wrapped policy, then vetoes its action when the sweep is not clear. ``decision`` is
    the last step's :class:`ShieldDecision`; ``interventions`` and ``steps`` count this episode.

    Args:
        policy: the controller to guard (the navigator, an :class:`~bulletnav.rl.policy.SB3Policy`, your own).
        env: the env it drives (the shield reads ``env.unwrapped.scene``: lidar, odometry, movers).
    """

    def __init__(self, policy: Any, env: Any, config: ShieldConfig = ShieldConfig()) -> None:
        self.policy = policy
        self._veto = Veto(env, config)
        self.decision: ShieldDecision = NO_DECISION
        self.interventions = 0
        self.steps = 0

    def reset(self, info: dict[str, Any]) -> None:
        self.policy.reset(info)
        self._veto.reset()
        self.decision, self.interventions, self.steps = NO_DECISION, 0, 0

    def act(self, obs: Any, info: dict[str, Any]) -> Any:
        action, self.decision = self._veto(self.policy.act(obs, info))
        self.steps += 1
        self.interventions += self.decision.intervened
        return action

    def __getattr__(self, name: str) -> Any:  # the wrapped policy's path, plan_times, replans ...
        if name == "policy":
            raise AttributeError(name)
        return getattr(self.policy, name)


class ShieldWrapper(gym.Wrapper):
    """The shield between any controller and an env: each ``step``'s action is checked against
    the current lidar scan and the scene's movers and replaced when its sweep is not clear;
    ``info["shield"]`` reports the decision (``intervened``, the sent ``v`` and ``w``, the
    wheel-speed ``change``, ``safe``). Evaluation (``--shield``) runs every controller this way,
    and with it around the training env (``train --shield``) a policy learns with the shield
    in the loop. :class:`SafetyShield` is the same veto as a policy wrapper.
    """

    def __init__(self, env: gym.Env, config: ShieldConfig = ShieldConfig()) -> None:
        super().__init__(env)
        self._veto = Veto(env, config)
        self.shield = self._veto.shield
        self.decision: ShieldDecision | None = None
        """The last step's decision."""

    def step(self, action: Any):
        action, d = self._veto(action)
        self.decision = d
        obs, reward, terminated, truncated, info = self.env.step(action)
        info["shield"] = d.as_info()
        return obs, reward, terminated, truncated, info

    def reset(self, **kwargs: Any):
        obs, info = self.env.reset(**kwargs)
        self._veto.reset()
        self.decision = None
        info["shield"] = NO_DECISION.as_info()
        return obs, info


def shield_for(env: Any, config: ShieldConfig = ShieldConfig()) -> Shield:
    """A :class:`Shield` for ``env`` (its robot, lidar, control period and action bounds)."""
    scene = env.unwrapped.scene
    lidar = scene.sensors.lidar
    space = env.action_space
    v_max, w_max = env.unwrapped.command(space.high.astype(np.float64))
    v_min, _ = env.unwrapped.command(space.low.astype(np.float64))
    if config.wheel_accel is None and scene.wheel_accel is not None:
        config = replace(config, wheel_accel=scene.wheel_accel)
    return Shield(scene.geometry, lidar.angles, lidar.config.max_range, scene.control_dt, v_max, w_max, config, v_min=v_min)
