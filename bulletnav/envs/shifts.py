"""Named evaluation shifts: the same episodes on a robot, floor or sensors that differ from
the ones a policy was trained on (``evaluate --perturb NAME``, ``navigate --perturb NAME``, or
the env kwarg ``perturb``).

Each is a fixed :class:`~bulletnav.config.ShiftConfig`; it changes no draw of the episode
(layout, start, goals, movers), so a shifted run and a nominal one score the same episodes.

| name | what changes |
|---|---|
| ``slippery`` | floor friction 1.0 -> 0.15 (wheel-floor 0.15: PyBullet multiplies the two); braking from 0.5 m/s takes 2x as far |
| ``heavy`` | body mass and inertia x 1.5, wheel torque limit x 0.6 |
| ``noisy`` | lidar range noise 0.05 m and 5 % of rays dropped per scan, IMU noise x 3 |
| ``miscalibrated`` | the odometry model's wheel radius x 1.05 and wheelbase x 0.95 |
| ``laggy`` | actions reach the motors 2 control steps (83 ms) late |
"""

from __future__ import annotations

from bulletnav.config import ShiftConfig

PERTURBATIONS: dict[str, ShiftConfig] = {
    "slippery": ShiftConfig(floor_friction=0.15),
    "heavy": ShiftConfig(mass_scale=1.5, motor_force_scale=0.6),
    "noisy": ShiftConfig(lidar_noise_std=0.05, lidar_dropout=0.05, imu_noise_scale=3.0),
    "miscalibrated": ShiftConfig(odometry_wheel_radius_scale=1.05, odometry_wheelbase_scale=0.95),
    "laggy": ShiftConfig(action_latency=2),
}
"""The named shifts (see the module docstring)."""


def perturbation(name: str) -> ShiftConfig:
    """The shift called ``name``.

    Raises:
        ValueError: an unknown name (the message lists the valid ones).
    """
    try:
        return PERTURBATIONS[name]
    except KeyError:
        raise ValueError(f"unknown perturbation {name!r}; choose one of {', '.join(PERTURBATIONS)}") from None


def describe(shift: ShiftConfig) -> dict[str, object]:
    """The fields of ``shift`` that differ from the nominal robot, floor and sensors."""
    nominal = ShiftConfig()
    return {k: v for k, v in vars(shift).items() if v != getattr(nominal, k)}

