"""The kinematic profile's compiled kernels (bulletnav.sim.kinematic_kernels) against
independent references: the lidar's culled level casts against the numpy ExactCaster (every
ray against every shape), the contact test against shapely's polygon distances, the drive
against its closed-form arcs and the IEEE remainder."""

from __future__ import annotations

import math

import numpy as np
import pytest
import shapely
from shapely import affinity

from bulletnav.sensors.lidar import ray_angles
from bulletnav.sensors.raycast import ExactCaster, LevelCaster
from bulletnav.sim import kinematic_kernels as kk
from bulletnav.sim.world import Primitive


def _cylinder(rng: np.random.Generator, r: float, spread: float) -> Primitive:
    """A cylinder of radius ``r`` centred within ``spread`` m of the origin, its height drawn."""
    return Primitive("cylinder", (rng.uniform(-spread, spread), rng.uniform(-spread, spread), rng.uniform(0.1, 1.0)),
                     (r, r, rng.uniform(0.05, 1.0)))


def _box(rng: np.random.Generator) -> Primitive:
    """A box of any size up to 6 x 6 m and any yaw, centred within 5 m of the origin."""
    return Primitive("box", (rng.uniform(-5, 5), rng.uniform(-5, 5), rng.uniform(0.1, 1.0)),
                     (rng.uniform(0.02, 3.0), rng.uniform(0.02, 3.0), rng.uniform(0.05, 1.0)), rng.uniform(-4, 4))


def _scene(rng: np.random.Generator) -> list[Primitive]:
    prims = [Primitive("plane", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))]
    for _ in range(int(rng.integers(0, 40))):
        prims.append(_cylinder(rng, rng.uniform(0.05, 0.5), 5.0) if rng.random() < 0.5 else _box(rng))
    return prims


@pytest.mark.parametrize("seed", range(6))
def test_culled_level_casts_equal_every_ray_against_every_shape(seed: int) -> None:
    rng = np.random.default_rng(seed)
    worst, hits = 0.0, 0
    for _ in range(60):
        prims = _scene(rng)
        n = int(rng.choice([1, 2, 5, 36, 72, 720]))
        fov = float(rng.choice([360.0, 270.0, 180.0, 45.0]))
        angles = ray_angles(n, fov)
        origin = (rng.uniform(-6, 6), rng.uniform(-6, 6), rng.uniform(0.05, 1.2))
        yaw, length = rng.uniform(-7, 7), float(rng.choice([2.0, 30.0]))
        a = angles + yaw
        ref = ExactCaster(prims).cast(np.array(origin), np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1), length)
        got = LevelCaster(prims, angles).cast(origin, yaw, length, np.full(n, np.inf))
        got[got > length] = np.inf
        assert np.array_equal(np.isfinite(ref), np.isfinite(got))
        both = np.isfinite(ref)
        hits += int(both.sum())
        if both.any():
            worst = max(worst, float(np.abs(ref[both] - got[both]).max()))
    assert hits > 500  # the scenes are hit, not empty
    assert worst < 1e-9


def _dense_scene(rng: np.random.Generator) -> list[Primitive]:
    """Up to 300 shapes, many of them small cylinders packed as in a BARN world, with long walls round them."""
    prims = []
    for _ in range(int(rng.integers(1, 300))):
        if rng.random() < 0.7:
            prims.append(_cylinder(rng, rng.uniform(0.03, 0.5) if rng.random() < 0.3 else 0.075, 3.0))
        else:
            prims.append(_box(rng))
    walls = [((0.0, 15.0), (5.0, 0.1)), ((0.0, -15.0), (5.0, 0.1)), ((5.0, 0.0), (0.1, 15.0)), ((-5.0, 0.0), (0.1, 15.0))]
    return prims + [Primitive("box", (x, y, 0.5), (hx, hy, 0.5)) for (x, y), (hx, hy) in walls]


@pytest.mark.parametrize("seed", range(4))
def test_grid_casts_are_the_culled_casts_to_the_bit_and_every_ray_against_every_shape(seed: int) -> None:
    """The grid walk (cast_grid) stops at the first cell whose far side lies beyond the nearest
    hit, and leaps through empty cells: its distances must be the culled caster's to the bit
    and the numpy reference's within rounding, rays starting inside shapes, outside the grid and
    beyond the walls included."""
    rng = np.random.default_rng(200 + seed)
    worst, hits = 0.0, 0
    for _ in range(40):
        prims = _dense_scene(rng)
        n = int(rng.choice([1, 5, 72, 720]))
        angles = ray_angles(n, float(rng.choice([360.0, 270.0])))
        grid, culled = LevelCaster(prims, angles, grid=True), LevelCaster(prims, angles, grid=False)
        for _ in range(5):
            origin = (rng.uniform(-7, 7), rng.uniform(-17, 17), rng.uniform(0.05, 1.2))
            yaw, length = rng.uniform(-7, 7), float(rng.choice([2.0, 30.0]))
            got = grid.cast(origin, yaw, length, np.full(n, np.inf))
            assert np.array_equal(np.minimum(got / length, 1.0),
                                  np.minimum(culled.cast(origin, yaw, length, np.full(n, np.inf)) / length, 1.0))
            a = angles + yaw
            ref = ExactCaster(prims).cast(np.array(origin), np.stack([np.cos(a), np.sin(a), np.zeros_like(a)], 1), length)
            got[got > length] = np.inf
            assert np.array_equal(np.isfinite(ref), np.isfinite(got))
            both = np.isfinite(ref)
            hits += int(both.sum())
            if both.any():
                worst = max(worst, float(np.abs(ref[both] - got[both]).max()))
    assert hits > 2000
    assert worst < 1e-9


def test_grid_lists_each_shape_where_it_lies_and_its_empty_distance_is_scipys() -> None:
    """The grid's cells against shapely (a cell lists a shape exactly where the shape's bounding
    box meets it) and its leap distances against scipy's chessboard distance transform."""
    from scipy.ndimage import distance_transform_cdt

    rng = np.random.default_rng(7)
    prims = _dense_scene(rng)
    caster = LevelCaster(prims, ray_angles(8, 360.0), grid=True)
    gx, gy, cell, nx, ny, starts, items, empty = caster._grid
    shapes = [("box", b) for b in caster._boxes] + [("cylinder", c) for c in caster._cyls]
    ix, iy = np.meshgrid(np.arange(nx), np.arange(ny), indexing="ij")
    squares = shapely.box(gx + ix.ravel() * cell, gy + iy.ravel() * cell, gx + (ix.ravel() + 1) * cell,
                          gy + (iy.ravel() + 1) * cell)  # cell ix * ny + iy
    member = np.zeros((len(shapes), nx * ny), dtype=bool)
    member[items, np.repeat(np.arange(nx * ny), np.diff(starts))] = True
    for j, (kind, sh) in enumerate(shapes):
        if kind == "box":
            c, s_ = abs(sh[2]), abs(sh[3])
            ex, ey = c * sh[4] + s_ * sh[5], s_ * sh[4] + c * sh[5]
        else:
            ex = ey = sh[2]
        bounds = shapely.box(sh[0] - ex, sh[1] - ey, sh[0] + ex, sh[1] + ey)
        listed = member[j]
        overlap = shapely.intersects(squares, bounds) & ~shapely.touches(squares, bounds)  # interiors meet
        assert np.all(listed[overlap])  # overlapping: listed (cells that only touch it may go either way)
        assert not np.any(listed[~shapely.dwithin(squares, bounds, 1e-5)])
    listed = (starts[1:] > starts[:-1]).reshape(nx, ny)
    assert np.array_equal(empty.reshape(nx, ny), distance_transform_cdt(~listed, metric="chessboard"))


def test_level_caster_refuses_uneven_fans_and_unknown_shapes() -> None:
    with pytest.raises(ValueError, match="evenly spaced"):
        LevelCaster([], np.array([0.0, 0.1, 0.5]))
    with pytest.raises(ValueError, match="mesh"):
        LevelCaster([Primitive("mesh", (0, 0, 0), (1, 1, 1))], ray_angles(8, 360.0))


def _rect(x: float, y: float, c: float, s: float, hx: float, hy: float) -> shapely.Polygon:
    box = shapely.box(-hx, -hy, hx, hy)
    return affinity.translate(affinity.rotate(box, math.atan2(s, c), use_radians=True, origin=(0, 0)), x, y)


@pytest.mark.parametrize("seed", range(4))
def test_contact_test_agrees_with_shapely_distances(seed: int) -> None:
    rng = np.random.default_rng(100 + seed)
    met = apart = 0
    for _ in range(400):
        k = int(rng.integers(1, 4))
        rects = np.array([(rng.uniform(-1, 1), rng.uniform(-1, 1), 0, 0, rng.uniform(0.05, 0.4), rng.uniform(0.05, 0.4))
                          for _ in range(k)])
        yaw = rng.uniform(-4, 4)
        rects[:, 2], rects[:, 3] = math.cos(yaw), math.sin(yaw)
        boxes = np.array([(rng.uniform(-2, 2), rng.uniform(-2, 2), *(lambda t: (math.cos(t), math.sin(t)))(rng.uniform(-4, 4)),
                           rng.uniform(0.02, 1), rng.uniform(0.02, 1)) for _ in range(int(rng.integers(0, 4)))]).reshape(-1, 6)
        cyls = np.array([(rng.uniform(-2, 2), rng.uniform(-2, 2), rng.uniform(0.02, 0.5))
                         for _ in range(int(rng.integers(0, 4)))]).reshape(-1, 3)
        margin = float(rng.choice([0.0, 0.05, 0.3]))
        box_hit, cyl_hit = np.zeros(len(boxes), bool), np.zeros(len(cyls), bool)
        reach = max(math.hypot(abs(r[0]), abs(r[1])) + math.hypot(r[4], r[5]) for r in rects)
        reaches = np.hypot(boxes[:, 4], boxes[:, 5])
        anything = kk.overlaps(rects, 0.0, 0.0, reach, margin, boxes, reaches, cyls, box_hit, cyl_hit, False)
        unmarked = np.zeros(len(boxes), bool), np.zeros(len(cyls), bool)
        first = kk.overlaps(rects, 0.0, 0.0, reach, margin, boxes, reaches, cyls, *unmarked, True)
        assert anything == box_hit.any() | cyl_hit.any() == first
        assert not unmarked[0].any() and not unmarked[1].any()
        robot = shapely.union_all([_rect(*r) for r in rects])
        for i, b in enumerate(boxes):
            # two rectangles each grown by margin meet iff some pair of their separating-axis
            # projections overlaps; shapely's distance <= margin is the same for margin 0 and a
            # bound either side otherwise: distance <= margin must hit, distance > 2 margin * sqrt2 must not
            d = robot.distance(_rect(*b))
            if d <= margin + 1e-9:
                assert box_hit[i], (rects, b, margin, d)
            elif d > 2 * margin * math.sqrt(2) + 1e-9:
                assert not box_hit[i], (rects, b, margin, d)
            met += bool(box_hit[i])
            apart += not box_hit[i]
        for i, (x, y, r) in enumerate(cyls):
            d = robot.distance(shapely.Point(x, y)) - r
            assert bool(cyl_hit[i]) == (d <= margin + 1e-9) or abs(d - margin) < 1e-9, (rects, (x, y, r), margin, d)
            met += bool(cyl_hit[i])
            apart += not cyl_hit[i]
    assert met > 100 and apart > 100


def test_drive_follows_exact_arcs_and_wraps_as_remainder() -> None:
    # no force limit to speak of: the rims reach their targets in one substep, then the pose is an exact arc
    wheelbase, radius, dt, n = 0.4, 0.1, 1 / 240, 240
    state = np.zeros(7)
    v, w = 0.8, 1.3
    tl, tr = v - w * wheelbase / 2, v + w * wheelbase / 2
    empty6, empty3 = np.zeros((0, 6)), np.zeros((0, 3))
    none = np.zeros(0, bool)
    assert not kk.drive(n, state, tl, tr, 1.0, 0.0, dt, 1e12, 8, wheelbase, radius, np.zeros((1, 4)), 0.3, 10.0,
                        empty6, np.zeros(0), empty3, none, none, False, empty6, np.zeros(0), empty3, none, none)
    t = n * dt
    r = v / w
    assert state[0] == pytest.approx(tl) and state[1] == pytest.approx(tr)
    assert state[2] == pytest.approx(r * math.sin(w * t), abs=1e-9)
    assert state[3] == pytest.approx(r * (1 - math.cos(w * t)), abs=1e-9)
    assert state[4] == pytest.approx(math.remainder(w * t, 2 * math.pi), abs=1e-12)
    assert state[5] == pytest.approx(tl * t / radius) and state[6] == pytest.approx(tr * t / radius)
    for yaw in np.random.default_rng(0).uniform(-3 * math.pi + 1e-9, 3 * math.pi - 1e-9, 2000):
        assert kk.wrap(float(yaw)) == math.remainder(float(yaw), 2 * math.pi)
    assert kk.wrap(math.pi) == math.remainder(math.pi, 2 * math.pi)
    assert kk.wrap(-math.pi) == math.remainder(-math.pi, 2 * math.pi)


def test_drive_stops_before_a_wall_and_marks_it() -> None:
    # a 0.2 m square robot driven at 1 m/s at a box whose face is 0.5 m ahead of its front
    wheelbase, radius, dt = 0.3, 0.05, 1 / 240
    body = np.array([[0.0, 0.0, 0.1, 0.1]])
    boxes = np.array([[1.1, 0.0, 1.0, 0.0, 0.5, 1.0]])
    hit = np.zeros(1, bool)
    empty6, empty3, none = np.zeros((0, 6)), np.zeros((0, 3)), np.zeros(0, bool)
    state = np.array([1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    assert kk.drive(240, state, 1.0, 1.0, 1.0, 0.0, dt, 1e12, 8, wheelbase, radius, body, math.hypot(0.1, 0.1),
                    1.0 + 1e-3, boxes, np.hypot(boxes[:, 4], boxes[:, 5]), empty3, hit, np.zeros(0, bool), False,
                    empty6, np.zeros(0), empty3, none, none)
    assert hit[0]
    assert 0.6 - dt <= state[2] + 0.1 <= 0.6  # front face stopped within a substep's travel of the wall
    assert state[0] == 0.0 and state[1] == 0.0
