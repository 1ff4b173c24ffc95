"""Start/goal sampling in the free space of a layout."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from bulletnav.config import SamplerConfig
from bulletnav.errors import SamplingError
from bulletnav.sim.layout import Layout


@dataclass(frozen=True)
class FreeSpace:
    """Coarse free-space grids of one layout, computed once and reused for every episode.

    ``clear[ix, iy]`` is True where a cell centre has the required clearance; ``component``
    labels the 8-connected regions of the robot's configuration space (obstacles inflated
    by the robot's disc, ``radius``), so two points are mutually reachable iff their labels match.
    """

    layout: Layout
    resolution: float
    xs: np.ndarray
    ys: np.ndarray
    clear: np.ndarray
    component: np.ndarray

    @classmethod
    def build(cls, layout: Layout, config: SamplerConfig, radius: float) -> FreeSpace:
        """Grids of ``layout`` for a robot disc of ``radius`` (m; ``RobotGeometry.radius``)."""
        xs, ys = layout.grid_axes(config.grid_resolution)
        gx, gy = np.meshgrid(xs, ys, indexing="ij")
        dist = layout.clearance(gx, gy)
        clear = dist > config.clearance
        passable = dist > radius
        component, _ = ndimage.label(passable, structure=np.ones((3, 3), dtype=bool))
        return cls(layout, config.grid_resolution, xs, ys, clear, component)

    def cell(self, xy: tuple[float, float] | np.ndarray) -> tuple[int, int]:
        hx, hy = self.layout.half_extents
        ix = int(np.clip((xy[0] + hx) // self.resolution, 0, len(self.xs) - 1))
        iy = int(np.clip((xy[1] + hy) // self.resolution, 0, len(self.ys) - 1))
        return ix, iy

    def reachable(self, a: tuple[float, float], b: tuple[float, float]) -> bool:
        """True when ``b`` is reachable from ``a`` for the robot footprint on the coarse grid."""
        ca, cb = self.component[self.cell(a)], self.component[self.cell(b)]
        return bool(ca != 0 and ca == cb)


def sample_start_goal(
    free: FreeSpace, rng: np.random.Generator, config: SamplerConfig
) -> tuple[tuple[float, float, float], tuple[float, float]]:
    """Draw a start pose (x, y, yaw) and a goal (x, y) from ``rng``.

    Both lie on cells with ``config.clearance`` to every obstacle, their straight-line
    distance is within ``[min_goal_distance, max_goal_distance]``, and the goal is reachable
    from the start on the free-space grid. The start yaw is uniform in [-pi, pi).

    Raises:
        SamplingError: the layout has no such pair.
    """
    cells = np.argwhere(free.clear & (free.component > 0))
    if len(cells) == 0:
        raise SamplingError(f"layout {free.layout.source or free.layout.name!r}: no free cell with "
                            f"{config.clearance} m clearance for a start or goal")
    points = np.stack([free.xs[cells[:, 0]], free.ys[cells[:, 1]]], axis=1)
    labels = free.component[cells[:, 0], cells[:, 1]]
    jitter = free.resolution / 2
    for _ in range(config.max_tries):
        i = int(rng.integers(len(points)))
        d = np.hypot(points[:, 0] - points[i, 0], points[:, 1] - points[i, 1])
        ok = (labels == labels[i]) & (d >= config.min_goal_distance + jitter * 1.5) & (d <= config.max_goal_distance - jitter * 1.5)
        candidates = np.flatnonzero(ok)
        if len(candidates) == 0:
            continue
        j = int(candidates[rng.integers(len(candidates))])
        # Jitter inside the cells so starts and goals are not quantised to the grid.
        sx, sy = points[i] + rng.uniform(-jitter, jitter, 2) * 0.5
        gx, gy = points[j] + rng.uniform(-jitter, jitter, 2) * 0.5
        yaw = float(rng.uniform(-math.pi, math.pi))
        return (float(sx), float(sy), yaw), (float(gx), float(gy))
    raise SamplingError(
        f"layout {free.layout.source or free.layout.name!r}: no reachable start/goal pair "
        f"{config.min_goal_distance}-{config.max_goal_distance} m apart with {config.clearance} m clearance "
        f"after {config.max_tries} tries"
    )
