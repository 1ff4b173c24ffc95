"""Trajectory maps: log ground-truth paths per episode and plot them over the warehouse.

Use with :func:`bulletnav.evaluation.run_episodes`::

    log = TrajectoryLog()
    run_episodes(env, policy, 10, seed=0, on_reset=log.on_reset, on_step=log.on_step,
                 on_episode=log.on_episode)
    plot_trajectories(log, "runs/trajectories.png", title="A* navigator")

Without the reset hook the log still works: it notices each new episode in ``on_step`` and
starts it at ``env.unwrapped.scene.start``. Poses come from ``info["pose"]``.

In dynamic worlds (``scene.dynamic``) the log also keeps each mover's pose after every step
(read from ``scene.movers``) and the episode's events (``scene.events``); the plot then
draws every mover's route (dashed, one shade per mover: forklifts yellow-amber, workers
blue-violet), its positions over the episode as a faint trail and its final footprint
(rectangle for a forklift, circle for a worker), and the events: an added obstacle's
footprint outlined, a removed one crossed out, each with its time. Static worlds log and
draw exactly what they did before.

In multi-goal missions (``info["goals"]`` with two or more goals) the log also keeps the
goals, ``info["reached_at"]`` (the last seen) and the control period; the plot then draws
every goal zone with its number (1..K in the episode's goal order) and, next to it, when it
was visited (``#2 @ 31.5 s``: second goal reached, 31.5 s into the episode); a goal never
reached has a dashed outline, a hollow number and ``not visited``. Single-goal episodes are
drawn exactly as before.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bulletnav.files import save_figure
from bulletnav.sim.layout import WALL_THICKNESS, Layout
from bulletnav.sim.world import COLOURS
from bulletnav.viz.mission import mission_goals, visit_order, visit_text
from bulletnav.viz.movers import EVENT_HEX, event_corners, forklift_corners, hex_colour, mover_colours
from bulletnav.viz.video import box_corners

log = logging.getLogger(__name__)

OUTCOME_COLOURS = {"success": "#2ca02c", "collision": "#d62728", "timeout": "#ff7f0e", "unfinished": "#7f7f7f"}
"""Path colour per episode outcome (matplotlib colours)."""
GOAL_COLOUR = "#1f77b4"
PANEL_IN = 3.0
"""Side of one small-multiple panel (inches); the single map is 7 x 7 in."""
LEGEND_IN = 0.5
"""Extra height (inches) for the legend row under the small multiples."""
DYNAMIC_LEGEND_IN = 0.25
"""More legend height (inches) when the small multiples show movers or events (a second row)."""
MOVER_GID = {"path": "mover_path", "trail": "mover_trail", "footprint": "mover_footprint"}
"""Matplotlib ``gid`` of each mover's artists: one route line, one trail line, one footprint patch."""
EVENT_GID = {"add": "event_add", "remove": "event_remove"}
"""Matplotlib ``gid`` of an event's marker: the added footprint's outline, the removed one's x."""
GOAL_GID = {"zone": "goal_zone", "number": "goal_number", "visit": "goal_visit", "unvisited": "goal_unvisited"}
"""Matplotlib ``gid`` of a mission goal's artists: its zone (two patches), its number (1..K), its
visit label (``#rank @ t s``) or, when never reached, its ``not visited`` label."""
UNVISITED_COLOUR = "#7f7f7f"
"""Mission goals never reached: outline, number and label."""


@dataclass
class MoverTrack:
    """One mover's episode, as ``scene.movers`` showed it."""

    kind: str
    """``"forklift"`` or ``"worker"``."""
    size: tuple[float, float, float]
    """Forklift: length along its heading, width, height (m); worker: (2 radius, 2 radius, height)."""
    path: tuple[tuple[float, float], ...]
    """Its route or waypoints (m)."""
    poses: list[tuple[float, float, float]] = field(default_factory=list)
    """(x m, y m, yaw rad): at reset (when ``on_reset`` was called), then after every step."""


@dataclass
class EpisodeTrajectory:
    """One episode's ground-truth track."""

    layout: Layout
    start: tuple[float, float, float]
    """Start pose (x m, y m, yaw rad)."""
    goal: tuple[float, float]
    """Goal (x, y) in metres."""
    goal_radius: float
    """Success radius around the goal (m)."""
    points: list[tuple[float, float]] = field(default_factory=list)
    """Body-centre positions (m): at reset, then after every step."""
    outcome: str = "unfinished"
    """'success', 'collision', 'timeout' or 'unfinished' (stopped by the caller)."""
    result: Any = None
    """The :class:`~bulletnav.evaluation.EpisodeResult`, when ``on_episode`` was called."""
    movers: list[MoverTrack] = field(default_factory=list)
    """The movers of a dynamic world, in ``scene.movers`` order (empty in static worlds)."""
    events: list[dict[str, Any]] = field(default_factory=list)
    """The episode's events so far (copies of ``scene.events``' dicts; empty in static worlds)."""
    goals: tuple[tuple[float, float], ...] = ()
    """A mission's goals (x, y) in the episode's goal order; empty for a single goal."""
    reached_at: tuple[int | None, ...] = ()
    """A mission's control step at which each goal was reached (None: not reached), from ``info``."""
    control_dt: float = 0.0
    """Control period (s), to turn ``reached_at`` into times (missions only)."""
    goal_order: str = ""
    """A mission's ``"fixed"`` or ``"free"`` order (from ``info``)."""

    @property
    def dynamic(self) -> bool:
        return bool(self.movers or self.events)

    @property
    def mission(self) -> bool:
        """Two or more goals: drawn numbered, with their visit order."""
        return len(self.goals) >= 2

    @property
    def visits(self) -> list[int | None]:
        """1-based rank in which each goal was reached (None: not reached)."""
        return visit_order(self.reached_at)


class TrajectoryLog:
    """Collects :class:`EpisodeTrajectory` records through env hooks (see the module docstring)."""

    def __init__(self) -> None:
        self.episodes: list[EpisodeTrajectory] = []
        self._stamp: int | None = None
        self._steps = 0
        self._dynamic = False

    def __len__(self) -> int:
        return len(self.episodes)

    def on_reset(self, env: Any, info: dict[str, Any]) -> None:
        """Start an episode; call right after ``env.reset`` with its ``info``."""
        self._begin(env, info)
        x, y, _ = info["pose"]
        self.episodes[-1].points.append((float(x), float(y)))
        if self._dynamic:
            self._record_dynamic(env.unwrapped.scene)
        self._record_mission(info)

    def on_step(self, env: Any, info: dict[str, Any]) -> None:
        """Record the pose after a step; call after every ``env.step`` (``run_episodes``' ``on_step``)."""
        scene = env.unwrapped.scene
        if scene.episode != self._stamp:  # no on_reset: the robot was placed exactly at start
            self._begin(env, info)
            self.episodes[-1].points.append((float(scene.start[0]), float(scene.start[1])))
        self._steps += 1
        x, y, _ = info["pose"]
        ep = self.episodes[-1]
        ep.points.append((float(x), float(y)))
        if self._dynamic:
            self._record_dynamic(scene)
        self._record_mission(info)
        if info.get("is_success"):
            ep.outcome = "success"
        elif info.get("collision"):
            ep.outcome = "collision"
        else:
            spec = env.spec
            limit = getattr(spec, "max_episode_steps", None)
            if limit is not None and self._steps >= limit:
                ep.outcome = "timeout"

    def on_episode(self, result: Any) -> None:
        """Attach ``run_episodes``' result to the latest episode (its outcome wins)."""
        if not self.episodes:
            return
        ep = self.episodes[-1]
        ep.result = result
        ep.outcome = "success" if result.success else "collision" if result.collision else "timeout"

    def _begin(self, env: Any, info: dict[str, Any] | None = None) -> None:
        scene = env.unwrapped.scene
        self._stamp = scene.episode
        self._steps = 0
        sx, sy, syaw = (float(v) for v in scene.start)
        gx, gy = scene.goal
        ep = EpisodeTrajectory(
            layout=scene.layout, start=(sx, sy, syaw), goal=(float(gx), float(gy)),
            goal_radius=float(scene.goal_radius),
        )
        goals = mission_goals(info, scene)
        if goals:
            ep.goals = goals
            ep.reached_at = (None,) * len(goals)
            ep.control_dt = float(scene.control_dt)
        self._dynamic = bool(scene.dynamic)
        if self._dynamic:
            ep.movers = [MoverTrack(m.kind, tuple(float(v) for v in m.size), tuple((float(x), float(y)) for x, y in m.path))
                         for m in scene.movers]
        self.episodes.append(ep)

    def _record_mission(self, info: dict[str, Any]) -> None:
        ep = self.episodes[-1]
        if not ep.mission:
            return
        reached_at = info.get("reached_at")
        if reached_at is not None and len(reached_at) == len(ep.goals):
            ep.reached_at = tuple(None if s is None else int(s) for s in reached_at)
        if info.get("goal_order"):
            ep.goal_order = str(info["goal_order"])

    def _record_dynamic(self, scene: Any) -> None:
        ep = self.episodes[-1]
        for track, m in zip(ep.movers, scene.movers):
            track.poses.append(tuple(float(v) for v in m.pose))  # type: ignore[arg-type]
        events = scene.events
        if len(events) > len(ep.events):
            ep.events.extend(dict(e) for e in events[len(ep.events):])


def figure_size(log_or_episodes: TrajectoryLog | list[EpisodeTrajectory], max_panels: int = 25,
                dpi: int = 100) -> tuple[int, int]:
    """(width, height) in pixels of the PNG :func:`plot_trajectories` writes."""
    episodes = _episodes(log_or_episodes)
    if _shared_layout(episodes):
        return 7 * dpi, 7 * dpi
    cols, rows = _grid(min(len(episodes), max_panels))
    legend = LEGEND_IN + (DYNAMIC_LEGEND_IN if any(ep.dynamic or ep.mission for ep in episodes[:max_panels])
                          else 0.0)
    return int(round(cols * PANEL_IN * dpi)), int(round((rows * PANEL_IN + legend) * dpi))


def plot_trajectories(log_or_episodes: TrajectoryLog | list[EpisodeTrajectory], path: str | Path,
                      title: str = "", max_panels: int = 25, dpi: int = 100) -> Path:
    """Write a PNG of the logged trajectories over their warehouse maps (atomically).

    Episodes that all share one layout go on one 7 x 7 in map; otherwise each gets a
    3 x 3 in panel in a grid (the first ``max_panels``). Paths are green (success), red
    (collision), orange (timeout) or grey (unfinished); the start is a white dot with a
    heading tick, the goal a blue circle of the success radius. Movers and events of
    dynamic worlds are drawn as the module docstring says (artists tagged with the gids of
    :data:`MOVER_GID` and :data:`EVENT_GID`); a mover route shared by several episodes on
    one map is drawn once.

    Raises:
        ValueError: nothing was logged.
    """
    fig = trajectory_figure(log_or_episodes, title, max_panels, dpi)
    return save_figure(fig, path, format="png", dpi=dpi)


def trajectory_figure(log_or_episodes: TrajectoryLog | list[EpisodeTrajectory], title: str = "",
                      max_panels: int = 25, dpi: int = 100) -> Any:
    """The matplotlib ``Figure`` that :func:`plot_trajectories` saves (for inspection or
    further drawing; it is not attached to pyplot).

    Raises:
        ValueError: nothing was logged.
    """
    from matplotlib.figure import Figure  # no pyplot: no global state, no GUI backend
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    episodes = _episodes(log_or_episodes)
    if not episodes:
        raise ValueError("plot_trajectories: the log holds no episodes")
    width, height = figure_size(episodes, max_panels, dpi)
    fig = Figure(figsize=(width / dpi, height / dpi), dpi=dpi, layout="constrained")
    if _shared_layout(episodes):
        ax = fig.add_subplot()
        draw_layout(ax, episodes[0].layout)
        routes: set[tuple[str, tuple[tuple[float, float], ...]]] = set()
        labels: dict[tuple[float, float], int] = {}
        for ep in episodes:
            _draw_episode(ax, ep, linewidth=1.8, routes=routes, labels=labels)
        ax.set_xlabel("x (m)")
        ax.set_ylabel("y (m)")
        shown = episodes
    else:
        shown = episodes[:max_panels]
        if len(episodes) > max_panels:
            log.info("plot_trajectories: drawing the first %d of %d episodes", max_panels, len(episodes))
        cols, rows = _grid(len(shown))
        for i, ep in enumerate(shown):
            ax = fig.add_subplot(rows, cols, i + 1)
            draw_layout(ax, ep.layout)
            _draw_episode(ax, ep, linewidth=1.4)
            ax.set_title(f"episode {i + 1}: {ep.outcome}", fontsize=8)
            # every panel to scale, in metres: its own ticks (the panels' worlds differ), and the
            # axis names on the outer ones
            ax.tick_params(labelsize=6, length=2, pad=1)
            if i % cols == 0:
                ax.set_ylabel("y (m)", fontsize=7)
            if i >= len(shown) - cols:
                ax.set_xlabel("x (m)", fontsize=7)
    # the three outcomes always, so the colour key reads the same on every plot
    outcomes = [o for o in OUTCOME_COLOURS if o != "unfinished" or any(ep.outcome == o for ep in shown)]
    handles = [Line2D([], [], color=OUTCOME_COLOURS[o], lw=2, label=o) for o in outcomes]
    handles += [Line2D([], [], ls="", marker="o", mfc="white", mec="black", label="start"),
                Patch(facecolor=GOAL_COLOUR, alpha=0.3, edgecolor=GOAL_COLOUR, label="goal zone")]
    extra = _dynamic_handles(shown) + _mission_handles(shown)
    ncols = len(handles) if not extra else math.ceil((len(handles) + len(extra)) / 2)
    fig.legend(handles=handles + extra, loc="outside lower center", ncols=ncols, fontsize=8, frameon=False)
    if title:
        fig.suptitle(title + ("" if len(shown) == len(episodes) else f" (first {len(shown)} of {len(episodes)})"))
    return fig


def _episodes(log_or_episodes: TrajectoryLog | list[EpisodeTrajectory]) -> list[EpisodeTrajectory]:
    return list(log_or_episodes.episodes if isinstance(log_or_episodes, TrajectoryLog) else log_or_episodes)


def _shared_layout(episodes: list[EpisodeTrajectory]) -> bool:
    return all(ep.layout == episodes[0].layout for ep in episodes[1:])


def _grid(n: int) -> tuple[int, int]:
    cols = max(1, math.ceil(math.sqrt(n)))
    return cols, max(1, math.ceil(n / cols))


def draw_layout(ax: Any, layout: Layout, obstacle: Any = None, wall: Any = None) -> None:
    """Draw ``layout`` (walls, floor, obstacles in their category colours) on matplotlib axes ``ax``, to scale.

    ``obstacle`` and ``wall``, matplotlib colours, draw every obstacle and the walls in one
    colour instead (the benchmark report keeps colour for its paths and movers)."""
    from matplotlib.patches import Circle, Polygon, Rectangle

    hx, hy = layout.half_extents
    x0, y0, x1, y1 = layout.bounds  # the world's frame: a user's map in its own coordinates
    t = WALL_THICKNESS
    ax.add_patch(Rectangle((x0 - t, y0 - t), 2 * (hx + t), 2 * (hy + t), color=COLOURS["wall"][:3] if wall is None else wall,
                           zorder=0))
    ax.add_patch(Rectangle((x0, y0), 2 * hx, 2 * hy, color=(0.93, 0.93, 0.94), zorder=0))
    for o in layout.obstacles:
        colour = COLOURS.get(o.label, COLOURS["box"])[:3] if obstacle is None else obstacle
        if o.kind == "cylinder":
            patch = Circle(o.center, o.radius, facecolor=colour, edgecolor="0.3", lw=0.5)
        else:
            patch = Polygon(box_corners(o), closed=True, facecolor=colour, edgecolor="0.3", lw=0.5)
        ax.add_patch(patch)
    ax.set_xlim(x0 - t, x1 + t)
    ax.set_ylim(y0 - t, y1 + t)
    ax.set_aspect("equal")


def _draw_episode(ax: Any, ep: EpisodeTrajectory, linewidth: float,
                  routes: set[tuple[str, tuple[tuple[float, float], ...]]] | None = None,
                  labels: dict[tuple[float, float], int] | None = None) -> None:
    from matplotlib.patches import Circle

    if ep.movers:
        draw_mover_tracks(ax, ep.movers, set() if routes is None else routes)
    if ep.events:
        draw_events(ax, ep.events)
    if ep.mission:
        _draw_mission(ax, ep, {} if labels is None else labels)
    else:
        ax.add_patch(Circle(ep.goal, ep.goal_radius, facecolor=GOAL_COLOUR, alpha=0.25, edgecolor="none", zorder=2))
        ax.add_patch(Circle(ep.goal, ep.goal_radius, fill=False, edgecolor=GOAL_COLOUR, lw=1.2, zorder=2))
    if ep.points:
        xs, ys = zip(*ep.points)
        ax.plot(xs, ys, color=OUTCOME_COLOURS.get(ep.outcome, "0.5"), lw=linewidth, zorder=3)
    sx, sy, syaw = ep.start
    ax.plot([sx, sx + 0.4 * math.cos(syaw)], [sy, sy + 0.4 * math.sin(syaw)], color="black", lw=1.2, zorder=4)
    ax.plot(sx, sy, ls="", marker="o", ms=5, mfc="white", mec="black", zorder=5)


def _draw_mission(ax: Any, ep: EpisodeTrajectory, labels: dict[tuple[float, float], int]) -> None:
    """Every goal's zone and number; its visit label (``#rank @ t s``) or ``not visited`` beside it.

    ``labels`` counts the visit labels already put at each goal on this map: episodes sharing a
    map stack theirs below one another instead of on top."""
    from matplotlib.patches import Circle

    visits = ep.visits
    for i, (goal, rank) in enumerate(zip(ep.goals, visits)):
        step = ep.reached_at[i] if i < len(ep.reached_at) else None
        reached = rank is not None and step is not None
        edge = GOAL_COLOUR if reached else UNVISITED_COLOUR
        ax.add_patch(Circle(goal, ep.goal_radius, facecolor=GOAL_COLOUR, alpha=0.25 if reached else 0.07,
                            edgecolor="none", zorder=2, gid=GOAL_GID["zone"], label=f"_goal {i + 1} zone"))
        ax.add_patch(Circle(goal, ep.goal_radius, fill=False, edgecolor=edge, lw=1.2, ls="-" if reached else "--",
                            zorder=2, gid=GOAL_GID["zone"], label=f"_goal {i + 1} outline"))
        n = labels.get(goal, 0)
        labels[goal] = n + 1
        if n == 0:  # one number per goal position and map
            box = dict(boxstyle="circle,pad=0.2", facecolor=GOAL_COLOUR if reached else "white", edgecolor=edge, lw=0.8)
            ax.text(goal[0], goal[1], str(i + 1), ha="center", va="center", fontsize=7, fontweight="bold",
                    color="white" if reached else UNVISITED_COLOUR, bbox=box, zorder=4.5, gid=GOAL_GID["number"])
        if reached:
            text, colour, gid = visit_text(rank, step, ep.control_dt), GOAL_COLOUR, GOAL_GID["visit"]
        else:
            text, colour, gid = "not visited", UNVISITED_COLOUR, GOAL_GID["unvisited"]
        ax.annotate(text, goal, xytext=(9, 4 - 9 * n), textcoords="offset points", fontsize=6.5, color=colour,
                    fontstyle="normal" if reached else "italic", zorder=4.6, gid=gid,
                    bbox=dict(boxstyle="round,pad=0.15", facecolor="white", edgecolor="none", alpha=0.7))


def _mission_handles(episodes: list[EpisodeTrajectory]) -> list[Any]:
    """Legend entries for mission goals (none when no episode is a mission)."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    missions = [ep for ep in episodes if ep.mission]
    if not missions:
        return []
    orders = sorted({ep.goal_order for ep in missions if ep.goal_order})
    order = f" ({'/'.join(orders)} order)" if orders else ""
    handles: list[Any] = [
        Line2D([], [], ls="", marker="o", ms=8, mfc=GOAL_COLOUR, mec=GOAL_COLOUR,
               label=f"goals numbered{order}"),
        Line2D([], [], ls="", marker="$\\#$", ms=7, color=GOAL_COLOUR, label="visit order @ time"),
    ]
    if any(r is None for ep in missions for r in ep.visits):
        handles.append(Patch(facecolor=GOAL_COLOUR, alpha=0.3, edgecolor=UNVISITED_COLOUR, ls="--",
                             label="goal not visited"))
    return handles


def draw_mover_tracks(ax: Any, movers: list[MoverTrack], routes: set[tuple[str, tuple[tuple[float, float], ...]]]) -> None:
    """Route (dashed), trail (faint) and final footprint of each mover, in its own shade."""
    from matplotlib.patches import Circle, Polygon

    for i, (track, rgb) in enumerate(zip(movers, mover_colours(m.kind for m in movers))):
        colour = hex_colour(rgb)
        name = f"{track.kind} {i + 1}"
        key = (track.kind, track.path)
        if key not in routes and len(track.path) >= 2:
            routes.add(key)
            xs, ys = zip(*track.path)
            ax.plot(xs, ys, color=colour, lw=1.1, ls=(0, (4, 2)), alpha=0.9, zorder=2.2, gid=MOVER_GID["path"],
                    label=f"_{name} route")
        if not track.poses:
            continue
        if len(track.poses) >= 2:
            xs, ys = [q[0] for q in track.poses], [q[1] for q in track.poses]
            ax.plot(xs, ys, color=colour, lw=2.5, alpha=0.25, solid_capstyle="round", zorder=2.1,
                    gid=MOVER_GID["trail"], label=f"_{name} trail")
        pose = track.poses[-1]
        edge = tuple(0.55 * c / 255 for c in rgb)
        if track.kind == "forklift":
            patch = Polygon(forklift_corners(pose, track.size), closed=True, facecolor=colour, edgecolor=edge,
                            lw=0.8, alpha=0.85, zorder=2.4)
        else:
            patch = Circle(pose[:2], track.size[0] / 2, facecolor=colour, edgecolor=edge, lw=0.8, alpha=0.85,
                           zorder=2.4)
        patch.set_gid(MOVER_GID["footprint"])
        patch.set_label(f"_{name} final footprint")
        ax.add_patch(patch)


def draw_events(ax: Any, events: list[dict[str, Any]]) -> None:
    """An added obstacle's footprint outlined, a removed one's crossed out; each with its time (s)."""
    from matplotlib.patches import Polygon

    for e in events:
        cx, cy = (float(v) for v in e["center"][:2])
        if e["action"] == "add":
            ax.add_patch(Polygon(event_corners(e), closed=True, fill=False, edgecolor=EVENT_HEX, lw=1.4, ls="--",
                                 zorder=3.5, gid=EVENT_GID["add"], label=f"_added {e.get('label', '')}"))
        else:
            ax.plot(cx, cy, ls="", marker="X", ms=8, mfc=EVENT_HEX, mec="white", mew=0.6, zorder=3.6,
                    gid=EVENT_GID["remove"], label=f"_removed {e.get('label', '')}")
        # added above, removed below the centre: an obstacle added and removed later keeps both times legible
        ax.annotate(f"{float(e['time_s']):.1f} s", (cx, cy), xytext=(5, 4 if e["action"] == "add" else -9),
                    textcoords="offset points", fontsize=6, color=EVENT_HEX, zorder=3.7, gid="event_time")


def _dynamic_handles(episodes: list[EpisodeTrajectory]) -> list[Any]:
    """Legend entries for what the dynamic episodes show (none for static ones)."""
    return dynamic_handles({m.kind for ep in episodes for m in ep.movers},
                           {e["action"] for ep in episodes for e in ep.events})


def dynamic_handles(kinds: set[str], actions: set[str]) -> list[Any]:
    """Legend entries for mover routes of ``kinds`` and events of ``actions`` ("add", "remove")."""
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    handles: list[Any] = []
    for kind in ("forklift", "worker"):
        if kind in kinds:
            (rgb,) = mover_colours([kind])
            handles.append(Line2D([], [], color=hex_colour(rgb), lw=1.1, ls=(0, (4, 2)), label=f"{kind} route"))
    if "add" in actions:
        handles.append(Patch(fill=False, edgecolor=EVENT_HEX, lw=1.4, ls="--", label="obstacle added"))
    if "remove" in actions:
        handles.append(Line2D([], [], ls="", marker="X", ms=8, mfc=EVENT_HEX, mec="white", mew=0.6,
                              label="obstacle removed"))
    return handles
