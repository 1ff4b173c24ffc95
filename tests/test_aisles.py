"""Aisle warehouses (``layout_style="aisles"``, ``bulletnav/WarehouseAisles-v0``): the generator's
geometry and the episodes' difficulty, each checked with geometry written here (footprints,
rasters, segment-rectangle tests), not with the generator's or the sampler's own code."""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
import shapely
from gymnasium.utils.env_checker import check_env as gym_check_env
from scipy import ndimage

import bulletnav
from bulletnav.config import AislesConfig, EnvConfig, SamplerConfig, WorldConfig
from bulletnav.envs.warehouse import make_config
from bulletnav.evaluation import shortest_path_length
from bulletnav.sim.generators import WORLDS, world_generator
from bulletnav.sim.sampler import FreeSpace, sample_start_goal
from conftest import bit_equal

AISLES_ID = "bulletnav/WarehouseAisles-v0"
SPEC = AislesConfig()  # the ranges are the defaults
ROBOT_RADIUS = 0.2
RES = 0.05


def _world() -> WorldConfig:
    return make_config(**bulletnav.AISLES_KWARGS).world


def _layout(seed: int):
    return world_generator("aisles")(np.random.default_rng(seed), _world())


# --------------------------------------------------------------------------- independent geometry


def _extents(o) -> tuple[float, float, float, float]:
    """Axis-aligned bounds (x0, x1, y0, y1) of a yaw-0 box."""
    assert o.kind == "box" and o.yaw == 0.0
    return o.center[0] - o.size[0] / 2, o.center[0] + o.size[0] / 2, o.center[1] - o.size[1] / 2, o.center[1] + o.size[1] / 2


def _local(layout):
    """Row racks as (u0, u1, v0, v1) with rows along u, the end racks, and the floor (lu, lv).
    The row direction is the one the racks' lengths add up most along."""
    racks = [o for o in layout.obstacles if o.label == "rack"]
    along_x = sum(max(o.size[0] - o.size[1], 0) for o in racks) >= sum(max(o.size[1] - o.size[0], 0) for o in racks)
    rows, ends = [], []
    for o in racks:
        x0, x1, y0, y1 = _extents(o)
        (ends if (o.size[0] >= o.size[1]) != along_x else rows).append((x0, x1, y0, y1) if along_x else (y0, y1, x0, x1))
    lu, lv = layout.size if along_x else layout.size[::-1]
    return rows, ends, lu, lv, along_x


def _merge(intervals, touch=1e-6):
    out = []
    for a, b in sorted(intervals):
        if out and a <= out[-1][1] + touch:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [tuple(x) for x in out]


def _structure(layout):
    """Blocks (u-intervals covered by row racks), row units (merged v-intervals) and aisles
    (v-intervals between units or between a unit and a side wall), measured from the racks."""
    rows, ends, lu, lv, along_x = _local(layout)
    blocks = _merge([(r[0], r[1]) for r in rows])
    units = _merge([(r[2], r[3]) for r in rows])
    edges = [-lv / 2] + [x for u in units for x in u] + [lv / 2]
    gaps = [(edges[i], edges[i + 1]) for i in range(0, len(edges), 2)]
    aisles = [g for g in gaps if g[1] - g[0] > 1e-6]
    return rows, ends, blocks, units, aisles, lu, lv, along_x


def _footprint_distance(o, x, y):
    """Distance from points to an obstacle footprint, written out here (0 inside)."""
    dx, dy = x - o.center[0], y - o.center[1]
    if o.kind == "cylinder":
        return np.maximum(np.sqrt(dx * dx + dy * dy) - o.radius, 0.0)
    c, s = math.cos(o.yaw), math.sin(o.yaw)
    bx, by = np.abs(c * dx + s * dy) - o.size[0] / 2, np.abs(-s * dx + c * dy) - o.size[1] / 2
    return np.sqrt(np.maximum(bx, 0.0) ** 2 + np.maximum(by, 0.0) ** 2)


def _free_raster(layout, radius=ROBOT_RADIUS):
    """True where the robot's disc centred on the cell centre touches nothing (walls included)."""
    hx, hy = layout.size[0] / 2, layout.size[1] / 2
    xs = np.arange(-hx + RES / 2, hx, RES)
    ys = np.arange(-hy + RES / 2, hy, RES)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    free = (np.abs(gx) < hx - radius) & (np.abs(gy) < hy - radius)
    for o in layout.obstacles:
        free &= _footprint_distance(o, gx, gy) > radius
    return free, xs, ys


def _segment_hits_box(p, q, o) -> bool:
    """Separating-axis test of the segment p-q against a (rotated) box footprint."""
    c, s = math.cos(o.yaw), math.sin(o.yaw)
    hx, hy = o.size[0] / 2, o.size[1] / 2
    corners = [(o.center[0] + c * a - s * b, o.center[1] + s * a + c * b) for a, b in ((hx, hy), (-hx, hy), (-hx, -hy), (hx, -hy))]
    d = (q[0] - p[0], q[1] - p[1])
    axes = [(c, s), (-s, c), (-d[1], d[0])]
    for ax in axes:
        if ax == (0.0, 0.0):
            continue
        box = [ax[0] * x + ax[1] * y for x, y in corners]
        seg = [ax[0] * p[0] + ax[1] * p[1], ax[0] * q[0] + ax[1] * q[1]]
        if max(seg) < min(box) or max(box) < min(seg):
            return False
    return True


# --------------------------------------------------------------------------- (a) the layouts


@pytest.mark.parametrize("seed", range(30))
def test_layout_meets_the_geometric_spec(seed):
    layout = _layout(seed)
    rows, ends, blocks, units, aisles, lu, lv, along_x = _structure(layout)
    labels = {o.label for o in layout.obstacles}
    assert labels <= {"rack", "pallet", "box", "column"} and {"rack", "column"} <= labels
    # racks: 0.8-1.2 m deep, 4-10 m long, 2 m tall, axis-aligned, on the floor
    for o in layout.obstacles:
        if o.label == "rack":
            depth, length = sorted(o.size[:2])
            assert 0.8 - 1e-9 <= depth <= 1.2 + 1e-9 and 4.0 - 1e-9 <= length <= 10.0 + 1e-9, o
            assert o.size[2] == 2.0
        if o.kind == "box":
            if o.yaw == 0.0:
                x0, x1, y0, y1 = _extents(o)
            else:  # a turned square
                half = o.size[0] / 2 * (abs(math.cos(o.yaw)) + abs(math.sin(o.yaw)))
                x0, x1, y0, y1 = o.center[0] - half, o.center[0] + half, o.center[1] - half, o.center[1] + half
            assert x0 >= -layout.size[0] / 2 - 1e-9 and x1 <= layout.size[0] / 2 + 1e-9, o
            assert y0 >= -layout.size[1] / 2 - 1e-9 and y1 <= layout.size[1] / 2 + 1e-9, o
    # parallel rows with aisles 1.0-2.5 m wide between them (or between a row and a side wall)
    assert len(units) >= 2 and len(aisles) >= 2
    for a0, a1 in aisles:
        assert 1.0 - 1e-9 <= a1 - a0 <= 2.5 + 1e-9, (a0, a1)
    # every rack of a row spans its whole unit depth range or half of a back-to-back pair
    for r in rows:
        assert any(u0 - 1e-9 <= r[2] and r[3] <= u1 + 1e-9 for u0, u1 in units)
    # a cross aisle: a band across the whole floor, at least 1.5 m wide, that no rack enters, with racks on both sides
    cross = [(blocks[i][1], blocks[i + 1][0]) for i in range(len(blocks) - 1)]
    assert cross, "no cross aisle"
    for c0, c1 in cross:
        assert c1 - c0 >= 1.5 - 1e-9
        assert not any(r[0] < c1 - 1e-9 and r[1] > c0 + 1e-9 for r in rows + ends)
    # the free space is one piece for the robot's disc, and some aisle is a dead end
    free, xs, ys = _free_raster(layout)
    labelled, n = ndimage.label(free)
    sizes = np.bincount(labelled.ravel())[1:]
    assert sizes.max() >= 0.97 * free.sum(), "the free space is split"
    dead_ends = _dead_end_segments(free, xs, ys, blocks, aisles, along_x)
    assert dead_ends, "no dead-end aisle"


def _dead_end_segments(free, xs, ys, blocks, aisles, along_x):
    """Aisle segments (an aisle within one block) that one can enter only from one side: with
    the segment cut across its middle, one half is left in a piece of free floor that lies
    wholly inside the segment; never both halves (that would be an enclosed pocket)."""
    us, vs = (xs, ys) if along_x else (ys, xs)
    grid = free if along_x else free.T  # index [iu, iv]
    dead = []
    for b0, b1 in blocks:
        for a0, a1 in aisles:
            inside_u = (us > b0) & (us < b1)
            inside_v = (vs > a0) & (vs < a1)
            mid = (b0 + b1) / 2
            cut = grid.copy()
            cut[np.ix_(np.abs(us - mid) < 0.1, inside_v)] = False
            labelled, _ = ndimage.label(cut)
            rect = np.zeros_like(grid)
            rect[np.ix_(inside_u, inside_v)] = True
            isolated = []
            for half in (us < mid, us > mid):
                region = rect & half[:, None] & cut
                ids = set(np.unique(labelled[region])) - {0}
                pockets = [i for i in ids if not (labelled == i)[~rect].any() and (labelled == i).sum() * RES * RES > 0.5]
                isolated.append(bool(pockets))
            assert not all(isolated), f"aisle {a0:.2f}-{a1:.2f} in block {b0:.2f}-{b1:.2f} is closed at both ends"
            if any(isolated):
                dead.append((b0, b1, a0, a1))
    return dead


def test_clutter_narrows_aisles_without_closing_them():
    """Pallets and boxes stand inside aisles; the raster's free space stays one piece (above), and
    somewhere an aisle is narrower than its rack-to-rack width by some clutter."""
    narrowed = 0
    for seed in range(10):
        layout = _layout(seed)
        rows, ends, blocks, units, aisles, lu, lv, along_x = _structure(layout)
        for o in layout.obstacles:
            if o.label in ("pallet", "box"):
                u, v = o.center if along_x else o.center[::-1]
                if any(a0 < v < a1 for a0, a1 in aisles) and any(b0 < u < b1 for b0, b1 in blocks):
                    narrowed += 1
    assert narrowed >= 20


def _footprint(o):
    """An obstacle's footprint as a Shapely polygon: the box's size rectangle turned by its yaw
    about its centre, or the cylinder's disc."""
    if o.kind == "box":
        sx, sy = o.size[0] / 2, o.size[1] / 2
        box = shapely.affinity.rotate(shapely.box(-sx, -sy, sx, sy), o.yaw, origin=(0, 0), use_radians=True)
        return shapely.affinity.translate(box, *o.center)
    return shapely.Point(o.center).buffer(o.radius, quad_segs=64)


def test_generator_is_seeded_and_registered():
    assert WORLDS["aisles"] is world_generator("aisles")
    assert _layout(5) == _layout(5) and _layout(5) != _layout(6)
    rows_along = {_local(_layout(s))[4] for s in range(20)}
    assert rows_along == {True, False}  # rows run along x in some layouts and along y in others
    for axis in ("x", "y"):
        cfg = replace(_world(), aisles=AislesConfig(row_axis=axis))
        assert all(_local(world_generator("aisles")(np.random.default_rng(s), cfg))[4] == (axis == "x") for s in range(5))
    # the default 14 x 14 floor fits an aisle warehouse too
    small = world_generator("aisles")(np.random.default_rng(0), WorldConfig(style="aisles"))
    assert small.size == (14.0, 14.0) and any(o.label == "rack" for o in small.obstacles)
    # By Shapely, on five seeds and the small floor: every footprint lies on the floor and no
    # two overlap (they may touch: a rack against the wall or its neighbour).
    for layout in [*(_layout(s) for s in range(5)), small]:
        hx, hy = layout.half_extents
        floor = shapely.box(-hx, -hy, hx, hy).buffer(1e-9)
        shapes = [_footprint(o) for o in layout.obstacles]
        assert all(floor.covers(shape) for shape in shapes)
        overlap = max(a.intersection(b).area for k, a in enumerate(shapes) for b in shapes[k + 1:])
        assert overlap < 1e-9


# --------------------------------------------------------------------------- sampler options


def test_sampler_defaults_draw_exactly_as_before():
    """With the new options at their defaults the sampler draws the same numbers as the plain path."""
    layout = _layout(1)
    plain = SamplerConfig()
    free = FreeSpace.build(layout, plain, ROBOT_RADIUS)
    a, b = np.random.default_rng(7), np.random.default_rng(7)
    assert sample_start_goal(free, a, plain) == sample_start_goal(free, b, replace(plain, detour_share=0.3))
    assert a.random() == b.random()  # same number of draws
    with pytest.raises(ValueError, match="min_detour"):
        SamplerConfig(min_detour=0.5)
    with pytest.raises(ValueError, match="detour_share"):
        SamplerConfig(detour_share=1.5)


# --------------------------------------------------------------------------- (b) the episodes


@pytest.mark.slow
def test_episodes_need_planning():
    """Over 100 seeded resets: every goal is reachable for the robot's disc, and in at least half
    the straight line crosses a rack and the shortest path is at least 1.3 x the straight line."""
    env = gym.make(AISLES_ID)
    scene = env.unwrapped.scene
    both = blocked = detour = 0
    n = 100
    for seed in range(n):
        env.reset(seed=seed)
        start, goal, layout = scene.start[:2], scene.goal, scene.layout
        straight = math.dist(start, goal)
        shortest = shortest_path_length(layout, start, goal, radius=scene.geometry.radius)
        assert math.isfinite(shortest), f"seed {seed}: goal unreachable"
        hits = any(_segment_hits_box(start, goal, o) for o in layout.obstacles if o.label == "rack")
        long_way = shortest >= 1.3 * straight
        blocked += hits
        detour += long_way
        both += hits and long_way
    env.close()
    assert both / n >= 0.5, (blocked, detour, both)


def test_segment_box_test_is_right():
    """The test's own segment-rectangle check on hand cases."""
    from bulletnav.sim.layout import Obstacle

    box = Obstacle("box", (0.0, 0.0), size=(2.0, 1.0, 1.0))
    assert _segment_hits_box((-3, 0), (3, 0), box) and not _segment_hits_box((-3, 0.6), (3, 0.6), box)
    assert not _segment_hits_box((-3, 2), (-1.1, 0), box) and _segment_hits_box((-3, 2), (-0.9, 0), box)
    turned = Obstacle("box", (0.0, 0.0), size=(2.0, 0.2, 1.0), yaw=math.pi / 4)
    assert _segment_hits_box((-1, 1), (1, -1), turned) and not _segment_hits_box((0.3, -0.8), (0.8, -0.3), turned)


# --------------------------------------------------------------------------- (c) the env


def _all_warnings(fn) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn()
    return [str(w.message) for w in caught]


def test_env_is_registered_with_its_settings():
    env = gym.make(AISLES_ID)
    cfg = env.unwrapped.config
    assert env.spec.max_episode_steps == 2400
    assert cfg.world.style == "aisles" and cfg.task.collision_terminates is True
    assert cfg.sampler.min_detour > 1.0 and cfg.sampler.blocked_by == ("rack",)
    env.close()
    base = make_config()
    assert base == EnvConfig() and base.sampler.min_detour == 1.0 and base.sampler.blocked_by == ()
    assert make_config(blocked_by="rack").sampler.blocked_by == ("rack",)


def test_check_env_passes():
    env = gym.make(AISLES_ID, normalize_actions=True)
    assert _all_warnings(lambda: gym_check_env(env.unwrapped, skip_render_check=True)) == []
    env.close()


def _rollout(seed: int, steps: int = 150):
    env = gym.make(AISLES_ID)
    env.action_space.seed(seed)
    trace = [env.reset(seed=seed)]
    for _ in range(steps):
        step = env.step(env.action_space.sample())
        trace.append(step)
        if step[2] or step[3]:
            trace.append(env.reset())
    layout = env.unwrapped.scene.layout
    env.close()
    return trace, layout


def test_env_is_deterministic_for_a_seed():
    a, layout_a = _rollout(4)
    b, layout_b = _rollout(4)
    assert layout_a == layout_b and bit_equal(a, b)
    assert _rollout(5, steps=0)[1] != layout_a
    # Every entry's goal distance is the Euclidean one from the true pose, and each episode's
    # path length the sum of the straight pieces between its poses.
    length = last = None
    for entry in a:
        info = entry[-1]
        (x, y, _), (gx, gy) = info["pose"], info["goal"]
        assert info["distance_to_goal"] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
        if len(entry) == 2:  # a reset
            assert info["initial_distance"] == info["distance_to_goal"]
            length, last = 0.0, (x, y)
            continue
        length += math.hypot(x - last[0], y - last[1])
        last = (x, y)
        assert info["path_length"] == pytest.approx(length, abs=1e-9)


def test_aisle_env_on_a_world_without_racks_draws_plain_episodes():
    """The planning filter needs racks; a YAML world without any gets plain pairs, not an error."""
    from bulletnav.config import asset_path

    env = gym.make("bulletnav/WarehouseAisles-v0", world=str(asset_path("worlds", "empty.yaml")))
    _, info = env.reset(seed=0)
    assert 3.0 <= info["initial_distance"] <= 10.0
    # A plain pair: the straight distance, both ends on the floor clear of its walls (Shapely).
    (x, y, _), (gx, gy) = info["pose"], info["goal"]
    assert info["initial_distance"] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
    hx, hy = env.unwrapped.scene.layout.half_extents
    floor = shapely.box(-hx, -hy, hx, hy)
    for point in (shapely.Point(x, y), shapely.Point(gx, gy)):
        assert floor.contains(point) and floor.exterior.distance(point) >= SamplerConfig().clearance - 0.05
    env.close()
