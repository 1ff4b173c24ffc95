"""A learned policy shared by every robot of a fleet, acting for all of them in one forward pass.

:class:`SharedPolicyController` is what ``bulletnav fleet --controller policy`` runs, for a
single-robot model zero-shot (``models/ppo_dynamic.zip``) and for one fine-tuned in the fleet
(``models/ppo_fleet.zip``, :mod:`bulletnav.fleet.training`) alike: the robots' observations
are stacked into one batch, normalised with the model's statistics when it normalised them,
and ``predict`` runs once per control step instead of once per robot.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np


class SharedPolicyController:
    """One SB3 model acting for every agent at once (a fleet controller).

    Args:
        model: any SB3 model with ``predict`` (it takes a batch of observations).
        normalizer: what normalises observations as the model's ``VecNormalize`` did
            (``norm_obs``, ``normalize_obs``), or None.
        agents: the fleet's agents, in the order their rows go into the batch.
        deterministic: act with the distribution's mode (evaluation) instead of sampling.
    """

    def __init__(self, model: Any, normalizer: Any, agents: Sequence[str], deterministic: bool = True) -> None:
        self.model = model
        self.normalizer = normalizer
        self.agents = list(agents)
        self.deterministic = deterministic
        self.forward_passes = 0
        """``predict`` calls so far (one per :meth:`act`)."""

    def reset(self, infos: dict[str, dict[str, Any]]) -> None:
        """Nothing to prepare: the policy is memoryless."""

    def act(self, observations: dict[str, Any], infos: dict[str, dict[str, Any]]) -> dict[str, np.ndarray]:
        """Every agent's action from one ``predict`` over the stacked observations."""
        agents = [a for a in self.agents if a in observations]
        if not agents:
            return {}
        batch = np.stack([np.asarray(observations[a]) for a in agents])
        if self.normalizer is not None and getattr(self.normalizer, "norm_obs", False):
            batch = self.normalizer.normalize_obs(batch)
        actions, _ = self.model.predict(batch, deterministic=self.deterministic)
        self.forward_passes += 1
        return {a: actions[i] for i, a in enumerate(agents)}


__all__ = ["SharedPolicyController"]
