"""The independent Foxglove WebSocket client (tests/foxglove_client.py) against a real foxglove-sdk server
and against a scripted fake server: what it receives and decodes is what was sent, late subscribers get
what is logged after they subscribe, two clients both get everything, one leaving breaks nothing, and a
frame the protocol does not allow is recorded as an error.

The messages are encoded here with mcap-ros2-support's dynamic encoder (or by hand), never by bulletnav.
Timeouts are hang detectors only."""

from __future__ import annotations

import json
import struct
import threading
from collections.abc import Iterator
from contextlib import contextmanager

import foxglove
import pytest
from mcap_ros2._dynamic import serialize_dynamic
from websockets.sync.server import serve

from foxglove_client import ChannelInfo, FoxgloveClient, Received

HANG_S = 60.0

FLOAT64 = ("std_msgs/msg/Float64", "float64 data\n")
LASER_SCAN = ("sensor_msgs/msg/LaserScan", """std_msgs/Header header
float32 angle_min
float32 angle_max
float32 angle_increment
float32 time_increment
float32 scan_time
float32 range_min
float32 range_max
float32[] ranges
float32[] intensities
================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
""")


class _Subscriptions:
    """A foxglove-sdk server listener that counts the subscriptions the server has taken in, so a test
    logs only after the server knows of them (the protocol has no acknowledgement of a subscribe)."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.count: dict[str, int] = {}

    def on_subscribe(self, client: object, channel: foxglove.websocket.ChannelView) -> None:
        with self.cond:
            self.count[channel.topic] = self.count.get(channel.topic, 0) + 1
            self.cond.notify_all()

    def on_unsubscribe(self, client: object, channel: foxglove.websocket.ChannelView) -> None:
        with self.cond:
            self.count[channel.topic] -= 1
            self.cond.notify_all()

    def wait(self, topic: str, n: int = 1) -> None:
        with self.cond:
            assert self.cond.wait_for(lambda: self.count.get(topic, 0) == n, HANG_S), \
                f"the server did not take in {n} subscription(s) to {topic} in {HANG_S} s: {self.count}"


@contextmanager
def _server() -> Iterator[tuple[str, foxglove.Context, _Subscriptions]]:
    ctx = foxglove.Context()
    subs = _Subscriptions()
    server = foxglove.start_server(host="127.0.0.1", port=0, context=ctx, server_listener=subs)
    try:
        yield f"ws://127.0.0.1:{server.port}", ctx, subs
    finally:
        server.stop()


def _channel(ctx: foxglove.Context, topic: str, schema: tuple[str, str]) -> foxglove.Channel:
    return foxglove.Channel(topic, schema=foxglove.Schema(name=schema[0], encoding="ros2msg", data=schema[1].encode()),
                            message_encoding="cdr", context=ctx)


def _encode(schema: tuple[str, str], msg: dict) -> bytes:
    return serialize_dynamic(*schema)[schema[0]](msg)


def _scan(i: int) -> dict:
    """A LaserScan whose every float is exact in float32, so decoded values compare with ==."""
    return {"header": {"stamp": {"sec": 100 + i, "nanosec": 250_000_000}, "frame_id": "base_scan"},
            "angle_min": -1.5, "angle_max": 1.5, "angle_increment": 0.75, "time_increment": 0.0,
            "scan_time": 0.125, "range_min": 0.25, "range_max": 8.0,
            "ranges": [0.5 * i, 1.25, 2.5, 8.0, 0.25 + i], "intensities": []}


def test_the_client_receives_and_decodes_what_the_server_logs():
    with _server() as (url, ctx, subs):
        scan = _channel(ctx, "/scan", LASER_SCAN)  # before the client connects: advertised on connect
        with FoxgloveClient(url, timeout=HANG_S) as client:
            assert client.subprotocol == "foxglove.sdk.v1"
            value = _channel(ctx, "/value", FLOAT64)  # after: advertised live
            chans = client.wait_for_topics(["/scan", "/value"], HANG_S)
            assert (chans["/scan"].encoding, chans["/scan"].schema_encoding) == ("cdr", "ros2msg")
            assert (chans["/scan"].schema_name, chans["/scan"].schema) == LASER_SCAN
            assert (chans["/value"].id, chans["/value"].schema) == (value.id(), FLOAT64[1])
            client.subscribe(["/scan", "/value"], HANG_S)
            subs.wait("/scan")
            subs.wait("/value")
            sent = {}
            for i in range(3):
                sent[("/scan", i)] = _encode(LASER_SCAN, _scan(i))
                scan.log(sent[("/scan", i)], log_time=1_000_000_000 * i + 7)
                sent[("/value", i)] = _encode(FLOAT64, {"data": 0.1 * i - 3.0})
                value.log(sent[("/value", i)], log_time=2**40 + i)
            client.wait_for(3, "/scan", HANG_S)
            client.wait_for(3, "/value", HANG_S)
            for i, got in enumerate(client.messages("/scan")):
                assert (got.log_time_ns, got.payload) == (1_000_000_000 * i + 7, sent[("/scan", i)])
                msg = got.decoded
                assert (msg.header.stamp.sec, msg.header.stamp.nanosec, msg.header.frame_id) == (100 + i, 250_000_000,
                                                                                                 "base_scan")
                assert (msg.angle_min, msg.angle_increment, msg.range_max) == (-1.5, 0.75, 8.0)
                assert list(msg.ranges) == [0.5 * i, 1.25, 2.5, 8.0, 0.25 + i]
            assert [(r.log_time_ns, r.decoded.data) for r in client.messages("/value")] == \
                [(2**40 + i, 0.1 * i - 3.0) for i in range(3)]
            assert client.errors == []


def test_a_late_subscriber_gets_what_is_logged_after_it_subscribes_and_a_closed_channel_goes():
    with _server() as (url, ctx, subs):
        value = _channel(ctx, "/value", FLOAT64)
        with FoxgloveClient(url, timeout=HANG_S) as client:
            client.wait_for_topics(["/value"], HANG_S)
            for i in range(3):
                value.log(_encode(FLOAT64, {"data": float(i)}))  # nobody subscribed: not kept for later
            client.subscribe(["/value"], HANG_S)
            subs.wait("/value")
            for i in range(3, 5):
                value.log(_encode(FLOAT64, {"data": float(i)}))
            got = client.wait_for(2, "/value", HANG_S)
            assert [r.decoded.data for r in got] == [3.0, 4.0]
            value.close()
            client.wait_until(lambda: "/value" not in client.topics(), "unadvertise of /value", HANG_S)
            assert client.errors == []


def test_two_clients_both_receive_everything_and_one_leaving_breaks_nothing():
    with _server() as (url, ctx, subs):
        value = _channel(ctx, "/value", FLOAT64)
        a = FoxgloveClient(url, timeout=HANG_S)
        with FoxgloveClient(url, timeout=HANG_S) as b:
            a.subscribe(["/value"], HANG_S)
            b.subscribe(["/value"], HANG_S)
            subs.wait("/value", 2)
            for i in range(5):
                value.log(_encode(FLOAT64, {"data": float(i)}))
            for client in (a, b):
                assert [r.decoded.data for r in client.wait_for(5, "/value", HANG_S)] == [0.0, 1.0, 2.0, 3.0, 4.0]
            a.close()
            assert a.closed and a.errors == []
            subs.wait("/value", 1)  # the server dropped a's subscription
            with FoxgloveClient(url, timeout=HANG_S) as c:  # the server still takes new clients
                c.subscribe(["/value"], HANG_S)
                subs.wait("/value", 2)
                for i in range(5, 8):
                    value.log(_encode(FLOAT64, {"data": float(i)}))
                assert [r.decoded.data for r in c.wait_for(3, "/value", HANG_S)] == [5.0, 6.0, 7.0]
                assert [r.decoded.data for r in b.wait_for(8, "/value", HANG_S)] == [float(i) for i in range(8)]
                assert c.errors == []
            assert len(a.messages("/value")) == 5
            assert b.errors == []


def _fake_server(connection) -> None:
    """A scripted server: advertises one channel, waits for the subscribe, then sends one good message
    (CDR of 2.0 written by hand, timestamp 0x0102030405060708) and five things the protocol forbids."""
    connection.send(json.dumps({"op": "serverInfo", "name": "fake", "capabilities": []}))
    connection.send(json.dumps({"op": "advertise", "channels": [
        {"id": 5, "topic": "/x", "encoding": "cdr", "schemaName": "std_msgs/msg/Float64", "schemaEncoding": "ros2msg",
         "schema": "float64 data\n"}]}))
    sub = json.loads(connection.recv(timeout=HANG_S))
    assert sub["op"] == "subscribe" and sub["subscriptions"][0]["channelId"] == 5
    sid = sub["subscriptions"][0]["id"]
    cdr = b"\x00\x01\x00\x00" + b"\x00\x00\x00\x00\x00\x00\x00\x40"  # little-endian CDR header, 2.0 as a double
    connection.send(b"\x01" + struct.pack("<I", sid) + bytes(range(8, 0, -1)) + cdr)
    connection.send(b"\x09\x00\x00")  # an opcode the protocol does not have
    connection.send(b"\x01" + struct.pack("<I", sid + 1000) + bytes(8) + cdr)  # a subscription never made
    connection.send(b"\x01\x00\x00")  # a messageData shorter than its header
    connection.send(json.dumps({"op": "nonsense"}))
    connection.send(json.dumps({"op": "status", "level": 2, "message": "broken"}))
    connection.recv(timeout=HANG_S)  # until the client closes


def test_the_client_decodes_a_hand_made_frame_and_records_every_frame_the_protocol_forbids():
    with serve(_fake_server, "127.0.0.1", 0, subprotocols=["foxglove.sdk.v1"]) as server:
        threading.Thread(target=server.serve_forever, daemon=True).start()
        port = server.socket.getsockname()[1]
        with FoxgloveClient(f"ws://127.0.0.1:{port}", timeout=HANG_S) as client:
            client.subscribe(["/x"], HANG_S)
            got = client.wait_for(1, "/x", HANG_S)
            assert (got[0].log_time_ns, got[0].decoded.data) == (0x0102030405060708, 2.0)
            client.wait_until(lambda: len(client.errors) >= 5, "five errors", HANG_S, allow_errors=True)
            errors = client.errors
        server.shutdown()
    assert len(errors) == 5, errors
    for text, error in zip(("unknown opcode 0x09", "subscription id", "shorter than its header", "'nonsense'",
                            "'broken'"), errors):
        assert text in error
    with pytest.raises(ValueError, match="cannot decode"):
        _ = Received("/j", 0, b"{}", ChannelInfo(1, "/j", "json", "J", "jsonschema", "{}"), 1).decoded


class _Published:
    """A foxglove-sdk server listener that keeps what clients advertise and publish."""

    def __init__(self) -> None:
        self.cond = threading.Condition()
        self.channels: dict[tuple[int, int], tuple[str, str, str, str | None]] = {}
        self.messages: list[tuple[str, bytes]] = []

    def on_client_advertise(self, client: object, channel: foxglove.websocket.ClientChannel) -> None:
        with self.cond:
            schema = None if channel.schema is None else bytes(channel.schema).decode()
            self.channels[(client.id, channel.id)] = (channel.topic, channel.encoding, channel.schema_name, schema)
            self.cond.notify_all()

    def on_message_data(self, client: object, client_channel_id: int, data: bytes) -> None:
        with self.cond:
            self.messages.append((self.channels[(client.id, client_channel_id)][0], bytes(data)))
            self.cond.notify_all()


def test_the_client_publishes_what_a_foxglove_sdk_server_receives():
    """Advertised client channels and published messages arrive at a foxglove-sdk server as sent
    (its own listener is the reference), in both encodings; the client refuses to advertise to a
    server without ``clientPublish`` or in an encoding the server does not take."""
    from foxglove.websocket import Capability

    ctx = foxglove.Context()
    got = _Published()
    server = foxglove.start_server(host="127.0.0.1", port=0, context=ctx, server_listener=got,
                                   capabilities=[Capability.ClientPublish], supported_encodings=["cdr", "json"])
    try:
        with FoxgloveClient(f"ws://127.0.0.1:{server.port}", timeout=HANG_S) as client:
            value = _encode(FLOAT64, {"data": -1.25})
            a = client.advertise("/value", "cdr", FLOAT64[0], FLOAT64[1], "ros2msg")
            b = client.advertise("/note", "json", "Note")
            client.publish(a, value)
            client.publish(b, b'{"text": "hi"}')
            with got.cond:
                assert got.cond.wait_for(lambda: len(got.messages) == 2, HANG_S), got.messages
            assert sorted(got.channels.values()) == [("/note", "json", "Note", None),
                                                     ("/value", "cdr", FLOAT64[0], FLOAT64[1])]
            assert got.messages == [("/value", value), ("/note", b'{"text": "hi"}')]
            with pytest.raises(ValueError, match="not 'protobuf'"):
                client.advertise("/x", "protobuf", "X")
            assert client.errors == []
    finally:
        server.stop()
    with _server() as (url, _, _), FoxgloveClient(url, timeout=HANG_S) as plain:
        with pytest.raises(ValueError, match="does not take client messages"):
            plain.advertise("/x", "json", "X")
