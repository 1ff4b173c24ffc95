"""The reset path's compiled kernels give the array code's results bit for bit: footprint
distances, occupancy at any resolution and inflation, several levels in one pass, and the
movers' sampled line of sight (independent references: the NumPy expressions they replace)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bulletnav.config import WorldConfig
from bulletnav.sim import kernels
from bulletnav.sim.aisles import generate_aisles
from bulletnav.sim.dynamic import ClearanceMap
from bulletnav.sim.layout import Layout, Obstacle, generate_warehouse


def _random_obstacle(rng: np.random.Generator) -> Obstacle:
    center = tuple(rng.uniform(-8, 8, 2))
    if rng.random() < 0.5:
        return Obstacle("box", center, size=(rng.uniform(0.1, 5), rng.uniform(0.1, 2), 1.0), yaw=rng.uniform(-4, 4))
    return Obstacle("cylinder", center, radius=rng.uniform(0.05, 0.5), height=1.0)


def test_compiled_footprint_distance_is_the_array_codes_to_the_bit():
    rng = np.random.default_rng(1)
    for _ in range(300):
        o = _random_obstacle(rng)
        xs, ys = np.sort(rng.uniform(-10, 10, 23)), np.sort(rng.uniform(-10, 10, 17))
        reference = o.distance(xs[:, None], ys[None, :])
        got = np.array([[kernels._distance(*o.footprint(), x, y) for y in ys] for x in xs])
        np.testing.assert_array_equal(got, reference)
        pad = float(rng.uniform(0, 1.5))
        out = np.zeros((len(xs), len(ys)), dtype=bool)
        kernels.mark_within(out, xs, ys, 0, 0, *o.footprint(), pad)
        np.testing.assert_array_equal(out, reference <= pad)
        grid = rng.random((len(xs), len(ys))) < 0.1
        assert kernels.any_within(grid, xs, ys, 0, 0, *o.footprint(), pad) == bool(np.any(grid & (reference <= pad)))


@pytest.mark.parametrize("style", ["scattered", "aisles", "handmade"])
def test_occupancy_and_levels_equal_the_full_clearance_grid(style):
    rng = np.random.default_rng(2)
    for _ in range(6):
        if style == "scattered":
            layout = generate_warehouse(rng, WorldConfig(num_obstacles=int(rng.integers(0, 45))))
        elif style == "aisles":
            layout = generate_aisles(rng, WorldConfig(style="aisles", size=(20.0, 16.0)))
        else:  # obstacles touching and overlapping the walls' reach, odd resolutions
            layout = Layout((9.0, 7.0), tuple(_random_obstacle(rng) for _ in range(8)))
        for res in (0.05, 0.1, 0.13):
            xs, ys = layout.grid_axes(res)
            gx, gy = np.meshgrid(xs, ys, indexing="ij")
            clearance = layout.clearance(gx, gy)
            levels = (0.0, 0.2, 0.4, float(rng.uniform(0, 1)))
            stacked = layout.within_levels(xs, ys, levels)
            for q, level in enumerate(levels):
                np.testing.assert_array_equal(stacked[q], clearance <= level)
                np.testing.assert_array_equal(layout.occupancy(res, inflate=level), clearance <= level)


def _line_clear_reference(cmap: ClearanceMap, a, b, need: float) -> bool:
    """The array code the kernel replaced."""
    n = max(2, int(math.dist(a, b) / (cmap.resolution / 2)) + 1)
    t = np.linspace(0.0, 1.0, n)
    hx, hy = cmap.layout.half_extents
    ix = np.clip(((a[0] + (b[0] - a[0]) * t + hx) / cmap.resolution).astype(int), 0, cmap.clearance.shape[0] - 1)
    iy = np.clip(((a[1] + (b[1] - a[1]) * t + hy) / cmap.resolution).astype(int), 0, cmap.clearance.shape[1] - 1)
    return bool(np.all(cmap.clearance[ix, iy] >= need))


def test_compiled_line_of_sight_is_the_array_codes():
    rng = np.random.default_rng(3)
    cmap = ClearanceMap(generate_aisles(rng, WorldConfig(style="aisles", size=(20.0, 16.0))))
    cells = np.argwhere(cmap.clearance > 0.3)
    seen = set()
    for k in range(3000):
        a = cmap.point(tuple(cells[rng.integers(len(cells))]))
        b = cmap.point(tuple(cells[rng.integers(len(cells))]))
        if k % 3 == 0:
            b = (a[0], b[1])  # axis-aligned: sample points land exactly on cell edges
        if k % 5 == 0:
            a = (float(rng.uniform(-11, 11)), float(rng.uniform(-9, 9)))  # off-grid, even off the floor
        need = float(rng.choice([0.4, 0.9, rng.uniform(0, 1)]))
        expected = _line_clear_reference(cmap, a, b, need)
        assert cmap.line_clear(a, b, need) == expected, (a, b, need)
        seen.add(expected)
    assert seen == {True, False}


# ------------------------------------------------------------------ the procedural warehouse's placement
def _python_shape(kind, rng, aisle_yaw):
    """The shape draws of generate_warehouse before its loop was compiled (NumPy's rng.uniform spelled out)."""
    if kind == "rack":
        return "box", (rng.uniform(2.0, 3.5), 0.6, 2.0), 0.0, 0.0, aisle_yaw
    if kind == "column":
        return "cylinder", (0.0, 0.0, 0.0), rng.uniform(0.15, 0.25), 3.0, 0.0
    if kind == "pallet":
        yaw = aisle_yaw + float(rng.choice([0.0, math.pi / 2])) + float(rng.normal(0.0, 0.05))
        return "box", (1.2, 0.8, rng.uniform(0.4, 1.2)), 0.0, 0.0, yaw
    side = rng.uniform(0.3, 0.7)
    height = rng.uniform(0.3, 0.8)
    return "box", (side, side, height), 0.0, 0.0, rng.uniform(-math.pi, math.pi)


def _python_inside(o, hx, hy):
    if o.kind == "cylinder":
        return abs(o.center[0]) + o.radius <= hx and abs(o.center[1]) + o.radius <= hy
    c, s = abs(math.cos(o.yaw)), abs(math.sin(o.yaw))
    ex = c * o.size[0] / 2 + s * o.size[1] / 2
    ey = s * o.size[0] / 2 + c * o.size[1] / 2
    return abs(o.center[0]) + ex <= hx and abs(o.center[1]) + ey <= hy


def _window(o, pad, hx, hy, res, shape):
    """The raster's cells within the footprint's bounding circle grown by ``pad`` (the rest are farther)."""
    r = o.bounding_radius() + pad
    return (slice(max(int((o.center[0] - r + hx) / res), 0), min(int((o.center[0] + r + hx) / res) + 1, shape[0])),
            slice(max(int((o.center[1] - r + hy) / res), 0), min(int((o.center[1] + r + hy) / res) + 1, shape[1])))


def _python_warehouse(rng, config):
    """generate_warehouse's rejection sampling in plain NumPy, claiming cells by the array code
    (Obstacle.distance on the raster's cell centres): the obstacles, or None where one found no place."""
    from bulletnav.sim.layout import _category_counts

    hx, hy, gap, res = config.size[0] / 2, config.size[1] / 2, config.min_gap, 0.05
    aisle_yaw = float(rng.choice([0.0, math.pi / 2]))
    counts = _category_counts(config.num_obstacles)
    grid = np.zeros((int(math.ceil(config.size[0] / res)), int(math.ceil(config.size[1] / res))), dtype=bool)
    xs = -hx + res * (np.arange(grid.shape[0]) + 0.5)
    ys = -hy + res * (np.arange(grid.shape[1]) + 0.5)
    placed = []
    for kind in ("rack", "pallet", "column", "box"):
        for _ in range(counts[kind]):
            for _try in range(config.max_placement_tries):
                geometry, size, radius, height, yaw = _python_shape(kind, rng, aisle_yaw)
                center = (rng.uniform(-hx + gap, hx - gap), rng.uniform(-hy + gap, hy - gap))
                cand = Obstacle(geometry, center, size, radius, height, yaw, kind)
                if not _python_inside(cand, hx - gap, hy - gap):
                    continue
                sx, sy = _window(cand, 0.0, hx, hy, res, grid.shape)
                if np.any(grid[sx, sy] & (cand.distance(xs[sx, None], ys[None, sy]) <= 0.0)):
                    continue
                sx, sy = _window(cand, gap + res, hx, hy, res, grid.shape)
                grid[sx, sy] |= cand.distance(xs[sx, None], ys[None, sy]) <= gap + res
                placed.append(cand)
                break
            else:
                return None
    return placed


@pytest.mark.parametrize("seed", range(3))
def test_compiled_warehouse_placement_is_the_python_loops_to_the_bit(seed):
    """generate_warehouse's compiled rejection sampling (kernels.place_obstacles, drawing from
    the same Generator inside the kernel) against the plain loop: the same obstacles to the bit
    on default and crowded floors, the same Generator state after, and a floor too small fails
    in both."""
    from bulletnav.sim.layout import LayoutError

    rng = np.random.default_rng(300 + seed)
    configs = [WorldConfig(size=(float(rng.uniform(6, 16)), float(rng.uniform(6, 16))),
                           num_obstacles=int(rng.integers(0, 45)), min_gap=float(rng.uniform(0.3, 0.9))) for _ in range(5)]
    configs += [WorldConfig(), WorldConfig(size=(5.0, 5.0), num_obstacles=30, max_placement_tries=50)]  # the last: no room
    failed = 0
    for config in configs:
        s = int(rng.integers(0, 2**31))
        a, b = np.random.default_rng(s), np.random.default_rng(s)
        reference = _python_warehouse(a, config)
        if reference is None:
            with pytest.raises(LayoutError, match="could not place obstacle"):
                generate_warehouse(b, config)
            failed += 1
            continue
        got = generate_warehouse(b, config).obstacles
        assert got == tuple(reference)
        assert a.random() == b.random()  # the same draws, to the last
    assert failed >= 1  # the floor with no room
