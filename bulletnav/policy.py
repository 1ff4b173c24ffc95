"""The one policy protocol every controller implements, classical or learned.

Evaluation, ``navigate``, ``evaluate``, ``demo`` and the dashboard drive any object with
these two methods through one code path (:func:`bulletnav.evaluation.run_episodes`)::

    obs, info = env.reset(seed=s)
    policy.reset(info)
    while not done:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs, info))

A policy sees only what the env hands out: ``obs``, ``info`` and, if it was given one at
construction, the read-only ``env.unwrapped.scene`` view. Implementations:
:class:`bulletnav.control.navigator.Navigator` (PID + A*/RRT) and
:class:`bulletnav.rl.policy.SB3Policy` (any Stable-Baselines3 model).
"""

from __future__ import annotations

from typing import Any, Protocol, runtime_checkable

import numpy as np


@runtime_checkable
class Policy(Protocol):
    """A controller: ``reset(info)`` at each episode start, ``act(obs, info)`` every step."""

    def reset(self, info: dict[str, Any]) -> None:
        """Prepare for the episode whose first ``info`` (from ``env.reset``) this is."""

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        """The action for observation ``obs`` with the ``info`` of the same step."""
        ...
