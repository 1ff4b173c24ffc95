"""Fleet controllers and metrics (``bulletnav.fleet.controllers``, ``spacetime``, ``metrics``):
the reservation table's conflicts, the space-time planner against a brute-force search,
rotating priorities, a coordinated episode without robot-robot collisions, the shield seeing
other robots, the deadlock detector and throughput on synthetic traces, and the CLI."""

from __future__ import annotations

import contextlib
import json
import math
import sys
from pathlib import Path

import numpy as np
import pytest

import hang
from bulletnav.errors import ConfigError
from bulletnav.fleet import fleet_v0
from bulletnav.fleet.controllers import CoordinatedConfig, CoordinatedController, ErrandNavigator, ShieldedController, make_controller
from bulletnav.fleet.metrics import (
    FleetTrace,
    deadlock_events,
    episode_metrics,
    errand_times,
    run_fleet_episodes,
    separation,
    summarize,
)
from bulletnav.fleet.spacetime import (
    MOVES,
    ReservationTable,
    distance_map,
    largest_component,
    path_cost,
    plan_dependencies,
    reserve_starts,
    space_time_astar,
)
from bulletnav.fleet.view import FleetView

ROOT = Path(__file__).resolve().parent.parent
EMPTY = str(ROOT / "bulletnav" / "assets" / "worlds" / "empty.yaml")
ROOM_STATIONS = {"pick_stations": [(2.0, 3.0), (-2.0, 3.0)], "drop_stations": [(3.0, -3.5), (-3.0, -3.5)]}


# ------------------------------------------------------------------ reservation table
def test_reservation_table_refuses_vertex_and_swap_conflicts():
    table = ReservationTable()
    table.reserve_path([(0, 0), (1, 0), (2, 0)], agent=0)
    assert not table.move_allowed((1, 1), (1, 0), 0, agent=1)  # (1, 0) is robot 0's at t=1: vertex conflict
    assert table.move_allowed((1, 1), (1, 0), 0, agent=0)  # its own reservation
    assert not table.move_allowed((1, 0), (0, 0), 0, agent=1)  # 0 moves (0,0)->(1,0) in step 0: a swap
    assert table.move_allowed((1, 0), (0, 0), 1, agent=1)  # a step later (0, 0) is free again
    assert table.move_allowed((3, 0), (3, 0), 0, agent=1)  # waiting elsewhere is fine
    assert table.owner((2, 0), 2) == 0 and table.owner((2, 0), 3) is None


def test_robust_reservations_keep_a_cell_after_it_is_left():
    table = ReservationTable(robustness=1)
    table.reserve_path([(0, 0), (1, 0)], agent=0)
    assert not table.move_allowed((0, 1), (0, 0), 0, agent=1)  # (0, 0) still held at t=1
    assert table.move_allowed((0, 1), (0, 0), 1, agent=1)  # free at t=2
    # leaving a cell another robot enters in the next step is refused too (we still hold it)
    table2 = ReservationTable(robustness=1)
    table2.reserve_path([(2, 0), (2, 0), (1, 0)], agent=0)
    assert not table2.move_allowed((1, 0), (1, 1), 1, agent=1)


# ------------------------------------------------------------------ space-time planning
def _brute_force_cost(blocked, start, goal, table, agent, window):
    """Exact minimum cost by dynamic programming over every (cell, time) layer: the same cost
    as the planner's (each step 1, waiting on the goal 0, plus the static distance to the goal
    at the window's end), found without a heuristic or a priority queue."""
    h = distance_map(blocked, goal)
    nx, ny = blocked.shape
    best = {start: 0.0}
    for t in range(window):
        nxt: dict = {}
        for (x, y), g in best.items():
            for dx, dy in MOVES:
                u, v = x + dx, y + dy
                if not (0 <= u < nx and 0 <= v < ny) or (blocked[u, v] and (u, v) != start):
                    continue
                if not table.move_allowed((x, y), (u, v), t, agent):
                    continue
                c = g + (0.0 if (dx, dy) == (0, 0) and (x, y) == goal else 1.0)
                if c < nxt.get((u, v), math.inf):
                    nxt[(u, v)] = c
        best = nxt
    return min((g + h[c] for c, g in best.items()), default=math.inf)


def _corridor():
    """A 7 x 3 grid: a one-cell corridor along y = 1 with one side cell (a niche) at (4, 2)."""
    blocked = np.ones((7, 3), dtype=bool)
    blocked[:, 1] = False
    blocked[4, 2] = False
    return blocked


def test_space_time_planner_passes_in_a_corridor_and_matches_brute_force():
    blocked = _corridor()
    window = 12
    table = ReservationTable()
    a, a_goal = (0, 1), (6, 1)
    b, b_goal = (6, 1), (0, 1)
    table.reserve_cell(a, 0, 0)
    table.reserve_cell(b, 0, 1)
    path_a, cost_a = space_time_astar(blocked, a, a_goal, table, 0, window)
    assert cost_a == 6.0 and path_a[6] == a_goal  # the first robot drives straight through
    table.reserve_path(path_a, 0)
    path_b, cost_b = space_time_astar(blocked, b, b_goal, table, 1, window)
    # no shared cell at any step, no swap
    for t in range(window + 1):
        assert path_a[t] != path_b[t]
    for t in range(window):
        assert not (path_a[t] == path_b[t + 1] and path_a[t + 1] == path_b[t])
    assert (4, 2) in path_b  # into the niche while the other passes
    assert path_b[-1] == b_goal
    # 6 corridor moves + into and out of the niche + one wait in it
    assert cost_b == _brute_force_cost(blocked, b, b_goal, table, 1, window) == 9.0
    assert cost_b == path_cost(path_b, b_goal, distance_map(blocked, b_goal))


def test_two_robots_pressed_together_can_both_plan_out():
    # robot 0 in (2, 2) stands close enough to robot 1 in (1, 2) to hold its cell too, and the
    # two cells' points conflict: with robot 0's hold reserved before robot 1's own cell, robot
    # 1 can neither wait nor leave (the lock of seed 3113); its own cell first, both plan out
    blocked = np.zeros((5, 5), dtype=bool)
    conflicts = {(1, 2): ((2, 2),), (2, 2): ((1, 2),)}
    starts, held = [(2, 2), (1, 2)], [[(2, 2), (1, 2)], [(1, 2), (2, 2)]]
    goals = [(4, 2), (0, 0)]

    old = ReservationTable(1, conflicts)
    for cells in ([[s] for s in starts], held):  # the order before reserve_starts
        for i, group in enumerate(cells):
            for cell in group:
                for t in range(2):
                    old.reserve_cell(cell, t, i)
    assert space_time_astar(blocked, starts[1], goals[1], old, 1, 6) is None

    for order in ([0, 1], [1, 0]):
        table = ReservationTable(1, conflicts)
        reserve_starts(table, starts, held, 2)
        assert table.owner((1, 2), 0) == 1 and table.owner((2, 2), 0) == 0
        for i in order:
            found = space_time_astar(blocked, starts[i], goals[i], table, i, 6)
            assert found is not None, (order, i)
            path = found[0]
            assert path[-1] != starts[i]  # it leaves
            table.reserve_path(path, i)


def test_space_time_planner_equals_brute_force_on_random_grids():
    rng = np.random.default_rng(7)
    for trial in range(12):
        blocked = rng.random((6, 5)) < 0.25
        free = np.argwhere(~blocked)
        if len(free) < 4:
            continue
        picks = rng.choice(len(free), 4, replace=False)
        s0, g0, s1, g1 = (tuple(int(v) for v in free[k]) for k in picks)
        if not np.isfinite(distance_map(blocked, g1)[s1]) or not np.isfinite(distance_map(blocked, g0)[s0]):
            continue
        table = ReservationTable(robustness=int(trial % 2))
        table.reserve_cell(s1, 0, 1)
        found0 = space_time_astar(blocked, s0, g0, table, 0, 8)
        if found0 is None:
            continue
        table.reserve_path(found0[0], 0)
        found1 = space_time_astar(blocked, s1, g1, table, 1, 8)
        brute = _brute_force_cost(blocked, s1, g1, table, 1, 8)
        if found1 is None:
            assert brute == math.inf
        else:
            assert found1[1] == brute


def test_free_grid_cost_is_the_static_distance():
    blocked = np.zeros((8, 8), dtype=bool)
    path, cost = space_time_astar(blocked, (0, 0), (5, 3), ReservationTable(), 0, 10)
    assert cost == 8.0 and path[8] == (5, 3) and path[-1] == (5, 3)


# ------------------------------------------------------------------ plan execution (dependencies)
def test_plan_dependencies_order_each_cell_as_planned():
    a = [(0, 0), (1, 0), (2, 0), (2, 0)]
    b = [(1, 1), (1, 1), (1, 0), (1, -1)]  # enters (1, 0) at step 2, after a was there at step 1
    deps = plan_dependencies([a, b])
    assert deps[1] == {2: [(0, 1)], 3: []}  # b waits for a to pass step 1 before entering (1, 0)
    assert deps[0] == {1: [], 2: []}  # wait steps (a at step 3) have no entry
    # a cell held at step 0 (a robot between two cells) and conflicting cells count as visits
    deps = plan_dependencies([[(0, 0), (1, 0)], [(2, 0), (2, 1), (2, 1)]], held=[[], [(1, 0)]])
    assert deps[0] == {1: [(1, 0)]}
    deps = plan_dependencies([[(0, 0), (1, 0)], [(1, 1), (2, 1)]], conflicts={(1, 1): ((1, 0),), (1, 0): ((1, 1),)})
    assert deps[0] == {1: [(1, 0)]} and deps[1] == {1: []}


def _execute(paths, deps, rng, ticks=400):
    """Execute plans with random speeds: at every tick each robot takes its next step with
    probability 0.3 if every dependency of that step is met. Returns the occupancy per tick."""
    progress = [0] * len(paths)
    history = []
    for _ in range(ticks):
        for i in rng.permutation(len(paths)):
            u = progress[i] + 1
            if u < len(paths[i]) and rng.random() < 0.3 and all(progress[j] > t for j, t in deps[i].get(u, ())):
                progress[i] = u
        history.append([paths[i][k] for i, k in enumerate(progress)])
    return history, progress


def test_dependency_execution_keeps_the_plans_collision_free_at_any_speed():
    """The dependency rule: a robot never enters a cell before the robot planned there
    earlier has left it. Plans executed at random speeds (no lockstep) never put two robots
    in one cell and all finish: two robots head-on in a corridor with a niche, and four
    robots swapping corners around a block."""
    ring = np.zeros((6, 4), dtype=bool)
    ring[2:4, 1:3] = True
    cases = [(_corridor(), [(0, 1), (6, 1)], [(6, 1), (0, 1)]),
             (ring, [(0, 0), (5, 3), (5, 0), (0, 3)], [(5, 3), (0, 0), (0, 3), (5, 0)])]
    for blocked, starts, goals in cases:
        table = ReservationTable(robustness=1)
        for i, s in enumerate(starts):
            table.reserve_cell(s, 0, i)
        paths = []
        for i in range(len(starts)):
            path, _ = space_time_astar(blocked, starts[i], goals[i], table, i, 20)
            table.reserve_path(path, i)
            paths.append(path)
        assert [p[-1] for p in paths] == goals
        deps = plan_dependencies(paths)
        for seed in range(20):
            history, progress = _execute(paths, deps, np.random.default_rng(seed))
            for cells in history:
                assert len(set(cells)) == len(cells)
            assert progress == [len(p) - 1 for p in paths]


def test_largest_component_drops_pockets_and_closed_moves():
    blocked = np.array([[0, 0, 1, 0], [0, 0, 1, 0], [1, 1, 1, 0]], dtype=bool)
    floor = largest_component(blocked)
    assert floor.sum() == 4 and floor[0, 0] and not floor[0, 3]
    closed = np.zeros((3, 4, len(MOVES)), dtype=bool)
    closed[0, 0, MOVES.index((1, 0))] = closed[1, 0, MOVES.index((-1, 0))] = True
    assert distance_map(blocked, (1, 0))[0, 0] == 1.0 and distance_map(blocked, (1, 0), closed)[0, 0] == 3.0


# ------------------------------------------------------------------ coordinated controller
def test_priorities_rotate_round_robin():
    env = fleet_v0.parallel_env(num_robots=3, duration_s=10.0)
    try:
        ctl = CoordinatedController(env, CoordinatedConfig(rotate_s=0.0))  # at every replan
        _, infos = env.reset(seed=1)
        ctl.reset(infos)
        orders = [ctl.order]
        for _ in range(3):
            ctl.replan()  # as the rolling horizon makes one
            orders.append(ctl.order)
        assert orders == [[0, 1, 2], [1, 2, 0], [2, 0, 1], [0, 1, 2]]
        # with rotate_s, at most one rotation every rotate_s of simulated time
        ctl = CoordinatedController(env, CoordinatedConfig(rotate_s=6.0))
        obs, infos = env.reset(seed=1)
        ctl.reset(infos)
        ctl.replan()
        assert ctl.order == [0, 1, 2]
        while env.agents and FleetView(env).time_s < ctl.config.rotate_s:
            obs, _, _, _, infos = env.step(ctl.act(obs, infos))
        ctl.replan()
        assert ctl.order in ([1, 2, 0], [2, 0, 1])
    finally:
        env.close()


@contextlib.contextmanager
def _coordinated(seed: int, **env_kwargs):
    """A fleet env reset on ``seed`` and its coordinated controller reset on it: (env, ctl, obs, infos)."""
    env = fleet_v0.parallel_env(**env_kwargs)
    try:
        ctl = CoordinatedController(env)
        obs, infos = env.reset(seed=seed)
        ctl.reset(infos)
        yield env, ctl, obs, infos
    finally:
        env.close()


def test_coordinated_two_robots_no_robot_collision():
    with _coordinated(3, num_robots=2, duration_s=20.0) as (env, ctl, obs, infos):
        sep = math.inf
        view = FleetView(env)
        while env.agents:
            obs, _, _, _, infos = env.step(ctl.act(obs, infos))
            sep = min(sep, math.dist(view.pose(0)[:2], view.pose(1)[:2]))
        assert sum(i["collisions_robot"] for i in infos.values()) == 0
        assert sum(i["collisions_static"] for i in infos.values()) == 0
        assert sum(i["legs_completed"] for i in infos.values()) >= 1  # it does drive its errands
        assert ctl.replans > 1 and sep > 0.4


def _dependencies_met(ctl):
    """Every step a robot has taken since the last replan had its dependencies met: each robot
    it waited on is past its step (progress only grows, so what held at entry still holds)."""
    for i, deps in enumerate(ctl.dependencies):
        for u in range(1, ctl.progress[i] + 1):
            for j, t in deps.get(u, ()):
                assert ctl.progress[j] > t, (i, u, j, t)


@pytest.mark.slow
def test_coordinated_crowded_dynamic_episode_keeps_the_plan_order():
    """Eight robots among forklifts, workers and pallet events: they drive their errands at
    their own pace (no lockstep), each entering a cell only after the robots planned there
    earlier have left it, without robot-robot collision. (The deadlock metric is not checked:
    a detour that leads away from the goal for 20 s beside another robot counts as one.)"""
    ctls = []

    def factory(env):
        ctls.append(CoordinatedController(env))
        return ctls[0]

    def check(env, infos):
        if ctls[0].paths:
            _dependencies_met(ctls[0])

    out = run_fleet_episodes({"num_robots": 8, "duration_s": 30.0, "dynamic": True}, factory, 1, seed=11, on_step=check)
    row = out["episodes"][0]
    assert row["collisions_robot_robot"] == 0
    assert row["legs"] >= 2
    assert ctls[0].replans > 10


@pytest.mark.slow
def test_restarts_plan_the_boxed_in_robots_first():
    """Prioritized planning with restarts: a robot that finds no path (the plans of robots
    ahead of it cross its cell) is planned first at the next try. In a crowded episode the
    restarts leave fewer failed plans than none, every restart's order starts with the robots
    that failed, and the replans that still fail are those where the restarted order failed too."""
    def run(restarts):
        ctls, orders = [], []

        def factory(env):
            # rotating at every replan boxes robots in on this episode
            ctls.append(CoordinatedController(env, CoordinatedConfig(restarts=restarts, rotate_s=0.0)))
            return ctls[0]

        def check(env, infos):
            ctl = ctls[0]
            if ctl.paths and (not orders or orders[-1][0] != ctl.replans):
                orders.append((ctl.replans, list(ctl.order), list(ctl.planned_order)))

        run_fleet_episodes({"num_robots": 8, "duration_s": 30.0, "dynamic": True}, factory, 1, seed=6, on_step=check)
        return ctls[0], orders

    plain, _ = run(0)
    restarted, orders = run(3)
    assert plain.restarted_plans == 0 and plain.failed_plans > 0  # the episode boxes robots in
    assert restarted.restarted_plans > 0
    assert restarted.failed_plans < plain.failed_plans
    changed = [(o, p) for _, o, p in orders if o != p]
    assert changed  # some replans restarted
    for order, planned in changed:
        assert sorted(order) == sorted(planned)  # the same robots, the failed ones moved to the front


# ------------------------------------------------------------------ independent + shield
def test_errand_navigator_replans_for_a_new_goal():
    env = fleet_v0.parallel_env(num_robots=1, duration_s=5.0, world=EMPTY, **ROOM_STATIONS)
    try:
        view = FleetView(env)
        nav = ErrandNavigator(view.robot(0))
        obs, infos = env.reset(seed=0)
        nav.reset(infos["robot_0"])
        nav.act(obs["robot_0"], infos["robot_0"])
        old_end = nav.navigator.path[-1]
        info = dict(infos["robot_0"], goal=(-3.0, -3.5))
        nav.act(obs["robot_0"], info)
        assert nav.goal_changes == 1 and nav.navigator.goal == (-3.0, -3.5)
        assert math.dist(nav.navigator.path[-1], (-3.0, -3.5)) < 0.2 and nav.navigator.path[-1] != old_end
    finally:
        env.close()


class _Forward:
    """Full speed ahead for every robot."""

    def __init__(self, env):
        self.agents = env.possible_agents

    def reset(self, infos):
        pass

    def act(self, observations, infos):
        return {a: np.array([0.5, 0.0], dtype=np.float32) for a in observations}


def test_shield_sees_other_robots_as_movers_and_stops_short():
    env = fleet_v0.parallel_env(num_robots=2, duration_s=4.0, world=EMPTY, **ROOM_STATIONS)
    try:
        ctl = ShieldedController(_Forward(env), env)
        obs, infos = env.reset(seed=0)
        env._scene.robots[0].reset_pose((-1.5, 0.0, 0.0))  # test-only: face to face, 3 m apart
        env._scene.robots[1].reset_pose((1.5, 0.0, math.pi))
        view = FleetView(env)
        movers = view.robot(0, others_as_movers=True).movers
        assert len(movers) == 1 and movers[0].kind == "robot" and movers[0].index == 1
        assert math.dist(movers[0].pose[:2], (1.5, 0.0)) < 1e-6
        assert view.robot(0).movers == ()  # the navigator's view keeps robots out of its mover list
        ctl.reset(infos)
        while env.agents:
            obs, _, _, _, infos = env.step(ctl.act(obs, infos))
        assert sum(i["collisions_robot"] for i in infos.values()) == 0
        assert ctl.interventions > 0
        assert math.dist(view.pose(0)[:2], view.pose(1)[:2]) > 0.3
    finally:
        env.close()


@pytest.mark.parametrize("gap", [0.45, 0.6, 0.75, 0.9, 1.1])
def test_shields_of_two_robots_at_rest_do_not_both_take_the_gap(gap):
    """Two robots at rest face to face, ``gap`` m of floor between their outlines, both told
    full speed ahead at once: the shields, deciding one robot after the other (the second
    sees the first at its committed speed), never let them touch, whatever the gap."""
    env = fleet_v0.parallel_env(num_robots=2, duration_s=3.0, world=EMPTY, **ROOM_STATIONS)
    try:
        ctl = ShieldedController(_Forward(env), env)
        obs, infos = env.reset(seed=0)
        view = FleetView(env)
        half = 0.5 * view.footprint[0]
        env._scene.robots[0].reset_pose((-half - gap / 2, 0.0, 0.0))  # test-only placement
        env._scene.robots[1].reset_pose((half + gap / 2, 0.0, math.pi))
        ctl.reset(infos)
        while env.agents:
            obs, _, _, _, infos = env.step(ctl.act(obs, infos))
        assert sum(i["collisions_robot"] for i in infos.values()) == 0
        assert math.dist(view.pose(0)[:2], view.pose(1)[:2]) > 2 * half
    finally:
        env.close()


class _Spin:
    """Every robot turns in place at the full rate."""

    def __init__(self, env):
        self.agents = env.possible_agents

    def reset(self, infos):
        pass

    def act(self, observations, infos):
        return {a: np.array([-1.0, 1.0], dtype=np.float32) for a in observations}  # normalised: v = 0, w = max


def _spin_side_by_side(shield: bool, gap: float) -> tuple[int, int]:
    """Robot-robot collisions and shield interventions of two robots ``gap`` m apart (centres),
    side by side, both turning in place for 3 s."""
    env = fleet_v0.parallel_env(num_robots=2, duration_s=3.0, world=EMPTY, normalize_actions=True, **ROOM_STATIONS)
    try:
        inner = _Spin(env)
        ctl = ShieldedController(inner, env) if shield else inner
        obs, infos = env.reset(seed=0)
        env._scene.robots[0].reset_pose((0.0, 0.0, 0.0))  # test-only placement
        env._scene.robots[1].reset_pose((0.0, gap, 0.0))
        ctl.reset(infos)
        while env.agents:
            obs, _, _, _, infos = env.step(ctl.act(obs, infos))
        return sum(i["collisions_robot"] for i in infos.values()), getattr(ctl, "interventions", 0)
    finally:
        env.close()


def test_shields_see_a_turning_robot_as_the_circle_its_corners_sweep():
    """Two robots side by side, 0.30 m between centres (their 0.24 m wide outlines 6 cm apart),
    both told to turn in place: either turn alone stays clear of the other robot at rest, the
    two together touch (checked without the shield). A shield that saw the other robot as its
    box at rest let both turn; it sees it as the circle its corners sweep (48 points on the
    half-diagonal and 3 cm), and they never touch."""
    assert _spin_side_by_side(shield=False, gap=0.30)[0] > 0  # the premise: unshielded, they touch
    collisions, interventions = _spin_side_by_side(shield=True, gap=0.30)
    assert collisions == 0 and interventions > 0
    env = fleet_v0.parallel_env(num_robots=2, duration_s=1.0, world=EMPTY, **ROOM_STATIONS)
    try:
        env.reset(seed=0)
        view = FleetView(env)
        mover = view.robot(0, others_as_movers=True).movers[0]
        assert mover.kind == "robot" and mover.size[:2] == view.footprint[:2]
    finally:
        env.close()


def test_make_controller_refuses_bad_names():
    env = fleet_v0.parallel_env(num_robots=1, duration_s=1.0)
    try:
        with pytest.raises(ConfigError, match="one of"):
            make_controller("bogus", env)
        with pytest.raises(ConfigError, match="takes no model"):
            make_controller("coordinated", env, model="models/ppo_dynamic.zip")
    finally:
        env.close()


# ------------------------------------------------------------------ metrics on synthetic traces
def test_deadlock_detector():
    dt, steps = 0.5, 121  # 60 s
    t = np.arange(steps) * dt
    xy = np.zeros((steps, 3, 2))
    xy[:, 0] = (0.0, 0.0)
    xy[:, 1] = (1.0, 0.0)  # within 2 m of robot 0
    xy[:, 2] = (10.0, 0.0)
    legs = np.zeros((steps, 3), dtype=int)
    distance = np.empty((steps, 3))
    distance[:, 0] = 5.0  # stalled
    distance[:, 1] = 5.0  # stalled
    distance[:, 2] = 20.0 - 0.3 * t  # progressing
    events = deadlock_events(xy, distance, legs, dt)
    assert events == [(20.0, (0, 1))]  # counted once, at 20 s, for the stalled pair only
    # the progressing robot moved next to the pair is not part of a deadlock
    xy[:, 2] = (0.5, 1.0)
    assert deadlock_events(xy, distance, legs, dt) == [(20.0, (0, 1))]
    # a stalled pair more than 2 m apart is not a deadlock
    xy2 = xy.copy()
    xy2[:, 1] = (3.0, 0.0)
    distance2 = distance.copy()
    distance2[:, 2] = 20.0 - 0.3 * t
    assert deadlock_events(xy2, distance2, legs, dt) == []
    # progress (>= 0.1 m closer) at 30 s ends the pair's event; stalled again 20 s later: a new event
    d3 = distance.copy()
    d3[t >= 30.0, :2] = 4.85
    events = deadlock_events(xy, d3, legs, dt)
    assert events == [(20.0, (0, 1)), (50.0, (0, 1))]
    # small wiggles (< 0.1 m) are not progress
    d4 = distance.copy()
    d4[:, 0] = 5.0 - 0.05 * np.sin(t)
    assert len(deadlock_events(xy, d4, legs, dt)) == 1
    # a completed leg is progress even when the new goal is farther
    legs5 = legs.copy()
    legs5[t >= 10.0, 0] = 1
    assert deadlock_events(xy, distance, legs5, dt) == [(30.0, (0, 1))]


def _infos(errands, legs, robot=0, static=0):
    return {f"robot_{i}": {"errands_completed": e, "legs_completed": leg, "collisions_robot": robot,
                           "collisions_static": static, "collisions_mover": 0, "collisions_person": 0,
                           "pose": (float(i), 0.0, 0.0), "distance_to_goal": 1.0}
            for i, (e, leg) in enumerate(zip(errands, legs))}


def test_throughput_arithmetic_and_errand_times():
    dt = 1.0
    trace = FleetTrace(dt)
    # two robots, 120 s: robot 0 completes errands at 30 s and 90 s, robot 1 one at 100 s
    for k in range(121):
        e0 = int(k >= 30) + int(k >= 90)
        e1 = int(k >= 100)
        trace.record(_infos([e0, e1], [2 * e0, 2 * e1]), workers=[(0.0, 1.0)])
    row = episode_metrics(trace, _infos([2, 1], [4, 2], robot=1, static=2), duration_s=120.0)
    assert row["errands"] == 3 and row["legs"] == 6
    assert row["throughput_per_hour"] == pytest.approx(3 * 30.0)  # 3 errands in 1/30 h
    assert row["throughput_per_robot_per_hour"] == pytest.approx(45.0)
    assert row["errand_time_s"] == pytest.approx((30 + 60 + 100) / 3)
    assert sorted(errand_times(np.stack(trace.errands), dt)) == [30.0, 60.0, 100.0]
    assert row["collisions_robot_robot"] == 2 and row["collisions_static"] == 4
    assert row["min_separation_m"] == pytest.approx(1.0) and row["near_misses"] == 0
    # robot 0 at distance 1 m of the worker: personal zone (1.2 m) all 120 s, never intimate
    assert row["personal_s"] == pytest.approx(120.0) and row["intimate_s"] == 0.0
    s = summarize([row, {**row, "errands": 1, "throughput_per_hour": 30.0, "min_separation_m": 0.5}])
    assert s["errands"] == 4 and s["throughput_per_hour"] == pytest.approx(60.0) and s["min_separation_m"] == 0.5


def test_near_miss_entries():
    xy = np.zeros((5, 2, 2))
    xy[:, 1, 0] = [1.0, 0.5, 0.5, 1.0, 0.4]
    sep, entries = separation(xy)
    assert sep == pytest.approx(0.4) and entries == 2


# ------------------------------------------------------------------ CLI
def _cli(*args):
    return hang.run([sys.executable, "-m", "bulletnav.cli", *args], f"bulletnav {' '.join(args)}", cwd=ROOT)


def test_cli_fleet_json():
    r = _cli("fleet", "--robots", "2", "--duration", "10", "--episodes", "1", "--controller", "coordinated", "--json")
    assert r.returncode == 0, r.stderr
    line = next(x for x in r.stdout.splitlines() if x.startswith("{"))
    out = json.loads(line)
    for key in ("throughput_per_hour", "collisions_robot_robot", "collisions_static", "collisions_mover",
                "collisions_person", "deadlocks", "min_separation_m", "errand_time_s", "rows"):
        assert key in out
    assert len(out["rows"]) == 1 and out["rows"][0]["seed"] == 0 and out["robots"] == 2


@pytest.mark.parametrize("args, message", [
    (("--robots", "0"), "--robots: expected a robot count, a whole number from 1 to 16, got 0"),
    (("--robots", "17"), "from 1 to 16, got 17"),
    (("--controller", "bogus"), "--controller: invalid choice: 'bogus'"),
    (("--duration", "-3"), "--duration: expected seconds > 0"),
    (("--episodes", "0"), "--episodes: expected a whole number >= 1, got 0"),
    (("--controller", "coordinated", "--model", "models/ppo_dynamic.zip"), "--model is for --controller policy"),
    (("--controller", "policy", "--model", "nothere.zip"), "model file not found"),
])
def test_cli_fleet_bad_arguments(args, message):
    r = _cli("fleet", *args)
    assert r.returncode == 2
    errors = [x for x in r.stderr.splitlines() if "error" in x]
    assert len(errors) == 1 and message in errors[0], r.stderr


def test_cell_points_keep_a_passage_off_the_cell_centres_open():
    """Seed 3020's aisle warehouse has an obstacle in the cross aisle that leaves a passage
    narrower than a plan cell, off the cells' centres. The plan's map must connect what the
    robot's free space connects (an independent check: components of the fine free grid), and
    every open move must be a free segment."""
    from scipy import ndimage

    env = fleet_v0.parallel_env(num_robots=8, duration_s=10.0, dynamic=True)
    try:
        _, infos = env.reset(seed=3020)
        maps = {}
        for repair in (False, True):
            ctl = CoordinatedController(env, CoordinatedConfig(repair_points=repair))
            ctl.reset(infos)
            maps[repair] = ctl
        fine = maps[True].view.occupancy(0.1, maps[True].config.clearance)
        labels, _ = ndimage.label(~fine.occupied)
        sizes = np.bincount(labels.ravel())
        sizes[0] = 0
        main = int(np.argmax(sizes))
        for repair, ctl in maps.items():
            free = ~ctl.static_blocked
            in_main = np.zeros_like(free)
            for x, y in zip(*np.nonzero(free)):
                fx, fy = fine.world_to_cell(tuple(ctl.cell_points[x, y]))
                in_main[x, y] = labels[fx, fy] == main
            missing = int((in_main & ~ctl._floor).sum())
            if repair:
                assert missing == 0  # every cell the robot can reach is on the plan's map
            else:
                assert missing > 100  # without the repair the map falls in two
            nx, ny = free.shape
            for x, y in zip(*np.nonzero(free)):
                for m, (dx, dy) in enumerate(MOVES[1:], 1):
                    u, v = x + dx, y + dy
                    if 0 <= u < nx and 0 <= v < ny and free[u, v] and not ctl.closed[x, y, m]:
                        assert fine.segment_free(ctl.cell_points[x, y], ctl.cell_points[u, v])
    finally:
        env.close()


def test_drive_cone_turns_a_robot_toward_a_point_behind_it_instead_of_driving_on():
    with _coordinated(3, num_robots=2, duration_s=10.0) as (_, ctl, _, _):
        ctl.config = CoordinatedConfig(drive_cone=90.0)
        clear = np.full(ctl.n_rays, ctl.max_range)
        pose, behind_left = (0.0, 0.0, 0.0), (-1.0, 0.2)  # the point lies 169 degrees to its left
        ahead, away = [(0.0, 0.0), (0.5, 0.1)], [(0.0, 0.0), (-0.5, 0.6)]
        # the tracker's blends would drive it on at 0.3 m/s, away from its point and into robot 1
        v, w = ctl.cone(0, pose, behind_left, clear, 0.3, -0.1, ahead)
        assert v == 0.0 and w >= 0.8
        # the side holds while the point stays behind it, even as it crosses to the right
        v, w = ctl.cone(0, pose, (-1.0, -0.2), clear, 0.3, -0.1, ahead)
        assert v == 0.0 and w >= 0.8
        assert ctl.cone(0, pose, (1.0, 0.5), clear, 0.3, 0.2, ahead) == (0.3, 0.2)  # inside the cone: the tracker's
        assert ctl.cone(0, pose, (-1.0, -0.5), clear, 0.3, -0.1, ahead)[1] <= -0.8  # a new turn takes the short side
        # no robot ahead to drive into (robot 1 behind it): the tracker's command stands
        assert ctl.cone(0, pose, behind_left, clear, 0.3, -0.1, away) == (0.3, -0.1)
        # no room to turn in place (something 0.15 m to its side): the tracker's command stands
        beside = clear.copy()
        beside[np.argmin(np.abs(ctl._cos))] = 0.15
        assert ctl.cone(0, pose, behind_left, beside, 0.3, -0.1, ahead) == (0.3, -0.1)
        ctl.config = CoordinatedConfig(drive_cone=0.0)  # off
        assert ctl.cone(0, pose, behind_left, clear, 0.3, -0.1, ahead) == (0.3, -0.1)
    with pytest.raises(ConfigError, match="drive_cone"):
        CoordinatedConfig(drive_cone=120.0)


def test_unknot_commits_a_swapping_turn_to_one_side():
    with _coordinated(3, num_robots=2, duration_s=10.0) as (_, ctl, _, _):
        pose, target = (0.0, 0.0, 0.0), (0.0, 1.0)  # the target is to the left: turn +
        out = [ctl.unknot(0, 0.1 * k, pose, target, 0.0, (-1.0) ** k) for k in range(4)]
        assert out == [(0.0, (-1.0) ** k) for k in range(4)]  # three swaps: left alone
        assert ctl.unknot(0, 0.4, pose, target, 0.0, 1.0) == (0.0, 0.8)  # the fourth: committed
        for k in range(5, 40):  # whatever the tracker asks for, it turns left until 4 s pass
            assert ctl.unknot(0, 0.1 * k, pose, target, 0.0, (-1.0) ** k) == (0.0, 0.8)
        assert ctl.unknot(0, 4.5, pose, target, 0.3, -1.0) == (0.3, -1.0)  # then the tracker again
        # facing the target ends the commitment at once; a moving robot is never taken over
        for k in range(5):
            ctl.unknot(1, 10 + 0.1 * k, pose, target, 0.0, (-1.0) ** k)
        assert ctl.unknot(1, 10.6, (0.0, 0.0, 1.5), target, 0.0, -0.5) == (0.0, -0.5)
        assert all(ctl.unknot(1, 20 + 0.1 * k, pose, target, 0.4, (-1.0) ** k) == (0.4, (-1.0) ** k) for k in range(10))
        # something inside the circle its outline sweeps (a forklift beside it): no turn in place
        clear = np.full(ctl.n_rays, ctl.max_range)
        beside = clear.copy()
        beside[np.argmin(np.abs(ctl._cos))] = 0.15  # 0.15 m to its side: inside the 0.18 m outline radius + 3 cm
        for k in range(8):
            assert ctl.unknot(0, 30 + 0.1 * k, pose, target, 0.0, (-1.0) ** k, beside) == (0.0, (-1.0) ** k)
        assert ctl.unknot(0, 30.8, pose, target, 0.0, 1.0, clear) == (0.0, 0.8)  # room again: it turns
        assert ctl.unknot(0, 30.9, pose, target, 0.0, -1.0, beside) == (0.0, -1.0)  # and stops when it has none


def test_a_holding_robot_boxed_in_stands_rather_than_turn_in_place():
    with _coordinated(3, num_robots=2, duration_s=10.0) as (_, ctl, _, _):
        clear = np.full(ctl.n_rays, ctl.max_range)
        beside = clear.copy()
        beside[np.argmin(np.abs(ctl._cos))] = 0.15  # 0.15 m to its side: no room to turn in place
        assert ctl.holds_boxed(0.25, 0.0, beside)  # near its hold point, a turn in place, no room: it stands
        assert not ctl.holds_boxed(0.25, 0.0, clear)  # room to turn: the tracker's turn stands
        assert not ctl.holds_boxed(0.25, 0.2, beside)  # driving on toward its point, not turning in place
        assert not ctl.holds_boxed(0.5, 0.0, beside)  # farther than hold_no_turn from its point
        ctl.config = CoordinatedConfig(hold_no_turn=0.0)  # off
        assert not ctl.holds_boxed(0.25, 0.0, beside)
    with pytest.raises(ConfigError, match="hold_no_turn"):
        CoordinatedConfig(hold_no_turn=-0.1)


def _first_move(path):
    """The first cell of ``path`` other than its start (None: all waits)."""
    return next((c for c in path[1:] if c != path[0]), None)


def test_a_replan_keeps_the_next_move_of_a_robot_already_heading_into_it():
    """``commit_cone``: a robot whose plan lets it into the cell ahead of it keeps that cell as its
    next move at a replan, even where the new shortest route starts the other way (its goal now
    lies behind it); a robot facing away from its next cell, or with the rule off, plans afresh;
    and the plan after the kept move still leads to the goal."""
    env = fleet_v0.parallel_env(num_robots=1, duration_s=5.0, world=EMPTY, **ROOM_STATIONS)
    try:
        def setup(cone):
            ctl = CoordinatedController(env, CoordinatedConfig(commit_cone=cone))
            _, infos = env.reset(seed=2)
            ctl.reset(infos)
            view = FleetView(env)
            x, y, yaw = view.pose(0)
            start = ctl._cell((x, y))
            # the neighbour whose point lies nearest the robot's heading, and the one opposite
            ahead = max(((start[0] + dx, start[1] + dy) for dx, dy in MOVES[1:]),
                        key=lambda c: math.cos(math.atan2(ctl._centre(c)[1] - y, ctl._centre(c)[0] - x) - yaw))
            behind = (2 * start[0] - ahead[0], 2 * start[1] - ahead[1])
            assert not ctl.static_blocked[ahead] and not ctl.static_blocked[behind]
            ctl.paths = [[start, ahead, ahead]]  # a plan that sends it on ahead
            ctl.progress = [0]
            ctl.dependencies = plan_dependencies(ctl.paths, [[start]], ctl.conflicts)
            far = (start[0] + 3 * (start[0] - ahead[0]), start[1] + 3 * (start[1] - ahead[1]))
            assert not ctl.static_blocked[far]
            ctl.goals = [ctl._centre(far)]  # its goal now lies 3 cells behind it
            return ctl, view, start, ahead, behind, far

        ctl, view, start, ahead, behind, far = setup(60.0)
        positions = [view.pose(0)[:2]]
        assert ctl.kept_moves(positions) == {0: ahead}
        ctl.replan()
        path = ctl.paths[0]
        assert _first_move(path) == ahead  # kept, though the goal lies the other way
        assert far in path  # and it turns back to its goal within the window
        ctl, view, start, ahead, behind, far = setup(0.0)  # the rule off: straight back
        assert ctl.kept_moves([view.pose(0)[:2]]) == {}
        ctl.replan()
        assert _first_move(ctl.paths[0]) == behind
        ctl, view, start, ahead, behind, far = setup(60.0)  # facing away from its next cell
        ctl.paths = [[start, behind, behind]]
        ctl.dependencies = plan_dependencies(ctl.paths, [[start]], ctl.conflicts)
        assert ctl.kept_moves([view.pose(0)[:2]]) == {}
    finally:
        env.close()
    with pytest.raises(ConfigError, match="commit_cone"):
        CoordinatedConfig(commit_cone=-1.0)


def test_the_action_map_against_hand_values():
    """Hand values of the one action <-> command map (0.5 m/s, 1.5 rad/s limits): [-1, 1]
    mapped linearly and clipped; the physical pair clipped; command -> action its inverse
    (unclipped). The fleet env, the single-robot env and the scene view all use it."""
    from bulletnav.config import TaskConfig
    from bulletnav.envs.actions import ActionMap

    norm, phys = ActionMap.of(TaskConfig(), True), ActionMap.of(TaskConfig(), False)
    assert norm.command(np.array([-1.0, 0.0])) == (0.0, 0.0)
    assert norm.command(np.array([1.0, -1.0])) == (0.5, -1.5)
    assert norm.command(np.array([0.0, 0.5])) == (0.25, 0.75)
    assert norm.command([3.0, -7.0]) == (0.5, -1.5)  # clipped
    assert phys.command([0.3, 2.0]) == (0.3, 1.5)
    assert phys.command([-0.1, -0.2]) == (0.0, -0.2)
    np.testing.assert_array_equal(norm.action(0.25, 0.75), np.array([0.0, 0.5], dtype=np.float32))
    np.testing.assert_array_equal(phys.action(0.25, 0.75), np.array([0.25, 0.75], dtype=np.float32))
    assert (norm.space().low.tolist(), norm.space().high.tolist()) == ([-1.0, -1.0], [1.0, 1.0])
    assert (phys.space().low.tolist(), phys.space().high.tolist()) == ([0.0, -1.5], [0.5, 1.5])
    with pytest.raises(ValueError, match="non-finite"):
        norm.command([math.nan, 0.0])
