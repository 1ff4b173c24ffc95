"""costmap_2d and navfn as ported in bulletnav.planning (costmap.py, navfn.py): costs, layers and
plans against hand-worked cases, costmap_2d's formula, and SciPy's Dijkstra."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from bulletnav.planning.costmap import (
    FREE_SPACE,
    INSCRIBED_INFLATED_OBSTACLE,
    LETHAL_OBSTACLE,
    NO_INFORMATION,
    Costmap2D,
    LayeredCostmap,
    ObstacleLayer,
    convex_fill_cells,
    footprint_radii,
    pad_footprint,
)
from bulletnav.planning.navfn import COST_NEUTRAL, make_plan, translate_costs

BARN_FOOTPRINT = [[-0.21, -0.165], [-0.21, 0.165], [0.21, 0.165], [0.21, -0.165]]
"""BARN's costmap_common_params.yaml footprint (m)."""


def test_barn_footprint_padded_and_its_radii_by_hand():
    padded = pad_footprint(BARN_FOOTPRINT, 0.1)  # footprint_padding 0.1: every |x| and |y| grows by 0.1
    assert np.allclose(padded, [[-0.31, -0.265], [-0.31, 0.265], [0.31, 0.265], [0.31, -0.265]])
    inscribed, circumscribed = footprint_radii(padded)
    assert inscribed == pytest.approx(0.265)  # the nearer edge
    assert circumscribed == pytest.approx(math.hypot(0.31, 0.265))  # a corner: 0.4078 m
    assert np.allclose(pad_footprint([[0.0, 0.2], [0.3, 0.0], [-0.3, 0.0]], 0.05),
                       [[0.0, 0.25], [0.35, 0.0], [-0.35, 0.0]])  # sign0: a zero coordinate stays zero


def _one_obstacle(radius: float, scaling: float, inscribed: float, res: float = 0.05, n: int = 41):
    """A map with one lethal cell in the middle, inflated."""
    fp = np.array([[-inscribed, -inscribed], [-inscribed, inscribed], [inscribed, inscribed], [inscribed, -inscribed]])
    cm = LayeredCostmap.make(n, n, res, 0.0, 0.0, fp, radius, scaling, footprint_clearing_enabled=False)
    cm.obstacles.costs[n // 2, n // 2] = LETHAL_OBSTACLE
    cm.master.reset()
    cm.obstacles.update_costs(cm.master)
    cm.inflation.update_costs(cm.master)
    return cm.master.costs


@pytest.mark.parametrize("radius,scaling", [(0.30, 10.0), (0.55, 3.0)])
def test_inflation_costs_follow_costmap_2ds_formula(radius, scaling):
    res, inscribed, n = 0.05, 0.265, 41
    costs = _one_obstacle(radius, scaling, inscribed, res, n)
    c = n // 2
    cell_radius = math.ceil(radius / res)
    for y in range(n):
        for x in range(n):
            d = math.hypot(x - c, y - c)  # cells; one source, so the wave's distance is the Euclidean one
            if d == 0:
                want = LETHAL_OBSTACLE
            elif d > cell_radius:
                want = FREE_SPACE
            elif d * res <= inscribed:
                want = INSCRIBED_INFLATED_OBSTACLE
            else:  # InflationLayer::computeCost
                want = int(252 * math.exp(-scaling * (d * res - inscribed)))
            assert costs[y, x] == want, (x, y, d)
    if radius == 0.30:  # BARN's: 6 cells out, 0.30 m: 252 exp(-10 x 0.035) = 177.6 -> 177 (by hand)
        assert costs[c, c + 6] == 177 and costs[c, c + 7] == 0 and costs[c + 5, c] == 253


def test_obstacle_layer_marks_hits_and_clears_rays_by_hand():
    # 20 x 10 cells of 0.1 m; the sensor at (0.25, 0.55), in cell (2, 5)
    layer = ObstacleLayer(20, 10, 0.1, 0.0, 0.0, obstacle_range=1.0, raytrace_range=1.2, footprint_clearing_enabled=False)
    layer.costs[5, 3:20] = LETHAL_OBSTACLE  # stale obstacles all along row 5
    layer.costs[8, 8] = LETHAL_OBSTACLE  # one off the rays
    # a hit at 0.8 m straight ahead (cell (10, 5)) and one at 1.5 m (cell (17, 5))
    layer.update_bounds(0.25, 0.55, 0.0, (0.25, 0.55), np.array([[1.05, 0.55], [1.75, 0.55]]), np.zeros((0, 2)))
    row = layer.costs[5]
    # the near ray clears cells 2..10 and the far ray, capped at 1.2 m = 12 cells, clears 2..14; then the
    # near hit is marked (0.8 m < obstacle_range) and the far one is not (1.5 m >= 1.0 m)
    assert row[2:15].tolist() == [0] * 8 + [LETHAL_OBSTACLE] + [0] * 4
    assert row[15:].tolist() == [LETHAL_OBSTACLE] * 5  # beyond the raytrace range: untouched
    assert layer.costs[8, 8] == LETHAL_OBSTACLE and int((layer.costs == LETHAL_OBSTACLE).sum()) == 7
    # a diagonal ray by Bresenham: from (2, 5) to (7, 8), cells (2,5) (3,6) (4,6) (5,7) (6,8)? -- costmap_2d's
    # bresenham2D steps x every cell and y when the error (starting at dx / 2 = 2) reaches dx = 5
    layer.costs[:] = LETHAL_OBSTACLE
    layer.marking = False
    layer.update_bounds(0.25, 0.55, 0.0, (0.25, 0.55), np.array([[0.75, 0.85]]), np.zeros((0, 2)))
    cleared = sorted(map(tuple, np.argwhere(layer.costs == FREE_SPACE)[:, ::-1].tolist()))
    assert cleared == [(2, 5), (3, 6), (4, 6), (5, 7), (6, 7), (7, 8)]


def test_footprint_clearing_and_rolling_window_by_hand():
    fp = pad_footprint(BARN_FOOTPRINT, 0.1)
    cm = LayeredCostmap.make(40, 40, 0.05, 0.0, 0.0, fp, 0.30, rolling_window=True)
    cm.obstacles.costs[:] = LETHAL_OBSTACLE
    cm.update_map(1.0, 1.0, 0.0, (1.0, 1.0), np.zeros((0, 2)))  # no scan: only the footprint clears
    free = np.argwhere(cm.obstacles.costs == FREE_SPACE)
    # the padded footprint spans x, y in [0.69, 1.31] x [0.735, 1.265]: cells 13-26 by 14-25, all filled
    assert (free[:, 1].min(), free[:, 1].max(), free[:, 0].min(), free[:, 0].max()) == (13, 26, 14, 25)
    assert len(free) == 14 * 12
    # the window follows the robot by whole cells and keeps what both windows share
    before = cm.obstacles.costs.copy()
    cm.obstacles.update_origin(0.0 + 3 * 0.05 + 0.01, 0.0 - 2 * 0.05 - 0.01)  # 3 cells right, 2 (truncated) down
    assert (cm.obstacles.origin_x, cm.obstacles.origin_y) == pytest.approx((0.15, -0.10))
    assert np.array_equal(cm.obstacles.costs[2:, :37], before[:38, 3:])
    assert (cm.obstacles.costs[:2] == FREE_SPACE).all() and (cm.obstacles.costs[:, 37:] == FREE_SPACE).all()


def test_clear_costmap_recovery_clears_outside_a_square_of_named_layers():
    fp = pad_footprint(BARN_FOOTPRINT, 0.1)
    cm = LayeredCostmap.make(100, 100, 0.05, 0.0, 0.0, fp, 0.30, obstacle_name="obstacles_layer")
    cm.obstacles.costs[:] = LETHAL_OBSTACLE
    # BARN's layer is "obstacles_layer"; ClearCostmapRecovery's default layer_names is ["obstacles"]
    assert not cm.clear_layers(2.5, 2.5, 3.0, ("obstacles",)) and (cm.obstacles.costs == LETHAL_OBSTACLE).all()
    assert cm.clear_layers(2.5, 2.5, 3.0, ("obstacles_layer",))
    # the square from 1.0 to 4.0 m: cells 20..80, of which clearArea keeps those strictly inside (21..79)
    kept = np.argwhere(cm.obstacles.costs == LETHAL_OBSTACLE)
    assert kept[:, 0].min() == kept[:, 1].min() == 21 and kept[:, 0].max() == kept[:, 1].max() == 79
    assert len(kept) == 59 * 59 and int((cm.obstacles.costs == NO_INFORMATION).sum()) == 100 * 100 - 59 * 59
    cm.update_map(2.5, 2.5, 0.0, (2.5, 2.5), np.zeros((0, 2)))  # unknown cells are free in the master
    assert cm.master.costs[0, 0] == FREE_SPACE and cm.master.costs[10, 50] == FREE_SPACE


def test_footprint_fill_cells_by_hand():
    # a 4 x 3 rectangle of cells (x 2..5, y 1..3): costmap_2d's convexFillCells fills every column
    # up to and including its top; base_local_planner's getFillCells stops one short
    xs, ys = np.array([2, 2, 5, 5]), np.array([1, 3, 3, 1])
    inclusive = {tuple(c) for c in convex_fill_cells(xs, ys, True).tolist()}
    assert inclusive == {(x, y) for x in range(2, 6) for y in range(1, 4)}
    short = {tuple(c) for c in convex_fill_cells(xs, ys, False).tolist()}
    assert short == inclusive  # the outline supplies the tops the fill leaves out


# ---------------------------------------------------------------------------------- navfn

def test_navfn_straight_corridor_by_hand():
    cm = Costmap2D(120, 40, 0.05, -1.0, -0.5)
    cm.costs[[4, 15], :] = LETHAL_OBSTACLE  # a corridor along x, rows 5-14
    plan = make_plan(cm, (-0.925, 0.025), (3.975, 0.025))  # robot in cell (1, 10), goal in (99, 10)
    # 98 steps of COST_NEUTRAL: the potential spreads from the robot, the goal's is 98 x 50
    assert plan.goal_potential == pytest.approx(98 * COST_NEUTRAL)
    assert plan.found and np.allclose(plan.path[:-1, 1], 0.0)  # row 10's lower edge: cell corners (navfn_ros's mapToWorld)
    assert plan.path[0].tolist() == pytest.approx([-1.0 + 1 * 0.05, 0.0])  # the robot's cell first
    assert plan.path[-2].tolist() == pytest.approx([-1.0 + 99 * 0.05, 0.0])  # calcPath's start, the goal's cell
    assert plan.path[-1].tolist() == [3.975, 0.025]  # then the goal pose itself
    steps = np.hypot(*np.diff(plan.path[:-1], axis=0)[::-1].T)  # from the goal's cell, as calcPath walks
    # two whole cells on the grid first (the wave stopped at the goal: the cells beyond it have no
    # potential, so calcPath follows the grid), then half-cell steps down the gradient, then the
    # jump onto the robot's cell once the potential is under COST_NEUTRAL
    assert np.allclose(steps[:2], 0.05) and np.allclose(steps[2:-1], 0.5 * 0.05) and np.isclose(steps[-1], 0.05)
    # navfn propagates for max(nx * ny / 20, nx + ny) cycles: on a 120 x 20 map, 140 do not reach 98 cells
    short = Costmap2D(120, 20, 0.05, -1.0, -0.5)
    assert not make_plan(short, (-0.925, 0.025), (3.975, 0.025)).found


def _dijkstra_cost(hf: np.ndarray, src: int, dst: int, diagonal: bool) -> float:
    """SciPy's Dijkstra on the grid graph: entering a cell costs its navfn cost (times sqrt 2 diagonally)."""
    ny, nx = hf.shape
    steps = [(1, 0), (-1, 0), (0, 1), (0, -1)] + ([(1, 1), (1, -1), (-1, 1), (-1, -1)] if diagonal else [])
    rows, cols, weights = [], [], []
    for y in range(1, ny - 1):
        for x in range(1, nx - 1):
            for dx, dy in steps:
                X, Y = x + dx, y + dy
                if not (1 <= X < nx - 1 and 1 <= Y < ny - 1) or hf[y, x] >= 254 or hf[Y, X] >= 254:
                    continue
                if dx and dy and (hf[y, X] >= 254 or hf[Y, x] >= 254):
                    continue
                rows.append(y * nx + x)
                cols.append(Y * nx + X)
                weights.append(math.hypot(dx, dy) * hf[Y, X])
    graph = coo_matrix((weights, (rows, cols)), shape=(nx * ny, nx * ny)).tocsr()
    return float(dijkstra(graph, indices=src)[dst])


@pytest.mark.parametrize("varied", [False, True])
def test_navfn_path_cost_against_scipys_dijkstra(varied):
    """navfn's interpolated potential sits between SciPy's 4-connected Dijkstra (its upper
    bound: the two-neighbour update is never worse than one neighbour plus the cell's cost) and
    the octile one divided by the octile metric's worst overestimate of Euclidean length,
    sqrt(4 - 2 sqrt 2) = 1.0824; on uniform costs it is the Euclidean geodesic, within 3 % of
    the octile cost below it."""
    rng = np.random.default_rng(7)
    cm = Costmap2D(60, 50, 0.1)
    if varied:
        cm.costs[:] = rng.integers(0, 120, cm.costs.shape)
    for _ in range(8):
        x, y = rng.integers(5, 55), rng.integers(5, 45)
        cm.costs[y:y + rng.integers(2, 10), x:x + rng.integers(2, 4)] = LETHAL_OBSTACLE
    cm.costs[5, 5] = cm.costs[44, 54] = 0
    hf = translate_costs(cm.costs.reshape(-1), True).reshape(cm.costs.shape).astype(float)  # navfn's costs
    hf[[0, -1], :] = hf[:, [0, -1]] = 254
    plan = make_plan(cm, (0.55, 0.55), (5.45, 4.45))
    d4 = _dijkstra_cost(hf, 5 * 60 + 5, 44 * 60 + 54, False)
    d8 = _dijkstra_cost(hf, 5 * 60 + 5, 44 * 60 + 54, True)
    assert plan.found and d8 / math.sqrt(4 - 2 * math.sqrt(2)) <= plan.goal_potential <= d4
    if not varied:
        assert 0.97 * d8 <= plan.goal_potential <= d8
    cells = np.floor((plan.path[:-1] + 1e-9) / 0.1).astype(int)  # navfn_ros's points are cell corners
    assert (cm.costs[cells[:, 1], cells[:, 0]] < LETHAL_OBSTACLE).all()
