"""Tasks: observation, reward and episode end on a scene. One module per task.

``TASKS`` maps a name (``EnvConfig.task_name``) to its class; :func:`register_task` adds one.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from bulletnav.config import EnvConfig
from bulletnav.tasks.base import Task
from bulletnav.tasks.mission import MissionTask
from bulletnav.tasks.navigation import NavigationTask

if TYPE_CHECKING:
    from bulletnav.tasks.view import TaskScene

TASKS: dict[str, type[Task]] = {}


def register_task(name: str, cls: type[Task]) -> None:
    """Make ``cls`` available as ``task_name=name``.

    Raises:
        ValueError: ``name`` is taken by another class.
    """
    if TASKS.get(name, cls) is not cls:
        raise ValueError(f"task name {name!r} is already registered to {TASKS[name].__qualname__}")
    TASKS[name] = cls


def make_task(config: EnvConfig, scene: TaskScene) -> Task:
    """The task ``config.task_name`` on ``scene``.

    Raises:
        ValueError: no task of that name (the message lists the registered ones).
    """
    try:
        cls = TASKS[config.task_name]
    except KeyError:
        raise ValueError(f"unknown task_name {config.task_name!r}; registered: {', '.join(sorted(TASKS))}") from None
    return cls(config, scene)


register_task("navigation", NavigationTask)
register_task("mission", MissionTask)

__all__ = ["TASKS", "MissionTask", "NavigationTask", "Task", "make_task", "register_task"]
