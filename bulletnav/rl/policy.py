"""Adapter from a Stable-Baselines3 model to the :class:`~bulletnav.policy.Policy` protocol."""

from __future__ import annotations

from typing import Any

import numpy as np


class SB3Policy:
    """A trained SB3 model (and its ``VecNormalize`` statistics, if any) as a policy.

    Args:
        model: any SB3 model with ``predict``.
        vecnorm: the ``VecNormalize`` it was trained behind (observations are normalised
            with its statistics when it normalised them), or None.
        deterministic: act with the distribution's mode (evaluation) instead of sampling.
    """

    def __init__(self, model: Any, vecnorm: Any = None, deterministic: bool = True) -> None:
        self.model = model
        self.vecnorm = vecnorm
        self.deterministic = deterministic

    def reset(self, info: dict[str, Any]) -> None:
        """Nothing to prepare: the policies here are memoryless."""

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        if self.vecnorm is not None and getattr(self.vecnorm, "norm_obs", False):
            obs = self.vecnorm.normalize_obs(obs)
        action, _ = self.model.predict(obs, deterministic=self.deterministic)
        return action
