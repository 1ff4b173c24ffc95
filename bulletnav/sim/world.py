"""The static scene in PyBullet: floor, enclosing walls and obstacles of a :class:`Layout`.

A scene is built with ``resetSimulation`` and rebuilt only when the layout changes, so
bodies are never added and removed per episode (PyBullet leaks memory that way).
"""

from __future__ import annotations

import logging
from typing import NamedTuple

import pybullet as p

from bulletnav.config import PhysicsConfig
from bulletnav.sim.client import configure_physics
from bulletnav.sim.layout import WALL_THICKNESS, Layout
from bulletnav.sim.specs import Obstacle

log = logging.getLogger(__name__)

RAY_GROUP = 1
"""Bullet's default filter group, which PyBullet's ray tests carry."""
ROBOT_GROUP = 2
"""Collision-filter group of the robot's body, caster and sensor links (they collide with everything)."""
STATIC_GROUP = 4
"""Collision-filter group of the floor, walls and obstacles; lidar rays test only this group."""
STATIC_MASK = ROBOT_GROUP | RAY_GROUP
"""Static bodies meet the robot and rays, never each other."""
FLOOR_GROUP = 8
"""Extra group of the floor alone: the only thing the wheel spheres touch."""
WHEEL_GROUP = 16
"""Collision-filter group of the two wheel spheres: they roll on the floor and meet nothing
else (obstacles meet the wheel-sized guard boxes on the robot's base instead)."""

COLOURS = {
    "rack": (0.85, 0.55, 0.15, 1.0),
    "pallet": (0.65, 0.45, 0.25, 1.0),
    "box": (0.8, 0.7, 0.45, 1.0),
    "column": (0.6, 0.6, 0.65, 1.0),
    "wall": (0.75, 0.75, 0.78, 1.0),
    "floor": (0.35, 0.36, 0.38, 1.0),
}


class Primitive(NamedTuple):
    """One static collision shape of a built world, as :class:`World` made it (world frame)."""

    kind: str
    """``"box"``, ``"cylinder"`` (axis along z) or ``"plane"`` (horizontal, facing up)."""
    center: tuple[float, float, float]
    """Centre (m); a plane's point (its height is ``center[2]``)."""
    half: tuple[float, float, float]
    """Half extents (m): a box's along its own axes; a cylinder's (radius, radius, half height)."""
    yaw: float = 0.0
    """Rotation about z (rad) of a box."""


FLOOR_FRICTION = 1.0
"""The floor's nominal lateral friction coefficient."""


class World:
    """Builds a layout into the physics client ``cid`` and remembers what each body is."""

    def __init__(self, cid: int, physics: PhysicsConfig) -> None:
        self.cid = cid
        self.physics = physics
        self.layout: Layout | None = None
        self.floor_id = -1
        self.wall_ids: list[int] = []
        self.obstacle_ids: list[int] = []
        self.static_set: frozenset[int] = frozenset()
        """Walls and obstacles: what the robot must not touch (the floor excluded); a set,
        made once per :meth:`build`, because the collision check runs every step."""
        self.labels: dict[int, str] = {}
        """Body id -> category (floor, wall, rack, pallet, box, column, robot)."""
        self.primitives: list[Primitive] = []
        """The floor, walls and obstacles as plain shapes, made once per :meth:`build` (for
        closed-form ray casts: :class:`~bulletnav.sensors.raycast.ExactCaster`)."""

    def set_floor_friction(self, mu: float) -> None:
        """Set the floor's lateral friction coefficient (PyBullet multiplies it with the wheels')."""
        p.changeDynamics(self.floor_id, -1, lateralFriction=mu, physicsClientId=self.cid)

    def build(self, layout: Layout) -> None:
        """Reset the simulation and create the floor, walls and obstacles of ``layout``.

        Everything in the client, the robot included, is removed: load the robot after.
        """
        cid = self.cid
        p.resetSimulation(physicsClientId=cid)
        configure_physics(cid, self.physics)
        self.layout = layout
        self.labels = {}
        self.primitives = [Primitive("plane", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))]
        hx, hy = layout.half_extents
        cx, cy = layout.centre  # (0, 0) but for a user's map, which stays in its own frame
        margin = WALL_THICKNESS
        floor_col = p.createCollisionShape(p.GEOM_PLANE, physicsClientId=cid)
        floor_vis = p.createVisualShape(
            p.GEOM_BOX, halfExtents=[hx + margin, hy + margin, 0.005], visualFramePosition=[0, 0, -0.005],
            rgbaColor=COLOURS["floor"], physicsClientId=cid,
        )
        self.floor_id = p.createMultiBody(0.0, floor_col, floor_vis, [cx, cy, 0], physicsClientId=cid)
        p.changeDynamics(self.floor_id, -1, lateralFriction=FLOOR_FRICTION, physicsClientId=cid)
        self.labels[self.floor_id] = "floor"
        self.wall_ids = [self._box(c, half, 0.0, COLOURS["wall"], "wall") for c, half in enclosure(layout)]
        self.obstacle_ids = [self._obstacle(o) for o in layout.obstacles]
        # Static bodies collide only with the robot group: otherwise Bullet tracks and
        # narrow-phases every floor-obstacle pair each step (70 us of a 100 us step here).
        for body in [*self.wall_ids, *self.obstacle_ids]:
            p.setCollisionFilterGroupMask(body, -1, STATIC_GROUP, STATIC_MASK, physicsClientId=cid)
        self.static_set = frozenset((*self.wall_ids, *self.obstacle_ids))
        p.setCollisionFilterGroupMask(self.floor_id, -1, STATIC_GROUP | FLOOR_GROUP, STATIC_MASK | WHEEL_GROUP,
                                      physicsClientId=cid)
        log.debug("built layout %r: %d obstacles", layout.name or layout.source, len(self.obstacle_ids))

    def _obstacle(self, o: Obstacle) -> int:
        colour = COLOURS.get(o.label, COLOURS["box"])
        if o.kind == "box":
            return self._box(o.center, (o.size[0] / 2, o.size[1] / 2, o.size[2] / 2), o.yaw, colour, o.label)
        body = static_body(self.cid, "cylinder", (o.radius, o.height), colour, (o.center[0], o.center[1], o.height / 2))
        self.labels[body] = o.label or "column"
        self.primitives.append(Primitive("cylinder", (o.center[0], o.center[1], o.height / 2),
                                         (o.radius, o.radius, o.height / 2)))
        return body

    def _box(self, center: tuple[float, float], half: tuple[float, float, float], yaw: float,
             colour: tuple[float, ...], label: str) -> int:
        orn = p.getQuaternionFromEuler([0.0, 0.0, yaw])
        body = static_body(self.cid, "box", half, colour, (center[0], center[1], half[2]), orn)
        self.labels[body] = label
        self.primitives.append(Primitive("box", (center[0], center[1], half[2]), half, yaw))
        return body


def enclosure(layout: Layout) -> tuple[tuple[tuple[float, float], tuple[float, float, float]], ...]:
    """The four walls around ``layout``'s floor, each as (centre (x, y), half extents (x, y, z)) (m)."""
    hx, hy = layout.half_extents
    cx, cy = layout.centre
    h = layout.wall_height
    t = WALL_THICKNESS
    walls = (
        ((cx, cy + (hy + t / 2)), (hx + t, t / 2)), ((cx, cy + (-hy - t / 2)), (hx + t, t / 2)),
        ((cx + (hx + t / 2), cy), (t / 2, hy)), ((cx + (-hx - t / 2), cy), (t / 2, hy)),
    )
    return tuple((c, (e[0], e[1], h / 2)) for c, e in walls)


def static_body(cid: int, kind: str, dims: tuple[float, ...], colour: tuple[float, ...],
                position: tuple[float, float, float], orientation: tuple[float, ...] | None = None) -> int:
    """A mass-0 body with one collision and one visual shape: ``kind`` ``"box"`` with ``dims``
    its half extents (m), or ``"cylinder"`` with ``dims`` = (radius, height) (m)."""
    if kind == "box":
        col = p.createCollisionShape(p.GEOM_BOX, halfExtents=dims, physicsClientId=cid)
        vis = p.createVisualShape(p.GEOM_BOX, halfExtents=dims, rgbaColor=colour, physicsClientId=cid)
    else:
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=dims[0], height=dims[1], physicsClientId=cid)
        vis = p.createVisualShape(p.GEOM_CYLINDER, radius=dims[0], length=dims[1], rgbaColor=colour, physicsClientId=cid)
    if orientation is None:
        return p.createMultiBody(0.0, col, vis, list(position), physicsClientId=cid)
    return p.createMultiBody(0.0, col, vis, list(position), orientation, physicsClientId=cid)

