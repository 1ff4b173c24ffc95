"""The coordinated fleet controller (:class:`CoordinatedController`): windowed prioritized
planning in space-time on the static map, executed without lockstep. Its settings are in
:mod:`~bulletnav.fleet.coordinated.config`, its map in :mod:`~bulletnav.fleet.coordinated.cellmap`,
its planning and execution halves in :mod:`~bulletnav.fleet.coordinated.planning` and
:mod:`~bulletnav.fleet.coordinated.execution`."""

from __future__ import annotations

from typing import Any

import numpy as np

from bulletnav.control.navigator import GoToGoal
from bulletnav.fleet.coordinated.cellmap import cell_map
from bulletnav.fleet.coordinated.config import CoordinatedConfig
from bulletnav.fleet.coordinated.execution import ExecutionMixin
from bulletnav.fleet.coordinated.planning import PlanningMixin
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.spacetime import Cell, ReservationTable, largest_component
from bulletnav.fleet.view import FleetView


class CoordinatedController(PlanningMixin, ExecutionMixin):
    """Prioritized planning in space-time on the static map, windowed and replanned on a
    rolling horizon (cooperative A* / WHCA*, Silver 2005), each robot executing its reserved
    path at its own pace under the plan's precedence constraints (an action dependency graph,
    Hönig et al. 2019, "Persistent and robust execution of MAPF schedules in warehouses").

    **Planning.** The static map at ``resolution`` (0.5 m), cells closer than ``clearance``
    to an obstacle blocked, plus (with ``obstacle_range`` > 0, off by default) the cells the
    robots' lidars saw blocked in the last ``obstacle_memory_s`` (movers, pallet events:
    returns within ``obstacle_range`` that are no robot). Every replan clears the reservation
    table, reserves for the next ``robustness`` steps each robot's cell and every cell whose
    point is within ``leave_distance`` of it
    (a robot between two cells holds both), then plans the robots one after another in
    priority order: each finds the cheapest ``window``-step path (moves and waits, waiting on
    its goal free, plus the distance on the current map from the window's end to the goal)
    that respects the reservations of those before it (no cell held by another robot, no swap),
    and reserves it. A robot with no such path waits in its cell. A robot standing in a cell
    seen blocked plans out of it; one whose plans have kept it in place for ``stuck_s`` takes
    any detour around seen obstacles and, near a mover standing to yield to it, ends its
    window ``yield_field`` away from it (they would otherwise wait for each other). A robot that
    its plan lets into its next cell and that already heads into it keeps that move
    (``commit_cone``, :meth:`kept_moves`), so that a replan does not turn it back and forth.

    **Priorities** rotate round-robin: the r-th rotation (at most one every ``rotate_s``) starts
    the order at robot ``r mod N`` (:attr:`order`), so every robot plans first once every N
    rotations and none starves.

    **Execution** (no lockstep). Robot i's progress :attr:`progress` is the plan step it has
    reached. It may enter the cell of its step u only when every robot j that the plan puts in
    that cell at an earlier step t has both progressed past t and moved ``leave_distance``
    away from the cell's centre; waits are passed at once. Since every such dependency points
    to an earlier plan step the robots cannot wait on each other in a cycle, and the order in
    which robots cross each cell, swaps included, is the plan's. Each robot steers with the
    PID controller at its next cell (its goal point in its goal's cell), reaching it within
    ``arrive_tolerance`` (``turn_tolerance`` where the path turns) and driving on without
    stopping while the cells after it are free; it slows down toward, and stops at the
    centre of, the last cell it may enter; a robot whose turn on the spot keeps swapping sides
    commits to one where it has room (:meth:`unknot`), and one near another robot whose next
    point lies behind it turns toward it rather than drive on where the tracker's lidar blend
    steers (:meth:`cone`); one holding near its hold point with no room to turn in place stands
    rather than turn (:meth:`holds_boxed`). The fleet replans from where the robots
    stand at every goal change, when a robot nears the end of its plan (``replan_margin``) and
    every ``replan_period_s``.

    **Map.** Each cell's point is its free point nearest the centre, except where a passage
    narrower than a cell would otherwise leave parts of the map unjoined (``repair_points``).

    Args:
        env: the fleet env it drives.
        config: planner and tracking settings.
    """

    def __init__(self, env: FleetEnv, config: CoordinatedConfig = CoordinatedConfig()) -> None:
        self.env = env
        self.config = config
        self.view = FleetView(env)
        self.agents = list(env.possible_agents)
        self.table = ReservationTable(config.robustness)
        self.replans = 0
        """Replans this episode."""
        self.order: list[int] = []
        """Priority order of the last replan (robot indices, first planned first)."""
        self.paths: list[list[Cell]] = []
        """Each robot's reserved cells, one per plan step from the last replan."""
        self.progress: list[int] = []
        """The plan step each robot has reached (an index into its path)."""
        self.failed_plans = 0
        """Plans this episode that found no path in the window (the robot waited)."""
        self.restarted_plans = 0
        """Restarts this episode (``restarts``)."""
        self.planned_order: list[int] = []
        self._rotation = 0

    # ------------------------------------------------------------------ episode
    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        view, cfg = self.view, self.config
        self.grid = view.occupancy(cfg.resolution, cfg.clearance)
        cells = cell_map(self.grid, view.occupancy(cfg.point_resolution, cfg.clearance), cfg.resolution,
                         cfg.point_resolution, cfg.leave_distance, cfg.repair_points)
        self.static_blocked = cells.blocked
        self.cell_points = cells.points
        """Each cell's point (m), NaN in blocked cells."""
        self.closed = cells.closed
        self.conflicts = cells.conflicts
        self.table = ReservationTable(cfg.robustness, self.conflicts)
        self.blocked = self.static_blocked
        self._floor = largest_component(self.static_blocked, self.closed)  # goals snap onto it, not into pockets
        self._seen_until = np.full(self.static_blocked.shape, -np.inf)
        self._heuristics: dict[tuple[Cell, bool], np.ndarray] = {}
        self._static_heuristics: dict[Cell, np.ndarray] = {}
        n = len(self.agents)
        first = view.robot(0)
        lidar = first.sensors.lidar
        self.n_rays, self.max_range = lidar.config.num_rays, lidar.config.max_range
        self._cos, self._sin = np.cos(lidar.angles), np.sin(lidar.angles)
        self._lidar_offset = view.geometry.lidar_offset
        self._turn_reach = view.geometry.outline_radius + cfg.unknot_margin
        self.dt = view.control_dt
        self.trackers = [GoToGoal(cfg.controller, lidar.angles, view.geometry) for _ in range(n)]
        self._action = first.action_for  # the same action scale for every robot
        self.replans = self.failed_plans = self.restarted_plans = 0
        self._rotation = 0
        self.order = []
        self._rotated_at = view.time_s
        self.goals = [self._goal(infos[a]) for a in self.agents]
        self.paths = []
        self._still_since = [view.time_s] * n
        self._anchors = [view.pose(i)[:2] for i in range(n)]
        self._moved_at = [view.time_s] * n
        self._knot = [(0.0, 0.0)] * n
        self._cone_side = [0.0] * n
        self._turns_seen: list[list[tuple[float, float]]] = [[] for _ in range(n)]
        self.replan()


__all__ = ["CoordinatedController"]
