"""The kinematic profile (``physics="kinematic"``): a scene without a physics engine.

:class:`KinematicSimulation` answers what :class:`~bulletnav.envs.scene.Scene` asks of
:class:`~bulletnav.sim.simulation.Simulation` (reset, step, contacts, movers, events, the lidar's
world), so tasks, sensors, controllers and the shield never learn which one runs them.

- The robot (:class:`KinematicRobot`) never slips: its two rims move the body. Each wheel's
  velocity motor pushes its rim toward the commanded speed with at most ``max_wheel_torque``
  (times the shift's motor scale) / wheel radius of force, against the robot's mass and yaw
  inertia about the axle's midpoint, both read from the URDF (every link's mass, inertia and
  place, and the wheels' spin inertia): the straight-line and turning accelerations PyBullet's
  robot shows (2.53 m/s^2 and 23.5 rad/s^2 for the shipped robot, 3.33 m/s^2 and 25.7 rad/s^2 for
  the Jackal, measured there). The two motors share the body, so their forces are solved
  together each ``physics_hz`` substep, each clamped to its limit (as PyBullet's solver
  clamps them). Within a substep the velocities are constant and the pose follows their arc
  exactly.
- The world (:class:`KinematicWorld`) holds the layout's walls and obstacles, the movers' and
  events' bodies as plain boxes and cylinders (:class:`~bulletnav.sim.world.Primitive`), placed,
  moved and parked by the same :class:`~bulletnav.sim.movers.Movers` and
  :class:`~bulletnav.sim.events.Events` kinematics as in PyBullet.
- Contacts: the robot's collision rectangles (:mod:`bulletnav.geometry`) against every shape
  standing, tested at each substep where anything lies within the step's reach (one test a
  control step otherwise). A substep that would overlap a shape is not taken: the robot stops
  where it was, touching, and the contact is reported; it never passes through.
- The lidar casts in closed form against the shapes standing at each scan
  (:meth:`bulletnav.sensors.lidar.Lidar.use_shapes`); odometry and IMU read the integrated
  motion as they read PyBullet's.

Not served: the camera, the GUI, wheel slip, floor friction and tipping.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from bulletnav.config import PhysicsConfig, RobotConfig
from bulletnav.errors import ConfigError
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.sim import kinematic_kernels as kk
from bulletnav.sim.client import Clock
from bulletnav.sim.events import Events
from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import Movers
from bulletnav.sim.robot import RobotState
from bulletnav.sim.simulation import LidarMount
from bulletnav.sim.specs import Obstacle
from bulletnav.sim.world import Primitive, enclosure
from bulletnav.xmlfile import XmlRefused, parse_xml

log = logging.getLogger(__name__)

_SOLVER_ITERATIONS = 8
"""Gauss-Seidel sweeps over the two clamped wheel forces (two unknowns: converged well before)."""


# ---------------------------------------------------------------------------------------- the drive
@dataclass(frozen=True)
class DriveModel:
    """What the wheels push against, from the URDF (body frame: x forward, y left, m)."""

    base_mass: float
    """The base link's mass (kg): what ``ShiftConfig.mass_scale`` scales, as in PyBullet."""
    other_mass: float
    """Every other link's mass plus the wheels' spin inertia over their radius squared (kg)."""
    base_inertia: float
    """The base link's yaw inertia about the axle's midpoint (kg m^2)."""
    other_inertia: float
    """Every other link's yaw inertia about the axle's midpoint, the wheels' spin included (kg m^2)."""
    rest_height: float
    """Height of the body origin above the floor at rest (m)."""


def _xyz(element, attribute: str = "xyz") -> tuple[float, float, float]:
    if element is None or element.get(attribute) is None:
        return 0.0, 0.0, 0.0
    x, y, z = (float(v) for v in element.get(attribute).split())
    return x, y, z


@lru_cache(maxsize=8)
def _drive_model(path: str) -> DriveModel:
    try:
        root = parse_xml(Path(path).read_bytes())
    except (OSError, XmlRefused) as exc:
        raise ConfigError(f"{path}: cannot read the robot URDF ({exc})") from None
    # where each link's frame sits in the base frame (joint origins summed along the tree; the
    # kinematic profile takes every joint as unrotated, which the shipped robots are)
    parent: dict[str, tuple[str, tuple[float, float, float]]] = {}
    axes: dict[str, tuple[float, float, float]] = {}
    for joint in root.findall("joint"):
        child, par = joint.find("child"), joint.find("parent")
        if child is None or par is None:
            continue
        parent[child.get("link", "")] = (par.get("link", ""), _xyz(joint.find("origin")))
        axes[child.get("link", "")] = _xyz(joint.find("axis")) if joint.find("axis") is not None else (1.0, 0.0, 0.0)

    def place(link: str) -> tuple[float, float, float]:
        x = y = z = 0.0
        seen = 0
        while link in parent and seen < 64:
            link, (dx, dy, dz) = parent[link]
            x, y, z, seen = x + dx, y + dy, z + dz, seen + 1
        return x, y, z

    joints = {j.get("name"): j for j in root.findall("joint")}
    try:
        wheels = [joints[n].find("child").get("link") for n in ("left_wheel_joint", "right_wheel_joint")]  # type: ignore[union-attr]
    except (KeyError, AttributeError):
        raise ConfigError(f"{path}: robot URDF lacks its wheel joints") from None
    lw, rw = place(wheels[0]), place(wheels[1])
    ax, ay = (lw[0] + rw[0]) / 2, (lw[1] + rw[1]) / 2
    if abs(ax) > 1e-6 or abs(ay) > 1e-6:
        raise ConfigError(f"{path}: physics='kinematic' needs the wheel axle's midpoint under the body centre, "
                          f"it is at ({ax:g}, {ay:g}) m: use physics='default'")
    geometry_half = abs(lw[1] - rw[1]) / 2
    base_mass = other_mass = base_inertia = other_inertia = 0.0
    wheel_radius = 0.0
    for link in root.findall("link"):
        name = link.get("name", "")
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass_el, inertia_el = inertial.find("mass"), inertial.find("inertia")
        mass = float(mass_el.get("value", "0")) if mass_el is not None else 0.0
        ox, oy, _ = _xyz(inertial.find("origin"))
        px, py, _ = place(name)
        izz = float(inertia_el.get("izz", "0")) if inertia_el is not None else 0.0
        yaw_inertia = izz + mass * ((px + ox - ax) ** 2 + (py + oy - ay) ** 2)
        if name == "base_link":
            base_mass, base_inertia = mass, yaw_inertia
            continue
        other_mass += mass
        other_inertia += yaw_inertia
        if name in wheels:
            shape = link.find("collision/geometry/*")
            radius = float(shape.get("radius", "0")) if shape is not None else 0.0
            if radius <= 0:
                raise ConfigError(f"{path}: wheel {name} has no collision radius")
            wheel_radius = radius
            axis = axes.get(name, (0.0, 1.0, 0.0))
            spin = float(inertia_el.get("iyy" if abs(axis[1]) >= abs(axis[0]) else "ixx", "0")) if inertia_el is not None else 0.0
            # the wheel's spin, turned by the rim: an extra mass spin/r^2 at the rim
            other_mass += spin / radius ** 2
            other_inertia += spin / radius ** 2 * geometry_half ** 2
    rest = wheel_radius - lw[2]
    return DriveModel(base_mass, other_mass, base_inertia, other_inertia, rest)


def drive_model(config: RobotConfig) -> DriveModel:
    """The :class:`DriveModel` of ``config``'s URDF (parsed once per file).

    Raises:
        ConfigError: the URDF is unreadable, or its axle's midpoint is not under the body centre.
    """
    return _drive_model(str(Path(config.urdf_path()).resolve()))


# ---------------------------------------------------------------------------------------- the world
def obstacle_primitive(o: Obstacle) -> Primitive:
    """An obstacle standing on the floor as the shape PyBullet's world gives it."""
    if o.kind == "box":
        return Primitive("box", (o.center[0], o.center[1], o.size[2] / 2), (o.size[0] / 2, o.size[1] / 2, o.size[2] / 2), o.yaw)
    return Primitive("cylinder", (o.center[0], o.center[1], o.height / 2), (o.radius, o.radius, o.height / 2))


class _Shapes:
    """A set of boxes and cylinders (with body ids) as the arrays the compiled drive
    (:func:`bulletnav.sim.kinematic_kernels.drive`) tests contacts against; it marks the shapes
    touched in :attr:`box_hit` and :attr:`cyl_hit`."""

    def __init__(self, items: list[tuple[int, Primitive]]) -> None:
        boxes = [(b, s) for b, s in items if s.kind == "box"]
        cyls = [(b, s) for b, s in items if s.kind == "cylinder"]
        self.box_ids = [b for b, _ in boxes]
        self.box = np.array([(s.center[0], s.center[1], math.cos(s.yaw), math.sin(s.yaw), s.half[0], s.half[1])
                             for _, s in boxes], dtype=np.float64).reshape(-1, 6)
        self.box_reach = np.hypot(self.box[:, 4], self.box[:, 5])
        self.cyl_ids = [b for b, _ in cyls]
        self.cyl = np.array([(s.center[0], s.center[1], s.half[0]) for _, s in cyls], dtype=np.float64).reshape(-1, 3)
        self.empty = not items
        self.box_hit = np.zeros(len(self.box_ids), dtype=np.bool_)
        self.cyl_hit = np.zeros(len(self.cyl_ids), dtype=np.bool_)

    def clear(self) -> None:
        """Unmark every shape (:attr:`box_hit`, :attr:`cyl_hit`)."""
        self.box_hit[:] = False
        self.cyl_hit[:] = False

    def touched(self) -> list[int]:
        """Ids of the shapes marked in :attr:`box_hit` and :attr:`cyl_hit`."""
        return ([self.box_ids[i] for i in np.flatnonzero(self.box_hit)]
                + [self.cyl_ids[i] for i in np.flatnonzero(self.cyl_hit)])


class KinematicWorld:
    """The layout's walls and obstacles, and the movers' and events' bodies, as shapes.

    Body ids are handed out here (the floor is 0) and keep the roles PyBullet's have: the
    world's :attr:`static_set`, the movers' and events' pools, :attr:`labels`.
    """

    def __init__(self, physics: PhysicsConfig) -> None:
        self.cid = -1
        self.physics = physics
        self.layout: Layout | None = None
        self.floor_id = -1
        self.wall_ids: list[int] = []
        self.obstacle_ids: list[int] = []
        self.static_set: frozenset[int] = frozenset()
        self.labels: dict[int, str] = {}
        self.primitives: list[Primitive] = []
        """The floor, walls and obstacles as built (as :attr:`bulletnav.sim.world.World.primitives`)."""
        self._shape: dict[int, Primitive] = {}  # every body's shape at its last place
        self._standing: set[int] = set()  # bodies in the world now (not parked)
        self._next = 0
        self.versions = [0, 0]
        """Counters of the static and the moving shapes, bumped at each change."""
        self._sets: list[_Shapes | None] = [None, None]

    def set_floor_friction(self, mu: float) -> None:
        """Nothing slips here: floor friction has no effect in the kinematic profile."""

    def new_id(self) -> int:
        body, self._next = self._next, self._next + 1
        return body

    def build(self, layout: Layout) -> None:
        """Forget every body and stand the floor, walls and obstacles of ``layout``."""
        self.layout = layout
        self._shape, self._standing, self._next = {}, set(), 0
        self.labels = {}
        self.floor_id = self.new_id()
        self.labels[self.floor_id] = "floor"
        self.primitives = [Primitive("plane", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))]
        self.wall_ids = []
        for (cx, cy), half in enclosure(layout):
            self.wall_ids.append(self._stand(Primitive("box", (cx, cy, half[2]), half, 0.0), "wall"))
        self.obstacle_ids = [self._stand(obstacle_primitive(o), o.label or ("column" if o.kind == "cylinder" else "box"))
                             for o in layout.obstacles]
        self.static_set = frozenset((*self.wall_ids, *self.obstacle_ids))
        self.versions = [self.versions[0] + 1, self.versions[1] + 1]
        self._sets = [None, None]

    def _stand(self, shape: Primitive, label: str) -> int:
        body = self.new_id()
        self.labels[body] = label
        self._shape[body] = shape
        self._standing.add(body)
        self.primitives.append(shape)
        return body

    # ------------------------------------------------------------------ bodies that come and go
    def add_body(self, shape: Primitive) -> int:
        """A new body of ``shape`` (its size; placed by :meth:`place`), parked."""
        body = self.new_id()
        self._shape[body] = shape
        return body

    def place(self, body: int, x: float, y: float, yaw: float) -> None:
        """Stand ``body`` with its footprint centre at (x, y) m, turned by ``yaw`` rad."""
        s = self._shape[body]
        self._shape[body] = Primitive(s.kind, (x, y, s.center[2]), s.half, yaw)
        self._standing.add(body)
        self._changed(body)

    def park(self, body: int) -> None:
        """Take ``body`` out of the world (rays and the robot pass where it stood)."""
        if body in self._standing:
            self._standing.discard(body)
            self._changed(body)

    def _changed(self, body: int) -> None:
        k = 0 if body in self.static_set else 1
        self.versions[k] += 1
        self._sets[k] = None

    # ------------------------------------------------------------------ queries
    def standing(self, static: bool) -> list[tuple[int, Primitive]]:
        """(body, shape) of the world's own walls and obstacles (``static``) or of the movers
        and events' bodies standing now."""
        return [(b, self._shape[b]) for b in sorted(self._standing) if (b in self.static_set) == static]

    def shapes(self, static: bool) -> _Shapes:
        k = 0 if static else 1
        shapes = self._sets[k]
        if shapes is None:
            shapes = self._sets[k] = _Shapes(self.standing(static))
        return shapes


# ---------------------------------------------------------------------------------------- movers and events
class KinematicMovers(Movers):
    """:class:`~bulletnav.sim.movers.Movers` whose bodies are shapes of a :class:`KinematicWorld`."""

    def __init__(self, world: KinematicWorld) -> None:
        super().__init__(-1)
        self.world = world

    def _new_body(self, kind: str, dims: tuple[float, ...]) -> int:
        if kind == "box":
            shape = Primitive("box", (0.0, 0.0, dims[2] / 2), (dims[0] / 2, dims[1] / 2, dims[2] / 2))
        else:
            shape = Primitive("cylinder", (0.0, 0.0, dims[1] / 2), (dims[0], dims[0], dims[1] / 2))
        return self.world.add_body(shape)

    def _park(self, body: int, slot: int) -> None:
        self.world.park(body)

    def _place(self, m, pose: tuple[float, float, float]) -> None:
        m.placed = pose
        self.world.place(m.body, pose[0], pose[1], pose[2])


class KinematicEvents(Events):
    """:class:`~bulletnav.sim.events.Events` whose bodies are shapes of a :class:`KinematicWorld`."""

    def __init__(self, world: KinematicWorld) -> None:
        super().__init__(-1)
        self.world = world

    def _body(self, o: Obstacle, labels: dict[int, str]) -> int:
        body = self.world.add_body(obstacle_primitive(o))
        labels[body] = o.label or "event"
        self.created += 1
        return body

    def _put(self, body: int, o: Obstacle) -> None:
        self.world.place(body, o.center[0], o.center[1], o.yaw)

    def _park(self, body: int, x: float = 0.0) -> None:
        self.world.park(body)


# ---------------------------------------------------------------------------------------- the robot
class KinematicRobot:
    """A differential-drive robot that moves as its rims say, with the
    :class:`~bulletnav.sim.robot.Robot` attributes that sensors and the scene read."""

    def __init__(self, config: RobotConfig, physics: PhysicsConfig) -> None:
        self.cid = -1
        self.config = config
        self.body = -1
        self.lidar_link = self.camera_link = self.caster_link = -1
        self.geometry: RobotGeometry = robot_geometry(config)
        self.drive = drive_model(config)
        self.wheel_radius = self.geometry.wheel_radius
        self.wheelbase = self.geometry.wheelbase
        self._dt = physics.physics_dt
        self._mass_scale = 1.0
        self._force = config.max_wheel_torque / self.wheel_radius
        self._set_mass(1.0)
        self.state: RobotState | None = None
        self.pose3 = (0.0, 0.0, 0.0)
        """Ground-truth (x, y, yaw) now (m, m, rad)."""
        self.rims = (0.0, 0.0)
        """Rim speeds (left, right) now (m/s)."""
        self._angles = (0.0, 0.0)
        self._target = (0.0, 0.0)
        self.contacts: set[int] = set()
        """Bodies touched during the last control step."""
        self._rects = np.array([(r.cx, r.cy, r.half_x, r.half_y) for r in self.geometry.rectangles], dtype=np.float64)
        self._state = np.zeros(7)  # the drive kernel's rims, pose and wheel angles
        self.reach = max(math.hypot(abs(r.cx) + r.half_x, abs(r.cy) + r.half_y) for r in self.geometry.rectangles)
        """Farthest point of the collision rectangles from the body centre (m)."""

    def _set_mass(self, mass_scale: float) -> None:
        d = self.drive
        mass = d.base_mass * mass_scale + d.other_mass
        inertia = d.base_inertia * mass_scale + d.other_inertia
        half = self.wheelbase / 2
        k = half * half / inertia
        # rim accelerations per unit force: own wheel (a), other wheel (b)
        self._a, self._b = 1.0 / mass + k, 1.0 / mass - k
        self._mass, self._inertia = mass, inertia

    # ------------------------------------------------------------------ set-up
    def load(self, pose: tuple[float, float, float], body: int) -> None:
        """Stand the robot at ``pose`` as body ``body`` of its world."""
        self.body = body
        self._force = self.config.max_wheel_torque / self.wheel_radius
        self._set_mass(1.0)
        self.reset_pose(pose)

    def apply_shift(self, mass_scale: float = 1.0, wheel_friction_scale: float = 1.0,
                    motor_force_scale: float = 1.0) -> None:
        """The base's mass and inertia and the motors' torque scaled (no wheel slips: friction has no effect)."""
        self._set_mass(mass_scale)
        self._force = self.config.max_wheel_torque * motor_force_scale / self.wheel_radius

    def reset_pose(self, pose: tuple[float, float, float]) -> None:
        """Teleport to ``pose`` at rest, wheels zeroed."""
        self.pose3 = (float(pose[0]), float(pose[1]), float(pose[2]))
        self.rims = self._target = (0.0, 0.0)
        self._angles = (0.0, 0.0)
        self.contacts = set()
        self.sample()

    # ------------------------------------------------------------------ commands
    def set_velocity(self, v: float, w: float) -> None:
        """Command forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s): the rims' targets."""
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"set_velocity needs finite values, got v={v}, w={w}")
        half = self.wheelbase / 2
        self._target = (v - w * half, v + w * half)

    def stop(self) -> None:
        self.set_velocity(0.0, 0.0)

    @property
    def braked(self) -> bool:
        """Whether the robot stands still on a zero command (nothing creeps here)."""
        return self._target == (0.0, 0.0) and self.rims == (0.0, 0.0)

    def substeps(self, n: int, static: _Shapes, moving: _Shapes, sweep: float, moving_always: bool) -> bool:
        """Take ``n`` substeps toward the rims' targets (:func:`bulletnav.sim.kinematic_kernels.drive`:
        the two motor forces that reach the targets, each clamped to the motor's limit, solved
        together by projected Gauss-Seidel; then the exact arc). ``static`` and ``moving`` are
        checked when one of them lies within ``sweep`` (m) of the outline now (``moving``
        always with ``moving_always``); a substep whose outline would overlap one is not taken:
        the rims stop where the body stands. True when a shape was touched (marked in its
        ``*_hit`` array, which the caller clears)."""
        s = self._state
        s[0], s[1] = self.rims
        s[2], s[3], s[4] = self.pose3
        s[5], s[6] = self._angles
        touched = kk.drive(n, s, self._target[0], self._target[1], self._a, self._b, self._dt, self._force,
                           _SOLVER_ITERATIONS, self.wheelbase, self.wheel_radius, self._rects, self.reach, sweep,
                           static.box, static.box_reach, static.cyl, static.box_hit, static.cyl_hit, moving_always,
                           moving.box, moving.box_reach, moving.cyl, moving.box_hit, moving.cyl_hit)
        self.rims = (float(s[0]), float(s[1]))
        self.pose3 = (float(s[2]), float(s[3]), float(s[4]))
        self._angles = (float(s[5]), float(s[6]))
        return touched

    # ------------------------------------------------------------------ state
    def sample(self) -> RobotState:
        """The ground truth now, kept as :attr:`state` (as :meth:`bulletnav.sim.robot.Robot.sample`)."""
        x, y, yaw = self.pose3
        left, right = self.rims
        v, w = (left + right) / 2, (right - left) / self.wheelbase
        c, s = math.cos(yaw), math.sin(yaw)
        r = self.wheel_radius
        self.state = RobotState(x, y, yaw, (v * c, v * s, 0.0), (0.0, 0.0, w), (c, -s, 0.0, s, c, 0.0, 0.0, 0.0, 1.0),
                                self._angles, (left / r, right / r))
        return self.state

    def planar_pose(self) -> tuple[float, float, float]:
        return self.pose3

    def pose(self) -> np.ndarray:
        return np.array(self.pose3)

    def velocity(self) -> np.ndarray:
        left, right = self.rims
        return np.array([(left + right) / 2, (right - left) / self.wheelbase])

    def lidar_pose(self) -> tuple[float, float, float, float]:
        """The lidar's origin (x, y, z m) and heading (rad) now."""
        x, y, yaw = self.pose3
        mx, my, mz = self.geometry.lidar_mount
        c, s = math.cos(yaw), math.sin(yaw)
        return x + c * mx - s * my, y + s * mx + c * my, self.drive.rest_height + mz, yaw

    def touching(self, bodies) -> bool:
        """True when the robot touched one of ``bodies`` in the last control step."""
        return any(b in bodies for b in self.contacts)

    def contact_kind(self, static, moving) -> str | None:
        """``"dynamic"`` for a touched mover, else ``"static"`` for a touched wall or obstacle, else None."""
        kind = None
        for b in self.contacts:
            if b in moving:
                return "dynamic"
            if b in static:
                kind = "static"
        return kind


# ---------------------------------------------------------------------------------------- the simulation
class KinematicSimulation:
    """The scene's simulation in the kinematic profile: :class:`~bulletnav.sim.simulation.Simulation`'s
    interface over a :class:`KinematicWorld` and a :class:`KinematicRobot`.

    Args:
        physics: the integration rate (``physics_hz``) and control rate.
        robot: the robot (URDF, motor torque).
    """

    backend = "kinematic"
    gui = False

    def __init__(self, physics: PhysicsConfig, robot: RobotConfig = RobotConfig()) -> None:
        self.physics = physics
        self.cid = -1
        self.clock = Clock(physics.physics_dt, physics.substeps)
        self.world = KinematicWorld(physics)
        self.robot = KinematicRobot(robot, physics)
        self.rebuilds = 0

    def make_movers(self) -> KinematicMovers:
        return KinematicMovers(self.world)

    def make_events(self) -> KinematicEvents:
        return KinematicEvents(self.world)

    def attach_lidar(self, lidar: LidarMount) -> None:
        lidar.use_shapes(self)

    # ------------------------------------------------------------------ what the lidar casts against
    @property
    def shape_versions(self) -> tuple[int, int]:
        return self.world.versions[0], self.world.versions[1]

    def static_primitives(self) -> list[Primitive]:
        return [s for _, s in self.world.standing(True)]

    def moving_primitives(self) -> list[Primitive]:
        return [s for _, s in self.world.standing(False)]

    def lidar_pose(self) -> tuple[float, float, float, float]:
        return self.robot.lidar_pose()

    # ------------------------------------------------------------------ episodes
    def reset(self, layout: Layout, start: tuple[float, float, float], rebuild: bool = False) -> None:
        """As :meth:`bulletnav.sim.simulation.Simulation.reset`."""
        if rebuild or self.world.layout != layout:
            self.world.build(layout)
            self.robot.load(start, self.world.new_id())
            self.world.labels[self.robot.body] = "robot"
            self.rebuilds += 1
        else:
            self.robot.reset_pose(start)
        self.clock.tick = 0
        self.clock.episode += 1

    def step(self, v: float, w: float, before_substep: Callable[[int, int], None] | None = None) -> None:
        """Command (v m/s, w rad/s) and advance one control period in ``substeps`` integration
        steps; ``before_substep(k, n)`` moves the movers near the robot before step ``k`` of ``n``."""
        robot, world = self.robot, self.world
        robot.set_velocity(v, w)
        robot.contacts = set()
        n, dt = self.physics.substeps, self.physics.physics_dt
        # how far any point of the outline can move in this control period: nothing farther matters
        left, right = robot.rims
        tl, tr = robot._target
        rim = max(abs(left), abs(right), abs(tl), abs(tr))
        sweep = (rim + 2.0 * rim / self.robot.wheelbase * robot.reach) * n * dt + 1e-3
        static = world.shapes(True)
        if before_substep is None:
            moving = world.shapes(False)
            touched = []
            if robot.substeps(n, static, moving, sweep, False):
                touched = static.touched() + moving.touched()
                static.clear()
                moving.clear()
        else:  # the movers move between substeps: one at a time, against the moving shapes as they stand then
            touched = []
            for k in range(n):
                before_substep(k, n)
                moving = world.shapes(False)
                if robot.substeps(1, static, moving, sweep, True):
                    touched += moving.touched()
                    moving.clear()
            touched += static.touched()
            static.clear()
        robot.contacts = set(touched)
        self.clock.tick += n
        robot.sample()

    def in_collision(self) -> bool:
        """True when the robot touched a wall or an obstacle in the last control step."""
        return self.robot.touching(self.world.static_set)

    def close(self) -> None:
        """Nothing to release."""
