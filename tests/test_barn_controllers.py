"""The classical controllers and the safety shield on BARN-v0's Jackal: settings from the env's
robot (Clearpath's control.yaml: 2.0 m/s, 4.0 rad/s; the spec sheet's 0.430 m width), the
braking speed and the outline worked by hand, the shield's stopping sweep against a cylinder at
a known distance (the sweep's kinematics written out here), and PyBullet's contacts; the article
robot keeps its settings bit for bit (the goldens check its episodes)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.cli import main
from bulletnav.control.navigator import (
    FIT_BRAKE_DECEL,
    FIT_NEAR_RANGE,
    GoToGoal,
    Navigator,
    NavigatorConfig,
    fit_to_robot,
    outline_reach,
)
from bulletnav.control.shield import ShieldWrapper, shield_for
from bulletnav.evaluation import run_episodes

JACKAL_V, JACKAL_W = 2.0, 4.0  # jackal_control/config/control.yaml: linear and angular max_velocity
JACKAL_HALF_WIDTH = 0.430 / 2  # Clearpath's spec sheet: 0.508 x 0.430 m
JACKAL_NOSE = 0.508 / 2
LIDAR_X = 0.055  # the lidar's mount ahead of the body centre (BARN's JACKAL_LASER_OFFSET on the front mount)


@pytest.fixture(scope="module")
def barn():
    env = gym.make("bulletnav/BARN-v0", world_idx=0)
    env.reset(seed=0)
    yield env
    env.close()


def test_navigator_settings_come_from_the_envs_robot(barn):
    scene = barn.unwrapped.scene
    fitted = fit_to_robot(NavigatorConfig(), scene)
    c = fitted.controller
    assert (c.max_speed, c.max_turn_rate) == (JACKAL_V, JACKAL_W)
    assert c.outline_clearance and (c.brake_decel, c.near_range) == (FIT_BRAKE_DECEL, FIT_NEAR_RANGE) == (2.5, 0.4)
    assert fitted.narrow_inflation == pytest.approx(JACKAL_HALF_WIDTH + 0.03)
    assert fit_to_robot(NavigatorConfig(fit_robot=False), scene).controller.max_speed == 0.5  # as given
    warehouse = gym.make("bulletnav/Warehouse-v0")
    try:
        warehouse.reset(seed=0)
        config = NavigatorConfig()
        assert fit_to_robot(config, warehouse.unwrapped.scene) is config  # the article robot: untouched
    finally:
        warehouse.close()


def test_outline_reach_and_braking_speed_by_hand(barn):
    scene = barn.unwrapped.scene
    angles = np.array([0.0, math.pi / 2, -math.pi / 2])
    reach = outline_reach(scene.geometry, angles)
    assert reach == pytest.approx([JACKAL_NOSE - LIDAR_X, JACKAL_HALF_WIDTH, JACKAL_HALF_WIDTH], abs=0.0021)
    cfg = fit_to_robot(NavigatorConfig(), scene).controller
    lidar = scene.sensors.lidar
    ctrl = GoToGoal(cfg, lidar.angles, scene.geometry)
    ranges = np.full(len(lidar.angles), 30.0)
    ahead = int(np.argmin(np.abs(lidar.angles)))
    ranges[ahead] = 1.0  # one hit 1 m out, 1.9 degrees off the axis
    x = LIDAR_X + math.cos(lidar.angles[ahead])
    expected = math.sqrt(2 * 2.5 * (x - JACKAL_NOSE - cfg.stop_distance))  # v^2 = 2 a d, braking at 2.5 m/s^2
    v, _ = ctrl.command((0.0, 0.0, 0.0), (10.0, 0.0), ranges, scene.control_dt, goal_distance=10.0)
    assert v == pytest.approx(expected, rel=1e-9)
    ranges[ahead] = 30.0
    v, _ = ctrl.command((0.0, 0.0, 0.0), (10.0, 0.0), ranges, scene.control_dt, goal_distance=10.0)
    assert v == pytest.approx(JACKAL_V, rel=1e-3)  # nothing ahead: the Jackal's top speed


def test_turn_guard_swings_the_jackals_corners_by_hand(barn):
    scene = barn.unwrapped.scene
    cfg = fit_to_robot(NavigatorConfig(), scene).controller
    ctrl = GoToGoal(cfg, scene.sensors.lidar.angles, scene.geometry)
    # turning clockwise by 0.2 rad swings the front-left corner (0.254, 0.215) to
    # (0.254 cos 0.2 + 0.215 sin 0.2, -0.254 sin 0.2 + 0.215 cos 0.2) = (0.292, 0.160): a hit at
    # (0.28, 0.16), 6 mm beyond the outline grown by 2 cm, is in its way; turning the other way
    # the corner moves back and left, away from it
    hit = np.array([[0.28, 0.16]])
    assert ctrl._turn_hits(hit, -1.0) and not ctrl._turn_hits(hit, 1.0)
    far = np.array([[0.40, 0.16]])  # the corner never gets past x = hypot(0.254, 0.215) = 0.333
    assert not ctrl._turn_hits(far, -1.0) and not ctrl._turn_hits(far, 1.0)


def test_a_turn_made_while_rolling_is_checked_along_the_roll(barn):
    """The hit at (0.40, 0.16) is out of the front-left corner's reach in place (above); rolling
    0.2 m forward while turning 0.35 rad clockwise, halfway (0.1 m along the heading -0.0875,
    turned 0.175 rad) the corner (0.254, 0.215) is at (0.0996 + 0.287, -0.0087 + 0.168) =
    (0.387, 0.159), 1.3 cm from the hit: within the guard's 2 cm margin. A navigator
    told to turn right there while still rolling at 0.45 m/s stops straight instead (BARN
    training worlds 271 and 283, seed 7100001: the rolling turn touched a cylinder)."""
    scene = barn.unwrapped.scene
    cfg = fit_to_robot(NavigatorConfig(), scene).controller
    ctrl = GoToGoal(cfg, scene.sensors.lidar.angles, scene.geometry)
    far = np.array([[0.40, 0.16]])
    assert not ctrl._turn_hits(far, -1.0) and ctrl._turn_hits(far, -1.0, roll=0.2)
    scan = _cylinder_scan(scene.sensors.lidar.angles, (0.30, -0.30))
    assert not ctrl._turn_hits(ctrl._near_points(scan), -1.0)
    assert ctrl._rolls_into(scan, -4.0, 0.45, 1 / 24) and not ctrl._rolls_into(scan, -4.0, 0.15, 1 / 24)


@pytest.mark.slow
@pytest.mark.parametrize("world", [271, 283])
def test_pid_astar_no_longer_turns_into_a_cylinder_while_rolling(world):
    """The two collisions of PID + A* on the 42 hard training worlds (seed 7100001): both end at the goal now."""
    env = gym.make("bulletnav/BARN-v0", world_idx=world, min_speed=-0.5)
    try:
        result = run_episodes(env, Navigator(env.unwrapped.scene, NavigatorConfig(planner="astar")), 1, seed=7100001)[0]
        assert result.success and not result.collision
    finally:
        env.close()


def _wall_scan(angles: np.ndarray, y: float) -> np.ndarray:
    """Ranges from the lidar at (LIDAR_X, 0) to the line y = ``y`` (a wall beside the robot), else 30 m."""
    sin = np.sin(angles)
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(sin * y > 0, y / sin, 30.0)
    return np.minimum(t, 30.0)


def test_the_avoidance_blend_turns_away_from_the_cylinder_in_the_way_not_toward_the_far_side(barn):
    """A cylinder 0.6 m ahead, its centre 0.12 m left of the axis (its nearest hits inside the
    corridor the Jackal's width sweeps), and a wall 0.6 m to the right: the rays on the right read
    short, so the article robot's rule (toward the side whose rays read farther) turns left, into
    the cylinder's side; the fitted Jackal (``avoid_side='away'``) turns right, away from it. The
    target dead ahead leaves the blend alone to decide (BARN test worlds 126 and 276, where the
    rule turned the robot onto the cylinder it was avoiding)."""
    scene = barn.unwrapped.scene
    angles = scene.sensors.lidar.angles
    scan = np.minimum(_cylinder_scan(angles, (0.6, 0.12)), _wall_scan(angles, -0.6))
    away = fit_to_robot(NavigatorConfig(), scene).controller
    assert away.avoid_side == "away"
    room = replace(away, avoid_side="room")
    args = ((0.0, 0.0, 0.0), (10.0, 0.0), scan, scene.control_dt, 10.0)
    assert GoToGoal(away, angles, scene.geometry)._corridor_hit(scan)[1] > 0.05  # the nearest hit: left of centre
    assert GoToGoal(away, angles, scene.geometry).command(*args)[1] < 0.0  # away: right
    assert GoToGoal(room, angles, scene.geometry).command(*args)[1] > 0.0  # toward the longer rays: left
    # a cylinder on the centre line has no side: the blend turns toward the target's
    centred = _cylinder_scan(angles, (0.6, 0.0))
    for target, sign in (((10.0, 1.0), 1.0), ((10.0, -1.0), -1.0)):
        w = GoToGoal(away, angles, scene.geometry).command((0.0, 0.0, 0.0), target, centred, scene.control_dt, 10.0)[1]
        assert math.copysign(1.0, w) == sign
    with pytest.raises(ValueError, match="avoid_side"):
        replace(away, avoid_side="left")


def test_a_guarded_turn_sent_the_long_way_round_goes_on_until_the_robot_faces_the_target(barn):
    """A cylinder at 0.4 m, 25 degrees left, blocks the clockwise turn (the front-left corner swings
    onto it) and not the counter-clockwise one. Asked to turn clockwise toward a target 2 rad off,
    the guard turns the other way and keeps turning that way as turn_first's turn, even once the
    cylinder is gone and clockwise is clear again: turned back at each step as the corners
    cleared, the robot rocked in place (BARN training world 271). A target under TURN_FIRST_RAD
    off is not committed to."""
    scene = barn.unwrapped.scene
    angles = scene.sensors.lidar.angles
    cfg = fit_to_robot(NavigatorConfig(), scene).controller
    blocked = _cylinder_scan(angles, (0.4 * math.cos(math.radians(25)), 0.4 * math.sin(math.radians(25))))
    clear = np.full(len(angles), 30.0)
    ctrl = GoToGoal(cfg, angles, scene.geometry)
    points = ctrl._near_points(blocked)
    assert ctrl._turn_hits(points, -1.0) and not ctrl._turn_hits(points, 1.0)
    v, w = ctrl._guard_turn(blocked, 0.05, -1.0, ahead=0.7, error=-2.0)
    assert w == 1.0 and ctrl._turning == 1.0
    behind_right = (-1.0, -1.5)  # 2.16 rad clockwise of the heading
    assert ctrl.turn_first((0.0, 0.0, 0.0), behind_right, clear)[1] > 0.0  # still the long way round
    assert GoToGoal(cfg, angles, scene.geometry).turn_first((0.0, 0.0, 0.0), behind_right, clear) is None
    small = GoToGoal(cfg, angles, scene.geometry)
    assert small._guard_turn(blocked, 0.05, -1.0, ahead=0.7, error=-0.5)[1] == 1.0 and small._turning == 0.0


def _cylinder_scan(angles: np.ndarray, centre: tuple[float, float], radius: float = 0.075) -> np.ndarray:
    """Ranges from the lidar at (LIDAR_X, 0) to one cylinder (ray-circle intersection), else 30 m."""
    ox, oy = LIDAR_X - centre[0], -centre[1]
    dx, dy = np.cos(angles), np.sin(angles)
    b = ox * dx + oy * dy
    disc = b * b - (ox * ox + oy * oy - radius * radius)
    t = -b - np.sqrt(np.maximum(disc, 0.0))
    return np.where((disc >= 0) & (t > 0), t, 30.0)


def test_shield_stops_the_jackal_by_its_own_sweep(barn):
    shield = shield_for(barn)
    assert (shield.v_max, shield.w_max) == (JACKAL_V, JACKAL_W)
    assert shield.geometry == barn.unwrapped.scene.geometry
    cfg, dt = shield.config, barn.unwrapped.scene.control_dt
    travel = JACKAL_V * dt + JACKAL_V**2 / (2 * cfg.decel)  # one period at 2 m/s, then braking at decel
    angles = shield.angles
    a = angles[int(np.argmin(np.abs(angles)))]  # the ray nearest the axis goes through the centre
    for slack, passes in ((0.02, True), (-0.02, False)):
        hit_x = JACKAL_NOSE + travel + cfg.margin + slack  # the cylinder's nearest point, body frame
        d = (hit_x - LIDAR_X) / math.cos(a) + 0.075
        ranges = _cylinder_scan(angles, (LIDAR_X + d * math.cos(a), d * math.sin(a)))
        decision = shield.filter(JACKAL_V, 0.0, JACKAL_V, ranges)
        assert decision.intervened is not passes
        if not passes:  # slower or swerving: a command whose own sweep misses the cylinder
            assert (decision.v, decision.w) != (JACKAL_V, 0.0) and decision.safe
            assert shield.check(decision.v, decision.w, JACKAL_V, shield.points(ranges))[0]


WALL = """name: wall
size: [12.0, 10.0]
start: [-4.0, 0.0, 0.0]
goal: [4.0, 0.0]
obstacles:
  - {type: box, center: [1.0, 0.0], size: [0.2, 8.0, 1.0], yaw: 0.0, label: wall}
"""


def test_shielded_jackal_at_full_speed_keeps_its_outline_off_a_wall(tmp_path):
    world = tmp_path / "wall.yaml"
    world.write_text(WALL)
    env = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", robot="jackal", world=str(world)))
    try:
        env.reset(seed=0)
        scene = env.unwrapped.scene
        full = scene.action_for(JACKAL_V, 0.0)
        top, closest = 0.0, math.inf
        corners = np.array([(sx * JACKAL_NOSE, sy * JACKAL_HALF_WIDTH) for sx in (-1, 1) for sy in (-1, 1)])
        for _ in range(80):  # 3.3 s: full speed east at the wall's face (x = 0.9), 4.6 m ahead of the nose
            _, _, terminated, truncated, info = env.step(full)
            top = max(top, float(scene.sensors.odometry.read()[3]))
            x, _, yaw = info["pose"][:3]
            front = x + corners[:, 0] * math.cos(yaw) - corners[:, 1] * math.sin(yaw)
            closest = min(closest, 0.9 - float(front.max()))
            assert not info["collision"] and not (terminated or truncated)
        assert top > 1.9  # it did reach the Jackal's speed
        # the Jackal's own corners stayed off the wall, within a shield margin of it (the article
        # robot's outline, 0.15 m long and 0.11 m wide, would have let them through)
        assert 0.0 < closest < 0.1
    finally:
        env.close()


def test_navigate_world_idx_drives_a_barn_training_world(capsys):
    assert main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", "40", "--episodes", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["world"] == "BARN world 40"
    episode = out["per_episode"][0]
    assert out["success_rate"] == 1.0 and out["collision_rate"] == 0.0
    assert episode["sim_time"] < 4 * 5.0  # under 4 t_opt (t_opt ~ 5 s): BARN's score >= 0.25


def test_navigate_on_barn_reports_barns_figures_per_episode_and_in_total(capsys):
    """``navigate`` on BARN-v0 shows BARN's clock, t_opt and metric per episode and report_test.py's
    line in total, in text and in --json; by hand: t_opt from report_test.py's start (-2, 3),
    metric = success x t_opt / clip(t, 2 t_opt, 8 t_opt)."""
    from bulletnav.barn import data, metric

    assert main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", "7", "--episodes", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    t_opt = metric.optimal_time(data.load_world(7).path_cells, metric.REPORT_START)
    rows = out["barn"]["per_episode"]
    assert len(rows) == 2
    for row, episode in zip(rows, out["per_episode"]):
        t = row["barn_time_s"]
        expect = (t_opt / min(max(t, 2 * t_opt), 8 * t_opt)) if episode["success"] else 0.0
        assert row["world_idx"] == 7 and row["t_opt_s"] == pytest.approx(t_opt, rel=1e-12)
        assert row["barn_metric"] == pytest.approx(expect, rel=1e-12)
    total = out["barn"]["summary"]
    assert total["metric"] == pytest.approx(sum(r["barn_metric"] for r in rows) / 2, rel=1e-12)
    assert total["line"].startswith("Avg Time: ") and "report_test.py's start (-2, 3)" in out["barn"]["metric"]
    assert main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", "7", "--episodes", "1"]) == 0
    text = capsys.readouterr().out
    assert "BARN world 7: clock " in text and f"t_opt {t_opt:.2f} s" in text
    assert "BARN (report_test.py) Avg Time: " in text and "BARN metric: success x t_opt" in text
    assert main(["navigate", "--episodes", "1", "--json"]) == 0
    assert "barn" not in json.loads(capsys.readouterr().out)  # a warehouse run has none


def test_world_idx_needs_barn_and_a_valid_index(capsys):
    assert main(["navigate", "--world-idx", "3", "--episodes", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--world-idx 3" in err and "bulletnav/BARN-v0" in err
    assert main(["evaluate", "--model", "models/ppo_barn.zip", "--env", "bulletnav/Warehouse-v0", "--world-idx", "test"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and "--world-idx test" in err and "bulletnav/BARN-v0" in err
    for given, needle in (("300", "expected a BARN world index, a whole number from 0 to 299, got 300"),
                          ("0,x", "got 'x'"), ("6,0,6", "names BARN world(s) [6] more than once"),
                          ("tests", "got 'tests'")):
        with pytest.raises(SystemExit):
            main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", given])
        err = capsys.readouterr().err.strip()
        assert needle in err and err.count("\n") == 0, (given, err)


def test_world_idx_several_worlds_run_in_turn_as_each_would_alone(capsys):
    """``--world-idx 0,6`` runs episode k on world k mod 2 with seed S + k, each episode the very
    one ``--world-idx W --seed S + k`` runs alone; ``test`` is BARN's 50 test worlds in order, for
    ``navigate`` and ``evaluate`` alike."""
    from bulletnav.barn.data import TEST_WORLDS

    assert main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", "0,6", "--seed", "4", "--episodes", "3",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["world"] == "BARN worlds 0, 6" and [r["world_idx"] for r in out["barn"]["per_episode"]] == [0, 6, 0]
    assert main(["navigate", "--env", "bulletnav/BARN-v0", "--world-idx", "6", "--seed", "5", "--episodes", "1",
                 "--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    same = {k: v for k, v in out["per_episode"][1].items() if k not in ("episode", "wall_time")}
    assert {k: v for k, v in alone["per_episode"][0].items() if k in same} == same and "seed" in same
    assert main(["evaluate", "--model", "models/ppo_barn.zip", "--world-idx", "test", "--episodes", "2", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["world"] == "BARN's 50 test worlds"
    assert [r["world_idx"] for r in out["barn"]["per_episode"]] == list(TEST_WORLDS[:2])


def test_navigator_reset_fits_each_episodes_robot(barn):
    nav = Navigator(barn.unwrapped.scene)
    _, info = barn.reset(seed=1)
    nav.reset(info)
    assert nav.config.controller.max_speed == JACKAL_V and nav.given == NavigatorConfig()
