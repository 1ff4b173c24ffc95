"""Closed-form ray casts against a static world of boxes, upright cylinders and the floor.

PyBullet casts a ray against a convex shape with an iterative convex cast (GJK), whose cost
grows with every shape whose bounding box the whole ray crosses, hit or not: a 30 m lidar in
a BARN world (181-365 cylinders) cost 2-7 ms a scan of 72 rays here, most of it on cylinders
behind the first hit; its hits on a cylinder lie up to about 2 mm outside the surface (a grazing
ray can read metres short), and its hit distances move by up to 2e-4 m with the ray's length. The
shapes a bulletnav world is built from (:class:`~bulletnav.sim.world.Primitive`) have exact
intersections: a slab test for a box, a quadratic and two caps for a cylinder, one division
for the floor. :class:`ExactCaster` does them for every ray and shape at once with numpy.

It sees only what it is given: the static primitives of a world. Movers, event bodies and any
body built outside :class:`~bulletnav.sim.world.World` are not in it (the scene refuses the
exact caster in a world that has them).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bulletnav.sim.kinematic_kernels import cast_grid, cast_level, shape_grid
from bulletnav.sim.world import Primitive


class ExactCaster:
    """Nearest hits of rays against a fixed set of primitives, in closed form.

    Args:
        primitives: the static shapes (world frame).
    """

    def __init__(self, primitives: Sequence[Primitive]) -> None:
        boxes = [s for s in primitives if s.kind == "box"]
        cylinders = [s for s in primitives if s.kind == "cylinder"]
        planes = [s for s in primitives if s.kind == "plane"]
        unknown = {s.kind for s in primitives} - {"box", "cylinder", "plane"}
        if unknown:
            raise ValueError(f"ExactCaster: cannot cast against {', '.join(sorted(unknown))}")
        # boxes: centre, half extents, yaw as cos/sin (rotation about z only)
        self._box_c = np.array([s.center for s in boxes], dtype=np.float64).reshape(-1, 3)
        self._box_h = np.array([s.half for s in boxes], dtype=np.float64).reshape(-1, 3)
        self._box_cs = np.array([(np.cos(s.yaw), np.sin(s.yaw)) for s in boxes], dtype=np.float64).reshape(-1, 2)
        # cylinders: axis along z; centre, radius, half height
        self._cyl_c = np.array([s.center for s in cylinders], dtype=np.float64).reshape(-1, 3)
        self._cyl_r = np.array([s.half[0] for s in cylinders], dtype=np.float64)
        self._cyl_hz = np.array([s.half[2] for s in cylinders], dtype=np.float64)
        # horizontal planes facing up (the floor): their heights
        self._plane_z = np.array([s.center[2] for s in planes], dtype=np.float64)

    def cast(self, origin: np.ndarray, directions: np.ndarray, length: float) -> np.ndarray:
        """Distance along each ray to its nearest hit, ``inf`` where nothing lies within ``length``.

        Args:
            origin: (3,) start of every ray (world frame, m).
            directions: (N, 3) unit directions (world frame).
            length: the rays' length (m).

        A ray that starts inside a shape hits it at 0.
        """
        o = np.asarray(origin, dtype=np.float64)
        d = np.asarray(directions, dtype=np.float64)
        best = np.full(len(d), np.inf)
        with np.errstate(divide="ignore", invalid="ignore"):
            if len(self._cyl_r):
                best = np.minimum(best, self._cylinders(o, d))
            if len(self._box_h):
                best = np.minimum(best, self._boxes(o, d))
            if len(self._plane_z):
                best = np.minimum(best, self._planes(o, d))
        best[best > length] = np.inf
        return best

    def _cylinders(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        # In each cylinder's frame the ray is inside the infinite cylinder |xy| <= r for t in
        # [t_in, t_out] (roots of a t^2 + 2 b t + c = 0) and inside the slab |z| <= hz for t in
        # [z_lo, z_hi]; it hits at the start of the overlap (0 if it starts inside). Only the
        # pairs whose line passes within r (b^2 >= a c) are solved.
        rel = self._cyl_c - o[None, :]  # (M, 3): centre minus origin
        dxy = d[:, :2]
        a = np.einsum("ij,ij->i", dxy, dxy)  # (N,)
        b = -(dxy @ rel[:, :2].T)  # (N, M): (o - centre) . d in the plane
        c = np.einsum("ij,ij->i", rel[:, :2], rel[:, :2]) - self._cyl_r ** 2  # (M,)
        disc = b * b - a[:, None] * c[None, :]
        ray, cyl = np.nonzero(disc >= 0)
        best = np.full(len(d), np.inf)
        if not len(ray):
            return best
        a_k, b_k, root = a[ray], b[ray, cyl], np.sqrt(disc[ray, cyl])
        # a vertical ray (no horizontal part: a = b = disc = 0 for every cylinder) stays where it
        # starts in the plane: inside the circle for all t when it starts within the radius
        # (c <= 0), else never
        flat = a_k <= 1e-12
        within = c[cyl] <= 0.0
        a_safe = np.where(flat, 1.0, a_k)
        t_in = np.where(flat, np.where(within, -np.inf, np.inf), (-b_k - root) / a_safe)
        t_out = np.where(flat, np.where(within, np.inf, -np.inf), (-b_k + root) / a_safe)
        oz = -rel[cyl, 2]
        dz = d[ray, 2]
        hz = self._cyl_hz[cyl]
        dz = np.where(dz == 0, 1e-300, dz)  # level: (-inf, inf) inside the slab, no overlap outside
        z1, z2 = (-hz - oz) / dz, (hz - oz) / dz
        z_lo, z_hi = np.minimum(z1, z2), np.maximum(z1, z2)
        enter = np.maximum(t_in, z_lo)
        leave = np.minimum(t_out, z_hi)
        ok = (enter <= leave) & (leave >= 0)
        t = np.where(ok, np.maximum(enter, 0.0), np.inf)
        np.minimum.at(best, ray, t)
        return best

    def _boxes(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        # slab test in each box's frame (rotated by -yaw); a direction component of 0 becomes
        # 1e-300, so a ray parallel to a slab gets (-inf, inf) inside it and no overlap outside
        cos, sin = self._box_cs[:, 0], self._box_cs[:, 1]
        rel = o[None, :] - self._box_c
        local_o = np.stack([cos * rel[:, 0] + sin * rel[:, 1], -sin * rel[:, 0] + cos * rel[:, 1], rel[:, 2]])  # (3, M)
        local_d = np.stack([np.outer(d[:, 0], cos) + np.outer(d[:, 1], sin),
                            np.outer(d[:, 1], cos) - np.outer(d[:, 0], sin),
                            np.broadcast_to(d[:, 2:3], (len(d), len(cos)))])  # (3, N, M)
        local_d = np.where(local_d == 0, 1e-300, local_d)
        h = self._box_h.T[:, None, :]  # (3, 1, M)
        t1 = (-h - local_o[:, None, :]) / local_d
        t2 = (h - local_o[:, None, :]) / local_d
        enter = np.minimum(t1, t2).max(axis=0)
        leave = np.maximum(t1, t2).min(axis=0)
        ok = (enter <= leave) & (leave >= 0)
        return np.where(ok, np.maximum(enter, 0.0), np.inf).min(axis=1)

    def _planes(self, o: np.ndarray, d: np.ndarray) -> np.ndarray:
        height = o[2] - self._plane_z[None, :]  # above each plane (> 0)
        t = -height / d[:, 2:3]
        ok = (d[:, 2:3] < 0) & (height >= 0)
        hits = np.where(ok, t, np.inf)
        return np.where(height <= 0, 0.0, hits).min(axis=1)


class LevelCaster:
    """Nearest hits of a fixed fan of level rays against boxes and cylinders, compiled
    (:func:`bulletnav.sim.kinematic_kernels.cast_level`): each shape is tested only against the
    rays inside the angle it subtends, so a scan costs what the shapes cover; with many shapes
    (:data:`GRID_MIN_SHAPES`) each ray walks a grid of them instead
    (:func:`~bulletnav.sim.kinematic_kernels.cast_grid`), the same distances to the bit. The same
    intersections as :class:`ExactCaster` (within rounding) for rays with no vertical part,
    as a lidar that never tilts casts (the kinematic profile's).

    Args:
        primitives: the shapes (world frame); planes are never hit by a level ray above them.
        angles: the fan's ray angles (rad from the heading), evenly spaced (:func:`bulletnav.sensors.lidar.ray_angles`).
        grid: walk a grid of the shapes (True), test them by angle (False), or choose by their
            number (None, :data:`GRID_MIN_SHAPES`).
    """

    def __init__(self, primitives: Sequence[Primitive], angles: np.ndarray, grid: bool | None = None) -> None:
        unknown = {s.kind for s in primitives} - {"box", "cylinder", "plane"}
        if unknown:
            raise ValueError(f"LevelCaster: cannot cast against {', '.join(sorted(unknown))}")
        self._boxes = np.array([(s.center[0], s.center[1], np.cos(s.yaw), np.sin(s.yaw), s.half[0], s.half[1],
                                 s.center[2], s.half[2]) for s in primitives if s.kind == "box"],
                               dtype=np.float64).reshape(-1, 8)
        self._cyls = np.array([(s.center[0], s.center[1], s.half[0], s.center[2], s.half[2])
                               for s in primitives if s.kind == "cylinder"], dtype=np.float64).reshape(-1, 5)
        self._planes = [s.center[2] for s in primitives if s.kind == "plane"]
        angles = np.asarray(angles, dtype=np.float64)
        self._cos, self._sin = np.cos(angles), np.sin(angles)
        # the window arithmetic takes the angles as a0 + i da modulo a turn (widened by a ray each side)
        steps = np.mod(np.diff(angles), 2 * np.pi)  # counter-clockwise steps, across the wrap at pi too
        self._a0 = float(angles[0]) if len(angles) else 0.0
        self._da = float(steps[0]) if len(steps) else 2 * np.pi
        if len(steps) and (self._da <= 0 or np.max(np.abs(steps - self._da)) > 1e-9):
            raise ValueError("LevelCaster: the ray angles must be evenly spaced, counter-clockwise")
        if grid is None:
            grid = len(self._boxes) + len(self._cyls) >= GRID_MIN_SHAPES
        self._grid = (shape_grid(self._boxes, self._cyls, GRID_CELL_MIN, GRID_CELL_MAX, GRID_CELLS_MAX)
                      if grid and len(self._boxes) + len(self._cyls) else None)

    def cast(self, origin: tuple[float, float, float], yaw: float, length: float, out: np.ndarray) -> np.ndarray:
        """Lower ``out`` (one entry a ray, ``inf`` for none yet) to each ray's distance to its
        nearest hit, the fan turned by ``yaw`` (rad) at ``origin`` (m); returns ``out``. A ray
        that starts inside a shape hits it at 0; hits beyond ``length`` may be left in ``out``."""
        x, y, z = origin
        if any(z <= h for h in self._planes):  # at or under a floor: every ray starts in it
            out[:] = 0.0
            return out
        if self._grid is not None:
            gx, gy, cell, nx, ny, starts, items, empty = self._grid
            cast_grid(float(x), float(y), float(z), float(yaw), self._cos, self._sin, self._boxes, self._cyls,
                      gx, gy, cell, nx, ny, starts, items, empty, float(length), out)
        else:
            cast_level(float(x), float(y), float(z), float(yaw), self._cos, self._sin, self._a0, self._da,
                       self._boxes, self._cyls, float(length), out)
        return out


GRID_MIN_SHAPES = 64
"""A :class:`LevelCaster` of at least this many shapes casts through a grid of them
(:func:`~bulletnav.sim.kinematic_kernels.cast_grid`; a BARN world's 237 cylinders: each ray
tests the few in the cells it crosses); fewer (a warehouse's racks and walls, a set of movers)
are tested shape by shape within the angle each subtends."""
GRID_CELLS_MAX = 65536
"""The most cells a shape grid has (its cells grow to keep within this)."""
GRID_CELL_MIN, GRID_CELL_MAX = 0.2, 2.0
"""The range (m) of a shape grid's cell size: four times the median shape's smaller half extent
(:func:`~bulletnav.sim.kinematic_kernels.shape_grid`; 0.3 m among BARN's cylinders)."""


