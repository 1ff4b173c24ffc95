"""A user's map lives in its own frame, end to end: a map_server map whose origin is far from
(0, 0) (as a SLAM run saves one) and a Gazebo world off the origin. The env's poses, goal and
path, the PyBullet bodies, a recording's ``/tf``, ``/map_truth``, ``/map``, ``/goal_pose`` and
``/plan`` all read back in the file's own coordinates, checked against the numbers in the file."""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.ros.record import McapRecorder, compose
from bulletnav.sim.layout import layout_to_dict, load_layout, parse_layout
from test_ros_record import read_ros2_messages

RES = 0.1
W, H = 80, 50  # an 8 x 5 m room
ORIGIN = (-53.7, 12.3)  # the YAML's origin: the lower-left pixel's corner in the map frame
START = (ORIGIN[0] + 1.2, ORIGIN[1] + 1.0, 0.3)  # given in the map frame, as the user reads them off the map
GOAL = (ORIGIN[0] + 6.8, ORIGIN[1] + 1.0)


def _room() -> np.ndarray:
    """Pixel rows (row 0 the top): the border walls, and a wall from the bottom to y = 3 m at x = 4 m."""
    cells = np.full((W, H), 254, dtype=np.uint8)
    cells[0, :] = cells[-1, :] = cells[:, 0] = cells[:, -1] = 0
    cells[39:42, 0:30] = 0
    return cells.T[::-1]


def _map(tmp_path: Path) -> Path:
    pixels = _room()
    (tmp_path / "room.pgm").write_bytes(b"P5\n%d %d\n255\n" % (W, H) + pixels.tobytes())
    (tmp_path / "room.yaml").write_text(
        f"image: room.pgm\nresolution: {RES}\norigin: [{ORIGIN[0]}, {ORIGIN[1]}, 0.0]\nnegate: 0\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\n")
    (tmp_path / "site.yaml").write_text(f"map: room.yaml\nstart: [{START[0]!r}, {START[1]!r}, {START[2]!r}]\n"
                                        f"goal: [{GOAL[0]!r}, {GOAL[1]!r}]\n")
    return tmp_path / "site.yaml"


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def _drive_recorded(world: Path, path: Path, seed: int = 3):
    """One PID + A* episode on ``world``, recorded to ``path``: (infos, the robot body's PyBullet
    positions, the recording's messages by topic)."""
    env = gym.make("bulletnav/Warehouse-v0", world=str(world))
    scene = env.unwrapped.scene
    nav = Navigator(scene, NavigatorConfig(planner="astar"))
    rec = McapRecorder(env, path, plan=lambda: nav.path)
    infos, bodies = [], []
    try:
        obs, info = rec.reset(seed=seed)
        nav.reset(info)
        infos.append(info)
        while True:
            obs, _, terminated, truncated, info = rec.step(nav.act(obs, info))
            infos.append(info)
            pos, _ = p.getBasePositionAndOrientation(scene.robot_body, physicsClientId=scene.client)
            bodies.append(pos[:2])
            if terminated or truncated:
                break
    finally:
        rec.close()
        env.close()
    messages = defaultdict(list)
    for m in read_ros2_messages(str(path)):
        messages[m.channel.topic].append(m.ros_msg)
    return infos, bodies, messages


@pytest.mark.slow
def test_a_map_far_off_the_origin_drives_and_records_in_its_own_frame(tmp_path):
    infos, bodies, msgs = _drive_recorded(_map(tmp_path), tmp_path / "run.mcap")
    first, last = infos[0], infos[-1]
    # the env: start and goal where the YAML puts them; the body and every pose in the map's coordinates
    assert tuple(first["goal"]) == GOAL
    assert tuple(first["pose"][:2]) == pytest.approx(START[:2], abs=0.01)
    assert last["is_success"] and not last["collision"]
    x0, y0, x1, y1 = ORIGIN[0], ORIGIN[1], ORIGIN[0] + W * RES, ORIGIN[1] + H * RES
    poses = np.array([i["pose"][:2] for i in infos])
    assert (poses[:, 0] > x0).all() and (poses[:, 0] < x1).all() and (poses[:, 1] > y0).all() and (poses[:, 1] < y1).all()
    # the PyBullet body stands there too (its base frame a few centimetres off the robot's centre)
    assert np.abs(np.array(bodies) - poses[1:]).max() < 0.05
    assert poses[:, 1].max() > ORIGIN[1] + 3.0  # round the wall's end (y = 3 m from the map's corner)
    # the recording: the maps carry the YAML's origin to the bit, the goal and the tf chain are the env's
    truth = msgs["/map_truth"][0]
    assert (truth.info.origin.position.x, truth.info.origin.position.y) == ORIGIN
    assert truth.info.width * truth.info.resolution == pytest.approx(W * RES)
    grown = msgs["/map"][-1]
    assert (grown.info.origin.position.x, grown.info.origin.position.y) == ORIGIN
    goal = msgs["/goal_pose"][0]
    assert goal.header.frame_id == "map" and (goal.pose.position.x, goal.pose.position.y) == GOAL
    for tf_msg, info in zip(msgs["/tf"], infos[1:]):
        tf = {(t.header.frame_id, t.child_frame_id): t.transform for t in tf_msg.transforms}
        a, b = tf[("map", "odom")], tf[("odom", "base_link")]
        x, y, _ = compose((a.translation.x, a.translation.y, _yaw(a.rotation)),
                          (b.translation.x, b.translation.y, _yaw(b.rotation)))
        assert (x, y) == pytest.approx(tuple(info["pose"][:2]), abs=1e-6)
    plan = np.array([(q.pose.position.x, q.pose.position.y) for q in msgs["/plan"][0].poses])
    assert plan[0] == pytest.approx(START[:2], abs=0.15) and plan[-1] == pytest.approx(GOAL, abs=0.15)
    # the /map_truth cells are the map's own: the wall pixels, cell for cell
    data = np.asarray(truth.data, dtype=np.int16).reshape(truth.info.height, truth.info.width)
    assert np.array_equal(data == 100, (_room()[::-1] == 0))


SDF = """<?xml version='1.0'?><sdf version='1.9'><world name='yard'>
  <model name='shed'><static>true</static><pose>120 -40 0 0 0 0</pose>
    <link name='l'>
      <collision name='south'><pose>0 -2.5 0.5 0 0 0</pose><geometry><box><size>8 0.2 1</size></box></geometry></collision>
      <collision name='north'><pose>0 2.5 0.5 0 0 0</pose><geometry><box><size>8 0.2 1</size></box></geometry></collision>
      <collision name='post'><pose>0 -0.5 0.5 0 0 0</pose>
        <geometry><cylinder><radius>0.4</radius><length>1</length></cylinder></geometry></collision>
    </link></model></world></sdf>
"""


@pytest.mark.slow
def test_a_gazebo_world_off_the_origin_keeps_its_coordinates(tmp_path):
    """The shed stands at (120, -40) in the Gazebo world: its post, the floor (the shapes' extent
    grown by the 1 m margin) and the robot all stay there, and so does the recording's map."""
    (tmp_path / "yard.world").write_text(SDF)
    (tmp_path / "run.yaml").write_text("map: yard.world\nstart: [117.0, -40.0, 0.0]\ngoal: [123.0, -40.0]\n")
    layout = load_layout(tmp_path / "run.yaml")
    assert layout.corner == pytest.approx((116.0 - 1.0, -42.6 - 1.0)) and layout.size == pytest.approx((10.0, 7.2))
    post = next(o for o in layout.obstacles if o.kind == "cylinder")
    assert post.center == pytest.approx((120.0, -40.5))
    infos, bodies, msgs = _drive_recorded(tmp_path / "run.yaml", tmp_path / "yard.mcap")
    assert tuple(infos[0]["goal"]) == (123.0, -40.0) and infos[-1]["is_success"] and not infos[-1]["collision"]
    assert tuple(infos[0]["pose"][:2]) == pytest.approx((117.0, -40.0), abs=0.01)
    gap = min(math.hypot(x - 120.0, y + 40.5) for x, y in bodies)
    assert gap > 0.4  # it went round the post, in the world's coordinates
    truth = msgs["/map_truth"][0]
    assert (truth.info.origin.position.x, truth.info.origin.position.y) == pytest.approx((115.0, -43.6))


def test_a_layout_with_a_corner_round_trips_and_a_far_corner_is_refused():
    """``corner`` in a layout file (what a recording attaches for a user's map) reads back to the
    same layout; the floor is where it says, and a corner past the map origin limit is one line."""
    from bulletnav.errors import LayoutError

    data = {"name": "off", "size": [6.0, 4.0], "corner": [-53.7, 12.3],
            "obstacles": [{"type": "box", "center": [-50.0, 14.0], "size": [0.5, 0.5, 1.0]}],
            "start": [-53.0, 13.0, 0.0], "goal": [-48.5, 15.5]}
    layout = parse_layout(data, "off.yaml")
    assert layout.bounds == pytest.approx((-53.7, 12.3, -47.7, 16.3)) and layout.centre == pytest.approx((-50.7, 14.3))
    assert parse_layout(layout_to_dict(layout), "again") == layout
    assert float(layout.clearance(np.array(-53.6), np.array(14.0))) == pytest.approx(0.1)
    with pytest.raises(LayoutError, match=r"off.yaml: field 'goal' \[-47.0, 15.5\] lies outside the floor"):
        parse_layout({**data, "goal": [-47.0, 15.5]}, "off.yaml")
    with pytest.raises(LayoutError, match=r"off.yaml: obstacles\[0\] .* extends outside the floor \(x in \[-53.7, -47.7"):
        parse_layout({**data, "obstacles": [{"type": "box", "center": [-47.8, 14.0], "size": [0.5, 0.5, 1.0]}]}, "off.yaml")
    with pytest.raises(LayoutError, match="field 'corner' must be within"):
        parse_layout({**data, "corner": [2e6, 0.0]}, "off.yaml")
