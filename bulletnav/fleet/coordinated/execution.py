"""The coordinated controller's execution half (:class:`ExecutionMixin`): each robot drives its
reserved path at its own pace under the plan's precedence constraints, with the PID tracker at
its next point and the rules that keep a boxed-in robot from knotting (no lockstep)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from bulletnav.fleet.coordinated.planning import next_move, off_heading
from bulletnav.fleet.spacetime import Cell


class ExecutionMixin:
    """The execution half of :class:`~bulletnav.fleet.coordinated.CoordinatedController` (its
    docstring describes the method); it reads the plan that :class:`~bulletnav.fleet.coordinated.planning.PlanningMixin`
    keeps."""

    def _advance(self, i: int, positions: list[tuple[float, float]]) -> None:
        path, cfg = self.paths[i], self.config
        k = self.progress[i]
        while k + 1 < len(path):
            if path[k + 1] != path[k]:
                if not self.may_enter(i, k + 1, positions):
                    break
                tol = cfg.turn_tolerance if self._turns(i, k + 1) else cfg.arrive_tolerance
                if math.dist(positions[i], self._centre(path[k + 1])) >= tol:
                    break
            k += 1
        self.progress[i] = k

    def _nears_end(self, i: int) -> bool:
        """True when robot ``i`` has no more than ``replan_margin`` steps of its plan left and
        the plan moves it but not yet to its goal (a plan of waits is renewed every
        ``replan_period_s``)."""
        path = self.paths[i]
        return (len(path) - 1 - self.progress[i] <= self.config.replan_margin and path[-1] != path[0]
                and path[-1] != self.goal_cells[i])

    def _turns(self, i: int, u: int) -> bool:
        """True when robot ``i``'s path turns at step ``u`` (its next move is not straight on)."""
        path = self.paths[i]
        before = (path[u][0] - path[u - 1][0], path[u][1] - path[u - 1][1])
        for w in range(u + 1, len(path)):
            if path[w] != path[u]:
                return (path[w][0] - path[u][0], path[w][1] - path[u][1]) != before
        return True  # it stops there: treat as a turn (reach it closely)

    def unknot(self, i: int, now: float, pose: tuple[float, float, float], target: tuple[float, float],
               v: float, w: float, ranges: np.ndarray | None = None) -> tuple[float, float]:
        """Robot ``i``'s command ``(v, w)`` at time ``now`` (s) after the knot check
        (``unknot_flips``): a robot commanded to stand (``v`` under 5 cm/s) and turn (over 0.3
        rad/s) whose turn swapped sides ``unknot_flips`` times within the last second turns in
        place toward ``target`` at 0.8 rad/s, one way, until it faces it within 0.3 rad or 4 s
        have passed, and only while its scan ``ranges`` (m, None: not checked) shows nothing
        within the circle its outline sweeps turning in place, grown by ``unknot_margin``."""
        error = off_heading(pose, target)
        clear = ranges is None or self._turn_clear(ranges)
        sign, until = self._knot[i]
        if sign:
            if abs(error) < 0.3 or now >= until or not clear:
                self._knot[i] = (0.0, 0.0)
            else:
                return 0.0, 0.8 * sign
        hist = self._turns_seen[i]
        if v < 0.05 and abs(w) > 0.3:
            hist.append((now, math.copysign(1.0, w)))
        else:
            hist.clear()
        while hist and hist[0][0] < now - 1.0:
            hist.pop(0)
        flips = sum(1 for a, b in zip(hist, hist[1:]) if a[1] != b[1])
        if flips >= self.config.unknot_flips and abs(error) >= 0.3 and clear:
            self._knot[i] = (math.copysign(1.0, error), now + 4.0)
            hist.clear()
            return 0.0, 0.8 * self._knot[i][0]
        return v, w

    def holds_boxed(self, ahead: float, v: float, ranges: np.ndarray) -> bool:
        """True when a robot that may enter no further cell, ``ahead`` m from its hold point and
        commanded ``v`` m/s, with the scan ``ranges`` (m), stands still rather than turn in place
        (``hold_no_turn``): a turn in place (``v`` under 5 cm/s) near the point with no room for it."""
        return v < 0.05 and 0 < ahead < self.config.hold_no_turn and not self._turn_clear(ranges)

    def cone(self, i: int, pose: tuple[float, float, float], target: tuple[float, float], ranges: np.ndarray,
              v: float, w: float, positions: list[tuple[float, float]]) -> tuple[float, float]:
        """Robot ``i``'s command ``(v, w)`` under ``drive_cone``: with ``target`` farther off its
        heading than the cone, its speed scaled down (to 0 at 90 degrees) and, where the turn in
        place is clear (the knot turn's check), a turn toward the target, keeping its side while
        the target lies more than 150 degrees off (so noise about the rear does not swap it). A
        robot boxed in too closely to turn keeps the tracker's command."""
        cone = self.config.drive_cone
        if cone <= 0:
            return v, w
        error = off_heading(pose, target)
        off = abs(math.degrees(error))
        if off <= cone:
            self._cone_side[i] = 0.0
            return v, w
        x, y, _ = pose
        reach, front = self.config.cone_reach, math.radians(100)
        if not any(j != i and math.hypot(p[0] - x, p[1] - y) < reach and abs(off_heading(pose, p)) < front
                   for j, p in enumerate(positions)):
            return v, w  # no robot ahead to drive into: the blends may steer it round a mover
        if not self._turn_clear(ranges):
            return v, w
        side = self._cone_side[i]
        if not side or off < 150.0:
            side = self._cone_side[i] = math.copysign(1.0, error)
        factor = 0.0 if off >= 90.0 else (90.0 - off) / (90.0 - cone)
        turn = self.config.controller.max_turn_rate
        return v * factor, side * min(turn, max(0.8, 1.5 * abs(error)))

    def _turn_clear(self, ranges: np.ndarray) -> bool:
        """True when no lidar return lies within the circle the robot's outline sweeps turning
        in place, grown by ``unknot_margin``."""
        x = self._lidar_offset + ranges * self._cos
        y = ranges * self._sin
        return bool(np.hypot(x, y).min() >= self._turn_reach)

    def _point(self, i: int, cell: Cell) -> tuple[float, float]:
        return self.goals[i] if cell == self.goal_cells[i] else self._centre(cell)

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        cfg, view, n = self.config, self.view, len(self.agents)
        goals = [self._goal(infos[a]) for a in self.agents]
        poses = [view.pose(i) for i in range(n)]
        positions = [p[:2] for p in poses]
        self._observe(observations, positions, poses)
        if goals != self.goals:
            self.goals = goals
            self.replan()
        for i in range(n):
            self._advance(i, positions)
        since = view.time_s - self._planned_at
        if since >= cfg.replan_period_s - 1e-9 or (since >= cfg.replan_min_s - 1e-9 and any(map(self._nears_end, range(n)))):
            self.replan()
            for i in range(n):
                self._advance(i, positions)
        actions = {}
        for i, agent in enumerate(self.agents):
            path, k = self.paths[i], self.progress[i]
            # the allowed part of the path: steps it may take now
            end = k
            while end + 1 < len(path) and (path[end + 1] == path[end] or self.may_enter(i, end + 1, positions)):
                end += 1
            nxt = next_move(path, k, end)
            pose = poses[i]
            if nxt is None:
                target = self._point(i, path[k])
                ahead = math.dist(pose[:2], target)
            else:
                target = self._point(i, path[nxt])
                moves = sum(1 for u in range(nxt + 1, end + 1) if path[u] != path[u - 1])
                ahead = math.dist(pose[:2], target) + cfg.resolution * moves
            if nxt is None and ahead < cfg.hold_radius:
                v, w = 0.0, 0.0  # at the last cell it may enter: hold
            else:
                ranges = self._ranges(observations[agent])
                v, w = self.trackers[i].command(pose, target, ranges, self.dt, ahead)
                v, w = self.cone(i, pose, target, ranges, v, w, positions)
                if cfg.unknot_flips > 0:
                    v, w = self.unknot(i, view.time_s, pose, target, v, w, ranges)
                if nxt is None and self.holds_boxed(ahead, v, ranges):
                    v, w = 0.0, 0.0
            actions[agent] = self._action(v, w)
        return actions


__all__ = ["ExecutionMixin"]
