"""Read-only views of a fleet env for its controllers, as ``env.unwrapped.scene`` is for a
single-robot env.

:class:`FleetView` shows the whole fleet (static map, every robot's pose and speed, the movers);
:class:`RobotView` shows one robot with the interface the single-robot consumers read
(:class:`~bulletnav.control.navigator.Navigator`, the :class:`~bulletnav.control.shield.Veto`):
``sensors``, ``geometry``, ``layout``, ``occupancy()``, ``pose``, ``dynamic``, ``movers``,
``control_dt``, ``normalized_actions``, ``command_limits``.

The other robots are moving obstacles to a robot. Two choices set how a view shows them:

- ``others_as_movers``: the other robots are listed in ``movers`` as :class:`RobotMover`
  entries (pose, forward speed along the heading, footprint box), exactly as the shield reads
  forklifts: this is how the shield sees them. ``speeds`` (a dict the owner fills) replaces
  the current speed of the robots it names: the fleet's shields, deciding one robot after the
  other, show each robot already decided this step at the speed it was committed to.
- in a fleet of two or more robots the view is ``dynamic`` even without movers, so the
  navigator's lidar map forgets cells a robot has left (free-space evidence clears them).

Nothing here changes the simulation or draws random numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from bulletnav.envs.scene import SceneReader
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.scene import FleetScene


@dataclass(frozen=True)
class RobotMover:
    """Another robot as a mover for the shield (the fields the shield reads from a
    :class:`~bulletnav.sim.movers.MoverView`)."""

    kind: str
    """Always ``"robot"`` (the shield models any kind but ``"worker"`` as a box)."""
    pose: tuple[float, float, float]
    """x, y (m) of its body centre and heading (rad)."""
    speed: float
    """Forward speed along its heading (m/s, >= 0: the robots drive forward only)."""
    size: tuple[float, float, float]
    """Length, width, height (m) of the box around its collision rectangles."""
    index: int
    """Its robot index in the fleet."""
    path: tuple = ()
    yielding: bool = False
    """Robots never wait for another robot of their own accord (the shield's creeping is for movers)."""


class FleetView(SceneReader):
    """The whole fleet, read-only (see the module docstring): besides the world, movers,
    events, action limits and clock every view of a scene shows (:class:`~bulletnav.envs.scene.SceneReader`),
    every robot's pose, speed and body.

    Args:
        env: the fleet env (a :class:`~bulletnav.fleet.env.FleetEnv`).
    """

    def __init__(self, env: FleetEnv) -> None:
        self._env = env
        self._scene: FleetScene = env._scene  # the fleet package's own env: the view is its public face
        g = self._scene.geometry
        xs = [abs(r.cx) + r.half_x for r in g.rectangles]
        ys = [abs(r.cy) + r.half_y for r in g.rectangles]
        self.footprint = (2 * max(xs), 2 * max(ys), 0.1)
        """Length, width, height (m) of the box around a robot's collision rectangles."""

    @property
    def num_robots(self) -> int:
        return len(self._scene.robots)

    @property
    def agents(self) -> list[str]:
        return list(self._env.possible_agents)

    @property
    def time_s(self) -> float:
        return self._scene.clock.time

    def pose(self, index: int) -> tuple[float, float, float]:
        """Robot ``index``'s ground-truth pose (x m, y m, yaw rad)."""
        s = self._scene.robots[index].state
        if s is None:
            raise RuntimeError("the robots have not been placed yet: reset the env first")
        return s.x, s.y, s.yaw

    def speed(self, index: int) -> float:
        """Robot ``index``'s forward speed (m/s, its velocity along its heading)."""
        s = self._scene.robots[index].state
        vx, vy = s.linear_velocity[0], s.linear_velocity[1]
        return vx * math.cos(s.yaw) + vy * math.sin(s.yaw)

    def positions(self) -> list[tuple[float, float]]:
        return [(r.state.x, r.state.y) for r in self._scene.robots]

    def robot_body(self, index: int) -> int:
        """Robot ``index``'s PyBullet body id, for colouring it in the GUI only."""
        return self._scene.robots[index].body

    def robot_movers(self, exclude: int | None = None, speeds: dict[int, float] | None = None) -> list[RobotMover]:
        """Every robot but ``exclude`` as a :class:`RobotMover`; a robot in ``speeds`` moves at
        the speed given there (m/s), the others at their current forward speed."""
        out = []
        for j in range(self.num_robots):
            if j == exclude:
                continue
            speed = speeds[j] if speeds is not None and j in speeds else self.speed(j)
            out.append(RobotMover("robot", self.pose(j), max(speed, 0.0), self.footprint, j))
        return out

    def robot(self, index: int, others_as_movers: bool = False, speeds: dict[int, float] | None = None) -> RobotView:
        """Robot ``index``'s view (see :class:`RobotView`)."""
        return RobotView(self, index, others_as_movers, speeds)


class RobotView(SceneReader):
    """One robot of the fleet as a single-robot consumer reads ``env.unwrapped.scene``."""

    def __init__(self, fleet: FleetView, index: int, others_as_movers: bool = False,
                 speeds: dict[int, float] | None = None) -> None:
        self.fleet = fleet
        self.index = index
        self.others_as_movers = others_as_movers
        self.speeds = speeds
        """With ``others_as_movers``: the speeds (m/s) the other robots are shown moving at, by
        index, where the owner of the dict has set one (the shield's commitments); the rest move
        at their current speed."""
        self._scene: FleetScene = fleet._scene
        self._slot = self._scene.slots[index]

    @property
    def sensors(self) -> Any:
        """The robot's sensors (``lidar``, ``imu``, ``odometry``), for their idempotent ``read()``."""
        return self._slot.sensors

    @property
    def pose(self) -> tuple[float, float, float]:
        return self.fleet.pose(self.index)

    @property
    def dynamic(self) -> bool:
        """True with movers, or with any other robot on the floor (they move)."""
        return self.fleet.dynamic or self.fleet.num_robots > 1

    @property
    def movers(self) -> tuple:
        """The movers; with ``others_as_movers`` the other robots too (:class:`RobotMover`)."""
        movers = self.fleet.movers
        if self.others_as_movers:
            return (*movers, *self.fleet.robot_movers(exclude=self.index, speeds=self.speeds))
        return movers


__all__ = ["FleetView", "RobotMover", "RobotView"]
