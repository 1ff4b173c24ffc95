"""How wide a robot can be and still get through a BARN world: the widest passage from start to goal.

A disc of radius ``r`` can travel from the start to the goal without touching a cylinder or the
floor's walls exactly when the two are connected in the free space shrunk by ``r`` (every point at
least ``r`` from every obstacle). The largest such ``r``, doubled, is the world's **widest
passage**: no robot wider than that, whatever drives it, can cross the world without a touch (a
robot turns its footprint, so it needs more than its width where the passage bends).

:func:`widest_passage` finds it on a grid: the clearance of every cell centre (distance to the
nearest cylinder surface or wall), then a bisection on ``r`` with a connected-component test.
It is independent of the navigator, the planner and PyBullet: it explains per world why a
controller cannot succeed there (the BARN benchmark's per-world account), not how to.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bulletnav.barn.metric import CYLINDER_RADIUS_M, GOAL_OFFSET, START


def clearance_grid(centres: np.ndarray, radius: float, bounds: tuple[float, float, float, float],
                   resolution: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(clearance, xs, ys)``: each cell centre's distance (m) to the nearest cylinder surface
    (cylinders of ``radius`` at ``centres``, n x 2) or to the rectangle ``bounds`` = (x0, y0, x1,
    y1)'s edges; negative inside a cylinder. ``clearance[i, j]`` is at ``(xs[i], ys[j])``."""
    from scipy.spatial import cKDTree

    x0, y0, x1, y1 = bounds
    xs = np.arange(x0 + resolution / 2, x1, resolution)
    ys = np.arange(y0 + resolution / 2, y1, resolution)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    walls = np.minimum(np.minimum(gx - x0, x1 - gx), np.minimum(gy - y0, y1 - gy))
    if len(centres):
        d, _ = cKDTree(np.asarray(centres, dtype=np.float64)).query(np.column_stack([gx.ravel(), gy.ravel()]))
        walls = np.minimum(walls, d.reshape(gx.shape) - radius)
    return walls, xs, ys


def widest_passage(centres: np.ndarray, start: tuple[float, float], goal: tuple[float, float],
                   bounds: tuple[float, float, float, float], radius: float = CYLINDER_RADIUS_M,
                   resolution: float = 0.01) -> float:
    """The widest passage (m): twice the largest clearance ``r`` for which ``start`` and ``goal``
    are connected through cells of clearance >= ``r`` (see the module docstring). Exact to about
    ``resolution``; 0 when they are not connected at all."""
    from scipy import ndimage

    clear, xs, ys = clearance_grid(centres, radius, bounds, resolution)

    def cell(p: tuple[float, float]) -> tuple[int, int]:
        return (int(np.clip(np.searchsorted(xs, p[0]), 0, len(xs) - 1)),
                int(np.clip(np.searchsorted(ys, p[1]), 0, len(ys) - 1)))

    a, b = cell(start), cell(goal)

    def connected(r: float) -> bool:
        labels, _ = ndimage.label(clear >= r)
        return labels[a] != 0 and labels[a] == labels[b]

    lo, hi = 0.0, float(min(clear[a], clear[b]))
    if hi <= 0 or not connected(0.0):
        return 0.0
    if connected(hi):
        return 2 * hi
    while hi - lo > resolution / 4:
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if connected(mid) else (lo, mid)
    return 2 * lo


BARN_BOUNDS = (-5.0, -0.5, 1.0, 15.0)
"""The part of ``BARN-v0``'s floor (x0, y0, x1, y1; m) the passage is sought in: the floor's left,
top and goal-side walls (x = -5, y = 15), the start's walled corridor (BARN's side columns and
bottom row of touching cylinders) and 1 m beside the right column. Leaving out the rest of the
open floor changes no passage narrower than 1 m."""


def barn_widest_passage(world_idx: int, resolution: float = 0.01) -> float:
    """:func:`widest_passage` of BARN world ``world_idx`` as ``bulletnav/BARN-v0`` builds it: its
    cylinders, BARN's start and goal, within :data:`BARN_BOUNDS`."""
    from bulletnav.barn.data import load_world

    world = load_world(world_idx)
    goal = (START[0] + GOAL_OFFSET[0], START[1] + GOAL_OFFSET[1])
    return widest_passage(world.cylinders, START[:2], goal, BARN_BOUNDS, resolution=resolution)


def passage_table(worlds: list[int], robot_width: float, resolution: float = 0.01) -> list[dict[str, Any]]:
    """Per world: its widest passage (m) and the room it leaves a robot ``robot_width`` wide (m;
    negative: that robot cannot cross without a touch)."""
    rows = []
    for w in worlds:
        width = barn_widest_passage(w, resolution)
        rows.append({"world": int(w), "widest_passage_m": round(width, 3), "room_m": round(width - robot_width, 3)})
    return rows


__all__ = ["BARN_BOUNDS", "barn_widest_passage", "clearance_grid", "passage_table", "widest_passage"]
