"""The robot drives like a differential-drive robot: distances, drift and yaw rates against physics."""

from __future__ import annotations

import math

import numpy as np
import pybullet as p
import pytest

from bulletnav.config import RobotConfig
from bulletnav.geometry import robot_geometry
from bulletnav.sim.layout import Layout
from conftest import drive

FLAT = Layout((30.0, 30.0))


def test_geometry_is_read_from_the_urdf(make_sim):
    sim = make_sim()
    sim.reset(FLAT, (0.0, 0.0, 0.0))
    assert sim.robot.wheel_radius == pytest.approx(0.05)
    assert sim.robot.wheelbase == pytest.approx(0.22)
    # PyBullet's loaded model and the URDF parse that every other consumer uses agree.
    geometry = robot_geometry()
    assert geometry.wheel_radius == pytest.approx(sim.robot.wheel_radius, abs=1e-9)
    assert geometry.wheelbase == pytest.approx(sim.robot.wheelbase, abs=1e-9)
    # Resting on wheels and caster, level, body origin 7 cm up.
    drive(sim, 0.0, 0.0, 1.0)
    # the base link frame's origin from PyBullet: its centre of mass less the inertial offset, turned
    robot = sim.robot
    com, orn = p.getBasePositionAndOrientation(robot.body, physicsClientId=robot.cid)
    inertial = p.getDynamicsInfo(robot.body, -1, physicsClientId=robot.cid)[3]
    pos = np.array(com) - np.array(p.getMatrixFromQuaternion(orn)).reshape(3, 3) @ np.array(inertial)
    assert pos[2] == pytest.approx(0.07, abs=2e-3)
    assert np.allclose(sim.robot.pose(), [0.0, 0.0, 0.0], atol=2e-3)


@pytest.mark.parametrize("yaw", [0.0, 2.0])
def test_straight_line_covers_the_commanded_distance_without_drift(make_sim, report, yaw):
    sim = make_sim()
    sim.reset(FLAT, (1.0, -2.0, yaw))
    drive(sim, 0.4, 0.0, 3.0)
    x, y, _ = sim.robot.pose()
    dx, dy = x - 1.0, y + 2.0
    along = dx * math.cos(yaw) + dy * math.sin(yaw)
    sideways = -dx * math.sin(yaw) + dy * math.cos(yaw)
    report("distance in 3 s at 0.4 m/s (m)", f"{along:.4f}")
    report("sideways drift (m)", f"{sideways:.4f}")
    assert along == pytest.approx(1.2, rel=0.05)
    assert abs(sideways) < 0.02


@pytest.mark.parametrize("w", [1.0, -1.0, 0.5])
def test_turn_in_place_reaches_the_commanded_yaw_rate(make_sim, report, w):
    sim = make_sim()
    sim.reset(FLAT, (0.0, 0.0, 0.0))
    drive(sim, 0.0, w, 0.5)  # settle
    yaws = []
    for _ in range(48):  # 2 s
        sim.step(0.0, w)
        yaws.append(sim.robot.pose()[2])
    rate = (np.unwrap(yaws)[-1] - yaws[0]) / (47 / 24)
    report(f"yaw rate at w={w} (rad/s)", f"{rate:.4f}")
    assert rate == pytest.approx(w, rel=0.05)
    assert np.hypot(*sim.robot.pose()[:2]) < 0.03  # turned in place


def test_arc_matches_kinematics(make_sim):
    sim = make_sim()
    sim.reset(FLAT, (0.0, 0.0, 0.0))
    drive(sim, 0.3, 0.6, 1.0)
    v, w = sim.robot.velocity()
    assert v == pytest.approx(0.3, rel=0.05)
    assert w == pytest.approx(0.6, rel=0.05)


def test_non_finite_command_is_refused(make_sim):
    sim = make_sim()
    sim.reset(FLAT, (0.0, 0.0, 0.0))
    with pytest.raises(ValueError, match="finite"):
        sim.robot.set_velocity(float("nan"), 0.0)
    with pytest.raises(ValueError) as err:
        sim.robot.set_velocity(0.3, float("inf"))
    assert str(err.value) == "set_velocity needs finite values, got v=0.3, w=inf"
    # The refused commands left nothing behind: stepped with no command, the robot stands where
    # it was placed, at rest.
    for _ in range(24):
        sim.step(0.0, 0.0)
    np.testing.assert_allclose(sim.robot.pose(), (0.0, 0.0, 0.0), atol=1e-3)


@pytest.mark.parametrize("face_y, touching", [(-0.14, False), (-0.125, False), (-0.115, True), (-0.095, True)])
def test_obstacles_meet_the_wheels_true_width(make_sim, face_y, touching):
    """A wall beside the right wheel counts as contact only once it reaches the wheel's
    0.02 m-wide footprint (outer face at y = -0.12), not the 0.05 m rolling sphere's
    (y = -0.16), and it does touch the body side (y = -0.10)."""
    import pybullet as p

    from bulletnav.sim.layout import Obstacle

    wall = Obstacle("box", (0.0, face_y - 0.05), (0.04, 0.1, 0.5))
    sim = make_sim()
    sim.reset(Layout((10.0, 10.0), obstacles=(wall,)), (0.0, 0.0, 0.0))
    p.performCollisionDetection(physicsClientId=sim.cid)
    assert sim.in_collision() is touching
    # The outline every planner and sampler uses (parsed from the URDF) puts the edge at the same place.
    edge = max(half_y for _, half_y in robot_geometry().centred_rectangles)
    assert edge == pytest.approx(0.12)
    assert (face_y > -edge) is touching


def _spin_then_stand(sim, steps: int) -> list[tuple[float, float, float]]:
    """Drive a tight arc and a turn in place, then command (0, 0) for ``steps`` control
    steps; the poses at every step of the standing."""
    for _ in range(12):
        sim.step(0.5, -1.5)
    for _ in range(6):
        sim.step(0.0, 1.5)
    poses = []
    for _ in range(steps):
        sim.step(0.0, 0.0)
        poses.append(sim.robot.planar_pose())
    return poses


def _moved(a, b) -> tuple[float, float]:
    return math.hypot(b[0] - a[0], b[1] - a[1]), abs(b[2] - a[2])


def test_a_stopped_robot_stands_still_with_the_park_brake(make_sim, report):
    # Without the brake PyBullet's velocity motors let a robot told to stand creep for as long
    # as it stands; with it the robot settles and then does not move at all.
    free = make_sim(robot=RobotConfig(park_brake_rate=0.0))
    free.reset(FLAT, (0.0, 0.0, 0.0))
    poses = _spin_then_stand(free, 960)
    creep, _ = _moved(poses[240], poses[-1])  # the 30 s after the first 10 s of standing
    assert not free.robot.braked
    braked = make_sim()
    braked.reset(FLAT, (0.0, 0.0, 0.0))
    poses = _spin_then_stand(braked, 960)
    assert braked.robot.braked
    held, turned = _moved(poses[240], poses[-1])
    report("creep in 30 s standing, brake off / on (mm)", f"{creep * 1e3:.2f} / {held * 1e3:.3f}")
    assert creep > 3e-3
    assert held < 1e-4 and turned < 1e-4


def test_the_park_brake_waits_for_the_wheels_to_slow_and_lets_go_on_the_next_command(make_sim):
    sim = make_sim()
    sim.reset(FLAT, (0.0, 0.0, 0.0))
    drive(sim, 0.5, 0.0, 1.0)
    sim.step(0.0, 0.0)  # wheels at 10 rad/s: the motors brake, the brake does not grab
    assert not sim.robot.braked
    reference = make_sim(robot=RobotConfig(park_brake_rate=0.0))
    reference.reset(FLAT, (0.0, 0.0, 0.0))
    drive(reference, 0.5, 0.0, 1.0)
    reference.step(0.0, 0.0)
    for _ in range(47):  # the stopping distance is the velocity motors', brake or no brake
        sim.step(0.0, 0.0)
        reference.step(0.0, 0.0)
    assert sim.robot.braked
    assert sim.robot.pose()[0] == pytest.approx(reference.robot.pose()[0], abs=2e-3)
    x0 = sim.robot.pose()[0]
    drive(sim, 0.3, 0.0, 1.0)  # released: drives on as commanded
    assert not sim.robot.braked
    assert sim.robot.pose()[0] - x0 == pytest.approx(0.3, rel=0.1)


def test_park_brake_rate_must_not_be_negative():
    with pytest.raises(ValueError, match="park_brake_rate"):
        RobotConfig(park_brake_rate=-1.0)
    # The boundary by hand: 0 rad/s is allowed, anything below it refused, NaN too, with the exact line.
    assert RobotConfig(park_brake_rate=0.0).park_brake_rate == 0.0
    for bad in (-1e-9, float("nan")):
        with pytest.raises(ValueError) as err:
            RobotConfig(park_brake_rate=bad)
        assert str(err.value) == f"RobotConfig.park_brake_rate must be >= 0 rad/s, got {bad}"
