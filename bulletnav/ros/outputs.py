"""Where a run's ROS 2 messages go: an MCAP file (``--record``), a live Foxglove server
(``--live``), or both, each message CDR-encoded once.

:class:`Ros2Encoder` turns a message (nested dicts, as :mod:`bulletnav.ros.record` builds them)
into CDR bytes with the definition :func:`~bulletnav.ros.msgdefs.msgdef` gives; :class:`Ros2Outputs`
hands those same bytes to every output, so a message streamed live and the one recorded are the
same bytes. :class:`McapFile` is the recording; :class:`~bulletnav.ros.live.LiveServer` the stream.

The outputs also say which topics anyone wants (:meth:`Ros2Outputs.wants`): a recording wants
every topic; a live server only those a client subscribes to, so a stream nobody watches costs
almost nothing.
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from bulletnav.errors import BulletnavError
from bulletnav.files import discard, finish, temp_path
from bulletnav.ros.cdr import encode
from bulletnav.ros.msgdefs import base_topic, msgdef

if TYPE_CHECKING:
    from bulletnav.ros.live import LiveServer

TOPIC_TYPES = {
    "/clock": "rosgraph_msgs/msg/Clock",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/odom": "nav_msgs/msg/Odometry",
    "/imu": "sensor_msgs/msg/Imu",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/goal_pose": "geometry_msgs/msg/PoseStamped",
    "/plan": "nav_msgs/msg/Path",
    "/map": "nav_msgs/msg/OccupancyGrid",
    "/map_truth": "nav_msgs/msg/OccupancyGrid",
    "/movers": "visualization_msgs/msg/MarkerArray",
    "/reward": "std_msgs/msg/Float64",
    "/goal_distance": "std_msgs/msg/Float64",
    "/shield/interventions": "std_msgs/msg/Float64",
    "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
    "/camera/depth": "sensor_msgs/msg/Image",
}
"""Every topic a run may publish and its message type (a fleet's robots publish theirs under
``/robot_<i>``)."""


def topic_type(topic: str) -> str:
    """The message type of ``topic``: :data:`TOPIC_TYPES`'s, a robot's namespaced topic
    (``/robot_2/scan``) that of its last part (``/scan``)."""
    name = base_topic(topic, TOPIC_TYPES)
    if name is None:
        raise KeyError(f"no message type for topic {topic!r}")
    return TOPIC_TYPES[name]


_GRID = "nav_msgs/msg/OccupancyGrid"


class Ros2Encoder:
    """CDR encoding of ROS 2 messages from their ``ros2msg`` definitions (:func:`bulletnav.ros.cdr.encode`:
    mcap-ros2-support's serializer's bytes, an ``OccupancyGrid``'s cells taken as one NumPy block)."""

    def encode(self, kind: str, message: dict[str, Any]) -> bytes:
        """``message`` (nested dicts) of type ``kind`` (``"sensor_msgs/msg/LaserScan"``) as CDR bytes;
        an ``OccupancyGrid``'s ``data`` may be any int8 array-like (a NumPy array included)."""
        if kind == _GRID and not isinstance(message["data"], np.ndarray):
            message = {**message, "data": np.asarray(message["data"], dtype=np.int8)}
        return encode(kind, message)


class McapFile:
    """An MCAP file (``ros2`` profile) of CDR messages written beside ``path`` and renamed by
    :meth:`close` (:meth:`abort` removes it): a schema per message type, a channel per topic.

    Raises:
        BulletnavError: ``path`` exists and ``overwrite`` is off, or does not end in ``.mcap``.
    """

    def __init__(self, path: str | Path, overwrite: bool = False) -> None:
        from mcap.writer import LIBRARY_IDENTIFIER, CompressionType, Writer

        from bulletnav import __version__

        self.path = Path(path)
        if self.path.suffix != ".mcap":
            raise BulletnavError(f"--record {self.path}: a recording is an .mcap file")
        if self.path.exists() and not overwrite:
            raise BulletnavError(f"--record {self.path}: the file already exists; pass --overwrite to replace it")
        self._tmp = temp_path(self.path)
        self._file = open(self._tmp, "wb")  # noqa: SIM115  (closed in close/abort)
        self.writer = Writer(self._file, chunk_size=1024 * 1024, compression=CompressionType.ZSTD, enable_crcs=True)
        """The ``mcap`` writer (metadata and attachments go straight to it)."""
        self.writer.start(profile="ros2", library=f"bulletnav {__version__}; {LIBRARY_IDENTIFIER}")
        self._schemas: dict[str, int] = {}
        self._channels: dict[str, int] = {}
        self.closed = False

    def write_encoded(self, topic: str, kind: str, data: bytes, ns: int, sequence: int) -> None:
        """One message of ``topic`` (type ``kind``, CDR ``data``) at ``ns`` (log and publish time)."""
        channel = self._channels.get(topic)
        if channel is None:
            schema = self._schemas.get(kind)
            if schema is None:
                schema = self._schemas[kind] = self.writer.register_schema(kind, "ros2msg", msgdef(kind).encode())
            channel = self._channels[topic] = self.writer.register_channel(topic, "cdr", schema)
        self.writer.add_message(channel, log_time=ns, data=data, publish_time=ns, sequence=sequence)

    def close(self) -> None:
        if not self.closed:
            self.closed = True
            self.writer.finish()
            self._file.close()
            finish(self._tmp, self.path)

    def abort(self) -> None:
        if not self.closed:
            self.closed = True
            self._file.close()
            discard(self._tmp)


class Ros2Outputs:
    """A run's ROS 2 outputs: ``mcap`` (a :class:`McapFile`), ``live`` (a
    :class:`~bulletnav.ros.live.LiveServer`), either or both.

    Raises:
        BulletnavError: neither is given.
    """

    def __init__(self, mcap: McapFile | None = None, live: LiveServer | None = None) -> None:
        if mcap is None and live is None:
            raise BulletnavError("ROS 2 outputs: give a recording (--record) or a live server (--live), or both")
        self.mcap = mcap
        self.live = live
        self.encoder = Ros2Encoder()
        self.counts: dict[str, int] = {}
        """Messages written per topic."""

    def wants(self, topic: str) -> bool:
        """Whether a message of ``topic`` goes anywhere now: always while recording; live, while a
        client subscribes to it (or before its channel exists, so that it is advertised)."""
        return self.mcap is not None or (self.live is not None and self.live.wants(topic))

    def watched(self, topic: str) -> bool:
        """Whether ``topic`` is taken right now: always while recording; live, while a client
        subscribes to it (or before its channel exists). Unlike :meth:`wants`, false for a latched
        topic nobody subscribes to (its publisher may then skip costly work, e.g. the lidar map)."""
        return self.mcap is not None or (self.live is not None and self.live.watched(topic))

    def write(self, topic: str, message: dict[str, Any], ns: int) -> None:
        """Encode ``message`` once and hand it to every output, stamped ``ns`` (simulated time)."""
        kind = topic_type(topic)
        data = self.encoder.encode(kind, message)
        seq = self.counts.get(topic, 0)
        if self.mcap is not None:
            self.mcap.write_encoded(topic, kind, data, ns, seq)
        if self.live is not None:
            self.live.write_encoded(topic, kind, data, ns)
        self.counts[topic] = seq + 1

    def add_metadata(self, name: str, data: dict[str, str]) -> None:
        """An MCAP metadata record (the recording's; a live stream has none)."""
        if self.mcap is not None:
            self.mcap.writer.add_metadata(name, data)

    def add_attachment(self, ns: int, name: str, media_type: str, data: bytes) -> None:
        """An MCAP attachment (the recording's; a live stream has none)."""
        if self.mcap is not None:
            self.mcap.writer.add_attachment(create_time=ns, log_time=ns, name=name, media_type=media_type, data=data)

    def pace(self, ns: int) -> None:
        """Let the live stream keep to its speed at simulated time ``ns`` (no-op without one)."""
        if self.live is not None:
            self.live.pace(ns)

    def close(self) -> None:
        """Finish the recording (the live server is its owner's to stop)."""
        if self.mcap is not None:
            self.mcap.close()

    def abort(self) -> None:
        """Drop the recording: nothing is left at its path or beside it."""
        if self.mcap is not None:
            self.mcap.abort()


__all__ = ["McapFile", "Ros2Encoder", "Ros2Outputs", "TOPIC_TYPES", "topic_type"]
