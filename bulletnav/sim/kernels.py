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


RACK, PALLET, COLUMN, CRATE = 0, 1, 2, 3
"""The procedural warehouse's obstacle categories, in the order they are placed (rack, pallet, column, box)."""


@njit(cache=True, nogil=True)
def _draw(kind: int, rng: np.random.Generator, aisle_yaw: float, shape: np.ndarray) -> None:
    # one candidate's shape, drawn from rng: (is_cylinder, size x, y, z, radius, height, yaw)
    if kind == RACK:
        shape[0], shape[1], shape[2], shape[3], shape[4], shape[5], shape[6] = \
            0.0, 2.0 + (3.5 - 2.0) * rng.random(), 0.6, 2.0, 0.0, 0.0, aisle_yaw
    elif kind == COLUMN:
        shape[0], shape[1], shape[2], shape[3], shape[4], shape[5], shape[6] = \
            1.0, 0.0, 0.0, 0.0, 0.15 + (0.25 - 0.15) * rng.random(), 3.0, 0.0
    elif kind == PALLET:
        turn = 0.0 if rng.integers(0, 2) == 0 else math.pi / 2  # rng.choice([0.0, pi / 2])
        yaw = aisle_yaw + turn + rng.normal(0.0, 0.05)
        shape[0], shape[1], shape[2], shape[3], shape[4], shape[5], shape[6] = \
            0.0, 1.2, 0.8, 0.4 + (1.2 - 0.4) * rng.random(), 0.0, 0.0, yaw
    else:
        side = 0.3 + (0.7 - 0.3) * rng.random()
        height = 0.3 + (0.8 - 0.3) * rng.random()
        shape[0], shape[1], shape[2], shape[3], shape[4], shape[5], shape[6] = \
            0.0, side, side, height, 0.0, 0.0, -math.pi + (math.pi - -math.pi) * rng.random()


@njit(cache=True, nogil=True)
def _footprint(shape: np.ndarray) -> tuple[int, float, float, float, float, float]:
    # Obstacle.footprint less the centre: (kind, c, s, half x, half y, radius)
    if shape[0] == 1.0:
        return CYLINDER, 1.0, 0.0, 0.0, 0.0, shape[4]
    return BOX, math.cos(shape[6]), math.sin(shape[6]), shape[1] / 2, shape[2] / 2, 0.0


@njit(cache=True, nogil=True)
def _window(grid: np.ndarray, x: float, y: float, r: float, hx: float, hy: float, res: float) -> tuple[int, int, int, int]:
    # the raster's cells [i0, i1) x [j0, j1) within a square of half side r round (x, y)
    i0 = max(int((x - r + hx) / res), 0)
    i1 = min(int((x + r + hx) / res) + 1, grid.shape[0])
    j0 = max(int((y - r + hy) / res), 0)
    j1 = min(int((y + r + hy) / res) + 1, grid.shape[1])
    return i0, i1, j0, j1


@njit(cache=True, nogil=True)
def place_obstacles(rng: np.random.Generator, kinds: np.ndarray, tries: int, hx: float, hy: float, gap: float,
                    aisle_yaw: float, grid: np.ndarray, xs: np.ndarray, ys: np.ndarray, res: float,
                    out: np.ndarray) -> int:
    """:func:`bulletnav.sim.layout.generate_warehouse`'s rejection sampling, compiled: for each
    category in ``kinds`` (:data:`RACK` ...), up to ``tries`` candidates drawn from ``rng`` (a rack
    2-3.5 m long along the aisles, a column of radius 0.15-0.25 m, a 1.2 x 0.8 m pallet turned
    with the aisles or across them, give or take N(0, 0.05) rad, a box of side 0.3-0.7 m at any
    yaw; then the centre), each kept where it lies on the floor ``gap`` from the walls and no
    claimed cell of ``grid`` (``xs``, ``ys`` its cell centres, ``res`` its cell size, the floor
    ``2 hx`` x ``2 hy``) lies on its footprint; a kept one claims the cells within ``gap + res``
    of it. The same draws from the same Generator, in the same order, as the Python loop it
    replaced (``tests/test_reset_kernels.py`` keeps that loop as its reference). Row ``k`` of ``out`` gets the k-th kept
    obstacle: is_cylinder, size x, y, z, radius, height, yaw, centre x, y. Returns how many were
    placed: fewer than ``len(kinds)`` when one found no place (the rest are not tried)."""
    lo_x = -hx + gap
    lo_y = -hy + gap
    shape = np.empty(7)
    for k in range(kinds.shape[0]):
        placed = False
        for _ in range(tries):
            _draw(kinds[k], rng, aisle_yaw, shape)
            r = shape[4] if shape[0] == 1.0 else 0.5 * math.hypot(shape[1], shape[2])
            x = lo_x + (-lo_x - lo_x) * rng.random()
            y = lo_y + (-lo_y - lo_y) * rng.random()
            kind, c, s, half_x, half_y, radius = _footprint(shape)
            if abs(x) + r > hx - gap or abs(y) + r > hy - gap:  # layout._inside, for the few near a wall
                if kind == CYLINDER:
                    inside = abs(x) + radius <= hx - gap and abs(y) + radius <= hy - gap
                else:
                    ca, sa = abs(c), abs(s)  # the footprint's cos and sin of the yaw
                    ex = ca * shape[1] / 2 + sa * shape[2] / 2
                    ey = sa * shape[1] / 2 + ca * shape[2] / 2
                    inside = abs(x) + ex <= hx - gap and abs(y) + ey <= hy - gap
                if not inside:
                    continue
            ci = min(int((x + hx) / res), grid.shape[0] - 1)  # the centre's cell first: most rejections end here
            cj = min(int((y + hy) / res), grid.shape[1] - 1)
            if grid[ci, cj]:
                continue
            i0, i1, j0, j1 = _window(grid, x, y, r, hx, hy, res)
            if any_within(grid, xs[i0:i1], ys[j0:j1], i0, j0, kind, x, y, c, s, half_x, half_y, radius, 0.0):
                continue
            i0, i1, j0, j1 = _window(grid, x, y, r + gap + res, hx, hy, res)
            mark_within(grid, xs[i0:i1], ys[j0:j1], i0, j0, kind, x, y, c, s, half_x, half_y, radius, gap + res)
            out[k, :7] = shape
            out[k, 7] = x
            out[k, 8] = y
            placed = True
            break
        if not placed:
            return k
    return kinds.shape[0]
