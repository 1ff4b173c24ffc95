"""Each robot's task in the fleet: the single-robot navigation task toward its current errand leg.

:class:`ErrandTask` is :class:`~bulletnav.tasks.navigation.NavigationTask` (same observation,
same named reward terms and weights, same success radius) with two changes: the goal moves on
when it is reached (pick, then drop, then the next errand's pick) instead of ending the
episode, and the episode never ends early (the fleet truncates every robot together).
The ``collision`` term is paid once per collision the fleet counts (at its first contact),
the ``goal`` term once per leg reached.
"""

from __future__ import annotations

from typing import Any

from bulletnav.fleet.scene import RobotSlot
from bulletnav.tasks.navigation import NavigationTask


class ErrandTask(NavigationTask):
    """Navigation toward a goal that the fleet moves along an errand (see the module docstring)."""

    def begin(self, slot: RobotSlot, start: tuple[float, float, float], goal: tuple[float, float]) -> None:
        """Start the episode of an already placed robot heading for ``goal``."""
        self.goals = ((float(goal[0]), float(goal[1])),)
        self._begin(slot, start, None)

    @property
    def reached(self) -> bool:
        """True when the last step ended within the goal radius of the goal (set by :meth:`reward`)."""
        return self._success

    def set_goal(self, slot: RobotSlot, goal: tuple[float, float]) -> None:
        """Head for ``goal`` from now on: the progress term restarts from the distance to it."""
        self._head_for(slot, goal)
        self._success = False

    def end(self, scene: Any) -> tuple[bool, bool, str | None]:
        """Never: the fleet ends the episode for every robot at once."""
        return False, False, None
