"""The one map between a robot's actions and its commands (:class:`ActionMap`): an action is
(v m/s, w rad/s), or with normalized actions its linear image in [-1, 1]; the single-robot env,
every robot of a fleet and the scene view's :meth:`~bulletnav.envs.scene.SceneView.action_for`
use it."""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
from gymnasium import spaces

from bulletnav.config import TaskConfig


@dataclass(frozen=True)
class ActionMap:
    """Actions <-> commands for one robot."""

    bounds: tuple[float, float, float, float]
    """(v min, v max) m/s and (w min, w max) rad/s of a command."""
    normalize: bool
    """True: actions are [-1, 1] mapped linearly onto ``bounds``; False: the physical pair."""

    @classmethod
    def of(cls, task: TaskConfig, normalize: bool) -> ActionMap:
        """The map of a robot driven at most ``task.max_speed`` forward (and back at down to
        ``task.min_speed``, 0 by default) and ``task.max_turn_rate`` either way."""
        return cls((task.min_speed, task.max_speed, -task.max_turn_rate, task.max_turn_rate), normalize)

    def space(self) -> spaces.Box:
        """The action space: [-1, 1]^2, or the physical command box (float32)."""
        if self.normalize:
            return spaces.Box(-1.0, 1.0, (2,), dtype=np.float32)
        v_lo, v_hi, w_lo, w_hi = self.bounds
        return spaces.Box(np.array([v_lo, w_lo], dtype=np.float32), np.array([v_hi, w_hi], dtype=np.float32),
                          dtype=np.float32)

    def command(self, action: Any) -> tuple[float, float]:
        """The (v m/s, w rad/s) that ``action`` commands, scaled and clipped (:func:`action_command`).

        Raises:
            ValueError: the action is not 2 finite numbers (a dict, a wrong shape, NaN).
        """
        return action_command(action, self.bounds, self.normalize)

    def action(self, v: float, w: float) -> np.ndarray:
        """The action (float32) that commands ``v`` m/s and ``w`` rad/s: the physical pair, or
        with ``normalize`` its linear image in [-1, 1] (not clipped)."""
        if self.normalize:
            v_lo, v_hi, w_lo, w_hi = self.bounds
            v, w = 2.0 * (v - v_lo) / (v_hi - v_lo) - 1.0, 2.0 * (w - w_lo) / (w_hi - w_lo) - 1.0
        return np.array([v, w], dtype=np.float32)


def action_command(action: Any, bounds: tuple[float, float, float, float], normalize: bool) -> tuple[float, float]:
    """The (v m/s, w rad/s) that ``action`` commands: with ``normalize``, [-1, 1] mapped
    linearly onto ``bounds`` = (v min, v max, w min, w max), then clipped to them. The one
    action map of the single-robot env and of every robot of a fleet.

    Raises:
        ValueError: the action is not 2 finite numbers (a dict, a wrong shape, NaN).
    """
    if type(action) is np.ndarray and action.shape == (2,) and action.dtype.kind == "f":
        a0, a1 = action.tolist()  # the common case, fast
    else:
        try:
            with warnings.catch_warnings():  # a complex number inside an object array: refused, not cast
                warnings.simplefilter("error", np.exceptions.ComplexWarning)
                arr = np.asarray(action, dtype=np.float64)
        except (TypeError, ValueError, OverflowError, np.exceptions.ComplexWarning):  # Overflow: an int beyond float64
            arr = None
        if arr is None or arr.shape != (2,) or np.iscomplexobj(action):
            raise ValueError(f"action must be 2 numbers (v, w), got {action!r} of type {type(action).__name__}"
                             f"{'' if arr is None else f' and shape {arr.shape}'}")
        a0, a1 = float(arr[0]), float(arr[1])
    if not (math.isfinite(a0) and math.isfinite(a1)):
        names = [n for n, x in (("v", a0), ("w", a1)) if not math.isfinite(x)]
        raise ValueError(f"action {[a0, a1]} has non-finite entries: {', '.join(names)}")
    v_lo, v_hi, w_lo, w_hi = bounds
    if normalize:  # [-1, 1] -> physical range
        a0 = v_lo + (a0 + 1.0) * 0.5 * (v_hi - v_lo)
        a1 = w_lo + (a1 + 1.0) * 0.5 * (w_hi - w_lo)
    return min(max(a0, v_lo), v_hi), min(max(a1, w_lo), w_hi)


__all__ = ["ActionMap", "action_command"]
