"""Pictures of a fleet episode: a top-down video, a still frame, a path plot and the GUI view.

Every robot keeps one colour everywhere, :func:`robot_colour` (a fixed qualitative palette of
16, :data:`ROBOT_PALETTE`, in robot order), and every picture shows its current errand.

Video frames (:class:`FleetFrames`, 1024 x 768 px, both divisible by 16 so H.264 needs no
resizing)::

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

The path plot (:func:`plot_fleet`) draws every robot's whole path in its colour over the
static map with the stations, each robot's start (hollow circle), end (filled disc), the
points where it completed a leg (pick: triangle, drop: star) and its last errand's goal, and
the movers and events as the single-robot plots draw them
(:func:`bulletnav.viz.plots.draw_mover_tracks`, :func:`bulletnav.viz.plots.draw_events`).

:class:`FleetVisuals` feeds both from :func:`bulletnav.fleet.metrics.run_fleet_episodes`'
``on_step`` hook; :class:`FleetDashboard` tints each robot's body in the PyBullet GUI and marks
its current goal. Everything reads only the agents' ``infos``, the env's ``stations`` and the
read-only :class:`~bulletnav.fleet.view.FleetView`: recording leaves the episodes unchanged.
"""

from __future__ import annotations

import logging
import math
from collections import deque
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image, ImageDraw

from bulletnav.files import save_figure, save_image
from bulletnav.viz.movers import event_text, hex_colour, mover_colour, mover_colours, movers_summary
from bulletnav.viz.plots import (
    MoverTrack,
    draw_layout,
    draw_mover_tracks,
    dynamic_handles,
)
from bulletnav.viz.plots import draw_events as plot_events
from bulletnav.viz.video import (
    BACKGROUND,
    DIM_TEXT,
    EVENT_RGB,
    TEXT,
    MapView,
    VideoWriter,
    category_rgb,
    draw_events,
    draw_movers,
    draw_text,
    label_image,
    mix_colour,
    ui_font,
)

log = logging.getLogger(__name__)

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


def robot_colour(index: int) -> RGB:
    """Robot ``index``'s colour (0-255); the palette repeats after 16."""
    return ROBOT_PALETTE[index % len(ROBOT_PALETTE)]


def _agent_index(agent: str) -> int:
    return int(agent.rsplit("_", 1)[-1])


def _sorted_agents(infos: dict[str, Any]) -> list[str]:
    return sorted(infos, key=_agent_index)


def _point(p: Any) -> tuple[float, float]:
    return float(p[0]), float(p[1])


def _fleet_view(env: Any) -> Any:
    from bulletnav.fleet.view import FleetView

    return FleetView(env)


# ---------------------------------------------------------------------------------- frames
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
        self._labels: dict[tuple[str, RGB, bool], Image.Image] = {}
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
        fleet = self._fleet = _fleet_view(env)
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
        self._trails = [deque([_point(infos[a]["pose"])], maxlen=keep) for a in _sorted_agents(infos)]
        self._infos = infos
        self._base = None

    def update(self, infos: dict[str, Any]) -> None:
        """Take one step's infos (poses for the trails, errands, counts)."""
        for trail, agent in zip(self._trails, _sorted_agents(infos)):
            trail.append(_point(infos[agent]["pose"]))
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
        agents = _sorted_agents(self._infos)
        for i, trail in enumerate(self._trails):
            if len(trail) >= 2:
                draw.line(view.to_px(list(trail)), fill=mix_colour(robot_colour(i), floor, 0.55), width=2, joint="curve")
        ring = max(view.metres(0.3), 5.0)
        for i, agent in enumerate(agents):  # errands: under the movers and robots
            info = self._infos[agent]
            rgb = robot_colour(i)
            errand = info["errand"]
            goal = _point(info["goal"])
            (gx, gy), = view.to_px(goal)
            (rx, ry), = view.to_px(_point(info["pose"]))
            if errand["leg"] == "pick":
                drop = _point(errand["drop"])
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
            (gx, gy), = view.to_px(_point(info["goal"]))
            label = self._label(f"#{errand['id']} {'P' if errand['leg'] == 'pick' else 'D'}", robot_colour(i))
            img.paste(label, (int(gx + ring * 0.7), int(gy - ring * 0.7 - label.height)))
        if self._dynamic:
            draw_movers(draw, view, fleet.movers, self._mover_rgb)
        r = self.robot_radius_px()
        for i, agent in enumerate(agents):  # numbers first: a robot's disc is never hidden by a label
            (cx, cy), = view.to_px(_point(self._infos[agent]["pose"]))
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
        for agent in _sorted_agents(self._infos):
            info = self._infos[agent]
            errand = info["errand"]
            gx, gy = _point(info["goal"])
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

    def _label(self, text: str, colour: RGB = TEXT, small: bool = True) -> Image.Image:
        """``text`` on a background box, rendered once and cached (text is most of a frame's drawing time)."""
        key = (text, colour, small)
        img = self._labels.get(key)
        if img is None:
            img = label_image(text, self._small if small else self._font, colour)
            if len(self._labels) > 256:  # per-step texts would otherwise pile up
                self._labels.clear()
            self._labels[key] = img
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


# ---------------------------------------------------------------------------------- paths
@dataclass
class FleetTrack:
    """One fleet episode as the path plot draws it."""

    layout: Any
    """The episode's :class:`~bulletnav.sim.layout.Layout`."""
    pick: tuple[tuple[float, float], ...]
    """Pick stations (m)."""
    drop: tuple[tuple[float, float], ...]
    """Drop stations (m)."""
    paths: list[list[tuple[float, float]]] = field(default_factory=list)
    """Per robot, its positions (m): at reset, then after every step."""
    starts: list[tuple[float, float, float]] = field(default_factory=list)
    """Per robot, its start pose (x m, y m, yaw rad)."""
    legs: list[list[tuple[str, tuple[float, float]]]] = field(default_factory=list)
    """Per robot, the legs it completed: (``"pick"`` or ``"drop"``, where it was then)."""
    goals: list[tuple[str, int, tuple[float, float]]] = field(default_factory=list)
    """Per robot, its last errand's (leg, id, goal)."""
    errands: list[int] = field(default_factory=list)
    """Per robot, errands completed."""
    movers: list[MoverTrack] = field(default_factory=list)
    """The movers (dynamic worlds), with their poses over the episode."""
    events: list[dict[str, Any]] = field(default_factory=list)
    """The episode's events (dynamic worlds)."""
    duration_s: float = 0.0
    """Simulated seconds recorded."""

    @property
    def dynamic(self) -> bool:
        return bool(self.movers or self.events)


class FleetTrackLog:
    """Records one fleet episode into a :class:`FleetTrack` (``begin`` after the reset, ``update`` after every step)."""

    def __init__(self) -> None:
        self.track: FleetTrack | None = None
        self._fleet: Any = None

    def begin(self, env: Any, infos: dict[str, Any]) -> None:
        fleet = self._fleet = _fleet_view(env)
        stations = env.stations
        agents = _sorted_agents(infos)
        self.track = t = FleetTrack(
            layout=fleet.layout, pick=tuple(stations.pick) if stations else (), drop=tuple(stations.drop) if stations else ())
        for a in agents:
            x, y, yaw = (float(v) for v in infos[a]["pose"])
            t.paths.append([(x, y)])
            t.starts.append((x, y, yaw))
            t.legs.append([])
        self._last(infos)
        if fleet.dynamic:
            t.movers = [MoverTrack(m.kind, tuple(float(v) for v in m.size), tuple(_point(q) for q in m.path))
                        for m in fleet.movers]
            self._record_dynamic()

    def update(self, infos: dict[str, Any]) -> None:
        t = self.track
        for i, a in enumerate(_sorted_agents(infos)):
            info = infos[a]
            xy = _point(info["pose"])
            t.paths[i].append(xy)
            while len(t.legs[i]) < int(info["legs_completed"]):  # legs alternate: pick, drop, pick, ...
                t.legs[i].append(("pick" if len(t.legs[i]) % 2 == 0 else "drop", xy))
        self._last(infos)
        t.duration_s = float(self._fleet.time_s)
        if t.movers or self._fleet.dynamic:
            self._record_dynamic()

    def _last(self, infos: dict[str, Any]) -> None:
        t = self.track
        agents = _sorted_agents(infos)
        t.goals = [(infos[a]["errand"]["leg"], int(infos[a]["errand"]["id"]), _point(infos[a]["goal"])) for a in agents]
        t.errands = [int(infos[a]["errands_completed"]) for a in agents]

    def _record_dynamic(self) -> None:
        t = self.track
        for track, m in zip(t.movers, self._fleet.movers):
            track.poses.append(tuple(float(v) for v in m.pose))  # type: ignore[arg-type]
        events = self._fleet.events
        if len(events) > len(t.events):
            t.events.extend(dict(e) for e in events[len(t.events):])


def fleet_figure(track: FleetTrack, title: str = "", dpi: int = 100) -> Any:
    """The matplotlib ``Figure`` of a fleet episode's paths (see the module docstring); not attached to pyplot."""
    from matplotlib import patheffects
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Circle

    n = len(track.paths)
    if n == 0:
        raise ValueError("plot_fleet: the track holds no robots")
    fig = Figure(figsize=(9.0, 7.0), dpi=dpi, layout="constrained")
    ax = fig.add_subplot()
    draw_layout(ax, track.layout)
    if track.pick:
        xs, ys = zip(*track.pick)
        ax.plot(xs, ys, ls="", marker="D", ms=4, mfc="none", mec="0.45", mew=0.8, zorder=1.5, gid="pick_station")
    if track.drop:
        xs, ys = zip(*track.drop)
        ax.plot(xs, ys, ls="", marker="s", ms=4.5, mfc="0.45", mec="0.45", zorder=1.5, gid="drop_station")
    if track.movers:
        draw_mover_tracks(ax, track.movers, set())
    if track.events:
        plot_events(ax, track.events)
    outline = [patheffects.withStroke(linewidth=3.2, foreground="0.2")]
    handles: list[Any] = []
    for i, points in enumerate(track.paths):
        colour = hex_colour(robot_colour(i))
        xs, ys = zip(*points)
        ax.plot(xs, ys, color=colour, lw=1.8, zorder=3, path_effects=outline, gid=f"robot_{i}_path",
                solid_capstyle="round")
        sx, sy, _ = track.starts[i]
        ax.plot(sx, sy, ls="", marker="o", ms=7, mfc="white", mec=colour, mew=2, zorder=4, gid=f"robot_{i}_start")
        ax.plot(xs[-1], ys[-1], ls="", marker="o", ms=8, mfc=colour, mec="0.15", mew=1, zorder=5, gid=f"robot_{i}_end")
        for leg, (lx, ly) in track.legs[i]:
            ax.plot(lx, ly, ls="", marker="^" if leg == "pick" else "*", ms=8 if leg == "pick" else 11, mfc=colour,
                    mec="0.15", mew=0.7, zorder=4.5, gid=f"robot_{i}_{leg}")
        if i < len(track.goals):
            leg, errand, goal = track.goals[i]
            ax.plot([xs[-1], goal[0]], [ys[-1], goal[1]], color=colour, lw=1.0, ls=(0, (3, 2)), zorder=2.8)
            ax.add_patch(Circle(goal, 0.3, fill=False, edgecolor=colour, lw=1.5, zorder=2.9))
            ax.annotate(f"#{errand} {'P' if leg == 'pick' else 'D'}", goal, xytext=(6, 5), textcoords="offset points",
                        fontsize=7, color="0.1", zorder=4.6,
                        bbox=dict(boxstyle="round,pad=0.15", facecolor=colour, edgecolor="none", alpha=0.8))
        done = track.errands[i] if i < len(track.errands) else 0
        handles.append(Line2D([], [], color=colour, lw=2.5, path_effects=outline,
                              label=f"robot {i}: {done} errand{'' if done == 1 else 's'}"))
    handles += [
        Line2D([], [], ls="", marker="D", ms=5, mfc="none", mec="0.45", label="pick station"),
        Line2D([], [], ls="", marker="s", ms=5, mfc="0.45", mec="0.45", label="drop station"),
        Line2D([], [], ls="", marker="o", ms=7, mfc="white", mec="0.3", mew=2, label="start"),
        Line2D([], [], ls="", marker="o", ms=7, mfc="0.6", mec="0.15", label="end"),
        Line2D([], [], ls="", marker="^", ms=7, mfc="0.6", mec="0.15", label="pick reached"),
        Line2D([], [], ls="", marker="*", ms=10, mfc="0.6", mec="0.15", label="drop reached (errand done)"),
        Line2D([], [], color="0.3", lw=1, ls=(0, (3, 2)), marker="o", ms=8, mfc="none", markevery=[1],
               label="last goal, errand id P/D"),
    ]
    handles += dynamic_handles({m.kind for m in track.movers}, {e["action"] for e in track.events})
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7.5, frameon=False)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    if title:
        ax.set_title(title, fontsize=10)
    return fig


def plot_fleet(track: FleetTrack, path: str | Path, title: str = "", dpi: int = 100) -> Path:
    """Write the PNG of :func:`fleet_figure` (atomically)."""
    return save_figure(fleet_figure(track, title, dpi), path, format="png", dpi=dpi)


# ---------------------------------------------------------------------------------- the hook
class FleetVisuals:
    """Video, still frame and path plot of one episode of :func:`~bulletnav.fleet.metrics.run_fleet_episodes`,
    fed by its ``on_step`` hook (call the object with ``(env, infos)`` after the reset and every step).

    Args:
        video: ``.mp4`` or ``.gif`` of the episode, one frame per ``stride`` control steps (None: none).
        frame: PNG of the frame at ``frame_at_s`` (None: none).
        frame_at_s: simulated seconds into the episode of the still frame (None: half the duration).
        plot: PNG of every robot's path over the episode (None: none).
        episode: which episode of the run (0: the first).
        title: the strip's and the plot's title (e.g. the controller).
        stride: control steps per video frame (>= 1).
        fps: video frames per second (None: the control rate over ``stride``, real time).
    """

    def __init__(self, video: str | Path | None = None, frame: str | Path | None = None,
                 frame_at_s: float | None = None, plot: str | Path | None = None, episode: int = 0,
                 title: str = "", stride: int = 1, fps: float | None = None) -> None:
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        self.video_path = Path(video) if video else None
        self.frame_path = Path(frame) if frame else None
        self.frame_at_s = frame_at_s
        self.plot_path = Path(plot) if plot else None
        self.episode = episode
        self.title = title
        self.stride = stride
        self.fps = fps
        self.frames = FleetFrames(title)
        self.log = FleetTrackLog()
        self.video: VideoWriter | None = None
        self.frame_written_at: float | None = None
        """Simulated time (s) of the still frame written, None before."""
        self._seen = -1
        self._env: Any = None
        self._fleet: Any = None
        self._stamp: int | None = None
        self._steps = 0
        self._active = False
        self._frame_due = math.inf
        self._done = False

    @property
    def frames_written(self) -> int:
        return self.video.frames_written if self.video is not None else 0

    def __call__(self, env: Any, infos: dict[str, Any]) -> None:
        if self._env is not env:
            self._env, self._fleet = env, _fleet_view(env)
        stamp = self._fleet.episode
        if stamp != self._stamp:  # a reset
            self._stamp = stamp
            self._seen += 1
            if self._active:
                self._finish_episode()
            self._active = self._seen == self.episode
            if self._active:
                self._begin(env, infos)
            return
        if not self._active:
            return
        self._steps += 1
        self.frames.update(infos)
        if self.plot_path is not None:
            self.log.update(infos)
        t = self._fleet.time_s
        frame = None
        if self.video is not None and self._steps % self.stride == 0:
            frame = self.frames.compose()
            self.video.append(frame)
        if self.frame_path is not None and self.frame_written_at is None and t >= self._frame_due - 1e-9:
            save_image(frame if frame is not None else self.frames.compose(), self.frame_path, optimize=True)
            self.frame_written_at = t
        if not env.agents:
            self._finish_episode()

    def _begin(self, env: Any, infos: dict[str, Any]) -> None:
        fleet = self._fleet
        duration = float(env.fleet_config.duration_s)
        self._steps = 0
        self.frames.begin(env, infos, f"episode {self.episode}")
        if self.plot_path is not None:
            self.log.begin(env, infos)
        self._frame_due = duration / 2 if self.frame_at_s is None else float(self.frame_at_s)
        if self.video_path is not None:
            fps = self.fps or max(1.0, 1.0 / fleet.control_dt / self.stride)
            self.video = VideoWriter(self.video_path, fps=fps)
            self.video.append(self.frames.compose())
        if self.frame_path is not None and self._frame_due <= 0.0:
            save_image(self.frames.compose(), self.frame_path, optimize=True)
            self.frame_written_at = 0.0

    def _finish_episode(self) -> None:
        self._active = False
        self._done = True

    def close(self, ok: bool = True) -> list[str]:
        """Finish the video and write the plot; with ``ok`` off (the run failed) drop the video and
        write nothing. Returns one line per file written."""
        written: list[str] = []
        if not ok:
            if self.video is not None:
                self.video.abort()
            return written
        if self.video is not None:
            self.video.close()
            written.append(f"video:  {self.video_path} (episode {self.episode}, {self.video.frames_written} frames)")
        if self.frame_path is not None:
            if self.frame_written_at is None:
                log.warning("no still frame written: episode %d ended before %.1f s", self.episode, self._frame_due)
            else:
                written.append(f"frame:  {self.frame_path} (episode {self.episode} at {self.frame_written_at:.1f} s)")
        if self.plot_path is not None and self.log.track is not None:
            title = f"{self.title}, episode {self.episode}" if self.title else f"episode {self.episode}"
            plot_fleet(self.log.track, self.plot_path, title=title)
            written.append(f"plot:   {self.plot_path} (episode {self.episode})")
        return written


# ---------------------------------------------------------------------------------- GUI
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
        self.fleet = _fleet_view(env)
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
        p.resetDebugVisualizerCamera(1.2 * max(hx, hy) + 2.0, 0.0, -89.0, [0.0, 0.0, 0.0], physicsClientId=self.cid)

    def on_step(self, infos: dict[str, Any]) -> None:
        self.steps += 1
        self._draw(infos, lines=self.steps % self.line_every == 0)

    def _draw(self, infos: dict[str, Any], lines: bool) -> None:
        for i, agent in enumerate(_sorted_agents(infos)):
            info = infos[agent]
            goal = _point(info["goal"])
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

        kwargs = dict(lineColorRGB=colour, lineWidth=width, physicsClientId=self.cid)
        self.debug_draw_calls += 1
        if i < len(ids) and ids[i] >= 0:
            new = p.addUserDebugLine(a, b, replaceItemUniqueId=ids[i], **kwargs)
            if new >= 0:
                ids[i] = new
                return
        new = p.addUserDebugLine(a, b, **kwargs)
        while len(ids) <= i:
            ids.append(-1)
        ids[i] = new

    def _text(self, i: int, text: str, pos: Any, colour: Any) -> None:
        import pybullet as p

        kwargs = dict(textColorRGB=colour, textSize=1.3, physicsClientId=self.cid)
        if i < len(self._text_ids) and self._text_ids[i] >= 0:
            new = p.addUserDebugText(text, pos, replaceItemUniqueId=self._text_ids[i], **kwargs)
            if new >= 0:
                self._text_ids[i] = new
                return
        new = p.addUserDebugText(text, pos, **kwargs)
        while len(self._text_ids) <= i:
            self._text_ids.append(-1)
        self._text_ids[i] = new


__all__ = ["FLEET_FRAME_SIZE", "FLEET_MAP_PX", "ROBOT_PALETTE", "FleetDashboard", "FleetFrames", "FleetTrack",
           "FleetTrackLog", "FleetVisuals", "fleet_figure", "plot_fleet", "robot_colour"]
