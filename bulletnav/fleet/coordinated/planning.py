"""The coordinated controller's planning half (:class:`PlanningMixin`): the map of seen
obstacles, priorities, windowed prioritized planning in space-time with restarts, and the plan's
precedence constraints (which robot may enter which cell when)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bulletnav.fleet.spacetime import (
    MOVES,
    Cell,
    ReservationTable,
    distance_map,
    nearest_free,
    plan_dependencies,
    reserve_starts,
    space_time_astar,
)


def off_heading(pose: tuple[float, float, float], point: tuple[float, float]) -> float:
    """The angle (rad, -pi to pi) from the heading of a robot at ``pose`` to ``point``."""
    return math.remainder(math.atan2(point[1] - pose[1], point[0] - pose[0]) - pose[2], 2 * math.pi)


def next_move(path: list[Cell], k: int, end: int) -> int | None:
    """The first step after ``k``, up to ``end``, at which ``path`` leaves the cell of step
    ``k`` (None: it only waits there)."""
    return next((u for u in range(k + 1, end + 1) if path[u] != path[k]), None)


class PlanningMixin:
    """The planning half of :class:`~bulletnav.fleet.coordinated.CoordinatedController` (its
    docstring describes the method); the controller's ``reset`` sets the map and state it reads."""

    # ------------------------------------------------------------------ the map
    def _goal(self, info: dict[str, Any]) -> tuple[float, float]:
        return float(info["goal"][0]), float(info["goal"][1])

    def _cell(self, xy: tuple[float, float]) -> Cell:
        nx, ny = self.static_blocked.shape
        ix, iy = self.grid.world_to_cell(xy)
        return min(max(ix, 0), nx - 1), min(max(iy, 0), ny - 1)

    def _centre(self, cell: Cell) -> tuple[float, float]:
        """The point a robot drives to in ``cell`` (its centre in a blocked one)."""
        p = self.cell_points[cell]
        return self.grid.cell_to_world(*cell) if np.isnan(p[0]) else (float(p[0]), float(p[1]))
    def _heuristic(self, goal: Cell, stuck: bool = False) -> np.ndarray:
        """Steps to ``goal`` on the current map (static plus seen obstacles); where the seen
        obstacles cut a cell off, its static distance plus ``detour_steps`` (they move on), or
        plus a prohibitive 1000 for a ``stuck`` robot."""
        h = self._heuristics.get((goal, stuck))
        if h is None:
            static = self._static_heuristics.get(goal)
            if static is None:
                static = self._static_heuristics[goal] = distance_map(self.static_blocked, goal, self.closed)
            h = static
            if self.blocked is not self.static_blocked:
                h = np.minimum(distance_map(self.blocked, goal, self.closed),
                               static + (1000.0 if stuck else self.config.detour_steps))
            self._heuristics[(goal, stuck)] = h
        return h

    # ------------------------------------------------------------------ movers on the map
    def _observe(self, observations: dict[str, Any], positions: list[tuple[float, float]],
                 poses: list[tuple[float, float, float]]) -> None:
        """Mark the cells near lidar returns that are no robot (see ``obstacle_*``)."""
        cfg = self.config
        if cfg.obstacle_range <= 0 or cfg.obstacle_memory_s <= 0:
            return
        now = self.view.time_s
        others = np.asarray(positions)
        res, (ox, oy) = self.grid.resolution, self.grid.origin
        nx, ny = self._seen_until.shape
        reach = int(math.ceil(cfg.obstacle_radius / res)) + 1
        pts = self.cell_points
        for i, agent in enumerate(self.agents):
            ranges = self._ranges(observations[agent])
            hit = ranges < min(cfg.obstacle_range, 0.98 * self.max_range)
            if not hit.any():
                continue
            x, y, yaw = poses[i]
            lx, ly = x + self._lidar_offset * math.cos(yaw), y + self._lidar_offset * math.sin(yaw)
            c, s = math.cos(yaw), math.sin(yaw)
            dx, dy = self._cos[hit] * ranges[hit], self._sin[hit] * ranges[hit]
            px, py = lx + c * dx - s * dy, ly + s * dx + c * dy
            near = np.hypot(px[:, None] - others[None, :, 0], py[:, None] - others[None, :, 1]).min(axis=1)
            keep = near > 0.35  # a robot's 0.2 m disc plus margin: returns off robots are the plan's business
            for qx, qy in zip(px[keep], py[keep]):
                cx, cy = round((qx - ox) / res), round((qy - oy) / res)
                for u in range(cx - reach, cx + reach + 1):
                    for v in range(cy - reach, cy + reach + 1):
                        if (0 <= u < nx and 0 <= v < ny and not self.static_blocked[u, v]
                                and math.hypot(pts[u, v, 0] - qx, pts[u, v, 1] - qy) <= cfg.obstacle_radius):
                            self._seen_until[u, v] = now + cfg.obstacle_memory_s

    def _ranges(self, obs: Any) -> np.ndarray:
        state = obs["state"] if isinstance(obs, dict) else obs
        return np.asarray(state[: self.n_rays], dtype=np.float64) * self.max_range
    # ------------------------------------------------------------------ planning
    def replan(self) -> None:
        """Plan every robot anew from where it stands, the next robot first in priority
        (the rolling horizon calls this; see the class docstring)."""
        n, view = len(self.agents), self.view
        positions = [view.pose(i)[:2] for i in range(n)]
        committed = self.kept_moves(positions)
        self._rotate_priorities()
        self._update_blocked()
        starts = [self._cell(p) for p in positions]
        held = [self._held(p, s) for p, s in zip(positions, starts)]
        self.table = self._start_table(starts, held)
        self.held = held
        self.goal_cells = [nearest_free(~self._floor, self._cell(g)) for g in self.goals]
        self._track_stillness(positions, starts)
        heuristics, maps = self._plan_maps(positions, starts)
        first_moves = self._first_move_maps(committed, starts, maps)
        paths, order, failed, attempt = self._plan_paths(starts, held, heuristics, maps, first_moves)
        self.failed_plans += len(failed)
        self.restarted_plans += attempt
        self.planned_order = order
        """The order the last replan's paths were found in (``order`` after its restarts)."""
        self.paths = paths
        self.progress = [0] * n
        self.dependencies = plan_dependencies(self.paths, self.held, self.conflicts)
        """Per robot, step -> the (robot, step) pairs it waits on (:func:`~bulletnav.fleet.spacetime.plan_dependencies`)."""
        self._planned_at = view.time_s
        self.replans += 1

    def _rotate_priorities(self) -> None:
        """Start the priority order at the next robot (``rotate_s`` after the last rotation, or
        at the first replan)."""
        n, now = len(self.agents), self.view.time_s
        if now >= self._rotated_at + self.config.rotate_s - 1e-9 or not self.order:
            self.order = [(self._rotation + k) % n for k in range(n)]
            self._rotation = (self._rotation + 1) % n
            self._rotated_at = now

    def _update_blocked(self) -> None:
        """The current map: the static one plus the cells seen blocked now (the heuristics'
        cache emptied when it changed)."""
        seen = self._seen_until > self.view.time_s
        blocked = self.static_blocked | seen if seen.any() else self.static_blocked
        if not np.array_equal(blocked, self.blocked):
            self._heuristics = {}
        self.blocked = blocked

    def _track_stillness(self, positions: list[tuple[float, float]], starts: list[Cell]) -> None:
        """Since when each robot's plans keep it in place, and since when it has not moved
        ``stuck_distance`` (both reset at its goal)."""
        now, cfg = self.view.time_s, self.config
        for i, path in enumerate(self.paths):
            if path and (path[-1] != path[0] or path[0] == self.goal_cells[i]):
                self._still_since[i] = now
            if math.dist(positions[i], self._anchors[i]) >= cfg.stuck_distance or starts[i] == self.goal_cells[i]:
                self._anchors[i], self._moved_at[i] = positions[i], now  # since when it has not moved

    def _plan_maps(self, positions: list[tuple[float, float]],
                   starts: list[Cell]) -> tuple[list[np.ndarray], list[np.ndarray]]:
        """Each robot's heuristic and map for this replan: a stuck robot (``stuck_s``) plans round
        the movers standing for the robots and backs off one yielding to it; a robot standing
        where a mover is seen plans out of its cell."""
        cfg, now, n = self.config, self.view.time_s, len(self.agents)
        heuristics, maps = [], []
        standing = None
        for i in range(n):
            stuck = max(now - self._still_since[i], now - self._moved_at[i]) >= cfg.stuck_s
            h, grid = self._heuristic(self.goal_cells[i], stuck), self.blocked
            if stuck and cfg.block_yielding:
                standing = self._standing_movers() if standing is None else standing
                if standing.any():  # a stuck robot plans round the movers standing for the robots
                    grid = self.blocked | standing
                    h = np.minimum(distance_map(grid, self.goal_cells[i], self.closed), h + 1000.0)
            maps.append(grid)
            if self.blocked[starts[i]] and not self.static_blocked[starts[i]]:
                h = h.copy()  # standing where a mover is seen: get out of its way
                h[starts[i]] += 100.0
            if stuck:
                h = self._back_off(h, positions[i])
            heuristics.append(h)
        return heuristics, maps

    def _first_move_maps(self, committed: dict[int, Cell], starts: list[Cell],
                         maps: list[np.ndarray]) -> dict[int, np.ndarray]:
        """Robot -> its map with the other neighbours of its cell closed, for each robot that keeps
        its next move (:meth:`kept_moves`) to a neighbouring cell short of its goal."""
        first_moves = {}
        for i, cell in committed.items():
            s0 = starts[i]
            if abs(cell[0] - s0[0]) + abs(cell[1] - s0[1]) == 1 and s0 != self.goal_cells[i]:
                grid = maps[i].copy()
                for dx, dy in MOVES[1:]:
                    u = (s0[0] + dx, s0[1] + dy)
                    if u != cell and 0 <= u[0] < grid.shape[0] and 0 <= u[1] < grid.shape[1]:
                        grid[u] = True
                first_moves[i] = grid
        return first_moves

    def _plan_paths(self, starts: list[Cell], held: list[list[Cell]], heuristics: list[np.ndarray],
                    maps: list[np.ndarray], first_moves: dict[int, np.ndarray],
                    ) -> tuple[list[list[Cell]], list[int], list[int], int]:
        """Prioritized planning with ``restarts``: each robot in turn its cheapest ``window``-step
        path that respects the reservations of those before it (with its kept move first, else
        without), reserved; a robot with none waits in its cell. When some found none, the plan
        starts over with those robots first. Returns the paths, the order they were found in,
        the robots that found none in the last attempt and the number of restarts."""
        cfg, n, table = self.config, len(self.agents), self.table
        order = list(self.order)
        for attempt in range(cfg.restarts + 1):
            if attempt:  # the robots that found no path first, the rest in the order they had
                table = self.table = self._start_table(starts, held)
            paths: list[list[Cell]] = [[] for _ in range(n)]
            failed = []
            for i in order:
                found = None
                if i in first_moves:
                    found = space_time_astar(first_moves[i], starts[i], self.goal_cells[i], table, i, cfg.window,
                                             heuristics[i], closed=self.closed)
                if found is None:
                    found = space_time_astar(maps[i], starts[i], self.goal_cells[i], table, i, cfg.window,
                                             heuristics[i], closed=self.closed)
                if found is None:
                    failed.append(i)
                    path = [starts[i]] * (cfg.window + 1)
                else:
                    path = found[0]
                table.reserve_path(path, i)
                paths[i] = path
            if not failed:
                break
            order = failed + [i for i in order if i not in failed]
        return paths, order, failed, attempt

    def kept_moves(self, positions: list[tuple[float, float]]) -> dict[int, Cell]:
        """Per robot that keeps its next move at this replan (``commit_cone``), that move's cell:
        the next cell of its current plan, which the plan lets it enter now and whose point lies
        within ``commit_cone`` of its heading."""
        cone = self.config.commit_cone
        out: dict[int, Cell] = {}
        if cone <= 0 or not self.paths:
            return out
        for i, path in enumerate(self.paths):
            k = self.progress[i]
            nxt = next_move(path, k, len(path) - 1)
            if nxt is None or not self.may_enter(i, nxt, positions):
                continue
            if abs(math.degrees(off_heading(self.view.pose(i), self._point(i, path[nxt])))) <= cone:
                out[i] = path[nxt]
        return out

    def _standing_movers(self) -> np.ndarray:
        """The free cells whose point lies in the footprint, grown by ``yield_margin``, of a mover
        standing to yield to a robot (``block_yielding``): it stays until the robots leave its
        field, so the plans go round it rather than into it."""
        out = np.zeros(self.static_blocked.shape, dtype=bool)
        if not self.config.block_yielding:
            return out
        pts, grow = self.cell_points, self.config.yield_margin
        for m in self.view.movers:
            if not m.yielding:
                continue
            x, y, yaw = m.pose
            dx, dy = pts[..., 0] - x, pts[..., 1] - y
            c, s = math.cos(yaw), math.sin(yaw)
            along, across = c * dx + s * dy, -s * dx + c * dy
            with np.errstate(invalid="ignore"):  # NaN points of blocked cells compare False
                out |= (np.abs(along) <= 0.5 * m.size[0] + grow) & (np.abs(across) <= 0.5 * m.size[1] + grow)
        return out

    def _start_table(self, starts: list[Cell], held: list[list[Cell]]) -> ReservationTable:
        """The reservation table at a replan's start: where the robots stand, for the first
        ``robustness + 1`` steps (:func:`~bulletnav.fleet.spacetime.reserve_starts`; without its
        own-cell-first rule two robots pressed together planned waits for the rest of the
        episode: seed 3113, static world, N = 8, from 63 s)."""
        self.table.clear()
        reserve_starts(self.table, starts, held, self.config.robustness + 1)
        return self.table

    def _back_off(self, h: np.ndarray, xy: tuple[float, float]) -> np.ndarray:
        """``h`` plus 100 steps on the cells within ``yield_field`` of a mover near ``xy`` that
        stands yielding to a robot: a stuck robot ends its window out of the mover's way, and
        the mover, no longer held up by it, moves on."""
        movers = [m for m in self.view.movers if m.yielding
                  and math.dist(m.pose[:2], xy) < 0.5 * math.hypot(m.size[0], m.size[1]) + self.config.yield_field + 0.5]
        if not movers:
            return h
        h = h.copy()
        pts = self.cell_points
        for m in movers:
            reach = 0.5 * math.hypot(m.size[0], m.size[1]) + self.config.yield_field
            near = np.hypot(pts[..., 0] - m.pose[0], pts[..., 1] - m.pose[1]) <= reach
            h[near] += 100.0
        return h

    def _held(self, xy: tuple[float, float], start: Cell) -> list[Cell]:
        """The cells a robot at ``xy`` holds at a replan: its own and those whose centre is
        within ``leave_distance`` of it."""
        nx, ny = self.static_blocked.shape
        out = []
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                c = (start[0] + dx, start[1] + dy)
                if 0 <= c[0] < nx and 0 <= c[1] < ny and math.dist(xy, self._centre(c)) < self.config.leave_distance:
                    out.append(c)
        return out

    def may_enter(self, i: int, u: int, positions: list[tuple[float, float]]) -> bool:
        """True when robot ``i`` may go on to step ``u`` of its path: a wait, or every robot the
        plan puts in that cell earlier has progressed past it and is ``leave_distance`` away."""
        deps = self.dependencies[i].get(u)
        if not deps:
            return True
        centre = self._centre(self.paths[i][u])
        return all(self.progress[j] > t and math.dist(positions[j], centre) >= self.config.leave_distance
                   for j, t in deps)


__all__ = ["PlanningMixin", "next_move", "off_heading"]
