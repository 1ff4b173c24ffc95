"""ROS recordings: ``map`` (bulletnav's lidar mapper on a bag: MCAP, ROS 1 .bag or ROS 2 .db3; the map
as a PNG or as Nav2's map_server YAML + PGM) and ``replay`` (a ``--record`` file drawn from the file alone)."""

from __future__ import annotations

import argparse
import math

import numpy as np

from bulletnav.cli.args import (
    PNG_FILE,
    VIDEO_FILE,
    add_command,
    add_overwrite_arg,
    finite_metres,
    non_negative_seconds,
    positive_seconds,
)
from bulletnav.cli.output import print_json, refuse_existing_file, refuse_existing_files


def register(sub) -> None:
    """Add ``map`` and ``replay`` to ``sub`` (``build_parser``'s subparsers)."""
    _register_map(sub)
    _register_replay(sub)


def _register_map(sub) -> None:
    mp = add_command(sub, "map", "bulletnav's lidar mapper (and A*) on a ROS bag's LaserScan and Odometry (or TF)")
    mp.add_argument("bag", metavar="BAG", help="a ROS 2 MCAP file, a ROS 1 .bag, or a ROS 2 sqlite3 .db3 (or its bag folder)")
    mp.add_argument("--scan-topic", default="/scan", help="sensor_msgs/msg/LaserScan topic (default /scan)")
    mp.add_argument("--odom-topic", default="/odom",
                    help="nav_msgs/msg/Odometry topic (default /odom; without it the /tf chain to the scan's frame)")
    mp.add_argument("--resolution", type=cell_metres, default=0.1, metavar="M", help="cell size in m (default 0.1)")
    mp.add_argument("--out", default=None, metavar="PATH",
                    help="write the map: a PNG with the path (--format png), or STEM.yaml + STEM.pgm (--format ros)")
    mp.add_argument("--format", choices=("png", "ros"), default="png",
                    help="--out as a PNG picture (default), or as ros: the map YAML and PGM Nav2's map_server reads")
    mp.add_argument("--plan-to", type=finite_metres, nargs=2, metavar=("X", "Y"), default=None,
                    help="plan an A* path on the map from the last scan's position to (X, Y) m")
    mp.add_argument("--json", action="store_true", help="print one JSON object")
    add_overwrite_arg(mp, "--out files")
    mp.set_defaults(func=cmd_map)


CELL_METRES = (0.001, 10.0)
"""The cell sizes ``map --resolution`` takes (m); the grid's size is bounded by the limits
``map_extent`` and ``map_cells`` (:mod:`bulletnav.limits`)."""


def cell_metres(text: str) -> float:
    """``map --resolution``: a cell size in metres, a finite number in :data:`CELL_METRES`."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not CELL_METRES[0] <= value <= CELL_METRES[1]:  # NaN fails too
        raise argparse.ArgumentTypeError(f"expected a cell size in metres from {CELL_METRES[0]:g} to {CELL_METRES[1]:g}, "
                                         f"got {text!r}")
    return value


def _register_replay(sub) -> None:
    rp = add_command(sub, "replay", "draw a recorded episode (a --record MCAP file) from the file alone: the live video and plot")
    rp.add_argument("recording", metavar="PATH.mcap", help="a recording written by --record")
    rp.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="write the episodes' video (.mp4 or .gif)")
    rp.add_argument("--plot", type=PNG_FILE, metavar="PNG", help="write every episode's path over its map")
    rp.add_argument("--frame", type=PNG_FILE, metavar="PNG",
                    help="write one frame of the first episode's video (see --frame-at)")
    rp.add_argument("--frame-at", type=non_negative_seconds, default=None, metavar="S",
                    help="simulated seconds into the first episode of the --frame (default: its middle)")
    rp.add_argument("--panel", type=PNG_FILE, metavar="PNG",
                    help="draw what the shipped Foxglove layout's 3D panel shows (top-down, from the messages) at --panel-at")
    rp.add_argument("--panel-at", type=positive_seconds, default=None, metavar="S",
                    help="simulated seconds into the first episode for --panel (default: its middle)")
    rp.add_argument("--json", action="store_true", help="print one JSON object")
    add_overwrite_arg(rp, "--video, --plot, --frame and --panel files")
    rp.set_defaults(func=cmd_replay)


def cmd_map(args: argparse.Namespace) -> int:
    """Map a ROS 2 bag with bulletnav's lidar mapper; optionally plan on it."""
    from bulletnav.ros.bagmap import build_map, plan_path, read_bag, write_map_png
    from bulletnav.ros.bags import is_rosbag, read_rosbag
    from bulletnav.sim.mapserver import write_map

    out = _map_out(args)
    read = read_rosbag if is_rosbag(args.bag) else read_bag
    data = read(args.bag, scan_topic=args.scan_topic, odom_topic=args.odom_topic)
    bag_map = build_map(data, resolution=args.resolution)
    goal = tuple(args.plan_to) if args.plan_to else None
    path = plan_path(bag_map, goal) if goal else None
    if args.out and args.format == "ros":
        m = bag_map.mapper
        write_map(out[0][:-5], m.state(), m.resolution, (m.x0, m.y0))
    elif args.out:
        write_map_png(bag_map, args.out, path, goal, title=f"{args.bag}: {bag_map.scans_used} scans")
    state = bag_map.mapper.state()
    summary = {"bag": str(args.bag), "scan_topic": args.scan_topic, "pose_source": data.pose_source,
               "fixed_frame": data.fixed_frame, "scans": bag_map.scans_used, "scans_without_pose": bag_map.scans_skipped,
               "poses_skipped": bag_map.poses_skipped, "scans_bad_geometry": data.scans_bad_geometry,
               "resolution_m": args.resolution, "cells": list(state.shape),
               "occupied_cells": int((state > 0).sum()), "free_cells": int((state == 0).sum()),
               "plan_to": list(goal) if goal else None, "path_found": None if goal is None else path is not None,
               "path_length_m": (None if not path else float(sum(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(path, path[1:])))),
               "out": out}
    if args.json:
        print_json(summary)
        return 0
    print(f"{args.bag}: {bag_map.scans_used} scans on {args.scan_topic} placed by {data.pose_source} "
          f"({data.fixed_frame} frame), {summary['occupied_cells']} occupied and {summary['free_cells']} free cells "
          f"of {args.resolution:g} m")
    if bag_map.poses_skipped:
        print(f"{bag_map.poses_skipped} of the bag's poses have a NaN or infinite value: dropped")
    if data.scans_bad_geometry:
        print(f"{data.scans_bad_geometry} scans have a NaN or infinite angle_min or angle_increment: dropped")
    if goal:
        print(f"A* to ({goal[0]:g}, {goal[1]:g}): " + (f"{summary['path_length_m']:.2f} m" if path else "no path"))
    if args.out:
        print(f"map: {' + '.join(out)}" if args.format == "ros" else f"map: {out}")
    return 0


def _map_out(args: argparse.Namespace) -> str | list[str] | None:
    """``map --out`` checked against ``--format`` (existing files refused without --overwrite):
    the PNG's path, or the YAML's and PGM's paths of the STEM (a .yaml or .pgm suffix dropped)."""
    from bulletnav.errors import ConfigError

    if not args.out:
        if args.format == "ros":
            raise ConfigError("--format ros writes STEM.yaml + STEM.pgm: pass --out STEM")
        return None
    if args.format == "png":
        try:
            PNG_FILE(args.out)
        except argparse.ArgumentTypeError as exc:
            raise ConfigError(f"--out {exc} (or pass --format ros for a map_server map)") from None
        refuse_existing_files(args, "out")
        return args.out
    lower = args.out.lower()
    if lower.endswith((".png", ".jpg", ".jpeg", ".ppm", ".pbm")):
        raise ConfigError(f"--out {args.out}: --format ros writes STEM.yaml + STEM.pgm (map_server's PGM): pass the "
                          f"stem, e.g. --out {args.out.rsplit('.', 1)[0]}")
    stem = args.out[:-4] if lower.endswith((".pgm", ".yml")) else args.out
    stem = stem[:-5] if stem.lower().endswith(".yaml") else stem
    out = [stem + ".yaml", stem + ".pgm"]
    for file in out:
        refuse_existing_file("out", file, args.overwrite)
    return out


def cmd_replay(args: argparse.Namespace) -> int:
    """Draw a recording's episodes from the file alone."""
    import tempfile
    from pathlib import Path

    from bulletnav.ros.replay import panel_view, replay

    if args.frame_at is not None and not args.frame:
        from bulletnav.errors import ConfigError

        raise ConfigError("--frame-at is the time of the --frame PNG: pass --frame too")
    refuse_existing_files(args, "video", "plot", "frame", "panel")
    if args.panel and not (args.video or args.plot or args.frame):
        summary = {"recording": args.recording, "panel": panel_view(args.recording, args.panel, at_s=args.panel_at)}
        if args.json:
            print_json(summary)
        else:
            print(f"panel: {args.panel} (t = {summary['panel']['time_s']:.2f} s)")
        return 0
    video = args.video
    scratch = None
    if args.frame and not video:
        scratch = tempfile.mkdtemp(prefix="bulletnav-replay-")
        video = str(Path(scratch) / "replay.mp4")
    try:
        summary = replay(args.recording, video=video, plot=args.plot, frame=args.frame, frame_at_s=args.frame_at)
    finally:
        if scratch is not None:
            import shutil

            shutil.rmtree(scratch, ignore_errors=True)
    if args.panel:
        summary["panel"] = panel_view(args.recording, args.panel, at_s=args.panel_at)["out"]
    if not args.video:
        summary["video"] = None
    if args.json:
        print_json(summary)
        return 0
    print(f"{args.recording}: {summary['episodes']} episodes, steps {summary['steps']}, outcomes {summary['outcomes']}")
    for key in ("video", "plot", "frame", "panel"):
        if summary.get(key):
            at = f" (episode 1 at {summary['frame_time_s']:.2f} s, step {summary['frame_step']})" if key == "frame" else ""
            print(f"{key}: {summary[key]}{at}")
    return 0
