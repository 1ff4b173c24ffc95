"""ROS 2 recordings (``bulletnav.ros``): an episode recorded with :class:`McapRecorder` and read
back by an independent reader (``mcap_ros2.reader``, the ROS 2 profile's own decoder): message
types, one message per control step, monotonic stamps, ranges equal to the env's lidar, the TF
chain map -> odom -> base_link -> laser against the true pose, episode metadata; the message
definitions against the ROS 2 message layout; refusals and the CLI."""

from __future__ import annotations

import math
import struct
import warnings
from collections import defaultdict

import gymnasium as gym
import numpy as np
import pytest
from mcap.reader import make_reader

import bulletnav  # noqa: F401  (registers the envs)
from bulletnav.cli import main
from bulletnav.control.navigator import Navigator
from bulletnav.errors import BulletnavError
from bulletnav.ros.msgdefs import known_types, msgdef
from bulletnav.ros.record import TOPIC_TYPES, McapRecorder, compose

STEPS = 150


def read_ros2_messages(path, topics=None):
    """``mcap_ros2.reader.read_ros2_messages`` (the ROS 2 profile's own decoder), its module's
    deprecation notice (it points to the same decoder through ``mcap.reader``) silenced."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)
        from mcap_ros2.reader import read_ros2_messages as read

    return list(read(path, topics=topics))


def _yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    """One PID + A* episode of ``STEPS`` steps in the dynamic aisle warehouse, recorded; what the
    env's sensors read at each step kept beside it."""
    path = tmp_path_factory.mktemp("ros") / "episode.mcap"
    env = gym.make("bulletnav/WarehouseDynamic-v0", max_episode_steps=STEPS)
    nav = Navigator(env.unwrapped.scene)
    rec = McapRecorder(env, path, plan=lambda: nav.path)
    scene = env.unwrapped.scene
    truth, ranges, odometry = [], [], []
    obs, info = rec.reset(seed=7)
    nav.reset(info)
    while True:
        obs, _, terminated, truncated, info = rec.step(nav.act(obs, info))
        truth.append(tuple(scene.pose))
        ranges.append(np.asarray(scene.sensors.lidar.read(), dtype=np.float32))
        odometry.append(np.asarray(scene.sensors.odometry.read(), dtype=np.float64))
        if terminated or truncated:
            break
    angles = scene.sensors.lidar.angles.copy()
    mount = scene.geometry.lidar_mount
    rec.close()
    messages = defaultdict(list)
    for m in read_ros2_messages(str(path)):
        messages[m.channel.topic].append(m)
    return {"path": path, "messages": messages, "truth": truth, "ranges": ranges, "odometry": odometry,
            "angles": angles, "mount": mount, "steps": len(truth), "info": info}


def test_types_counts_and_stamps(recording):
    msgs, steps = recording["messages"], recording["steps"]
    assert steps > 50
    for topic, items in msgs.items():
        assert {m.schema.name for m in items} == {TOPIC_TYPES[topic]}, topic
    for topic in ("/clock", "/tf", "/scan", "/odom", "/imu", "/cmd_vel", "/movers"):
        assert len(msgs[topic]) == steps, topic  # one per control step
    assert len(msgs["/tf_static"]) == len(msgs["/map_truth"]) == 1
    assert len(msgs["/goal_pose"]) >= 1 and len(msgs["/plan"]) >= 1 and len(msgs["/map"]) >= 2
    dt_ns = 1e9 / 24
    for topic in ("/clock", "/scan"):
        times = [m.log_time_ns for m in msgs[topic]]
        assert all(b > a for a, b in zip(times, times[1:])), topic  # strictly increasing
        assert times[0] == pytest.approx(dt_ns, abs=1) and times[-1] == pytest.approx(steps * dt_ns, abs=1)
    for m in msgs["/scan"]:
        st = m.ros_msg.header.stamp
        assert st.sec * 1_000_000_000 + st.nanosec == m.log_time_ns  # header stamp = sim time = log time
    clock = msgs["/clock"][10].ros_msg.clock
    assert clock.sec * 1_000_000_000 + clock.nanosec == msgs["/clock"][10].log_time_ns


def test_scan_equals_the_env_lidar(recording):
    msgs, angles = recording["messages"], recording["angles"]
    first = msgs["/scan"][0].ros_msg
    assert first.header.frame_id == "laser"
    assert len(first.ranges) == len(angles) == 36
    assert first.angle_min == pytest.approx(angles[0]) and first.angle_max == pytest.approx(angles[-1])
    assert first.angle_increment == pytest.approx(2 * math.pi / 36)
    assert first.range_max == pytest.approx(5.0) and first.range_min == pytest.approx(0.0)
    for m, expected in zip(msgs["/scan"], recording["ranges"]):
        np.testing.assert_array_equal(np.asarray(m.ros_msg.ranges, dtype=np.float32), expected)


def test_tf_chain_reaches_the_true_pose(recording):
    msgs = recording["messages"]
    static = {t.child_frame_id: t for t in msgs["/tf_static"][0].ros_msg.transforms}
    assert static["laser"].header.frame_id == "base_link"
    assert static["laser"].transform.translation.x == pytest.approx(recording["mount"][0])
    assert "camera_link" in static
    drift_seen = 0.0
    for m, truth, odo in zip(msgs["/tf"], recording["truth"], recording["odometry"]):
        tf = {(t.header.frame_id, t.child_frame_id): t.transform for t in m.ros_msg.transforms}
        assert set(tf) == {("map", "odom"), ("odom", "base_link")}
        a, b = tf[("map", "odom")], tf[("odom", "base_link")]
        map_odom = (a.translation.x, a.translation.y, _yaw(a.rotation))
        odom_base = (b.translation.x, b.translation.y, _yaw(b.rotation))
        assert odom_base[:2] == pytest.approx(tuple(odo[:2]), abs=1e-9)  # the odometry's estimate
        x, y, yaw = compose(map_odom, odom_base)
        assert (x, y) == pytest.approx(truth[:2], abs=1e-6)
        assert math.remainder(yaw - truth[2], 2 * math.pi) == pytest.approx(0.0, abs=1e-6)
        drift_seen = max(drift_seen, math.hypot(*map_odom[:2]))
    assert drift_seen > 0.0  # the odometry drifts, and map -> odom shows it
    odom = msgs["/odom"][-1].ros_msg
    assert odom.header.frame_id == "odom" and odom.child_frame_id == "base_link"
    assert odom.twist.twist.linear.x == pytest.approx(recording["odometry"][-1][3], abs=1e-6)
    imu = msgs["/imu"][-1].ros_msg
    assert imu.orientation_covariance[0] == -1.0  # no orientation estimate, as the message defines
    assert imu.linear_acceleration.z == pytest.approx(9.81, abs=1.0)


def test_maps_movers_and_metadata(recording):
    msgs = recording["messages"]
    truth_map = msgs["/map_truth"][0].ros_msg
    data = np.asarray(truth_map.data, dtype=np.int16).reshape(truth_map.info.height, truth_map.info.width)
    assert set(np.unique(data)) <= {0, 100} and (data == 100).any()
    assert (data[0, :] == 100).all()  # the floor's bottom wall
    grown = msgs["/map"][-1].ros_msg
    cells = np.asarray(grown.data, dtype=np.int16)
    assert {-1, 0, 100} <= set(np.unique(cells))  # unknown, seen free, seen occupied
    markers = msgs["/movers"][0].ros_msg.markers
    assert markers[0].action == 3 and len(markers) > 1  # DELETEALL, then one per mover
    assert {m.ns for m in markers[1:]} <= {"forklift", "worker"}
    with open(recording["path"], "rb") as f:
        meta = [r for r in make_reader(f).iter_metadata() if r.name == "episode"]
    assert len(meta) == 1
    assert meta[0].metadata["steps"] == str(recording["steps"]) and meta[0].metadata["seed"] == "7"
    assert meta[0].metadata["end_reason"] == (recording["info"]["end_reason"] or "timeout")  # the step limit truncated it


_INT_RANGES = {"int8": (-128, 127), "uint8": (0, 255), "byte": (0, 255), "char": (-128, 127), "int16": (-2**15, 2**15 - 1),
               "uint16": (0, 2**16 - 1), "int32": (-2**31, 2**31 - 1), "uint32": (0, 2**32 - 1), "int64": (-2**63, 2**63 - 1),
               "uint64": (0, 2**64 - 1)}


def _random_message(rng, kind: str) -> dict:
    """A message of ``kind`` with random values; a fifth of its fields left out (defaults), arrays
    of random lengths (fixed ones shorter and longer than they are), ``uint8[]`` as bytes or a list."""
    from bulletnav.ros.msgdefs import fields

    def value(kind: str):
        if kind in _INT_RANGES:
            return int(rng.integers(*_INT_RANGES[kind], endpoint=True, dtype=np.int64 if kind != "uint64" else np.uint64))
        if kind == "bool":
            return bool(rng.random() < 0.5)
        if kind == "float32":
            return float(np.float32(rng.uniform(-1e3, 1e3)))
        if kind == "float64":
            return float(rng.choice([rng.uniform(-1e6, 1e6), math.inf, -0.0, math.nan]))
        return "".join(rng.choice(list("ab/_é9"), size=int(rng.integers(0, 9))))

    out = {}
    for f in fields(kind):
        if rng.random() < 0.2:
            continue
        make = (lambda f=f: _random_message(rng, f.kind)) if not f.primitive else (lambda f=f: value(f.kind))
        if f.length is None:
            out[f.name] = make()
            continue
        items = [make() for _ in range(int(rng.integers(0, 6 if f.length < 0 else f.length + 3)))]
        out[f.name] = bytes(items) if f.kind == "uint8" and rng.random() < 0.5 else items
    return out


def test_the_encoder_writes_mcap_ros2_supports_bytes_for_every_type():
    """bulletnav's own CDR encoder (:mod:`bulletnav.ros.cdr`) against mcap-ros2-support's
    serializer, byte for byte: 60 random messages of every type bulletnav writes (defaults,
    padded and cut fixed arrays, strings of several lengths shifting the alignment)."""
    import copy

    from mcap_ros2._dynamic import serialize_dynamic

    from bulletnav.ros.cdr import encode

    rng = np.random.default_rng(11)
    for datatype in known_types():
        reference = serialize_dynamic(datatype, msgdef(datatype))[datatype]
        for _ in range(60):
            msg = _random_message(rng, datatype)
            assert encode(datatype, copy.deepcopy(msg)) == reference(copy.deepcopy(msg)), (datatype, msg)
    # a NumPy block is its values one by one
    assert encode("std_msgs/msg/Float64", {"data": 2.5})[4:] == struct.pack("<d", 2.5)
    grid = {"data": np.array([[-1, 0], [100, 5]], dtype=np.int64)}
    assert encode("nav_msgs/msg/OccupancyGrid", grid) == encode("nav_msgs/msg/OccupancyGrid", {"data": [-1, 0, 100, 5]})


def test_message_definitions_parse_as_ros2_types():
    from mcap_ros2._dynamic import serialize_dynamic

    for datatype in known_types():
        encoders = serialize_dynamic(datatype, msgdef(datatype))
        assert datatype in encoders
    assert msgdef("sensor_msgs/LaserScan") == msgdef("sensor_msgs/msg/LaserScan")
    with pytest.raises(KeyError, match="no message definition"):
        msgdef("sensor_msgs/msg/PointCloud2")


def test_refusals_and_abort_leave_nothing(tmp_path):
    env = gym.make("bulletnav/WarehouseAisles-v0")
    try:
        existing = tmp_path / "old.mcap"
        existing.write_bytes(b"x")
        with pytest.raises(BulletnavError, match="already exists"):
            McapRecorder(env, existing)
        with pytest.raises(BulletnavError, match=r"\.mcap"):
            McapRecorder(env, tmp_path / "episode.bag")
        rec = McapRecorder(env, tmp_path / "dropped.mcap")
        rec.reset(seed=0)
        rec.step(env.action_space.sample())
        rec.abort()
        assert sorted(p.name for p in tmp_path.iterdir()) == ["old.mcap"]
    finally:
        env.close()


@pytest.mark.slow
def test_cli_navigate_records(tmp_path, capsys):
    out = tmp_path / "nav.mcap"
    assert main(["navigate", "--env", "bulletnav/WarehouseAisles-v0", "--planner", "astar", "--episodes", "2",
                 "--seed", "3", "--record", str(out)]) == 0
    assert "recording:" in capsys.readouterr().out
    with open(out, "rb") as f:
        episodes = [r.metadata for r in make_reader(f).iter_metadata() if r.name == "episode"]
    assert [e["seed"] for e in episodes] == ["3", "4"]
    assert int(episodes[1]["start_ns"]) > int(episodes[0]["end_ns"])  # one time line, episodes one after the other
    scans = sum(1 for _ in read_ros2_messages(str(out), topics=["/scan"]))
    assert scans == int(episodes[0]["steps"]) + int(episodes[1]["steps"])
    with pytest.raises(SystemExit):
        main(["navigate", "--episodes", "1", "--record", str(tmp_path / "nav.txt")])
    capsys.readouterr()
    assert main(["navigate", "--episodes", "1", "--record", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err


def test_camera_topics(tmp_path, recording):
    """With the camera in the observation every step carries a JPEG image and a 32FC1 depth
    image equal to the camera's; without it, none unless ``camera_hz`` asks (then at that rate)."""
    import io

    from PIL import Image

    assert "/camera/depth" not in recording["messages"]  # the fixture's camera is not in its observation
    env = gym.make("bulletnav/WarehouseAisles-v0", camera_obs=True, max_episode_steps=8)
    rec = McapRecorder(env, tmp_path / "cam.mcap")
    rec.reset(seed=0)
    depths, rgbs = [], []
    for _ in range(8):
        rec.step(env.action_space.sample())
        image = env.unwrapped.scene.sensors.camera.read()
        depths.append(np.asarray(image.depth, dtype=np.float32).copy())
        rgbs.append(np.asarray(image.rgb).copy())
    rec.close()
    msgs = read_ros2_messages(str(tmp_path / "cam.mcap"), topics=["/camera/image/compressed", "/camera/depth"])
    depth = [m.ros_msg for m in msgs if m.channel.topic == "/camera/depth"]
    jpeg = [m.ros_msg for m in msgs if m.channel.topic == "/camera/image/compressed"]
    assert len(depth) == len(jpeg) == 8
    for msg, expected in zip(depth, depths):
        assert msg.encoding == "32FC1" and msg.step == msg.width * 4
        np.testing.assert_array_equal(np.frombuffer(bytes(msg.data), dtype="<f4").reshape(msg.height, msg.width), expected)
    decoded = np.asarray(Image.open(io.BytesIO(bytes(jpeg[-1].data))).convert("RGB"), dtype=np.int16)
    assert jpeg[-1].format == "jpeg" and decoded.shape == rgbs[-1].shape
    assert np.abs(decoded - rgbs[-1]).mean() < 6.0  # JPEG at quality 90
    env = gym.make("bulletnav/WarehouseAisles-v0", max_episode_steps=48)  # 2 s
    rec = McapRecorder(env, tmp_path / "rate.mcap", camera_hz=4.0)
    rec.reset(seed=0)
    for _ in range(48):
        rec.step(env.action_space.sample())
    rec.close()
    assert rec.counts["/camera/depth"] == 8  # 4 per simulated second
    with pytest.raises(BulletnavError, match="camera_hz"):
        McapRecorder(env, tmp_path / "bad.mcap", camera_hz=0)


def test_fleet_recording_one_namespace_per_robot(tmp_path, capsys):
    """``bulletnav fleet --record``: every robot's scan, odometry, IMU and goal under
    ``/robot_<i>/``, its frames prefixed, one TF tree: ``map -> robot_<i>/odom ->
    robot_<i>/base_link`` composes to that robot's true pose (checked through a hook that reads
    the poses in the same steps)."""
    from bulletnav.fleet.controllers import make_controller
    from bulletnav.fleet.metrics import run_fleet_episodes
    from bulletnav.fleet.view import FleetView
    from bulletnav.ros.fleet_record import FleetMcapRecorder

    path = tmp_path / "fleet.mcap"
    rec = FleetMcapRecorder(path)
    poses: list[list[tuple]] = []

    def hook(env, infos):
        rec(env, infos)
        view = FleetView(env)
        poses.append([tuple(view.pose(i)) for i in range(view.num_robots)])

    run_fleet_episodes({"num_robots": 2, "duration_s": 2.0, "dynamic": True},
                       lambda env: make_controller("independent", env), 1, seed=3, on_step=hook)
    assert rec.close(True)
    msgs = defaultdict(list)
    for m in read_ros2_messages(str(path)):
        msgs[m.channel.topic].append(m)
    steps = len(poses) - 1  # the reset's call writes no step
    assert steps == 48
    for i in range(2):
        for topic, kind in (("scan", "sensor_msgs/msg/LaserScan"), ("odom", "nav_msgs/msg/Odometry"),
                            ("imu", "sensor_msgs/msg/Imu")):
            items = msgs[f"/robot_{i}/{topic}"]
            assert len(items) == steps and {m.schema.name for m in items} == {kind}
        assert msgs[f"/robot_{i}/scan"][0].ros_msg.header.frame_id == f"robot_{i}/laser"
        assert len(msgs[f"/robot_{i}/goal_pose"]) >= 1
    assert len(msgs["/tf"]) == 2 * steps and len(msgs["/clock"]) == steps and len(msgs["/movers"]) == steps
    static = {t.child_frame_id: t.header.frame_id for t in msgs["/tf_static"][0].ros_msg.transforms}
    assert static["robot_1/laser"] == "robot_1/base_link"
    for k, m in enumerate(msgs["/tf"]):
        tf = {(t.header.frame_id, t.child_frame_id): t.transform for t in m.ros_msg.transforms}
        (odom,) = [c for (p, c) in tf if p == "map"]
        i = int(odom.split("/")[0].split("_")[1])
        a, b = tf[("map", odom)], tf[(odom, f"robot_{i}/base_link")]
        x, y, yaw = compose((a.translation.x, a.translation.y, _yaw(a.rotation)),
                            (b.translation.x, b.translation.y, _yaw(b.rotation)))
        truth = poses[1 + k // 2][i]
        assert (x, y) == pytest.approx(truth[:2], abs=1e-6)
    with open(path, "rb") as f:
        meta = [r.metadata for r in make_reader(f).iter_metadata() if r.name == "episode"]
    assert len(meta) == 1 and meta[0]["robots"] == "2"


def test_cli_fleet_and_evaluate_record(tmp_path, capsys):
    out = tmp_path / "fleet.mcap"
    assert main(["fleet", "--robots", "2", "--duration", "1", "--episodes", "2", "--seed", "1", "--record", str(out)]) == 0
    assert "one namespace per robot" in capsys.readouterr().out
    with open(out, "rb") as f:
        meta = [r.metadata for r in make_reader(f).iter_metadata() if r.name == "episode"]
    assert [m["index"] for m in meta] == ["0", "1"] and int(meta[1]["start_ns"]) > int(meta[0]["end_ns"])
    assert len(read_ros2_messages(str(out), topics=["/robot_1/scan"])) == 2 * 24
    ev = tmp_path / "ev.mcap"
    from pathlib import Path

    model = Path(__file__).resolve().parent.parent / "models" / "ppo_warehouse.zip"
    assert main(["evaluate", "--model", str(model), "--episodes", "1", "--seed", "1000", "--json",
                 "--record", str(ev)]) == 0
    capsys.readouterr()
    scans = read_ros2_messages(str(ev), topics=["/scan", "/cmd_vel"])
    assert len(scans) >= 2 and len({m.channel.topic for m in scans}) == 2
