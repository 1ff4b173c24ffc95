"""Random commands: the careless controller a safety shield is tried against.

:class:`RandomCommands` drives with a new command drawn uniformly from the robot's whole command
range (``scene.command_limits``: forward speed and yaw rate, reverse where the env allows it)
every ``hold`` control steps. It knows nothing of obstacles: alone it collides at once in a
cluttered world, and behind the shield (``shield: true`` in a suite, ``--shield`` on the command
line) every collision it has is one the shield let through. ``bulletnav benchmark shield-random``
runs it on BARN's Jackal and every warehouse id.
"""

from __future__ import annotations

from typing import Any

import numpy as np


class RandomCommands:
    """A :class:`~bulletnav.policy.Policy` that holds a uniformly drawn (v, w) for ``hold`` steps.

    The numbers come from a generator seeded by ``(seed, the episode's start pose and goal)``,
    so the same episode gets the same commands whatever ran before it, and every episode its own.

    Args:
        scene: ``env.unwrapped.scene`` of the env it drives (its command limits and action map).
        hold: control steps each command is held (8: a third of a second at 24 Hz).
        seed: first word of every episode's generator seed.
    """

    def __init__(self, scene: Any, hold: int = 8, seed: int = 0) -> None:
        if isinstance(hold, bool) or not isinstance(hold, int) or hold < 1:
            raise ValueError(f"hold must be an integer >= 1 (control steps), got {hold!r}")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            raise ValueError(f"seed must be an integer >= 0, got {seed!r}")
        self.scene = scene
        self.hold = hold
        self.seed = seed
        self._rng = np.random.default_rng(seed)
        self._left = 0
        self._action = np.zeros(2, dtype=np.float32)

    def reset(self, info: dict[str, Any]) -> None:
        pose = np.asarray(info["pose"], dtype=np.float64)[:3]
        goal = np.asarray(info["goal"], dtype=np.float64)[:2]
        words = np.frombuffer(np.concatenate([pose, goal]).tobytes(), dtype=np.uint32)
        self._rng = np.random.default_rng([self.seed, *words.tolist()])
        self._left = 0

    def act(self, obs: Any, info: dict[str, Any]) -> np.ndarray:
        if self._left == 0:
            (v_lo, v_hi), (w_lo, w_hi) = self.scene.command_limits
            v = float(self._rng.uniform(v_lo, v_hi))
            w = float(self._rng.uniform(w_lo, w_hi))
            self._action = self.scene.action_for(v, w)
            self._left = self.hold
        self._left -= 1
        return self._action.copy()
