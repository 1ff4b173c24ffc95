"""A Foxglove WebSocket client for the tests, written from the published protocol, not from the server's code.

It shares no code with bulletnav or with foxglove-sdk: it speaks the Foxglove WebSocket protocol
(github.com/foxglove/ws-protocol, docs/spec.md) over the ``websockets`` library and decodes CDR payloads
with mcap-ros2-support's dynamic decoder, built from the ``ros2msg`` schema text the server advertises.
So a test that checks bulletnav's live stream with it checks the bytes a Foxglove app would see.

What it does, as the spec says:

- It offers the subprotocols of :data:`SUBPROTOCOLS` in order; the server must pick one.
- The server sends a JSON ``serverInfo`` first, then ``advertise`` for the channels it has (and more
  ``advertise`` / ``unadvertise`` as channels come and go); the client keeps :attr:`FoxgloveClient.channels`.
- The client sends ``subscribe`` with ``subscriptions: [{id, channelId}]``, ids it chooses and never reuses.
- The server sends each message as a binary frame: opcode ``0x01``, the subscription id (uint32 LE),
  the message's timestamp in ns (uint64 LE), then the payload.
- Publishing (only to a server whose ``serverInfo`` lists the ``clientPublish`` capability, in one of
  its ``supportedEncodings``): the client sends ``advertise`` with ``channels: [{id, topic, encoding,
  schemaName, schema?, schemaEncoding?}]`` (ids it chooses), then each message as a binary frame:
  opcode ``0x01``, the channel id (uint32 LE), the payload; ``unadvertise`` with ``channelIds``.
- ``origin``: the HTTP ``Origin`` header of the handshake, as a browser sends the page's origin.

It is strict: a frame the spec does not allow here (an unknown binary opcode, a message for a
subscription never made, a malformed frame, a JSON message of an unknown ``op``, a status of level
error, a channel id re-advertised with other contents) goes into :attr:`FoxgloveClient.errors`, which
a test asserts empty. Every wait has a timeout, so a broken server fails a test instead of hanging it;
the timeouts are hang detectors, never a verdict on speed.

The module's name does not start with ``test_``, so pytest does not collect it.
"""

from __future__ import annotations

import functools
import json
import struct
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import Any

from mcap_ros2._dynamic import generate_dynamic
from websockets.exceptions import ConnectionClosedError
from websockets.sync.client import connect

SUBPROTOCOLS = ("foxglove.sdk.v1", "foxglove.websocket.v1")
"""The subprotocols offered, in order of preference: the Foxglove SDK's name for protocol v1 (the one
foxglove-sdk 0.30.3's server accepts) and the ws-protocol spec's."""

DEFAULT_TIMEOUT_S = 120.0
"""How long a wait lasts before it fails as a suspected hang (seconds): generous, for a loaded machine."""

OP_MESSAGE_DATA = 0x01
OP_TIME = 0x02
_MESSAGE_HEADER = struct.Struct("<BIQ")  # opcode, subscription id, timestamp (ns)
_TIME_FRAME = struct.Struct("<BQ")  # opcode, timestamp (ns)
_ERROR_LEVEL = 2


@dataclass(frozen=True)
class ChannelInfo:
    """One channel as the server advertised it."""

    id: int
    topic: str
    encoding: str
    """The message encoding (``cdr`` for ROS 2 messages)."""
    schema_name: str
    schema_encoding: str | None
    """``ros2msg`` for a ROS 2 message definition; None where the server left it out."""
    schema: str


@functools.cache
def _decoder(schema_name: str, schema_text: str) -> Callable[[bytes], Any]:
    """The mcap_ros2 dynamic decoder of one ros2msg schema, built once per schema."""
    decoders = generate_dynamic(schema_name, schema_text)
    return decoders[schema_name]


@dataclass(frozen=True)
class Received:
    """One message the client received on a subscription."""

    topic: str
    log_time_ns: int
    """The timestamp the server put in the frame (the message's log time, ns)."""
    payload: bytes
    """The message's bytes as sent (CDR for a ``cdr`` channel)."""
    channel: ChannelInfo = field(repr=False)
    subscription_id: int = field(repr=False)

    @functools.cached_property
    def decoded(self) -> Any:
        """The payload decoded with the advertised schema by mcap_ros2's dynamic decoder (done on first
        use, off the receiving thread). Raises ValueError for a channel that is not ``cdr`` + ``ros2msg``."""
        ch = self.channel
        if ch.encoding != "cdr" or ch.schema_encoding not in ("ros2msg", None):
            raise ValueError(f"{ch.topic}: cannot decode encoding {ch.encoding!r} with schema "
                             f"encoding {ch.schema_encoding!r} (only cdr + ros2msg)")
        return _decoder(ch.schema_name, ch.schema)(self.payload)


def _channel_from_json(entry: Any) -> ChannelInfo:
    """A ChannelInfo from one entry of an ``advertise``; ValueError naming the field that is wrong."""
    if not isinstance(entry, dict):
        raise ValueError(f"advertise: a channel is not an object: {entry!r}")
    for key, kind in (("id", int), ("topic", str), ("encoding", str), ("schemaName", str), ("schema", str)):
        if not isinstance(entry.get(key), kind) or isinstance(entry.get(key), bool):
            raise ValueError(f"advertise: channel field {key!r} is {entry.get(key)!r}, not a {kind.__name__}")
    schema_encoding = entry.get("schemaEncoding")
    if schema_encoding is not None and not isinstance(schema_encoding, str):
        raise ValueError(f"advertise: channel field 'schemaEncoding' is {schema_encoding!r}, not a str")
    return ChannelInfo(entry["id"], entry["topic"], entry["encoding"], entry["schemaName"], schema_encoding,
                       entry["schema"])


class FoxgloveClient:
    """A synchronous Foxglove WebSocket client; a background thread receives every frame.

    ``FoxgloveClient(url)`` connects and waits for the server's ``serverInfo`` (ConnectionError if the
    server picks no subprotocol or sends none in time). Use it as a context manager, or call
    :meth:`close`. All state is read under one lock; the accessors return copies.
    """

    def __init__(self, url: str, subprotocols: Sequence[str] = SUBPROTOCOLS,
                 timeout: float = DEFAULT_TIMEOUT_S, origin: str | None = None) -> None:
        self.url = url
        self._cond = threading.Condition()
        self._channels: dict[int, ChannelInfo] = {}
        self._subs: dict[int, ChannelInfo] = {}  # active subscription id -> channel
        self._retired: set[int] = set()  # subscription ids unsubscribed: frames in flight are not errors
        self._next_sub = 1
        self._received: list[Received] = []
        self._errors: list[str] = []
        self.statuses: list[dict] = []
        """Every ``status`` message, in order of arrival."""
        self.server_info: dict | None = None
        self.times_ns: list[int] = []
        """Timestamps of binary ``time`` frames (only a server with the ``time`` capability sends them)."""
        self.late_frames = 0
        """Frames that arrived for a subscription after this client unsubscribed it (allowed in flight)."""
        self._closing = False
        self._closed = False
        self._next_channel = 1
        self._advertised: dict[int, tuple[str, str]] = {}  # client channel id -> (topic, encoding)
        self._ws = connect(url, subprotocols=list(subprotocols), open_timeout=timeout, close_timeout=timeout,
                           max_size=None, max_queue=4096, compression=None, proxy=None, legacy=True,
                           origin=origin)  # type: ignore[arg-type]
        self.subprotocol = self._ws.subprotocol
        """The subprotocol the server picked."""
        if self.subprotocol not in subprotocols:
            self._ws.close()
            raise ConnectionError(f"{url}: the server picked subprotocol {self.subprotocol!r}, "
                                  f"not one of {list(subprotocols)}")
        self._thread = threading.Thread(target=self._receive_loop, name=f"foxglove-client {url}", daemon=True)
        self._thread.start()
        try:
            self._wait(lambda: self.server_info is not None, timeout, "the server's serverInfo")
        except BaseException:
            self.close()
            raise

    # ---- context manager
    def __enter__(self) -> FoxgloveClient:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- receiving (the background thread)
    def _receive_loop(self) -> None:
        try:
            for frame in self._ws:
                with self._cond:
                    if isinstance(frame, str):
                        self._on_text(frame)
                    else:
                        self._on_binary(bytes(frame))
                    self._cond.notify_all()
        except ConnectionClosedError as exc:
            with self._cond:
                if not self._closing:
                    self._errors.append(f"the connection closed abnormally: {exc}")
        except Exception as exc:  # a bug here must fail the test, not vanish with the thread
            with self._cond:
                self._errors.append(f"the receiving thread failed: {type(exc).__name__}: {exc}")
        finally:
            with self._cond:
                self._closed = True
                self._cond.notify_all()

    def _on_text(self, text: str) -> None:
        try:
            msg = json.loads(text)
        except ValueError as exc:
            self._errors.append(f"a text frame that is not JSON ({exc}): {text[:200]!r}")
            return
        op = msg.get("op") if isinstance(msg, dict) else None
        if self.server_info is None and op != "serverInfo":
            self._errors.append(f"{op!r} arrived before serverInfo")
        if op == "serverInfo":
            self.server_info = msg
        elif op == "advertise":
            self._on_advertise(msg.get("channels"))
        elif op == "unadvertise":
            self._on_unadvertise(msg.get("channelIds"))
        elif op == "status":
            self.statuses.append(msg)
            if msg.get("level") == _ERROR_LEVEL:
                self._errors.append(f"the server sent an error status: {msg.get('message')!r}")
        elif op == "removeStatus":
            pass
        else:
            self._errors.append(f"a JSON message of unexpected op {op!r}: {text[:200]!r}")

    def _on_advertise(self, channels: Any) -> None:
        if not isinstance(channels, list):
            self._errors.append(f"advertise without a channels list: {channels!r}")
            return
        for entry in channels:
            try:
                ch = _channel_from_json(entry)
            except ValueError as exc:
                self._errors.append(str(exc))
                continue
            old = self._channels.get(ch.id)
            if old is not None and old != ch:
                self._errors.append(f"channel id {ch.id} re-advertised with other contents: {old} then {ch}")
            self._channels[ch.id] = ch

    def _on_unadvertise(self, ids: Any) -> None:
        if not isinstance(ids, list):
            self._errors.append(f"unadvertise without a channelIds list: {ids!r}")
            return
        for cid in ids:
            if self._channels.pop(cid, None) is None:
                self._errors.append(f"unadvertise of channel id {cid!r}, never advertised")
            for sid in [s for s, ch in self._subs.items() if ch.id == cid]:
                del self._subs[sid]  # the server drops the subscription with the channel
                self._retired.add(sid)

    def _on_binary(self, data: bytes) -> None:
        if not data:
            self._errors.append("an empty binary frame")
        elif data[0] == OP_MESSAGE_DATA:
            if len(data) < _MESSAGE_HEADER.size:
                self._errors.append(f"a messageData frame of {len(data)} bytes, shorter than its header")
                return
            _, sid, stamp = _MESSAGE_HEADER.unpack_from(data)
            ch = self._subs.get(sid)
            if ch is not None:
                self._received.append(Received(ch.topic, stamp, data[_MESSAGE_HEADER.size:], ch, sid))
            elif sid in self._retired:
                self.late_frames += 1
            else:
                self._errors.append(f"a messageData frame for subscription id {sid}, never subscribed")
        elif data[0] == OP_TIME:
            caps = (self.server_info or {}).get("capabilities", [])
            if "time" not in caps or len(data) != _TIME_FRAME.size:
                self._errors.append(f"a time frame of {len(data)} bytes from a server with capabilities {caps}")
                return
            self.times_ns.append(_TIME_FRAME.unpack(data)[1])
        else:
            self._errors.append(f"a binary frame of unknown opcode 0x{data[0]:02x} ({len(data)} bytes)")

    # ---- waiting
    def _wait(self, ready: Callable[[], Any], timeout: float, what: str, allow_errors: bool = False) -> Any:
        """Wait (lock held while testing) until ``ready()`` is truthy; return its value. TimeoutError
        after ``timeout`` s, ConnectionError if the connection closes first, and (unless
        ``allow_errors``) AssertionError as soon as a protocol error is recorded, so a broken stream
        fails at once instead of at the timeout."""
        deadline = time.monotonic() + timeout
        with self._cond:
            while True:
                value = ready()
                if value:
                    return value
                if self._errors and not allow_errors:
                    raise AssertionError(f"{self.url}: protocol errors while waiting for {what}: {self._errors}")
                if self._closed:
                    raise ConnectionError(f"{self.url}: the connection closed while waiting for {what}; "
                                          f"errors: {self._errors}")
                left = deadline - time.monotonic()
                if left <= 0:
                    raise TimeoutError(f"{self.url}: no {what} in {timeout:.0f} s (a hang?); "
                                       f"{self._summary()}")
                self._cond.wait(min(left, 1.0))

    def wait_until(self, ready: Callable[[], Any], what: str, timeout: float = DEFAULT_TIMEOUT_S,
                   allow_errors: bool = False) -> Any:
        """Wait until ``ready()`` (called with the client's lock held, so it may read the accessors) is
        truthy; return its value. TimeoutError naming ``what`` after ``timeout`` s; AssertionError
        once a protocol error is recorded, unless ``allow_errors``."""
        return self._wait(ready, timeout, what, allow_errors)

    def _summary(self) -> str:
        counts: dict[str, int] = {}
        for r in self._received:
            counts[r.topic] = counts.get(r.topic, 0) + 1
        topics = sorted(ch.topic for ch in self._channels.values())
        return f"advertised {topics}, received {counts}, errors {self._errors}"

    def wait_for_topics(self, topics: Iterable[str], timeout: float = DEFAULT_TIMEOUT_S) -> dict[str, ChannelInfo]:
        """Wait until every topic is advertised; return topic -> channel. Fails on a protocol error."""
        wanted = list(topics)

        def ready() -> dict[str, ChannelInfo] | None:
            by_topic = {ch.topic: ch for ch in self._channels.values()}
            return {t: by_topic[t] for t in wanted} if all(t in by_topic for t in wanted) else None
        return self._wait(ready, timeout, f"advertise of {wanted}")

    def wait_for(self, condition: int | Callable[[list[Received]], Any], topic: str | None = None,
                 timeout: float = DEFAULT_TIMEOUT_S) -> list[Received]:
        """Wait until ``condition`` holds for the messages received (on ``topic``, or all): an int
        means at least that many; a callable is called with the list and must return truthy.
        Returns the list of messages at that moment. Fails at once on a protocol error."""
        def ready() -> list[Received] | None:
            got = [r for r in self._received if topic is None or r.topic == topic]
            ok = len(got) >= condition if isinstance(condition, int) else condition(got)
            return got if ok else None
        what = f"{condition} messages" if isinstance(condition, int) else "messages that satisfy the condition"
        return self._wait(ready, timeout, what + (f" on {topic}" if topic else ""))

    # ---- subscribing
    def subscribe(self, topics: Iterable[str], timeout: float = DEFAULT_TIMEOUT_S) -> dict[str, int]:
        """Wait until the topics are advertised, then subscribe to each in one ``subscribe`` message.
        Returns topic -> subscription id. ValueError for a topic already subscribed or advertised twice."""
        wanted = list(topics)
        self.wait_for_topics(wanted, timeout)
        with self._cond:
            subs = []
            for topic in wanted:
                chans = [ch for ch in self._channels.values() if ch.topic == topic]
                if len(chans) != 1:
                    raise ValueError(f"topic {topic} is advertised on {len(chans)} channels: {chans}")
                if any(ch.id == chans[0].id for ch in self._subs.values()):
                    raise ValueError(f"topic {topic} is already subscribed")
                subs.append((self._next_sub, chans[0]))
                self._next_sub += 1
            for sid, ch in subs:
                self._subs[sid] = ch
        self._send({"op": "subscribe", "subscriptions": [{"id": sid, "channelId": ch.id} for sid, ch in subs]})
        return {ch.topic: sid for sid, ch in subs}

    def subscribe_all(self) -> dict[str, int]:
        """Subscribe to every channel advertised now and not yet subscribed."""
        with self._cond:
            taken = {ch.id for ch in self._subs.values()}
            topics = [ch.topic for ch in self._channels.values() if ch.id not in taken]
        return self.subscribe(topics) if topics else {}

    def unsubscribe(self, topics: Iterable[str]) -> None:
        """Send ``unsubscribe`` for the subscriptions to these topics (KeyError for one not subscribed)."""
        wanted = set(topics)
        with self._cond:
            sids = [sid for sid, ch in self._subs.items() if ch.topic in wanted]
            if len(sids) != len(wanted):
                raise KeyError(f"not subscribed to {sorted(wanted - {self._subs[s].topic for s in sids})}")
            for sid in sids:
                del self._subs[sid]
                self._retired.add(sid)
        self._send({"op": "unsubscribe", "subscriptionIds": sids})

    def _send(self, msg: dict) -> None:
        self._ws.send(json.dumps(msg))

    # ---- publishing
    def advertise(self, topic: str, encoding: str, schema_name: str, schema: str | None = None,
                  schema_encoding: str | None = None) -> int:
        """Advertise a client channel (one ``advertise`` message); returns its id. ValueError unless the
        server said it takes client messages (``clientPublish``) in ``encoding``."""
        info = self.server_info or {}
        if "clientPublish" not in info.get("capabilities", []):
            raise ValueError(f"{self.url}: the server does not take client messages (capabilities {info.get('capabilities')})")
        if encoding not in info.get("supportedEncodings", []):
            raise ValueError(f"{self.url}: the server takes {info.get('supportedEncodings')}, not {encoding!r}")
        with self._cond:
            cid = self._next_channel
            self._next_channel += 1
            self._advertised[cid] = (topic, encoding)
        channel: dict[str, Any] = {"id": cid, "topic": topic, "encoding": encoding, "schemaName": schema_name}
        if schema is not None:
            channel["schema"] = schema
        if schema_encoding is not None:
            channel["schemaEncoding"] = schema_encoding
        self._send({"op": "advertise", "channels": [channel]})
        return cid

    def publish(self, channel_id: int, payload: bytes) -> None:
        """Send one message on an advertised client channel (a binary ``0x01`` frame)."""
        with self._cond:
            if channel_id not in self._advertised:
                raise KeyError(f"client channel {channel_id} is not advertised")
        self._ws.send(struct.pack("<BI", OP_MESSAGE_DATA, channel_id) + bytes(payload))

    def unadvertise(self, channel_ids: Iterable[int]) -> None:
        """Withdraw client channels (one ``unadvertise`` message)."""
        ids = list(channel_ids)
        with self._cond:
            for cid in ids:
                del self._advertised[cid]
        self._send({"op": "unadvertise", "channelIds": ids})

    # ---- reading what arrived
    @property
    def channels(self) -> dict[int, ChannelInfo]:
        """Channel id -> channel, as advertised and not unadvertised."""
        with self._cond:
            return dict(self._channels)

    def topics(self) -> set[str]:
        """The topics advertised now."""
        return {ch.topic for ch in self.channels.values()}

    def messages(self, topic: str | None = None) -> list[Received]:
        """The messages received so far on ``topic`` (or all), in order of arrival."""
        with self._cond:
            return [r for r in self._received if topic is None or r.topic == topic]

    @property
    def errors(self) -> list[str]:
        """Protocol violations seen so far (see the module's doc); a test asserts this empty."""
        with self._cond:
            return list(self._errors)

    @property
    def closed(self) -> bool:
        """True once the connection is closed (by either side)."""
        with self._cond:
            return self._closed

    def close(self, timeout: float = DEFAULT_TIMEOUT_S) -> None:
        """Close the connection cleanly (close frame, code 1000) and stop the receiving thread."""
        with self._cond:
            self._closing = True
        self._ws.close()
        self._thread.join(timeout)
        if self._thread.is_alive():
            raise TimeoutError(f"{self.url}: the receiving thread did not stop in {timeout:.0f} s (a hang?)")
