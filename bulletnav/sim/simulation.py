"""The physics of one env: a private PyBullet client holding a world and a robot.

``Simulation.step`` is the physics half of an env step (dm_control's ``Physics``): apply
the command, advance ``substeps`` physics steps, take the robot's ground-truth snapshot
(``robot.state``). Sensors are mounted on the robot by the scene
(:mod:`bulletnav.envs.scene`); the task (reward, termination) lives in :mod:`bulletnav.tasks`.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Protocol

import pybullet as p

from bulletnav.config import PhysicsConfig, RobotConfig
from bulletnav.sim.client import Clock, connect
from bulletnav.sim.events import Events
from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import Movers
from bulletnav.sim.robot import Robot
from bulletnav.sim.world import Primitive, World


class LidarMount(Protocol):
    """What a simulation shows a lidar of the world it built (:class:`bulletnav.sensors.lidar.Lidar`)."""

    def use_world(self, primitives: list[Primitive]) -> None:
        """The static shapes, for a closed-form caster."""

    def use_shapes(self, shapes: Any) -> None:
        """A live source of every shape standing now (the kinematic profile's)."""

log = logging.getLogger(__name__)


class Simulation:
    """A private PyBullet client with a warehouse and the robot.

    Args:
        physics: rates and solver settings.
        robot: robot model and motor settings.
        gui: open the PyBullet GUI instead of DIRECT (needs an X display).
    """

    backend = "bullet"
    """Which simulation runs the scene (``PhysicsConfig.backend``): PyBullet here,
    ``"kinematic"`` for :class:`~bulletnav.sim.kinematic.KinematicSimulation`."""

    def __init__(self, physics: PhysicsConfig = PhysicsConfig(), robot: RobotConfig = RobotConfig(),
                 gui: bool = False) -> None:
        self.physics = physics
        self.gui = gui
        self.cid = connect(gui=gui)
        self.clock = Clock(physics.physics_dt, physics.substeps)
        self.world = World(self.cid, physics)
        self.robot = Robot(self.cid, robot)
        self.rebuilds = 0
        """How many times the scene was rebuilt (layout changes), for diagnostics."""

    def make_movers(self) -> Movers:
        """The scene's (empty) movers, whose bodies live in this client."""
        return Movers(self.cid)

    def make_events(self) -> Events:
        """The scene's (empty) events, whose bodies live in this client."""
        return Events(self.cid)

    def attach_lidar(self, lidar: LidarMount) -> None:
        """Show ``lidar`` the world just built (its ``"exact"`` caster casts against the primitives)."""
        lidar.use_world(self.world.primitives)

    # ------------------------------------------------------------------ episodes
    def reset(self, layout: Layout, start: tuple[float, float, float], rebuild: bool = False) -> None:
        """Start an episode in ``layout`` with the robot at rest at ``start`` = (x, y, yaw).

        The scene is rebuilt when the layout differs from the current one or ``rebuild`` is
        set; otherwise the robot is teleported (fast, but the solver keeps warm-start state,
        so only a rebuild makes the next steps independent of history).
        """
        if rebuild or self.world.layout != layout:
            if self.gui:  # the GUI redraws after every body created: seconds for a warehouse
                p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 0, physicsClientId=self.cid)
            self.world.build(layout)
            self.robot.load(start)
            if self.gui:
                p.configureDebugVisualizer(p.COV_ENABLE_RENDERING, 1, physicsClientId=self.cid)
            self.world.labels[self.robot.body] = "robot"
            self.rebuilds += 1
        else:
            self.robot.reset_pose(start)
        self.clock.tick = 0
        self.clock.episode += 1

    def step(self, v: float, w: float, before_substep: Callable[[int, int], None] | None = None) -> None:
        """Command (v m/s, w rad/s) and advance one control period; ``before_substep(k, n)``
        runs before physics step ``k`` of ``n`` (to move kinematic bodies)."""
        self.robot.set_velocity(v, w)
        cid = self.cid
        if before_substep is None:
            for _ in range(self.physics.substeps):
                p.stepSimulation(physicsClientId=cid)
        else:
            n = self.physics.substeps
            for k in range(n):
                before_substep(k, n)
                p.stepSimulation(physicsClientId=cid)
        self.clock.tick += self.physics.substeps
        self.robot.sample()  # the ground truth of this step, shared by sensors and task

    def in_collision(self) -> bool:
        """True when the robot touches a wall or an obstacle (the floor does not count)."""
        return self.robot.touching(self.world.static_set)

    def close(self) -> None:
        if self.cid >= 0:
            try:
                p.disconnect(physicsClientId=self.cid)
            except p.error:  # already gone (GUI window closed by the user)
                pass
            self.cid = -1
