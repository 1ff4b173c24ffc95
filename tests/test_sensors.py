"""Sensors against physics: known wall distances, noise statistics, odometry vs ground truth."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bulletnav.config import CameraConfig, ImuConfig, LidarConfig, OdometryConfig, SensorsConfig
from bulletnav.geometry import robot_geometry
from bulletnav.sensors import CameraImage
from bulletnav.sim.layout import Layout
from conftest import drive, place

LIDAR_X = 0.1  # lidar link ahead of the body centre (m), from the URDF


@pytest.fixture
def wall_room(write_layout):
    """A 12 x 6 m room with a wall-like box whose front face is at x = 2.0 m."""
    return write_layout({
        "name": "wall-test", "size": [12.0, 6.0],
        "obstacles": [{"type": "box", "center": [2.1, 0.0], "size": [0.2, 3.0, 1.5]}],
    })


def test_lidar_reads_a_wall_at_a_known_distance(make_scene, rng, wall_room, report):
    scene = make_scene()
    place(scene, wall_room, (0.0, 0.0, 0.0), rng)
    drive(scene, 0.0, 0.0, 0.5)
    ranges = scene.sensors.lidar.read()
    lidar = scene.sensors.lidar
    assert ranges.shape == (36,) and ranges.dtype == np.float32
    ahead = ranges[int(np.argmin(np.abs(lidar.angles)))]
    left = ranges[int(np.argmin(np.abs(lidar.angles - math.pi / 2)))]
    right = ranges[int(np.argmin(np.abs(lidar.angles + math.pi / 2)))]
    behind = ranges[int(np.argmin(np.abs(np.abs(lidar.angles) - math.pi)))]
    report("ray ahead vs wall at 1.9 m (m)", f"{ahead:.4f}")
    assert robot_geometry().lidar_offset == pytest.approx(LIDAR_X)  # the constant above is the URDF's
    assert ahead == pytest.approx(2.0 - LIDAR_X, abs=0.02)
    assert left == pytest.approx(3.0, abs=0.02) and right == pytest.approx(3.0, abs=0.02)  # side walls
    assert behind == pytest.approx(5.0)  # back wall at 6.1 m: beyond range reads max range
    # Rotated 30 deg: the ray at -30 deg still faces the wall square on; slant rays follow 1/cos.
    place(scene, wall_room, (0.0, 0.0, math.radians(30)), rng)
    ranges = scene.sensors.lidar.read()
    i = int(np.argmin(np.abs(lidar.angles + math.radians(30))))
    lx = LIDAR_X * math.cos(math.radians(30))
    assert ranges[i] == pytest.approx(2.0 - lx, abs=0.02)
    j = int(np.argmin(np.abs(lidar.angles)))  # the heading ray meets the wall at 30 deg incidence
    assert ranges[j] == pytest.approx((2.0 - lx) / math.cos(math.radians(30)), abs=0.02)


def test_lidar_never_sees_the_robot_and_reads_max_range_in_the_open(make_scene, rng):
    scene = make_scene(SensorsConfig(lidar=LidarConfig(num_rays=360)))
    place(scene, Layout((30.0, 30.0)), (0.0, 0.0, 1.0), rng)
    drive(scene, 0.3, 0.5, 1.0)  # moving, wheels turning
    assert np.all(scene.sensors.lidar.read() == pytest.approx(5.0))


def test_lidar_noise_has_the_configured_std(make_scene, rng, wall_room):
    scene = make_scene(SensorsConfig(lidar=LidarConfig(noise_std=0.05)))
    place(scene, wall_room, (0.0, 0.0, 0.0), rng)
    samples = []
    for _ in range(400):
        scene.step(0.0, 0.0)
        samples.append(scene.sensors.lidar.read()[0])
    assert np.std(samples) == pytest.approx(0.05, rel=0.15)
    assert np.mean(samples) == pytest.approx(1.9, abs=0.01)


def test_sensor_reads_are_idempotent_within_a_step(make_scene, rng, wall_room):
    scene = make_scene(SensorsConfig(lidar=LidarConfig(noise_std=0.05)))
    place(scene, wall_room, (0.0, 0.0, 0.0), rng)
    a = scene.sensors.lidar.read()
    b = scene.sensors.lidar.read()
    assert np.array_equal(a, b) and a is not b
    a[0] = -1.0  # callers get copies
    assert scene.sensors.lidar.read()[0] != -1.0
    # What was read is the room's geometry plus noise: the noise-free cast reads the wall
    # 2.0 - 0.1 m ahead and the side walls 3 m away, and each read ray lies within 5 sigma of it.
    lidar = scene.sensors.lidar
    exact = lidar.cast() * lidar.config.max_range
    for angle, distance in ((0.0, 2.0 - LIDAR_X), (math.pi / 2, 3.0), (-math.pi / 2, 3.0)):
        i = int(np.argmin(np.abs(lidar.angles - angle)))
        assert exact[i] == pytest.approx(distance, abs=0.02)
        assert abs(b[i] - distance) < 5 * 0.05


def test_every_sensor_reading_lies_in_its_space(make_scene, wall_room):
    """Each sensor's ``read()`` lies in its ``space()``, at the edges too: lidar noise large
    enough to clip at both range limits, odometry yaw wrapping through +-pi, and the camera's
    three images (a NamedTuple) against the entries of its Dict space."""
    scene = make_scene(SensorsConfig(lidar=LidarConfig(noise_std=0.5, min_range=0.1),
                                     odometry=OdometryConfig(encoder_noise_std=0.01)))
    present = scene.sensors.present()
    assert list(present) == ["lidar", "camera", "imu", "odometry"]
    rng = np.random.default_rng(3)
    ranges, yaws, reads = [], [], 0
    runs = [((1.5, 0.0, 0.0), (0.3, 0.0)),  # up to the wall: ranges near min_range
            ((-3.0, 1.0, math.pi - 0.05), (0.1, 1.5)),  # yaw crosses +pi
            ((0.0, -1.0, -math.pi + 0.05), (0.0, -1.5))]  # yaw crosses -pi
    for run, (start, (v, w)) in enumerate(runs):
        place(scene, wall_room, start, rng)
        for _ in range(30):
            if run == 0:  # heading square at the wall's face (x = 2 m): the noise-free ray ahead by hand
                x, _, yaw = scene.robot.pose()
                assert abs(yaw) < 0.01
                lidar = present["lidar"]
                assert lidar.cast()[0] * 5.0 == pytest.approx(2.0 - x - LIDAR_X, abs=0.01)
            for name, sensor in present.items():
                space, value = sensor.space(), sensor.read()
                if name == "camera":
                    assert isinstance(value, CameraImage)
                    assert set(space.keys()) == set(value._fields)
                    for field in value._fields:
                        assert space[field].contains(getattr(value, field)), field
                    assert space.contains(value._asdict())
                else:
                    assert space.contains(value), (name, value)
                reads += 1
            ranges.append(present["lidar"].read())
            yaws.append(float(present["odometry"].read()[2]))
            scene.step(v, w)
    assert reads == 3 * 30 * 4
    ranges = np.array(ranges)
    assert ranges.min() == np.float32(0.1) and ranges.max() == np.float32(5.0)  # both clip limits reached
    assert max(yaws) > 3.1 and min(yaws) < -3.1  # odometry wrapped at +-pi


@pytest.mark.parametrize("pitch, face_x", [(0.0, 3.0), (-10.0, 1.3)])
def test_depth_camera_centre_pixel_reads_the_wall_distance(make_scene, rng, write_layout, report, pitch, face_x):
    layout = write_layout({"size": [12.0, 8.0],
                           "obstacles": [{"type": "box", "center": [face_x + 0.1, 0.0], "size": [0.2, 6.0, 2.0]}]})
    scene = make_scene(SensorsConfig(camera=CameraConfig(pitch=pitch)))
    place(scene, layout, (0.0, 0.0, 0.0), rng)
    drive(scene, 0.0, 0.0, 0.25)
    image = scene.sensors.camera.read()
    assert image.rgb.shape == (240, 320, 3) and image.rgb.dtype == np.uint8
    assert image.depth.shape == (240, 320) and image.depth.dtype == np.float32
    _, eye, forward = scene.sensors.camera.view_matrix()
    expected = (face_x - eye[0]) / forward[0]  # along the optical axis to the wall plane
    centre = float(image.depth[119:121, 159:161].mean())
    report(f"centre depth at pitch {pitch} (m)", f"{centre:.4f} vs {expected:.4f}")
    assert centre == pytest.approx(expected, rel=0.02)
    wall_id = scene.sim.world.obstacle_ids[0]
    assert image.segmentation[120, 160] == wall_id
    assert (image.segmentation == scene.robot.body).any()  # the robot's own back is in view


def test_imu_noise_statistics_and_gravity_at_rest(make_scene, rng, report):
    cfg = ImuConfig(accel_noise_std=0.05, gyro_noise_std=0.01)
    scene = make_scene(SensorsConfig(imu=cfg))
    place(scene, Layout((10.0, 10.0)), (0.0, 0.0, 0.3), rng)
    drive(scene, 0.0, 0.0, 0.5)
    samples = []
    for _ in range(1000):
        scene.step(0.0, 0.0)
        samples.append(scene.sensors.imu.read())
    s = np.array(samples, dtype=np.float64)
    std = s.std(axis=0)
    report("IMU sample std (ax ay az gx gy gz)", np.array2string(std, precision=4))
    np.testing.assert_allclose(std[:3], 0.05, rtol=0.10)
    np.testing.assert_allclose(std[3:], 0.01, rtol=0.10)
    mean = s.mean(axis=0)
    assert np.all(np.abs(mean[3:]) < 0.002)  # gyro ~0 (3 sigma of the mean is 0.001)
    np.testing.assert_allclose(mean[:3], [0.0, 0.0, 9.81], atol=0.01)


def test_imu_bias_and_rotation_rate(make_scene, rng):
    cfg = ImuConfig(accel_noise_std=0.0, gyro_noise_std=0.0, gyro_bias=(0.0, 0.0, 0.02), accel_bias=(0.1, 0.0, 0.0))
    scene = make_scene(SensorsConfig(imu=cfg))
    place(scene, Layout((10.0, 10.0)), (0.0, 0.0, 0.0), rng)
    drive(scene, 0.0, 1.0, 1.0)
    reading = scene.sensors.imu.read()
    assert reading[5] == pytest.approx(1.02, abs=0.02)
    # Turning in place: centripetal acceleration is small; x carries the bias.
    assert reading[0] == pytest.approx(0.1, abs=0.05)
    # Speeding up shows as forward specific force.
    place(scene, Layout((10.0, 10.0)), (0.0, 0.0, 0.0), rng)
    scene.step(0.4, 0.0)
    assert scene.sensors.imu.read()[0] > 1.0


def test_odometry_tracks_ground_truth(make_scene, rng, report):
    scene = make_scene()
    place(scene, Layout((20.0, 20.0)), (-4.0, 1.0, 0.2), rng)
    drive(scene, 0.4, 0.0, 7.5)  # ~3 m straight
    truth = scene.robot.pose()
    odo = scene.sensors.odometry.read()
    travelled = math.hypot(truth[0] + 4.0, truth[1] - 1.0)
    pos_err = math.hypot(*(odo[:2] - truth[:2]))
    report("straight: distance (m)", f"{travelled:.3f}")
    report("straight: odometry position error (m)", f"{pos_err:.4f}")
    report("straight: odometry yaw error (rad)", f"{abs(odo[2] - truth[2]):.5f}")
    assert travelled > 2.9
    # Bound: measured 8.9 mm and 5.2 mrad over 3 m (small wheel slip while accelerating and
    # uneven contact loads). 3 cm (1 % of the distance, ~3x measured) and 0.02 rad leave room
    # for solver changes, while a 2 % wheel-radius error (6 cm) still fails.
    assert pos_err < 0.03
    assert abs(odo[2] - truth[2]) < 0.02
    assert odo[3] == pytest.approx(0.4, rel=0.02)

    place(scene, Layout((20.0, 20.0)), (0.0, 0.0, 0.0), rng)
    drive(scene, 0.0, 1.0, 2 * math.pi)  # one full turn in place
    truth = scene.robot.pose()
    odo = scene.sensors.odometry.read()
    yaw_err = abs(math.remainder(odo[2] - truth[2], 2 * math.pi))
    report("full turn: odometry yaw error (rad)", f"{yaw_err:.4f}")
    report("full turn: odometry position error (m)", f"{math.hypot(*(odo[:2] - truth[:2])):.4f}")
    # Bound: measured 0.004 rad per turn (the wheels barely slip turning in place); 0.02 rad
    # leaves 5x margin while a 2 % wheelbase error (0.13 rad per turn) fails.
    assert yaw_err < 0.02
    assert math.hypot(*(odo[:2] - truth[:2])) < 0.02
    assert odo[4] == pytest.approx(1.0, rel=0.03)
