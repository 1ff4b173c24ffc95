"""Episodes as ROS 2 messages in an MCAP file, stamped in simulated time.

:class:`McapRecorder` wraps a single-robot env (outermost, over a shield wrapper if there is
one) and writes, for every control step, what a ROS 2 robot driver and navigation stack would
publish: the file opens beside a real robot's bag in Foxglove or RViz, and any ROS 2 tool reads
it. Messages are CDR-encoded with their definitions embedded (``mcap`` + ``mcap-ros2-support``;
no ROS installation). The same messages, the same bytes, can also go to a live Foxglove server
(``live``: :mod:`bulletnav.ros.live`), with or without a file (:mod:`bulletnav.ros.outputs`).

Topics (frames: ``map`` the world, ``odom`` where the wheel odometry started, ``base_link``
the robot, ``laser`` and ``camera_link`` its sensors):

- ``/clock`` (``rosgraph_msgs/msg/Clock``): every step.
- ``/tf_static``: ``base_link -> laser`` and ``base_link -> camera_link`` from the URDF's
  mounts, at every episode start.
- ``/tf``: ``map -> odom`` (the odometry's drift: the true pose composed with the inverse of
  the odometry's estimate) and ``odom -> base_link`` (the odometry's estimate), every step.
- ``/scan`` (``sensor_msgs/msg/LaserScan``): the ranges the robot's observation holds (noise,
  dropouts and all), one per step, in ``laser``.
- ``/odom`` (``nav_msgs/msg/Odometry``), ``/imu`` (``sensor_msgs/msg/Imu``: no orientation
  estimate, so its covariance's first element is -1 as the message defines), every step.
- ``/cmd_vel`` (``geometry_msgs/msg/Twist``): the command the robot was sent (after the shield
  when one is on), every step.
- ``/goal_pose`` (``geometry_msgs/msg/PoseStamped``): at episode start and whenever the goal moves.
- ``/plan`` (``nav_msgs/msg/Path``): the classical planner's path (``plan`` callable), whenever it changes.
- ``/map`` (``nav_msgs/msg/OccupancyGrid``): a lidar occupancy map (bulletnav's
  :class:`~bulletnav.planning.mapping.LidarMapper`, its scans placed at the true pose) every
  ``map_period_s``; ``/map_truth``: the true static map at every episode start.
- ``/movers`` (``visualization_msgs/msg/MarkerArray``): forklifts (cubes) and workers
  (cylinders), every step in dynamic worlds.
- ``/reward`` (``std_msgs/msg/Float64``): the step's reward, every step.
- ``/goal_distance`` (``std_msgs/msg/Float64``): metres from the robot's true position to the
  goal, every step; ``/shield/interventions`` (``std_msgs/msg/Float64``): how many steps of the
  episode so far the safety shield replaced the command, every step behind a shield
  (``ShieldWrapper``).
- ``/camera/image/compressed`` (``sensor_msgs/msg/CompressedImage``, JPEG) and ``/camera/depth``
  (``sensor_msgs/msg/Image``, ``32FC1`` metres), in ``camera_link``: every step when the camera
  is in the observation (``camera_obs=True``: the env renders it anyway), else at ``camera_hz``
  when one is given (rendering costs about 10 ms a frame), else never.

Each episode also carries an attachment ``episode-<k>.json`` (``application/json``): the
warehouse layout (``layout_to_dict``: floor, obstacles with their categories), the start pose,
the goals, the goal radius, the robot's radius, the movers' routes, the env id and its step limit, so that
``bulletnav replay`` draws the episode from the file alone.

Episodes follow each other in one time line: episode k+1 starts ``gap_s`` after episode k
ended. Each episode is an MCAP metadata record named ``episode`` (index, seed, first and last
stamp in ns, steps, end reason, success, collision). The file is written beside its name and
renamed when :meth:`McapRecorder.close` is called after a complete run; :meth:`abort` (or an
exception in the ``with`` block) removes it, so no half-written recording is left.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from bulletnav.errors import BulletnavError
from bulletnav.ros.outputs import TOPIC_TYPES, McapFile, Ros2Outputs, topic_type

log = logging.getLogger(__name__)

MAP_RESOLUTION = 0.1
"""Cell size (m) of ``/map`` and ``/map_truth``."""


def stamp(ns: int) -> dict[str, int]:
    """A ``builtin_interfaces/Time`` of ``ns`` nanoseconds."""
    return {"sec": ns // 1_000_000_000, "nanosec": ns % 1_000_000_000}


def quaternion(yaw: float) -> dict[str, float]:
    """The rotation by ``yaw`` (rad) about z."""
    return {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)}


def message_yaw(q: Any) -> float:
    """The heading (rad) of a quaternion message (``x``, ``y``, ``z``, ``w`` attributes): the
    inverse of :func:`quaternion` for a rotation about z."""
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _pose(x: float, y: float, yaw: float, z: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": quaternion(yaw)}


def _transform(ns: int, parent: str, child: str, x: float, y: float, yaw: float, z: float = 0.0) -> dict[str, Any]:
    return {"header": {"stamp": stamp(ns), "frame_id": parent}, "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": y, "z": z}, "rotation": quaternion(yaw)}}


def compose(a: tuple[float, float, float], b: tuple[float, float, float]) -> tuple[float, float, float]:
    """The 2-D pose ``a * b`` (``b`` expressed in ``a``'s frame)."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], math.remainder(a[2] + b[2], 2 * math.pi)


def inverse(a: tuple[float, float, float]) -> tuple[float, float, float]:
    """The 2-D pose ``a`` inverted."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return -c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]


def occupancy_message(ns: int, frame: str, cells: np.ndarray, resolution: float,
                      corner: tuple[float, float]) -> dict[str, Any]:
    """A ``nav_msgs/msg/OccupancyGrid`` of ``cells`` (indexed [ix, iy]; -1 unknown, 0 free,
    100 occupied) whose cell (0, 0) has its lower-left corner at ``corner`` (m)."""
    nx, ny = cells.shape
    return {"header": {"stamp": stamp(ns), "frame_id": frame},
            "info": {"map_load_time": stamp(ns), "resolution": float(resolution), "width": int(nx), "height": int(ny),
                     "origin": _pose(float(corner[0]), float(corner[1]), 0.0)},
            "data": np.ascontiguousarray(cells.T, dtype=np.int8).reshape(-1)}


def robot_messages(write: Callable[[str, dict[str, Any], int], None], robot: Any, ns: int, dt: float,
                   prefix: str = "", wants: Callable[[str], bool] | None = None
                   ) -> tuple[tuple[float, float, float], np.ndarray, np.ndarray]:
    """Write one robot's ``/tf`` (``map -> odom -> base_link``), ``/scan``, ``/odom`` and ``/imu`` for
    the step at ``ns`` (topics and frames under ``prefix``, e.g. ``robot_2``, but ``/tf`` is the one
    global topic, as RViz and Foxglove read it); returns its true pose, ray angles and ranges.
    ``robot``: a scene view (``pose``, ``sensors``). ``wants(topic)``: whether anyone takes that
    topic now (a live stream nobody watches); the others are not built (default: all are)."""
    t = stamp(ns)
    top = f"/{prefix}" if prefix else ""
    odom_f, base_f, laser_f = (f"{prefix}/{f}" if prefix else f for f in ("odom", "base_link", "laser"))
    truth = tuple(float(v) for v in robot.pose)
    sensors = robot.sensors
    lidar = sensors.lidar
    ranges = np.asarray(lidar.read(), dtype=np.float32)
    angles = lidar.angles
    if wants is None or wants("/tf") or wants(f"{top}/odom"):
        odo = [float(v) for v in sensors.odometry.read()]
        est = (odo[0], odo[1], odo[2])
        drift = compose(truth, inverse(est))  # map -> odom
        write("/tf", {"transforms": [_transform(ns, "map", odom_f, *drift), _transform(ns, odom_f, base_f, *est)]}, ns)
        zeros36 = [0.0] * 36
        write(f"{top}/odom", {"header": {"stamp": t, "frame_id": odom_f}, "child_frame_id": base_f,
                              "pose": {"pose": _pose(*est), "covariance": zeros36},
                              "twist": {"twist": {"linear": {"x": odo[3], "y": 0.0, "z": 0.0},
                                                  "angular": {"x": 0.0, "y": 0.0, "z": odo[4]}},
                                        "covariance": zeros36}}, ns)
    if wants is None or wants(f"{top}/scan"):
        cfg = lidar.config
        increment = float(angles[1] - angles[0]) if len(angles) > 1 else 0.0
        write(f"{top}/scan", {"header": {"stamp": t, "frame_id": laser_f}, "angle_min": float(angles[0]),
                              "angle_max": float(angles[-1]), "angle_increment": increment, "time_increment": 0.0,
                              "scan_time": dt, "range_min": float(cfg.min_range), "range_max": float(cfg.max_range),
                              "ranges": ranges.tolist(), "intensities": []}, ns)
    if wants is None or wants(f"{top}/imu"):
        imu = [float(v) for v in sensors.imu.read()] if sensors.imu is not None else [0.0] * 6
        write(f"{top}/imu", {"header": {"stamp": t, "frame_id": base_f},
                             "orientation": {"x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0},
                             "orientation_covariance": [-1.0] + [0.0] * 8,
                             "angular_velocity": {"x": imu[3], "y": imu[4], "z": imu[5]},
                             "angular_velocity_covariance": [0.0] * 9,
                             "linear_acceleration": {"x": imu[0], "y": imu[1], "z": imu[2]},
                             "linear_acceleration_covariance": [0.0] * 9}, ns)
    return truth, angles, ranges


def truth_map_message(ns: int, view: Any) -> dict[str, Any]:
    """``/map_truth``: the scene's true static map (``view.occupancy``) at :data:`MAP_RESOLUTION`."""
    truth = view.occupancy(MAP_RESOLUTION)
    layout = getattr(view, "layout", None)
    if layout is not None and layout.corner is not None:  # a user's map: its own origin, to the bit
        corner = layout.corner
    else:
        corner = (truth.origin[0] - MAP_RESOLUTION / 2, truth.origin[1] - MAP_RESOLUTION / 2)
    return occupancy_message(ns, "map", np.where(truth.occupied, 100, 0), MAP_RESOLUTION, corner)


def goal_message(ns: int, goal: tuple[float, float]) -> dict[str, Any]:
    """A ``geometry_msgs/msg/PoseStamped`` of the goal point in ``map``."""
    return {"header": {"stamp": stamp(ns), "frame_id": "map"}, "pose": _pose(float(goal[0]), float(goal[1]), 0.0)}


def static_mounts(ns: int, geometry: Any, prefix: str = "") -> list[dict[str, Any]]:
    """``base_link -> laser`` and ``base_link -> camera_link`` of a robot (frames under ``prefix``)."""
    base, laser, cam = (f"{prefix}/{f}" if prefix else f for f in ("base_link", "laser", "camera_link"))
    lx, ly, lz = geometry.lidar_mount
    mounts = [_transform(ns, base, laser, lx, ly, 0.0, lz)]
    if geometry.camera_mount is not None:
        cx, cy, cz = geometry.camera_mount
        mounts.append(_transform(ns, base, cam, cx, cy, 0.0, cz))
    return mounts


def movers_message(t: dict[str, int], movers: Any) -> dict[str, Any]:
    """A ``MarkerArray``: a ``DELETEALL``, then each mover (forklift: cube, worker: cylinder)."""
    markers = [{"header": {"stamp": t, "frame_id": "map"}, "ns": "movers", "id": 0, "type": 0, "action": 3,
                "pose": _pose(0.0, 0.0, 0.0), "scale": {"x": 0.0, "y": 0.0, "z": 0.0},
                "color": {"r": 0.0, "g": 0.0, "b": 0.0, "a": 0.0}, "lifetime": stamp(0),
                "frame_locked": False, "points": [], "colors": [], "text": "", "mesh_resource": "",
                "mesh_use_embedded_materials": False}]
    for k, m in enumerate(movers, 1):
        sx, sy, sz = (float(v) for v in m.size)
        worker = m.kind == "worker"
        markers.append({**markers[0], "ns": m.kind, "id": k, "type": 3 if worker else 1, "action": 0,
                        "pose": _pose(float(m.pose[0]), float(m.pose[1]), float(m.pose[2]), sz / 2),
                        "scale": {"x": sx, "y": sy, "z": sz},
                        "color": ({"r": 0.2, "g": 0.5, "b": 1.0, "a": 0.9} if worker
                                  else {"r": 1.0, "g": 0.6, "b": 0.0, "a": 0.9}),
                        "text": m.kind})
    return {"markers": markers}


class McapRecorder(gym.Wrapper):
    """Publish every episode of ``env`` as ROS 2 messages (see the module docstring): recorded
    into ``path``, streamed live to ``live``'s clients, or both (the same bytes to each).

    Args:
        env: a single-robot bulletnav env (``gym.make``), possibly shielded.
        path: the ``.mcap`` file to write; None: no recording (``live`` only).
        plan: called after each step, returns the classical planner's current path (a list of
            (x, y) in m) or None; None: no ``/plan``.
        map_period_s: seconds of simulated time between two ``/map`` messages.
        gap_s: seconds of the time line between one episode's end and the next one's start.
        overwrite: replace an existing ``path`` (else refused).
        camera_hz: record camera images at this rate (per simulated second) when the camera is
            not in the observation; None: only when it is.
        live: a :class:`~bulletnav.ros.live.LiveServer` to stream to (paced at its speed); the
            caller starts and stops it. Topics no client subscribes to are not built.

    Raises:
        BulletnavError: ``path`` exists and ``overwrite`` is off, or does not end in ``.mcap``;
            neither ``path`` nor ``live`` is given.
    """

    def __init__(self, env: gym.Env, path: str | Path | None, plan: Callable[[], Any] | None = None,
                 map_period_s: float = 1.0, gap_s: float = 1.0, overwrite: bool = False,
                 camera_hz: float | None = None, live: Any = None) -> None:
        super().__init__(env)
        self.path = None if path is None else Path(path)
        self.plan = plan
        if camera_hz is not None and not camera_hz > 0:
            raise BulletnavError(f"camera_hz must be > 0 (images per simulated second), got {camera_hz!r}")
        self.camera_hz = camera_hz
        self.map_period_s = float(map_period_s)
        self.gap_s = float(gap_s)
        self._out = Ros2Outputs(None if path is None else McapFile(path, overwrite), live)
        self.counts = self._out.counts
        """Messages written per topic."""
        self._write = self._out.write
        self._next_start_ns = 0
        self._closed = False
        self._episode: dict[str, Any] | None = None
        self.episodes = 0
        """Episodes recorded so far."""

    def _now_ns(self) -> int:
        ep = self._episode
        assert ep is not None
        return ep["start_ns"] + int(round(ep["steps"] * self._dt * 1e9))

    # ------------------------------------------------------------------ gym
    def reset(self, **kwargs: Any) -> tuple[Any, dict[str, Any]]:
        obs, info = self.env.reset(**kwargs)
        self._end_episode(None)
        scene = self.env.unwrapped.scene
        self._dt = float(scene.control_dt)
        start_ns = self._next_start_ns
        self._episode = {"index": self.episodes, "seed": kwargs.get("seed"), "start_ns": start_ns, "steps": 0}
        self._goal: tuple[float, float] | None = None
        self._interventions = 0
        self._plan_sent: Any = None
        self._map_due = 0.0
        self._camera_due = 0.0
        config = getattr(self.env.unwrapped, "config", None)
        self._camera_in_obs = bool(config is not None and config.camera_obs)  # the env renders it every step anyway
        self._lidar = scene.sensors.lidar
        self._bounds = scene.layout.bounds  # a user's map: in its own frame
        from bulletnav.planning.mapping import LidarMapper

        self._mapper = LidarMapper(self._bounds, MAP_RESOLUTION)
        self._out.pace(start_ns)
        self._write("/tf_static", {"transforms": static_mounts(start_ns, scene.geometry)}, start_ns)
        self._write("/map_truth", truth_map_message(start_ns, scene), start_ns)
        self._publish_goal(scene, start_ns)
        self._attach_episode(scene, start_ns)
        self.episodes += 1
        return obs, info

    def _attach_episode(self, scene: Any, ns: int) -> None:
        import json

        from bulletnav.sim.layout import layout_to_dict

        spec = self.env.spec
        record = {"layout": layout_to_dict(scene.layout), "start": [float(v) for v in scene.start],
                  "goals": [[float(g[0]), float(g[1])] for g in scene.goals],
                  "goal_radius": float(scene.goal_radius), "robot_radius": float(scene.geometry.radius),
                  "lidar_mount": [float(v) for v in scene.geometry.lidar_mount],
                  "control_dt": self._dt, "env_id": getattr(spec, "id", None),
                  "mover_routes": [[[float(x), float(y)] for x, y in m.path] for m in scene.movers] if scene.dynamic else [],
                  "max_episode_steps": getattr(spec, "max_episode_steps", None)}
        self._out.add_attachment(ns, f"episode-{self.episodes}.json", "application/json", json.dumps(record).encode())

    def step(self, action: Any) -> tuple[Any, float, bool, bool, dict[str, Any]]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        ep = self._episode
        if ep is None:
            raise BulletnavError("McapRecorder: step() before reset()")
        ep["steps"] += 1
        ns = self._now_ns()
        scene = self.env.unwrapped.scene
        self._record_step(scene, action, info, ns)
        self._record_progress(scene, reward, info, ns)
        self._out.pace(ns)
        if terminated or truncated:
            self._end_episode(info, truncated=truncated and not terminated)
        return obs, reward, terminated, truncated, info

    # ------------------------------------------------------------------ one step
    def _record_progress(self, scene: Any, reward: float, info: dict[str, Any], ns: int) -> None:
        """``/reward``, ``/goal_distance`` and (behind a shield) ``/shield/interventions``."""
        wants = self._out.wants
        if wants("/reward"):
            self._write("/reward", {"data": float(reward)}, ns)
        goal = scene.goal
        if goal is not None and wants("/goal_distance"):
            x, y = (float(v) for v in scene.pose[:2])
            self._write("/goal_distance", {"data": math.hypot(float(goal[0]) - x, float(goal[1]) - y)}, ns)
        veto = info.get("shield")
        if isinstance(veto, dict) and "intervened" in veto:
            self._interventions += bool(veto["intervened"])
            if wants("/shield/interventions"):
                self._write("/shield/interventions", {"data": float(self._interventions)}, ns)

    def _command(self, action: Any, info: dict[str, Any]) -> tuple[float, float]:
        """The command carried out: the shield's, else the env's own reading of the action
        (``WarehouseEnv.command``: scaled and clipped to the robot's limits)."""
        veto = info.get("shield")
        if isinstance(veto, dict) and "v" in veto:
            return float(veto["v"]), float(veto["w"])
        return self.env.unwrapped.command(action)

    def _record_step(self, scene: Any, action: Any, info: dict[str, Any], ns: int) -> None:
        t = stamp(ns)
        wants = self._out.wants
        if wants("/clock"):
            self._write("/clock", {"clock": t}, ns)
        truth, angles, ranges = robot_messages(self._write, scene, ns, self._dt, wants=wants)
        cfg = self._lidar.config
        if wants("/cmd_vel"):
            v, w = self._command(action, info)
            self._write("/cmd_vel", {"linear": {"x": v, "y": 0.0, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": w}}, ns)
        self._publish_goal(scene, ns)
        if self.plan is not None:
            path = self.plan()
            key = None if path is None else tuple((round(float(x), 6), round(float(y), 6)) for x, y in path)
            if key != self._plan_sent:
                self._plan_sent = key
                poses = [{"header": {"stamp": t, "frame_id": "map"}, "pose": _pose(x, y, 0.0)} for x, y in (key or ())]
                self._write("/plan", {"header": {"stamp": t, "frame_id": "map"}, "poses": poses}, ns)
        now_s = self._episode["steps"] * self._dt
        if self._out.watched("/map"):  # the lidar map costs ~half a step: built while anyone takes it
            self._mapper.integrate(truth, angles, ranges.astype(np.float64), float(cfg.max_range),
                                   sensor_offset=float(scene.geometry.lidar_mount[0]))
        else:
            self._map_due = now_s  # a client that subscribes gets the map at once
        if now_s + 1e-9 >= self._map_due and self._out.watched("/map"):
            self._map_due = now_s + self.map_period_s
            state = self._mapper.state()
            cells = np.where(state < 0, -1, np.where(state > 0, 100, 0))
            self._write("/map", occupancy_message(ns, "map", cells, MAP_RESOLUTION, self._bounds[:2]), ns)
        self._record_camera(scene, t, ns, now_s)
        if scene.dynamic and wants("/movers"):
            self._write("/movers", movers_message(t, scene.movers), ns)

    def _record_camera(self, scene: Any, t: dict[str, int], ns: int, now_s: float) -> None:
        camera = scene.sensors.camera
        if camera is None or not (self._out.wants("/camera/image/compressed") or self._out.wants("/camera/depth")):
            return
        if not self._camera_in_obs:
            if self.camera_hz is None or now_s + 1e-9 < self._camera_due:
                return
            self._camera_due = now_s + 1.0 / self.camera_hz
        import io

        from PIL import Image

        image = camera.read()
        buf = io.BytesIO()
        Image.fromarray(np.asarray(image.rgb, dtype=np.uint8)).save(buf, format="JPEG", quality=90)
        header = {"stamp": t, "frame_id": "camera_link"}
        self._write("/camera/image/compressed", {"header": header, "format": "jpeg", "data": buf.getvalue()}, ns)
        depth = np.ascontiguousarray(image.depth, dtype="<f4")
        h, w = depth.shape
        self._write("/camera/depth", {"header": header, "height": h, "width": w, "encoding": "32FC1", "is_bigendian": 0,
                                      "step": w * 4, "data": depth.tobytes()}, ns)

    def _publish_goal(self, scene: Any, ns: int) -> None:
        goal = scene.goal
        if goal is None:
            return
        goal = (float(goal[0]), float(goal[1]))
        if goal != self._goal:
            self._goal = goal
            self._write("/goal_pose", goal_message(ns, goal), ns)

    def _end_episode(self, info: dict[str, Any] | None, truncated: bool = False) -> None:
        ep = self._episode
        if ep is None:
            return
        end_ns = self._now_ns()
        data = {"index": ep["index"], "seed": ep["seed"], "start_ns": ep["start_ns"], "end_ns": end_ns,
                "steps": ep["steps"]}
        if info is not None:
            reason = info.get("end_reason") or ("timeout" if truncated else None)
            data.update(end_reason=reason, is_success=info.get("is_success"), collision=info.get("collision"))
        else:
            data.update(end_reason="reset before the end")
        self._out.add_metadata("episode", {k: str(v) for k, v in data.items()})
        self._next_start_ns = end_ns + int(round(self.gap_s * 1e9))
        self._episode = None

    # ------------------------------------------------------------------ files
    def close(self) -> None:
        """Finish the file and move it to ``path`` (an episode still open is ended first)."""
        if not self._closed:
            self._closed = True
            self._end_episode(None)
            self._out.close()
            if self.path is not None:
                log.info("recorded %d episode(s) into %s", self.episodes, self.path)
        super().close()

    def abort(self) -> None:
        """Drop the recording: nothing is left at ``path`` or beside it."""
        self._out.abort()


__all__ = ["MAP_RESOLUTION", "McapFile", "McapRecorder", "TOPIC_TYPES", "goal_message", "movers_message", "robot_messages",
           "static_mounts", "topic_type", "truth_map_message", "compose", "inverse", "message_yaw", "occupancy_message", "quaternion",
           "stamp"]
