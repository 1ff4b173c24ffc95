"""The robot's geometry, read once from its URDF: the one source for every consumer.

The collision outline seen from above, the disc used for sampling, reachability, planning
inflation and scoring, the wheel kinematics and the sensor mounts all come from here, so a
changed URDF changes them everywhere (``rl/features.py``, the navigator, the start/goal
sampler, evaluation's shortest path, the tests). Parsing needs no physics client.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from bulletnav.config import RobotConfig
from bulletnav.errors import ConfigError
from bulletnav.xmlfile import XmlRefused, parse_xml


@dataclass(frozen=True)
class Rectangle:
    """An axis-aligned rectangle of the outline in the body frame (m), centred on ``(cx, cy)``."""

    cx: float
    cy: float
    half_x: float
    half_y: float


@dataclass(frozen=True)
class RobotGeometry:
    """Planar geometry of the robot in its body frame: x forward, y left, origin at the body centre (m)."""

    rectangles: tuple[Rectangle, ...]
    """Footprints of the base link's collision boxes (body and wheel guards): the outline
    that walls and obstacles meet. The wheel spheres roll on the floor only."""
    outline_radius: float
    """Distance from the body centre to the outline's farthest corner (m)."""
    radius: float
    """Disc radius for start/goal sampling, reachability, planning inflation and the
    evaluation's shortest path (m): ``RobotConfig.footprint_radius``, at least ``outline_radius``."""
    wheel_radius: float
    """Wheel radius (m), from the wheel collision sphere."""
    wheelbase: float
    """Distance between the two wheel joints (m)."""
    lidar_mount: tuple[float, float, float]
    """Lidar origin in the body frame (m)."""
    camera_mount: tuple[float, float, float]
    """Camera mount origin in the body frame (m)."""

    @property
    def lidar_offset(self) -> float:
        """How far the lidar sits ahead of the body centre (m)."""
        return self.lidar_mount[0]

    @property
    def half_width(self) -> float:
        """Half the outline's width across the body (m): the farthest any rectangle reaches sideways."""
        return max(abs(r.cy) + r.half_y for r in self.rectangles)

    @property
    def nose(self) -> float:
        """How far the outline reaches ahead of the body centre (m)."""
        return max(r.cx + r.half_x for r in self.rectangles)

    @property
    def centred_rectangles(self) -> tuple[tuple[float, float], ...]:
        """``(half_x, half_y)`` of each rectangle, for outlines symmetric about the body axes.

        Raises:
            ConfigError: a rectangle is off-centre in x or is not mirrored in y.
        """
        out = []
        for r in self.rectangles:
            if abs(r.cx) > 1e-9:
                raise ConfigError(f"outline rectangle {r} is not centred in x")
            out.append((r.half_x, abs(r.cy) + r.half_y))
        return tuple(dict.fromkeys(out))  # mirrored pairs (left/right wheel guard) give one entry


def _xyz(element: ET.Element | None, attribute: str = "xyz") -> tuple[float, float, float]:
    if element is None or element.get(attribute) is None:
        return 0.0, 0.0, 0.0
    x, y, z = (float(v) for v in element.get(attribute, "").split())
    return x, y, z


@lru_cache(maxsize=8)
def _parse(path: str, footprint_radius: float) -> RobotGeometry:
    try:
        with open(path, "rb") as f:
            root = parse_xml(f.read())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot read the robot URDF ({exc.strerror or exc})") from None
    except XmlRefused as exc:
        raise ConfigError(f"{path}: cannot read the robot URDF ({exc})") from None
    links = {link.get("name"): link for link in root.findall("link")}
    joints = {joint.get("name"): joint for joint in root.findall("joint")}
    for name in ("base_link",):
        if name not in links:
            raise ConfigError(f"{path}: robot URDF lacks link {name!r}")
    for name in ("left_wheel_joint", "right_wheel_joint", "lidar_joint", "camera_joint"):
        if name not in joints:
            raise ConfigError(f"{path}: robot URDF lacks joint {name!r}")
    rectangles = []
    for collision in links["base_link"].findall("collision"):
        box = collision.find("geometry/box")
        if box is None:
            continue
        sx, sy, _ = _xyz(box, "size")
        ox, oy, _ = _xyz(collision.find("origin"))
        rectangles.append(Rectangle(ox, oy, sx / 2, sy / 2))
    if not rectangles:
        raise ConfigError(f"{path}: base_link has no collision box to take the outline from")
    outline = max(math.hypot(abs(r.cx) + r.half_x, abs(r.cy) + r.half_y) for r in rectangles)
    if footprint_radius < outline:
        raise ConfigError(f"RobotConfig.footprint_radius={footprint_radius} m is smaller than the robot's outline "
                          f"({outline:.3f} m from the centre to its farthest corner in {path})")
    left = _xyz(joints["left_wheel_joint"].find("origin"))
    right = _xyz(joints["right_wheel_joint"].find("origin"))
    wheel_link = links.get(joints["left_wheel_joint"].find("child").get("link"))  # type: ignore[union-attr]
    shape = None if wheel_link is None else wheel_link.find("collision/geometry/*")
    if shape is None or shape.get("radius") is None:
        raise ConfigError(f"{path}: the left wheel has no collision sphere or cylinder with a radius")
    return RobotGeometry(
        rectangles=tuple(rectangles), outline_radius=outline, radius=footprint_radius,
        wheel_radius=float(shape.get("radius", "0")), wheelbase=abs(left[1] - right[1]),
        lidar_mount=_xyz(joints["lidar_joint"].find("origin")),
        camera_mount=_xyz(joints["camera_joint"].find("origin")),
    )


def robot_geometry(config: RobotConfig | None = None) -> RobotGeometry:
    """The geometry of ``config``'s URDF (default: the shipped robot); parsed once per file.

    Raises:
        ConfigError: the URDF is unreadable or lacks a part, or the footprint radius is
            smaller than the outline.
    """
    config = config or RobotConfig()
    return _parse(str(Path(config.urdf_path()).resolve()), float(config.footprint_radius))
