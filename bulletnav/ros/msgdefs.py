"""ROS 2 message definitions (the ``.msg`` text, comments and constants' comments left out) of
the messages bulletnav writes, as the MCAP ``ros2msg`` schema encoding carries them: the
message's own definition, then each type it uses after a line of 80 ``=`` and ``MSG: pkg/Type``.

The definitions are those of ROS 2 Humble (``builtin_interfaces``, ``std_msgs``,
``geometry_msgs``, ``sensor_msgs``, ``nav_msgs``, ``tf2_msgs``, ``rosgraph_msgs``,
``visualization_msgs``); a reader decodes from the schema in the file, so no ROS installation
is needed on either side.
"""

from __future__ import annotations

from dataclasses import dataclass

_SEPARATOR = "=" * 80

# Each type's own fields; nested types are named as in .msg files (pkg/Type, or Type in the same package).
_FIELDS: dict[str, str] = {
    "builtin_interfaces/Time": "int32 sec\nuint32 nanosec",
    "builtin_interfaces/Duration": "int32 sec\nuint32 nanosec",
    "std_msgs/Header": "builtin_interfaces/Time stamp\nstring frame_id",
    "std_msgs/ColorRGBA": "float32 r\nfloat32 g\nfloat32 b\nfloat32 a",
    "std_msgs/Float64": "float64 data",
    "rosgraph_msgs/Clock": "builtin_interfaces/Time clock",
    "geometry_msgs/Vector3": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Point": "float64 x\nfloat64 y\nfloat64 z",
    "geometry_msgs/Quaternion": "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1",
    "geometry_msgs/Pose": "Point position\nQuaternion orientation",
    "geometry_msgs/PoseStamped": "std_msgs/Header header\nPose pose",
    "geometry_msgs/PoseWithCovariance": "Pose pose\nfloat64[36] covariance",
    "geometry_msgs/Twist": "Vector3 linear\nVector3 angular",
    "geometry_msgs/TwistWithCovariance": "Twist twist\nfloat64[36] covariance",
    "geometry_msgs/Transform": "Vector3 translation\nQuaternion rotation",
    "geometry_msgs/TransformStamped": "std_msgs/Header header\nstring child_frame_id\nTransform transform",
    "tf2_msgs/TFMessage": "geometry_msgs/TransformStamped[] transforms",
    "sensor_msgs/LaserScan": (
        "std_msgs/Header header\nfloat32 angle_min\nfloat32 angle_max\nfloat32 angle_increment\n"
        "float32 time_increment\nfloat32 scan_time\nfloat32 range_min\nfloat32 range_max\n"
        "float32[] ranges\nfloat32[] intensities"),
    "sensor_msgs/Imu": (
        "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n"
        "geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n"
        "geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance"),
    "sensor_msgs/CompressedImage": "std_msgs/Header header\nstring format\nuint8[] data",
    "sensor_msgs/Image": (
        "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\nuint8 is_bigendian\n"
        "uint32 step\nuint8[] data"),
    "nav_msgs/Odometry": (
        "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n"
        "geometry_msgs/TwistWithCovariance twist"),
    "nav_msgs/Path": "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses",
    "nav_msgs/MapMetaData": (
        "builtin_interfaces/Time map_load_time\nfloat32 resolution\nuint32 width\nuint32 height\n"
        "geometry_msgs/Pose origin"),
    "nav_msgs/OccupancyGrid": "std_msgs/Header header\nMapMetaData info\nint8[] data",
    "visualization_msgs/Marker": (
        "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\nint32 LINE_LIST=5\n"
        "int32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\n"
        "int32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ADD=0\nint32 MODIFY=0\nint32 DELETE=2\n"
        "int32 DELETEALL=3\nstd_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\n"
        "geometry_msgs/Pose pose\ngeometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\n"
        "builtin_interfaces/Duration lifetime\nbool frame_locked\ngeometry_msgs/Point[] points\n"
        "std_msgs/ColorRGBA[] colors\nstring text\nstring mesh_resource\nbool mesh_use_embedded_materials"),
    "visualization_msgs/MarkerArray": "Marker[] markers",
}

_PRIMITIVES = {"bool", "byte", "char", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64",
               "float32", "float64", "string", "wstring"}


@dataclass(frozen=True)
class Field:
    """One field of a message definition."""

    kind: str
    """A primitive type (``float32``, ``string``) or a message type, fully named (``std_msgs/Header``)."""
    name: str
    length: int | None = None
    """None: one value; -1: a sequence (``float32[]``); N: a fixed array of N (``float64[36]``)."""
    default: str | None = None
    """The default written after the name (``float64 w 1``), as text."""

    @property
    def primitive(self) -> bool:
        return self.kind in _PRIMITIVES


def fields(datatype: str) -> list[Field]:
    """The fields of ``datatype`` (``"sensor_msgs/msg/LaserScan"`` or ``"sensor_msgs/LaserScan"``) in
    order, constants left out, message types fully named.

    Raises:
        KeyError: a type bulletnav does not write.
    """
    name = datatype.replace("/msg/", "/")
    package = name.split("/")[0]
    out = []
    for line in _FIELDS[name].splitlines():
        spec, field_name, *default = line.split(maxsplit=2)
        if "=" in field_name:  # a constant
            continue
        kind, bracket, size = spec.partition("[")
        if kind not in _PRIMITIVES and "/" not in kind:
            kind = f"{package}/{kind}"
        length = (-1 if size == "]" else int(size[:-1])) if bracket else None
        out.append(Field(kind, field_name, length, default[0] if default else None))
    return out


def _dependencies(name: str) -> list[str]:
    """The types ``name`` uses (depth first, each once), fully named."""
    out: list[str] = []
    for f in fields(name):
        if f.primitive:
            continue
        for dep in [*_dependencies(f.kind), f.kind]:
            if dep not in out:
                out.append(dep)
    return out


def msgdef(datatype: str) -> str:
    """The schema text of ``datatype`` (``"sensor_msgs/msg/LaserScan"`` or ``"sensor_msgs/LaserScan"``).

    Raises:
        KeyError: a type bulletnav does not write.
    """
    name = datatype.replace("/msg/", "/")
    if name not in _FIELDS:
        raise KeyError(f"no message definition for {datatype!r}; known: {', '.join(sorted(_FIELDS))}")
    parts = [_FIELDS[name]]
    for dep in _dependencies(name):
        parts.append(f"{_SEPARATOR}\nMSG: {dep}\n{_FIELDS[dep]}")
    return "\n".join(parts)


def base_topic(topic: str, names) -> str | None:
    """The topic of ``names`` that ``topic`` is, itself or under a robot's namespace
    (``/robot_2/scan`` is ``/scan``; the longest name that ends it wins), or None."""
    if topic in names:
        return topic
    return next((name for name in sorted(names, key=len, reverse=True) if topic.endswith(name)), None)


def known_types() -> list[str]:
    """Every type :func:`msgdef` knows, as ``pkg/msg/Type``."""
    return sorted(n.replace("/", "/msg/", 1) for n in _FIELDS)


__all__ = ["Field", "base_topic", "fields", "known_types", "msgdef"]
