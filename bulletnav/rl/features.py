"""Policy-side lidar features: how close each ray's obstacle is to the robot's own outline.

The env's observation scales lidar ranges by the 5 m maximum, so touching an obstacle
(0.05-0.27 m from the lidar, depending on the ray) and being safely clear of it (0.3 m)
differ by a few hundredths of an input unit, and where contact happens differs by ray: the
lidar sits 5 cm behind the front face, 25 cm ahead of the rear and 10-12 cm from the sides
and wheels. :class:`ClearanceFeatures` appends, for every ray, the closeness
``exp(-clearance / scale)``. Two clearances are offered (``metric``):

- ``"ray"``: the range minus the distance from the lidar to the edge of the robot's collision
  outline along that ray (:func:`footprint_distances`). Blind between rays: an obstacle edge
  8 mm off the outer front corner of a wheel reads as 3 cm clear on the nearest ray
  (-110 deg).
- ``"point"``: the distance from the point the ray hit to the nearest part of the outline
  (the body rectangle and the wheel guards), whatever direction that is in.

The numbers above are the article robot's. The outline, the lidar's mount and the rays' spread
are the env's robot's (``robot=`` and ``fov=``: the Jackal of ``bulletnav/BARN-v0`` has a
0.508 x 0.430 m outline, its lidar 5.5 cm ahead of the centre and 72 rays over 270 degrees).

It is part of the policy (saved in the model, applied in ``predict``), so the env and its
observation stay as specified.
"""

from __future__ import annotations

import functools
import math

import numpy as np
import torch
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor

from bulletnav.config import ROBOTS, EnvConfig, robot_preset
from bulletnav.geometry import RobotGeometry, robot_geometry
from bulletnav.sensors.lidar import ray_angles

DEFAULT_ROBOT = "article"
"""The robot whose outline :class:`ClearanceFeatures` uses unless told (``robot=``): the article
robot, which every shipped model before the Jackal was trained on (their saved kwargs name none)."""


@functools.lru_cache(maxsize=len(ROBOTS))
def outline(robot: str = DEFAULT_ROBOT) -> tuple[tuple[tuple[float, float], ...], float]:
    """Robot ``robot``'s collision outline seen from above, read from its URDF
    (:mod:`bulletnav.geometry`): ``(half_x, half_y)`` of rectangles centred on the body origin
    (for the article robot the 0.3 x 0.2 m body and the two wheel guards reaching 2 cm past its
    sides; for the Jackal the 0.508 x 0.31 m body and bumpers and the guards out to 0.215 m), and
    how far (m) the lidar sits ahead of the body centre.

    Raises:
        ValueError: an unknown robot name.
    """
    geometry: RobotGeometry = robot_geometry(robot_preset(EnvConfig(), robot).robot)
    return geometry.centred_rectangles, geometry.lidar_offset


def robot_fov(robot: str = DEFAULT_ROBOT) -> float:
    """The field of view (deg) of robot ``robot``'s lidar (:func:`bulletnav.config.robot_preset`)."""
    return float(robot_preset(EnvConfig(), robot).sensors.lidar.fov)


_RECTANGLES, LIDAR_X = outline()
"""The article robot's outline and lidar offset (m), as before robots could be chosen."""


def _ray_interval(ox: float, c: float, s: float, hx: float, hy: float) -> tuple[float, float]:
    """Parameters ``(t_in, t_out)`` where the ray ``(ox + t c, t s)`` is inside the centred
    rectangle ``|x| <= hx, |y| <= hy`` (slab method; ``t_in > t_out`` when it misses)."""
    lo, hi = -math.inf, math.inf
    for o, d, h in ((ox, c, hx), (0.0, s, hy)):
        if abs(d) < 1e-12:
            if abs(o) > h:
                return math.inf, -math.inf
            continue
        a, b = (-h - o) / d, (h - o) / d
        lo, hi = max(lo, min(a, b)), min(hi, max(a, b))
    return lo, hi


def footprint_distances(num_rays: int, fov_deg: float = 360.0, lidar_x: float | None = None,
                        robot: str = DEFAULT_ROBOT) -> np.ndarray:
    """Distance (m) from the lidar to the edge of robot ``robot``'s outline along each ray
    (``lidar_x``: the lidar's offset ahead of the body centre, default the robot's).

    Rays are spread as the :class:`~bulletnav.sensors.lidar.Lidar` spreads them
    (:func:`~bulletnav.sensors.lidar.ray_angles`).
    """
    rectangles, offset = outline(robot)
    lidar_x = offset if lidar_x is None else lidar_x
    angles = ray_angles(num_rays, fov_deg)
    out = np.empty(num_rays)
    for i, a in enumerate(angles):
        c, s = math.cos(a), math.sin(a)
        t = 0.0  # the lidar is inside the body; walk out through every rectangle the ray is in
        grown = True
        while grown:
            grown = False
            for hx, hy in rectangles:
                t_in, t_out = _ray_interval(lidar_x, c, s, hx, hy)
                if t_in <= t + 1e-9 and t_out > t + 1e-9:
                    t, grown = t_out, True
        out[i] = t
    return out


class ClearanceFeatures(BaseFeaturesExtractor):
    """Observation (as is) followed by one closeness value per lidar ray.

    Args:
        observation_space: the env's ``Box(num_rays + 7,)``.
        num_rays: lidar rays at the start of the observation.
        lidar_range: metres that a lidar entry of 1.0 stands for.
        scale: clearance (m) at which closeness falls to 1/e.
        fov: lidar field of view (deg); None takes ``robot``'s (:func:`robot_fov`).
        metric: ``"ray"`` (clearance along each ray) or ``"point"`` (from each hit point to
            the nearest part of the outline); see the module docstring.
        robot: the robot (:data:`bulletnav.config.ROBOTS`) whose outline and lidar mount the
            clearances are measured from: the env's ``robot``. The default, the article robot,
            is what every model saved without this argument was trained with.
    """

    METRICS = ("ray", "point")

    def __init__(self, observation_space, num_rays: int = 36, lidar_range: float = 5.0, scale: float = 0.15,
                 fov: float | None = 360.0, metric: str = "ray", robot: str = DEFAULT_ROBOT) -> None:
        n_obs = int(observation_space.shape[0])
        if n_obs < num_rays:
            raise ValueError(f"observation has {n_obs} entries, fewer than num_rays={num_rays}")
        if metric not in self.METRICS:
            raise ValueError(f"metric must be one of {self.METRICS}, got {metric!r}")
        if robot not in ROBOTS:
            raise ValueError(f"robot must be one of {tuple(ROBOTS)}, got {robot!r}")
        fov = robot_fov(robot) if fov is None else float(fov)
        super().__init__(observation_space, features_dim=n_obs + num_rays)
        self.num_rays = num_rays
        self.lidar_range = float(lidar_range)
        self.scale = float(scale)
        self.metric = metric
        self.robot = robot
        self.rectangles, self.lidar_x = outline(robot)
        angles = ray_angles(num_rays, fov)
        footprint = footprint_distances(num_rays, fov, robot=robot)
        self.register_buffer("footprint", torch.as_tensor(footprint, dtype=torch.float32))
        # not saved with the model (persistent=False): models saved before "point" existed still load
        self.register_buffer("cos", torch.as_tensor(np.cos(angles), dtype=torch.float32), persistent=False)
        self.register_buffer("sin", torch.as_tensor(np.sin(angles), dtype=torch.float32), persistent=False)

    def clearance(self, observations: torch.Tensor) -> torch.Tensor:
        """Per-ray clearance (m) to the robot's outline, shape ``(batch, num_rays)``."""
        ranges = observations[:, : self.num_rays] * self.lidar_range
        if self.metric == "ray":
            return torch.clamp(ranges - self.footprint, min=0.0)
        x = (self.lidar_x + ranges * self.cos).abs()  # hit points in the body frame
        y = (ranges * self.sin).abs()
        parts = [torch.hypot(torch.clamp(x - hx, min=0.0), torch.clamp(y - hy, min=0.0)) for hx, hy in self.rectangles]
        return functools.reduce(torch.minimum, parts)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return torch.cat([observations, torch.exp(-self.clearance(observations) / self.scale)], dim=1)
