"""Compiled (numba, ``cache=True``) kernels of the reset path, each the exact arithmetic of the
NumPy code it replaces, in the same order, so results are bit for bit the same
(``tests/test_reset_kernels.py`` checks them against that code on random inputs).

- :func:`mark_within`: OR into a grid window the cells whose centre lies within ``pad`` of an
  obstacle footprint (:meth:`bulletnav.sim.layout.Obstacle.distance` ``<= pad``);
- :func:`mark_levels`: the same for several distances at once, one distance per grid;
- :func:`any_within`: whether any marked cell of a window lies within ``pad`` of a footprint;
- :func:`line_clear`: :meth:`bulletnav.sim.dynamic.ClearanceMap.line_clear`'s sampled
  line-of-sight test on a clearance grid.

Footprints are passed as plain numbers: ``kind`` 0 for a box (``half_x``, ``half_y`` its half
sizes, ``c``, ``s`` the cosine and sine of its yaw), 1 for a cylinder (``radius``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

BOX, CYLINDER = 0, 1


@njit(cache=True, nogil=True)
def _distance(kind: int, cx: float, cy: float, c: float, s: float, half_x: float, half_y: float, radius: float,
              x: float, y: float) -> float:
    # Obstacle.distance, one point: the same operations in the same order as the array code
    dx = x - cx
    dy = y - cy
    if kind == CYLINDER:
        return max(math.hypot(dx, dy) - radius, 0.0)
    lx = abs(c * dx + s * dy) - half_x
    ly = abs(-s * dx + c * dy) - half_y
    return math.hypot(max(lx, 0.0), max(ly, 0.0))


@njit(cache=True, nogil=True)
def mark_within(out: np.ndarray, xs: np.ndarray, ys: np.ndarray, i0: int, j0: int, kind: int, cx: float, cy: float,
                c: float, s: float, half_x: float, half_y: float, radius: float, pad: float) -> None:
    """``out[i0 + a, j0 + b] |= distance(xs[a], ys[b]) <= pad`` for every point of the window
    (a point already set is not measured again)."""
    for a in range(xs.shape[0]):
        x = xs[a]
        for b in range(ys.shape[0]):
            if not out[i0 + a, j0 + b] and _distance(kind, cx, cy, c, s, half_x, half_y, radius, x, ys[b]) <= pad:
                out[i0 + a, j0 + b] = True


@njit(cache=True, nogil=True)
def mark_levels(out: np.ndarray, xs: np.ndarray, ys: np.ndarray, i0: int, j0: int, kind: int, cx: float, cy: float,
                c: float, s: float, half_x: float, half_y: float, radius: float, levels: np.ndarray) -> None:
    """``out[q, i0 + a, j0 + b] |= distance(xs[a], ys[b]) <= levels[q]`` for every level ``q``:
    :func:`mark_within` for several distances, each point's distance computed once."""
    for a in range(xs.shape[0]):
        x = xs[a]
        for b in range(ys.shape[0]):
            d = _distance(kind, cx, cy, c, s, half_x, half_y, radius, x, ys[b])
            for q in range(levels.shape[0]):
                if d <= levels[q]:
                    out[q, i0 + a, j0 + b] = True


@njit(cache=True, nogil=True)
def any_within(grid: np.ndarray, xs: np.ndarray, ys: np.ndarray, i0: int, j0: int, kind: int, cx: float, cy: float,
               c: float, s: float, half_x: float, half_y: float, radius: float, pad: float) -> bool:
    """Whether some ``grid[i0 + a, j0 + b]`` is set where ``distance(xs[a], ys[b]) <= pad``."""
    for a in range(xs.shape[0]):
        x = xs[a]
        for b in range(ys.shape[0]):
            if grid[i0 + a, j0 + b] and _distance(kind, cx, cy, c, s, half_x, half_y, radius, x, ys[b]) <= pad:
                return True
    return False


@njit(cache=True, nogil=True)
def line_clear(clearance: np.ndarray, ax: float, ay: float, bx: float, by: float, n: int, need: float, hx: float,
               hy: float, resolution: float) -> bool:
    """``ClearanceMap.line_clear`` for ``n`` samples (the caller computes ``n`` with Python's
    ``math.dist``, as that method does): the points of ``np.linspace(0, 1, n)`` along the
    segment, each sample's cell (truncated, clipped to the grid) with clearance >= ``need``.
    ``hx``, ``hy``: minus the grid's lower-left corner (the floor's half size when it is centred)."""
    step = 1.0 / (n - 1)
    nx, ny = clearance.shape
    for k in range(n):
        t = 1.0 if k == n - 1 else k * step  # np.linspace(0, 1, n): k * step, the last one exactly 1
        ix = min(max(int((ax + (bx - ax) * t + hx) / resolution), 0), nx - 1)
        iy = min(max(int((ay + (by - ay) * t + hy) / resolution), 0), ny - 1)
        if not clearance[ix, iy] >= need:
            return False
    return True
