"""The policy's clearance features against the robot's real collision shapes in PyBullet."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest
import torch
from gymnasium import spaces

from bulletnav.config import EnvConfig
from bulletnav.envs.scene import Scene
from bulletnav.geometry import robot_geometry
from bulletnav.rl.features import ClearanceFeatures, footprint_distances
from bulletnav.sensors.lidar import ray_angles
from bulletnav.sim.layout import Layout


def outline_distance(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Shapely's distance (m) from body-frame points to the robot's outline seen from above (the
    union of its centred collision rectangles from the URDF; 0 inside)."""
    from shapely.geometry import Point, box
    from shapely.ops import unary_union

    outline = unary_union([box(-hx, -hy, hx, hy) for hx, hy in robot_geometry().centred_rectangles])
    return np.array([outline.distance(Point(float(a), float(b))) for a, b in zip(np.ravel(x), np.ravel(y))])


@pytest.fixture
def scene_at_origin(rng):
    """A scene with the robot at rest at the origin of an empty 10 x 10 m room; closed after the test."""
    scene = Scene(EnvConfig())
    try:
        scene.use_layout(Layout((10.0, 10.0)))
        scene.place_robot((0.0, 0.0, 0.0), rng)
        yield scene
    finally:
        scene.close()


def test_footprint_matches_the_robots_collision_outline(scene_at_origin, report):
    """Cast rays inward, at wheel-centre height, from 1 m outside toward the point under the
    lidar: the first hit is where the robot's outline ends along that ray."""
    scene = scene_at_origin
    cid, body, robot = scene.cid, scene.robot.body, scene.robot
    lidar_xy = p.getLinkState(body, robot.lidar_link, physicsClientId=cid)[4][:2]
    wheel_z = p.getLinkState(body, robot.left_joint, physicsClientId=cid)[4][2]
    angles = ray_angles(36, 360.0)
    starts = [[lidar_xy[0] + math.cos(a), lidar_xy[1] + math.sin(a), wheel_z] for a in angles]
    ends = [[lidar_xy[0], lidar_xy[1], wheel_z]] * len(angles)
    hits = p.rayTestBatch(starts, ends, physicsClientId=cid)
    assert all(h[0] == body for h in hits), "every inward ray must hit the robot"
    measured = np.array([1.0 - h[2] for h in hits])  # metres from the lidar's vertical to the outline
    expected = footprint_distances(36)
    err = np.abs(measured - expected)
    report("largest footprint error over 36 rays (m)", f"{err.max():.4f}")
    assert err.max() < 0.005


def test_closeness_is_one_at_contact_and_fades_with_clearance():
    obs_space = spaces.Box(-3.0, 3.0, (43,), dtype=np.float32)
    extractor = ClearanceFeatures(obs_space, num_rays=36, lidar_range=5.0, scale=0.15)
    assert extractor.features_dim == 79
    foot = footprint_distances(36)
    obs = np.ones((3, 43), dtype=np.float32)
    obs[0, :36] = foot / 5.0                  # every ray touching the outline
    obs[1, :36] = (foot + 0.15) / 5.0         # 0.15 m clear everywhere
    obs[2, :36] = (foot - 0.02) / 5.0         # inside the outline (noise): counts as contact
    out = extractor(torch.as_tensor(obs)).numpy()
    np.testing.assert_array_equal(out[:, :43], obs)  # the observation passes through unchanged
    np.testing.assert_allclose(out[0, 43:], 1.0, atol=1e-5)
    np.testing.assert_allclose(out[1, 43:], math.exp(-1.0), atol=1e-5)
    np.testing.assert_allclose(out[2, 43:], 1.0, atol=1e-6)


def test_extractor_rejects_an_observation_shorter_than_the_scan():
    with pytest.raises(ValueError, match="fewer than num_rays"):
        ClearanceFeatures(spaces.Box(0.0, 1.0, (10,), dtype=np.float32), num_rays=36)


def test_point_clearance_matches_pybullet_closest_distance(scene_at_origin, rng, report):
    """Probe points around the robot at wheel-centre height: the outline clearance equals
    PyBullet's closest distance between the base link's collision shapes (body and wheel
    guards; the wheel spheres meet only the floor) and a tiny sphere there."""
    scene = scene_at_origin
    cid, body, robot = scene.cid, scene.robot.body, scene.robot
    x0, y0, yaw = robot.pose()  # the body frame (PyBullet's base position is the centre of mass)
    wheel_z = p.getLinkState(body, robot.left_joint, physicsClientId=cid)[4][2]
    probe_r = 1e-3
    probe = p.createMultiBody(0.0, p.createCollisionShape(p.GEOM_SPHERE, radius=probe_r, physicsClientId=cid),
                              basePosition=[5.0, 5.0, wheel_z], physicsClientId=cid)
    bx = rng.uniform(-0.35, 0.35, 200)
    by = rng.uniform(-0.35, 0.35, 200)
    expected = outline_distance(bx, by)
    keep = expected > 0.003  # outside the outline (inside, PyBullet reports penetration instead)
    measured = []
    for x, y in zip(bx[keep], by[keep]):
        wx = x0 + x * math.cos(yaw) - y * math.sin(yaw)
        wy = y0 + x * math.sin(yaw) + y * math.cos(yaw)
        p.resetBasePositionAndOrientation(probe, [wx, wy, wheel_z], [0, 0, 0, 1], physicsClientId=cid)
        pts = p.getClosestPoints(body, probe, distance=1.0, linkIndexA=-1, physicsClientId=cid)
        measured.append(min(c[8] for c in pts) + probe_r)
    err = np.abs(np.array(measured) - expected[keep])
    report(f"outline clearance vs PyBullet closest distance, {keep.sum()} points: largest error (m)",
           f"{err.max():.4f}")
    assert keep.sum() > 100
    assert err.max() < 0.003


def test_point_metric_sees_an_edge_between_rays():
    """An obstacle edge almost touching the right wheel from the front-right, seen by the ray
    at -110 deg: along the ray it looks 3 cm clear, to the outline it is 8 mm away."""
    obs_space = spaces.Box(-3.0, 3.0, (43,), dtype=np.float32)
    ray = ClearanceFeatures(obs_space, metric="ray")
    point = ClearanceFeatures(obs_space, metric="point")
    angles = ray_angles(36, 360.0)
    i = int(np.argmin(np.abs(angles - math.radians(-110.0))))
    r = 0.135  # the hit point (0.054, -0.127) m in the body frame: 8 mm from the wheel's corner
    obs = np.ones((1, 43), dtype=np.float32)
    obs[0, i] = r / 5.0
    along_ray = ray.clearance(torch.as_tensor(obs)).numpy()[0, i]
    to_outline = point.clearance(torch.as_tensor(obs)).numpy()[0, i]
    assert along_ray > 0.025
    assert to_outline < 0.01
    np.testing.assert_allclose(to_outline, outline_distance(np.array([0.10 + r * math.cos(angles[i])]),
                                                            np.array([r * math.sin(angles[i])]))[0], atol=1e-5)
    with pytest.raises(ValueError, match="metric"):
        ClearanceFeatures(obs_space, metric="nearest")


# The Jackal's outline by hand (Clearpath's spec sheet: 0.508 m long, 0.430 m wide) and its lidar
# 5.5 cm ahead of the body centre (BARN's JACKAL_LASER_OFFSET on the front mount, run.py:42).
JACKAL_HALF_LENGTH, JACKAL_HALF_WIDTH, JACKAL_LIDAR_X = 0.508 / 2, 0.430 / 2, 0.055


def test_jackal_outline_by_hand_and_the_article_robots_unchanged():
    """73 rays over 270 deg (every 3.75 deg) put rays straight ahead, at +-90 deg and at -135 deg:
    the front face is 0.254 - 0.055 m ahead of the lidar, the sides (wheel guards) 0.215 m beside
    it, and at -135 deg the ray leaves through the guard's side at 0.215 * sqrt(2). The default
    extractor is still the article robot's (front face 0.15 m, lidar 0.10 m ahead of the centre)."""
    foot = footprint_distances(73, 270.0, robot="jackal")
    assert foot[36] == pytest.approx(JACKAL_HALF_LENGTH - JACKAL_LIDAR_X, abs=1e-9)
    assert foot[60] == pytest.approx(JACKAL_HALF_WIDTH, abs=1e-9)
    assert foot[12] == pytest.approx(JACKAL_HALF_WIDTH, abs=1e-9)
    assert foot[0] == pytest.approx(JACKAL_HALF_WIDTH * math.sqrt(2.0), abs=1e-9)
    jackal = ClearanceFeatures(spaces.Box(-3.0, 3.0, (79,), dtype=np.float32), num_rays=72, lidar_range=30.0,
                               fov=None, robot="jackal")  # fov None: the Jackal's 270 deg
    np.testing.assert_allclose(jackal.footprint.numpy(), footprint_distances(72, 270.0, robot="jackal"), rtol=1e-6)
    obs = np.ones((1, 79), dtype=np.float32)
    obs[0, :72] = jackal.footprint.numpy() / 30.0  # every ray touching the Jackal's outline
    np.testing.assert_allclose(jackal(torch.as_tensor(obs)).numpy()[0, 79:], 1.0, atol=1e-4)
    article = ClearanceFeatures(spaces.Box(-3.0, 3.0, (43,), dtype=np.float32))
    assert float(article.footprint[int(np.argmin(np.abs(ray_angles(36, 360.0))))]) == pytest.approx(0.15 - 0.10, abs=1e-7)
    with pytest.raises(ValueError, match="robot must be one of"):
        ClearanceFeatures(spaces.Box(-3.0, 3.0, (43,), dtype=np.float32), robot="husky")


def test_jackal_footprint_matches_its_collision_outline_in_pybullet():
    """As for the article robot: rays cast inward at wheel-centre height toward the Jackal's lidar
    first hit its collision outline where footprint_distances says, over its 72 rays and 270 deg."""
    from bulletnav.config import robot_preset

    scene = Scene(robot_preset(EnvConfig(), "jackal"))
    try:
        scene.use_layout(Layout((10.0, 10.0)))
        scene.place_robot((0.0, 0.0, 0.0), np.random.default_rng(0))
        cid, body, robot = scene.cid, scene.robot.body, scene.robot
        lidar_xy = p.getLinkState(body, robot.lidar_link, physicsClientId=cid)[4][:2]
        wheel_z = p.getLinkState(body, robot.left_joint, physicsClientId=cid)[4][2]
        angles = ray_angles(72, 270.0)
        starts = [[lidar_xy[0] + math.cos(a), lidar_xy[1] + math.sin(a), wheel_z] for a in angles]
        hits = p.rayTestBatch(starts, [[lidar_xy[0], lidar_xy[1], wheel_z]] * len(angles), physicsClientId=cid)
    finally:
        scene.close()
    assert all(h[0] == body for h in hits), "every inward ray must hit the robot"
    measured = np.array([1.0 - h[2] for h in hits])
    assert np.abs(measured - footprint_distances(72, 270.0, robot="jackal")).max() < 0.005
