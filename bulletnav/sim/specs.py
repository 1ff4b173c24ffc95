"""The frozen descriptions a layout is made of: static :class:`Obstacle` footprints, moving
obstacles (:class:`ForkliftSpec`, :class:`WorkerSpec`) and scripted :class:`EventSpec` events.

Plain data, no PyBullet: :mod:`bulletnav.sim.layout` parses them from YAML and generates them,
:mod:`bulletnav.sim.movers` and :mod:`bulletnav.sim.events` animate them, and each imports them
from here, one way (this module imports none of them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import ClassVar

import numpy as np

from bulletnav.sim.kernels import BOX, CYLINDER


@dataclass(frozen=True)
class Obstacle:
    """One static obstacle footprint extruded to a height.

    ``kind`` is ``"box"`` (``size`` = full x, y, z extents in its own frame, rotated by
    ``yaw``) or ``"cylinder"`` (``radius``, ``height``). ``center`` is the footprint centre
    (x, y) in metres; every obstacle stands on the floor.
    """

    kind: str
    center: tuple[float, float]
    size: tuple[float, float, float] = (0.0, 0.0, 0.0)
    radius: float = 0.0
    height: float = 0.0
    yaw: float = 0.0
    label: str = ""
    """Free-form category (rack, pallet, box, column) used for colours and statistics."""

    @property
    def top(self) -> float:
        """Height of the obstacle's top above the floor (m)."""
        return self.size[2] if self.kind == "box" else self.height

    def distance(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """Euclidean distance from points (x, y) to the footprint (0 inside)."""
        dx = x - self.center[0]
        dy = y - self.center[1]
        if self.kind == "cylinder":
            return np.maximum(np.hypot(dx, dy) - self.radius, 0.0)
        c, s = math.cos(self.yaw), math.sin(self.yaw)
        lx = np.abs(c * dx + s * dy) - self.size[0] / 2
        ly = np.abs(-s * dx + c * dy) - self.size[1] / 2
        return np.hypot(np.maximum(lx, 0.0), np.maximum(ly, 0.0))

    def footprint(self) -> tuple[int, float, float, float, float, float, float, float]:
        """The footprint as the numbers :mod:`bulletnav.sim.kernels` takes (kind, centre, cos and
        sin of yaw, half sizes, radius), for the compiled form of :meth:`distance`."""
        if self.kind == "cylinder":
            return CYLINDER, self.center[0], self.center[1], 1.0, 0.0, 0.0, 0.0, self.radius
        return BOX, self.center[0], self.center[1], math.cos(self.yaw), math.sin(self.yaw), self.size[0] / 2, \
            self.size[1] / 2, 0.0

    def bounding_radius(self) -> float:
        """Radius of the smallest centred circle that holds the footprint (m)."""
        if self.kind == "cylinder":
            return self.radius
        return 0.5 * math.hypot(self.size[0], self.size[1])


@dataclass(frozen=True)
class ForkliftSpec:
    """A forklift: a box ``size`` = (length along its heading, width, height) m driving
    ``route`` (at least 2 points, m) back and forth at ``speed`` m/s."""

    route: tuple[tuple[float, float], ...]
    speed: float = 0.5
    size: tuple[float, float, float] = (1.1, 0.8, 2.0)
    accel: float | None = None
    """m/s^2 ramp from rest and down to each reversal; None = constant speed."""
    yield_to_robot: bool = True
    field_length: float = 1.0
    """Length (m) of the safety field ahead of the front."""
    field_margin: float = 0.2
    """The field is the forklift's width plus this (m) wide."""
    turn_rate: float = 1.0
    """At a route corner it stops and turns in place at this rate (rad/s); while it turns,
    its field is the circle it sweeps (half its diagonal + ``field_margin``). At a route's
    end it drives back the way it came (no turn: a box reversed covers the same floor)."""
    kind: ClassVar[str] = "forklift"

    @property
    def shape(self) -> tuple[str, tuple[float, ...]]:
        return ("box", tuple(self.size))

    @property
    def bounding_radius(self) -> float:
        return 0.5 * math.hypot(self.size[0], self.size[1])


@dataclass(frozen=True)
class WorkerSpec:
    """A worker: a cylinder (``radius``, ``height`` m) walking ``waypoints`` back and forth
    at ``speed`` m/s, pausing ``pause`` s at each waypoint."""

    waypoints: tuple[tuple[float, float], ...]
    speed: float = 1.0
    radius: float = 0.25
    height: float = 1.7
    pause: float = 1.0
    yield_to_robot: bool = True
    stop_distance: float = 0.6
    """The worker stops while the robot's footprint is closer than this (m)."""
    kind: ClassVar[str] = "worker"

    @property
    def shape(self) -> tuple[str, tuple[float, ...]]:
        return ("cylinder", (self.radius, self.height))

    @property
    def bounding_radius(self) -> float:
        return self.radius


MoverSpec = ForkliftSpec | WorkerSpec


@dataclass(frozen=True)
class EventSpec:
    """At ``at`` seconds, add the obstacle ``add`` or remove the obstacles labelled ``remove``."""

    at: float
    add: Obstacle | None = None
    remove: str | None = None
