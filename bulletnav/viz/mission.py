"""Multi-goal missions in the pictures: which goals, which were reached, in what order.

A mission episode's ``info`` carries ``goals`` (every goal, in the episode's goal order),
``reached`` and ``reached_at`` (control step each goal was reached at, or None); single-goal
episodes carry no ``goals`` (or one) and are drawn exactly as before. The trajectory plots,
the videos and the GUI dashboard share the helpers here.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any


def mission_goals(info: dict[str, Any] | None, scene: Any = None) -> tuple[tuple[float, float], ...]:
    """The episode's goals when it is a mission of two or more goals, else ``()``.

    Read from ``info["goals"]``, else from ``scene.goals``."""
    goals: Any = None
    if info is not None and info.get("goals") is not None:
        goals = info["goals"]
    elif scene is not None:
        goals = getattr(scene, "goals", None)
    if goals is None or len(goals) < 2:
        return ()
    return tuple((float(g[0]), float(g[1])) for g in goals)


def visit_order(reached_at: Sequence[int | None]) -> list[int | None]:
    """1-based rank in which each goal was reached (by ``reached_at`` step, then goal index);
    None for a goal not reached."""
    done = sorted((step, i) for i, step in enumerate(reached_at) if step is not None)
    order: list[int | None] = [None] * len(reached_at)
    for rank, (_, i) in enumerate(done, start=1):
        order[i] = rank
    return order


def visit_text(rank: int, step: int, control_dt: float) -> str:
    """``#2 @ 31.5 s``: visited second, ``step * control_dt`` seconds into the episode."""
    return f"#{rank} @ {step * control_dt:.1f} s"


def progress_text(reached: int, total: int) -> str:
    """``goals 1/3``."""
    return f"goals {reached}/{total}"
