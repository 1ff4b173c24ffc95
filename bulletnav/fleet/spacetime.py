"""Prioritized planning in space-time: a reservation table and windowed space-time A*
(cooperative A* and its windowed, hierarchical form WHCA*; Silver 2005, "Cooperative Pathfinding").

Pure algorithms on a boolean grid (``blocked[ix, iy]``), no simulation. Time advances in whole
steps; in one step a robot moves to one of its 4 neighbouring cells or waits in its cell.

- :class:`ReservationTable` holds, per time step, which robot has reserved each cell (vertex
  reservations) and each move between two cells (edge reservations). A move is refused when
  its target cell is reserved by another robot at the arrival step (a *vertex conflict*) or
  another robot has reserved the opposite move in the same step (a *swap*, an edge conflict).
  With ``robustness`` k a path also holds each cell for k steps after it leaves it, so a robot
  never enters a cell less than k + 1 steps after another left it (slack for tracking error).
- :func:`space_time_astar` finds, for one robot, the cheapest path of exactly ``window`` steps
  that respects the table. Each step costs 1, except waiting on the goal (0). The path's cost
  is the cost of its steps plus the true distance (:func:`distance_map`, steps on the static
  grid, ignoring other robots) from its last cell to the goal: the hierarchical heuristic of
  HCA*, which is also the A* heuristic (consistent, so the first window-end state popped is
  optimal). Ties break toward the larger time-in-window and then the lower cell index, so
  plans are deterministic.
"""

from __future__ import annotations

import heapq
from collections import deque

import numpy as np

Cell = tuple[int, int]
MOVES: tuple[Cell, ...] = ((0, 0), (1, 0), (-1, 0), (0, 1), (0, -1))
"""Wait, then the 4 neighbours (the order in which successors are generated)."""


class ReservationTable:
    """Cells and moves reserved per time step by robots (see the module docstring).

    Args:
        robustness: steps a path keeps each cell after leaving it (0: plain vertex reservations).
        conflicts: cell -> the other cells a robot in it also holds (cells whose points a robot
            drives to are too close together for two robots); none by default.
    """

    def __init__(self, robustness: int = 0, conflicts: dict[Cell, tuple[Cell, ...]] | None = None) -> None:
        if robustness < 0:
            raise ValueError(f"robustness must be >= 0, got {robustness}")
        self.robustness = robustness
        self.conflicts = conflicts or {}
        self._vertex: dict[tuple[Cell, int], int] = {}
        self._edge: dict[tuple[Cell, Cell, int], int] = {}

    def clear(self) -> None:
        self._vertex.clear()
        self._edge.clear()

    def owner(self, cell: Cell, t: int) -> int | None:
        """The robot that reserved ``cell`` at step ``t``, or None."""
        return self._vertex.get((cell, t))

    def vertex_free(self, cell: Cell, t: int, agent: int) -> bool:
        """True when nobody but ``agent`` holds ``cell`` at step ``t``."""
        who = self._vertex.get((cell, t))
        return who is None or who == agent

    def move_allowed(self, a: Cell, b: Cell, t: int, agent: int) -> bool:
        """True when ``agent`` may go from ``a`` (at step ``t``) to ``b`` (at ``t + 1``):
        ``b`` is not held by another robot at ``t + 1``, no other robot moves ``b -> a`` in
        that step, and (with ``robustness`` k) nobody else holds ``a`` in the k steps after
        it is left (this robot still does)."""
        if not self.vertex_free(b, t + 1, agent):
            return False
        if a != b:
            who = self._edge.get((b, a, t))
            if who is not None and who != agent:
                return False
            for dt in range(1, self.robustness + 1):
                if not self.vertex_free(a, t + dt, agent):
                    return False
        return True

    def reserve_cell(self, cell: Cell, t: int, agent: int, conflicts: bool = True) -> None:
        """Hold ``cell`` (and, with ``conflicts``, the cells it conflicts with) at step ``t`` for
        ``agent`` (first come first served: an existing reservation by another robot is kept)."""
        self._vertex.setdefault((cell, t), agent)
        if not conflicts:
            return
        for other in self.conflicts.get(cell, ()):
            self._vertex.setdefault((other, t), agent)

    def reserve_path(self, path: list[Cell], agent: int, t0: int = 0) -> None:
        """Reserve ``path`` (one cell per step from step ``t0``): each cell at its step and
        the ``robustness`` steps after, and each move as an edge."""
        k = self.robustness
        for i, cell in enumerate(path):
            for dt in range(k + 1):
                self.reserve_cell(cell, t0 + i + dt, agent)
            if i + 1 < len(path) and path[i + 1] != cell:
                self._edge.setdefault((cell, path[i + 1], t0 + i), agent)

    def __len__(self) -> int:
        return len(self._vertex)


def reserve_starts(table: ReservationTable, starts: list[Cell], held: list[list[Cell]], steps: int) -> None:
    """Reserve, for steps ``0 .. steps - 1``, where the robots stand at a replan: first every
    robot's own cell (``starts[i]``, without the cells it conflicts with), then every start
    cell with its conflicts, then the cells each robot also holds (``held[i]``: cells it is too
    close to for another robot), first come first served. A robot's own cell stays its own
    even where another robot stands close enough to hold it too (two robots pressed together):
    were the other's hold reserved first, the robot could neither wait in its cell nor leave
    it (leaving checks that nobody else holds the cell it leaves), and two such robots would
    plan waits for good."""
    for i, cell in enumerate(starts):
        for t in range(steps):
            table.reserve_cell(cell, t, i, conflicts=False)
    for cells in ([[s] for s in starts], held):
        for i, group in enumerate(cells):
            for cell in group:
                for t in range(steps):
                    table.reserve_cell(cell, t, i)


def distance_map(blocked: np.ndarray, goal: Cell, closed: np.ndarray | None = None) -> np.ndarray:
    """Steps (4-connected) from every cell to ``goal`` on the static grid; ``inf`` where
    unreachable or blocked (the goal itself counts as free). ``closed[x, y, m]`` (optional,
    symmetric) forbids the move ``MOVES[m]`` out of cell (x, y) between two free cells."""
    nx, ny = blocked.shape
    dist = np.full((nx, ny), np.inf)
    gx, gy = goal
    if not (0 <= gx < nx and 0 <= gy < ny):
        return dist
    dist[gx, gy] = 0.0
    queue = deque([goal])
    while queue:
        x, y = queue.popleft()
        d = dist[x, y] + 1.0
        for m, (dx, dy) in enumerate(MOVES[1:], 1):
            u, v = x + dx, y + dy
            if closed is not None and closed[x, y, m]:
                continue
            if 0 <= u < nx and 0 <= v < ny and not blocked[u, v] and dist[u, v] == np.inf:
                dist[u, v] = d
                queue.append((u, v))
    return dist


def space_time_astar(blocked: np.ndarray, start: Cell, goal: Cell, table: ReservationTable, agent: int,
                     window: int, heuristic: np.ndarray | None = None, max_expansions: int = 200_000,
                     closed: np.ndarray | None = None) -> tuple[list[Cell], float] | None:
    """The cheapest ``window``-step path from ``start`` (at step 0) for ``agent``, respecting
    ``table``: ``(cells, cost)`` with ``window + 1`` cells, or None when every path is blocked
    within the window (or ``max_expansions`` states were expanded).

    Args:
        blocked: static obstacles (True = blocked); the start cell is always allowed.
        start, goal: cells (ix, iy).
        table: the reservations of the robots planned before this one.
        agent: this robot's id (its own reservations do not block it).
        window: steps to plan (>= 1).
        heuristic: :func:`distance_map` of ``goal`` (computed when None).
        closed: moves forbidden between free cells, as :func:`distance_map` takes them.
    """
    if window < 1:
        raise ValueError(f"window must be >= 1 step, got {window}")
    h = distance_map(blocked, goal, closed) if heuristic is None else heuristic
    nx, ny = blocked.shape
    sx, sy = start
    h0 = h[sx, sy] if np.isfinite(h[sx, sy]) else _fallback_h(start, goal)
    # entries: (f, -t, cell index, g, t, cell); parents by (cell, t)
    heap = [(h0, 0, sx * ny + sy, 0.0, 0, start)]
    parent: dict[tuple[Cell, int], tuple[Cell, int] | None] = {(start, 0): None}
    best_g: dict[tuple[Cell, int], float] = {(start, 0): 0.0}
    expansions = 0
    while heap:
        f, _, _, g, t, cell = heapq.heappop(heap)
        if g > best_g.get((cell, t), np.inf):
            continue
        if t == window:
            path = [cell]
            key = parent[(cell, t)]
            while key is not None:
                path.append(key[0])
                key = parent[key]
            return path[::-1], float(f)
        expansions += 1
        if expansions > max_expansions:
            return None
        x, y = cell
        for m, (dx, dy) in enumerate(MOVES):
            u, v = x + dx, y + dy
            nxt = (u, v)
            if not (0 <= u < nx and 0 <= v < ny):
                continue
            if closed is not None and closed[x, y, m] and not blocked[x, y]:
                continue
            if blocked[u, v] and nxt != start:
                continue
            if not table.move_allowed(cell, nxt, t, agent):
                continue
            step = 0.0 if (dx, dy) == (0, 0) and cell == goal else 1.0
            g2 = g + step
            key2 = (nxt, t + 1)
            if g2 < best_g.get(key2, np.inf):
                best_g[key2] = g2
                parent[key2] = (cell, t)
                hv = h[u, v] if np.isfinite(h[u, v]) else _fallback_h(nxt, goal)
                heapq.heappush(heap, (g2 + hv, -(t + 1), u * ny + v, g2, t + 1, nxt))
    return None


def _fallback_h(cell: Cell, goal: Cell) -> float:
    """Manhattan distance, for a cell the static grid cannot reach the goal from (a robot
    standing in an inflated cell): large enough to prefer leaving it."""
    return float(abs(cell[0] - goal[0]) + abs(cell[1] - goal[1])) + 1000.0


def path_cost(path: list[Cell], goal: Cell, heuristic: np.ndarray) -> float:
    """The cost :func:`space_time_astar` gives ``path``: its steps (waiting on the goal free)
    plus the distance from its last cell to the goal."""
    g = sum(0.0 if (a == b and a == goal) else 1.0 for a, b in zip(path, path[1:]))
    return g + float(heuristic[path[-1]])


def plan_dependencies(paths: list[list[Cell]], held: list[list[Cell]] | None = None,
                      conflicts: dict[Cell, tuple[Cell, ...]] | None = None) -> list[dict[int, list[tuple[int, int]]]]:
    """The precedence of a set of plans (an action dependency graph, Hönig et al. 2019): for
    robot i and each step u at which ``paths[i]`` enters a new cell, the pairs ``(j, t)``
    such that robot j is in that cell (or one conflicting with it) at step t < u, the latest
    such t per robot. Executing the plans so that robot i takes step u only once every robot
    j of its pairs has progressed past step t keeps each cell's order of robots the plan's
    whatever the robots' speeds; every pair points to an earlier step, so no cycle of waits.

    Args:
        paths: each robot's cells, one per plan step from step 0.
        held: cells each robot also holds at step 0 (besides ``paths[i][0]``).
        conflicts: cell -> cells a robot in it also holds (as :class:`ReservationTable` takes it).
    """
    conflicts = conflicts or {}
    visits: dict[Cell, list[tuple[int, int]]] = {}
    for j, path in enumerate(paths):
        extra = held[j] if held is not None else ()
        for t, cell in [*enumerate(path), *((0, c) for c in extra)]:
            for c in (cell, *conflicts.get(cell, ())):
                visits.setdefault(c, []).append((t, j))
    out: list[dict[int, list[tuple[int, int]]]] = []
    for i, path in enumerate(paths):
        deps: dict[int, list[tuple[int, int]]] = {}
        for u in range(1, len(path)):
            if path[u] == path[u - 1]:
                continue
            last: dict[int, int] = {}
            for t, j in visits.get(path[u], ()):
                if j != i and t < u:
                    last[j] = max(last.get(j, -1), t)
            deps[u] = sorted(last.items())
        out.append(deps)
    return out


def largest_component(blocked: np.ndarray, closed: np.ndarray | None = None) -> np.ndarray:
    """The free cells of the largest 4-connected free region of ``blocked`` (a bool mask of its
    shape; ``closed`` as :func:`distance_map` takes it): the floor the robots share, without
    the pockets a coarse grid cuts off."""
    nx, ny = blocked.shape
    label = np.full((nx, ny), -1, dtype=np.int64)
    sizes: list[int] = []
    for x0 in range(nx):
        for y0 in range(ny):
            if blocked[x0, y0] or label[x0, y0] >= 0:
                continue
            k = len(sizes)
            label[x0, y0] = k
            queue, size = deque([(x0, y0)]), 0
            while queue:
                x, y = queue.popleft()
                size += 1
                for m, (dx, dy) in enumerate(MOVES[1:], 1):
                    u, v = x + dx, y + dy
                    if closed is not None and closed[x, y, m]:
                        continue
                    if 0 <= u < nx and 0 <= v < ny and not blocked[u, v] and label[u, v] < 0:
                        label[u, v] = k
                        queue.append((u, v))
            sizes.append(size)
    if not sizes:
        return np.zeros((nx, ny), dtype=bool)
    return label == int(np.argmax(sizes))


def nearest_free(blocked: np.ndarray, cell: Cell) -> Cell:
    """``cell`` when it is free, else the nearest free cell (breadth-first, 4-connected);
    ``cell`` itself when the grid has no free cell."""
    nx, ny = blocked.shape
    x, y = min(max(cell[0], 0), nx - 1), min(max(cell[1], 0), ny - 1)
    if not blocked[x, y]:
        return x, y
    seen = {(x, y)}
    queue = deque([(x, y)])
    while queue:
        a, b = queue.popleft()
        for dx, dy in MOVES[1:]:
            u, v = a + dx, b + dy
            if 0 <= u < nx and 0 <= v < ny and (u, v) not in seen:
                if not blocked[u, v]:
                    return u, v
                seen.add((u, v))
                queue.append((u, v))
    return x, y


__all__ = ["MOVES", "ReservationTable", "distance_map", "largest_component", "nearest_free", "path_cost",
           "plan_dependencies", "reserve_starts", "space_time_astar"]
