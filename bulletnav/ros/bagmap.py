"""bulletnav's lidar mapper and planner on any ROS 2 bag: ``bulletnav map BAG.mcap``.

:func:`read_bag` reads the ``sensor_msgs/msg/LaserScan`` messages of one topic and the robot's
pose from a ``nav_msgs/msg/Odometry`` topic (or, without one, from ``/tf``: the chain from a
fixed frame to the scan's frame), with the schemas the file carries (``mcap_ros2``'s decoder:
nothing in the file is executed, only CDR data decoded against its message definitions).
:func:`build_map` places every scan at the lidar's pose (the odometry pose, interpolated to the
scan's stamp, composed with the ``/tf_static`` mount of the scan's frame when the bag has one)
and integrates it with :class:`~bulletnav.planning.mapping.LidarMapper`.

Any scan geometry is read: ``angle_min``, ``angle_increment``, any ray count. A range that is
NaN, below ``range_min`` or negative is no reading (skipped); ``+inf`` or at least ``range_max``
is a ray that hit nothing within range (free space along it), as REP 117 defines them.
"""

from __future__ import annotations

import bisect
import logging
import math
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import BulletnavError
from bulletnav.planning.mapping import LidarMapper
from bulletnav.ros.record import compose, message_yaw

log = logging.getLogger(__name__)

SCAN_TYPE = "sensor_msgs/msg/LaserScan"
ODOM_TYPE = "nav_msgs/msg/Odometry"
TF_TYPE = "tf2_msgs/msg/TFMessage"


@dataclass
class Scan:
    """One laser scan: stamp (ns), frame, ray angles (rad, in the scan's frame), ranges (m)."""

    stamp_ns: int
    frame: str
    angles: np.ndarray
    ranges: np.ndarray
    range_min: float
    range_max: float


@dataclass
class BagData:
    """What :func:`read_bag` found."""

    scans: list[Scan]
    poses: list[tuple[int, tuple[float, float, float]]]
    """(stamp ns, (x, y, yaw)) of the robot's base in the fixed frame, in time order."""
    mounts: dict[str, tuple[float, float, float]] = field(default_factory=dict)
    """Static 2-D pose of each sensor frame in the base frame (from ``/tf_static``)."""
    base_frame: str = "base_link"
    fixed_frame: str = "odom"
    pose_source: str = "odometry"
    scans_bad_geometry: int = 0
    """Scans dropped for a NaN or infinite ``angle_min`` or ``angle_increment`` (no ray has a
    direction then); the map is built from the others."""


def _stamp_ns(header: Any) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def read_bag(path: str | Path, scan_topic: str = "/scan", odom_topic: str = "/odom") -> BagData:
    """Read scans and poses from the MCAP file ``path``.

    Raises:
        BulletnavError: the file is missing, not MCAP or truncated; the scan topic is missing or
            not ``LaserScan``; neither the odometry topic nor ``/tf`` gives a pose.
    """
    path = Path(path)
    if not path.is_file():
        raise BulletnavError(f"{path}: no such bag file")
    return collect_bag(_mcap_messages(path, scan_topic, odom_topic), path, scan_topic, odom_topic)


def _mcap_messages(path: Path, scan_topic: str, odom_topic: str) -> Iterator[tuple[str, str, Any]]:
    """An MCAP file's messages on the topics :func:`collect_bag` reads, as its stream: each topic's
    type announced first (from the summary, else at its first message; ``untyped`` without a
    schema); a truncated or corrupt file is a :class:`BulletnavError`."""
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    try:
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            summary = reader.get_summary()
            announced: set[str] = set()
            if summary is not None:
                for c in summary.channels.values():
                    announced.add(c.topic)
                    yield "", summary.schemas[c.schema_id].name if c.schema_id in summary.schemas else "no schema", c.topic
            for schema, channel, _message, msg in reader.iter_decoded_messages(
                    topics=[scan_topic, odom_topic, "/tf", "/tf_static"], log_time_order=True):
                if channel.topic not in announced:
                    announced.add(channel.topic)
                    yield "", schema.name if schema else "", channel.topic
                yield channel.topic, schema.name if schema else "untyped", lambda msg=msg: msg
    except McapError as exc:
        raise BulletnavError(f"{path}: not a readable MCAP file ({exc})") from exc
    except (EOFError, ValueError, KeyError, IndexError) as exc:  # a truncated or corrupt record
        raise BulletnavError(f"{path}: not a readable MCAP file ({type(exc).__name__}: {exc})") from exc


def collect_bag(stream: Iterator[tuple[str, str, Any]], path: Path, scan_topic: str, odom_topic: str) -> BagData:
    """A bag's scans and poses from its messages as ``(topic, type, decode)`` in log-time order
    (``decode()`` gives the message; ``("", type, topic)`` announces a topic's type for the
    messages naming what the bag holds): the one collector of every bag format (MCAP here, ROS 1
    and ROS 2 bags in :mod:`bulletnav.ros.bags`)."""
    scans: list[Scan] = []
    odom: list[tuple[int, tuple[float, float, float]]] = []
    odom_frames: tuple[str, str] | None = None
    tf: dict[tuple[str, str], list[tuple[int, tuple[float, float, float]]]] = {}
    mounts: dict[tuple[str, str], tuple[float, float, float]] = {}
    types: dict[str, str] = {}
    bad_geometry = 0
    for topic, typ, decode in stream:
        if not topic:  # a topic's announcement: (``""``, type, name)
            types[decode] = typ
            continue
        if topic == scan_topic:
            if typ != SCAN_TYPE:
                raise BulletnavError(f"{path}: topic {scan_topic} holds {typ} messages, not {SCAN_TYPE}")
            msg = decode()
            if not (math.isfinite(float(msg.angle_min)) and math.isfinite(float(msg.angle_increment))):
                bad_geometry += 1  # no ray has a direction: dropped, and counted
                continue
            n = len(msg.ranges)
            angles = float(msg.angle_min) + float(msg.angle_increment) * np.arange(n)
            scans.append(Scan(_stamp_ns(msg.header), msg.header.frame_id, angles, np.asarray(msg.ranges, dtype=np.float64),
                              float(msg.range_min), float(msg.range_max)))
        elif topic == odom_topic:
            if typ != ODOM_TYPE:
                raise BulletnavError(f"{path}: topic {odom_topic} holds {typ} messages, not {ODOM_TYPE}")
            msg = decode()
            p = msg.pose.pose
            odom.append((_stamp_ns(msg.header), (float(p.position.x), float(p.position.y), message_yaw(p.orientation))))
            odom_frames = (msg.header.frame_id, msg.child_frame_id)
        elif topic in ("/tf", "/tf_static") and typ == TF_TYPE:
            for t in decode().transforms:
                tr = t.transform
                pose2d = (float(tr.translation.x), float(tr.translation.y), message_yaw(tr.rotation))
                key = (t.header.frame_id, t.child_frame_id)
                if topic == "/tf_static":
                    mounts[key] = pose2d
                else:
                    tf.setdefault(key, []).append((_stamp_ns(t.header), pose2d))
    have = ", ".join(f"{t} ({k})" for t, k in sorted(types.items())) or "none"
    if not scans and bad_geometry:
        raise BulletnavError(f"{path}: every one of the {bad_geometry} scans on {scan_topic} has a NaN or infinite "
                             "angle_min or angle_increment: no ray has a direction")
    if not scans:
        raise BulletnavError(f"{path}: no {SCAN_TYPE} messages on {scan_topic} (topics: {have}); "
                             "name the scan topic with --scan-topic")
    scans.sort(key=lambda s: s.stamp_ns)
    if odom:
        fixed, base = odom_frames or ("odom", "base_link")
        sensor_mounts = {child: pose for (parent, child), pose in mounts.items() if parent == base}
        return BagData(scans, sorted(odom), sensor_mounts, base, fixed, "odometry", bad_geometry)
    poses = _tf_poses(tf, mounts, scans[0].frame)
    if poses is None:
        raise BulletnavError(f"{path}: no pose for the scans: no {ODOM_TYPE} on {odom_topic} and no /tf chain to the "
                             f"scan frame {scans[0].frame!r} (topics: {have}); name the odometry topic with --odom-topic")
    fixed, chain_poses = poses
    return BagData(scans, chain_poses, {}, scans[0].frame, fixed, "tf", bad_geometry)



def _tf_poses(tf: dict, mounts: dict, frame: str) -> tuple[str, list] | None:
    """The pose of ``frame`` in the root of its /tf tree at every stamp of the chain's last
    dynamic transform (static links from ``mounts``); None without a dynamic link."""
    parents = {child: (parent, "tf") for (parent, child) in tf}
    parents.update({child: (parent, "static") for (parent, child) in mounts if child not in parents})
    chain = []
    node = frame
    while node in parents and len(chain) < 32:
        parent, kind = parents[node]
        chain.append((parent, node, kind))
        node = parent
    dynamic = [(p, c) for p, c, k in chain if k == "tf"]
    if not dynamic:
        return None
    stamps = sorted({t for key in dynamic for t, _ in tf[key]})
    link_stamps = {key: [t for t, _ in tf[key]] for key in dynamic}  # each link's stamps, listed once
    out = []
    for t in stamps:
        pose = (0.0, 0.0, 0.0)
        for parent, child, kind in reversed(chain):  # root first
            key = (parent, child)
            link = mounts[key] if kind == "static" else _held(tf[key], t, link_stamps[key])
            if link is None:
                break
            pose = compose(pose, link)
        else:
            out.append((t, pose))
    return (node, out) if out else None


def _held(series: list[tuple[int, tuple[float, float, float]]], t: int,
          stamps: list[int]) -> tuple[float, float, float] | None:
    """The last value at or before ``t`` (None before the first); ``stamps``: the series' stamps."""
    i = bisect.bisect_right(stamps, t) - 1
    return series[i][1] if i >= 0 else None


def pose_at(poses: list[tuple[int, tuple[float, float, float]]], t: int,
            stamps: list[int] | None = None) -> tuple[float, float, float] | None:
    """The pose at ``t`` (ns), interpolated linearly between the two around it (yaw along the
    shorter turn); None outside the poses' time span by more than 0.1 s. ``stamps``: the poses'
    stamps (``[s for s, _ in poses]``), listed once by a caller that asks for many times."""
    if not poses:
        return None
    if stamps is None:
        stamps = [s for s, _ in poses]
    i = bisect.bisect_left(stamps, t)
    if i < len(stamps) and stamps[i] == t:
        return poses[i][1]
    if i == 0 or i == len(stamps):
        j = 0 if i == 0 else len(stamps) - 1
        return poses[j][1] if abs(stamps[j] - t) <= 100_000_000 else None
    (t0, a), (t1, b) = poses[i - 1], poses[i]
    f = (t - t0) / (t1 - t0)
    dyaw = math.remainder(b[2] - a[2], 2 * math.pi)
    return a[0] + f * (b[0] - a[0]), a[1] + f * (b[1] - a[1]), math.remainder(a[2] + f * dyaw, 2 * math.pi)


@dataclass
class BagMap:
    """The map built from a bag."""

    mapper: LidarMapper
    scans_used: int
    scans_skipped: int
    trajectory: list[tuple[float, float]]
    """The lidar's positions (m) where scans were integrated."""
    poses_skipped: int = 0
    """Poses of the bag with a NaN or infinite x, y or yaw: dropped before any scan is placed
    (a scan whose time only such poses cover counts in ``scans_skipped``)."""


def build_map(data: BagData, resolution: float = 0.1, margin: float | None = None) -> BagMap:
    """Integrate every scan of ``data`` at its lidar pose (see the module docstring).

    The grid covers the trajectory grown by the largest finite ``range_max`` (capped at 30 m;
    10 m when no scan gives one), or by ``margin`` (m). Poses with a NaN or infinite value are
    dropped and counted (``poses_skipped``, logged as a warning).

    Raises:
        BulletnavError: no scan has a finite pose.
        LimitError: the grid would pass the limits ``map_extent`` or ``map_cells``
            (:mod:`bulletnav.limits`; the message names the variable that raises it).
    """
    poses = [(t, p) for t, p in data.poses if all(math.isfinite(v) for v in p)]
    bad_poses = len(data.poses) - len(poses)
    if bad_poses:
        log.warning("%d of %d %s poses have a NaN or infinite value: dropped", bad_poses, len(data.poses), data.pose_source)
    stamps = [t for t, _ in poses]
    placed = []
    skipped = 0
    for scan in data.scans:
        base = pose_at(poses, scan.stamp_ns, stamps)
        pose = None if base is None else compose(base, data.mounts.get(scan.frame, (0.0, 0.0, 0.0)))
        if pose is None or not all(math.isfinite(v) for v in pose):
            skipped += 1
            continue
        placed.append((pose, scan))
    if not placed:
        dropped = f" ({bad_poses} of {len(data.poses)} not finite, dropped)" if bad_poses else ""
        raise BulletnavError(f"no scan has a pose: the {data.pose_source} poses{dropped} span "
                             f"{(poses[0][0] if poses else 0) / 1e9:.3f}-"
                             f"{(poses[-1][0] if poses else 0) / 1e9:.3f} s, the scans do not fall in it")
    finite = [s.range_max for _, s in placed if math.isfinite(s.range_max) and s.range_max > 0]
    reach = margin if margin is not None else (min(max(finite), 30.0) if finite else 10.0)
    xs = [p[0] for p, _ in placed]
    ys = [p[1] for p, _ in placed]
    mapper = LidarMapper((min(xs) - reach, min(ys) - reach, max(xs) + reach, max(ys) + reach), resolution)
    for pose, scan in placed:
        r = scan.ranges
        valid = ~np.isnan(r) & (r >= max(scan.range_min, 0.0))
        max_range = scan.range_max if math.isfinite(scan.range_max) else reach
        ranges = np.where(np.isposinf(r) | (r >= max_range), max_range, r)[valid]
        mapper.integrate(pose, scan.angles[valid], ranges, max_range)
    return BagMap(mapper, len(placed), skipped, [(p[0], p[1]) for p, _ in placed], bad_poses)


def plan_path(bag_map: BagMap, goal: tuple[float, float], radius: float = 0.2) -> list[tuple[float, float]] | None:
    """A* on the map (occupied cells grown by ``radius``; unknown counts as free) from the
    last scan's position to ``goal``; None when there is no path."""
    from bulletnav.planning.astar import astar

    grid = bag_map.mapper.grid().inflate(radius)
    return astar(grid, bag_map.trajectory[-1], goal)


MAP_GREYS = {"free": 1.0, "occupied": 0.0, "unknown": 0.75}
"""The map PNG's cell shades (0 black .. 1 white), named in its legend."""
START_COLOUR, END_COLOUR = "#009e73", "#d55e00"
"""The first and last scan positions' marks (Okabe-Ito green and vermilion: told apart by
colour-blind readers, and by shape: a ring and a filled square)."""


def write_map_png(bag_map: BagMap, out: str | Path, path: list[tuple[float, float]] | None = None,
                  goal: tuple[float, float] | None = None, title: str = "") -> None:
    """:func:`map_figure` as a PNG, written beside ``out`` and renamed."""
    from bulletnav.files import save_figure

    fig = map_figure(bag_map, path, goal, title)
    save_figure(fig, out, format="png", dpi=100, bbox_inches="tight")  # the legend beside the map whole


def map_figure(bag_map: BagMap, path: list[tuple[float, float]] | None = None,
               goal: tuple[float, float] | None = None, title: str = "") -> Any:
    """The map (unknown grey, free white, occupied black), the lidar's trajectory with its start
    (first scan: ring) and end (last scan: square), the planned path and its goal, and a legend
    beside the map naming each: a matplotlib ``Figure``, not attached to pyplot."""
    from matplotlib.figure import Figure
    from matplotlib.lines import Line2D
    from matplotlib.patches import Patch

    m = bag_map.mapper
    state = m.state()
    img = np.where(state < 0, MAP_GREYS["unknown"], np.where(state > 0, MAP_GREYS["occupied"], MAP_GREYS["free"])).T
    extent = (m.x0, m.x0 + m.nx * m.resolution, m.y0, m.y0 + m.ny * m.resolution)
    fig = Figure(figsize=(10.5, 8 * (extent[3] - extent[2]) / max(extent[1] - extent[0], 1e-9) + 0.6), layout="tight")
    ax = fig.add_subplot()
    ax.imshow(img, origin="lower", extent=extent, cmap="gray", vmin=0.0, vmax=1.0, interpolation="nearest")
    tx, ty = zip(*bag_map.trajectory)
    handles = [Patch(facecolor=str(MAP_GREYS[k]), edgecolor="0.3", label=f"{k} cell") for k in ("free", "occupied", "unknown")]
    handles += ax.plot(tx, ty, color="#0072b2", lw=1.2, label="lidar trajectory")
    ax.plot([tx[0]], [ty[0]], ls="none", marker="o", ms=10, mfc="none", mec=START_COLOUR, mew=2.5, zorder=5, gid="start")
    ax.plot([tx[-1]], [ty[-1]], ls="none", marker="s", ms=8, mfc=END_COLOUR, mec="black", mew=0.8, zorder=5, gid="end")
    handles += [Line2D([], [], ls="none", marker="o", ms=10, mfc="none", mec=START_COLOUR, mew=2.5,
                       label="start (first scan)"),
                Line2D([], [], ls="none", marker="s", ms=8, mfc=END_COLOUR, mec="black", mew=0.8,
                       label="end (last scan)")]
    if path:
        px, py = zip(*path)
        handles += ax.plot(px, py, color="#cc79a7", lw=2.0, label="A* path (from the end)")
    if goal is not None:
        handles += ax.plot([goal[0]], [goal[1]], marker="*", color="#e69f00", mec="black", mew=0.6, ms=15, ls="none",
                           label="goal")
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_title(title or f"{bag_map.scans_used} scans, {m.resolution:g} m cells")
    ax.legend(handles=handles, loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=9, frameon=False,
              title=f"{m.resolution:g} m cells", title_fontsize=9)
    return fig


__all__ = ["MAP_GREYS", "BagData", "BagMap", "Scan", "build_map", "map_figure", "plan_path", "pose_at", "read_bag", "write_map_png"]
