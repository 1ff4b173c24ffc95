"""costmap_2d, ported: a grid of ``uint8`` costs built from laser scans by an obstacle layer and
an inflation layer, rolling with the robot or fixed in the world.

Follows ros-planning/navigation (``noetic-devel``), package ``costmap_2d``; each piece names the
file and function it ports. The costs are costmap_2d's (:data:`FREE_SPACE` 0,
:data:`INSCRIBED_INFLATED_OBSTACLE` 253, :data:`LETHAL_OBSTACLE` 254, :data:`NO_INFORMATION`
255), cells are indexed ``costs[my, mx]`` so that the flat index is costmap_2d's
``my * size_x + mx``, and a cell ``(mx, my)`` covers ``[origin + m * resolution, origin + (m + 1)
* resolution)``.

What differs from costmap_2d, and why:

- :meth:`LayeredCostmap.update_map` recomputes the master grid over the whole map at every
  update; costmap_2d recomputes it inside the update's bounding box only, which by its design
  gives the same costs (the box covers every cell a change can reach) and is a speed-up.
- Observations are one scan per update, given as hit points in the costmap's frame (costmap_2d's
  observation buffer with ``observation_persistence`` 0 keeps exactly the latest scan); a scan's
  points are in the sensor's plane, so the obstacle heights' filter has nothing to remove.

A pure algorithm module: no simulation, sensors or envs. The numba kernels compile on first
use and are cached on disk; :func:`warmup` pays that up front.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from numba import njit

FREE_SPACE = 0
"""costmap_2d's cost of a free cell (``cost_values.h``)."""
INSCRIBED_INFLATED_OBSTACLE = 253
"""A cell within the robot's inscribed radius of an obstacle: the robot's centre there collides."""
LETHAL_OBSTACLE = 254
"""A cell holding an obstacle."""
NO_INFORMATION = 255
"""A cell nothing has been seen in (only where unknown space is tracked)."""


# ---------------------------------------------------------------------------------- footprints

def pad_footprint(footprint: Sequence[Sequence[float]], padding: float) -> np.ndarray:
    """The footprint polygon (N, 2) m, each vertex moved ``padding`` m away from the robot's
    centre along x and y (``costmap_2d/src/footprint.cpp``, ``padFootprint``: x += sign0(x) *
    padding, y += sign0(y) * padding; a coordinate of 0 stays 0)."""
    pts = np.asarray(footprint, dtype=np.float64).reshape(-1, 2)
    return pts + np.sign(pts) * padding


def footprint_from_radius(radius: float) -> np.ndarray:
    """A circular robot's footprint: 16 points on the circle of ``radius`` m
    (``footprint.cpp``, ``makeFootprintFromRadius``)."""
    angles = np.arange(16) * 2.0 * math.pi / 16
    return np.stack([np.cos(angles) * radius, np.sin(angles) * radius], axis=1)


def footprint_radii(footprint: np.ndarray) -> tuple[float, float]:
    """(inscribed, circumscribed) radius (m) of a footprint polygon (``footprint.cpp``,
    ``calculateMinAndMaxDistances``): the smallest and largest distance from the centre to a
    vertex or an edge."""
    pts = np.asarray(footprint, dtype=np.float64)
    lo, hi = math.inf, 0.0
    for i in range(len(pts)):
        a, b = pts[i], pts[(i + 1) % len(pts)]
        vertex = math.hypot(a[0], a[1])
        edge = _distance_to_line(0.0, 0.0, a[0], a[1], b[0], b[1])
        lo = min(lo, vertex, edge)
        hi = max(hi, vertex, edge)
    return lo, hi


def _distance_to_line(px: float, py: float, x0: float, y0: float, x1: float, y1: float) -> float:
    """``costmap_math.cpp``, ``distanceToLine``: distance from a point to a segment."""
    a, b, c, d = px - x0, py - y0, x1 - x0, y1 - y0
    dot, len_sq = a * c + b * d, c * c + d * d
    param = dot / len_sq
    if param < 0:
        xx, yy = x0, y0
    elif param > 1:
        xx, yy = x1, y1
    else:
        xx, yy = x0 + param * c, y0 + param * d
    return math.hypot(px - xx, py - yy)


def oriented_footprint(x: float, y: float, theta: float, footprint: np.ndarray) -> np.ndarray:
    """The footprint at pose (x, y, theta), in the costmap's frame (``footprint.cpp``, ``transformFootprint``)."""
    c, s = math.cos(theta), math.sin(theta)
    pts = np.asarray(footprint, dtype=np.float64)
    return np.stack([x + pts[:, 0] * c - pts[:, 1] * s, y + pts[:, 0] * s + pts[:, 1] * c], axis=1)


# ---------------------------------------------------------------------------------- the grid

class Costmap2D:
    """``costmap_2d::Costmap2D`` (``costmap_2d/src/costmap_2d.cpp``): ``size_x`` x ``size_y`` cells
    of ``resolution`` m from ``(origin_x, origin_y)``, each a ``uint8`` cost.

    Args:
        size_x, size_y: cells along x and y.
        resolution: cell side (m).
        origin_x, origin_y: the map's lower-left corner (m).
        default_value: the cost every cell starts at, and is reset to.
    """

    def __init__(self, size_x: int, size_y: int, resolution: float, origin_x: float = 0.0, origin_y: float = 0.0,
                 default_value: int = FREE_SPACE) -> None:
        if size_x < 1 or size_y < 1 or not resolution > 0:
            raise ValueError(f"a costmap needs at least one cell of positive size, got {size_x} x {size_y} at {resolution} m")
        self.size_x, self.size_y = int(size_x), int(size_y)
        self.resolution = float(resolution)
        self.origin_x, self.origin_y = float(origin_x), float(origin_y)
        self.default_value = int(default_value)
        self.costs = np.full((self.size_y, self.size_x), self.default_value, dtype=np.uint8)
        """The costs, ``costs[my, mx]``."""

    @property
    def size_in_meters(self) -> tuple[float, float]:
        """(x, y) extent of the map (m): ``(size - 1 + 1) * resolution`` as ``getSizeInMetersX`` has it."""
        return (self.size_x - 1 + 1) * self.resolution, (self.size_y - 1 + 1) * self.resolution

    def world_to_map(self, wx: float, wy: float) -> tuple[int, int] | None:
        """The cell holding world point (wx, wy) m, or None off the map (``worldToMap``)."""
        if wx < self.origin_x or wy < self.origin_y:
            return None
        mx = int((wx - self.origin_x) / self.resolution)
        my = int((wy - self.origin_y) / self.resolution)
        if mx < self.size_x and my < self.size_y:
            return mx, my
        return None

    def world_to_map_no_bounds(self, wx: float, wy: float) -> tuple[int, int]:
        """The cell of (wx, wy) m, maybe off the map (``worldToMapNoBounds``: truncation toward 0)."""
        return int((wx - self.origin_x) / self.resolution), int((wy - self.origin_y) / self.resolution)

    def map_to_world(self, mx: float, my: float) -> tuple[float, float]:
        """The centre of cell (mx, my) in metres (``mapToWorld``)."""
        return self.origin_x + (mx + 0.5) * self.resolution, self.origin_y + (my + 0.5) * self.resolution

    def cell_distance(self, world_dist: float) -> int:
        """``world_dist`` m in cells, rounded up (``cellDistance``)."""
        return int(max(0.0, math.ceil(world_dist / self.resolution)))

    def cost(self, mx: int, my: int) -> int:
        """The cost of cell (mx, my) (``getCost``)."""
        return int(self.costs[my, mx])

    def reset(self) -> None:
        """Every cell back to the default value (``resetMaps``)."""
        self.costs.fill(self.default_value)

    def update_origin(self, new_origin_x: float, new_origin_y: float) -> None:
        """Move the map to a new lower-left corner, snapped to whole cells, keeping the costs of
        the cells both windows share and resetting the others (``updateOrigin``)."""
        res = self.resolution
        cell_ox = int((new_origin_x - self.origin_x) / res)
        cell_oy = int((new_origin_y - self.origin_y) / res)
        if cell_ox == 0 and cell_oy == 0:
            return
        lx, ly = min(max(cell_ox, 0), self.size_x), min(max(cell_oy, 0), self.size_y)
        ux, uy = min(max(cell_ox + self.size_x, 0), self.size_x), min(max(cell_oy + self.size_y, 0), self.size_y)
        kept = self.costs[ly:uy, lx:ux].copy()
        self.reset()
        self.origin_x += cell_ox * res
        self.origin_y += cell_oy * res
        sx, sy = lx - cell_ox, ly - cell_oy
        self.costs[sy:sy + kept.shape[0], sx:sx + kept.shape[1]] = kept


# ---------------------------------------------------------------------------------- kernels

@njit(cache=True, nogil=True)
def _world_to_map(wx, wy, origin_x, origin_y, res, size_x, size_y):  # pragma: no cover  (compiled)
    """``Costmap2D::worldToMap``: (mx, my, on the map)."""
    if wx < origin_x or wy < origin_y:
        return 0, 0, False
    mx = int((wx - origin_x) / res)
    my = int((wy - origin_y) / res)
    return mx, my, mx < size_x and my < size_y


@njit(cache=True, nogil=True)
def _raytrace_line(flat, size_x, x0, y0, x1, y1, max_length, value):  # pragma: no cover  (compiled)
    """``Costmap2D::raytraceLine`` with ``MarkCell(value)``: Bresenham from (x0, y0) toward
    (x1, y1), at most ``max_length`` cells along the dominant axis, marking the cells passed and
    the one it stops on (``costmap_2d.h``, ``bresenham2D``)."""
    dx, dy = x1 - x0, y1 - y0
    abs_dx, abs_dy = abs(dx), abs(dy)
    offset_dx = 1 if dx > 0 else -1
    offset_dy = (1 if dy > 0 else -1) * size_x
    offset = y0 * size_x + x0
    dist = math.hypot(dx, dy)
    scale = 1.0 if dist == 0.0 else min(1.0, max_length / dist)
    if abs_dx >= abs_dy:
        abs_da, abs_db, error_b, offset_a, offset_b = abs_dx, abs_dy, abs_dx // 2, offset_dx, offset_dy
    else:
        abs_da, abs_db, error_b, offset_a, offset_b = abs_dy, abs_dx, abs_dy // 2, offset_dy, offset_dx
    end = min(int(scale * abs_da), abs_da)
    for _ in range(end):
        flat[offset] = value
        offset += offset_a
        error_b += abs_db
        if error_b >= abs_da:
            offset += offset_b
            error_b -= abs_da
    flat[offset] = value


@njit(cache=True, nogil=True)
def _obstacle_update(flat, size_x, size_y, origin_x, origin_y, res, ox, oy, px, py,  # pragma: no cover  (compiled)
                     obstacle_range, raytrace_cells, marking, clearing):
    """``ObstacleLayer::updateBounds`` for one scan: first ``raytraceFreespace`` (each ray
    clipped to the map as costmap_2d clips it, then cleared up to ``raytrace_cells``), then the
    hits closer than ``obstacle_range`` marked lethal."""
    if clearing:
        x0, y0, inside = _world_to_map(ox, oy, origin_x, origin_y, res, size_x, size_y)
        if inside:
            map_end_x = origin_x + size_x * res
            map_end_y = origin_y + size_y * res
            for i in range(px.shape[0]):
                wx, wy = px[i], py[i]
                a, b = wx - ox, wy - oy
                if wx < origin_x:
                    t = (origin_x - ox) / a
                    wx, wy = origin_x, oy + b * t
                if wy < origin_y:
                    t = (origin_y - oy) / b
                    wx, wy = ox + a * t, origin_y
                if wx > map_end_x:
                    t = (map_end_x - ox) / a
                    wx, wy = map_end_x - 0.001, oy + b * t
                if wy > map_end_y:
                    t = (map_end_y - oy) / b
                    wx, wy = ox + a * t, map_end_y - 0.001
                x1, y1, ok = _world_to_map(wx, wy, origin_x, origin_y, res, size_x, size_y)
                if ok:
                    _raytrace_line(flat, size_x, x0, y0, x1, y1, raytrace_cells, 0)
    if marking:
        sq_range = obstacle_range * obstacle_range
        for i in range(px.shape[0]):
            ddx, ddy = px[i] - ox, py[i] - oy
            if ddx * ddx + ddy * ddy >= sq_range:
                continue
            mx, my, ok = _world_to_map(px[i], py[i], origin_x, origin_y, res, size_x, size_y)
            if ok:
                flat[my * size_x + mx] = 254


@njit(cache=True, nogil=True)
def convex_fill_cells(xs, ys, inclusive):  # pragma: no cover  (compiled)
    """The cells of a convex polygon given by its vertices' cells (``xs``, ``ys``), as
    ``Costmap2D::convexFillCells`` (``inclusive``: the outline by ``raytraceLine``, each column up
    to and including its top cell) or base_local_planner's ``FootprintHelper::getFootprintCells``
    with ``fill`` (not inclusive: the outline by ``getLineCells``, each column short of its top
    cell) finds them: the outline's cells, a gnome sort by x, then each column between its lowest
    and highest outline cell. Returns (N, 2) cells (x, y), the outline's first (sorted)."""
    n = xs.shape[0]
    if n < 3:
        return np.empty((0, 2), dtype=np.int64)
    total = 0
    for k in range(n):
        total += max(abs(xs[(k + 1) % n] - xs[k]), abs(ys[(k + 1) % n] - ys[k])) + 1
    pts = np.empty((total, 2), dtype=np.int64)
    m = 0
    for k in range(n):
        m = _line_cells(xs[k], ys[k], xs[(k + 1) % n], ys[(k + 1) % n], inclusive, pts, m)
    i = 0
    while i < m - 1:  # the reference's "quick bubble sort": a gnome sort, stable
        if pts[i, 0] > pts[i + 1, 0]:
            a0, a1 = pts[i, 0], pts[i, 1]
            pts[i, 0], pts[i, 1] = pts[i + 1, 0], pts[i + 1, 1]
            pts[i + 1, 0], pts[i + 1, 1] = a0, a1
            if i > 0:
                i -= 1
        else:
            i += 1
    lows = np.empty(pts[m - 1, 0] - pts[0, 0] + 1, dtype=np.int64)
    tops = np.empty_like(lows)
    cols = 0
    i = 0
    for x in range(pts[0, 0], pts[m - 1, 0] + 1):
        if i >= m - 1:
            break
        if pts[i, 1] < pts[i + 1, 1]:
            lo, hi = pts[i, 1], pts[i + 1, 1]
        else:
            lo, hi = pts[i + 1, 1], pts[i, 1]
        i += 2
        while i < m and pts[i, 0] == x:
            if pts[i, 1] < lo:
                lo = pts[i, 1]
            elif pts[i, 1] > hi:
                hi = pts[i, 1]
            i += 1
        lows[cols] = lo
        tops[cols] = hi + 1 if inclusive else hi
        cols += 1
    filled = 0
    for c in range(cols):
        filled += max(tops[c] - lows[c], 0)
    cells = np.empty((m + filled, 2), dtype=np.int64)
    cells[:m] = pts[:m]
    k = m
    for c in range(cols):
        for y in range(lows[c], tops[c]):
            cells[k, 0], cells[k, 1] = pts[0, 0] + c, y
            k += 1
    return cells


@njit(inline="always")
def line_start(x0, y0, x1, y1):  # pragma: no cover  (compiled)
    """base_local_planner's ``LineIterator`` from cell (x0, y0) to (x1, y1) (Bresenham; both ends
    are among its ``numpixels + 1`` cells): ``(xinc1, yinc1, xinc2, yinc2, den, num, numadd,
    numpixels)``, its constructor's increments and counters. The first cell is (x0, y0), each
    next one :func:`line_next`'s."""
    deltax, deltay = abs(x1 - x0), abs(y1 - y0)
    xinc = 1 if x1 >= x0 else -1
    yinc = 1 if y1 >= y0 else -1
    if deltax >= deltay:
        return 0, yinc, xinc, 0, deltax, deltax // 2, deltay, deltax
    return xinc, 0, 0, yinc, deltay, deltay // 2, deltax, deltay


@njit(inline="always")
def line_next(x, y, num, xinc1, yinc1, xinc2, yinc2, den, numadd):  # pragma: no cover  (compiled)
    """``LineIterator::advance``: the cell after (x, y) and the new ``num`` (see :func:`line_start`)."""
    num += numadd
    if num >= den:
        num -= den
        x += xinc1
        y += yinc1
    return x + xinc2, y + yinc2, num


@njit(cache=True, nogil=True)
def _line_cells(x0, y0, x1, y1, raytrace, out, m):  # pragma: no cover  (compiled)
    """Write the Bresenham cells from (x0, y0) to (x1, y1) into ``out`` from row ``m``; returns
    the next free row. ``raytrace``: costmap_2d's ``raytraceLine`` (``bresenham2D``); else
    base_local_planner's ``FootprintHelper::getLineCells``. Both visit the two ends."""
    dx, dy = x1 - x0, y1 - y0
    if raytrace:
        abs_dx, abs_dy = abs(dx), abs(dy)
        sx = 1 if dx > 0 else -1
        sy = 1 if dy > 0 else -1
        x, y = x0, y0
        if abs_dx >= abs_dy:
            err = abs_dx // 2
            for _ in range(abs_dx):
                out[m, 0], out[m, 1] = x, y
                m += 1
                x += sx
                err += abs_dy
                if err >= abs_dx:
                    y += sy
                    err -= abs_dx
        else:
            err = abs_dy // 2
            for _ in range(abs_dy):
                out[m, 0], out[m, 1] = x, y
                m += 1
                y += sy
                err += abs_dx
                if err >= abs_dy:
                    x += sx
                    err -= abs_dy
        out[m, 0], out[m, 1] = x, y
        return m + 1
    xinc1, yinc1, xinc2, yinc2, den, num, numadd, numpixels = line_start(x0, y0, x1, y1)
    x, y = x0, y0
    for _ in range(numpixels + 1):
        out[m, 0], out[m, 1] = x, y
        m += 1
        x, y, num = line_next(x, y, num, xinc1, yinc1, xinc2, yinc2, den, numadd)
    return m


@njit(cache=True, nogil=True)
def _inflate(flat, size_x, size_y, cost_table, dist_table, level_of, n_levels, radius_cells,  # pragma: no cover
             inflate_unknown):
    """``InflationLayer::updateCosts`` over the whole map: every lethal cell a source at distance
    0; cells taken in order of their distance to their source (costmap_2d's ``std::map`` of
    distance bins, each bin in the order cells were added; a cell added to a bin behind the one
    being processed is never visited, as there), each given the cached cost of its offset from
    its source (the larger of it and its cost, or the cost itself on an unknown cell when
    ``inflate_unknown`` or the cost is inscribed or lethal), its 4 neighbours added while within
    ``radius_cells`` of the source (``enqueue``)."""
    n = size_x * size_y
    seen = np.zeros(n, dtype=np.bool_)
    ent = np.empty((1024, 5), dtype=np.int64)  # index, mx, my, src_x, src_y
    nxt = np.full(1024, -1, dtype=np.int64)
    head = np.full(n_levels, -1, dtype=np.int64)
    tail = np.full(n_levels, -1, dtype=np.int64)
    count = 0
    for index in range(n):
        if flat[index] == 254:
            mx, my = index % size_x, index // size_x
            ent, nxt, count = _append(ent, nxt, head, tail, count, 0, index, mx, my, mx, my)
    steps = ((-1, 0), (0, -1), (1, 0), (0, 1))  # inflation_layer.cpp's order: left, down, right, up
    for level in range(n_levels):
        e = head[level]
        while e >= 0:
            index, mx, my, sx, sy = ent[e, 0], ent[e, 1], ent[e, 2], ent[e, 3], ent[e, 4]
            if not seen[index]:
                seen[index] = True
                cost = cost_table[abs(mx - sx), abs(my - sy)]
                old = flat[index]
                if old == 255 and (cost > 0 if inflate_unknown else cost >= 253):
                    flat[index] = cost
                else:
                    flat[index] = max(old, cost)
                for dx, dy in steps:
                    nx_, ny_ = mx + dx, my + dy
                    if nx_ < 0 or ny_ < 0 or nx_ >= size_x or ny_ >= size_y:
                        continue
                    ni = ny_ * size_x + nx_
                    ddx, ddy = abs(nx_ - sx), abs(ny_ - sy)
                    if seen[ni] or dist_table[ddx, ddy] > radius_cells:
                        continue
                    lv = level_of[ddx, ddy]
                    if lv >= level:  # a bin before the current one: std::map's iterator has passed it
                        ent, nxt, count = _append(ent, nxt, head, tail, count, lv, ni, nx_, ny_, sx, sy)
            e = nxt[e]


@njit(cache=True, nogil=True)
def _append(ent, nxt, head, tail, count, level, index, mx, my, sx, sy):  # pragma: no cover  (compiled)
    """Add a cell (index, mx, my) inflated from (sx, sy) at the end of distance bin ``level``;
    returns the (maybe grown) entry arrays and the new count."""
    if count == ent.shape[0]:
        bigger = np.empty((count * 2, 5), dtype=np.int64)
        bigger[:count] = ent
        more = np.full(count * 2, -1, dtype=np.int64)
        more[:count] = nxt
        ent, nxt = bigger, more
    ent[count, 0], ent[count, 1], ent[count, 2], ent[count, 3], ent[count, 4] = index, mx, my, sx, sy
    nxt[count] = -1
    if tail[level] < 0:
        head[level] = count
    else:
        nxt[tail[level]] = count
    tail[level] = count
    return ent, nxt, count + 1


# ---------------------------------------------------------------------------------- layers

def inflation_cost(distance_cells: float, resolution: float, inscribed_radius: float, cost_scaling_factor: float) -> int:
    """``InflationLayer::computeCost``: the cost of a cell ``distance_cells`` cells from the
    nearest lethal cell: :data:`LETHAL_OBSTACLE` at 0, :data:`INSCRIBED_INFLATED_OBSTACLE`
    within the inscribed radius (m), else ``int(252 * exp(-cost_scaling_factor * (d -
    inscribed_radius)))`` with ``d`` in metres."""
    if distance_cells == 0:
        return LETHAL_OBSTACLE
    d = distance_cells * resolution
    if d <= inscribed_radius:
        return INSCRIBED_INFLATED_OBSTACLE
    return int((INSCRIBED_INFLATED_OBSTACLE - 1) * math.exp(-1.0 * cost_scaling_factor * (d - inscribed_radius)))


class InflationLayer:
    """``costmap_2d::InflationLayer`` (``plugins/inflation_layer.cpp``): costs falling off with
    the distance to the nearest lethal cell, up to ``inflation_radius``.

    Args:
        inflation_radius: how far costs spread from an obstacle (m).
        cost_scaling_factor: the exponential decay rate beyond the inscribed radius (1/m;
            costmap_2d's default 10.0).
        inscribed_radius: the padded footprint's inscribed radius (m): cells within it are
            :data:`INSCRIBED_INFLATED_OBSTACLE`.
        resolution: the map's cell side (m).
        inflate_unknown: unknown cells take any inflated cost (else only inscribed and lethal ones).
        name: the layer's name (the plugin's ``name`` in the costmap's ``plugins`` list).
    """

    def __init__(self, inflation_radius: float, cost_scaling_factor: float, inscribed_radius: float, resolution: float,
                 inflate_unknown: bool = False, name: str = "inflation_layer", enabled: bool = True) -> None:
        self.inflation_radius = float(inflation_radius)
        self.cost_scaling_factor = float(cost_scaling_factor)
        self.inscribed_radius = float(inscribed_radius)
        self.resolution = float(resolution)
        self.inflate_unknown = bool(inflate_unknown)
        self.name = name
        self.enabled = enabled
        self.cell_inflation_radius = int(max(0.0, math.ceil(self.inflation_radius / self.resolution)))
        r = self.cell_inflation_radius + 2
        ij = np.indices((r, r))
        self.cached_distances = np.hypot(ij[0], ij[1])
        """``cached_distances_[dx][dy]`` = hypot(dx, dy) (cells), for offsets 0 .. radius + 1."""
        self.cached_costs = np.array([[inflation_cost(d, self.resolution, self.inscribed_radius, self.cost_scaling_factor)
                                       for d in row] for row in self.cached_distances], dtype=np.uint8)
        """``cached_costs_[dx][dy]``: the cost at that offset from a lethal cell."""
        levels = np.unique(self.cached_distances)
        self._levels = np.searchsorted(levels, self.cached_distances).astype(np.int64)
        self._n_levels = len(levels)

    def update_costs(self, master: Costmap2D) -> None:
        """Inflate the lethal cells of ``master`` in place (``updateCosts``)."""
        if not self.enabled or self.cell_inflation_radius == 0:
            return
        _inflate(master.costs.reshape(-1), master.size_x, master.size_y, self.cached_costs, self.cached_distances,
                 self._levels, self._n_levels, float(self.cell_inflation_radius), self.inflate_unknown)


class ObstacleLayer(Costmap2D):
    """``costmap_2d::ObstacleLayer`` (``plugins/obstacle_layer.cpp``) with one laser source:
    scan hits closer than ``obstacle_range`` are marked lethal, and the cells along each ray
    (up to ``raytrace_range``) are cleared first; the cells under the robot's footprint are
    cleared after (``footprint_clearing_enabled``).

    Args:
        size_x, size_y, resolution, origin_x, origin_y: the grid, as the master's.
        obstacle_range: hits at least this far from the sensor are not marked (m).
        raytrace_range: rays clear at most this far (m).
        marking, clearing: the source marks obstacles / clears free space.
        track_unknown_space: cells start unknown (:data:`NO_INFORMATION`) instead of free.
        footprint_clearing_enabled: clear the cells under the footprint at every update.
        rolling_window: the map follows the robot (centred on it at every update).
        name: the layer's name (the plugin's ``name``; recoveries clear layers by name).
    """

    def __init__(self, size_x: int, size_y: int, resolution: float, origin_x: float, origin_y: float,
                 obstacle_range: float = 2.5, raytrace_range: float = 3.0, marking: bool = True, clearing: bool = True,
                 track_unknown_space: bool = False, footprint_clearing_enabled: bool = True, rolling_window: bool = False,
                 name: str = "obstacle_layer", enabled: bool = True, combination_method: int = 1) -> None:
        super().__init__(size_x, size_y, resolution, origin_x, origin_y,
                         NO_INFORMATION if track_unknown_space else FREE_SPACE)
        self.obstacle_range, self.raytrace_range = float(obstacle_range), float(raytrace_range)
        self.marking, self.clearing = bool(marking), bool(clearing)
        self.footprint_clearing_enabled = bool(footprint_clearing_enabled)
        self.rolling_window = bool(rolling_window)
        self.name = name
        self.enabled = enabled
        self.combination_method = combination_method
        self._footprint_cells = np.empty((0, 2), dtype=np.int64)

    def update_bounds(self, robot_x: float, robot_y: float, robot_yaw: float, sensor_origin: tuple[float, float],
                      hits: np.ndarray, footprint: np.ndarray) -> None:
        """``updateBounds``: follow the robot (rolling window), clear along the rays, mark the
        hits, and note the cells under ``footprint`` (robot frame, m) for :meth:`update_costs`.

        Args:
            sensor_origin: the sensor's position (m, costmap frame).
            hits: (N, 2) scan hit points (m, costmap frame); rays that hit nothing are left out.
        """
        if self.rolling_window:
            sx, sy = self.size_in_meters
            self.update_origin(robot_x - sx / 2, robot_y - sy / 2)
        pts = np.asarray(hits, dtype=np.float64).reshape(-1, 2)
        _obstacle_update(self.costs.reshape(-1), self.size_x, self.size_y, self.origin_x, self.origin_y, self.resolution,
                         float(sensor_origin[0]), float(sensor_origin[1]), np.ascontiguousarray(pts[:, 0]),
                         np.ascontiguousarray(pts[:, 1]), self.obstacle_range, self.cell_distance(self.raytrace_range),
                         self.marking, self.clearing)
        self._footprint_cells = np.empty((0, 2), dtype=np.int64)
        if self.footprint_clearing_enabled:
            poly = oriented_footprint(robot_x, robot_y, robot_yaw, footprint)
            cells = [self.world_to_map(px, py) for px, py in poly]
            if all(c is not None for c in cells):  # setConvexPolygonCost fills nothing for a polygon off the map
                xs = np.array([c[0] for c in cells], dtype=np.int64)
                ys = np.array([c[1] for c in cells], dtype=np.int64)
                self._footprint_cells = convex_fill_cells(xs, ys, True)

    def update_costs(self, master: Costmap2D) -> None:
        """``updateCosts``: clear the footprint's cells, then combine into ``master``
        (``combination_method`` 1, costmap_2d's default: the larger cost where this layer knows the cell)."""
        if len(self._footprint_cells):
            self.costs[self._footprint_cells[:, 1], self._footprint_cells[:, 0]] = FREE_SPACE
        if not self.enabled:
            return
        known = self.costs != NO_INFORMATION
        if self.combination_method == 0:  # updateWithOverwrite
            master.costs[known] = self.costs[known]
            return
        old = master.costs
        take = known & ((old == NO_INFORMATION) | (old < self.costs))
        master.costs[take] = self.costs[take]

    def clear_area(self, start_x: int, start_y: int, end_x: int, end_y: int, invert_area: bool = False) -> None:
        """``CostmapLayer::clearArea``: every cell strictly outside the box (start_x, end_x) x
        (start_y, end_y) (inside it with ``invert_area``) becomes :data:`NO_INFORMATION`."""
        xs = np.arange(self.size_x)
        ys = np.arange(self.size_y)
        inside = ((xs[None, :] > start_x) & (xs[None, :] < end_x)) & ((ys[:, None] > start_y) & (ys[:, None] < end_y))
        self.costs[inside == invert_area] = NO_INFORMATION


@dataclass
class LayeredCostmap:
    """``costmap_2d::LayeredCostmap`` of an obstacle layer and an inflation layer, with the
    robot's padded footprint (``Costmap2DROS``: the footprint padded by ``footprint_padding``).

    Build one with :meth:`make`.
    """

    master: Costmap2D
    """The combined costs the planners read."""
    obstacles: ObstacleLayer
    inflation: InflationLayer
    footprint: np.ndarray
    """The padded footprint (N, 2), robot frame (m)."""
    rolling_window: bool
    inscribed_radius: float
    circumscribed_radius: float

    @classmethod
    def make(cls, size_x: int, size_y: int, resolution: float, origin_x: float, origin_y: float, footprint: np.ndarray,
             inflation_radius: float, cost_scaling_factor: float = 10.0, obstacle_range: float = 2.5,
             raytrace_range: float = 3.0, rolling_window: bool = False, track_unknown_space: bool = False,
             obstacle_name: str = "obstacle_layer", inflation_name: str = "inflation_layer",
             footprint_clearing_enabled: bool = True, inflate_unknown: bool = False, marking: bool = True,
             clearing: bool = True, combination_method: int = 1) -> LayeredCostmap:
        """A costmap of ``size_x`` x ``size_y`` cells of ``resolution`` m from (origin_x,
        origin_y) m for a robot of (already padded) ``footprint`` (N, 2) m; the rest are the
        layers' parameters (:class:`ObstacleLayer`, :class:`InflationLayer`)."""
        fp = np.asarray(footprint, dtype=np.float64).reshape(-1, 2)
        inscribed, circumscribed = footprint_radii(fp)
        master = Costmap2D(size_x, size_y, resolution, origin_x, origin_y,
                           NO_INFORMATION if track_unknown_space else FREE_SPACE)
        obstacles = ObstacleLayer(size_x, size_y, resolution, origin_x, origin_y, obstacle_range, raytrace_range,
                                  marking, clearing, track_unknown_space, footprint_clearing_enabled, rolling_window,
                                  obstacle_name, combination_method=combination_method)
        inflation = InflationLayer(inflation_radius, cost_scaling_factor, inscribed, resolution, inflate_unknown,
                                   inflation_name)
        return cls(master, obstacles, inflation, fp, rolling_window, inscribed, circumscribed)

    def update_map(self, robot_x: float, robot_y: float, robot_yaw: float, sensor_origin: tuple[float, float],
                   hits: np.ndarray) -> None:
        """One update (``LayeredCostmap::updateMap``): the window follows the robot when
        rolling, the obstacle layer takes the scan, and the master is rebuilt: reset, the
        obstacle layer combined in, inflated."""
        if self.rolling_window:
            sx, sy = self.master.size_in_meters
            self.master.update_origin(robot_x - sx / 2, robot_y - sy / 2)
        self.obstacles.update_bounds(robot_x, robot_y, robot_yaw, sensor_origin, hits, self.footprint)
        self.master.reset()
        self.obstacles.update_costs(self.master)
        self.inflation.update_costs(self.master)

    def clear_layers(self, x: float, y: float, reset_distance: float, layer_names: Sequence[str],
                     invert_area: bool = False) -> bool:
        """``ClearCostmapRecovery::clear``: in each layer whose name is in ``layer_names`` (the
        obstacle layer is the only one that keeps a grid), every cell outside the square of side
        ``reset_distance`` m centred on (x, y) (inside it with ``invert_area``) becomes unknown
        (``clearMap``). The master is rebuilt at the next :meth:`update_map`. Returns whether a
        layer was cleared."""
        if self.obstacles.name not in layer_names:
            return False
        start_x, start_y = x - reset_distance / 2, y - reset_distance / 2
        x0, y0 = self.obstacles.world_to_map_no_bounds(start_x, start_y)
        x1, y1 = self.obstacles.world_to_map_no_bounds(start_x + reset_distance, start_y + reset_distance)
        self.obstacles.clear_area(x0, y0, x1, y1, invert_area)
        return True


def warmup() -> None:
    """Compile (or load from numba's disk cache) the costmap kernels on a tiny map."""
    cm = LayeredCostmap.make(8, 8, 0.1, 0.0, 0.0, pad_footprint([[-0.1, -0.1], [-0.1, 0.1], [0.1, 0.1], [0.1, -0.1]], 0.0),
                             0.2, rolling_window=True)
    cm.update_map(0.4, 0.4, 0.0, (0.4, 0.4), np.array([[0.7, 0.4], [0.4, 0.75]]))
    convex_fill_cells(np.array([0, 3, 3]), np.array([0, 0, 3]), False)
