"""Warehouse layouts: the pure-geometry description of a world, independent of PyBullet.

A :class:`Layout` is a floor size plus a tuple of :class:`Obstacle` footprints. It comes
from a YAML file (:func:`load_layout`) or from a seeded generator
(:func:`generate_warehouse`), and can be rasterised into an occupancy grid
(:meth:`Layout.occupancy`) for start/goal sampling, shortest paths and map checks.

YAML format (stable; see docs/worlds.md)::

    name: aisle-test                 # optional
    size: [12.0, 10.0]               # floor extent x, y (m), centred on the origin
    wall_height: 2.0                 # optional
    obstacles:                       # walls are not obstacles
      - {type: box, center: [2.0, 1.5], size: [3.0, 0.6, 1.8], yaw: 0.0}
      - {type: cylinder, center: [0.0, 0.0], radius: 0.2, height: 3.0}
    start: [-5.0, -4.0, 0.0]         # optional x, y, yaw
    goal: [5.0, 4.0]                 # optional x, y
    dynamic:                         # optional moving obstacles (bulletnav.sim.movers)
      - {type: forklift, route: [[-4, 0], [4, 0]], speed: 0.5}   # size [1.1, 0.8, 2.0], accel, yield_to_robot
      - {type: worker, waypoints: [[0, -3], [0, 3]], speed: 1.0, pause: 2.0}   # radius 0.25, height 1.7
    events:                          # optional obstacles appearing / vanishing (bulletnav.sim.events)
      - {at: 5.0, add: {type: box, center: [2, -2], size: [1.2, 0.8, 1.0], label: pallet_a}}
      - {at: 20.0, remove: pallet_a}
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav import limits
from bulletnav.config import WorldConfig
from bulletnav.errors import LayoutError, LimitError
from bulletnav.sim.kernels import COLUMN, CRATE, PALLET, RACK, mark_levels, place_obstacles
from bulletnav.sim.specs import EventSpec, ForkliftSpec, MoverSpec, Obstacle, WorkerSpec
from bulletnav.yamlfile import read_yaml, show

WALL_THICKNESS = 0.2
"""Thickness of the enclosing walls (m); they stand just outside the floor extent."""


@dataclass(frozen=True)
class Layout:
    """A warehouse floor with its static obstacles and optional fixed start and goal."""

    size: tuple[float, float]
    obstacles: tuple[Obstacle, ...] = ()
    wall_height: float = 2.0
    name: str = ""
    start: tuple[float, float, float] | None = None
    goal: tuple[float, float] | None = None
    source: str = field(default="", compare=False)
    """Where it came from (file path or ``procedural seed=...``), for messages only."""
    dynamic: tuple[MoverSpec, ...] = ()
    """Moving obstacles (forklifts, workers) animated in every episode on this layout."""
    events: tuple[EventSpec, ...] = ()
    """Obstacles that appear or vanish at given times in every episode on this layout."""
    goals: tuple[tuple[float, float], ...] = ()
    """Mission goals (``goals:`` list), used by the mission task instead of sampled ones."""
    corner: tuple[float, float] | None = None
    """The floor's lower-left corner (x, y m) in the world frame. None: the floor is centred on
    the origin (layout files and procedural worlds). A map_server map or a Gazebo world
    (:mod:`bulletnav.sim.userworld`) lives in the file's own frame: its corner is the map's
    ``origin`` (or the Gazebo shapes' extent less the margin), and every pose, path and map is
    in that frame."""

    @property
    def half_extents(self) -> tuple[float, float]:
        return self.size[0] / 2, self.size[1] / 2

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """The floor's extent in the world frame (m): ``(x_min, y_min, x_max, y_max)``."""
        if self.corner is None:
            hx, hy = self.size[0] / 2, self.size[1] / 2
            return -hx, -hy, hx, hy
        x0, y0 = self.corner
        return x0, y0, x0 + self.size[0], y0 + self.size[1]

    @property
    def centre(self) -> tuple[float, float]:
        """The floor's centre in the world frame (m): (0, 0) unless it has a ``corner``."""
        if self.corner is None:
            return 0.0, 0.0
        return self.corner[0] + self.size[0] / 2, self.corner[1] + self.size[1] / 2

    def on_floor(self, x: float, y: float) -> bool:
        """Whether (x, y) lies strictly inside the floor's extent."""
        x0, y0, x1, y1 = self.bounds
        return x0 < x < x1 and y0 < y < y1

    def clearance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Distance from points to the nearest obstacle or wall (m); <= 0 outside the floor."""
        x0, y0, x1, y1 = self.bounds
        d = np.minimum(np.minimum(x1 - x, x - x0), np.minimum(y1 - y, y - y0))
        for obs in self.obstacles:
            d = np.minimum(d, obs.distance(x, y))
        return d

    def grid_axes(self, resolution: float) -> tuple[np.ndarray, np.ndarray]:
        """Cell-centre coordinates along x and y for a grid covering the floor."""
        nx = int(math.ceil(self.size[0] / resolution - 1e-9))
        ny = int(math.ceil(self.size[1] / resolution - 1e-9))
        x0, y0, _, _ = self.bounds
        xs = x0 + resolution * (np.arange(nx) + 0.5)
        ys = y0 + resolution * (np.arange(ny) + 0.5)
        return xs, ys

    def occupancy(self, resolution: float, inflate: float = 0.0) -> np.ndarray:
        """Boolean grid ``[ix, iy]`` over the floor: True where a cell centre lies within
        ``inflate`` metres of an obstacle or wall (or inside one).

        Cell (0, 0) is centred at ``(x_min + res/2, y_min + res/2)`` (:attr:`bounds`).
        """
        xs, ys = self.grid_axes(resolution)
        return self.within(xs, ys, inflate)

    def within(self, xs: np.ndarray, ys: np.ndarray, distance: float) -> np.ndarray:
        """Boolean grid ``[ix, iy]`` over the points (``xs[ix]``, ``ys[iy]``): True where
        :meth:`clearance` is ``<= distance`` (m), bit for bit (:meth:`within_levels` for one distance)."""
        return self.within_levels(xs, ys, (distance,))[0]

    def within_levels(self, xs: np.ndarray, ys: np.ndarray, distances: tuple[float, ...]) -> np.ndarray:
        """Boolean grids ``[k, ix, iy]`` over increasing ``xs`` and ``ys``: True where :meth:`clearance` at (``xs[ix]``, ``ys[iy]``)
        is ``<= distances[k]`` (m), bit for bit, all distances in one pass.

        The same per-point arithmetic as :meth:`clearance` (compiled, :mod:`bulletnav.sim.kernels`),
        but each obstacle is measured only on the window of cells its footprint grown by the
        largest distance can reach (a cell farther than its bounding circle plus that distance plus
        a cell's margin cannot be within it), so the cost follows the obstacles' area, not floor
        area times obstacle count.
        """
        x0, y0, x1, y1 = self.bounds
        xs = np.ascontiguousarray(xs, dtype=np.float64)
        ys = np.ascontiguousarray(ys, dtype=np.float64)
        levels = np.asarray(distances, dtype=np.float64)
        gx = xs[:, None]
        gy = ys[None, :]
        walls = np.minimum(np.minimum(x1 - gx, gx - x0), np.minimum(y1 - gy, gy - y0))
        out = walls[None, :, :] <= levels[:, None, None]
        if not self.obstacles:
            return out
        # cell spacing (grids are uniform; a single point has none) widens the window conservatively
        margin = float(max(np.max(np.diff(xs), initial=0.0), np.max(np.diff(ys), initial=0.0))) + 1e-6
        farthest = float(levels.max())
        for obs in self.obstacles:
            reach = obs.bounding_radius() + farthest + margin
            i0, i1 = np.searchsorted(xs, (obs.center[0] - reach, obs.center[0] + reach))
            j0, j1 = np.searchsorted(ys, (obs.center[1] - reach, obs.center[1] + reach))
            if i0 < i1 and j0 < j1:
                mark_levels(out, xs[i0:i1], ys[j0:j1], int(i0), int(j0), *obs.footprint(), levels)
        return out


# --------------------------------------------------------------------------- YAML


def _num(value: Any, where: str, field_name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise LayoutError(f"{where}: field '{field_name}' must be a finite number, got {show(value)}")
    return float(value)


def _vec(value: Any, n: int, where: str, field_name: str) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != n:
        raise LayoutError(f"{where}: field '{field_name}' must be a list of {n} numbers, got {show(value)}")
    return tuple(_num(v, where, f"{field_name}[{i}]") for i, v in enumerate(value))


def _positive(value: float, where: str, field_name: str) -> float:
    if value <= 0:
        raise LayoutError(f"{where}: field '{field_name}' must be > 0, got {value}")
    return value


def _parse_obstacle(raw: Any, where: str, index: int, tag: str = "") -> Obstacle:
    tag = tag or f"obstacles[{index}]"
    if not isinstance(raw, dict):
        raise LayoutError(f"{where}: {tag} must be a mapping, got {show(raw)}")
    kind = raw.get("type")
    if kind not in ("box", "cylinder"):
        raise LayoutError(f"{where}: field '{tag}.type' must be 'box' or 'cylinder', got {show(kind)}")
    allowed = {"type", "center", "yaw", "label"} | ({"size"} if kind == "box" else {"radius", "height"})
    unknown = sorted(set(raw) - allowed, key=str)
    if unknown:
        raise LayoutError(f"{where}: {tag} ({kind}) has unknown field(s) {unknown}; allowed: {sorted(allowed)}")
    for required in ("center", "size") if kind == "box" else ("center", "radius", "height"):
        if required not in raw:
            raise LayoutError(f"{where}: field '{tag}.{required}' is missing")
    center = _vec(raw["center"], 2, where, f"{tag}.center")
    yaw = _num(raw.get("yaw", 0.0), where, f"{tag}.yaw")
    label = str(raw.get("label", kind))
    if kind == "box":
        size = _vec(raw["size"], 3, where, f"{tag}.size")
        for i, s in enumerate(size):
            _positive(s, where, f"{tag}.size[{i}]")
        return Obstacle("box", center, size=size, yaw=yaw, label=label)  # type: ignore[arg-type]
    radius = _positive(_num(raw["radius"], where, f"{tag}.radius"), where, f"{tag}.radius")
    height = _positive(_num(raw["height"], where, f"{tag}.height"), where, f"{tag}.height")
    return Obstacle("cylinder", center, radius=radius, height=height, yaw=yaw, label=label)  # type: ignore[arg-type]


def parse_layout(data: Any, where: str = "<layout>") -> Layout:
    """Validate a decoded YAML document and build a :class:`Layout`.

    Raises:
        LayoutError: naming ``where`` (the file), the field and the problem.
    """
    if not isinstance(data, dict):
        raise LayoutError(f"{where}: top level must be a mapping with 'size' and 'obstacles', got {type(data).__name__}")
    unknown = sorted(set(data) - {"name", "size", "corner", "wall_height", "obstacles", "start", "goal", "goals",
                                  "dynamic", "events"}, key=str)
    if unknown:
        raise LayoutError(f"{where}: unknown top-level field(s) {unknown}")
    if "size" not in data:
        raise LayoutError(f"{where}: field 'size' is missing")
    size = _vec(data["size"], 2, where, "size")
    for i, s in enumerate(size):
        if s <= 2.0:
            raise LayoutError(f"{where}: field 'size[{i}]' must be > 2 m, got {s}")
        _limit("world_size", s, where, f"size[{i}]")
    wall_height = _positive(_num(data.get("wall_height", 2.0), where, "wall_height"), where, "wall_height")
    raw_obstacles = data.get("obstacles", [])
    if raw_obstacles is None:
        raw_obstacles = []
    if not isinstance(raw_obstacles, list):
        raise LayoutError(f"{where}: field 'obstacles' must be a list, got {type(raw_obstacles).__name__}")
    _limit("obstacles", len(raw_obstacles), where, "obstacles (entries)")
    for key, name in (("dynamic", "movers"), ("events", "events")):
        if isinstance(data.get(key), list):
            _limit(name, len(data[key]), where, f"{key} (entries)")
    obstacles = tuple(_parse_obstacle(o, where, i) for i, o in enumerate(raw_obstacles))
    corner = _parse_corner(data.get("corner"), where)
    _check_on_floor(Layout(size, (), corner=corner), obstacles, where)  # type: ignore[arg-type]
    layout = Layout(size, obstacles, wall_height, str(data.get("name", "")), source=where,  # type: ignore[arg-type]
                    corner=corner)
    start = goal = None
    if data.get("start") is not None:
        start = _vec(data["start"], 3, where, "start")
        _check_free(layout, start[:2], where, "start")
    if data.get("goal") is not None:
        goal = _vec(data["goal"], 2, where, "goal")
        _check_free(layout, goal, where, "goal")
    dynamic = _parse_dynamic(data.get("dynamic"), layout, where)
    events = _parse_events(data.get("events"), layout, where)
    goals: tuple[tuple[float, ...], ...] = ()
    if data.get("goals") is not None:
        raw = data["goals"]
        if not isinstance(raw, list) or not raw:
            raise LayoutError(f"{where}: field 'goals' must be a non-empty list of [x, y] points, got {show(raw)}")
        _limit("goals", len(raw), where, "goals (entries)")
        goals = tuple(_vec(g, 2, where, f"goals[{i}]") for i, g in enumerate(raw))
        for i, g in enumerate(goals):
            _check_free(layout, g, where, f"goals[{i}]")
    return Layout(size, obstacles, wall_height, layout.name, start, goal, where, dynamic, events,  # type: ignore[arg-type]
                  goals, corner=corner)  # type: ignore[arg-type]


def _parse_corner(value: Any, where: str) -> tuple[float, float] | None:
    """A layout's ``corner`` (the floor's lower-left corner, m) or None (a centred floor)."""
    if value is None:
        return None
    from bulletnav.sim.mapserver import MAX_ORIGIN

    corner = _vec(value, 2, where, "corner")
    if max(abs(corner[0]), abs(corner[1])) > MAX_ORIGIN:
        raise LayoutError(f"{where}: field 'corner' must be within {MAX_ORIGIN:g} m of the origin, got {list(corner)}")
    return corner  # type: ignore[return-value]


def _check_on_floor(floor: Layout, obstacles: tuple[Obstacle, ...], where: str) -> None:
    """Every obstacle's footprint within ``floor``'s extent (1 nm of slack)."""
    x0, y0, x1, y1 = floor.bounds
    cx, cy = floor.centre
    hx, hy = floor.half_extents
    for i, obs in enumerate(obstacles):
        r = obs.bounding_radius() if obs.kind == "cylinder" else None
        dx, dy = obs.center[0] - cx, obs.center[1] - cy
        if obs.kind == "cylinder":
            inside = abs(dx) + r <= hx + 1e-9 and abs(dy) + r <= hy + 1e-9  # type: ignore[operator]
        else:
            c, s = math.cos(obs.yaw), math.sin(obs.yaw)
            ex = abs(c) * obs.size[0] / 2 + abs(s) * obs.size[1] / 2
            ey = abs(s) * obs.size[0] / 2 + abs(c) * obs.size[1] / 2
            inside = abs(dx) + ex <= hx + 1e-9 and abs(dy) + ey <= hy + 1e-9
        if not inside:
            raise LayoutError(
                f"{where}: obstacles[{i}] at center {list(obs.center)} extends outside the floor "
                f"(x in [{x0}, {x1}], y in [{y0}, {y1}])"
            )


def _points(value: Any, where: str, field_name: str, layout: Layout) -> tuple[tuple[float, float], ...]:
    if not isinstance(value, list) or len(value) < 2:
        raise LayoutError(f"{where}: field '{field_name}' must be a list of at least 2 [x, y] points, got {show(value)}")
    pts = tuple(_vec(v, 2, where, f"{field_name}[{i}]") for i, v in enumerate(value))
    for i, xy in enumerate(pts):
        _check_free(layout, xy, where, f"{field_name}[{i}]")
    for i, (a, b) in enumerate(zip(pts, pts[1:])):
        if a == b:
            raise LayoutError(f"{where}: field '{field_name}' repeats point {i} ({list(a)}): segments need length")
    return pts  # type: ignore[return-value]


def _parse_dynamic(raw: Any, layout: Layout, where: str) -> tuple[MoverSpec, ...]:

    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise LayoutError(f"{where}: field 'dynamic' must be a list, got {type(raw).__name__}")
    out: list[MoverSpec] = []
    for i, entry in enumerate(raw):
        tag = f"dynamic[{i}]"
        if not isinstance(entry, dict):
            raise LayoutError(f"{where}: {tag} must be a mapping, got {show(entry)}")
        kind = entry.get("type")
        allowed = {"forklift": {"type", "route", "speed", "size", "accel", "yield_to_robot"},
                   "worker": {"type", "waypoints", "speed", "radius", "height", "pause", "yield_to_robot"}}
        if not isinstance(kind, str) or kind not in allowed:
            raise LayoutError(f"{where}: field '{tag}.type' must be 'forklift' or 'worker', got {show(kind)}")
        unknown = sorted(set(entry) - allowed[kind], key=str)
        if unknown:
            raise LayoutError(f"{where}: {tag} ({kind}) has unknown field(s) {unknown}; allowed: {sorted(allowed[kind])}")
        path_key = "route" if kind == "forklift" else "waypoints"
        if path_key not in entry:
            raise LayoutError(f"{where}: field '{tag}.{path_key}' is missing")
        path = _points(entry[path_key], where, f"{tag}.{path_key}", layout)
        yield_ = entry.get("yield_to_robot", True)
        if not isinstance(yield_, bool):
            raise LayoutError(f"{where}: field '{tag}.yield_to_robot' must be true or false, got {show(yield_)}")
        speed = _positive(_num(entry.get("speed", 0.5 if kind == "forklift" else 1.0), where, f"{tag}.speed"),
                          where, f"{tag}.speed")
        if kind == "forklift":
            size = _vec(entry.get("size", [1.1, 0.8, 2.0]), 3, where, f"{tag}.size")
            for k, v in enumerate(size):
                _positive(v, where, f"{tag}.size[{k}]")
            accel = entry.get("accel")
            if accel is not None:
                accel = _positive(_num(accel, where, f"{tag}.accel"), where, f"{tag}.accel")
            out.append(ForkliftSpec(path, speed, size, accel, yield_))  # type: ignore[arg-type]
        else:
            radius = _positive(_num(entry.get("radius", 0.25), where, f"{tag}.radius"), where, f"{tag}.radius")
            height = _positive(_num(entry.get("height", 1.7), where, f"{tag}.height"), where, f"{tag}.height")
            pause = _num(entry.get("pause", 1.0), where, f"{tag}.pause")
            if pause < 0:
                raise LayoutError(f"{where}: field '{tag}.pause' must be >= 0, got {pause}")
            out.append(WorkerSpec(path, speed, radius, height, pause, yield_))
    return tuple(out)


def _parse_events(raw: Any, layout: Layout, where: str) -> tuple[EventSpec, ...]:

    if raw is None:
        return ()
    if not isinstance(raw, list):
        raise LayoutError(f"{where}: field 'events' must be a list, got {type(raw).__name__}")
    labels = {o.label for o in layout.obstacles}
    out = []
    for i, entry in enumerate(raw):
        tag = f"events[{i}]"
        if not isinstance(entry, dict):
            raise LayoutError(f"{where}: {tag} must be a mapping, got {show(entry)}")
        unknown = sorted(set(entry) - {"at", "add", "remove"}, key=str)
        if unknown:
            raise LayoutError(f"{where}: {tag} has unknown field(s) {unknown}; allowed: ['add', 'at', 'remove']")
        if "at" not in entry:
            raise LayoutError(f"{where}: field '{tag}.at' is missing")
        at = _num(entry["at"], where, f"{tag}.at")
        if at < 0:
            raise LayoutError(f"{where}: field '{tag}.at' must be >= 0 s, got {at}")
        if ("add" in entry) == ("remove" in entry):
            raise LayoutError(f"{where}: {tag} needs exactly one of 'add' (an obstacle entry) or 'remove' (a label)")
        if "add" in entry:
            o = _parse_obstacle(entry["add"], where, i, tag=f"{tag}.add")
            if not layout.on_floor(o.center[0], o.center[1]):
                raise LayoutError(f"{where}: field '{tag}.add.center' {list(o.center)} lies outside the floor")
            labels.add(o.label)
            out.append(EventSpec(at, add=o))
        else:
            label = entry["remove"]
            if not isinstance(label, str) or label not in labels:
                raise LayoutError(f"{where}: field '{tag}.remove' must name the label of an obstacle or of an earlier "
                                  f"'add', got {show(label)}; labels: {sorted(labels)}")
            out.append(EventSpec(at, remove=label))
    return tuple(sorted(out, key=lambda e: e.at))


def _limit(name: str, value: float, where: str, field_name: str) -> None:
    """:func:`bulletnav.limits.check` as a :class:`LayoutError` naming the file."""
    try:
        limits.check(name, value, f"field '{field_name}'")
    except LimitError as exc:
        raise LayoutError(f"{where}: {exc}") from None


def _check_free(layout: Layout, xy: tuple[float, ...], where: str, field_name: str) -> None:
    if not layout.on_floor(xy[0], xy[1]):
        raise LayoutError(f"{where}: field '{field_name}' {list(xy)} lies outside the floor")
    for i, obs in enumerate(layout.obstacles):
        if float(obs.distance(np.array(xy[0]), np.array(xy[1]))) <= 0.0:
            raise LayoutError(f"{where}: field '{field_name}' {list(xy)} lies inside obstacles[{i}]")


def load_layout(path: str | Path) -> Layout:
    """Read and validate a YAML layout file, a ROS map_server map YAML or a Gazebo SDF world
    (the last two: :mod:`bulletnav.sim.userworld`).

    Raises:
        LayoutError: the file is missing, is not YAML, or a field is wrong (named in the message).
    """
    from bulletnav.sim import userworld  # a user's own maps

    path = Path(path)
    if userworld.is_sdf(path):
        return Layout(**userworld.load_sdf(path))
    userworld.refuse_wrong_kind(path)
    data = read_yaml(path, "layout file", LayoutError)
    if userworld.is_user_map(data):
        return Layout(**userworld.load_user_map(path, data))
    return parse_layout(data, str(path))


def layout_to_dict(layout: Layout) -> dict[str, Any]:
    """The YAML-ready form of a layout (inverse of :func:`parse_layout`)."""
    out: dict[str, Any] = {"name": layout.name, "size": list(layout.size), "wall_height": layout.wall_height}
    if layout.corner is not None:
        out["corner"] = list(layout.corner)
    out["obstacles"] = [_obstacle_to_dict(o) for o in layout.obstacles]
    if layout.start is not None:
        out["start"] = list(layout.start)
    if layout.goal is not None:
        out["goal"] = list(layout.goal)
    if layout.goals:
        out["goals"] = [list(g) for g in layout.goals]
    if layout.dynamic:
        out["dynamic"] = [_mover_to_dict(m) for m in layout.dynamic]
    if layout.events:
        out["events"] = [{"at": e.at, **({"add": _obstacle_to_dict(e.add)} if e.add is not None else {"remove": e.remove})}
                         for e in layout.events]
    return out


def _obstacle_to_dict(o: Obstacle) -> dict[str, Any]:
    if o.kind == "box":
        return {"type": "box", "center": list(o.center), "size": list(o.size), "yaw": o.yaw, "label": o.label}
    return {"type": "cylinder", "center": list(o.center), "radius": o.radius, "height": o.height, "label": o.label}


def _mover_to_dict(m: MoverSpec) -> dict[str, Any]:
    if m.kind == "forklift":
        out = {"type": "forklift", "route": [list(q) for q in m.route], "speed": m.speed, "size": list(m.size),
               "yield_to_robot": m.yield_to_robot}
        if m.accel is not None:
            out["accel"] = m.accel
        return out
    return {"type": "worker", "waypoints": [list(q) for q in m.waypoints], "speed": m.speed, "radius": m.radius,
            "height": m.height, "pause": m.pause, "yield_to_robot": m.yield_to_robot}


# --------------------------------------------------------------------------- procedural


_CATEGORY_SHARES = (("rack", 0.20), ("column", 0.13), ("pallet", 0.32))  # boxes take the rest


def _category_counts(n: int) -> dict[str, int]:
    counts = {name: int(round(share * n)) for name, share in _CATEGORY_SHARES}
    while sum(counts.values()) > n:  # only possible for tiny n
        largest = max(counts, key=counts.__getitem__)
        counts[largest] -= 1
    counts["box"] = n - sum(counts.values())
    return counts


def generate_warehouse(rng: np.random.Generator, config: WorldConfig = WorldConfig()) -> Layout:
    """A seeded procedural warehouse: racks along aisles, columns, loaded pallets and boxes.

    Obstacles are placed by rejection sampling so that every pair of footprints, and every
    footprint and wall, is at least ``config.min_gap`` apart (checked on a 5 cm raster,
    conservatively); with a gap wider than the robot the free space stays connected.

    Raises:
        LayoutError: when ``config.num_obstacles`` cannot be placed on the floor.
    """
    hx, hy = config.size[0] / 2, config.size[1] / 2
    aisle_yaw = float(rng.choice([0.0, math.pi / 2]))
    counts = _category_counts(config.num_obstacles)
    order = ("rack", "pallet", "column", "box")  # big things first: they are hardest to fit
    kinds = np.array([code for kind, code in zip(order, (RACK, PALLET, COLUMN, CRATE)) for _ in range(counts[kind])],
                     dtype=np.int64)
    claimed = _Raster(config.size, _RASTER)
    rows = np.zeros((len(kinds), 9))
    n = place_obstacles(rng, kinds, config.max_placement_tries, hx, hy, config.min_gap, aisle_yaw, claimed.grid,
                        claimed.xs, claimed.ys, _RASTER, rows)
    if n < len(kinds):
        raise LayoutError(
            f"procedural warehouse: could not place obstacle {n + 1} of {config.num_obstacles} "
            f"({order[int(kinds[n])]}) on a {config.size[0]} x {config.size[1]} m floor with min_gap={config.min_gap} m; "
            "use fewer obstacles, a larger floor or a smaller gap"
        )
    placed = [Obstacle("cylinder" if row[0] == 1.0 else "box", (float(row[7]), float(row[8])),
                       (float(row[1]), float(row[2]), float(row[3])), float(row[4]), float(row[5]), float(row[6]),
                       order[int(code)])
              for row, code in zip(rows, kinds)]
    return Layout(config.size, tuple(placed), config.wall_height, name="procedural", source="procedural")


_RASTER = 0.05
"""Cell size of the placement raster (m)."""


class _Raster:
    """A boolean raster of claimed floor (footprints dilated by the gap) and its cell centres, for
    the placement kernel (:func:`bulletnav.sim.kernels.place_obstacles`)."""

    def __init__(self, size: tuple[float, float], res: float) -> None:
        self.res = res
        self.hx, self.hy = size[0] / 2, size[1] / 2
        self.grid = np.zeros((int(math.ceil(size[0] / res)), int(math.ceil(size[1] / res))), dtype=bool)
        # cell centres, computed as the array code always did: -h + res * (index + 0.5)
        self.xs = -self.hx + self.res * (np.arange(self.grid.shape[0]) + 0.5)
        self.ys = -self.hy + self.res * (np.arange(self.grid.shape[1]) + 0.5)


