"""The scene of an env: physics client, world, robot and the robot's sensors.

:class:`Scene` is what the env and its task drive: it holds the current layout and its
free-space grids, places the robot, steps physics and sensors. :class:`SceneView` is the
one public, read-only window onto it for everything outside the env -- navigator,
evaluation, videos, plots, dashboard -- reached as ``env.unwrapped.scene``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from bulletnav.config import EnvConfig
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.sensors.suite import SensorSuite
from bulletnav.sim.layout import Layout
from bulletnav.sim.sampler import FreeSpace
from bulletnav.sim.simulation import Simulation

if TYPE_CHECKING:
    from bulletnav.tasks.base import Task


class Scene:
    """Client, world, robot and sensors of one env (the task reads it through its methods).

    Args:
        config: the env's configuration.
        gui: open the PyBullet GUI (needs an X display).
    """

    def __init__(self, config: EnvConfig, gui: bool = False) -> None:
        self.config = config
        self.geometry: RobotGeometry = robot_geometry(config.robot)
        self.sim = Simulation(config.physics, config.robot, gui=gui)
        self.robot = self.sim.robot
        self.clock = self.sim.clock
        self.sensors = SensorSuite.build(config.sensors, self.robot, self.clock, config.physics.gravity)
        self.layout: Layout | None = None
        self.start: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Where the robot was placed this episode (x m, y m, yaw rad)."""
        self._free: FreeSpace | None = None
        self._rebuild = False
        self._grids: dict[tuple[float, float], OccupancyGrid] = {}

    @property
    def cid(self) -> int:
        """The scene's own PyBullet client id."""
        return self.sim.cid

    # ------------------------------------------------------------------ episodes
    def use_layout(self, layout: Layout, rebuild: bool = False) -> None:
        """Make ``layout`` this episode's world; it is built (or the robot teleported) at
        :meth:`place_robot`. ``rebuild`` forces a fresh physics scene even for the same layout."""
        if layout is not self.layout:
            self._free = None
            self._grids = {}
        self.layout = layout
        self._rebuild = rebuild

    @property
    def free_space(self) -> FreeSpace:
        """Free-space grids of the current layout for the robot's disc (built once per layout)."""
        if self.layout is None:
            raise RuntimeError("the scene has no layout yet: reset the env first")
        if self._free is None:
            self._free = FreeSpace.build(self.layout, self.config.sampler, self.geometry.radius)
        return self._free

    def place_robot(self, start: tuple[float, float, float], rng: np.random.Generator) -> None:
        """Start the episode: build the world if needed, put the robot at rest at ``start``
        and give each sensor its noise generator from ``rng``."""
        if self.layout is None:
            raise RuntimeError("use_layout() before place_robot()")
        self.sim.reset(self.layout, start, rebuild=self._rebuild)
        self._rebuild = False
        self.sensors.reset(rng)
        self.start = (float(start[0]), float(start[1]), float(start[2]))

    def step(self, v: float, w: float) -> None:
        """Command (v m/s, w rad/s), advance one control period, update the sensors."""
        self.sim.step(v, w)
        self.sensors.update()

    def in_collision(self) -> bool:
        """True when the robot touches a wall or an obstacle (the floor does not count)."""
        return self.robot.touching(self.sim.world.static_set)  # Simulation.in_collision(), one call less per step

    def occupancy(self, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
        """The current layout rasterised at ``resolution`` (m), obstacles grown by ``inflate``
        (m); cached per layout. Treat the grid as read-only."""
        key = (float(resolution), float(inflate))
        grid = self._grids.get(key)
        if grid is None:
            if self.layout is None:
                raise RuntimeError("the scene has no layout yet: reset the env first")
            occ = self.layout.occupancy(resolution, inflate=inflate)
            xs, ys = self.layout.grid_axes(resolution)
            occ.flags.writeable = False
            grid = self._grids[key] = OccupancyGrid(occ, resolution, (float(xs[0]), float(ys[0])))
        return grid

    def close(self) -> None:
        self.sim.close()


class SceneView:
    """Read-only view of an env's scene and task: what consumers may look at besides ``obs``
    and ``info`` (``env.unwrapped.scene``).

    Everything here reads; nothing changes the simulation or draws random numbers, so a
    consumer can never change an episode. Sensor objects are exposed for their idempotent
    ``read()`` (cached per sensor period) and their geometry (``lidar.angles``,
    ``camera.view_matrix()``).
    """

    def __init__(self, scene: Scene, task: Task) -> None:
        self._scene = scene
        self._task = task

    # ------------------------------------------------------------------ the world
    @property
    def client(self) -> int:
        """The env's PyBullet client id, for drawing debug items in the GUI only."""
        return self._scene.cid

    @property
    def layout(self) -> Layout | None:
        """The static layout of the current episode (floor, obstacles); None before a reset."""
        return self._scene.layout

    def occupancy(self, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
        """The true static map at ``resolution`` (m), obstacles grown by ``inflate`` (m)."""
        return self._scene.occupancy(resolution, inflate)

    @property
    def movers(self) -> tuple[Any, ...]:
        """Moving obstacles of the current world (none in static worlds)."""
        return ()

    @property
    def scene_builds(self) -> int:
        """How many times the physics scene was rebuilt; debug items vanish at each rebuild."""
        return self._scene.sim.rebuilds

    # ------------------------------------------------------------------ the robot
    @property
    def robot_body(self) -> int:
        """The robot's PyBullet body id in :attr:`client` (for drawing and benchmarks: queries
        only; moving the body would change the episode)."""
        return self._scene.robot.body

    @property
    def geometry(self) -> RobotGeometry:
        """The robot's outline, disc radius, wheels and sensor mounts (from its URDF)."""
        return self._scene.geometry

    @property
    def pose(self) -> tuple[float, float, float]:
        """Ground-truth pose (x m, y m, yaw rad) after the last step or reset."""
        state = self._scene.robot.state
        if state is None:
            raise RuntimeError("the robot has not been placed yet: reset the env first")
        return state.x, state.y, state.yaw

    @property
    def start(self) -> tuple[float, float, float]:
        """Where the robot started this episode (x m, y m, yaw rad)."""
        return self._scene.start

    @property
    def sensors(self) -> SensorSuite:
        """The robot's sensors (``lidar``, ``camera``, ``imu``, ``odometry``; None if disabled)."""
        return self._scene.sensors

    # ------------------------------------------------------------------ the task
    @property
    def goal(self) -> tuple[float, float] | None:
        """The task's current goal point (m), if it has one."""
        return self._task.goal

    @property
    def goals(self) -> tuple[tuple[float, float], ...]:
        """All goal points of the episode, in the task's order."""
        return self._task.goals

    @property
    def goal_radius(self) -> float:
        """Distance (m) from a goal under which it counts as reached."""
        return self._scene.config.task.goal_radius

    # ------------------------------------------------------------------ actions
    @property
    def command_limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Physical command ranges: (v min, v max) m/s and (w min, w max) rad/s."""
        t = self._scene.config.task
        return (0.0, t.max_speed), (-t.max_turn_rate, t.max_turn_rate)

    @property
    def normalized_actions(self) -> bool:
        """True when actions are [-1, 1] mapped linearly onto :attr:`command_limits`."""
        return self._scene.config.normalize_actions

    # ------------------------------------------------------------------ time
    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per env step."""
        return self._scene.config.physics.control_dt

    @property
    def steps(self) -> int:
        """Env steps since the last reset."""
        return self._scene.clock.tick // self._scene.clock.control_ticks

    @property
    def episode(self) -> int:
        """Resets so far; changes at every reset."""
        return self._scene.clock.episode
