"""Top-down video frames of a fleet episode (:class:`FleetFrames`): 1024 x 768 px, both
divisible by 16 so H.264 needs no resizing::

    +------------------------------------+---------------------+
    | top-down map 720 x 720             | one row per robot:  |
    | (static layout, stations, mover    | colour, errand id,  |
    |  routes cached; trails, errands,   | leg, goal, errands  |
    |  movers, events, robots)           | and legs done;      |
    |                                    | legend below        |
    +------------------------------------+---------------------+
    | text strip 1024 x 48: episode, time, fleet totals, world, movers, latest event |
    +--------------------------------------------------------------------------------+

On the map: pick stations (hollow grey diamonds) and drop stations (filled grey squares);
each robot as a disc in its colour with a dark heading line and its number beside it, inside a
white octagon while it serves a collision penalty; its trail over the last ``trail_s`` seconds
(solid); a thin pale dotted "to goal" line, straight from the robot to its current goal (where
the goal is, not the way there: it crosses racks), that goal a ring with a cross in the robot's
colour, labelled with the errand id and leg (``#12 P`` going to pick, ``#12 D`` going to drop)
and, on a pick leg, a fainter dotted line on to the errand's drop station (a small hollow
square). Movers and events are drawn as in the single-robot video
(:func:`bulletnav.viz.video.draw_movers`, :func:`bulletnav.viz.video.draw_events`). The legend
under the robot rows shows every one of these marks as the map draws it. Text is drawn with
spaces a third of the font size wide (:func:`bulletnav.viz.video.draw_text`).
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from bulletnav.viz.fleet_robots import RGB, agent_point, fleet_view, robot_colour, sorted_agents
from bulletnav.viz.movers import event_text, mover_colour, mover_colours, movers_summary
from bulletnav.viz.video import (
    BACKGROUND,
    DIM_TEXT,
    EVENT_RGB,
    TEXT,
    LabelCache,
    MapView,
    category_rgb,
    draw_events,
    draw_movers,
    draw_text,
    mix_colour,
    ui_font,
)

FLEET_FRAME_SIZE = (1024, 768)
"""Composed frame (width, height) in pixels."""
FLEET_MAP_PX = 720
"""Side of the square top-down map panel (px)."""
STRIP_H = FLEET_FRAME_SIZE[1] - FLEET_MAP_PX
"""Height of the text strip under the map (px)."""
PICK_RGB: RGB = (150, 154, 162)
"""Pick stations: hollow diamonds."""
DROP_RGB: RGB = (200, 204, 212)
"""Drop stations (the dock): filled squares."""
STOPPED_RGB: RGB = (255, 255, 255)
"""The octagon (a stop sign's outline) around a robot serving a collision penalty: white, a colour
no robot has, and a shape no goal has (goals are round, in their robot's colour)."""
TO_GOAL_SHARE = 0.7
"""How much of a robot's colour its "to goal" line takes (the rest: the floor's): thinner and
paler than the trail, dotted, a straight line that says where the goal is, not a path."""
TRAIL_S = 15.0
"""Seconds of trail drawn behind each robot in the video."""


class FleetFrames:
    """Composes top-down frames of a fleet episode (see the module docstring).

    Call :meth:`begin` after ``env.reset``, :meth:`update` after every ``env.step``, and
    :meth:`compose` for a frame of the current state.

    Args:
        title: what the strip's second line starts with (e.g. the controller).
        trail_s: seconds of trail behind each robot.
    """

    def __init__(self, title: str = "", trail_s: float = TRAIL_S) -> None:
        self.title = title
        self.trail_s = float(trail_s)
        self.frame_size: tuple[int, int] = FLEET_FRAME_SIZE
        """(width, height) of every frame (px)."""
        self.view: MapView | None = None
        """The map transform of the current episode (world m -> map px, map at the frame's top left)."""
        self.last_frame: np.ndarray | None = None
        """The most recent composed frame, (H, W, 3) uint8."""
        self._font = ui_font(13)
        self._small = ui_font(11)
        self._label = LabelCache(self._font, self._small, 256)  # per-step texts would otherwise pile up
        self._maps: dict[Any, tuple[MapView, Image.Image]] = {}
        self._layer: Image.Image | None = None
        self._fleet: Any = None
        self._infos: dict[str, Any] = {}
        self._trails: list[deque[tuple[float, float]]] = []
        self._mover_rgb: list[RGB] = []
        self._events_drawn = 0
        self._event_text = "none"
        self._dynamic = False
        self._base: Image.Image | None = None
        self.episode_label = ""
        """The strip's episode name, e.g. ``episode 0 (seed 7)``."""

    # ------------------------------------------------------------------ state
    def begin(self, env: Any, infos: dict[str, Any], episode_label: str = "") -> None:
        """Start an episode: draw its static layer (map, stations, mover routes)."""
        fleet = self._fleet = fleet_view(env)
        self.episode_label = episode_label
        layout = fleet.layout
        if layout not in self._maps:
            view = MapView(layout, size=FLEET_MAP_PX)
            self._maps = {layout: (view, view.render_static())}  # the fleet keeps one layout at a time
        self.view, static = self._maps[layout]
        layer = static.copy()
        draw = ImageDraw.Draw(layer)
        stations = env.stations
        if stations is not None:
            s = max(self.view.metres(0.12), 3.0)
            for x, y in self.view.to_px(stations.pick):
                draw.polygon([(x, y - s), (x + s, y), (x, y + s), (x - s, y)], outline=PICK_RGB, width=1)
            for x, y in self.view.to_px(stations.drop):
                draw.rectangle((x - s * 0.8, y - s * 0.8, x + s * 0.8, y + s * 0.8), fill=DROP_RGB)
        self._dynamic = bool(fleet.dynamic)
        movers = fleet.movers
        self._mover_rgb = mover_colours(m.kind for m in movers)
        floor = category_rgb("floor")
        for m, rgb in zip(movers, self._mover_rgb):
            if len(m.path) >= 2:  # routes are fixed for the episode
                draw.line(self.view.to_px(m.path), fill=mix_colour(rgb, floor, 0.7), width=1)
        self._layer = layer
        self._events_drawn = 0
        self._event_text = "none"
        keep = max(2, int(round(self.trail_s / fleet.control_dt)) + 1)
        self._trails = [deque([agent_point(infos[a]["pose"])], maxlen=keep) for a in sorted_agents(infos)]
        self._infos = infos
        self._base = None

    def update(self, infos: dict[str, Any]) -> None:
        """Take one step's infos (poses for the trails, errands, counts)."""
        for trail, agent in zip(self._trails, sorted_agents(infos)):
            trail.append(agent_point(infos[agent]["pose"]))
        self._infos = infos

    # ------------------------------------------------------------------ drawing
    def compose(self) -> np.ndarray:
        """The frame of the current state, (H, W, 3) uint8."""
        if self._layer is None or self.view is None:
            raise RuntimeError("FleetFrames.begin() must be called first")
        fleet, view = self._fleet, self.view
        if self._dynamic:
            events = fleet.events
            if len(events) > self._events_drawn:  # they stay for the episode: drawn into its layer
                draw_events(ImageDraw.Draw(self._layer), view, events[self._events_drawn:])
                self._events_drawn = len(events)
                self._event_text = event_text(events[-1])
        if self._base is None:
            self._base = self._render_base(len(self._trails))
        frame = self._base.copy()
        frame.paste(self._map(fleet, view), (0, 0))
        self._side(frame)
        self._strip(frame, fleet)
        out = np.asarray(frame, dtype=np.uint8)
        self.last_frame = out
        return out

    def robot_radius_px(self) -> float:
        """A robot's disc radius on the map (px)."""
        return max(self.view.metres(self._fleet.geometry.radius), 3.0)

    def _map(self, fleet: Any, view: MapView) -> Image.Image:
        img = self._layer.copy()
        draw = ImageDraw.Draw(img)
        floor = category_rgb("floor")
        agents = sorted_agents(self._infos)
        for i, trail in enumerate(self._trails):
            if len(trail) >= 2:
                draw.line(view.to_px(list(trail)), fill=mix_colour(robot_colour(i), floor, 0.55), width=2, joint="curve")
        ring = max(view.metres(0.3), 5.0)
        for i, agent in enumerate(agents):  # errands: under the movers and robots
            info = self._infos[agent]
            rgb = robot_colour(i)
            errand = info["errand"]
            goal = agent_point(info["goal"])
            (gx, gy), = view.to_px(goal)
            (rx, ry), = view.to_px(agent_point(info["pose"]))
            if errand["leg"] == "pick":
                drop = agent_point(errand["drop"])
                (dx, dy), = view.to_px(drop)
                faint = mix_colour(rgb, floor, 0.4)
                _dashed(draw, (gx, gy), (dx, dy), faint, width=1, dash=2.0, gap=6.0)
                s = max(view.metres(0.15), 3.0)
                draw.rectangle((dx - s, dy - s, dx + s, dy + s), outline=faint, width=1)
            _dashed(draw, (rx, ry), (gx, gy), mix_colour(rgb, floor, TO_GOAL_SHARE), width=1, dash=3.0, gap=4.0)
            _goal_mark(draw, (gx, gy), ring, rgb)
        for i, agent in enumerate(agents):  # goal labels over every goal line
            info = self._infos[agent]
            errand = info["errand"]
            (gx, gy), = view.to_px(agent_point(info["goal"]))
            label = self._label(f"#{errand['id']} {'P' if errand['leg'] == 'pick' else 'D'}", robot_colour(i))
            img.paste(label, (int(gx + ring * 0.7), int(gy - ring * 0.7 - label.height)))
        if self._dynamic:
            draw_movers(draw, view, fleet.movers, self._mover_rgb)
        r = self.robot_radius_px()
        for i, agent in enumerate(agents):  # numbers first: a robot's disc is never hidden by a label
            (cx, cy), = view.to_px(agent_point(self._infos[agent]["pose"]))
            number = self._label(str(i), robot_colour(i))
            img.paste(number, (int(cx + r + 1), int(cy - r - number.height + 2)))
        for i, agent in enumerate(agents):
            info = self._infos[agent]
            x, y, yaw = (float(v) for v in info["pose"])
            (cx, cy), = view.to_px((x, y))
            if info.get("stopped_s", 0.0) > 0.0:
                draw.polygon(_octagon((cx, cy), r + 5), outline=STOPPED_RGB, width=2)
            draw.ellipse((cx - r, cy - r, cx + r, cy + r), fill=robot_colour(i), outline=BACKGROUND, width=1)
            tip = (cx + r * math.cos(yaw), cy - r * math.sin(yaw))
            draw.line(((cx, cy), tip), fill=BACKGROUND, width=2)
        return img

    def _side(self, frame: Image.Image) -> None:
        """One row per robot: errand, leg, goal, errands and legs done, penalty."""
        x0 = FLEET_MAP_PX + 10
        y = 30
        row = self._row_height(len(self._trails))
        for agent in sorted_agents(self._infos):
            info = self._infos[agent]
            errand = info["errand"]
            gx, gy = agent_point(info["goal"])
            leg = "pick" if errand["leg"] == "pick" else "drop"
            line1 = f"#{errand['id']:<3d} {leg} ({gx:+5.1f}, {gy:+5.1f})"
            frame.paste(self._label(line1, TEXT), (x0 + 38, y))
            errands, legs = int(info["errands_completed"]), int(info["legs_completed"])
            line2 = f"{errands} errand{'' if errands == 1 else 's'}, {legs} leg{'' if legs == 1 else 's'}"
            stopped = float(info.get("stopped_s", 0.0))
            frame.paste(self._label(line2, DIM_TEXT), (x0 + 38, y + 14))
            if stopped > 0.0:
                frame.paste(self._label(f"stopped {stopped:3.1f} s", STOPPED_RGB), (x0 + 180, y + 14))
            y += row

    def _strip(self, frame: Image.Image, fleet: Any) -> None:
        infos = self._infos.values()
        total = lambda key: sum(int(info[key]) for info in infos)  # noqa: E731
        t = float(fleet.time_s)
        line1 = (f"{self.episode_label}   t {t:6.1f} s   errands {total('errands_completed')}   "
                 f"legs {total('legs_completed')}   collisions: robot {total('collisions_robot')}  static "
                 f"{total('collisions_static')}  mover {total('collisions_mover')}  person {total('collisions_person')}")
        draw_text(ImageDraw.Draw(frame), (10, FLEET_MAP_PX + 6), line1, self._font, TEXT)
        name = fleet.layout.name or "layout"
        line2 = f"{self.title + '   ' if self.title else ''}{len(self._trails)} robots   {name}"
        if self._dynamic:
            line2 += (f"   movers: {movers_summary(m.kind for m in fleet.movers)}   "
                      f"last event: {self._event_text}")
        draw_text(ImageDraw.Draw(frame), (10, FLEET_MAP_PX + 26), line2, self._small, DIM_TEXT)

    def _row_height(self, n: int) -> int:
        return 32 if n <= 14 else 29  # 16 rows of 29 px leave the legend's 11 entries room

    def _render_base(self, n: int) -> Image.Image:
        """What stays the same for the episode: background, robot swatches, legend."""
        img = Image.new("RGB", FLEET_FRAME_SIZE, BACKGROUND)
        draw = ImageDraw.Draw(img)
        x0 = FLEET_MAP_PX + 10
        draw_text(draw, (x0, 8), "robots: current errand", self._font, TEXT)
        y = 30
        row = self._row_height(n)
        for i in range(n):
            rgb = robot_colour(i)
            draw.ellipse((x0, y + 3, x0 + 20, y + 23), fill=rgb, outline=BACKGROUND)
            draw_text(draw, (x0 + 24, y + 6), str(i), self._small, TEXT)
            y += row
        y += 6
        entries: list[tuple[str, RGB, str]] = [
            ("pick station", PICK_RGB, "diamond"), ("drop station (dock)", DROP_RGB, "square"),
            ("robot (its colour), heading", DIM_TEXT, "robot"), (f"trail, last {self.trail_s:g} s", DIM_TEXT, "trail"),
            ("goal, errand id, P/D leg", DIM_TEXT, "goal"), ("to goal (straight, not a path)", DIM_TEXT, "to_goal"),
            ("then to its drop (pick leg)", DIM_TEXT, "hollow"),
            ("collision penalty (stopped)", STOPPED_RGB, "octagon"),
        ]
        if self._dynamic:
            entries += [("forklift", mover_colour("forklift", 0), "fill"), ("worker", mover_colour("worker", 0), "fill"),
                        ("event (add / remove)", EVENT_RGB, "fill")]
        for name, rgb, shape in entries:
            if y > FLEET_MAP_PX - 16:
                break
            _legend_swatch(draw, shape, x0, y, rgb)
            draw_text(draw, (x0 + 24, y + 2), name, self._small, TEXT)
            y += 18
        draw.line((0, FLEET_MAP_PX, FLEET_FRAME_SIZE[0], FLEET_MAP_PX), fill=(60, 64, 70))
        draw.line((FLEET_MAP_PX, 0, FLEET_MAP_PX, FLEET_MAP_PX), fill=(60, 64, 70))
        return img


def _dashed(draw: ImageDraw.ImageDraw, a: tuple[float, float], b: tuple[float, float], fill: RGB, width: int,
            dash: float, gap: float | None = None) -> None:
    """A dashed line from ``a`` to ``b`` (px): dashes of ``dash`` px, gaps of ``gap`` (default ``dash``)."""
    length = math.dist(a, b)
    if length < 1e-6:
        return
    gap = dash if gap is None else gap
    ux, uy = (b[0] - a[0]) / length, (b[1] - a[1]) / length
    s = 0.0
    while s < length:
        e = min(s + dash, length)
        draw.line(((a[0] + ux * s, a[1] + uy * s), (a[0] + ux * e, a[1] + uy * e)), fill=fill, width=width)
        s += dash + gap


def _octagon(centre: tuple[float, float], r: float) -> list[tuple[float, float]]:
    """The corners (px) of a regular octagon of circumradius ``r`` with flat top and bottom (a stop sign)."""
    cx, cy = centre
    return [(cx + r * math.cos(math.pi / 8 + k * math.pi / 4), cy + r * math.sin(math.pi / 8 + k * math.pi / 4))
            for k in range(8)]


def _goal_mark(draw: ImageDraw.ImageDraw, centre: tuple[float, float], r: float, rgb: RGB) -> None:
    """A goal: a ring in its robot's colour with a cross through its centre (round, unlike the
    collision octagon; hollow, unlike the robots' filled discs)."""
    gx, gy = centre
    draw.ellipse((gx - r, gy - r, gx + r, gy + r), outline=rgb, width=2)
    k = r * 0.45
    draw.line(((gx - k, gy), (gx + k, gy)), fill=rgb, width=1)
    draw.line(((gx, gy - k), (gx, gy + k)), fill=rgb, width=1)


def _legend_swatch(draw: ImageDraw.ImageDraw, shape: str, x0: float, y: float, rgb: RGB) -> None:
    """The legend's 16 px sample of a mark, drawn as the map draws it."""
    box = (x0 + 4, y + 3, x0 + 14, y + 13)
    if shape == "diamond":
        draw.polygon([(x0 + 9, y + 2), (x0 + 15, y + 8), (x0 + 9, y + 14), (x0 + 3, y + 8)], outline=rgb)
    elif shape == "goal":
        _goal_mark(draw, (x0 + 9, y + 8), 7, rgb)
    elif shape == "octagon":
        draw.polygon(_octagon((x0 + 9, y + 8), 8), outline=rgb, width=2)
    elif shape == "robot":
        draw.ellipse((x0 + 3, y + 2, x0 + 15, y + 14), fill=rgb, outline=BACKGROUND)
        draw.line(((x0 + 9, y + 8), (x0 + 15, y + 8)), fill=BACKGROUND, width=2)
    elif shape == "trail":
        draw.line(((x0, y + 8), (x0 + 18, y + 8)), fill=mix_colour(rgb, category_rgb("floor"), 0.55), width=2)
    elif shape == "to_goal":
        _dashed(draw, (x0, y + 8), (x0 + 18, y + 8), mix_colour(rgb, category_rgb("floor"), TO_GOAL_SHARE), width=1,
                dash=3.0, gap=4.0)
    elif shape == "hollow":
        draw.rectangle(box, outline=rgb)
    else:
        draw.rectangle(box, fill=rgb)


__all__ = ["DROP_RGB", "FLEET_FRAME_SIZE", "FLEET_MAP_PX", "PICK_RGB", "STOPPED_RGB", "FleetFrames"]
