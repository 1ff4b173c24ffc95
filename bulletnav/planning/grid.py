"""A 2-D boolean occupancy grid in world coordinates, with exact segment checks.

Conventions (shared by every planner in this package):

* ``occupied[ix, iy]`` is True for an occupied cell; ``ix`` runs along world x, ``iy`` along y.
* ``resolution`` is the cell side in metres; ``origin`` is the world (x, y) in metres of the
  *centre* of cell (0, 0). Cell (ix, iy) is the half-open square
  ``[ox + (ix - 1/2) res, ox + (ix + 1/2) res) x [oy + (iy - 1/2) res, oy + (iy + 1/2) res)``.
* Everything outside the grid counts as occupied, so plans never leave the map.
* A segment occupies the cells its points lie in, with one conservative exception: passing
  exactly through a corner where two cells meet diagonally also touches the two cells beside
  the corner (a zero-width gap is not a passage, as in A*'s no-corner-cutting rule).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numba import njit
from scipy import ndimage

#: Slack (relative) on the inflation radius, so a radius that is an exact multiple of the
#: resolution (0.3 m on 0.1 m cells) still covers the cell whose centre is at that distance
#: despite ``0.3 / 0.1 == 2.9999999999999996``.
_INFLATE_REL_TOL = 1e-9


@njit(cache=True, nogil=True)
def _segment_free(occ: np.ndarray, res: float, ox: float, oy: float,
                  ax: float, ay: float, bx: float, by: float) -> bool:
    """True iff no point of segment a-b (world metres) lies in an occupied or outside cell.

    Amanatides-Woo traversal in supercover form: when the segment passes exactly through a
    cell corner, both cells beside the corner are checked too, so touching counts as hitting.
    """
    nx, ny = occ.shape
    # Continuous cell coordinates: cell i spans [i, i + 1) here, the same floor rule as
    # OccupancyGrid.world_to_cell, so both agree bit for bit on which cell holds a point.
    gax = (ax - ox) / res + 0.5
    gay = (ay - oy) / res + 0.5
    gbx = (bx - ox) / res + 0.5
    gby = (by - oy) / res + 0.5
    ix = int(math.floor(gax))
    iy = int(math.floor(gay))
    ex = int(math.floor(gbx))
    ey = int(math.floor(gby))
    # The grid is a convex box, so the segment stays inside iff both ends do.
    if ix < 0 or iy < 0 or ix >= nx or iy >= ny or ex < 0 or ey < 0 or ex >= nx or ey >= ny:
        return False
    dx = gbx - gax
    dy = gby - gay
    sx = 1 if dx > 0 else -1
    sy = 1 if dy > 0 else -1
    inf = math.inf
    if dx != 0.0:
        t_dx = abs(1.0 / dx)
        t_x = ((ix + 1 - gax) if dx > 0 else (gax - ix)) * t_dx
    else:
        t_dx = inf
        t_x = inf
    if dy != 0.0:
        t_dy = abs(1.0 / dy)
        t_y = ((iy + 1 - gay) if dy > 0 else (gay - iy)) * t_dy
    else:
        t_dy = inf
        t_y = inf
    if occ[ix, iy]:
        return False
    # Each step moves one axis toward the end cell; once an axis has arrived it is frozen, so
    # rounding in t_x / t_y can reorder steps but never overshoot or loop forever.
    while ix != ex or iy != ey:
        if iy == ey or (ix != ex and t_x < t_y):
            ix += sx
            t_x += t_dx
        elif ix == ex or t_y < t_x:
            iy += sy
            t_y += t_dy
        else:
            # Exactly through a corner: the supercover includes both side cells.
            if occ[ix + sx, iy] or occ[ix, iy + sy]:
                return False
            ix += sx
            iy += sy
            t_x += t_dx
            t_y += t_dy
        if occ[ix, iy]:
            return False
    return True


class OccupancyGrid:
    """An immutable boolean occupancy grid.

    Args:
        occupied: (nx, ny) array, True = occupied, indexed ``[ix, iy]``. Copied and made read-only.
        resolution: Cell side (m), > 0.
        origin: World (x, y) (m) of the centre of cell (0, 0).

    Raises:
        ValueError: ``occupied`` is not a non-empty 2-D array, or ``resolution`` is not a
            positive finite number, or ``origin`` is not two finite numbers.
    """

    __slots__ = ("_occ", "_res", "_origin")

    def __init__(self, occupied: np.ndarray, resolution: float,
                 origin: tuple[float, float] = (0.0, 0.0)) -> None:
        occ = np.asarray(occupied)
        if occ.ndim != 2 or occ.size == 0:
            raise ValueError(f"occupied must be a non-empty 2-D array, got shape {occ.shape}")
        res = float(resolution)
        if not (math.isfinite(res) and res > 0):
            raise ValueError(f"resolution must be a positive finite number of metres, got {resolution!r}")
        if len(origin) != 2 or not all(math.isfinite(float(v)) for v in origin):
            raise ValueError(f"origin must be two finite numbers (x, y) in metres, got {origin!r}")
        # A private C-contiguous bool copy: the numba kernels compile once for this layout,
        # and nobody can change the map under a planner's feet.
        self._occ = np.ascontiguousarray(occ != 0, dtype=np.bool_)
        self._occ.setflags(write=False)
        self._res = res
        self._origin = (float(origin[0]), float(origin[1]))

    @property
    def occupied(self) -> np.ndarray:
        """(nx, ny) read-only bool array, True = occupied."""
        return self._occ

    @property
    def resolution(self) -> float:
        """Cell side (m)."""
        return self._res

    @property
    def origin(self) -> tuple[float, float]:
        """World (x, y) (m) of the centre of cell (0, 0)."""
        return self._origin

    @property
    def shape(self) -> tuple[int, int]:
        """(nx, ny) in cells."""
        return self._occ.shape  # type: ignore[return-value]

    @property
    def bounds(self) -> tuple[float, float, float, float]:
        """World extent (x_min, x_max, y_min, y_max) in metres, cell edges included."""
        (nx, ny), r, (ox, oy) = self._occ.shape, self._res, self._origin
        return (ox - 0.5 * r, ox + (nx - 0.5) * r, oy - 0.5 * r, oy + (ny - 0.5) * r)

    def world_to_cell(self, xy: Sequence[float]) -> tuple[int, int]:
        """The cell (ix, iy) holding world point ``xy`` (m); may be out of bounds."""
        return (math.floor((xy[0] - self._origin[0]) / self._res + 0.5),
                math.floor((xy[1] - self._origin[1]) / self._res + 0.5))

    def cell_to_world(self, ix: int, iy: int) -> tuple[float, float]:
        """World (x, y) (m) of the centre of cell (ix, iy)."""
        return (self._origin[0] + ix * self._res, self._origin[1] + iy * self._res)

    def in_bounds(self, ix: int, iy: int) -> bool:
        """True iff cell (ix, iy) lies on the grid."""
        nx, ny = self._occ.shape
        return 0 <= ix < nx and 0 <= iy < ny

    def is_free_point(self, xy: Sequence[float]) -> bool:
        """True iff world point ``xy`` (m) lies in a free cell on the grid."""
        ix, iy = self.world_to_cell(xy)
        return self.in_bounds(ix, iy) and not self._occ[ix, iy]

    def segment_free(self, a_xy: Sequence[float], b_xy: Sequence[float]) -> bool:
        """True iff the segment a-b (m) crosses no occupied cell and stays on the grid.

        Exact (grid traversal, not sampling); a segment through a cell corner touches all
        four cells around it.
        """
        return bool(_segment_free(self._occ, self._res, self._origin[0], self._origin[1],
                                  float(a_xy[0]), float(a_xy[1]), float(b_xy[0]), float(b_xy[1])))

    def inflate(self, radius_m: float) -> OccupancyGrid:
        """A new grid with every cell whose centre is within ``radius_m`` (m) of an occupied
        cell's centre marked occupied (Euclidean disc footprint).

        Raises:
            ValueError: ``radius_m`` is negative or not finite.
        """
        return self.inflate_many((radius_m,))[0]

    def inflate_many(self, radii_m) -> list[OccupancyGrid]:
        """:meth:`inflate` by each of ``radii_m`` (m), from one distance transform.

        Raises:
            ValueError: a radius is negative or not finite.
        """
        radii = [float(r) for r in radii_m]
        for r, given in zip(radii, radii_m):
            if not (math.isfinite(r) and r >= 0):
                raise ValueError(f"radius_m must be a finite number >= 0 metres, got {given!r}")
        if not self._occ.any():
            return [OccupancyGrid(self._occ, self._res, self._origin) for _ in radii]
        # Exact Euclidean distance (in cells) from each cell centre to the nearest occupied
        # centre; squared distances are integers, so round them before comparing.
        dist = ndimage.distance_transform_edt(~self._occ)
        squared = np.rint(dist * dist)
        return [OccupancyGrid(squared <= (r / self._res) ** 2 * (1.0 + _INFLATE_REL_TOL), self._res, self._origin)
                for r in radii]

    def __repr__(self) -> str:
        nx, ny = self.shape
        return (f"OccupancyGrid({nx}x{ny} cells, resolution={self._res} m, origin={self._origin}, "
                f"{int(self._occ.sum())} occupied)")
