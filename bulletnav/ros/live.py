"""A live stream of a run's ROS 2 messages: a Foxglove WebSocket server (``--live [HOST:]PORT``).

:class:`LiveServer` serves the messages :class:`~bulletnav.ros.outputs.Ros2Outputs` hands it
(the same CDR bytes a recording gets) on one channel per topic, with the ``ros2msg`` definition
as the channel's schema, through the ``foxglove-sdk`` server. Foxglove (desktop or web app)
connects to ``ws://HOST:PORT``; so can any client of the Foxglove WebSocket protocol.

- **Listening**: on 127.0.0.1 (this machine only) unless a host is given. ``0.0.0.0`` exposes the
  stream, unauthenticated and unencrypted, to every machine that can reach the port.
- **Pacing**: :meth:`LiveServer.pace` holds the run to ``speed`` times real time (1: real time;
  0: as fast as it goes). A run slower than that is not hurried to catch up.
- **Late join**: the last message of each latched topic (:data:`LATCHED`: static transforms,
  maps, goals, plans) is sent again when a client subscribes to it (the others already
  subscribed get it twice).
- **Clients never slow the run**: messages go into each client's own queue (``foxglove-sdk``
  drops the oldest data of a client that falls 1,024 messages behind); a client that leaves
  changes nothing but the queue.
- **Nobody watching costs little**: :meth:`LiveServer.wants` is false for a topic no client
  subscribes to, and the publisher then does not build its messages.
- **Driving** (``control``, ``--live-control``): the server also takes messages clients publish
  (the ``clientPublish`` capability, in the encodings of :data:`CONTROL_ENCODINGS`), which
  :meth:`LiveServer.receive` hands to the run (:mod:`bulletnav.ros.live_control` reads goals and
  teleop from them), and :meth:`LiveServer.status` answers. It then listens behind
  :class:`~bulletnav.ros.live_gate.OriginGate`: a web page of another site cannot connect, and only
  connections through the gate may publish.
"""

from __future__ import annotations

import functools
import hmac
import logging
import queue
import secrets
import threading
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from bulletnav.errors import BulletnavError
from bulletnav.ros.live_gate import GATE_TOPIC_PREFIX, OriginGate, OriginPolicy
from bulletnav.ros.msgdefs import base_topic, msgdef

log = logging.getLogger(__name__)

SPEED_RANGE = (0.001, 1000.0)
"""``speed`` other than 0: from a thousandth of real time (a step of 1/24 s shown over 42 s)
to a thousand times it (``1e-300`` asked for a wait too long for the clock: OverflowError)."""
DEFAULT_HOST = "127.0.0.1"
"""Where the server listens when ``--live`` names only a port: this machine alone."""

LAYOUT = Path(__file__).resolve().parent.parent / "assets" / "foxglove_layout.json"
"""The Foxglove layout shipped with bulletnav (Layouts -> Import from file): a 3D panel following
``base_link`` with the maps, scan, plan, goal and movers; the camera image; plots of commanded and
measured speeds, distance to goal, the shield's interventions and the reward. It serves a live
stream and a recording alike (one robot's topics)."""

CONTROL_ENCODINGS = ("cdr", "json")
"""The message encodings a driving stream takes from clients, in Foxglove's order of preference
(it publishes in the first of them it supports): ``cdr`` (ROS 2 messages), ``json``."""
INBOX_LIMIT = 1024
"""Client messages held for the run at most; more are dropped (the run takes them every step)."""
STATUS_LEVELS = ("info", "warning", "error")
"""The levels of :meth:`LiveServer.status`."""

LATCHED = ("/tf_static", "/map_truth", "/map", "/goal_pose", "/plan")
"""Topics (and a fleet robot's ``/robot_<i>/...`` of them) whose last message a client that
subscribes later still gets, as a ROS 2 transient-local publisher would give it."""


def parse_address(text: str) -> tuple[str, int]:
    """``[HOST:]PORT`` (``8765``, ``0.0.0.0:8765``, ``[::1]:8765``) as ``(host, port)``; the host
    defaults to :data:`DEFAULT_HOST`, port 0 takes any free port.

    Raises:
        BulletnavError: not of that form, or the port is outside 0-65535.
    """
    text = str(text).strip()
    host, sep, port_text = text.rpartition(":")
    if not sep:
        host = DEFAULT_HOST
    elif host.startswith("[") and host.endswith("]"):
        host = host[1:-1]
    if sep and not host:
        raise BulletnavError(f"--live {text!r}: the host before ':' is empty (give [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765)")
    try:
        port = int(port_text)
    except ValueError:
        raise BulletnavError(f"--live {text!r}: the port is not a number (give [HOST:]PORT, e.g. 8765 or 0.0.0.0:8765)") from None
    if not 0 <= port <= 65535:
        raise BulletnavError(f"--live {text!r}: port {port} is outside 0-65535")
    return host, port


@functools.lru_cache(maxsize=1024)
def is_latched(topic: str) -> bool:
    """Whether ``topic`` is one of :data:`LATCHED` (also under a robot's namespace)."""
    return base_topic(topic, LATCHED) is not None


@dataclass(frozen=True)
class ClientMessage:
    """One message a client published to a driving stream."""

    client: int
    """The server's id of the client's connection."""
    topic: str
    encoding: str
    """The message encoding the client advertised (one of :data:`CONTROL_ENCODINGS`)."""
    schema_name: str
    """The type the client advertised (``geometry_msgs/msg/PoseStamped``, ...)."""
    data: bytes


class _Listener:
    """The server's callbacks (its own thread): a subscription to a latched topic gets its last
    message again; on a driving stream, client channels and messages go to the owner."""

    def __init__(self, owner: LiveServer) -> None:
        self.owner = owner

    def on_subscribe(self, client: Any, channel: Any) -> None:
        self.owner._subscribed(channel.topic)

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        self.owner._unsubscribed(channel.topic)

    def on_client_advertise(self, client: Any, channel: Any) -> None:
        self.owner._client_advertised(int(client.id), channel)

    def on_client_unadvertise(self, client: Any, client_channel_id: int) -> None:
        self.owner._client_unadvertised(int(client.id), int(client_channel_id))

    def on_message_data(self, client: Any, client_channel_id: int, data: bytes) -> None:
        self.owner._client_message(int(client.id), int(client_channel_id), data)


class LiveServer:
    """A Foxglove WebSocket server for one run (see the module docstring).

    Args:
        address: ``[HOST:]PORT`` (:func:`parse_address`).
        speed: simulated seconds per wall-clock second (1: real time); 0: unpaced.
        name: the server's name, shown by Foxglove.
        control: who may drive (an :class:`~bulletnav.ros.live_gate.OriginPolicy`): clients may
            then publish (see the module docstring); None: a stream to watch only.

    Raises:
        BulletnavError: the address is malformed, ``speed`` is negative, or the port cannot be
            bound (in use, or not this machine's address).
    """

    def __init__(self, address: str = f"{DEFAULT_HOST}:8765", speed: float = 1.0, name: str = "bulletnav",
                 control: OriginPolicy | None = None) -> None:
        import foxglove
        from foxglove.websocket import Capability

        if not (speed == 0 or SPEED_RANGE[0] <= speed <= SPEED_RANGE[1]):
            raise BulletnavError(f"--speed {speed!r}: give 0 (as fast as it goes) or a speed from {SPEED_RANGE[0]:g} to "
                                 f"{SPEED_RANGE[1]:g} (1: real time)")
        self.host, port = parse_address(address)
        self.speed = float(speed)
        self.control = control
        """Who may drive, or None (a stream to watch only)."""
        self.closed = False
        self._context = foxglove.Context()
        self._token = secrets.token_hex(16)
        self._lock = threading.Lock()
        self._through_gate: set[int] = set()
        self._client_channels: dict[tuple[int, int], tuple[str, str, str]] = {}
        self._inbox: queue.SimpleQueue[ClientMessage] = queue.SimpleQueue()
        self._warned: set[tuple[str, int]] = set()
        self._subscriptions: dict[str, int] = {}  # topic -> client subscriptions taken in
        self._count_lock = threading.Lock()
        self._gate: OriginGate | None = None
        capabilities = [Capability.Time] if control is None else [Capability.Time, Capability.ClientPublish]
        at = (self.host, port) if control is None else ("127.0.0.1", 0)  # behind the gate: a loopback port of its own
        try:
            self._server = foxglove.start_server(name=name, host=at[0], port=at[1], context=self._context,
                                                 server_listener=_Listener(self), capabilities=capabilities,
                                                 supported_encodings=None if control is None else list(CONTROL_ENCODINGS))
        except RuntimeError as e:
            reason = str(e).removeprefix("FoxgloveError: ")
            raise BulletnavError(f"--live {address}: cannot listen on {at[0]}:{at[1]}: {reason}") from None
        self.port = int(self._server.port)
        """The port listened on (the one asked for, or the free one port 0 found)."""
        if control is not None:
            try:
                self._gate = OriginGate(self.host, port, self.port, control, self._token)
            except OSError as e:
                self._server.stop()
                raise BulletnavError(f"--live {address}: cannot listen on {self.host}:{port}: {e.strerror or e}") from None
            self.port = self._gate.port
        self._channels: dict[str, Any] = {}
        self._latched: dict[str, tuple[bytes, int]] = {}
        self._anchor: tuple[float, int] | None = None  # (wall s, simulated ns) pacing counts from
        log.info("live: Foxglove WebSocket server on ws://%s:%d", self.host, self.port)

    @property
    def url(self) -> str:
        """``ws://HOST:PORT`` (IPv6 hosts in brackets)."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"ws://{host}:{self.port}"

    @property
    def gate(self) -> OriginGate | None:
        """The front that checks who may drive (a driving stream), else None."""
        return self._gate

    # ------------------------------------------------------------------ what clients publish
    def _client_advertised(self, client: int, channel: Any) -> None:
        topic = str(channel.topic)
        if topic.startswith(GATE_TOPIC_PREFIX) and hmac.compare_digest(topic[len(GATE_TOPIC_PREFIX):], self._token):
            with self._lock:
                self._through_gate.add(client)
            return
        with self._lock:
            self._client_channels[(client, int(channel.id))] = (topic, str(channel.encoding), str(channel.schema_name))

    def _client_unadvertised(self, client: int, channel_id: int) -> None:
        with self._lock:
            self._client_channels.pop((client, channel_id), None)

    def _client_message(self, client: int, channel_id: int, data: bytes) -> None:
        with self._lock:
            through = client in self._through_gate
            channel = self._client_channels.get((client, channel_id))
        if not through:
            self._warn_once("gate", client, "live: dropped what client %d publishes: it did not connect through "
                                            "the address announced (port %d)", client, self.port)
            return
        if channel is None or self.closed:
            return
        if self._inbox.qsize() >= INBOX_LIMIT:
            self._warn_once("full", client, "live: client %d publishes faster than the run takes it in: "
                                            "messages dropped", client)
            return
        self._inbox.put(ClientMessage(client, channel[0], channel[1], channel[2], bytes(data)))

    def _warn_once(self, kind: str, client: int, message: str, *args: Any) -> None:
        with self._lock:
            first = (kind, client) not in self._warned
            self._warned.add((kind, client))
        (log.warning if first else log.debug)(message, *args)

    def receive(self) -> list[ClientMessage]:
        """The messages clients published since the last call, in order of arrival (a driving
        stream's; always empty otherwise)."""
        out = []
        while True:
            try:
                out.append(self._inbox.get_nowait())
            except queue.Empty:
                return out

    def status(self, message: str, level: str = "error") -> None:
        """Tell every client ``message`` (a Foxglove ``status`` of ``level``, one of :data:`STATUS_LEVELS`)."""
        from foxglove.websocket import StatusLevel

        if level not in STATUS_LEVELS:
            raise ValueError(f"status level must be one of {STATUS_LEVELS}, got {level!r}")
        if not self.closed:
            self._server.publish_status(message, {"info": StatusLevel.Info, "warning": StatusLevel.Warning,
                                                  "error": StatusLevel.Error}[level])

    def _subscribed(self, topic: str) -> None:
        with self._count_lock:
            self._subscriptions[topic] = self._subscriptions.get(topic, 0) + 1
        last = self._latched.get(topic)  # (one dict read: atomic beside the run's thread)
        if last is not None and not self.closed:
            self._channels[topic].log(last[0], log_time=last[1])

    def _unsubscribed(self, topic: str) -> None:
        with self._count_lock:
            self._subscriptions[topic] = max(0, self._subscriptions.get(topic, 0) - 1)

    def subscriptions(self, topic: str) -> int:
        """How many client subscriptions to ``topic`` the server has taken in now (a client's
        subscription counts from when messages logged after it reach that client)."""
        with self._count_lock:
            return self._subscriptions.get(topic, 0)

    def _channel(self, topic: str, kind: str) -> Any:
        channel = self._channels.get(topic)
        if channel is None:
            from foxglove import Channel, Schema

            schema = Schema(name=kind, encoding="ros2msg", data=msgdef(kind).encode())
            channel = self._channels[topic] = Channel(topic, message_encoding="cdr", schema=schema, context=self._context)
        return channel

    def wants(self, topic: str) -> bool:
        """Whether a client subscribes to ``topic`` now; true too for a latched topic (its last
        message is kept for later clients) and for one not yet advertised."""
        return is_latched(topic) or self.watched(topic)

    @property
    def topics(self) -> tuple[str, ...]:
        """The topics advertised so far (one channel each)."""
        return tuple(self._channels)

    def watched(self, topic: str) -> bool:
        """Whether a client subscribes to ``topic`` now (true too before it is advertised)."""
        channel = self._channels.get(topic)
        return channel is None or channel.has_sinks()

    def write_encoded(self, topic: str, kind: str, data: bytes, ns: int) -> None:
        """Send one message of ``topic`` (type ``kind``, CDR ``data``, simulated time ``ns``) to the
        clients subscribed to it (advertising the topic on its first message)."""
        if self.closed:
            return
        if is_latched(topic):
            self._latched[topic] = (data, ns)
        self._channel(topic, kind).log(data, log_time=ns)

    def pace(self, ns: int) -> None:
        """Wait until simulated time ``ns`` is due at :attr:`speed` (no wait when unpaced or late);
        also tells clients the time (``ns``)."""
        if self.closed:
            return
        self._server.broadcast_time(int(ns))
        if self.speed <= 0:
            return
        now = time.perf_counter()
        if self._anchor is None or ns < self._anchor[1]:
            self._anchor = (now, int(ns))
            return
        due = self._anchor[0] + (ns - self._anchor[1]) / 1e9 / self.speed
        if due > now:
            time.sleep(due - now)
        elif now - due > 0.5:  # behind (the run is slower than the speed): go on from here, no catching up
            self._anchor = (now, int(ns))

    def close(self) -> None:
        """Stop the server (clients are disconnected)."""
        if not self.closed:
            self.closed = True
            self._server.stop()  # first: its close frames reach the clients through the gate
            if self._gate is not None:
                self._gate.close()

    def __enter__(self) -> LiveServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


__all__ = ["CONTROL_ENCODINGS", "DEFAULT_HOST", "LATCHED", "LAYOUT", "ClientMessage", "LiveServer", "OriginPolicy", "is_latched",
           "parse_address"]
