"""The benchmark's metrics: one definition each, per episode and per cell with 95 % intervals.

Per episode, :class:`EpisodeTrace` collects what a metric needs from the steps (ground-truth
pose, the movers in view, the shield's decisions) while :func:`bulletnav.evaluation.run_episodes`
runs it; :func:`episode_metrics` turns trace and :class:`~bulletnav.evaluation.EpisodeResult`
into one flat row. Per cell (a world x a controller), :func:`cell_summary` gives each metric's
mean over episodes with a 95 % percentile-bootstrap interval (fixed-seed resampling, so a
summary is a pure function of its rows).

Every metric, with its source (the row keys):
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from bulletnav.barn.metric import INFO_KEYS, barn_metric
from bulletnav.evaluation import INTIMATE_M, NEAR_MISS_M, PERSONAL_M, EpisodeResult

STOPPED_MPS = 0.05
"""The robot counts as stopped below this speed (m/s): a person then approaches it, not it them."""
BOOTSTRAP_RESAMPLES = 2000
"""Resamples of each cell's 95 % percentile-bootstrap interval."""
BOOTSTRAP_SEED = 20261125
"""Seed of the bootstrap's resampling: intervals are reproducible to the bit."""

METRICS: dict[str, str] = {
    "success": "1 if the robot reached the goal (every goal of a mission) before the time limit, without a collision.",
    "collision": "1 if the episode ended in a collision (any kind).",
    "collision_static": "1 if it ended touching a wall or obstacle.",
    "collision_mover": "1 if it ended touching a forklift (a mover that is not a person).",
    "collision_person": "1 if it ended touching a worker (workers are people).",
    "timeout": "1 if the time limit ended it (neither success nor collision).",
    "spl": "Success weighted by path length, S l / max(p, l), l the shortest path for the robot's disc "
           "(Anderson et al. 2018, as Habitat scores it).",
    "sct": "Success weighted by completion time, S t* / max(t, t*), t* the time-optimal drive of the shortest path "
           "at the robot's limits (top speed, acceleration; Yokoyama et al. 2021).",
    "barn_score": "S t_opt / clip(t, 2 t_opt, 8 t_opt), t_opt = shortest path / top speed: the BARN challenge's "
                  "score (Perille et al. 2020; bulletnav.barn.metric.barn_metric, as BARN's run.py computes it) with "
                  "bulletnav's shortest path and the episode's time.",
    "time_s": "Simulated seconds to the episode's end.",
    "path_length_m": "Metres driven (ground truth).",
    "path_irregularity": "Total turning over distance driven, sum |d heading| / path length (rad/m): "
                         "Arena-Rosnav's angle-over-length smoothness measure.",
    "jerk": "Mean magnitude of the third time derivative of the robot's position (m/s^3), finite differences "
            "at the control rate (Arena-Rosnav's jerk).",
    "min_separation_m": "Smallest distance from the robot's outline to a mover over the episode (m; empty without movers).",
    "near_miss_rate": f"Share of steps with a mover closer than {NEAR_MISS_M} m to the robot's outline.",
    "intimate_robot_s": f"Seconds the moving robot spends within {INTIMATE_M} m of a person (HuNavSim's intimate "
                        "zone, centre to centre): the robot's intrusion.",
    "intimate_person_s": f"Seconds within {INTIMATE_M} m of a person while the robot is stopped (speed under "
                         f"{STOPPED_MPS} m/s): the person's approach.",
    "personal_robot_s": f"Seconds the moving robot spends within {PERSONAL_M} m of a person (HuNavSim's personal zone).",
    "personal_person_s": f"Seconds within {PERSONAL_M} m of a person while the robot is stopped.",
    "shield_rate": "Share of steps on which the safety shield replaced the controller's command.",
}
"""Metric name -> its definition and source (the docs page and the report print these)."""

__doc__ += "\n".join(f"- ``{name}``: {text}" for name, text in METRICS.items())

BARN_KEYS = INFO_KEYS
"""What a row of a ``bulletnav/BARN-v0`` episode adds (from the last step's ``info``): the BARN
world, BARN's clock (s; it starts at the first 0.1 m of motion) and BARN's score of the episode
as the env reports it (t_opt from BARN's reference path measured from run.py's start (-2.25, 3),
:func:`bulletnav.barn.metric.barn_metric`; the BARN tables recompute it from report_test.py's
start (-2, 3), :data:`bulletnav.benchmark.barn.METRIC_LABEL`). Rows of other worlds have none."""

RATE_METRICS = ("success", "collision", "collision_static", "collision_mover", "collision_person", "timeout")
"""Metrics that are 0/1 per episode (their cell mean is a rate)."""


@dataclass
class EpisodeTrace:
    """What the metrics read from one episode's steps (see :meth:`record`)."""

    dt: float
    """Seconds per control step."""
    top_speed: float
    """The robot's top forward speed (m/s)."""
    xy: list[tuple[float, float]] = field(default_factory=list)
    yaw: list[float] = field(default_factory=list)
    person_distances: list[float] = field(default_factory=list)
    """Per step, the distance (m, centre to centre) to the nearest worker; inf without workers."""
    hit: str | None = None
    """Which kind the robot touched at the end: ``"static"``, ``"mover"``, ``"person"`` or None."""
    barn: dict[str, Any] = field(default_factory=dict)
    """In ``bulletnav/BARN-v0``: the last step's ``world_idx``, ``barn_time_s`` and ``barn_metric``
    (BARN's world, clock and score, :mod:`bulletnav.barn.task`); empty elsewhere."""

    def record(self, scene: Any, info: dict[str, Any]) -> None:
        """One step (or the reset) from the read-only scene view and ``info``."""
        x, y, yaw = scene.pose
        self.xy.append((x, y))
        self.yaw.append(yaw)
        movers = scene.movers
        persons = [m for m in movers if m.kind == "worker"]
        self.person_distances.append(min((math.hypot(m.pose[0] - x, m.pose[1] - y) for m in persons), default=math.inf))
        if info.get("collision"):
            self.hit = _collision_kind(info, movers, (x, y))
        if "barn_time_s" in info:
            self.barn = {key: info[key] for key in BARN_KEYS if key in info}


def _collision_kind(info: dict[str, Any], movers: tuple, xy: tuple[float, float]) -> str:
    """``"static"``, or the kind of mover the robot touches: the mover whose footprint comes
    nearest to the robot's centre (forklift: its rectangle; worker: its disc)."""
    if info.get("collision_with") != "dynamic" or not movers:
        return "static"

    def gap(m) -> float:
        dx, dy = xy[0] - m.pose[0], xy[1] - m.pose[1]
        if m.kind == "worker":
            return math.hypot(dx, dy) - m.size[0] / 2
        c, s = math.cos(m.pose[2]), math.sin(m.pose[2])
        lx, ly = abs(c * dx + s * dy) - m.size[0] / 2, abs(-s * dx + c * dy) - m.size[1] / 2
        return math.hypot(max(lx, 0.0), max(ly, 0.0))

    return "person" if min(movers, key=gap).kind == "worker" else "mover"


def drive_time(length: float, top_speed: float, accel: float) -> float:
    """Seconds to drive ``length`` m from rest to rest at most ``top_speed`` (m/s) and
    ``accel`` (m/s^2): a trapezoidal speed profile (triangular when too short to reach top speed)."""
    if length <= 0:
        return 0.0
    if length >= top_speed ** 2 / accel:
        return length / top_speed + top_speed / accel
    return 2.0 * math.sqrt(length / accel)


def episode_metrics(result: EpisodeResult, trace: EpisodeTrace, accel: float) -> dict[str, Any]:
    """One flat row of :data:`METRICS` (plus the episode's identity) for an episode."""
    t = result.steps * trace.dt
    shortest = result.shortest_path
    ok = result.success and shortest > 0 and math.isfinite(shortest)
    t_star = drive_time(shortest, trace.top_speed, accel) if ok else math.nan
    t_opt = shortest / trace.top_speed if ok else math.nan
    xy = np.asarray(trace.xy, dtype=float)
    yaw = np.unwrap(np.asarray(trace.yaw, dtype=float))
    turning = float(np.abs(np.diff(yaw)).sum()) if len(yaw) > 1 else 0.0
    jerk = math.nan
    if len(xy) >= 4:
        j = np.diff(xy, n=3, axis=0) / trace.dt ** 3
        jerk = float(np.mean(np.hypot(j[:, 0], j[:, 1])))
    speeds = np.hypot(*np.diff(xy, axis=0).T) / trace.dt if len(xy) > 1 else np.zeros(0)
    # step k's zone time: the distance after step k, the robot's speed over step k
    person = np.asarray(trace.person_distances[1:], dtype=float)
    moving = speeds >= STOPPED_MPS
    zones = {}
    for name, radius in (("intimate", INTIMATE_M), ("personal", PERSONAL_M)):
        inside = person < radius
        zones[f"{name}_robot_s"] = float(np.sum(inside & moving) * trace.dt)
        zones[f"{name}_person_s"] = float(np.sum(inside & ~moving) * trace.dt)
    hit = trace.hit if result.collision else None
    has_movers = not math.isnan(result.min_separation_m)
    return {
        "episode": result.episode, "seed": result.seed,
        "success": int(result.success), "collision": int(result.collision),
        "collision_static": int(hit == "static" or (result.collision and hit is None)),
        "collision_mover": int(hit == "mover"), "collision_person": int(hit == "person"),
        "timeout": int(result.timeout),
        "spl": float(result.spl),
        "sct": float(t_star / max(t, t_star)) if ok else 0.0,
        "barn_score": barn_metric(True, t, t_opt) if ok else 0.0,
        "time_s": t, "path_length_m": float(result.path_length),
        "path_irregularity": turning / result.path_length if result.path_length > 1e-6 else 0.0,
        "jerk": jerk,
        "min_separation_m": float(result.min_separation_m) if has_movers else math.nan,
        "near_miss_rate": result.near_miss_steps / result.steps if result.steps else 0.0,
        **zones,
        "shield_rate": result.shield_steps / result.steps if result.steps else 0.0,
        "steps": result.steps, "shortest_path_m": float(shortest), "reward": float(result.reward),
        "goals_reached": result.goals_reached, "goals_total": result.goals_total,
        "path": [[round(float(x), 3), round(float(y), 3)] for x, y in xy[:: max(1, len(xy) // 200)]],
        **trace.barn,
    }


def bootstrap_interval(values: np.ndarray, resamples: int = BOOTSTRAP_RESAMPLES,
                       seed: int = BOOTSTRAP_SEED) -> tuple[float, float]:
    """95 % percentile-bootstrap interval of the mean of ``values`` (NaN entries dropped)."""
    values = values[~np.isnan(values)]
    if len(values) == 0:
        return math.nan, math.nan
    rng = np.random.default_rng(seed)
    means = values[rng.integers(0, len(values), size=(resamples, len(values)))].mean(axis=1)
    lo, hi = np.percentile(means, [2.5, 97.5])
    return float(lo), float(hi)


def cell_summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """Per metric of :data:`METRICS`: ``{"mean", "lo", "hi", "n"}`` over the rows (NaN rows,
    such as separations in worlds without movers, left out; ``mean`` None when none is left)."""
    out: dict[str, Any] = {"episodes": len(rows)}
    for name in METRICS:
        values = np.array([r[name] for r in rows], dtype=float)
        kept = values[~np.isnan(values)]
        if len(kept) == 0:
            out[name] = {"mean": None, "lo": None, "hi": None, "n": 0}
            continue
        lo, hi = bootstrap_interval(values)
        out[name] = {"mean": float(kept.mean()), "lo": lo, "hi": hi, "n": int(len(kept))}
    return out
