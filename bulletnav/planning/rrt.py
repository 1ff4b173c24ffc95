"""RRT in continuous 2-D space over an :class:`~bulletnav.planning.grid.OccupancyGrid`.

Tree growth, nearest-neighbour search (brute force over a preallocated node array, which
beats a k-d tree at a few thousand nodes) and shortcutting run in numba. Random numbers are
drawn from the caller's ``numpy.random.Generator`` in Python and handed to the kernel, so a
seeded generator gives the same path on every run and no global random state is touched.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence

import numpy as np
from numba import njit

from bulletnav.planning.grid import OccupancyGrid, _segment_free

#: Iterations per kernel call; between calls the Python side checks the time budget and
#: draws the next batch of random numbers. Most problems finish inside the first batch.
_BATCH = 256


@njit(cache=True, nogil=True)
def _rrt_grow(occ: np.ndarray, res: float, ox: float, oy: float,
              x0: float, y0: float, width: float, height: float,
              gx: float, gy: float, step: float, goal_bias: float,
              rand: np.ndarray, nodes: np.ndarray, parent: np.ndarray, n: int) -> tuple[int, int]:
    """Run one RRT iteration per row of ``rand`` (u_bias, u_x, u_y in [0, 1)).

    ``nodes[:n]`` / ``parent[:n]`` hold the tree and are extended in place; the arrays must
    have room for two more nodes per row. Returns (new node count, index of the goal node or
    -1 if it was not reached).
    """
    step2 = step * step
    for it in range(rand.shape[0]):
        if rand[it, 0] < goal_bias:
            qx, qy = gx, gy
        else:
            qx = x0 + rand[it, 1] * width
            qy = y0 + rand[it, 2] * height
        best = 0
        best_d2 = math.inf
        for i in range(n):
            ddx = nodes[i, 0] - qx
            ddy = nodes[i, 1] - qy
            d2 = ddx * ddx + ddy * ddy
            if d2 < best_d2:
                best_d2 = d2
                best = i
        if best_d2 == 0.0:
            continue  # the sample is already a node: nothing to grow
        nx_, ny_ = nodes[best, 0], nodes[best, 1]
        if best_d2 > step2:
            scale = step / math.sqrt(best_d2)
            px = nx_ + (qx - nx_) * scale
            py = ny_ + (qy - ny_) * scale
        else:
            px, py = qx, qy
        if not _segment_free(occ, res, ox, oy, nx_, ny_, px, py):
            continue
        nodes[n, 0] = px
        nodes[n, 1] = py
        parent[n] = best
        n += 1
        if px == gx and py == gy:
            return n, n - 1
        ddx = gx - px
        ddy = gy - py
        if ddx * ddx + ddy * ddy <= step2 and _segment_free(occ, res, ox, oy, px, py, gx, gy):
            nodes[n, 0] = gx
            nodes[n, 1] = gy
            parent[n] = n - 1
            return n + 1, n
    return n, -1


@njit(cache=True, nogil=True)
def _extract_path(nodes: np.ndarray, parent: np.ndarray, goal: int) -> np.ndarray:
    """(k, 2) waypoints from the root (node 0) to node ``goal``."""
    k = 1
    c = goal
    while parent[c] >= 0:
        c = parent[c]
        k += 1
    out = np.empty((k, 2))
    c = goal
    for i in range(k - 1, -1, -1):
        out[i, 0] = nodes[c, 0]
        out[i, 1] = nodes[c, 1]
        c = parent[c]
    return out


@njit(cache=True, nogil=True)
def _shortcut(occ: np.ndarray, res: float, ox: float, oy: float, path: np.ndarray) -> np.ndarray:
    """Greedy shortcut: from each kept waypoint jump to the farthest later one in free sight."""
    k = path.shape[0]
    keep = np.empty(k, dtype=np.int64)
    keep[0] = 0
    m = 1
    i = 0
    while i < k - 1:
        j = k - 1
        # j = i + 1 is always reachable: that segment is a tree edge, checked when it was added.
        while j > i + 1 and not _segment_free(occ, res, ox, oy, path[i, 0], path[i, 1], path[j, 0], path[j, 1]):
            j -= 1
        keep[m] = j
        m += 1
        i = j
    out = np.empty((m, 2))
    for r in range(m):
        out[r, 0] = path[keep[r], 0]
        out[r, 1] = path[keep[r], 1]
    return out


def rrt(grid: OccupancyGrid, start_xy: Sequence[float], goal_xy: Sequence[float], rng: np.random.Generator, *,
        step: float = 0.5, goal_bias: float = 0.1, max_iters: int = 5000, time_budget_s: float = 0.05,
        shortcut: bool = True) -> list[tuple[float, float]] | None:
    """Plan a collision-free polyline from ``start_xy`` to ``goal_xy`` (m) with RRT.

    Samples uniformly over the grid's world extent (with probability ``goal_bias`` the goal
    itself), steers at most ``step`` metres from the nearest tree node, and accepts an edge
    only if :meth:`OccupancyGrid.segment_free` holds for it exactly. Whenever a new node is
    within ``step`` of the goal with free sight, the goal is joined and the search stops.

    Args:
        grid: The map; cells outside it count as occupied.
        start_xy: Start (m); must lie in a free cell.
        goal_xy: Goal (m); must lie in a free cell.
        rng: Source of every random number (three per iteration, drawn in batches).
        step: Maximum edge length (m), > 0.
        goal_bias: Probability in [0, 1] of sampling the goal.
        max_iters: Maximum number of iterations, >= 0.
        time_budget_s: Wall-clock budget (s), > 0; checked every few hundred iterations.
        shortcut: Whether to shortcut the tree path greedily afterwards.

    Returns:
        Waypoints (m) from exactly ``start_xy`` to exactly ``goal_xy``, every segment free;
        or None when start or goal is not free or the iteration or time budget runs out.

    Raises:
        ValueError: A parameter is out of range.
    """
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a positive number of metres, got {step!r}")
    if not 0.0 <= goal_bias <= 1.0:
        raise ValueError(f"goal_bias must be in [0, 1], got {goal_bias!r}")
    if max_iters < 0:
        raise ValueError(f"max_iters must be >= 0, got {max_iters!r}")
    if not time_budget_s > 0:
        raise ValueError(f"time_budget_s must be > 0 seconds, got {time_budget_s!r}")
    deadline = time.perf_counter() + time_budget_s
    sx, sy = float(start_xy[0]), float(start_xy[1])
    gx, gy = float(goal_xy[0]), float(goal_xy[1])
    if not (grid.is_free_point((sx, sy)) and grid.is_free_point((gx, gy))):
        return None
    occ, res, (ox, oy) = grid.occupied, grid.resolution, grid.origin
    if (sx, sy) == (gx, gy):
        return [(sx, sy), (gx, gy)]
    if math.hypot(gx - sx, gy - sy) <= step and _segment_free(occ, res, ox, oy, sx, sy, gx, gy):
        return [(sx, sy), (gx, gy)]
    x0, x1, y0, y1 = grid.bounds
    max_iters = int(max_iters)
    nodes = np.empty((max_iters + 2, 2))
    parent = np.empty(max_iters + 2, dtype=np.int64)
    nodes[0] = sx, sy
    parent[0] = -1
    n, goal_node, done = 1, -1, 0
    while done < max_iters and goal_node < 0:
        if done and time.perf_counter() > deadline:
            return None
        batch = min(_BATCH, max_iters - done)
        rand = rng.random((batch, 3))
        n, goal_node = _rrt_grow(occ, res, ox, oy, x0, y0, x1 - x0, y1 - y0, gx, gy,
                                 float(step), float(goal_bias), rand, nodes, parent, n)
        done += batch
    if goal_node < 0:
        return None
    path = _extract_path(nodes, parent, goal_node)
    if shortcut:
        path = _shortcut(occ, res, ox, oy, path)
    out = list(map(tuple, path.tolist()))
    # The kernel copied start and goal bit for bit, but hand back the caller's exact values.
    out[0], out[-1] = (sx, sy), (gx, gy)
    return out
