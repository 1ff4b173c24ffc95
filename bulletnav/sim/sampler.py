"""Start/goal sampling in the free space of a layout."""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, replace
from functools import cached_property

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix, csr_matrix
from scipy.sparse.csgraph import dijkstra

from bulletnav.config import SamplerConfig
from bulletnav.errors import SamplingError
from bulletnav.sim.layout import Layout
from bulletnav.sim.specs import Obstacle

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FreeSpace:
    """Coarse free-space grids of one layout, computed once and reused for every episode.

    ``clear[ix, iy]`` is True where a cell centre has the required clearance; ``component``
    labels the 8-connected regions of the robot's configuration space (obstacles inflated
    by the robot's disc, ``radius``), so two points are mutually reachable iff their labels match.
    """

    layout: Layout
    resolution: float
    xs: np.ndarray
    ys: np.ndarray
    clear: np.ndarray
    component: np.ndarray

    @classmethod
    def build(cls, layout: Layout, config: SamplerConfig, radius: float) -> FreeSpace:
        """Grids of ``layout`` for a robot disc of ``radius`` (m; ``RobotGeometry.radius``)."""
        xs, ys = layout.grid_axes(config.grid_resolution)
        near = layout.within_levels(xs, ys, (config.clearance, radius))
        return cls.from_occupancy(layout, config, near[0], near[1])

    @classmethod
    def from_occupancy(cls, layout: Layout, config: SamplerConfig, within_clearance: np.ndarray,
                       within_radius: np.ndarray) -> FreeSpace:
        """Grids from the layout's occupancy at ``config.grid_resolution``, obstacles grown by
        ``config.clearance`` and by the robot's radius (:meth:`Layout.within_levels`), for
        callers that computed them already (the scene shares them with the movers and events)."""
        xs, ys = layout.grid_axes(config.grid_resolution)
        # clearance > d is the negation of clearance <= d, bit for bit (distances are never NaN)
        clear, passable = ~within_clearance, ~within_radius
        component, _ = ndimage.label(passable, structure=np.ones((3, 3), dtype=bool))
        return cls(layout, config.grid_resolution, xs, ys, clear, component)

    def cell(self, xy: tuple[float, float] | np.ndarray) -> tuple[int, int]:
        x0, y0, _, _ = self.layout.bounds
        ix = int(np.clip((xy[0] - x0) // self.resolution, 0, len(self.xs) - 1))
        iy = int(np.clip((xy[1] - y0) // self.resolution, 0, len(self.ys) - 1))
        return ix, iy

    def reachable(self, a: tuple[float, float], b: tuple[float, float]) -> bool:
        """True when ``b`` is reachable from ``a`` for the robot footprint on the coarse grid."""
        ca, cb = self.component[self.cell(a)], self.component[self.cell(b)]
        return bool(ca != 0 and ca == cb)

    @cached_property
    def _graph(self) -> csr_matrix:
        """The 8-connected graph of passable cells (node = flat cell index), edges in cells."""
        return grid_graph(self.component > 0)  # the same neighbourhood as the component labels

    def path_lengths(self, cell: tuple[int, int]) -> np.ndarray:
        """Shortest path length (m) from ``cell`` to every cell for the robot's disc: Dijkstra
        over the 8-connected passable cells (diagonal steps sqrt(2) cells long), inf where
        unreachable. This octile length exceeds the Euclidean shortest path by at most 8 %."""
        nx, ny = self.component.shape
        dist = dijkstra(self._graph, directed=False, indices=cell[0] * ny + cell[1])
        return dist.reshape(nx, ny) * self.resolution


def grid_graph(passable: np.ndarray, cost: np.ndarray | None = None) -> csr_matrix:
    """The 8-connected graph of the ``passable`` cells of a grid (node = flat cell index ``ix *
    ny + iy``), each edge as long as its step in cells (1 or sqrt(2)), times the mean ``cost`` of
    its two cells when a cost grid is given."""
    nx, ny = passable.shape
    index = np.arange(nx * ny).reshape(nx, ny)
    rows, cols, weights = [], [], []
    for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
        a = (slice(0, nx - dx), slice(max(-dy, 0), ny - max(dy, 0)))
        b = (slice(dx, nx), slice(max(dy, 0), ny - max(-dy, 0)))
        both = passable[a] & passable[b]
        rows.append(index[a][both])
        cols.append(index[b][both])
        step = math.hypot(dx, dy)
        weights.append(np.full(int(both.sum()), step) if cost is None
                       else step * 0.5 * (cost[a][both] + cost[b][both]))
    r, c, w = np.concatenate(rows), np.concatenate(cols), np.concatenate(weights)
    return coo_matrix((w, (r, c)), shape=(nx * ny, nx * ny)).tocsr()


def sample_start_goal(
    free: FreeSpace, rng: np.random.Generator, config: SamplerConfig
) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """Draw a start pose (x, y, yaw) and a goal (x, y) from ``rng``.

    Both lie on cells with ``config.clearance`` to every obstacle, their straight-line
    distance is within ``[min_goal_distance, max_goal_distance]``, and the goal is reachable
    from the start on the free-space grid. The start yaw is uniform in [-pi, pi).

    Raises:
        SamplingError: the layout has no such pair.

    With the planning options (``min_detour``, ``blocked_by``) a pair must also make a
    planning episode; a layout where none does (a YAML world without racks) gets a plain
    pair, with a warning.
    """
    cells = np.argwhere(free.clear & (free.component > 0))
    if len(cells) == 0:
        raise SamplingError(f"layout {free.layout.source or free.layout.name!r}: no free cell with "
                            f"{config.clearance} m clearance for a start or goal")
    points = np.stack([free.xs[cells[:, 0]], free.ys[cells[:, 1]]], axis=1)
    labels = free.component[cells[:, 0], cells[:, 1]]
    jitter = free.resolution / 2
    planning = False
    if config.min_detour > 1.0 or config.blocked_by:
        # planning episodes: drawn only with these options, so the default path draws what it always drew
        planning = config.detour_share >= 1.0 or rng.random() < config.detour_share
    blockers = [o for o in free.layout.obstacles if o.label in config.blocked_by] if planning else []
    for _ in range(config.max_tries):
        i = int(rng.integers(len(points)))
        d = np.hypot(points[:, 0] - points[i, 0], points[:, 1] - points[i, 1])
        ok = (labels == labels[i]) & (d >= config.min_goal_distance + jitter * 1.5) & (d <= config.max_goal_distance - jitter * 1.5)
        if planning:
            ok &= _planning_pairs(free, config, blockers, cells, points, i, d, ok)
        candidates = np.flatnonzero(ok)
        if len(candidates) == 0:
            continue
        j = int(candidates[rng.integers(len(candidates))])
        # Jitter inside the cells so starts and goals are not quantised to the grid.
        sx, sy = points[i] + rng.uniform(-jitter, jitter, 2) * 0.5
        gx, gy = points[j] + rng.uniform(-jitter, jitter, 2) * 0.5
        yaw = float(rng.uniform(-math.pi, math.pi))
        return (float(sx), float(sy), yaw), (float(gx), float(gy))
    if planning:  # e.g. a YAML world without racks on the aisle env: plain episodes rather than none
        log.warning("layout %r: no start/goal pair makes a planning episode (straight line through %s, detour %s); "
                    "drawing a plain pair", free.layout.source or free.layout.name, list(config.blocked_by),
                    config.min_detour)
        return sample_start_goal(free, rng, replace(config, min_detour=1.0, blocked_by=(), detour_share=0.0))
    raise SamplingError(
        f"layout {free.layout.source or free.layout.name!r}: no reachable start/goal pair "
        f"{config.min_goal_distance}-{config.max_goal_distance} m apart with {config.clearance} m clearance"
        f" after {config.max_tries} tries"
    )


def sample_mission(free: FreeSpace, rng: np.random.Generator, config: SamplerConfig, k: int, separation: float,
                   start: tuple[float, float, float] | None = None, tries: int = 200
                   ) -> tuple[tuple[float, float, float], tuple[tuple[float, float], ...]]:
    """A start pose and ``k`` goals for a mission, all with ``config.clearance``, mutually
    reachable, at least ``separation`` m apart, each goal ``min_goal_distance`` to
    ``max_goal_distance`` from the point before it (the start for the first).

    Raises:
        SamplingError: the layout has no such mission after ``tries`` attempts.
    """
    cells = np.argwhere(free.clear & (free.component > 0))
    if len(cells) == 0:
        raise SamplingError(f"layout {free.layout.source or free.layout.name!r}: no free cell for a mission")
    points = np.stack([free.xs[cells[:, 0]], free.ys[cells[:, 1]]], axis=1)
    labels = free.component[cells[:, 0], cells[:, 1]]
    jitter = free.resolution / 4
    for _ in range(tries):
        if start is None:
            i = int(rng.integers(len(points)))
            s = (float(points[i, 0] + rng.uniform(-jitter, jitter)), float(points[i, 1] + rng.uniform(-jitter, jitter)),
                 float(rng.uniform(-math.pi, math.pi)))
        else:
            s = start
        label = free.component[free.cell(s[:2])]
        if label == 0:
            if start is not None:
                raise SamplingError(f"mission start {list(s)} is not reachable free space")
            continue
        chosen = [np.array(s[:2])]
        ok_label = labels == label
        for _ in range(k):
            prev = chosen[-1]
            d = np.hypot(points[:, 0] - prev[0], points[:, 1] - prev[1])
            ok = ok_label & (d >= config.min_goal_distance) & (d <= config.max_goal_distance)
            for q in chosen:
                ok &= np.hypot(points[:, 0] - q[0], points[:, 1] - q[1]) >= separation + 2 * jitter
            candidates = np.flatnonzero(ok)
            if len(candidates) == 0:
                break
            j = int(candidates[rng.integers(len(candidates))])
            chosen.append(points[j] + rng.uniform(-jitter, jitter, 2))
        if len(chosen) == k + 1:
            return s, tuple((float(g[0]), float(g[1])) for g in chosen[1:])
    raise SamplingError(f"layout {free.layout.source or free.layout.name!r}: no mission of {k} goals "
                        f"{config.min_goal_distance}-{config.max_goal_distance} m apart after {tries} tries")


def _planning_pairs(free: FreeSpace, config: SamplerConfig, blockers: list[Obstacle], cells: np.ndarray,
                    points: np.ndarray, i: int, d: np.ndarray, ok: np.ndarray) -> np.ndarray:
    """Which goal candidates make a planning episode with start cell ``i``: the straight
    segment crosses an obstacle labelled in ``config.blocked_by``, and the shortest path
    (:meth:`FreeSpace.path_lengths`) is at least ``config.min_detour`` times the straight line."""
    keep = ok.copy()
    if config.blocked_by:
        crossed = np.zeros(len(points), dtype=bool)
        start = points[i]
        reach = config.max_goal_distance + 1.0  # every candidate lies within max_goal_distance of the start
        for obstacle in blockers:
            # an obstacle out of every candidate segment's reach, or candidates already crossed,
            # cannot change ``crossed``: test only the rest (each segment's test is its own)
            if math.hypot(obstacle.center[0] - start[0], obstacle.center[1] - start[1]) > reach + obstacle.bounding_radius():
                continue
            todo = np.flatnonzero(keep & ~crossed)
            if len(todo) == 0:
                break
            crossed[todo] = segments_cross(obstacle, start, points[todo])
        keep &= crossed
    if config.min_detour > 1.0 and keep.any():
        lengths = free.path_lengths((int(cells[i, 0]), int(cells[i, 1])))[cells[:, 0], cells[:, 1]]
        # jitter moves each end by up to a quarter cell: demand the ratio with that much to spare
        keep &= lengths >= config.min_detour * (d + free.resolution / 2)
    return keep


def segments_cross(obstacle: Obstacle, start: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """For each segment from ``start`` (x, y) to a row of ``ends`` (n, 2): does it meet the
    obstacle's footprint? (Liang-Barsky clipping in the box's frame; distance for a cylinder.)"""
    p = np.asarray(start, dtype=float) - np.asarray(obstacle.center)
    q = np.asarray(ends, dtype=float) - np.asarray(obstacle.center)
    if obstacle.kind == "cylinder":
        d = q - p
        t = np.clip(-(d @ p) / np.maximum(np.einsum("ij,ij->i", d, d), 1e-18), 0.0, 1.0)
        closest = p + t[:, None] * d
        return np.hypot(closest[:, 0], closest[:, 1]) <= obstacle.radius
    c, s = math.cos(obstacle.yaw), math.sin(obstacle.yaw)
    rot = np.array([[c, s], [-s, c]])  # world -> box frame
    p, q = rot @ p, q @ rot.T
    t0, t1 = np.zeros(len(q)), np.ones(len(q))
    for axis, half in ((0, obstacle.size[0] / 2), (1, obstacle.size[1] / 2)):
        d = q[:, axis] - p[axis]
        with np.errstate(divide="ignore", invalid="ignore"):
            ta, tb = (-half - p[axis]) / d, (half - p[axis]) / d
        lo, hi = np.minimum(ta, tb), np.maximum(ta, tb)
        parallel = d == 0
        inside = abs(p[axis]) <= half
        lo = np.where(parallel, np.where(inside, -np.inf, np.inf), lo)
        hi = np.where(parallel, np.where(inside, np.inf, -np.inf), hi)
        t0, t1 = np.maximum(t0, lo), np.minimum(t1, hi)
    return t0 <= t1
