"""Moving obstacles: forklifts that patrol routes and workers that walk between waypoints.

A mover is described by a frozen spec (:class:`ForkliftSpec`, :class:`WorkerSpec`: from a
YAML layout's ``dynamic:`` list or generated per episode by :mod:`bulletnav.sim.dynamic`)
and moved by :class:`Movers`, which owns a pool of PyBullet bodies created with the world
(resets on the same layout reuse them: no body is created or removed per reset).

Kinematics (exact, no physics acts on a mover): a forklift drives its route back and forth
at constant ``speed`` (with ``accel`` set, it ramps up from rest and slows to a stop before
each reversal), heading along the segment it drives; it starts at the route's first point,
facing the first segment. A worker walks its waypoints back and forth at ``speed``, pausing
``pause`` seconds at each. Movers are mass-0 bodies teleported every physics step while
they are near the robot (so contacts see them move smoothly) and once per control step
otherwise (so every sensor reading sees each mover where its kinematics put it).

Yielding (``yield_to_robot``, default true): a forklift stops while the robot's footprint
disc overlaps its safety field, a rectangle ahead of its front (``field_length`` = 1.0 m
long, its width + 0.2 m wide), and resumes when the robot leaves; a worker stops while the
gap between the robot's footprint disc and its body is under ``stop_distance`` (0.6 m).
Decided once per control step from the robot's ground truth; with several robots (a fleet),
from the robot nearest the field (:func:`yield_target`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import pybullet as p

from bulletnav.sim.specs import ForkliftSpec, MoverSpec, WorkerSpec
from bulletnav.sim.world import STATIC_GROUP, STATIC_MASK, static_body

PARK_Z = -20.0
"""Height (m) at which unused pool bodies wait, below the floor: no ray, camera or robot reaches them."""

FORKLIFT_COLOUR = (0.95, 0.62, 0.05, 1.0)
WORKER_COLOUR = (0.15, 0.45, 0.95, 1.0)


@dataclass(frozen=True)
class MoverView:
    """A mover as consumers see it (``env.unwrapped.scene.movers``): read-only."""

    kind: str
    """``"forklift"`` or ``"worker"``."""
    pose: tuple[float, float, float]
    """x, y (m) of its centre and heading (rad)."""
    speed: float
    """Current speed (m/s); 0 while stopped, paused or yielding."""
    size: tuple[float, float, float]
    """Forklift: length, width, height (m); worker: (2 radius, 2 radius, height)."""
    path: tuple[tuple[float, float], ...]
    """Its route or waypoints (m)."""
    yielding: bool
    """True while it waits for the robot."""
    body: int
    """Its PyBullet body id (for drawing; do not move it)."""


class _Track:
    """Back-and-forth motion along a polyline: segment, direction and arc position."""

    __slots__ = ("points", "lengths", "yaws", "seg", "dir", "s")

    def __init__(self, points: tuple[tuple[float, float], ...]) -> None:
        self.points = points
        self.lengths = [math.dist(a, b) for a, b in zip(points, points[1:])]
        # heading along each segment, driven forward (+1) and back (-1)
        self.yaws = {(i, d): math.atan2(d * (b[1] - a[1]), d * (b[0] - a[0]))
                     for i, (a, b) in enumerate(zip(points, points[1:])) for d in (1, -1)}
        self.seg, self.dir, self.s = 0, 1, 0.0

    def position(self) -> tuple[float, float, float]:
        (ax, ay), (bx, by) = self.points[self.seg], self.points[self.seg + 1]
        length = self.lengths[self.seg]
        f = self.s / length if length > 0 else 0.0
        return ax + (bx - ax) * f, ay + (by - ay) * f, self.yaws[self.seg, self.dir]

    def to_end(self) -> float:
        """Distance left before the next reversal (m)."""
        if self.dir > 0:
            return self.lengths[self.seg] - self.s + sum(self.lengths[self.seg + 1:])
        return self.s + sum(self.lengths[:self.seg])

    def advance(self, distance: float, stop_at_vertex: bool = False, stop_at_corner: bool = False) -> bool:
        """Move ``distance`` m along the track (reversing at its ends). Returns True when a
        vertex was reached and cut the move short there: any vertex with ``stop_at_vertex``,
        an interior one (a corner, not an end) with ``stop_at_corner``."""
        last = len(self.lengths) - 1
        while distance > 0.0:
            if self.dir > 0:
                room = self.lengths[self.seg] - self.s
                if distance < room:
                    self.s += distance
                    return False
                distance -= room
                if self.seg < last:
                    self.seg, self.s = self.seg + 1, 0.0
                    if stop_at_corner:
                        return True
                else:
                    self.s, self.dir = self.lengths[self.seg], -1
            else:
                if distance < self.s:
                    self.s -= distance
                    return False
                distance -= self.s
                if self.seg > 0:
                    self.seg -= 1
                    self.s = self.lengths[self.seg]
                    if stop_at_corner:
                        return True
                else:
                    self.s, self.dir = 0.0, 1
            if stop_at_vertex:
                return True
        return False


class _Mover:
    """One active mover: its spec, track, speed state and pool body."""

    __slots__ = ("spec", "track", "body", "speed", "pause_left", "yielding", "pose", "half_height", "placed", "reach", "radius",
                 "gap", "turn_to")

    def __init__(self, spec: MoverSpec, body: int) -> None:
        self.spec = spec
        self.track = _Track(spec.route if isinstance(spec, ForkliftSpec) else spec.waypoints)
        self.body = body
        self.speed = 0.0 if isinstance(spec, ForkliftSpec) and spec.accel else spec.speed
        self.pause_left = 0.0
        self.yielding = False
        self.pose = self.track.position()
        self.half_height = (spec.size[2] if isinstance(spec, ForkliftSpec) else spec.height) / 2
        self.placed: tuple[float, float, float] | None = None
        """Where its body was last put (None: parked)."""
        # beyond this centre distance (plus the robot's radius) the robot cannot be in its field
        self.radius = spec.bounding_radius
        self.turn_to: float | None = None
        """A forklift turning in place at a route corner: the heading it turns to (rad)."""
        self.gap = math.inf
        """Centre distance to the robot minus :attr:`radius` after the last step (m)."""
        self.reach = spec.bounding_radius + (spec.field_length if isinstance(spec, ForkliftSpec) else spec.stop_distance)

    def step(self, dt: float, robot_xy: tuple[float, float], robot_radius: float) -> None:
        """Advance ``dt`` seconds of kinematics, yielding to the robot at ``robot_xy``."""
        spec = self.spec
        x, y, _ = self.pose
        self.yielding = (spec.yield_to_robot and abs(robot_xy[0] - x) < self.reach + robot_radius
                         and abs(robot_xy[1] - y) < self.reach + robot_radius and self._robot_in_field(robot_xy, robot_radius))
        if self.yielding:
            self.speed = 0.0 if isinstance(spec, ForkliftSpec) and spec.accel else self.speed
            return
        if self.turn_to is not None:  # a forklift turning in place at a corner
            x, y, yaw = self.pose
            left = math.remainder(self.turn_to - yaw, 2 * math.pi)
            turn = spec.turn_rate * dt
            if abs(left) <= turn:
                self.pose, self.turn_to = (x, y, self.turn_to), None
            else:
                self.pose = (x, y, yaw + math.copysign(turn, left))
            return
        if isinstance(spec, WorkerSpec):
            if self.pause_left > 0.0:
                self.pause_left = max(0.0, self.pause_left - dt)
                return  # standing at a waypoint: the pose is unchanged
            if self.track.advance(spec.speed * dt, stop_at_vertex=True):
                self.pause_left = spec.pause
        elif spec.accel:
            # ramp up, and never faster than what still stops at the next reversal
            brake = math.sqrt(2.0 * spec.accel * self.track.to_end())
            v_next = min(spec.speed, self.speed + spec.accel * dt, max(brake, spec.accel * dt))
            distance = 0.5 * (self.speed + v_next) * dt
            before = self.track.dir
            if self.track.advance(distance, stop_at_corner=True):
                self.speed = 0.0
                yaw = self.pose[2]
                x, y, self.turn_to = self.track.position()
                self.pose = (x, y, yaw)
                return
            self.speed = 0.0 if self.track.dir != before else v_next
        elif self.track.advance(spec.speed * dt, stop_at_corner=True):  # at a corner: turn before driving on
            yaw = self.pose[2]
            x, y, self.turn_to = self.track.position()
            self.pose = (x, y, yaw)
            return
        self.pose = self.track.position()

    def moving_speed(self) -> float:
        if self.yielding or self.pause_left > 0.0:
            return 0.0
        return self.speed

    def _robot_in_field(self, robot_xy: tuple[float, float], robot_radius: float) -> bool:
        x, y, yaw = self.pose
        dx, dy = robot_xy[0] - x, robot_xy[1] - y
        spec = self.spec
        if isinstance(spec, WorkerSpec):
            return math.hypot(dx, dy) - spec.radius - robot_radius < spec.stop_distance
        if self.turn_to is not None:  # turning in place: the field is the circle it sweeps
            return math.hypot(dx, dy) < spec.bounding_radius + spec.field_margin + robot_radius
        c, s = math.cos(yaw), math.sin(yaw)
        lx, ly = c * dx + s * dy, -s * dx + c * dy  # robot centre in the forklift's frame
        x0 = spec.size[0] / 2
        x1 = x0 + spec.field_length
        half_w = (spec.size[1] + spec.field_margin) / 2
        ex = max(x0 - lx, 0.0, lx - x1)
        ey = max(abs(ly) - half_w, 0.0)
        return math.hypot(ex, ey) < robot_radius

    def view(self) -> MoverView:
        spec = self.spec
        if isinstance(spec, ForkliftSpec):
            size, path = tuple(spec.size), spec.route
        else:
            size, path = (2 * spec.radius, 2 * spec.radius, spec.height), spec.waypoints
        return MoverView(spec.kind, self.pose, self.moving_speed(), size, path, self.yielding, self.body)  # type: ignore[arg-type]


class Movers:
    """The movers of one scene: a body pool made with the world, and their kinematics.

    Args:
        cid: the PyBullet client.
        shapes: the pool, as (shape, count) pairs; a shape is ``("box", (l, w, h))`` or
            ``("cylinder", (radius, height))``.
    """

    def __init__(self, cid: int) -> None:
        self.cid = cid
        self.pool: dict[tuple[str, tuple[float, ...]], list[int]] = {}
        self.active: list[_Mover] = []
        self.body_ids: frozenset[int] = frozenset()
        """Every pool body (active or parked), for the collision check."""
        self.created = 0
        """Bodies created so far (for the no-body-per-reset test)."""

    def build(self, shapes: dict[tuple[str, tuple[float, ...]], int], labels: dict[int, str]) -> None:
        """Create the pool in a freshly built world (``labels``: the world's body labels)."""
        self.pool = {}
        self.active = []
        for shape, count in shapes.items():
            kind, dims = shape
            bodies = []
            for _ in range(count):
                body = self._new_body(kind, dims)
                labels[body] = "forklift" if kind == "box" else "worker"
                bodies.append(body)
                self.created += 1
            self.pool[shape] = bodies
        self.body_ids = frozenset(b for bodies in self.pool.values() for b in bodies)

    def start(self, specs: tuple[MoverSpec, ...]) -> None:
        """Begin an episode with ``specs`` (each takes a pool body of its shape; the rest park)."""
        free = {shape: list(bodies) for shape, bodies in self.pool.items()}
        self.active = []
        for spec in specs:
            bodies = free.get(spec.shape)
            if not bodies:
                raise ValueError(f"no pool body left for a {spec.kind} of shape {spec.shape}; pool {self.pool_summary()}")
            self.active.append(_Mover(spec, bodies.pop(0)))
        for bodies in free.values():
            for i, body in enumerate(bodies):
                self._park(body, i)
        for m in self.active:
            self._place(m, m.pose)

    def _new_body(self, kind: str, dims: tuple[float, ...]) -> int:
        """A parked pool body: a ``"box"`` of full size ``dims`` (l, w, h) or a ``"cylinder"`` of (radius, height)."""
        cid = self.cid
        if kind == "box":
            body = static_body(cid, "box", (dims[0] / 2, dims[1] / 2, dims[2] / 2), FORKLIFT_COLOUR, (0.0, 0.0, PARK_Z))
        else:
            body = static_body(cid, "cylinder", dims, WORKER_COLOUR, (0.0, 0.0, PARK_Z))
        p.setCollisionFilterGroupMask(body, -1, STATIC_GROUP, STATIC_MASK, physicsClientId=cid)
        return body

    def _park(self, body: int, slot: int) -> None:
        """Put an unused pool body away (under the floor, ``slot`` keeping parked bodies apart)."""
        p.resetBasePositionAndOrientation(body, [3.0 * slot, 0.0, PARK_Z], [0, 0, 0, 1], physicsClientId=self.cid)

    def pool_summary(self) -> dict[str, int]:
        return {f"{k}{list(d)}": len(v) for (k, d), v in self.pool.items()}

    def plan_step(self, dt: float, robots_xy: Sequence[tuple[float, float]], robot_radius: float, near: float,
                  visible: float = math.inf) -> list[tuple[_Mover, tuple[float, float, float], tuple[float, float, float]]]:
        """Advance every mover by one control period ``dt``, each yielding to the robot nearest
        its safety field (:func:`yield_target`; a single robot is the one-element list); return
        (mover, pose before, pose after) of those within ``near`` m of any robot (to be moved at
        every physics step) and place the others at their new pose now, except those farther
        than ``visible`` m from every robot, which no sensor can see (their body catches up as
        soon as they come within range)."""
        near_ones = []
        for m in self.active:
            before = m.pose
            m.step(dt, yield_target(m.spec, before, m.turn_to is not None, robots_xy), robot_radius)
            pose = m.pose
            gap = m.gap = min(math.hypot(pose[0] - x, pose[1] - y) for x, y in robots_xy) - m.radius
            if gap < near and pose != before and m.placed == before:
                near_ones.append((m, before, pose))
            elif gap <= visible:
                if m.placed != pose:
                    self._place(m, pose)
        return near_ones

    def _place(self, m: _Mover, pose: tuple[float, float, float]) -> None:
        m.placed = pose
        x, y, yaw = pose
        half = 0.5 * yaw
        p.resetBasePositionAndOrientation(m.body, [x, y, m.half_height], [0.0, 0.0, math.sin(half), math.cos(half)],
                                          physicsClientId=self.cid)

    def place_between(self, near_ones, f: float) -> None:
        """Put the near movers at fraction ``f`` of their way through this control period."""
        for m, (x0, y0, a0), after in near_ones:
            if f >= 1.0:
                self._place(m, after)
                continue
            x1, y1, a1 = after
            # modulo pi: a box and a cylinder look the same turned by a half-turn, and a
            # forklift reversing at its route's end flips its heading by exactly pi; turning
            # its body through the half-turn within one control period would sweep the
            # circle around it and shove whatever stands beside it
            da = math.remainder(a1 - a0, math.pi)
            self._place(m, (x0 + (x1 - x0) * f, y0 + (y1 - y0) * f, a0 + da * f))

    def views(self) -> tuple[MoverView, ...]:
        return tuple(m.view() for m in self.active)

    def nearest_gap(self, outline: list[tuple[float, float]], robot_xy: tuple[float, float], outline_radius: float,
                    exact_within: float = 1.0) -> float:
        """Smallest distance (m) between the robot's outline polygon (world frame, convex,
        counter-clockwise) and any mover; ``inf`` without movers. Exact under
        ``exact_within``; beyond, a lower bound (centre distance minus both bounding radii),
        which is all a far mover needs."""
        rx, ry = robot_xy
        best = math.inf
        for m in self.active:
            x, y, _ = m.pose
            rough = math.hypot(x - rx, y - ry) - m.radius - outline_radius
            if rough >= best:
                continue
            best = min(best, mover_gap(m.spec, m.pose, outline)) if rough < exact_within else rough
        return max(best, 0.0)


def yield_target(spec: MoverSpec, pose: tuple[float, float, float], turning: bool,
                 robots_xy: Sequence[tuple[float, float]]) -> tuple[float, float]:
    """The robot position a mover decides its yielding on: the robot nearest its safety field
    (a forklift's rectangle ahead, or the disc it sweeps while turning; a worker's body). If
    any robot is in the field, this one is; a single robot is always its own target."""
    if len(robots_xy) == 1:
        return robots_xy[0]
    x, y, yaw = pose
    if isinstance(spec, WorkerSpec) or turning:
        return min(robots_xy, key=lambda r: math.hypot(r[0] - x, r[1] - y))
    c, s = math.cos(yaw), math.sin(yaw)
    x0 = spec.size[0] / 2
    x1 = x0 + spec.field_length
    half_w = (spec.size[1] + spec.field_margin) / 2

    def field_gap(r: tuple[float, float]) -> float:
        dx, dy = r[0] - x, r[1] - y
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        return math.hypot(max(x0 - lx, 0.0, lx - x1), max(abs(ly) - half_w, 0.0))

    return min(robots_xy, key=field_gap)


def kinematic_poses(specs: Sequence[MoverSpec], robot_xy: Sequence[tuple[float, float]], dt: float,
                    robot_radius: float) -> list[list[tuple[float, float, float]]]:
    """Each mover's pose (x m, y m, yaw rad) at the start and after each control period ``dt``
    (s), the robot's centre at ``robot_xy[k]`` during period ``k``: the kinematics and yielding
    that :meth:`Movers.plan_step` gives a single robot's movers, without bodies or PyBullet.
    With an episode's specs (``scene.mover_specs`` after its reset) and the robot's recorded
    track, it re-creates where the movers were (the benchmark report draws them so)."""
    movers = [_Mover(spec, -1) for spec in specs]
    poses = [[m.pose] for m in movers]
    for xy in robot_xy:
        for m, track in zip(movers, poses):
            m.step(dt, xy, robot_radius)
            track.append(m.pose)
    return poses


def box_corners(center: tuple[float, float], yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    """Corners (counter-clockwise) of a ``length`` x ``width`` rectangle at ``center`` turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = length / 2, width / 2
    return [(center[0] + c * x - s * y, center[1] + s * x + c * y) for x, y in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]


def _point_segment(px: float, py: float, a: tuple[float, float], b: tuple[float, float]) -> float:
    ax, ay = a
    dx, dy = b[0] - ax, b[1] - ay
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0 else max(0.0, min(1.0, ((px - ax) * dx + (py - ay) * dy) / length2))
    return math.hypot(px - ax - t * dx, py - ay - t * dy)


def _inside(px: float, py: float, poly: list[tuple[float, float]]) -> bool:
    """Point in a convex counter-clockwise polygon (boundary included)."""
    n = len(poly)
    for i in range(n):
        (ax, ay), (bx, by) = poly[i], poly[(i + 1) % n]
        if (bx - ax) * (py - ay) - (by - ay) * (px - ax) < 0:
            return False
    return True


def mover_gap(spec: MoverSpec, pose: tuple[float, float, float], outline: list[tuple[float, float]]) -> float:
    """Distance (m) between a mover at ``pose`` and the robot's convex outline polygon
    (world frame, counter-clockwise); 0 when they overlap."""
    px, py, yaw = pose
    if isinstance(spec, WorkerSpec):
        if _inside(px, py, outline):
            return 0.0
        n = len(outline)
        d = min(_point_segment(px, py, outline[i], outline[(i + 1) % n]) for i in range(n))
        return max(0.0, d - spec.radius)
    # work in the forklift's frame, where it is the box |x| <= hx, |y| <= hy
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = spec.size[0] / 2, spec.size[1] / 2
    local = [(c * (x - px) + s * (y - py), -s * (x - px) + c * (y - py)) for x, y in outline]
    if _overlap_box(local, hx, hy):
        return 0.0
    best = min(math.hypot(max(abs(x) - hx, 0.0), max(abs(y) - hy, 0.0)) for x, y in local)
    n = len(local)
    for cx, cy in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy)):
        for i in range(n):
            best = min(best, _point_segment(cx, cy, local[i], local[(i + 1) % n]))
    return best


def _overlap_box(poly: list[tuple[float, float]], hx: float, hy: float) -> bool:
    """Separating-axis test of a convex polygon against the box |x| <= hx, |y| <= hy."""
    xs = [x for x, _ in poly]
    ys = [y for _, y in poly]
    if min(xs) > hx or max(xs) < -hx or min(ys) > hy or max(ys) < -hy:
        return False
    n = len(poly)
    for i in range(n):
        (ax, ay), (bx, by) = poly[i], poly[(i + 1) % n]
        nx, ny = by - ay, ax - bx  # outward normal of a counter-clockwise edge
        edge = nx * ax + ny * ay
        # the box's support point in the direction -normal
        if -abs(nx) * hx - abs(ny) * hy > edge:
            return False
    return True
