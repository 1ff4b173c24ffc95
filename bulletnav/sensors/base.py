"""The sensor interface shared by lidar, camera, IMU and odometry."""

from __future__ import annotations

from abc import ABC, abstractmethod
from array import array
from typing import Any

import numpy as np
from gymnasium import spaces

from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot


class Sensor(ABC):
    """A sensor mounted on a robot in one physics client.

    Life cycle, driven by the scene: :meth:`reset` at every episode start with the sensor's
    own ``numpy.random.Generator`` (so reading one sensor never shifts another's noise),
    :meth:`update` once after every control step, and :meth:`read` whenever a measurement
    is wanted. ``read`` is idempotent within a sensor period: it returns a fresh copy of the
    same measurement, so extra reads change neither results nor random streams.

    Args:
        robot: the robot the sensor is mounted on (its physics client is the sensor's).
        clock: the scene's simulated time.
        rate_hz: new measurements per simulated second; None = one per control step.
    """

    name: str = "sensor"

    def __init__(self, robot: Robot, clock: Clock, rate_hz: float | None = None) -> None:
        self.robot = robot
        self.clock = clock
        self.rng = np.random.default_rng(0)
        if rate_hz is None:
            self.period = clock.control_ticks
        else:
            physics_hz = 1.0 / clock.physics_dt
            if rate_hz > physics_hz:
                raise ValueError(f"{self.name} rate_hz={rate_hz} exceeds the physics rate {physics_hz:g} Hz")
            self.period = max(1, round(physics_hz / rate_hz))
        """Physics steps between new measurements."""
        self._stamp = (-1, -1)  # (episode, period index) of the cached measurement
        self._value: Any = None

    def reset(self, rng: np.random.Generator) -> None:
        """Start a new episode with noise drawn from ``rng``."""
        self.rng = rng
        self._stamp = (-1, -1)

    def update(self) -> None:  # noqa: B027 (an optional hook: stateless sensors keep the default)
        """Advance internal state after a control step (stateless sensors do nothing)."""

    def read(self) -> Any:
        """The current measurement as fresh NumPy array(s)."""
        value = self.current()
        return value.copy() if type(value) is np.ndarray else _copy(value)

    def current(self) -> Any:
        """The current measurement itself, not a copy (for the env's per-step code, which
        only reads it; callers must not modify it). Measures when a new period has begun."""
        stamp = self.period_stamp()
        if stamp != self._stamp:
            self._value = self.measure()
            self._stamp = stamp
        return self._value

    def period_stamp(self) -> tuple[int, int]:
        """(episode, index of the sensor period) now: a measurement is new when this changes."""
        clock = self.clock
        return clock.episode, clock.tick // self.period

    @abstractmethod
    def measure(self) -> Any:
        """Take a new measurement (called at most once per sensor period by :meth:`read`)."""

    @abstractmethod
    def space(self) -> spaces.Space:
        """The Gymnasium space that every :meth:`read` lies in."""


class VectorSensor(Sensor):
    """A sensor whose reading is a flat float32 vector (lidar, IMU, odometry).

    It measures into Python floats rounded to float32 (:meth:`measure_floats`), once per
    period: :meth:`floats` hands that list to per-step code without touching NumPy (each
    small NumPy call costs microseconds on a path that runs thousands of times a second),
    and :meth:`read` / :meth:`current` give the same values as a float32 array.
    """

    def __init__(self, robot: Robot, clock: Clock, rate_hz: float | None = None) -> None:
        super().__init__(robot, clock, rate_hz)
        self._floats: list[float] = []
        self._float_stamp = (-1, -1)

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self._float_stamp = (-1, -1)

    def floats(self) -> list[float]:
        """The current reading as a list of Python floats (float32 values, exactly); the
        caller must not modify it. Measures when a new period has begun."""
        stamp = self.period_stamp()
        if stamp != self._float_stamp:
            self._floats = self.measure_floats()
            self._float_stamp = stamp
        return self._floats

    def measure(self) -> np.ndarray:
        return np.array(self.floats(), dtype=np.float32)

    @abstractmethod
    def measure_floats(self) -> list[float]:
        """Take a new measurement as float32-rounded Python floats (see :func:`float32_list`)."""


def float32_list(values: Any) -> list[float]:
    """``values`` rounded to float32 (as NumPy's cast rounds) and returned as Python floats."""
    return array("f", values).tolist()


def _copy(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple) and hasattr(value, "_fields"):
        return type(value)(*(_copy(v) for v in value))
    return value
