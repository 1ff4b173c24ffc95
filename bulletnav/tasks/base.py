"""The task interface (dm_control's split): what an episode asks of the robot.

A task turns the scene into an observation, a reward made of named terms and an episode
end; it also chooses where each episode starts. The env calls, every step::

    scene.step(v, w) -> task.after_step(scene) -> task.reward(scene) -> task.end(scene)
                     -> task.observe(scene) -> task.info(scene)

and at every reset ``task.initialize_episode(scene, rng, options)`` (which places the
robot with ``scene.place_robot``) and then ``observe`` and ``info``.

A task sees the scene only through :class:`~bulletnav.tasks.view.TaskScene`, a read-only
protocol below both packages: ``bulletnav.envs`` imports the tasks, never the other way.

Add a task by writing one module with a :class:`Task` subclass and registering it with
:func:`bulletnav.tasks.register_task`; see ``docs/architecture.md``.
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING, Any, ClassVar

import numpy as np
from gymnasium import spaces

from bulletnav.config import EnvConfig

if TYPE_CHECKING:
    from bulletnav.tasks.view import TaskScene


class Task(ABC):
    """One kind of episode on a scene: observation, named reward terms, episode end.

    Args:
        config: the env configuration (tasks read their settings from it).
        scene: the scene the task will run on (for spaces that depend on its sensors).
    """

    reward_terms: ClassVar[tuple[str, ...]] = ()
    """Names of the reward terms; ``info`` carries each as ``reward_<name>``."""

    def __init__(self, config: EnvConfig, scene: TaskScene) -> None:
        self.config = config
        self.goals: tuple[tuple[float, float], ...] = ()
        """The episode's goal points (m), in the task's order; empty for goal-free tasks."""

    @property
    def goal(self) -> tuple[float, float] | None:
        """The goal the robot is heading for now (None for goal-free tasks)."""
        return self.goals[0] if self.goals else None

    @abstractmethod
    def observation_space(self) -> spaces.Space:
        """The space of :meth:`observe`'s value."""

    @abstractmethod
    def initialize_episode(self, scene: TaskScene, rng: np.random.Generator, options: dict[str, Any]) -> None:
        """Choose the episode (start, goals) with ``rng`` and ``options`` and place the robot
        with ``scene.place_robot``. The scene's layout is already chosen."""

    def after_step(self, scene: TaskScene) -> None:  # noqa: B027 (an optional hook)
        """Read what the other hooks of this step need (once, after physics)."""

    @abstractmethod
    def observe(self, scene: TaskScene) -> Any:
        """The observation of the current state (a fresh array or dict of arrays)."""

    @abstractmethod
    def reward(self, scene: TaskScene) -> dict[str, float]:
        """Named reward terms of the step just taken (the env's reward is their sum)."""

    @abstractmethod
    def end(self, scene: TaskScene) -> tuple[bool, bool, str | None]:
        """``(terminated, truncated, reason)`` after the step; reason is None while running."""

    def info(self, scene: TaskScene) -> dict[str, Any]:
        """The task's entries of ``info`` (the env adds the reward terms and ``end_reason``)."""
        return {}


def pose_option(value: Any, n: int, name: str) -> tuple[float, ...]:
    """``options[name]`` as ``n`` finite floats.

    Raises:
        ValueError: not ``n`` finite numbers (the message names the option).
    """
    try:
        out = tuple(float(v) for v in value)
    except (TypeError, ValueError, OverflowError):  # OverflowError: an int beyond float64
        raise ValueError(f"options[{name!r}] must be {n} numbers, got {value!r}") from None
    if len(out) != n or not all(math.isfinite(v) for v in out):
        raise ValueError(f"options[{name!r}] must be {n} finite numbers, got {value!r}")
    return out
