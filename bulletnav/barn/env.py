"""``bulletnav/BARN-v0``: BARN's 300 static worlds with BARN's start, goal, rules and score."""

from __future__ import annotations

from typing import Any

import bulletnav.barn.task  # noqa: F401  (registers the "barn" task)
from bulletnav.barn.data import check_index, load_world
from bulletnav.barn.world import BarnPhysicsWorld, barn_layout
from bulletnav.config import EnvConfig
from bulletnav.envs.warehouse import WarehouseEnv
from bulletnav.yamlfile import show

BARN_KWARGS: dict[str, Any] = {"task_name": "barn", "goal_radius": 1.0, "collision_terminates": True, "robot": "jackal"}
"""What BARN-v0 sets on top of Warehouse-v0's defaults: BARN's task, its 1 m goal radius, a
collision ending the episode, BARN's robot (a Jackal, :func:`bulletnav.config.robot_preset`)."""


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
    ``gym.make("bulletnav/BARN-v0", world_idx=N)``, N in 0-299 (default 0), and Warehouse-v0's
    keywords except ``world`` and ``task_name``. ``reset(options={"world_idx": N})`` switches world; a bad index raises
    :class:`~bulletnav.errors.LayoutError` naming it.

    ## Version History
    - v0: initial release.
    """

    def __init__(self, world_idx: int = 0, render_mode: str | None = None, config: EnvConfig | None = None,
                 **kwargs: Any) -> None:
        if "world" in kwargs:
            raise TypeError(f"bulletnav/BARN-v0 takes world_idx (0-299), not world={show(kwargs['world'])}")
        if kwargs.get("task_name", "barn") != "barn":
            raise TypeError(f"bulletnav/BARN-v0 runs BARN's task only, not task_name={show(kwargs['task_name'])}")
        index = check_index(world_idx)
        super().__init__(render_mode, config, **{**BARN_KWARGS, **kwargs})
        scene = self._scene
        scene.sim.world = scene.world = BarnPhysicsWorld(scene.cid, self.config.physics)
        self._use_world(index)

    @property
    def world_idx(self) -> int:
        """The BARN world of the current (or next) episode."""
        return self._world_idx

    def _use_world(self, index: int) -> None:
        self._world_idx = index
        self._fixed_layout = barn_layout(index)
        self.task.set_reference(load_world(index).path_cells)

    def reset(self, *, seed: int | None = None, options: dict[str, Any] | None = None):
        if isinstance(options, dict) and "world_idx" in options:
            options = dict(options)
            self._use_world(check_index(options.pop("world_idx")))
        obs, info = super().reset(seed=seed, options=options)
        info["world_idx"] = self._world_idx
        return obs, info

    def step(self, action):
        obs, reward, terminated, truncated, info = super().step(action)
        info["world_idx"] = self._world_idx
        return obs, reward, terminated, truncated, info
