"""Pure-algorithm path planning on 2-D occupancy grids (no PyBullet here).

* :class:`OccupancyGrid`: a boolean grid in world metres with exact segment checks and inflation.
* :func:`astar`: optimal 8-connected grid A* (numba); :func:`astar_result` also gives the cost.
* :func:`rrt`: RRT with greedy shortcutting in continuous space (numba), seeded by the caller.
* :func:`bench_planners`: timing of both on standard random problems.

The numba kernels compile on first use (and are cached on disk); call :func:`warmup` to
pay that cost up front.
"""

from __future__ import annotations

import numpy as np

from bulletnav.planning.astar import AStarResult, astar, astar_cost, astar_result
from bulletnav.planning.bench import bench_planners
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.planning.rrt import rrt

__all__ = ["AStarResult", "OccupancyGrid", "astar", "astar_cost", "astar_result", "bench_planners", "rrt", "warmup"]


def warmup() -> None:
    """Compile (or load from the on-disk cache) every numba kernel by planning on a tiny map."""
    occ = np.zeros((4, 4), dtype=bool)
    occ[1, 1:3] = True
    grid = OccupancyGrid(occ, 1.0)
    grid.segment_free((0.0, 0.0), (3.0, 3.0))
    astar(grid, (0.0, 0.0), (3.0, 3.0))
    rrt(grid, (0.0, 0.0), (3.0, 3.0), np.random.default_rng(0), step=1.0, time_budget_s=1.0)
