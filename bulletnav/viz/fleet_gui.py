"""A fleet in the PyBullet GUI (:class:`FleetDashboard`): each robot tinted in its colour
(:func:`~bulletnav.viz.fleet_robots.robot_colour`), its current goal marked."""

from __future__ import annotations

import functools
from typing import Any

from bulletnav.viz.dashboard import draw_in_place
from bulletnav.viz.fleet_robots import agent_point, fleet_view, robot_colour, sorted_agents

GOAL_POST_M = 0.9
"""Height (m) of the goal posts in the GUI."""


class FleetDashboard:
    """A fleet in the PyBullet GUI: every robot's body tinted in its colour, a post in its colour
    on its current goal with the robot's number, the errand id and leg above it
    (``2: #7 pick``), and a line from the robot to it.

    Three debug items per robot, created at the first reset and then replaced in place (each is
    a round trip to the GUI's render thread, 80-230 ms to create under Xvfb): a goal's post and
    text when the goal changes, the robot-to-goal lines every ``line_every`` steps. Call
    :meth:`on_reset` after ``env.reset`` and :meth:`on_step` after every step.

    Counters (for tests): ``debug_draw_calls`` (``addUserDebugLine`` calls, replacements
    included), ``tinted`` (robot bodies coloured at the last reset).

    Args:
        env: a fleet env made with ``render_mode="human"``.
        line_every: control steps between redraws of the robot-to-goal lines.
    """

    def __init__(self, env: Any, line_every: int = 12) -> None:
        if getattr(env, "render_mode", None) != "human":
            raise ValueError("FleetDashboard draws in the PyBullet GUI: make the fleet env with render_mode='human'")
        self.env = env
        self.fleet = fleet_view(env)
        self.cid = self.fleet.client
        self.line_every = max(1, int(line_every))
        self.debug_draw_calls = 0
        self.tinted = 0
        self.steps = 0
        self._goals: list[tuple[float, float] | None] = []
        self._line_ids: list[int] = []
        self._post_ids: list[int] = []
        self._text_ids: list[int] = []
        self._builds = -1

    def on_reset(self, infos: dict[str, Any]) -> None:
        import pybullet as p

        fleet = self.fleet
        if fleet.scene_builds != self._builds:  # a rebuilt scene dropped every debug item
            self._line_ids, self._post_ids, self._text_ids = [], [], []
            self._builds = fleet.scene_builds
        self.tinted = 0
        for i in range(fleet.num_robots):
            r, g, b = (c / 255 for c in robot_colour(i))
            p.changeVisualShape(fleet.robot_body(i), -1, rgbaColor=(r, g, b, 1.0), physicsClientId=self.cid)
            self.tinted += 1
        self._goals = [None] * fleet.num_robots
        self.steps = 0
        self._draw(infos, lines=True)
        hx, hy = fleet.layout.half_extents
        cx, cy = fleet.layout.centre
        p.resetDebugVisualizerCamera(1.2 * max(hx, hy) + 2.0, 0.0, -89.0, [cx, cy, 0.0], physicsClientId=self.cid)

    def on_step(self, infos: dict[str, Any]) -> None:
        self.steps += 1
        self._draw(infos, lines=self.steps % self.line_every == 0)

    def _draw(self, infos: dict[str, Any], lines: bool) -> None:
        for i, agent in enumerate(sorted_agents(infos)):
            info = infos[agent]
            goal = agent_point(info["goal"])
            colour = tuple(c / 255 for c in robot_colour(i))
            if goal != self._goals[i]:
                self._goals[i] = goal
                gx, gy = goal
                self._item(self._post_ids, i, (gx, gy, 0.0), (gx, gy, GOAL_POST_M), colour, 4.0)
                errand = info["errand"]
                self._text(i, f"{i}: #{errand['id']} {errand['leg']}", (gx, gy, GOAL_POST_M + 0.15), colour)
                lines = True
            if lines:
                x, y, _ = (float(v) for v in info["pose"])
                self._item(self._line_ids, i, (x, y, 0.25), (goal[0], goal[1], 0.25), colour, 1.5)

    def _item(self, ids: list[int], i: int, a: Any, b: Any, colour: Any, width: float) -> None:
        import pybullet as p

        self.debug_draw_calls += 1
        kwargs = dict(lineColorRGB=colour, lineWidth=width, physicsClientId=self.cid)
        draw_in_place(ids, i, functools.partial(p.addUserDebugLine, a, b, **kwargs))

    def _text(self, i: int, text: str, pos: Any, colour: Any) -> None:
        import pybullet as p

        kwargs = dict(textColorRGB=colour, textSize=1.3, physicsClientId=self.cid)
        draw_in_place(self._text_ids, i, functools.partial(p.addUserDebugText, text, pos, **kwargs))

__all__ = ["GOAL_POST_M", "FleetDashboard"]
