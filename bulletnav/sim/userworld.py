"""A user's own maps as bulletnav layouts: a ROS ``map_server`` / Nav2 map YAML (with its PGM or
PNG image) or a Gazebo SDF world, given wherever a layout file is (``world=PATH``, ``--world PATH``).

:func:`~bulletnav.sim.layout.load_layout` sends a file here when it is SDF (suffix ``.world`` or
``.sdf``, or text starting ``<?xml`` or ``<sdf``) or a YAML mapping with ``image`` (a map_server
map: its other fields are checked as map_server's, a misspelt one named with the nearest) or with
``map`` and no ``size`` (a wrapper naming one). An image or a saved model given as a world is
refused with what belongs there (:func:`refuse_wrong_kind`). The functions here return the
:class:`~bulletnav.sim.layout.Layout`'s fields, which ``load_layout`` builds (so this module does
not import the layout module that imports it)::

    map: site.yaml          # a map_server map YAML or a Gazebo world, relative to this file
    start: [1.0, 2.0, 0.0]  # optional x, y, yaw in the map's frame (else sampled as for any layout)
    goal: [8.5, 3.0]        # optional x, y in the map's frame
    unknown: free           # map_server maps: unknown cells are walls unless this says free
    height: 2.0             # map_server maps: height of the walls built from occupied cells (m)
    margin: 1.0             # Gazebo worlds: floor beyond the shapes' extent on every side (m)
    name: my-site

The same keys (all but ``map``) may stand in the map_server YAML itself: ``map_server`` reads only
its own keys. The world lives in the file's own frame: the floor's lower-left corner
(``Layout.corner``) is the map's ``origin`` (a Gazebo world: its shapes' extent less the margin),
so the PyBullet bodies, every pose and path the env reports, the lidar map and a recording's
``/tf`` and ``/map`` are all in the map's coordinates, and start and goal are given in them.

A map_server map: each cell's value as Nav2 reads it (:mod:`bulletnav.sim.mapserver`); walls where
it is 100 (occupied) and, unless ``unknown: free``, -1 (unknown); values 1-99 (scale and raw modes)
are free, as Nav2's static costmap layer takes them by default (``trinary_costmap: true``,
``lethal_cost_threshold: 100``). The wall cells are merged into few boxes
(:func:`~bulletnav.sim.mapserver.merge_boxes`); the floor is the image's extent. A map whose
``origin`` has a yaw is turned into the map frame: its image is resampled at its own resolution
onto the cells of the axis-aligned rectangle that bounds it, and the cells outside the image are
walls (the edge of the map, as an unturned map's floor ends there). A cell is a wall where any of
nine points over it (its centre, corners and edge midpoints) falls on a wall pixel or off the
image, so every point of a wall pixel within half a cell of its centre stays in a wall (a wall's
very edge may move inward by up to a tenth of a cell; it grows by up to a cell's diagonal).

A Gazebo world: its box and cylinder collisions (:mod:`bulletnav.sim.sdf`); the floor is their
extent grown by ``margin`` on every side (a stock ground plane is 100 m wide: taking its size
would give a floor mostly empty).
"""

from __future__ import annotations

import difflib
import math
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav import limits
from bulletnav.errors import LayoutError, LimitError
from bulletnav.filekinds import wrong_kind
from bulletnav.sim import mapserver, sdf
from bulletnav.sim.mapserver import finite
from bulletnav.sim.specs import Obstacle
from bulletnav.yamlfile import read_yaml, show

SDF_SUFFIXES = (".world", ".sdf")
OPTIONS = {"start", "goal", "unknown", "height", "margin", "name"}
"""bulletnav's keys beside a map (in a wrapper, or in a map_server YAML)."""
MAX_WALL_HEIGHT = 100.0
"""Tallest walls (m) a map_server map's ``height`` may ask for (the default is 2 m)."""
WRAPPER_KEYS = OPTIONS | {"map"}
DEFAULT_HEIGHT = 2.0
"""Height of the walls built from a map_server map's wall cells (m)."""
DEFAULT_MARGIN = 1.0
"""Floor beyond a Gazebo world's shapes on every side (m)."""


def is_sdf(path: Path) -> bool:
    """True for an SDF file: suffix ``.world`` / ``.sdf``, or text starting ``<?xml`` / ``<sdf``."""
    if path.suffix.lower() in SDF_SUFFIXES:
        return True
    try:
        with open(path, "rb") as f:
            head = f.read(256)
    except OSError:
        return False  # the YAML reader names the problem
    head = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    return head.startswith((b"<?xml", b"<sdf"))


def is_user_map(data: Any) -> bool:
    """True for a decoded YAML that is a map_server map (it names an ``image``, map_server's own
    field: its other fields may be misspelt) or a wrapper naming a map."""
    return isinstance(data, dict) and ("image" in data or ("map" in data and "size" not in data))


IMAGE_MAGIC = (b"\x89PNG\r\n\x1a\n", b"P1", b"P2", b"P3", b"P4", b"P5", b"P6", b"\xff\xd8\xff", b"GIF8", b"BM")
"""The first bytes of PNG, the netpbm family (PBM/PGM/PPM), JPEG, GIF and BMP images."""
MODEL_MAGIC = b"PK\x03\x04"
"""The first bytes of a zip archive (a saved model)."""


def refuse_wrong_kind(path: Path) -> None:
    """Refuse, naming what belongs where, a file given as a world that is an image (a map's
    picture: its YAML is the world) or a saved model (a zip archive).

    Raises:
        LayoutError: the file is an image or a zip archive.
    """
    try:
        with open(path, "rb") as f:
            head = f.read(8)
    except OSError:
        return  # the YAML reader names the problem
    if head.startswith(IMAGE_MAGIC) or path.suffix.lower() in (".pgm", ".png", ".pbm", ".ppm", ".jpg", ".jpeg"):
        beside = _yaml_naming(path)
        hint = f"{beside.name} beside it" if beside else f"the .yaml beside it that names {path.name} as its image"
        raise LayoutError(f"{path}: an image, not a world: give the map's YAML ({hint}), not its image")
    if head.startswith(MODEL_MAGIC):
        raise LayoutError(f"{path}: a zip archive (a saved model?), not a world: a model goes to --model; "
                          "a world is a layout or map YAML or a Gazebo .world/.sdf file")
    other = wrong_kind(path, "world")  # a suite, hyperparameters, a recording or a bag given as a world
    if other:
        raise LayoutError(other)


def _yaml_naming(image: Path) -> Path | None:
    """The map YAML in ``image``'s folder whose ``image:`` names it (its namesake first; the
    first 50 YAML files looked at, each under 64 kB), or None."""
    try:
        candidates = sorted((p for p in image.parent.iterdir() if p.suffix.lower() in (".yaml", ".yml")),
                            key=lambda p: (p.stem != image.stem, p.name))[:50]  # its namesake first
    except OSError:
        return None
    for candidate in candidates:
        try:
            if candidate.stat().st_size > 65536:
                continue
            text = candidate.read_text(errors="replace")
        except OSError:
            continue
        for line in text.splitlines():
            key, _, value = line.partition(":")
            if key.strip() == "image" and Path(value.strip().strip("'\"")).name == image.name:
                return candidate
    return None


# --------------------------------------------------------------------------- loading


def load_sdf(path: str | Path, options: dict[str, Any] | None = None, where: str | None = None) -> dict[str, Any]:
    """A Gazebo SDF world as a layout's fields (module docstring); ``options`` are a wrapper's keys."""
    path = Path(path)
    options = options or {}
    where = where or str(path)
    _no_options(options, ("unknown", "height"), where, "a Gazebo world")
    margin = _positive(options.get("margin", DEFAULT_MARGIN), where, "margin", allow_zero=True)
    shapes, _ground, world_name = sdf.read_shapes(path)
    if not shapes:
        raise LayoutError(f"{path}: no box or cylinder collision to build (a world of a ground plane alone)")
    _limit("obstacles", len(shapes), where, "shapes (box and cylinder collisions)")
    points = np.vstack([s.corners() for s in shapes])
    lo, hi = points.min(axis=0), points.max(axis=0)
    size = (float(hi[0] - lo[0] + 2 * margin), float(hi[1] - lo[1] + 2 * margin))
    _floor(size, where)
    obstacles = []
    for s in shapes:
        xy = (float(s.center[0]), float(s.center[1]))
        if s.kind == "box":
            obstacles.append(Obstacle("box", xy, size=(s.size[0], s.size[1], s.top), yaw=s.yaw, label=s.model))
        else:
            obstacles.append(Obstacle("cylinder", xy, radius=s.size[0] / 2, height=s.top, label=s.model))
    name = options.get("name", world_name or path.stem)
    layout = {"size": size, "obstacles": tuple(obstacles), "name": str(name), "source": where,
              "corner": (float(lo[0]) - margin, float(lo[1]) - margin)}
    return _place(layout, options, where, None)


def load_map_yaml(path: Path, data: dict[str, Any], options: dict[str, Any] | None = None,
                  where: str | None = None) -> dict[str, Any]:
    """A map_server map (its decoded YAML ``data``) as a layout's fields (module docstring)."""
    where = where or str(path)
    unknown_keys = [k for k in data if k not in mapserver.KEYS and k not in OPTIONS]
    if unknown_keys:
        key = unknown_keys[0]
        own_options = sorted(OPTIONS - {"margin"})  # margin is for Gazebo worlds
        near = difflib.get_close_matches(str(key), [*mapserver.KEYS, *own_options], n=1)
        hint = f" (did you mean '{near[0]}'?)" if near else ""
        raise LayoutError(f"{where}: unknown map field '{key}'{hint}; a map_server map YAML has "
                          f"{', '.join(mapserver.KEYS)} and bulletnav's {', '.join(own_options)}")
    own = {k: v for k, v in data.items() if k in OPTIONS}
    options = {**own, **(options or {})}
    _no_options(options, ("margin",), where, "a map_server map")
    unknown = options.get("unknown", "occupied")
    if unknown not in ("occupied", "free"):
        raise LayoutError(f"{where}: field 'unknown' must be 'occupied' (walls, the default) or 'free', got {show(unknown)}")
    height = _positive(options.get("height", DEFAULT_HEIGHT), where, "height")
    if height > MAX_WALL_HEIGHT:
        raise LayoutError(f"{where}: field 'height' must be at most {MAX_WALL_HEIGHT:g} m (the walls' height), "
                          f"got {show(options['height'])}")
    meta, grid = mapserver.read_grid(data, str(path))
    ox, oy, oyaw = meta.origin
    res = meta.resolution
    corner = (ox, oy)
    if oyaw != 0.0:  # turned into the map frame: resampled onto the cells of its bounding rectangle
        corner, grid = _turned(grid, res, meta.origin)
    walls = grid == mapserver.OCCUPIED
    if unknown == "occupied":
        walls |= grid == mapserver.UNKNOWN
    try:
        most = limits.current().obstacles
    except LimitError as exc:
        raise LayoutError(f"{where}: {exc}") from None
    boxes = mapserver.merge_boxes(walls, most)
    if boxes is None:  # merging stopped at the limit: a hostile image costs the limit, not its cells
        raise LayoutError(f"{where}: the map's walls need more than {most} boxes (merged wall cells), past the limit "
                          f"obstacles = {most} (raise it with {limits.env_var('obstacles')})")
    _limit("obstacles", len(boxes), where, "boxes (merged wall cells)")
    nx, ny = grid.shape
    size = (nx * res, ny * res)
    _floor(size, where)
    x0, y0 = corner
    obstacles = tuple(Obstacle("box", (x0 + (i0 + i1) * res / 2, y0 + (j0 + j1) * res / 2),
                               size=((i1 - i0) * res, (j1 - j0) * res, height), label="map")
                      for i0, j0, i1, j1 in boxes)
    layout = {"size": size, "obstacles": obstacles, "wall_height": max(height, 0.5),
              "name": str(options.get("name", path.stem)), "source": where, "corner": (float(x0), float(y0))}
    return _place(layout, options, where, (grid, res))


OUTSIDE = mapserver.OCCUPIED
"""The value of a turned map's cells outside its image (walls: the edge of the map)."""


def _turned(grid: np.ndarray, res: float, origin: tuple[float, float, float]) -> tuple[tuple[float, float], np.ndarray]:
    """A map whose origin has a yaw, in the map frame: the lower-left corner of the axis-aligned
    rectangle that bounds its image, and the grid over that rectangle at the same resolution. Each
    cell is looked at in nine points (centre, corners, edge midpoints): occupied (:data:`OUTSIDE`
    off the image) where any is, else unknown where any is, else the value under its centre."""
    ox, oy, yaw = origin
    nx, ny = grid.shape
    c, s = math.cos(yaw), math.sin(yaw)
    ex, ey = np.array([0.0, nx * res, 0.0, nx * res]), np.array([0.0, 0.0, ny * res, ny * res])
    xs, ys = ox + c * ex - s * ey, oy + s * ex + c * ey  # the image's corners in the map frame
    x0, y0 = float(xs.min()), float(ys.min())
    mx = max(1, int(math.ceil((float(xs.max()) - x0) / res - 1e-9)))
    my = max(1, int(math.ceil((float(ys.max()) - y0) / res - 1e-9)))
    try:
        limits.check("map_cells", mx * my, "cells of the turned map")
    except LimitError as exc:
        raise LayoutError(str(exc)) from None
    occupied = np.zeros((mx, my), dtype=bool)
    unknown = np.zeros((mx, my), dtype=bool)
    centre = np.full((mx, my), OUTSIDE, dtype=grid.dtype)
    for fx in (0.5, 0.0, 1.0):
        for fy in (0.5, 0.0, 1.0):
            cx = x0 + res * (np.arange(mx) + fx) - ox
            cy = y0 + res * (np.arange(my) + fy) - oy
            u = (c * cx[:, None] + s * cy[None, :]) / res  # the points in pixel units of the image
            v = (-s * cx[:, None] + c * cy[None, :]) / res
            i, j = np.floor(u).astype(np.int64), np.floor(v).astype(np.int64)
            on = (i >= 0) & (i < nx) & (j >= 0) & (j < ny)
            value = np.full((mx, my), OUTSIDE, dtype=grid.dtype)
            value[on] = grid[i[on], j[on]]
            occupied |= value == mapserver.OCCUPIED
            unknown |= value == mapserver.UNKNOWN
            if fx == fy == 0.5:
                centre = value
    out = np.where(occupied, mapserver.OCCUPIED, np.where(unknown, mapserver.UNKNOWN, centre)).astype(grid.dtype)
    return (x0, y0), out


def load_user_map(path: Path, data: dict[str, Any]) -> dict[str, Any]:
    """A map_server map YAML, or a wrapper (``map:`` plus options) naming one or a Gazebo world,
    as a layout's fields."""
    where = str(path)
    if "map" not in data or ("image" in data and "resolution" in data):
        return load_map_yaml(path, data)
    unknown_keys = sorted(set(data) - WRAPPER_KEYS, key=str)
    if unknown_keys:
        raise LayoutError(f"{where}: unknown field(s) {unknown_keys}; a map wrapper has {sorted(WRAPPER_KEYS)}")
    target = data["map"]
    if not isinstance(target, str) or not target.strip():
        raise LayoutError(f"{where}: field 'map' must name a map_server YAML or a Gazebo world file, got {show(target)}")
    target_path = Path(target) if Path(target).is_absolute() else path.parent / target
    options = {k: v for k, v in data.items() if k != "map"}
    if not target_path.is_file():
        raise LayoutError(f"{where}: field 'map' names {target_path}, which does not exist")
    if is_sdf(target_path):
        return load_sdf(target_path, options, where=f"{where} (map {target_path})")
    inner = read_yaml(target_path, "map file", LayoutError)
    if not (isinstance(inner, dict) and "image" in inner and "resolution" in inner):
        raise LayoutError(f"{where}: field 'map' names {target_path}, neither a map_server map YAML "
                          "(image, resolution, ...) nor a Gazebo world (.world, .sdf)")
    return load_map_yaml(target_path, inner, options, where=f"{where} (map {target_path})")


# --------------------------------------------------------------------------- helpers


def _no_options(options: dict[str, Any], keys: tuple[str, ...], where: str, kind: str) -> None:
    given = [k for k in keys if k in options]
    if given:
        raise LayoutError(f"{where}: field '{given[0]}' does not apply to {kind}")


def _positive(value: Any, where: str, field_name: str, allow_zero: bool = False) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not finite(value) or (
            value < 0 if allow_zero else value <= 0):
        raise LayoutError(f"{where}: field '{field_name}' must be a {'non-negative' if allow_zero else 'positive'} "
                          f"number of metres, got {show(value)}")
    return float(value)


def _limit(name: str, value: float, where: str, what: str) -> None:
    try:
        limits.check(name, value, what)
    except LimitError as exc:
        raise LayoutError(f"{where}: {exc}") from None


def _floor(size: tuple[float, float], where: str) -> None:
    for i, s in enumerate(size):
        if s <= 2.0:
            raise LayoutError(f"{where}: the map is {size[0]:.3g} x {size[1]:.3g} m; bulletnav needs a floor over 2 m "
                              f"along {'xy'[i]}")
        _limit("world_size", s, where, f"map extent along {'xy'[i]} (m)")


def _point(value: Any, n: int, where: str, field_name: str) -> tuple[float, ...]:
    if not isinstance(value, (list, tuple)) or len(value) != n or not all(
            isinstance(v, (int, float)) and not isinstance(v, bool) and finite(v) for v in value):
        what = "[x, y, yaw]" if n == 3 else "[x, y]"
        raise LayoutError(f"{where}: field '{field_name}' must be {what} (finite numbers, the map's frame), got {show(value)}")
    return tuple(float(v) for v in value)


def _place(layout: dict[str, Any], options: dict[str, Any], where: str,
           grid: tuple[np.ndarray, float] | None) -> dict[str, Any]:
    """``layout``'s fields with the start and goal the options give (in the map's frame, the
    world's), checked free."""
    start = goal = None
    if options.get("start") is not None:
        sx, sy, syaw = _point(options["start"], 3, where, "start")
        _check_free(layout, (sx, sy), where, "start", grid)
        start = (sx, sy, math.remainder(syaw, 2 * math.pi))
    if options.get("goal") is not None:
        gx, gy = _point(options["goal"], 2, where, "goal")
        _check_free(layout, (gx, gy), where, "goal", grid)
        goal = (gx, gy)
    return {**layout, "start": start, "goal": goal}


def _check_free(layout: dict[str, Any], xy: tuple[float, float], where: str, field_name: str,
                grid: tuple[np.ndarray, float] | None) -> None:
    x0, y0 = layout["corner"]
    sx, sy = layout["size"]
    at = f"field '{field_name}' [{xy[0]:g}, {xy[1]:g}] (map frame)"
    if not (x0 < xy[0] < x0 + sx and y0 < xy[1] < y0 + sy):
        raise LayoutError(f"{where}: {at} lies outside the map (x in [{x0:g}, {x0 + sx:g}], y in [{y0:g}, {y0 + sy:g}])")
    for o in layout["obstacles"]:
        if float(o.distance(np.array(xy[0]), np.array(xy[1]))) <= 0.0:
            what = f"model {o.label!r}"
            if grid is not None:
                values, res = grid
                ix = min(max(int((xy[0] - x0) / res), 0), values.shape[0] - 1)
                iy = min(max(int((xy[1] - y0) / res), 0), values.shape[1] - 1)
                what = ("an unknown cell (a wall unless 'unknown: free')" if values[ix, iy] == mapserver.UNKNOWN
                        else "a wall (occupied cells)")
            raise LayoutError(f"{where}: {at} lies on or inside {what}")


__all__ = ["is_sdf", "is_user_map", "load_map_yaml", "load_sdf", "load_user_map"]
