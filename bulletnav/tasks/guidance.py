"""Path guidance from the floor plan: which way the shortest clear path to a goal leaves the robot.

A warehouse robot knows its floor plan (the racks, shelves and walls of the static layout),
not where forklifts, workers or dropped pallets are. With ``guidance="floorplan"`` a task adds
to its observation the direction of a point a little way along the shortest clear path to its
target and that path's length, and measures its ``progress`` reward term along the path
instead of the straight line -- the role of the global planner's subgoal in arena-rosnav's
observation. The robot still has to avoid everything with its lidar: the plan knows nothing
that moves or appears during the episode.

**The path.** One cost field per goal over the layout's free-space grid
(:class:`~bulletnav.sim.sampler.FreeSpace`: 0.1 m cells, passable where the cell centre is more
than the robot's disc radius from every obstacle and wall): Dijkstra over the 8-connected
passable cells from the goal, each step's length multiplied by ``1 + wall_cost *
max(0, 1 - margin / wall_margin)``, ``margin`` being how much more clearance than the disc
radius the two cells have (the mean of the two). The costlier cells near racks keep the path
in the middle of an aisle instead of grazing rack corners; in open floor the cost is length.

**Per step** (:meth:`PathGuide.query`): the path cost from the robot is the least, over the
passable cells within ``reach`` cells of it, of the cell's cost plus the straight distance to
its centre (continuous in the robot's position, so the progress term is smooth); the lookahead
point is reached from that cell by ``lookahead`` steps of steepest descent of the field. Where
no passable cell is near (a goal given inside the inflated obstacles, or the robot pressed
against a rack) the guide falls back to the straight line.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit
from scipy.sparse.csgraph import dijkstra

from bulletnav.sim.sampler import FreeSpace, grid_graph

WALL_COST = 3.0
"""Extra cost factor of a step right at the disc radius from an obstacle."""
WALL_MARGIN = 0.4
"""Clearance beyond the disc radius (m) over which the extra cost fades to zero."""


@njit(cache=True, nogil=True)
def _query(field: np.ndarray, res: float, x0: float, y0: float, x: float, y: float, reach: int, lookahead: int
           ) -> tuple[float, float, float]:
    """(path cost, lookahead x, lookahead y) from (x, y); cost inf when no finite cell is near."""
    nx, ny = field.shape
    cx = int(round((x - x0) / res))
    cy = int(round((y - y0) / res))
    best, bx, by = np.inf, -1, -1
    for i in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
        for j in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
            f = field[i, j]
            if f < np.inf:
                d = f + math.hypot(x - (x0 + i * res), y - (y0 + j * res))
                if d < best:
                    best, bx, by = d, i, j
    if bx < 0:
        return np.inf, x, y
    for _ in range(lookahead):
        low, lx, ly = field[bx, by], bx, by
        for di in (-1, 0, 1):
            for dj in (-1, 0, 1):
                i, j = bx + di, by + dj
                if 0 <= i < nx and 0 <= j < ny and field[i, j] < low:
                    low, lx, ly = field[i, j], i, j
        if lx == bx and ly == by:
            break
        bx, by = lx, ly
    return best, x0 + bx * res, y0 + by * res


class PathGuide:
    """Cost fields to a set of goals over one layout's free space (see the module docstring).

    Args:
        free: the layout's free-space grids (``scene.free_space``).
        radius: the robot's disc radius (m), the one ``free`` was built for.
        reach: cells searched around the robot for the nearest point of the field.
        lookahead: descent steps (cells) from the robot to the lookahead point.
        wall_cost: the extra cost factor right at the disc radius from an obstacle
            (:data:`WALL_COST`; 0 makes the cost the path's length in metres).
    """

    def __init__(self, free: FreeSpace, radius: float, reach: int = 3, lookahead: int = 8,
                 wall_cost: float = WALL_COST) -> None:
        self.free = free
        self.reach, self.lookahead = reach, lookahead
        self.resolution = free.resolution
        self.x0, self.y0 = float(free.xs[0]), float(free.ys[0])
        gx, gy = np.meshgrid(free.xs, free.ys, indexing="ij")
        clearance = free.layout.clearance(gx, gy)
        self._passable = (free.component > 0) & (clearance > radius)
        penalty = 1.0 + wall_cost * np.clip(1.0 - (clearance - radius) / WALL_MARGIN, 0.0, 1.0)
        self._graph = grid_graph(self._passable, penalty)
        self.fields: list[np.ndarray] = []

    def set_goals(self, goals: tuple[tuple[float, float], ...]) -> None:
        """One cost field (m) per goal, from the passable cell nearest each goal."""
        self.fields = []
        for goal in goals:
            self.add_goal(goal)

    def add_goal(self, goal: tuple[float, float]) -> int:
        """Add the cost field (m) to ``goal``, from the passable cell nearest it; its index for :meth:`query`."""
        gx, gy = goal
        nx, ny = self._passable.shape
        cell = self._nearest_passable(gx, gy)
        if cell is None:
            self.fields.append(np.full((nx, ny), np.inf))
            return len(self.fields) - 1
        dist = dijkstra(self._graph, directed=False, indices=cell[0] * ny + cell[1])
        field = dist.reshape(nx, ny) * self.resolution
        # the goal point itself, off the cell centre: cost through the centre
        field += math.hypot(gx - (self.x0 + cell[0] * self.resolution), gy - (self.y0 + cell[1] * self.resolution))
        self.fields.append(field)
        return len(self.fields) - 1

    def _nearest_passable(self, x: float, y: float, reach: int = 3) -> tuple[int, int] | None:
        res = self.resolution
        cx, cy = round((x - self.x0) / res), round((y - self.y0) / res)
        nx, ny = self._passable.shape
        best, cell = math.inf, None
        for i in range(max(cx - reach, 0), min(cx + reach + 1, nx)):
            for j in range(max(cy - reach, 0), min(cy + reach + 1, ny)):
                if self._passable[i, j]:
                    d = math.hypot(x - (self.x0 + i * res), y - (self.y0 + j * res))
                    if d < best:
                        best, cell = d, (i, j)
        return cell

    def query(self, goal: int, x: float, y: float) -> tuple[float, float, float]:
        """``(cost, lx, ly)``: the path cost (m) from (x, y) to goal ``goal`` and the lookahead
        point; the straight line (distance, the goal itself) where the field has nothing near."""
        cost, lx, ly = _query(self.fields[goal], self.resolution, self.x0, self.y0, x, y, self.reach, self.lookahead)
        if cost == math.inf:
            return math.inf, lx, ly
        return float(cost), float(lx), float(ly)
