"""``--live``: the Foxglove WebSocket server a command streams its run to (:mod:`bulletnav.ros.live`)."""

from __future__ import annotations

import argparse
import sys

from bulletnav.errors import BulletnavError


def start_live(args: argparse.Namespace):
    """The :class:`~bulletnav.ros.live.LiveServer` ``args.live`` asks for (None without ``--live``),
    announced in one line (on stderr under ``--json``, whose stdout is the document alone).

    Raises:
        BulletnavError: ``--speed`` without ``--live``; the port cannot be bound.
    """
    live, speed = getattr(args, "live", None), getattr(args, "speed", None)
    control = bool(getattr(args, "live_control", False))
    if live is None:
        if speed is not None:
            raise BulletnavError("--speed paces a live stream: give --live [HOST:]PORT too")
        if control:
            raise BulletnavError("--live-control drives the robot from Foxglove: give --live [HOST:]PORT too")
        return None
    if getattr(args, "live_allow_origin", None) and not control:
        raise BulletnavError("--live-allow-origin says which web pages may drive the robot: give --live-control too")
    from bulletnav.ros.live import LAYOUT, LiveServer, OriginPolicy

    policy = OriginPolicy.of(getattr(args, "live_allow_origin", None)) if control else None
    server = LiveServer(live, 1.0 if speed is None else speed, control=policy)
    pace = "as fast as it goes" if server.speed == 0 else ("real time" if server.speed == 1 else f"{server.speed:g} x real time")
    loopback = server.host in ("127.0.0.1", "localhost", "::1")
    if loopback:
        exposed = ""
    elif control:
        exposed = (f"; listening on {server.host}: ANYONE WHO REACHES THIS PORT CAN DRIVE THE ROBOT (no password, no "
                   "encryption; only web pages of other sites are refused)")
    else:
        exposed = f"; listening on {server.host}: anyone who reaches this port can watch (no password, no encryption)"
    notes = sys.stderr if getattr(args, "json", False) else sys.stdout
    print(f"live: {server.url} ({pace}){exposed}; in Foxglove: Open connection -> Foxglove WebSocket -> {server.url}; "
          f"layout: {LAYOUT}", file=notes, flush=True)
    return server
