"""The path plot of a fleet episode: :class:`FleetTrackLog` records it, :func:`fleet_figure` and
:func:`plot_fleet` draw it.

The plot draws every robot's whole path in its colour over the
static map with the stations, each robot's start (hollow circle), end (filled disc), the
points where it completed a leg (pick: triangle, drop: star) and its last errand's goal, and
the movers and events as the single-robot plots draw them
(:func:`bulletnav.viz.plots.draw_mover_tracks`, :func:`bulletnav.viz.plots.draw_events`).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from bulletnav.files import save_figure
from bulletnav.viz.fleet_robots import agent_point, fleet_view, robot_colour, sorted_agents
from bulletnav.viz.movers import hex_colour
from bulletnav.viz.plots import MoverTrack, draw_layout, draw_mover_tracks, dynamic_handles
from bulletnav.viz.plots import draw_events as plot_events


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
        fleet = self._fleet = fleet_view(env)
        stations = env.stations
        agents = sorted_agents(infos)
        self.track = t = FleetTrack(
            layout=fleet.layout, pick=tuple(stations.pick) if stations else (), drop=tuple(stations.drop) if stations else ())
        for a in agents:
            x, y, yaw = (float(v) for v in infos[a]["pose"])
            t.paths.append([(x, y)])
            t.starts.append((x, y, yaw))
            t.legs.append([])
        self._last(infos)
        if fleet.dynamic:
            t.movers = [MoverTrack(m.kind, tuple(float(v) for v in m.size), tuple(agent_point(q) for q in m.path))
                        for m in fleet.movers]
            self._record_dynamic()

    def update(self, infos: dict[str, Any]) -> None:
        t = self.track
        for i, a in enumerate(sorted_agents(infos)):
            info = infos[a]
            xy = agent_point(info["pose"])
            t.paths[i].append(xy)
            while len(t.legs[i]) < int(info["legs_completed"]):  # legs alternate: pick, drop, pick, ...
                t.legs[i].append(("pick" if len(t.legs[i]) % 2 == 0 else "drop", xy))
        self._last(infos)
        t.duration_s = float(self._fleet.time_s)
        if t.movers or self._fleet.dynamic:
            self._record_dynamic()

    def _last(self, infos: dict[str, Any]) -> None:
        t = self.track
        agents = sorted_agents(infos)
        t.goals = [(infos[a]["errand"]["leg"], int(infos[a]["errand"]["id"]), agent_point(infos[a]["goal"])) for a in agents]
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


__all__ = ["FleetTrack", "FleetTrackLog", "fleet_figure", "plot_fleet"]
