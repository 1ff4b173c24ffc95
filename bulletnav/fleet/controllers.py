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
  map (:mod:`bulletnav.fleet.spacetime`, WHCA*), each robot tracking its reserved path with the
  PID go-to-point controller.
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
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bulletnav.control.navigator import ControllerConfig, GoToGoal, Navigator, NavigatorConfig
from bulletnav.control.shield import ShieldConfig, ShieldDecision, Veto
from bulletnav.errors import ConfigError, ModelError
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.learned import SharedPolicyController
from bulletnav.fleet.spacetime import Cell, ReservationTable, distance_map, nearest_free, space_time_astar
from bulletnav.fleet.view import FleetView, RobotView
from bulletnav.policy import Policy

log = logging.getLogger(__name__)

CONTROLLERS = ("independent", "coordinated", "policy")
"""Names :func:`make_controller` takes."""
DEFAULT_MODEL = "models/ppo_dynamic.zip"
"""The single-robot model the ``policy`` controller drives with unless told otherwise."""


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
    """Windowed prioritized planning in space-time (:class:`CoordinatedController`)."""

    resolution: float = 0.5
    """Grid cell side (m): one plan step moves a robot one cell (4-connected) or waits."""
    clearance: float = 0.3
    """A cell is free when its centre is at least this far (m) from every obstacle and wall
    (the robot's 0.2 m disc plus 0.1 m for tracking error)."""
    window: int = 16
    """Steps each robot plans and reserves (WHCA*'s window)."""
    replan_every: int = 4
    """Plan steps between replans (rolling horizon); any goal change replans at once."""
    robustness: int = 1
    """Steps a robot keeps a cell reserved after leaving it (k-robust plans: a robot enters a
    cell no sooner than k + 1 steps after another left it)."""
    arrive_tolerance: float = 0.25
    """A robot has reached its step's cell within this distance (m) of its centre (half a cell:
    it is inside the cell)."""
    hold_radius: float = 0.1
    """A robot that has reached its step's cell stops within this distance (m) of its centre
    and holds until the fleet's next step (it keeps driving toward it from farther)."""
    max_step_s: float = 3.0
    """Plan steps advance when every robot has reached its step's cell, or after this long (s)."""
    controller: ControllerConfig = field(default_factory=lambda: ControllerConfig(safety_distance=0.35, side_margin=0.1))
    """The PID go-to-point controller that tracks the path (its lidar blends kept short: the
    plan keeps robots a cell apart)."""

    def __post_init__(self) -> None:
        if not (self.resolution > 0 and self.clearance >= 0 and self.arrive_tolerance > 0 and self.max_step_s > 0
                and 0 < self.hold_radius <= self.arrive_tolerance):
            raise ConfigError(f"coordinated planner needs resolution > 0, clearance >= 0, max_step_s > 0, "
                              f"0 < hold_radius <= arrive_tolerance; got {self}")
        if not (1 <= self.replan_every <= self.window and self.robustness >= 0):
            raise ConfigError(f"coordinated planner needs 1 <= replan_every <= window and robustness >= 0; got {self}")


class CoordinatedController:
    """Prioritized planning in space-time on the static map, windowed and replanned on a
    rolling horizon (cooperative A* / WHCA*, Silver 2005), each robot tracking its reserved
    path with the PID go-to-point controller.

    **Planning.** The static map at ``resolution`` (0.5 m) with cells closer than ``clearance``
    to an obstacle blocked. Every replan clears the reservation table, reserves each robot's
    current cell for the next ``robustness`` steps, then plans the robots one after another in
    priority order: each finds the cheapest ``window``-step path (moves and waits, waiting on its
    goal free, plus the static distance from the window's end to the goal) that respects the
    reservations of those before it (no cell held by another robot, no swap), and reserves it.
    A robot with no such path waits in its cell.

    **Priorities** rotate round-robin: at replan r the order starts at robot ``r mod N``
    (:attr:`order`), so every robot plans first once every N replans and none starves.

    **Execution.** Plan steps advance together: step k+1 starts when every robot is within
    ``arrive_tolerance`` of its step-k cell, or ``max_step_s`` after step k began (a robot held
    by a collision penalty does not stall the fleet). Each robot steers with the PID
    controller at its next cell (its goal point itself in its goal's cell) and holds still
    within ``hold_radius`` of it. The fleet replans every ``replan_every`` steps and whenever a goal changes.

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
        self.failed_plans = 0
        """Plans this episode that found no path in the window (the robot waited)."""
        self._rotation = 0

    # ------------------------------------------------------------------ episode
    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        view, cfg = self.view, self.config
        grid = view.occupancy(cfg.resolution, cfg.clearance)
        self.grid = grid
        self.blocked = grid.occupied
        self._heuristics: dict[Cell, np.ndarray] = {}
        n = len(self.agents)
        first = view.robot(0)
        lidar = first.sensors.lidar
        self.n_rays, self.max_range = lidar.config.num_rays, lidar.config.max_range
        self.dt = view.control_dt
        self.trackers = [GoToGoal(cfg.controller, lidar.angles, view.geometry) for _ in range(n)]
        self.normalized = first.normalized_actions
        self.limits = first.command_limits
        self.replans = self.failed_plans = 0
        self._rotation = 0
        self.goals = [self._goal(infos[a]) for a in self.agents]
        self._plan(infos)

    def _goal(self, info: dict[str, Any]) -> tuple[float, float]:
        return float(info["goal"][0]), float(info["goal"][1])

    def _cell(self, xy: tuple[float, float]) -> Cell:
        nx, ny = self.blocked.shape
        ix, iy = self.grid.world_to_cell(xy)
        return min(max(ix, 0), nx - 1), min(max(iy, 0), ny - 1)

    def _heuristic(self, goal: Cell) -> np.ndarray:
        h = self._heuristics.get(goal)
        if h is None:
            h = self._heuristics[goal] = distance_map(self.blocked, goal)
        return h

    # ------------------------------------------------------------------ planning
    def _plan(self, infos: dict[str, dict[str, Any]]) -> None:
        cfg, n = self.config, len(self.agents)
        self.order = [(self._rotation + k) % n for k in range(n)]
        self._rotation = (self._rotation + 1) % n
        table = self.table
        table.clear()
        starts = [self._cell(self.view.pose(i)[:2]) for i in range(n)]
        for i, cell in enumerate(starts):  # nobody else steps into a robot's cell right away
            for t in range(cfg.robustness + 1):
                table.reserve_cell(cell, t, i)
        self.goal_cells = [nearest_free(self.blocked, self._cell(g)) for g in self.goals]
        paths: list[list[Cell]] = [[] for _ in range(n)]
        for i in self.order:
            found = space_time_astar(self.blocked, starts[i], self.goal_cells[i], table, i, cfg.window,
                                     self._heuristic(self.goal_cells[i]))
            if found is None:
                self.failed_plans += 1
                path = [starts[i]] * (cfg.window + 1)
            else:
                path = found[0]
            table.reserve_path(path, i)
            paths[i] = path
        self.paths = paths
        self.step = 0
        self._step_began = self.view.time_s
        self.replans += 1

    # ------------------------------------------------------------------ acting
    def _target(self, i: int, k: int) -> tuple[float, float]:
        path = self.paths[i]
        cell = path[min(k, len(path) - 1)]
        if cell == self.goal_cells[i]:
            return self.goals[i]
        return self.grid.cell_to_world(*cell)

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        cfg, view, n = self.config, self.view, len(self.agents)
        goals = [self._goal(infos[a]) for a in self.agents]
        poses = [view.pose(i) for i in range(n)]
        if goals != self.goals:
            self.goals = goals
            self._plan(infos)
        else:
            nxt = self.step + 1
            arrived = all(math.dist(poses[i][:2], self._target(i, nxt)) < cfg.arrive_tolerance for i in range(n))
            if arrived or view.time_s - self._step_began >= cfg.max_step_s:
                self.step, self._step_began = nxt, view.time_s
                if self.step >= cfg.replan_every:
                    self._plan(infos)
        actions = {}
        for i, agent in enumerate(self.agents):
            target = self._target(i, self.step + 1)
            pose = poses[i]
            d = math.dist(pose[:2], target)
            if d < cfg.hold_radius:
                v, w = 0.0, 0.0  # there: hold until the fleet's next step
            else:
                state = observations[agent]["state"] if isinstance(observations[agent], dict) else observations[agent]
                ranges = np.asarray(state[: self.n_rays], dtype=np.float64) * self.max_range
                ahead = d + cfg.resolution * self._run(i, self.step + 1)
                v, w = self.trackers[i].command(pose, target, ranges, self.dt, ahead)
            actions[agent] = self._action(v, w)
        return actions

    def _run(self, i: int, k: int) -> int:
        """Moves that follow step ``k`` of robot ``i``'s path in the same direction (up to 2),
        so it does not slow down at every cell of a straight run."""
        path = self.paths[i]
        if k <= 0 or k >= len(path):
            return 0
        d = (path[k][0] - path[k - 1][0], path[k][1] - path[k - 1][1])
        run = 0
        while run < 2 and k + run + 1 < len(path):
            a, b = path[k + run], path[k + run + 1]
            if (b[0] - a[0], b[1] - a[1]) != d or d == (0, 0):
                break
            run += 1
        return run

    def _action(self, v: float, w: float) -> np.ndarray:
        if self.normalized:
            (v_lo, v_hi), (w_lo, w_hi) = self.limits
            v, w = 2.0 * (v - v_lo) / (v_hi - v_lo) - 1.0, 2.0 * (w - w_lo) / (w_hi - w_lo) - 1.0
        return np.array([v, w], dtype=np.float32)


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


class ShieldedController:
    """A fleet controller behind the safety shield: every robot's action goes through its
    own :class:`~bulletnav.control.shield.Veto`, which sees its lidar scan, odometry, the
    movers and the other robots as movers (pose, forward speed, footprint box).
    ``decisions`` holds the last step's :class:`~bulletnav.control.shield.ShieldDecision`
    per agent; ``interventions`` counts this episode's replaced actions over all robots.

    Args:
        inner: the controller to guard.
        env: the fleet env.
        config: the shield's settings.
    """

    def __init__(self, inner: FleetController, env: FleetEnv, config: ShieldConfig = ShieldConfig()) -> None:
        self.inner = inner
        view = FleetView(env)
        self.vetoes = {a: Veto(_RobotEnv(env, a, view.robot(i, others_as_movers=True)), config)
                       for i, a in enumerate(env.possible_agents)}
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
        for agent, action in actions.items():
            out[agent], d = self.vetoes[agent](action)
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
