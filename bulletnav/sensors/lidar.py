"""2-D scanning lidar: one ``rayTestBatch`` per scan, cast in the lidar link's frame (or, with
``LidarConfig.caster="exact"``, closed-form casts against the world's shapes: :mod:`bulletnav.sensors.raycast`)."""

from __future__ import annotations

import math
from typing import Protocol

import numpy as np
import pybullet as p
from gymnasium import spaces

from bulletnav.config import LidarConfig
from bulletnav.sensors.base import VectorSensor, float32_list
from bulletnav.sensors.raycast import ExactCaster, LevelCaster
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot
from bulletnav.sim.world import STATIC_GROUP, Primitive


class ShapeSource(Protocol):
    """What a lidar casts against in the kinematic profile (:class:`~bulletnav.sim.kinematic.KinematicWorld`)."""

    @property
    def shape_versions(self) -> tuple[int, int]:
        """Counters of the static and of the moving shapes: a changed one means new shapes."""

    def static_primitives(self) -> list[Primitive]:
        """The walls and the obstacles standing now."""

    def moving_primitives(self) -> list[Primitive]:
        """The movers and event bodies placed now."""

    def lidar_pose(self) -> tuple[float, float, float, float]:
        """The lidar's origin (x, y, z m) and heading (rad) now."""


def ray_angles(num_rays: int, fov_deg: float) -> np.ndarray:
    """Ray directions (rad from the heading, counter-clockwise, wrapped to (-pi, pi]): evenly
    spaced from 0 for a full circle, else from ``-fov/2`` to ``fov/2``."""
    if fov_deg >= 360.0:
        angles = np.arange(num_rays) * (2 * math.pi / num_rays)
    else:
        fov = math.radians(fov_deg)
        angles = np.linspace(-fov / 2, fov / 2, num_rays)
    return np.where(angles > math.pi, angles - 2 * math.pi, angles)


class Lidar(VectorSensor):
    """Ranges (m) along ``num_rays`` evenly spaced horizontal rays from the lidar link.

    Ray ``i`` points at ``angles[i]`` radians from the robot heading (counter-clockwise),
    starting at 0 (straight ahead) for a 360 deg scan. Rays are given in the link frame
    (PyBullet's ``parentObjectUniqueId``), so they tilt with the robot, and test only the
    static collision group: the robot never sees itself. Nothing hit reads ``max_range``.

    With ``config.caster == "exact"`` the same rays (from the lidar link's pose) are cast in
    closed form against the primitives handed to :meth:`use_world` instead of by PyBullet.
    """

    name = "lidar"

    def __init__(self, robot: Robot, clock: Clock, config: LidarConfig = LidarConfig()) -> None:
        super().__init__(robot, clock, config.rate_hz)
        self.config = config
        self.angles = ray_angles(config.num_rays, config.fov)
        directions = np.stack([np.cos(self.angles), np.sin(self.angles), np.zeros_like(self.angles)], axis=1)
        self._ray_from = np.zeros((config.num_rays, 3)).tolist()
        self._ray_to = (directions * config.max_range).tolist()
        self._directions = directions
        self._caster: ExactCaster | None = None
        self._shapes: ShapeSource | None = None  # a kinematic world: casts in closed form against what it holds now
        self._casters: tuple[LevelCaster | None, LevelCaster | None] = (None, None)
        self._versions = (-1, -1)
        self.extra_noise_std = 0.0
        """Extra range noise (m) of an evaluation shift or randomization, on top of the config's."""
        self.dropout = 0.0
        """Probability that a ray returns nothing (``max_range``), per ray and scan."""

    def space(self) -> spaces.Box:
        cfg = self.config
        return spaces.Box(np.float32(cfg.min_range), np.float32(cfg.max_range), (cfg.num_rays,), dtype=np.float32)

    def use_world(self, primitives: list[Primitive]) -> None:
        """The static shapes the exact caster casts against (call after every world build);
        nothing for PyBullet's caster."""
        if self.config.caster == "exact":
            self._caster = ExactCaster(primitives)

    def use_shapes(self, shapes: ShapeSource) -> None:
        """Cast in closed form against everything ``shapes`` holds at each scan, its static
        shapes and its movers and events (a kinematic world), whatever ``config.caster`` says."""
        self._shapes = shapes
        self._casters, self._versions = (None, None), (-1, -1)

    @property
    def sees_movers(self) -> bool:
        """Whether the scans see movers and event bodies (PyBullet's rays, or a kinematic world's shapes)."""
        return self._shapes is not None or self.config.caster == "bullet"

    def _shape_fractions(self, shapes: ShapeSource) -> np.ndarray:
        versions = shapes.shape_versions
        if versions != self._versions:
            static, moving = self._casters
            if versions[0] != self._versions[0]:
                static = LevelCaster(shapes.static_primitives(), self.angles)
            if versions[1] != self._versions[1]:
                prims = shapes.moving_primitives()
                moving = LevelCaster(prims, self.angles) if prims else None
            self._casters, self._versions = (static, moving), versions
        x, y, z, yaw = shapes.lidar_pose()
        max_range = self.config.max_range
        t = np.full(len(self.angles), np.inf)
        static, moving = self._casters
        static.cast((x, y, z), yaw, max_range, t)
        if moving is not None:
            moving.cast((x, y, z), yaw, max_range, t)
        return np.minimum(t / max_range, 1.0)

    def _fractions(self) -> list[float]:
        """Hit fraction of each ray in [0, 1] (1 = nothing within ``max_range``)."""
        if self._shapes is not None:
            return self._shape_fractions(self._shapes).tolist()
        if self.config.caster == "bullet":
            return [r[2] for r in self._rays()]
        if self._caster is None:
            raise RuntimeError("lidar caster 'exact' has no world: call use_world() after building one")
        cid, body, link = self.robot.cid, self.robot.body, self.robot.lidar_link
        pos, orn = p.getLinkState(body, link, physicsClientId=cid)[4:6]
        rotation = np.array(p.getMatrixFromQuaternion(orn, physicsClientId=cid)).reshape(3, 3)
        max_range = self.config.max_range
        t = self._caster.cast(np.array(pos), self._directions @ rotation.T, max_range)
        return np.minimum(t / max_range, 1.0).tolist()

    def _rays(self) -> tuple:
        return p.rayTestBatch(
            self._ray_from, self._ray_to, parentObjectUniqueId=self.robot.body,
            parentLinkIndex=self.robot.lidar_link, collisionFilterMask=STATIC_GROUP,
            physicsClientId=self.robot.cid,
        )

    def cast(self) -> np.ndarray:
        """Hit fractions of the rays in [0, 1] (1 = nothing within ``max_range``), noise-free."""
        if self._shapes is not None:
            return self._shape_fractions(self._shapes)
        return np.array(self._fractions())

    def measure_floats(self) -> list[float]:
        cfg = self.config
        if cfg.noise_std > 0 or self.extra_noise_std > 0 or self.dropout > 0:
            ranges = self.cast() * cfg.max_range
            std = math.hypot(cfg.noise_std, self.extra_noise_std)
            if std > 0:
                ranges += self.rng.normal(0.0, std, ranges.shape)
            if self.dropout > 0:
                ranges[self.rng.random(ranges.shape) < self.dropout] = cfg.max_range
            np.maximum(ranges, cfg.min_range, out=ranges)  # np.clip's bounds, without its wrapper's cost
            np.minimum(ranges, cfg.max_range, out=ranges)
            return ranges.astype(np.float32).tolist()  # float32_list's rounding
        # Noise-free (the default, once per step): the double products rounded to float32.
        max_range = cfg.max_range
        ranges = float32_list([f * max_range for f in self._fractions()])
        if cfg.min_range > 0:
            floor = float32_list([cfg.min_range])[0]
            ranges = [r if r > floor else floor for r in ranges]
        return ranges

    def origin(self) -> tuple[float, float, float]:
        """World position of the lidar (m), where its rays start."""
        if self._shapes is not None:
            return self._shapes.lidar_pose()[:3]
        return tuple(p.getLinkState(self.robot.body, self.robot.lidar_link, physicsClientId=self.robot.cid)[4])

    def hit_points(self, ranges: np.ndarray) -> np.ndarray:
        """World (x, y) of each ray's end point for ``ranges`` (for maps and drawing)."""
        yaw = self.robot.state.yaw
        pos = self.origin()
        a = self.angles + yaw
        r = np.asarray(ranges, dtype=np.float64)
        return np.stack([pos[0] + r * np.cos(a), pos[1] + r * np.sin(a)], axis=1)
