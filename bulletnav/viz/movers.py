"""What the videos, trajectory plots and GUI dashboard share for dynamic worlds: mover
colours, footprints and event texts.

Everything reads only ``env.unwrapped.scene.movers`` (:class:`~bulletnav.sim.movers.MoverView`)
and the event dicts of ``scene.events`` / ``info["events"]`` (``time_s``, ``action`` "add" or
"remove", ``label``, ``center``, ``size``, ``source``). An event carries no yaw: its footprint
is the axis-aligned ``size[0]`` x ``size[1]`` box (rotated only if a ``yaw`` key is present).

Forklifts are drawn in yellows and ambers, workers in blues and violets (the families of
their PyBullet colours); within a family each mover of the episode keeps its own shade, by
its order among the movers of its kind.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from typing import Any

RGB = tuple[int, int, int]

FORKLIFT_PALETTE: tuple[RGB, ...] = (
    (255, 200, 0), (230, 150, 0), (255, 230, 110), (190, 140, 0), (255, 175, 70), (150, 110, 10),
)
"""Forklift shades (0-255): yellows and ambers."""
WORKER_PALETTE: tuple[RGB, ...] = (
    (40, 120, 255), (150, 90, 240), (90, 60, 190), (100, 175, 255), (195, 125, 255), (30, 70, 200),
)
"""Worker shades (0-255): blues and violets."""
EVENT_RGB: RGB = (0, 210, 190)
"""Events on the dark video map (added footprints outlined, removed ones crossed out)."""
EVENT_HEX = "#008b8b"
"""Events on the light trajectory plots."""


def mover_colour(kind: str, index: int) -> RGB:
    """The shade of the ``index``-th mover of ``kind`` (0-based, in the order of ``scene.movers``)."""
    palette = FORKLIFT_PALETTE if kind == "forklift" else WORKER_PALETTE
    return palette[index % len(palette)]


def mover_colours(kinds: Iterable[str]) -> list[RGB]:
    """One shade per mover, given the movers' kinds in order."""
    seen: dict[str, int] = {}
    out = []
    for kind in kinds:
        k = seen.get(kind, 0)
        seen[kind] = k + 1
        out.append(mover_colour(kind, k))
    return out


def hex_colour(rgb: RGB) -> str:
    return "#{:02x}{:02x}{:02x}".format(*rgb)


def rect_corners(center: Sequence[float], yaw: float, length: float, width: float) -> list[tuple[float, float]]:
    """Corners (counter-clockwise) of a ``length`` x ``width`` rectangle at ``center``, turned by ``yaw``."""
    c, s = math.cos(yaw), math.sin(yaw)
    hx, hy = length / 2, width / 2
    cx, cy = float(center[0]), float(center[1])
    return [(cx + c * x - s * y, cy + s * x + c * y) for x, y in ((-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy))]


def forklift_corners(pose: Sequence[float], size: Sequence[float]) -> list[tuple[float, float]]:
    """A forklift's footprint at ``pose`` (x, y, yaw): ``size[0]`` along its heading, ``size[1]`` across."""
    return rect_corners(pose[:2], float(pose[2]), float(size[0]), float(size[1]))


def event_corners(event: dict[str, Any]) -> list[tuple[float, float]]:
    """An event's footprint: its ``size[0]`` x ``size[1]`` box around ``center``."""
    size = event.get("size") or (0.5, 0.5)
    return rect_corners(event["center"], float(event.get("yaw", 0.0)), float(size[0]), float(size[1]))


def event_text(event: dict[str, Any]) -> str:
    """``12.3 s add pallet (+1.0, -2.0)``."""
    x, y = event["center"][:2]
    return f"{event['time_s']:.1f} s {event['action']} {event.get('label') or 'obstacle'} ({x:+.1f}, {y:+.1f})"


def movers_summary(kinds: Iterable[str]) -> str:
    """``3 forklifts, 2 workers`` (``none`` without movers)."""
    kinds = list(kinds)
    parts = []
    for kind in ("forklift", "worker"):
        n = kinds.count(kind)
        if n:
            parts.append(f"{n} {kind}{'' if n == 1 else 's'}")
    others = len(kinds) - sum(kinds.count(k) for k in ("forklift", "worker"))
    if others:
        parts.append(f"{others} other")
    return ", ".join(parts) or "none"
