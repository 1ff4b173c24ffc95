"""Layouts: YAML validation, procedural generation, start/goal sampling."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
import shapely
from scipy.sparse import csgraph

from bulletnav.config import RobotConfig, SamplerConfig, WorldConfig, asset_path
from bulletnav.errors import LayoutError, SamplingError
from bulletnav.geometry import robot_geometry
from bulletnav.sim.layout import generate_warehouse, layout_to_dict, load_layout, parse_layout
from bulletnav.sim.sampler import FreeSpace, sample_start_goal

RADIUS = robot_geometry().radius  # the robot's disc for reachability (RobotConfig.footprint_radius)
BASE = {"size": [10.0, 8.0], "obstacles": [{"type": "box", "center": [1.0, 1.0], "size": [1.0, 0.5, 1.0]}]}


@pytest.mark.parametrize("name", ["aisles", "hall", "empty"])
def test_sample_layouts_load_and_admit_start_goal_pairs(name):
    layout = load_layout(asset_path("worlds", f"{name}.yaml"))
    free = FreeSpace.build(layout, SamplerConfig(), RADIUS)
    cfg = SamplerConfig()
    start, goal = sample_start_goal(free, np.random.default_rng(0), cfg)
    assert free.reachable(start[:2], goal)
    if layout.start is not None:
        assert free.reachable(layout.start[:2], layout.goal)
    # Against references outside the sampler: the Euclidean start-goal distance, Shapely's
    # clearance from the file's own obstacle fields, SciPy's connected components.
    assert cfg.min_goal_distance <= math.hypot(goal[0] - start[0], goal[1] - start[1]) <= cfg.max_goal_distance
    clearance = _shapely_clearance(layout_to_dict(layout), np.array([start[:2], goal]))
    assert clearance.min() >= cfg.clearance - 0.04  # up to the sampler's grid
    assert _reachable_independent(layout, start[:2], goal, cfg)


@pytest.mark.parametrize(
    "mutate, field",
    [
        (lambda d: d.pop("size"), "'size' is missing"),
        (lambda d: d.update(size=[10.0, "wide"]), "'size[1]'"),
        (lambda d: d["obstacles"][0].pop("center"), "'obstacles[0].center' is missing"),
        (lambda d: d["obstacles"][0].update(type="cone"), "'obstacles[0].type'"),
        (lambda d: d["obstacles"][0].update(size=[1.0, 0.5]), "'obstacles[0].size'"),
        (lambda d: d["obstacles"][0].update(size=[1.0, -0.5, 1.0]), "'obstacles[0].size[1]' must be > 0"),
        (lambda d: d["obstacles"][0].update(center=[4.8, 0.0]), "obstacles[0] at center [4.8, 0.0] extends outside the floor"),
        (lambda d: d.update(start=[1.0, 1.0, 0.0]), "'start' [1.0, 1.0] lies inside obstacles[0]"),
        (lambda d: d.update(goal=[9.0, 0.0]), "'goal' [9.0, 0.0] lies outside the floor"),
        (lambda d: d.update(obstacles="many"), "'obstacles' must be a list"),
        (lambda d: d.update(colour="red"), "unknown top-level field(s) ['colour']"),
    ],
)
def test_bad_layout_files_name_file_and_field(tmp_path, mutate, field):
    import copy

    import yaml

    data = copy.deepcopy(BASE)
    mutate(data)
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(data))
    with pytest.raises(LayoutError) as err:
        load_layout(path)
    assert str(path) in str(err.value)
    assert field in str(err.value)


def test_unreadable_and_non_yaml_files(tmp_path):
    with pytest.raises(LayoutError, match="cannot read layout file"):
        load_layout(tmp_path / "missing.yaml")
    bad = tmp_path / "broken.yaml"
    bad.write_text("size: [1, 2\n")
    with pytest.raises(LayoutError, match="not valid YAML"):
        load_layout(bad)


def _shapely_clearance(data: dict, points: np.ndarray) -> np.ndarray:
    """Distance from each point (inside the floor) to the nearest wall or obstacle footprint,
    by Shapely from a layout dict's fields: a box is its ``size`` rectangle turned by ``yaw``
    about ``center``, a cylinder the disc of ``radius`` (exact: point distance less radius)."""
    hx, hy = data["size"][0] / 2, data["size"][1] / 2
    walls = shapely.box(-hx, -hy, hx, hy).exterior
    pts = shapely.points(points)
    out = shapely.distance(walls, pts)
    for o in data["obstacles"]:
        if o["type"] == "box":
            sx, sy = o["size"][0] / 2, o["size"][1] / 2
            shape = shapely.affinity.rotate(shapely.box(-sx, -sy, sx, sy), o.get("yaw", 0.0), origin=(0, 0),
                                            use_radians=True)
            d = shapely.distance(shapely.affinity.translate(shape, *o["center"]), pts)
        else:
            d = np.maximum(shapely.distance(shapely.Point(o["center"]), pts) - o["radius"], 0.0)
        out = np.minimum(out, d)
    return out


def test_layout_round_trips_through_dict():
    layout = generate_warehouse(np.random.default_rng(3))
    data = layout_to_dict(layout)
    again = parse_layout(data)
    assert again == layout
    # The dict's fields mean the footprints the layout measures: its clearance at 4,000 random
    # points on the floor against Shapely's from the dict alone.
    hx, hy = layout.half_extents
    pts = np.random.default_rng(0).uniform((-hx, -hy), (hx, hy), size=(4000, 2))
    expected = _shapely_clearance(data, pts)
    assert (expected == 0).sum() > 100 and expected.max() > 0.5  # points inside footprints and in the open
    np.testing.assert_allclose(again.clearance(pts[:, 0], pts[:, 1]), expected, atol=1e-9)


def test_same_seed_same_layout_and_different_seed_different_layout():
    a = generate_warehouse(np.random.default_rng(7))
    b = generate_warehouse(np.random.default_rng(7))
    c = generate_warehouse(np.random.default_rng(8))
    assert a == b
    assert a != c
    assert len(a.obstacles) == 31  # the article's count
    assert {o.label for o in a.obstacles} == {"rack", "pallet", "column", "box"}


@pytest.mark.parametrize("count", [0, 5, 40])
def test_obstacle_count_is_configurable_and_gaps_hold(count):
    cfg = WorldConfig(num_obstacles=count)
    layout = generate_warehouse(np.random.default_rng(count), cfg)
    assert len(layout.obstacles) == count
    # Independent check of the gap on a fine grid: points within min_gap/2 of two different
    # footprints would mean the footprints are closer than min_gap (up to grid error).
    xs, ys = layout.grid_axes(0.02)
    gx, gy = np.meshgrid(xs, ys, indexing="ij")
    near = np.stack([o.distance(gx, gy) < cfg.min_gap / 2 - 0.03 for o in layout.obstacles]) if count else np.zeros((0,))
    if count:
        assert near.sum(axis=0).max() <= 1
        hx, hy = layout.half_extents
        for o in layout.obstacles:
            assert layout.clearance(np.array(o.center[0]), np.array(o.center[1])) <= 0  # centre inside itself
            assert np.all(o.distance(np.array([hx, -hx]), np.array([0.0, 0.0])) >= cfg.min_gap - 0.06)


def test_too_many_obstacles_raise_a_clear_error():
    with pytest.raises(LayoutError, match="could not place obstacle"):
        generate_warehouse(np.random.default_rng(0), WorldConfig(size=(4.0, 4.0), num_obstacles=40, max_placement_tries=200))


def test_sampler_respects_distance_clearance_and_reachability():
    cfg = SamplerConfig()
    assert RADIUS == RobotConfig().footprint_radius == 0.2  # what SamplerConfig.robot_radius was
    rng = np.random.default_rng(11)
    for seed in range(10):
        layout = generate_warehouse(np.random.default_rng(seed))
        free = FreeSpace.build(layout, cfg, RADIUS)
        for _ in range(5):
            (sx, sy, syaw), (gx, gy) = sample_start_goal(free, rng, cfg)
            d = math.hypot(gx - sx, gy - sy)
            assert cfg.min_goal_distance <= d <= cfg.max_goal_distance
            assert layout.clearance(np.array([sx, gx]), np.array([sy, gy])).min() >= cfg.clearance - 0.04
            assert -math.pi <= syaw < math.pi
            assert _reachable_independent(layout, (sx, sy), (gx, gy), cfg)


def _reachable_independent(layout, a, b, cfg):
    """Reachability by scipy connected components on an 8-connected graph of passable cells
    (the layout's own occupancy grid, obstacles grown by the robot's disc)."""
    passable = ~layout.occupancy(cfg.grid_resolution, inflate=RADIUS)
    idx = -np.ones(passable.shape, dtype=int)
    idx[passable] = np.arange(passable.sum())
    rows, cols = [], []
    h, w = passable.shape
    for di, dj in ((1, 0), (0, 1), (1, 1), (1, -1)):  # each neighbour pair once
        src = idx[max(0, -di):h - max(0, di), max(0, -dj):w - max(0, dj)]
        dst = idx[max(0, di):h - max(0, -di), max(0, dj):w - max(0, -dj)]
        ok = (src >= 0) & (dst >= 0)
        rows += list(src[ok])
        cols += list(dst[ok])
    from scipy.sparse import coo_matrix

    n = int(passable.sum())
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n))
    _, labels = csgraph.connected_components(graph, directed=False)
    hx, hy = layout.half_extents
    ca = idx[int((a[0] + hx) / cfg.grid_resolution), int((a[1] + hy) / cfg.grid_resolution)]
    cb = idx[int((b[0] + hx) / cfg.grid_resolution), int((b[1] + hy) / cfg.grid_resolution)]
    return ca >= 0 and cb >= 0 and labels[ca] == labels[cb]


def test_layout_without_valid_pair_raises(write_layout):
    # A wall of boxes splits the room; each half is too small for a 2 m start-goal distance.
    data = {"size": [2.5, 3.0], "obstacles": [{"type": "box", "center": [0.0, 0.0], "size": [2.5, 0.4, 1.0]}]}
    layout = write_layout(data)
    with pytest.raises(SamplingError, match="no reachable start/goal pair"):
        sample_start_goal(FreeSpace.build(layout, SamplerConfig(), RADIUS), np.random.default_rng(0), SamplerConfig(max_tries=50))
    # The refusal is right, by Shapely: the places clear by the sampler's clearance form two
    # pieces (one per half), and the farthest two points of either are closer than the minimum
    # start-goal distance.
    cfg = SamplerConfig()
    clear = shapely.box(-1.25, -1.5, 1.25, 1.5).difference(shapely.box(-1.25, -0.2, 1.25, 0.2)).buffer(-cfg.clearance)
    pieces = list(getattr(clear, "geoms", [clear]))
    assert len(pieces) == 2
    for piece in pieces:
        corners = np.array(piece.convex_hull.exterior.coords)
        diameter = np.max(np.hypot(*(corners[:, None, :] - corners[None, :, :]).transpose(2, 0, 1)))
        assert 1.0 < diameter < cfg.min_goal_distance  # 1.77 m: hypot(2.5 - 0.8, 1.3 - 0.8)
    points = np.random.default_rng(0).uniform((-1.25, -1.5), (1.25, 1.5), size=(2000, 2))
    inside = shapely.contains_xy(clear, points[:, 0], points[:, 1])
    np.testing.assert_array_equal(inside, _shapely_clearance(data, points) >= cfg.clearance)  # the same places
    # Below that diameter the sampler does find pairs, both ends in one piece (up to its grid).
    near = replace(cfg, min_goal_distance=1.5)
    (sx, sy, _), (gx, gy) = sample_start_goal(FreeSpace.build(layout, near, RADIUS), np.random.default_rng(0), near)
    assert math.hypot(gx - sx, gy - sy) >= 1.5
    assert any(piece.buffer(0.05).contains(shapely.MultiPoint([(sx, sy), (gx, gy)])) for piece in pieces)


def test_disconnected_halves_are_not_reachable(write_layout):
    layout = write_layout({"size": [10.0, 4.0], "obstacles": [{"type": "box", "center": [0.0, 0.0], "size": [0.4, 4.0, 1.0]}]})
    free = FreeSpace.build(layout, SamplerConfig(), RADIUS)
    assert not free.reachable((-3.0, 0.0), (3.0, 0.0))
    assert free.reachable((-3.0, 0.0), (-1.0, 1.0))
    for seed in range(20):
        (sx, _, _), (gx, _) = sample_start_goal(free, np.random.default_rng(seed), SamplerConfig())
        assert np.sign(sx) == np.sign(gx)
