"""``bulletnav/BARN-v0``: BARN's 300 static worlds with BARN's start, goal, rules and score."""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from typing import Any

import numpy as np

import bulletnav.barn.task  # noqa: F401  (registers the "barn" task)
from bulletnav.barn.data import check_index, load_world, world_pool
from bulletnav.barn.world import BarnPhysicsWorld, barn_layout
from bulletnav.config import EnvConfig
from bulletnav.envs.warehouse import WarehouseEnv
from bulletnav.yamlfile import show

BARN_KWARGS: dict[str, Any] = {"task_name": "barn", "goal_radius": 1.0, "collision_terminates": True, "robot": "jackal",
                               "lidar_caster": "exact"}
"""What BARN-v0 sets on top of Warehouse-v0's defaults: BARN's task, its 1 m goal radius, a
collision ending the episode, BARN's robot (a Jackal, :func:`bulletnav.config.robot_preset`), and
the lidar cast in closed form against BARN's cylinders (:mod:`bulletnav.sensors.raycast`: the
true geometry, and a scan of 30 m rays through hundreds of cylinders in a fraction of PyBullet's time:
``bulletnav bench env --env bulletnav/BARN-v0``)."""
BARN_RULES: dict[str, Any] = {"goal_radius": 1.0, "collision_terminates": True, "goals": 1, "goal_order": "free",
                              "forklifts": (0, 0), "workers": (0, 0), "pallet_events_per_min": 0.0}
"""Keywords that would change BARN's rules (its 1 m goal, a collision ending the run, one goal,
a static world): BARN-v0 accepts them only at BARN's own values, so an episode scored by BARN's
metric is always one BARN's rules would score."""
BARN_WORLD_KEYWORDS = frozenset({"num_obstacles", "world_size", "layout_style", "aisles", "min_goal_distance",
                                 "max_goal_distance", "min_detour", "blocked_by", "detour_share", "layouts_every",
                                 "steps_per_goal", "yield_to_robot", "forklift_speed", "worker_speed"})
"""Warehouse-v0 keywords that draw a warehouse's world, goals or movers: BARN's worlds, start and
goal are BARN's (and its clock, not a step budget, ends a run), so BARN-v0 refuses them."""
DEFAULT_WORLD = 1
"""The world of ``gym.make("bulletnav/BARN-v0")`` without ``world_idx``: the first non-test world
(BARN's test worlds 0, 6, ..., 294 are for scoring only; never train or tune on them)."""
POOL_STREAM = 0xBA2
"""Second word of the pool generator's seed (``[seed, POOL_STREAM]``): the world draws are a stream
of their own, apart from the episode's ``np_random``."""


def check_barn_kwargs(kwargs: dict[str, Any]) -> None:
    """Refuse keywords that would change BARN's rules (:data:`BARN_RULES`, unless at BARN's
    value) or draw a warehouse (:data:`BARN_WORLD_KEYWORDS`).

    Raises:
        TypeError: naming the keyword, its value and BARN's.
    """
    for key, rule in BARN_RULES.items():
        if key in kwargs and not _same(kwargs[key], rule):
            raise TypeError(f"bulletnav/BARN-v0 keeps BARN's rules: {key}={show(kwargs[key])} would change them "
                            f"(BARN's is {show(rule)})")
    drawn = sorted(BARN_WORLD_KEYWORDS & set(kwargs))
    if drawn:
        raise TypeError(f"bulletnav/BARN-v0 runs BARN's worlds, start and goal: {drawn[0]}={show(kwargs[drawn[0]])} "
                        "does not apply (it draws a warehouse's)")


def _same(value: Any, rule: Any) -> bool:
    """``value`` equals BARN's ``rule`` as Warehouse-v0 would read it: a list for a tuple, one
    number for a (min, max) pair of equal numbers, any real number (numpy's too) for a number."""
    if isinstance(rule, tuple):
        if isinstance(value, numbers.Real) and not isinstance(value, bool):
            return all(_same(value, r) for r in rule)
        return isinstance(value, (list, tuple)) and len(value) == len(rule) and all(_same(v, r) for v, r in zip(value, rule))
    if isinstance(rule, bool) or isinstance(value, (bool, np.bool_)):
        return isinstance(value, (bool, np.bool_)) and bool(value) is rule
    if isinstance(rule, (int, float)):
        return isinstance(value, numbers.Real) and value == rule
    return value == rule


class BarnEnv(WarehouseEnv):
    """Drive to BARN's goal through one of BARN's 300 static worlds (Perille et al. 2020).

    ## Description
    World ``world_idx`` (0-299) of the BARN challenge (github.com/Daffan/the-barn-challenge, MIT
    license): 181-365 static cylinders (radius 0.075 m, 1 m tall) at the world file's poses, in
    BARN's frame. The robot starts at BARN's start (-2.25, 3) with yaw 1.57 rad and drives to
    BARN's goal (-2.25, 13), as BARN's ``run.py`` sets them for static worlds. The robot is a
    Clearpath Jackal-sized one by default (``robot="jackal"``: 0.508 x 0.430 m, 2.0 m/s, 4.0 rad/s,
    a 270-degree lidar seen as 72 rays; ``robot="article"`` gives Warehouse-v0's); the observation
    and the reward are Warehouse-v0's for that robot (``lidar_rays + 7`` entries, 79 by default).

    ## Episode End
    By BARN's rules (:mod:`bulletnav.barn.task`): a collision (any contact) terminates; BARN's
    clock, which starts when the robot has first moved 0.1 m from its start, reaching 100 s
    truncates (``end_reason="timeout"``); being within 1 m of the goal terminates with success.
    No step limit besides (``max_episode_steps=None``).

    ## Info
    Warehouse-v0's entries, plus ``barn_time_s`` (BARN's clock, s) every step and, at the end,
    ``barn_metric``: BARN's score success x t_opt / clip(t, 2 t_opt, 8 t_opt)
    (:func:`bulletnav.barn.metric.barn_metric`).

    ## Arguments
    ``gym.make("bulletnav/BARN-v0", world_idx=N)``, N in 0-299 (default 1, the first non-test
    world), and Warehouse-v0's keywords except ``world``, ``task_name``, those that draw a
    warehouse (:data:`BARN_WORLD_KEYWORDS`) and those that would change BARN's rules
    (:data:`BARN_RULES`: accepted at BARN's values only). ``reset(options={"world_idx": N})`` switches world; a bad index raises
    :class:`~bulletnav.errors.LayoutError` naming it.

    ``world_idx`` may also name a pool: ``"train"`` (BARN's 250 non-test worlds,
    :data:`~bulletnav.barn.data.TRAIN_WORLDS`), ``"test"`` (the 50 test worlds 0, 6, ..., 294,
    :data:`~bulletnav.barn.data.TEST_WORLDS`) or a list of indices. Every reset then draws its
    world uniformly from the pool with a numpy Generator of its own, seeded by a seeded reset
    (``[seed, POOL_STREAM]``): the same seeds give the same worlds. ``options={"world_idx": N}``
    still picks one world explicitly (any of the 300) for that reset. ``info["world_idx"]`` is
    the episode's world. An unseeded reset onto another world rebuilds the cylinders.

    ## Version History
    - v0: initial release.
    """

    def __init__(self, world_idx: int | str | Sequence[int] = DEFAULT_WORLD, render_mode: str | None = None,
                 config: EnvConfig | None = None, **kwargs: Any) -> None:
        if "world" in kwargs:
            raise TypeError(f"bulletnav/BARN-v0 takes world_idx (0-299), not world={show(kwargs['world'])}")
        if kwargs.get("task_name", "barn") != "barn":
            raise TypeError(f"bulletnav/BARN-v0 runs BARN's task only, not task_name={show(kwargs['task_name'])}")
        check_barn_kwargs(kwargs)
        if isinstance(world_idx, (int, np.integer)):
            self._pool: tuple[int, ...] | None = None
            index = check_index(world_idx)
        else:
            self._pool = world_pool(world_idx)
            index = self._pool[0]
        self._pool_rng: np.random.Generator | None = None
        super().__init__(render_mode, config, **{**BARN_KWARGS, **kwargs})
        task, dynamic = self.config.task, self.config.dynamic
        made = {"goal_radius": task.goal_radius, "collision_terminates": task.collision_terminates, "goals": task.goals,
                "goal_order": task.goal_order, "forklifts": tuple(dynamic.forklifts), "workers": tuple(dynamic.workers),
                "pallet_events_per_min": dynamic.pallet_events_per_min}
        check_barn_kwargs(made)  # a config= given whole must keep BARN's rules too
        scene = self._scene
        if scene.sim.backend == "bullet":  # the kinematic profile's world holds cylinders as they come
            scene.sim.world = scene.world = BarnPhysicsWorld(scene.cid, self.config.physics)
        self._use_world(index)

    @property
    def world_idx(self) -> int:
        """The BARN world of the current (or next) episode."""
        return self._world_idx

    @property
    def world_pool(self) -> tuple[int, ...] | None:
        """The worlds resets draw from (None: one fixed world)."""
        return self._pool

    def _use_world(self, index: int) -> None:
        self._world_idx = index
        self._fixed_layout = barn_layout(index)
        self.task.set_reference(load_world(index).path_cells)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if self._pool is not None:
            if seed is not None:
                self._pool_rng = np.random.default_rng([seed, POOL_STREAM])
            elif self._pool_rng is None:
                self._pool_rng = np.random.default_rng()
        if isinstance(options, dict) and "world_idx" in options:
            options = dict(options)
            self._use_world(check_index(options.pop("world_idx")))
        elif self._pool is not None:
            assert self._pool_rng is not None
            index = self._pool[int(self._pool_rng.integers(len(self._pool)))]
            if index != self._world_idx:
                self._use_world(index)
        obs, info = super().reset(seed=seed, options=options)
        info["world_idx"] = self._world_idx
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = super().step(action)
        info["world_idx"] = self._world_idx
        return obs, reward, terminated, truncated, info
