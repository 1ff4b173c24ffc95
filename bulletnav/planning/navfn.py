"""navfn, ported: move_base's default global planner (``navfn/NavfnROS``).

A Dijkstra wavefront on a costmap (:class:`~bulletnav.planning.costmap.Costmap2D`) with navfn's
cost translation, its priority buffers and its quadratic two-neighbour potential update, run
from the robot's cell until the goal's cell has a potential, then a path by gradient descent
on the potential from the goal back to the robot (ros-planning/navigation ``noetic-devel``,
``navfn/src/navfn.cpp`` and ``navfn/src/navfn_ros.cpp``). The potential and the path are
float32, as navfn's; the costs of a path step are navfn's: :data:`COST_NEUTRAL` (50) for a free
cell plus :data:`COST_FACTOR` (0.8) times its costmap cost.

:func:`make_plan` is ``NavfnROS::makePlan`` with ``default_tolerance`` 0 (move_base's use): it
also clears the robot's cell in the costmap it plans on, as navfn does (``clearRobotCell``).

A pure algorithm module: no simulation, sensors or envs. The kernels compile with numba on first
use and are cached on disk (:func:`warmup`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit

from bulletnav.planning.costmap import FREE_SPACE, Costmap2D

COST_UNKNOWN_ROS = 255
"""navfn.h: a ROS costmap's unknown cell."""
COST_OBS = 254
"""navfn.h: a cell navfn never enters."""
COST_OBS_ROS = 253
"""navfn.h: ROS costs from this up are obstacles."""
COST_NEUTRAL = 50
"""navfn.h: the cost of a step through free space."""
COST_FACTOR = 0.8
"""navfn.h: each unit of costmap cost adds this much to a step (``setCostmap``)."""
POT_HIGH = 1.0e10
"""navfn.h: the potential of a cell not reached."""
PRIORITYBUFSIZE = 10000
"""navfn.h: the size of each of the three priority buffers (a push beyond it is dropped)."""
INVSQRT2 = 0.707106781
"""navfn.cpp's 1/sqrt(2)."""


@njit(cache=True, nogil=True)
def translate_costs(costs, allow_unknown):  # pragma: no cover  (compiled)
    """``NavFn::setCostmap`` for a ROS costmap (flat ``uint8``): a cost below 253 becomes
    ``int(50 + 0.8 * cost)`` (at most 253), unknown (255) becomes 253 when ``allow_unknown``,
    everything else 254 (:data:`COST_OBS`)."""
    out = np.empty(costs.shape[0], dtype=np.uint8)
    for i in range(costs.shape[0]):
        v = int(costs[i])
        c = 254
        if v < 253:
            w = int(50 + 0.8 * v)
            c = 253 if w >= 254 else w
        elif v == 255 and allow_unknown:
            c = 253
        out[i] = c
    return out


@njit(cache=True, nogil=True)
def _push(buf, n, cell, pending, costarr):  # pragma: no cover  (compiled)
    """navfn.cpp's ``push_cur``/``push_next``/``push_over``: a cell not pending, not an obstacle,
    while there is room."""
    if 0 <= cell < costarr.shape[0] and not pending[cell] and costarr[cell] < 254 and n < buf.shape[0]:
        buf[n] = cell
        pending[cell] = True
        return n + 1
    return n


@njit(cache=True, nogil=True)
def _update_cell(n, nx, potarr, costarr, pending, cur_t, nxt, n_next, over, n_over):  # pragma: no cover
    """``NavFn::updateCell``: the quadratic two-neighbour update of cell ``n``; neighbours that
    could improve go to the next buffer (below the threshold) or the overflow buffer."""
    le_, r, u, d = potarr[n - 1], potarr[n + 1], potarr[n - nx], potarr[n + nx]  # navfn's l, r, u, d
    tc = le_ if le_ < r else r
    ta = u if u < d else d
    if costarr[n] < 254:
        hf = np.float32(costarr[n])
        dc = np.float32(tc - ta)
        if dc < 0:
            dc = np.float32(-dc)
            ta = tc
        if dc >= hf:
            pot = np.float32(ta + hf)
        else:
            dd = np.float32(dc / hf)
            v = np.float32(-0.2301 * dd * dd + 0.5307 * dd + 0.7040)
            pot = np.float32(ta + hf * v)
        if pot < potarr[n]:
            le = np.float32(INVSQRT2 * np.float32(costarr[n - 1]))
            re = np.float32(INVSQRT2 * np.float32(costarr[n + 1]))
            ue = np.float32(INVSQRT2 * np.float32(costarr[n - nx]))
            de = np.float32(INVSQRT2 * np.float32(costarr[n + nx]))
            potarr[n] = pot
            if pot < cur_t:
                if le_ > pot + le:
                    n_next = _push(nxt, n_next, n - 1, pending, costarr)
                if r > pot + re:
                    n_next = _push(nxt, n_next, n + 1, pending, costarr)
                if u > pot + ue:
                    n_next = _push(nxt, n_next, n - nx, pending, costarr)
                if d > pot + de:
                    n_next = _push(nxt, n_next, n + nx, pending, costarr)
            else:
                if le_ > pot + le:
                    n_over = _push(over, n_over, n - 1, pending, costarr)
                if r > pot + re:
                    n_over = _push(over, n_over, n + 1, pending, costarr)
                if u > pot + ue:
                    n_over = _push(over, n_over, n - nx, pending, costarr)
                if d > pot + de:
                    n_over = _push(over, n_over, n + nx, pending, costarr)
    return n_next, n_over


@njit(cache=True, nogil=True)
def propagate(costarr, nx, ny, goal_cell, start_cell, cycles, at_start):  # pragma: no cover  (compiled)
    """``NavFn::setupNavFn`` then ``NavFn::propNavFnDijkstra``: the potential (float32, flat)
    spread from ``goal_cell`` (navfn's goal: the robot, in move_base) through ``costarr`` (navfn
    costs, flat; its border made :data:`COST_OBS` here) for at most ``cycles`` buffer passes,
    stopping once ``start_cell`` has a potential when ``at_start``. Returns the potential."""
    ns = nx * ny
    potarr = np.full(ns, np.float32(1.0e10), dtype=np.float32)
    for i in range(nx):
        costarr[i] = 254
        costarr[(ny - 1) * nx + i] = 254
    for j in range(ny):
        costarr[j * nx] = 254
        costarr[j * nx + nx - 1] = 254
    pending = np.zeros(ns, dtype=np.bool_)
    bufs = np.empty((3, 10000), dtype=np.int64)
    cur, nxt, over = 0, 1, 2
    n_cur, n_next, n_over = 0, 0, 0
    cur_t = np.float32(254.0)
    potarr[goal_cell] = 0.0
    for cell in (goal_cell + 1, goal_cell - 1, goal_cell - nx, goal_cell + nx):  # initCost
        n_cur = _push(bufs[cur], n_cur, cell, pending, costarr)
    for _ in range(cycles):
        if n_cur == 0 and n_next == 0:
            break
        for k in range(n_cur):
            pending[bufs[cur, k]] = False
        for k in range(n_cur):
            n_next, n_over = _update_cell(bufs[cur, k], nx, potarr, costarr, pending, cur_t, bufs[nxt], n_next,
                                          bufs[over], n_over)
        n_cur, n_next = n_next, 0
        cur, nxt = nxt, cur
        if n_cur == 0:
            cur_t = np.float32(cur_t + 2 * 50)  # priInc = 2 * COST_NEUTRAL
            n_cur, n_over = n_over, 0
            cur, over = over, cur
        if at_start and potarr[start_cell] < 1.0e10:
            break
    return potarr


@njit(cache=True, nogil=True)
def _grad_cell(n, nx, ns, potarr, gradx, grady):  # pragma: no cover  (compiled)
    """``NavFn::gradCell``: the normalised potential gradient at cell ``n`` (cached)."""
    if gradx[n] + grady[n] > 0.0:
        return
    if n < nx or n > ns - nx:
        return
    cv = potarr[n]
    dx = np.float32(0.0)
    dy = np.float32(0.0)
    if cv >= 1.0e10:
        if potarr[n - 1] < 1.0e10:
            dx = np.float32(-254.0)
        elif potarr[n + 1] < 1.0e10:
            dx = np.float32(254.0)
        if potarr[n - nx] < 1.0e10:
            dy = np.float32(-254.0)
        elif potarr[n + nx] < 1.0e10:
            dy = np.float32(254.0)
    else:
        if potarr[n - 1] < 1.0e10:
            dx += potarr[n - 1] - cv
        if potarr[n + 1] < 1.0e10:
            dx += cv - potarr[n + 1]
        if potarr[n - nx] < 1.0e10:
            dy += potarr[n - nx] - cv
        if potarr[n + nx] < 1.0e10:
            dy += cv - potarr[n + nx]
    norm = np.float32(math.hypot(dx, dy))
    if norm > 0:
        norm = np.float32(1.0 / norm)
        gradx[n] = np.float32(norm * dx)
        grady[n] = np.float32(norm * dy)


@njit(cache=True, nogil=True)
def _as_int(p):  # pragma: no cover  (compiled)
    """C's float -> int conversion as x86 does it (out of range: INT_MIN)."""
    if p >= 2147483648.0 or p < -2147483648.0:
        return -2147483648
    return int(p)


@njit(cache=True, nogil=True)
def _c_round(x):  # pragma: no cover  (compiled)
    """C's ``round``: halves away from zero (Python's ``round`` takes them to even)."""
    return math.floor(x + 0.5) if x >= 0 else -math.floor(-x + 0.5)


@njit(cache=True, nogil=True)
def _lowest_neighbour(stc, nx, potarr):  # pragma: no cover  (compiled)
    """calcPath's grid step: the lowest of the 8 neighbours (or ``stc``), compared with the
    potential of ``stc`` truncated to an int, as navfn's ``int minp`` does."""
    minc = stc
    minp = _as_int(potarr[stc])
    for st in (stc - nx - 1, stc - nx, stc - nx + 1, stc - 1, stc + 1, stc + nx - 1, stc + nx, stc + nx + 1):
        if potarr[st] < minp:
            minp = _as_int(potarr[st])
            minc = st
    return minc


@njit(cache=True, nogil=True)
def calc_path(potarr, nx, ny, start_x, start_y, goal_x, goal_y, n, step):  # pragma: no cover  (compiled)
    """``NavFn::calcPath``: from navfn's start cell (the global goal, in move_base) down the
    potential's interpolated gradient in steps of ``step`` cells (``pathStep`` 0.5), following
    the grid where the potential is unknown nearby or the path oscillates, for at most ``n``
    steps, until a point's potential is under :data:`COST_NEUTRAL` (then navfn's goal cell is the
    last point). Returns (K, 2) float32 cell coordinates, empty when no path was found."""
    ns = nx * ny
    px = np.zeros(n + 1, dtype=np.float32)
    py = np.zeros(n + 1, dtype=np.float32)
    gradx = np.zeros(ns, dtype=np.float32)
    grady = np.zeros(ns, dtype=np.float32)
    stc = start_y * nx + start_x
    dx = np.float32(0.0)
    dy = np.float32(0.0)
    npath = 0
    for _ in range(n):
        nearest = max(0, min(ns - 1, stc + int(_c_round(dx)) + int(nx * _c_round(dy))))
        if potarr[nearest] < 50:
            px[npath], py[npath] = goal_x, goal_y
            npath += 1
            return np.stack((px[:npath], py[:npath]), axis=1)
        if stc < nx or stc > ns - nx:
            return np.empty((0, 2), dtype=np.float32)
        px[npath] = np.float32(stc % nx + dx)
        py[npath] = np.float32(stc // nx + dy)
        npath += 1
        oscillation = npath > 2 and px[npath - 1] == px[npath - 3] and py[npath - 1] == py[npath - 3]
        stcnx, stcpx = stc + nx, stc - nx
        if (potarr[stc] >= 1.0e10 or potarr[stc + 1] >= 1.0e10 or potarr[stc - 1] >= 1.0e10
                or potarr[stcnx] >= 1.0e10 or potarr[stcnx + 1] >= 1.0e10 or potarr[stcnx - 1] >= 1.0e10
                or potarr[stcpx] >= 1.0e10 or potarr[stcpx + 1] >= 1.0e10 or potarr[stcpx - 1] >= 1.0e10
                or oscillation):
            stc = _lowest_neighbour(stc, nx, potarr)
            dx = np.float32(0.0)
            dy = np.float32(0.0)
            if potarr[stc] >= 1.0e10:
                return np.empty((0, 2), dtype=np.float32)
        else:
            for cell in (stc, stc + 1, stcnx, stcnx + 1):
                _grad_cell(cell, nx, ns, potarr, gradx, grady)
            x1 = np.float32((1.0 - dx) * gradx[stc] + dx * gradx[stc + 1])
            x2 = np.float32((1.0 - dx) * gradx[stcnx] + dx * gradx[stcnx + 1])
            x = np.float32((1.0 - dy) * x1 + dy * x2)
            y1 = np.float32((1.0 - dx) * grady[stc] + dx * grady[stc + 1])
            y2 = np.float32((1.0 - dx) * grady[stcnx] + dx * grady[stcnx + 1])
            y = np.float32((1.0 - dy) * y1 + dy * y2)
            if x == 0.0 and y == 0.0:
                return np.empty((0, 2), dtype=np.float32)
            ss = np.float32(step / math.hypot(x, y))
            dx = np.float32(dx + x * ss)
            dy = np.float32(dy + y * ss)
            if dx > 1.0:
                stc += 1
                dx = np.float32(dx - 1.0)
            if dx < -1.0:
                stc -= 1
                dx = np.float32(dx + 1.0)
            if dy > 1.0:
                stc += nx
                dy = np.float32(dy - 1.0)
            if dy < -1.0:
                stc -= nx
                dy = np.float32(dy + 1.0)
    return np.empty((0, 2), dtype=np.float32)


@dataclass(frozen=True)
class NavfnPlan:
    """One :func:`make_plan`: the path and what navfn computed on the way."""

    path: np.ndarray
    """(N, 2) world points (m) from the robot to the goal, the goal itself last; empty: no plan."""
    potential: np.ndarray
    """navfn's potential (float32, ``[my, mx]``; :data:`POT_HIGH` where not reached)."""
    goal_potential: float
    """The potential at the goal's cell (navfn's path cost, in its cost units; POT_HIGH: not reached)."""

    @property
    def found(self) -> bool:
        return len(self.path) > 0


def make_plan(costmap: Costmap2D, start: tuple[float, float], goal: tuple[float, float],
              allow_unknown: bool = True, path_step: float = 0.5) -> NavfnPlan:
    """``NavfnROS::makePlan`` from ``start`` to ``goal`` (world m) on ``costmap``, with
    ``default_tolerance`` 0: the robot's cell cleared in ``costmap`` (``clearRobotCell``), navfn's
    costs, Dijkstra from the robot (navfn's goal) to the goal (navfn's start) with
    ``max(nx * ny / 20, nx + ny)`` cycles, then ``calcPath`` from the goal's cell for ``4 *
    size_x`` steps, reversed; each point ``origin + cell * resolution`` (navfn_ros.cpp's
    ``mapToWorld``, without the half cell), the goal pose appended.

    Returns an empty plan when the start or the goal is off the map, the goal is not reached, or
    the descent fails.
    """
    empty = np.empty((0, 2))
    nx, ny = costmap.size_x, costmap.size_y
    start_cell = costmap.world_to_map(*start)
    if start_cell is None:
        return NavfnPlan(empty, np.full((ny, nx), POT_HIGH, dtype=np.float32), POT_HIGH)
    costmap.costs[start_cell[1], start_cell[0]] = FREE_SPACE  # clearRobotCell
    costarr = translate_costs(costmap.costs.reshape(-1), allow_unknown)
    goal_cell = costmap.world_to_map(*goal)
    if goal_cell is None:
        return NavfnPlan(empty, np.full((ny, nx), POT_HIGH, dtype=np.float32), POT_HIGH)
    robot = start_cell[1] * nx + start_cell[0]
    target = goal_cell[1] * nx + goal_cell[0]
    potarr = propagate(costarr, nx, ny, robot, target, max(nx * ny // 20, nx + ny), True)
    potential = potarr.reshape(ny, nx)
    goal_potential = float(potarr[target])
    if not goal_potential < POT_HIGH:
        return NavfnPlan(empty, potential, goal_potential)
    cells = calc_path(potarr, nx, ny, goal_cell[0], goal_cell[1], start_cell[0], start_cell[1], 4 * nx, path_step)
    if len(cells) == 0:
        return NavfnPlan(empty, potential, goal_potential)
    cells = cells[::-1].astype(np.float64)
    world = np.stack([costmap.origin_x + cells[:, 0] * costmap.resolution,
                      costmap.origin_y + cells[:, 1] * costmap.resolution], axis=1)
    return NavfnPlan(np.vstack([world, [goal]]), potential, goal_potential)


def warmup() -> None:
    """Compile (or load from numba's disk cache) navfn's kernels on a tiny map."""
    cm = Costmap2D(12, 12, 0.1)
    make_plan(cm, (0.25, 0.25), (0.95, 0.85))
