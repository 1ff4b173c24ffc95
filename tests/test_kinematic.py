"""The kinematic profile (``physics="kinematic"``) against PyBullet's (``physics="default"``).

PyBullet's full physics is the reference throughout: the same pose gives the same scan, the
same commands the same motion, the same drive into a wall the same contact step, the same seed
the same episode set-up. Tolerances are stated at each assertion.
"""

from __future__ import annotations

import math
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env as gym_check_env

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.bench.kinematic_bench import MANOEUVRES, contact_step, contact_target, drive, seeded_scans, world_source
from bulletnav.errors import ConfigError

IDS = ("bulletnav/Warehouse-v0", "bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0",
       "bulletnav/WarehouseMission-v0", "bulletnav/BARN-v0")

@pytest.mark.parametrize("source", ["procedural", "aisles", "yaml", "map_server", "sdf", "barn"])
def test_scans_match_pybullet_in_every_world_source(source, tmp_path):
    # the same seeded reset puts the robot at rest at the same pose in the same world: both
    # profiles' scans (noise off) agree within 1 cm on at least 99 % of the rays
    env_id, kwargs = world_source(source, tmp_path)
    seeds = range(6)
    physics, _ = seeded_scans(env_id, kwargs, "default", seeds)
    kinematic, _ = seeded_scans(env_id, kwargs, "kinematic", seeds)
    diff = np.abs(np.concatenate(physics) - np.concatenate(kinematic))
    assert np.mean(diff <= 0.01) >= 0.99, (source, np.sort(diff)[-5:])
    assert len(diff) >= 6 * 36


@pytest.mark.parametrize("robot, v, w", [("article", 0.5, 1.5), ("jackal", 2.0, 4.0)])
def test_straight_drive_and_turn_in_place_end_where_pybullet_ends(robot, v, w):
    # straight: 2 s at full speed then 1 s of zero command (article 1.0 m, Jackal 3.96 m in PyBullet):
    # the end points agree within 1.5 % of the distance and 0.01 rad. Turn in place: 1 s at the
    # full turn rate then 1 s of zero: the headings agree within 1 % of the angle and 0.02 rad.
    straight = MANOEUVRES["straight"]  # 2 s at the top speed (v), then the 1 s of zero every manoeuvre ends with
    a, b = drive("default", robot, straight), drive("kinematic", robot, straight)
    distance = math.hypot(a[0], a[1])
    assert math.hypot(a[0] - b[0], a[1] - b[1]) <= 0.015 * distance, (a, b)
    assert abs(math.remainder(a[2] - b[2], 2 * math.pi)) <= 0.01
    turn = MANOEUVRES["turn in place"]  # 1 s at the top turn rate (w), then 1 s of zero
    a, b = drive("default", robot, turn), drive("kinematic", robot, turn)
    assert abs(math.remainder(a[2] - b[2], 2 * math.pi)) <= max(0.02, 0.01 * w)
    assert math.hypot(a[0] - b[0], a[1] - b[1]) <= 0.01


def _pushed(physics: str, env_id: str, kwargs: dict, start: tuple[float, float, float], goal, steps: int = 240) -> float:
    """How far along its heading (m) a robot driven at full speed from ``start`` gets in ``steps``
    steps of pushing on past the contact (the simulation stepped directly: the episode ends at it)."""
    env = gym.make(env_id, physics=physics, **kwargs)
    env.reset(seed=0, options={"start": start} if goal is None else {"start": start, "goal": goal})
    scene = env.unwrapped._scene
    v = env.unwrapped.config.task.max_speed
    c, s = math.cos(start[2]), math.sin(start[2])
    farthest = -math.inf
    for _ in range(steps):
        scene.step(v, 0.0)
        st = scene.robot.state
        farthest = max(farthest, (st.x - start[0]) * c + (st.y - start[1]) * s)
    env.close()
    return farthest


@pytest.mark.parametrize("target", ["wall", "rack", "barn_cylinder"])
def test_full_speed_contact_is_reported_at_pybullets_step(target, tmp_path):
    # wall: 3 m to the north wall of an empty 10 x 10 m room's floor edge; rack: a 0.9 m deep rack
    # whose face stands 1.55 m ahead; a BARN cylinder 1.5 m ahead of the Jackal at 2 m/s. The
    # first contact comes at the same step (+-1) in both profiles, and in the kinematic one the
    # robot never gets past the obstacle's face (its nose stops within 2 cm of it).
    env_id, kwargs, start, goal, face = contact_target(target, tmp_path)
    physics_step, _, _ = contact_step("default", env_id, kwargs, start, goal)
    kinematic_step, _, nose = contact_step("kinematic", env_id, kwargs, start, goal)
    kinematic_far = _pushed("kinematic", env_id, kwargs, start, goal)
    assert physics_step is not None and kinematic_step is not None
    assert abs(physics_step - kinematic_step) <= 1, (physics_step, kinematic_step)
    assert kinematic_far + nose <= face + 1e-9
    assert kinematic_far + nose >= face - 0.02


@pytest.mark.parametrize("env_id", IDS)
def test_env_checkers_pass(env_id):
    from stable_baselines3.common.env_checker import check_env as sb3_check_env

    env = gym.make(env_id, physics="kinematic")
    gym_check_env(env.unwrapped, skip_render_check=True)
    sb3_check_env(env.unwrapped, warn=False)
    env.close()


def _setups(env_id: str, physics: str, seeds: range):
    env = gym.make(env_id, physics=physics)
    out = []
    for seed in seeds:
        obs, info = env.reset(seed=seed)
        scene = env.unwrapped.scene
        out.append((scene.layout, scene.start, scene.goals, scene.mover_specs, sorted(info), np.shape(obs)))
        obs, reward, terminated, truncated, info = env.step(env.action_space.sample() * 0)
        out.append((sorted(info), type(reward), np.shape(obs)))
    env.close()
    return out


@pytest.mark.parametrize("env_id", IDS)
def test_seeded_resets_give_pybullets_world_start_goal_and_movers(env_id):
    seeds = range(3)
    assert _setups(env_id, "kinematic", seeds) == _setups(env_id, "default", seeds)


def test_refusals_are_one_line_naming_the_profile_that_serves():
    for kwargs, needle in (({"camera_obs": True}, "camera"), ({"render_mode": "human"}, "GUI"),
                           ({"render_mode": "rgb_array"}, "frames")):
        with pytest.raises(ConfigError) as info:
            gym.make("bulletnav/Warehouse-v0", physics="kinematic", **kwargs)
        message = str(info.value)
        assert "\n" not in message and needle in message and "physics='default'" in message, message


def test_step_parts_time_the_scenes_own_drive_and_lidar():
    """``bench env --physics kinematic``'s profile of a step times the scene's own simulation
    step and closed-form lidar cast: both read time in the kinematic profile; under PyBullet the
    rays are PyBullet's (no closed-form cast: 0) while its step still reads time."""
    from bulletnav.envs.profiling import step_parts

    kin = step_parts("bulletnav/Warehouse-v0", "kinematic", steps=300, seed=1)
    full = step_parts("bulletnav/Warehouse-v0", "default", steps=60, seed=1)
    assert kin["sim_us"] > 0 and kin["lidar_us"] > 0 and kin["rest_us"] > 0, kin
    assert full["sim_us"] > 0 and full["lidar_us"] == 0, full


def test_cli_refuses_the_gui_in_one_line():
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "bulletnav.cli", "navigate", "--physics", "kinematic", "--episodes", "1",
                          "--gui"], capture_output=True, text=True, timeout=300)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "physics='default'" in lines[0], (run.returncode, run.stderr[-800:])


@pytest.mark.slow
def test_bench_outcomes_pairs_each_world_with_its_kinematic_twin(tmp_path):
    """``bench kinematic``'s outcome table against the suite's own rows, counted here: per world
    and controller, both profiles' success and collision rates, and the episodes that differ."""
    import json

    from bulletnav.bench.kinematic_bench import bench_outcomes

    suite = Path(__file__).resolve().parent / "data" / "kinematic_pair_tiny.yaml"
    record = bench_outcomes(tmp_path / "pair", suite_path=suite)
    rows = json.loads((tmp_path / "pair" / "results.json").read_text())["episodes"]
    assert {r["world"] for r in rows} == {"scattered", "scattered kinematic"} and len(rows) == 12
    assert [(p["world"], p["controller"]) for p in record["pairs"]] == [("scattered", "PID"), ("scattered", "PID + A*")]

    def outcome(r):
        return "success" if r["success"] else "collision" if r["collision"] else "time-out"

    for pair in record["pairs"]:
        mine = {w: sorted((r for r in rows if r["world"] == w and r["controller"] == pair["controller"]),
                          key=lambda r: r["episode"]) for w in ("scattered", "scattered kinematic")}
        for profile, world in (("default", "scattered"), ("kinematic", "scattered kinematic")):
            assert pair[profile]["success"] == pytest.approx(sum(r["success"] for r in mine[world]) / 3)
            assert pair[profile]["collision"] == pytest.approx(sum(r["collision"] for r in mine[world]) / 3)
        differ = [a["episode"] for a, b in zip(mine["scattered"], mine["scattered kinematic"]) if outcome(a) != outcome(b)]
        assert [d["episode"] for d in pair["differing"]] == differ
        assert pair["same_outcome"] == pytest.approx(1 - len(differ) / 3)
    again = bench_outcomes(tmp_path / "pair", suite_path=suite)  # resumed: nothing rerun, the same table
    assert again["pairs"] == record["pairs"]


@pytest.mark.slow
def test_a_model_trained_kinematic_is_evaluated_in_full_physics_unless_asked(tmp_path, capsys):
    """The shipped Warehouse-v0 PPO with its sidecar saying it trained with physics="kinematic":
    ``evaluate`` runs it in full physics and says which profile it trained on; ``--physics
    kinematic`` runs it there. The in-training evaluation keeps the training's profile."""
    import json
    import shutil

    from bulletnav.cli import main
    from bulletnav.rl.envs import evaluation_env_kwargs

    models = Path(__file__).resolve().parents[1] / "models"
    for suffix in (".zip", ".json", ".safetensors", "_vecnormalize.json"):
        shutil.copy(models / f"ppo_warehouse{suffix}", tmp_path / f"kin{suffix}")
    sidecar = tmp_path / "kin.json"
    meta = json.loads(sidecar.read_text())
    meta["env_kwargs"] = {**meta["env_kwargs"], "physics": "kinematic"}
    sidecar.write_text(json.dumps(meta))
    argv = ["evaluate", "--model", str(tmp_path / "kin.zip"), "--episodes", "1", "--seed", "5"]
    assert main([*argv, "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["physics"], out["trained_physics"]) == ("default", "kinematic")
    assert main([*argv, "--json", "--physics", "kinematic"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["physics"], out["trained_physics"]) == ("kinematic", "kinematic")
    assert main(argv) == 0
    assert "trained with physics=kinematic; these episodes run with physics=default" in capsys.readouterr().out
    assert "physics" not in evaluation_env_kwargs(meta["env_kwargs"])
    assert evaluation_env_kwargs(meta["env_kwargs"], keep=("physics",))["physics"] == "kinematic"


@pytest.mark.slow
def test_the_kinematic_trained_policy_scores_its_cards_episodes_in_full_physics(capsys):
    """``models/ppo_warehouse_kinematic.zip`` (trained in the kinematic profile) is evaluated in
    full physics by default, and its first episodes there are, to the bit, the committed
    evaluation's (``docs/results/kinematic_policy/full_physics_200.json``, the model card's)."""
    import json

    from bulletnav.cli import main

    root = Path(__file__).resolve().parent.parent
    card = json.loads((root / "docs/results/kinematic_policy/full_physics_200.json").read_text())
    assert main(["evaluate", "--model", str(root / "models/ppo_warehouse_kinematic.zip"), "--episodes", "3",
                 "--seed", "1000000", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["physics"] == "default" and out["trained_physics"] == "kinematic"
    for got, want in zip(out["per_episode"], card["per_episode"][:3]):
        assert {k: v for k, v in got.items() if k != "wall_time"} == {k: v for k, v in want.items() if k != "wall_time"}

