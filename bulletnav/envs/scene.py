"""The scene of an env: physics client, world, robot and the robot's sensors.

:class:`Scene` is what the env and its task drive: it holds the current layout and its
free-space grids, places the robot, steps physics and sensors. :class:`SceneView` is the
one public, read-only window onto it for everything outside the env -- navigator,
evaluation, videos, plots, dashboard -- reached as ``env.unwrapped.scene``.

What the fleet's scene and views share with these lives here once: :class:`SceneCore`
(the layout's cached grids, the pools and start of movers and events, the robot's outline)
under :class:`Scene` and :class:`~bulletnav.fleet.scene.FleetScene`, and :class:`SceneReader`
(the read-only world, movers, events, action limits and clock) under :class:`SceneView` and
the fleet's views.
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from bulletnav.config import EnvConfig, ShiftConfig
from bulletnav.envs.actions import ActionMap
from bulletnav.errors import ConfigError
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.sensors.suite import SensorSuite
from bulletnav.sim.client import Clock
from bulletnav.sim.dynamic import RESOLUTION as CLEARANCE_RESOLUTION
from bulletnav.sim.dynamic import ClearanceMap, draw_movers
from bulletnav.sim.events import Events
from bulletnav.sim.kinematic import KinematicSimulation
from bulletnav.sim.layout import Layout
from bulletnav.sim.movers import Movers, MoverView
from bulletnav.sim.robot import RobotState
from bulletnav.sim.sampler import FreeSpace
from bulletnav.sim.simulation import Simulation
from bulletnav.sim.specs import MoverSpec
from bulletnav.sim.world import World

if TYPE_CHECKING:
    from bulletnav.tasks.base import Task


class SceneCore:
    """What a single-robot :class:`Scene` and a fleet's scene
    (:class:`~bulletnav.fleet.scene.FleetScene`) share: the current layout with its free-space
    grids and occupancy grids (cached per layout), the pools of movers and events made once per
    physics scene, their start at each episode, and the robot's outline.

    A subclass sets ``movers``, ``events``, ``world``, ``rebuilds`` and ``dynamic``.

    Args:
        config: the env's (per-robot) configuration.
    """

    cid: int
    """The scene's own PyBullet client id."""
    clock: Clock
    movers: Movers
    events: Events
    world: World
    """The static world (floor, walls, obstacles) in the scene's client."""
    rebuilds: int
    """How many times the physics scene was built."""
    dynamic: bool
    """True when this episode has movers or events."""

    def __init__(self, config: EnvConfig) -> None:
        self.config = config
        self.geometry: RobotGeometry = robot_geometry(config.robot)
        self.layout: Layout | None = None
        self._free: FreeSpace | None = None
        self._rebuild = False
        self._grids: dict[tuple[float, float], OccupancyGrid] = {}
        self._cmap: ClearanceMap | None = None
        self._built_at = -1
        corners = [(sx * r.half_x + r.cx, sy * r.half_y + r.cy) for r in self.geometry.rectangles
                   for sx in (-1, 1) for sy in (-1, 1)]
        self._outline = convex_hull(corners)

    # ------------------------------------------------------------------ the layout
    def use_layout(self, layout: Layout, rebuild: bool = False) -> None:
        """Make ``layout`` this episode's world; it is built (or the robots teleported) when the
        episode starts. ``rebuild`` forces a fresh physics scene even for the same layout."""
        if layout is not self.layout:
            self._free = None
            self._grids = {}
            self._cmap = None
        self.layout = layout
        self._rebuild = rebuild

    @property
    def free_space(self) -> FreeSpace:
        """Free-space grids of the current layout for the robot's disc (built once per layout)."""
        if self.layout is None:
            raise RuntimeError("the scene has no layout yet: reset the env first")
        if self._free is None:
            self._share_grids()
        return self._free

    def _share_grids(self) -> None:
        """The layout's occupancy at the sampler's resolution, grown by the sampler's clearance,
        by the robot's radius and not at all, in one pass: the free space is built from the
        first two, and the last two serve :meth:`occupancy` (the events' inflated map and the
        movers' clearance map ask for them), so no grid is computed twice."""
        layout, sampler, radius = self.layout, self.config.sampler, self.geometry.radius
        res = sampler.grid_resolution
        xs, ys = layout.grid_axes(res)
        near = layout.within_levels(xs, ys, (sampler.clearance, radius, 0.0))
        self._free = FreeSpace.from_occupancy(layout, sampler, near[0], near[1])
        for inflate, occ in ((radius, near[1]), (0.0, near[2])):
            key = (float(res), float(inflate))
            if key not in self._grids:
                occ.flags.writeable = False
                self._grids[key] = OccupancyGrid(occ, res, (float(xs[0]), float(ys[0])))

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

    # ------------------------------------------------------------------ movers and events
    def _start_dynamic(self, layout: Layout, rng: np.random.Generator, avoid: tuple[tuple[float, float], ...],
                       speed_scale: float = 1.0) -> None:
        """Start this episode's movers (the layout's, then those drawn from ``rng``, none near a
        point of ``avoid``; speeds scaled by ``speed_scale``) and events (drawn from ``rng``),
        making the pools first in a freshly built physics scene."""
        dyn = self.config.dynamic
        if self._built_at != self.rebuilds:  # a fresh client: make the pools once for this world
            self._build_pools(layout)
        specs = layout.dynamic
        if dyn.forklifts[1] > 0 or dyn.workers[1] > 0:
            if self._cmap is None:
                self._cmap = ClearanceMap(layout, occupied=self.occupancy(CLEARANCE_RESOLUTION).occupied)
            specs = specs + draw_movers(layout, rng, dyn, self.geometry.radius, avoid, self._cmap)
        if speed_scale != 1.0:
            specs = tuple(replace(s, speed=s.speed * speed_scale) for s in specs)
        self.movers.start(specs)
        inflated = self.occupancy(self.events.resolution, self.geometry.radius).occupied
        self.events.start(rng if dyn.pallet_events_per_min > 0 else None, dyn.pallet_events_per_min, inflated)

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
        world = self.world
        labels = world.labels
        self.movers.build(shapes, labels)
        self.events.build(layout, world.obstacle_ids, dyn.event_pallets if dyn.pallet_events_per_min > 0 else 0, labels)
        self._built_at = self.rebuilds

    # ------------------------------------------------------------------ the robot's outline
    def _outline_at(self, state: RobotState) -> list[tuple[float, float]]:
        """The outline (convex hull of the collision boxes) of a robot in ``state``, world frame, counter-clockwise."""
        c, s = math.cos(state.yaw), math.sin(state.yaw)
        return [(state.x + c * x - s * y, state.y + s * x + c * y) for x, y in self._outline]

    def _nearest_mover_to(self, state: RobotState) -> float:
        """Distance (m) between the outline of a robot in ``state`` and the nearest mover; inf without movers."""
        if not self.movers.active:
            return math.inf
        return self.movers.nearest_gap(self._outline_at(state), (state.x, state.y), self.geometry.outline_radius)


class Scene(SceneCore):
    """Client, world, robot and sensors of one env (the task reads it through its methods).

    Args:
        config: the env's configuration.
        gui: open the PyBullet GUI (needs an X display).
    """

    def __init__(self, config: EnvConfig, gui: bool = False) -> None:
        super().__init__(config)
        self.sim = make_simulation(config, gui)
        self.world = self.sim.world
        self.robot = self.sim.robot
        self.clock = self.sim.clock
        sensors = config.sensors
        if self.sim.backend != "bullet" and sensors.camera.enabled:  # no renderer: the camera is refused by the env
            sensors = replace(sensors, camera=replace(sensors.camera, enabled=False))
        self.sensors = SensorSuite.build(sensors, self.robot, self.clock, config.physics.gravity)
        self.start: tuple[float, float, float] = (0.0, 0.0, 0.0)
        """Where the robot was placed this episode (x m, y m, yaw rad)."""
        # moving obstacles and events (inactive, and never touching PyBullet, in static worlds)
        self.movers = self.sim.make_movers()
        self.events = self.sim.make_events()
        self.dynamic = False
        """True when this episode's world has movers or events (set at :meth:`place_robot`)."""
        self.goals: tuple[tuple[float, float], ...] = ()
        self.collision_with: str | None = None
        """``"static"`` or ``"dynamic"`` after a step in contact, else None (dynamic worlds)."""
        self.step_events: list[dict] = []
        """Events that happened in the last step."""
        self.shift: ShiftConfig = config.shift
        """The robot, floor and sensor shift of this episode (``EnvConfig.shift`` unless the env sets another)."""
        self._shifted = False
        self._latency: deque[tuple[float, float]] | None = None
        self._mover_set: frozenset[int] = frozenset()
        self._static_set: frozenset[int] = frozenset()
        # movers farther than this cannot be seen (lidar range; everywhere when a camera looks)
        lidar = self.sensors.lidar
        self._visible = math.inf if self.sensors.camera is not None or lidar is None else lidar.config.max_range + 0.5

    @property
    def cid(self) -> int:
        """The scene's own PyBullet client id."""
        return self.sim.cid

    # ------------------------------------------------------------------ episodes
    def place_robot(self, start: tuple[float, float, float], rng: np.random.Generator,
                    goals: tuple[tuple[float, float], ...] = ()) -> None:
        """Start the episode: build the world if needed, put the robot at rest at ``start``,
        give each sensor its noise generator from ``rng``, then start the movers and events
        (drawn from ``rng``; none start near ``start`` or the ``goals``)."""
        layout = self.layout
        if layout is None:
            raise RuntimeError("use_layout() before place_robot()")
        builds = self.sim.rebuilds
        self.sim.reset(layout, start, rebuild=self._rebuild)
        self._rebuild = False
        lidar = self.sensors.lidar
        if lidar is not None and self.sim.rebuilds != builds:
            self.sim.attach_lidar(lidar)
        if self._shifted or not self.shift.nominal:  # a nominal env never touches these
            self._apply_shift(self.shift)
        self.sensors.reset(rng)
        self.start = (float(start[0]), float(start[1]), float(start[2]))
        self.goals = tuple((float(g[0]), float(g[1])) for g in goals)
        dyn = self.config.dynamic
        self.dynamic = dyn.active or bool(layout.dynamic) or bool(layout.events)
        if not self.dynamic:
            return
        if lidar is not None and not lidar.sees_movers:
            raise ConfigError(f"lidar caster 'exact' sees only the static world, and {layout.name or layout.source or 'this world'} "
                              "has movers or events: use caster 'bullet'")
        self._start_dynamic(layout, rng, (self.start[:2], *self.goals), self.shift.mover_speed_scale)
        self.collision_with = None
        self.step_events = []

    def _apply_shift(self, shift: ShiftConfig) -> None:
        """Floor friction, the robot's mass, wheel friction and torque limit (after the robot
        was placed: a rebuilt scene reloads it nominal), the sensors' models and the action delay."""
        self.sim.world.set_floor_friction(shift.floor_friction)
        self.robot.apply_shift(shift.mass_scale, shift.wheel_friction_scale, shift.motor_force_scale)
        self.sensors.apply_shift(shift)
        self._latency = deque([(0.0, 0.0)] * shift.action_latency) if shift.action_latency else None
        self._shifted = not shift.nominal

    @property
    def rebuilds(self) -> int:
        """How many times the physics scene was built (a fresh one needs fresh pools of movers and events)."""
        return self.sim.rebuilds

    def _build_pools(self, layout: Layout) -> None:
        super()._build_pools(layout)
        self._mover_set = self.movers.body_ids
        self._static_set = self.world.static_set | self.events.body_ids

    def step(self, v: float, w: float) -> None:
        """Command (v m/s, w rad/s), advance one control period, update the sensors. With an
        action latency of k steps the motors get the command of k steps before."""
        if self._latency is not None:
            self._latency.append((v, w))
            v, w = self._latency.popleft()
        if not self.dynamic:
            self.sim.step(v, w)
            self.sensors.update()
            return
        state = self.robot.state
        near = self.movers.plan_step(self.config.physics.control_dt, [(state.x, state.y)], self.geometry.radius,
                                     self.config.dynamic.near, self._visible)
        if near:
            movers = self.movers
            self.sim.step(v, w, before_substep=lambda k, n: movers.place_between(near, (k + 1) / n))
        else:
            self.sim.step(v, w)
        state = self.robot.state
        self.step_events = self.events.step(self.clock.time, self.config.physics.control_dt, (state.x, state.y),
                                            self.goals, self.geometry.radius, self.movers.active)
        self.sensors.update()

    def in_collision(self) -> bool:
        """True when the robot touches a wall, an obstacle or a mover (the floor does not count).
        In dynamic worlds :attr:`collision_with` says which kind."""
        if not self.dynamic:
            return self.sim.in_collision()
        self.collision_with = self.robot.contact_kind(self._static_set, self._mover_set)
        return self.collision_with is not None

    def outline(self) -> list[tuple[float, float]]:
        """The robot's outline (convex hull of its collision boxes), world frame, counter-clockwise."""
        return self._outline_at(self.robot.state)

    def nearest_mover(self) -> float:
        """Distance (m) between the robot's outline and the nearest mover; inf without movers."""
        return self._nearest_mover_to(self.robot.state)

    def dynamic_info(self) -> dict[str, Any]:
        """The scene's part of ``info`` in dynamic worlds."""
        return {"nearest_mover_m": self.nearest_mover(), "collision_with": self.collision_with,
                "events": self.step_events}

    def close(self) -> None:
        self.sim.close()


class SceneReader:
    """What every read-only view of a scene shows, a single-robot env's (:class:`SceneView`)
    or a fleet's (:class:`~bulletnav.fleet.view.FleetView`, :class:`~bulletnav.fleet.view.RobotView`):
    the world, its movers and events, the action limits and the clock. It reads ``_scene``, the
    :class:`SceneCore` it views; nothing here changes the simulation or draws random numbers."""

    _scene: SceneCore

    # ------------------------------------------------------------------ the world
    @property
    def client(self) -> int:
        """The scene's PyBullet client id, for drawing debug items in the GUI only."""
        return self._scene.cid

    @property
    def layout(self) -> Layout | None:
        """The static layout of the current episode (floor, obstacles); None before a reset."""
        return self._scene.layout

    def occupancy(self, resolution: float, inflate: float = 0.0) -> OccupancyGrid:
        """The true static map at ``resolution`` (m), obstacles grown by ``inflate`` (m); cached per layout."""
        return self._scene.occupancy(resolution, inflate)

    @property
    def free_space(self) -> FreeSpace:
        """The current layout's free-space grids for the robot's disc (cached per layout)."""
        return self._scene.free_space

    @property
    def movers(self) -> tuple[MoverView, ...]:
        """Moving obstacles now (kind, pose, speed, size, route, yielding); none in static worlds."""
        return self._scene.movers.views() if self._scene.dynamic else ()

    @property
    def mover_specs(self) -> tuple[MoverSpec, ...]:
        """This episode's movers as specified (frozen specs, in :attr:`movers` order; none in
        static worlds): what their kinematics follow (:func:`bulletnav.sim.movers.kinematic_poses`)."""
        return tuple(m.spec for m in self._scene.movers.active) if self._scene.dynamic else ()

    @property
    def events(self) -> tuple[dict, ...]:
        """Events so far this episode (time, add/remove, label, centre, size, scripted/drawn); none in static worlds."""
        return tuple(self._scene.events.log) if self._scene.dynamic else ()

    @property
    def dynamic(self) -> bool:
        """True when this episode has movers or events."""
        return self._scene.dynamic

    @property
    def scene_builds(self) -> int:
        """How many times the physics scene was built; debug items vanish at each rebuild."""
        return self._scene.rebuilds

    # ------------------------------------------------------------------ the robot
    @property
    def geometry(self) -> RobotGeometry:
        """The robot's outline, disc radius, wheels and sensor mounts (from its URDF)."""
        return self._scene.geometry

    @property
    def wheel_accel(self) -> float | None:
        """The robot's measured rim acceleration (m/s^2; ``RobotConfig.wheel_accel``), None where not measured."""
        return self._scene.config.robot.wheel_accel

    # ------------------------------------------------------------------ actions
    @property
    def command_limits(self) -> tuple[tuple[float, float], tuple[float, float]]:
        """Physical command ranges: (v min, v max) m/s and (w min, w max) rad/s; v min is
        ``TaskConfig.min_speed`` (0: forward only, negative: the robot may back up)."""
        t = self._scene.config.task
        return (t.min_speed, t.max_speed), (-t.max_turn_rate, t.max_turn_rate)

    @property
    def normalized_actions(self) -> bool:
        """True when actions are [-1, 1] mapped linearly onto :attr:`command_limits`."""
        return self._scene.config.normalize_actions

    def action_for(self, v: float, w: float) -> np.ndarray:
        """The action (float32) that commands ``v`` m/s and ``w`` rad/s: the physical pair, or
        with :attr:`normalized_actions` its linear image in [-1, 1] (not clipped;
        :meth:`~bulletnav.envs.actions.ActionMap.action`)."""
        return ActionMap.of(self._scene.config.task, self.normalized_actions).action(v, w)

    # ------------------------------------------------------------------ time
    @property
    def control_dt(self) -> float:
        """Seconds of simulated time per env step."""
        return self._scene.config.physics.control_dt

    @property
    def episode(self) -> int:
        """Resets so far; changes at every reset."""
        return self._scene.clock.episode


class SceneView(SceneReader):
    """Read-only view of an env's scene and task: what consumers may look at besides ``obs``
    and ``info`` (``env.unwrapped.scene``).

    Everything here reads; nothing changes the simulation or draws random numbers, so a
    consumer can never change an episode. Sensor objects are exposed for their idempotent
    ``read()`` (cached per sensor period) and their geometry (``lidar.angles``,
    ``camera.view_matrix()``).
    """

    def __init__(self, scene: Scene, task: Task) -> None:
        self._scene: Scene = scene
        self._task = task

    # ------------------------------------------------------------------ the world
    @property
    def nearest_mover_m(self) -> float:
        """Distance (m) between the robot's outline and the nearest mover now (``inf`` without movers)."""
        return self._scene.nearest_mover() if self._scene.dynamic else float("inf")

    # ------------------------------------------------------------------ the robot
    @property
    def robot_body(self) -> int:
        """The robot's PyBullet body id in :attr:`client` (for drawing and benchmarks: queries
        only; moving the body would change the episode)."""
        return self._scene.robot.body

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

    # ------------------------------------------------------------------ time
    @property
    def steps(self) -> int:
        """Env steps since the last reset."""
        return self._scene.clock.tick // self._scene.clock.control_ticks


def make_simulation(config: EnvConfig, gui: bool = False) -> Simulation | KinematicSimulation:
    """The simulation ``config.physics.backend`` names: PyBullet's, or the kinematic one.

    Raises:
        ConfigError: the GUI asked of the kinematic profile (one line naming the profile that has it).
    """
    if config.physics.backend == "kinematic":
        if gui:
            raise ConfigError("physics='kinematic' has no GUI (render_mode='human', view): use physics='default'")
        return KinematicSimulation(config.physics, config.robot)
    return Simulation(config.physics, config.robot, gui=gui)


def convex_hull(points: list[tuple[float, float]]) -> list[tuple[float, float]]:
    """Counter-clockwise convex hull (Andrew's monotone chain)."""
    pts = sorted(set(points))
    if len(pts) <= 2:
        return pts

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])

    lower: list[tuple[float, float]] = []
    for q in pts:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], q) <= 0:
            lower.pop()
        lower.append(q)
    upper: list[tuple[float, float]] = []
    for q in reversed(pts):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], q) <= 0:
            upper.pop()
        upper.append(q)
    return lower[:-1] + upper[:-1]
