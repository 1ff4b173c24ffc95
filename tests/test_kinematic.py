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
from bulletnav.barn.world import barn_layout
from bulletnav.errors import ConfigError

IDS = ("bulletnav/Warehouse-v0", "bulletnav/WarehouseAisles-v0", "bulletnav/WarehouseDynamic-v0",
       "bulletnav/WarehouseMission-v0", "bulletnav/BARN-v0")

SDF_WORLD = """<?xml version="1.0" ?>
<sdf version="1.9">
  <world name="site">
    <model name="walls">
      <static>true</static>
      <pose>10 20 0 0 0 0</pose>
      <link name="outer">
        <collision name="south"><pose>0 -3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="north"><pose>0 3.5 1 0 0 0</pose><geometry><box><size>10 0.2 2</size></box></geometry></collision>
        <collision name="west"><pose>-5 0 1 0 0 1.5707963</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
        <collision name="east"><pose>5 0 1 0 0 1.5707963</pose><geometry><box><size>7 0.2 2</size></box></geometry></collision>
      </link>
      <link name="divider"><pose>1 -1 0 0 0 0.3</pose>
        <collision name="c"><pose>0 0 0.75 0 0 0</pose><geometry><box><size>0.3 3 1.5</size></box></geometry></collision>
      </link>
    </model>
    <model name="pillar">
      <static>true</static>
      <pose>7.5 22 0 0 0 0</pose>
      <link name="l"><collision name="c"><pose>0 0 1.5 0 0 0</pose>
        <geometry><cylinder><radius>0.25</radius><length>3</length></cylinder></geometry></collision></link>
    </model>
  </world>
</sdf>
"""


def _map_server(tmp_path: Path) -> Path:
    """A 12 x 10 m map_server map (0.1 m cells): an outer wall, a block and a bar."""
    rows = np.full((100, 120), 254, dtype=np.uint8)
    rows[:3, :] = rows[-3:, :] = 0
    rows[:, :3] = rows[:, -3:] = 0
    rows[30:45, 20:40] = 0
    rows[55:60, 60:100] = 0
    (tmp_path / "site.pgm").write_bytes(b"P5\n120 100\n255\n" + rows.tobytes())
    path = tmp_path / "site.yaml"
    path.write_text("image: site.pgm\nresolution: 0.1\norigin: [2.0, -3.0, 0]\nnegate: 0\n"
                    "occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: trinary\n")
    return path


def _source(name: str, tmp_path: Path) -> tuple[str, dict]:
    """(env id, keywords) of one world source."""
    if name == "procedural":
        return "bulletnav/Warehouse-v0", {}
    if name == "aisles":
        return "bulletnav/WarehouseAisles-v0", {}
    if name == "yaml":
        return "bulletnav/Warehouse-v0", {"world": str(Path(bulletnav.__file__).parent / "assets" / "worlds" / "hall.yaml")}
    if name == "map_server":
        return "bulletnav/Warehouse-v0", {"world": str(_map_server(tmp_path)), "min_goal_distance": 1.0}
    if name == "sdf":
        path = tmp_path / "site.world"
        path.write_text(SDF_WORLD)
        return "bulletnav/Warehouse-v0", {"world": str(path), "min_goal_distance": 1.0, "max_goal_distance": 4.0}
    return "bulletnav/BARN-v0", {"lidar_rays": 720, "lidar_noise": 0.0, "world_idx": (0, 1, 2, 3, 4)}


def _scans(env_id: str, kwargs: dict, physics: str, seeds: range) -> list[np.ndarray]:
    env = gym.make(env_id, physics=physics, **kwargs)
    out = []
    for seed in seeds:
        env.reset(seed=seed)
        out.append(env.unwrapped.scene.sensors.lidar.read().astype(np.float64))
    env.close()
    return out


@pytest.mark.parametrize("source", ["procedural", "aisles", "yaml", "map_server", "sdf", "barn"])
def test_scans_match_pybullet_in_every_world_source(source, tmp_path):
    # the same seeded reset puts the robot at rest at the same pose in the same world: both
    # profiles' scans (noise off) agree within 1 cm on at least 99 % of the rays
    env_id, kwargs = _source(source, tmp_path)
    seeds = range(6)
    physics = _scans(env_id, kwargs, "default", seeds)
    kinematic = _scans(env_id, kwargs, "kinematic", seeds)
    diff = np.abs(np.concatenate(physics) - np.concatenate(kinematic))
    assert np.mean(diff <= 0.01) >= 0.99, (source, np.sort(diff)[-5:])
    assert len(diff) >= 6 * 36


def _drive(physics: str, robot: str, commands: list[tuple[float, float]]) -> tuple[float, float, float]:
    env = gym.make("bulletnav/Warehouse-v0", physics=physics, robot=robot, num_obstacles=0, world_size=(30, 30))
    env.reset(seed=1, options={"start": (0.0, 0.0, 0.0), "goal": (12.0, 12.0)})
    scene = env.unwrapped._scene
    for v, w in commands:
        scene.step(v, w)
    state = scene.robot.state
    env.close()
    return state.x, state.y, state.yaw


@pytest.mark.parametrize("robot, v, w", [("article", 0.5, 1.5), ("jackal", 2.0, 4.0)])
def test_straight_drive_and_turn_in_place_end_where_pybullet_ends(robot, v, w):
    # straight: 2 s at full speed then 1 s of zero command (article 1.0 m, Jackal 3.96 m in PyBullet):
    # the end points agree within 1.5 % of the distance and 0.01 rad. Turn in place: 1 s at the
    # full turn rate then 1 s of zero: the headings agree within 1 % of the angle and 0.02 rad.
    straight = [(v, 0.0)] * 48 + [(0.0, 0.0)] * 24
    a, b = _drive("default", robot, straight), _drive("kinematic", robot, straight)
    distance = math.hypot(a[0], a[1])
    assert math.hypot(a[0] - b[0], a[1] - b[1]) <= 0.015 * distance, (a, b)
    assert abs(math.remainder(a[2] - b[2], 2 * math.pi)) <= 0.01
    turn = [(0.0, w)] * 24 + [(0.0, 0.0)] * 24
    a, b = _drive("default", robot, turn), _drive("kinematic", robot, turn)
    assert abs(math.remainder(a[2] - b[2], 2 * math.pi)) <= max(0.02, 0.01 * w)
    assert math.hypot(a[0] - b[0], a[1] - b[1]) <= 0.01


def _contact_step(physics: str, env_id: str, kwargs: dict, start: tuple[float, float, float], goal, steps: int = 240):
    """The step at which a robot driven at full speed from ``start`` first reports a contact, and
    the farthest it got along its heading in ``steps`` steps of pushing on (m)."""
    env = gym.make(env_id, physics=physics, **kwargs)
    env.reset(seed=0, options={"start": start} if goal is None else {"start": start, "goal": goal})
    scene = env.unwrapped._scene
    v = env.unwrapped.config.task.max_speed
    c, s = math.cos(start[2]), math.sin(start[2])
    first, farthest = None, -math.inf
    for k in range(steps):
        scene.step(v, 0.0)
        st = scene.robot.state
        farthest = max(farthest, (st.x - start[0]) * c + (st.y - start[1]) * s)
        if first is None and scene.in_collision():
            first = k
    env.close()
    return first, farthest


def _rack_world(tmp_path: Path) -> str:
    path = tmp_path / "rack.yaml"
    path.write_text("name: rack\nsize: [10.0, 10.0]\nobstacles:\n"
                    "  - {type: box, center: [2.0, 0.0], size: [0.9, 3.0, 2.0], label: rack}\n")
    return str(path)


@pytest.mark.parametrize("target", ["wall", "rack", "barn_cylinder"])
def test_full_speed_contact_is_reported_at_pybullets_step(target, tmp_path):
    # wall: 3 m to the north wall of an empty 10 x 10 m room's floor edge; rack: a 0.9 m deep rack
    # whose face stands 1.55 m ahead; a BARN cylinder 1.5 m ahead of the Jackal at 2 m/s. The
    # first contact comes at the same step (+-1) in both profiles, and in the kinematic one the
    # robot never gets past the obstacle's face (its nose stops within 2 cm of it).
    if target == "wall":
        env_id, kwargs = "bulletnav/Warehouse-v0", {"num_obstacles": 0, "world_size": (10, 10)}
        start, goal = (0.0, 2.0, math.pi / 2), (-3.0, -3.0)
        face = 5.0 - 2.0
    elif target == "rack":
        env_id, kwargs, start, goal = "bulletnav/Warehouse-v0", {"world": _rack_world(tmp_path)}, (0.0, 0.0, 0.0), (-3.0, -3.0)
        face = 2.0 - 0.45
    else:
        layout = barn_layout(0)
        cyl = min(layout.obstacles, key=lambda o: math.dist(o.center, (-2.25, 6.0)))
        start = (cyl.center[0], cyl.center[1] - 1.5, math.pi / 2)
        env_id, kwargs, goal = "bulletnav/BARN-v0", {"world_idx": 0}, None
        face = 1.5 - cyl.radius
    physics_step, physics_far = _contact_step("default", env_id, kwargs, start, goal)
    kinematic_step, kinematic_far = _contact_step("kinematic", env_id, kwargs, start, goal)
    assert physics_step is not None and kinematic_step is not None
    assert abs(physics_step - kinematic_step) <= 1, (physics_step, kinematic_step)
    env = gym.make(env_id, physics="kinematic", **kwargs)
    nose = env.unwrapped.scene.geometry.nose
    env.close()
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


def test_cli_refuses_the_gui_in_one_line():
    import subprocess
    import sys

    run = subprocess.run([sys.executable, "-m", "bulletnav.cli", "navigate", "--physics", "kinematic", "--episodes", "1",
                          "--gui"], capture_output=True, text=True, timeout=300)
    lines = run.stderr.strip().splitlines()
    assert run.returncode == 2 and len(lines) == 1 and "physics='default'" in lines[0], (run.returncode, run.stderr[-800:])
