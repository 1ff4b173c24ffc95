"""base_local_planner's TrajectoryPlanner and TrajectoryPlannerROS, ported (the DWA mode BARN runs).

ros-planning/navigation ``noetic-devel``, package ``base_local_planner``:

- :class:`TrajectoryPlanner` is ``trajectory_planner.cpp``: velocity samples in the dynamic
  window, each rolled out (``generateTrajectory``) and scored ``pdist_scale * path_dist +
  gdist_scale * goal_dist + occdist_scale * occ_cost``, in-place rotations chosen by the goal
  distance ``heading_lookahead`` ahead, the oscillation flags and the escape (``createTrajectories``,
  ``findBestPath``);
- the path and goal distances are ``map_grid.cpp``'s ``MapGrid`` (breadth-first over the local
  costmap's cells from the plan's cells and from the local goal);
- a footprint's legality is ``costmap_model.cpp``'s ``CostmapModel::footprintCost``: the
  footprint's outline rasterised with ``line_iterator.h``; illegal if an outline cell is lethal
  (or unknown, or the outline leaves the map), else its highest cost. An inscribed (253) cell on
  the outline is legal there: ``pointCost`` refuses lethal and unknown cells only;
- :class:`TrajectoryPlannerROS` is ``trajectory_planner_ros.cpp``: the plan transformed and
  pruned (``goal_functions.cpp``), the goal tolerances, stopping and rotating to the goal's yaw.

Two things differ from ROS, both documented where they are: ``meter_scoring`` scales the path
and goal biases by the resolution as ``TrajectoryPlanner::reconfigure`` means to (there it reads
a member its constructor never sets), and with ``escape`` off (an env whose robot cannot back
up) the escape trajectory is skipped, so a robot with nothing legal to do gets no command, as
when the escape itself has no path (-2).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numba import njit

from bulletnav.control.dwa_params import TrajectoryPlannerParams
from bulletnav.planning.costmap import NO_INFORMATION, Costmap2D, convex_fill_cells, line_next, line_start


def shortest_angular_distance(a: float, b: float) -> float:
    """angles::shortest_angular_distance: b - a wrapped into [-pi, pi]."""
    d = math.fmod(b - a + math.pi, 2.0 * math.pi)  # angles::normalize_angle, as the angles package writes it
    return d + math.pi if d <= 0.0 else d - math.pi


# ---------------------------------------------------------------------------------- kernels

@njit(cache=True, nogil=True)
def map_grid_distances(costs, size_x, size_y, within_robot, targets, n_targets):  # pragma: no cover  (compiled)
    """``MapGrid::computeTargetDistance`` from the cells ``targets[:n_targets]`` (flat indices,
    distance 0, pushed in order): breadth-first over the 4-neighbours; a neighbour that is
    lethal, inscribed or unknown (and not ``within_robot``) gets ``obstacleCosts`` (the number of
    cells) and stops the wave; cells never reached keep ``unreachableCellCosts`` (cells + 1)."""
    n = size_x * size_y
    dist = np.full(n, float(n + 1))
    mark = np.zeros(n, dtype=np.bool_)
    queue = np.empty(n + n_targets, dtype=np.int64)
    head, tail = 0, 0
    for k in range(n_targets):
        dist[targets[k]] = 0.0
        mark[targets[k]] = True
        queue[tail] = targets[k]
        tail += 1
    while head < tail:
        cur = queue[head]
        head += 1
        cx, cy = cur % size_x, cur // size_x
        for k in range(4):
            if k == 0:
                if cx == 0:
                    continue
                nb = cur - 1
            elif k == 1:
                if cx >= size_x - 1:
                    continue
                nb = cur + 1
            elif k == 2:
                if cy == 0:
                    continue
                nb = cur - size_x
            else:
                if cy >= size_y - 1:
                    continue
                nb = cur + size_x
            if mark[nb]:
                continue
            mark[nb] = True
            c = costs[nb]
            if not within_robot[nb] and (c == 254 or c == 253 or c == 255):
                dist[nb] = float(n)
                continue
            if dist[cur] + 1 < dist[nb]:
                dist[nb] = dist[cur] + 1
            if tail < queue.shape[0]:
                queue[tail] = nb
                tail += 1
    return dist


@njit(cache=True, nogil=True)
def footprint_cost(x, y, theta, footprint, costs, size_x, size_y, origin_x, origin_y, res):  # pragma: no cover
    """``WorldModel::footprintCost`` then ``CostmapModel::footprintCost``: -3 when the centre or a
    vertex is off the map, -1 (-2) when the outline (``LineIterator`` between consecutive vertices,
    then last to first) crosses a lethal (unknown) cell, else the outline's highest cost."""
    if x < origin_x or y < origin_y:
        return -3.0
    if int((x - origin_x) / res) >= size_x or int((y - origin_y) / res) >= size_y:
        return -3.0
    c, s = math.cos(theta), math.sin(theta)
    n = footprint.shape[0]
    best = 0.0
    for k in range(n):
        a, b = k, (k + 1) % n
        ax = x + (footprint[a, 0] * c - footprint[a, 1] * s)
        ay = y + (footprint[a, 0] * s + footprint[a, 1] * c)
        bx = x + (footprint[b, 0] * c - footprint[b, 1] * s)
        by = y + (footprint[b, 0] * s + footprint[b, 1] * c)
        if ax < origin_x or ay < origin_y or bx < origin_x or by < origin_y:
            return -3.0
        x0, y0 = int((ax - origin_x) / res), int((ay - origin_y) / res)
        x1, y1 = int((bx - origin_x) / res), int((by - origin_y) / res)
        if x0 >= size_x or y0 >= size_y or x1 >= size_x or y1 >= size_y:
            return -3.0
        line = _line_cost(costs, size_x, x0, y0, x1, y1)
        if line < 0:
            return line
        if line > best:
            best = line
    return best


@njit(cache=True, nogil=True)
def _line_cost(costs, size_x, x0, y0, x1, y1):  # pragma: no cover  (compiled)
    """``CostmapModel::lineCost``: the highest cost along ``LineIterator(x0, y0, x1, y1)``; -1 at a
    lethal cell, -2 at an unknown one (``pointCost``)."""
    xinc1, yinc1, xinc2, yinc2, den, num, numadd, numpixels = line_start(x0, y0, x1, y1)
    x, y = x0, y0
    line = 0.0
    for _ in range(numpixels + 1):
        v = costs[y * size_x + x]
        if v == 255:
            return -2.0
        if v == 254:
            return -1.0
        if v > line:
            line = float(v)
        x, y, num = line_next(x, y, num, xinc1, yinc1, xinc2, yinc2, den, numadd)
    return line


@njit(cache=True, nogil=True)
def _new_velocity(vg, vi, a_max, dt):  # pragma: no cover  (compiled)
    """``computeNewVelocity``: from ``vi`` toward ``vg`` at most ``a_max * dt``."""
    if vg - vi >= 0:
        return min(vg, vi + a_max * dt)
    return max(vg, vi - a_max * dt)


@njit(cache=True, nogil=True)
def generate_trajectory(x, y, theta, vx, vtheta, vx_samp, vtheta_samp, acc_x, acc_theta, impossible_cost,
                        sim_time, sim_granularity, angular_sim_granularity, pdist_bias, gdist_bias, occdist_scale,
                        costs, size_x, size_y, origin_x, origin_y, res, path_dist, goal_dist, footprint,
                        points):  # pragma: no cover  (compiled)
    """``TrajectoryPlanner::generateTrajectory`` for a differential-drive robot (no sideways
    speed, ``heading_scoring`` and ``simple_attractor`` off): ``num_steps`` points ``sim_time /
    num_steps`` apart, the speeds approaching the sample at the acceleration limits, each point's
    footprint checked (illegal: -1), its path and goal distances read (no path: -2); the cost of
    the last point's distances and the highest cell cost met. Writes the points into ``points``
    (rows x, y, theta); returns (cost, points written)."""
    vmag = abs(vx_samp)
    num_steps = int(max((vmag * sim_time) / sim_granularity, abs(vtheta_samp) / angular_sim_granularity) + 0.5)
    if num_steps == 0:
        num_steps = 1
    dt = sim_time / num_steps
    x_i, y_i, th_i, vx_i, vth_i = x, y, theta, vx, vtheta
    path_d, goal_d, occ = 0.0, 0.0, 0.0
    npts = 0
    for _ in range(num_steps):
        if x_i < origin_x or y_i < origin_y:
            return -1.0, npts
        cx, cy = int((x_i - origin_x) / res), int((y_i - origin_y) / res)
        if cx >= size_x or cy >= size_y:
            return -1.0, npts
        fc = footprint_cost(x_i, y_i, th_i, footprint, costs, size_x, size_y, origin_x, origin_y, res)
        if fc < 0:
            return -1.0, npts
        cell = cy * size_x + cx
        occ = max(max(occ, fc), float(costs[cell]))
        path_d = path_dist[cell]
        goal_d = goal_dist[cell]
        if impossible_cost <= goal_d or impossible_cost <= path_d:
            return -2.0, npts
        if npts < points.shape[0]:
            points[npts, 0], points[npts, 1], points[npts, 2] = x_i, y_i, th_i
            npts += 1
        vx_i = _new_velocity(vx_samp, vx_i, acc_x, dt)
        vth_i = _new_velocity(vtheta_samp, vth_i, acc_theta, dt)
        x_i = x_i + (vx_i * math.cos(th_i) + 0.0 * math.cos(math.pi / 2 + th_i)) * dt
        y_i = y_i + (vx_i * math.sin(th_i) + 0.0 * math.sin(math.pi / 2 + th_i)) * dt
        th_i = th_i + vth_i * dt
    return pdist_bias * path_d + goal_d * gdist_bias + occdist_scale * occ, npts


@njit(cache=True, nogil=True)
def score_samples(x, y, theta, vx, vtheta, vx_samps, vtheta_samps, acc_x, acc_theta, impossible_cost, sim_time,
                  sim_granularity, angular_sim_granularity, pdist_bias, gdist_bias, occdist_scale, costs, size_x, size_y,
                  origin_x, origin_y, res, path_dist, goal_dist, footprint, max_points):  # pragma: no cover  (compiled)
    """:func:`generate_trajectory` for each sample: (costs (S,), end points (S, 3): each
    trajectory's last point, as ``Trajectory::getEndpoint`` gives it)."""
    n = vx_samps.shape[0]
    out = np.empty(n)
    ends = np.zeros((n, 3))
    points = np.empty((max_points, 3))
    for k in range(n):
        cost, npts = generate_trajectory(x, y, theta, vx, vtheta, vx_samps[k], vtheta_samps[k], acc_x, acc_theta,
                                         impossible_cost, sim_time, sim_granularity, angular_sim_granularity, pdist_bias,
                                         gdist_bias, occdist_scale, costs, size_x, size_y, origin_x, origin_y, res,
                                         path_dist, goal_dist, footprint, points)
        out[k] = cost
        if npts > 0:
            ends[k, 0], ends[k, 1], ends[k, 2] = points[npts - 1, 0], points[npts - 1, 1], points[npts - 1, 2]
    return out, ends


# ---------------------------------------------------------------------------------- the planner

@dataclass
class Trajectory:
    """``base_local_planner::Trajectory``: a sampled command and its cost (negative: illegal)."""

    xv: float
    """Forward speed sampled (m/s)."""
    thetav: float
    """Yaw rate sampled (rad/s)."""
    cost: float = -1.0
    """Its score (lower is better); -1 illegal, -2 no path to the goal."""
    end: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Its last point (x m, y m, theta rad)."""


def adjust_plan_resolution(plan: np.ndarray, resolution: float) -> np.ndarray:
    """``MapGrid::adjustPlanResolution``: points inserted so that consecutive points are at most
    ``resolution`` apart (each gap over it cut into ``ceil(d / resolution)`` steps)."""
    if len(plan) == 0:
        return plan
    out = [plan[0]]
    last = plan[0]
    for p in plan[1:]:
        sq = (p[0] - last[0]) ** 2 + (p[1] - last[1]) ** 2
        if sq > resolution * resolution:
            steps = math.ceil(math.sqrt(sq) / resolution)
            dx, dy = (p[0] - last[0]) / steps, (p[1] - last[1]) / steps
            out += [(last[0] + j * dx, last[1] + j * dy, *p[2:]) for j in range(1, steps)]
        out.append(p)
        last = p
    return np.array(out, dtype=np.float64)


class TrajectoryPlanner:
    """``base_local_planner::TrajectoryPlanner`` on a local costmap (its master grid).

    Args:
        params: the ``TrajectoryPlannerROS`` parameters.
        costmap: the local costmap's master grid (read at every call: it rolls and updates).
        footprint: the padded footprint (N, 2) m, robot frame.
        sim_period: the control period the dynamic window assumes (s).
        escape: allow the escape trajectory at ``escape_vel`` (off when the robot cannot back up).
    """

    def __init__(self, params: TrajectoryPlannerParams, costmap: Costmap2D, footprint: np.ndarray, sim_period: float,
                 escape: bool = True) -> None:
        self.p = params
        self.costmap = costmap
        self.footprint = np.ascontiguousarray(footprint, dtype=np.float64)
        self.sim_period = float(sim_period)
        self.escape = escape
        scale = costmap.resolution if params.meter_scoring else 1.0  # meter_scoring: the biases per metre
        self.path_distance_bias = params.pdist_scale * scale
        self.goal_distance_bias = params.gdist_scale * scale
        self.global_plan = np.empty((0, 3))
        self.final_goal: tuple[float, float] | None = None
        self.path_dist = np.empty(0)
        """``path_map_``'s distances (cells), flat: the last :meth:`find_best_path`'s."""
        self.goal_dist = np.empty(0)
        """``goal_map_``'s distances (cells), flat."""
        self.local_goal: tuple[float, float] | None = None
        self.stuck_left = self.stuck_right = self.rotating_left = self.rotating_right = False
        self.escaping = False
        self.prev_x = self.prev_y = 0.0
        self.escape_x = self.escape_y = self.escape_theta = 0.0

    # ------------------------------------------------------------------ the plan and the grids
    def update_plan(self, plan: np.ndarray) -> None:
        """``updatePlan`` (without computing distances): the plan (N, 3: x, y, yaw) and its end."""
        self.global_plan = np.asarray(plan, dtype=np.float64).reshape(-1, 3)
        self.final_goal = (float(self.global_plan[-1, 0]), float(self.global_plan[-1, 1])) if len(self.global_plan) else None

    def _plan_cells(self) -> tuple[list[int], int | None]:
        """``setTargetCells``' and ``setLocalGoal``'s walk over the plan at the map's resolution:
        the cells of the points from the first on the map (and known) to the last before the plan
        leaves it, and the last of them (the local goal)."""
        cm = self.costmap
        cells: list[int] = []
        started = False
        for px, py, *_ in adjust_plan_resolution(self.global_plan, cm.resolution):
            m = cm.world_to_map(px, py)
            if m is not None and cm.costs[m[1], m[0]] != NO_INFORMATION:
                cells.append(m[1] * cm.size_x + m[0])
                started = True
            elif started:
                break
        return cells, (cells[-1] if cells else None)

    def compute_distances(self, pose: tuple[float, float, float]) -> None:
        """``findBestPath``'s first half: the cells under the footprint at ``pose`` marked within
        the robot (``FootprintHelper::getFootprintCells`` with fill; the path map only), then the
        path distances from the plan's cells and the goal distances from the local goal."""
        cm = self.costmap
        n = cm.size_x * cm.size_y
        costs = cm.costs.reshape(-1)
        within = np.zeros(n, dtype=np.bool_)
        c, s = math.cos(pose[2]), math.sin(pose[2])
        cells = [cm.world_to_map(pose[0] + fx * c - fy * s, pose[1] + fx * s + fy * c) for fx, fy in self.footprint]
        if all(m is not None for m in cells):
            filled = convex_fill_cells(np.array([m[0] for m in cells]), np.array([m[1] for m in cells]), False)
            within[filled[:, 1] * cm.size_x + filled[:, 0]] = True
        targets, goal = self._plan_cells()
        t = np.array(targets, dtype=np.int64)
        self.path_dist = map_grid_distances(costs, cm.size_x, cm.size_y, within, t, len(t))
        g = np.array([] if goal is None else [goal], dtype=np.int64)
        self.goal_dist = map_grid_distances(costs, cm.size_x, cm.size_y, np.zeros(n, dtype=np.bool_), g, len(g))
        self.local_goal = None if goal is None else cm.map_to_world(goal % cm.size_x, goal // cm.size_x)

    # ------------------------------------------------------------------ rollouts
    def score(self, pose: tuple[float, float, float], vel: tuple[float, float], vx_samps,
              vtheta_samps) -> tuple[np.ndarray, np.ndarray]:
        """Costs and end points of the samples (:func:`score_samples`) on the current grids."""
        cm, p = self.costmap, self.p
        vx_s = np.asarray(vx_samps, dtype=np.float64).reshape(-1)
        vt_s = np.asarray(vtheta_samps, dtype=np.float64).reshape(-1)
        max_points = self._max_points(vx_s, vt_s)
        return score_samples(pose[0], pose[1], pose[2], vel[0], vel[1], vx_s, vt_s, p.acc_lim_x, p.acc_lim_theta,
                             float(cm.size_x * cm.size_y), p.sim_time, p.sim_granularity, p.angular_sim_granularity,
                             self.path_distance_bias, self.goal_distance_bias, p.occdist_scale, cm.costs.reshape(-1),
                             cm.size_x, cm.size_y, cm.origin_x, cm.origin_y, cm.resolution, self.path_dist,
                             self.goal_dist, self.footprint, max_points)

    def _max_points(self, vx_s: np.ndarray, vt_s: np.ndarray) -> int:
        """The most points a rollout of these samples has (generate_trajectory's ``num_steps``)."""
        p = self.p
        if len(vx_s) == 0:
            return 1
        return int(max(float(np.abs(vx_s).max()) * p.sim_time / p.sim_granularity,
                       float(np.abs(vt_s).max()) / p.angular_sim_granularity) + 0.5) + 2

    def rollout(self, pose: tuple[float, float, float], vel: tuple[float, float], vx_samp: float,
                vtheta_samp: float) -> tuple[float, np.ndarray]:
        """One trajectory's cost and points (K, 3) on the current grids (for drawing and tests)."""
        cm, p = self.costmap, self.p
        points = np.empty((self._max_points(np.array([vx_samp]), np.array([vtheta_samp])), 3))
        cost, n = generate_trajectory(pose[0], pose[1], pose[2], vel[0], vel[1], vx_samp, vtheta_samp, p.acc_lim_x,
                                      p.acc_lim_theta, float(cm.size_x * cm.size_y), p.sim_time, p.sim_granularity,
                                      p.angular_sim_granularity, self.path_distance_bias, self.goal_distance_bias,
                                      p.occdist_scale, cm.costs.reshape(-1), cm.size_x, cm.size_y, cm.origin_x,
                                      cm.origin_y, cm.resolution, self.path_dist, self.goal_dist, self.footprint, points)
        return cost, points[:n].copy()

    def window(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> tuple[float, float, float, float]:
        """``createTrajectories``' velocity limits: (min_vel_x, max_vel_x, min_vel_theta,
        max_vel_theta) reachable within ``sim_period`` (DWA) or ``sim_time``, the top speed
        capped at the plan end's distance / ``sim_time``."""
        p = self.p
        max_vel_x = p.max_vel_x
        if self.final_goal is not None:
            max_vel_x = min(max_vel_x, math.hypot(self.final_goal[0] - pose[0], self.final_goal[1] - pose[1]) / p.sim_time)
        horizon = self.sim_period if p.dwa else p.sim_time
        vx, vth = vel
        max_vel_x = max(min(max_vel_x, vx + p.acc_lim_x * horizon), p.min_vel_x)
        min_vel_x = max(p.min_vel_x, vx - p.acc_lim_x * horizon)
        max_vel_theta = min(p.max_vel_theta, vth + p.acc_lim_theta * horizon)
        min_vel_theta = max(p.min_vel_theta, vth - p.acc_lim_theta * horizon)
        return min_vel_x, max_vel_x, min_vel_theta, max_vel_theta

    def samples(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> tuple[np.ndarray, np.ndarray, float]:
        """The forward samples (F, 2: vx, vtheta) in ``createTrajectories``' order (each speed:
        straight, then ``vtheta_samples - 1`` yaw rates from the lowest, accumulated as it
        accumulates them), the in-place rotations' yaw rates (``vtheta_samples``, before
        ``min_in_place_vel_theta``), and the yaw step ``dvtheta``."""
        p = self.p
        min_vx, max_vx, min_vth, max_vth = self.window(pose, vel)
        with np.errstate(divide="ignore", invalid="ignore"):
            dvx = float(np.float64(max_vx - min_vx) / np.float64(p.vx_samples - 1))
            dvtheta = float(np.float64(max_vth - min_vth) / np.float64(p.vtheta_samples - 1))
        forward = []
        vx_samp = min_vx
        for _ in range(p.vx_samples):
            forward.append((vx_samp, 0.0))
            vth = min_vth
            for _ in range(p.vtheta_samples - 1):
                forward.append((vx_samp, vth))
                vth += dvtheta
            vx_samp += dvx
        rotations = []
        vth = min_vth
        for _ in range(p.vtheta_samples):
            rotations.append(vth)
            vth += dvtheta
        return np.array(forward).reshape(-1, 2), np.array(rotations), dvtheta

    def create_trajectories(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> Trajectory:
        """``createTrajectories``: the best forward sample (unless escaping), else an in-place
        rotation toward open space (the one whose end, ``heading_lookahead`` ahead, is nearest the
        local goal, the direction it last got stuck in excluded), else the escape."""
        p = self.p
        forward, rotations, dvtheta = self.samples(pose, vel)
        best = Trajectory(0.0, 0.0)
        if not self.escaping:
            costs, ends = self.score(pose, vel, forward[:, 0], forward[:, 1])
            for (vx_s, vth_s), cost, end in zip(forward, costs, ends):
                if cost >= 0 and (cost < best.cost or best.cost < 0):
                    best = Trajectory(float(vx_s), float(vth_s), float(cost), tuple(end))
        limited = np.where(rotations > 0, np.maximum(rotations, p.min_in_place_vel_theta),
                           np.minimum(rotations, -p.min_in_place_vel_theta))
        costs, ends = self.score(pose, vel, np.zeros(len(limited)), limited)
        heading_dist = math.inf
        cm = self.costmap
        for vth_s, vth_lim, cost, end in zip(rotations, limited, costs, ends):
            if not (cost >= 0 and (cost <= best.cost or best.cost < 0) and (vth_s > dvtheta or vth_s < -dvtheta)):
                continue
            ahead = cm.world_to_map(end[0] + p.heading_lookahead * math.cos(end[2]),
                                    end[1] + p.heading_lookahead * math.sin(end[2]))
            if ahead is None:
                continue
            ahead_gdist = self.goal_dist[ahead[1] * cm.size_x + ahead[0]]
            if ahead_gdist < heading_dist and ((vth_s < 0 and not self.stuck_left) or (vth_s > 0 and not self.stuck_right)):
                best = Trajectory(0.0, float(vth_lim), float(cost), tuple(end))
                heading_dist = ahead_gdist
        if best.cost >= 0:
            self._note_rotation(pose, best)
            return best
        return self._escape(pose, vel, best)

    def _note_rotation(self, pose: tuple[float, float, float], best: Trajectory) -> None:
        """The oscillation flags after a legal choice: an in-place rotation the same way twice
        marks that way stuck; moving ``oscillation_reset_dist`` clears them; leaving the escape
        pose by ``escape_reset_dist`` or ``escape_reset_theta`` ends escaping."""
        x, y, theta = pose
        if not best.xv > 0:
            if best.thetav < 0:
                if self.rotating_right:
                    self.stuck_right = True
                self.rotating_right = True
            elif best.thetav > 0:
                if self.rotating_left:
                    self.stuck_left = True
                self.rotating_left = True
            self.prev_x, self.prev_y = x, y
        self._reset_oscillation(x, y)
        self._end_escape(x, y, theta)

    def _reset_oscillation(self, x: float, y: float) -> None:
        if math.hypot(x - self.prev_x, y - self.prev_y) > self.p.oscillation_reset_dist:
            self.rotating_left = self.rotating_right = self.stuck_left = self.stuck_right = False

    def _end_escape(self, x: float, y: float, theta: float) -> None:
        if (math.hypot(x - self.escape_x, y - self.escape_y) > self.p.escape_reset_dist
                or abs(shortest_angular_distance(self.escape_theta, theta)) > self.p.escape_reset_theta):
            self.escaping = False

    def _escape(self, pose: tuple[float, float, float], vel: tuple[float, float], best: Trajectory) -> Trajectory:
        """The last resort: back up at ``escape_vel`` even through what the costmap shows (its -1
        becomes cost 1), entering escape mode; without ``escape``, nothing (the failed ``best``)."""
        if not self.escape:
            return best
        x, y, theta = pose
        costs, ends = self.score(pose, vel, [self.p.escape_vel], [0.0])
        traj = Trajectory(float(self.p.escape_vel), 0.0, float(costs[0]), tuple(ends[0]))
        self._reset_oscillation(x, y)
        if not self.escaping and traj.cost > -2.0:
            self.escape_x, self.escape_y, self.escape_theta = x, y, theta
            self.escaping = True
        self._end_escape(x, y, theta)
        if traj.cost == -1.0:
            traj.cost = 1.0
        return traj

    def find_best_path(self, pose: tuple[float, float, float], vel: tuple[float, float]) -> tuple[Trajectory, tuple[float, float]]:
        """``findBestPath``: the grids, then the best trajectory and the command it gives ((0, 0)
        when its cost is negative)."""
        self.compute_distances(pose)
        best = self.create_trajectories(pose, vel)
        return best, ((0.0, 0.0) if best.cost < 0 else (best.xv, best.thetav))

    def check_trajectory(self, pose: tuple[float, float, float], vel: tuple[float, float], vx_samp: float,
                         vtheta_samp: float) -> bool:
        """``checkTrajectory``: whether the sample's trajectory is legal (cost >= 0) on the current grids."""
        costs, _ = self.score(pose, vel, [vx_samp], [vtheta_samp])
        return bool(costs[0] >= 0)


# ---------------------------------------------------------------------------------- the ROS wrapper

def transform_global_plan(plan: np.ndarray, pose: tuple[float, float, float], costmap: Costmap2D) -> np.ndarray:
    """``transformGlobalPlan`` (goal_functions.cpp) in one frame: from the first plan point within
    half the local map's larger side of the robot, every point up to and including the first
    beyond it again."""
    if len(plan) == 0:
        return plan
    threshold = max(costmap.size_x * costmap.resolution / 2.0, costmap.size_y * costmap.resolution / 2.0)
    sq_threshold = threshold * threshold
    d = (plan[:, 0] - pose[0]) ** 2 + (plan[:, 1] - pose[1]) ** 2
    i = 0
    while i < len(plan) and d[i] > sq_threshold:
        i += 1
    out = []
    sq = d[i] if i < len(plan) else 0.0
    while i < len(plan) and sq <= sq_threshold:
        out.append(plan[i])
        sq = d[i]
        i += 1
    return np.array(out).reshape(-1, 3)


def prune_plan(pose: tuple[float, float, float], plan: np.ndarray, global_plan: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``prunePlan``: drop points from the fronts of ``plan`` and ``global_plan`` together until
    ``plan``'s first is within 1 m of the robot."""
    k = 0
    while k < len(plan) and (pose[0] - plan[k, 0]) ** 2 + (pose[1] - plan[k, 1]) ** 2 >= 1:
        k += 1
    return plan[k:], global_plan[min(k, len(global_plan)):]


@dataclass
class TrajectoryPlannerROS:
    """``TrajectoryPlannerROS``: the planner on the local costmap, the plan handed to it
    (transformed, pruned), and the goal: stop within ``xy_goal_tolerance`` (with the acceleration
    limits), then rotate to the goal's yaw.

    Args:
        planner: the :class:`TrajectoryPlanner`.
    """

    planner: TrajectoryPlanner
    global_plan: np.ndarray = field(default_factory=lambda: np.empty((0, 3)))
    """The plan as set (x, y, yaw rows), pruned as the robot passes its points."""
    xy_tolerance_latch: bool = False
    reached_goal: bool = False
    rotating_to_goal: bool = False
    rot_stopped_velocity: float = 1e-2
    """Below this yaw rate (rad/s) the robot counts as stopped."""
    trans_stopped_velocity: float = 1e-2
    """Below this speed (m/s) the robot counts as stopped."""
    last: Trajectory | None = None
    """The last trajectory chosen."""

    def set_plan(self, plan: np.ndarray) -> None:
        """``setPlan``: a new plan clears the goal latch and the reached flag."""
        self.global_plan = np.asarray(plan, dtype=np.float64).reshape(-1, 3)
        self.xy_tolerance_latch = False
        self.reached_goal = False

    def compute_velocity_commands(self, pose: tuple[float, float, float],
                                  vel: tuple[float, float]) -> tuple[bool, tuple[float, float]]:
        """``computeVelocityCommands``: (valid, (v m/s, w rad/s))."""
        tc, p = self.planner, self.planner.p
        transformed = transform_global_plan(self.global_plan, pose, tc.costmap)
        if p.prune_plan:
            transformed, self.global_plan = prune_plan(pose, transformed, self.global_plan)
        if len(transformed) == 0:
            return False, (0.0, 0.0)
        goal_x, goal_y, goal_th = transformed[-1]
        if self.xy_tolerance_latch or math.hypot(goal_x - pose[0], goal_y - pose[1]) <= p.xy_goal_tolerance:
            if p.latch_xy_goal_tolerance:
                self.xy_tolerance_latch = True
            if abs(shortest_angular_distance(pose[2], goal_th)) <= p.yaw_goal_tolerance:
                self.rotating_to_goal = False
                self.xy_tolerance_latch = False
                self.reached_goal = True
                return True, (0.0, 0.0)
            tc.update_plan(transformed)
            self.last, _ = tc.find_best_path(pose, vel)
            stopped = abs(vel[1]) <= self.rot_stopped_velocity and abs(vel[0]) <= self.trans_stopped_velocity
            if not self.rotating_to_goal and not stopped:
                return self._stop_with_acc_limits(pose, vel)
            self.rotating_to_goal = True
            return self._rotate_to_goal(pose, vel, goal_th)
        tc.update_plan(transformed)
        self.last, cmd = tc.find_best_path(pose, vel)
        return self.last.cost >= 0, cmd

    def _stop_with_acc_limits(self, pose, vel) -> tuple[bool, tuple[float, float]]:
        """``stopWithAccLimits``: slow down by one period's worth of acceleration, if that trajectory is legal."""
        tc, p = self.planner, self.planner.p
        vx = math.copysign(1.0, vel[0]) * max(0.0, abs(vel[0]) - p.acc_lim_x * tc.sim_period)
        vth = math.copysign(1.0, vel[1]) * max(0.0, abs(vel[1]) - p.acc_lim_theta * tc.sim_period)
        if tc.check_trajectory(pose, vel, vx, vth):
            return True, (vx, vth)
        return False, (0.0, 0.0)

    def _rotate_to_goal(self, pose, vel, goal_th: float) -> tuple[bool, tuple[float, float]]:
        """``rotateToGoal``: turn toward the goal's yaw at a rate between ``min_in_place_vel_theta``
        and ``max_rotational_vel``, within the acceleration limit and able to stop in time."""
        tc, p = self.planner, self.planner.p
        ang_diff = shortest_angular_distance(pose[2], goal_th)
        lo, hi = -p.max_rotational_vel, p.max_rotational_vel
        if ang_diff > 0.0:
            v = min(hi, max(p.min_in_place_vel_theta, ang_diff))
        else:
            v = max(lo, min(-1.0 * p.min_in_place_vel_theta, ang_diff))
        max_acc_vel = abs(vel[1]) + p.acc_lim_theta * tc.sim_period
        min_acc_vel = abs(vel[1]) - p.acc_lim_theta * tc.sim_period
        v = math.copysign(1.0, v) * min(max(abs(v), min_acc_vel), max_acc_vel)
        v = math.copysign(1.0, v) * min(math.sqrt(2 * p.acc_lim_theta * abs(ang_diff)), abs(v))
        v = min(hi, max(p.min_in_place_vel_theta, v)) if v > 0.0 else max(lo, min(-1.0 * p.min_in_place_vel_theta, v))
        if tc.check_trajectory(pose, vel, 0.0, v):
            return True, (0.0, v)
        return False, (0.0, 0.0)


def warmup() -> None:
    """Compile (or load from numba's disk cache) the planner's kernels on a tiny map."""
    from bulletnav.control.dwa_params import TrajectoryPlannerParams as Params

    cm = Costmap2D(20, 20, 0.1)
    fp = np.array([[-0.2, -0.2], [-0.2, 0.2], [0.2, 0.2], [0.2, -0.2]])
    tc = TrajectoryPlanner(Params(vx_samples=2, vtheta_samples=3, escape_vel=-0.1), cm, fp, 0.05)
    tc.update_plan(np.array([[1.0, 1.0, 0.0], [1.5, 1.0, 0.0]]))
    tc.find_best_path((1.0, 1.0, 0.0), (0.0, 0.0))
