"""``bulletnav/Warehouse-v0``: drive a differential-drive robot to a goal through a warehouse."""

from __future__ import annotations

import math
import numbers
import time
from dataclasses import fields, replace
from os import PathLike
from types import UnionType
from typing import Any, Union, get_args, get_origin, get_type_hints

import gymnasium as gym
import numpy as np
import pybullet as p
from gymnasium import spaces

from bulletnav.config import EnvConfig, RewardConfig, ShiftConfig, physics_profile, robot_preset
from bulletnav.envs.actions import ActionMap
from bulletnav.envs.randomization import STREAM as DR_STREAM
from bulletnav.envs.randomization import Distribution, draw, draw_world, parse_randomize
from bulletnav.envs.scene import Scene, SceneView
from bulletnav.envs.shifts import describe, perturbation
from bulletnav.errors import ConfigError
from bulletnav.sim.generators import world_generator
from bulletnav.sim.layout import Layout, load_layout
from bulletnav.tasks import make_task
from bulletnav.yamlfile import show

_KWARGS = {
    # keyword -> (config section path, field)
    "num_obstacles": (("world",), "num_obstacles"),
    "world_size": (("world",), "size"),
    "min_goal_distance": (("sampler",), "min_goal_distance"),
    "max_goal_distance": (("sampler",), "max_goal_distance"),
    "lidar_rays": (("sensors", "lidar"), "num_rays"),
    "lidar_range": (("sensors", "lidar"), "max_range"),
    "lidar_noise": (("sensors", "lidar"), "noise_std"),
    "lidar_caster": (("sensors", "lidar"), "caster"),
    "imu_accel_noise": (("sensors", "imu"), "accel_noise_std"),
    "imu_gyro_noise": (("sensors", "imu"), "gyro_noise_std"),
    "odometry_noise": (("sensors", "odometry"), "encoder_noise_std"),
    "physics_hz": (("physics",), "physics_hz"),
    "control_hz": (("physics",), "control_hz"),
    "solver_iterations": (("physics",), "solver_iterations"),
    "goal_radius": (("task",), "goal_radius"),
    "min_speed": (("task",), "min_speed"),
    "pose_source": (("task",), "pose_source"),
    "collision_terminates": (("task",), "collision_terminates"),
    "layout_style": (("world",), "style"),
    "lidar_rate_hz": (("sensors", "lidar"), "rate_hz"),
    "camera_enabled": (("sensors", "camera"), "enabled"),
    "task_name": ((), "task_name"),
    "layouts_every": ((), "layouts_every"),
    "camera_obs": ((), "camera_obs"),
    "normalize_actions": ((), "normalize_actions"),
    "min_detour": (("sampler",), "min_detour"),
    "blocked_by": (("sampler",), "blocked_by"),
    "detour_share": (("sampler",), "detour_share"),
    "aisles": (("world",), "aisles"),
    "lidar_history": (("task",), "lidar_history"),
    "guidance": (("task",), "guidance"),
    "goals": (("task",), "goals"),
    "goal_order": (("task",), "goal_order"),
    "steps_per_goal": (("task",), "steps_per_goal"),
    "forklifts": (("dynamic",), "forklifts"),
    "workers": (("dynamic",), "workers"),
    "forklift_speed": (("dynamic",), "forklift_speed"),
    "worker_speed": (("dynamic",), "worker_speed"),
    "pallet_events_per_min": (("dynamic",), "pallet_events_per_min"),
    "yield_to_robot": (("dynamic",), "yield_to_robot"),
}
_REWARD_FIELDS = {f.name for f in fields(RewardConfig)}
STAGE_KWARGS = frozenset({
    "num_obstacles", "world_size", "layout_style", "aisles", "min_goal_distance", "max_goal_distance", "min_detour",
    "blocked_by", "detour_share", "forklifts", "workers", "forklift_speed", "worker_speed", "pallet_events_per_min",
    "yield_to_robot", "perturb", "randomize", *(f"shift_{f.name}" for f in fields(ShiftConfig)),
})
"""Keyword arguments :meth:`WarehouseEnv.set_episode_config` accepts: what episodes are drawn
from (world, goals, movers, shifts), never what changes the spaces, the task or the reward."""
_SHIFT_FIELDS = {f.name for f in fields(ShiftConfig)}


def make_config(config: EnvConfig | None = None, **kwargs: Any) -> EnvConfig:
    """Build an :class:`EnvConfig` from flat keyword arguments on top of ``config``.

    Besides the names in the env docstring, ``reward_<field>`` sets a :class:`RewardConfig`
    field (e.g. ``reward_collision=-20``), ``world`` names a YAML layout file and ``physics``
    a named physics profile (:data:`~bulletnav.config.PHYSICS_PROFILES`: ``"default"``,
    ``"fast"``), which replaces the physics section before ``physics_hz`` and the other
    physics keywords apply, and ``robot`` a named robot (:func:`~bulletnav.config.robot_preset`:
    ``"article"``, ``"jackal"``), applied before the other keywords too.

    Raises:
        TypeError: an unknown keyword (the message lists the known ones).
        ValueError: an unknown physics profile name.
    """
    if config is not None and not isinstance(config, EnvConfig):
        raise TypeError(f"bulletnav/Warehouse-v0 keyword 'config' must be an EnvConfig, got {show(config)}")
    cfg = config or EnvConfig()
    if "physics" in kwargs:  # a named profile first, so physics_hz & co. apply on top in any order
        kwargs = dict(kwargs)
        cfg = _apply(cfg, "physics", kwargs.pop("physics"))
    if "robot" in kwargs:  # a named robot first, so lidar_rays & co. apply on top in any order
        kwargs = dict(kwargs)
        cfg = _apply(cfg, "robot", kwargs.pop("robot"))
    for key, value in kwargs.items():
        cfg = _apply(cfg, key, value)
    return cfg


def _apply(cfg: EnvConfig, key: str, value: Any) -> EnvConfig:
    """``cfg`` with keyword ``key`` set; any TypeError or ValueError names the keyword."""
    try:
        return _set(cfg, key, value)
    except (TypeError, ValueError, OverflowError) as exc:  # OverflowError: an int beyond float64 (a ValueError here)
        message = str(exc)
        if f"'{key}'" in message or f"{key}=" in message:
            raise
        kind = ValueError if isinstance(exc, OverflowError) else type(exc)
        try:
            named = kind(f"bulletnav/Warehouse-v0 keyword {key}={show(value)}: {message}")
        except Exception:  # noqa: BLE001  (an exception type with other arguments: keep it as it is)
            raise exc from None
        raise named from exc


def _set(cfg: EnvConfig, key: str, value: Any) -> EnvConfig:
    if key == "physics":
        return replace(cfg, physics=physics_profile(value))
    if key == "robot":
        return robot_preset(cfg, value)
    if key == "world":
        if value is not None and not isinstance(value, (str, PathLike)):
            raise TypeError(f"must be a layout file path or None, got {type(value).__name__}")
        return replace(cfg, layout_file=None if value is None else str(value))
    if key == "randomize":
        return replace(cfg, randomize=value if _parsed(value) else parse_randomize(value))
    if key == "perturb":
        return replace(cfg, shift=ShiftConfig() if value is None else perturbation(value))
    if key.startswith("shift_") and key[6:] in _SHIFT_FIELDS:
        if key in ("shift_imu_accel_bias", "shift_imu_gyro_bias"):
            value = tuple(float(v) for v in value)
        return replace(cfg, shift=_replace_checked(cfg.shift, key[6:], value))
    if key.startswith("reward_") and key[7:] in _REWARD_FIELDS:
        return replace(cfg, task=replace(cfg.task, reward=_replace_checked(cfg.task.reward, key[7:], value)))
    if key in _KWARGS:
        path, name = _KWARGS[key]
        if key in ("world_size", "blocked_by"):
            value = (value,) if isinstance(value, str) else tuple(value)
        elif key in ("forklifts", "workers"):
            value = (int(value), int(value)) if isinstance(value, (int, np.integer)) else tuple(value)
        elif key in ("forklift_speed", "worker_speed"):
            value = (float(value), float(value)) if isinstance(value, (int, float)) else tuple(value)
        return _replace_at(cfg, path, name, value)
    raise TypeError(f"bulletnav/Warehouse-v0 got an unknown keyword argument {key!r}; known: {', '.join(known_kwargs())}")


def _refuse_kinematic(cfg: EnvConfig, render_mode: str | None) -> None:
    """What the kinematic profile cannot serve, refused in one line naming the profiles that can.

    Raises:
        ConfigError: the camera as an observation, or a rendered frame or window.
    """
    can = "use physics='default' (or 'fast')"
    if cfg.camera_obs:
        raise ConfigError(f"physics='kinematic' has no camera (camera_obs=True): {can}")
    if render_mode == "human":
        raise ConfigError(f"physics='kinematic' has no GUI (render_mode='human'): {can}")
    if render_mode == "rgb_array":
        raise ConfigError(f"physics='kinematic' renders no frames (render_mode='rgb_array'): {can}")


def known_kwargs() -> list[str]:
    """Every keyword argument ``WarehouseEnv`` (and the ids built on it) takes, sorted."""
    return sorted([*_KWARGS, "world", "config", "render_mode", "perturb", "randomize", "physics", "robot",
                   *(f"reward_{f}" for f in _REWARD_FIELDS), *(f"shift_{f}" for f in _SHIFT_FIELDS)])


def _conforms(value: Any, hint: Any) -> bool:
    """``value`` has the type a config field is annotated with (numbers of any width; an int
    where a float is expected)."""
    if hint is Any:
        return True
    origin, args = get_origin(hint), get_args(hint)
    if origin in (Union, UnionType):
        return any(_conforms(value, a) for a in args)
    if hint is type(None):
        return value is None
    if hint is bool:
        return isinstance(value, (bool, np.bool_))
    if hint is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, (bool, np.bool_))
    if hint is float:
        return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))
    if origin is tuple:
        if not isinstance(value, tuple):
            return False
        if len(args) == 2 and args[1] is Ellipsis:
            return all(_conforms(v, args[0]) for v in value)
        return len(value) == len(args) and all(_conforms(v, a) for v, a in zip(value, args))
    if isinstance(hint, type):
        return isinstance(value, hint)
    return True


def _replace_checked(obj: Any, name: str, value: Any) -> Any:
    """``replace(obj, name=value)`` after checking ``value`` against the field's annotation."""
    hint = get_type_hints(type(obj))[name]
    if not _conforms(value, hint):
        shown = hint.__name__ if isinstance(hint, type) and not get_args(hint) else str(hint).replace("typing.", "")
        raise TypeError(f"must be {shown}, got {show(value)} ({type(value).__name__})")
    return replace(obj, **{name: value})


def _parsed(value: Any) -> bool:
    """True for distributions already parsed (a config's ``randomize`` passed on)."""
    return isinstance(value, tuple) and all(isinstance(d, Distribution) for d in value)


def _replace_at(obj: Any, path: tuple[str, ...], name: str, value: Any) -> Any:
    if not path:
        return _replace_checked(obj, name, value)
    child = getattr(obj, path[0])
    return replace(obj, **{path[0]: _replace_at(child, path[1:], name, value)})


class WarehouseEnv(gym.Env):
    """Drive a differential-drive robot to a goal through a cluttered warehouse.

    ## Description
    A procedural warehouse (walls, shelving racks, pallets, boxes, columns; 31 obstacles by
    default) or a YAML layout. Each episode places the robot at rest at a start pose and a
    goal 2-6 m away in reachable free space. PyBullet runs at ``physics_hz`` (240 Hz); one
    action holds for ``physics_hz / control_hz`` (10) physics steps.

    ## Action Space
    ``Box(low=[0.0, -1.5], high=[0.5, 1.5], dtype=float32)``

    | index | action | unit | range |
    |---|---|---|---|
    | 0 | forward speed v (forward only by default) | m/s | [min_speed, 0.5]; min_speed 0 by default |
    | 1 | yaw rate w (counter-clockwise +) | rad/s | [-1.5, 1.5] |

    ``min_speed`` (m/s, default 0) below 0 lets the robot back up at down to that speed: the
    action space's lower bound of v becomes it (nothing else changes; the observation still
    divides v by the top speed). Out-of-range actions are clipped; a NaN or infinite action raises ``ValueError``. With
    ``normalize_actions=True`` the space is ``Box(-1, 1, (2,))``, mapped linearly onto the
    ranges above (what SB3 recommends for Gaussian policies).

    ## Observation Space
    ``Box(43,)`` float32 (``lidar_rays + 7`` in general), every entry clipped to its range:

    | index | observation | unit before scaling | scaling | range |
    |---|---|---|---|---|
    | 0-35 | lidar ranges, ray i at 10 i deg counter-clockwise from the heading | m | / lidar_range (5 m) | [0, 1] |
    | 36 | heading error: goal bearing minus robot heading | rad | / pi | [-1, 1] |
    | 37 | forward speed v from wheel odometry | m/s | / 0.5 | [-2, 2] |
    | 38 | yaw rate w from wheel odometry | rad/s | / 1.5 | [-2, 2] |
    | 39 | IMU accelerometer x (body frame, specific force) | m/s^2 | / 9.81 | [-3, 3] |
    | 40 | IMU accelerometer y | m/s^2 | / 9.81 | [-3, 3] |
    | 41 | IMU gyroscope z | rad/s | / 1.5 | [-3, 3] |
    | 42 | distance to the goal | m | / 10 | [0, 3] |
    | 43- | with ``lidar_history=k``: the k - 1 earlier scans, newest first, 36 each | m | / lidar_range | [0, 1] |
    | then | with ``guidance="floorplan"``: path cost to the target along the floor plan | m | / 10 | [0, 3] |
    | +1, +2 | sin, cos of the bearing of the point 0.8 m along that path, from the heading | - | - | [-1, 1] |
    | then | missions (``task_name="mission"``): distance to the target goal | m | / 10 | [0, 3] |
    | +1, +2 | sin, cos of the target's bearing from the heading | - | - | [-1, 1] |
    | +3 | goals left / K | - | - | [0, 1] |
    | +4 ... | ``goal_order="free"``: K slots of (distance / 10, sin, cos of bearing, 1 if still to visit); zeros once reached | | | |

    Missions (``bulletnav/WarehouseMission-v0``; :mod:`bulletnav.tasks.mission`): in free order
    the target, and the progress term, is the nearest goal not yet reached; entries 36 and 42
    refer to the target. With ``guidance="floorplan"`` the free-order target is instead the next
    goal of the shortest tour on the floor plan's path costs (fixed for the episode), and the
    progress term of any task is measured along the path (:mod:`bulletnav.tasks.guidance`).

    The robot's pose for entries 36 and 42 is ground truth (``pose_source="truth"``, as in
    the article) or the odometry estimate (``pose_source="odometry"``). With
    ``camera_obs=True`` the observation is a ``Dict`` with ``state`` (the vector above),
    ``rgb`` (240, 320, 3) uint8 and ``depth`` (240, 320, 1) float32 metres.

    ## Rewards
    The sum of named terms, each in ``info`` as ``reward_<name>`` (weights are
    ``reward_<name>`` keyword arguments):

    | term | value |
    |---|---|
    | progress | +1.0 x metres gained toward the goal this step |
    | goal | +50 when the goal is reached |
    | collision | -10 on contact with a wall or obstacle |
    | time | -0.01 every step |
    | heading | +0.1 x (1 - abs(heading error) / pi) while farther than 1 m from the goal |
    | stuck | -0.1 while progress over the last 20 steps is under 0.1 m and the goal is > 1 m away |
    | proximity | -1.0 x (0.3 - closest lidar range) while the closest range is under 0.3 m |
    | mover_proximity | off (0); set, weight x (0.3 - outline-to-mover gap) while under 0.3 m |

    ## Starting State
    Robot at rest at a sampled (or given) start pose with uniform random yaw.

    ## Episode End
    - Termination: distance to the goal < 0.5 m (``info["is_success"] = True``).
    - Truncation: a collision (any contact between the robot and a wall or obstacle), or
      ``max_episode_steps`` (1000, Gymnasium's ``TimeLimit``; pass ``max_episode_steps`` to
      ``gym.make`` to change it). With ``collision_terminates=True`` a collision terminates
      the episode instead (a real end, what a learner should bootstrap as such).

    ## Info
    The reward terms, ``distance_to_goal`` (m), ``collision``, ``is_success``,
    ``path_length`` (m driven, ground truth), ``initial_distance`` (m), ``goal`` (x, y),
    ``pose`` (x, y, yaw ground truth), and ``end_reason`` (``"success"``, ``"collision"``,
    or None while the episode runs; Gymnasium's ``TimeLimit`` truncates without one).

    ## Scene
    ``env.unwrapped.scene`` is a read-only :class:`~bulletnav.envs.scene.SceneView`: true
    pose, start, goal(s), static layout, occupancy map at any resolution, movers, robot
    geometry, sensors (``scene.sensors.lidar`` ...), step and episode counters. Controllers,
    evaluation and visualisation read only ``obs``, ``info`` and this view.

    ## Arguments
    ``gym.make("bulletnav/Warehouse-v0", **kwargs)`` with any of: ``num_obstacles`` (31),
    ``world`` (YAML layout path or None), ``world_size`` ((14, 14) m),
    ``min_goal_distance`` (2 m), ``max_goal_distance`` (6 m), ``lidar_rays`` (36),
    ``lidar_range`` (5 m), ``lidar_noise`` (0 m), ``lidar_caster`` ("bullet"; "exact" casts in
    closed form, static worlds only), ``imu_accel_noise`` (0.05 m/s^2),
    ``imu_gyro_noise`` (0.01 rad/s), ``odometry_noise`` (0 rad), ``physics`` ("default": 240 Hz;
    "fast": the measured fast profile of ``bulletnav.config.PHYSICS_PROFILES``), ``physics_hz`` (240),
    ``control_hz`` (24), ``solver_iterations``, ``goal_radius`` (0.5 m), ``min_speed`` (0 m/s: forward
    only; e.g. -0.5 lets the robot back up at 0.5 m/s),
    ``pose_source`` ("truth"), ``collision_terminates`` (False), ``normalize_actions``
    (False), ``layouts_every`` (1: a new procedural warehouse every reset),
    ``layout_style`` ("scattered"; any registered world generator), ``lidar_rate_hz`` (None:
    every control step), ``camera_enabled`` (True), ``camera_obs`` (False), ``task_name``
    ("navigation"; any registered task), ``min_detour`` (1.0: off; planning episodes need a
    shortest path at least this many times the straight line), ``blocked_by`` (() : off;
    planning episodes need the straight line to cross an obstacle with one of these labels,
    e.g. ``("rack",)``), ``detour_share`` (1.0; share of planning episodes while either is on),
    ``aisles`` (an :class:`~bulletnav.config.AislesConfig` for ``layout_style="aisles"``),
    ``reward_<term>`` weights, ``guidance`` ("none"; "floorplan": see the observation table),
    ``robot`` ("article": the robot above; "jackal": a Clearpath Jackal-sized robot, 0.508 x 0.430 m,
    2.0 m/s, 4.0 rad/s, a 270-degree 30 m lidar of 72 rays; :func:`~bulletnav.config.robot_preset`),
    ``perturb`` (None; a named shift of :mod:`bulletnav.envs.shifts`: ``slippery``, ``heavy``,
    ``noisy``, ``miscalibrated``, ``laggy``), ``shift_<field>`` (a
    :class:`~bulletnav.config.ShiftConfig` field: friction, mass, motor force, odometry model,
    action latency, sensor noise, mover speeds), ``randomize`` (a mapping of parameter to
    distribution drawn every episode, :mod:`bulletnav.envs.randomization`; ``info["dr"]``
    reports the draws, ``info["shift"]`` a fixed shift), ``render_mode``
    (``"human"``: PyBullet GUI, needs a display; ``"rgb_array"``: a chase-camera frame), and
    ``config`` (an :class:`EnvConfig` the other keywords modify).

    ``reset(seed, options)`` takes ``options={"start": (x, y, yaw), "goal": (x, y)}`` to
    place either exactly. A seeded reset draws a new layout, start and goal from
    ``self.np_random``.

    ## Version History
    - v0: initial release. Later additions (``end_reason`` in ``info``, the options
      ``collision_terminates``, ``layout_style``, ``lidar_rate_hz``, ``camera_enabled``,
      ``task_name``, ``min_detour``, ``blocked_by``, ``detour_share``, ``aisles``,
      ``lidar_history``, ``guidance``, the movers' ``forklifts``, ``workers``, ``forklift_speed``,
      ``worker_speed``, ``pallet_events_per_min``, ``yield_to_robot``, ``perturb``,
      ``shift_<field>``, ``randomize``, ``physics``; YAML ``dynamic:`` and ``events:``) leave every default
      episode bit-identical.
    - ``bulletnav/WarehouseAisles-v0``: the same env with ``layout_style="aisles"`` on a 20 x 16 m
      floor, goals 3-10 m away, 80 % planning episodes (straight line through a rack, detour
      >= 1.5 on the sampler's grid), ``collision_terminates=True``, 2,400 steps
      (``bulletnav.AISLES_KWARGS``).
    - ``bulletnav/WarehouseDynamic-v0``: the aisle warehouses with 2-4 forklifts (0.3-1.0 m/s),
      2-6 workers (0.5-1.4 m/s) and pallets appearing and vanishing (2 a minute), all yielding
      to the robot (``bulletnav.DYNAMIC_KWARGS``). In worlds with movers or events ``info``
      adds ``nearest_mover_m`` (robot outline to the nearest mover, m; ``inf`` if none),
      ``collision_with`` (``"static"``, ``"dynamic"`` or None) and ``events`` (this step's).
    - ``bulletnav/WarehouseMission-v0``: the aisle warehouses with ``task_name="mission"``, 3 goals in
      free order (``goals``, ``goal_order``, ``steps_per_goal`` kwargs; ``reward_subgoal``), truncated
      after 1,200 steps per goal; ``info`` adds ``goals``, ``goals_reached``, ``goals_total``,
      ``reached``, ``reached_at`` and ``goal_order``.
    """

    metadata = {"render_modes": ["human", "rgb_array"], "render_fps": 24}

    def __init__(self, render_mode: str | None = None, config: EnvConfig | None = None, **kwargs: Any) -> None:
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ValueError(f"render_mode must be one of {self.metadata['render_modes']} or None, got {render_mode!r}")
        self.config = cfg = make_config(config, **kwargs)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": cfg.physics.control_hz}
        self._generate = world_generator(cfg.world.style)
        self._fixed_layout: Layout | None = load_layout(cfg.layout_file) if cfg.layout_file else None
        if cfg.physics.backend == "kinematic":
            _refuse_kinematic(cfg, render_mode)
        self._scene = Scene(cfg, gui=render_mode == "human")
        try:
            self.task = make_task(cfg, self._scene)
            """The task (observation, reward, episode end); see :mod:`bulletnav.tasks`."""
            if cfg.camera_obs:
                self._scene.sensors.require("camera", by="camera_obs=True")
        except BaseException:
            self._scene.close()
            raise
        self.scene = SceneView(self._scene, self.task)
        """Read-only view for controllers, evaluation and visualisation."""
        self.pace_gui = True
        """In human mode, hold each step to real time (one control period); benchmarks turn it off."""
        self._actions = ActionMap.of(cfg.task, cfg.normalize_actions)
        self.action_space = self._actions.space()
        state = self.task.observation_space()
        if cfg.camera_obs:
            cam = cfg.sensors.camera
            self.observation_space: spaces.Space = spaces.Dict({
                "state": state,
                "rgb": spaces.Box(0, 255, (cam.height, cam.width, 3), dtype=np.uint8),
                "depth": spaces.Box(0.0, cam.far, (cam.height, cam.width, 1), dtype=np.float32),
            })
        else:
            self.observation_space = state
        self._term_keys = tuple(f"reward_{name}" for name in self.task.reward_terms)
        self._shift_info = None if cfg.shift.nominal else describe(cfg.shift)
        self._made_config = cfg
        self._dr_rng: np.random.Generator | None = None
        self._dr_world: dict[str, Any] = {}
        self._dr_info: dict[str, Any] = {}
        self._resets_on_layout = 0
        self._last_frame_time = 0.0

    def set_episode_config(self, **kwargs: Any) -> None:
        """Draw the next episodes from another distribution (a curriculum stage): keyword
        arguments as for ``gym.make``, limited to :data:`STAGE_KWARGS`, applied on top of the
        config the env was made with (no arguments restore it). The env is not rebuilt; the next
        reset draws a new layout. Reaches sub-process envs through ``VecEnv.env_method``.

        Raises:
            ValueError: a keyword outside :data:`STAGE_KWARGS` (the message lists them).
        """
        bad = sorted(set(kwargs) - STAGE_KWARGS, key=str)
        if bad:
            raise ValueError(f"set_episode_config: {', '.join(bad)} cannot change between episodes "
                             f"(they change the spaces, the task or the reward); allowed: {', '.join(sorted(STAGE_KWARGS))}")
        cfg = make_config(self._made_config, **kwargs)
        self.config = self.task.config = self._scene.config = cfg
        self._scene.shift = cfg.shift
        self._generate = world_generator(cfg.world.style)
        self._shift_info = None if cfg.shift.nominal else describe(cfg.shift)
        self._resets_on_layout = cfg.layouts_every  # the next reset draws a new layout

    # ------------------------------------------------------------------ gym API
    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        super().reset(seed=seed)
        if options is not None and not isinstance(options, dict):
            raise ValueError(f"options must be a dict (start, goal, goals) or None, got {show(options)}")
        options = options or {}
        cfg = self.config
        rng = self.np_random
        scene = self._scene
        layout = self._fixed_layout
        dr = cfg.randomize
        if seed is not None:  # randomization's own stream, seeded with the reset (also for a later stage's)
            self._dr_rng = np.random.default_rng([seed, DR_STREAM])
        elif dr and self._dr_rng is None:
            self._dr_rng = np.random.default_rng()
        if layout is None:
            layout = scene.layout
            if seed is not None or layout is None or self._resets_on_layout >= cfg.layouts_every:
                world = cfg.world
                if dr:
                    world, self._dr_world = draw_world(dr, self._dr_rng, world)
                layout = self._generate(rng, world)
                self._resets_on_layout = 0
        if dr:
            scene.shift, values = draw(dr, self._dr_rng, cfg.shift)
            self._dr_info = {**values, **self._dr_world}
        self._resets_on_layout += 1
        # A seeded reset rebuilds the scene so that it is bit-identical whatever came before.
        scene.use_layout(layout, rebuild=seed is not None)
        self.task.initialize_episode(scene, rng, options)
        if self.render_mode == "human":
            self._follow_camera()
        terms = dict.fromkeys(self.task.reward_terms, 0.0)
        return self._observation(), self._info(terms, None)

    def step(self, action):
        scene, task = self._scene, self.task
        v, w = self.command(action)
        scene.step(v, w)
        task.after_step(scene)
        terms = task.reward(scene)
        terminated, truncated, reason = task.end(scene)
        reward = float(sum(terms.values()))
        if self.render_mode == "human":
            self._follow_camera()
            if self.pace_gui:
                self._pace()
        return self._observation(), reward, terminated, truncated, self._info(terms, reason)

    def command(self, action: Any) -> tuple[float, float]:
        """The (v m/s, w rad/s) an action commands, after scaling and clipping
        (:meth:`~bulletnav.envs.actions.ActionMap.command`).

        Raises:
            ValueError: the action is not 2 finite numbers (a dict, a wrong shape, NaN).
        """
        return self._actions.command(action)

    def render(self):
        if self.render_mode == "rgb_array":
            return self._chase_frame()
        return None

    def close(self) -> None:
        self._scene.close()

    # ------------------------------------------------------------------ helpers
    def _observation(self):
        state = self.task.observe(self._scene)
        if not self.config.camera_obs:
            return state
        image = self._scene.sensors.camera.read()
        return {"state": state, "rgb": image.rgb, "depth": image.depth[:, :, None]}

    def _info(self, terms: dict[str, float], reason: str | None) -> dict[str, Any]:
        info: dict[str, Any] = dict(zip(self._term_keys, terms.values()))  # the task's terms are floats
        info.update(self.task.info(self._scene))
        if self._scene.dynamic:
            info.update(self._scene.dynamic_info())
        if self._shift_info is not None:
            info["shift"] = dict(self._shift_info)
        if self.config.randomize:
            info["dr"] = dict(self._dr_info)
        info["end_reason"] = reason
        return info

    def _chase_frame(self, width: int = 480, height: int = 360) -> np.ndarray:
        cid = self._scene.cid
        x, y, yaw = self._scene.robot.planar_pose()
        eye = [x - 2.2 * math.cos(yaw), y - 2.2 * math.sin(yaw), 2.4]
        view = p.computeViewMatrix(eye, [x + 0.8 * math.cos(yaw), y + 0.8 * math.sin(yaw), 0.0], [0, 0, 1],
                                   physicsClientId=cid)
        proj = p.computeProjectionMatrixFOV(60.0, width / height, 0.05, 30.0, physicsClientId=cid)
        _, _, rgba, _, _ = p.getCameraImage(width, height, view, proj, renderer=p.ER_TINY_RENDERER,
                                            flags=p.ER_NO_SEGMENTATION_MASK, physicsClientId=cid)
        return np.reshape(np.asarray(rgba, dtype=np.uint8), (height, width, 4))[:, :, :3].copy()

    def _follow_camera(self) -> None:
        x, y, yaw = self._scene.robot.planar_pose()
        p.resetDebugVisualizerCamera(3.5, math.degrees(yaw) - 90.0, -45.0, [x, y, 0.0],
                                     physicsClientId=self._scene.cid)

    def _pace(self) -> None:
        """Hold the GUI to real time (one control period per step)."""
        period = self.config.physics.control_dt
        now = time.perf_counter()
        wait = self._last_frame_time + period - now
        if wait > 0:
            time.sleep(wait)
        self._last_frame_time = time.perf_counter()
