"""The fleet as a Stable-Baselines3 vector env: every robot of every fleet one slot.

:class:`FleetVecEnv` is what SuperSuit's ``pettingzoo_env_to_vec_env_v1`` +
``concat_vec_envs_v1`` build, kept small and in this package (SuperSuit would add a compiled
dependency, ``tinyscaler``, for these few lines, and its concatenation reseeds and resets on
its own terms): a parameter-shared policy acts for all robots at once, and each robot's
transitions are its own trajectory.

- Slots: fleet 0's ``possible_agents`` in order, then fleet 1's, ...; ``num_envs`` is the
  number of robots over all fleets. Observation and action spaces are the per-agent ones,
  which must be equal for every agent of every fleet.
- Episode end: a fleet truncates all its agents together (``FleetEnv`` never terminates one
  early). Then every slot of that fleet reports ``done``, its ``info`` carries
  ``terminal_observation`` (the last observation) and ``TimeLimit.truncated`` (True), and
  the fleet is reset at once (autoreset, as SB3's own vector envs do): the observation
  returned is the new episode's first.
- Seeding: :meth:`FleetVecEnv.seed` gives fleet ``k`` the seed ``seed + k`` for its next
  reset; later (automatic) resets continue each fleet's own generator, so a seeded run is
  reproducible step for step.

Every fleet runs in this process, one after the other (the fleet's own step already moves
all its robots in one physics scene).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from copy import deepcopy
from typing import Any

import numpy as np
from stable_baselines3.common.vec_env.base_vec_env import VecEnv, VecEnvIndices, VecEnvObs, VecEnvStepReturn

from bulletnav.errors import ConfigError
from bulletnav.fleet.env import FleetEnv


def _same_space(a: Any, b: Any) -> bool:
    return (a.shape == b.shape and a.dtype == b.dtype and np.array_equal(a.low, b.low)
            and np.array_equal(a.high, b.high))


class FleetVecEnv(VecEnv):
    """Fleets of robots as one SB3 :class:`~stable_baselines3.common.vec_env.VecEnv`, one
    slot per robot (see the module docstring).

    Args:
        env_fns: one thunk per fleet, each returning a :class:`~bulletnav.fleet.env.FleetEnv`
            (or any PettingZoo ``ParallelEnv`` whose agents all share one observation and
            one action space and end their episodes together).

    Raises:
        ConfigError: no fleet, or agents whose spaces differ.
    """

    def __init__(self, env_fns: Sequence[Callable[[], FleetEnv]]) -> None:
        if not env_fns:
            raise ConfigError("FleetVecEnv needs at least one fleet")
        self.fleets: list[FleetEnv] = []
        try:
            for fn in env_fns:
                self.fleets.append(fn())
        except BaseException:
            for fleet in self.fleets:
                fleet.close()
            raise
        first = self.fleets[0]
        agent = first.possible_agents[0]
        obs_space, act_space = first.observation_space(agent), first.action_space(agent)
        self.slots: list[tuple[int, str]] = []
        """Slot index -> (fleet index, agent name)."""
        for k, fleet in enumerate(self.fleets):
            for a in fleet.possible_agents:
                if not (_same_space(fleet.observation_space(a), obs_space) and _same_space(fleet.action_space(a), act_space)):
                    self.close()
                    raise ConfigError(f"FleetVecEnv: fleet {k}'s agent {a!r} has other spaces than {agent!r} "
                                      "(a shared policy needs one observation and one action space)")
                self.slots.append((k, a))
        self._first_slot = np.cumsum([0] + [len(f.possible_agents) for f in self.fleets])
        super().__init__(len(self.slots), obs_space, act_space)
        self.render_mode = None
        self._actions: np.ndarray | None = None
        self.reset_infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]

    # ------------------------------------------------------------------ seeding
    def seed(self, seed: int | None = None) -> Sequence[int | None]:
        """Fleet ``k``'s next reset uses ``seed + k`` (every slot of a fleet shows its fleet's seed)."""
        if seed is None:
            seed = int(np.random.randint(0, np.iinfo(np.uint32).max, dtype=np.uint32))
        self._seeds = [seed + k for k, _ in self.slots]
        return self._seeds

    def _fleet_slots(self, k: int) -> range:
        return range(int(self._first_slot[k]), int(self._first_slot[k + 1]))

    # ------------------------------------------------------------------ reset / step
    def _reset_fleet(self, k: int, seed: int | None) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        first = int(self._first_slot[k])
        obs, infos = self.fleets[k].reset(seed=seed, options=self._options[first] or None)
        return obs, infos

    def reset(self) -> VecEnvObs:
        """Reset every fleet (with the seeds :meth:`seed` set, once) and return all slots' observations."""
        out = np.zeros((self.num_envs, *self.observation_space.shape), dtype=self.observation_space.dtype)
        for k in range(len(self.fleets)):
            obs, infos = self._reset_fleet(k, self._seeds[int(self._first_slot[k])])
            for i in self._fleet_slots(k):
                agent = self.slots[i][1]
                out[i] = obs[agent]
                self.reset_infos[i] = infos[agent]
        self._reset_seeds()
        self._reset_options()
        return out

    def step_async(self, actions: np.ndarray) -> None:
        self._actions = np.asarray(actions)

    def step_wait(self) -> VecEnvStepReturn:
        if self._actions is None:
            raise RuntimeError("step_wait() without step_async()")
        actions, self._actions = self._actions, None
        out = np.zeros((self.num_envs, *self.observation_space.shape), dtype=self.observation_space.dtype)
        rewards = np.zeros(self.num_envs, dtype=np.float32)
        dones = np.zeros(self.num_envs, dtype=bool)
        infos: list[dict[str, Any]] = [{} for _ in range(self.num_envs)]
        for k, fleet in enumerate(self.fleets):
            slots = self._fleet_slots(k)
            obs, rew, terms, truncs, finfos = fleet.step({self.slots[i][1]: actions[i] for i in slots})
            for i in slots:
                agent = self.slots[i][1]
                out[i] = obs[agent]
                rewards[i] = rew[agent]
                dones[i] = bool(terms[agent] or truncs[agent])
                infos[i] = dict(finfos[agent])
            if fleet.agents and any(dones[i] for i in slots):
                raise RuntimeError(f"FleetVecEnv: fleet {k} ended some agents' episodes but not all "
                                   "(the adapter needs every agent to end together)")
            if not fleet.agents:  # the episode is over for all its agents: autoreset
                new_obs, new_infos = self._reset_fleet(k, None)
                for i in slots:
                    agent = self.slots[i][1]
                    infos[i]["terminal_observation"] = out[i].copy()
                    infos[i]["TimeLimit.truncated"] = bool(truncs[agent] and not terms[agent])
                    out[i] = new_obs[agent]
                    self.reset_infos[i] = new_infos[agent]
        return out, rewards, dones, infos

    def close(self) -> None:
        for fleet in self.fleets:
            fleet.close()

    # ------------------------------------------------------------------ attributes
    def _targets(self, indices: VecEnvIndices) -> list[FleetEnv]:
        return [self.fleets[self.slots[i][0]] for i in self._get_indices(indices)]

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        """The attribute of the fleet each slot belongs to."""
        return [getattr(fleet, attr_name) for fleet in self._targets(indices)]

    def set_attr(self, attr_name: str, value: Any, indices: VecEnvIndices = None) -> None:
        """Set the attribute on the fleets the slots belong to (once per fleet)."""
        for fleet in {id(f): f for f in self._targets(indices)}.values():
            setattr(fleet, attr_name, deepcopy(value))

    def env_method(self, method_name: str, *method_args: Any, indices: VecEnvIndices = None, **method_kwargs: Any) -> list[Any]:
        """Call the method on the fleet of each slot (a fleet with several slots is called once per slot)."""
        return [getattr(fleet, method_name)(*method_args, **method_kwargs) for fleet in self._targets(indices)]

    def env_is_wrapped(self, wrapper_class: type, indices: VecEnvIndices = None) -> list[bool]:
        """Fleets are PettingZoo envs, never wrapped in a Gymnasium wrapper."""
        return [False for _ in self._get_indices(indices)]

    def get_images(self) -> Sequence[np.ndarray | None]:
        return [None for _ in range(self.num_envs)]


__all__ = ["FleetVecEnv"]
