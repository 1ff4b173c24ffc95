"""``bulletnav map BAG.mcap``: bulletnav's lidar mapper on ROS 2 bags. A bag written
independently of bulletnav's writer (the ``rosbags`` library, rosbag2's MCAP storage) of a known
6 m x 4 m room, scanned with another geometry (360 rays, range limits, NaN, +inf and
below-minimum readings, a lidar mounted off the base on ``/tf_static``, odometry on a topic of
another name) maps to the room's walls within one cell; a bag bulletnav recorded maps onto the
true static map; bad bags are refused naming the file and topic."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from bulletnav.cli import main
from bulletnav.errors import BulletnavError
from bulletnav.ros.bagmap import BagData, Scan, build_map, plan_path, pose_at, read_bag

ROOM = (-3.0, -2.0, 3.0, 2.0)  # x0, y0, x1, y1 of the walls' inner faces (m)
MOUNT = (0.1, 0.05, 0.0)  # the lidar on the base (x, y, yaw)
RAYS, RANGE_MIN, RANGE_MAX = 360, 0.12, 3.5


def _cast(x: float, y: float, angle: float) -> float:
    """Distance from (x, y) inside the room to its wall along ``angle`` (exact)."""
    c, s = math.cos(angle), math.sin(angle)
    ts = []
    if c > 1e-12:
        ts.append((ROOM[2] - x) / c)
    if c < -1e-12:
        ts.append((ROOM[0] - x) / c)
    if s > 1e-12:
        ts.append((ROOM[3] - y) / s)
    if s < -1e-12:
        ts.append((ROOM[1] - y) / s)
    return min(ts)


def _room_bag(tmp_path: Path) -> Path:
    """The room's bag, written with rosbags (no bulletnav code); returns the .mcap file."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS2_HUMBLE)
    Time = ts.types["builtin_interfaces/msg/Time"]
    Header = ts.types["std_msgs/msg/Header"]
    LaserScan = ts.types["sensor_msgs/msg/LaserScan"]
    Odometry = ts.types["nav_msgs/msg/Odometry"]
    PoseWithCovariance = ts.types["geometry_msgs/msg/PoseWithCovariance"]
    TwistWithCovariance = ts.types["geometry_msgs/msg/TwistWithCovariance"]
    Pose = ts.types["geometry_msgs/msg/Pose"]
    Point = ts.types["geometry_msgs/msg/Point"]
    Quaternion = ts.types["geometry_msgs/msg/Quaternion"]
    Twist = ts.types["geometry_msgs/msg/Twist"]
    Vector3 = ts.types["geometry_msgs/msg/Vector3"]
    TFMessage = ts.types["tf2_msgs/msg/TFMessage"]
    TransformStamped = ts.types["geometry_msgs/msg/TransformStamped"]
    Transform = ts.types["geometry_msgs/msg/Transform"]

    def header(ns: int, frame: str):
        return Header(stamp=Time(sec=ns // 10**9, nanosec=ns % 10**9), frame_id=frame)

    def quat(yaw: float):
        return Quaternion(x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2))

    out = tmp_path / "room_bag"
    rng = np.random.default_rng(5)
    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        scan_c = writer.add_connection("/front_scan", LaserScan.__msgtype__, typestore=ts)
        odom_c = writer.add_connection("/wheel_odom", Odometry.__msgtype__, typestore=ts)
        static_c = writer.add_connection("/tf_static", TFMessage.__msgtype__, typestore=ts)
        mount = TransformStamped(header=header(0, "base_footprint"), child_frame_id="front_laser",
                                 transform=Transform(translation=Vector3(x=MOUNT[0], y=MOUNT[1], z=0.2), rotation=quat(MOUNT[2])))
        writer.write(static_c, 0, ts.serialize_cdr(TFMessage(transforms=[mount]), TFMessage.__msgtype__))
        angle_min, inc = -math.pi, 2 * math.pi / RAYS
        for k in range(60):
            ns = 10**9 + k * 100_000_000  # 10 Hz from t = 1 s
            f = k / 59
            x, y, yaw = -1.8 + 3.6 * f, -0.6 + 1.2 * f, 0.3 * math.sin(4 * f)
            odom = Odometry(header=header(ns, "odom"), child_frame_id="base_footprint",
                            pose=PoseWithCovariance(pose=Pose(position=Point(x=x, y=y, z=0.0), orientation=quat(yaw)),
                                                    covariance=np.zeros(36)),
                            twist=TwistWithCovariance(twist=Twist(linear=Vector3(x=0.0, y=0.0, z=0.0),
                                                                  angular=Vector3(x=0.0, y=0.0, z=0.0)),
                                                      covariance=np.zeros(36)))
            writer.write(odom_c, ns, ts.serialize_cdr(odom, Odometry.__msgtype__))
            lx = x + math.cos(yaw) * MOUNT[0] - math.sin(yaw) * MOUNT[1]
            ly = y + math.sin(yaw) * MOUNT[0] + math.cos(yaw) * MOUNT[1]
            ranges = np.array([_cast(lx, ly, yaw + MOUNT[2] + angle_min + i * inc) for i in range(RAYS)])
            ranges += rng.normal(0.0, 0.005, RAYS)
            ranges[ranges > RANGE_MAX] = np.inf  # nothing within range
            ranges[rng.random(RAYS) < 0.05] = np.nan  # dropped returns
            ranges[rng.random(RAYS) < 0.02] = 0.05  # below range_min: no reading
            scan = LaserScan(header=header(ns + 20_000_000, "front_laser"), angle_min=angle_min,
                             angle_max=angle_min + (RAYS - 1) * inc, angle_increment=inc, time_increment=0.0,
                             scan_time=0.1, range_min=RANGE_MIN, range_max=RANGE_MAX,
                             ranges=ranges.astype(np.float32), intensities=np.zeros(0, dtype=np.float32))
            writer.write(scan_c, ns + 20_000_000, ts.serialize_cdr(scan, LaserScan.__msgtype__))
    files = list(out.glob("*.mcap"))
    assert len(files) == 1
    return files[0]


@pytest.fixture(scope="module")
def room_bag(tmp_path_factory):
    pytest.importorskip("rosbags")
    return _room_bag(tmp_path_factory.mktemp("bags"))


def _wall_distance(x: float, y: float) -> float:
    """Distance (m) from a point to the nearest of the room's four wall lines."""
    return min(abs(x - ROOM[0]), abs(x - ROOM[2]), abs(y - ROOM[1]), abs(y - ROOM[3]))


def test_independent_bag_maps_the_known_room(room_bag, tmp_path, capsys):
    png = tmp_path / "room.png"
    assert main(["map", str(room_bag), "--scan-topic", "/front_scan", "--odom-topic", "/wheel_odom",
                 "--out", str(png), "--plan-to", "-2.2", "1.4", "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["scans"] == 60 and summary["pose_source"] == "odometry"
    assert summary["path_found"] is True and png.stat().st_size > 0
    data = read_bag(room_bag, "/front_scan", "/wheel_odom")
    assert data.mounts["front_laser"] == pytest.approx(MOUNT, abs=1e-9)
    bag_map = build_map(data, resolution=0.1)
    m = bag_map.mapper
    state = m.state()
    res = m.resolution
    occupied = np.argwhere(state > 0)
    centres = [(m.x0 + (i + 0.5) * res, m.y0 + (j + 0.5) * res) for i, j in occupied]
    assert len(centres) > 100
    # every occupied cell lies within one cell of a wall (the hit's cell and the one behind it)
    worst = max(_wall_distance(x, y) for x, y in centres)
    assert worst <= res * math.sqrt(2) + 1e-9
    # each wall is found along its length (the part within range of the path)
    for axis, value, lo, hi in ((0, ROOM[0], -1.5, 1.5), (0, ROOM[2], -1.5, 1.5), (1, ROOM[1], -2.5, 2.5),
                                (1, ROOM[3], -2.5, 2.5)):
        along = np.arange(lo, hi, res) + res / 2
        found = 0
        for a in along:
            near = [(x, y) for x, y in centres if abs((x, y)[axis] - value) <= res and abs((x, y)[1 - axis] - a) <= res]
            found += bool(near)
        assert found / len(along) > 0.9, (axis, value)
    # inside the room: seen free, nothing occupied
    inside = [(x, y) for x, y in centres if ROOM[0] + 0.3 < x < ROOM[2] - 0.3 and ROOM[1] + 0.3 < y < ROOM[3] - 0.3]
    assert not inside
    path = plan_path(bag_map, (-2.2, 1.4))
    assert path is not None and all(_wall_distance(x, y) >= 0.2 - 1e-9 for x, y in path[1:-1])


def test_bulletnav_bag_maps_onto_the_true_map(tmp_path, capsys):
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.control.navigator import Navigator
    from bulletnav.ros.record import McapRecorder

    bag = tmp_path / "aisles.mcap"
    env = gym.make("bulletnav/WarehouseAisles-v0", max_episode_steps=300)
    nav = Navigator(env.unwrapped.scene)
    rec = McapRecorder(env, bag, plan=lambda: nav.path)
    obs, info = rec.reset(seed=2)
    nav.reset(info)
    truth = env.unwrapped.scene.occupancy(0.1)
    done = False
    while not done:
        obs, _, terminated, truncated, info = rec.step(nav.act(obs, info))
        done = terminated or truncated
    rec.close()
    bag_map = build_map(read_bag(bag), resolution=0.1)
    m = bag_map.mapper
    occupied = np.argwhere(m.state() > 0)
    assert len(occupied) > 50
    true_xy = np.array([truth.cell_to_world(i, j) for i, j in np.argwhere(truth.occupied)])
    near = 0
    for i, j in occupied:
        x, y = m.x0 + (i + 0.5) * m.resolution, m.y0 + (j + 0.5) * m.resolution
        near += np.min(np.hypot(true_xy[:, 0] - x, true_xy[:, 1] - y)) <= 0.25  # two cells: odometry drift
    assert near / len(occupied) > 0.9


def test_bad_bags_are_refused(room_bag, tmp_path, capsys):
    with pytest.raises(BulletnavError, match=r"no sensor_msgs/msg/LaserScan messages on /scan.*/front_scan"):
        read_bag(room_bag)  # the default topic is not in this bag: the error lists what is
    with pytest.raises(BulletnavError, match="/wheel_odom holds nav_msgs/msg/Odometry messages, not sensor_msgs"):
        read_bag(room_bag, scan_topic="/wheel_odom")
    with pytest.raises(BulletnavError, match="no pose for the scans"):
        read_bag(room_bag, scan_topic="/front_scan", odom_topic="/nothing")
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(room_bag.read_bytes()[: room_bag.stat().st_size // 2])
    with pytest.raises(BulletnavError, match=r"cut\.mcap: not a readable MCAP file"):
        read_bag(cut, "/front_scan", "/wheel_odom")
    with pytest.raises(BulletnavError, match="no such bag file"):
        read_bag(tmp_path / "missing.mcap")
    assert main(["map", str(tmp_path / "missing.mcap")]) == 2
    assert "missing.mcap" in capsys.readouterr().err


def test_map_png_has_a_legend_and_start_end_marks(room_bag, tmp_path):
    """The map's legend names the three cell states, the trajectory, its start and end, the path
    and the goal; the start mark stands where the first scan was taken, worked out here from the
    bag's odometry (10 Hz from 1 s, the scan 20 ms after its pose, interpolated) and the mount."""
    from bulletnav.ros.bagmap import MAP_GREYS, map_figure, write_map_png

    bag_map = build_map(read_bag(room_bag, "/front_scan", "/wheel_odom"), resolution=0.1)
    goal = (-2.2, 1.4)
    fig = map_figure(bag_map, plan_path(bag_map, goal), goal)
    ax = fig.axes[0]
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert labels == ["free cell", "occupied cell", "unknown cell", "lidar trajectory", "start (first scan)",
                      "end (last scan)", "A* path (from the end)", "goal"]
    greys = [p.get_facecolor()[0] for p in ax.get_legend().get_patches()[:3]]
    assert greys == pytest.approx([MAP_GREYS["free"], MAP_GREYS["occupied"], MAP_GREYS["unknown"]])
    marks = {line.get_gid(): (line.get_xdata()[0], line.get_ydata()[0]) for line in ax.get_lines() if line.get_gid()}
    f = 0.2 / 59  # the first scan: a fifth of the way from odometry pose 0 to pose 1 (f = k / 59)
    x, y, yaw = -1.8 + 3.6 * f, -0.6 + 1.2 * f, 0.3 * math.sin(4 * f)
    start = (x + math.cos(yaw) * MOUNT[0] - math.sin(yaw) * MOUNT[1], y + math.sin(yaw) * MOUNT[0] + math.cos(yaw) * MOUNT[1])
    assert marks["start"] == pytest.approx(start, abs=2e-3)
    assert marks["end"] == pytest.approx(bag_map.trajectory[-1]) and marks["end"][0] > 1.8  # the far end of the drive
    out = tmp_path / "map.png"
    write_map_png(bag_map, out, plan_path(bag_map, goal), goal)
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def _pose_by_search(poses, t):
    """``pose_at``'s rule by a linear search of the poses (the reference): the pose stamped
    ``t``; else the two around ``t``, interpolated (yaw along the shorter turn); else the first
    or last pose within 0.1 s; else None."""
    for s, pose in poses:
        if s == t:
            return pose
    before = [k for k, (s, _) in enumerate(poses) if s < t]
    after = [k for k, (s, _) in enumerate(poses) if s > t]
    if not before or not after:
        s, pose = poses[after[0]] if after else poses[before[-1]]
        return pose if abs(s - t) <= 100_000_000 else None
    (t0, a), (t1, b) = poses[before[-1]], poses[after[0]]
    f = (t - t0) / (t1 - t0)
    dyaw = math.remainder(b[2] - a[2], 2 * math.pi)
    return a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), math.remainder(a[2] + f * dyaw, 2 * math.pi)


def test_scans_take_the_poses_a_linear_search_gives():
    """``build_map`` lists the pose stamps once for all scans (it listed them again for every
    scan); every scan still takes the pose of :func:`_pose_by_search`, to the bit: at a pose's
    stamp, between two (yaw across +-pi too), within and beyond 0.1 s of either end."""
    # by hand: half-way from yaw 3.0 to -3.0 is the short way round, through pi
    x, y, yaw = pose_at([(0, (0.0, 0.0, 3.0)), (10**9, (1.0, 2.0, -3.0))], 5 * 10**8)
    assert (x, y) == (0.5, 1.0) and abs(yaw) == pytest.approx(math.pi)
    rng = np.random.default_rng(3)
    stamps = (10**9 + np.cumsum(rng.integers(1, 80_000_000, 200))).tolist()
    yaws = np.cumsum(rng.normal(0.0, 0.8, 200))
    poses = [(t, (float(rng.normal()), float(rng.normal()), math.remainder(float(w), 2 * math.pi)))
             for t, w in zip(stamps, yaws, strict=True)]
    times = [stamps[0] - 150_000_000, stamps[0] - 50_000_000, *stamps[::7],
             *rng.integers(stamps[0], stamps[-1], 60).tolist(), stamps[-1] + 50_000_000, stamps[-1] + 150_000_000]
    expected = [_pose_by_search(poses, t) for t in times]
    assert [pose_at(poses, t, stamps) for t in times] == [pose_at(poses, t) for t in times] == expected
    assert expected[0] is None and expected[-1] is None and expected[1] == poses[0][1]
    scans = [Scan(t, "laser", np.zeros(1), np.ones(1), 0.0, 5.0) for t in times]
    bag_map = build_map(BagData(scans, poses), margin=1.0)
    placed = [pose[:2] for pose in expected if pose is not None]
    assert (bag_map.scans_used, bag_map.scans_skipped) == (len(placed), len(times) - len(placed))
    assert bag_map.trajectory == placed



def test_scans_without_a_ray_direction_are_dropped_and_counted_and_careless_map_options_refused(room_bag, tmp_path,
                                                                                              capsys):
    """A scan whose angle_min or angle_increment is NaN or infinite has no ray direction: it is
    dropped and counted (the map was silently empty); a bag of only such scans is refused.
    ``--plan-to nan inf`` and ``--format ros --out x.png`` are one line each, exit 2."""
    from types import SimpleNamespace as NS

    from bulletnav.ros.bagmap import collect_bag

    def header(k: int, frame: str):
        return NS(stamp=NS(sec=1 + k // 10, nanosec=(k % 10) * 100_000_000), frame_id=frame)

    def stream(bad: set[int]):
        yield "", "sensor_msgs/msg/LaserScan", "/scan"
        yield "", "nav_msgs/msg/Odometry", "/odom"
        for k in range(10):
            pose = NS(position=NS(x=0.1 * k, y=0.0, z=0.0), orientation=NS(x=0.0, y=0.0, z=0.0, w=1.0))
            odom = NS(header=header(k, "odom"), child_frame_id="base_link", pose=NS(pose=pose))
            yield "/odom", "nav_msgs/msg/Odometry", lambda m=odom: m
            inc = math.nan if k in bad else 2 * math.pi / 90
            scan = NS(header=header(k, "base_link"), angle_min=-math.pi, angle_increment=inc, range_min=0.1,
                      range_max=8.0, ranges=[2.0] * 90)
            yield "/scan", "sensor_msgs/msg/LaserScan", lambda m=scan: m

    some = collect_bag(stream({2, 5, 7}), tmp_path / "b.mcap", "/scan", "/odom")
    assert some.scans_bad_geometry == 3 and len(some.scans) == 7
    with pytest.raises(BulletnavError, match=r"b\.mcap: every one of the 10 scans on /scan has a NaN or infinite "
                                             "angle_min or angle_increment"):
        collect_bag(stream(set(range(10))), tmp_path / "b.mcap", "/scan", "/odom")
    for argv, needle in ((["--plan-to", "nan", "inf"], "--plan-to: expected a finite coordinate in m"),
                         (["--format", "ros", "--out", str(tmp_path / "x.png")],
                          f"--out {tmp_path / 'x.png'}: --format ros writes STEM.yaml + STEM.pgm")):
        argv = ["map", str(room_bag), "--scan-topic", "/front_scan", "--odom-topic", "/wheel_odom", *argv]
        try:
            code = main(argv)
        except SystemExit as exc:  # argparse's own refusal
            code = exc.code
        err = capsys.readouterr().err.strip()
        assert code == 2 and err.count("\n") == 0 and needle in err, err
    assert not (tmp_path / "x.png.yaml").exists()
