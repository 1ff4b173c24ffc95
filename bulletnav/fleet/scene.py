"""The fleet's scene: one PyBullet client holding the world, N robots with their own sensors,
and the movers and events of a dynamic warehouse.

:class:`FleetScene` composes the single-robot parts (:class:`~bulletnav.sim.world.World`,
:class:`~bulletnav.sim.robot.Robot`, :class:`~bulletnav.sensors.suite.SensorSuite`,
:class:`~bulletnav.sim.movers.Movers`, :class:`~bulletnav.sim.events.Events`) for several robots;
:class:`RobotSlot` shows one robot of it with the interface a single-robot task reads, so the
navigation task's observation and reward run unchanged on every robot.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pybullet as p

from bulletnav.config import EnvConfig
from bulletnav.fleet.lidar import FIRST_ROBOT_BIT, FleetLidar, robot_group
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.sensors.camera import Camera
from bulletnav.sensors.imu import Imu
from bulletnav.sensors.odometry import Odometry
from bulletnav.sensors.suite import SensorSuite
from bulletnav.sim.client import Clock, connect
from bulletnav.sim.dynamic import RESOLUTION as CLEARANCE_RESOLUTION
from bulletnav.sim.dynamic import ClearanceMap, draw_movers
from bulletnav.sim.events import Events
from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import ForkliftSpec, Movers, WorkerSpec
from bulletnav.sim.robot import Robot
from bulletnav.sim.sampler import FreeSpace
from bulletnav.sim.world import World

KINDS = ("static", "mover", "person", "robot")
"""What a robot can collide with: walls and obstacles (pallet events included), forklifts,
walking workers, other robots."""
_ALL_BITS = 0x7FFFFFFF  # every collision-filter group (robots collide with each other and with everything else)


class FleetMovers(Movers):
    """:class:`~bulletnav.sim.movers.Movers` that yield to whichever robot stands in a mover's
    safety field (the single-robot pool, kinematics and placement otherwise)."""

    def plan_step_fleet(self, dt: float, robots_xy: list[tuple[float, float]], robot_radius: float, near: float,
                        visible: float = math.inf) -> list:
        """As :meth:`Movers.plan_step` with several robots: each mover yields to the robot
        nearest its field, and is moved at every physics step while it is within ``near`` m of
        any robot (and placed only while within ``visible`` m of one)."""
        near_ones = []
        for m in self.active:
            before = m.pose
            m.step(dt, yield_target(m.spec, m.pose, m.turn_to is not None, robots_xy), robot_radius)
            pose = m.pose
            gap = m.gap = min(math.hypot(pose[0] - x, pose[1] - y) for x, y in robots_xy) - m.radius
            if gap < near and pose != before and m.placed == before:
                near_ones.append((m, before, pose))
            elif gap <= visible:
                if m.placed != pose:
                    self._place(m, pose)
        return near_ones


def yield_target(spec: Any, pose: tuple[float, float, float], turning: bool,
                 robots_xy: list[tuple[float, float]]) -> tuple[float, float]:
    """The robot position a mover decides its yielding on: the robot nearest its safety field
    (a forklift's rectangle ahead, or the disc it sweeps while turning; a worker's body). If
    any robot is in the field, this one is."""
    x, y, yaw = pose
    if isinstance(spec, WorkerSpec) or turning:
        return min(robots_xy, key=lambda r: math.hypot(r[0] - x, r[1] - y))
    assert isinstance(spec, ForkliftSpec)
    c, s = math.cos(yaw), math.sin(yaw)
    x0 = spec.size[0] / 2
    x1 = x0 + spec.field_length
    half_w = (spec.size[1] + spec.field_margin) / 2

    def field_gap(r: tuple[float, float]) -> float:
        dx, dy = r[0] - x, r[1] - y
        lx, ly = c * dx + s * dy, -s * dx + c * dy
        return math.hypot(max(x0 - lx, 0.0, lx - x1), max(abs(ly) - half_w, 0.0))

    return min(robots_xy, key=field_gap)


class FleetScene:
    """Client, world, robots, sensors, movers and events of one fleet env.

    Args:
        config: the per-robot configuration (the single-robot env's).
        num_robots: how many robots.
        gui: open the PyBullet GUI (needs an X display).
    """

    def __init__(self, config: EnvConfig, num_robots: int, gui: bool = False) -> None:
        self.config = config
        self.geometry: RobotGeometry = robot_geometry(config.robot)
        physics = config.physics
        self.cid = connect(gui=gui)
        self.gui = gui
        self.clock = Clock(physics.physics_dt, physics.substeps)
        self.world = World(self.cid, physics)
        self.robots = [Robot(self.cid, config.robot) for _ in range(num_robots)]
        bits = [1 << (FIRST_ROBOT_BIT + i) for i in range(num_robots)]
        drop = self.geometry.lidar_mount[2]
        sensors = config.sensors
        self.sensors: list[SensorSuite] = []
        for i, robot in enumerate(self.robots):
            others = sum(b for j, b in enumerate(bits) if j != i)
            self.sensors.append(SensorSuite(
                lidar=FleetLidar(robot, self.clock, sensors.lidar, others, drop, self.robots)
                if sensors.lidar.enabled else None,
                camera=Camera(robot, self.clock, sensors.camera) if sensors.camera.enabled else None,
                imu=Imu(robot, self.clock, sensors.imu, gravity=physics.gravity) if sensors.imu.enabled else None,
                odometry=Odometry(robot, self.clock, sensors.odometry) if sensors.odometry.enabled else None,
            ))
        self.slots = [RobotSlot(self, i) for i in range(num_robots)]
        self.movers = FleetMovers(self.cid)
        self.events = Events(self.cid)
        self.layout: Layout | None = None
        self.dynamic = False
        """True when this episode has movers or events."""
        self.goals: tuple[tuple[float, float], ...] = ()
        """The robots' current goals, kept clear by the events."""
        self.rebuilds = 0
        self._rebuild = False
        self._free: FreeSpace | None = None
        self._grids: dict[tuple[float, float], OccupancyGrid] = {}
        self._cmap: ClearanceMap | None = None
        self._built_at = -1
        self._robot_index: dict[int, int] = {}
        self._kind_of: dict[int, str] = {}
        lidar = sensors.lidar
        self._visible = math.inf if sensors.camera.enabled or not lidar.enabled else lidar.max_range + 0.5
        corners = [(sx * r.half_x + r.cx, sy * r.half_y + r.cy) for r in self.geometry.rectangles
                   for sx in (-1, 1) for sy in (-1, 1)]
        self._outline = convex_hull(corners)

    # ------------------------------------------------------------------ episodes
    def use_layout(self, layout: Layout, rebuild: bool = False) -> None:
        """Make ``layout`` the world of the next :meth:`place` (``rebuild``: a fresh physics scene)."""
        if layout is not self.layout:
            self._free = None
            self._grids = {}
            self._cmap = None
        self.layout = layout
        self._rebuild = rebuild

    @property
    def free_space(self) -> FreeSpace:
        """Free-space grids of the layout for one robot's disc (built once per layout)."""
        if self.layout is None:
            raise RuntimeError("the fleet has no layout yet: reset the env first")
        if self._free is None:
            self._free = FreeSpace.build(self.layout, self.config.sampler, self.geometry.radius)
        return self._free

    def occupancy(self, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
        """The layout rasterised at ``resolution`` (m), obstacles grown by ``inflate`` (m); cached."""
        key = (float(resolution), float(inflate))
        grid = self._grids.get(key)
        if grid is None:
            occ = self.layout.occupancy(resolution, inflate=inflate)
            xs, ys = self.layout.grid_axes(resolution)
            occ.flags.writeable = False
            grid = self._grids[key] = OccupancyGrid(occ, resolution, (float(xs[0]), float(ys[0])))
        return grid

    def place(self, starts: list[tuple[float, float, float]], rng: np.random.Generator,
              goals: tuple[tuple[float, float], ...]) -> None:
        """Start an episode: build the world if needed, put robot ``i`` at rest at ``starts[i]``,
        hand each robot's sensors their noise generators from ``rng`` (robot by robot), then
        draw the movers (none starting near a start or one of ``goals``) and the events."""
        layout = self.layout
        if layout is None:
            raise RuntimeError("use_layout() before place()")
        if self._rebuild or self.world.layout != layout:
            if self.gui:
                p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 0, physicsClientId=self.cid)
            self.world.build(layout)
            for i, (robot, start) in enumerate(zip(self.robots, starts)):
                robot.load(start)
                group = robot_group(i)
                for link in (-1, *range(p.getNumJoints(robot.body, physicsClientId=self.cid))):
                    if link not in (robot.left_joint, robot.right_joint):  # wheel spheres keep their floor-only filter
                        p.setCollisionFilterGroupMask(robot.body, link, group, _ALL_BITS,
                                                      physicsClientId=self.cid)
                self.world.labels[robot.body] = "robot"
            if self.gui:
                p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 1, physicsClientId=self.cid)
            self.rebuilds += 1
        else:
            for robot, start in zip(self.robots, starts):
                robot.reset_pose(start)
        self._rebuild = False
        self.clock.tick = 0
        self.clock.episode += 1
        for suite in self.sensors:
            suite.reset(rng)
        self.goals = tuple(goals)
        dyn = self.config.dynamic
        self.dynamic = dyn.active or bool(layout.dynamic) or bool(layout.events)
        if self.dynamic:
            if self._built_at != self.rebuilds:
                self._build_pools(layout)
            specs = layout.dynamic
            if dyn.forklifts[1] > 0 or dyn.workers[1] > 0:
                if self._cmap is None:
                    self._cmap = ClearanceMap(layout, occupied=self.occupancy(CLEARANCE_RESOLUTION).occupied)
                avoid = (*((s[0], s[1]) for s in starts), *goals)
                specs = specs + draw_movers(layout, rng, dyn, self.geometry.radius, avoid, self._cmap)
            self.movers.start(specs)
            inflated = self.occupancy(self.events.resolution, self.geometry.radius).occupied
            self.events.start(rng if dyn.pallet_events_per_min > 0 else None, dyn.pallet_events_per_min, inflated)
        self._robot_index = {robot.body: i for i, robot in enumerate(self.robots)}
        labels = self.world.labels
        static = self.world.static_set | self.events.body_ids
        self._kind_of = {b: "static" for b in static}
        self._kind_of.update({b: "person" if labels.get(b) == "worker" else "mover" for b in self.movers.body_ids})
        self._kind_of.update({b: "robot" for b in self._robot_index})
        self.step_events: list[dict] = []

    def _build_pools(self, layout: Layout) -> None:
        dyn = self.config.dynamic
        shapes: dict[tuple[str, tuple[float, ...]], int] = {}
        for spec in layout.dynamic:
            shapes[spec.shape] = shapes.get(spec.shape, 0) + 1
        if dyn.forklifts[1]:
            key = ("box", tuple(dyn.forklift_size))
            shapes[key] = shapes.get(key, 0) + dyn.forklifts[1]
        if dyn.workers[1]:
            key = ("cylinder", (dyn.worker_radius, 1.7))
            shapes[key] = shapes.get(key, 0) + dyn.workers[1]
        labels = self.world.labels
        self.movers.build(shapes, labels)
        self.events.build(layout, self.world.obstacle_ids,
                          dyn.event_pallets if dyn.pallet_events_per_min > 0 else 0, labels)
        self._built_at = self.rebuilds

    # ------------------------------------------------------------------ steps
    def step(self, commands: list[tuple[float, float]]) -> None:
        """Command robot ``i`` with ``commands[i]`` = (v m/s, w rad/s), advance one control
        period (movers near a robot move at every physics step), update the sensors."""
        for robot, (v, w) in zip(self.robots, commands):
            robot.set_velocity(v, w)
        cid, n = self.cid, self.config.physics.substeps
        near = []
        if self.dynamic:
            xy = [(r.state.x, r.state.y) for r in self.robots]
            near = self.movers.plan_step_fleet(self.config.physics.control_dt, xy, self.geometry.radius,
                                               self.config.dynamic.near, self._visible)
        for k in range(n):
            if near:
                self.movers.place_between(near, (k + 1) / n)
            p.stepSimulation(physicsClientId=cid)
        self.clock.tick += n
        for robot in self.robots:
            robot.sample()
        if self.dynamic:
            xy = [(r.state.x, r.state.y) for r in self.robots]
            # the events keep clear of, and connected to, every robot and every current goal
            self.step_events = self.events.step(self.clock.time, self.config.physics.control_dt, xy[0],
                                                (*xy[1:], *self.goals), self.geometry.radius, self.movers.active)
        for suite in self.sensors:
            suite.update()

    def contacts(self, index: int) -> dict[int, str]:
        """Body id -> kind (:data:`KINDS`) of everything robot ``index`` touches now (not the floor)."""
        kind_of = self._kind_of
        out = {}
        for c in p.getContactPoints(bodyA=self.robots[index].body, physicsClientId=self.cid):
            kind = kind_of.get(c[2])
            if kind is not None:
                out[c[2]] = kind
        return out

    def outline(self, index: int) -> list[tuple[float, float]]:
        """Robot ``index``'s outline (convex hull of its collision boxes), world frame."""
        state = self.robots[index].state
        c, s = math.cos(state.yaw), math.sin(state.yaw)
        return [(state.x + c * x - s * y, state.y + s * x + c * y) for x, y in self._outline]

    def nearest_mover(self, index: int) -> float:
        """Distance (m) between robot ``index``'s outline and the nearest mover; inf without movers."""
        if not self.dynamic or not self.movers.active:
            return math.inf
        state = self.robots[index].state
        return self.movers.nearest_gap(self.outline(index), (state.x, state.y), self.geometry.outline_radius)

    def close(self) -> None:
        if self.cid >= 0:
            try:
                p.disconnect(physicsClientId=self.cid)
            except p.error:
                pass
            self.cid = -1


class RobotSlot:
    """One robot of a :class:`FleetScene` as a single-robot task sees its scene: ``robot``,
    ``sensors``, ``geometry``, ``layout``, ``free_space``, ``in_collision()``,
    ``nearest_mover()``. Placing is the fleet's job, so :meth:`place_robot` does nothing."""

    def __init__(self, fleet: FleetScene, index: int) -> None:
        self.fleet = fleet
        self.index = index
        self.robot = fleet.robots[index]
        self.sensors = fleet.sensors[index]
        self.geometry = fleet.geometry
        self.config = fleet.config
        self.collision: str | None = None
        """The kind of collision counted for this robot in the last step, else None (set by the env)."""

    @property
    def layout(self) -> Layout | None:
        return self.fleet.layout

    @property
    def free_space(self) -> FreeSpace:
        return self.fleet.free_space

    def place_robot(self, start: tuple[float, float, float], rng: Any, goals: tuple = ()) -> None:
        """Nothing: the fleet placed every robot already (:meth:`FleetScene.place`)."""

    def in_collision(self) -> bool:
        """True when a new collision was counted for this robot in the last step."""
        return self.collision is not None

    def nearest_mover(self) -> float:
        return self.fleet.nearest_mover(self.index)

    def occupancy(self, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
        return self.fleet.occupancy(resolution, inflate)


def convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Counter-clockwise convex hull (Andrew's monotone chain), as the single-robot scene's outline."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    hull: list[tuple[float, float]] = []
    for seq in (pts, pts[::-1]):
        part: list[tuple[float, float]] = []
        for q in seq:
            while len(part) >= 2 and cross(part[-2], part[-1], q) <= 0:
                part.pop()
            part.append(q)
        hull += part[:-1]
    return hull
