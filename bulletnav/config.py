"""Frozen configuration dataclasses for every part of the simulation.

Each field carries a one-line docstring with its unit. Configs are immutable;
derive a variant with :func:`dataclasses.replace`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from importlib import resources
from pathlib import Path
from types import MappingProxyType
from typing import Any

from bulletnav import limits


def asset_path(*parts: str) -> Path:
    """Absolute path of a file shipped in ``bulletnav/assets``."""
    return Path(str(resources.files("bulletnav").joinpath("assets", *parts)))


PHYSICS_BACKENDS = ("bullet", "kinematic")
"""The simulations a scene can run on (``PhysicsConfig.backend``)."""


@dataclass(frozen=True)
class PhysicsConfig:
    """Physics engine rate and solver settings."""

    physics_hz: int = 240
    """Physics steps per simulated second (Hz)."""
    control_hz: int = 24
    """Control (agent action) steps per simulated second (Hz); must divide ``physics_hz``."""
    solver_iterations: int = 10
    """Constraint-solver iterations per physics step (PyBullet ``numSolverIterations``; its default is 50)."""
    solver_residual_threshold: float = 1e-7
    """The solver stops early once the residual falls below this (PyBullet ``solverResidualThreshold``)."""
    cone_friction: bool = True
    """Implicit friction cone (True, PyBullet's default) or the cheaper pyramid approximation."""
    gravity: float = 9.81
    """Magnitude of gravity (m/s^2), pointing down -z."""
    backend: str = "bullet"
    """What simulates the scene: ``"bullet"`` (PyBullet) or ``"kinematic"`` (no physics engine:
    the robot follows its commands through its motors' limits, the lidar and contacts are
    closed-form against the world's shapes; :mod:`bulletnav.sim.kinematic`). The kinematic
    backend uses ``physics_hz`` as its integration rate and ignores the solver settings."""

    def __post_init__(self) -> None:
        if self.backend not in PHYSICS_BACKENDS:
            raise ValueError(f"physics backend must be one of {', '.join(PHYSICS_BACKENDS)}, got {self.backend!r}")
        if self.physics_hz <= 0 or self.control_hz <= 0:
            raise ValueError(
                f"physics_hz and control_hz must be positive, got {self.physics_hz} and {self.control_hz}"
            )
        if self.physics_hz % self.control_hz:
            raise ValueError(
                f"control_hz={self.control_hz} must divide physics_hz={self.physics_hz} exactly"
            )
        if self.solver_iterations < 1:
            raise ValueError(f"solver_iterations must be >= 1, got {self.solver_iterations}")

    @property
    def substeps(self) -> int:
        """Physics steps per control step."""
        return self.physics_hz // self.control_hz

    @property
    def control_dt(self) -> float:
        """Seconds between control steps."""
        return 1.0 / self.control_hz

    @property
    def physics_dt(self) -> float:
        """Seconds per physics step."""
        return 1.0 / self.physics_hz


PHYSICS_PROFILES: MappingProxyType[str, PhysicsConfig] = MappingProxyType({
    "default": PhysicsConfig(),
    "fast": PhysicsConfig(physics_hz=96),
    "kinematic": PhysicsConfig(backend="kinematic"),
})
"""Named physics settings, chosen with the env keyword ``physics`` (``--physics`` on the CLI).

``"default"``: 240 Hz physics, 10 substeps per 24 Hz control step (every published result).
``"fast"``: 96 Hz physics, 4 substeps per control step, solver otherwise unchanged: the
lowest rate of ``bulletnav bench physics`` (240 / 120 / 96 / 48 Hz) whose driving stays within
1 % of 240 Hz and on which the shipped PPO stays within 2 points of its 240 Hz success and
collision rates; 48 Hz misses the driving bound (docs/performance/physics.md has the table).
``"kinematic"``: no physics engine (:mod:`bulletnav.sim.kinematic`): the robot's wheels follow
the command at the accelerations its URDF's masses and motor torque allow, integrated at 240 Hz,
never slipping; lidar and contacts closed-form against the world's boxes and cylinders; no
camera and no GUI (docs/env.md)."""


def physics_profile(name: str) -> PhysicsConfig:
    """The :data:`PHYSICS_PROFILES` entry called ``name``.

    Raises:
        ValueError: an unknown name (the message names it and the known ones).
    """
    try:
        return PHYSICS_PROFILES[name]
    except (KeyError, TypeError):
        raise ValueError(f"unknown physics profile {name!r}; known: {', '.join(PHYSICS_PROFILES)}") from None


@dataclass(frozen=True)
class RobotConfig:
    """The differential-drive robot. Geometry (wheel radius, wheelbase) is read from the URDF."""

    urdf: str = ""
    """Path of the robot URDF; empty means the shipped ``assets/diff_drive.urdf``."""
    max_wheel_torque: float = 0.15
    """Velocity-motor torque limit per wheel (N*m): 2.6 m/s^2 peak acceleration, below wheel slip and tipping."""
    wheel_friction: float = 1.0
    """Coulomb friction coefficient between the wheels and the floor."""
    caster_friction: float = 0.0
    """Friction of the passive caster ball; 0 models a free-rolling ball caster."""
    park_brake_rate: float = 0.25
    """Parking brake: on a command of exactly (0, 0), once both wheels turn slower than this
    (rad/s), the motors hold the wheels at their angles and the wheel contacts keep friction
    anchors, until the next non-zero command. PyBullet's velocity motors and sliding contacts
    let a robot told to stand still creep ~0.3 mm/s for as long as it stands (15 mm a minute
    after a turn); braked, it settles within seconds. 0 turns the brake off."""
    footprint_radius: float = 0.2
    """Disc radius (m) standing for the robot in start/goal sampling, reachability, planning
    inflation and the evaluation's shortest path: the outline's farthest corner (0.18 m for
    the shipped URDF) plus 2 cm. Must be at least the outline's (checked at load)."""
    wheel_accel: float | None = None
    """How fast its wheels' rim speeds follow a command (m/s^2), as measured on the robot: the
    safety shield then also checks each command the wheels cannot reach within one control
    period along the sweep they can follow (``ShieldConfig.wheel_accel``). None: not used (the
    article robot, whose shielded results were measured without it)."""

    def __post_init__(self) -> None:
        if not (self.park_brake_rate >= 0.0):
            raise ValueError(f"RobotConfig.park_brake_rate must be >= 0 rad/s, got {self.park_brake_rate}")

    def urdf_path(self) -> Path:
        return Path(self.urdf) if self.urdf else asset_path("diff_drive.urdf")


@dataclass(frozen=True)
class AislesConfig:
    """Aisle warehouses (``WorldConfig.style="aisles"``, :func:`bulletnav.sim.aisles.generate_aisles`):
    parallel rack rows with aisles between them, cross aisles, dead ends, clutter and columns."""

    row_axis: str = "random"
    """Direction the rack rows run along: 'x', 'y', or 'random' (one draw per layout)."""
    rack_depth: tuple[float, float] = (0.8, 1.2)
    """Range of one rack's depth across its row (m); a double row is two racks back to back."""
    rack_length: tuple[float, float] = (4.0, 10.0)
    """Range of one rack's length along its row (m); a longer row is several racks end to end."""
    rack_height: float = 2.0
    """Height of every rack (m)."""
    aisle_width: tuple[float, float] = (1.0, 2.5)
    """Range of the width of an aisle between two rows, or between a row and a side wall (m)."""
    cross_aisle_width: tuple[float, float] = (1.5, 2.5)
    """Range of the width of a cross aisle, and of an open end aisle along an end wall (m)."""
    max_cross_aisles: int = 1
    """Most cross aisles cutting the rows (always at least one; fewer where racks would get too short)."""
    double_row_prob: float = 0.6
    """Chance that a row between two aisles is a back-to-back double row rather than a single rack."""
    wall_row_prob: float = 0.4
    """Chance, for each side wall, that a single row stands against it instead of an aisle running beside it."""
    end_weights: tuple[float, float, float] = (0.2, 0.4, 0.4)
    """Relative chances, for each end wall, of an open end aisle, rows running into the wall, and a rack
    row along the wall that the rows run into (the last two dead-end every aisle on that side)."""
    pallet_stack_prob: float = 0.4
    """Chance that an aisle segment open at both ends gets one end closed by a pallet stack
    (at least one aisle is always dead-ended)."""
    clutter_per_metre: float = 0.15
    """Mean number of pallets and boxes per metre of aisle segment, standing against a rack face or a wall."""
    pallet_share: float = 0.5
    """Share of that clutter that is loaded pallets (1.2 x 0.8 m); the rest are boxes (0.3-0.7 m)."""
    min_passage: float = 0.8
    """Narrowest free width (m) an aisle keeps beside its pallets and boxes (the robot's disc is 0.4 m)."""
    columns: tuple[int, int] = (2, 6)
    """Range of the number of building columns, standing at row ends in cross and end aisles."""

    def __post_init__(self) -> None:
        if self.row_axis not in ("x", "y", "random"):
            raise ValueError(f"aisles row_axis must be 'x', 'y' or 'random', got {self.row_axis!r}")
        for name in ("rack_depth", "rack_length", "aisle_width", "cross_aisle_width", "columns"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"aisles {name} must be a range (lo, hi) with 0 <= lo <= hi, got {(lo, hi)}")
        if self.rack_length[1] < 2 * self.rack_length[0]:
            raise ValueError(f"aisles rack_length needs hi >= 2 lo so that any row length can be split, got {self.rack_length}")
        if self.rack_depth[0] <= 0 or self.aisle_width[0] <= 0 or self.cross_aisle_width[0] <= 0:
            raise ValueError("aisles rack_depth, aisle_width and cross_aisle_width must be positive")
        if self.max_cross_aisles < 1:
            raise ValueError(f"aisles max_cross_aisles must be >= 1, got {self.max_cross_aisles}")
        if len(self.end_weights) != 3 or min(self.end_weights) < 0 or sum(self.end_weights) <= 0:
            raise ValueError(f"aisles end_weights must be 3 non-negative weights, not all 0, got {self.end_weights}")


@dataclass(frozen=True)
class WorldConfig:
    """Procedural warehouse generation (ignored for the obstacles of a YAML layout)."""

    style: str = "scattered"
    """Registered world generator (``bulletnav.sim.generators.WORLDS``) that draws each layout."""
    size: tuple[float, float] = (14.0, 14.0)
    """Floor extent along x and y (m), centred on the origin; walls enclose it."""
    num_obstacles: int = 31
    """Obstacles (racks, columns, pallets, boxes) placed in a procedural layout; walls excluded."""
    wall_height: float = 2.0
    """Height of the enclosing walls (m)."""
    min_gap: float = 0.6
    """Minimum free gap between any two obstacle footprints, and between obstacles and walls (m)."""
    max_placement_tries: int = 4000
    """Rejection-sampling attempts before a procedural layout gives up on an obstacle."""
    aisles: AislesConfig = field(default_factory=AislesConfig)
    """Parameters of the ``"aisles"`` style (other styles ignore them)."""

    def __post_init__(self) -> None:
        if self.num_obstacles < 0:
            raise ValueError(f"num_obstacles must be >= 0, got {self.num_obstacles}")
        if min(self.size) <= 2.0:
            raise ValueError(f"size must exceed 2 m on both axes, got {self.size}")
        for axis, side in zip("xy", self.size):
            limits.check("world_size", side, f"world size ({axis})")
        limits.check("obstacles", self.num_obstacles, "world num_obstacles")


@dataclass(frozen=True)
class SamplerConfig:
    """Start/goal sampling in free space."""

    min_goal_distance: float = 2.0
    """Smallest straight-line start-goal distance (m)."""
    max_goal_distance: float = 6.0
    """Largest straight-line start-goal distance (m)."""
    clearance: float = 0.4
    """Minimum distance from the start or goal point to any obstacle or wall (m)."""
    grid_resolution: float = 0.1
    """Cell size of the coarse free-space grid used for clearance and reachability (m); the
    robot's disc for the reachability check is ``RobotConfig.footprint_radius``."""
    max_tries: int = 200
    """Goal draws per start before the sampler gives up."""
    min_detour: float = 1.0
    """Planning episodes need a shortest path at least this many times the straight start-goal
    distance; 1.0 turns the test off. The path is measured on the free-space grid: Dijkstra over
    the 8-connected cells passable for the robot's disc, in octile length (diagonal steps
    sqrt(2) cells), which exceeds the true shortest path by at most 8 %."""
    blocked_by: tuple[str, ...] = ()
    """Planning episodes need the straight start-goal segment to cross the footprint of an
    obstacle with one of these labels (e.g. ``("rack",)``); empty turns the test off."""
    detour_share: float = 1.0
    """Share of episodes drawn as planning episodes when ``min_detour`` > 1 or ``blocked_by`` is set
    (one extra uniform draw per episode when below 1); the others are sampled as without them."""

    def __post_init__(self) -> None:
        if not 0.0 <= self.min_goal_distance <= self.max_goal_distance:
            raise ValueError(
                "need 0 <= min_goal_distance <= max_goal_distance, got "
                f"min_goal_distance={self.min_goal_distance} and max_goal_distance={self.max_goal_distance}"
            )
        if self.min_detour < 1.0:
            raise ValueError(f"min_detour must be >= 1, got {self.min_detour}")
        if not 0.0 <= self.detour_share <= 1.0:
            raise ValueError(f"detour_share must be in [0, 1], got {self.detour_share}")


LIDAR_CASTERS = ("bullet", "exact")
"""The lidar's ray casters (:attr:`LidarConfig.caster`)."""


@dataclass(frozen=True)
class LidarConfig:
    """2-D scanning lidar cast with ``rayTestBatch`` from the lidar link."""

    enabled: bool = True
    """Build the sensor; the task's observation needs it."""
    rate_hz: float | None = None
    """New scans per simulated second; None (or the control rate) scans every control step.
    Between scans ``read`` returns the last one (a real lidar's scan period)."""
    num_rays: int = 36
    """Rays per scan, evenly spaced over ``fov``."""
    fov: float = 360.0
    """Angular field of view (degrees), centred on the robot heading."""
    max_range: float = 5.0
    """Maximum range (m); rays that hit nothing read this value."""
    min_range: float = 0.0
    """Minimum range (m) the sensor can report."""
    noise_std: float = 0.0
    """Standard deviation of additive Gaussian range noise (m); 0 disables noise."""
    caster: str = "bullet"
    """How rays are cast: ``"bullet"``, PyBullet's ``rayTestBatch`` against every static body;
    ``"exact"``, closed-form intersections with the world's boxes, cylinders and floor
    (:mod:`bulletnav.sensors.raycast`), for static worlds only (no movers, no events, no fleet).
    PyBullet's hits on a cylinder lie up to about 2 mm outside its surface (a grazing ray can read
    metres short); exact is the true geometry and, in a BARN world, several times faster
    (``bulletnav bench env --env bulletnav/BARN-v0`` times both)."""

    def __post_init__(self) -> None:
        _check_rate("lidar", self.rate_hz)
        if self.caster not in LIDAR_CASTERS:
            raise ValueError(f"lidar caster must be one of {', '.join(LIDAR_CASTERS)}, got {self.caster!r}")
        if self.num_rays < 1:
            raise ValueError(f"lidar num_rays must be >= 1, got {self.num_rays}")
        limits.check("lidar_rays", self.num_rays, "lidar num_rays")
        if not 0.0 <= self.min_range < self.max_range:
            raise ValueError(f"need 0 <= lidar min_range < max_range, got {self.min_range}, {self.max_range}")
        if self.noise_std < 0:
            raise ValueError(f"lidar noise_std must be >= 0, got {self.noise_std}")


@dataclass(frozen=True)
class CameraConfig:
    """RGB-D + segmentation camera on the camera mount link, rendered with TinyRenderer.

    Rendering costs ~10 ms a frame, so the camera renders only when read: never in training
    unless ``camera_obs`` puts it in the observation."""

    enabled: bool = True
    """Build the sensor (videos, the dashboard and ``camera_obs`` read it)."""
    rate_hz: float | None = None
    """New frames per simulated second; None renders on every control step it is read."""
    width: int = 320
    """Image width (pixels)."""
    height: int = 240
    """Image height (pixels)."""
    fov: float = 60.0
    """Vertical field of view (degrees)."""
    near: float = 0.05
    """Near clipping plane (m)."""
    far: float = 20.0
    """Far clipping plane (m); depth saturates here."""
    pitch: float = -10.0
    """Optical-axis pitch relative to the mount (degrees, negative looks down)."""

    def __post_init__(self) -> None:
        _check_rate("camera", self.rate_hz)
        if self.width < 1 or self.height < 1:
            raise ValueError(f"camera size must be positive, got {self.width}x{self.height}")
        limits.check("camera_width", self.width, "camera width")
        limits.check("camera_height", self.height, "camera height")
        limits.check("camera_pixels", self.width * self.height, f"camera pixels ({self.width} x {self.height})")
        if not 0.0 < self.near < self.far:
            raise ValueError(f"need 0 < camera near < far, got {self.near}, {self.far}")


@dataclass(frozen=True)
class ImuConfig:
    """Accelerometer and gyroscope on the robot body."""

    enabled: bool = True
    """Build the sensor; the task's observation needs it."""
    rate_hz: float | None = None
    """Readings per simulated second; None (or the control rate) gives a new one every control step."""
    accel_noise_std: float = 0.05
    """Accelerometer white-noise standard deviation (m/s^2)."""
    gyro_noise_std: float = 0.01
    """Gyroscope white-noise standard deviation (rad/s)."""
    accel_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Constant accelerometer bias in the body frame (m/s^2)."""
    gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Constant gyroscope bias in the body frame (rad/s)."""

    def __post_init__(self) -> None:
        _check_rate("imu", self.rate_hz)
        if self.accel_noise_std < 0 or self.gyro_noise_std < 0:
            raise ValueError("IMU noise standard deviations must be >= 0")


@dataclass(frozen=True)
class OdometryConfig:
    """Wheel odometry."""

    enabled: bool = True
    """Build the sensor; the task's observation needs it."""
    rate_hz: float | None = None
    """Readings per simulated second; None (or the control rate) gives a new one every control
    step. The pose is integrated every control step whatever the rate."""
    encoder_noise_std: float = 0.0
    """Gaussian noise on each wheel's angle increment per control step (rad); 0 = ideal encoders."""

    def __post_init__(self) -> None:
        _check_rate("odometry", self.rate_hz)
        if self.encoder_noise_std < 0:
            raise ValueError(f"odometry encoder_noise_std must be >= 0, got {self.encoder_noise_std}")


def _check_rate(sensor: str, rate_hz: float | None) -> None:
    if rate_hz is not None and not rate_hz > 0:
        raise ValueError(f"{sensor} rate_hz must be > 0 or None, got {rate_hz}")


@dataclass(frozen=True)
class SensorsConfig:
    """Which sensors the robot carries and how each is set up."""

    lidar: LidarConfig = field(default_factory=LidarConfig)
    camera: CameraConfig = field(default_factory=CameraConfig)
    imu: ImuConfig = field(default_factory=ImuConfig)
    odometry: OdometryConfig = field(default_factory=OdometryConfig)


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the named reward terms (the article's values)."""

    progress: float = 1.0
    """Per metre of distance to the goal gained this step."""
    goal: float = 50.0
    """Once, when the goal is reached."""
    collision: float = -10.0
    """Once, on contact with a wall or obstacle."""
    time: float = -0.01
    """Every step."""
    heading: float = 0.1
    """Times (1 - |heading error| / pi) while farther than ``heading_distance`` from the goal."""
    heading_distance: float = 1.0
    """Heading and stuck terms apply only beyond this distance to the goal (m)."""
    stuck: float = -0.1
    """Every step while progress over the last ``stuck_window`` steps is under ``stuck_progress``."""
    stuck_window: int = 20
    """Steps over which progress is summed for the stuck test."""
    stuck_progress: float = 0.1
    """Progress (m) below which the robot counts as stuck."""
    proximity: float = -1.0
    """Times (proximity_distance - closest lidar range) while the closest range is under it."""
    proximity_distance: float = 0.3
    """Lidar range (m) under which the proximity penalty applies."""
    mover_proximity: float = 0.0
    """Times (mover_proximity_distance - gap) while the gap between the robot's outline and
    the nearest mover (``info["nearest_mover_m"]``, exact) is under it. 0 (default): the term
    is not computed and not listed (``reward_mover_proximity`` appears only when it is set).
    The gap is ground truth the policy does not observe: a training signal, like ``collision``."""
    mover_proximity_distance: float = 0.3
    """Outline-to-mover gap (m) under which the mover proximity penalty applies."""
    subgoal: float = 10.0
    """Missions (``task_name="mission"``): once per goal reached before the last (the last one
    earns ``goal``)."""


@dataclass(frozen=True)
class TaskConfig:
    """Episode rules and observation scaling."""

    goal_radius: float = 0.5
    """Distance to the goal (m) under which the episode terminates with success."""
    max_speed: float = 0.5
    """Top forward speed (m/s): action bound and velocity normalisation."""
    min_speed: float = 0.0
    """Lowest speed (m/s) an action may command: 0 (the default) drives forward only; a negative
    value lets the robot back up at down to that speed (move_base's ``escape_vel``). It moves the
    action space's lower bound of v and nothing else: the observation still divides v by
    ``max_speed``."""
    max_turn_rate: float = 1.5
    """Top yaw rate (rad/s): action bound and normalisation."""
    distance_scale: float = 10.0
    """Distance to the goal is divided by this in the observation (m)."""
    pose_source: str = "truth"
    """Where the robot's pose for heading/distance observations comes from: 'truth' or 'odometry'."""
    goals: int = 1
    """Missions (``task_name="mission"``): goal points per episode, 1-8."""
    goal_order: str = "free"
    """Missions: ``"fixed"`` (visit in the given order) or ``"free"`` (any order)."""
    steps_per_goal: int = 1200
    """Missions: the episode is truncated after this many control steps per goal."""
    min_goal_separation: float = 1.5
    """Missions: sampled goals keep at least this distance (m) from each other and the start."""
    lidar_history: int = 1
    """Scans in the observation: the current one, then the k - 1 before it, newest first
    (appended after the 7 scalars, each scaled like the current scan); 1 = today's vector."""
    guidance: str = "none"
    """``"floorplan"``: the observation adds the path cost to the target and the bearing of a
    point 0.8 m along the shortest clear path on the static floor plan, and the progress term is
    measured along that path (:mod:`bulletnav.tasks.guidance`); ``"none"``: neither."""
    collision_terminates: bool = False
    """A collision ends the episode as terminated (a real end, what learners should see)
    instead of truncated (the article's rule, ``Warehouse-v0``)."""
    reward: RewardConfig = field(default_factory=RewardConfig)

    def __post_init__(self) -> None:
        if self.pose_source not in ("truth", "odometry"):
            raise ValueError(f"pose_source must be 'truth' or 'odometry', got {self.pose_source!r}")
        if not (isinstance(self.goals, int) and not isinstance(self.goals, bool) and self.goals >= 1):
            raise ValueError(f"goals must be an integer >= 1, got {self.goals!r}")
        limits.check("goals", self.goals, "task goals")
        if self.goal_order not in ("fixed", "free"):
            raise ValueError(f"goal_order must be 'fixed' or 'free', got {self.goal_order!r}")
        if self.steps_per_goal < 1:
            raise ValueError(f"steps_per_goal must be >= 1, got {self.steps_per_goal}")
        limits.check("episode_steps", self.steps_per_goal * self.goals,
                     f"task steps_per_goal x goals ({self.steps_per_goal} x {self.goals})")
        if not (isinstance(self.lidar_history, int) and self.lidar_history >= 1):
            raise ValueError(f"lidar_history must be an integer >= 1, got {self.lidar_history!r}")
        if self.guidance not in ("none", "floorplan"):
            raise ValueError(f"guidance must be 'none' or 'floorplan', got {self.guidance!r}")
        if self.goal_radius <= 0:
            raise ValueError(f"goal_radius must be > 0, got {self.goal_radius}")
        if not (math.isfinite(self.min_speed) and self.min_speed <= 0.0):
            raise ValueError(f"min_speed must be a finite number <= 0 m/s, got {self.min_speed!r}")


@dataclass(frozen=True)
class DynamicConfig:
    """Procedural moving obstacles and events, drawn for every episode (``bulletnav.sim.dynamic``).

    Counts are inclusive ranges drawn uniformly per episode; all zero (the default) keeps an
    env static. A YAML layout's own ``dynamic:`` and ``events:`` sections always apply.
    """

    forklifts: tuple[int, int] = (0, 0)
    """Forklifts per episode (min, max)."""
    forklift_speed: tuple[float, float] = (0.3, 1.0)
    """Forklift cruise speed range (m/s)."""
    forklift_size: tuple[float, float, float] = (1.1, 0.8, 2.0)
    """Forklift box: length, width, height (m)."""
    workers: tuple[int, int] = (0, 0)
    """Workers per episode (min, max)."""
    worker_speed: tuple[float, float] = (0.5, 1.4)
    """Walking speed range (m/s)."""
    worker_pause: tuple[float, float] = (0.5, 3.0)
    """Pause at each waypoint (s)."""
    worker_radius: float = 0.25
    """Worker cylinder radius (m); 1.7 m tall."""
    pallet_events_per_min: float = 0.0
    """Rate of drawn pallet events (appear or vanish), per simulated minute."""
    event_pallets: int = 4
    """Pallets in the event pool (at most this many appear at once)."""
    yield_to_robot: bool = True
    """Movers stop for the robot (forklift safety field, worker stop distance)."""
    keep_clear: float = 2.0
    """No mover starts within this distance (m) of the robot's start or a goal."""
    near: float = 0.5
    """Movers within this gap (m) of the robot are moved at every physics step (the rest once
    per control step, before the sensors read); robot and mover close at most 1.9 m/s, 8 cm
    a control step."""

    def __post_init__(self) -> None:
        for name in ("forklifts", "workers"):
            lo, hi = getattr(self, name)
            if not 0 <= lo <= hi:
                raise ValueError(f"dynamic.{name} must be (min, max) with 0 <= min <= max, got {(lo, hi)}")
        for name in ("forklift_speed", "worker_speed"):
            lo, hi = getattr(self, name)
            if not 0 < lo <= hi:
                raise ValueError(f"dynamic.{name} must be (min, max) m/s with 0 < min <= max, got {(lo, hi)}")
        if self.pallet_events_per_min < 0:
            raise ValueError(f"dynamic.pallet_events_per_min must be >= 0, got {self.pallet_events_per_min}")
        limits.check("movers", self.forklifts[1] + self.workers[1],
                     f"dynamic forklifts + workers ({self.forklifts[1]} + {self.workers[1]})")
        limits.check("event_rate", self.pallet_events_per_min, "dynamic pallet_events_per_min")
        limits.check("events", self.event_pallets, "dynamic event_pallets")

    @property
    def active(self) -> bool:
        """True when episodes draw movers or events."""
        return self.forklifts[1] > 0 or self.workers[1] > 0 or self.pallet_events_per_min > 0


@dataclass(frozen=True)
class ShiftConfig:
    """Departures of the robot, the floor and the sensors from their nominal models, applied at
    every reset. Named evaluation shifts fix them (:data:`bulletnav.envs.shifts.PERTURBATIONS`);
    the defaults change nothing, and an env whose shift is the default never touches them.

    PyBullet combines the friction of two touching bodies as the product of their coefficients,
    so the wheel-floor friction is ``RobotConfig.wheel_friction * wheel_friction_scale *
    floor_friction``.
    """

    floor_friction: float = 1.0
    """The floor's lateral friction coefficient (nominal 1.0)."""
    wheel_friction_scale: float = 1.0
    """Multiplies the wheels' lateral friction coefficient."""
    mass_scale: float = 1.0
    """Multiplies the robot body's mass and its inertia (the wheels keep theirs)."""
    motor_force_scale: float = 1.0
    """Multiplies the wheel motors' torque limit."""
    odometry_wheel_radius_scale: float = 1.0
    """The odometry model's wheel radius over the true one (a miscalibrated encoder model)."""
    odometry_wheelbase_scale: float = 1.0
    """The odometry model's wheelbase over the true one."""
    action_latency: int = 0
    """Control steps between an action and the motors receiving it (0-2 typical); the motors
    hold a stop command for the first ``action_latency`` steps of an episode."""
    lidar_noise_std: float = 0.0
    """Extra Gaussian range noise (m), independent of ``LidarConfig.noise_std``."""
    lidar_dropout: float = 0.0
    """Probability that a ray returns nothing (reads ``max_range``), per ray and scan."""
    imu_noise_scale: float = 1.0
    """Multiplies the IMU's white-noise standard deviations."""
    imu_accel_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Added to the accelerometer's constant bias (m/s^2, body frame)."""
    imu_gyro_bias: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Added to the gyroscope's constant bias (rad/s, body frame)."""
    depth_noise_std: float = 0.0
    """Gaussian noise on the camera's depth image (m), clipped to [near, far]."""
    mover_speed_scale: float = 1.0
    """Multiplies every mover's cruise or walking speed (procedural and YAML movers)."""

    def __post_init__(self) -> None:
        for name in ("floor_friction", "wheel_friction_scale", "mass_scale", "motor_force_scale",
                     "odometry_wheel_radius_scale", "odometry_wheelbase_scale", "imu_noise_scale", "mover_speed_scale"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                raise ValueError(f"shift {name} must be a finite number > 0, got {value!r}")
        if not (isinstance(self.action_latency, int) and 0 <= self.action_latency <= 10):
            raise ValueError(f"shift action_latency must be an integer from 0 to 10 control steps, got {self.action_latency!r}")
        for name in ("lidar_noise_std", "depth_noise_std"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"shift {name} must be >= 0, got {getattr(self, name)!r}")
        if not 0.0 <= self.lidar_dropout < 1.0:
            raise ValueError(f"shift lidar_dropout must be in [0, 1), got {self.lidar_dropout!r}")
        for name in ("imu_accel_bias", "imu_gyro_bias"):
            if len(getattr(self, name)) != 3:
                raise ValueError(f"shift {name} must have 3 entries (x, y, z), got {getattr(self, name)!r}")

    @property
    def nominal(self) -> bool:
        """True when this shift changes nothing."""
        return self == ShiftConfig()


@dataclass(frozen=True)
class EnvConfig:
    """Everything that defines a ``bulletnav/Warehouse-v0`` episode."""

    task_name: str = "navigation"
    """Registered task (``bulletnav.tasks.TASKS``) that gives observation, reward and episode end."""
    physics: PhysicsConfig = field(default_factory=PhysicsConfig)
    robot: RobotConfig = field(default_factory=RobotConfig)
    world: WorldConfig = field(default_factory=WorldConfig)
    sampler: SamplerConfig = field(default_factory=SamplerConfig)
    sensors: SensorsConfig = field(default_factory=SensorsConfig)
    task: TaskConfig = field(default_factory=TaskConfig)
    dynamic: DynamicConfig = field(default_factory=DynamicConfig)
    shift: ShiftConfig = field(default_factory=ShiftConfig)
    randomize: tuple[Any, ...] = ()
    """Domain randomization: :class:`bulletnav.envs.randomization.Distribution` per parameter,
    drawn every episode (the env kwarg ``randomize`` parses a mapping into these); empty: none."""
    layout_file: str | None = None
    """YAML layout to use for every episode; None draws procedural warehouses."""
    layouts_every: int = 1
    """A procedural layout is redrawn every this many resets (always on a seeded reset)."""
    camera_obs: bool = False
    """Add the camera's RGB and depth images to the observation (Dict space; ~10 ms a frame)."""
    normalize_actions: bool = False
    """Expose actions as Box(-1, 1, (2,)) mapped onto (v, w) instead of physical units."""

    def __post_init__(self) -> None:
        if self.layouts_every < 1:
            raise ValueError(f"layouts_every must be >= 1, got {self.layouts_every}")


JACKAL = "jackal"
"""The Clearpath Jackal-sized robot of :func:`robot_preset` (``robot="jackal"``)."""
ROBOTS = ("article", JACKAL)
"""Robot names the env keyword ``robot`` takes: ``"article"`` (the shipped default) or ``"jackal"``."""


def robot_preset(config: EnvConfig, name: str) -> EnvConfig:
    """``config`` with the robot ``name`` (:data:`ROBOTS`): its URDF, motors and footprint, its
    top speed and turn rate (the action bounds) and its lidar. ``"article"`` leaves ``config`` as it is.

    ``"jackal"`` (numbers from Clearpath's github.com/jackal/jackal, commit c6ab6ca):
    ``assets/jackal.urdf`` (0.508 x 0.430 m outline, track 0.37559 m, wheels 0.098 m; its comment
    says how the four skid-steered wheels become two and two casters), 2.0 m/s and 4.0 rad/s
    (``jackal_control/config/control.yaml``), and the Hokuyo UST-10 BARN's Jackal carries
    (``hokuyo_ust10.urdf.xacro``): 270 degrees, 0.1-30 m, Gaussian noise 1 mm, cast as
    :data:`JACKAL_LIDAR_RAYS` (72) rays spread evenly over the 270 degrees (every 3.8 degrees; the
    UST-10 has 720, every 0.38 degrees), which is the scan the policy sees. ``lidar_rays=720``
    gives the full scan. The preset keeps ``config``'s lidar caster (BARN-v0 sets ``"exact"``).

    Raises:
        ValueError: an unknown name (the message names it and the known ones).
    """
    if name == "article":
        return config
    if name != JACKAL:
        raise ValueError(f"unknown robot {name!r}; known: {', '.join(ROBOTS)}")
    robot = RobotConfig(urdf=str(asset_path("jackal.urdf")), max_wheel_torque=JACKAL_WHEEL_TORQUE,
                        footprint_radius=0.35, wheel_accel=JACKAL_WHEEL_ACCEL)
    lidar = LidarConfig(num_rays=JACKAL_LIDAR_RAYS, fov=270.0, max_range=30.0, min_range=0.1, noise_std=0.001,
                        rate_hz=config.sensors.lidar.rate_hz, enabled=config.sensors.lidar.enabled,
                        caster=config.sensors.lidar.caster)
    return replace(config, robot=robot, task=replace(config.task, max_speed=2.0, max_turn_rate=4.0),
                   sensors=replace(config.sensors, lidar=lidar))


JACKAL_LIDAR_RAYS = 72
"""Rays of the Jackal's lidar scan by default (over its 270 degrees); the UST-10 itself has 720."""
JACKAL_WHEEL_ACCEL = 3.5
"""The Jackal's rim acceleration (m/s^2) at :data:`JACKAL_WHEEL_TORQUE` (measured there). A
command to turn at 3 rad/s while speeding up from 1 to 2 m/s waits three control periods for its
first yaw: the wheels' torque goes into the speed first."""
JACKAL_WHEEL_TORQUE = 3.0
"""Motor torque limit per wheel of the Jackal (N*m): about 3.5 m/s^2 from rest to its 2.0 m/s in
0.7 s, straight (yaw within 0.002 rad over 4 m and a full stop). Clearpath's controller allows
20 m/s^2 (``control.yaml``); two wheels with friction 1 cannot put that on the floor, and at
6 N*m the wheels slip when braking and the robot turns 0.02 rad."""
