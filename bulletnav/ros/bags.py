"""ROS 1 ``.bag`` and ROS 2 ``.db3`` (sqlite3) bags for ``bulletnav map``, read with the
``rosbags`` library (pure Python; no ROS installation).

:func:`read_rosbag` gives the same :class:`~bulletnav.ros.bagmap.BagData` as the MCAP reader:
``sensor_msgs/msg/LaserScan`` on the scan topic, the robot's pose from ``nav_msgs/msg/Odometry``
(or, without it, the ``/tf`` chain to the scan's frame), sensor mounts from ``/tf_static``.
Messages are decoded against the definitions the bag carries (a ROS 1 bag always does; a ROS 2
bag's ``metadata.yaml`` may), else against ROS 2 Humble's standard definitions; nothing in a bag
is executed.

Accepted paths: a ROS 1 ``.bag`` file; a ROS 2 bag directory (with ``metadata.yaml``); a ``.db3``
file inside one; or a ``.db3`` file alone (read with :mod:`sqlite3`: its ``topics`` and
``messages`` tables, CDR messages decoded against Humble's definitions).
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

from bulletnav.errors import BulletnavError
from bulletnav.ros.bagmap import BagData, collect_bag

SUFFIXES = (".bag", ".db3")


def is_rosbag(path: str | Path) -> bool:
    """True for a path :func:`read_rosbag` reads (``.bag``, ``.db3`` or a ROS 2 bag directory)."""
    path = Path(path)
    return path.suffix.lower() in SUFFIXES or (path.is_dir() and (path / "metadata.yaml").is_file())


def _decoder(decode: Any, path: Path, kind: str) -> Any:
    """``decode`` with any failure (a corrupt or truncated message) as one BulletnavError naming the file."""
    def run() -> Any:
        try:
            return decode()
        except Exception as exc:  # rosbags' SerdeError, struct.error, IndexError ... on a bad message
            raise BulletnavError(f"{path}: not a readable {kind}: a message does not decode ({type(exc).__name__}: {exc})") from None
    return run


def _any_reader(paths: list[Path], kind: str, path: Path) -> Iterator[tuple[str, str, Any]]:
    """(topic, type, message) of every message, in time order, through ``rosbags.highlevel.AnyReader``."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    try:
        with AnyReader(paths, default_typestore=get_typestore(Stores.ROS2_HUMBLE)) as reader:
            yield from (("", c.msgtype, c.topic) for c in reader.connections)  # announce every topic first
            for connection, _t, raw in reader.messages(connections=reader.connections):
                yield connection.topic, connection.msgtype, _decoder(lambda r=raw, c=connection: reader.deserialize(r, c.msgtype),
                                                                     path, kind)
    except BulletnavError:
        raise
    except Exception as exc:  # rosbags raises its own errors, and struct/KeyError on corrupt records
        raise BulletnavError(f"{path}: not a readable {kind} ({type(exc).__name__}: {exc})") from None


BAG_TABLES = ("topics", "messages")


def _sqlite(path: Path, wanted: tuple[str, ...]) -> Iterator[tuple[str, str, Any]]:
    """The same from a lone ``.db3`` (no ``metadata.yaml``): its tables, Humble's definitions,
    the messages of the ``wanted`` topics only. The file is opened read-only with
    ``trusted_schema`` off, and its ``topics`` and ``messages`` must be plain tables: a view (or
    a virtual table) is SQL of the file's author, run by whoever reads it, and one view can
    be an endless query. A progress handler lets Ctrl-C and SIGTERM in during a long query."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    try:
        db = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
    except sqlite3.Error as exc:
        raise BulletnavError(f"{path}: not a readable ROS 2 sqlite3 bag ({exc})") from None
    try:
        db.execute("PRAGMA trusted_schema = OFF")
        db.execute("PRAGMA query_only = ON")
        db.set_progress_handler(_let_signals_in, 100_000)
        # SQLite's own account of each table (PRAGMA table_list: table, view, virtual or shadow),
        # not the text of its CREATE statement, which a hand-edited schema can dress up
        kinds = {name: kind for _schema, name, kind, *_rest in db.execute("PRAGMA main.table_list")
                 if name in BAG_TABLES}
        for table in BAG_TABLES:
            kind = kinds.get(table, "")
            if not kind:
                raise BulletnavError(f"{path}: not a ROS 2 sqlite3 bag: it has no {table!r} table")
            if kind != "table":
                what = "a virtual table" if kind == "virtual" else f"a {kind}"
                raise BulletnavError(f"{path}: not a ROS 2 sqlite3 bag: {table!r} is {what}, not a plain table "
                                     "(bulletnav does not run a bag's own SQL)")
            # a generated column (hidden 2 or 3) is an expression of the file's author, run on every read
            generated = [col for _cid, col, *_mid, hidden in db.execute(f"PRAGMA main.table_xinfo({table})")
                         if hidden in (2, 3)]
            if generated:
                raise BulletnavError(f"{path}: not a ROS 2 sqlite3 bag: {table}.{generated[0]} is a generated column "
                                     "(bulletnav does not run a bag's own SQL)")
        topics = {tid: (name, typ) for tid, name, typ in db.execute("SELECT id, name, type FROM topics")}
        yield from (("", typ, name) for name, typ in topics.values())
        ids = [tid for tid, (name, _typ) in topics.items() if name in wanted]
        if not ids:
            return
        marks = ", ".join("?" * len(ids))
        for tid, raw in db.execute(f"SELECT topic_id, data FROM messages WHERE topic_id IN ({marks}) "
                                   "ORDER BY timestamp, id", ids):
            name, typ = topics.get(tid, ("", ""))
            yield name, typ, _decoder(lambda r=raw, t=typ: store.deserialize_cdr(r, t), path, "ROS 2 sqlite3 bag")
    except sqlite3.Error as exc:
        raise BulletnavError(f"{path}: not a readable ROS 2 sqlite3 bag ({exc})") from None
    except (KeyError, IndexError, ValueError, TypeError) as exc:
        raise BulletnavError(f"{path}: not a readable ROS 2 sqlite3 bag ({type(exc).__name__}: {exc})") from None
    finally:
        db.close()


def _let_signals_in() -> int:
    """SQLite's progress handler: Python code, so a pending signal's handler runs here (Python
    runs them between its own steps only); 0 lets the query go on."""
    return 0


def read_rosbag(path: str | Path, scan_topic: str = "/scan", odom_topic: str = "/odom") -> BagData:
    """Read scans and poses from a ROS 1 or ROS 2 (sqlite3) bag (module docstring).

    Raises:
        BulletnavError: the path is missing or not a readable bag; the scan topic is missing or not
            ``LaserScan``; neither the odometry topic nor ``/tf`` gives a pose.
    """
    path = Path(path)
    if not path.exists():
        raise BulletnavError(f"{path}: no such bag file")
    if path.suffix.lower() == ".bag":
        stream = _any_reader([path], "ROS 1 bag", path)
    elif path.is_dir():
        stream = _any_reader([path], "ROS 2 bag", path)
    elif (path.parent / "metadata.yaml").is_file():
        stream = _any_reader([path.parent], "ROS 2 bag", path)
    else:
        stream = _sqlite(path, (scan_topic, odom_topic, "/tf", "/tf_static"))
    return collect_bag(stream, path, scan_topic, odom_topic)


__all__ = ["is_rosbag", "read_rosbag"]
