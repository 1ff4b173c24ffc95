"""A throttled live dashboard in the PyBullet GUI (``render_mode="human"``).

Everything drawn in the GUI is a round trip to its render thread, and under a software
renderer (Xvfb, no GPU) those are slow. Measured on a busy 2-core machine: adding a debug
line 80-230 ms (it waits for a GUI frame), replacing one in place 4-15 ms, a 320 x 240
``getCameraImage`` 100-480 ms. Hence three rules: draw only every few control steps, draw a
subset of the lidar rays, and never add a debug item per step -- items are created once and
then moved with ``replaceItemUniqueId``.

Dynamic worlds (``scene.dynamic``): the movers are PyBullet bodies, so the GUI shows them
already; the dashboard adds each mover's route as debug lines (one shade per mover:
forklifts yellow-amber, workers blue-violet), drawn once per reset, and a text message at
each event (``+ label (t s)`` over an added obstacle, ``- label (t s)`` over a removed one),
read from ``scene.events`` on the step it happens, and one line of the episode's safety
metrics above the robot (nearest mover, smallest separation so far, near-miss share of
steps, as evaluation counts them), updated with the lidar rays. Events are rare, and their messages
reuse a ring of :data:`EVENT_TEXTS` text items. Static worlds draw exactly what they did.
Behind the safety shield (``info["shield"]`` given to :meth:`Dashboard.on_step`), the same
line, in any world, adds the share of steps on which the shield replaced the command and its
mean change in wheel speeds.

Multi-goal missions (``scene.goals`` holds two or more goals): a marker (post and cross) for
every goal, with its number (1..K in the episode's goal order) above it, coloured by state
(current target bright green, reached blue and ``n done``, the others pale), and one progress
text over the current target, ``goals 1/3``. All are created at reset and replaced in place
when a goal is reached (at once) or the target changes (checked every ``lidar_every`` steps).
What was reached comes from ``on_step``'s ``info`` (``info["reached"]``); without it, a goal
counts as reached when the robot's true pose is inside its radius while it is the target.
Single-goal episodes draw exactly what they did.

Use::

    env = gym.make("bulletnav/Warehouse-v0", render_mode="human")
    obs, info = env.reset(seed=0)
    nav = Navigator(env.unwrapped.scene)
    nav.reset(info)
    dash = Dashboard(env)
    while True:
        obs, r, term, trunc, info = env.step(nav.act(obs, info))
        dash.on_step(nav.path)
        if term or trunc:
            obs, info = env.reset(); nav.reset(info); dash.on_reset()
"""

from __future__ import annotations

import functools
import logging
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import pybullet as p

from bulletnav.evaluation import NEAR_MISS_M
from bulletnav.viz.mission import mission_goals, progress_text
from bulletnav.viz.movers import mover_colours

log = logging.getLogger(__name__)

GOAL_COLOUR = (0.1, 0.9, 0.3)
GOAL_REACHED_COLOUR = (0.2, 0.45, 0.95)
"""A mission goal already reached."""
GOAL_PENDING_COLOUR = (0.55, 0.75, 0.6)
"""A mission goal still to visit that is not the current target."""
RAY_FREE_COLOUR = (0.1, 0.85, 0.2)
"""Rays that hit nothing within the lidar's range."""
RAY_HIT_COLOUR = (0.95, 0.15, 0.1)
PATH_COLOUR = (0.9, 0.3, 0.9)
EVENT_ADD_COLOUR = (0.0, 0.8, 0.75)
EVENT_REMOVE_COLOUR = (1.0, 0.4, 0.15)
HUD_COLOUR = (0.1, 0.1, 0.1)
EVENT_TEXTS = 4
"""Event messages shown at once in the GUI (the oldest is overwritten by a new event)."""
ROUTE_Z = 0.04
"""Height (m) of the mover route lines, just above the floor."""
_HIDDEN = ((0.0, 0.0, -5.0), (0.0, 0.0, -5.0))
"""A zero-length line under the floor: how unused path segments are hidden (removing is slow)."""
_PREVIEW_FLAGS = ("COV_ENABLE_GUI", "COV_ENABLE_RGB_BUFFER_PREVIEW", "COV_ENABLE_DEPTH_BUFFER_PREVIEW",
                  "COV_ENABLE_SEGMENTATION_MARK_PREVIEW")


def draw_in_place(ids: list[int], i: int, draw: Callable[..., int]) -> int:
    """Item ``i`` of a group of GUI debug items (``ids``: their PyBullet ids, -1 for none yet)
    drawn by ``draw`` (``addUserDebugLine`` or ``addUserDebugText`` with its arguments bound):
    replaced in place when it exists (each creation is a round trip to the GUI's render thread),
    else created, ``ids`` growing to hold it. An item that vanished (a rebuilt scene drops them
    all) is drawn anew. Returns the ``draw`` calls made (1, or 2 for a vanished item)."""
    calls = 1
    if i < len(ids) and ids[i] >= 0:
        new = draw(replaceItemUniqueId=ids[i])
        if new >= 0:
            ids[i] = new
            return calls
        log.debug("debug item %d vanished; drawing it anew", ids[i])
        calls += 1
    ids.extend([-1] * (i + 1 - len(ids)))
    ids[i] = draw()
    return calls


@dataclass(frozen=True)
class DashboardConfig:
    """How often the dashboard draws; periods are in control steps (1/24 s each by default)."""

    camera_every: int = 10
    """Control steps between robot-camera renders into the GUI's RGB/depth/segmentation preview tabs."""
    lidar_every: int = 10
    """Control steps between redraws of the lidar rays."""
    lidar_ray_stride: int = 10
    """Draw rays 0, stride, 2 stride, ... (36 rays / 10 -> 4 rays)."""
    path_every: int = 10
    """Control steps between redraws of the planned path (when one is given)."""
    follow_camera: bool = True
    """True: keep the env's chase view (the env re-aims the GUI camera every step in human mode).
    False: a top-down view of the whole floor, re-applied after every step because the env re-aims it."""
    max_path_segments: int = 40
    """Longest path polyline drawn (segments, ~4 ms each per redraw); longer plans are thinned."""
    line_width: float = 2.0
    """Debug line width (px)."""
    hardware_camera: bool = True
    """Render the preview with ``ER_BULLET_HARDWARE_OPENGL`` through the GUI's OpenGL context
    (fast with a GPU); False uses the CPU TinyRenderer, often faster under Xvfb's software GL.
    Both fill the preview tabs."""

    def __post_init__(self) -> None:
        for name in ("camera_every", "lidar_every", "lidar_ray_stride", "path_every", "max_path_segments"):
            if getattr(self, name) < 1:
                raise ValueError(f"DashboardConfig.{name} must be >= 1, got {getattr(self, name)}")

    @classmethod
    def unthrottled(cls, follow_camera: bool = True) -> DashboardConfig:
        """Everything every step, every ray: the naive dashboard, for comparison."""
        return cls(camera_every=1, lidar_every=1, lidar_ray_stride=1, path_every=1, follow_camera=follow_camera)


class Dashboard:
    """Camera preview, lidar rays, planned path and goal marker(s) in the PyBullet GUI.

    Construction turns on the GUI panels and the RGB, depth and segmentation preview tabs
    and, when the env has been reset, calls :meth:`on_reset`. Call :meth:`on_reset` after
    every ``env.reset`` and :meth:`on_step` after every ``env.step``.

    Counters (for tests and profiling):
        camera_renders: ``getCameraImage`` calls made (one every ``camera_every`` steps; none at reset).
        debug_draw_calls: ``addUserDebugLine`` calls made, replacements included.
        debug_text_calls: ``addUserDebugText`` calls made (event messages, replacements included).
        debug_items: debug items this dashboard currently owns.

    Per episode of ``n`` steps with a path of ``s`` segments: ``n // camera_every`` renders
    and ``3 + (n // lidar_every) * ceil(rays / lidar_ray_stride) + (n // path_every) * s``
    line calls (3 for the goal marker), plus one call per visible ray or path segment hidden
    at a reset that keeps the scene. A dynamic world adds, at each reset, one line call per
    mover route segment (and one per route segment of the last episode left to hide), and
    one text call per event (plus one per shown message hidden at a reset that keeps the scene).
    A mission of ``K`` goals draws ``3 K`` goal lines and ``K + 1`` texts (numbers, progress) at
    reset instead of the 3 lines, then 3 line calls and 1 text call per goal whose look changes
    (reached, or becoming or ceasing to be the target) and 1 text call when the progress or
    the target changes.
    """

    def __init__(self, env: Any, config: DashboardConfig = DashboardConfig()) -> None:
        u = env.unwrapped
        if getattr(u, "render_mode", None) != "human":
            raise ValueError("Dashboard draws in the PyBullet GUI: make the env with render_mode='human'")
        self.env = env
        self.config = config
        self.scene = u.scene
        self.cid = self.scene.client
        self.camera_renders = 0
        self.debug_draw_calls = 0
        self.debug_text_calls = 0
        self.steps = 0
        """Control steps since the last reset."""
        self._goal_ids: list[int] = []
        self._ray_ids: list[int] = []
        self._path_ids: list[int] = []
        self._path_visible = 0
        self._rays_visible = False
        self._route_ids: list[int] = []
        self._routes_visible = 0
        self._text_ids: list[int] = []
        self._texts_visible = False
        self._hud_ids: list[int] = []
        self._goal_text_ids: list[int] = []
        self._goals_visible = 0
        self._progress_ids: list[int] = []
        self._goals: tuple[tuple[float, float], ...] = ()
        self._reached: list[bool] = []
        self._target: tuple[float, float] | None = None
        self._shown: tuple[tuple[bool, ...], tuple[float, float] | None, tuple[bool, ...]] | None = None
        """(reached, target, is target) per goal as last drawn; None: nothing drawn this episode."""
        self._last_reached = 0
        self.goals_shown = 0
        """Mission goals the progress text shows reached (0 for single-goal episodes)."""
        self._dynamic = False
        self._events_seen = 0
        self._events_shown = 0
        self._rebuilds = -1
        self._episode = -1
        for name in _PREVIEW_FLAGS:
            p.configureDebugVisualizer(getattr(p, name), 1, physicsClientId=self.cid)
        if self.scene.layout is not None:
            self.on_reset()

    @property
    def debug_items(self) -> int:
        return (len(self._goal_ids) + len(self._ray_ids) + len(self._path_ids) + len(self._route_ids)
                + len(self._text_ids) + len(self._hud_ids) + len(self._goal_text_ids) + len(self._progress_ids))

    # ------------------------------------------------------------------ hooks
    def on_reset(self) -> None:
        """Start an episode: (re)draw the goal marker and hide last episode's rays and path;
        in dynamic worlds draw the movers' routes and hide last episode's event messages."""
        scene = self.scene
        self.steps = 0
        self._episode = scene.episode
        if scene.scene_builds != self._rebuilds:
            # resetSimulation (seeded reset or new layout) deleted every debug item and
            # restarts their ids: forget ours, replacing a stale id would draw nothing
            self._goal_ids, self._ray_ids, self._path_ids = [], [], []
            self._path_visible, self._rays_visible = 0, False
            self._route_ids, self._routes_visible = [], 0
            self._text_ids, self._texts_visible = [], False
            self._hud_ids = []
            self._goal_text_ids, self._goals_visible, self._progress_ids = [], 0, []
            self._rebuilds = scene.scene_builds
        else:
            if self._rays_visible:
                for i in range(len(self._ray_ids)):
                    self._line(self._ray_ids, i, *_HIDDEN, RAY_FREE_COLOUR)
                self._rays_visible = False
            self._hide_path_from(0)
            if self._texts_visible:
                for i in range(len(self._text_ids)):
                    self._text(i, " ", _HIDDEN[0], EVENT_ADD_COLOUR)
                self._texts_visible = False
            if self._hud_ids:
                self._text(0, " ", _HIDDEN[0], HUD_COLOUR, self._hud_ids)
        self._dynamic = scene.dynamic
        self._events_seen = 0
        self._min_separation = float("inf")
        self._near_miss_steps = 0
        self._shield_steps, self._shield_change, self._shielded = 0, 0.0, False
        if self._dynamic:
            self._draw_routes()
        elif self._routes_visible:
            self._hide_routes_from(0)
        self._goals = mission_goals(None, scene)
        self._reached = [False] * len(self._goals)
        self._target = scene.goal
        self._shown = None
        self._last_reached = 0
        if self._goals:
            self._draw_goals()
        else:
            self._hide_goals_from(3, 0)  # after a mission: its other markers, numbers and progress
            self.goals_shown = 0
            gx, gy = scene.goal
            r = scene.goal_radius
            marker = [((gx, gy, 0.0), (gx, gy, 1.0)),  # a post, visible from afar
                      ((gx - r, gy, 0.02), (gx + r, gy, 0.02)), ((gx, gy - r, 0.02), (gx, gy + r, 0.02))]  # the zone
            for i, (a, b) in enumerate(marker):
                self._line(self._goal_ids, i, a, b, GOAL_COLOUR, width=3.0)
        if not self.config.follow_camera:
            self._overview()

    def on_step(self, path: Sequence[tuple[float, float]] | None = None, info: dict[str, Any] | None = None) -> None:
        """Account for one ``env.step`` and draw whatever is due; ``path`` is the current plan (x, y) list,
        ``info`` the step's (missions: which goals are reached; optional)."""
        if self.scene.episode != self._episode:
            log.debug("new episode without Dashboard.on_reset(): resetting now")
            self.on_reset()
        self.steps += 1
        cfg = self.config
        if self._goals:
            self._update_goals(info)
        if self.steps % cfg.camera_every == 0:
            self._render_camera()
        if self.steps % cfg.lidar_every == 0:
            self._draw_rays()
        if path is not None and self.steps % cfg.path_every == 0:
            self._draw_path(path)
        veto = info.get("shield") if info is not None else None
        if veto is not None:  # behind the safety shield (ShieldWrapper)
            self._shielded = True
            if veto["intervened"]:
                self._shield_steps += 1
                self._shield_change += float(veto["change"])
        gap = None
        if self._dynamic:
            events = self.scene.events
            if len(events) > self._events_seen:  # rare: a few per minute at most
                for e in events[self._events_seen:]:
                    self._show_event(e)
                self._events_seen = len(events)
            gap = self.scene.nearest_mover_m
            self._min_separation = min(self._min_separation, gap)
            self._near_miss_steps += gap < NEAR_MISS_M
        if (self._dynamic or self._shielded) and self.steps % cfg.lidar_every == 0:
            self._show_metrics(gap)
        if not cfg.follow_camera:
            self._overview()

    # ------------------------------------------------------------------ drawing
    def _line(self, ids: list[int], i: int, a: Sequence[float], b: Sequence[float], colour: Sequence[float],
              width: float | None = None) -> None:
        """Draw line ``i`` of a group: replace it in place when it exists, else create it."""
        kwargs = dict(lineColorRGB=colour, lineWidth=width or self.config.line_width, physicsClientId=self.cid)
        self.debug_draw_calls += draw_in_place(ids, i, functools.partial(p.addUserDebugLine, a, b, **kwargs))

    def _render_camera(self) -> None:
        # in GUI mode every getCameraImage also fills the RGB / depth / segmentation preview
        # tabs, which is all we want here; the sensor's cached read() is left alone
        cam = self.scene.sensors.camera
        if cam is None:
            return
        view, _, _ = cam.view_matrix()
        renderer = p.ER_BULLET_HARDWARE_OPENGL if self.config.hardware_camera else p.ER_TINY_RENDERER
        p.getCameraImage(cam.config.width, cam.config.height, view, cam.projection, renderer=renderer,
                         physicsClientId=self.cid)
        self.camera_renders += 1

    def _draw_rays(self) -> None:
        lidar = self.scene.sensors.lidar
        if lidar is None:
            return
        ranges = lidar.read()  # cached for this control step: no extra ray cast, no random draws
        origin = lidar.origin()
        yaw = self.scene.pose[2]
        max_range = lidar.config.max_range
        for slot, i in enumerate(range(0, len(ranges), self.config.lidar_ray_stride)):
            a = yaw + float(lidar.angles[i])
            r = float(ranges[i])
            end = (origin[0] + r * math.cos(a), origin[1] + r * math.sin(a), origin[2])
            colour = RAY_FREE_COLOUR if r >= max_range - 1e-6 else RAY_HIT_COLOUR
            self._line(self._ray_ids, slot, origin, end, colour)
        self._rays_visible = True

    def _draw_path(self, path: Sequence[tuple[float, float]]) -> None:
        pts = simplify_path(path, self.config.max_path_segments)
        for i, (a, b) in enumerate(zip(pts[:-1], pts[1:])):
            self._line(self._path_ids, i, (a[0], a[1], 0.03), (b[0], b[1], 0.03), PATH_COLOUR)
        self._path_visible = max(self._path_visible, len(pts) - 1)
        self._hide_path_from(max(len(pts) - 1, 0))

    def _hide_path_from(self, first: int) -> None:
        for i in range(first, self._path_visible):
            self._line(self._path_ids, i, *_HIDDEN, PATH_COLOUR)
        self._path_visible = min(self._path_visible, first)

    def _draw_routes(self) -> None:
        """Every mover's route as debug lines, in its shade (once per reset, replaced in place)."""
        movers = self.scene.movers
        i = 0
        for m, rgb in zip(movers, mover_colours(mv.kind for mv in movers)):
            colour = tuple(c / 255 for c in rgb)
            pts = simplify_path(m.path, self.config.max_path_segments)
            for a, b in zip(pts[:-1], pts[1:]):
                self._line(self._route_ids, i, (a[0], a[1], ROUTE_Z), (b[0], b[1], ROUTE_Z), colour)
                i += 1
        self._routes_visible = max(self._routes_visible, i)
        self._hide_routes_from(i)

    def _hide_routes_from(self, first: int) -> None:
        for i in range(first, self._routes_visible):
            self._line(self._route_ids, i, *_HIDDEN, PATH_COLOUR)
        self._routes_visible = min(self._routes_visible, first)

    def _update_goals(self, info: dict[str, Any] | None) -> None:
        """Follow a mission's progress; redraw its markers when a goal is reached (at once) or
        the target moved (checked with the lidar rays)."""
        scene = self.scene
        reached = info.get("reached") if info is not None else None
        if reached is not None and len(reached) == len(self._goals):
            self._reached = [bool(v) for v in reached]
        elif self._target is not None:  # no info: the target of the step counts when the robot is in its zone
            x, y, _ = scene.pose
            for i, (gx, gy) in enumerate(self._goals):
                if (not self._reached[i] and (gx, gy) == tuple(self._target)
                        and math.hypot(gx - x, gy - y) < scene.goal_radius):
                    self._reached[i] = True
        if self._shown is not None:
            for i, (was, now) in enumerate(zip(self._shown[0], self._reached)):
                if now and not was:
                    self._last_reached = i
        self._target = scene.goal
        assert self._shown is not None
        if tuple(self._reached) != self._shown[0] or (
                self.steps % self.config.lidar_every == 0 and self._target != self._shown[1]):
            self._draw_goals()

    def _draw_goals(self) -> None:
        """Every mission goal's marker and number whose look changed (all of them after a reset),
        and the progress text over the current target when the count or the target changed."""
        scene = self.scene
        r = scene.goal_radius
        target = None if all(self._reached) else scene.goal
        current = [target is not None and (gx, gy) == tuple(target) and not done
                   for (gx, gy), done in zip(self._goals, self._reached)]
        shown = self._shown
        for k, ((gx, gy), done) in enumerate(zip(self._goals, self._reached)):
            if shown is not None and shown[0][k] == done and shown[2][k] == current[k]:
                continue  # looks as drawn: no GUI round trip
            colour = GOAL_REACHED_COLOUR if done else GOAL_COLOUR if current[k] else GOAL_PENDING_COLOUR
            height = 1.0 if current[k] else 0.7
            marker = [((gx, gy, 0.0), (gx, gy, height)),
                      ((gx - r, gy, 0.02), (gx + r, gy, 0.02)), ((gx, gy - r, 0.02), (gx, gy + r, 0.02))]
            for i, (a, b) in enumerate(marker):
                self._line(self._goal_ids, 3 * k + i, a, b, colour, width=3.0 if current[k] else 2.0)
            self._text(k, f"{k + 1} done" if done else str(k + 1), (gx, gy, height + 0.1), colour,
                       self._goal_text_ids)
        if shown is None:
            self._hide_goals_from(3 * len(self._goals), len(self._goals))
            self._goals_visible = len(self._goals)
        n = sum(self._reached)
        here = tuple(target) if target is not None else None
        if shown is None or n != sum(shown[0]) or here != shown[1]:
            px, py = here if here is not None else self._goals[self._last_reached]
            self._text(0, progress_text(n, len(self._goals)), (px, py, 1.35), HUD_COLOUR, self._progress_ids)
        self.goals_shown = n
        self._shown = (tuple(self._reached), here, tuple(current))

    def _hide_goals_from(self, first_line: int, first_text: int) -> None:
        """Hide goal marker lines ``first_line``.. and goal numbers ``first_text``.. (a reset that
        keeps the scene with fewer goals than before); with no mission, the progress text too."""
        for i in range(first_line, len(self._goal_ids)):
            self._line(self._goal_ids, i, *_HIDDEN, GOAL_COLOUR)
        for i in range(first_text, min(self._goals_visible, len(self._goal_text_ids))):
            self._text(i, " ", _HIDDEN[0], GOAL_COLOUR, self._goal_text_ids)
        if not self._goals and self._goals_visible and self._progress_ids:
            self._text(0, " ", _HIDDEN[0], HUD_COLOUR, self._progress_ids)
        self._goals_visible = min(self._goals_visible, first_text)

    def _show_metrics(self, gap: float | None) -> None:
        """The episode's safety metrics so far, in one text item above the robot: the movers'
        (``gap``: nearest mover now, None in static worlds) and the shield's (when it is on)."""
        x, y, _ = self.scene.pose
        parts = []
        if gap is not None:
            parts.append(f"nearest mover {gap:.2f} m | min {self._min_separation:.2f} m | "
                         f"near misses {100.0 * self._near_miss_steps / max(self.steps, 1):.1f} % of steps")
        if self._shielded:
            change = self._shield_change / self._shield_steps if self._shield_steps else 0.0
            parts.append(f"shield acted {100.0 * self._shield_steps / max(self.steps, 1):.1f} % of steps, "
                         f"mean change {change:.2f} m/s")
        text = " | ".join(parts)
        self._text(0, text, (x, y, 1.2), HUD_COLOUR, self._hud_ids)

    def _show_event(self, event: dict[str, Any]) -> None:
        """A message over the event's place: ``+ label (t s)`` when added, ``- label (t s)`` when removed."""
        add = event["action"] == "add"
        x, y = (float(v) for v in event["center"][:2])
        size = event.get("size") or (0.0, 0.0, 1.0)
        text = f"{'+' if add else '-'} {event.get('label') or 'obstacle'} ({float(event['time_s']):.1f} s)"
        slot = len(self._text_ids) if len(self._text_ids) < EVENT_TEXTS else self._events_shown % EVENT_TEXTS
        # added above, removed below the centre (in y): an obstacle added and later removed keeps both legible
        pos = (x, y + (0.3 if add else -0.3), float(size[2]) + 0.4)
        self._text(slot, text, pos, EVENT_ADD_COLOUR if add else EVENT_REMOVE_COLOUR)
        self._events_shown += 1
        self._texts_visible = True

    def _text(self, i: int, text: str, pos: Sequence[float], colour: Sequence[float],
              ids: list[int] | None = None) -> None:
        """Debug text ``i`` of a group (default: the event ring): replaced in place when it
        exists, else created."""
        kwargs = dict(textColorRGB=colour, textSize=1.4, physicsClientId=self.cid)
        ids = self._text_ids if ids is None else ids
        self.debug_text_calls += draw_in_place(ids, i, functools.partial(p.addUserDebugText, text, pos, **kwargs))

    def _overview(self) -> None:
        hx, hy = self.scene.layout.half_extents
        cx, cy = self.scene.layout.centre
        p.resetDebugVisualizerCamera(1.2 * max(hx, hy) + 2.0, 0.0, -89.0, [cx, cy, 0.0], physicsClientId=self.cid)


def simplify_path(path: Sequence[tuple[float, float]], max_segments: int) -> list[tuple[float, float]]:
    """Drop points where the path goes straight on, then thin evenly to ``max_segments`` segments.

    Grid plans step cell by cell; only their corners need a debug line.
    """
    pts = [(float(x), float(y)) for x, y in path]
    if len(pts) <= 2:
        return pts
    keep = [pts[0]]
    for prev, cur, nxt in zip(pts[:-2], pts[1:-1], pts[2:]):
        cross = (cur[0] - prev[0]) * (nxt[1] - cur[1]) - (cur[1] - prev[1]) * (nxt[0] - cur[0])
        if abs(cross) > 1e-9:
            keep.append(cur)
    keep.append(pts[-1])
    if len(keep) - 1 > max_segments:
        idx = np.linspace(0, len(keep) - 1, max_segments + 1).round().astype(int)
        keep = [keep[i] for i in idx]
    return keep
