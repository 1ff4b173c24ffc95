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
- :class:`~bulletnav.fleet.coordinated.CoordinatedController` (:mod:`bulletnav.fleet.coordinated`):
  windowed prioritized planning in space-time on the static map (:mod:`bulletnav.fleet.spacetime`,
  WHCA*), each robot driving its reserved path at its own pace with the PID go-to-point
  controller, entering a cell only after the robots planned there earlier have left it (an
  action dependency graph, no lockstep).
- :func:`policy_controller`: one single-robot SB3 model, zero-shot on every robot (the fleet
  env must be made with the model's env settings, :func:`model_env_kwargs`).
- :class:`ShieldedController`: any of them behind the safety shield
  (:mod:`bulletnav.control.shield`), each robot's shield seeing the other robots as movers
  (pose, forward speed, footprint box), as the single-robot shield sees forklifts.

:func:`make_controller` builds one by name (what the CLI's ``fleet --controller`` takes).
"""

from __future__ import annotations

import logging
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.control.shield import ShieldConfig, ShieldDecision, Veto
from bulletnav.errors import ConfigError, ModelError
from bulletnav.fleet.coordinated import CoordinatedConfig, CoordinatedController
from bulletnav.fleet.env import FleetEnv
from bulletnav.fleet.learned import SharedPolicyController
from bulletnav.fleet.view import FleetView, RobotView
from bulletnav.policy import Policy

log = logging.getLogger(__name__)

CONTROLLERS = ("independent", "coordinated", "policy")
"""Names :func:`make_controller` takes."""
DEFAULT_FLEET_MODEL = "models/ppo_dynamic.zip"
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
    from bulletnav.rl.io import model_file
    from bulletnav.rl.sidecar import sidecar_path

    model_path = model_file(model_path)
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


def policy_controller(env: FleetEnv, model_path: str | Path = DEFAULT_FLEET_MODEL) -> SharedPolicyController:
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
        controller = policy_controller(env, model or DEFAULT_FLEET_MODEL)
    return ShieldedController(controller, env) if shield else controller


__all__ = ["CONTROLLERS", "DEFAULT_FLEET_MODEL", "CoordinatedConfig", "CoordinatedController", "ErrandNavigator",
           "FleetController", "PerRobotController", "ShieldedController", "independent_controller", "make_controller",
           "model_env_kwargs", "policy_controller"]
