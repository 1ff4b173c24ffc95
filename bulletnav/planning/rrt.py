"""RRT in continuous 2-D space over an :class:`~bulletnav.planning.grid.OccupancyGrid`.

The search runs in two phases, both bounded by iterations (samples):

1. The first batch of 256 iterations is plain RRT from the start with a goal bias, joining the
   goal once a new node sees it within one step. It solves most open maps (81 % of the box
   problems of ``bulletnav.bench.planner_bench``), with paths that head for the goal. PID + RRT
   navigation on 400 warehouse episodes (seeds 1000-1099, four random streams) timed out 3
   times with this phase, 11 times with RRT-Connect from the first iteration, and 7 times with
   the former one-tree RRT alone (0.05 s budget); no collisions, SPL 0.87 in all three.
2. If that fails, the grid's free cells are checked for a connection between start and goal
   (none: no path exists, stop at once), and the search goes on as RRT-Connect (Kuffner and
   LaValle, 2000): a second tree grows from the goal; each iteration extends one tree a step
   toward a sample and drives the other straight at the new node until it joins or is blocked,
   and the trees swap roles. Half the non-goal samples now fall inside *narrow* free cells:
   cells whose free run along x, y or a diagonal, wall to wall, is at most ``step`` long, such
   as a gap in a wall or a tight corridor. Both trees need samples in the gap to get through
   it, and uniform samples land there about once in a few thousand iterations.

No wall-clock limit: a problem and a generator state give the same path (bit for bit) on any
machine and in any process, whether or not numba had to compile first. Tree growth,
nearest-neighbour search (brute force over a preallocated node array, which beats a k-d tree
at a few thousand nodes), the grid analyses and shortcutting run in numba with ``cache=True``;
random numbers are drawn from the caller's ``numpy.random.Generator`` in Python and handed to
the kernel in batches, so no global random state is touched.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit

from bulletnav.planning.grid import OccupancyGrid, _segment_free

#: Iterations per kernel call, and the length of the one-tree phase; between calls the Python
#: side draws the next batch of random numbers and grows the node arrays.
_BATCH = 256

#: Share of the non-goal samples drawn from narrow cells once they are known (second batch on).
_NARROW_SHARE = 0.5

#: Default iteration budget. Fraction solved within a budget (2 000 problems each; mazes 1 000):
#: the narrow-passage problems of ``bulletnav.bench.planner_bench``: 99.5 % by 2 048, all by
#: 5 000; walls 0.1-0.5 m thick with 0.15-0.3 m gaps: 99.85 % by 5 000, all by 10 000;
#: 10 x 10-room mazes with 0.2-0.5 m corridors: 94 % by 10 000, 99.9 % by 20 000, all by 50 000.
#: An unsolved problem costs the whole budget (about 0.1 s on those maps), except that one whose start and
#: goal are disconnected on the grid stops after the first batch.
DEFAULT_MAX_ITERS = 50_000


@njit(cache=True, nogil=True)
def _append(nodes: np.ndarray, parent: np.ndarray, count: np.ndarray, t: int, x: float, y: float, p: int) -> int:
    """Add node (x, y) with parent ``p`` to tree ``t``; returns its index."""
    k = count[t]
    nodes[t, k, 0] = x
    nodes[t, k, 1] = y
    parent[t, k] = p
    count[t] = k + 1
    return k


@njit(cache=True, nogil=True)
def _nearest(nodes: np.ndarray, t: int, n: int, qx: float, qy: float) -> tuple[int, float]:
    """Index of the node of tree ``t`` (``nodes[t, :n]``) nearest to (qx, qy), and its squared distance (m^2)."""
    best = 0
    best_d2 = math.inf
    for i in range(n):
        ddx = nodes[t, i, 0] - qx
        ddy = nodes[t, i, 1] - qy
        d2 = ddx * ddx + ddy * ddy
        if d2 < best_d2:
            best_d2 = d2
            best = i
    return best, best_d2


@njit(cache=True, nogil=True)
def _grow(occ: np.ndarray, res: float, ox: float, oy: float,
          x0: float, y0: float, width: float, height: float, step: float, goal_bias: float,
          rand: np.ndarray, narrow: np.ndarray, nodes: np.ndarray, parent: np.ndarray,
          count: np.ndarray, state: np.ndarray, bidirectional: bool) -> None:
    """Run one iteration per row of ``rand`` (four uniforms in [0, 1) each): RRT-Connect if
    ``bidirectional``, else one-tree RRT from the start that joins the goal within one step.
    ``narrow`` holds the flat indices (``ix * ny + iy``) of the narrow cells, or nothing.

    Tree 0 is rooted at the start, tree 1 at the goal: ``nodes[t, :count[t]]`` and
    ``parent[t, :count[t]]`` hold tree ``t`` and are extended in place (the caller leaves room
    for one node plus a full straight connect per row). ``state`` is (tree that extends next,
    join node in tree 0, join node in tree 1); the join entries stay -1 until the trees meet
    through a free segment of length <= ``step``, and the kernel returns as soon as they do."""
    step2 = step * step
    ny = occ.shape[1]
    t = state[0]
    for it in range(rand.shape[0]):
        o = 1 - t
        # Extend tree t one step toward a sample: with probability goal_bias the other root,
        # else a point in a random narrow cell or uniform over the map.
        u = rand[it, 0]
        if u < goal_bias:
            qx, qy = nodes[o, 0, 0], nodes[o, 0, 1]
        elif narrow.shape[0] > 0 and u < goal_bias + (1.0 - goal_bias) * _NARROW_SHARE:
            c = narrow[min(int(rand[it, 1] * narrow.shape[0]), narrow.shape[0] - 1)]
            cx = c // ny
            qx = ox + (cx - 0.5 + rand[it, 2]) * res
            qy = oy + (c - cx * ny - 0.5 + rand[it, 3]) * res
        else:
            qx = x0 + rand[it, 1] * width
            qy = y0 + rand[it, 2] * height
        best, best_d2 = _nearest(nodes, t, count[t], qx, qy)
        added = False
        px = py = 0.0  # the new node, when one is added
        if best_d2 > 0.0:  # a sample that already is a node grows nothing
            bx, by = nodes[t, best, 0], nodes[t, best, 1]
            if best_d2 > step2:
                scale = step / math.sqrt(best_d2)
                px = bx + (qx - bx) * scale
                py = by + (qy - by) * scale
            else:
                px, py = qx, qy
            if _segment_free(occ, res, ox, oy, bx, by, px, py):
                _append(nodes, parent, count, t, px, py, best)
                added = True
        if added and not bidirectional:
            # One tree (t == 0): join the goal, tree 1's root, when it is within a step in free sight.
            gx, gy = nodes[1, 0, 0], nodes[1, 0, 1]
            ddx = gx - px
            ddy = gy - py
            if ddx * ddx + ddy * ddy <= step2 and _segment_free(occ, res, ox, oy, px, py, gx, gy):
                state[1] = count[0] - 1
                state[2] = 0
                return
        elif added:
            # Connect: march tree o straight at the new node until it joins or is blocked.
            new = count[t] - 1
            j, d2 = _nearest(nodes, o, count[o], px, py)
            while True:
                jx, jy = nodes[o, j, 0], nodes[o, j, 1]
                if d2 <= step2:
                    if _segment_free(occ, res, ox, oy, jx, jy, px, py):
                        state[0] = o
                        state[1 + t] = new
                        state[1 + o] = j
                        return
                    break
                scale = step / math.sqrt(d2)
                sx = jx + (px - jx) * scale
                sy = jy + (py - jy) * scale
                if not _segment_free(occ, res, ox, oy, jx, jy, sx, sy):
                    break
                j = _append(nodes, parent, count, o, sx, sy, j)
                ddx = px - sx
                ddy = py - sy
                d2 = ddx * ddx + ddy * ddy
        if bidirectional:
            t = o
    state[0] = t


@njit(cache=True, nogil=True)
def _connected(occ: np.ndarray, sx: int, sy: int, gx: int, gy: int) -> bool:
    """True iff free cells (sx, sy) and (gx, gy) are joined through edge-sharing free cells.

    Every collision-free segment visits edge-adjacent cells only (a segment through a corner
    also needs both cells beside it free), so any RRT path implies this connection: when it
    is missing no number of iterations can help.
    """
    nx, ny = occ.shape
    seen = np.zeros((nx, ny), dtype=np.bool_)
    stack = np.empty(nx * ny, dtype=np.int64)
    seen[sx, sy] = True
    stack[0] = sx * ny + sy
    top = 1
    while top > 0:
        top -= 1
        c = stack[top]
        x = c // ny
        y = c - x * ny
        if x == gx and y == gy:
            return True
        for d in range(4):
            ax = x + (1 if d == 0 else -1 if d == 1 else 0)
            ay = y + (1 if d == 2 else -1 if d == 3 else 0)
            if 0 <= ax < nx and 0 <= ay < ny and not seen[ax, ay] and not occ[ax, ay]:
                seen[ax, ay] = True
                stack[top] = ax * ny + ay
                top += 1
    return False


@njit(cache=True, nogil=True)
def _narrow_cells(occ: np.ndarray, res: float, width: float) -> np.ndarray:
    """Flat indices (``ix * ny + iy``) of the free cells whose run of free cells along x, y or
    a diagonal, between occupied cells or the map's edge, spans at most ``width`` metres."""
    nx, ny = occ.shape
    mark = np.zeros((nx, ny), dtype=np.bool_)
    limit = width * (1.0 + 1e-9)  # so 3 cells of 0.1 m count as 0.3 m despite 3 * 0.1 > 0.3
    for d in range(4):
        # Direction (dx, dy): x, y, diagonal, anti-diagonal; a diagonal step spans sqrt(2) cells.
        dx = 0 if d == 1 else 1
        dy = 0 if d == 0 else (-1 if d == 3 else 1)
        span = res * (1.4142135623730951 if d >= 2 else 1.0)
        # Walk every grid line once: it starts at a cell on the x = 0 column or on the y edge
        # the direction leaves from, whose predecessor is off the grid.
        for s in range(nx + ny - 1):
            x = 0 if s < ny else s - ny + 1
            y = s if s < ny else (0 if dy >= 0 else ny - 1)
            if 0 <= x - dx < nx and 0 <= y - dy < ny:
                continue  # not the first cell of its line
            length = 0
            while True:
                inside = 0 <= x < nx and 0 <= y < ny
                if inside and not occ[x, y]:
                    length += 1
                else:
                    if length * span <= limit:  # the free run just behind (x, y) is narrow
                        for k in range(1, length + 1):
                            mark[x - k * dx, y - k * dy] = True
                    length = 0
                    if not inside:
                        break
                x += dx
                y += dy
    return np.flatnonzero(mark.ravel())


@njit(cache=True, nogil=True)
def _join_path(nodes: np.ndarray, parent: np.ndarray, a: int, b: int) -> np.ndarray:
    """(k, 2) waypoints: start (root of tree 0) to node ``a``, then node ``b`` of tree 1 to the goal.

    A join node that coincides with its partner (the extension landed exactly on it) is kept once.
    """
    ka = 1
    c = a
    while parent[0, c] >= 0:
        c = parent[0, c]
        ka += 1
    kb = 1
    c = b
    while parent[1, c] >= 0:
        c = parent[1, c]
        kb += 1
    same = nodes[0, a, 0] == nodes[1, b, 0] and nodes[0, a, 1] == nodes[1, b, 1]
    k = ka + kb - (1 if same else 0)
    out = np.empty((k, 2))
    c = a
    for i in range(ka - 1, -1, -1):
        out[i, 0] = nodes[0, c, 0]
        out[i, 1] = nodes[0, c, 1]
        c = parent[0, c]
    c = parent[1, b] if same else b
    for i in range(ka, k):
        out[i, 0] = nodes[1, c, 0]
        out[i, 1] = nodes[1, c, 1]
        c = parent[1, c]
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
        # j = i + 1 is always reachable: that segment is a tree edge or the join, checked when made.
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
        step: float = 0.5, goal_bias: float = 0.1, max_iters: int = DEFAULT_MAX_ITERS,
        shortcut: bool = True) -> list[tuple[float, float]] | None:
    """Plan a collision-free polyline from ``start_xy`` to ``goal_xy`` (m) with RRT, then RRT-Connect.

    For the first 256 iterations one tree grows from the start: each steps at most ``step``
    metres from its nearest node toward a sample drawn uniformly over the grid's world extent
    (with probability ``goal_bias`` the goal), and the goal is joined once a new node is within
    ``step`` of it in free sight. After that, if start and goal are connected on the grid, a
    second tree grows from the goal and the two take turns (RRT-Connect), with half the
    non-goal samples in narrow free cells; see the module docstring. Every edge, the join
    included, is at most ``step`` long and accepted only if
    :meth:`OccupancyGrid.segment_free` holds for it exactly.

    The budget is ``max_iters`` samples; there is no wall-clock limit, so the result depends
    only on the arguments and the state of ``rng``, never on the machine or on compile time.
    Passing the former ``time_budget_s`` raises TypeError.

    Args:
        grid: The map; cells outside it count as occupied.
        start_xy: Start (m); must lie in a free cell.
        goal_xy: Goal (m); must lie in a free cell.
        rng: Source of every random number (four per iteration, drawn in batches of 256).
        step: Maximum edge length (m), > 0.
        goal_bias: Probability in [0, 1] of sampling the goal (with two trees: the other tree's root).
        max_iters: Maximum number of iterations (samples), >= 0.
        shortcut: Whether to shortcut the tree path greedily afterwards.

    Returns:
        Waypoints (m) from exactly ``start_xy`` to exactly ``goal_xy``, every segment free;
        or None when start or goal is not free, when they are not connected on the grid, or
        when ``max_iters`` iterations run out.

    Raises:
        ValueError: A parameter is out of range.
    """
    _check_arguments(step, goal_bias, max_iters)
    sx, sy = float(start_xy[0]), float(start_xy[1])
    gx, gy = float(goal_xy[0]), float(goal_xy[1])
    if not (grid.is_free_point((sx, sy)) and grid.is_free_point((gx, gy))):
        return None
    occ, res, (ox, oy) = grid.occupied, grid.resolution, grid.origin
    if (sx, sy) == (gx, gy):
        return [(sx, sy), (gx, gy)]
    if math.hypot(gx - sx, gy - sy) <= step and _segment_free(occ, res, ox, oy, sx, sy, gx, gy):
        return [(sx, sy), (gx, gy)]
    trees = _grow_trees(grid, (sx, sy), (gx, gy), rng, float(step), float(goal_bias), int(max_iters))
    if trees is None:
        return None
    nodes, parent, state = trees
    path = _join_path(nodes, parent, int(state[1]), int(state[2]))
    if shortcut:
        path = _shortcut(occ, res, ox, oy, path)
    out = list(map(tuple, path.tolist()))
    # The kernel copied start and goal bit for bit, but hand back the caller's exact values.
    out[0], out[-1] = (sx, sy), (gx, gy)
    return out


def _check_arguments(step: float, goal_bias: float, max_iters: int) -> None:
    """Raise ValueError for a parameter of :func:`rrt` out of range."""
    if not (math.isfinite(step) and step > 0):
        raise ValueError(f"step must be a positive number of metres, got {step!r}")
    if not 0.0 <= goal_bias <= 1.0:
        raise ValueError(f"goal_bias must be in [0, 1], got {goal_bias!r}")
    if max_iters < 0:
        raise ValueError(f"max_iters must be >= 0, got {max_iters!r}")


def _grow_trees(grid: OccupancyGrid, start: tuple[float, float], goal: tuple[float, float], rng: np.random.Generator,
                step: float, goal_bias: float, max_iters: int) -> tuple[np.ndarray, np.ndarray, np.ndarray] | None:
    """The two trees (nodes, parents) and the search state (extending tree, join node in tree 0,
    in tree 1) once they are joined, in batches of :data:`_BATCH` iterations; None when start and
    goal are not connected on the grid or ``max_iters`` run out (see :func:`rrt`)."""
    (sx, sy), (gx, gy) = start, goal
    occ, res, (ox, oy) = grid.occupied, grid.resolution, grid.origin
    x0, x1, y0, y1 = grid.bounds
    # One iteration adds at most one node to the extending tree and, while connecting, one
    # per step along a straight line across the map to the other.
    per_iter = 2 + int(math.ceil(math.hypot(x1 - x0, y1 - y0) / step))
    capacity = 1 + min(_BATCH, max_iters) * per_iter
    nodes = np.empty((2, capacity, 2))
    parent = np.empty((2, capacity), dtype=np.int64)
    nodes[0, 0] = sx, sy
    nodes[1, 0] = gx, gy
    parent[:, 0] = -1
    count = np.ones(2, dtype=np.int64)
    state = np.array([0, -1, -1], dtype=np.int64)  # extending tree, join node in tree 0, in tree 1
    narrow = np.empty(0, dtype=np.int64)
    done = 0
    while done < max_iters and state[1] < 0:
        if done == _BATCH:
            # Grid analyses only once the first batch failed: most problems never pay for them.
            if not _connected(occ, *grid.world_to_cell((sx, sy)), *grid.world_to_cell((gx, gy))):
                return None
            narrow = _narrow_cells(occ, res, step)
        batch = min(_BATCH, max_iters - done)
        need = int(count.max()) + batch * per_iter
        if need > capacity:  # grow geometrically; the trees' contents carry over unchanged
            capacity = max(need, 2 * capacity)
            nodes, parent = _enlarged(nodes, parent, capacity)
        rand = rng.random((batch, 4))
        _grow(occ, res, ox, oy, x0, y0, x1 - x0, y1 - y0, step, goal_bias,
              rand, narrow, nodes, parent, count, state, done >= _BATCH)
        done += batch
    return None if state[1] < 0 else (nodes, parent, state)


def _enlarged(nodes: np.ndarray, parent: np.ndarray, capacity: int) -> tuple[np.ndarray, np.ndarray]:
    """The two trees' arrays with room for ``capacity`` nodes each, their contents copied."""
    grown_nodes = np.empty((2, capacity, 2))
    grown_parent = np.empty((2, capacity), dtype=np.int64)
    grown_nodes[:, : nodes.shape[1]] = nodes
    grown_parent[:, : parent.shape[1]] = parent
    return grown_nodes, grown_parent


def _warmup() -> None:
    """Compile (or load from the on-disk cache) every kernel here, with the argument types rrt uses."""
    occ = np.zeros((4, 4), dtype=bool)
    occ[1, 1:3] = True
    grid = OccupancyGrid(occ, 1.0)
    rrt(grid, (0.0, 0.0), (3.0, 3.0), np.random.default_rng(0), step=1.0)
    # The grid analyses run only after a failed first batch, which a tiny map never has.
    _connected(grid.occupied, 0, 0, 3, 3)
    _narrow_cells(grid.occupied, grid.resolution, 1.0)
