"""Timing of the planners on the standard random problems.

* A*: 50 x 50 grids (0.1 m cells), 20 % of cells occupied at random, start in the 5 x 5 cell
  corner region at (0, 0) and goal in the opposite one, redrawn until connected.
* RRT: 10 x 10 m maps (0.1 m cells) with 31 random axis-aligned boxes of sides 0.3-1.2 m,
  start and goal free, at least 5 m apart and connected on the grid.

Figures are wall-clock milliseconds per plan call, taken with ``time.perf_counter`` after a
warm-up, so they exclude numba compilation.
"""

from __future__ import annotations

import time

import numpy as np

from bulletnav.planning.astar import astar, astar_result
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.planning.rrt import rrt


def astar_problem(rng: np.random.Generator, size: int = 50, density: float = 0.2,
                  resolution: float = 0.1) -> tuple[OccupancyGrid, tuple[float, float], tuple[float, float]]:
    """A random (grid, start, goal) with start and goal in opposite 5 x 5 corner regions, connected."""
    while True:
        grid = OccupancyGrid(rng.random((size, size)) < density, resolution)
        s = grid.cell_to_world(*rng.integers(0, 5, 2))
        g = grid.cell_to_world(*(size - 1 - rng.integers(0, 5, 2)))
        if astar_result(grid, s, g) is not None:
            return grid, s, g


def box_world(rng: np.random.Generator, size_m: float = 10.0, resolution: float = 0.1, n_boxes: int = 31,
              side_m: tuple[float, float] = (0.3, 1.2)) -> OccupancyGrid:
    """A ``size_m`` square map with ``n_boxes`` random axis-aligned boxes (sides in ``side_m``)."""
    n = int(round(size_m / resolution))
    centres = (np.arange(n) + 0.5) * resolution  # origin at the map corner, cells inside it
    occ = np.zeros((n, n), dtype=bool)
    for _ in range(n_boxes):
        w, h = rng.uniform(*side_m, 2)
        x, y = rng.uniform(0, size_m - w), rng.uniform(0, size_m - h)
        occ[np.ix_((centres >= x) & (centres <= x + w), (centres >= y) & (centres <= y + h))] = True
    return OccupancyGrid(occ, resolution, (0.5 * resolution, 0.5 * resolution))


def rrt_problem(rng: np.random.Generator,
                min_distance_m: float = 5.0) -> tuple[OccupancyGrid, tuple[float, float], tuple[float, float]]:
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


def bench_planners(seed: int = 0, n: int = 200) -> dict[str, float]:
    """Time A* and RRT on ``n`` random problems each (see the module docstring).

    Returns:
        ``astar_median_ms``, ``astar_p95_ms``, ``rrt_median_ms``, ``rrt_p95_ms`` (all
        attempts, failures included), ``rrt_success_rate`` in [0, 1], and ``n``.
    """
    from bulletnav.planning import warmup

    warmup()
    rng = np.random.default_rng(seed)
    clock = time.perf_counter
    a_ms = np.empty(n)
    for i in range(n):
        grid, s, g = astar_problem(rng)
        t0 = clock()
        astar(grid, s, g)
        a_ms[i] = (clock() - t0) * 1e3
    r_ms = np.empty(n)
    solved = 0
    for i in range(n):
        grid, s, g = rrt_problem(rng)
        plan_rng = np.random.default_rng([seed, i])
        t0 = clock()
        path = rrt(grid, s, g, plan_rng)
        r_ms[i] = (clock() - t0) * 1e3
        solved += path is not None
    return {
        "astar_median_ms": float(np.median(a_ms)),
        "astar_p95_ms": float(np.percentile(a_ms, 95)),
        "rrt_median_ms": float(np.median(r_ms)),
        "rrt_p95_ms": float(np.percentile(r_ms, 95)),
        "rrt_success_rate": solved / n,
        "n": n,
    }
