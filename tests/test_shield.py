"""Safety shield: analytic cases on synthetic scans, the sweep against closed forms, a fuzz
test in cluttered worlds with movers (no contact with the shield on), the policy and env
wrappers on the same episodes, evaluation's intervention figures, the CLI's ``--shield``,
``train --shield``, the video tint, the dashboard line and ``bench shield``."""

from __future__ import annotations

import json
import math

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401
from bulletnav.cli import main
from bulletnav.config import asset_path
from bulletnav.control.shield import SafetyShield, Shield, ShieldConfig, ShieldWrapper
from bulletnav.evaluation import run_episodes, summarize
from bulletnav.geometry import robot_geometry
from bulletnav.sensors.lidar import ray_angles
from bulletnav.sim.movers import MoverView

ANGLES = ray_angles(36, 360.0)
GEOMETRY = robot_geometry()
OX = GEOMETRY.lidar_offset


def _shield() -> Shield:
    return Shield(GEOMETRY, ANGLES, 5.0, 1 / 24, 0.5, 1.5)


def _wall_ahead(distance: float) -> np.ndarray:
    """Ranges to a wall x = distance (body frame) across the robot's path."""
    c = np.cos(ANGLES)
    with np.errstate(divide="ignore"):
        r = np.where(c > 1e-6, (distance - OX) / c, 5.0)
    return np.minimum(r, 5.0)


def _box(cx: float, cy: float, half: float, n: int = 400) -> np.ndarray:
    """Ranges to a square box centred at (cx, cy) (body frame), ray-cast analytically."""
    r = np.full(len(ANGLES), 5.0)
    for k, a in enumerate(ANGLES):
        d = np.array([math.cos(a), math.sin(a)])
        o = np.array([OX, 0.0])
        lo, hi = -math.inf, math.inf
        for axis, c in ((0, cx), (1, cy)):
            if abs(d[axis]) < 1e-12:
                if abs(o[axis] - c) > half:
                    lo, hi = math.inf, -math.inf
                continue
            t1, t2 = (c - half - o[axis]) / d[axis], (c + half - o[axis]) / d[axis]
            lo, hi = max(lo, min(t1, t2)), min(hi, max(t1, t2))
        if lo <= hi and hi > 0:
            r[k] = min(r[k], max(lo, 0.0))
    return r


def test_a_wall_inside_the_stopping_sweep_stops_a_forward_command_and_one_just_beyond_does_not():
    """At 0.5 m/s the sweep is one control period at full speed plus the braking distance:
    0.5 / 24 + 0.5^2 / (2 x 1.5) = 0.104 m past the front face (0.15 m) and its 0.05 m margin:
    0.304 m from the centre, so a wall dead ahead at 0.3 m stops it."""
    reach = 0.15 + 0.05 + 0.5 / 24 + 0.5**2 / (2 * 1.5)
    shield = _shield()
    at_03 = shield.filter(0.5, 0.0, 0.5, _wall_ahead(0.3))  # the case: a wall dead ahead at 0.3 m
    assert at_03.intervened and (at_03.v, at_03.w) == (0.0, 0.0) and at_03.safe
    near = shield.filter(0.5, 0.0, 0.5, _wall_ahead(reach - 0.01))
    far = shield.filter(0.5, 0.0, 0.5, _wall_ahead(reach + 0.01))
    assert near.intervened and near.v == 0.0 and near.safe
    assert not far.intervened
    close = shield.filter(0.5, 0.0, 0.5, _wall_ahead(0.2))  # a wall 5 cm ahead: nothing forward is safe
    assert close.intervened and close.v == 0.0


def test_the_same_command_passes_unchanged_with_the_wall_3_m_away():
    d = _shield().filter(0.5, 0.0, 0.5, _wall_ahead(3.0))
    assert not d.intervened and (d.v, d.w) == (0.5, 0.0) and d.change == 0.0


def test_a_turn_that_sweeps_a_box_corner_is_vetoed_and_one_that_clears_it_is_not():
    ranges = _box(0.32, 0.27, 0.1)  # a box ahead-left: its near corner (0.22, 0.17) is beside the path
    shield = _shield()
    assert not shield.filter(0.5, 0.0, 0.5, ranges).intervened  # straight on passes it
    left = shield.filter(0.5, 1.5, 0.5, ranges)
    right = shield.filter(0.5, -1.5, 0.5, ranges)
    assert left.intervened and left.w < 1.5 and left.change > 0
    assert not right.intervened


def test_the_wrapper_reports_its_decision_and_passes_actions_bit_for_bit_when_clear():
    plain = gym.make("bulletnav/Warehouse-v0", world="bulletnav/assets/worlds/empty.yaml")
    shielded = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", world="bulletnav/assets/worlds/empty.yaml"))
    options = {"start": [0.0, 0.0, 0.0], "goal": [3.0, 3.0]}
    plain.reset(seed=0, options=options)
    _, info = shielded.reset(seed=0, options=options)
    assert info["shield"]["intervened"] is False
    for _ in range(20):
        a, _, _, _, _ = plain.step(np.array([0.3, 0.2]))
        b, _, _, _, info = shielded.step(np.array([0.3, 0.2]))
        assert not info["shield"]["intervened"]
        np.testing.assert_array_equal(a, b)
    plain.close()
    shielded.close()


def test_the_sweep_ends_where_the_closed_form_stop_does():
    """Straight: one control period at speed, then v^2 / (2 decel). On an arc of curvature
    w / v the end pose is (R sin th, R (1 - cos th), th) with th = w s / v."""
    shield = _shield()
    dt, decel = 1 / 24, ShieldConfig().decel
    s = 0.4 * dt + 0.4**2 / (2 * decel)
    poses, times = shield.sweep(0.4, 0.0, 0.4)
    np.testing.assert_allclose(poses[0, -1], (s, 0.0, 0.0), atol=1e-12)
    assert times[0, 1] == pytest.approx(dt) and times[0, -1] == pytest.approx(dt + 0.4 / decel)
    poses, _ = shield.sweep(0.4, 1.0, 0.4)
    th, radius = 1.0 * s / 0.4, 0.4 / 1.0
    np.testing.assert_allclose(poses[0, -1], (radius * math.sin(th), radius * (1 - math.cos(th)), th), atol=2e-4)
    # a turn in place slows at the rim deceleration: w dt + w^2 (b / 2) / (2 decel) in all
    poses, _ = shield.sweep(0.0, 1.5, 0.0)
    half = GEOMETRY.wheelbase / 2
    assert poses[0, -1, 2] == pytest.approx(1.5 * dt + 1.5**2 * half / (2 * decel), rel=1e-9)
    np.testing.assert_allclose(poses[0, :, :2], 0.0)


def test_turning_in_place_inside_the_margin_may_turn_away_from_a_wall_but_never_into_it():
    """The robot beside a wall (its wheels 2.8 cm off it, inside the 3 cm margin at rest):
    nothing is clear with the margin, so only a turn whose every pose keeps every corner of the
    bare outline at least 1.5 cm off the wall (checked analytically here) may pass."""
    wall_y = -(0.12 + 0.028)  # the wheels stick out to 0.12 m
    s = np.sin(ANGLES)
    with np.errstate(divide="ignore"):
        ranges = np.minimum(np.where(s < -1e-6, wall_y / s, 5.0), 5.0)
    shield = _shield()
    corners = np.array([(r.cx + sx * r.half_x, r.cy + sy * r.half_y) for r in GEOMETRY.rectangles
                        for sx in (-1, 1) for sy in (-1, 1)])
    turned = 0
    for w in (1.5, -1.5, 0.8, -0.8, 0.3, -0.3):
        d = shield.filter(0.3, w, 0.0, ranges, w_now=0.0, stuck=0.0)
        assert d.intervened and d.v == 0.0
        poses, _ = shield.sweep(d.v, d.w, 0.0, 0.0)
        for _x, y, yaw in poses[0]:
            world_y = y + np.sin(yaw) * corners[:, 0] + np.cos(yaw) * corners[:, 1]
            assert world_y.min() >= wall_y + 0.015
        turned += d.w != 0.0
    assert turned  # it does turn away when asked to move


def _fuzz(env, rng: np.random.Generator, driver: str, steps: int, clearances: list | None = None) -> tuple[int, int, int]:
    """(collisions, interventions, steps) of one episode of a random or a ramming driver; with
    ``clearances``, Shapely's clearance of the robot's outline after every step appended to it."""
    low, high = env.action_space.low, env.action_space.high
    hold, action, vetoed, n = 0, None, 0, 0
    for _ in range(steps):
        if driver == "random":
            action = rng.uniform(low, high).astype(np.float32)
        elif hold <= 0:  # full speed ahead on a held heading change, into whatever is there
            action = np.array([high[0], rng.uniform(low[1], high[1]) * rng.choice([0.0, 0.3, 1.0])], dtype=np.float32)
            hold = int(rng.integers(5, 60))
        hold -= 1
        _, _, terminated, truncated, info = env.step(action)
        n += 1
        vetoed += info["shield"]["intervened"]
        if clearances is not None:
            clearances.append(_clearance(env.unwrapped.scene))
        if info["collision"]:
            return 1, vetoed, n
        if terminated or truncated:
            break
    return 0, vetoed, n


@pytest.mark.slow
@pytest.mark.parametrize("env_id,kwargs", [
    ("bulletnav/Warehouse-v0", {"num_obstacles": 40}),
    ("bulletnav/WarehouseAisles-v0", {}),
    ("bulletnav/WarehouseDynamic-v0", {"forklift_speed": 1.0}),  # movers, events, fast forklifts
])
def test_fuzz_random_and_ramming_drivers_never_touch_anything_behind_the_shield(env_id, kwargs):
    env = ShieldWrapper(gym.make(env_id, **kwargs))
    try:
        collisions = vetoed = steps = 0
        clearances: list[float] = []
        for k in range(3):
            for driver in ("random", "ram"):
                env.reset(seed=4200 + k)
                c, v, n = _fuzz(env, np.random.default_rng(4200 + k), driver, 250, clearances)
                collisions, vetoed, steps = collisions + c, vetoed + v, steps + n
        assert collisions == 0
        assert vetoed > 0.05 * steps  # the drivers did push it: the shield acted often
        # and not only by PyBullet's contact report: Shapely finds the outline clear of everything after every step
        assert len(clearances) == steps and min(clearances) > 0.0, min(clearances)
    finally:
        env.close()


class _Ram:
    """A user's controller: full speed ahead, slowly turning left, whatever is in the way."""

    def reset(self, info):
        self.calls = 0

    def act(self, obs, info):
        self.calls += 1
        return np.array([0.5, 0.05], dtype=np.float32)


def test_the_policy_wrapper_and_the_env_wrapper_run_the_same_episodes_and_evaluation_counts_them():
    kwargs = {"num_obstacles": 40, "max_episode_steps": 300}
    by_policy = gym.make("bulletnav/Warehouse-v0", **kwargs)
    by_env = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", **kwargs))
    try:
        policy = SafetyShield(_Ram(), by_policy)
        a = run_episodes(by_policy, policy, 2, seed=7)
        b = run_episodes(by_env, _Ram(), 2, seed=7)
        assert policy.calls == policy.steps  # the wrapped policy's attributes show through
        for ra, rb in zip(a, b):
            assert (ra.steps, ra.path_length, ra.collision, ra.shield_steps) == (rb.steps, rb.path_length, rb.collision,
                                                                               rb.shield_steps)
            assert ra.shield_change == pytest.approx(rb.shield_change)
            assert not ra.collision and ra.shield_steps > 0  # it drove at the clutter and was stopped
        s = summarize(b)
        assert s["shield_rate"] == pytest.approx(sum(r.shield_steps for r in b) / sum(r.steps for r in b))
        assert s["shield_change_mean"] > 0
        plain = summarize(run_episodes(by_policy, _Ram(), 1, seed=7))
        assert plain["shield_rate"] == 0.0 and math.isnan(plain["shield_change_mean"]) and plain["collision_rate"] == 1.0
    finally:
        by_policy.close()
        by_env.close()


def test_navigate_and_evaluate_take_shield_and_report_it(capsys):
    assert main(["navigate", "--planner", "none", "--episodes", "2", "--obstacles", "40", "--seed", "11",
                 "--shield", "--json"]) == 0
    nav = json.loads(capsys.readouterr().out)
    assert nav["shield"] is True and 0.0 <= nav["shield_rate"] <= 1.0 and nav["collision_rate"] == 0.0
    assert main(["evaluate", "--model", "models/ppo_warehouse.zip", "--episodes", "1", "--shield"]) == 0
    out = capsys.readouterr().out
    assert ", shield)" in out and "Shield: replaced the command on" in out
    assert main(["evaluate", "--model", "models/ppo_warehouse.zip", "--episodes", "1", "--json"]) == 0
    plain = json.loads(capsys.readouterr().out)
    assert plain["shield"] is False and plain["shield_rate"] == 0.0


@pytest.mark.slow
def test_train_with_the_shield_in_the_loop_steps_every_training_step_through_it(tmp_path, capsys, monkeypatch):
    """``train --shield``: every step the learner takes goes through a ShieldWrapper, and the run
    records it. One env, --timesteps 256 and ppo.yml's n_steps of 512: one whole rollout, so
    512 training steps by hand, each a shield decision. (At 052a810 only the flag was checked.)"""
    stepped: dict[int, int] = {}  # steps per ShieldWrapper, in the order they were made
    real_step = ShieldWrapper.step

    def counting_step(self, action):
        stepped[id(self)] = stepped.get(id(self), 0) + 1
        obs, reward, terminated, truncated, info = real_step(self, action)
        assert {"intervened", "v", "w"} <= set(info["shield"])  # the decision reached the learner's info
        return obs, reward, terminated, truncated, info

    monkeypatch.setattr(ShieldWrapper, "step", counting_step)
    out = tmp_path / "run"
    assert main(["train", "--timesteps", "256", "--n-envs", "1", "--vec-env", "dummy", "--out", str(out),
                 "--eval-freq", "256", "--eval-episodes", "1", "--no-progress", "--shield"]) == 0
    record = json.loads((out / "run.json").read_text())
    assert record["shield"] is True and json.loads((out / "model.json").read_text())["shield"] is True
    assert record["total_timesteps"] == 512
    training, *evaluation = stepped.values()  # the training env is made before the evaluation env
    assert training == 512
    assert evaluation and all(n > 0 for n in evaluation)  # evaluated behind the shield too


def test_video_tints_the_robot_on_shielded_steps(tmp_path):
    from bulletnav.viz.video import ROBOT, SHIELD, EpisodeRecorder

    env = gym.make("bulletnav/Warehouse-v0", world=str(asset_path("worlds", "empty.yaml")))
    try:
        _, info = env.reset(seed=0)
        with EpisodeRecorder(tmp_path / "v.gif", shield=True) as rec:
            rec.on_reset(env, info)
            _, _, _, _, info = env.step(np.zeros(2, dtype=np.float32))
            rec.on_step(env, {**info, "shield": {"intervened": False, "change": 0.0}})
            calm = rec.last_frame[:480, :480].copy()
            rec.on_step(env, {**info, "shield": {"intervened": True, "change": 0.3}})
            vetoed = rec.last_frame[:480, :480].copy()
        def has(frame, colour):
            return bool(np.all(frame == np.array(colour, dtype=np.uint8), axis=-1).any())
        assert has(calm, ROBOT) and not has(calm, SHIELD)
        assert has(vetoed, SHIELD)
    finally:
        env.close()


def _outline(scene):
    """The robot's collision rectangles at its pose, as one Shapely geometry."""
    from shapely import box, union_all
    from shapely.affinity import rotate, translate

    x, y, yaw = scene.pose
    return union_all([translate(rotate(box(r.cx - r.half_x, r.cy - r.half_y, r.cx + r.half_x, r.cy + r.half_y), yaw,
                                       origin=(0, 0), use_radians=True), x, y) for r in scene.geometry.rectangles])


def _clearance(scene) -> float:
    """Shapely's distance (m) from the robot's outline to the nearest wall face, obstacle
    footprint, pallet added by an event and mover; 0 in contact."""
    from shapely import Point, box
    from shapely.affinity import rotate, translate

    def turned(cx, cy, sx, sy, yaw):
        return translate(rotate(box(-sx / 2, -sy / 2, sx / 2, sy / 2), yaw, origin=(0, 0), use_radians=True), cx, cy)

    robot = _outline(scene)
    hx, hy = scene.layout.size[0] / 2, scene.layout.size[1] / 2
    floor = box(-hx, -hy, hx, hy)
    if not floor.contains(robot):
        return 0.0
    gaps = [floor.exterior.distance(robot)]
    for o in scene.layout.obstacles:
        gaps.append(turned(*o.center, o.size[0], o.size[1], o.yaw).distance(robot) if o.kind == "box"
                    else max(0.0, Point(o.center).distance(robot) - o.radius))
    pallets = {}
    for e in scene.events:
        if e["action"] == "add":
            pallets[e["label"]] = turned(*e["center"], e["size"][0], e["size"][1], 0.0)
        else:
            pallets.pop(e["label"], None)
    gaps += [pallet.distance(robot) for pallet in pallets.values()]
    for m in scene.movers:
        gaps.append(turned(*m.pose[:2], m.size[0], m.size[1], m.pose[2]).distance(robot) if m.kind == "forklift"
                    else max(0.0, Point(m.pose[:2]).distance(robot) - m.size[0] / 2))
    return min(gaps)


def test_bench_shield_times_each_decision_and_its_drive_keeps_clear_by_shapely(capsys, monkeypatch):
    """``bench shield`` on a fake clock: a decision that passes the command costs 0.1 ms, one that
    replaces it 0.3 ms, an env step 2 ms; the figures must be those costs' statistics over the
    decisions the benchmark timed. Its ramming driver's "0 collisions" is checked with Shapely:
    after every step the robot's outline keeps clear of every wall, obstacle, added pallet and
    mover. (At 052a810 only plausibility: n, a positive mean, 0 collisions as reported.)"""
    import statistics
    import types

    from bulletnav.bench import shield_bench

    now = [0.0]
    decisions: list[bool] = []
    clearances: list[float] = []
    ends: list[bool] = []

    class CostedVeto(shield_bench.Veto):
        def __call__(self, action):
            action, decision = super().__call__(action)
            now[0] += 0.3e-3 if decision.intervened else 0.1e-3
            decisions.append(decision.intervened)
            return action, decision

    class Watched(gym.Wrapper):
        def step(self, action):
            now[0] += 2e-3
            obs, reward, terminated, truncated, info = self.env.step(action)
            clearances.append(_clearance(self.env.unwrapped.scene))
            if terminated or truncated:
                ends.append(bool(info["collision"]))
            return obs, reward, terminated, truncated, info

    monkeypatch.setattr(shield_bench, "time", types.SimpleNamespace(perf_counter=lambda: now[0]))
    monkeypatch.setattr(shield_bench, "Veto", CostedVeto)
    monkeypatch.setattr(shield_bench, "gym", types.SimpleNamespace(make=lambda *a, **k: Watched(gym.make(*a, **k))))
    assert main(["bench", "shield", "--steps", "150", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    timed = decisions[10:]  # the first ten calls are the benchmark's untimed warm-up
    assert len(timed) == 150 and len(clearances) == 150
    vetoed = sum(timed)
    assert vetoed > 0  # the ramming driver did make the shield act
    costs = [0.3 if v else 0.1 for v in timed]
    d = result["decision_ms"]
    assert d["n"] == 150 and d["mean"] == pytest.approx(statistics.fmean(costs))
    assert d["median"] == pytest.approx(statistics.median(costs)) and d["max"] == pytest.approx(max(costs))
    assert d["p99"] == pytest.approx(statistics.quantiles(costs, n=100, method="inclusive")[-1])
    assert result["decision_vetoed_ms"]["n"] == vetoed and result["decision_vetoed_ms"]["mean"] == pytest.approx(0.3)
    assert result["decision_passed_ms"]["n"] == 150 - vetoed and result["decision_passed_ms"]["mean"] == pytest.approx(0.1)
    assert result["env_step_ms"]["mean"] == pytest.approx(2.0)
    assert result["ratio_decision_to_env_step"] == pytest.approx(statistics.fmean(costs) / 2.0)
    assert result["intervention_rate"] == pytest.approx(vetoed / 150)
    assert result["collisions"] == sum(ends) == 0 and result["episodes"] == 1 + len(ends)
    assert min(clearances) > 0.0, min(clearances)


def test_bench_shield_drives_with_a_trained_model_and_times_its_creeps_apart(capsys):
    model = str(asset_path("..", "..", "models", "ppo_dynamic.zip"))
    assert main(["bench", "shield", "--driver", "policy", "--model", model, "--steps", "100", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    assert result["driver"] == "policy" and result["model"] == model and result["decision_ms"]["n"] == 100
    assert result["decision_creep_ms"]["n"] <= result["decision_vetoed_ms"]["n"]
    with pytest.raises(ValueError, match="--driver policy needs --model"):
        main(["bench", "shield", "--driver", "policy", "--steps", "10"])


@pytest.mark.gui
def test_dashboard_shows_the_shields_share_of_steps_in_a_static_world(display, drawn_texts):
    from bulletnav.viz.dashboard import Dashboard, DashboardConfig

    env = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", render_mode="human",
                                 world=str(asset_path("worlds", "empty.yaml"))))
    try:
        env.reset(seed=0, options={"start": [3.9, 0.0, 0.0], "goal": [-3.0, 0.0]})  # facing the wall 1 m ahead
        dash = Dashboard(env, DashboardConfig(camera_every=10_000))
        vetoed = 0
        steps = 6 * dash.config.lidar_every  # the line is redrawn with the lidar rays
        for _ in range(steps):
            _, _, _, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
            vetoed += info["shield"]["intervened"]
            dash.on_step(info=info)
        line = [t for t in drawn_texts if t.startswith("shield acted")][-1]
        assert vetoed > 0 and f"shield acted {100 * vetoed / steps:.1f} % of steps" in line
    finally:
        env.close()


def test_a_stop_always_passes_and_a_blocked_command_held_for_long_gets_turns_not_a_deadlock():
    """The front face 4 cm from a wall: every forward command sweeps into the margin, a slow
    turn in place (3 cm margin at rest) clears the corners."""
    shield = _shield()
    ranges = _wall_ahead(0.19)
    assert not shield.filter(0.0, 0.0, 0.0, ranges).intervened
    held = shield.filter(0.5, 0.0, 0.0, ranges)  # forward into it: stopped (first among equal changes)
    assert held.intervened and (held.v, held.w) == (0.0, 0.0)
    stuck = shield.filter(0.5, 0.0, 0.0, ranges, stuck=0.0)  # after patience: a turn in place instead
    assert stuck.intervened and stuck.v == 0.0 and stuck.w != 0.0 and stuck.safe
    assert shield.filter(0.5, 0.0, 0.0, ranges, stuck=-1.0).w < 0  # kept to the way it took
    assert shield.filter(0.5, 0.0, 0.0, ranges, stuck=1.0).w > 0


def _passage(worker: tuple[float, float], wall_y: float, radius: float = 0.25) -> np.ndarray:
    """Ranges to a wall y = ``wall_y`` on the left and a worker's cylinder (centre ``worker``,
    body frame) on the right, ray-cast analytically."""
    r = np.full(len(ANGLES), 5.0)
    o = np.array([OX, 0.0])
    c = np.asarray(worker)
    for k, a in enumerate(ANGLES):
        d = np.array([math.cos(a), math.sin(a)])
        if d[1] > 1e-9:
            r[k] = min(r[k], wall_y / d[1])
        b = float(np.dot(d, o - c))
        disc = b * b - float(np.dot(o - c, o - c)) + radius**2
        if disc >= 0 and -b - math.sqrt(disc) > 0:
            r[k] = min(r[k], -b - math.sqrt(disc))
    return r


def _worker(x: float, y: float, yielding: bool) -> MoverView:
    return MoverView("worker", (x, y, 0.0), 0.0, (0.5, 0.5, 1.7), ((x, y), (x + 5.0, y)), yielding, -1)


def _gap_to(poses: np.ndarray, worker: tuple[float, float], wall_y: float, radius: float = 0.25) -> float:
    """The smallest distance (m) from the robot's collision rectangles at ``poses`` (K, 3) to
    the wall and the worker's circle, by closed form (point-to-rectangle, not the shield's code)."""
    gap = math.inf
    for x, y, yaw in poses:
        c, s = math.cos(yaw), math.sin(yaw)
        # the worker's centre in the pose's frame: distance to each rectangle, less the radius
        dx, dy = worker[0] - x, worker[1] - y
        bx, by = c * dx + s * dy, -s * dx + c * dy
        for r in GEOMETRY.rectangles:
            ex = max(abs(bx - r.cx) - r.half_x, 0.0)
            ey = max(abs(by - r.cy) - r.half_y, 0.0)
            gap = min(gap, math.hypot(ex, ey) - radius)
            # the wall: the rectangle's highest corner
            top = max(y + s * (r.cx + sx * r.half_x) + c * (r.cy + sy * r.half_y) for sx in (-1, 1) for sy in (-1, 1))
            gap = min(gap, wall_y - top)
    return gap


@pytest.mark.parametrize("side", [0.149, 0.145])
def test_stuck_beside_a_waiting_worker_it_creeps_through_the_gap_without_coming_closer(side):
    """A passage 2.9 cm (or 2.5 cm) wider than the robot's wheels on each side: a wall on
    the left, a worker yielding to the robot on the right. A worker that yields waits while the
    robot stands near, so standing is a deadlock; stuck, the shield lets the forward command
    pass at the creep speed, and its sweep comes no closer to either side (closed-form
    distances) than the robot already is. The same worker walking on (not
    yielding): no creep, the shield holds the robot."""
    shield = _shield()
    worker = (0.0, -(side + 0.25))  # its surface as far right of the wheels as the wall is left of them
    ranges = _passage(worker, side)
    now = _gap_to(np.zeros((1, 3)), worker, side)
    assert 0.02 < now < 0.03  # inside the at-rest margin: nothing normal is clear
    for stuck in (None, 0.0):  # not yet stuck, or stuck beside a worker that walks on: no creep
        d = shield.filter(0.5, 0.0, 0.0, ranges, [_worker(*worker, yielding=stuck is None)], stuck=stuck)
        assert d.intervened and d.v == 0.0 and not d.creep
    d = shield.filter(0.5, 0.0, 0.0, ranges, [_worker(*worker, yielding=True)], stuck=0.0)
    assert d.intervened and d.creep and d.safe and d.v == ShieldConfig().creep_speed
    poses, _ = shield.sweep(d.v, d.w, 0.0, 0.0)
    assert _gap_to(poses[0], worker, side) >= now - 1e-4  # no closer to either side than it was
    assert ShieldConfig(creep_speed=0.0).creep_speed == 0.0
    off = Shield(GEOMETRY, ANGLES, 5.0, 1 / 24, 0.5, 1.5, ShieldConfig(creep_speed=0.0))
    assert not off.filter(0.5, 0.0, 0.0, ranges, [_worker(*worker, yielding=True)], stuck=0.0).creep


@pytest.mark.parametrize("ahead", [0.028, 0.015])
def test_it_never_creeps_toward_a_waiting_worker_dead_ahead(ahead):
    """The worker 2.8 cm (1.5 cm) ahead of the front face: every forward creep would come
    closer to it than the robot is, so none is taken (a turn in place or the stop)."""
    shield = _shield()
    worker = (0.15 + ahead + 0.25, 0.0)
    ranges = _passage(worker, 5.0)
    d = shield.filter(0.5, 0.0, 0.0, ranges, [_worker(*worker, yielding=True)], stuck=0.0)
    assert d.intervened and d.v == 0.0


def test_the_veto_becomes_stuck_after_patience_steps_and_forgets_at_reset():
    env = ShieldWrapper(gym.make("bulletnav/Warehouse-v0", world=str(asset_path("worlds", "empty.yaml"))))
    patience = ShieldConfig().patience
    try:
        options = {"start": [3.5, 0.0, 0.0], "goal": [-3.0, 0.0]}  # facing the wall 1.5 m ahead
        env.reset(seed=0, options=options)
        sent = []
        for _ in range(120):  # a controller that only ever asks for full speed ahead
            _, _, _, _, info = env.step(np.array([0.5, 0.0], dtype=np.float32))
            assert not info["collision"]
            sent.append((info["shield"]["v"], info["shield"]["w"]) if info["shield"]["intervened"] else None)
        first = next(i for i, s in enumerate(sent) if s is not None and s[0] == 0.0 and s[1] != 0.0)
        assert first >= patience and all(s is not None and s[0] == 0.0 for s in sent[first - patience:first])
        run, runs = [], []  # the turns of each stretch held still, one way each: no dithering
        for s in sent[first:]:
            if s is not None and s[0] == 0.0:
                run.append(np.sign(s[1]))
            elif run:
                runs.append(run)
                run = []
        runs.append(run)
        assert all(len(set(r) - {0.0}) <= 1 for r in runs)
        env.reset(seed=0, options=options)
        assert env._veto.held == 0 and env._veto.escape == 0.0
    finally:
        env.close()


def _polygon_ranges(vertices: np.ndarray) -> np.ndarray:
    """Ranges from the lidar to a convex polygon (body frame), ray-cast analytically."""
    r = np.full(len(ANGLES), 5.0)
    o = np.array([OX, 0.0])
    for k, a in enumerate(ANGLES):
        d = np.array([math.cos(a), math.sin(a)])
        for p0, p1 in zip(vertices, np.roll(vertices, -1, axis=0)):
            e = p1 - p0
            den = d[0] * -e[1] - d[1] * -e[0]
            if abs(den) < 1e-12:
                continue
            w = p0 - o
            t = (w[0] * -e[1] - w[1] * -e[0]) / den
            u = (d[0] * w[1] - d[1] * w[0]) / den
            if t > 0 and 0 <= u <= 1:
                r[k] = min(r[k], t)
    return r


@pytest.mark.parametrize("bearing_deg, distance", [(5.0, 0.35), (-125.0, 0.25), (93.0, 0.6)])
def test_a_box_corner_between_two_rays_is_rebuilt(bearing_deg, distance):
    # A square box (0.5 m) turned so that a corner points at the lidar, between two rays: the
    # straight join of the two nearest hits cuts the corner off by a centimetre or more; the
    # rebuilt scan has the corner itself.
    bearing = math.radians(bearing_deg)
    u = np.array([math.cos(bearing), math.sin(bearing)])
    corner = np.array([OX, 0.0]) + distance * u
    n = np.array([-u[1], u[0]])
    h = 0.5 / math.sqrt(2)
    vertices = np.array([corner, corner + h * (u + n), corner + 2 * h * u, corner + h * (u - n)])
    ranges = _polygon_ranges(vertices)
    points = _shield().points(ranges, fill=0.01)
    assert np.hypot(*(points - corner).T).min() < 1e-6
    # the two hits either side of the corner, and how far their straight join passes from it
    k = int(np.argmin(np.abs(np.angle(np.exp(1j * (ANGLES - bearing))))))
    k2 = k + 1 if math.remainder(bearing - ANGLES[k], 2 * math.pi) > 0 else k - 1
    a_, b_ = (np.array([OX + ranges[i] * math.cos(ANGLES[i]), ranges[i] * math.sin(ANGLES[i])]) for i in (k, k2 % 36))
    t = np.clip(np.dot(corner - a_, b_ - a_) / np.dot(b_ - a_, b_ - a_), 0, 1)
    assert np.hypot(*(a_ + t * (b_ - a_) - corner)) > 0.004
    # every point lies on the box's boundary (none in front of it)
    centre = corner + h * u
    assert np.all(np.abs(np.dot(points - centre, u)) + np.abs(np.dot(points - centre, n)) <= h + 1e-6)


@pytest.mark.slow
def test_a_shielded_episode_among_movers_reproduces_the_committed_result_to_the_bit(capsys):
    """Seed 1158 of the dynamic policy behind the shield (the table in docs/shield.md): the shield replaced
    the command on 1,185 of its 2,399 steps, and it reached its goal by creeping past a mover
    that waited for it (before the creep it timed out, `before_creep/`). The episode replayed
    now must match the committed one exactly, so the compiled geometry (scan points, sweeps,
    the hit test) and the creep decide as the code that produced the table did."""
    path = asset_path("..", "..", "docs", "results", "shield", "ppo_dynamic_shield_dynamic.json")
    want = next(e for e in json.loads(open(path).read())["per_episode"] if e["seed"] == 1158)
    assert want["shield_steps"] > 1000 and want["success"]
    model = asset_path("..", "..", "models", "ppo_dynamic.zip")
    assert main(["evaluate", "--model", str(model), "--env", "bulletnav/WarehouseDynamic-v0", "--episodes", "1",
                 "--seed", "1158", "--shield", "--json"]) == 0
    (got,) = json.loads(capsys.readouterr().out)["per_episode"]
    for key in ("steps", "reward", "path_length", "final_distance", "shield_steps", "shield_change", "near_miss_steps",
                "success", "collision"):
        assert got[key] == want[key], key


def test_with_a_creep_floor_it_does_not_creep_along_a_gap_narrower_than_the_floor():
    """A passage 1.5 cm wider than the robot on each side (wall left, yielding worker right):
    without a floor the stuck robot creeps along it (its clearance kept); with the fleet's
    floor of 2 cm a creep must also end 1 cm farther from both sides, which no forward creep
    between two parallel sides does, so the shield holds the robot instead: a creep's
    millimetres of error can no longer walk it into a side."""
    from bulletnav.fleet.controllers import FLEET_SHIELD

    assert FLEET_SHIELD.creep_floor == ShieldConfig().close_margin == 0.02
    side = 0.135
    worker = (0.0, -(side + 0.25))
    ranges = _passage(worker, side)
    now = _gap_to(np.zeros((1, 3)), worker, side)
    assert 0.005 < now < 0.02
    movers = [_worker(*worker, yielding=True)]
    d = _shield().filter(0.5, 0.0, 0.0, ranges, movers, stuck=0.0)
    assert d.creep and d.v > 0.0  # the floorless rule: no closer than now is enough
    floored = Shield(GEOMETRY, ANGLES, 5.0, 1 / 24, 0.5, 1.5, FLEET_SHIELD)
    d = floored.filter(0.5, 0.0, 0.0, ranges, movers, stuck=0.0)
    assert not d.creep and d.v == 0.0
    with pytest.raises(ValueError, match="creep_floor"):
        ShieldConfig(creep_floor=-0.01)


def test_nearer_than_the_floor_it_still_creeps_away_from_what_it_is_near():
    """A wall 1 cm behind the robot's rear face and a worker yielding 20 cm ahead: inside the
    margin, nothing normal passes; with the fleet's floor the stuck robot may creep forward,
    since that ends at least 5 mm farther from the wall (closed form) and no closer to the worker."""
    from bulletnav.fleet.controllers import FLEET_SHIELD

    rear = min(r.cx - r.half_x for r in GEOMETRY.rectangles)
    front = max(r.cx + r.half_x for r in GEOMETRY.rectangles)
    wall_x = rear - 0.01
    worker = (front + 0.20 + 0.25, 0.0)
    ranges = _passage(worker, 5.0)
    for k, a in enumerate(ANGLES):  # the wall x = wall_x behind, ray-cast from the lidar
        if math.cos(a) < -1e-9:
            ranges[k] = min(ranges[k], (wall_x - OX) / math.cos(a))
    floored = Shield(GEOMETRY, ANGLES, 5.0, 1 / 24, 0.5, 1.5, FLEET_SHIELD)
    d = floored.filter(0.5, 0.0, 0.0, ranges, [_worker(*worker, yielding=True)], stuck=0.0)
    assert d.intervened and d.creep and d.v > 0.0
    poses, _ = floored.sweep(d.v, d.w, 0.0, 0.0)
    end = poses[0, -1]
    corners = [end[0] + math.cos(end[2]) * (r.cx + sx * r.half_x) - math.sin(end[2]) * (r.cy + sy * r.half_y)
               for r in GEOMETRY.rectangles for sx in (-1, 1) for sy in (-1, 1)]
    assert min(corners) - wall_x >= 0.01 + 0.005 - 1e-4  # 5 mm farther from the wall, by closed form
