"""``bulletnav map`` on ROS 1 ``.bag`` and ROS 2 sqlite3 ``.db3`` bags, and ``--format ros``.

The bags are written by the ``rosbags`` library's own writers (``rosbag1.Writer``, ``rosbag2.Writer``
with sqlite3 storage; no bulletnav code): a robot crossing a known 6 m x 4 m room, its LaserScan
(cast exactly against the room's walls here) and Odometry. Each must map to the room's walls within
one cell. ``--format ros`` must write what Nav2's map_server reads: the YAML and PGM are read back
with PyYAML and Pillow (not bulletnav's reader) and checked cell by cell against the map, then
loaded as a world through bulletnav's map_server reader (the round trip).
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml
from PIL import Image

from bulletnav.cli import main
from bulletnav.errors import BulletnavError
from bulletnav.ros.bagmap import build_map
from bulletnav.ros.bags import read_rosbag

pytest.importorskip("rosbags")

ROOM = (-3.0, -2.0, 3.0, 2.0)  # x0, y0, x1, y1 of the walls' inner faces (m)
RAYS, RANGE_MIN, RANGE_MAX, SCANS = 180, 0.1, 8.0, 30


def _cast(x: float, y: float, angle: float) -> float:
    """Distance from (x, y) inside the room to its wall along ``angle`` (exact)."""
    c, s = math.cos(angle), math.sin(angle)
    ts = [(ROOM[2] - x) / c if c > 1e-12 else math.inf, (ROOM[0] - x) / c if c < -1e-12 else math.inf,
          (ROOM[3] - y) / s if s > 1e-12 else math.inf, (ROOM[1] - y) / s if s < -1e-12 else math.inf]
    return min(ts)


def _messages(ts):
    """(topic, msgtype, stamp ns, message) of the room's drive, built from typestore ``ts``'s types."""
    T = ts.types
    Time, Header = T["builtin_interfaces/msg/Time"], T["std_msgs/msg/Header"]
    LaserScan, Odometry = T["sensor_msgs/msg/LaserScan"], T["nav_msgs/msg/Odometry"]
    Pose, Point, Quaternion = T["geometry_msgs/msg/Pose"], T["geometry_msgs/msg/Point"], T["geometry_msgs/msg/Quaternion"]
    Twist, Vector3 = T["geometry_msgs/msg/Twist"], T["geometry_msgs/msg/Vector3"]
    PoseCov, TwistCov = T["geometry_msgs/msg/PoseWithCovariance"], T["geometry_msgs/msg/TwistWithCovariance"]
    ros1 = "seq" in Header.__dataclass_fields__

    def header(ns, frame):
        extra = {"seq": 0} if ros1 else {}
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame, **extra)

    out = []
    inc = 2 * math.pi / RAYS
    for k in range(SCANS):
        ns = 10**9 + k * 100_000_000
        f = k / (SCANS - 1)
        x, y, yaw = -2.0 + 4.0 * f, -0.8 + 1.6 * f, 0.4 * math.sin(3 * f)
        odom = Odometry(header=header(ns, "odom"), child_frame_id="base_link",
                        pose=PoseCov(pose=Pose(position=Point(x=x, y=y, z=0.0),
                                               orientation=Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))),
                                     covariance=np.zeros(36)),
                        twist=TwistCov(twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0), angular=Vector3(x=0.0, y=0.0, z=0.0)),
                                       covariance=np.zeros(36)))
        ranges = np.array([_cast(x, y, yaw - math.pi + i * inc) for i in range(RAYS)], dtype=np.float32)
        scan = LaserScan(header=header(ns, "laser"), angle_min=-math.pi, angle_max=-math.pi + (RAYS - 1) * inc,
                         angle_increment=inc, time_increment=0.0, scan_time=0.1, range_min=RANGE_MIN, range_max=RANGE_MAX,
                         ranges=ranges, intensities=np.zeros(0, dtype=np.float32))
        out += [("/odom", Odometry.__msgtype__, ns, odom), ("/scan", LaserScan.__msgtype__, ns, scan)]
    return out


def _ros1_bag(folder: Path) -> Path:
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC)
    path = folder / "room.bag"
    with Writer(path) as writer:
        conns = {}
        for topic, msgtype, ns, msg in _messages(ts):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            writer.write(conns[topic], ns, ts.serialize_ros1(msg, msgtype))
    return path


def _ros2_sqlite_bag(folder: Path) -> Path:
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    out = folder / "room_ros2"
    with Writer(out, version=8, storage_plugin=StoragePlugin.SQLITE3) as writer:
        conns = {}
        for topic, msgtype, ns, msg in _messages(ts):
            if topic not in conns:
                conns[topic] = writer.add_connection(topic, msgtype, typestore=ts)
            writer.write(conns[topic], ns, ts.serialize_cdr(msg, msgtype))
    files = list(out.glob("*.db3"))
    assert len(files) == 1
    return files[0]


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    folder = tmp_path_factory.mktemp("rosbags")
    return {"ros1": _ros1_bag(folder), "ros2": _ros2_sqlite_bag(folder)}


def _check_room(state: np.ndarray, x0: float, y0: float, res: float) -> None:
    """Every occupied cell within one cell of a wall, and every wall found along its middle."""
    occupied = np.argwhere(state > 0)
    assert len(occupied) > 60
    xs, ys = x0 + (occupied[:, 0] + 0.5) * res, y0 + (occupied[:, 1] + 0.5) * res
    wall = np.minimum.reduce([np.abs(xs - ROOM[0]), np.abs(xs - ROOM[2]), np.abs(ys - ROOM[1]), np.abs(ys - ROOM[3])])
    assert wall.max() <= res * math.sqrt(2) + 1e-9
    for axis, value in ((0, ROOM[0]), (0, ROOM[2]), (1, ROOM[1]), (1, ROOM[3])):
        on = np.abs((xs if axis == 0 else ys) - value) <= res
        along = (ys if axis == 0 else xs)[on]
        assert along.min() < -1.0 and along.max() > 1.0, (axis, value)


@pytest.mark.parametrize("kind", ["ros1", "ros2"])
def test_rosbags_bags_map_the_known_room(bags, kind, capsys):
    data = read_rosbag(bags[kind])
    assert len(data.scans) == SCANS and data.pose_source == "odometry" and data.fixed_frame == "odom"
    m = build_map(data, resolution=0.1).mapper
    _check_room(m.state(), m.x0, m.y0, m.resolution)
    assert main(["map", str(bags[kind]), "--json"]) == 0  # the CLI reads the same file
    summary = json.loads(capsys.readouterr().out)
    assert summary["scans"] == SCANS and summary["occupied_cells"] == int((m.state() > 0).sum())


def test_a_lone_db3_and_a_bag_directory_read_alike(bags, tmp_path):
    lone = tmp_path / "copy.db3"  # without its metadata.yaml: read through sqlite3 and Humble's definitions
    lone.write_bytes(bags["ros2"].read_bytes())
    a, b, c = read_rosbag(lone), read_rosbag(bags["ros2"].parent), read_rosbag(bags["ros2"])
    for other in (b, c):
        assert [s.stamp_ns for s in a.scans] == [s.stamp_ns for s in other.scans]
        assert a.poses == other.poses
        assert all(np.array_equal(s.ranges, t.ranges) for s, t in zip(a.scans, other.scans))


def test_bad_rosbags_are_refused_naming_the_file(bags, tmp_path):
    junk = tmp_path / "junk.bag"
    junk.write_bytes(b"#ROSBAG V2.0\n" + b"\x00" * 40)
    with pytest.raises(BulletnavError, match="junk.bag: not a readable ROS 1 bag"):
        read_rosbag(junk)
    notdb = tmp_path / "notdb.db3"
    notdb.write_bytes(b"hello")
    with pytest.raises(BulletnavError, match="notdb.db3: not a readable ROS 2 sqlite3 bag"):
        read_rosbag(notdb)
    with pytest.raises(BulletnavError, match=r"room.bag: no sensor_msgs/msg/LaserScan messages on /front.*--scan-topic"):
        read_rosbag(bags["ros1"], scan_topic="/front")
    with pytest.raises(BulletnavError, match=r"room.bag: topic /odom holds nav_msgs/msg/Odometry messages, not sensor_msgs"):
        read_rosbag(bags["ros1"], scan_topic="/odom")


def test_a_db3_whose_tables_are_views_is_refused_at_once(tmp_path):
    """A ``.db3`` whose ``messages`` is a view over an endless recursive query (SQL of the file's
    author): refused by name before any query of it runs, in the time a plain open takes. It
    ran until SIGKILL before. Views and virtual tables are refused alike."""
    import sqlite3
    import subprocess
    import sys
    import time

    endless = tmp_path / "endless.db3"
    db = sqlite3.connect(endless)
    db.execute("CREATE TABLE topics (id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT)")
    db.execute("INSERT INTO topics VALUES (1, '/scan', 'sensor_msgs/msg/LaserScan', 'cdr')")
    db.execute("CREATE VIEW messages AS WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c) "
               "SELECT x AS id, 1 AS topic_id, x AS timestamp, x'00' AS data FROM c ORDER BY x DESC")
    db.commit()
    db.close()
    t = time.monotonic()
    run = subprocess.run([sys.executable, "-m", "bulletnav.cli", "map", str(endless)], capture_output=True, text=True,
                         timeout=600)
    assert run.returncode == 2 and "Traceback" not in run.stderr
    assert run.stderr.strip() == (f"bulletnav map: error: {endless}: not a ROS 2 sqlite3 bag: 'messages' is a view, "
                                  "not a plain table (bulletnav does not run a bag's own SQL)")
    assert time.monotonic() - t < 300  # a hang detector: it never ended before
    generated = tmp_path / "generated.db3"  # a generated column: an expression of the author's on every read
    db = sqlite3.connect(generated)
    db.execute("CREATE TABLE topics (id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT)")
    db.execute("CREATE TABLE messages (id INTEGER PRIMARY KEY, topic_id INTEGER, timestamp INTEGER, "
               "data BLOB AS (zeroblob(1000000000)))")
    db.commit()
    db.close()
    with pytest.raises(BulletnavError, match="generated.db3: not a ROS 2 sqlite3 bag: messages.data is a generated column"):
        read_rosbag(generated)
    virtual = tmp_path / "virtual.db3"  # a virtual table whose CREATE text is dressed up by a hand-edited schema
    db = sqlite3.connect(virtual)
    db.execute("CREATE TABLE topics (id INTEGER PRIMARY KEY, name TEXT, type TEXT, serialization_format TEXT)")
    db.execute("CREATE VIRTUAL TABLE messages USING fts5(data)")
    db.execute("PRAGMA writable_schema = ON")
    db.execute("UPDATE sqlite_master SET sql = replace(sql, 'CREATE VIRTUAL', 'CREATE /*x*/ VIRTUAL') "
               "WHERE name = 'messages'")
    db.commit()
    db.close()
    with pytest.raises(BulletnavError, match="virtual.db3: not a ROS 2 sqlite3 bag: 'messages' is a virtual table"):
        read_rosbag(virtual)
    missing = tmp_path / "missing.db3"
    db = sqlite3.connect(missing)
    db.execute("CREATE TABLE topics (id INTEGER, name TEXT, type TEXT)")
    db.commit()
    db.close()
    with pytest.raises(BulletnavError, match="missing.db3: not a ROS 2 sqlite3 bag: it has no 'messages' table"):
        read_rosbag(missing)


def test_a_db3_is_read_for_the_topics_the_map_needs_only(bags, tmp_path):
    """Messages of a topic the map does not read (here one whose data would not even decode as
    CDR) are never read: the map is the same as without them."""
    import sqlite3

    lone = tmp_path / "extra.db3"
    lone.write_bytes(bags["ros2"].read_bytes())
    db = sqlite3.connect(lone)
    columns = [row[1] for row in db.execute("PRAGMA table_info(topics)")]  # rosbags' schema version's columns
    values = {"id": 99, "name": "/camera", "type": "sensor_msgs/msg/Image", "serialization_format": "cdr"}
    db.execute(f"INSERT INTO topics ({', '.join(columns)}) VALUES ({', '.join('?' * len(columns))})",
               [values.get(c, "") for c in columns])
    db.executemany("INSERT INTO messages (topic_id, timestamp, data) VALUES (99, ?, ?)",
                   [(k, b"\xff" * 7) for k in range(1000)])
    db.commit()
    db.close()
    a, b = read_rosbag(lone), read_rosbag(bags["ros2"])
    assert [s.stamp_ns for s in a.scans] == [s.stamp_ns for s in b.scans] and a.poses == b.poses
    from bulletnav.ros.bags import _sqlite

    stream = list(_sqlite(lone, ("/scan", "/odom", "/tf", "/tf_static")))
    assert ("", "sensor_msgs/msg/Image", "/camera") in stream  # announced (an error names every topic) ...
    assert not [m for m in stream if m[0] == "/camera"]  # ... but none of its 1,000 messages is read


def test_format_ros_is_what_map_server_reads(bags, tmp_path, capsys):
    stem = tmp_path / "site"
    assert main(["map", str(bags["ros1"]), "--format", "ros", "--out", str(stem), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    meta = yaml.safe_load((tmp_path / "site.yaml").read_text())  # PyYAML and Pillow, not bulletnav's reader
    assert meta["image"] == "site.pgm" and meta["mode"] == "trinary" and meta["negate"] == 0
    assert meta["occupied_thresh"] == 0.65 and meta["free_thresh"] == 0.196
    image = Image.open(tmp_path / meta["image"])
    assert image.format == "PPM" and image.mode == "L"
    pixels = np.asarray(image)
    assert set(np.unique(pixels)) <= {0, 205, 254}
    # the same map built here: pixel (col, row) is cell (col, height - 1 - row); origin its lower-left corner
    m = build_map(read_rosbag(bags["ros1"]), resolution=0.1).mapper
    state = m.state()
    assert pixels.shape == (state.shape[1], state.shape[0])
    cells = pixels[::-1].T
    assert np.array_equal(cells == 0, state > 0) and np.array_equal(cells == 254, state == 0)
    assert np.array_equal(cells == 205, state < 0)
    assert meta["resolution"] == pytest.approx(m.resolution) and meta["origin"] == pytest.approx([m.x0, m.y0, 0.0])
    assert summary["out"] == [str(tmp_path / "site.yaml"), str(tmp_path / "site.pgm")]
    # Nav2's thresholds on these pixels (occ = 1 - p/255): 0 occupied, 254 free, 205 unknown
    occ = 1.0 - np.array([0, 254, 205]) / 255.0
    assert list(occ > 0.65) == [True, False, False] and list(occ < 0.196) == [False, True, False]


def test_format_ros_round_trips_through_the_world_reader(bags, tmp_path, capsys):
    from bulletnav.sim.layout import load_layout

    stem = tmp_path / "room"
    assert main(["map", str(bags["ros2"]), "--format", "ros", "--out", str(stem)]) == 0
    capsys.readouterr()
    layout = load_layout(tmp_path / "room.yaml")  # unknown cells (outside the room) are walls
    m = build_map(read_rosbag(bags["ros2"]), resolution=0.1).mapper
    state = m.state()
    assert layout.size == pytest.approx((state.shape[0] * 0.1, state.shape[1] * 0.1))
    # the layout's walls, rasterised at the map's cell centres, are exactly the occupied and unknown cells
    walls = layout.occupancy(0.1)
    assert np.array_equal(walls, state != 0)
    # the world is in the map's frame: its floor starts where the map's cells do
    assert layout.corner == pytest.approx((m.x0, m.y0), abs=1e-12)
    # the room's middle (map frame) is free in the layout, a point in its wall is not
    inside, wall = (0.0, 0.0), (ROOM[2] + 0.05, 0.0)
    assert layout.clearance(np.array(inside[0]), np.array(inside[1])) > 1.0
    assert layout.clearance(np.array(wall[0]), np.array(wall[1])) <= 0.0


def test_format_ros_needs_an_out_stem_and_keeps_existing_files(bags, tmp_path, capsys):
    assert main(["map", str(bags["ros1"]), "--format", "ros"]) == 2
    assert "--format ros writes STEM.yaml + STEM.pgm: pass --out STEM" in capsys.readouterr().err
    (tmp_path / "old.pgm").write_bytes(b"kept")
    assert main(["map", str(bags["ros1"]), "--format", "ros", "--out", str(tmp_path / "old.yaml")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and f"--out {tmp_path / 'old.pgm'}: the file already exists" in err
    assert (tmp_path / "old.pgm").read_bytes() == b"kept" and not (tmp_path / "old.yaml").exists()
    assert main(["map", str(bags["ros1"]), "--format", "ros", "--out", str(tmp_path / "old"), "--overwrite"]) == 0
    assert (tmp_path / "old.pgm").read_bytes().startswith(b"P5\n")
    assert main(["map", str(bags["ros1"]), "--out", str(tmp_path / "map.jpg")]) == 2  # --format png wants a .png
    assert "(or pass --format ros for a map_server map)" in capsys.readouterr().err
