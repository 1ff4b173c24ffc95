"""Who may drive the robot of a ``--live-control`` stream: the web page a client runs in.

A browser tells a WebSocket server which web site opened the connection (the HTTP ``Origin``
header of the handshake) and lets any page connect to any server, ``ws://127.0.0.1`` included.
So a page of another site, open in the user's browser, could drive the robot of a stream that
accepts goals and teleop. The ``foxglove-sdk`` server offers no hook on the handshake, so the
stream that can drive listens behind :class:`OriginGate`, a small front on the user's address:

- **The handshake is read first.** A request with an ``Origin`` that :class:`OriginPolicy` does
  not allow is answered ``403 Forbidden`` and closed; the SDK's server never sees it. Allowed:
  no ``Origin`` (Foxglove's desktop app, scripts and tools), loopback pages
  (``http(s)://localhost``, ``127.0.0.1``, ``[::1]``, any port), Foxglove's own web app
  (:data:`FOXGLOVE_APP`) and the origins the user lists (``--live-allow-origin``).
- **Then bytes pass through unchanged** to the SDK's server on a loopback port of its own, both
  ways, with two changes at the start: the request's ``Sec-WebSocket-Extensions`` is left out
  (no compression, so the first frame can be read), and the server's first frame, its
  ``serverInfo``, gains the metadata ``ROS_DISTRO`` (:data:`ROS_DISTRO`): Foxglove lets its 3D
  panel publish poses only to a ROS data source, and this stream's messages are ROS 2's.
- **Only connections through the gate may publish.** The SDK's own port is on loopback, where a
  page could still find it by trying ports. So the gate, after each handshake it lets through,
  advertises and at once unadvertises a client channel whose topic holds a secret drawn for this
  server (:meth:`OriginGate.token_frames`); the server's listener marks that connection as one
  that came through the gate, and what any other connection publishes is dropped.
- A slow client slows nothing: each direction is copied with back-pressure, so the SDK's server
  sees a slow socket and drops that client's oldest messages as it does without the gate.
"""

from __future__ import annotations

import asyncio
import ipaddress
import json
import logging
import os
import socket
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass
from urllib.parse import urlsplit

from bulletnav.errors import BulletnavError

log = logging.getLogger(__name__)

FOXGLOVE_APP = "https://app.foxglove.dev"
"""Foxglove's web app, allowed to drive without being listed."""
LOOPBACK_HOSTS = ("localhost", "127.0.0.1", "::1")
"""Host names of a page served from this machine (any port, http or https)."""
ROS_DISTRO = "humble"
"""The ``ROS_DISTRO`` the gate adds to the ``serverInfo`` metadata: the ROS 2 release whose
message definitions the stream uses (:mod:`bulletnav.ros.msgdefs`)."""
HANDSHAKE_BYTES = 16 * 1024
"""The longest handshake request the gate reads (bytes); a longer one is refused."""
HANDSHAKE_S = 10.0
"""Seconds a client has to send its whole handshake request."""
GATE_CHANNEL_ID = 0xFFFF_FFFF
"""The client channel id of the gate's own advertisement (the largest uint32: out of the way of
the ids a client counts up from)."""
GATE_TOPIC_PREFIX = "/bulletnav/gate/"
"""The topic of the gate's advertisement is this followed by the server's secret."""


def normalize_origin(text: str) -> str:
    """``text``, an origin (``scheme://host[:port]``), as browsers send it: scheme and host in lower
    case, a default port (80 for http, 443 for https) left out.

    Raises:
        BulletnavError: not an http(s) origin of that form (a path, a query, a user name, no host).
    """
    value = str(text).strip()
    try:
        parts = urlsplit(value)
        port = parts.port
    except ValueError as exc:
        raise BulletnavError(f"--live-allow-origin {text!r}: not an origin ({exc})") from None
    if parts.scheme not in ("http", "https") or not parts.hostname or parts.username is not None \
            or parts.password is not None or parts.path not in ("", "/") or parts.query or parts.fragment:
        raise BulletnavError(f"--live-allow-origin {text!r}: give an origin as a browser sends it, scheme://host[:port] "
                             "(e.g. https://robots.example.com or http://192.168.1.20:8080), no path")
    host = parts.hostname.lower()
    shown = f"[{host}]" if ":" in host else host
    default = {"http": 80, "https": 443}[parts.scheme]
    return f"{parts.scheme}://{shown}" + (f":{port}" if port is not None and port != default else "")


def _is_loopback_page(origin: str) -> bool:
    try:
        parts = urlsplit(origin)
        parts.port  # noqa: B018  (a malformed port raises here)
    except ValueError:
        return False
    if parts.scheme not in ("http", "https") or parts.path or parts.query or parts.fragment or parts.username:
        return False
    return (parts.hostname or "").lower() in LOOPBACK_HOSTS


MAX_REFUSED_ORIGINS = 256
"""Refused origins counted by name; any more are counted together."""


@dataclass(frozen=True)
class OriginPolicy:
    """Which clients may connect to a stream that drives the robot, by their ``Origin`` header."""

    allowed: tuple[str, ...] = ()
    """Origins allowed besides no ``Origin``, loopback pages and :data:`FOXGLOVE_APP`
    (``--live-allow-origin``), each as :func:`normalize_origin` writes it."""

    @classmethod
    def of(cls, origins: tuple[str, ...] | list[str] | None) -> OriginPolicy:
        """The policy allowing ``origins`` too (each checked by :func:`normalize_origin`)."""
        return cls(tuple(dict.fromkeys(normalize_origin(o) for o in origins or ())))

    def allows(self, origin: str | None) -> bool:
        """Whether a client whose handshake carries ``origin`` (None: no ``Origin`` header) may connect."""
        if origin is None:
            return True
        if _is_loopback_page(origin):
            return True
        try:
            normal = normalize_origin(origin)
        except BulletnavError:  # "null" (a file or a sandboxed page) and anything else malformed
            return False
        return normal == FOXGLOVE_APP or normal in self.allowed


def _listen(host: str, port: int) -> socket.socket:
    """A listening TCP socket on ``host``:``port`` (IPv4 or IPv6 as the host is written)."""
    family = socket.AF_INET6 if ":" in host else socket.AF_INET
    try:
        ipaddress.ip_address(host)
    except ValueError:  # a name (localhost): its first address
        family, _, _, _, _ = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM, flags=socket.AI_PASSIVE)[0]
    sock = socket.socket(family, socket.SOCK_STREAM)
    try:
        if os.name != "nt":
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        sock.bind((host, port))
        sock.listen(64)
        sock.setblocking(False)
    except BaseException:
        sock.close()
        raise
    return sock


def parse_request(head: bytes) -> tuple[str, list[tuple[str, str]]]:
    """The request line and the headers (name, value) of an HTTP request head ending in a blank line.

    Raises:
        ValueError: not an HTTP/1.1 GET request head.
    """
    text = head.decode("latin-1")
    lines = text.split("\r\n")
    request = lines[0]
    if not request.startswith("GET ") or not request.endswith(" HTTP/1.1"):
        raise ValueError(f"not a WebSocket handshake: {request[:80]!r}")
    headers = []
    for line in lines[1:]:
        if not line:
            continue
        name, sep, value = line.partition(":")
        if not sep or not name or name != name.strip():
            raise ValueError(f"a malformed header line: {line[:80]!r}")
        headers.append((name, value.strip()))
    return request, headers


def _frame(opcode: int, payload: bytes, mask: bytes | None) -> bytes:
    """One whole WebSocket frame (FIN set), masked with ``mask`` (a client's) or not (a server's)."""
    n = len(payload)
    masked = 0x80 if mask is not None else 0
    if n < 126:
        head = struct.pack("!BB", 0x80 | opcode, masked | n)
    elif n < 1 << 16:
        head = struct.pack("!BBH", 0x80 | opcode, masked | 126, n)
    else:
        head = struct.pack("!BBQ", 0x80 | opcode, masked | 127, n)
    if mask is None:
        return head + payload
    body = bytes(b ^ mask[i % 4] for i, b in enumerate(payload))
    return head + mask + body


async def _read_frame(reader: asyncio.StreamReader) -> tuple[bytes, int, bytes]:
    """A server's frame: (the bytes as read, the first byte, the payload)."""
    raw = await reader.readexactly(2)
    first, second = raw[0], raw[1]
    n = second & 0x7F
    if n == 126:
        ext = await reader.readexactly(2)
        raw += ext
        n = struct.unpack("!H", ext)[0]
    elif n == 127:
        ext = await reader.readexactly(8)
        raw += ext
        n = struct.unpack("!Q", ext)[0]
    if second & 0x80 or n > HANDSHAKE_BYTES * 64:  # a server never masks; a serverInfo is small
        return raw, first, b""
    payload = await reader.readexactly(n)
    return raw + payload, first, payload


def _with_ros_distro(frame: bytes, first: int, payload: bytes) -> bytes:
    """The server's first frame with ``ROS_DISTRO`` in its ``serverInfo`` metadata; the frame as it
    was when it is not a whole, uncompressed ``serverInfo`` text frame."""
    if first != 0x81 or not payload:
        return frame
    try:
        info = json.loads(payload)
    except ValueError:
        return frame
    if not isinstance(info, dict) or info.get("op") != "serverInfo":
        return frame
    metadata = info.get("metadata") if isinstance(info.get("metadata"), dict) else {}
    info["metadata"] = {**metadata, "ROS_DISTRO": metadata.get("ROS_DISTRO", ROS_DISTRO)}
    return _frame(0x1, json.dumps(info, separators=(",", ":")).encode(), None)


class OriginGate:
    """The front of a stream that drives the robot (see the module docstring): listens on
    ``host``:``port`` and passes the connections :class:`OriginPolicy` allows to the
    ``foxglove-sdk`` server on ``127.0.0.1``:``backend_port``.

    Args:
        host: where to listen (``0.0.0.0``, ``::``, ``127.0.0.1`` ...).
        port: the port (0: any free one; :attr:`port` says which).
        backend_port: the SDK server's loopback port.
        policy: who may connect.
        token: the secret the gate's advertisement carries (:meth:`token_frames`).

    Raises:
        OSError: the address cannot be bound.
    """

    def __init__(self, host: str, port: int, backend_port: int, policy: OriginPolicy, token: str) -> None:
        self.policy = policy
        self.backend_port = int(backend_port)
        self._token_frames = self.token_frames(token)
        self._sock = _listen(host, port)
        self.port = int(self._sock.getsockname()[1])
        """The port listened on."""
        self.refused: dict[str, int] = {}
        """Handshakes refused so far, by their ``Origin``."""
        self.on_refused: Callable[[str], None] | None = None
        """Called (on the gate's thread) with the ``Origin`` of each refused handshake."""
        self._loop = asyncio.new_event_loop()
        self._tasks: set[asyncio.Task] = set()
        self._server: asyncio.AbstractServer | None = None
        started = threading.Event()
        self._thread = threading.Thread(target=self._run, args=(started,), name="bulletnav-live-gate", daemon=True)
        self._thread.start()
        started.wait()

    @staticmethod
    def token_frames(token: str) -> bytes:
        """The two masked client frames the gate sends the SDK's server after each handshake it
        lets through: ``advertise`` of a channel on ``/bulletnav/gate/<token>``, then
        ``unadvertise`` of it."""
        mask = os.urandom(4)
        advertise = {"op": "advertise", "channels": [{"id": GATE_CHANNEL_ID, "topic": GATE_TOPIC_PREFIX + token,
                                                       "encoding": "json", "schemaName": "bulletnav.Gate"}]}
        unadvertise = {"op": "unadvertise", "channelIds": [GATE_CHANNEL_ID]}
        return b"".join(_frame(0x1, json.dumps(m).encode(), mask) for m in (advertise, unadvertise))

    # ------------------------------------------------------------------ the loop (its own thread)
    def _run(self, started: threading.Event) -> None:
        asyncio.set_event_loop(self._loop)
        try:
            self._server = self._loop.run_until_complete(asyncio.start_server(self._serve, sock=self._sock,
                                                                              limit=HANDSHAKE_BYTES))
        finally:
            started.set()
        self._loop.run_forever()
        self._loop.run_until_complete(self._loop.shutdown_asyncgens())
        self._loop.close()

    async def _serve(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        if task is not None:
            self._tasks.add(task)
        try:
            await self._connection(reader, writer)
        except (OSError, asyncio.IncompleteReadError, asyncio.LimitOverrunError, TimeoutError, ValueError) as exc:
            log.debug("live gate: a connection ended: %s: %s", type(exc).__name__, exc)
        except asyncio.CancelledError:  # the gate closes: the connection's task ends here, quietly
            pass
        finally:
            writer.close()
            if task is not None:
                self._tasks.discard(task)

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), HANDSHAKE_S)
        request, headers = parse_request(head)
        origins = [value for name, value in headers if name.lower() == "origin"]
        origin = origins[0] if len(origins) == 1 else None
        if len(origins) > 1 or not self.policy.allows(origin):
            shown = origin if len(origins) <= 1 else " and ".join(origins)
            self._refuse(writer, str(shown))
            await writer.drain()
            return
        kept = [f"{name}: {value}" for name, value in headers if name.lower() != "sec-websocket-extensions"]
        b_reader, b_writer = await asyncio.open_connection("127.0.0.1", self.backend_port, limit=HANDSHAKE_BYTES)
        try:
            b_writer.write("\r\n".join([request, *kept, "", ""]).encode("latin-1"))
            response = await asyncio.wait_for(b_reader.readuntil(b"\r\n\r\n"), HANDSHAKE_S)
            upgraded = response.startswith(b"HTTP/1.1 101")
            if upgraded:
                b_writer.write(self._token_frames)
            writer.write(response)
            if upgraded:
                raw, first, payload = await asyncio.wait_for(_read_frame(b_reader), HANDSHAKE_S)
                writer.write(_with_ros_distro(raw, first, payload))
            up = asyncio.ensure_future(_pipe(reader, b_writer, lambda: _write_eof(b_writer)))
            try:
                await _pipe(b_reader, writer, writer.close)  # the server's end ends the connection
            finally:
                up.cancel()
                await asyncio.gather(up, return_exceptions=True)
        finally:
            b_writer.close()

    def _refuse(self, writer: asyncio.StreamWriter, origin: str) -> None:
        first = origin not in self.refused
        if first and len(self.refused) >= MAX_REFUSED_ORIGINS:  # counted, not named, past the first few hundred
            origin = "(other origins)"
        self.refused[origin] = self.refused.get(origin, 0) + 1
        try:
            page, remedy = f"a page of {normalize_origin(origin)}", f" (--live-allow-origin {normalize_origin(origin)} lets it)"
        except BulletnavError:  # "null" (a local file, a sandboxed page) and what is no origin at all
            page, remedy = f"a page with Origin {origin!r}", ""
        body = (f"bulletnav --live-control: {page} may not drive this robot; this server lets connect clients with "
                f"no Origin, loopback pages, {FOXGLOVE_APP} and the origins given with --live-allow-origin\n").encode()
        writer.write(b"HTTP/1.1 403 Forbidden\r\nContent-Type: text/plain; charset=utf-8\r\n"
                     + f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n".encode() + body)
        (log.warning if first else log.debug)("live: refused a connection from %s: it may not drive the robot%s",
                                              page, remedy)
        if self.on_refused is not None:
            self.on_refused(origin)

    # ------------------------------------------------------------------ closing
    async def _shutdown(self) -> None:
        if self._server is not None:
            self._server.close()
        tasks = list(self._tasks)
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        self._loop.stop()

    def close(self) -> None:
        """Stop listening and close every connection through the gate."""
        if not self._thread.is_alive():
            return
        asyncio.run_coroutine_threadsafe(self._shutdown(), self._loop)
        self._thread.join(5.0)


async def _pipe(source: asyncio.StreamReader, sink: asyncio.StreamWriter, at_end: Callable[[], None]) -> None:
    """Bytes from ``source`` to ``sink`` (with back-pressure) until ``source`` ends, then ``at_end()``.
    A ``sink`` that fails is dropped and ``source`` still read to its end: a socket closed with
    bytes unread would reset the connection, and the SDK's server logs a reset as an error."""
    sending = True
    try:
        while True:
            data = await source.read(1 << 16)
            if not data:
                break
            if sending:
                try:
                    sink.write(data)
                    await sink.drain()
                except (OSError, RuntimeError):  # RuntimeError: the transport is closing
                    sending = False
    except OSError:
        pass
    finally:
        at_end()


def _write_eof(writer: asyncio.StreamWriter) -> None:
    """Tell the other end nothing more comes (a half close: what it still sends is read)."""
    try:
        if writer.can_write_eof() and not writer.is_closing():
            writer.write_eof()
    except (OSError, RuntimeError):
        writer.close()


__all__ = ["FOXGLOVE_APP", "LOOPBACK_HOSTS", "OriginGate", "OriginPolicy", "ROS_DISTRO", "normalize_origin", "parse_request"]
