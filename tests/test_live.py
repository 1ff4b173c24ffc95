"""The live stream (``--live``, :mod:`bulletnav.ros.live`) as a Foxglove app receives it.

Every check reads the stream with ``tests/foxglove_client.py``: a client written from the
published Foxglove WebSocket protocol with the ``websockets`` library, decoding CDR with
mcap-ros2-support's decoder from the schemas the server advertises (no bulletnav or foxglove-sdk
code). The references: the env's own sensors at the same step, the URDF mounts, an unstreamed run
of the same seed and actions (bit for bit), and a recording made with the stream (byte for byte).
"""

from __future__ import annotations

import socket

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401
from bulletnav.errors import BulletnavError
from bulletnav.ros.live import LiveServer, parse_address
from bulletnav.ros.record import McapRecorder
from foxglove_client import FoxgloveClient
from hang import HANG_S

ACTIONS = [np.array([0.8, 0.3 * np.sin(k / 5)], dtype=np.float32) for k in range(60)]


def _wait_watched(live: LiveServer, topics, clients: int = 1) -> None:
    """Until the server has taken in ``clients`` subscriptions to each topic (a subscribe has no
    acknowledgement)."""
    import time

    end = time.monotonic() + HANG_S
    while not all(t in live.topics and live.watched(t) and live.subscriptions(t) >= clients for t in topics):
        assert time.monotonic() < end, f"subscriptions to {topics} not taken in: a hang?"
        time.sleep(0.01)


def _plain_run(seed: int) -> list[np.ndarray]:
    env = gym.make("bulletnav/Warehouse-v0")
    try:
        obs, _ = env.reset(seed=seed)
        out = [obs]
        for a in ACTIONS:
            obs, *_ = env.step(a)
            out.append(obs)
        return out
    finally:
        env.close()


def test_live_stream_is_the_env_step_by_step(tmp_path):
    """``/scan`` at each step is the env's lidar at that step and ``/odom`` its odometry; a client
    that joins after the reset still gets ``/tf_static`` and ``/map_truth``; two clients both get
    every message; one leaving mid-run changes nothing; the episode is bit for bit the unstreamed
    one; and a recording made with the stream holds the same bytes."""
    from mcap.reader import make_reader

    seed = 11
    live = LiveServer("127.0.0.1:0", speed=0)
    env = McapRecorder(gym.make("bulletnav/Warehouse-v0"), tmp_path / "run.mcap", live=live)
    a = b = None
    try:
        obs, _ = env.reset(seed=seed)
        observations = [obs]
        scene = env.unwrapped.scene
        obs, *_ = env.step(ACTIONS[0])  # every per-step topic is advertised now
        observations.append(obs)
        topics = ["/scan", "/odom", "/tf_static", "/map_truth", "/goal_pose"]
        a, b = FoxgloveClient(live.url), FoxgloveClient(live.url)
        a.subscribe(topics)
        b.subscribe(["/scan"])
        _wait_watched(live, topics)
        _wait_watched(live, ["/scan"], clients=2)  # b's too, or b may miss the first scans
        lidar, odometry, expected = scene.sensors.lidar, scene.sensors.odometry, {}
        for k, action in enumerate(ACTIONS[1:], 2):
            obs, *_ = env.step(action)
            observations.append(obs)
            ns = int(round(k * scene.control_dt * 1e9))
            expected[ns] = (lidar.read().astype(np.float32), odometry.read())
            if k == 30:  # b leaves mid-run, having had the scans so far
                b.wait_for(lambda ms: len(ms) >= 29, topic="/scan")
                b.close()
        a.wait_for(lambda ms: len(ms) >= len(expected), topic="/scan")
        geometry = scene.geometry
    finally:
        env.close()
        live.close()
        for c in (a, b):
            if c is not None:
                c.close()
    assert a.errors == [] and b.errors == []
    assert a.subprotocol == "foxglove.sdk.v1"
    scans = {m.log_time_ns: m.decoded for m in a.messages("/scan")}
    assert set(expected) <= set(scans)
    for ns, (ranges, _) in expected.items():
        scan = scans[ns]
        assert scan.header.stamp.sec * 10**9 + scan.header.stamp.nanosec == ns
        assert np.array_equal(np.asarray(scan.ranges, dtype=np.float32), ranges)
    odoms = {m.log_time_ns: m.decoded for m in a.messages("/odom")}
    for ns, (_, odo) in expected.items():
        p = odoms[ns].pose.pose.position
        assert (p.x, p.y) == pytest.approx((odo[0], odo[1]), abs=1e-12)
        assert odoms[ns].twist.twist.linear.x == pytest.approx(odo[3], abs=1e-12)
    # late join: the reset's latched messages arrived although sent before a subscribed
    static = a.messages("/tf_static")[0].decoded.transforms[0]
    assert static.child_frame_id == "laser"
    assert (static.transform.translation.x, static.transform.translation.z) == pytest.approx(
        (geometry.lidar_mount[0], geometry.lidar_mount[2]))
    grid = a.messages("/map_truth")[0].decoded
    assert grid.info.resolution == pytest.approx(0.1) and len(grid.data) == grid.info.width * grid.info.height > 0
    assert a.messages("/goal_pose") and a.messages("/goal_pose")[0].log_time_ns == 0
    # the second client: every scan from its subscription to its leaving, the same bytes as a's
    b_scans = {m.log_time_ns: m.payload for m in b.messages("/scan")}
    assert len(b_scans) >= 29
    assert all(b_scans[ns] == m.payload for m in a.messages("/scan") for ns in [m.log_time_ns] if ns in b_scans)
    # streaming changed nothing: the same episode as without it
    plain = _plain_run(seed)
    assert all(np.array_equal(x, y) for x, y in zip(observations, plain)) and len(observations) == len(plain)
    # one encoder: the recording's /scan bytes are the streamed ones
    with open(tmp_path / "run.mcap", "rb") as f:
        recorded = {m.log_time: m.data for _, ch, m in make_reader(f).iter_messages(topics=["/scan"])}
    assert all(recorded[m.log_time_ns] == m.payload for m in a.messages("/scan"))


def test_unwatched_topics_are_not_built():
    """With no client, per-step topics are advertised once and then not built (a stream nobody
    watches costs little); latched ones are kept for later clients."""
    live = LiveServer("127.0.0.1:0", speed=0)
    env = McapRecorder(gym.make("bulletnav/Warehouse-v0"), None, live=live)
    try:
        env.reset(seed=3)
        for a in ACTIONS[:10]:
            env.step(a)
        counts = dict(env.counts)
    finally:
        env.close()
        live.close()
    assert counts["/scan"] == counts["/odom"] == counts["/clock"] == 1  # the first step advertises them
    assert counts["/tf_static"] == counts["/map_truth"] == 1 and counts["/goal_pose"] >= 1


def test_subscriptions_count_each_client():
    """``subscriptions(topic)`` counts the clients subscribed: up on each subscribe, down on an
    unsubscribe and on a client leaving without one (what the step-by-step test waits on)."""
    import time

    def settles(n: int) -> bool:
        end = time.monotonic() + HANG_S
        while live.subscriptions("/x") != n and time.monotonic() < end:
            time.sleep(0.01)
        return live.subscriptions("/x") == n

    live = LiveServer("127.0.0.1:0", speed=0)
    a = b = None
    try:
        live.write_encoded("/x", "std_msgs/Float64", b"\x00\x01\x00\x00" + bytes(8), 0)  # advertises /x
        assert live.subscriptions("/x") == 0 and live.subscriptions("/never") == 0
        a, b = FoxgloveClient(live.url), FoxgloveClient(live.url)
        a.subscribe(["/x"])
        b.subscribe(["/x"])
        assert settles(2)
        a.unsubscribe(["/x"])
        assert settles(1)
        b.close()
        assert settles(0)
    finally:
        live.close()
        for c in (a, b):
            if c is not None:
                c.close()


def test_pacing_follows_simulated_time(monkeypatch):
    """``pace`` sleeps so that simulated time runs at ``speed`` x the wall clock (a fake clock:
    no timing in the test), does not catch up when the run is late, and never waits unpaced."""
    import bulletnav.ros.live as live_mod

    clock = {"t": 100.0}
    slept: list[float] = []
    monkeypatch.setattr(live_mod.time, "perf_counter", lambda: clock["t"])

    def sleep(s: float) -> None:
        slept.append(s)
        clock["t"] += s

    monkeypatch.setattr(live_mod.time, "sleep", sleep)
    with LiveServer("127.0.0.1:0", speed=2.0) as live:
        live.pace(0)
        clock["t"] += 0.01  # a step took 10 ms of wall time ...
        live.pace(100_000_000)  # ... for 0.1 s of simulated time: due at 0.05 s at speed 2
        assert slept == [pytest.approx(0.04)]
        clock["t"] += 2.0  # a 2 s stall: late by more than 0.5 s
        live.pace(200_000_000)
        assert len(slept) == 1  # no wait, and no catching up afterwards:
        live.pace(300_000_000)
        assert slept[-1] == pytest.approx(0.05)
    with LiveServer("127.0.0.1:0", speed=0) as live:
        live.pace(0)
        live.pace(10**12)
    assert len(slept) == 2


@pytest.mark.parametrize("text, expected", [("8765", ("127.0.0.1", 8765)), ("0.0.0.0:9000", ("0.0.0.0", 9000)),
                                            ("[::1]:0", ("::1", 0)), ("localhost:65535", ("localhost", 65535))])
def test_parse_address(text, expected):
    assert parse_address(text) == expected


@pytest.mark.parametrize("text", ["", "http", ":8765", "host:", "8765x", "70000", "-1"])
def test_parse_address_refuses(text):
    with pytest.raises(BulletnavError, match="--live"):
        parse_address(text)


def test_cli_port_in_use_and_speed_alone(tmp_path, capsys):
    """A port already taken is one line and exit 2 (no file written); ``--speed`` without
    ``--live`` is refused."""
    from bulletnav.cli import main

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        code = main(["navigate", "--episodes", "1", "--live", f"127.0.0.1:{port}", "--record", str(tmp_path / "r.mcap")])
    err = capsys.readouterr().err
    assert code == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and f"127.0.0.1:{port}" in lines[0] and "in use" in lines[0], err
    assert list(tmp_path.iterdir()) == []
    assert main(["navigate", "--episodes", "1", "--speed", "0"]) == 2
    assert "--speed paces a live stream: give --live" in capsys.readouterr().err
    for speed in ("1e-300", "nan", "-1", "1e9"):  # 1e-300 asked for a wait past the clock's range: OverflowError
        with pytest.raises(SystemExit) as exit_:
            main(["navigate", "--episodes", "1", "--live", "0", "--speed", speed])
        assert exit_.value.code == 2
        err = capsys.readouterr().err.strip()
        assert err.count("\n") == 0 and "--speed" in err and "0.001-1000" in err and speed in err, err


def test_cli_navigate_live_announces_and_finishes(capsys):
    """``navigate --live 127.0.0.1:0 --speed 0``: one line with the address and the layout, then the
    usual report (no client: the run goes as fast as without the stream)."""
    from bulletnav.cli import main
    from bulletnav.ros.live import LAYOUT

    assert main(["navigate", "--episodes", "1", "--seed", "4", "--live", "127.0.0.1:0", "--speed", "0"]) == 0
    out = capsys.readouterr().out
    live_line = next(line for line in out.splitlines() if line.startswith("live: ws://127.0.0.1:"))
    assert "as fast as it goes" in live_line and str(LAYOUT) in live_line and LAYOUT.is_file()
    assert "episode   1/1 seed 4: SUCCESS" in out and "success rate   100.0 %" in out


@pytest.mark.parametrize("shape, frame", [((3, 5), "map"), ((7, 1), "x"), ((40, 33), "robot_10/map"), ((0, 4), "map")])
def test_grid_shortcut_is_the_serializer_byte_for_byte(shape, frame):
    """The encoder's shortcut for an OccupancyGrid's cells gives mcap-ros2-support's own
    serializer's bytes (frame names of several lengths shift the alignment before the cells)."""
    from mcap_ros2._dynamic import serialize_dynamic

    from bulletnav.ros.msgdefs import msgdef
    from bulletnav.ros.outputs import Ros2Encoder
    from bulletnav.ros.record import occupancy_message

    kind = "nav_msgs/msg/OccupancyGrid"
    cells = np.random.default_rng(sum(shape)).choice([-1, 0, 100], size=shape)
    msg = occupancy_message(1_234_567_891, frame, cells, 0.1, (-1.5, 2.25))
    slow = serialize_dynamic(kind, msgdef(kind))[kind]({**msg, "data": msg["data"].tolist()})
    assert Ros2Encoder().encode(kind, msg) == slow


def test_fleet_stream_one_namespace_per_robot():
    """``fleet --live``: each robot's scan under ``/robot_<i>/scan`` equals that robot's lidar at
    that step (a client joining after the first step, so the fleet's static transforms come by
    late join)."""
    from bulletnav.fleet.controllers import make_controller
    from bulletnav.fleet.metrics import run_fleet_episodes
    from bulletnav.fleet.view import FleetView
    from bulletnav.ros.fleet_record import FleetMcapRecorder

    live = LiveServer("127.0.0.1:0", speed=0)
    stream = FleetMcapRecorder(None, live=live)
    topics = ["/robot_0/scan", "/robot_1/scan", "/tf_static"]
    seen: dict[tuple[int, int], np.ndarray] = {}
    state: dict = {"client": None, "calls": 0}

    def hook(env, infos):
        stream(env, infos)
        state["calls"] += 1
        if state["calls"] == 2:  # after the first step: every topic is advertised
            state["client"] = FoxgloveClient(live.url)
            state["client"].subscribe(topics)
            _wait_watched(live, topics)
        elif state["calls"] > 2:
            ns = int(round(float(next(iter(infos.values()))["time_s"]) * 1e9))
            view = FleetView(env)
            for i in range(2):
                seen[(i, ns)] = view.robot(i).sensors.lidar.read().astype(np.float32)

    try:
        run_fleet_episodes({"num_robots": 2, "duration_s": 1.0}, lambda env: make_controller("independent", env), 1,
                           seed=5, on_step=hook)
        client = state["client"]
        for i in range(2):
            client.wait_for(lambda ms, n=len(seen) // 2: len(ms) >= n, topic=f"/robot_{i}/scan")
    finally:
        stream.close(ok=False)
        live.close()
        if state["client"] is not None:
            state["client"].close()
    assert client.errors == [] and len(seen) == 2 * 23  # steps 2-24 of 24 (1 s at 24 Hz)
    for i in range(2):
        got = {m.log_time_ns: m.decoded for m in client.messages(f"/robot_{i}/scan")}
        for (j, ns), ranges in seen.items():
            if j == i:
                assert got[ns].header.frame_id == f"robot_{i}/laser"
                assert np.array_equal(np.asarray(got[ns].ranges, dtype=np.float32), ranges)
    static = {t.child_frame_id for t in client.messages("/tf_static")[0].decoded.transforms}
    assert {"robot_0/laser", "robot_1/laser"} <= static
