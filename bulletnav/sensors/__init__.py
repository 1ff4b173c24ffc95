"""Sensors: one module each, all reading from the robot's own physics client."""

from bulletnav.sensors.base import Sensor
from bulletnav.sensors.camera import Camera, CameraImage
from bulletnav.sensors.imu import Imu
from bulletnav.sensors.lidar import Lidar, ray_angles
from bulletnav.sensors.odometry import Odometry
from bulletnav.sensors.suite import SensorSuite

__all__ = ["Camera", "CameraImage", "Imu", "Lidar", "Odometry", "Sensor", "SensorSuite", "ray_angles"]
