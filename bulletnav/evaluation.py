"""Scoring episodes the same way for every controller, classical or learned.

Episode ``k`` of a run with seed ``S`` is ``env.reset(seed=S + k)``: the same warehouse,
start and goal for every controller given the same env settings. Every controller runs
through :func:`run_episodes` as a :class:`~bulletnav.policy.Policy`, and is scored from
``info`` and the read-only scene view only. SPL is success weighted by path length
(Anderson et al. 2018, as in Habitat): ``S_i * l_i / max(p_i, l_i)`` with ``l_i`` the
shortest collision-free path on the true map for the robot's disc and ``p_i`` the driven
length.

Safety metrics read two optional ``info`` keys that envs with moving obstacles report:
``nearest_mover_m`` (metres from the robot's outline to the nearest mover, ``inf`` when
there is none) and ``collision_with`` (``"static"``, ``"dynamic"`` or None). Static worlds
leave both out: a collision there is a static one, and an episode has no separation to
movers (NaN) and no near misses. Behind a safety shield (``ShieldWrapper``, which reports
``info["shield"]``, or a ``SafetyShield`` policy, read through its ``decision``) each
episode also counts the steps the shield replaced the command and by how much.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import InitVar, asdict, dataclass, field
from typing import Any

import numpy as np

from bulletnav.barn.metric import INFO_KEYS
from bulletnav.geometry import robot_geometry
from bulletnav.planning import OccupancyGrid, astar
from bulletnav.policy import Policy
from bulletnav.sim.layout import Layout


@dataclass
class EpisodeResult:
    episode: int
    seed: int
    initial_distance: float
    """Straight-line start-goal distance (m)."""
    shortest_path: float
    """Shortest collision-free path on the true map (m)."""
    steps: int
    reward: float
    final_distance: float
    path_length: float
    """Metres driven (ground truth)."""
    success: bool
    collision: bool
    spl: float
    sim_time: float
    """Simulated seconds to the end of the episode."""
    wall_time: float
    plan_ms: list[float] = field(default_factory=list)
    replans: int = 0
    collision_static: bool = False
    """The episode ended in a collision with the static world (every collision where the env reports no movers)."""
    collision_dynamic: bool = False
    """The episode ended in a collision with a mover (``info["collision_with"] == "dynamic"``)."""
    timeout: bool = False
    """Neither success nor collision: the time limit ended the episode."""
    near_miss_steps: int = 0
    """Steps with ``info["nearest_mover_m"] < NEAR_MISS_M``."""
    goals_total: int = 1
    """Goals of the episode (missions: K)."""
    goals_reached: int = 0
    """Goals reached (1 on a successful single-goal episode)."""
    ppl: float = 0.0
    """Progress (goals reached / goals) x optimal tour / max(driven, optimal tour); SPL for one goal."""
    shield_steps: int = 0
    """Steps on which a safety shield replaced the command (``info["shield"]["intervened"]``)."""
    shield_change: float = 0.0
    """Sum over those steps of the shield's change in wheel rim speeds (m/s)."""
    min_separation: InitVar[float] = math.nan
    # Not a field: NaN (no movers) has no strict-JSON form, and the per-episode rows
    # (``asdict``, ``summarize``'s ``per_episode``, the CLI's JSON) stay plain numbers.
    barn: InitVar[dict[str, Any] | None] = None
    # Not a field either: only BARN-v0's episodes have it, and the other envs' rows stay as they were.

    def __post_init__(self, min_separation: float, barn: dict[str, Any] | None) -> None:
        self._min_separation_m = float(min_separation)
        self._barn = dict(barn) if barn else None

    @property
    def barn_info(self) -> dict[str, Any] | None:
        """In ``bulletnav/BARN-v0``: the last ``info``'s BARN world, clock (s) and score
        (:data:`bulletnav.barn.metric.INFO_KEYS`); None elsewhere."""
        return self._barn

    @property
    def min_separation_m(self) -> float:
        """Smallest ``info["nearest_mover_m"]`` over the episode's steps (m); NaN when it had no movers."""
        return self._min_separation_m


SAFETY_KEYS = ("collision_static_rate", "collision_dynamic_rate", "timeout_rate", "min_separation_m", "near_miss_rate",
               "episode_time_s")
"""The safety entries of :func:`summarize`."""

SHIELD_KEYS = ("shield_rate", "shield_change_mean")
"""The safety shield's entries of :func:`summarize` (0 and NaN without a shield)."""

NEAR_MISS_M = 0.2
"""A step is a near miss when the robot's outline comes closer than this to a mover (m)."""
INTIMATE_M = 0.45
"""HuNavSim's intimate zone: within this distance (m, centre to centre) of a person."""
PERSONAL_M = 1.2
"""HuNavSim's personal zone: within this distance (m, centre to centre) of a person."""


class SafetyTracker:
    """Per-episode safety figures from the ``info`` dicts of its steps (see the module docstring)."""

    def __init__(self) -> None:
        self.min_separation_m = math.inf
        self.near_miss_steps = 0

    def step(self, info: dict) -> None:
        d = info.get("nearest_mover_m")
        if d is None:
            return
        d = float(d)
        if d < self.min_separation_m:
            self.min_separation_m = d
        if d < NEAR_MISS_M:
            self.near_miss_steps += 1

    def result(self, final_info: dict) -> dict[str, Any]:
        """The :class:`EpisodeResult` arguments ``collision_static``, ``collision_dynamic``,
        ``timeout``, ``near_miss_steps`` and ``min_separation`` of an episode whose last step
        returned ``final_info``."""
        collision = bool(final_info["collision"])
        dynamic = collision and final_info.get("collision_with") == "dynamic"
        return {
            "collision_static": collision and not dynamic,
            "collision_dynamic": dynamic,
            "timeout": not bool(final_info["is_success"]) and not collision,
            "near_miss_steps": self.near_miss_steps,
            "min_separation": self.min_separation_m if math.isfinite(self.min_separation_m) else math.nan,
        }


def shortest_path_length(layout: Layout, start: tuple[float, float], goal: tuple[float, float],
                         radius: float | None = None, resolution: float = 0.05) -> float:
    """Length (m) of the shortest path for a disc of ``radius`` (default: the shipped robot's,
    ``RobotGeometry.radius``) on the true map: A* on a fine grid, then shortened by
    line-of-sight shortcuts. NaN when no path exists."""
    if radius is None:
        radius = robot_geometry().radius
    occ = layout.occupancy(resolution, inflate=radius)
    xs, ys = layout.grid_axes(resolution)
    grid = OccupancyGrid(occ, resolution, (float(xs[0]), float(ys[0])))
    # the start and goal have clearance by construction, but a user-placed one may not
    for point in (start, goal):
        ix, iy = grid.world_to_cell(point)
        occ[ix, iy] = False
    path = astar(OccupancyGrid(occ, resolution, grid.origin), start, goal)
    if path is None:
        return math.nan
    pts = [path[0]]
    i = 0
    free = OccupancyGrid(occ, resolution, grid.origin)
    while i < len(path) - 1:
        j = len(path) - 1
        while j > i + 1 and not free.segment_free(path[i], path[j]):
            j -= 1
        pts.append(path[j])
        i = j
    return float(sum(math.dist(a, b) for a, b in zip(pts[:-1], pts[1:])))


def optimal_tour_length(layout: Layout, start: tuple[float, float], goals, order: str = "free",
                        radius: float = 0.2) -> float:
    """Length (m) of the shortest tour from ``start`` through ``goals``: the shortest path
    between every pair (:func:`shortest_path_length`), then the best order by dynamic
    programming over subsets (``free``) or the given order (``fixed``), exact for up to 8 goals."""
    from bulletnav.planning.tour import tour_through

    points = [tuple(start), *(tuple(g) for g in goals)]
    length, _ = tour_through(points, lambda a, b: shortest_path_length(layout, a, b, radius=radius), order)
    return length


def run_episodes(env, policy: Policy, episodes: int, seed: int,
                 on_episode: Callable[[EpisodeResult], None] | None = None,
                 on_step: Callable[[Any, dict], None] | None = None,
                 on_reset: Callable[[Any, dict], None] | None = None,
                 reset_options: Callable[[int], dict[str, Any] | None] | None = None) -> list[EpisodeResult]:
    """Run ``episodes`` episodes of ``policy`` in ``env`` (made with ``gym.make``): episode
    ``k`` is ``env.reset(seed=seed + k)``, with ``options=reset_options(k)`` when given (e.g.
    BARN-v0's ``{"world_idx": N}``).

    Hooks (for recording and drawing; they must only read): ``on_reset(env, info)`` after
    each reset, ``on_step(env, info)`` after each step, ``on_episode(result)`` at each end.
    """
    results = []
    scene = env.unwrapped.scene
    for k in range(episodes):
        obs, info = env.reset(seed=seed + k, options=None if reset_options is None else reset_options(k))
        policy.reset(info)
        if on_reset is not None:
            on_reset(env, info)
        start = scene.start
        goals = info.get("goals") or (scene.goal,)
        if len(goals) > 1:  # a mission: the optimal tour through its goals
            shortest = optimal_tour_length(scene.layout, (start[0], start[1]), goals, info.get("goal_order", "free"),
                                           radius=scene.geometry.radius)
        else:
            shortest = shortest_path_length(scene.layout, (start[0], start[1]), scene.goal, radius=scene.geometry.radius)
        total, steps = 0.0, 0
        safety = SafetyTracker()
        shield_steps, shield_change = 0, 0.0
        t0 = time.perf_counter()
        while True:
            action = policy.act(obs, info)
            obs, reward, terminated, truncated, info = env.step(action)
            total += reward
            steps += 1
            safety.step(info)
            veto = _shield_decision(info, policy)
            if veto is not None and veto["intervened"]:
                shield_steps += 1
                shield_change += float(veto["change"])
            if on_step is not None:
                on_step(env, info)
            if terminated or truncated:
                break
        success = bool(info["is_success"])
        driven = float(info["path_length"])
        spl = (shortest / max(driven, shortest)) if success and shortest > 0 else 0.0
        reached = int(info.get("goals_reached", int(success)))
        progress = reached / len(goals)
        ppl = progress * shortest / max(driven, shortest) if shortest > 0 else 0.0
        result = EpisodeResult(
            episode=k + 1, seed=seed + k, initial_distance=float(info["initial_distance"]), shortest_path=shortest,
            steps=steps, reward=total, final_distance=float(info["distance_to_goal"]), path_length=driven,
            success=success, collision=bool(info["collision"]), spl=spl,
            sim_time=steps * scene.control_dt, wall_time=time.perf_counter() - t0,
            plan_ms=[t * 1e3 for t in getattr(policy, "plan_times", [])], replans=int(getattr(policy, "replans", 0)),
            goals_total=len(goals), goals_reached=reached, ppl=ppl, shield_steps=shield_steps,
            shield_change=shield_change, **safety.result(info),
            barn={key: info[key] for key in INFO_KEYS if key in info} if "barn_time_s" in info else None,
        )
        results.append(result)
        if on_episode is not None:
            on_episode(result)
    return results


def _shield_decision(info: dict, policy: Any) -> dict | None:
    """This step's shield decision: ``info["shield"]`` (a ``ShieldWrapper``), else a
    ``SafetyShield`` policy's ``decision``; None when no shield is on."""
    veto = info.get("shield")
    if veto is None:
        decision = getattr(policy, "decision", None)
        veto = decision.as_info() if hasattr(decision, "as_info") else None
    return veto


def summarize(results: list[EpisodeResult]) -> dict[str, Any]:
    """The article's summary plus collision rate, SPL, planning statistics and safety:
    collisions split into static and dynamic (with a mover), the timeout rate, the mean
    over episodes with movers of each one's smallest separation from a mover (NaN when none
    had movers), the share of all steps that were near misses, and the mean episode length
    in simulated seconds. Missions add ``progress`` (mean share of goals reached), ``ppl``
    (progress weighted by the optimal tour over the path driven) and ``goals_per_minute``
    (goals reached per simulated minute, all episodes); for single goals ``ppl`` is SPL.
    Behind a safety shield: ``shield_rate`` (share of all steps on which it replaced the
    command) and ``shield_change_mean`` (mean change in wheel rim speeds over those steps,
    m/s; NaN when it never intervened)."""
    n = len(results)
    rewards = np.array([r.reward for r in results])
    lengths = np.array([r.steps for r in results])
    dists = np.array([r.path_length for r in results])
    success = [r for r in results if r.success]
    plan = np.array([t for r in results for t in r.plan_ms])
    separations = [r.min_separation_m for r in results if not math.isnan(r.min_separation_m)]
    total_steps = int(lengths.sum()) if n else 0
    return {
        "episodes": n,
        "success_rate": len(success) / n if n else 0.0,
        "collision_rate": sum(r.collision for r in results) / n if n else 0.0,
        "mean_reward": float(rewards.mean()) if n else 0.0,
        "std_reward": float(rewards.std()) if n else 0.0,
        "mean_length": float(lengths.mean()) if n else 0.0,
        "std_length": float(lengths.std()) if n else 0.0,
        "mean_distance": float(dists.mean()) if n else 0.0,
        "std_distance": float(dists.std()) if n else 0.0,
        "spl": float(np.mean([r.spl for r in results])) if n else 0.0,
        "mean_sim_time_success": float(np.mean([r.sim_time for r in success])) if success else math.nan,
        "mean_path_length_success": float(np.mean([r.path_length for r in success])) if success else math.nan,
        "plan_ms_median": float(np.median(plan)) if plan.size else math.nan,
        "plan_ms_p95": float(np.percentile(plan, 95)) if plan.size else math.nan,
        "plan_calls": int(plan.size),
        "replans_mean": float(np.mean([r.replans for r in results])) if n else 0.0,
        "collision_static_rate": sum(r.collision_static for r in results) / n if n else 0.0,
        "collision_dynamic_rate": sum(r.collision_dynamic for r in results) / n if n else 0.0,
        "timeout_rate": sum(r.timeout for r in results) / n if n else 0.0,
        "min_separation_m": float(np.mean(separations)) if separations else math.nan,
        "near_miss_rate": sum(r.near_miss_steps for r in results) / total_steps if total_steps else 0.0,
        "episode_time_s": float(np.mean([r.sim_time for r in results])) if n else 0.0,
        "progress": float(np.mean([r.goals_reached / r.goals_total for r in results])) if n else 0.0,
        "ppl": float(np.mean([r.ppl for r in results])) if n else 0.0,
        "goals_per_minute": (60.0 * sum(r.goals_reached for r in results) / sum(r.sim_time for r in results)
                             if n and sum(r.sim_time for r in results) > 0 else 0.0),
        "shield_rate": sum(r.shield_steps for r in results) / total_steps if total_steps else 0.0,
        "shield_change_mean": (sum(r.shield_change for r in results) / sum(r.shield_steps for r in results)
                               if any(r.shield_steps for r in results) else math.nan),
        "per_episode": [{k: v for k, v in asdict(r).items() if k != "plan_ms"} for r in results],
    }
