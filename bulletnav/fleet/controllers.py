"""Fleet controllers: one action per robot from the per-agent observations and infos.

A fleet controller has the :class:`~bulletnav.policy.Policy` protocol's two methods over all
agents at once (:class:`FleetController`)::

    observations, infos = env.reset(seed=s)
    controller.reset(infos)
    while env.agents:
        observations, rewards, terms, truncs, infos = env.step(controller.act(observations, infos))

- :func:`independent_controller`: every robot the single-robot PID + A*
  :class:`~bulletnav.control.navigator.Navigator` on its own lidar map (the other robots are
  obstacles its lidar sees, forgotten when they leave), toward its current errand goal; a new
  goal (every leg) makes it replan at once (:class:`ErrandNavigator`).
- :class:`CoordinatedController`: windowed prioritized planning in space-time on the static
  map (:mod:`bulletnav.fleet.spacetime`, WHCA*), each robot driving its reserved path at its own
  pace with the PID go-to-point controller, entering a cell only after the robots planned
  there earlier have left it (an action dependency graph, no lockstep).
- :func:`policy_controller`: one single-robot SB3 model, zero-shot on every robot (the fleet
  env must be made with the model's env settings, :func:`model_env_kwargs`).
- :class:`ShieldedController`: any of them behind the safety shield
  (:mod:`bulletnav.control.shield`), each robot's shield seeing the other robots as movers
  (pose, forward speed, footprint box), as the single-robot shield sees forklifts.

:func:`make_controller` builds one by name (what the CLI's ``fleet --controller`` takes).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bulletnav.control.navigator import ControllerConfig, GoToGoal, Navigator, NavigatorConfig
from bulletnav.control.shield import ShieldConfig, ShieldDecision, Veto
from bulletnav.errors import ConfigError, ModelError
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.learned import SharedPolicyController
from bulletnav.fleet.spacetime import (
    MOVES,
    Cell,
    ReservationTable,
    distance_map,
    largest_component,
    nearest_free,
    plan_dependencies,
    reserve_starts,
    space_time_astar,
)
from bulletnav.fleet.view import FleetView, RobotView
from bulletnav.policy import Policy

log = logging.getLogger(__name__)

CONTROLLERS = ("independent", "coordinated", "policy")
"""Names :func:`make_controller` takes."""
DEFAULT_MODEL = "models/ppo_dynamic.zip"
"""The single-robot model the ``policy`` controller drives with unless told otherwise."""


def _off_heading(pose: tuple[float, float, float], point: tuple[float, float]) -> float:
    """The angle (rad, -pi to pi) from the heading of a robot at ``pose`` to ``point``."""
    return math.remainder(math.atan2(point[1] - pose[1], point[0] - pose[0]) - pose[2], 2 * math.pi)


def _next_move(path: list[Cell], k: int, end: int) -> int | None:
    """The first step after ``k``, up to ``end``, at which ``path`` leaves the cell of step
    ``k`` (None: it only waits there)."""
    return next((u for u in range(k + 1, end + 1) if path[u] != path[k]), None)


class FleetController(Protocol):
    """One action per agent: ``reset(infos)`` at each episode start, ``act(observations, infos)`` every step."""

    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        """Prepare for the episode whose first infos (from ``env.reset``) these are."""

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        """The action of every agent in ``observations``."""
        ...


class PerRobotController:
    """A fleet controller made of one :class:`~bulletnav.policy.Policy` per agent.

    Args:
        policies: agent name -> its policy.
    """

    def __init__(self, policies: dict[str, Policy]) -> None:
        self.policies = policies

    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        for agent, policy in self.policies.items():
            policy.reset(infos[agent])

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        return {a: self.policies[a].act(observations[a], infos[a]) for a in observations}


# ---------------------------------------------------------------------- independent
class ErrandNavigator:
    """A :class:`~bulletnav.control.navigator.Navigator` whose goal follows ``info["goal"]``:
    when the fleet moves the robot's goal on (a leg completed), the navigator drops its plan
    and plans toward the new goal at once, keeping its lidar map. A Policy."""

    def __init__(self, scene: RobotView, config: NavigatorConfig = NavigatorConfig()) -> None:
        self.navigator = Navigator(scene, config)
        self.goal_changes = 0
        """How many times the goal moved on this episode."""

    def reset(self, info: dict[str, Any]) -> None:
        self.navigator.reset(info)
        self.goal_changes = 0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        nav = self.navigator
        goal = (float(info["goal"][0]), float(info["goal"][1]))
        if goal != nav.goal:
            nav.goal, nav.path = goal, None  # a None path makes the navigator plan on this step
            self.goal_changes += 1
        return nav.act(obs, info)


def independent_controller(env: FleetEnv, config: NavigatorConfig = NavigatorConfig()) -> PerRobotController:
    """Every robot its own PID + A* navigator on its own lidar map (see the module docstring)."""
    view = FleetView(env)
    return PerRobotController({a: ErrandNavigator(view.robot(i), config) for i, a in enumerate(env.possible_agents)})


# ---------------------------------------------------------------------- policy
def model_env_kwargs(model_path: str | Path) -> dict[str, Any]:
    """The env settings a single-robot model was trained with that a fleet env must share
    for the model's observations and actions to mean the same (its sidecar's ``env_kwargs``
    minus reward overrides and learning-only options, and minus the single-robot-only ones).

    Raises:
        ModelError: no model file, or no readable sidecar beside it.
    """
    import json

    from bulletnav.fleet.env import _UNSUPPORTED
    from bulletnav.rl.envs import evaluation_env_kwargs
    from bulletnav.rl.io import sidecar_path

    if not Path(model_path).is_file():
        raise ModelError(f"{model_path}: model file not found")
    side = sidecar_path(model_path)
    try:
        meta = json.loads(side.read_text())
    except (OSError, ValueError) as exc:
        raise ModelError(f"{side}: cannot read the model's sidecar ({exc})") from None
    if not isinstance(meta, dict):
        raise ModelError(f"{side}: model metadata must be a JSON object")
    kwargs = evaluation_env_kwargs(meta.get("env_kwargs") or {})
    return {k: v for k, v in kwargs.items() if k not in _UNSUPPORTED and not k.startswith("shift_")}


def policy_controller(env: FleetEnv, model_path: str | Path = DEFAULT_MODEL) -> SharedPolicyController:
    """One SB3 model on every robot, all robots in one forward pass per step
    (:class:`~bulletnav.fleet.learned.SharedPolicyController`): a single-robot model zero-shot
    (``models/ppo_dynamic.zip``) or one fine-tuned in the fleet (``models/ppo_fleet.zip``).

    Raises:
        ModelError: the model cannot be loaded, or its observation or action space differs
            from the fleet's per-agent one (make the env with :func:`model_env_kwargs`).
    """
    from bulletnav.rl.io import load_model

    model, _meta, normalizer = load_model(model_path)
    agent = env.possible_agents[0]
    for what, mine, theirs in (("observation", env.observation_space(agent), model.observation_space),
                               ("action", env.action_space(agent), model.action_space)):
        if mine.shape != theirs.shape or not (np.allclose(mine.low, theirs.low) and np.allclose(mine.high, theirs.high)):
            raise ModelError(f"{model_path}: the model's {what} space {theirs} does not fit the fleet's {mine}; "
                             "make the fleet env with the model's env settings (fleet.controllers.model_env_kwargs)")
    return SharedPolicyController(model, normalizer, env.possible_agents)


# ---------------------------------------------------------------------- coordinated
@dataclass(frozen=True)
class CoordinatedConfig:
    """Windowed prioritized planning in space-time, executed without lockstep
    (:class:`CoordinatedController`)."""

    resolution: float = 0.5
    """Grid cell side (m): one plan step moves a robot one cell (4-connected) or waits."""
    clearance: float = 0.3
    """A point is free when it is at least this far (m) from every obstacle and wall (the
    robot's 0.2 m disc plus 0.1 m for tracking error)."""
    point_resolution: float = 0.1
    """Side (m) of the fine grid on which each cell's point is found: the free point of the
    cell nearest its centre (a cell with none is blocked). Robots drive from point to point;
    a move is open when the segment between the two points is free, so a narrow passage off
    the cell centres stays open."""
    repair_points: bool = True
    """Where no open move joins two parts of the map but the segment between two neighbouring
    cells' points, one in each, could be free, move those two points to the free pair nearest
    the centres that opens the move and closes no other: a passage narrower than a cell and off
    the centres (a gap beside an obstacle in a cross aisle) stays on the plan's map. Without it
    seed 3020's map fell in two halves and robots in the smaller one never moved."""
    window: int = 16
    """Steps each robot plans and reserves (WHCA*'s window)."""
    replan_margin: int = 6
    """The fleet replans when a robot has no more than this many steps of its plan left to
    execute (and at every goal change, and every ``replan_period_s``)."""
    rotate_s: float = 10.0
    """Priorities rotate at the first replan at least this long (s) after the last rotation (0:
    at every replan). Rotating at every replan (at most 2 s apart) handed the right of way back
    and forth: two robots meeting in a one-lane passage each planned to wait for the other in
    turn (seed 3108, 40-60 s). On 60 dynamic development episodes (N = 8, seeds 3000-3019,
    3100-3119, 3200-3219) 10 s gave 403 errands, 21 deadlock events and 8 robot-robot
    collisions against 382, 26 and 20 at every replan; 4 s and 20 s measured worse on seeds
    3100-3119 (docs/fleet.md)."""
    replan_min_s: float = 0.5
    """Shortest time (s) between two replans that no goal change asks for (a robot whose plan
    ends in waits reaches its end at once)."""
    replan_period_s: float = 2.0
    """Longest time (s) between two replans: a robot held up by a mover, or serving a
    collision penalty, is planned around from where it stands."""
    robustness: int = 1
    """Steps a robot keeps a cell reserved after leaving it in the plan (k-robust plans: in plan
    time a robot enters a cell no sooner than k + 1 steps after another left it)."""
    arrive_tolerance: float = 0.25
    """A robot has reached a cell on a straight run within this distance (m) of its centre,
    and steers on at the next one."""
    turn_tolerance: float = 0.12
    """A robot has reached a cell where its path turns within this distance (m) of its centre
    (tighter than ``arrive_tolerance``: cutting a corner would sweep the inner diagonal cell)."""
    leave_distance: float = 0.45
    """A robot has left a cell once its centre is this far (m) from the cell's centre (a
    robot's 0.4 m diameter plus 5 cm): only then may the robot planned there next enter it."""
    hold_radius: float = 0.05
    """A robot whose next cell is not yet free stops within this distance (m) of the centre of
    the last cell it may enter."""
    obstacle_range: float = 0.0
    """Lidar returns closer than this (m) that are not another robot mark cells blocked (the
    movers and pallet events the static plan does not know); 0 (the default) marks none: on the
    dynamic aisle warehouse (N = 8, 120 s, seeds 3000-3007) marking within 1.5 m completed 18
    errands against 50 without, its robots waiting on workers and forklifts that wait for them. The PID
    tracker's lidar blend keeps the robots off the movers, and a stuck robot backs off a
    yielding one (``yield_field``)."""
    obstacle_radius: float = 0.25
    """A lidar return blocks the cells whose centres lie within this distance (m) of it (under
    ``clearance``, so returns off the static obstacles block no free cell)."""
    obstacle_memory_s: float = 3.0
    """How long (s) a cell stays blocked after a lidar return last marked it."""
    detour_steps: int = 20
    """Where seen obstacles cut a cell off from the goal, the planner counts its distance as
    the static one plus this many steps (so a robot takes a detour shorter than that, else
    waits near the obstacle for it to move on)."""
    yield_field: float = 1.2
    """A stuck robot (``stuck_s``) near a mover that stands yielding to a robot plans to end its
    window farther than this (m) beyond the mover's bounding circle (its safety field, 1 m,
    plus the robot's 0.2 m), so that the mover drives on."""
    restarts: int = 3
    """Times a replan starts over when robots found no path, those robots planned first (then
    the rest in their order): prioritized planning with restarts, so a robot boxed in by the
    plans of robots ahead of it in priority gets its way out reserved before them."""
    block_yielding: bool = True
    """A stuck robot (``stuck_s``) plans round the movers that stand yielding to a robot (their
    footprint grown by ``yield_margin``): they stand until no robot is in their field, so a plan
    through one keeps the robot in front of it and the mover waiting for the robot. (Every
    robot planning round them measured worse: 90 errands/h against 172 at N = 8, seeds
    3004-3007, and 82 when only movers yielding for 3 s or more were planned round.)"""
    yield_margin: float = 0.22
    """How far (m) ``block_yielding`` grows a standing mover's footprint: the robot's 0.2 m
    radius and 2 cm, so a stuck robot boxed in by forklifts plans out through a gap that its
    body fits."""
    stuck_s: float = 4.0
    """A robot whose plans have kept it in place this long (s), or that has not moved
    ``stuck_distance`` in this long (its plan moves it, but a mover ahead stops it), away from
    its goal, plans around the seen obstacles whatever the detour and out of the way of a
    mover yielding to it (a forklift or worker yielding to it waits for it to leave)."""
    unknot_flips: int = 4
    """A robot commanded to stand and turn whose turn swapped direction this many times in the
    last second turns in place toward its next point, one way, until it faces it within
    0.3 rad or 4 s pass (0: off; :meth:`CoordinatedController.unknot`). Without it a robot
    boxed in between a rack and a mover can turn left and right on the spot for the rest of
    the episode (two such knots in 32 dev episodes, N = 8, seeds 3000-3031: with the turn's
    room checked, ``unknot_margin``, it undoes the one at seed 3008; at seed 3003 the turn
    would touch the robot beside it and is not made)."""
    unknot_margin: float = 0.03
    """The knot turn is made only while no lidar return lies within the robot's outline radius
    plus this (m) of its centre (a turn in place sweeps that circle; PyBullet reports contact
    from about 2 cm), so it does not swing the robot's corners into what stands beside it
    (unchecked, it did: four mover collisions at N = 8, seed 1000)."""
    stuck_distance: float = 0.25
    """How far (m) a robot must move to count as moving for ``stuck_s``."""
    hold_no_turn: float = 0.35
    """A robot that may enter no further cell does not turn in place (a command under 5 cm/s)
    while it is within this distance (m) of its hold point and its scan shows no room to turn
    (the knot turn's check, ``unknot_margin``): it stands still instead; 0: off. Without it a
    robot holding on the line between two cells, two forklifts standing for it 0.67 m away,
    turned toward the point of one cell and then the other, +1.2 and -1.2 rad/s on alternate
    steps, and touched a forklift every 6 s for the last minute of the episode (seed 6017,
    N = 8: 11 mover collisions, none with it). Standing still whenever boxed in near the hold
    point, not only instead of a turn, gave 10 deadlock events against 6 on development seeds
    3100-3119 (docs/fleet.md)."""
    drive_cone: float = 90.0
    """Near another robot (``cone_reach``), a robot whose next point lies more than this angle
    (degrees, at most 90) off its heading slows (to 0 at 90 degrees) and turns toward the
    point, where it has room to turn in place (0: off; :meth:`CoordinatedController.cone`).
    The tracker's lidar blends steer a robot boxed in by its neighbours toward the side with
    more room, and without the cone it drove on that way, off its reserved cells and into the
    robot beside it (seed 3113, static world, N = 8, 61-63 s: 0.15-0.47 m/s with its point
    95-153 degrees behind it). With it (and :func:`~bulletnav.fleet.spacetime.reserve_starts`),
    40 dynamic development episodes (N = 8, seeds 3100-3119 and 3200-3219) had 10 robot-robot
    and no mover collisions, against 36 and 8 without either (docs/fleet.md)."""
    cone_reach: float = 0.75
    """``drive_cone`` acts only while another robot's centre lies within this distance (m) and
    100 degrees of the robot's heading; elsewhere the blends may steer it round a mover (with
    the cone everywhere, 60 degrees, the same 20 dynamic episodes 3100-3119 gave 104 errands and
    20 deadlock events against 140 and 10)."""
    commit_cone: float = 60.0
    """At a replan, a robot that its plan lets into its next cell and whose heading lies within
    this angle (degrees) of that cell's point keeps the cell as its next move: the space-time
    search closes the other neighbours of its cell to it for the window (its goal too, where
    that is one of them: the robot reaches it a replan later), and plans without the
    commitment where that finds no path (0: off; :meth:`CoordinatedController.kept_moves`).
    Without it a replan, every 2 s or sooner, could hand a robot that had turned toward one cell
    another, and robots passing in a corridor turned back and forth: three robots for 20 s at
    seed 3104, dynamic, N = 8, 76-96 s. With it, on development seeds (N = 8, 120 s), 770
    errands and 44 deadlock events in 120 dynamic episodes (3000-3039, 3100-3119, 3200-3219,
    3300-3339) against 770 and 52, and 342 and 1 in 40 episodes without movers (3100-3119,
    3200-3219) against 326 and 6 (docs/fleet-deadlocks.md)."""
    controller: ControllerConfig = field(default_factory=lambda: ControllerConfig(safety_distance=0.35, side_margin=0.1))
    """The PID go-to-point controller that tracks the path (its lidar blends kept short: the
    plan keeps robots a cell apart)."""

    def __post_init__(self) -> None:
        if not (self.resolution > 0 and self.clearance >= 0 and self.replan_period_s > 0
                and 0 <= self.replan_min_s <= self.replan_period_s
                and 0 < self.turn_tolerance <= self.arrive_tolerance and self.hold_radius > 0
                and self.leave_distance > 0 and self.obstacle_range >= 0 and self.obstacle_radius >= 0
                and self.obstacle_memory_s >= 0 and self.hold_no_turn >= 0):
            raise ConfigError(f"coordinated planner needs resolution > 0, clearance >= 0, replan_period_s > 0, "
                              f"0 < turn_tolerance <= arrive_tolerance, hold_radius > 0, leave_distance > 0 and "
                              f"non-negative obstacle settings and hold_no_turn; got {self}")
        if not 0 <= self.drive_cone <= 90:
            raise ConfigError(f"coordinated planner needs drive_cone from 0 to 90 degrees, got {self.drive_cone!r}")
        if not 0 <= self.commit_cone <= 180:
            raise ConfigError(f"coordinated planner needs commit_cone from 0 to 180 degrees, got {self.commit_cone!r}")
        if not (0 <= self.replan_margin < self.window and self.robustness >= 0 and self.restarts >= 0):
            raise ConfigError(f"coordinated planner needs 0 <= replan_margin < window, robustness >= 0 and "
                              f"restarts >= 0; got {self}")


class CoordinatedController:
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
        self._points(view.occupancy(cfg.point_resolution, cfg.clearance))
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

    def _points(self, fine: Any) -> None:
        """Each cell's point, the blocked cells, the closed moves and the conflicting cells
        (two cells whose points are closer than ``leave_distance``) from the fine grid."""
        cfg, grid = self.config, self.grid
        nx, ny = grid.shape
        occ, (fnx, fny) = fine.occupied, fine.shape
        k = int(round(0.5 * cfg.resolution / cfg.point_resolution))
        offsets = sorted(((a * cfg.point_resolution, b * cfg.point_resolution) for a in range(-k, k + 1)
                          for b in range(-k, k + 1)), key=lambda o: (o[0] ** 2 + o[1] ** 2, o))
        half = 0.5 * cfg.resolution + 1e-9
        offsets = [o for o in offsets if abs(o[0]) < half and abs(o[1]) < half]
        points = np.full((nx, ny, 2), np.nan)
        blocked = np.ones((nx, ny), dtype=bool)

        def free_points(cell: Cell) -> Iterator[tuple[float, float]]:
            """The cell's free fine points, nearest its centre first."""
            cx, cy = grid.cell_to_world(*cell)
            for ox, oy in offsets:
                fx, fy = fine.world_to_cell((cx + ox, cy + oy))
                if 0 <= fx < fnx and 0 <= fy < fny and not occ[fx, fy]:
                    yield fine.cell_to_world(fx, fy)

        for x in range(nx):
            for y in range(ny):
                point = next(free_points((x, y)), None)
                if point is not None:
                    points[x, y] = point
                    blocked[x, y] = False
        if cfg.repair_points:
            self._repair_points(points, blocked, free_points, fine)
        closed = np.zeros((nx, ny, len(MOVES)), dtype=bool)
        conflicts: dict[Cell, list[Cell]] = {}
        for x in range(nx):
            for y in range(ny):
                if blocked[x, y]:
                    continue
                for m, (dx, dy) in enumerate(MOVES[1:], 1):
                    u, v = x + dx, y + dy
                    if 0 <= u < nx and 0 <= v < ny and not blocked[u, v] and (dx, dy) > (0, 0):
                        if not fine.segment_free(points[x, y], points[u, v]):
                            closed[x, y, m] = closed[u, v, MOVES.index((-dx, -dy))] = True
                for dx in range(-1, 2):
                    for dy in range(-1, 2):
                        u, v = x + dx, y + dy
                        if ((dx, dy) != (0, 0) and 0 <= u < nx and 0 <= v < ny and not blocked[u, v]
                                and math.dist(points[x, y], points[u, v]) < cfg.leave_distance):
                            conflicts.setdefault((x, y), []).append((u, v))
        self.static_blocked = blocked
        self.cell_points = points
        """Each cell's point (m), NaN in blocked cells."""
        self.closed = closed
        self.conflicts = {c: tuple(o) for c, o in conflicts.items()}

    def _repair_points(self, points: np.ndarray, blocked: np.ndarray,
                       free_points: Callable[[Cell], Iterator[tuple[float, float]]], fine: Any) -> None:
        """``repair_points``: where two neighbouring cells lie in parts of the map that no open
        move joins and the segment between their points is not free, move the two points to the
        pair of their cells' free points nearest the centres whose segment is free and that keeps
        every other open move of the two cells open (a passage narrower than a cell and off the
        centres joins the parts). Maps without such parts keep their points."""
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
            centre_a, centre_b = self.grid.cell_to_world(*a), self.grid.cell_to_world(*b)
            for _, pa, pb in sorted(((math.dist(pa, centre_a) + math.dist(pb, centre_b), pa, pb) for pa in ca for pb in cb),
                                    key=lambda e: e[0]):
                if free(pa, pb):
                    points[a], points[b] = pa, pb
                    parent[root(a)] = root(b)
                    break

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
        cfg, n, view = self.config, len(self.agents), self.view
        positions = [view.pose(i)[:2] for i in range(n)]
        committed = self.kept_moves(positions)
        if view.time_s >= self._rotated_at + cfg.rotate_s - 1e-9 or not self.order:
            self.order = [(self._rotation + k) % n for k in range(n)]
            self._rotation = (self._rotation + 1) % n
            self._rotated_at = view.time_s
        seen = self._seen_until > view.time_s
        blocked = self.static_blocked | seen if seen.any() else self.static_blocked
        if not np.array_equal(blocked, self.blocked):
            self._heuristics = {}
        self.blocked = blocked
        starts = [self._cell(p) for p in positions]
        held = [self._held(p, s) for p, s in zip(positions, starts)]
        table = self.table = self._start_table(starts, held)
        self.held = held
        self.goal_cells = [nearest_free(~self._floor, self._cell(g)) for g in self.goals]
        now = view.time_s
        for i, path in enumerate(self.paths):  # since when each robot's plans keep it in place
            if path and (path[-1] != path[0] or path[0] == self.goal_cells[i]):
                self._still_since[i] = now
            if math.dist(positions[i], self._anchors[i]) >= cfg.stuck_distance or starts[i] == self.goal_cells[i]:
                self._anchors[i], self._moved_at[i] = positions[i], now  # since when it has not moved
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
        first_moves = {}  # robot -> its map with the other neighbours of its cell closed
        for i, cell in committed.items():
            s0 = starts[i]
            if abs(cell[0] - s0[0]) + abs(cell[1] - s0[1]) == 1 and s0 != self.goal_cells[i]:
                grid = maps[i].copy()
                for dx, dy in MOVES[1:]:
                    u = (s0[0] + dx, s0[1] + dy)
                    if u != cell and 0 <= u[0] < grid.shape[0] and 0 <= u[1] < grid.shape[1]:
                        grid[u] = True
                first_moves[i] = grid
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
            nxt = _next_move(path, k, len(path) - 1)
            if nxt is None or not self.may_enter(i, nxt, positions):
                continue
            if abs(math.degrees(_off_heading(self.view.pose(i), self._point(i, path[nxt])))) <= cone:
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

    # ------------------------------------------------------------------ acting
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
        error = _off_heading(pose, target)
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
        error = _off_heading(pose, target)
        off = abs(math.degrees(error))
        if off <= cone:
            self._cone_side[i] = 0.0
            return v, w
        x, y, _ = pose
        reach, front = self.config.cone_reach, math.radians(100)
        if not any(j != i and math.hypot(p[0] - x, p[1] - y) < reach and abs(_off_heading(pose, p)) < front
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
            nxt = _next_move(path, k, end)
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


# ---------------------------------------------------------------------- shield
class _RobotEnv:
    """One robot of the fleet as the shield's :class:`~bulletnav.control.shield.Veto` reads an
    env: ``unwrapped.scene`` (the robot's view, the other robots among its movers),
    ``action_space`` and ``command``."""

    def __init__(self, env: FleetEnv, agent: str, scene: RobotView) -> None:
        self.unwrapped = self
        self.scene = scene
        self.action_space = env.action_space(agent)
        self.command = env.command


FLEET_SHIELD = ShieldConfig(creep_floor=ShieldConfig().close_margin)
"""The fleet's shield settings: the defaults, with creeping kept off the last ``close_margin``
(2 cm) of a gap. Robots of a fleet wait for one another far more often than a single robot
waits for a yielding worker, so they creep often, and without the floor a creep's
millimetre-sized errors let one robot ratchet into a rack (seed 1035, N = 8, docs/fleet.md)."""


class ShieldedController:
    """A fleet controller behind the safety shield: every robot's action goes through its
    own :class:`~bulletnav.control.shield.Veto`, which sees its lidar scan, odometry, the
    movers and the other robots as movers (pose, forward speed, footprint box). The shields
    decide one robot after the other; a robot decided this step is shown to the later ones at
    the speed its own sweep assumed (the larger of its speed and its command), so two robots
    never each take the same gap on the belief that the other stands still.
    ``decisions`` holds the last step's :class:`~bulletnav.control.shield.ShieldDecision`
    per agent; ``interventions`` counts this episode's replaced actions over all robots.

    Args:
        inner: the controller to guard.
        env: the fleet env.
        config: the shield's settings.
    """

    def __init__(self, inner: FleetController, env: FleetEnv, config: ShieldConfig = FLEET_SHIELD) -> None:
        self.inner = inner
        view = self.view = FleetView(env)
        self.commitments: dict[int, float] = {}
        """This step's decided robots: index -> the forward speed (m/s) the later robots' shields
        see it moving at (the larger of its speed and its shielded command)."""
        self.vetoes = {a: Veto(_RobotEnv(env, a, view.robot(i, others_as_movers=True, speeds=self.commitments)), config)
                       for i, a in enumerate(env.possible_agents)}
        self.index = {a: i for i, a in enumerate(env.possible_agents)}
        self.decisions: dict[str, ShieldDecision] = {}
        self.interventions = 0
        self.steps = 0

    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        self.inner.reset(infos)
        for veto in self.vetoes.values():
            veto.reset()
        self.decisions, self.interventions, self.steps = {}, 0, 0

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        actions = self.inner.act(observations, infos)
        out = {}
        self.commitments.clear()
        for agent, action in actions.items():
            out[agent], d = self.vetoes[agent](action)
            i = self.index[agent]
            self.commitments[i] = max(self.view.speed(i), d.v)  # the speed its own sweep assumed
            self.decisions[agent] = d
            self.interventions += d.intervened
            self.steps += 1
        return out


# ---------------------------------------------------------------------- by name
def make_controller(name: str, env: FleetEnv, shield: bool = False, model: str | Path | None = None) -> FleetController:
    """The controller called ``name`` (:data:`CONTROLLERS`) for ``env``, behind the shield with ``shield``.

    Raises:
        ConfigError: an unknown name, or a model given to a controller that takes none.
        ModelError: the ``policy`` controller's model cannot drive this env.
    """
    if name not in CONTROLLERS:
        raise ConfigError(f"fleet controller must be one of {', '.join(CONTROLLERS)}, got {name!r}")
    if model is not None and name != "policy":
        raise ConfigError(f"fleet controller {name!r} takes no model (only 'policy' does)")
    if name == "independent":
        controller: FleetController = independent_controller(env)
    elif name == "coordinated":
        controller = CoordinatedController(env)
    else:
        controller = policy_controller(env, model or DEFAULT_MODEL)
    return ShieldedController(controller, env) if shield else controller


__all__ = ["CONTROLLERS", "DEFAULT_MODEL", "CoordinatedConfig", "CoordinatedController", "ErrandNavigator",
           "FleetController", "PerRobotController", "ShieldedController", "independent_controller", "make_controller",
           "model_env_kwargs", "policy_controller"]
