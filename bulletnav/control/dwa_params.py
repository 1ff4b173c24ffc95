"""move_base's parameters for navfn and TrajectoryPlannerROS in DWA mode, read as move_base reads them.

The parameter tree is the one BARN's ``move_base_DWA.launch`` (github.com/Daffan/the-barn-challenge,
commit bf5a226) puts on the parameter server, namespaces and all: ``costmap_common_params.yaml``
loaded into both ``global_costmap`` and ``local_costmap``, the two ``odom_nav_params`` files,
``base_local_planner_params.yaml`` (``TrajectoryPlannerROS``) and ``move_base_params.yaml`` (top
level). :func:`load_dwa_params` reads BARN's five files (shipped verbatim in
``bulletnav/assets/barn/params/``) and lays a user's YAML of the same shape over them; the result
is :class:`DWAParams`, frozen dataclasses with a unit under every field.

A field's default is what move_base uses when no file sets it: for the trajectory planner the
``BaseLocalPlanner.cfg`` default (its dynamic reconfigure server overwrites the planner's values
with the server's or the .cfg's defaults at start-up, ``TrajectoryPlanner::reconfigure``), for
the rest the ``param(...)`` default in the C++ source that reads it. Ranges are dynamic
reconfigure's where it has one (a value outside it is refused here; ROS would clamp it).

Keys that move_base reads but that change nothing here (frames, publishing, voxel settings) are
accepted and ignored (:data:`INERT_KEYS`); any other key is an error naming the file, the key and
the nearest valid key. Values are read with the project's safe YAML loader
(:func:`bulletnav.yamlfile.read_yaml`).
"""

from __future__ import annotations

import difflib
import math
import numbers
from collections.abc import Mapping
from dataclasses import dataclass, field, fields, replace
from pathlib import Path
from typing import Any, get_type_hints

from bulletnav.config import asset_path
from bulletnav.errors import ConfigError
from bulletnav.yamlfile import read_yaml, show

BARN_PARAMS_DIR = ("barn", "params")
"""Where BARN's five parameter files live under ``bulletnav/assets``."""
BARN_FILES: tuple[tuple[str, str], ...] = (
    ("costmap_common_params.yaml", "global_costmap"),
    ("costmap_common_params.yaml", "local_costmap"),
    ("odom_nav_params/global_costmap_params.yaml", ""),
    ("odom_nav_params/local_costmap_params.yaml", ""),
    ("base_local_planner_params.yaml", ""),
    ("move_base_params.yaml", ""),
)
"""BARN's parameter files and the namespace ``move_base_DWA.launch`` loads each into, in its order."""
SHIPPED = {"barn": None, "barn-2ms": ("dwa", "barn-2ms.yaml"), "barn-per-cell": ("dwa", "barn-per-cell.yaml")}
"""Shipped parameter sets by name: ``barn`` (BARN's files as they are), ``barn-2ms`` (an override
under ``bulletnav/assets/dwa/``: BARN's with the Jackal's full speed limits) and ``barn-per-cell``
(BARN's with the scores' biases per cell: ``meter_scoring`` off, what a ROS process does when
``TrajectoryPlanner``'s uninitialised ``meter_scoring_`` member is false)."""


def _p(default: Any, lo: float | None = None, hi: float | None = None, aliases: tuple[str, ...] = (),
       preferred: str | None = None) -> Any:
    """A field with its default, its allowed range (inclusive), the other names it is read under
    and the one of them that wins when a file sets several (ROS's current name over its
    deprecated one; the field's own name when None)."""
    meta = {"range": (lo, hi), "aliases": aliases, "preferred": preferred}
    return field(default=tuple(default) if isinstance(default, (tuple, list)) else default, metadata=meta)


@dataclass(frozen=True)
class TrajectoryPlannerParams:
    """``TrajectoryPlannerROS`` (base_local_planner/src/trajectory_planner_ros.cpp and the planner
    it configures, trajectory_planner.cpp; ranges from cfg/BaseLocalPlanner.cfg)."""

    acc_lim_x: float = _p(2.5, 0.0, 20.0)
    """Forward acceleration limit (m/s^2): the dynamic window and the rollouts' speed-up."""
    acc_lim_theta: float = _p(3.2, 0.0, 20.0)
    """Yaw acceleration limit (rad/s^2)."""
    max_vel_x: float = _p(0.55, 0.0, 20.0)
    """Top forward speed sampled (m/s)."""
    min_vel_x: float = _p(0.0, 0.0, 20.0)
    """Lowest forward speed sampled (m/s); stopping is an in-place rotation's job."""
    max_vel_theta: float = _p(1.0, 0.0, 20.0)
    """Top yaw rate sampled (rad/s)."""
    min_vel_theta: float = _p(-1.0, -20.0, 0.0)
    """Lowest (most negative) yaw rate sampled (rad/s)."""
    min_in_place_vel_theta: float = _p(0.4, 0.0, 20.0, aliases=("min_in_place_rotational_vel",))
    """Slowest in-place rotation (rad/s): smaller samples are raised to it."""
    max_rotational_vel: float = _p(1.0, 0.0, 20.0)
    """Top yaw rate when rotating to the goal's yaw (rad/s; the ROS wrapper's own, not ``max_vel_theta``)."""
    escape_vel: float = _p(-0.1, -2.0, 2.0, aliases=("backup_vel",))
    """Speed of the escape trajectory taken when nothing else is legal (m/s; negative backs up)."""
    holonomic_robot: bool = _p(False)
    """Sample sideways speeds (ROS's default is true; bulletnav's robots are differential-drive: false only)."""
    yaw_goal_tolerance: float = _p(0.05, 0.0, math.pi)
    """Yaw within which the goal's orientation counts as reached (rad)."""
    xy_goal_tolerance: float = _p(0.10, 0.0, 1e3)
    """Distance within which the goal's position counts as reached (m)."""
    latch_xy_goal_tolerance: bool = _p(False)
    """Once within ``xy_goal_tolerance``, only rotate to the goal's yaw, even when pushed out again."""
    sim_time: float = _p(1.7, 0.0, 10.0)
    """How far ahead each trajectory is rolled out (s)."""
    sim_granularity: float = _p(0.025, 0.0, 5.0)
    """Distance between the rollout's points (m)."""
    angular_sim_granularity: float = _p(0.025, 0.0, math.pi / 2)
    """Yaw between the rollout's points (rad)."""
    vx_samples: int = _p(20, 1, 300)
    """Forward speeds sampled."""
    vtheta_samples: int = _p(20, 1, 300)
    """Yaw rates sampled."""
    controller_frequency: float | None = _p(None, 0.0, 1e3)
    """Rate the planner assumes it runs at (Hz): ``sim_period`` = 1 / it; None: move_base's
    ``controller_frequency`` (ROS finds the nearest with ``searchParam``)."""
    meter_scoring: bool = _p(False)
    """Scale ``pdist_scale`` and ``gdist_scale`` by the costmap's resolution (distances then count in metres, not cells)."""
    occdist_scale: float = _p(0.01, 0.0, 5.0)
    """Weight of the highest obstacle cost along a trajectory (per cost unit, 0-254)."""
    pdist_scale: float = _p(0.6, 0.0, 5.0, aliases=("path_distance_bias",), preferred="path_distance_bias")
    """Weight of the trajectory end's distance to the global plan (per cell, or per metre with ``meter_scoring``)."""
    gdist_scale: float = _p(0.8, 0.0, 5.0, aliases=("goal_distance_bias",), preferred="goal_distance_bias")
    """Weight of the trajectory end's distance to the local goal (per cell, or per metre with ``meter_scoring``)."""
    heading_lookahead: float = _p(0.325, 0.0, 5.0)
    """How far ahead of an in-place rotation's end its goal distance is read (m)."""
    heading_scoring: bool = _p(False)
    """Score by heading to the plan instead of distance to it (false only here, as BARN has it)."""
    heading_scoring_timestep: float = _p(0.1, 0.0, 1.0)
    """With ``heading_scoring``: how far along the rollout the heading is read (s)."""
    dwa: bool = _p(False)
    """The dynamic window from one control period (``sim_period``) instead of the whole ``sim_time``."""
    simple_attractor: bool = _p(False)
    """Score by straight-line distance to the plan's end (false only here, as BARN has it)."""
    oscillation_reset_dist: float = _p(0.05, 0.0, 5.0)
    """Distance to travel before the oscillation flags are reset (m)."""
    escape_reset_dist: float = _p(0.10, 0.0, 5.0)
    """Distance to travel before escaping ends (m)."""
    escape_reset_theta: float = _p(math.pi / 2, 0.0, 5.0)
    """Yaw to turn before escaping ends (rad)."""
    prune_plan: bool = _p(True)
    """Drop the plan's points the robot has passed (those before the first within 1 m)."""


@dataclass(frozen=True)
class ObservationSourceParams:
    """One observation source of an obstacle layer (``obstacles_layer/scan`` in BARN's file;
    costmap_2d/plugins/obstacle_layer.cpp, ``onInitialize``)."""

    name: str = "scan"
    """The source's name (``observation_sources``)."""
    marking: bool = _p(True)
    """Its hits mark obstacles."""
    clearing: bool = _p(False)
    """Its rays clear free space."""
    obstacle_range: float | None = _p(None, 0.0, 1e3)
    """Hits at least this far are not marked (m); None: the layer's, else the costmap's, else 2.5."""
    raytrace_range: float | None = _p(None, 0.0, 1e3)
    """Rays clear at most this far (m); None: the layer's, else the costmap's, else 3.0."""
    min_obstacle_height: float = _p(0.0, -1e3, 1e3)
    """Lowest point kept (m; a scan's points lie in the sensor's plane, which BARN's -2..2 m keeps)."""
    max_obstacle_height: float = _p(2.0, -1e3, 1e3)
    """Highest point kept (m)."""
    inf_is_valid: bool = _p(False)
    """Rays reading infinity clear to ``raytrace_range`` (false only here: a ray that hits nothing is dropped)."""


@dataclass(frozen=True)
class ObstacleLayerParams:
    """``costmap_2d::ObstacleLayer`` (plugins/obstacle_layer.cpp)."""

    name: str = "obstacle_layer"
    """The plugin's name (recoveries clear layers by name)."""
    enabled: bool = _p(True)
    """The layer takes part."""
    track_unknown_space: bool | None = _p(None)
    """Cells start unknown instead of free; None: the costmap's ``track_unknown_space``."""
    footprint_clearing_enabled: bool = _p(True)
    """Clear the cells under the robot's footprint at every update."""
    combination_method: int = _p(1, 0, 2)
    """How the layer joins the master: 0 overwrite, 1 maximum (costmap_2d's default), 2 not at all."""
    max_obstacle_height: float = _p(2.0, -1e3, 1e3)
    """The layer's highest point kept (m)."""
    obstacle_range: float | None = _p(None, 0.0, 1e3)
    """The layer-level ``obstacle_range`` (m) its sources find upward."""
    raytrace_range: float | None = _p(None, 0.0, 1e3)
    """The layer-level ``raytrace_range`` (m)."""
    source: ObservationSourceParams = field(default_factory=ObservationSourceParams)
    """Its one observation source."""


@dataclass(frozen=True)
class InflationLayerParams:
    """``costmap_2d::InflationLayer`` (plugins/inflation_layer.cpp; ranges from cfg/InflationPlugin.cfg)."""

    name: str = "inflation_layer"
    """The plugin's name."""
    enabled: bool = _p(True)
    """The layer takes part."""
    inflation_radius: float = _p(0.55, 0.0, 50.0)
    """How far costs spread from an obstacle (m)."""
    cost_scaling_factor: float = _p(10.0, 0.0, 100.0)
    """Exponential decay rate of the cost beyond the inscribed radius (1/m)."""
    inflate_unknown: bool = _p(False)
    """Unknown cells take any inflated cost (else only inscribed and lethal ones)."""


@dataclass(frozen=True)
class CostmapParams:
    """One ``costmap_2d::Costmap2DROS`` (``global_costmap`` or ``local_costmap``;
    costmap_2d/src/costmap_2d_ros.cpp and layered_costmap.cpp)."""

    width: float = _p(10.0, 0.0, 1e4)
    """Map width (m)."""
    height: float = _p(10.0, 0.0, 1e4)
    """Map height (m)."""
    resolution: float = _p(0.05, 1e-4, 1e2)
    """Cell side (m)."""
    origin_x: float = _p(0.0, -1e6, 1e6)
    """The map's lower-left corner, x (m, the odometry frame: BARN's odom frame starts at the robot's start)."""
    origin_y: float = _p(0.0, -1e6, 1e6)
    """The map's lower-left corner, y (m)."""
    rolling_window: bool = _p(False)
    """The map is centred on the robot at every update."""
    update_frequency: float = _p(5.0, 0.0, 1e3)
    """Updates per second (Hz)."""
    track_unknown_space: bool = _p(False)
    """Cells nothing has seen are unknown (255) instead of free."""
    footprint: tuple[tuple[float, float], ...] = _p(())
    """The robot's outline, robot frame (m): vertices (x forward, y left); empty: a circle of ``robot_radius``."""
    robot_radius: float = _p(0.46, 0.0, 1e3)
    """A circular robot's radius (m), when no ``footprint`` is given."""
    footprint_padding: float = _p(0.01, -1e3, 1e3)
    """Added to every vertex's |x| and |y| (m, costmap_2d's ``padFootprint``)."""
    obstacle_range: float | None = _p(None, 0.0, 1e3)
    """The costmap-level ``obstacle_range`` (m) the observation sources find upward."""
    raytrace_range: float | None = _p(None, 0.0, 1e3)
    """The costmap-level ``raytrace_range`` (m)."""
    inscribed_radius: float = _p(0.325, 0.0, 1e3)
    """move_base's own ``local_costmap/inscribed_radius`` (m; not the costmap's, which comes from the footprint)."""
    circumscribed_radius: float = _p(0.46, 0.0, 1e3)
    """move_base's own ``local_costmap/circumscribed_radius`` (m): the aggressive reset clears
    beyond 4 times it (not the footprint's circumscribed radius)."""
    obstacle_layer: ObstacleLayerParams = field(default_factory=ObstacleLayerParams)
    inflation_layer: InflationLayerParams = field(default_factory=InflationLayerParams)


@dataclass(frozen=True)
class NavfnParams:
    """``NavfnROS`` (navfn/src/navfn_ros.cpp)."""

    allow_unknown: bool = _p(True)
    """Plan through unknown cells."""
    default_tolerance: float = _p(0.0, 0.0, 0.0)
    """How far from the goal a reachable point may be taken instead (m; 0 only here, move_base's use)."""


@dataclass(frozen=True)
class ClearCostmapParams:
    """One ``ClearCostmapRecovery`` (clear_costmap_recovery/src/clear_costmap_recovery.cpp)."""

    layer_names: tuple[str, ...] = _p(("obstacles",))
    """Layers it clears, by plugin name (BARN's obstacle layer is ``obstacles_layer``, which the
    default does not name: in BARN these recoveries clear nothing)."""
    affected_maps: str = _p("both")
    """``local``, ``global`` or ``both``."""
    invert_area_to_clear: bool = _p(False)
    """Clear inside the square instead of outside it."""


@dataclass(frozen=True)
class RotateRecoveryParams:
    """``RotateRecovery`` (rotate_recovery/src/rotate_recovery.cpp)."""

    sim_granularity: float = _p(0.017, 1e-4, math.pi)
    """Yaw step of its collision check over the rotation left (rad)."""
    frequency: float = _p(20.0, 1e-3, 1e3)
    """Its command rate (Hz)."""


@dataclass(frozen=True)
class MoveBaseParams:
    """move_base's own (move_base/src/move_base.cpp, ``MoveBase::MoveBase``)."""

    controller_frequency: float = _p(20.0, 0.0, 1e3)
    """Control cycles per second (Hz)."""
    planner_frequency: float = _p(0.0, 0.0, 1e3)
    """Global plans per second while controlling (Hz); 0: plan only when asked."""
    controller_patience: float = _p(15.0, 0.0, 1e6)
    """Seconds without a valid command before the recoveries start (s)."""
    planner_patience: float = _p(5.0, 0.0, 1e6)
    """Seconds without a valid plan before the recoveries start (s)."""
    max_planning_retries: int = _p(-1, -1, 2**31 - 1)
    """Failed plans before the recoveries start; -1: no limit (only ``planner_patience``)."""
    oscillation_timeout: float = _p(0.0, 0.0, 1e6)
    """Seconds without moving ``oscillation_distance`` before the recoveries start (s); 0: never."""
    oscillation_distance: float = _p(0.5, 0.0, 1e3)
    """Distance that counts as moving, for ``oscillation_timeout`` (m)."""
    recovery_behavior_enabled: bool = _p(True)
    """Run the recoveries before aborting."""
    clearing_rotation_allowed: bool = _p(True)
    """The default recoveries include the in-place rotation."""
    conservative_reset_dist: float = _p(3.0, 0.0, 1e3)
    """The conservative reset keeps a square of this side around the robot (m)."""


@dataclass(frozen=True)
class DWAParams:
    """Everything move_base with navfn and TrajectoryPlannerROS reads, by namespace."""

    move_base: MoveBaseParams = field(default_factory=MoveBaseParams)
    """The top level."""
    trajectory_planner: TrajectoryPlannerParams = field(default_factory=TrajectoryPlannerParams)
    """``TrajectoryPlannerROS``."""
    local_costmap: CostmapParams = field(default_factory=CostmapParams)
    """``local_costmap``."""
    global_costmap: CostmapParams = field(default_factory=CostmapParams)
    """``global_costmap``."""
    navfn: NavfnParams = field(default_factory=NavfnParams)
    """``NavfnROS``."""
    conservative_reset: ClearCostmapParams = field(default_factory=ClearCostmapParams)
    """``conservative_reset`` (its ``reset_distance`` is ``conservative_reset_dist``, as move_base sets it)."""
    aggressive_reset: ClearCostmapParams = field(default_factory=ClearCostmapParams)
    """``aggressive_reset`` (its ``reset_distance`` is 4 x ``local_costmap/circumscribed_radius``)."""
    rotate_recovery: RotateRecoveryParams = field(default_factory=RotateRecoveryParams)
    """``rotate_recovery``."""
    sources: tuple[str, ...] = ()
    """The files read, in order (BARN's, then the override)."""

    @property
    def sim_period(self) -> float:
        """``TrajectoryPlannerROS``'s ``sim_period`` (s): 1 / the nearest ``controller_frequency``
        (0.05 when it is not positive, as the wrapper falls back to 20 Hz)."""
        f = self.trajectory_planner.controller_frequency
        f = self.move_base.controller_frequency if f is None else f
        return 1.0 / f if f > 0 else 0.05


INERT_KEYS: Mapping[str, str] = {
    # top level
    "shutdown_costmaps": "costmaps are never stopped here",
    "base_global_planner": "navfn/NavfnROS only",
    "base_local_planner": "base_local_planner/TrajectoryPlannerROS only",
    "clearing_radius": "not used by move_base's noetic recoveries",
    "make_plan_clear_costmap": "the make_plan service only",
    "make_plan_add_unreachable_goal": "the make_plan service only",
    # TrajectoryPlannerROS
    "publish_cost_grid_pc": "visualisation",
    "publish_cost_grid": "visualisation",
    "global_frame_id": "frames: everything is in the world-aligned odometry frame",
    "world_model": "costmap only",
    "acc_lim_y": "holonomic robots only",
    "y_vels": "holonomic robots only",
    "stop_time_buffer": "its use is commented out in trajectory_planner.cpp",
    # costmaps
    "map_type": "the pre-hydro layer choice; the plugins list decides",
    "static_map": "the pre-hydro layer choice; the plugins list decides",
    "origin_z": "voxel layers only",
    "z_resolution": "voxel layers only",
    "z_voxels": "voxel layers only",
    "unknown_threshold": "voxel layers only",
    "mark_threshold": "voxel layers only",
    "publish_voxel_map": "visualisation",
    "publish_frequency": "visualisation",
    "transform_tolerance": "no transforms here: poses are read at once",
    "global_frame": "frames: everything is in the world-aligned odometry frame",
    "robot_base_frame": "frames",
    "always_send_full_costmap": "visualisation",
    "footprint_topic": "the footprint is fixed",
    "meter_scoring": "a costmap does not score (BARN's costmap file sets it; TrajectoryPlannerROS reads its own)",
    # observation sources
    "sensor_frame": "the lidar's pose comes from the robot's geometry",
    "data_type": "a laser scan",
    "topic": "the env's scan",
    "observation_persistence": "one scan per update (costmap_2d's 0)",
    "expected_update_rate": "the scan comes every env step",
    # recoveries
    "force_updating": "the costmaps are rebuilt at their next update either way",
    "reset_distance": "move_base overwrites it (conservative_reset_dist, 4 x circumscribed_radius)",
    # navfn
    "visualize_potential": "visualisation",
    "planner_window_x": "not used by navfn_ros.cpp's makePlan",
    "planner_window_y": "not used by navfn_ros.cpp's makePlan",
    "old_navfn_behavior": "global_planner's, not navfn's",
}
"""Keys move_base (or a plugin) reads that change nothing in this port, with why; accepted and ignored."""

LAYER_TYPES = {"costmap_2d::ObstacleLayer": "obstacle", "costmap_2d::InflationLayer": "inflation"}
"""The costmap plugins ported, by type."""


class _Tree:
    """A parameter tree with the file each value came from (for messages)."""

    def __init__(self) -> None:
        self.data: dict[str, Any] = {}
        self.origin: dict[tuple[str, ...], str] = {}
        self.files: list[str] = []

    def merge(self, raw: Any, path: str, namespace: tuple[str, ...] = ()) -> None:
        """Lay the document ``raw`` of file ``path`` over the tree at ``namespace``, as
        ``rosparam load`` merges mappings (a value replaces, a mapping merges into a mapping)."""
        if path not in self.files:
            self.files.append(path)
        if raw is None:
            return
        if not isinstance(raw, dict):
            raise ConfigError(f"{path}: a parameter file must be a mapping of names to values, got {show(raw)}")
        node = self.data
        for name in namespace:
            node = node.setdefault(name, {})
        self._merge(node, raw, path, namespace)

    def _merge(self, node: dict, raw: dict, path: str, at: tuple[str, ...]) -> None:
        for key, value in raw.items():
            if not isinstance(key, str):
                raise ConfigError(f"{path}: key {show(key)} under {'.'.join(at) or 'the top level'} is not a name")
            where = (*at, key)
            if isinstance(value, dict) and isinstance(node.get(key), dict):
                self.origin.setdefault(where, path)
                self._merge(node[key], value, path, where)
            else:
                node[key] = _copy(value)
                self._mark(where, value, path)

    def _mark(self, where: tuple[str, ...], value: Any, path: str) -> None:
        self.origin[where] = path
        if isinstance(value, dict):
            for k, v in value.items():
                self._mark((*where, str(k)), v, path)

    def file(self, where: tuple[str, ...]) -> str:
        while where and where not in self.origin:
            where = where[:-1]
        return self.origin.get(where, "<parameters>")


def _copy(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _copy(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_copy(v) for v in value]
    return value


def _dotted(where: tuple[str, ...]) -> str:
    return ".".join(where)


def _unknown(tree: _Tree, where: tuple[str, ...], valid: set[str]) -> ConfigError:
    key = where[-1]
    near = difflib.get_close_matches(key, sorted(valid), n=1, cutoff=0.0)
    hint = f"; the nearest valid key is {_dotted((*where[:-1], near[0]))!r}" if near else ""
    return ConfigError(f"{tree.file(where)}: unknown key {_dotted(where)!r}{hint}")


def _check(tree: _Tree, where: tuple[str, ...], value: Any, hint: Any, rng: tuple[Any, Any]) -> Any:
    """``value`` of key ``where`` converted to the field's type and checked against its range."""
    lo, hi = rng
    file, name = tree.file(where), _dotted(where)
    text = hint.__name__ if isinstance(hint, type) else str(hint).replace("typing.", "")
    is_bool = isinstance(value, bool)
    if value is None and "None" in text:
        return None
    if text.startswith("bool"):
        if not is_bool:
            raise ConfigError(f"{file}: key {name!r} must be true or false, got {show(value)}")
        return value
    if text.startswith("float"):
        if is_bool or not isinstance(value, numbers.Real) or not math.isfinite(float(value)):
            raise ConfigError(f"{file}: key {name!r} must be a number, got {show(value)}")
        value = float(value)
    elif text.startswith("int"):
        if is_bool or not isinstance(value, numbers.Integral):
            raise ConfigError(f"{file}: key {name!r} must be a whole number, got {show(value)}")
        value = int(value)
    elif text == "str":
        if not isinstance(value, str):
            raise ConfigError(f"{file}: key {name!r} must be a string, got {show(value)}")
        return value
    elif text.startswith("tuple[str"):
        if isinstance(value, str):
            value = [value]
        if not isinstance(value, list) or not all(isinstance(v, str) for v in value):
            raise ConfigError(f"{file}: key {name!r} must be a list of names, got {show(value)}")
        return tuple(value)
    elif text.startswith("tuple[tuple"):
        return _footprint(file, name, value)
    if lo is not None and not (lo <= value <= hi):
        raise ConfigError(f"{file}: key {name!r} must be from {lo:g} to {hi:g}, got {show(value)}")
    return value


def _footprint(file: str, name: str, value: Any) -> tuple[tuple[float, float], ...]:
    """A footprint: a list of at least 3 [x, y] pairs, or costmap_2d's string form ``"[[x, y], ...]"``."""
    if isinstance(value, str):
        from bulletnav.yamlfile import safe_load

        try:
            value = safe_load(value)
        except Exception:  # noqa: BLE001  (any parse failure is the same bad value)
            value = None
    ok = (isinstance(value, list) and len(value) >= 3 and all(
        isinstance(p, list) and len(p) == 2 and all(isinstance(c, numbers.Real) and not isinstance(c, bool)
                                                    and math.isfinite(float(c)) for c in p) for p in value))
    if not ok:
        raise ConfigError(f"{file}: key {name!r} must be a list of at least 3 [x, y] points (m), got {show(value)}")
    return tuple((float(p[0]), float(p[1])) for p in value)


def _build(cls: type, tree: _Tree, where: tuple[str, ...], raw: dict, skip: set[str] = frozenset(), **extra: Any) -> Any:
    """An instance of dataclass ``cls`` from mapping ``raw`` at ``where`` (its fields, their
    aliases, inert keys ignored); keys in ``skip`` are the caller's (sub-namespaces)."""
    hints = get_type_hints(cls)
    specs = {f.name: f for f in fields(cls) if f.metadata and f.name not in extra}  # file keys: the _p fields
    names = {alias: f.name for f in specs.values() for alias in (f.name, *f.metadata["aliases"])}
    kwargs: dict[str, Any] = dict(extra)
    chosen: dict[str, str] = {}
    for key, value in raw.items():
        at = (*where, key)
        if key in skip:
            continue
        if key in names:
            target = names[key]
            checked = _check(tree, at, value, hints[target], specs[target].metadata["range"])
            preferred = specs[target].metadata["preferred"] or target
            if target in chosen and chosen[target] == preferred:
                continue  # ROS's current name wins over its deprecated one (loadParameterWithDeprecation)
            kwargs[target] = checked
            chosen[target] = key
        elif key in INERT_KEYS:
            continue
        else:
            raise _unknown(tree, at, set(names) | set(INERT_KEYS) | set(skip))
    return cls(**kwargs)


def _mapping(tree: _Tree, where: tuple[str, ...], value: Any) -> dict:
    if value is None:
        return {}
    if not isinstance(value, dict):
        raise ConfigError(f"{tree.file(where)}: key {_dotted(where)!r} must be a mapping, got {show(value)}")
    return value


def _costmap(tree: _Tree, name: str) -> CostmapParams:
    """``global_costmap`` or ``local_costmap``: its keys, its plugins and their namespaces."""
    where = (name,)
    raw = _mapping(tree, where, tree.data.get(name))
    plugins = raw.get("plugins")
    if plugins is None:  # costmap_2d's pre-hydro conversion: an obstacle layer and an inflation layer
        names = {"obstacle": "obstacle_layer", "inflation": "inflation_layer"}
    else:
        names = _plugins(tree, (*where, "plugins"), plugins)
    obstacle_raw = _mapping(tree, (*where, names["obstacle"]), raw.get(names["obstacle"]))
    inflation_raw = _mapping(tree, (*where, names["inflation"]), raw.get(names["inflation"]))
    obstacle = _obstacle_layer(tree, (*where, names["obstacle"]), obstacle_raw, names["obstacle"])
    inflation = _build(InflationLayerParams, tree, (*where, names["inflation"]), inflation_raw, name=names["inflation"])
    params = _build(CostmapParams, tree, where, raw, skip={"plugins", *names.values()}, obstacle_layer=obstacle,
                    inflation_layer=inflation)
    if params.width < params.resolution or params.height < params.resolution:
        raise ConfigError(f"{tree.file(where)}: {name} must be at least one cell ({params.resolution:g} m) wide and high, "
                          f"got {params.width:g} x {params.height:g} m")
    return params


def _plugins(tree: _Tree, where: tuple[str, ...], plugins: Any) -> dict[str, str]:
    """The names of the obstacle and inflation layers in a ``plugins`` list (exactly one each)."""
    file = tree.file(where)
    if not isinstance(plugins, list) or not all(isinstance(p, dict) and set(p) == {"name", "type"} for p in plugins):
        raise ConfigError(f"{file}: key {_dotted(where)!r} must be a list of {{name, type}} entries, got {show(plugins)}")
    names: dict[str, str] = {}
    for p in plugins:
        kind = LAYER_TYPES.get(p["type"])
        if kind is None:
            near = difflib.get_close_matches(str(p["type"]), list(LAYER_TYPES), n=1, cutoff=0.0)
            raise ConfigError(f"{file}: key {_dotted(where)!r}: layer type {show(p['type'])} is not ported "
                              f"(ported: {', '.join(LAYER_TYPES)}; nearest {near[0]!r})")
        if kind in names:
            raise ConfigError(f"{file}: key {_dotted(where)!r} has two {p['type']} layers; one is ported")
        names[kind] = str(p["name"])
    if [LAYER_TYPES[p["type"]] for p in plugins] != ["obstacle", "inflation"]:
        raise ConfigError(f"{file}: key {_dotted(where)!r} must list an ObstacleLayer and then an InflationLayer, "
                          f"got {show(plugins)}")
    return names


def _obstacle_layer(tree: _Tree, where: tuple[str, ...], raw: dict, name: str) -> ObstacleLayerParams:
    sources = raw.get("observation_sources", "")
    if not isinstance(sources, str) or len(sources.split()) > 1:
        raise ConfigError(f"{tree.file((*where, 'observation_sources'))}: key {_dotted((*where, 'observation_sources'))!r} "
                          f"must name one source (a laser scan), got {show(sources)}")
    source_name = sources.strip()
    source = ObservationSourceParams()
    if source_name:
        at = (*where, source_name)
        source = _build(ObservationSourceParams, tree, at, _mapping(tree, at, raw.get(source_name)), name=source_name)
        if source.inf_is_valid:
            raise ConfigError(f"{tree.file((*at, 'inf_is_valid'))}: key {_dotted((*at, 'inf_is_valid'))!r}: only false is "
                              "ported (a ray that hits nothing is dropped)")
    skip = {"observation_sources", *([source_name] if source_name else [])}
    return _build(ObstacleLayerParams, tree, where, raw, skip=skip, name=name, source=source)


def _section(tree: _Tree, cls: type, name: str) -> Any:
    return _build(cls, tree, (name,), _mapping(tree, (name,), tree.data.get(name)))


NAMESPACES = ("TrajectoryPlannerROS", "local_costmap", "global_costmap", "NavfnROS", "conservative_reset",
              "aggressive_reset", "rotate_recovery")
"""The sub-namespaces of move_base's parameters this port reads."""


def params_from_tree(tree: _Tree) -> DWAParams:
    """:class:`DWAParams` from a merged parameter tree (every key checked, errors naming its file)."""
    top = _build(MoveBaseParams, tree, (), tree.data, skip=set(NAMESPACES))
    planner = _section(tree, TrajectoryPlannerParams, "TrajectoryPlannerROS")
    for flag in ("holonomic_robot", "heading_scoring", "simple_attractor"):
        if getattr(planner, flag):
            at = ("TrajectoryPlannerROS", flag)
            raise ConfigError(f"{tree.file(at)}: key {_dotted(at)!r}: only false is ported (bulletnav drives "
                              "differential-drive robots and scores as BARN does)")
    if planner.min_vel_x > planner.max_vel_x:
        at = ("TrajectoryPlannerROS", "min_vel_x")
        raise ConfigError(f"{tree.file(at)}: key {_dotted(at)!r} ({planner.min_vel_x:g}) must not exceed max_vel_x "
                          f"({planner.max_vel_x:g})")
    resets = {}
    for name in ("conservative_reset", "aggressive_reset"):
        resets[name] = _section(tree, ClearCostmapParams, name)
        if resets[name].affected_maps not in ("local", "global", "both"):
            at = (name, "affected_maps")
            raise ConfigError(f"{tree.file(at)}: key {_dotted(at)!r} must be local, global or both, "
                              f"got {show(resets[name].affected_maps)}")
    sources = tuple(tree.files)
    return DWAParams(top, planner, _costmap(tree, "local_costmap"), _costmap(tree, "global_costmap"),
                     _section(tree, NavfnParams, "NavfnROS"), resets["conservative_reset"], resets["aggressive_reset"],
                     _section(tree, RotateRecoveryParams, "rotate_recovery"), sources)


def barn_tree() -> _Tree:
    """BARN's five files merged as ``move_base_DWA.launch`` loads them."""
    tree = _Tree()
    for name, namespace in BARN_FILES:
        path = asset_path(*BARN_PARAMS_DIR, *name.split("/"))
        tree.merge(read_yaml(path, "move_base parameter file", ConfigError), str(path),
                   (namespace,) if namespace else ())
    return tree


def resolve_params(name_or_path: str | Path) -> Path | None:
    """The override file a shipped name (:data:`SHIPPED`) or a path names (None: BARN's own).

    Raises:
        ConfigError: neither a shipped name nor an existing file.
    """
    text = str(name_or_path)
    if text in SHIPPED:
        shipped = SHIPPED[text]
        return None if shipped is None else asset_path(*shipped)
    path = Path(text)
    if not path.is_file():
        raise ConfigError(f"no DWA parameter set {show(text)}: neither a shipped one ({', '.join(SHIPPED)}) nor a file")
    return path


def load_dwa_params(override: str | Path | None = None) -> DWAParams:
    """move_base's parameters: BARN's files (``bulletnav/assets/barn/params/``) with ``override``
    laid over them: a YAML of the same namespaces (``TrajectoryPlannerROS``, ``local_costmap``,
    ``global_costmap``, top-level move_base keys, ...), or a shipped name (``"barn"``: nothing
    over BARN's; ``"barn-2ms"``: the Jackal's full speed).

    Raises:
        ConfigError: a file missing or not YAML, an unknown key (the message names the file, the
            key and the nearest valid key), a value of the wrong type or out of range.
    """
    tree = barn_tree()
    if override is not None:
        path = resolve_params(override)
        if path is not None:
            tree.merge(read_yaml(path, "move_base parameter file", ConfigError), str(path))
    return params_from_tree(tree)


def with_overrides(params: DWAParams, **sections: dict[str, Any]) -> DWAParams:
    """``params`` with fields of its sections replaced (``trajectory_planner={"max_vel_x": 1.0}``),
    for code; files go through :func:`load_dwa_params`."""
    return replace(params, **{name: replace(getattr(params, name), **values) for name, values in sections.items()})
