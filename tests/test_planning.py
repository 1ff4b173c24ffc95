"""Planning algorithms checked against independent references.

A* costs against scipy's Dijkstra on an explicitly built graph, segment checks against dense
point sampling, inflation against brute-force distances, RRT paths by sampling and RRT's grid
analyses against brute force. No timing assertions: RRT is bounded by iterations only, and the
benchmark figures are only reported. Fresh-process RRT checks are in test_rrt_fresh_process.py.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from bulletnav.bench.planner_bench import bench_planners, box_world, narrow_problem, rrt_problem
from bulletnav.planning import OccupancyGrid, astar, astar_cost, astar_result, rrt, warmup
from bulletnav.planning.rrt import DEFAULT_MAX_ITERS, _connected, _narrow_cells

SQRT2 = math.sqrt(2.0)


@pytest.fixture(scope="module", autouse=True)
def _compiled():
    warmup()


# --- independent references -------------------------------------------------------------

def cells_of(grid: OccupancyGrid, pts: np.ndarray) -> np.ndarray:
    """(m, 2) cells holding (m, 2) world points, by the documented half-open convention."""
    return np.floor((pts - np.asarray(grid.origin)) / grid.resolution + 0.5).astype(np.int64)


def free_cells_mask(grid: OccupancyGrid, cells: np.ndarray) -> np.ndarray:
    nx, ny = grid.shape
    inside = (cells[:, 0] >= 0) & (cells[:, 0] < nx) & (cells[:, 1] >= 0) & (cells[:, 1] < ny)
    free = np.zeros(len(cells), dtype=bool)
    free[inside] = ~grid.occupied[cells[inside, 0], cells[inside, 1]]
    return free


def grid_graph_costs(occ: np.ndarray, res: float, start: tuple[int, int]) -> np.ndarray:
    """Dijkstra distances (m) from ``start`` over the 8-connected, no-corner-cutting graph."""
    nx, ny = occ.shape
    free = ~occ
    rows, cols, weights = [], [], []
    for dx, dy in [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (1, -1), (-1, 1), (-1, -1)]:
        for ix in range(nx):
            jx = ix + dx
            if not 0 <= jx < nx:
                continue
            for iy in range(ny):
                jy = iy + dy
                if not 0 <= jy < ny or not (free[ix, iy] and free[jx, jy]):
                    continue
                if dx and dy and not (free[jx, iy] and free[ix, jy]):
                    continue
                rows.append(ix * ny + iy)
                cols.append(jx * ny + jy)
                weights.append(res * (SQRT2 if dx and dy else 1.0))
    graph = coo_matrix((weights, (rows, cols)), shape=(nx * ny, nx * ny)).tocsr()
    return dijkstra(graph, directed=True, indices=start[0] * ny + start[1]).reshape(nx, ny)


def sampled_segment_free(grid: OccupancyGrid, a, b, step: float = 1e-3) -> bool:
    """Free iff every point sampled every ``step`` m (plus the crossing points of diagonal
    jumps, found by bisection) lies in a free cell on the grid."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    m = max(2, int(math.ceil(np.linalg.norm(b - a) / step)) + 1)
    t = np.linspace(0.0, 1.0, m)
    cells = cells_of(grid, a + t[:, None] * (b - a))
    extra = []
    # A step that changes both indices may have clipped a cell corner in between: bisect for
    # the point where the segment leaves the first cell and take the cell it enters.
    for i in np.flatnonzero(np.all(cells[1:] != cells[:-1], axis=1)):
        lo, hi = t[i], t[i + 1]
        for _ in range(60):
            mid = 0.5 * (lo + hi)
            if np.array_equal(cells_of(grid, (a + mid * (b - a))[None])[0], cells[i]):
                lo = mid
            else:
                hi = mid
        extra.append(cells_of(grid, (a + hi * (b - a))[None])[0])
    if extra:
        cells = np.vstack([cells, extra])
    return bool(free_cells_mask(grid, cells).all())


def distance_to_nearest_corner(grid: OccupancyGrid, a, b) -> float:
    """Distance (m) from segment a-b to the nearest cell corner point in its bounding box."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    (ox, oy), r = grid.origin, grid.resolution
    lo, hi = np.minimum(a, b), np.maximum(a, b)
    xs = ox + (np.arange(math.floor((lo[0] - ox) / r), math.ceil((hi[0] - ox) / r) + 2) - 0.5) * r
    ys = oy + (np.arange(math.floor((lo[1] - oy) / r), math.ceil((hi[1] - oy) / r) + 2) - 0.5) * r
    corners = np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1).reshape(-1, 2)
    d = b - a
    t = np.clip(((corners - a) @ d) / max(d @ d, 1e-300), 0.0, 1.0)
    return float(np.min(np.linalg.norm(a + t[:, None] * d - corners, axis=1)))


def sample_free_cell(rng: np.random.Generator, occ: np.ndarray) -> tuple[int, int]:
    free = np.argwhere(~occ)
    return tuple(int(v) for v in free[rng.integers(len(free))])


# --- OccupancyGrid -----------------------------------------------------------------------

@pytest.mark.parametrize("occ, res, origin", [
    (np.zeros(5, bool), 0.1, (0.0, 0.0)),
    (np.zeros((2, 2, 2), bool), 0.1, (0.0, 0.0)),
    (np.zeros((0, 3), bool), 0.1, (0.0, 0.0)),
    (np.zeros((3, 3), bool), 0.0, (0.0, 0.0)),
    (np.zeros((3, 3), bool), -0.1, (0.0, 0.0)),
    (np.zeros((3, 3), bool), float("nan"), (0.0, 0.0)),
    (np.zeros((3, 3), bool), 0.1, (0.0, float("inf"))),
    (np.zeros((3, 3), bool), 0.1, (0.0,)),
])
def test_grid_rejects_bad_input(occ, res, origin):
    with pytest.raises(ValueError):
        OccupancyGrid(occ, res, origin)


def test_grid_coordinates_and_immutability():
    occ = np.zeros((4, 7), dtype=bool)
    occ[2, 5] = True
    grid = OccupancyGrid(occ, 0.25, (-1.0, 2.0))
    occ[0, 0] = True  # the grid holds its own copy
    assert not grid.occupied[0, 0]
    with pytest.raises(ValueError):
        grid.occupied[1, 1] = True
    assert grid.shape == (4, 7)
    assert grid.bounds == (-1.125, -1.0 + 3.5 * 0.25, 1.875, 2.0 + 6.5 * 0.25)
    for ix in range(4):
        for iy in range(7):
            x, y = grid.cell_to_world(ix, iy)
            assert grid.world_to_cell((x, y)) == (ix, iy)
            # Anywhere strictly inside the cell maps back to it.
            assert grid.world_to_cell((x + 0.124, y - 0.124)) == (ix, iy)
    assert grid.world_to_cell((-1.125, 1.875)) == (0, 0)  # lower edges belong to the cell
    assert grid.world_to_cell((-1.126, 2.0)) == (-1, 0)
    assert not grid.in_bounds(-1, 0) and not grid.in_bounds(4, 0) and grid.in_bounds(3, 6)
    assert not grid.is_free_point(grid.cell_to_world(2, 5))
    assert grid.is_free_point(grid.cell_to_world(2, 4))
    assert not grid.is_free_point((-5.0, 2.0))


def test_segment_free_matches_dense_sampling():
    rng = np.random.default_rng(7)
    disagreements = near_corner = checked = 0
    for density in (0.05, 0.2, 0.4):
        for _ in range(4):
            nx, ny = rng.integers(20, 40, 2)
            grid = OccupancyGrid(rng.random((nx, ny)) < density, 0.1, tuple(rng.uniform(-1, 1, 2)))
            x0, x1, y0, y1 = grid.bounds
            for k in range(80):
                heading = rng.uniform(0, 2 * math.pi)
                u = np.array([math.cos(heading), math.sin(heading)])
                if k % 2:
                    # Mostly inside; some ends a little off the map, some short segments.
                    a = rng.uniform([x0 - 0.2, y0 - 0.2], [x1 + 0.2, y1 + 0.2])
                    b = a + (rng.uniform(0, 0.3) if rng.random() < 0.3 else rng.uniform(0, 2.5)) * u
                else:
                    # Passing 10 um to 0.3 mm beside a cell corner, where a cell is clipped by
                    # less than the sampling step: the hard case for any traversal.
                    corner = np.array(grid.cell_to_world(*rng.integers(0, (nx, ny)))) - 0.05
                    offset = rng.choice([-1, 1]) * 10 ** rng.uniform(-5, -3.5)
                    through = corner + offset * np.array([-u[1], u[0]])
                    a, b = through - rng.uniform(0.02, 1.0) * u, through + rng.uniform(0.02, 1.0) * u
                got = grid.segment_free(a, b)
                want = sampled_segment_free(grid, a, b)
                checked += 1
                if got != want:
                    disagreements += 1
                    assert distance_to_nearest_corner(grid, a, b) < 1e-6, (a, b, got, want)
                    near_corner += 1
    assert checked == 960 and disagreements == near_corner
    # Axis-parallel, degenerate and exactly-through-a-corner cases.
    occ = np.zeros((3, 3), dtype=bool)
    occ[1, 0] = occ[0, 1] = True
    grid = OccupancyGrid(occ, 1.0)
    assert not grid.segment_free((0.0, 0.0), (1.0, 1.0))  # squeezes through a diagonal gap
    assert OccupancyGrid(np.zeros((3, 3), bool), 1.0).segment_free((0.0, 0.0), (2.0, 2.0))
    assert grid.segment_free((0.0, 0.0), (0.0, 0.0))
    assert grid.segment_free((1.0, 2.0), (2.0, 0.0)) == sampled_segment_free(grid, (1.0, 2.0), (2.0, 0.0))
    assert not grid.segment_free((0.0, 0.0), (0.0, 2.0))  # straight through occupied (0, 1)
    assert not grid.segment_free((2.0, 2.0), (3.6, 2.0))  # leaves the map


def test_inflate_matches_brute_force():
    rng = np.random.default_rng(3)
    for density in (0.01, 0.05, 0.15):
        occ = rng.random((23, 31)) < density
        grid = OccupancyGrid(occ, 0.1, (0.3, -0.2))
        centres = np.stack(np.meshgrid(0.3 + 0.1 * np.arange(23), -0.2 + 0.1 * np.arange(31), indexing="ij"), -1)
        occupied_centres = centres[occ]
        dist = np.linalg.norm(centres[:, :, None, :] - occupied_centres[None, None], axis=-1).min(axis=-1)
        for radius in (0.0, 0.05, 0.1, 0.15, 0.3, 0.37):
            inflated = grid.inflate(radius)
            np.testing.assert_array_equal(inflated.occupied, dist <= radius + 1e-9)
            assert inflated.resolution == grid.resolution and inflated.origin == grid.origin
    np.testing.assert_array_equal(OccupancyGrid(np.zeros((4, 4), bool), 0.1).inflate(1.0).occupied, False)
    with pytest.raises(ValueError):
        grid.inflate(-0.1)


# --- A* --------------------------------------------------------------------------------

def check_astar_path(grid: OccupancyGrid, start, goal, result) -> None:
    path, cells = result.path, result.cells
    assert path[0] == tuple(start) and path[-1] == tuple(goal)
    waypoint_cells = [grid.world_to_cell(p) for p in path]
    if len(cells) == 1:  # start and goal share a cell: [start, goal]
        assert len(path) == 2 and waypoint_cells == [tuple(cells[0])] * 2
    else:
        assert waypoint_cells == [tuple(c) for c in cells.tolist()]
        assert path[1:-1] == [grid.cell_to_world(*c) for c in cells[1:-1].tolist()]
    assert not grid.occupied[cells[:, 0], cells[:, 1]].any()
    steps = np.diff(cells, axis=0)
    assert np.all(np.abs(steps).max(axis=1) == 1)  # consecutive cells are 8-adjacent
    for c, (dx, dy) in zip(cells[:-1], steps):
        if dx and dy:  # no corner cutting
            assert not grid.occupied[c[0] + dx, c[1]] and not grid.occupied[c[0], c[1] + dy]
    length = grid.resolution * np.where(np.abs(steps).sum(axis=1) == 2, SQRT2, 1.0).sum()
    assert result.cost == pytest.approx(length, rel=1e-12, abs=1e-12)
    # The waypoint polyline itself is collision-free.
    assert all(grid.segment_free(p, q) for p, q in zip(path[:-1], path[1:]))


@pytest.mark.parametrize("heuristic", ["octile", "euclidean"])
def test_astar_cost_matches_dijkstra(heuristic):
    rng = np.random.default_rng(11)
    solved = unsolved = 0
    for k in range(36):
        density = (0.0, 0.1, 0.2, 0.2, 0.3, 0.4)[k % 6]
        nx, ny = rng.integers(8, 45, 2)  # non-square on purpose: catches swapped indices
        res = float(rng.choice([0.05, 0.1, 0.5]))
        occ = rng.random((nx, ny)) < density
        grid = OccupancyGrid(occ, res, tuple(rng.uniform(-3, 3, 2)))
        s, g = sample_free_cell(rng, occ), sample_free_cell(rng, occ)
        # Exact points anywhere inside the start and goal cells.
        start = tuple(np.add(grid.cell_to_world(*s), rng.uniform(-0.49, 0.49, 2) * res).tolist())
        goal = tuple(np.add(grid.cell_to_world(*g), rng.uniform(-0.49, 0.49, 2) * res).tolist())
        want = grid_graph_costs(occ, res, s)[g]
        result = astar_result(grid, start, goal, heuristic=heuristic)
        if np.isinf(want):
            assert result is None and astar(grid, start, goal, heuristic=heuristic) is None
            unsolved += 1
            continue
        solved += 1
        assert result.cost == pytest.approx(want, rel=1e-9, abs=1e-12)
        assert astar_cost(grid, start, goal, heuristic=heuristic) == result.cost
        assert astar(grid, start, goal, heuristic=heuristic) == result.path
        check_astar_path(grid, start, goal, result)
    assert solved >= 30 and unsolved >= 1


def test_astar_none_cases():
    occ = np.zeros((20, 12), dtype=bool)
    occ[9, :] = True  # a wall splitting the grid
    grid = OccupancyGrid(occ, 0.1)
    assert astar(grid, (0.2, 0.5), (1.8, 0.5)) is None
    assert astar(grid, (0.9, 0.5), (0.2, 0.5)) is None  # start occupied
    assert astar(grid, (0.2, 0.5), (0.9, 0.5)) is None  # goal occupied
    assert astar(grid, (-0.5, 0.5), (0.2, 0.5)) is None  # start off the map
    assert astar(grid, (0.2, 0.5), (0.2, 5.0)) is None  # goal off the map
    # A diagonal gap between two occupied cells is not a passage: no corner cutting.
    corner = np.zeros((3, 3), dtype=bool)
    corner[1, 0] = corner[0, 1] = True
    assert astar(OccupancyGrid(corner, 1.0), (0.0, 0.0), (2.0, 2.0)) is None
    corner[0, 1] = False
    assert astar_cost(OccupancyGrid(corner, 1.0), (0.0, 0.0), (2.0, 2.0)) == pytest.approx(2.0 + SQRT2)
    same = astar_result(grid, (0.21, 0.52), (0.23, 0.49))
    assert same.path == [(0.21, 0.52), (0.23, 0.49)] and same.cost == 0.0
    with pytest.raises(ValueError):
        astar(grid, (0.2, 0.5), (0.3, 0.5), heuristic="manhattan")  # type: ignore[arg-type]


def test_astar_on_inflated_grid_avoids_inflated_cells():
    rng = np.random.default_rng(5)
    for _ in range(10):
        grid = box_world(rng, size_m=6.0, n_boxes=10)
        inflated = grid.inflate(0.25)
        s, g = sample_free_cell(rng, inflated.occupied), sample_free_cell(rng, inflated.occupied)
        result = astar_result(inflated, inflated.cell_to_world(*s), inflated.cell_to_world(*g))
        want = grid_graph_costs(inflated.occupied, inflated.resolution, s)[g]
        if result is None:
            assert np.isinf(want)
            continue
        assert not inflated.occupied[result.cells[:, 0], result.cells[:, 1]].any()
        assert result.cost == pytest.approx(want, rel=1e-9)
        # So the robot's centre keeps >= 0.25 m (to cell-centre precision) from obstacle cells.
        obstacles = np.argwhere(grid.occupied) * grid.resolution
        d = np.linalg.norm(result.cells[:, None, :] * grid.resolution - obstacles[None], axis=-1)
        assert d.min() > 0.25


# --- RRT -------------------------------------------------------------------------------

def sampled_path_free(grid: OccupancyGrid, path) -> bool:
    """Every segment sampled at half-cell spacing lies in free cells on the map."""
    for p, q in zip(path[:-1], path[1:]):
        p, q = np.asarray(p), np.asarray(q)
        m = max(2, int(math.ceil(np.linalg.norm(q - p) / (0.5 * grid.resolution))) + 1)
        pts = p + np.linspace(0, 1, m)[:, None] * (q - p)
        if not free_cells_mask(grid, cells_of(grid, pts)).all():
            return False
    return True


def test_rrt_paths_are_valid():
    rng = np.random.default_rng(2)
    for make in (rrt_problem, narrow_problem):
        for i in range(40):
            grid, start, goal = make(rng)
            for shortcut in (True, False):
                path = rrt(grid, start, goal, np.random.default_rng(i), shortcut=shortcut)
                assert path is not None  # connected on the grid, and the default budget is ample
                assert path[0] == start and path[-1] == goal
                assert all(grid.segment_free(p, q) for p, q in zip(path[:-1], path[1:]))
                assert sampled_path_free(grid, path)
                if not shortcut:
                    assert all(math.dist(p, q) <= 0.5 + 1e-12 for p, q in zip(path[:-1], path[1:]))


def test_rrt_shortcut_never_lengthens():
    rng = np.random.default_rng(4)
    for make in (rrt_problem, narrow_problem):
        for i in range(10):
            grid, start, goal = make(rng)
            raw = rrt(grid, start, goal, np.random.default_rng(i), shortcut=False)
            short = rrt(grid, start, goal, np.random.default_rng(i), shortcut=True)
            assert (raw is None) == (short is None)
            if raw is not None:
                length = lambda path: sum(math.dist(p, q) for p, q in zip(path[:-1], path[1:]))  # noqa: E731
                assert set(short) <= set(raw) and length(short) <= length(raw) + 1e-12
                assert short[0] == start and short[-1] == goal and sampled_path_free(grid, short)  # shortcuts stay free


@pytest.mark.parametrize("make", [rrt_problem, narrow_problem])
def test_rrt_deterministic_per_seed(make):
    grid, start, goal = make(np.random.default_rng(9))
    plan = lambda seed: rrt(grid, start, goal, np.random.default_rng(seed), shortcut=False)  # noqa: E731
    np.random.seed(0)
    first = plan(123)
    np.random.seed(1)  # global random state must not matter
    assert first is not None and plan(123) == first
    assert len({tuple(plan(seed)) for seed in range(6)}) > 1


def test_rrt_budget_only_truncates():
    """A budget changes nothing but where the iterations stop: below the smallest budget that
    finds the full-budget path (found by bisection) every budget gives None, from it on every
    budget gives exactly that path, and the path is free by dense sampling. (At 052a810 this
    read ``path is None or path == full``, which held if every budget failed.)"""
    rng = np.random.default_rng(5)
    truncated = 0
    for i in range(20):
        grid, start, goal = narrow_problem(rng)
        plan = lambda budget, p=(grid, start, goal), i=i: rrt(*p, np.random.default_rng(i), max_iters=budget)  # noqa: E731
        full = plan(DEFAULT_MAX_ITERS)
        assert full is not None and full[0] == start and full[-1] == goal and sampled_path_free(grid, full)
        lo, hi = 0, DEFAULT_MAX_ITERS  # plan(lo) is None (no iterations), plan(hi) is the path
        assert plan(lo) is None
        while hi - lo > 1:
            mid = (lo + hi) // 2
            lo, hi = (lo, mid) if plan(mid) is not None else (mid, hi)
        for budget in sorted({1, 255, 256, 257, 1000, hi - 1, hi, hi + 1, 2 * hi} - {0}):
            assert plan(budget) == (full if budget >= hi else None), (i, budget, hi)
        truncated += hi > 1
    assert truncated == 20  # one iteration never suffices here: the None side was checked on every problem


def test_rrt_none_cases():
    occ = np.zeros((40, 40), dtype=bool)
    occ[25:32, 25] = occ[25:32, 31] = occ[25, 25:32] = occ[31, 25:32] = True  # a closed box
    grid = OccupancyGrid(occ, 0.1)
    rng = np.random.default_rng(0)
    assert rrt(grid, (0.5, 0.5), (2.8, 2.8), rng) is None  # goal enclosed: disconnected on the grid
    assert rrt(grid, (2.5, 2.8), (0.5, 0.5), rng) is None  # start occupied
    assert rrt(grid, (0.5, 0.5), (9.0, 0.5), rng) is None  # goal off the map
    assert rrt(grid, (0.5, 0.5), (3.5, 0.5), rng, max_iters=0) is None
    assert rrt(grid, (0.5, 0.5), (0.7, 0.6), rng) == [(0.5, 0.5), (0.7, 0.6)]  # direct reach
    for bad in ({"step": 0.0}, {"goal_bias": 1.5}, {"max_iters": -1}):
        with pytest.raises(ValueError):
            rrt(grid, (0.5, 0.5), (3.5, 0.5), rng, **bad)
    with pytest.raises(TypeError):  # the wall-clock budget is gone
        rrt(grid, (0.5, 0.5), (3.5, 0.5), rng, time_budget_s=0.05)


def test_rrt_none_when_iterations_run_out():
    # A 4 x 4 m map split by a wall at x = 2 m with a gap at its top: one iteration adds one
    # node within 0.5 m of the start (0.5, 0.5), which neither sees the goal (3.5, 0.5) nor lies
    # within a step of it, so it cannot reach the goal; the default budget always does.
    occ = np.zeros((40, 40), dtype=bool)
    occ[20, :36] = True
    grid = OccupancyGrid(occ, 0.1)
    start, goal = (0.5, 0.5), (3.5, 0.5)
    for seed in range(20):
        assert rrt(grid, start, goal, np.random.default_rng(seed), max_iters=1) is None
        path = rrt(grid, start, goal, np.random.default_rng(seed))
        assert path is not None and path[0] == start and path[-1] == goal
        assert all(grid.segment_free(p, q) for p, q in zip(path[:-1], path[1:]))


def test_connected_matches_astar():
    """RRT's early exit: 4-connectivity of free cells is what A* (no corner cutting) reaches."""
    rng = np.random.default_rng(6)
    for _ in range(200):
        grid = OccupancyGrid(rng.random((12, 9)) < rng.uniform(0.2, 0.6), 0.1)
        s, g = sample_free_cell(rng, grid.occupied), sample_free_cell(rng, grid.occupied)
        want = astar_result(grid, grid.cell_to_world(*s), grid.cell_to_world(*g)) is not None
        assert _connected(grid.occupied, *s, *g) == want


def narrow_cells_reference(occ: np.ndarray, res: float, width: float) -> np.ndarray:
    """Free cells whose free run through them along x, y or a diagonal spans <= ``width`` m, by walking."""
    nx, ny = occ.shape
    free = lambda x, y: 0 <= x < nx and 0 <= y < ny and not occ[x, y]  # noqa: E731
    out = []
    for x in range(nx):
        for y in range(ny):
            if not free(x, y):
                continue
            for dx, dy in ((1, 0), (0, 1), (1, 1), (1, -1)):
                n = 1
                for sign in (1, -1):
                    k = 1
                    while free(x + sign * k * dx, y + sign * k * dy):
                        n += 1
                        k += 1
                if n * res * math.hypot(dx, dy) <= width * (1 + 1e-9):
                    out.append(x * ny + y)
                    break
    return np.array(out, dtype=np.int64)


def test_narrow_cells_match_brute_force():
    rng = np.random.default_rng(8)
    for _ in range(60):
        occ = rng.random((int(rng.integers(1, 20)), int(rng.integers(1, 20)))) < rng.uniform(0.0, 0.5)
        occ = OccupancyGrid(occ, 0.1).occupied  # read-only, as rrt passes it
        for width in (0.1, 0.3, 0.5, 1.0):
            assert np.array_equal(_narrow_cells(occ, 0.1, width), narrow_cells_reference(occ, 0.1, width))


def test_narrow_problems_are_narrow():
    """The benchmark's narrow-passage maps do have a gap of at most 0.4 m between start and goal."""
    rng = np.random.default_rng(10)
    separated = 0
    for _ in range(20):
        grid, start, goal = narrow_problem(rng)
        assert astar(grid, start, goal) is not None
        # Closing every narrow cell (free runs <= 0.4 m wide) must disconnect start from goal.
        closed = grid.occupied.copy()
        closed.ravel()[_narrow_cells(grid.occupied, grid.resolution, 0.4)] = True
        s, g = grid.world_to_cell(start), grid.world_to_cell(goal)
        labels, _ = ndimage.label(~closed)  # SciPy's 4-connected components of what is left free
        assert closed[s] or closed[g] or labels[s] != labels[g]
        separated += not (closed[s] or closed[g])
    assert separated >= 15  # mostly by the components, not because start or goal itself was closed


def test_bench_planners_times_each_call_and_counts_only_valid_paths(monkeypatch, report):
    """The benchmark on a fake clock: A* costs 1.25 ms a call, RRT 2.5 ms when it finds a path
    and 40 ms when it does not. The figures must be those costs' median and 95th percentile
    (the standard library's), and each solve rate the share of RRT paths that run from start to
    goal and are free by dense sampling. (At 052a810 only the keys and finiteness were checked.)"""
    import statistics
    import types

    from bulletnav.bench import planner_bench

    now = [0.0]
    plans = []
    real_astar, real_rrt = planner_bench.astar, planner_bench.rrt

    def astar_costing(grid, start, goal, **kwargs):
        now[0] += 1.25e-3
        return real_astar(grid, start, goal, **kwargs)

    def rrt_costing(grid, start, goal, rng, **kwargs):
        path = real_rrt(grid, start, goal, rng, **kwargs)
        now[0] += 2.5e-3 if path is not None else 40e-3
        plans.append((grid, start, goal, path))
        return path

    monkeypatch.setattr(planner_bench, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))
    monkeypatch.setattr(planner_bench, "astar", astar_costing)
    monkeypatch.setattr(planner_bench, "rrt", rrt_costing)
    n = 30
    figures = bench_planners(seed=1, n=n)
    assert figures["n"] == n and len(plans) == 2 * n  # the boxes' plans, then the narrow ones'
    assert figures["astar_median_ms"] == pytest.approx(1.25) and figures["astar_p95_ms"] == pytest.approx(1.25)
    for name, chunk in (("rrt", plans[:n]), ("rrt_narrow", plans[n:])):
        valid = [path is not None and path[0] == start and path[-1] == goal and sampled_path_free(grid, path)
                 for grid, start, goal, path in chunk]
        assert all(v for v, (*_, path) in zip(valid, chunk) if path is not None), f"{name}: a path that is not free"
        assert figures[f"{name}_success_rate"] == sum(valid) / n
        costs = [2.5 if v else 40.0 for v in valid]
        assert figures[f"{name}_median_ms"] == pytest.approx(statistics.median(costs))
        assert figures[f"{name}_p95_ms"] == pytest.approx(statistics.quantiles(costs, n=20, method="inclusive")[-1])
        report(f"{name} solved (fake-clock run, seed 1)", f"{sum(valid)}/{n}")
