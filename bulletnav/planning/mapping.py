"""Occupancy mapping from lidar scans in the world frame (log-odds evidence per cell)."""

from __future__ import annotations

import math

import numpy as np

from bulletnav import limits
from bulletnav.planning.grid import OccupancyGrid

UNKNOWN, FREE, OCCUPIED = -1, 0, 1


class LidarMapper:
    """Accumulates lidar evidence on a fixed grid covering ``bounds`` (x0, y0, x1, y1) metres.

    Each ray adds ``l_free`` to the cells it passes through (sampled every half cell) and
    ``l_occ`` to the cell of its end point, and to the cell half a cell beyond it, when it hit
    something (range < max range). A ray that hit gives free evidence only up to
    ``free_margin`` m short of its hit: a ray grazing a long wall meets it at a shallow angle,
    and without the margin its free samples just in front of the hit fall in the wall's own
    cells and erase them scan after scan (a rack face seen along an aisle would dissolve).
    A ray that hit nothing clears up to half a cell short of its maximum range. Cells that a
    moving obstacle left are cleared by later rays passing through them. Log-odds are clamped
    to ``+/- l_max`` so the map can change its mind. A cell is occupied above
    ``occ_threshold``, free below ``free_threshold``, unknown in between (including never
    seen). Each cell gets at most one free vote per scan, so long rays do not outweigh their
    end points.

    Raises:
        ValueError: non-finite or reversed bounds, a resolution that is not a finite number > 0.
        LimitError: an extent past the limit ``map_extent`` or more cells than ``map_cells``
            (:mod:`bulletnav.limits`), before the grid is allocated.
    """

    def __init__(self, bounds: tuple[float, float, float, float], resolution: float = 0.2,
                 l_free: float = -0.4, l_occ: float = 0.85, l_max: float = 3.5,
                 occ_threshold: float = 0.6, free_threshold: float = -0.3, free_margin: float = 0.4) -> None:
        if not (math.isfinite(resolution) and resolution > 0):
            raise ValueError(f"resolution must be a finite number > 0 m, got {resolution}")
        x0, y0, x1, y1 = bounds
        if not all(math.isfinite(v) for v in bounds) or x1 < x0 or y1 < y0:
            raise ValueError(f"map bounds must be finite (x0, y0, x1, y1) m with x0 <= x1 and y0 <= y1, got {bounds}")
        limits.check("map_extent", x1 - x0, "map extent (x)")
        limits.check("map_extent", y1 - y0, "map extent (y)")
        self.resolution = resolution
        self.nx = max(1, int(math.ceil((x1 - x0) / resolution - 1e-9)))
        self.ny = max(1, int(math.ceil((y1 - y0) / resolution - 1e-9)))
        limits.check("map_cells", self.nx * self.ny, f"map cells ({self.nx} x {self.ny} of {resolution:g} m)")
        self.x0, self.y0 = x0, y0
        self.log_odds = np.zeros((self.nx, self.ny), dtype=np.float32)
        self.l_free, self.l_occ, self.l_max = l_free, l_occ, l_max
        self.occ_threshold, self.free_threshold = occ_threshold, free_threshold
        self.free_margin = free_margin
        self.freed = 0
        """Cells that stopped being occupied in the last :meth:`integrate` (a mover left them)."""

    @property
    def origin(self) -> tuple[float, float]:
        """World position of the centre of cell (0, 0)."""
        return self.x0 + self.resolution / 2, self.y0 + self.resolution / 2

    def reset(self) -> None:
        self.log_odds[:] = 0.0

    def _cells(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        ix = np.floor((x - self.x0) / self.resolution).astype(np.int64)
        iy = np.floor((y - self.y0) / self.resolution).astype(np.int64)
        ok = (ix >= 0) & (ix < self.nx) & (iy >= 0) & (iy < self.ny)
        return ix, iy, ok

    def integrate(self, pose: tuple[float, float, float], angles: np.ndarray, ranges: np.ndarray,
                  max_range: float, sensor_offset: float = 0.0) -> set[tuple[int, int]]:
        """Add one scan taken at ``pose`` (x, y, yaw of the robot; the lidar sits
        ``sensor_offset`` m ahead of it). Returns the cells that became occupied."""
        x, y, yaw = pose
        sx, sy = x + sensor_offset * math.cos(yaw), y + sensor_offset * math.sin(yaw)
        ranges = np.asarray(ranges, dtype=np.float64)
        a = np.asarray(angles, dtype=np.float64) + yaw
        c, s = np.cos(a), np.sin(a)
        was_occ = self.log_odds > self.occ_threshold
        # free space: samples every half cell along each ray, stopping free_margin short of a
        # hit (half a cell short of the maximum range for a ray that hit nothing)
        step = self.resolution / 2
        t = np.arange(0.0, max_range, step)
        hit = ranges < max_range - 1e-6
        reach = np.maximum(np.where(hit, ranges - max(self.free_margin, step), ranges - step), 0.0)
        along = t[None, :] <= reach[:, None]
        px = sx + c[:, None] * t[None, :]
        py = sy + s[:, None] * t[None, :]
        ix, iy, ok = self._cells(px[along], py[along])
        flat = np.unique(ix[ok] * self.ny + iy[ok])
        self.log_odds.reshape(-1)[flat] += self.l_free
        # hits: the end point's cell and the cell half a cell beyond it (the obstacle's inside)
        depth = np.concatenate([ranges[hit], ranges[hit] + step])
        ch, sh = np.tile(c[hit], 2), np.tile(s[hit], 2)
        hx, hy, ok = self._cells(sx + ch * depth, sy + sh * depth)
        flat = np.unique(hx[ok] * self.ny + hy[ok])
        self.log_odds.reshape(-1)[flat] += self.l_occ
        np.clip(self.log_odds, -self.l_max, self.l_max, out=self.log_odds)
        now_occ = self.log_odds > self.occ_threshold
        new = np.argwhere(now_occ & ~was_occ)
        self.freed = int(np.count_nonzero(was_occ & ~now_occ))
        return {(int(i), int(j)) for i, j in new}

    def state(self) -> np.ndarray:
        """Grid of UNKNOWN (-1), FREE (0) and OCCUPIED (1) per cell, indexed [ix, iy]."""
        out = np.full(self.log_odds.shape, UNKNOWN, dtype=np.int8)
        out[self.log_odds < self.free_threshold] = FREE
        out[self.log_odds > self.occ_threshold] = OCCUPIED
        return out

    def grid(self) -> OccupancyGrid:
        """Occupied cells as an :class:`OccupancyGrid` (unknown counts as free: optimistic planning)."""
        return OccupancyGrid(self.log_odds > self.occ_threshold, self.resolution, self.origin)
