"""What kind of bulletnav file a path holds, told from its first bytes, so that a file given
where another kind belongs (a suite as a world, a layout as hyperparameters, a world as a
model) is refused by what it is and where it goes, not by the fields it lacks.

Nothing is imported, run or unpickled: the file's first :data:`HEAD` bytes are matched against
magic numbers, and a YAML file that small is decoded by the safe reader
(:func:`bulletnav.yamlfile.safe_load`) and told apart by its top-level keys.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

HEAD = 64 * 1024
"""Bytes read to tell a file's kind (a YAML file longer than this is not decoded)."""

KINDS: dict[str, tuple[str, str]] = {
    "model": ("a zip archive (a saved model?)", "a model goes to --model"),
    "image": ("an image (a map's picture?)", "a map is its YAML, given to --world"),
    "gazebo": ("a Gazebo world (SDF)", "a world goes to --world"),
    "map": ("a map_server map", "a world goes to --world"),
    "layout": ("a layout (a world)", "a world goes to --world"),
    "suite": ("a benchmark suite", "run it with `bulletnav benchmark FILE`"),
    "hyperparams": ("a hyperparameter file", "it goes to `bulletnav train --hyperparams FILE`"),
    "recording": ("an MCAP recording", "read it with `bulletnav replay FILE` or `bulletnav map FILE`"),
    "rosbag": ("a ROS bag", "read it with `bulletnav map FILE`"),
}
"""Each kind: what it is, and where it belongs (the second half of a refusal)."""

WORLD_KINDS = frozenset({"gazebo", "map", "layout"})

_IMAGE_MAGIC = (b"\x89PNG\r\n\x1a\n", b"P1\n", b"P2\n", b"P3\n", b"P4\n", b"P5\n", b"P6\n", b"P5 ", b"P2 ",
                b"\xff\xd8\xff", b"GIF8")
_ENV_ID = re.compile(r"^([\w.-]+/)?[\w.-]+-v\d+$")  # RL Zoo's blocks: bulletnav/Warehouse-v0, CartPole-v1
_HYPER_KEYS = frozenset({"n_timesteps", "policy", "n_envs", "learning_rate", "n_steps", "batch_size", "gamma",
                         "env_kwargs", "normalize", "policy_kwargs"})


def sniff(path: str | Path) -> str | None:
    """The kind of file at ``path`` (a key of :data:`KINDS`), or None when it is none of them
    for sure (a YAML with misspelt fields, say: the kind's own reader names those)."""
    try:
        with open(path, "rb") as f:
            head = f.read(HEAD + 1)
    except OSError:
        return None
    if head.startswith(b"PK\x03\x04"):
        return "model"
    if head.startswith(_IMAGE_MAGIC) or Path(path).suffix.lower() in (".pgm", ".png", ".pbm", ".ppm", ".jpg", ".jpeg"):
        return "image"
    if head.startswith(b"\x89MCAP"):
        return "recording"
    if head.startswith((b"#ROSBAG", b"SQLite format 3\x00")) or Path(path).suffix.lower() in (".bag", ".db3"):
        return "rosbag"
    text = head.lstrip(b"\xef\xbb\xbf \t\r\n")
    if (text.startswith((b"<?xml", b"<sdf")) and b"<sdf" in head[:4096]) or Path(path).suffix.lower() in (".world", ".sdf"):
        return "gazebo"
    if len(head) > HEAD:
        return None
    return _yaml_kind(head)


def _yaml_kind(data: bytes) -> str | None:
    from bulletnav.yamlfile import safe_load

    try:
        doc: Any = safe_load(data.decode("utf-8-sig"))
    except Exception:  # noqa: BLE001  (anything unreadable is simply no kind: its reader says why)
        return None
    if not isinstance(doc, dict):
        return None
    keys = {str(k) for k in doc}
    if "image" in keys or ("map" in keys and "worlds" not in keys):  # a map, or a wrapper naming one
        return "map"
    if {"worlds", "controllers"} <= keys:
        return "suite"
    if "obstacles" in keys or {"size", "start"} <= keys:
        return "layout"
    if any(_ENV_ID.match(k) for k in keys) or (keys and keys <= _HYPER_KEYS and "policy" in keys):
        return "hyperparams"
    return None


def wrong_kind(path: str | Path, wanted: str) -> str | None:
    """The one-line refusal of ``path`` given where ``wanted`` belongs (``"world"``, ``"suite"``,
    ``"hyperparams"`` or ``"model"``), or None when it is that kind or no kind for sure."""
    kind = sniff(path)
    if kind is None or kind == wanted or (wanted == "world" and kind in WORLD_KINDS):
        return None
    what, where = KINDS[kind]
    wanted_text = {"world": "a world", "suite": "a benchmark suite", "hyperparams": "a hyperparameter file",
                   "model": "a model"}[wanted]
    return f"{path}: {what}, not {wanted_text}: {where}"
