"""Policy-side lidar features: how close each ray's obstacle is to the robot's own outline.

The env's observation scales lidar ranges by the 5 m maximum, so touching an obstacle
(0.05-0.16 m from the lidar, depending on the ray) and being safely clear of it (0.3 m)
differ by a few hundredths of an input unit, and where contact happens differs by ray: the
lidar sits 5 cm behind the front face, 25 cm ahead of the rear and 16 cm inside the wheel
spheres' outer edge. :class:`ClearanceFeatures` appends, for every ray, the closeness
``exp(-clearance / scale)``. Two clearances are offered (``metric``):

- ``"ray"``: the range minus the distance from the lidar to the edge of the robot's collision
  outline along that ray (:func:`footprint_distances`). Blind between rays: an obstacle edge
  10 cm off the body side, just ahead of a wheel, reads as 5 cm clear on the nearest ray
  while it touches the wheel.
- ``"point"``: the distance from the point the ray hit to the nearest part of the outline
  (:func:`outline_clearance`), whatever direction that is in.

It is part of the policy (saved in the model, applied in ``predict``), so the env and its
observation stay as specified.
"""

from __future__ import annotations

import math

import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from bulletnav.sensors.lidar import ray_angles

# Collision outline of bulletnav/assets/diff_drive.urdf in the body frame (m): the 0.3 x 0.2 m
# body box and the two wheel spheres (r 0.05 m, centres 0.11 m left and right), seen from above.
BODY_HALF_LENGTH = 0.15
BODY_HALF_WIDTH = 0.10
WHEEL_Y = 0.11
WHEEL_RADIUS = 0.05
LIDAR_X = 0.10


def footprint_distances(num_rays: int, fov_deg: float = 360.0, lidar_x: float = LIDAR_X) -> np.ndarray:
    """Distance (m) from the lidar to the edge of the robot's outline along each ray.

    Rays are spread as the :class:`~bulletnav.sensors.lidar.Lidar` spreads them
    (:func:`~bulletnav.sensors.lidar.ray_angles`).
    """
    angles = ray_angles(num_rays, fov_deg)
    out = np.empty(num_rays)
    for i, a in enumerate(angles):
        c, s = math.cos(a), math.sin(a)
        # leave the body rectangle (the lidar is inside it)
        tx = (math.copysign(BODY_HALF_LENGTH, c) - lidar_x) / c if abs(c) > 1e-12 else math.inf
        ty = BODY_HALF_WIDTH / abs(s) if abs(s) > 1e-12 else math.inf
        t = min(tx, ty)
        # a wheel disc the ray crosses extends the outline to the disc's far side
        for wy in (WHEEL_Y, -WHEEL_Y):
            # |(lidar_x + t c, t s) - (0, wy)| = r  ->  t^2 + 2 t (lidar_x c - wy s) + lidar_x^2 + wy^2 - r^2 = 0
            b = lidar_x * c - wy * s
            disc = b * b - (lidar_x**2 + wy**2 - WHEEL_RADIUS**2)
            if disc >= 0.0:
                far = -b + math.sqrt(disc)
                near = -b - math.sqrt(disc)
                if far > 0.0 and near <= t + 1e-9:  # the disc continues the outline along the ray
                    t = max(t, far)
        out[i] = t
    return out


def outline_clearance(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Distance (m) from body-frame points ``(x, y)`` to the robot's collision outline seen
    from above (0 inside it): the body rectangle and the two wheel discs."""
    x, y = np.asarray(x, dtype=float), np.asarray(y, dtype=float)
    dx = np.maximum(np.abs(x) - BODY_HALF_LENGTH, 0.0)
    dy = np.maximum(np.abs(y) - BODY_HALF_WIDTH, 0.0)
    body = np.hypot(dx, dy)
    wheel = np.hypot(x, np.abs(y) - WHEEL_Y) - WHEEL_RADIUS
    return np.maximum(np.minimum(body, wheel), 0.0)


class ClearanceFeatures(BaseFeaturesExtractor):
    """Observation (as is) followed by one closeness value per lidar ray.

    Args:
        observation_space: the env's ``Box(num_rays + 7,)``.
        num_rays: lidar rays at the start of the observation.
        lidar_range: metres that a lidar entry of 1.0 stands for.
        scale: clearance (m) at which closeness falls to 1/e.
        fov: lidar field of view (deg).
        metric: ``"ray"`` (clearance along each ray) or ``"point"`` (from each hit point to
            the nearest part of the outline); see the module docstring.
    """

    METRICS = ("ray", "point")

    def __init__(self, observation_space, num_rays: int = 36, lidar_range: float = 5.0, scale: float = 0.15,
                 fov: float = 360.0, metric: str = "ray") -> None:
        n_obs = int(observation_space.shape[0])
        if n_obs < num_rays:
            raise ValueError(f"observation has {n_obs} entries, fewer than num_rays={num_rays}")
        if metric not in self.METRICS:
            raise ValueError(f"metric must be one of {self.METRICS}, got {metric!r}")
        super().__init__(observation_space, features_dim=n_obs + num_rays)
        self.num_rays = num_rays
        self.lidar_range = float(lidar_range)
        self.scale = float(scale)
        self.metric = metric
        angles = ray_angles(num_rays, fov)
        self.register_buffer("footprint", torch.as_tensor(footprint_distances(num_rays, fov), dtype=torch.float32))
        # not saved with the model (persistent=False): models saved before "point" existed still load
        self.register_buffer("cos", torch.as_tensor(np.cos(angles), dtype=torch.float32), persistent=False)
        self.register_buffer("sin", torch.as_tensor(np.sin(angles), dtype=torch.float32), persistent=False)

    def clearance(self, observations: torch.Tensor) -> torch.Tensor:
        """Per-ray clearance (m) to the robot's outline, shape ``(batch, num_rays)``."""
        ranges = observations[:, : self.num_rays] * self.lidar_range
        if self.metric == "ray":
            return torch.clamp(ranges - self.footprint, min=0.0)
        x = LIDAR_X + ranges * self.cos  # hit points in the body frame
        y = ranges * self.sin
        body = torch.hypot(torch.clamp(x.abs() - BODY_HALF_LENGTH, min=0.0),
                           torch.clamp(y.abs() - BODY_HALF_WIDTH, min=0.0))
        wheel = torch.hypot(x, y.abs() - WHEEL_Y) - WHEEL_RADIUS
        return torch.clamp(torch.minimum(body, wheel), min=0.0)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return torch.cat([observations, torch.exp(-self.clearance(observations) / self.scale)], dim=1)
