"""Fleet metrics, per episode and over episodes, and the seeded episode runner.

:class:`FleetTrace` records what the metrics need at every step (robot positions, distances
to goals, completed legs and errands, workers' positions); :func:`episode_metrics` turns a
trace and the last infos into one flat row; :func:`summarize` aggregates rows;
:func:`run_fleet_episodes` runs seeded episodes of a controller.

Every metric (row keys):
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bulletnav.evaluation import INTIMATE_M, PERSONAL_M

DEADLOCK_WINDOW_S = 20.0
"""A robot that has not progressed for this long (s) is stalled."""
DEADLOCK_RADIUS_M = 2.0
"""Stalled robots this close (m, centre to centre) to each other are deadlocked together."""
PROGRESS_M = 0.1
"""Progress: the distance to the current goal falls this much (m) below its best so far this leg."""
NEAR_MISS_CENTRES_M = 0.6
"""Two robots closer than this (m, centre to centre: their 0.2 m discs 0.2 m apart) are a near miss."""
TYPICAL_ERRAND_S = 70.0
"""A robot's errand (assignment to drop) takes about this long in the fleet's aisle warehouse: the
mean ``errand_time_s`` of 8 robots over 120 s episodes is 64.6-70.8 s in every comparison of
docs/results/fleet_fresh_seeds. An episode shorter than that ends before a robot can be expected
to finish one, so its errands per hour (0.0 for most such runs) say how early the run was cut,
not how the fleet works: the tables leave the rate out and say why (``--json`` keeps the numbers)."""


def rate_counts(duration_s: float) -> bool:
    """Whether episodes of ``duration_s`` seconds are long enough for errands per hour to mean
    something (at least :data:`TYPICAL_ERRAND_S`)."""
    return duration_s >= TYPICAL_ERRAND_S

METRICS: dict[str, str] = {
    "errands": "Errands completed (pick then drop), whole fleet.",
    "legs": "Legs completed (a pick or a drop reached), whole fleet.",
    "throughput_per_hour": "Errands completed per hour of simulated time, whole fleet.",
    "throughput_per_robot_per_hour": "Errands completed per hour per robot.",
    "collisions_robot_robot": "Robot-robot collisions: each robot counts its own (a collision of two robots counts "
                              "twice when both were moving into it, once when one was serving a penalty).",
    "collisions_static": "Collisions with walls and obstacles (pallet events included), all robots.",
    "collisions_mover": "Collisions with forklifts, all robots.",
    "collisions_person": "Collisions with walking workers, all robots.",
    "deadlocks": f"Deadlock events: two or more robots, each within {DEADLOCK_RADIUS_M} m of another of them, none "
                 f"progressing for {DEADLOCK_WINDOW_S} s. A robot progresses when its distance to its current goal "
                 "along the floor plan (the shortest path for its disc past racks and walls, RouteDistance) "
                 f"falls at least {PROGRESS_M} m below the smallest it has been since the leg began, or when a leg "
                 "completes (the episode's start counts as progress). An event is counted once, when such a group "
                 "forms with no robot already in an event; a robot leaves its event when it progresses.",
    "errand_time_s": "Mean simulated seconds from an errand's assignment (episode start or the previous errand's "
                     "drop) to its drop; NaN when no errand was completed.",
    "min_separation_m": "Smallest distance between two robots' centres over the episode (m); NaN with one robot.",
    "near_misses": f"Times two robots came closer than {NEAR_MISS_CENTRES_M} m (centre to centre): entries into that range, "
                   "per pair.",
    "intimate_s": f"Robot-seconds within {INTIMATE_M} m of a worker (HuNavSim's intimate zone, centre to centre), "
                  "summed over robots.",
    "personal_s": f"Robot-seconds within {PERSONAL_M} m of a worker (HuNavSim's personal zone), summed over robots.",
    "shield_rate": "Share of robot-steps on which the safety shield replaced the command (0 without a shield).",
}
"""Metric name -> its definition."""

__doc__ += "\n".join(f"- ``{name}``: {text}" for name, text in METRICS.items())

COUNT_METRICS = ("errands", "legs", "collisions_robot_robot", "collisions_static", "collisions_mover",
                 "collisions_person", "deadlocks", "near_misses")
"""Metrics summed over episodes in :func:`summarize` (the others are averaged, separation is the minimum)."""


@dataclass
class FleetTrace:
    """What the metrics read from one episode (see :meth:`record`)."""

    dt: float
    """Seconds per control step."""
    xy: list[np.ndarray] = field(default_factory=list)
    """Per step, the robots' positions (N, 2) m."""
    distance: list[np.ndarray] = field(default_factory=list)
    """Per step, each robot's distance to its current goal (m): along the floor plan with
    :attr:`route`, else the straight line."""
    legs: list[np.ndarray] = field(default_factory=list)
    """Per step, each robot's legs completed so far."""
    errands: list[np.ndarray] = field(default_factory=list)
    """Per step, each robot's errands completed so far."""
    person: list[np.ndarray] = field(default_factory=list)
    """Per step, each robot's distance (m, centre to centre) to the nearest worker; inf without workers."""
    route: Callable[[tuple[float, float], float, float], float] | None = None
    """``route(goal, x, y)``: the distance (m) along the floor plan to ``goal``
    (:class:`RouteDistance`); without it :attr:`distance` holds straight-line distances."""

    def record(self, infos: dict[str, dict[str, Any]], workers: list[tuple[float, float]] = ()) -> None:
        """One step (or the reset) from the agents' infos and the workers' positions."""
        agents = sorted(infos, key=lambda a: int(a.rsplit("_", 1)[-1]))
        xy = np.array([[float(infos[a]["pose"][0]), float(infos[a]["pose"][1])] for a in agents])
        self.xy.append(xy)
        if self.route is None:
            self.distance.append(np.array([float(infos[a]["distance_to_goal"]) for a in agents]))
        else:
            self.distance.append(np.array([self.route((float(infos[a]["goal"][0]), float(infos[a]["goal"][1])),
                                                      xy[i, 0], xy[i, 1]) for i, a in enumerate(agents)]))
        self.legs.append(np.array([int(infos[a]["legs_completed"]) for a in agents]))
        self.errands.append(np.array([int(infos[a]["errands_completed"]) for a in agents]))
        if len(workers):
            w = np.asarray(workers, dtype=float)
            self.person.append(np.hypot(xy[:, None, 0] - w[None, :, 0], xy[:, None, 1] - w[None, :, 1]).min(axis=1))
        else:
            self.person.append(np.full(len(agents), np.inf))


class RouteDistance:
    """Distance (m) along the floor plan from a point to a goal: the shortest path for the
    robot's disc over the layout's free space (8-connected 0.1 m cells, Dijkstra from the goal,
    one field per goal as it first appears; :class:`~bulletnav.tasks.guidance.PathGuide` with
    no wall cost). Racks and walls only: movers and pallet events are not on the plan. Where
    no free cell is near the point, the straight line.

    Args:
        view: the fleet's :class:`~bulletnav.fleet.view.FleetView` (after a reset: its layout).
    """

    def __init__(self, view: Any) -> None:
        from bulletnav.tasks.guidance import PathGuide

        self.guide = PathGuide(view.free_space, view.geometry.radius, reach=5, wall_cost=0.0)
        self.fields: dict[tuple[float, float], int] = {}

    def __call__(self, goal: tuple[float, float], x: float, y: float) -> float:
        index = self.fields.get(goal)
        if index is None:
            index = self.fields[goal] = self.guide.add_goal(goal)
        cost = self.guide.query(index, x, y)[0]
        return cost if math.isfinite(cost) else math.hypot(goal[0] - x, goal[1] - y)


def deadlock_events(xy: np.ndarray, distance: np.ndarray, legs: np.ndarray, dt: float,
                    window_s: float = DEADLOCK_WINDOW_S, radius_m: float = DEADLOCK_RADIUS_M,
                    progress_m: float = PROGRESS_M) -> list[tuple[float, tuple[int, ...]]]:
    """Deadlock events in a trace (see ``METRICS["deadlocks"]``): ``(time s, robots)`` at each
    event's start.

    Args:
        xy: positions (T, N, 2) m, one row per step (row 0 the reset).
        distance: distances to the current goals (T, N) m.
        legs: legs completed so far (T, N).
        dt: seconds per step.
    """
    xy, distance, legs = np.asarray(xy, float), np.asarray(distance, float), np.asarray(legs)
    steps, n = distance.shape
    best = distance[0].copy()
    last = np.zeros(n)  # time of each robot's last progress
    in_event = np.zeros(n, dtype=bool)
    events = []
    for k in range(steps):
        t = k * dt
        if k:
            done = legs[k] != legs[k - 1]
            better = distance[k] <= best - progress_m
            moved = done | better
            best = np.where(done, distance[k], np.where(better, distance[k], best))
            last[moved] = t
            in_event[moved] = False
        stalled = (t - last) >= window_s - 1e-9
        idx = np.flatnonzero(stalled)
        if len(idx) < 2:
            continue
        # groups of stalled robots linked by distance < radius (connected components)
        seen: set[int] = set()
        for i in idx:
            if i in seen:
                continue
            group, todo = [], [int(i)]
            seen.add(int(i))
            while todo:
                a = todo.pop()
                group.append(a)
                for b in idx:
                    b = int(b)
                    if b not in seen and math.dist(xy[k, a], xy[k, b]) < radius_m:
                        seen.add(b)
                        todo.append(b)
            if len(group) >= 2 and not in_event[group].any():
                events.append((t, tuple(sorted(group))))
                in_event[group] = True
    return events


def errand_times(errands: np.ndarray, dt: float) -> list[float]:
    """Seconds of every completed errand: from its assignment (the start, or the step the
    robot's previous errand completed) to the step it completed. ``errands`` (T, N): counts so far."""
    errands = np.asarray(errands)
    out = []
    for i in range(errands.shape[1]):
        began = 0.0
        for k in np.flatnonzero(np.diff(errands[:, i]) > 0) + 1:
            out.append(k * dt - began)
            began = k * dt
    return out


def separation(xy: np.ndarray, threshold: float = NEAR_MISS_CENTRES_M) -> tuple[float, int]:
    """(smallest centre distance over steps and pairs m, entries of pairs into ``threshold``)
    of positions (T, N, 2); (NaN, 0) with fewer than 2 robots. A pair closer than the threshold
    at the first step counts as one entry."""
    xy = np.asarray(xy, float)
    if xy.ndim != 3 or xy.shape[1] < 2:
        return math.nan, 0
    i, j = np.triu_indices(xy.shape[1], k=1)
    d = np.hypot(xy[:, i, 0] - xy[:, j, 0], xy[:, i, 1] - xy[:, j, 1])  # (T, pairs)
    close = d < threshold
    entries = int(close[0].sum() + (close[1:] & ~close[:-1]).sum())
    return float(d.min()), entries


def episode_metrics(trace: FleetTrace, infos: dict[str, dict[str, Any]], duration_s: float,
                    shield_rate: float = 0.0) -> dict[str, Any]:
    """One flat row of :data:`METRICS` for an episode of ``duration_s`` simulated seconds."""
    n = len(infos)
    total = lambda key: int(sum(int(info[key]) for info in infos.values()))  # noqa: E731
    errands = total("errands_completed")
    hours = duration_s / 3600.0
    xy = np.stack(trace.xy)
    min_sep, near = separation(xy)
    times = errand_times(np.stack(trace.errands), trace.dt)
    events = deadlock_events(xy, np.stack(trace.distance), np.stack(trace.legs), trace.dt)
    person = np.stack(trace.person)[1:]  # step k's zone time: the distance after step k
    return {
        "robots": n, "duration_s": duration_s,
        "errands": errands, "legs": total("legs_completed"),
        "throughput_per_hour": errands / hours, "throughput_per_robot_per_hour": errands / hours / n,
        "collisions_robot_robot": total("collisions_robot"), "collisions_static": total("collisions_static"),
        "collisions_mover": total("collisions_mover"), "collisions_person": total("collisions_person"),
        "deadlocks": len(events), "deadlock_events": [[round(t, 2), list(g)] for t, g in events],
        "errand_time_s": float(np.mean(times)) if times else math.nan,
        "min_separation_m": min_sep, "near_misses": near,
        "intimate_s": float((person < INTIMATE_M).sum() * trace.dt),
        "personal_s": float((person < PERSONAL_M).sum() * trace.dt),
        "shield_rate": float(shield_rate),
    }


def summarize(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Over episodes: counts (:data:`COUNT_METRICS`) summed, ``min_separation_m`` the minimum,
    every other metric the mean (NaN entries left out; NaN when none is left). Also the mean
    errands per episode."""
    out: dict[str, Any] = {"episodes": len(rows)}
    for name in METRICS:
        values = np.array([r[name] for r in rows], dtype=float)
        kept = values[~np.isnan(values)]
        if name in COUNT_METRICS:
            out[name] = int(values.sum())
        elif len(kept) == 0:
            out[name] = math.nan
        elif name == "min_separation_m":
            out[name] = float(kept.min())
        else:
            out[name] = float(kept.mean())
    out["errands_per_episode"] = out["errands"] / len(rows) if rows else math.nan
    return out


def run_fleet_episodes(env_kwargs: dict[str, Any], controller_factory: Callable[[Any], Any], episodes: int,
                       seed: int = 0, on_step: Callable[[Any, dict], None] | None = None) -> dict[str, Any]:
    """Run ``episodes`` fleet episodes, episode k reset with seed ``seed + k``.

    Args:
        env_kwargs: the :class:`~bulletnav.fleet.env.FleetEnv`'s keyword arguments.
        controller_factory: ``env -> controller`` (a :class:`~bulletnav.fleet.controllers.FleetController`),
            called once; the controller is reset at every episode.
        episodes: how many (>= 1).
        seed: the first episode's seed.
        on_step: called with ``(env, infos)`` after the reset and every step (optional).

    Returns:
        ``{"episodes": [row, ...], "summary": summarize(rows)}``; each row also carries
        ``episode``, ``seed`` and ``wall_s``.
    """
    import time

    from bulletnav.errors import ConfigError
    from bulletnav.fleet.env import FleetEnv
    from bulletnav.fleet.view import FleetView

    if isinstance(episodes, bool) or not isinstance(episodes, int) or episodes < 1:
        raise ConfigError(f"episodes must be a whole number >= 1, got {episodes!r}")
    env = FleetEnv(**env_kwargs)
    rows = []
    try:
        controller = controller_factory(env)
        view = FleetView(env)
        dt = view.control_dt
        for k in range(episodes):
            t0 = time.perf_counter()
            observations, infos = env.reset(seed=seed + k)
            controller.reset(infos)
            trace = FleetTrace(dt, route=RouteDistance(view))
            trace.record(infos, _workers(view))
            if on_step is not None:
                on_step(env, infos)
            while env.agents:
                observations, _, _, _, infos = env.step(controller.act(observations, infos))
                trace.record(infos, _workers(view))
                if on_step is not None:
                    on_step(env, infos)
            steps = getattr(controller, "steps", 0)
            rate = getattr(controller, "interventions", 0) / steps if steps else 0.0
            row = {"episode": k, "seed": seed + k,
                   **episode_metrics(trace, infos, env.fleet_config.duration_s, rate),
                   "wall_s": time.perf_counter() - t0}
            rows.append(row)
    finally:
        env.close()
    return {"episodes": rows, "summary": summarize(rows)}


def _workers(view: Any) -> list[tuple[float, float]]:
    return [(m.pose[0], m.pose[1]) for m in view.movers if m.kind == "worker"]


__all__ = ["COUNT_METRICS", "DEADLOCK_RADIUS_M", "DEADLOCK_WINDOW_S", "METRICS", "NEAR_MISS_CENTRES_M", "PROGRESS_M",
           "FleetTrace", "RouteDistance", "deadlock_events", "episode_metrics", "errand_times", "run_fleet_episodes", "separation",
           "summarize"]
