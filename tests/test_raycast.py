"""The closed-form ray caster against hand geometry and against PyBullet's own ray tests."""

from __future__ import annotations

import math

import gymnasium as gym
import numpy as np
import pybullet as p
import pytest

import bulletnav  # noqa: F401  (registers the ids)
from bulletnav.errors import ConfigError
from bulletnav.sensors.raycast import ExactCaster
from bulletnav.sim.world import Primitive


def unit(*v: float) -> np.ndarray:
    a = np.array(v, dtype=np.float64)
    return a / np.linalg.norm(a)


def test_hits_on_hand_geometry():
    cyl = Primitive("cylinder", (3.0, 0.0, 0.5), (0.2, 0.2, 0.5))
    caster = ExactCaster([cyl])
    o = np.array([0.0, 0.0, 0.3])
    # head on: the near side, 2.8 m away
    assert caster.cast(o, unit(1, 0, 0)[None], 10.0)[0] == pytest.approx(2.8, abs=1e-12)
    # a ray passing 0.15 m from the axis: enters at sqrt(0.2^2 - 0.15^2) before the closest point
    d = unit(3.0, 0.15, 0.0)
    along, offset = 3.0 * d[0], 3.0 * d[1]  # the axis: its projection on the ray, its distance from it
    expect = along - math.sqrt(0.2 ** 2 - offset ** 2)
    assert caster.cast(o, d[None], 10.0)[0] == pytest.approx(expect, abs=1e-12)
    # tangent-plus-a-hair misses, tangent-minus-a-hair hits
    for miss, gap in ((True, 1e-6), (False, -1e-6)):
        angle = math.asin((0.2 + gap) / 3.0)
        got = caster.cast(o, unit(math.cos(angle), math.sin(angle), 0)[None], 10.0)[0]
        assert math.isinf(got) if miss else got == pytest.approx(3.0 * math.cos(angle), abs=1e-3)
    # beyond the ray's length: nothing
    assert math.isinf(caster.cast(o, unit(1, 0, 0)[None], 2.5)[0])
    # from below the cylinder, straight up: its bottom cap (z = 0) is 0.3 m above an origin at z = -0.3
    assert caster.cast(np.array([3.05, 0.0, -0.3]), unit(0, 0, 1)[None], 5.0)[0] == pytest.approx(0.3, abs=1e-12)
    # over the top: a ray rising past z = 1 before it reaches the cylinder misses it
    assert math.isinf(caster.cast(np.array([0.0, 0.0, 0.9]), unit(1, 0, 0.1)[None], 10.0)[0])
    # from inside: 0
    assert caster.cast(np.array([3.0, 0.1, 0.5]), unit(1, 0, 0)[None], 5.0)[0] == 0.0


def test_vertical_rays_hit_only_the_cylinders_they_start_over():
    """A ray with no horizontal part stays over the point it starts from: straight down from
    z = 2 it meets a cylinder's top cap (z = 1, 1 m below) only where that point lies within the
    cylinder's radius, by hand. (It "hit" every cylinder in the world before, wherever it was.)"""
    near = Primitive("cylinder", (3.0, 0.0, 0.5), (0.2, 0.2, 0.5))
    far = Primitive("cylinder", (-4.0, 5.0, 0.5), (0.075, 0.075, 0.5))
    caster = ExactCaster([near, far])
    down, up = unit(0, 0, -1)[None], unit(0, 0, 1)[None]
    assert math.isinf(caster.cast(np.array([0.0, 0.0, 2.0]), down, 10.0)[0])  # over neither
    assert math.isinf(caster.cast(np.array([3.0, 0.21, 2.0]), down, 10.0)[0])  # 1 cm outside the radius
    assert caster.cast(np.array([3.0, 0.19, 2.0]), down, 10.0)[0] == pytest.approx(1.0, abs=1e-12)
    assert caster.cast(np.array([-4.0, 5.07, 2.0]), down, 10.0)[0] == pytest.approx(1.0, abs=1e-12)
    assert math.isinf(caster.cast(np.array([3.0, 0.19, 2.0]), up, 10.0)[0])  # rising away from it
    many = ExactCaster([Primitive("cylinder", (x, 0.0, 0.5), (0.1, 0.1, 0.5)) for x in range(-50, 50, 2)])
    assert math.isinf(many.cast(np.array([1.0, 0.0, 2.0]), down, 10.0)[0])  # between two of fifty


def test_box_plane_and_the_nearest_of_several():
    # a box turned 45 degrees: its corner points at the origin, sqrt(2) * 0.5 from its centre
    box = Primitive("box", (4.0, 0.0, 1.0), (0.5, 0.5, 1.0), math.pi / 4)
    floor = Primitive("plane", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    near = Primitive("cylinder", (2.0, 3.0, 0.5), (0.1, 0.1, 0.5))
    caster = ExactCaster([box, floor, near])
    o = np.array([0.0, 0.0, 0.25])
    dirs = np.stack([unit(1, 0, 0), unit(-1, 0, -0.05), unit(2.0, 3.0, 0.0), unit(0, 1, 0)])
    got = caster.cast(o, dirs, 30.0)
    assert got[0] == pytest.approx(4.0 - math.sqrt(2) * 0.5, abs=1e-12)
    assert got[1] == pytest.approx(0.25 / math.sin(math.atan(0.05)), abs=1e-9)  # the floor, 5 m out
    assert got[2] == pytest.approx(math.hypot(2.0, 3.0) - 0.1, abs=1e-12)
    assert math.isinf(got[3])
    # parallel to a box's face, inside its slab and outside it
    flat = ExactCaster([Primitive("box", (5.0, 0.0, 1.0), (1.0, 1.0, 1.0))])
    assert flat.cast(np.array([0.0, 0.5, 0.5]), unit(1, 0, 0)[None], 10.0)[0] == pytest.approx(4.0)
    assert math.isinf(flat.cast(np.array([0.0, 1.5, 0.5]), unit(1, 0, 0)[None], 10.0)[0])
    with pytest.raises(ValueError, match="sphere"):
        ExactCaster([Primitive("sphere", (0.0, 0.0, 0.0), (1.0, 1.0, 1.0))])


def _pybullet_cast(primitives, origins, dirs, length):
    """The same rays through PyBullet: bodies built from the primitives, rayTestBatch."""
    cid = p.connect(p.DIRECT)
    try:
        for s in primitives:
            if s.kind == "box":
                col = p.createCollisionShape(p.GEOM_BOX, halfExtents=s.half, physicsClientId=cid)
            else:
                col = p.createCollisionShape(p.GEOM_CYLINDER, radius=s.half[0], height=2 * s.half[2], physicsClientId=cid)
            orn = p.getQuaternionFromEuler([0, 0, s.yaw])
            p.createMultiBody(0.0, col, -1, s.center, orn, physicsClientId=cid)
        starts = np.repeat(origins, len(dirs) // len(origins), axis=0)
        hits = p.rayTestBatch(starts.tolist(), (starts + dirs * length).tolist(), physicsClientId=cid)
        return np.array([h[2] * length if h[0] >= 0 else math.inf for h in hits]), np.array([h[3] for h in hits])
    finally:
        p.disconnect(cid)


def test_agrees_with_pybullet_to_its_convex_cast_tolerance():
    rng = np.random.default_rng(7)
    prims = [Primitive("cylinder", (x, y, 0.5), (0.075, 0.075, 0.5)) for x, y in rng.uniform(-4, 4, (120, 2))]
    prims += [Primitive("box", (x, y, 0.4), (hx, hy, 0.4), yaw)
              for x, y, hx, hy, yaw in zip(*rng.uniform(-4, 4, (2, 12)), *rng.uniform(0.1, 0.6, (2, 12)),
                                             rng.uniform(-math.pi, math.pi, 12))]
    caster = ExactCaster(prims)
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    fan = np.stack([np.cos(angles), np.sin(angles), np.full_like(angles, -0.002)], 1)
    fan /= np.linalg.norm(fan, axis=1, keepdims=True)
    # origins outside every shape (PyBullet does not report a shape a ray starts in)
    candidates = rng.uniform(-5, 5, (60, 3)) * [1, 1, 0] + [0, 0, 0.25]
    origins = np.array([o for o in candidates if caster.cast(o, fan, 30.0).min() > 0][:20])
    dirs = np.concatenate([fan] * len(origins))
    theirs, points = _pybullet_cast(prims, origins, dirs, 30.0)
    ours = np.concatenate([caster.cast(o, fan, 30.0) for o in origins])
    both = np.isfinite(ours) & np.isfinite(theirs)
    assert both.sum() > 900
    diff = ours[both] - theirs[both]
    assert np.median(np.abs(diff)) < 2e-4 and np.mean(np.abs(diff) <= 1e-3) > 0.8
    # PyBullet's shapes are never thinner than the true ones, so the exact range is never shorter ...
    assert np.all(ours >= theirs - 1e-3)
    # ... and where it is longer, PyBullet's hit lies within 2 mm outside a shape's true surface
    # (its convex cast's tolerance; a grazing ray can then read metres shorter)
    longer = np.where(ours > theirs + 1e-3)[0]
    assert len(longer)
    centres = np.array([s.center[:2] for s in prims if s.kind == "cylinder"])
    for i in longer:
        gap = np.min(np.hypot(*(centres - points[i][:2]).T)) - 0.075
        assert gap <= 2e-3 or _near_a_box(points[i], prims)


def _near_a_box(point, prims, tol=2e-3):
    for s in prims:
        if s.kind != "box":
            continue
        c, sn = math.cos(s.yaw), math.sin(s.yaw)
        dx, dy = point[0] - s.center[0], point[1] - s.center[1]
        lx, ly = c * dx + sn * dy, -sn * dx + c * dy
        if abs(lx) <= s.half[0] + tol and abs(ly) <= s.half[1] + tol:
            return True
    return False


def test_barn_lidar_matches_pybullet_and_the_caster_is_checked():
    exact = gym.make("bulletnav/BARN-v0", world_idx=12, lidar_noise=0.0)
    bullet = gym.make("bulletnav/BARN-v0", world_idx=12, lidar_noise=0.0, lidar_caster="bullet")
    try:
        a, _ = exact.reset(seed=1)
        b, _ = bullet.reset(seed=1)
        ra = np.asarray(exact.unwrapped.scene.sensors.lidar.read())
        rb = np.asarray(bullet.unwrapped.scene.sensors.lidar.read())
        assert exact.unwrapped.config.sensors.lidar.caster == "exact"
        assert np.mean(np.abs(ra - rb) <= 1e-3) > 0.9
        assert np.all(ra >= rb - 1e-3)
    finally:
        exact.close()
        bullet.close()
    with pytest.raises(ValueError, match="lidar_caster='laser'.*caster must be one of bullet, exact"):
        gym.make("bulletnav/BARN-v0", lidar_caster="laser")
    env = gym.make("bulletnav/Warehouse-v0", lidar_caster="exact", forklifts=1)
    try:
        with pytest.raises(ConfigError, match="caster 'exact' sees only the static world"):
            env.reset(seed=0)
    finally:
        env.close()
