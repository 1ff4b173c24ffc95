"""The coordinated planner's map: each cell's point, the blocked cells, the closed moves and the
conflicting cells, found on a fine occupancy grid (:func:`cell_map`)."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from typing import Any

import numpy as np

from bulletnav.fleet.spacetime import MOVES, Cell

FreePoints = Callable[[Cell], Iterator[tuple[float, float]]]
"""A cell -> its free fine points, nearest its centre first."""


@dataclass(frozen=True)
class CellMap:
    """The plan's map on a grid of ``(nx, ny)`` cells."""

    points: np.ndarray
    """Each cell's point (m), shape ``(nx, ny, 2)``, NaN in blocked cells."""
    blocked: np.ndarray
    """Cells with no free point, shape ``(nx, ny)``."""
    closed: np.ndarray
    """``closed[x, y, m]``: the move ``MOVES[m]`` out of cell ``(x, y)`` is shut (the segment
    between the two cells' points is not free)."""
    conflicts: dict[Cell, tuple[Cell, ...]]
    """Cell -> the neighbouring free cells whose points lie closer than ``leave_distance``."""


def cell_map(grid: Any, fine: Any, resolution: float, point_resolution: float, leave_distance: float,
             repair: bool) -> CellMap:
    """The map of ``grid`` (cells of side ``resolution``, m) from the ``fine`` occupancy grid
    (side ``point_resolution``): each cell's point is its free fine point nearest its centre (a
    cell with none is blocked), repaired where a passage off the centres would otherwise leave
    parts unjoined (``repair``, :func:`repair_points`); a move is closed when the segment
    between the two points is not free; two cells conflict when their points are closer than
    ``leave_distance`` (m)."""
    free_points = _free_points(grid, fine, resolution, point_resolution)
    points, blocked = _nearest_points(grid.shape, free_points)
    if repair:
        repair_points(grid, points, blocked, free_points, fine)
    closed = _closed_moves(points, blocked, fine)
    return CellMap(points, blocked, closed, _conflicts(points, blocked, leave_distance))


def _free_points(grid: Any, fine: Any, resolution: float, point_resolution: float) -> FreePoints:
    """A cell -> its free fine points, nearest its centre first (ties in offset order)."""
    occ, (fnx, fny) = fine.occupied, fine.shape
    k = int(round(0.5 * resolution / point_resolution))
    offsets = sorted(((a * point_resolution, b * point_resolution) for a in range(-k, k + 1)
                      for b in range(-k, k + 1)), key=lambda o: (o[0] ** 2 + o[1] ** 2, o))
    half = 0.5 * resolution + 1e-9
    offsets = [o for o in offsets if abs(o[0]) < half and abs(o[1]) < half]

    def free_points(cell: Cell) -> Iterator[tuple[float, float]]:
        cx, cy = grid.cell_to_world(*cell)
        for ox, oy in offsets:
            fx, fy = fine.world_to_cell((cx + ox, cy + oy))
            if 0 <= fx < fnx and 0 <= fy < fny and not occ[fx, fy]:
                yield fine.cell_to_world(fx, fy)

    return free_points


def _nearest_points(shape: tuple[int, int], free_points: FreePoints) -> tuple[np.ndarray, np.ndarray]:
    """Each cell's free point nearest its centre (NaN where none) and the cells with none."""
    nx, ny = shape
    points = np.full((nx, ny, 2), np.nan)
    blocked = np.ones((nx, ny), dtype=bool)
    for x in range(nx):
        for y in range(ny):
            point = next(free_points((x, y)), None)
            if point is not None:
                points[x, y] = point
                blocked[x, y] = False
    return points, blocked


def _closed_moves(points: np.ndarray, blocked: np.ndarray, fine: Any) -> np.ndarray:
    """``closed[x, y, m]``: the segment from cell ``(x, y)``'s point to that of its neighbour
    by ``MOVES[m]`` is not free on ``fine`` (both directions marked)."""
    nx, ny = blocked.shape
    closed = np.zeros((nx, ny, len(MOVES)), dtype=bool)
    for x in range(nx):
        for y in range(ny):
            if blocked[x, y]:
                continue
            for m, (dx, dy) in enumerate(MOVES[1:], 1):
                u, v = x + dx, y + dy
                if 0 <= u < nx and 0 <= v < ny and not blocked[u, v] and (dx, dy) > (0, 0):
                    if not fine.segment_free(points[x, y], points[u, v]):
                        closed[x, y, m] = closed[u, v, MOVES.index((-dx, -dy))] = True
    return closed


def _conflicts(points: np.ndarray, blocked: np.ndarray, leave_distance: float) -> dict[Cell, tuple[Cell, ...]]:
    """Free cell -> its free neighbours (8-connected) whose points lie closer than ``leave_distance``."""
    nx, ny = blocked.shape
    conflicts: dict[Cell, list[Cell]] = {}
    for x in range(nx):
        for y in range(ny):
            if blocked[x, y]:
                continue
            for dx in range(-1, 2):
                for dy in range(-1, 2):
                    u, v = x + dx, y + dy
                    if ((dx, dy) != (0, 0) and 0 <= u < nx and 0 <= v < ny and not blocked[u, v]
                            and math.dist(points[x, y], points[u, v]) < leave_distance):
                        conflicts.setdefault((x, y), []).append((u, v))
    return {c: tuple(o) for c, o in conflicts.items()}


def repair_points(grid: Any, points: np.ndarray, blocked: np.ndarray, free_points: FreePoints, fine: Any) -> None:
    """Where two neighbouring cells lie in parts of the map that no open move joins and the
    segment between their points is not free, move the two points (in place) to the pair of their
    cells' free points nearest the centres whose segment is free and that keeps every other open
    move of the two cells open (a passage narrower than a cell and off the centres joins the
    parts). Maps without such parts keep their points."""
    free = fine.segment_free
    cells = {(int(x), int(y)) for x, y in zip(*np.nonzero(~blocked))}
    parent = {c: c for c in cells}

    def root(c: Cell) -> Cell:
        while parent[c] != c:
            parent[c] = parent[parent[c]]
            c = parent[c]
        return c

    pairs = [((x, y), (x + dx, y + dy)) for (x, y) in sorted(cells) for dx, dy in ((1, 0), (0, 1))
             if (x + dx, y + dy) in cells]
    shut = []
    for a, b in pairs:
        if free(points[a], points[b]):
            parent[root(a)] = root(b)
        else:
            shut.append((a, b))

    def open_neighbours(cell: Cell, but: Cell) -> list[tuple[float, float]]:
        out = []
        for dx, dy in MOVES[1:]:
            n = (cell[0] + dx, cell[1] + dy)
            if n != but and n in cells and free(points[cell], points[n]):
                out.append(points[n])
        return out

    for a, b in shut:
        if root(a) == root(b):
            continue
        keep_a, keep_b = open_neighbours(a, b), open_neighbours(b, a)
        ca = [p for p in free_points(a) if all(free(p, q) for q in keep_a)]
        cb = [p for p in free_points(b) if all(free(p, q) for q in keep_b)]
        centre_a, centre_b = grid.cell_to_world(*a), grid.cell_to_world(*b)
        for _, pa, pb in sorted(((math.dist(pa, centre_a) + math.dist(pb, centre_b), pa, pb) for pa in ca for pb in cb),
                                key=lambda e: e[0]):
            if free(pa, pb):
                points[a], points[b] = pa, pb
                parent[root(a)] = root(b)
                break


__all__ = ["CellMap", "FreePoints", "cell_map", "repair_points"]
