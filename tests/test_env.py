"""The Gymnasium env: API checks, determinism, reward bookkeeping and episode rules."""

from __future__ import annotations

import json
import math
import os
import re
import shutil
import subprocess
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import shapely
from gymnasium.utils.env_checker import check_env as gym_check_env
from stable_baselines3.common.env_checker import check_env as sb3_check_env

import bulletnav  # noqa: F401  (registers the env)
import hang
from bulletnav.bench.env_bench import bench_env
from bulletnav.cli import main
from bulletnav.config import EnvConfig, ImuConfig, LidarConfig, OdometryConfig, SensorsConfig, asset_path
from bulletnav.errors import DisplayError
from bulletnav.geometry import robot_geometry
from bulletnav.sim.client import _xlib
from bulletnav.sim.generators import WORLDS
from bulletnav.tasks import TASKS, NavigationTask
from conftest import _xvfb, bit_equal

ENV_ID = "bulletnav/Warehouse-v0"
ACTION_SPACE_ADVICE = ("symmetric and normalized", "symmetric and normalized Box action space")
WRAPPED_ADVICE = "using the raw environment for `check_env`"


def _all_warnings(fn) -> list[str]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        fn()
    return [str(w.message) for w in caught]


@pytest.fixture
def make_env():
    envs = []

    def _make(**kwargs):
        env = gym.make(ENV_ID, **kwargs)
        envs.append(env)
        return env

    yield _make
    for env in envs:
        env.close()


def test_spaces_match_the_article(make_env):
    env = make_env()
    assert env.observation_space.shape == (43,) and env.observation_space.dtype == np.float32
    np.testing.assert_array_equal(env.action_space.low, [0.0, -1.5])
    np.testing.assert_array_equal(env.action_space.high, [0.5, 1.5])
    assert env.spec.max_episode_steps == 1000
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    u = env.unwrapped
    scene = u.scene
    assert len(u._scene.sim.world.obstacle_ids) == 31 and len(scene.layout.obstacles) == 31
    assert set(scene.sensors.present()) == {"lidar", "camera", "imu", "odometry"}
    assert u.task.reward_terms == NavigationTask.reward_terms
    assert len(u.task.reward_terms) == 7
    for name in u.task.reward_terms:
        assert info[f"reward_{name}"] == 0.0
    assert info["end_reason"] is None
    # Observation entries against their sources (the live PyBullet pose, not the view's snapshot).
    x, y, yaw = u._scene.robot.pose()
    assert scene.pose == (x, y, yaw)
    np.testing.assert_array_equal(info["pose"], scene.pose)
    np.testing.assert_allclose(scene.start, scene.pose, atol=1e-9)  # placed at rest where it starts
    gx, gy = info["goal"]
    assert scene.goal == (gx, gy) and scene.goals == ((gx, gy),)
    assert obs[42] == pytest.approx(math.hypot(gx - x, gy - y) / 10, abs=1e-6)
    assert obs[36] * math.pi == pytest.approx(math.remainder(math.atan2(gy - y, gx - x) - yaw, 2 * math.pi), abs=1e-5)
    np.testing.assert_allclose(obs[:36], scene.sensors.lidar.read() / 5.0, atol=1e-6)


@pytest.mark.gui
@pytest.mark.slow
@pytest.mark.parametrize("render_mode", [None, "rgb_array"])
def test_checkers_pass_without_warnings_with_normalized_actions(make_env, display, render_mode):
    env = make_env(normalize_actions=True, render_mode=render_mode)
    # Gymnasium's render check also builds a "human" env (hence the display).
    assert _all_warnings(lambda: gym_check_env(env.unwrapped)) == []
    assert _all_warnings(lambda: sb3_check_env(env)) == []
    assert _all_warnings(lambda: sb3_check_env(env.unwrapped)) == []
    # On the made env Gymnasium adds only its advice to check the raw env instead.
    assert all(WRAPPED_ADVICE in w for w in _all_warnings(lambda: gym_check_env(env, skip_render_check=True)))


@pytest.mark.gui
@pytest.mark.slow
def test_checkers_pass_in_human_mode(make_env, display):
    env = make_env(normalize_actions=True, render_mode="human")
    # PyBullet allows one GUI connection per process, and Gymnasium's render and close
    # checks open a second env from the spec; the render check of "human" ran above.
    assert _all_warnings(lambda: gym_check_env(env.unwrapped, skip_render_check=True, skip_close_check=True)) == []
    assert _all_warnings(lambda: sb3_check_env(env)) == []


def test_physical_action_space_draws_only_the_normalisation_advice(make_env):
    """The article's action box exceeds [-1, 1], which both checkers advise against; nothing else."""
    env = make_env()
    caught = _all_warnings(lambda: (gym_check_env(env.unwrapped, skip_render_check=True), sb3_check_env(env)))
    assert len(caught) == 2
    assert all(any(a in w for a in ACTION_SPACE_ADVICE) for w in caught)


def test_rgb_array_render(make_env):
    env = make_env(render_mode="rgb_array")
    env.reset(seed=1)
    frame = env.render()
    assert frame.shape == (360, 480, 3) and frame.dtype == np.uint8 and frame.std() > 5


def test_human_mode_without_display_raises_clearly(monkeypatch):
    monkeypatch.delenv("DISPLAY", raising=False)
    with pytest.raises(DisplayError, match="needs an X display.*xvfb-run"):
        gym.make(ENV_ID, render_mode="human")
    monkeypatch.setenv("DISPLAY", ":987")  # nothing listens there
    with pytest.raises(DisplayError, match="does not answer"):
        gym.make(ENV_ID, render_mode="human")


def _free_display(first: int, last: int) -> int:
    """A display number in [first, last) that no X server holds (no lock file)."""
    return next(n for n in range(first, last) if not Path(f"/tmp/.X{n}-lock").exists())


@pytest.mark.skipif(shutil.which("Xvfb") is None or shutil.which("xauth") is None or _xlib() is None,
                    reason="needs Xvfb, xauth and libX11")
def test_human_mode_on_a_display_that_refuses_the_connection_raises_clearly(tmp_path, monkeypatch):
    """An X server whose socket answers but which refuses this process (a wrong authority, as
    when two servers or cookies get mixed up) is a DisplayError naming it, not PyBullet's GUI
    thread calling exit() and the process hanging on it."""
    from bulletnav.sim.client import display_accepts, display_available

    number = _free_display(170, 400)
    server_auth, other_auth = tmp_path / "server", tmp_path / "other"
    for path, cookie in ((server_auth, "0123456789abcdef0123456789abcdef"), (other_auth, "fedcba9876543210fedcba9876543210")):
        path.touch()
        subprocess.run(["xauth", "-f", str(path), "add", f":{number}", ".", cookie], check=True, capture_output=True)
    with _xvfb(number, "-auth", str(server_auth)):
        monkeypatch.setenv("DISPLAY", f":{number}")
        monkeypatch.setenv("XAUTHORITY", str(server_auth))
        assert display_accepts()  # the right cookie: Xlib opens it
        monkeypatch.setenv("XAUTHORITY", str(other_auth))
        assert display_available() and not display_accepts(tries=2, pause_s=0.05)
        with pytest.raises(DisplayError, match=f"DISPLAY=':{number}' answers but refused the connection"):
            gym.make(ENV_ID, render_mode="human")


class _FakeXlib:
    """Stands in for libX11: records the calls, in order, in ``calls``."""

    def __init__(self, calls: list[str], refuse: int = 0) -> None:
        self.calls, self.refuse = calls, refuse

    def XOpenDisplay(self, name):  # noqa: N802 (Xlib's name)
        self.calls.append("XOpenDisplay")
        if self.refuse:
            self.refuse -= 1
            return None
        return 1234

    def XCloseDisplay(self, handle):  # noqa: N802
        assert handle == 1234
        self.calls.append("XCloseDisplay")


@pytest.mark.parametrize("gui_connects", [True, False])
def test_gui_connect_holds_its_own_x_connection_until_pybullet_has_opened_one(monkeypatch, gui_connects):
    """An X server resets when its last client leaves and refuses clients meanwhile, and
    PyBullet's GUI thread calls exit() when it is refused: so the library's own connection to
    the display, tried again while refused, stays open until PyBullet's connect has returned
    (and is closed however that ends)."""
    import pybullet

    from bulletnav.sim import client

    calls: list[str] = []
    fake = _FakeXlib(calls, refuse=2)  # a server still resetting refuses the first two tries

    def gui_connect(mode, options=""):
        assert mode == pybullet.GUI
        calls.append("pybullet.connect")
        if not gui_connects:
            raise RuntimeError("the GUI failed")
        return 7

    monkeypatch.setattr(client, "_xlib", lambda: fake)
    monkeypatch.setattr(client, "display_available", lambda display=None: True)
    monkeypatch.setattr(client, "X_OPEN_PAUSE_S", 0.0)
    monkeypatch.setattr(client.p, "connect", gui_connect)
    if gui_connects:
        assert client.connect(gui=True) == 7
    else:
        with pytest.raises(RuntimeError, match="the GUI failed"):
            client.connect(gui=True)
    assert calls == ["XOpenDisplay"] * 3 + ["pybullet.connect", "XCloseDisplay"]


@pytest.mark.slow
@pytest.mark.skipif(shutil.which("Xvfb") is None or _xlib() is None, reason="needs Xvfb and libX11")
def test_a_held_x_connection_keeps_a_resetting_server_from_refusing_clients(report):
    """The premise of the hold above, on a real Xvfb started as `xvfb-run` starts it (it resets
    when its last client leaves): a client that connects right after another left is refused
    now and then, and never while a connection is held open."""
    import socket

    from bulletnav.sim.client import _open_display

    lib = _xlib()
    number = _free_display(400, 600)
    name = f":{number}".encode()

    def refused_after_a_probe(cycles: int) -> int:
        refused = 0
        for _ in range(cycles):
            with socket.socket(socket.AF_UNIX, socket.SOCK_STREAM) as probe:  # display_available's check
                probe.connect(f"/tmp/.X11-unix/X{number}")
            for _ in range(2):  # a client that comes and goes, then one right after it
                handle = lib.XOpenDisplay(name)
                if not handle:
                    refused += 1
                    time.sleep(0.2)  # let the reset end
                    break
                lib.XCloseDisplay(handle)
        return refused

    with _xvfb(number):
        held = _open_display(f":{number}", tries=100, pause_s=0.05)
        assert held is not None, "the fresh Xvfb never accepted a client"
        try:
            assert refused_after_a_probe(60) == 0
        finally:
            held.close()
        time.sleep(0.5)
        report("clients refused in 60 probe cycles, a connection held / none held",
               f"0 / {refused_after_a_probe(60)}")


def _shapely_scan(layout, pose, num_rays: int = 36, max_range: float = 5.0) -> np.ndarray:
    """The ranges a noise-free 360 deg lidar should read at ``pose``, by Shapely: rays from the
    lidar mount (``lidar_mount`` ahead of the centre) to their first crossing of a wall's inner
    face or an obstacle footprint's outline (every obstacle stands taller than the mount)."""
    hx, hy = layout.half_extents
    outlines = [shapely.box(-hx, -hy, hx, hy).exterior]
    for o in layout.obstacles:
        if o.kind == "box":
            sx, sy = o.size[0] / 2, o.size[1] / 2
            shape = shapely.affinity.rotate(shapely.box(-sx, -sy, sx, sy), o.yaw, origin=(0, 0), use_radians=True)
            outlines.append(shapely.affinity.translate(shape, *o.center).exterior)
        else:
            outlines.append(shapely.Point(o.center).buffer(o.radius, quad_segs=256).exterior)
    edges = shapely.union_all(outlines)
    x, y, yaw = pose
    mount = robot_geometry().lidar_mount[0]
    ox, oy = x + mount * math.cos(yaw), y + mount * math.sin(yaw)
    out = []
    for k in range(num_rays):
        a = yaw + 2 * math.pi * k / num_rays
        ray = shapely.LineString([(ox, oy), (ox + max_range * math.cos(a), oy + max_range * math.sin(a))])
        hit = ray.intersection(edges)
        out.append(max_range if hit.is_empty else shapely.Point(ox, oy).distance(hit))
    return np.array(out)


def _rollout(seed: int, steps: int = 300):
    env = gym.make(ENV_ID, lidar_noise=0.02)
    env.action_space.seed(seed)
    trace = []
    obs, info = env.reset(seed=seed)
    resets = 0
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample())
        trace.append((obs, reward, terminated, truncated, info))
        if terminated or truncated:
            obs, info = env.reset()
            resets += 1
            trace.append((obs, info))
    layout = env.unwrapped.scene.layout
    env.close()
    return trace, resets, layout


def test_same_seed_is_bit_identical_across_resets():
    a, resets_a, layout_a = _rollout(seed=3)
    b, resets_b, layout_b = _rollout(seed=3)
    assert resets_a >= 2, "the rollout should span several episodes"
    assert resets_a == resets_b and layout_a == layout_b
    assert bit_equal(a, b)
    # Against the formulas: each episode's path length is the sum of the straight segments
    # between the true poses it passed, and a reset's initial distance the Euclidean one.
    length, last = 0.0, None
    for entry in a:
        info = entry[-1]
        if len(entry) == 2:  # a reset
            (x, y, _), (gx, gy) = info["pose"], info["goal"]
            assert info["initial_distance"] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
            length, last = 0.0, info["pose"]
            continue
        if last is not None:  # from the first reset in the trace on
            length += math.hypot(info["pose"][0] - last[0], info["pose"][1] - last[1])
            assert info["path_length"] == pytest.approx(length, abs=1e-9)
            last = info["pose"]
    _, _, layout_c = _rollout(seed=4, steps=1)
    assert layout_c != layout_a


def test_seeded_reset_is_independent_of_history(make_env):
    env = make_env()
    first, info = env.reset(seed=11)
    # The seeded reset's scan against Shapely's ray cast on the layout, from the placed pose.
    np.testing.assert_allclose(first[:36] * 5.0, _shapely_scan(env.unwrapped.scene.layout, info["pose"]), atol=2e-3)
    for _ in range(30):
        env.step(env.action_space.sample())
    again, _ = env.reset(seed=11)
    np.testing.assert_array_equal(first, again)
    step_a = env.step(np.array([0.3, 0.2], dtype=np.float32))[0]
    env.reset(seed=11)
    step_b = env.step(np.array([0.3, 0.2], dtype=np.float32))[0]
    np.testing.assert_array_equal(step_a, step_b)


# Env settings for the property tests over random rollouts, each with its own rollout seed
# (the same seed would drive the normalized env along the default env's path).
ROLLOUT_SETTINGS = {
    "default": ({}, 5),
    "normalized": ({"normalize_actions": True}, 6),
    "odometry-pose-noisy": ({"pose_source": "odometry", "lidar_noise": 0.05, "odometry_noise": 0.01}, 7),
}


def _random_rollout(env, steps: int, seed: int):
    """``steps`` uniform random actions from ``np.random.default_rng(seed)``, reaching 25 %
    past each bound of the action box (clipped by the env); a new episode at every end.
    Yields ``(obs, reward, terminated, truncated, info)``, the reset's with reward None."""
    rng = np.random.default_rng(seed)
    low, high = env.action_space.low, env.action_space.high
    pad = 0.25 * (high - low)
    obs, info = env.reset(seed=seed)
    yield obs, None, False, False, info
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(low - pad, high + pad).astype(np.float32))
        yield obs, reward, terminated, truncated, info
        if terminated or truncated:
            obs, info = env.reset()
            yield obs, None, False, False, info


@pytest.mark.parametrize("setting", ROLLOUT_SETTINGS)
def test_reward_terms_sum_to_the_reward(make_env, setting):
    kwargs, seed = ROLLOUT_SETTINGS[setting]
    env = make_env(**kwargs)
    names = env.unwrapped.task.reward_terms
    odometry_pose = kwargs.get("pose_source") == "odometry"
    seen, steps, ends = set(), 0, 0
    before = None
    for obs, reward, terminated, truncated, info in _random_rollout(env, 1000, seed=seed):
        terms = [info[f"reward_{name}"] for name in names]
        if reward is None:  # a reset: every term starts at zero
            assert terms == [0.0] * len(names)
            before = info["distance_to_goal"]
            continue
        # Each term against the article's weights and formulas, from the step's own info and
        # observation (the distance from the true pose where the task uses it).
        t = dict(zip(names, terms))
        (x, y, yaw), (gx, gy) = info["pose"], info["goal"]
        distance = info["distance_to_goal"]
        if not odometry_pose:
            assert distance == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
            heading = math.remainder(math.atan2(gy - y, gx - x) - yaw, 2 * math.pi)
            assert t["heading"] == pytest.approx(0.1 * (1 - abs(heading) / math.pi) if distance > 1.0 else 0.0, abs=1e-9)
        assert t["progress"] == pytest.approx(before - distance, abs=1e-12)
        assert t["time"] == -0.01
        assert t["goal"] == (50.0 if distance < 0.5 else 0.0)
        assert t["collision"] == (-10.0 if info["collision"] else 0.0)
        closest = float(obs[:36].min()) * 5.0
        assert t["proximity"] == pytest.approx(-(0.3 - closest) if closest < 0.3 else 0.0, abs=1e-5)
        before = distance
        steps += 1
        ends += terminated or truncated
        assert type(reward) is float and all(type(t) is float for t in terms)
        assert reward == sum(terms)  # exactly: the env adds the same floats in the same order
        seen |= {name for name, t in zip(names, terms) if t != 0.0}
    assert steps == 1000 and ends >= 2, "the rollout should span several episodes"
    assert {"progress", "time", "heading"} <= seen


@pytest.mark.parametrize("setting", ROLLOUT_SETTINGS)
def test_every_observation_lies_in_the_observation_space(make_env, setting):
    kwargs, seed = ROLLOUT_SETTINGS[setting]
    env = make_env(**kwargs)
    space = env.observation_space
    count, resets = 0, 0
    lo, hi = np.full(space.shape, np.inf), np.full(space.shape, -np.inf)
    for obs, reward, _, _, info in _random_rollout(env, 1000, seed=seed + 100):
        assert space.contains(obs), f"observation {count} is outside {space}: {obs}"
        if kwargs.get("pose_source") != "odometry":  # goal distance and bearing from the true pose, by hand
            (x, y, yaw), (gx, gy) = info["pose"], info["goal"]
            bearing = math.remainder(math.atan2(gy - y, gx - x) - yaw, 2 * math.pi)
            assert obs[42] == pytest.approx(min(math.hypot(gx - x, gy - y) / 10, space.high[42]), abs=1e-6)
            assert obs[36] == pytest.approx(bearing / math.pi, abs=1e-6)
        lo, hi = np.minimum(lo, obs), np.maximum(hi, obs)
        count += 1
        resets += reward is None
    assert count == 1000 + resets and resets >= 2
    # The rollout reaches the lidar's range limit (nothing hit) and comes within 0.25 m of obstacles.
    assert lo[:36].min() < 0.05 and hi[:36].max() == 1.0


_HASH_SCRIPT = """
import hashlib

import gymnasium as gym
import numpy as np

import bulletnav  # noqa: F401


def trace_hash(seed, steps):
    \"\"\"SHA-256 of every observation, reward, end flag and float info entry of a seeded
    random rollout (seeded resets), and the number of episode ends.\"\"\"
    env = gym.make("bulletnav/Warehouse-v0", lidar_noise=0.02)
    rng = np.random.default_rng(seed)
    digest = hashlib.sha256()

    def add(obs, info):
        digest.update(obs.tobytes())
        for key in sorted(info):
            value = info[key]
            if isinstance(value, (float, tuple, np.ndarray)) and not isinstance(value, bool):
                digest.update(key.encode() + np.asarray(value, dtype=np.float64).tobytes())

    ends = 0
    obs, info = env.reset(seed=seed)
    add(obs, info)
    for _ in range(steps):
        obs, reward, terminated, truncated, info = env.step(rng.uniform(env.action_space.low, env.action_space.high))
        digest.update(np.float64(reward).tobytes() + bytes([terminated, truncated]))
        add(obs, info)
        if terminated or truncated:
            ends += 1
            obs, info = env.reset(seed=seed + ends)
            add(obs, info)
    env.close()
    return digest.hexdigest(), ends
"""


@pytest.mark.slow
def test_same_seed_gives_the_same_trajectory_in_two_processes():
    """Two fresh interpreters (with different string-hash seeds) run the same seeded rollout;
    the hashes of everything they saw agree bit for bit, and agree with this process's."""
    seed, steps = 3, 200
    code = _HASH_SCRIPT + f"\nprint(*trace_hash({seed}, {steps}))\n"
    procs = [subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                              env={**os.environ, "PYTHONHASHSEED": str(k)}) for k in (1, 2)]
    results = []
    for proc in procs:
        out, err = hang.communicate(proc, "the seeded rollout in a fresh interpreter")
        assert proc.returncode == 0, err
        digest, ends = out.strip().splitlines()[-1].split()
        results.append((digest, int(ends)))
    assert results[0] == results[1]
    assert re.fullmatch(r"[0-9a-f]{64}", results[0][0]) and results[0][1] >= 1, "the rollout should end an episode"
    namespace: dict = {}
    exec(compile(_HASH_SCRIPT, "<trace_hash>", "exec"), namespace)
    assert namespace["trace_hash"](seed, steps) == results[0]  # here too, after other tests' envs
    assert namespace["trace_hash"](seed + 1, steps)[0] != results[0][0]  # the hash sees the trajectory


EMPTY = str(asset_path("worlds", "empty.yaml"))


def test_scripted_drive_to_a_nearby_goal_terminates_with_the_goal_term(make_env):
    env = make_env(world=EMPTY)
    obs, _ = env.reset(seed=0, options={"start": (-2.0, 0.0, 0.0), "goal": (0.0, 0.3)})
    total, steps = 0.0, 0
    while True:
        obs, reward, terminated, truncated, info = env.step(np.array([0.5, 2.0 * obs[36] * math.pi]))
        total += reward
        steps += 1
        if terminated or truncated:
            break
    assert terminated and not truncated
    assert info["is_success"] and info["reward_goal"] == 50.0 and info["distance_to_goal"] < 0.5
    assert info["initial_distance"] == pytest.approx(math.hypot(2.0, 0.3), abs=1e-6)
    assert info["path_length"] == pytest.approx(info["initial_distance"] - info["distance_to_goal"], abs=0.1)
    assert total > 50.0


def test_driving_into_a_wall_truncates_with_the_collision_term(make_env):
    env = make_env(world=EMPTY)
    env.reset(seed=0, options={"start": (3.5, 0.0, 0.0), "goal": (-3.0, 0.0)})
    for _ in range(200):
        _, _, terminated, truncated, info = env.step(np.array([0.5, 0.0]))
        if terminated or truncated:
            break
    assert truncated and not terminated
    assert info["collision"] and info["reward_collision"] == -10.0 and not info["is_success"]
    assert info["end_reason"] == "collision"
    assert env.unwrapped.scene.pose[0] == pytest.approx(5.0 - 0.15, abs=0.06)  # front face at the wall


def _into_the_wall(env):
    """Rewards, end flags and last info of the same seeded drive into the east wall as above."""
    env.reset(seed=0, options={"start": (3.5, 0.0, 0.0), "goal": (-3.0, 0.0)})
    rewards = []
    for _ in range(200):
        _, reward, terminated, truncated, info = env.step(np.array([0.5, 0.0]))
        rewards.append(reward)
        if terminated or truncated:
            break
    return rewards, terminated, truncated, info


def test_driving_into_a_wall_terminates_with_collision_terminates(make_env):
    default = _into_the_wall(make_env(world=EMPTY))
    rewards, terminated, truncated, info = _into_the_wall(make_env(world=EMPTY, collision_terminates=True))
    assert terminated and not truncated
    assert info["end_reason"] == "collision" and info["collision"] and not info["is_success"]
    assert info["reward_collision"] == -10.0
    assert default[1:3] == (False, True) and default[3]["end_reason"] == "collision"
    assert rewards == default[0]  # the same episode, step for step: only the end flag differs
    # It stops where the body's front face (0.15 m ahead of the centre) meets the wall at x = 5 m.
    assert info["pose"][0] == pytest.approx(5.0 - 0.15, abs=0.06) and abs(info["pose"][1]) < 0.02


def test_top_speed_into_a_wall_never_passes_through(make_env):
    env = make_env(world=EMPTY)
    env.reset(seed=0, options={"start": (3.0, 1.0, 0.1), "goal": (-3.0, 0.0)})
    xs = []
    for _ in range(24 * 20):  # keep pushing for 20 s after the contact, ignoring truncation
        env.unwrapped.step(np.array([0.5, 0.0]))
        xs.append(env.unwrapped._scene.robot.pose()[0])
    assert max(xs) < 5.0  # the wall's inner face is at x = 5 m


def test_bad_actions_and_options(make_env):
    env = make_env()
    env.reset(seed=0)
    with pytest.raises(ValueError, match="non-finite entries: v"):
        env.step(np.array([np.nan, 0.0]))
    with pytest.raises(ValueError, match="non-finite entries: w"):
        env.step(np.array([0.1, np.inf]))
    assert env.unwrapped.command(np.array([9.0, -9.0])) == (0.5, -1.5)  # clipped
    assert env.unwrapped.command(np.array([-1.0, 0.7])) == (0.0, 0.7)
    assert env.unwrapped.command([0.25, -0.5]) == (0.25, -0.5)  # any 2 numbers will do
    assert env.unwrapped.command(np.array([0, 1])) == (0.0, 1.0)
    for bad in ({"v": 0.1, "w": 0.0}, np.array([0.1, 0.0, 0.0]), [0.1, 0.0, 0.0], "fast"):
        with pytest.raises(ValueError, match="action must be 2 numbers"):
            env.step(bad)
    with pytest.raises(ValueError) as err:
        gym.make(ENV_ID, min_goal_distance=5, max_goal_distance=3)
    assert "min_goal_distance" in str(err.value) and "max_goal_distance" in str(err.value)
    with pytest.raises(ValueError, match="options\\['start'\\]"):
        env.reset(options={"start": (1.0, 2.0)})
    with pytest.raises(TypeError, match="unknown keyword argument 'num_obstacle'"):
        gym.make(ENV_ID, num_obstacle=3)


def test_normalized_actions_map_onto_the_physical_range(make_env):
    env = make_env(normalize_actions=True)
    u = env.unwrapped
    assert u.command(np.array([-1.0, -1.0])) == (0.0, -1.5)
    assert u.command(np.array([1.0, 1.0])) == (0.5, 1.5)
    assert u.command(np.array([0.0, 0.0])) == (0.25, 0.0)


def test_options_place_start_and_goal_exactly(make_env):
    env = make_env(layouts_every=100)  # keep the warehouse across resets
    obs, info = env.reset(seed=2)
    u = env.unwrapped
    layout = u.scene.layout
    free = u._scene.free_space
    builds = u.scene.scene_builds
    (sx, sy, _), goal = info["pose"], info["goal"]
    obs2, info2 = env.reset(options={"start": (float(sx), float(sy), 0.5), "goal": goal})
    assert u.scene.layout is layout and free is u._scene.free_space
    assert u.scene.scene_builds == builds  # teleported, not rebuilt
    np.testing.assert_allclose(info2["pose"], [sx, sy, 0.5], atol=1e-9)
    assert info2["goal"] == goal
    assert u.scene.start == (float(sx), float(sy), 0.5) and u.scene.goal == goal
    # The scan is the one Shapely casts from the placed pose (turned to 0.5 rad) on the layout.
    np.testing.assert_allclose(obs2[:36] * 5.0, _shapely_scan(layout, (sx, sy, 0.5)), atol=2e-3)


def test_kwargs_reach_the_configs(make_env):
    env = make_env(num_obstacles=12, lidar_rays=72, physics_hz=240, control_hz=12, reward_collision=-20.0,
                   min_goal_distance=3.0, max_goal_distance=4.0)
    u = env.unwrapped
    assert env.observation_space.shape == (79,)
    _, info = env.reset(seed=0)
    assert len(u._scene.sim.world.obstacle_ids) == 12
    assert u.config.physics.substeps == 20
    assert u.config.task.reward.collision == -20.0
    assert 3.0 <= info["initial_distance"] <= 4.0
    with pytest.raises(ValueError, match="must divide"):
        gym.make(ENV_ID, control_hz=7)
    cfg = make_env(collision_terminates=True, layout_style="scattered", lidar_rate_hz=12.0, camera_enabled=False,
                   task_name="navigation").unwrapped.config
    assert cfg.task.collision_terminates is True and cfg.world.style == "scattered" and cfg.task_name == "navigation"
    assert cfg.sensors.lidar.rate_hz == 12.0 and cfg.sensors.camera.enabled is False


def test_camera_observations(make_env):
    env = make_env(camera_obs=True, normalize_actions=True)
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"state", "rgb", "depth"}
    assert obs["rgb"].shape == (240, 320, 3) and obs["depth"].shape == (240, 320, 1)
    assert env.observation_space.contains(obs)
    assert _all_warnings(lambda: gym_check_env(env.unwrapped, skip_render_check=True)) == []


def _free_client_slot() -> int:
    """The id PyBullet gives the next client (it reuses the lowest free one)."""
    import pybullet as p

    cid = p.connect(p.DIRECT)
    p.disconnect(cid)
    return cid


def test_disabled_camera_changes_no_observation(make_env):
    """The camera is only rendered when read, and its noise seed is drawn whether it exists or
    not: without it the env gives the same episodes, observation for observation."""
    on, off = make_env(lidar_noise=0.02), make_env(lidar_noise=0.02, camera_enabled=False)
    assert on.unwrapped._scene.sensors.camera is not None
    assert off.unwrapped._scene.sensors.camera is None
    assert set(off.unwrapped.scene.sensors.present()) == {"lidar", "imu", "odometry"}
    a, b = list(_random_rollout(on, 300, seed=8)), list(_random_rollout(off, 300, seed=8))
    assert sum(r is None for _, r, *_ in a) >= 2, "the rollout should span several episodes"
    assert len(a) == len(b)
    for (obs_a, *rest_a, info_a), (obs_b, *rest_b, info_b) in zip(a, b):
        np.testing.assert_array_equal(obs_a, obs_b)
        assert rest_a == rest_b and info_a["distance_to_goal"] == info_b["distance_to_goal"]
    # The first scan is Shapely's ray cast plus the configured N(0, 0.02 m) noise: every ray
    # within 5 sigma, and the rays short of the range limit (unclipped) spread with sigma 0.02.
    obs, info = off.reset(seed=8)  # the rollout's first episode again, on its own layout
    np.testing.assert_array_equal(obs, b[0][0])
    residual = obs[:36] * 5.0 - _shapely_scan(off.unwrapped.scene.layout, info["pose"])
    inside = obs[:36] * 5.0 < 4.9
    assert np.abs(residual).max() < 0.1 and inside.sum() >= 20
    assert 0.01 < residual[inside].std() < 0.03
    slot = _free_client_slot()
    with pytest.raises(ValueError, match="camera_obs=True needs the camera sensor"):
        gym.make(ENV_ID, camera_obs=True, camera_enabled=False)
    assert _free_client_slot() == slot  # the failed env closed its physics client


def test_lidar_rate_holds_each_scan_for_its_period(make_env):
    """At 12 Hz (half the 24 Hz control rate) a new scan comes every second step and the step
    in between repeats it; the rest of the observation, and the physics, are untouched."""
    fast, slow = make_env(), make_env(lidar_rate_hz=12)
    assert slow.unwrapped._scene.sensors.lidar.period == 2 * fast.unwrapped._scene.sensors.lidar.period == 20
    runs = []
    for env in (fast, slow):
        obs, _ = env.reset(seed=4)
        trace = [obs]
        for _ in range(48):  # 2 s driving a tight circle (ignoring any episode end)
            trace.append(env.unwrapped.step(np.array([0.1, 1.5]))[0])
        runs.append(np.array(trace))
        yaw_turned = abs(math.remainder(env.unwrapped.scene.pose[2] - env.unwrapped.scene.start[2], 2 * math.pi))
        assert yaw_turned > 0.3  # the robot moved (2.9 rad of turn, wrapped)
    f, s = runs
    n = 36
    assert np.all(np.any(f[1:, :n] != f[:-1, :n], axis=1)), "the default lidar scans every step"
    changed = np.any(s[1:, :n] != s[:-1, :n], axis=1)
    np.testing.assert_array_equal(changed, np.arange(1, 49) % 2 == 0)
    for k in range(len(s)):  # the held scan is the one taken at the last even step
        np.testing.assert_array_equal(s[k, :n], f[k - k % 2, :n])
    np.testing.assert_array_equal(s[:, n:], f[:, n:])


@pytest.mark.parametrize("sensor, config", [("lidar", LidarConfig(enabled=False)), ("imu", ImuConfig(enabled=False)),
                                            ("odometry", OdometryConfig(enabled=False))])
def test_navigation_task_refuses_a_missing_sensor(sensor, config):
    cfg = EnvConfig(sensors=replace(SensorsConfig(), **{sensor: config}))
    slot = _free_client_slot()
    with pytest.raises(ValueError, match=f"the navigation task needs the {sensor} sensor"):
        gym.make(ENV_ID, config=cfg)
    assert _free_client_slot() == slot  # the failed env closed its physics client


def test_unknown_task_and_world_style_list_the_registered_ones():
    with pytest.raises(ValueError, match="unknown task_name 'nope'") as err:
        gym.make(ENV_ID, task_name="nope")
    assert "navigation" in TASKS and all(name in str(err.value) for name in TASKS)
    with pytest.raises(ValueError, match="unknown layout_style 'nope'") as err:
        gym.make(ENV_ID, layout_style="nope")
    assert "scattered" in WORLDS and all(style in str(err.value) for style in WORLDS)


def test_yaml_world_uses_its_start_and_goal(make_env):
    env = make_env(world=str(asset_path("worlds", "aisles.yaml")))
    _, info = env.reset(seed=0)
    np.testing.assert_allclose(info["pose"], [-5.0, -4.0, 0.0], atol=1e-6)
    assert info["goal"] == (4.5, 4.2)
    assert len(env.unwrapped._scene.sim.world.obstacle_ids) == 10 and len(env.unwrapped.scene.layout.obstacles) == 10


def test_bench_env_cli_prints_the_ratio_with_its_provenance(capsys):
    """``bulletnav bench env --json``: both loops' rates, their ratio, and where the figures
    came from (no timing is asserted: these machines are noisy)."""
    t0 = time.perf_counter()
    assert main(["bench", "env", "--steps", "200", "--resets", "10", "--json"]) == 0  # few resets: a quick run
    elapsed = time.perf_counter() - t0
    result = json.loads(capsys.readouterr().out)  # --json: the whole of stdout is one document
    assert result["benchmark"] == "env" and result["steps"] == 200
    # Both timed loops ran inside the command: their times add up to less than its wall time.
    assert 200 / result["env_steps_per_s"] + 200 / result["raw_steps_per_s"] < elapsed
    # The raw loops replayed the env's own physics: every block ended at the env's pose, to the bit.
    assert result["replay_exact"] == 1.0
    assert result["ratio_of_totals"] == pytest.approx(result["env_steps_per_s"] / result["raw_steps_per_s"], rel=1e-3)
    # Both rates are rounded to 0.1 step/s and the overhead to 0.1 us: the bound is that
    # rounding carried through 1e6 / rate (0.05 * 1e6 / rate^2 each), not a fixed 0.5 us, which
    # a loaded machine (rates of a few hundred per second) overran.
    env_rate, raw_rate = result["env_steps_per_s"], result["raw_steps_per_s"]
    assert result["env_overhead_us_per_step"] == pytest.approx(
        (1 / env_rate - 1 / raw_rate) * 1e6, abs=0.05 * 1e6 * (1 / env_rate**2 + 1 / raw_rate**2) + 0.05 + 1e-9)
    # The headline ratio is the median of per-block ratios: with one block, the ratio of totals.
    single = bench_env(steps=100, block=100)
    assert single["ratio"] == single["ratio_of_totals"]
    assert single["ratio"] == pytest.approx(single["env_steps_per_s"] / single["raw_steps_per_s"], rel=1e-3)
    assert re.fullmatch(r"([0-9a-f]{40}(-dirty)?|unknown)", result["git_commit"])
    assert "cores, python" in result["machine"] and result["command"]
