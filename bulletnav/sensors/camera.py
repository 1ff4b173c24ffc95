"""RGB, metric depth and segmentation from the camera mount link (TinyRenderer, DIRECT mode)."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import pybullet as p
from gymnasium import spaces

from bulletnav.config import CameraConfig
from bulletnav.sensors.base import Sensor
from bulletnav.sim.client import Clock
from bulletnav.sim.robot import Robot


class CameraImage(NamedTuple):
    rgb: np.ndarray
    """(H, W, 3) uint8 colour image."""
    depth: np.ndarray
    """(H, W) float32 depth along the optical axis (m), linearised from the depth buffer; ``far`` where empty."""
    segmentation: np.ndarray
    """(H, W) int32 PyBullet body id per pixel, -1 for background."""


def linearize_depth(buffer: np.ndarray, near: float, far: float) -> np.ndarray:
    """Metric z-depth (m) from an OpenGL depth buffer in [0, 1] with the given clip planes."""
    return far * near / (far - (far - near) * buffer)


class Camera(Sensor):
    """A pinhole camera ``fov`` degrees high, pitched ``pitch`` degrees from the mount's x axis.

    The mount link sits above and behind the body and looks along the heading, so the frame
    shows the path ahead with the robot's own back in the lower edge.
    """

    name = "camera"

    def __init__(self, robot: Robot, clock: Clock, config: CameraConfig = CameraConfig(),
                 renderer: int = p.ER_TINY_RENDERER) -> None:
        super().__init__(robot, clock, config.rate_hz)
        self.config = config
        self.renderer = renderer
        self.projection = p.computeProjectionMatrixFOV(
            config.fov, config.width / config.height, config.near, config.far, physicsClientId=robot.cid
        )
        pitch = math.radians(config.pitch)
        self._forward = np.array([math.cos(pitch), 0.0, math.sin(pitch)])
        self._up = np.array([-math.sin(pitch), 0.0, math.cos(pitch)])
        self.depth_noise_std = 0.0
        """Gaussian depth noise (m) of an evaluation shift or randomization; 0: exact depth."""

    def space(self) -> spaces.Dict:
        cfg = self.config
        return spaces.Dict({
            "rgb": spaces.Box(0, 255, (cfg.height, cfg.width, 3), dtype=np.uint8),
            "depth": spaces.Box(np.float32(0.0), np.float32(cfg.far), (cfg.height, cfg.width), dtype=np.float32),
            "segmentation": spaces.Box(-1, np.iinfo(np.int32).max, (cfg.height, cfg.width), dtype=np.int32),
        })

    def view_matrix(self) -> tuple[list[float], np.ndarray, np.ndarray]:
        """PyBullet view matrix of the current mount pose, with the eye position and forward axis."""
        pos, orn = p.getLinkState(self.robot.body, self.robot.camera_link, computeForwardKinematics=True,
                                  physicsClientId=self.robot.cid)[4:6]
        rot = np.reshape(p.getMatrixFromQuaternion(orn), (3, 3))
        eye = np.asarray(pos)
        forward = rot @ self._forward
        view = p.computeViewMatrix(eye.tolist(), (eye + forward).tolist(), (rot @ self._up).tolist(),
                                   physicsClientId=self.robot.cid)
        return view, eye, forward

    def measure(self) -> CameraImage:
        cfg = self.config
        view, _, _ = self.view_matrix()
        _, _, rgba, depth, seg = p.getCameraImage(
            cfg.width, cfg.height, view, self.projection, renderer=self.renderer, physicsClientId=self.robot.cid
        )
        rgb = np.reshape(np.asarray(rgba, dtype=np.uint8), (cfg.height, cfg.width, 4))[:, :, :3].copy()
        depth_m = linearize_depth(np.reshape(np.asarray(depth, dtype=np.float64), (cfg.height, cfg.width)),
                                  cfg.near, cfg.far).astype(np.float32)
        if self.depth_noise_std > 0:
            depth_m += self.rng.normal(0.0, self.depth_noise_std, depth_m.shape).astype(np.float32)
            np.clip(depth_m, cfg.near, cfg.far, out=depth_m)
        seg_ids = np.reshape(np.asarray(seg, dtype=np.int32), (cfg.height, cfg.width))
        return CameraImage(rgb, depth_m, seg_ids)
