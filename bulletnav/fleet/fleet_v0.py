"""``fleet_v0``: the multi-robot warehouse as PettingZoo envs (the module layout PettingZoo's own envs use).

>>> from bulletnav.fleet import fleet_v0
>>> env = fleet_v0.parallel_env(num_robots=4)   # ParallelEnv
>>> aec = fleet_v0.env(num_robots=4)            # AECEnv, through PettingZoo's converter
"""

from __future__ import annotations

from typing import Any

from pettingzoo.utils.conversions import parallel_to_aec

from bulletnav.fleet.env import FleetEnv


def parallel_env(**kwargs: Any) -> FleetEnv:
    """A :class:`~bulletnav.fleet.env.FleetEnv` (keyword arguments as its docstring lists)."""
    return FleetEnv(**kwargs)


def raw_env(**kwargs: Any):
    """The fleet as an AEC env (agents act in turn; one physics step per full cycle)."""
    return parallel_to_aec(FleetEnv(**kwargs))


env = raw_env

__all__ = ["FleetEnv", "env", "parallel_env", "raw_env"]
