"""``bulletnav.fleet``: N robots running pick-and-drop errands in one warehouse (PettingZoo ``ParallelEnv``)."""

from __future__ import annotations

import math
from dataclasses import fields
from typing import Any

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv

from bulletnav import AISLES_KWARGS, DYNAMIC_KWARGS
from bulletnav.config import EnvConfig
from bulletnav.envs.actions import ActionMap
from bulletnav.envs.warehouse import make_config
from bulletnav.errors import ConfigError, SamplingError
from bulletnav.fleet.config import FleetConfig
from bulletnav.fleet.scene import KINDS, FleetScene
from bulletnav.fleet.stations import Errand, ErrandStream, Stations, find_stations, load_world, points_arg
from bulletnav.fleet.task import ErrandTask
from bulletnav.sim.generators import world_generator
from bulletnav.sim.layout import Layout

_FLEET_FIELDS = {f.name for f in fields(FleetConfig)}
_UNSUPPORTED = ("task_name", "camera_obs", "randomize", "perturb", "goals", "goal_order", "steps_per_goal")
"""Single-robot arguments the fleet does not take (yet)."""
_PRIORITY = ("person", "robot", "mover", "static")
"""When one step brings new contacts of several kinds, the collision counts as the first of these."""


class FleetEnv(ParallelEnv):
    """N differential-drive robots running lifelong pick -> drop errands in one warehouse.

    ## Description
    An aisle warehouse (``WarehouseAisles-v0``'s generator and settings by default; any
    ``layout_style`` or YAML ``world``) with ``num_robots`` (4) identical robots, each with its
    own lidar, IMU and odometry. Every lidar sees the other robots' bodies (never its own,
    :mod:`bulletnav.fleet.lidar`). With ``dynamic=True`` (or the movers' own arguments, as
    ``WarehouseDynamic-v0`` takes them) forklifts, walking workers and pallet events share the
    floor; movers yield to whichever robot stands in their safety field.

    ## Agents
    ``robot_0`` ... ``robot_{N-1}``; all act every step (a parallel env) and none leaves early.

    ## Action and Observation Spaces
    Per agent, EQUAL to the single-robot env's for the same arguments
    (``gymnasium.make("bulletnav/WarehouseAisles-v0", **kwargs)``): ``Box(2,)`` (v m/s, w rad/s;
    ``[-1, 1]`` with ``normalize_actions=True``) and the navigation task's vector toward the
    robot's current goal (43 floats by default; ``guidance="floorplan"`` adds 3). Every
    single-robot controller and model runs unchanged on each robot.

    ## Tasks
    Pick stations in front of rack faces, drop stations along the dock wall
    (:mod:`bulletnav.fleet.stations`). Each robot runs errands from a seeded stream: its goal
    is the errand's pick station, then its drop station; reaching a goal (within
    ``goal_radius``, 0.5 m) completes that leg, completing the drop completes the errand and
    the next one is assigned at once.

    ## Rewards
    Per agent, the single-robot navigation terms toward its current goal (``progress``,
    ``goal`` once per leg, ``collision`` once per counted collision, ``time``, ``heading``,
    ``stuck``, ``proximity``; ``mover_proximity`` when weighted), each in ``infos[agent]`` as
    ``reward_<name>``; weights are the same ``reward_<name>`` arguments.

    ## Collisions
    A robot that comes into contact with something it was not touching the step before (a
    wall or obstacle, a forklift, a worker, another robot) while it is not already stopped
    counts one collision of that kind and stands still for ``collision_penalty_s`` (5 s): its
    actions are ignored and its wheels stopped. The episode goes on.

    ## Episode End
    After ``duration_s`` (180 s) of simulated time every agent is truncated together;
    ``terminations`` are always False.

    ## Info (per agent)
    The reward terms; ``pose`` (x, y, yaw ground truth), ``goal``, ``distance_to_goal``,
    ``path_length`` (m this episode); ``errand`` (``id``, ``pick``, ``drop``, ``leg``: "pick"
    or "drop"), ``errands_completed``, ``legs_completed``; ``collisions_static``,
    ``collisions_mover``, ``collisions_person``, ``collisions_robot`` (counts this episode),
    ``collision_with`` (the kind counted this step, else None), ``stopped_s`` (penalty time
    left, s); ``time_s``; in dynamic worlds ``nearest_mover_m``.

    ## Arguments
    Fleet arguments (:class:`~bulletnav.fleet.config.FleetConfig`): ``num_robots`` (4, 1-16),
    ``duration_s`` (180), ``collision_penalty_s`` (5), ``min_clearance`` (0.3 m between robots'
    footprint discs at the start), ``station_spacing`` (1 m), ``station_offset`` (0.55 m),
    ``dock_wall`` ("auto"), ``pick_stations`` / ``drop_stations`` (explicit points);
    ``dynamic`` (False: ``True`` adds ``WarehouseDynamic-v0``'s forklifts, workers and pallet
    events); ``config`` (an :class:`~bulletnav.config.EnvConfig` to start from instead of the
    aisle env's settings); and every single-robot keyword of ``bulletnav/Warehouse-v0`` except
    ``task_name``, ``camera_obs``, ``randomize``, ``perturb``, ``shift_<field>`` and the mission's.
    ``reset(seed=...)`` draws the layout, the robots' starts, the errand stream, the sensors'
    noise and the movers from one seeded generator.

    ## Version History
    - v0: initial release.
    """

    metadata = {"name": "bulletnav_fleet_v0", "render_modes": ["human"], "is_parallelizable": True, "render_fps": 24}

    def __init__(self, num_robots: int = 4, render_mode: str | None = None, config: EnvConfig | None = None,
                 dynamic: bool = False, **kwargs: Any) -> None:
        if render_mode not in (None, "human"):
            raise ConfigError(f"fleet render_mode must be None or 'human', got {render_mode!r}")
        fleet_kwargs = {k: kwargs.pop(k) for k in list(kwargs) if k in _FLEET_FIELDS}
        for name in ("pick_stations", "drop_stations"):
            if fleet_kwargs.get(name) is not None:
                fleet_kwargs[name] = points_arg(fleet_kwargs[name], f"fleet {name}")
        self.fleet_config = fc = FleetConfig(num_robots=num_robots, **fleet_kwargs)
        for key in kwargs:
            if key in _UNSUPPORTED or key.startswith("shift_"):
                raise ConfigError(f"fleet: argument {key!r} is not supported by the multi-robot env")
        base = {} if config is not None else dict(AISLES_KWARGS)
        if dynamic:
            base.update({k: v for k, v in DYNAMIC_KWARGS.items() if k not in AISLES_KWARGS})
        self.config = cfg = make_config(config, **{**base, **kwargs})
        if cfg.task_name != "navigation" or cfg.camera_obs:
            raise ConfigError("fleet: config must use task_name='navigation' and camera_obs=False")
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": cfg.physics.control_hz}
        self._generate = world_generator(cfg.world.style)
        self._fixed_layout: Layout | None = None
        self._named: dict[str, tuple[tuple[float, float], ...]] = {}
        if cfg.layout_file:
            self._fixed_layout, self._named = load_world(cfg.layout_file)
        if fc.pick_stations is not None:
            self._named["pick"] = fc.pick_stations
        if fc.drop_stations is not None:
            self._named["drop"] = fc.drop_stations
        self.possible_agents = [f"robot_{i}" for i in range(fc.num_robots)]
        self.agents: list[str] = []
        self._scene = FleetScene(cfg, fc.num_robots, gui=render_mode == "human")
        try:
            self._tasks = [ErrandTask(cfg, slot) for slot in self._scene.slots]
        except BaseException:
            self._scene.close()
            raise
        self._actions = ActionMap.of(cfg.task, cfg.normalize_actions)
        action = self._actions.space()
        self._action_spaces = {a: action if i == 0 else spaces.Box(action.low, action.high, dtype=np.float32)
                               for i, a in enumerate(self.possible_agents)}
        self._observation_spaces = {a: task.observation_space() for a, task in zip(self.possible_agents, self._tasks)}
        self._term_keys = tuple(f"reward_{n}" for n in self._tasks[0].reward_terms)
        self._max_steps = max(1, round(fc.duration_s * cfg.physics.control_hz))
        self._penalty_steps = round(fc.collision_penalty_s * cfg.physics.control_hz)
        self._np_random: np.random.Generator | None = None
        self._resets_on_layout = 0
        self._stations: Stations | None = None
        self._stations_for: Layout | None = None
        self._steps = 0
        n = fc.num_robots
        self._errands: list[Errand] = []
        self._legs = ["pick"] * n
        self._done_errands = [0] * n
        self._done_legs = [0] * n
        self._counts = [dict.fromkeys(KINDS, 0) for _ in range(n)]
        self._stopped = [0] * n
        self._touching: list[set[int]] = [set() for _ in range(n)]
        self._stream: ErrandStream | None = None

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: str) -> spaces.Space:
        """The agent's observation space (the same object at every call, as PettingZoo asks)."""
        return self._observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Space:
        """The agent's action space (the same object at every call)."""
        return self._action_spaces[agent]

    @property
    def stations(self) -> Stations | None:
        """The current layout's pick and drop stations (None before the first reset)."""
        return self._stations

    # ------------------------------------------------------------------ API
    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None):
        """Start an episode (``options`` are accepted and ignored). A seeded reset draws a new
        layout and rebuilds the physics scene, so it is bit-identical whatever came before."""
        if seed is not None or self._np_random is None:
            self._np_random, _ = seeding.np_random(seed)
        rng = self._np_random
        cfg, fc, scene = self.config, self.fleet_config, self._scene
        layout = self._fixed_layout
        if layout is None:
            layout = scene.layout
            if seed is not None or layout is None or self._resets_on_layout >= cfg.layouts_every:
                layout = self._generate(rng, cfg.world)
                self._resets_on_layout = 0
        self._resets_on_layout += 1
        scene.use_layout(layout, rebuild=seed is not None)
        if self._stations_for is not layout:
            self._stations = find_stations(layout, scene.free_space, cfg.sampler.clearance, fc.station_offset,
                                           fc.station_spacing, fc.dock_wall, self._named)
            self._stations_for = layout
        stations = self._stations
        starts = self._draw_starts(rng, stations.component)
        self._stream = ErrandStream(np.random.default_rng(int(rng.integers(0, 2**63 - 1))), stations)
        self._errands = []
        for _ in range(fc.num_robots):
            self._errands.append(self._stream.next({e.pick for e in self._errands}))
        scene.place(starts, rng, tuple(e.pick for e in self._errands))
        n = fc.num_robots
        self._legs = ["pick"] * n
        self._done_errands = [0] * n
        self._done_legs = [0] * n
        self._counts = [dict.fromkeys(KINDS, 0) for _ in range(n)]
        self._stopped = [0] * n
        self._touching = [set() for _ in range(n)]
        self._steps = 0
        for slot, task, start, errand in zip(scene.slots, self._tasks, starts, self._errands):
            slot.collision = None
            task.begin(slot, start, errand.pick)
        self.agents = list(self.possible_agents)
        terms = dict.fromkeys(self._tasks[0].reward_terms, 0.0)
        obs = {a: task.observe(slot) for a, task, slot in zip(self.agents, self._tasks, scene.slots)}
        infos = {a: self._info(i, terms) for i, a in enumerate(self.agents)}
        return obs, infos

    def step(self, actions: dict[str, Any]):
        """Advance every robot one control period. A robot without an action (or None) stops;
        a robot serving a collision penalty ignores its action."""
        if not self.agents:
            raise RuntimeError("the fleet episode is over: call reset()")
        scene, n = self._scene, self.fleet_config.num_robots
        commands = []
        held = []
        for i, agent in enumerate(self.possible_agents):
            held.append(self._stopped[i] > 0)
            if held[i]:
                self._stopped[i] -= 1
                commands.append((0.0, 0.0))
            elif agent in actions and actions[agent] is not None:
                commands.append(self.command(actions[agent]))
            else:
                commands.append((0.0, 0.0))
        scene.step(commands)
        for i in range(n):
            touching = scene.contacts(i)
            new = {kind for body, kind in touching.items() if body not in self._touching[i]}
            self._touching[i] = set(touching)
            slot = scene.slots[i]
            slot.collision = None
            if new and not held[i]:
                kind = next(k for k in _PRIORITY if k in new)
                slot.collision = kind
                self._counts[i][kind] += 1
                self._stopped[i] = self._penalty_steps
        self._steps += 1
        rewards, all_terms = {}, []
        for i, (agent, task, slot) in enumerate(zip(self.possible_agents, self._tasks, scene.slots)):
            task.after_step(slot)
            terms = task.reward(slot)
            rewards[agent] = float(sum(terms.values()))
            all_terms.append(terms)
            if task.reached:
                self._advance(i)
        scene.goals = tuple(task.goal for task in self._tasks)
        obs = {a: task.observe(slot) for a, task, slot in zip(self.possible_agents, self._tasks, scene.slots)}
        infos = {a: self._info(i, all_terms[i]) for i, a in enumerate(self.possible_agents)}
        over = self._steps >= self._max_steps
        terminations = dict.fromkeys(self.possible_agents, False)
        truncations = dict.fromkeys(self.possible_agents, over)
        if over:
            self.agents = []
        return obs, rewards, terminations, truncations, infos

    def command(self, action: Any) -> tuple[float, float]:
        """The (v m/s, w rad/s) an action commands, after scaling and clipping: the single-robot
        env's map (:meth:`~bulletnav.envs.actions.ActionMap.command`).

        Raises:
            ValueError: the action is not 2 finite numbers.
        """
        return self._actions.command(action)

    def render(self) -> None:
        return None

    def close(self) -> None:
        self._scene.close()

    # ------------------------------------------------------------------ helpers
    def _advance(self, i: int) -> None:
        """Robot ``i`` reached its goal: the next leg, or the next errand."""
        self._done_legs[i] += 1
        if self._legs[i] == "pick":
            self._legs[i] = "drop"
            goal = self._errands[i].drop
        else:
            self._done_errands[i] += 1
            busy = {t.goal for j, t in enumerate(self._tasks) if j != i}
            self._errands[i] = self._stream.next(busy)
            self._legs[i] = "pick"
            goal = self._errands[i].pick
        self._tasks[i].set_goal(self._scene.slots[i], goal)

    def _draw_starts(self, rng: np.random.Generator, region: int) -> list[tuple[float, float, float]]:
        """One start pose per robot on free floor of ``region``, footprint discs at least
        ``min_clearance`` apart, yaw uniform."""
        free = self._scene.free_space
        fc = self.fleet_config
        cells = np.argwhere(free.clear & (free.component == region))
        points = np.stack([free.xs[cells[:, 0]], free.ys[cells[:, 1]]], axis=1) if len(cells) else np.zeros((0, 2))
        need = 2 * self._scene.geometry.radius + fc.min_clearance
        chosen: list[np.ndarray] = []
        for k in rng.permutation(len(points)):
            q = points[k]
            if all(math.hypot(q[0] - c[0], q[1] - c[1]) >= need for c in chosen):
                chosen.append(q)
                if len(chosen) == fc.num_robots:
                    break
        if len(chosen) < fc.num_robots:
            where = self._scene.layout.source or self._scene.layout.name or "the world"
            raise SamplingError(f"fleet num_robots={fc.num_robots}: only {len(chosen)} robots fit on the free floor of "
                                f"{where} ({self.config.sampler.clearance} m from obstacles, {fc.min_clearance} m apart)")
        yaws = rng.uniform(-math.pi, math.pi, fc.num_robots)
        return [(float(q[0]), float(q[1]), float(y)) for q, y in zip(chosen, yaws)]

    def _info(self, i: int, terms: dict[str, float]) -> dict[str, Any]:
        task, slot = self._tasks[i], self._scene.slots[i]
        info: dict[str, Any] = dict(zip(self._term_keys, terms.values()))
        info.update(task.info(slot))
        info.pop("is_success", None)
        info["errand"] = self._errands[i].as_dict(self._legs[i])
        info["errands_completed"] = self._done_errands[i]
        info["legs_completed"] = self._done_legs[i]
        for kind, count in self._counts[i].items():
            info[f"collisions_{kind}"] = count
        info["collision_with"] = slot.collision
        info["stopped_s"] = self._stopped[i] * self.config.physics.control_dt
        info["time_s"] = self._scene.clock.time
        if self._scene.dynamic:
            info["nearest_mover_m"] = self._scene.nearest_mover(i)
        return info
