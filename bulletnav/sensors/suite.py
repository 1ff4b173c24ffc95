"""The robot's sensors as one typed set, built from :class:`~bulletnav.config.SensorsConfig`."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from gymnasium import spaces

from bulletnav.config import SensorsConfig, ShiftConfig
from bulletnav.sensors.base import Sensor
from bulletnav.sensors.camera import Camera
from bulletnav.sensors.imu import Imu
from bulletnav.sensors.lidar import Lidar
from bulletnav.sensors.odometry import Odometry
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot

ORDER = ("lidar", "camera", "imu", "odometry")
"""Fixed order of the sensors: their noise seeds are handed out in it, present or not. A new
sensor goes at the end."""
_DRAWS = 4
"""Seeds drawn from the env's generator at every reset (the original four sensors')."""


@dataclass(frozen=True)
class SensorSuite:
    """The sensors on one robot, each a typed attribute (None when disabled in the config)."""

    lidar: Lidar | None
    camera: Camera | None
    imu: Imu | None
    odometry: Odometry | None

    @classmethod
    def build(cls, config: SensorsConfig, robot: Robot, clock: Clock, gravity: float = 9.81) -> SensorSuite:
        return cls(
            lidar=Lidar(robot, clock, config.lidar) if config.lidar.enabled else None,
            camera=Camera(robot, clock, config.camera) if config.camera.enabled else None,
            imu=Imu(robot, clock, config.imu, gravity=gravity) if config.imu.enabled else None,
            odometry=Odometry(robot, clock, config.odometry) if config.odometry.enabled else None,
        )

    def present(self) -> dict[str, Sensor]:
        """Name -> sensor for the sensors that exist, in :data:`ORDER`."""
        return {name: s for name in ORDER if (s := getattr(self, name)) is not None}

    def spaces(self) -> spaces.Dict:
        """The space of each present sensor's reading."""
        return spaces.Dict({name: s.space() for name, s in self.present().items()})

    def reset(self, rng: np.random.Generator) -> None:
        """Give each sensor its own generator drawn from ``rng``.

        Always exactly four draws from ``rng``, whatever sensors exist, so disabling a sensor
        or adding a new one never shifts another sensor's noise or the env's later draws
        (layouts, starts, goals). Sensors after the first four in :data:`ORDER` get
        generators seeded from the first draw and their position.
        """
        seeds = [int(s) for s in rng.integers(0, 2**63 - 1, size=_DRAWS)]
        for i, name in enumerate(ORDER):
            sensor = getattr(self, name)
            if sensor is not None:
                sensor.reset(np.random.default_rng(seeds[i] if i < _DRAWS else [seeds[0], i]))

    def apply_shift(self, shift: ShiftConfig) -> None:
        """Take the sensor part of ``shift`` (noise, dropout, biases, the odometry model) from the
        next :meth:`reset` on; the default :class:`ShiftConfig` restores the nominal sensors."""
        if self.lidar is not None:
            self.lidar.extra_noise_std, self.lidar.dropout = shift.lidar_noise_std, shift.lidar_dropout
        if self.imu is not None:
            self.imu.shift(shift.imu_noise_scale, shift.imu_accel_bias, shift.imu_gyro_bias)
        if self.odometry is not None:
            self.odometry.model_scale = (shift.odometry_wheel_radius_scale, shift.odometry_wheelbase_scale)
        if self.camera is not None:
            self.camera.depth_noise_std = shift.depth_noise_std

    def update(self) -> None:
        """Advance the stateful sensors after a control step."""
        if self.imu is not None:
            self.imu.update()
        if self.odometry is not None:
            self.odometry.update()

    def require(self, *names: str, by: str) -> None:
        """Raise a clear error when a sensor that ``by`` needs is disabled.

        Raises:
            ValueError: one of ``names`` is disabled.
        """
        missing = [n for n in names if getattr(self, n) is None]
        if missing:
            raise ValueError(f"{by} needs the {', '.join(missing)} sensor(s); enable them in SensorsConfig "
                             f"(sensors.{missing[0]}.enabled=True)")
