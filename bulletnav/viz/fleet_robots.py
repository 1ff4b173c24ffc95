"""A fleet's robots as every fleet picture shows them: one colour each, :func:`robot_colour` (a
fixed qualitative palette of 16, :data:`ROBOT_PALETTE`, in robot order), and their infos in
robot order (:func:`sorted_agents`)."""

from __future__ import annotations

from typing import Any

RGB = tuple[int, int, int]

ROBOT_PALETTE: tuple[RGB, ...] = (
    (60, 180, 75), (245, 130, 48), (70, 240, 240), (240, 50, 230), (210, 245, 60), (250, 190, 212),
    (0, 170, 160), (220, 190, 255), (170, 110, 40), (170, 255, 195), (255, 215, 180), (128, 128, 0),
    (145, 30, 180), (0, 130, 200), (255, 225, 25), (230, 25, 75),
)
"""Robot colours (0-255), robot 0 first: a fixed qualitative palette (after Sasha Trubetskoy's
20 distinct colours, without black, white, grey, navy and maroon). None is white, the colour of
the collision-penalty mark; the blues, violets and yellows of the movers come late, red (the
lidar hits' colour in the single-robot video) last, for a 16th robot only."""


def robot_colour(index: int) -> RGB:
    """Robot ``index``'s colour (0-255); the palette repeats after 16."""
    return ROBOT_PALETTE[index % len(ROBOT_PALETTE)]


def _agent_index(agent: str) -> int:
    return int(agent.rsplit("_", 1)[-1])


def sorted_agents(infos: dict[str, Any]) -> list[str]:
    """The agents of ``infos`` in robot order (``robot_0``, ``robot_1``, ..., ``robot_10``)."""
    return sorted(infos, key=_agent_index)


def agent_point(p: Any) -> tuple[float, float]:
    """The (x, y) of a pose or point of an agent's info (m), as floats."""
    return float(p[0]), float(p[1])


def fleet_view(env: Any) -> Any:
    """The read-only :class:`~bulletnav.fleet.view.FleetView` of a fleet env (pictures read nothing else of it)."""
    from bulletnav.fleet.view import FleetView

    return FleetView(env)


__all__ = ["ROBOT_PALETTE", "agent_point", "fleet_view", "robot_colour", "sorted_agents"]
