"""What a task sees of the scene it runs on: :class:`TaskScene`, a read-only protocol.

Tasks are written against this protocol, never against :mod:`bulletnav.envs`: the env's
:class:`~bulletnav.envs.scene.Scene` and a fleet robot's
:class:`~bulletnav.fleet.scene.RobotSlot` implement it structurally (no inheritance), and
``bulletnav.envs`` imports ``bulletnav.tasks`` one way. It lies below both and imports only
the simulation, sensors and geometry it names.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Protocol, runtime_checkable

if TYPE_CHECKING:
    import numpy as np

    from bulletnav.geometry import RobotGeometry
    from bulletnav.sensors.suite import SensorSuite
    from bulletnav.sim.layout import Layout
    from bulletnav.sim.robot import Robot
    from bulletnav.sim.sampler import FreeSpace


@runtime_checkable
class TaskScene(Protocol):
    """The scene as a task reads it: the layout and its free space, the robot and its sensors
    (all read-only), plus the one thing a task does to it, :meth:`place_robot` at a reset."""

    @property
    def layout(self) -> Layout | None:
        """The episode's layout (None before the first reset)."""

    @property
    def free_space(self) -> FreeSpace:
        """Free-space grids of the layout for the robot's disc."""

    @property
    def geometry(self) -> RobotGeometry:
        """The robot's outline, disc and sensor mounts."""

    @property
    def robot(self) -> Robot:
        """The robot (tasks read its ``state``: pose and velocities)."""

    @property
    def sensors(self) -> SensorSuite:
        """The robot's sensors (``require``, ``lidar``, ``imu``, ``odometry``, ...)."""

    def place_robot(self, start: tuple[float, float, float], rng: np.random.Generator,
                    goals: tuple[tuple[float, float], ...] = ()) -> None:
        """Start the episode with the robot at rest at ``start`` (x m, y m, yaw rad)."""

    def in_collision(self) -> bool:
        """True while the robot touches an obstacle (static or moving)."""

    def nearest_mover(self) -> float:
        """Gap (m) between the robot's outline and the nearest moving obstacle (inf if none)."""
