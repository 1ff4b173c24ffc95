"""The differential-drive robot: loading, (v, w) commands and ground-truth state."""

from __future__ import annotations

import math
from collections.abc import Collection
from typing import NamedTuple

import numpy as np
import pybullet as p

from bulletnav.config import RobotConfig
from bulletnav.sim.world import FLOOR_GROUP, ROBOT_GROUP, WHEEL_GROUP

_motors = p.setJointMotorControlArray
_base_pose = p.getBasePositionAndOrientation
_base_velocity = p.getBaseVelocity
_joint_states = p.getJointStates
_matrix = p.getMatrixFromQuaternion

_BRAKE_GAIN = 0.5
"""Position gain of the parking brake's wheel motors (PyBullet ``positionGains``)."""

REST_HEIGHT = 0.07
"""Height of the base origin above the floor when the robot rests on its wheels (m)."""


class RobotState(NamedTuple):
    """Ground truth of the robot at one instant, as :meth:`Robot.sample` reads it."""

    x: float
    """Body-centre x, world frame (m)."""
    y: float
    """Body-centre y, world frame (m)."""
    yaw: float
    """Heading, counter-clockwise from +x (rad)."""
    linear_velocity: tuple[float, float, float]
    """Body-centre velocity, world frame (m/s)."""
    angular_velocity: tuple[float, float, float]
    """Angular velocity, world frame (rad/s)."""
    rotation: tuple[float, ...]
    """Row-major body-to-world rotation matrix."""
    wheel_angles: tuple[float, float]
    """Wheel joint angles (left, right) (rad)."""
    wheel_rates: tuple[float, float]
    """Wheel joint rates (left, right) (rad/s)."""


class Robot:
    """A differential-drive robot in physics client ``cid``.

    Wheel radius and wheelbase are read from the loaded URDF, so the kinematics always
    match the model. Call :meth:`load` after every :meth:`World.build`.
    """

    def __init__(self, cid: int, config: RobotConfig = RobotConfig()) -> None:
        self.cid = cid
        self.config = config
        self.body = -1
        self.left_joint = self.right_joint = -1
        self._wheels: list[int] = []
        self._torques = [config.max_wheel_torque] * 2
        self.lidar_link = self.camera_link = self.caster_link = -1
        self.wheel_radius = 0.0
        """Wheel radius read from the URDF collision shape (m)."""
        self.wheelbase = 0.0
        """Distance between the wheel contact points, read from the URDF joints (m)."""
        self._com_offset: tuple[float, float, float] = (0.0, 0.0, 0.0)
        self._rest_height = REST_HEIGHT
        self._nominal_mass: tuple[float, tuple[float, ...]] = (0.0, (0.0, 0.0, 0.0))
        self._held: tuple[float, float] | None = None  # wheel angles the parking brake holds (rad)
        self._urdf: str | None = None
        self.state: RobotState | None = None
        """The snapshot taken by the last :meth:`sample`: after every control step and every
        :meth:`reset_pose` (the per-step code of sensors and task reads this one)."""

    # ------------------------------------------------------------------ set-up
    def load(self, pose: tuple[float, float, float]) -> None:
        """Load the URDF at ``pose`` = (x, y, yaw) and configure motors and contacts."""
        cid = self.cid
        x, y, yaw = pose
        if self._urdf is None:  # resolved once: importlib.resources costs ~0.2 ms a reset
            self._urdf = str(self.config.urdf_path())
        self.body = p.loadURDF(
            self._urdf, [0, 0, 0], flags=p.URDF_USE_INERTIA_FROM_FILE | p.URDF_USE_IMPLICIT_CYLINDER,
            physicsClientId=cid,
        )
        # PyBullet places and reports the base by its centre of mass; keep the offset to the
        # URDF link frame so that poses refer to the body centre.
        self._com_offset = tuple(p.getDynamicsInfo(self.body, -1, physicsClientId=cid)[3])
        links = {}
        joints = {}
        for j in range(p.getNumJoints(self.body, physicsClientId=cid)):
            info = p.getJointInfo(self.body, j, physicsClientId=cid)
            joints[info[1].decode()] = j
            links[info[12].decode()] = j
        try:
            self.left_joint = joints["left_wheel_joint"]
            self.right_joint = joints["right_wheel_joint"]
            self.lidar_link = links["lidar_link"]
            self.camera_link = links["camera_link"]
            self.caster_link = links["caster_wheel"]
        except KeyError as exc:
            raise ValueError(f"{self.config.urdf_path()}: robot URDF lacks joint/link {exc}") from exc
        self._wheels = [self.left_joint, self.right_joint]
        left = p.getJointInfo(self.body, self.left_joint, physicsClientId=cid)[14]
        right = p.getJointInfo(self.body, self.right_joint, physicsClientId=cid)[14]
        self.wheelbase = abs(left[1] - right[1])
        shape = p.getCollisionShapeData(self.body, self.left_joint, physicsClientId=cid)[0]
        # an implicit cylinder's dimensions are (length, radius, 0); a sphere's (radius, ...)
        self.wheel_radius = float(shape[3][1] if shape[2] == p.GEOM_CYLINDER else shape[3][0])
        # the URDF origin's height at rest: wheel radius above the axle's height in the URDF frame
        # (the joint's parent frame is given from the base's centre of mass); the shipped robot's
        # is REST_HEIGHT exactly, as always
        rest = self.wheel_radius - (left[2] + self._com_offset[2])
        self._rest_height = REST_HEIGHT if math.isclose(rest, REST_HEIGHT, abs_tol=1e-9) else rest
        for link in (-1, *range(p.getNumJoints(self.body, physicsClientId=cid))):
            p.setCollisionFilterGroupMask(self.body, link, ROBOT_GROUP, 0xFFFF, physicsClientId=cid)
        # The wheel spheres are for rolling only; obstacles meet the base's wheel guard boxes,
        # which have the wheels' true 0.1 x 0.02 m footprint (see the URDF).
        for wheel in (self.left_joint, self.right_joint):
            p.setCollisionFilterGroupMask(self.body, wheel, WHEEL_GROUP, FLOOR_GROUP, physicsClientId=cid)
        for wheel in (self.left_joint, self.right_joint):
            p.changeDynamics(self.body, wheel, lateralFriction=self.config.wheel_friction,
                             rollingFriction=0.0, spinningFriction=0.0, physicsClientId=cid)
        p.changeDynamics(self.body, self.caster_link, lateralFriction=self.config.caster_friction,
                         rollingFriction=0.0, spinningFriction=0.0, physicsClientId=cid)
        info = p.getDynamicsInfo(self.body, -1, physicsClientId=cid)
        self._nominal_mass = (float(info[0]), tuple(float(v) for v in info[2]))
        self._torques = [self.config.max_wheel_torque] * 2
        self._held = None  # a new body: no brake, no friction anchors
        self.reset_pose(pose)

    def apply_shift(self, mass_scale: float = 1.0, wheel_friction_scale: float = 1.0,
                    motor_force_scale: float = 1.0) -> None:
        """Scale the body's mass and inertia, the wheels' friction and the motors' torque limit
        from their nominal (URDF and :class:`RobotConfig`) values; 1.0 restores each."""
        cid = self.cid
        mass, inertia = self._nominal_mass
        p.changeDynamics(self.body, -1, mass=mass * mass_scale,
                         localInertiaDiagonal=[v * mass_scale for v in inertia], physicsClientId=cid)
        for wheel in (self.left_joint, self.right_joint):
            p.changeDynamics(self.body, wheel, lateralFriction=self.config.wheel_friction * wheel_friction_scale,
                             physicsClientId=cid)
        self._torques = [self.config.max_wheel_torque * motor_force_scale] * 2

    def reset_pose(self, pose: tuple[float, float, float]) -> None:
        """Teleport to ``pose`` at rest, wheels zeroed, motors stopped (no reload)."""
        cid = self.cid
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        ox, oy, oz = self._com_offset
        com = [x + c * ox - s * oy, y + s * ox + c * oy, self._rest_height + oz]
        p.resetBasePositionAndOrientation(self.body, com, p.getQuaternionFromEuler([0, 0, yaw]), physicsClientId=cid)
        p.resetBaseVelocity(self.body, [0, 0, 0], [0, 0, 0], physicsClientId=cid)
        for j in (self.left_joint, self.right_joint):
            p.resetJointState(self.body, j, 0.0, 0.0, physicsClientId=cid)
        self._release_brake()
        self._drive(0.0, 0.0)  # motors stopped; the brake engages on a later zero command
        self.sample()

    # ------------------------------------------------------------------ commands
    def set_velocity(self, v: float, w: float) -> None:
        """Command forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s) through the wheel motors."""
        if not (math.isfinite(v) and math.isfinite(w)):
            raise ValueError(f"set_velocity needs finite values, got v={v}, w={w}")
        if v == 0.0 and w == 0.0 and self.config.park_brake_rate > 0.0:
            if self._held is None:
                state = self.state
                rate = self.config.park_brake_rate
                if state is not None and abs(state.wheel_rates[0]) < rate and abs(state.wheel_rates[1]) < rate:
                    self._engage_brake(state.wheel_angles)
            if self._held is not None:
                return
        elif self._held is not None:
            self._release_brake()
        self._drive(v, w)

    @property
    def braked(self) -> bool:
        """Whether the parking brake holds the wheels (see ``RobotConfig.park_brake_rate``)."""
        return self._held is not None

    def _drive(self, v: float, w: float) -> None:
        """The wheel velocity motors for (v, w)."""
        # inverse kinematics: wheel rates (left, right) = (v -+ w L / 2) / r
        half, r = self.wheelbase / 2, self.wheel_radius
        _motors(self.body, self._wheels, p.VELOCITY_CONTROL, targetVelocities=[(v - w * half) / r, (v + w * half) / r],
                forces=self._torques, physicsClientId=self.cid)

    def stop(self) -> None:
        self.set_velocity(0.0, 0.0)

    def _engage_brake(self, angles: tuple[float, float]) -> None:
        """Hold the wheels at ``angles`` with position motors at the torque limit, and anchor
        the wheels' floor contacts (PyBullet's friction anchors stop the contacts' slow slide)."""
        cid = self.cid
        self._held = (float(angles[0]), float(angles[1]))
        _motors(self.body, self._wheels, p.POSITION_CONTROL, targetPositions=list(self._held),
                targetVelocities=[0.0, 0.0], forces=self._torques, positionGains=[_BRAKE_GAIN] * 2,
                velocityGains=[1.0, 1.0], physicsClientId=cid)
        for wheel in self._wheels:
            p.changeDynamics(self.body, wheel, frictionAnchor=1, physicsClientId=cid)

    def _release_brake(self) -> None:
        if self._held is None:
            return
        self._held = None
        for wheel in self._wheels:
            p.changeDynamics(self.body, wheel, frictionAnchor=0, physicsClientId=self.cid)

    # ------------------------------------------------------------------ state
    # Plain floats and tuples below: these run every control step, and NumPy's per-call
    # overhead on 3-vectors (np.cross ~100 us) would dominate the step time.
    def _frame(self) -> tuple[tuple[float, float, float], tuple[float, ...], tuple[float, ...]]:
        """Body-centre position, orientation quaternion and row-major rotation matrix."""
        com, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        m = p.getMatrixFromQuaternion(orn)
        ox, oy, oz = self._com_offset
        pos = (com[0] - (m[0] * ox + m[1] * oy + m[2] * oz),
               com[1] - (m[3] * ox + m[4] * oy + m[5] * oz),
               com[2] - (m[6] * ox + m[7] * oy + m[8] * oz))
        return pos, orn, m

    def pose(self) -> np.ndarray:
        """Ground-truth planar pose ``[x, y, yaw]`` of the body centre (m, m, rad)."""
        return np.array(self.planar_pose())

    def planar_pose(self) -> tuple[float, float, float]:
        """:meth:`pose` as a tuple of floats (cheaper in per-step code)."""
        pos, orn, _ = self._frame()
        return pos[0], pos[1], _yaw(orn)

    def kinematics(self) -> tuple[tuple[float, ...], tuple[float, ...], tuple[float, ...]]:
        """Body-centre linear velocity (m/s) and angular velocity (rad/s), world frame, and the
        row-major body-to-world rotation matrix."""
        lin, ang = p.getBaseVelocity(self.body, physicsClientId=self.cid)
        _, orn = p.getBasePositionAndOrientation(self.body, physicsClientId=self.cid)
        m = p.getMatrixFromQuaternion(orn)
        return self._centre_velocity(lin, ang, m), ang, m

    def _centre_velocity(self, lin: tuple[float, ...], ang: tuple[float, ...], m: tuple[float, ...]) -> tuple[float, float, float]:
        """Body-centre velocity from PyBullet's centre-of-mass velocity."""
        ox, oy, oz = self._com_offset
        rx, ry, rz = m[0] * ox + m[1] * oy + m[2] * oz, m[3] * ox + m[4] * oy + m[5] * oz, m[6] * ox + m[7] * oy + m[8] * oz
        # v_centre = v_com + w x (p_centre - p_com) = v_com - w x (R @ offset)
        wx, wy, wz = ang
        return (lin[0] - (wy * rz - wz * ry), lin[1] - (wz * rx - wx * rz), lin[2] - (wx * ry - wy * rx))

    def sample(self) -> RobotState:
        """Read the ground truth once and keep it as :attr:`state`.

        Three PyBullet queries (base pose, base velocity, wheel joints). Each state query of
        PyBullet's DIRECT client copies a large fixed-size buffer (~30k instructions, several
        times what the answer costs to build), so the per-step code shares this snapshot
        instead of asking again; :class:`~bulletnav.sim.simulation.Simulation` takes it after
        every control step. The arithmetic is :meth:`_frame`'s and :meth:`_centre_velocity`'s,
        written out once (this runs every control step).
        """
        body, cid = self.body, self.cid
        com, orn = _base_pose(body, physicsClientId=cid)
        lin, ang = _base_velocity(body, physicsClientId=cid)
        left, right = _joint_states(body, self._wheels, physicsClientId=cid)
        m = _matrix(orn)
        ox, oy, oz = self._com_offset
        rx, ry, rz = m[0] * ox + m[1] * oy + m[2] * oz, m[3] * ox + m[4] * oy + m[5] * oz, m[6] * ox + m[7] * oy + m[8] * oz
        qx, qy, qz, qw = orn
        wx, wy, wz = ang
        self.state = RobotState(
            com[0] - rx, com[1] - ry, math.atan2(2.0 * (qw * qz + qx * qy), 1.0 - 2.0 * (qy * qy + qz * qz)),
            (lin[0] - (wy * rz - wz * ry), lin[1] - (wz * rx - wx * rz), lin[2] - (wx * ry - wy * rx)), ang, m,
            (left[0], right[0]), (left[1], right[1]),
        )
        return self.state

    def velocity(self) -> np.ndarray:
        """Ground-truth ``[v, w]``: forward speed along the heading (m/s) and yaw rate (rad/s)."""
        lin, ang, m = self.kinematics()
        # heading = body x axis = first column of R
        return np.array([lin[0] * m[0] + lin[1] * m[3] + lin[2] * m[6], ang[2]])

    def touching(self, bodies: Collection[int]) -> bool:
        """True when any robot link is in contact with one of ``bodies`` (pass a set: this
        runs every step)."""
        # One query for all links: each query costs a fixed ~30k-instruction buffer copy in
        # PyBullet's client, far more than the few floor contacts of the wheels it returns.
        for c in p.getContactPoints(bodyA=self.body, physicsClientId=self.cid):
            if c[2] in bodies:
                return True
        return False

    def contact_kind(self, static: Collection[int], moving: Collection[int]) -> str | None:
        """``"dynamic"`` when the robot touches one of ``moving``, else ``"static"`` when it
        touches one of ``static``, else None."""
        kind = None
        for c in p.getContactPoints(bodyA=self.body, physicsClientId=self.cid):
            if c[2] in moving:
                return "dynamic"
            if c[2] in static:
                kind = "static"
        return kind


def _yaw(orn: tuple[float, ...]) -> float:
    """Heading (rad) of an orientation quaternion (x, y, z, w)."""
    x, y, z, w = orn
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))
