"""Goals and teleop from Foxglove (``view --live ... --live-control``, :mod:`bulletnav.ros.live_control`),
checked with the tests' own Foxglove WebSocket client (``tests/foxglove_client.py``: the ``websockets``
library and the published protocol, no bulletnav or foxglove-sdk code).

The client publishes ``/goal_pose`` and ``/cmd_vel`` as Foxglove's panels do, CDR-encoded by
mcap-ros2-support's serializer or as JSON, and reads the robot back from the stream's ``/tf``
(decoded by mcap-ros2-support, composed in the test). References: the goal point (a hand-chosen
one, or one placed by the test's own 2-D transform), the teleop command's 0.5 s at 24 Hz (12
steps), PyBullet's own closest-point query between the robot and the walls, a run without the
shield that does hit the wall, and MCAP's reader on the recording. Timeouts are hang detectors.
"""

from __future__ import annotations

import contextlib
import json
import math
import struct

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest
from mcap_ros2._dynamic import serialize_dynamic
from websockets.exceptions import InvalidStatus

import bulletnav  # noqa: F401
from bulletnav.errors import BulletnavError
from bulletnav.ros.live import LiveServer
from bulletnav.ros.live_gate import OriginPolicy, normalize_origin
from foxglove_client import FoxgloveClient
from hang import HANG_S

_VECTOR3 = "MSG: geometry_msgs/Vector3\nfloat64 x\nfloat64 y\nfloat64 z\n"
_SEP = "=" * 80 + "\n"
TWIST = ("geometry_msgs/msg/Twist", "geometry_msgs/Vector3 linear\ngeometry_msgs/Vector3 angular\n" + _SEP + _VECTOR3)
POSE_STAMPED = ("geometry_msgs/msg/PoseStamped", "std_msgs/Header header\ngeometry_msgs/Pose pose\n" + _SEP
                + "MSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + _SEP
                + "MSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n" + _SEP
                + "MSG: geometry_msgs/Pose\ngeometry_msgs/Point position\ngeometry_msgs/Quaternion orientation\n" + _SEP
                + "MSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n" + _SEP
                + "MSG: geometry_msgs/Quaternion\nfloat64 x\nfloat64 y\nfloat64 z\nfloat64 w\n")
"""The two message types as a ROS 2 client advertises them (the Humble definitions, written here)."""
GOAL_RADIUS = 0.5
"""Warehouse-v0's success radius (m): a goal is reached within it (the env's docstring)."""
DT = 1 / 24
"""Warehouse-v0's control period (s)."""


def _cdr(schema: tuple[str, str], message: dict) -> bytes:
    return serialize_dynamic(*schema)[schema[0]](message)


def _goal_message(x: float, y: float, frame: str = "map") -> dict:
    return {"header": {"stamp": {"sec": 1, "nanosec": 2}, "frame_id": frame},
            "pose": {"position": {"x": x, "y": y, "z": 0.0}, "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0}}}


def _twist_message(v: float, w: float) -> dict:
    return {"linear": {"x": v, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": w}}


def _compose(a, b):
    """The 2-D pose a * b, written here (not bulletnav's)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _tf_pose(message) -> tuple[float, float, float]:
    """The robot's pose in map from one decoded /tf message (map -> odom, odom -> base_link)."""
    by_child = {t.child_frame_id: t for t in message.transforms}
    out = (0.0, 0.0, 0.0)
    for child in ("odom", "base_link"):
        t = by_child[child].transform
        out = _compose(out, (t.translation.x, t.translation.y, _yaw(t.rotation)))
    return out


def _pose_at(client: FoxgloveClient, ns: int, allow_errors: bool = False) -> tuple[float, float, float]:
    """The robot's pose from the /tf the client received stamped ``ns``."""
    got = client.wait_until(lambda: next((m for m in client.messages("/tf") if m.log_time_ns == ns), None),
                            f"/tf at {ns} ns", HANG_S, allow_errors=allow_errors)
    return _tf_pose(got.decoded)


def _now_ns(session) -> int:
    return int(round(session.steps * session.scene.control_dt * 1e9))


@contextlib.contextmanager
def _session(seed: int = 0, start=None, record=None, policy: OriginPolicy = OriginPolicy(), **env_kwargs):
    """A driving session on a stream at port 0 (unpaced), PID + A*, its event lines collected."""
    from bulletnav.control.navigator import Navigator
    from bulletnav.ros.live_control import NO_STEP_LIMIT, TASK_NAME, LiveControl

    live = LiveServer("127.0.0.1:0", speed=0, control=policy)
    env = gym.make("bulletnav/Warehouse-v0", task_name=TASK_NAME, max_episode_steps=NO_STEP_LIMIT, **env_kwargs)
    events: list[str] = []
    session = LiveControl(env, Navigator(env.unwrapped.scene), live, record=record, on_event=events.append)
    session.events = events
    try:
        session.reset(seed=seed, options=None if start is None else {"start": start})
        session.step()  # every per-step topic is advertised now
        yield session, live
    finally:
        session.close()
        live.close()


def _watch(session, live, topics=("/tf", "/goal_pose", "/cmd_vel")) -> FoxgloveClient:
    """A client (no Origin) subscribed to ``topics``, once the server has taken the subscriptions in
    and the session has stepped once more (so the robot's pose now is on its way)."""
    client = FoxgloveClient(live.url, timeout=HANG_S)
    client.subscribe(list(topics), HANG_S)
    _wait_watched(live, [t for t in topics if t != "/goal_pose"])
    session.step()
    return client


def _wait_watched(live: LiveServer, topics) -> None:
    import time

    end = time.monotonic() + HANG_S
    while not all(live.watched(t) for t in topics):
        assert time.monotonic() < end, f"subscriptions to {topics} not taken in: a hang?"
        time.sleep(0.01)


def _step_until(session, done, limit: int, what: str) -> None:
    for _ in range(limit):
        if done():
            return
        session.step()
    assert done(), f"{what} not within {limit} steps; events: {session.events}"


def _free_goal(layout, start, rng, near=(2.5, 3.5)):
    """A point ``near`` metres from ``start``, 0.6 m clear of everything and reachable (picked with
    the layout's own geometry: only the choice, never the verdict)."""
    from bulletnav.config import SamplerConfig
    from bulletnav.sim.sampler import FreeSpace

    free = FreeSpace.build(layout, SamplerConfig(), 0.2)
    for _ in range(2000):
        r, a = rng.uniform(*near), rng.uniform(-math.pi, math.pi)
        x, y = start[0] + r * math.cos(a), start[1] + r * math.sin(a)
        if layout.on_floor(x, y) and float(layout.clearance(np.array(x), np.array(y))) > 0.6 \
                and free.reachable((start[0], start[1]), (x, y)):
            return x, y
    raise AssertionError("no free goal found")


def _free_nearby(layout, pose) -> tuple[float, float]:
    """A point about 2 m from the robot at ``pose``, in its own frame, 0.5 m clear of everything."""
    for d in (2.0, 1.6, 2.4, 1.2):
        for a in (0.0, 0.5, -0.5, 1.0, -1.0, 2.0, -2.0, 3.0):
            local = (d * math.cos(a), d * math.sin(a))
            x, y, _ = _compose(pose, (*local, 0.0))
            if layout.on_floor(x, y) and float(layout.clearance(np.array(x), np.array(y))) > 0.5:
                return local
    raise AssertionError("no free point near the robot")


# ---------------------------------------------------------------------------------------
# the CDR decoder and the message readers

@pytest.mark.parametrize("kind, message", [
    ("geometry_msgs/msg/PoseStamped", _goal_message(1.25, -3.5, "base_link")),
    ("geometry_msgs/msg/Twist", _twist_message(0.4, -1.0)),
    ("sensor_msgs/msg/LaserScan", {"header": {"stamp": {"sec": -3, "nanosec": 9}, "frame_id": "laser"}, "angle_min": -1.5,
                                   "angle_max": 1.5, "angle_increment": 0.75, "time_increment": 0.0, "scan_time": 0.125,
                                   "range_min": 0.25, "range_max": 8.0, "ranges": [0.5, 1.25, 8.0], "intensities": []}),
    ("nav_msgs/msg/Path", {"header": {"frame_id": "map"}, "poses": [_goal_message(1.0, 2.0), _goal_message(-0.5, 7.25)]}),
    ("std_msgs/msg/Float64", {"data": -2.5e-300}),
])
def test_cdr_decoder_reads_what_mcap_ros2_writes(kind, message):
    """:func:`bulletnav.ros.cdr.decode` gives back the message mcap-ros2-support's serializer
    encoded (values exact in float32 where the field is float32); a big-endian copy written by hand
    for the Twist decodes the same."""
    from bulletnav.ros.cdr import decode
    from bulletnav.ros.msgdefs import msgdef

    data = serialize_dynamic(kind, msgdef(kind))[kind](message)
    got = decode(kind, data)

    def same(a, b):
        if isinstance(b, dict):
            return all(same(a[k], v) for k, v in b.items())
        if isinstance(b, list):
            return len(a) == len(b) and all(same(x, y) for x, y in zip(a, b))
        return a == b

    assert same(got, message), got
    if kind == "geometry_msgs/msg/Twist":
        big = b"\x00\x00\x00\x00" + struct.pack(">6d", 0.4, 0.0, 0.0, 0.0, 0.0, -1.0)
        assert decode(kind, big) == got


@pytest.mark.parametrize("data, says", [
    (b"", "not plain CDR"),
    (b"\x00\x07\x00\x00" + bytes(48), "not plain CDR"),  # XCDR2
    (b"\x00\x01\x00\x00" + bytes(20), "needs 8 bytes"),  # a Twist cut short
    (b"\x00\x01\x00\x00" + bytes(56), "left over"),  # 8 bytes too many
])
def test_cdr_decoder_refuses_malformed_twists(data, says):
    from bulletnav.ros.cdr import decode

    with pytest.raises(ValueError, match=says):
        decode("geometry_msgs/msg/Twist", data)


def test_cdr_decoder_refuses_malformed_strings_and_lengths():
    from bulletnav.ros.cdr import decode

    good = _cdr(POSE_STAMPED, _goal_message(1.0, 2.0, "map"))
    frame_at = 4 + 8  # header, then stamp (int32 + uint32): the frame's length, then its bytes
    no_nul = good[:frame_at + 4 + 3] + b"X" + good[frame_at + 8:]
    not_utf8 = good[:frame_at + 4] + b"\xff\xfe\x00" + good[frame_at + 7:]
    huge = good[:frame_at] + struct.pack("<I", 2**31) + good[frame_at + 4:]
    for data, says in ((no_nul, "closing NUL"), (not_utf8, "not UTF-8"), (huge, "needs 2147483648 bytes"),
                       (good[:-3], "needs 8 bytes")):
        with pytest.raises(ValueError, match=says):
            decode("geometry_msgs/msg/PoseStamped", data)
    path = bytes.fromhex("00010000") + bytes(8) + struct.pack("<I", 4) + b"map\x00" + struct.pack("<I", 10**6)
    with pytest.raises(ValueError, match="a sequence of 1000000 items"):
        decode("nav_msgs/msg/Path", path)


def test_goal_and_twist_readers_take_both_encodings_and_refuse_bad_ones():
    from bulletnav.ros.live_control import GoalRequest, TeleopRequest, read_goal, read_twist

    pose = _goal_message(1.5, -2.25, "/map")
    assert read_goal("cdr", "geometry_msgs/msg/PoseStamped", _cdr(POSE_STAMPED, pose)) == GoalRequest("map", 1.5, -2.25)
    assert read_goal("json", "geometry_msgs/PoseStamped", json.dumps(pose).encode()) == GoalRequest("map", 1.5, -2.25)
    assert read_twist("cdr", "geometry_msgs/Twist", _cdr(TWIST, _twist_message(0.25, 1.0))) == TeleopRequest(0.25, 1.0)
    assert read_twist("json", "geometry_msgs/msg/Twist", b'{"linear": {"x": 1}, "angular": {"z": -0.5}}') == \
        TeleopRequest(1.0, -0.5)
    bad = [
        (read_goal, "json", "geometry_msgs/msg/PoseStamped", b'{"pose": {"position": {"x": 1, "y": 2}}}', "header"),
        (read_goal, "json", "geometry_msgs/msg/PoseStamped",
         json.dumps(_goal_message(1.0, 2.0, "")).encode(), "not a frame's name"),
        (read_goal, "json", "geometry_msgs/msg/PoseStamped",
         b'{"header": {"frame_id": "map"}, "pose": {"position": {"x": NaN, "y": 2}}}', "NaN"),
        (read_goal, "json", "geometry_msgs/msg/PoseStamped",
         b'{"header": {"frame_id": "map"}, "pose": {"position": {"x": 1e999, "y": 2}}}', "not a finite number"),
        (read_goal, "json", "geometry_msgs/msg/PoseStamped",
         b'{"header": {"frame_id": "map"}, "pose": {"position": {"x": true, "y": 2}}}', "not a number"),
        (read_goal, "cdr", "geometry_msgs/msg/Twist", _cdr(TWIST, _twist_message(0.1, 0.1)), "not geometry_msgs/msg/PoseStamped"),
        (read_goal, "protobuf", "geometry_msgs/msg/PoseStamped", b"", "not cdr or json"),
        (read_twist, "json", "geometry_msgs/msg/Twist", b"\xff", "not UTF-8"),
        (read_twist, "json", "geometry_msgs/msg/Twist", b"[" * 100_000 + b"]" * 100_000, "more than"),
        (read_twist, "json", "geometry_msgs/msg/Twist", b'{"linear": {"x": 1}}', "angular"),
        (read_twist, "cdr", "geometry_msgs/msg/Twist", b"\x00\x01\x00\x00" + bytes(3), "needs 8 bytes"),
        # (review) an integer float() overflows on, and finite numbers no action can hold
        (read_twist, "json", "geometry_msgs/msg/Twist", b'{"linear": {"x": 1' + b"0" * 400 + b'}, "angular": {"z": 0}}',
         "too large for a float"),
        (read_twist, "json", "geometry_msgs/msg/Twist", b'{"linear": {"x": 1e300}, "angular": {"z": -1e300}}',
         "at most 1e\\+06"),
        (read_goal, "json", "geometry_msgs/msg/PoseStamped",
         b'{"header": {"frame_id": "map"}, "pose": {"position": {"x": 2e6, "y": 2}}}', "at most 1e\\+06"),
    ]
    for reader, encoding, schema, data, says in bad:
        with pytest.raises(ValueError, match=says):
            reader(encoding, schema, data)


# ---------------------------------------------------------------------------------------
# who may drive

@pytest.mark.parametrize("origin, allowed", [
    (None, True), ("http://localhost", True), ("http://localhost:5173", True), ("https://127.0.0.1:8443", True),
    ("http://[::1]:3000", True), ("https://app.foxglove.dev", True), ("HTTPS://APP.FOXGLOVE.DEV:443", True),
    ("https://robots.example.com", True),  # listed
    ("https://evil.example", False), ("http://localhost.evil.example", False), ("http://127.0.0.1.nip.io", False),
    ("null", False), ("file://", False), ("https://app.foxglove.dev.evil.example", False),
    ("http://app.foxglove.dev", False), ("https://robots.example.com:8443", False), ("", False),
    ("http://localhost:99999", False), ("ftp://localhost", False),
])
def test_origin_policy(origin, allowed):
    """Loopback pages (any port), Foxglove's web app, no Origin and the listed origins drive; any
    other site, a look-alike host, another scheme or port of a listed one, or ``null`` does not."""
    policy = OriginPolicy.of(["https://Robots.example.com:443/"])
    assert policy.allowed == ("https://robots.example.com",)
    assert policy.allows(origin) is allowed


@pytest.mark.parametrize("text", ["robots.example.com", "https://", "https://x/path", "https://u@x", "ws://x", "https://x?q"])
def test_allow_origin_refuses_what_is_not_an_origin(text):
    with pytest.raises(BulletnavError, match="--live-allow-origin"):
        normalize_origin(text)


# ---------------------------------------------------------------------------------------
# the session, through the stream

def test_a_client_publishes_goals_in_both_encodings_and_the_robot_gets_there(tmp_path, report):
    """A client (no Origin, as the desktop app) publishes a goal in the map frame as CDR: the robot,
    read back from the stream's /tf, ends within the goal radius of it; the goal is echoed on
    /goal_pose and recorded; the client gets an info status. A second client (a loopback page, as
    Foxglove's web app served locally) publishes one as JSON in base_link, 2 m from the robot as /tf
    places it: the task takes the point the test's own transform gives, and the robot gets there
    too. The server says what it takes: clientPublish in cdr and json, ROS_DISTRO for Foxglove's panels."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    record = tmp_path / "session.mcap"
    with _session(seed=7, record=record) as (session, live):
        desk = _watch(session, live)
        page = FoxgloveClient(live.url, timeout=HANG_S, origin="http://localhost:5173")
        info = desk.server_info
        assert "clientPublish" in info["capabilities"] and info["supportedEncodings"] == ["cdr", "json"]
        assert info["metadata"]["ROS_DISTRO"] == "humble"
        scene = session.scene
        goal = _free_goal(scene.layout, scene.pose, np.random.default_rng(7))
        channel = desk.advertise("/goal_pose", "cdr", POSE_STAMPED[0], POSE_STAMPED[1], "ros2msg")
        desk.publish(channel, _cdr(POSE_STAMPED, _goal_message(*goal)))
        _step_until(session, lambda: session.goals_reached == 1, 1500, "the first goal")
        first = _pose_at(desk, _now_ns(session))
        assert math.hypot(first[0] - goal[0], first[1] - goal[1]) < GOAL_RADIUS
        assert first == pytest.approx(tuple(scene.pose[:2]) + (first[2],), abs=1e-9)
        # the second goal: about 2 m from the robot in base_link, as JSON from the page; the robot's
        # pose then is the /tf of the step before the one that takes the goal in
        local = _free_nearby(scene.layout, first)
        channel = page.advertise("/goal_pose", "json", "geometry_msgs/PoseStamped")
        page.publish(channel, json.dumps(_goal_message(*local, "base_link")).encode())
        _step_until(session, lambda: session.goals_taken == 2, 200, "the second goal taken")
        then = _pose_at(desk, int(round((session.steps - 1) * DT * 1e9)))
        second = _compose(then, (*local, 0.0))[:2]
        assert scene.goal == pytest.approx(second, abs=1e-6)
        _step_until(session, lambda: session.goals_reached == 2, 1500, "the second goal")
        last = _pose_at(desk, _now_ns(session))
        assert math.hypot(last[0] - second[0], last[1] - second[1]) < GOAL_RADIUS
        echoes = desk.wait_for(lambda ms: len(ms) >= 3, topic="/goal_pose", timeout=HANG_S)
        reached = desk.wait_until(lambda: len([s for s in desk.statuses if "reached goal" in s["message"]]) == 2 and
                                  [s for s in desk.statuses if "reached goal" in s["message"]], "two statuses")
        assert [s["level"] for s in reached] == [0, 0] and desk.errors == [] and page.errors == []
        for line in session.events:
            report("event", line)
        page.close()
        desk.close()
    echoed = [(m.decoded.pose.position.x, m.decoded.pose.position.y, m.decoded.header.frame_id) for m in echoes]
    assert echoed[-2:] == [pytest.approx((*goal, "map")), pytest.approx((*second, "map"))]
    with open(record, "rb") as f:
        recorded = [(m.pose.position.x, m.pose.position.y) for _, _, _, m in
                    make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(topics=["/goal_pose"])]
    assert recorded[-2:] == [pytest.approx(goal), pytest.approx(second)]
    assert any("taken from client" in e and "(cdr)" in e for e in session.events)
    assert any("in base_link" in e and "(json)" in e for e in session.events)


def test_teleop_in_both_encodings_drives_the_robot_for_half_a_second_a_message(report):
    """One /cmd_vel message (CDR) of 0.3 m/s: the stream's /cmd_vel carries it for exactly 12 steps
    (0.5 s at 24 Hz), the robot moves ahead along its heading, then stops; one JSON message of
    1 rad/s turns it in place for 12 steps, counter-clockwise."""
    with _session(seed=1, start=(0.0, 0.0, 0.0), num_obstacles=0) as (session, live):
        client = _watch(session, live)
        before = _pose_at(client, _now_ns(session))
        channel = client.advertise("/cmd_vel", "cdr", TWIST[0], TWIST[1], "ros2msg")
        client.publish(channel, _cdr(TWIST, _twist_message(0.3, 0.0)))
        _step_until(session, lambda: session.events and "teleop ended" in session.events[-1], 200, "the burst's end")
        for _ in range(24):
            session.step()
        moved = _pose_at(client, _now_ns(session))
        turn = client.advertise("/cmd_vel", "json", "geometry_msgs/Twist")
        client.publish(turn, json.dumps(_twist_message(0.0, 1.0)).encode())
        _step_until(session, lambda: sum("teleop ended" in e for e in session.events) == 2, 200, "the second burst's end")
        for _ in range(24):
            session.step()
        turned = _pose_at(client, _now_ns(session))
        commands = client.wait_for(lambda ms: ms[-1].log_time_ns == _now_ns(session), topic="/cmd_vel")
        assert client.errors == []
        client.close()
    forward = [m for m in commands if m.decoded.linear.x == pytest.approx(0.3, abs=1e-6)]
    spinning = [m for m in commands if m.decoded.angular.z == pytest.approx(1.0, abs=1e-6)]
    assert len(forward) == 12 and len(spinning) == 12
    assert all(m.decoded.linear.x == 0 and m.decoded.angular.z == 0 for m in commands if m not in forward + spinning)
    dx, dy = moved[0] - before[0], moved[1] - before[1]
    assert 0.03 < dx < 0.3 * 0.5 + 0.05 and abs(dy) < 0.01  # at most 0.3 m/s for 0.5 s, plus braking
    assert 0.2 < turned[2] - moved[2] < 0.5 + 0.1 and math.hypot(turned[0] - moved[0], turned[1] - moved[1]) < 0.02
    report("teleop", f"0.3 m/s for 12 steps: {dx:.3f} m ahead; 1 rad/s for 12 steps: {turned[2] - moved[2]:.3f} rad")
    for line in session.events:
        report("event", line)


def _closest_to_walls(scene, floor: set[int]) -> float:
    """PyBullet's own closest distance (m) between the robot and every body but itself and the floor."""
    cid, robot = scene.client, scene.robot_body
    gaps = [c[8] for i in range(p.getNumBodies(physicsClientId=cid))
            for body in [p.getBodyUniqueId(i, physicsClientId=cid)] if body != robot and body not in floor
            for c in p.getClosestPoints(robot, body, 2.0, physicsClientId=cid)]
    return min(gaps, default=math.inf)


def test_a_teleop_burst_at_a_wall_passes_the_shield_without_touching_it(report):
    """The robot 1 m from a wall, facing it; a client holds 0.5 m/s at it for 3 s (a message every
    0.25 s). Behind the shield, PyBullet's closest distance between the robot and the wall never
    reaches 0 and the shield replaced commands; the same commands without the shield hit the wall."""
    start = (5.8, 0.0, 0.0)  # the 14 m floor ends at x = 7: the wall is 1.2 m ahead of the centre
    with _session(start=start, num_obstacles=0) as (session, live):
        scene = session.scene
        floor = {c[2] for c in p.getContactPoints(bodyA=scene.robot_body, physicsClientId=scene.client)}
        client = _watch(session, live)
        channel = client.advertise("/cmd_vel", "cdr", TWIST[0], TWIST[1], "ros2msg")
        gaps = []

        def step() -> None:
            session.step()
            gaps.append(_closest_to_walls(scene, floor))

        for k in range(12):  # a message every 6 steps (0.25 s), each taken before the next
            client.publish(channel, _cdr(TWIST, _twist_message(0.5, 0.0)))
            for _ in range(200):
                step()
                if session.teleop_messages > k:
                    break
            for _ in range(5):
                step()
        while "teleop ended" not in session.events[-1]:
            step()
        burst = session.events[-1]
        pose = _pose_at(client, _now_ns(session))
        assert client.errors == []
        client.close()
    assert session.collisions == 0 and min(gaps) > 0.0, (min(gaps), session.events)
    assert "the shield replaced 0" not in burst and ", 0 steps touching" in burst
    report("wall", f"closest robot-wall distance {min(gaps):.3f} m (PyBullet); stopped at x {pose[0]:.3f}; {burst}")
    for line in session.events:
        report("event", line)
    # the same commands without the shield: the robot hits the wall
    env = gym.make("bulletnav/Warehouse-v0", num_obstacles=0)
    try:
        env.reset(seed=0, options={"start": start})
        hit = any(env.step(np.array([0.5, 0.0], dtype=np.float32))[4]["collision"] for _ in range(72))
    finally:
        env.close()
    assert hit


def test_a_bad_goal_gets_a_status_error_and_changes_nothing(report):
    """Goals inside an obstacle, outside the world or in a frame the stream does not have, a CDR
    goal cut short, a JSON goal with NaN and a goal of another type: each is answered with a status
    of level error saying why; the task's goal and the robot stay as they were."""
    with _session(seed=3) as (session, live):
        scene = session.scene
        client = _watch(session, live)
        box = next(o for o in scene.layout.obstacles if o.kind == "box")
        goal_before, pose_before = scene.goal, _pose_at(client, _now_ns(session))
        cdr = client.advertise("/goal_pose", "cdr", POSE_STAMPED[0], POSE_STAMPED[1], "ros2msg")
        js = client.advertise("/goal_pose", "json", "geometry_msgs/msg/PoseStamped")
        wrong = client.advertise("/goal_pose", "json", "geometry_msgs/msg/Twist")
        sent = [
            (cdr, _cdr(POSE_STAMPED, _goal_message(*box.center)), f"inside a {box.label}"),
            (cdr, _cdr(POSE_STAMPED, _goal_message(100.0, 0.0)), "outside the world"),
            (js, json.dumps(_goal_message(1.0, 1.0, "world")).encode(), "frame 'world' is not one of the stream's"),
            (cdr, _cdr(POSE_STAMPED, _goal_message(1.0, 1.0))[:-8], "needs 8 bytes"),
            (js, b'{"header": {"frame_id": "map"}, "pose": {"position": {"x": NaN, "y": 0}}}', "NaN"),
            (wrong, json.dumps(_twist_message(0.1, 0.0)).encode(), "not geometry_msgs/msg/PoseStamped"),
        ]
        for k, (channel, data, _) in enumerate(sent, 1):
            client.publish(channel, data)
            _step_until(session, lambda k=k: sum(s["level"] == 2 for s in client.statuses) >= k, 500, f"status error {k}")
        for _ in range(24):
            session.step()
        pose_after = _pose_at(client, _now_ns(session), allow_errors=True)
        errors = [s["message"] for s in client.statuses if s["level"] == 2]
        client.close()
    assert len(errors) == len(sent)
    for message, (_, _, says) in zip(errors, sent):
        assert says in message, (says, message)
        report("status error", message)
    assert scene.goal == goal_before and session.goals_taken == 0 and (session.goals_refused, session.messages_refused) == (3, 3)
    assert math.hypot(pose_after[0] - pose_before[0], pose_after[1] - pose_before[1]) < 1e-3


def test_a_client_with_a_foreign_origin_cannot_drive(report):
    """Pages of other sites (and ``null``) are refused at the handshake (HTTP 403), a listed origin
    is let in; a client that reaches the SDK's own loopback port without the gate (as a page trying
    ports could) publishes a goal and teleop that change nothing, while the same goal through the
    gate is taken."""
    with _session(seed=3, policy=OriginPolicy.of(["https://robots.example.com"])) as (session, live):
        for origin in ("https://evil.example", "null", "http://localhost.evil.example"):
            with pytest.raises(InvalidStatus) as refused:
                FoxgloveClient(live.url, timeout=HANG_S, origin=origin)
            response = refused.value.response
            assert response.status_code == 403 and b"may not drive this robot" in response.body
            report("refused", f"Origin {origin}: HTTP {response.status_code} {response.reason_phrase}: "
                              f"{response.body.decode().strip()}")
        assert set(live.gate.refused) == {"https://evil.example", "null", "http://localhost.evil.example"}
        listed = FoxgloveClient(live.url, timeout=HANG_S, origin="https://robots.example.com")
        listed.close()
        watcher = _watch(session, live)
        sneak = FoxgloveClient(f"ws://127.0.0.1:{live.gate.backend_port}", timeout=HANG_S)
        goal = _free_goal(session.scene.layout, session.scene.pose, np.random.default_rng(3), near=(1.5, 2.5))
        before, goal_before = _pose_at(watcher, _now_ns(session)), session.scene.goal
        c1 = sneak.advertise("/goal_pose", "json", "geometry_msgs/msg/PoseStamped")
        c2 = sneak.advertise("/cmd_vel", "json", "geometry_msgs/msg/Twist")
        sneak.publish(c1, json.dumps(_goal_message(*goal)).encode())
        sneak.publish(c2, json.dumps(_twist_message(0.5, 0.0)).encode())
        for _ in range(48):
            session.step()
        after = _pose_at(watcher, _now_ns(session))
        assert session.goals_taken == 0 and session.scene.goal == goal_before and not session.events
        assert math.hypot(after[0] - before[0], after[1] - before[1]) < 1e-3
        channel = watcher.advertise("/goal_pose", "json", "geometry_msgs/msg/PoseStamped")
        watcher.publish(channel, json.dumps(_goal_message(*goal)).encode())
        _step_until(session, lambda: session.goals_taken == 1, 200, "the goal through the gate")
        assert watcher.errors == [] and sneak.errors == []
        sneak.close()
        watcher.close()


# ---------------------------------------------------------------------------------------
# the command line

def test_cli_view_live_control_announces_drives_and_records(tmp_path, capsys):
    """``view --live 127.0.0.1:0 --live-control --seconds 0.5 --speed 0 --record``: the address, the
    controller behind the shield, the summary, a recording whose /goal_pose is the robot's start (it
    waits there); on 0.0.0.0 the line says anyone who reaches the port can drive."""
    from mcap.reader import make_reader

    from bulletnav.cli import main

    record = tmp_path / "s.mcap"
    assert main(["view", "--live", "127.0.0.1:0", "--live-control", "--seconds", "0.5", "--speed", "0", "--record",
                 str(record)]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("live: ws://127.0.0.1:") and "ANYONE" not in out[0]
    assert out[1].startswith("driving with PID + A* behind the safety shield until 0.5 s: publish /goal_pose")
    assert out[-1].startswith("drove ") and "0 goal(s) taken" in out[-1] and f"recording: {record}" in out[-1]
    with open(record, "rb") as f:
        topics = {ch.topic for _, ch, _ in make_reader(f).iter_messages()}
    assert {"/tf", "/goal_pose", "/cmd_vel", "/scan", "/shield/interventions"} <= topics
    assert main(["view", "--live", "0.0.0.0:0", "--live-control", "--seconds", "0.1", "--speed", "0"]) == 0
    assert "ANYONE WHO REACHES THIS PORT CAN DRIVE THE ROBOT" in capsys.readouterr().out.splitlines()[0]
    assert main(["view", "--live", "127.0.0.1:0", "--live-control", "--seconds", "0.1", "--record", str(record)]) == 2
    captured = capsys.readouterr()
    assert "the file already exists" in captured.err and "live: ws://" not in captured.out
    import socket

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        assert main(["view", "--live", f"127.0.0.1:{port}", "--live-control", "--seconds", "0.1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and f"cannot listen on 127.0.0.1:{port}" in err and "in use" in err, err


@pytest.mark.parametrize("argv, says", [
    (["--live-control"], "--live-control drives the robot from Foxglove: give --live [HOST:]PORT too"),
    (["--controller", "rrt"], "--controller: for a session driven from Foxglove"),
    (["--live", "0", "--live-allow-origin", "https://x.example"], "--live-allow-origin says which web pages"),
    (["--live", "0", "--live-control", "--live-allow-origin", "ftp://x"], "'ftp://x': give an origin"),
    (["--live", "0", "--live-control", "--controller", "astr"], "--controller astr: neither one of astar, rrt, pid, dwa"),
    (["--live", "0", "--live-control", "--robots", "2"], "--live-control drives one robot"),
    (["--live", "0", "--live-control", "--env", "bulletnav/BARN-v0"], "cannot take goals from Foxglove"),
])
def test_cli_view_live_control_refuses(argv, says, capsys):
    """Each misuse is one line on stderr and exit 2, before any port is opened."""
    from bulletnav.cli import main

    try:
        code = main(["view", *argv])
    except SystemExit as exc:  # argparse's own refusals
        code = exc.code
    captured = capsys.readouterr()
    assert code == 2 and captured.err.count("\n") == 1 and says in captured.err, captured.err
    assert "live: ws://" not in captured.out
