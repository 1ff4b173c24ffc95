"""Pure-algorithm path planning on 2-D occupancy grids (no PyBullet here).

* :class:`OccupancyGrid`: a boolean grid in world metres with exact segment checks and inflation.
* :func:`astar`: optimal 8-connected grid A* (numba); :func:`astar_result` also gives the cost.
* :func:`rrt`: RRT-Connect with greedy shortcutting in continuous space (numba), bounded by
  iterations and seeded by the caller.

Benchmarks of these planners live in :mod:`bulletnav.bench.planner_bench`.

The numba kernels compile on first use and are cached on disk (``cache=True``); call
:func:`warmup` to pay that cost up front. Compilation only costs time: no planner has a
wall-clock budget, so results are the same either way.
"""

from __future__ import annotations

import numpy as np

from bulletnav.planning.astar import AStarResult, astar, astar_cost, astar_result
from bulletnav.planning.grid import OccupancyGrid
from bulletnav.planning.rrt import _warmup as _rrt_warmup
from bulletnav.planning.rrt import rrt

__all__ = ["AStarResult", "OccupancyGrid", "astar", "astar_cost", "astar_result", "rrt", "warmup"]


def warmup() -> None:
    """Compile (or load from the on-disk cache) every numba kernel by planning on tiny maps."""
    occ = np.zeros((4, 4), dtype=bool)
    occ[1, 1:3] = True
    grid = OccupancyGrid(occ, 1.0)
    grid.segment_free((0.0, 0.0), (3.0, 3.0))
    astar(grid, (0.0, 0.0), (3.0, 3.0))
    _rrt_warmup()
