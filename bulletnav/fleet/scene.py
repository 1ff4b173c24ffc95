"""The fleet's scene: one PyBullet client holding the world, N robots with their own sensors,
and the movers and events of a dynamic warehouse.

:class:`FleetScene` composes the single-robot parts (:class:`~bulletnav.sim.world.World`,
:class:`~bulletnav.sim.robot.Robot`, :class:`~bulletnav.sensors.suite.SensorSuite`,
:class:`~bulletnav.sim.movers.Movers`, :class:`~bulletnav.sim.events.Events`) for several robots,
on the single-robot scene's own base (:class:`~bulletnav.envs.scene.SceneCore`: layout grids,
mover and event pools, outline); the movers yield to whichever robot stands in their field
(:meth:`~bulletnav.sim.movers.Movers.plan_step` takes every robot's position).
:class:`RobotSlot` shows one robot of it with the interface a single-robot task reads, so the
navigation task's observation and reward run unchanged on every robot.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pybullet as p

from bulletnav.config import EnvConfig
from bulletnav.envs.scene import SceneCore
from bulletnav.fleet.lidar import FIRST_ROBOT_BIT, FleetLidar, robot_group
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.sensors.camera import Camera
from bulletnav.sensors.imu import Imu
from bulletnav.sensors.odometry import Odometry
from bulletnav.sensors.suite import SensorSuite
from bulletnav.sim.client import Clock, connect
from bulletnav.sim.events import Events
from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import Movers
from bulletnav.sim.robot import Robot
from bulletnav.sim.sampler import FreeSpace
from bulletnav.sim.world import World

KINDS = ("static", "mover", "person", "robot")
"""What a robot can collide with: walls and obstacles (pallet events included), forklifts,
walking workers, other robots."""
_ALL_BITS = 0x7FFFFFFF  # every collision-filter group (robots collide with each other and with everything else)


class FleetScene(SceneCore):
    """Client, world, robots, sensors, movers and events of one fleet env.

    Args:
        config: the per-robot configuration (the single-robot env's).
        num_robots: how many robots.
        gui: open the PyBullet GUI (needs an X display).
    """

    def __init__(self, config: EnvConfig, num_robots: int, gui: bool = False) -> None:
        super().__init__(config)
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
        self.movers = Movers(self.cid)
        self.events = Events(self.cid)
        self.dynamic = False
        """True when this episode has movers or events."""
        self.goals: tuple[tuple[float, float], ...] = ()
        """The robots' current goals, kept clear by the events."""
        self.rebuilds = 0
        self._robot_index: dict[int, int] = {}
        self._kind_of: dict[int, str] = {}
        lidar = sensors.lidar
        self._visible = math.inf if sensors.camera.enabled or not lidar.enabled else lidar.max_range + 0.5

    # ------------------------------------------------------------------ episodes
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
            self._start_dynamic(layout, rng, (*((s[0], s[1]) for s in starts), *goals))
        self._robot_index = {robot.body: i for i, robot in enumerate(self.robots)}
        labels = self.world.labels
        static = self.world.static_set | self.events.body_ids
        self._kind_of = {b: "static" for b in static}
        self._kind_of.update({b: "person" if labels.get(b) == "worker" else "mover" for b in self.movers.body_ids})
        self._kind_of.update({b: "robot" for b in self._robot_index})
        self.step_events: list[dict] = []

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
            near = self.movers.plan_step(self.config.physics.control_dt, xy, self.geometry.radius,
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
        return self._outline_at(self.robots[index].state)

    def nearest_mover(self, index: int) -> float:
        """Distance (m) between robot ``index``'s outline and the nearest mover; inf without movers."""
        if not self.dynamic:
            return math.inf
        return self._nearest_mover_to(self.robots[index].state)

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
