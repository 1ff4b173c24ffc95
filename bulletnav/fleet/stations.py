"""Pick and drop stations of a warehouse layout, and the seeded stream of errands between them.

**Pick stations** stand in front of rack faces: along each long face of every obstacle
labelled ``rack``, ``station_offset`` (0.55 m) out from the face, one every
``station_spacing`` (1 m). **Drop stations** line the dock: one wall (``dock_wall``; with
``"auto"`` the wall with the most stations along it), ``station_offset`` from it, one every
``station_spacing``; where racks line every wall, the dock is the first line farther in (in
steps of ``DOCK_STEP``, up to 3 m) with free floor along some wall: the aisle in front of the
racks. A station is kept where the floor around it is free (more than the
sampler's clearance, 0.4 m, from every obstacle and wall: a pallet stacked against a rack
takes the stations in front of it) and where it is reachable for the robot's disc. Of the
connected regions of the floor the one holding the most stations is used, so every station
is reachable from every other and from every robot's start.

A YAML world may name its stations instead, in a top-level ``stations:`` mapping with
``pick:`` and ``drop:`` lists of ``[x, y]`` points (or the env's ``pick_stations`` /
``drop_stations`` arguments); named stations must lie in free, reachable floor. A user's own
map (a map_server map YAML or a wrapper naming a map or a Gazebo world,
:mod:`bulletnav.sim.userworld`) takes the same ``stations:`` section, in the map's frame; a
Gazebo world file itself has no place for them, and a user map has no obstacle labelled
``rack``, so such a world needs its pick stations named (in a wrapper, or as ``pick_stations``).

**Errands**: :class:`ErrandStream` draws, from its own seeded generator, a pick station and
a drop station for a robot whenever it needs a new errand, avoiding the stations other
robots are heading for while any other is left.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import ConfigError, LayoutError
from bulletnav.sim.layout import Layout, parse_layout
from bulletnav.sim.sampler import FreeSpace
from bulletnav.yamlfile import read_yaml

Point = tuple[float, float]


@dataclass(frozen=True)
class Stations:
    """The stations of one layout (x, y in m) and the floor region they lie in."""

    pick: tuple[Point, ...]
    drop: tuple[Point, ...]
    component: int
    """Label of the free-space region (:attr:`FreeSpace.component`) every station lies in."""
    dock_wall: str
    """The wall the drop stations line, or ``"named"`` when they were given."""


@dataclass(frozen=True)
class Errand:
    """One job of a robot: drive to ``pick``, then to ``drop``."""

    id: int
    """Errand number within the episode (over all robots, in the order assigned)."""
    pick: Point
    drop: Point

    def as_dict(self, leg: str) -> dict[str, Any]:
        return {"id": self.id, "pick": self.pick, "drop": self.drop, "leg": leg}


def load_world(path: str | Path) -> tuple[Layout, dict[str, tuple[Point, ...]]]:
    """A YAML layout file and its optional ``stations:`` section (``pick`` and ``drop`` point lists).

    Raises:
        LayoutError: the file is missing or malformed (the message names the file and field).
    """
    from bulletnav.sim import userworld  # a user's own maps

    path = Path(path)
    if userworld.is_sdf(path):
        return Layout(**userworld.load_sdf(path)), {}
    data = read_yaml(path, "layout file", LayoutError)
    named: dict[str, tuple[Point, ...]] = {}
    if isinstance(data, dict) and "stations" in data:
        data = dict(data)
        raw = data.pop("stations")
        if not isinstance(raw, dict) or set(raw) - {"pick", "drop"}:
            raise LayoutError(f"{path}: field 'stations' must be a mapping with 'pick' and/or 'drop' point lists")
        for key, points in raw.items():
            named[key] = points_arg(points, f"{path}: field 'stations.{key}'", LayoutError)
    if userworld.is_user_map(data):  # stations in the map's frame, as its start and goal
        layout = Layout(**userworld.load_user_map(path, data))
        return layout, named
    return parse_layout(data, str(path)), named


def points_arg(value: Any, name: str, error: type[Exception] = ConfigError) -> tuple[Point, ...]:
    """``value`` as a non-empty tuple of (x, y) float pairs; ``error`` names ``name`` otherwise."""
    try:
        points = tuple((float(x), float(y)) for x, y in value)
    except (TypeError, ValueError):
        raise error(f"{name} must be a list of [x, y] points, got {value!r}") from None
    if not points or not all(math.isfinite(v) for pt in points for v in pt):
        raise error(f"{name} must be a non-empty list of finite [x, y] points, got {value!r}")
    return points


def rack_faces(layout: Layout, offset: float, spacing: float) -> list[Point]:
    """Candidate pick points in front of both long faces of every box labelled ``rack``."""
    out: list[Point] = []
    for o in layout.obstacles:
        if o.label != "rack" or o.kind != "box":
            continue
        long_axis = 0 if o.size[0] >= o.size[1] else 1
        length, depth = o.size[long_axis], o.size[1 - long_axis]
        c, s = math.cos(o.yaw), math.sin(o.yaw)
        axes = ((c, s), (-s, c))
        t, n = axes[long_axis], axes[1 - long_axis]
        count = max(1, int(length // spacing))
        for side in (1.0, -1.0):
            fx = o.center[0] + side * n[0] * (depth / 2 + offset)
            fy = o.center[1] + side * n[1] * (depth / 2 + offset)
            for k in range(count):
                along = (k + 0.5) * length / count - length / 2
                out.append((fx + t[0] * along, fy + t[1] * along))
    return out


def wall_points(layout: Layout, wall: str, offset: float, spacing: float) -> list[Point]:
    """Candidate drop points along one wall, ``offset`` m from it."""
    hx, hy = layout.half_extents
    x0, y0, x1, y1 = layout.bounds
    cx, cy = layout.centre
    length = 2 * (hx if wall in ("south", "north") else hy)
    count = max(1, int(length // spacing))
    along = [(k + 0.5) * length / count - length / 2 for k in range(count)]
    if wall == "south":
        return [(cx + a, y0 + offset) for a in along]
    if wall == "north":
        return [(cx + a, y1 - offset) for a in along]
    if wall == "west":
        return [(x0 + offset, cy + a) for a in along]
    return [(x1 - offset, cy + a) for a in along]


def _keep(points: list[Point], layout: Layout, free: FreeSpace, clearance: float) -> list[tuple[Point, int]]:
    """The points with more than ``clearance`` to every obstacle and wall, with their region label."""
    if not points:
        return []
    xy = np.asarray(points, dtype=float)
    clear = layout.clearance(xy[:, 0], xy[:, 1]) > clearance
    out = []
    for pt, ok in zip(points, clear.tolist()):
        label = int(free.component[free.cell(pt)])
        if ok and label != 0:
            out.append((pt, label))
    return out


DOCK_STEP = 0.25
"""Where no wall has free floor ``station_offset`` from it (racks line every wall), the dock's
line moves in by this much (m) at a time ..."""
DOCK_STEPS = 12
"""... at most this many times (3 m): the first line with a free station on some wall is the dock."""


def find_stations(layout: Layout, free: FreeSpace, clearance: float, offset: float, spacing: float,
                  dock_wall: str = "auto", named: dict[str, tuple[Point, ...]] | None = None) -> Stations:
    """The pick and drop stations of ``layout`` (see the module docstring).

    Args:
        layout: the world.
        free: its free space for the robot's disc (reachability).
        clearance: least distance (m) from a station to any obstacle or wall (the sampler's).
        offset: distance (m) of derived stations from their rack face or wall.
        spacing: distance (m) between neighbouring derived stations.
        dock_wall: ``"auto"`` or a wall name (south -y, north +y, west -x, east +x).
        named: stations given by the world file or the env's arguments (keys ``pick``, ``drop``).

    Raises:
        ConfigError: the world has no pick or no drop station, no region holding both, or
            a named station lies in an obstacle or out of reach (the message says which).
    """
    named = named or {}
    where = layout.source or layout.name or "the world"
    if "pick" in named:
        pick = _named(named["pick"], layout, free, clearance, "pick_stations")
    else:
        pick = _keep(rack_faces(layout, offset, spacing), layout, free, clearance)
        if not pick:
            raise ConfigError(f"{where} has no pick stations: no free floor {offset} m in front of a rack "
                              f"(no obstacle labelled 'rack'?); name them with pick_stations=[(x, y), ...] "
                              f"or a 'stations: {{pick: [...]}}' section in the world file")
    if "drop" in named:
        drop = _named(named["drop"], layout, free, clearance, "drop_stations")
        wall = "named"
    else:
        walls = ("south", "north", "west", "east") if dock_wall == "auto" else (dock_wall,)
        for step in range(DOCK_STEPS + 1):  # racks along every wall: the dock moves in, to the first free aisle
            at = offset + step * DOCK_STEP
            options = [(w, _keep(wall_points(layout, w, at, spacing), layout, free, clearance)) for w in walls]
            wall, drop = max(options, key=lambda item: len(item[1]))  # the first of equals: a fixed order
            if drop:
                break
        if not drop:
            raise ConfigError(f"{where} has no drop stations: no free floor {offset}-{offset + DOCK_STEPS * DOCK_STEP:g} m "
                              f"from the {'walls' if dock_wall == 'auto' else dock_wall + ' wall'} (dock_wall={dock_wall!r}); "
                              f"name them with drop_stations=[(x, y), ...] or 'stations: {{drop: [...]}}' in the world file")
    counts: dict[int, list[int]] = {}
    for _, label in pick:
        counts.setdefault(label, [0, 0])[0] += 1
    for _, label in drop:
        counts.setdefault(label, [0, 0])[1] += 1
    both = {label: n for label, n in counts.items() if n[0] and n[1]}
    if not both:
        raise ConfigError(f"{where}: no pick station can reach a drop station (they lie in separate regions of the floor)")
    region = max(sorted(both), key=lambda label: sum(both[label]))
    if "pick" in named or "drop" in named:
        for name, kept in (("pick_stations", pick), ("drop_stations", drop)):
            cut = [pt for pt, label in kept if label != region]
            if cut and name[:4] in named:
                raise ConfigError(f"{where}: {name} {cut[0]} cannot be reached from the other stations")
    return Stations(tuple(pt for pt, label in pick if label == region), tuple(pt for pt, label in drop if label == region),
                    region, wall)


def _named(points: tuple[Point, ...], layout: Layout, free: FreeSpace, clearance: float, name: str
           ) -> list[tuple[Point, int]]:
    kept = _keep(list(points), layout, free, clearance)
    if len(kept) != len(points):
        bad = next(pt for pt in points if pt not in {k for k, _ in kept})
        raise ConfigError(f"{name}: station {bad} is not free, reachable floor (it must lie more than "
                          f"{clearance} m from every obstacle and wall)")
    return kept


class ErrandStream:
    """The seeded sequence of errands of one episode.

    Args:
        rng: the stream's own generator (drawn from the env's at reset).
        stations: where errands go.
    """

    def __init__(self, rng: np.random.Generator, stations: Stations) -> None:
        self.rng = rng
        self.stations = stations
        self.issued = 0
        """Errands handed out so far this episode."""

    def next(self, busy: set[Point] = frozenset()) -> Errand:  # type: ignore[assignment]
        """A new errand whose stations are not in ``busy`` (the other robots' targets) while
        free stations are left."""
        pick = self._draw(self.stations.pick, busy)
        drop = self._draw(self.stations.drop, busy)
        errand = Errand(self.issued, pick, drop)
        self.issued += 1
        return errand

    def _draw(self, points: tuple[Point, ...], busy: set[Point]) -> Point:
        options = [pt for pt in points if pt not in busy] or list(points)
        return options[int(self.rng.integers(len(options)))]
