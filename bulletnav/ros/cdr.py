"""CDR encoding (little-endian, XCDR1, as ROS 2's ``rmw`` writes it) of the messages bulletnav
writes, from their definitions in :mod:`bulletnav.ros.msgdefs`.

A message is nested dicts (as :mod:`bulletnav.ros.record` builds them), read as
mcap-ros2-support's serializer reads them, whose bytes these are to the byte
(``tests/test_ros_record.py`` compares them): a missing field is its default (the
definition's, else 0, ``""`` or ``False``), a missing nested message an empty dict, a fixed
array is padded with defaults or cut to its length; ``bytes`` fill a ``uint8[]`` as they are.
A primitive array may also be a NumPy array (an ``OccupancyGrid``'s 60,000 cells go in as one
block instead of one value at a time).

Every value of N bytes starts at a multiple of N counted from the end of the 4-byte
encapsulation header; a string is its length with the closing NUL (uint32), its UTF-8 bytes and
a NUL; a sequence is its length (uint32), then its items. ``wstring`` is not written (none of
bulletnav's messages has one): it is refused with a ValueError.

:func:`decode` reads such bytes back (what a Foxglove client publishes to a ``--live-control``
stream: ``/goal_pose``, ``/cmd_vel``), little- or big-endian CDR, into nested dicts. It trusts
nothing in them: a wrong header, a length that runs past the end, a string without its NUL or not
UTF-8, a non-finite or otherwise odd value left for the caller to judge, and bytes left over after
the message (beyond the 0-3 bytes of padding some writers add) are each refused with a ValueError
naming the field.
"""

from __future__ import annotations

import functools
import struct
from typing import Any

import numpy as np

from bulletnav.ros.msgdefs import Field, fields

HEADER = b"\x00\x01\x00\x00"
"""The encapsulation header: CDR, little-endian."""
_HEADERS = {b"\x00\x00": ">", b"\x00\x01": "<"}
"""The encapsulation kinds :func:`decode` reads (plain CDR, big- and little-endian) and their byte order."""
MAX_DECODE_BYTES = 1 << 20
"""The most bytes :func:`decode` takes (1 MiB: a goal or a twist is under 100)."""

_FORMATS = {"bool": "B", "byte": "B", "char": "b", "int8": "b", "uint8": "B", "int16": "h", "uint16": "H",
            "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q", "float32": "f", "float64": "d"}
"""struct format of each fixed-size primitive (its size is its alignment)."""


def _coerce(kind: str, value: Any, default: Any) -> Any:
    """``value`` as ``kind`` takes it (None: the default)."""
    if value is None:
        return default
    if kind == "string":
        return str(value)
    if kind in ("float32", "float64"):
        return float(value)
    if kind == "bool":
        return 1 if value else 0
    return int(value)


@functools.cache
def _default(f: Field) -> Any:
    """The value of primitive field ``f`` when a message leaves it out."""
    if f.kind == "string":
        return f.default if f.default is not None else ""
    if f.kind in ("float32", "float64"):
        return float(f.default) if f.default is not None else 0.0
    if f.kind == "bool":
        return 1 if f.default in ("true", "True", "1") else 0
    return int(f.default, 0) if f.default is not None else 0


@functools.cache
def _fields(kind: str) -> tuple[Field, ...]:
    if kind == "wstring":  # no message bulletnav writes has one, and rmw implementations disagree on its width
        raise ValueError("a wstring field: bulletnav writes none (its messages are in bulletnav.ros.msgdefs)")
    return tuple(fields(kind))


class _Writer:
    def __init__(self) -> None:
        self.buf = bytearray(HEADER)

    def align(self, size: int) -> None:
        self.buf += b"\0" * (-(len(self.buf) - len(HEADER)) % size)

    def values(self, kind: str, values: list) -> None:
        if kind == "string":
            for value in values:
                data = value.encode()
                self.align(4)
                self.buf += struct.pack("<I", len(data) + 1) + data + b"\0"
            return
        fmt = _FORMATS[kind]
        self.align(struct.calcsize(fmt))
        self.buf += struct.pack(f"<{len(values)}{fmt}", *values)

    def message(self, kind: str, msg: Any) -> None:
        if not _fields(kind):  # an empty message is one uint8 in ROS 2's IDL
            self.values("uint8", [0])
        for f in _fields(kind):
            value = _get(msg, f.name)
            if not f.primitive:
                if f.length is None:
                    self.message(f.kind, value or {})
                    continue
                items = _items(f, value, {})
                if f.length < 0:
                    self.values("uint32", [len(items)])
                for item in items:
                    self.message(f.kind, item)
            elif f.length is None:
                self.values(f.kind, [_coerce(f.kind, value, _default(f))])
            elif isinstance(value, (bytes, bytearray, np.ndarray)) and f.kind != "string":
                self._block(f, value)
            else:
                items = _items(f, value, None)
                if f.length < 0:
                    self.values("uint32", [len(items)])
                self.values(f.kind, [_coerce(f.kind, v, _default(f)) for v in items])

    def _block(self, f: Field, value: bytes | bytearray | np.ndarray) -> None:
        """A primitive array given as bytes (``uint8[]`` only) or a NumPy array, in one piece."""
        if isinstance(value, np.ndarray):
            data = np.ascontiguousarray(value, dtype="<" + _FORMATS[f.kind]).reshape(-1).tobytes()
        elif f.kind in ("uint8", "byte"):
            data = bytes(value)
        else:
            raise ValueError(f"field {f.name!r} is {f.kind}[], not uint8[]: bytes do not fill it")
        size = struct.calcsize(_FORMATS[f.kind])
        if f.length >= 0:
            data = data[:f.length * size].ljust(f.length * size, b"\0")  # (a default other than 0 is never padded in)
        else:
            self.values("uint32", [len(data) // size])
        self.align(size)
        self.buf += data


def _get(msg: Any, name: str) -> Any:
    try:
        return msg[name]
    except (KeyError, TypeError):
        return getattr(msg, name, None)


def _items(f: Field, value: Any, fill: Any) -> list:
    """A field's array as a list: None is empty; a fixed array padded with ``fill`` or cut."""
    if value is None:
        value = []
    if not isinstance(value, (list, tuple)):
        raise ValueError(f"field {f.name!r} is an array ({f.kind}[]), not {type(value).__name__}")
    items = list(value)
    if f.length >= 0:
        items = (items + [fill] * (f.length - len(items)))[:f.length]
    return items


def encode(datatype: str, message: Any) -> bytes:
    """``message`` of type ``datatype`` (``"sensor_msgs/msg/LaserScan"``) as CDR bytes, header first.

    Raises:
        KeyError: a type bulletnav does not write.
        ValueError: an array field holds something that is not one.
    """
    writer = _Writer()
    writer.message(datatype.replace("/msg/", "/"), message)
    return bytes(writer.buf)


class _Reader:
    """Reads CDR values from ``data`` (its encapsulation header already checked) in byte order ``order``."""

    def __init__(self, data: bytes, order: str) -> None:
        self.data = memoryview(data)
        self.order = order
        self.at = len(HEADER)

    def align(self, size: int) -> None:
        self.at += -(self.at - len(HEADER)) % size

    def take(self, n: int, what: str) -> memoryview:
        if n < 0 or self.at + n > len(self.data):
            raise ValueError(f"{what}: needs {n} bytes at offset {self.at}, the message has {len(self.data)}")
        out = self.data[self.at:self.at + n]
        self.at += n
        return out

    def values(self, kind: str, count: int, what: str) -> list:
        if kind == "string":
            return [self.string(what) for _ in range(count)]
        fmt = _FORMATS[kind]
        size = struct.calcsize(fmt)
        self.align(size)
        raw = self.take(size * count, what)
        out = list(struct.unpack(f"{self.order}{count}{fmt}", raw))
        if kind == "bool" and any(v > 1 for v in out):
            raise ValueError(f"{what}: a bool that is neither 0 nor 1")
        return [bool(v) for v in out] if kind == "bool" else out

    def string(self, what: str) -> str:
        self.align(4)
        (n,) = struct.unpack(f"{self.order}I", self.take(4, what))
        if n == 0:
            raise ValueError(f"{what}: a string of length 0 (it must count its closing NUL)")
        raw = bytes(self.take(n, what))
        if raw[-1] != 0:
            raise ValueError(f"{what}: a string without its closing NUL")
        try:
            return raw[:-1].decode("utf-8")
        except UnicodeDecodeError as exc:
            raise ValueError(f"{what}: a string that is not UTF-8 ({exc.reason} at byte {exc.start})") from None

    def count(self, what: str) -> int:
        (n,) = self.values("uint32", 1, what)
        if n > len(self.data) - self.at:  # every item takes at least one byte: a length past the end is a lie
            raise ValueError(f"{what}: a sequence of {n} items in {len(self.data) - self.at} bytes left")
        return n

    def message(self, kind: str, what: str) -> dict[str, Any]:
        if not _fields(kind):
            self.values("uint8", 1, what)
            return {}
        out: dict[str, Any] = {}
        for f in _fields(kind):
            name = f"{what}.{f.name}" if what else f.name
            if not f.primitive:
                if f.length is None:
                    out[f.name] = self.message(f.kind, name)
                else:
                    n = self.count(name) if f.length < 0 else f.length
                    out[f.name] = [self.message(f.kind, f"{name}[{i}]") for i in range(n)]
            elif f.length is None:
                out[f.name] = self.values(f.kind, 1, name)[0]
            else:
                out[f.name] = self.values(f.kind, self.count(name) if f.length < 0 else f.length, name)
        return out


def decode(datatype: str, data: bytes) -> dict[str, Any]:
    """The message of type ``datatype`` (one bulletnav writes: ``"geometry_msgs/msg/PoseStamped"``)
    in the CDR ``data`` (encapsulation header first), as nested dicts; arrays are lists.

    Raises:
        KeyError: a type bulletnav does not know.
        ValueError: ``data`` is not such a message: too long, not plain CDR (XCDR2 and others are
            refused), cut short, a string or bool out of rule, or more than 3 bytes left over.
    """
    data = bytes(data)
    kind = datatype.replace("/msg/", "/")
    _fields(kind)  # KeyError for a type bulletnav does not know, before looking at the bytes
    if len(data) > MAX_DECODE_BYTES:
        raise ValueError(f"{datatype}: {len(data)} bytes, more than the {MAX_DECODE_BYTES} a message may have")
    order = _HEADERS.get(data[:2])
    if len(data) < len(HEADER) or order is None:
        raise ValueError(f"{datatype}: not plain CDR (the encapsulation header is {data[:4].hex() or 'missing'}, "
                         "expected 00010000 or 00000000)")
    reader = _Reader(data, order)
    message = reader.message(kind, "")
    left = len(data) - reader.at
    if left > 3 or any(data[reader.at:]):
        raise ValueError(f"{datatype}: {left} bytes left over after the message (a different type?)")
    return message


__all__ = ["HEADER", "MAX_DECODE_BYTES", "decode", "encode"]
