"""Procedural movers for an episode: forklift routes and worker walks planned on the static map.

Forklifts patrol between two points at least 4 m apart along the shortest path through
cells whose clearance lets a forklift and the robot pass each other (half the forklift's
width + the robot's diameter + 0.1 m), so routes follow the wide aisles and never cut
through racks; the grid path is shortened to a polyline by line of sight inside those cells.
Workers walk 2-4 waypoints, each leg a straight line through cells with clearance for their
body (radius + 0.15 m). No mover starts, and no worker pauses, within ``keep_clear`` of the
robot's start or a goal. Everything is drawn from the episode's generator.
"""

from __future__ import annotations

import math

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from bulletnav.config import DynamicConfig
from bulletnav.sim.kernels import line_clear
from bulletnav.sim.layout import Layout
from bulletnav.sim.specs import ForkliftSpec, MoverSpec, WorkerSpec

RESOLUTION = 0.1
"""Grid resolution (m) of the clearance map."""


class ClearanceMap:
    """Distance (m) from each cell centre to the nearest obstacle or wall, for one layout."""

    def __init__(self, layout: Layout, resolution: float = RESOLUTION, occupied: np.ndarray | None = None) -> None:
        """``occupied``: the layout's occupancy at ``resolution`` (``layout.occupancy(resolution)``)
        when the caller has it already."""
        self.layout = layout
        self.resolution = resolution
        occ = layout.occupancy(resolution) if occupied is None else occupied
        self.clearance = ndimage.distance_transform_edt(~occ) * resolution
        xs, ys = layout.grid_axes(resolution)
        self.xs, self.ys = xs, ys
        x0, y0, x1, y1 = layout.bounds
        # walls: cells near the border are no further from a wall than from their border distance
        gx, gy = xs[:, None], ys[None, :]
        self.clearance = np.minimum(self.clearance, np.minimum(np.minimum(x1 - gx, gx - x0), np.minimum(y1 - gy, gy - y0)))
        self._graphs: dict[float, tuple] = {}
        self._cells: dict[float, np.ndarray] = {}

    def cells(self, need: float) -> np.ndarray:
        """Indices (n, 2) of the cells with clearance >= ``need`` (m), row-major (cached)."""
        if need not in self._cells:
            self._cells[need] = np.argwhere(self.clearance >= need)
        return self._cells[need]

    def cell(self, xy) -> tuple[int, int]:
        x0, y0, _, _ = self.layout.bounds
        nx, ny = self.clearance.shape
        return (min(max(int((xy[0] - x0) / self.resolution), 0), nx - 1),
                min(max(int((xy[1] - y0) / self.resolution), 0), ny - 1))

    def point(self, cell) -> tuple[float, float]:
        return float(self.xs[cell[0]]), float(self.ys[cell[1]])

    def line_clear(self, a, b, need: float) -> bool:
        """True when every sample of segment ``a``-``b`` (every half cell) lies in a cell with
        clearance >= ``need`` (m)."""
        n = max(2, int(math.dist(a, b) / (self.resolution / 2)) + 1)
        x0, y0, _, _ = self.layout.bounds
        return line_clear(self.clearance, float(a[0]), float(a[1]), float(b[0]), float(b[1]), n, need, -x0, -y0,
                          self.resolution)

    def graph(self, need: float):
        """8-connected graph of the cells with clearance >= ``need`` (cached)."""
        if need not in self._graphs:
            ok = self.clearance >= need
            nx, ny = ok.shape
            ci, cj = np.nonzero(ok)
            rows, cols, weights = [], [], []
            for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
                i2, j2 = ci + dx, cj + dy
                valid = (i2 < nx) & (j2 >= 0) & (j2 < ny)
                valid[valid] &= ok[i2[valid], j2[valid]]
                rows.append(ci[valid] * ny + cj[valid])
                cols.append(i2[valid] * ny + j2[valid])
                weights.append(np.full(int(valid.sum()), math.hypot(dx, dy)))
            r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
            g = coo_matrix((np.concatenate([w, w]), (np.concatenate([r, c]), np.concatenate([c, r]))),
                           shape=(nx * ny, nx * ny)).tocsr()
            self._graphs[need] = (g, ok)
        return self._graphs[need]


def _far_from(xy, points, distance: float) -> bool:
    return all(math.dist(xy, q) >= distance for q in points)


def forklift_route(cmap: ClearanceMap, rng: np.random.Generator, need: float, avoid, keep_clear: float,
                   min_length: float = 4.0, tries: int = 30) -> tuple[tuple[float, float], ...] | None:
    """A patrol route between two cells >= ``min_length`` apart, or None if none fits."""
    g, ok = cmap.graph(need)
    cells = cmap.cells(need)
    if len(cells) < 2:
        return None
    ny = ok.shape[1]
    for _ in range(tries):
        a = tuple(cells[rng.integers(len(cells))])
        b = tuple(cells[rng.integers(len(cells))])
        pa, pb = cmap.point(a), cmap.point(b)
        if math.dist(pa, pb) < min_length or not _far_from(pa, avoid, keep_clear):
            continue
        dist, pred = dijkstra(g, indices=a[0] * ny + a[1], return_predecessors=True)
        target = b[0] * ny + b[1]
        if not np.isfinite(dist[target]):
            continue
        path = [target]
        while path[-1] != a[0] * ny + a[1]:
            path.append(int(pred[path[-1]]))
        pts = [cmap.point(divmod(i, ny)) for i in reversed(path)]
        # shortcut by line of sight inside the allowed cells
        route = [pts[0]]
        i = 0
        while i < len(pts) - 1:
            j = len(pts) - 1
            while j > i + 1 and not cmap.line_clear(pts[i], pts[j], need):
                j -= 1
            route.append(pts[j])
            i = j
        return tuple((round(x, 3), round(y, 3)) for x, y in route)
    return None


def worker_walk(cmap: ClearanceMap, rng: np.random.Generator, need: float, avoid, keep_clear: float,
                tries: int = 40) -> tuple[tuple[float, float], ...] | None:
    """2-4 waypoints joined by clear straight legs of 2-6 m, none within ``keep_clear`` of ``avoid``."""
    cells = cmap.cells(need)
    if len(cells) == 0:
        return None
    want = int(rng.integers(2, 5))
    for _ in range(tries):
        first = cmap.point(tuple(cells[rng.integers(len(cells))]))
        if not _far_from(first, avoid, keep_clear):
            continue
        pts = [first]
        for _ in range(want - 1):
            for _ in range(tries):
                q = cmap.point(tuple(cells[rng.integers(len(cells))]))
                if 2.0 <= math.dist(pts[-1], q) <= 6.0 and _far_from(q, avoid, keep_clear) \
                        and cmap.line_clear(pts[-1], q, need):
                    pts.append(q)
                    break
        if len(pts) >= 2:
            return tuple((round(x, 3), round(y, 3)) for x, y in pts)
    return None


def draw_movers(layout: Layout, rng: np.random.Generator, config: DynamicConfig, robot_radius: float,
                avoid: tuple[tuple[float, float], ...], cmap: ClearanceMap | None = None) -> tuple[MoverSpec, ...]:
    """The procedural movers of one episode (see the module docstring)."""
    cmap = cmap or ClearanceMap(layout)
    specs: list[MoverSpec] = []
    n_fork = int(rng.integers(config.forklifts[0], config.forklifts[1] + 1))
    n_work = int(rng.integers(config.workers[0], config.workers[1] + 1))
    need_fork = config.forklift_size[1] / 2 + 2 * robot_radius + 0.1
    for _ in range(n_fork):
        route = forklift_route(cmap, rng, need_fork, avoid, config.keep_clear)
        if route is None:
            break
        speed = float(rng.uniform(*config.forklift_speed))
        specs.append(ForkliftSpec(route, speed, tuple(config.forklift_size), None, config.yield_to_robot))
    for _ in range(n_work):
        walk = worker_walk(cmap, rng, config.worker_radius + 0.15, avoid, config.keep_clear)
        if walk is None:
            break
        specs.append(WorkerSpec(walk, float(rng.uniform(*config.worker_speed)), config.worker_radius, 1.7,
                                float(rng.uniform(*config.worker_pause)), config.yield_to_robot))
    return tuple(specs)
