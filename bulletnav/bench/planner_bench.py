"""A* against RRT: planning cost and RRT solve rates on standard problems, and navigation on the same episodes.

Standard problems (:func:`bench_planners`), each drawn from a seeded ``numpy.random.Generator``:

* A*: 50 x 50 grids (0.1 m cells), 20 % of cells occupied at random, start in the 5 x 5 cell
  corner region at (0, 0) and goal in the opposite one, redrawn until connected.
* RRT, boxes: 10 x 10 m maps (0.1 m cells) with 31 random axis-aligned boxes of sides
  0.3-1.2 m, start and goal free, at least 5 m apart and connected on the grid.
* RRT, narrow passages: 10 x 10 m maps (0.1 m cells) crossed by one or two walls 0.1-0.3 m
  thick, each with one gap 0.2-0.4 m wide at a random place, plus 6 random boxes; start and
  goal on opposite sides of every wall, free and connected on the grid.

Figures are wall-clock milliseconds per plan call, taken with ``time.perf_counter`` after a
warm-up, so they exclude numba compilation; they are reported, never asserted. RRT solve rates
do not depend on timing at all: RRT is bounded by iterations only.

:func:`bench_navigation` reproduces the article's experiment: the same PID follower, the same
lidar map, the same ``bulletnav/Warehouse-v0`` episodes (seed ``S + k``), only the planner differs.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from bulletnav.planning import OccupancyGrid, astar, astar_result, rrt, warmup

Problem = tuple[OccupancyGrid, tuple[float, float], tuple[float, float]]


def astar_problem(rng: np.random.Generator, size: int = 50, density: float = 0.2, resolution: float = 0.1) -> Problem:
    """A random (grid, start, goal) with start and goal in opposite 5 x 5 corner regions, connected."""
    while True:
        grid = OccupancyGrid(rng.random((size, size)) < density, resolution)
        s = grid.cell_to_world(*rng.integers(0, 5, 2))
        g = grid.cell_to_world(*(size - 1 - rng.integers(0, 5, 2)))
        if astar_result(grid, s, g) is not None:
            return grid, s, g


def _add_boxes(rng: np.random.Generator, occ: np.ndarray, centres: np.ndarray, size_m: float, n_boxes: int,
               side_m: tuple[float, float]) -> None:
    """Mark ``n_boxes`` random axis-aligned boxes (sides in ``side_m``, m) occupied in ``occ``."""
    for _ in range(n_boxes):
        w, h = rng.uniform(*side_m, 2)
        x, y = rng.uniform(0, size_m - w), rng.uniform(0, size_m - h)
        occ[np.ix_((centres >= x) & (centres <= x + w), (centres >= y) & (centres <= y + h))] = True


def box_world(rng: np.random.Generator, size_m: float = 10.0, resolution: float = 0.1, n_boxes: int = 31,
              side_m: tuple[float, float] = (0.3, 1.2)) -> OccupancyGrid:
    """A ``size_m`` square map with ``n_boxes`` random axis-aligned boxes (sides in ``side_m``)."""
    n = int(round(size_m / resolution))
    centres = (np.arange(n) + 0.5) * resolution  # origin at the map corner, cells inside it
    occ = np.zeros((n, n), dtype=bool)
    _add_boxes(rng, occ, centres, size_m, n_boxes, side_m)
    return OccupancyGrid(occ, resolution, (0.5 * resolution, 0.5 * resolution))


def rrt_problem(rng: np.random.Generator, min_distance_m: float = 5.0) -> Problem:
    """A random box world with free start and goal at least ``min_distance_m`` apart, connected."""
    while True:
        grid = box_world(rng)
        x0, x1, y0, y1 = grid.bounds
        s = (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)))
        g = (float(rng.uniform(x0, x1)), float(rng.uniform(y0, y1)))
        if np.hypot(g[0] - s[0], g[1] - s[1]) < min_distance_m:
            continue
        if astar(grid, s, g) is not None:  # also rejects occupied start or goal
            return grid, s, g


def narrow_problem(rng: np.random.Generator, size_m: float = 10.0, resolution: float = 0.1,
                   gap_m: tuple[float, float] = (0.2, 0.4), thickness_m: tuple[float, float] = (0.1, 0.3),
                   n_boxes: int = 6) -> Problem:
    """A random narrow-passage problem: one or two walls across the map, each with one gap.

    Walls run along y (or, half the time, along x) at random places; each is ``thickness_m``
    thick with a gap ``gap_m`` wide (m) whose position along the wall is random. ``n_boxes``
    boxes of sides 0.3-1.2 m go anywhere, gaps included. Start and goal lie on opposite sides
    of every wall, in free cells, and are connected on the grid; draws that fail are redrawn.
    """
    n = int(round(size_m / resolution))
    centres = (np.arange(n) + 0.5) * resolution
    while True:
        occ = np.zeros((n, n), dtype=bool)
        if rng.random() < 0.5:  # one wall in the middle band, or two in the outer thirds
            lows = [rng.uniform(0.3, 0.7) * size_m]
        else:
            lows = [rng.uniform(0.2, 0.4) * size_m, rng.uniform(0.6, 0.8) * size_m]
        high = lows[0]
        for low in lows:
            thick, gap = rng.uniform(*thickness_m), rng.uniform(*gap_m)
            gap_low = rng.uniform(0.5, size_m - 0.5 - gap)  # keep the gap off the map's edge
            wall = (centres >= low) & (centres <= low + thick)
            hole = (centres >= gap_low) & (centres <= gap_low + gap)
            occ[np.ix_(wall, ~hole)] = True
            high = low + thick
        _add_boxes(rng, occ, centres, size_m, n_boxes, (0.3, 1.2))
        # Across the walls: before the first one and beyond the last, anywhere along them.
        a = (float(rng.uniform(0.0, lows[0])), float(rng.uniform(0.0, size_m)))
        b = (float(rng.uniform(high, size_m)), float(rng.uniform(0.0, size_m)))
        if rng.random() < 0.5:
            a, b = b, a
        if rng.random() < 0.5:  # walls along x instead: swap the axes of map and points
            occ = occ.T
            a, b = (a[1], a[0]), (b[1], b[0])
        grid = OccupancyGrid(occ, resolution, (0.5 * resolution, 0.5 * resolution))
        if astar(grid, a, b) is not None:  # also rejects an occupied start or goal
            return grid, a, b


def _time_rrt(problems: list[Problem], seed: int, stream: int) -> tuple[np.ndarray, int]:
    """Milliseconds per RRT call (failures included) and the number solved; plan i uses seed (seed, stream, i)."""
    clock = time.perf_counter
    ms = np.empty(len(problems))
    solved = 0
    for i, (grid, s, g) in enumerate(problems):
        plan_rng = np.random.default_rng([seed, stream, i])
        t0 = clock()
        path = rrt(grid, s, g, plan_rng)
        ms[i] = (clock() - t0) * 1e3
        solved += path is not None
    return ms, solved


def bench_planners(seed: int = 0, n: int = 200) -> dict[str, float]:
    """Time A* and RRT on ``n`` random problems of each kind (see the module docstring).

    Returns:
        ``astar_median_ms``, ``astar_p95_ms``; ``rrt_median_ms``, ``rrt_p95_ms`` and
        ``rrt_success_rate`` in [0, 1] on the box problems; ``rrt_narrow_median_ms``,
        ``rrt_narrow_p95_ms`` and ``rrt_narrow_success_rate`` on the narrow-passage problems
        (times over all attempts, failures included); and ``n``.
    """
    warmup()
    rng = np.random.default_rng(seed)
    clock = time.perf_counter
    a_ms = np.empty(n)
    for i in range(n):
        grid, s, g = astar_problem(rng)
        t0 = clock()
        astar(grid, s, g)
        a_ms[i] = (clock() - t0) * 1e3
    box_ms, box_solved = _time_rrt([rrt_problem(rng) for _ in range(n)], seed, 0)
    narrow_ms, narrow_solved = _time_rrt([narrow_problem(rng) for _ in range(n)], seed, 1)
    return {
        "astar_median_ms": float(np.median(a_ms)),
        "astar_p95_ms": float(np.percentile(a_ms, 95)),
        "rrt_median_ms": float(np.median(box_ms)),
        "rrt_p95_ms": float(np.percentile(box_ms, 95)),
        "rrt_success_rate": box_solved / n,
        "rrt_narrow_median_ms": float(np.median(narrow_ms)),
        "rrt_narrow_p95_ms": float(np.percentile(narrow_ms, 95)),
        "rrt_narrow_success_rate": narrow_solved / n,
        "n": n,
    }


def bench_navigation(episodes: int = 50, seed: int = 1000, num_obstacles: int = 31) -> dict[str, Any]:
    """The standard problems (:func:`bench_planners`), then ``episodes`` navigation episodes per planner."""
    # Imported here so the standard problems above need only numpy and the planners.
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the environments)
    from bulletnav.control.navigator import Navigator, NavigatorConfig
    from bulletnav.evaluation import run_episodes, summarize

    warmup()
    micro = bench_planners(seed=0, n=200)
    rows = {}
    for planner in ("astar", "rrt"):
        env = gym.make("bulletnav/Warehouse-v0", num_obstacles=num_obstacles)
        try:
            results = run_episodes(env, Navigator(env.unwrapped.scene, NavigatorConfig(planner=planner)), episodes, seed)
        finally:
            env.close()
        s = summarize(results)
        rows[planner] = {
            "success_rate": s["success_rate"],
            "collision_rate": s["collision_rate"],
            "spl": round(s["spl"], 4),
            "plan_ms_median": round(s["plan_ms_median"], 4),
            "plan_ms_p95": round(s["plan_ms_p95"], 4),
            "plan_calls": s["plan_calls"],
            "replans_per_episode": round(s["replans_mean"], 2),
            "sim_time_to_goal_s": round(s["mean_sim_time_success"], 3),
            "path_length_m": round(s["mean_path_length_success"], 3),
            "mean_steps": round(s["mean_length"], 1),
            "_results": results,
        }
    # paired comparison on the episodes both planners solved
    a, r = rows["astar"].pop("_results"), rows["rrt"].pop("_results")
    paired = [(x, y) for x, y in zip(a, r) if x.success and y.success]

    def paired_mean(values: list[float]) -> float | None:
        return round(float(np.mean(values)), 3) if paired else None

    comparison = {
        "episodes_both_succeeded": len(paired),
        "rrt_minus_astar_sim_time_s": paired_mean([y.sim_time - x.sim_time for x, y in paired]),
        "rrt_minus_astar_path_m": paired_mean([y.path_length - x.path_length for x, y in paired]),
        "rrt_faster_to_goal_fraction": paired_mean([y.sim_time < x.sim_time for x, y in paired]),
    }
    return {"benchmark": "planners", "episodes": episodes, "seed": seed, "num_obstacles": num_obstacles,
            "standard_problems": micro, "navigation": rows, "paired": comparison}
