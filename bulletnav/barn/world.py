"""BARN worlds as bulletnav layouts, and their build in PyBullet.

A BARN world keeps BARN's own frame: cylinders at the world file's (x, y), start (-2.25, 3),
goal (-2.25, 13). The floor is centred on BARN's origin, :data:`FLOOR_SIZE` = 10 x 30 m (x in [-5, 5], y in [-15, 15]): BARN's field
(x in [-4.5, 0], y in [0, 9.6], the goal 3.4 m above it) lies inside with room to spare. BARN
has no enclosing walls; ours stand 0.5 m beyond BARN's side rows of cylinders and 2 m beyond
the goal.

:class:`BarnPhysicsWorld` builds the cylinders in one PyBullet call, ``createMultiBody`` with
``batchPositions``: one static rigid body per cylinder, all sharing one collision shape.
(PyBullet caps a compound shape at 16 children and a multibody at 128 links, so neither can hold
a BARN world in one body.)
"""

from __future__ import annotations

import functools
from dataclasses import replace

import pybullet as p

from bulletnav.barn.data import load_world
from bulletnav.barn.metric import CYLINDER_RADIUS_M, GOAL_OFFSET, START
from bulletnav.errors import LayoutError
from bulletnav.sim.layout import Layout
from bulletnav.sim.specs import Obstacle
from bulletnav.sim.world import STATIC_GROUP, STATIC_MASK, Primitive, World

FLOOR_SIZE = (10.0, 30.0)
"""Floor extent (m) of every BARN layout, centred on BARN's origin."""
CYLINDER_HEIGHT_M = 1.0
"""Height of BARN's cylinders (m, the world files' ``<length>``); ours stand on the floor."""
LABEL = "barn_cylinder"
"""Obstacle label of BARN's cylinders (a layout's statistics and colours)."""


@functools.lru_cache(maxsize=16)
def barn_layout(world_idx: int) -> Layout:
    """BARN world ``world_idx`` (0-299) as a layout with BARN's start and goal (run.py lines 44-47).

    Cached: the same index gives the same object, so an unseeded reset on the same world moves the
    robot back instead of rebuilding the world (a seeded reset rebuilds, as in every bulletnav env)."""
    world = load_world(world_idx)
    obstacles = tuple(Obstacle("cylinder", (float(x), float(y)), radius=CYLINDER_RADIUS_M, height=CYLINDER_HEIGHT_M,
                               label=LABEL) for x, y in world.cylinders)
    goal = (START[0] + GOAL_OFFSET[0], START[1] + GOAL_OFFSET[1])
    return Layout(FLOOR_SIZE, obstacles, name=f"BARN world {world.index}", start=START, goal=goal,
                  source=f"BARN world_{world.index}.world")


class BarnPhysicsWorld(World):
    """:class:`~bulletnav.sim.world.World` that builds a layout's cylinders in one batched call."""

    def build(self, layout: Layout) -> None:
        cylinders = [o for o in layout.obstacles if o.kind == "cylinder"]
        super().build(replace(layout, obstacles=tuple(o for o in layout.obstacles if o.kind != "cylinder")))
        self.layout = layout  # the layout asked for, so the same world is not rebuilt on the next reset
        if not cylinders:
            return
        cid = self.cid
        radius, height = cylinders[0].radius, cylinders[0].height
        if any((o.radius, o.height) != (radius, height) for o in cylinders):
            raise LayoutError(f"{layout.source or layout.name}: BarnPhysicsWorld builds cylinders of one size only")
        col = p.createCollisionShape(p.GEOM_CYLINDER, radius=radius, height=height, physicsClientId=cid)
        # no visual shape: PyBullet's renderers draw the collision shape instead, and a BARN world
        # is built in half the time (209 cylinders here: 66 ms against 133 ms)
        vis = -1
        # maximal coordinates: plain static rigid bodies, which a physics step skips; as multibodies
        # (PyBullet's default) 209 cylinders cost 120 us a physics step here against 30 us
        bodies = p.createMultiBody(0.0, col, vis, batchPositions=[[o.center[0], o.center[1], height / 2] for o in cylinders],
                                   useMaximalCoordinates=True, physicsClientId=cid)
        for body in bodies:  # as the base world's obstacles: they meet the robot and rays, never each other
            p.setCollisionFilterGroupMask(body, -1, STATIC_GROUP, STATIC_MASK, physicsClientId=cid)
            self.labels[body] = LABEL
        self.obstacle_ids = [*self.obstacle_ids, *bodies]
        self.primitives += [Primitive("cylinder", (o.center[0], o.center[1], height / 2), (radius, radius, height / 2))
                            for o in cylinders]
        self.static_set = frozenset((*self.wall_ids, *self.obstacle_ids))


