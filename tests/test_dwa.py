"""move_base + navfn + TrajectoryPlannerROS (DWA) as ported in bulletnav.control (dwa.py,
trajectory_planner.py, dwa_params.py): rollouts against the arc, the dynamic window against its
formula, choices in hand-made scenes, the oscillation and escape rules, the goal tolerances,
move_base's recoveries, the parameter files, suites, the reverse keyword and whole episodes."""

from __future__ import annotations

import math
import shlex
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest
import yaml

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.benchmark.suite import SuiteError, load_suite, replay_command
from bulletnav.control.dwa import CONTROLLING, MoveBaseDWA, dwa_env_kwargs, load_dwa_params
from bulletnav.control.dwa_params import with_overrides
from bulletnav.control.trajectory_planner import TrajectoryPlanner, TrajectoryPlannerROS, footprint_cost
from bulletnav.errors import ConfigError
from bulletnav.evaluation import run_episodes
from bulletnav.planning.costmap import INSCRIBED_INFLATED_OBSTACLE, LETHAL_OBSTACLE, LayeredCostmap, pad_footprint

BARN = load_dwa_params()
TP = BARN.trajectory_planner
FOOTPRINT = pad_footprint([[-0.21, -0.165], [-0.21, 0.165], [0.21, 0.165], [0.21, -0.165]], 0.1)
"""BARN's footprint, padded (0.62 x 0.53 m)."""


def _local(lethal: list[tuple[float, float]] = (), size: int = 200) -> LayeredCostmap:
    """A 10 x 10 m costmap at 0.05 m around the origin with lethal cells at the given points, inflated as BARN's."""
    cm = LayeredCostmap.make(size, size, 0.05, -size * 0.025, -size * 0.025, FOOTPRINT, 0.30,
                             obstacle_name="obstacles_layer", footprint_clearing_enabled=False)
    for x, y in lethal:
        m = cm.obstacles.world_to_map(x, y)
        cm.obstacles.costs[m[1], m[0]] = LETHAL_OBSTACLE
    cm.master.reset()
    cm.obstacles.update_costs(cm.master)
    cm.inflation.update_costs(cm.master)
    return cm


def _planner(cm: LayeredCostmap, plan_to: tuple[float, float] = (4.0, 0.0), escape: bool = True,
             pose: tuple[float, float, float] = (0.0, 0.0, 0.0), **changes) -> TrajectoryPlanner:
    tc = TrajectoryPlanner(replace(TP, **changes), cm.master, cm.footprint, BARN.sim_period, escape)
    n = 200
    tc.update_plan(np.stack([np.linspace(pose[0], plan_to[0], n), np.linspace(pose[1], plan_to[1], n), np.zeros(n)], axis=1))
    tc.compute_distances(pose)
    return tc


# ---------------------------------------------------------------------------------- rollouts and the window

def test_rollout_follows_the_closed_form_arc():
    tc = _planner(_local())
    v, w = 0.5, 0.5
    cost, pts = tc.rollout((0.0, 0.0, 0.0), (v, w), v, w)
    # num_steps = int(max(v * sim_time / sim_granularity, w / angular_sim_granularity) + 0.5) = max(50, 25) = 50
    assert cost >= 0 and len(pts) == 50
    dt = TP.sim_time / 50
    t = dt * np.arange(50)
    assert np.allclose(pts[:, 2], w * t)
    # forward Euler, as generateTrajectory integrates (x += v cos(theta) dt), written out here
    x = np.concatenate([[0.0], np.cumsum(v * np.cos(w * t[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(v * np.sin(w * t[:-1]) * dt)])
    assert np.allclose(pts[:, 0], x, atol=1e-12) and np.allclose(pts[:, 1], y, atol=1e-12)
    # the arc of radius v / w, which Euler trails by about v w dt t / 2 (its heading lags half a step)
    arc = np.stack([v / w * np.sin(w * t), v / w * (1 - np.cos(w * t))], axis=1)
    err = np.hypot(*(pts[:, :2] - arc).T)
    assert (err <= 1.05 * v * w * dt * t / 2 + 1e-12).all() and err[-1] > 0.5 * v * w * dt * t[-1] / 2
    # from rest the speed ramps at acc_lim_x: 10 m/s^2 x 0.04 s = 0.4 m/s, then the sample's 0.5 m/s
    _, pts = tc.rollout((0.0, 0.0, 0.0), (0.0, 0.0), 0.5, 0.0)
    assert pts[:4, 0].tolist() == pytest.approx([0.0, 0.4 * dt, 0.4 * dt + 0.5 * dt, 0.4 * dt + 1.0 * dt])


def test_dynamic_window_samples_match_the_formula():
    tc = _planner(_local())
    vx, vth = 0.2, 0.3
    forward, rotations, dvtheta = tc.samples((0.0, 0.0, 0.0), (vx, vth))
    period = 1 / 20  # sim_period = 1 / controller_frequency
    lo_x, hi_x = max(0.1, vx - 10 * period), max(min(0.5, vx + 10 * period), 0.1)  # acc_lim_x 10, min/max_vel_x
    lo_th, hi_th = max(-1.57, vth - 20 * period), min(1.57, vth + 20 * period)  # acc_lim_theta 20, +-1.57
    assert (lo_x, hi_x, lo_th, hi_th) == pytest.approx((0.1, 0.5, -0.7, 1.3))
    want = [(v, 0.0) for v in np.linspace(lo_x, hi_x, 6)]  # vx_samples 6: straight first, then 19 yaw rates
    want = [s for v, _ in want for s in [(v, 0.0), *[(v, th) for th in np.linspace(lo_th, hi_th, 20)[:-1]]]]
    assert forward.shape == (6 * 20, 2) and np.allclose(forward, want, atol=1e-12)
    assert np.allclose(rotations, np.linspace(lo_th, hi_th, 20)) and dvtheta == pytest.approx(2.0 / 19)
    # the top speed is capped so that sim_time at it ends at the plan's end: 0.6 m / 2 s = 0.3 m/s
    tc.update_plan(np.array([[0.0, 0.0, 0.0], [0.6, 0.0, 0.0]]))
    assert tc.window((0.0, 0.0, 0.0), (vx, vth))[1] == pytest.approx(0.3)
    # dwa: false (trajectory rollout) takes the whole sim_time: 0.2 + 10 x 2 caps at max_vel_x
    rollout = _planner(_local(), dwa=False)
    assert rollout.window((0.0, 0.0, 0.0), (vx, vth)) == pytest.approx((0.1, 0.5, -1.57, 1.57))


def test_footprint_cost_follows_costmap_model_by_hand():
    cm = _local([(0.0, 0.0)])
    costs, m = cm.master.costs.reshape(-1), cm.master

    def cost(x, y, theta=0.0):
        return footprint_cost(x, y, theta, cm.footprint, costs, m.size_x, m.size_y, m.origin_x, m.origin_y, m.resolution)

    # CostmapModel checks the outline only: a lethal cell inside the footprint is legal, its
    # cost the highest on the outline (inscribed cells there: 0.265 m from the obstacle, 253)
    assert cost(0.05, 0.0) == INSCRIBED_INFLATED_OBSTACLE
    assert cost(0.31, 0.0) == -1.0  # the outline's rear edge on the lethal cell
    assert cost(0.0, 0.6) == 177.0  # the lower edge (y 0.335) in row 106: 6 cells out, 252 exp(-10 x 0.035)
    assert cost(0.0, 0.7) == 0.0  # 8 cells out: beyond the inflation (6 cells)
    assert cost(-4.9, 0.0) == -3.0  # a vertex off the map


# ---------------------------------------------------------------------------------- choices

def _wall_with_gap_left() -> LayeredCostmap:
    """A wall across x = 1.0 m from y = -2.5 to 2.5 with a 1.2 m gap at y = 0.4..1.6 (to the robot's left)."""
    ys = np.arange(-2.5, 2.5, 0.05)
    return _local([(1.0, float(y)) for y in ys if not 0.4 < y < 1.6])


def test_a_wall_ahead_turns_the_robot_toward_the_gap_on_its_left():
    cm = _wall_with_gap_left()
    tc = _planner(cm, plan_to=(1.0, 1.0))  # the plan: to the gap's middle
    straight = [tc.rollout((0.0, 0.0, 0.0), (0.5, 0.0), v, 0.0)[0] for v in (0.1, 0.42, 0.5)]
    assert straight[0] >= 0 and straight[1:] == [-1.0, -1.0]  # 0.84 m and more straight on: the nose on the wall
    best, cmd = tc.find_best_path((0.0, 0.0, 0.0), (0.5, 0.0))
    assert best.cost >= 0 and best.thetav > 0.3 and cmd == (best.xv, best.thetav)
    assert best.end[1] > 0.1  # it ends to the left, toward the gap


def test_in_place_rotations_mark_the_stuck_side_and_moving_clears_it():
    wall = [(0.5, float(y)) for y in np.arange(-1.0, 1.0, 0.05)]
    cm = _local(wall)  # a wall 0.19 m beyond the nose: turning in place is legal (corners 0.41 m out), 0.2 m forward is not
    tc = _planner(cm, plan_to=(-3.0, 0.5))  # the plan leaves behind, to the left
    first, _ = tc.find_best_path((0.0, 0.0, 0.0), (0.0, 0.0))
    assert first.xv == 0.0 and first.thetav >= TP.min_in_place_vel_theta  # a left turn in place, toward the plan
    assert tc.rotating_left and not tc.stuck_left and (tc.prev_x, tc.prev_y) == (0.0, 0.0)
    second, _ = tc.find_best_path((0.0, 0.0, 0.0), (0.0, 0.0))
    assert second.thetav == first.thetav and tc.stuck_left  # the same way twice: stuck_left (it bars turning right)
    # away from the wall, having moved 0.06 m (> oscillation_reset_dist 0.05) from the last turn, the flags clear
    free = _planner(_local(), plan_to=(4.0, 0.06), pose=(0.0, 0.06, 0.0))
    free.stuck_left = free.rotating_left = True
    best, _ = free.find_best_path((0.0, 0.06, 0.0), (0.3, 0.0))
    assert best.xv > 0 and not (free.stuck_left or free.rotating_left)


def test_escape_backs_up_when_nothing_else_is_legal_and_only_where_the_env_allows_it():
    box = [(0.36, y) for y in np.arange(-0.4, 0.45, 0.05)] + [(x, s * 0.30) for x in np.arange(-0.3, 0.4, 0.05)
                                                               for s in (-1, 1)]
    cm = _local(box)  # walls 5 cm beyond the nose and the sides: no move but straight back is legal
    tc = _planner(cm)
    best, cmd = tc.find_best_path((0.0, 0.0, 0.0), (0.0, 0.0))
    assert cmd == (TP.escape_vel, 0.0) == (-0.5, 0.0) and best.cost >= 0  # escape_vel, straight back
    assert tc.escaping and (tc.escape_x, tc.escape_y, tc.escape_theta) == (0.0, 0.0, 0.0)
    # escaping: no forward samples until it moved escape_reset_dist (0.1 m) or turned escape_reset_theta (0.1 rad)
    tc.find_best_path((-0.05, 0.0, 0.0), (-0.5, 0.0))
    assert tc.escaping
    tc.find_best_path((-0.11, 0.0, 0.0), (-0.5, 0.0))
    assert not tc.escaping
    # a robot that cannot back up gets no escape: no command, a failed trajectory
    stuck = _planner(cm, escape=False)
    best, cmd = stuck.find_best_path((0.0, 0.0, 0.0), (0.0, 0.0))
    assert best.cost < 0 and cmd == (0.0, 0.0) and not stuck.escaping


def test_goal_tolerance_stop_then_rotate_by_hand():
    cm = _local()
    ros = TrajectoryPlannerROS(_planner(cm))
    goal = np.array([[0.0, 0.0, 0.0], [0.1, 0.0, 0.0], [0.2, 0.0, 0.0]])
    ros.set_plan(goal)
    pose = (0.05, 0.0, -1.0)  # within xy_goal_tolerance (0.25 m), 1 rad off the goal's yaw
    # moving: stop within the acceleration limits, 0.3 - 10 x 0.05 -> 0 m/s, 0.4 - 20 x 0.05 -> 0 rad/s
    assert ros.compute_velocity_commands(pose, (0.3, 0.4)) == (True, (0.0, 0.0))
    # stopped: rotate toward yaw 0 at min(max_rotational_vel 1.0, max(0.314, 1 rad)) within 0 + 20 x 0.05
    assert ros.compute_velocity_commands(pose, (0.0, 0.0)) == (True, (0.0, pytest.approx(1.0)))
    ok, (v, w) = ros.compute_velocity_commands((0.05, 0.0, -0.2), (0.0, 0.3))  # 0.2 rad left: 0.314 (min in place)
    assert ok and (v, w) == (0.0, pytest.approx(TP.min_in_place_vel_theta)) and not ros.reached_goal
    assert ros.compute_velocity_commands((0.05, 0.0, 0.1), (0.0, 0.0)) == (True, (0.0, 0.0))  # within 0.157 rad
    assert ros.reached_goal


# ---------------------------------------------------------------------------------- move_base

def test_move_base_runs_its_default_recoveries_then_aborts_and_stands_still():
    env = gym.make("bulletnav/Warehouse-v0", min_speed=-0.5, max_episode_steps=600)
    params = with_overrides(BARN, move_base={"planner_patience": 1.0})
    dwa = MoveBaseDWA(env.unwrapped.scene, params)
    obs, info = env.reset(seed=3, options={"goal": (30.0, 0.0)})  # off the global costmap: navfn never plans
    dwa.reset(info)
    yaws = []
    while dwa.stop_reason is None:
        obs, _, terminated, truncated, info = env.step(dwa.act(obs, info))
        yaws.append(float(info["pose"][2]))
        assert not (terminated or truncated)
    names = [what.split(": ")[1] for _, what in dwa.events if what.startswith("recovery")]
    assert names == ["conservative_reset", "rotate_recovery", "aggressive_reset", "rotate_recovery"]  # move_base.cpp
    assert dwa.stop_reason == "aborted: Failed to find a valid plan. Even after executing recovery behaviors."
    cleared = [what for _, what in dwa.events if "cleared nothing" in what]
    assert len(cleared) == 2  # BARN's layer is obstacles_layer, the recoveries' default layer_names ["obstacles"]
    turned = np.sum(np.abs(np.diff(np.unwrap(yaws))))
    assert turned > 2 * (2 * math.pi - 2 * TP.yaw_goal_tolerance) or any("collision ahead" in w for _, w in dwa.events)
    for _ in range(24):  # aborted: it stands still (BARN's robot waits for the 100 s time-out)
        obs, *_, info = env.step(dwa.act(obs, info))
        assert dwa.cmd == (0.0, 0.0)
    env.close()


def test_a_new_goal_preempts_and_a_mission_sends_one_goal_at_a_time():
    env = gym.make("bulletnav/Warehouse-v0", min_speed=-0.5)
    dwa = MoveBaseDWA(env.unwrapped.scene)
    obs, info = env.reset(seed=2)
    dwa.reset(info)
    obs, *_, info = env.step(dwa.act(obs, info))
    assert dwa.state == CONTROLLING and dwa.path is not None
    moved = dict(info, goal=(info["goal"][0] + 0.5, info["goal"][1]))  # executeCb's preemption by a new goal
    dwa.act(obs, moved)
    assert dwa.goal[:2] == moved["goal"] and any(what.startswith("new goal") for _, what in dwa.events)
    assert dwa.recovery_index == 0 and dwa.run_planner
    x, y = float(info["pose"][0]), float(info["pose"][1])
    goals = ((x + 3.0, y), (x + 1.0, y), (x - 2.0, y))
    mission = dict(info, goals=goals, reached=(False, False, False), goal_order="free", goal=goals[0])
    assert dwa._goal_of(mission, (x, y, 0.0)) == goals[1]  # free order: the nearest goal left
    assert dwa._goal_of(dict(mission, goal_order="fixed"), (x, y, 0.0)) == goals[0]  # fixed: the first left
    dwa.goal = (*goals[1], 0.0)
    assert dwa._goal_of(dict(mission, goal_order="fixed"), (x, y, 0.0)) == goals[1]  # held until reached
    assert dwa._goal_of(dict(mission, reached=(False, True, False)), (x, y, 0.0)) == goals[2]
    env.close()


# ---------------------------------------------------------------------------------- parameters

def test_barns_files_give_the_documented_values():
    p = BARN
    assert (TP.max_vel_x, TP.min_vel_x, TP.max_vel_theta, TP.min_vel_theta, TP.escape_vel) == (0.5, 0.1, 1.57, -1.57, -0.5)
    assert (TP.acc_lim_x, TP.acc_lim_theta, TP.vx_samples, TP.vtheta_samples, TP.sim_time) == (10.0, 20.0, 6, 20, 2.0)
    assert (TP.pdist_scale, TP.gdist_scale, TP.occdist_scale, TP.meter_scoring, TP.dwa) == (0.75, 1.0, 0.1, True, True)
    assert (TP.xy_goal_tolerance, TP.yaw_goal_tolerance, TP.max_rotational_vel) == (0.25, 0.157, 1.0)  # the last: ROS's default
    assert p.sim_period == 0.05 and p.move_base.planner_frequency == 20.0 and p.move_base.controller_patience == 15.0
    for c in (p.local_costmap, p.global_costmap):
        assert c.footprint == ((-0.21, -0.165), (-0.21, 0.165), (0.21, 0.165), (0.21, -0.165)) and c.footprint_padding == 0.1
        assert c.inflation_layer.inflation_radius == 0.30 and c.inflation_layer.cost_scaling_factor == 10.0  # the default
        assert c.obstacle_layer.name == "obstacles_layer" and c.obstacle_layer.source.obstacle_range == 2.5
        assert c.obstacle_layer.source.raytrace_range == 3.0 and c.obstacle_layer.source.clearing
    assert (p.local_costmap.width, p.local_costmap.rolling_window, p.local_costmap.update_frequency) == (10.0, True, 20.0)
    assert (p.global_costmap.width, p.global_costmap.origin_x, p.global_costmap.update_frequency) == (40.0, -20.0, 10.0)
    assert p.conservative_reset.layer_names == ("obstacles",) and p.local_costmap.circumscribed_radius == 0.46
    assert load_dwa_params("barn-per-cell").trajectory_planner.meter_scoring is False
    assert load_dwa_params("barn").trajectory_planner.meter_scoring is True
    fast = load_dwa_params("barn-2ms").trajectory_planner
    assert (fast.max_vel_x, fast.max_vel_theta, fast.min_vel_theta, fast.acc_lim_x) == (2.0, 4.0, -4.0, 10.0)


def test_a_users_yaml_overrides_and_bad_keys_name_file_key_and_nearest(tmp_path):
    good = tmp_path / "mine.yaml"
    good.write_text("TrajectoryPlannerROS: {max_vel_x: 0.8, path_distance_bias: 0.5}\n"
                    "local_costmap: {inflater_layer: {cost_scaling_factor: 3.0}}\ncontroller_patience: 5\n")
    p = load_dwa_params(good)
    assert p.trajectory_planner.max_vel_x == 0.8 and p.move_base.controller_patience == 5.0
    assert p.trajectory_planner.pdist_scale == 0.5  # ROS's current name wins over BARN's deprecated pdist_scale
    assert p.local_costmap.inflation_layer.cost_scaling_factor == 3.0 and p.global_costmap.inflation_layer.cost_scaling_factor == 10.0
    assert p.sources[-1] == str(good) and p.trajectory_planner.sim_time == 2.0  # the rest is BARN's
    cases = {
        "TrajectoryPlannerROS: {max_vel_xx: 2.0}\n": "unknown key 'TrajectoryPlannerROS.max_vel_xx'; the nearest valid key "
                                                    "is 'TrajectoryPlannerROS.max_vel_x'",
        "local_costmap: {inflater_layer: {inflation_raduis: 0.4}}\n": "'local_costmap.inflater_layer.inflation_radius'",
        "TrajectoryPlannerROS: {vx_samples: 2.5}\n": "key 'TrajectoryPlannerROS.vx_samples' must be a whole number, got 2.5",
        "TrajectoryPlannerROS: {max_vel_x: 30}\n": "key 'TrajectoryPlannerROS.max_vel_x' must be from 0 to 20, got 30.0",
        "global_costmap: {footprint: [[0, 0], [1, 1]]}\n": "key 'global_costmap.footprint' must be a list of at least 3",
        "TrajectoryPlannerROS: {holonomic_robot: true}\n": "key 'TrajectoryPlannerROS.holonomic_robot': only false",
        "TrajectoryPlannerROS: !!python/object:os.system {}\n": "not valid YAML",
    }
    for text, message in cases.items():
        bad = tmp_path / "bad.yaml"
        bad.write_text(text)
        with pytest.raises(ConfigError) as err:
            load_dwa_params(bad)
        assert str(err.value).startswith(f"{bad}") and message in str(err.value), str(err.value)
    with pytest.raises(ConfigError, match="neither a shipped one"):
        load_dwa_params("barn-3ms")


def test_suites_parse_dwa_controllers_with_params_and_env(tmp_path):
    (tmp_path / "fast.yaml").write_text("TrajectoryPlannerROS: {max_vel_x: 1.0}\n")
    suite_file = tmp_path / "s.yaml"
    doc = {"name": "dwa-test", "episodes": 1, "worlds": [{"env": "bulletnav/BARN-v0", "kwargs": {"world_idx": 7}}],
           "controllers": [{"type": "dwa"}, {"name": "fast", "type": "dwa", "params": "fast.yaml",
                                             "env": {"min_speed": -0.5, "lidar_rays": 720}},
                           {"type": "dwa", "params": "barn-2ms", "shield": True}]}
    suite_file.write_text(yaml.safe_dump(doc))
    suite = load_suite(str(suite_file))
    plain, fast, shipped = suite.controllers
    assert (plain.name, plain.params, plain.env) == ("DWA", "", {})
    assert fast.params == str(tmp_path / "fast.yaml") and fast.env == {"min_speed": -0.5, "lidar_rays": 720}
    assert shipped.name == "DWA (barn-2ms) + shield" and shipped.params == "barn-2ms"
    command = replay_command(suite, suite.worlds[0], fast, 5, tmp_path)
    assert command.startswith("bulletnav navigate --planner dwa --dwa-params ")
    args = shlex.split(command)
    pairs = dict(zip(args[2::2], args[3::2]))  # after "bulletnav navigate": flag, value pairs
    assert {k: pairs[k] for k in ("--world-idx", "--min-speed", "--lidar-rays", "--seed", "--episodes")} == {
        "--world-idx": "7", "--min-speed": "-0.5", "--lidar-rays": "720", "--seed": "5", "--episodes": "1"}
    assert "--dwa-params barn-2ms" in replay_command(suite, suite.worlds[0], shipped, 5, tmp_path) and "--shield" in \
        replay_command(suite, suite.worlds[0], shipped, 5, tmp_path)
    assert dwa_env_kwargs(BARN) == {"min_speed": -0.5} and dwa_env_kwargs(BARN, {"min_speed": 0.0}) == {}
    for entry, message in [({"type": "dwa", "env": {"min_sped": -0.5}}, "has unknown field(s) ['min_sped']"),
                           ({"type": "dwa", "env": {"min_speed": 0.5}}, "field 'controllers[0].env.min_speed' = 0.5"),
                           ({"type": "dwa", "params": "nope.yaml"}, "field 'controllers[0].params' = 'nope.yaml'"),
                           ({"type": "navigator", "params": "barn"}, "'controllers[0].params' is for dwa controllers only"),
                           ({"type": "model", "model": "shipped", "env": {"lidar_rays": 720}}, "'controllers[0].env' is for")]:
        suite_file.write_text(yaml.safe_dump({**doc, "controllers": [entry]}))
        with pytest.raises(SuiteError) as err:
            load_suite(str(suite_file))
        assert str(err.value).startswith(str(suite_file)) and message in str(err.value), str(err.value)


# ---------------------------------------------------------------------------------- reverse

def test_min_speed_lets_the_robot_back_up_and_changes_nothing_else():
    plain = gym.make("bulletnav/Warehouse-v0")
    back = gym.make("bulletnav/Warehouse-v0", min_speed=-0.3)
    assert plain.action_space.low.tolist() == [0.0, -1.5] and back.action_space.low.tolist() == pytest.approx([-0.3, -1.5])
    assert back.unwrapped.scene.command_limits == ((-0.3, 0.5), (-1.5, 1.5))
    obs_a, _ = plain.reset(seed=4)
    obs_b, info = back.reset(seed=4)
    assert np.array_equal(obs_a, obs_b) and plain.observation_space == back.observation_space
    x0 = info["pose"]
    for _ in range(48):  # 2 s at -0.3 m/s (and -1 m/s asked: clipped to -0.3)
        obs_b, *_, info = back.step(np.array([-1.0, 0.0], dtype=np.float32))
    moved = (info["pose"][:2] - x0[:2]) @ np.array([math.cos(x0[2]), math.sin(x0[2])])
    assert -0.6 <= moved < -0.45  # backward, 0.6 m at most (acceleration takes a little)
    assert obs_b[36 + 1] == pytest.approx(-0.3 / 0.5, abs=0.02)  # odometry v / max_speed, as before, now negative
    with pytest.raises(ValueError, match="min_speed"):
        gym.make("bulletnav/Warehouse-v0", min_speed=0.2)
    plain.close()
    back.close()


# ---------------------------------------------------------------------------------- episodes

def test_dwa_reaches_the_goal_in_warehouse_v0():
    env = gym.make("bulletnav/Warehouse-v0", **dwa_env_kwargs(BARN))
    results = run_episodes(env, MoveBaseDWA(env.unwrapped.scene), episodes=1, seed=0)
    env.close()
    r = results[0]
    assert r.success and not r.collision
    assert r.shortest_path - 0.5 <= r.path_length + 0.05  # never shorter than the shortest path to the success disc
    assert r.sim_time <= 3 * r.shortest_path / TP.max_vel_x  # and within 3 x the time at top speed


@pytest.mark.slow
@pytest.mark.parametrize("world", [101, 151])  # BARN training worlds (not multiples of 6)
def test_dwa_reaches_the_goal_in_barn_training_worlds(world):
    env = gym.make("bulletnav/BARN-v0", world_idx=world, **dwa_env_kwargs(BARN))
    dwa = MoveBaseDWA(env.unwrapped.scene)
    obs, info = env.reset(seed=0)
    dwa.reset(info)
    while True:
        obs, _, terminated, truncated, info = env.step(dwa.act(obs, info))
        if terminated or truncated:
            break
    env.close()
    assert info["end_reason"] == "success" and dwa.stop_reason is None
    assert info["barn_metric"] > 0.0  # BARN's score: success within 8 t_opt
