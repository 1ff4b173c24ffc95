"""The fleet's lidar: the single-robot lidar that also sees the other robots, never itself.

The robot's lidar sits 0.11 m above the body centre, above the 0.1 m tall body of every
robot: a plane scan at that height would pass over the other robots. A warehouse robot's
scanner sees the robots around it (their bodies are what a safety scanner must detect), so
each scan is cast twice from the lidar's position: once at the lidar's height against walls,
obstacles and movers (exactly the single-robot scan) and once at the body centre's height
against the other robots' bodies only; each ray reads the nearer hit. Each robot carries a
collision-filter bit of its own (:func:`robot_group`), so the second cast can leave the
scanning robot out: its own body never shows in its scan.
"""

from __future__ import annotations

import math

import pybullet as p

from bulletnav.config import LidarConfig
from bulletnav.sensors.lidar import Lidar
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot
from bulletnav.sim.world import ROBOT_GROUP

FIRST_ROBOT_BIT = 5
"""Collision-filter bit of ``robot_0``; robot ``i`` has bit ``FIRST_ROBOT_BIT + i`` (bits 0-4
are the single-robot groups of :mod:`bulletnav.sim.world`)."""


def robot_group(index: int) -> int:
    """The collision-filter group of robot ``index``'s body links: the shared robot group
    (what walls, obstacles and movers collide with) plus the robot's own bit."""
    return ROBOT_GROUP | (1 << (FIRST_ROBOT_BIT + index))


class FleetLidar(Lidar):
    """A :class:`~bulletnav.sensors.lidar.Lidar` that also sees other robots (see the module docstring).

    Args:
        robot: the robot it is mounted on.
        clock: the scene's clock.
        config: the lidar settings (the single-robot env's).
        others_mask: the OR of the other robots' own bits (:func:`robot_group` minus the shared group).
        drop: height (m) of the lidar above the body centre, where the second cast runs.
        robots: the fleet's robots (for the cheap test whether any other one is in range).
    """

    def __init__(self, robot: Robot, clock: Clock, config: LidarConfig, others_mask: int, drop: float,
                 robots: list[Robot]) -> None:
        if config.caster != "bullet":
            raise ValueError(f"the fleet's lidar casts with PyBullet (it sees the other robots), not caster {config.caster!r}")
        super().__init__(robot, clock, config)
        self.others_mask = others_mask
        self.robots = robots
        self._low_from = [[0.0, 0.0, -drop]] * config.num_rays
        self._low_to = [[x, y, z - drop] for x, y, z in self._ray_to]
        self._reach = config.max_range + 0.5  # centre distance beyond which no other robot can be hit (m)

    def _rays(self) -> tuple:
        rays = super()._rays()
        if not self.others_mask or not self._other_in_range():
            return rays
        low = p.rayTestBatch(
            self._low_from, self._low_to, parentObjectUniqueId=self.robot.body,
            parentLinkIndex=self.robot.lidar_link, collisionFilterMask=self.others_mask,
            physicsClientId=self.robot.cid,
        )
        return tuple(b if b[2] < a[2] else a for a, b in zip(rays, low))

    def _other_in_range(self) -> bool:
        me = self.robot.state
        for other in self.robots:
            if other is self.robot or other.state is None:
                continue
            if math.hypot(other.state.x - me.x, other.state.y - me.y) < self._reach:
                return True
        return False


__all__ = ["FIRST_ROBOT_BIT", "FleetLidar", "robot_group"]
