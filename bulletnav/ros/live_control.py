"""Goals and teleop from Foxglove: one robot that waits for goals (``view --live ... --live-control``).

:class:`LiveControl` runs one robot in the world on a driving stream
(:class:`~bulletnav.ros.live.LiveServer` with ``control``), stepping the env at the stream's pace.
What clients publish steers it:

- ``/goal_pose`` (``geometry_msgs/msg/PoseStamped``, Foxglove's 3D panel's *Publish pose*): the
  goal from now on. Its point (the orientation is not used: goals are points) is read in the
  ``map`` frame, or in any frame of the stream's ``/tf`` tree (``odom``, ``base_link``,
  ``laser``, ``camera_link``: Foxglove publishes in the 3D panel's display frame) at the pose of
  the moment it arrives. The controller then drives to it and replans; the accepted goal is
  echoed on ``/goal_pose`` (and recorded with ``--record``). A goal outside the world's floor or
  inside an obstacle is answered with a Foxglove ``status`` of level error naming why, and
  nothing else changes. The run never ends at a goal: the robot stops there and waits.
- ``/cmd_vel`` (``geometry_msgs/msg/Twist``, the Teleop panel): ``linear.x`` (m/s) and
  ``angular.z`` (rad/s) drive the robot for :data:`TELEOP_HOLD_S` of simulated time after each
  message, the goal being driven to is dropped (the robot stops after the burst and waits), and
  every command, the controller's too, passes the safety shield
  (:class:`~bulletnav.control.shield.ShieldWrapper`): a command whose stopping sweep would touch
  what the lidar sees is replaced by the closest safe one.

Both topics are taken in either encoding a Foxglove client may publish in: ``cdr`` (read by
:func:`bulletnav.ros.cdr.decode`) and ``json``. A message that cannot be read (malformed bytes, a
missing or non-finite field, another type) is logged and answered with an error status; it never
stops the run. Other topics are answered with a warning status, once per client and topic.

The env runs :class:`GoalPoseTask` (``task_name="goal_pose"``, registered on import): the navigation
task, its observation and reward unchanged, with a goal that changes while it runs, the robot
waiting where it starts until the first, and no episode end (a collision is reported, not ended on).
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.control.shield import ShieldWrapper
from bulletnav.errors import BulletnavError
from bulletnav.ros.cdr import decode
from bulletnav.ros.live import ClientMessage, LiveServer
from bulletnav.ros.record import McapRecorder, compose, inverse
from bulletnav.tasks import register_task
from bulletnav.tasks.navigation import NavigationTask

log = logging.getLogger(__name__)

GOAL_TOPIC = "/goal_pose"
TELEOP_TOPIC = "/cmd_vel"
TASK_NAME = "goal_pose"
"""The env's ``task_name`` for :class:`GoalPoseTask`."""
TELEOP_HOLD_S = 0.5
"""Seconds of simulated time one ``/cmd_vel`` message drives the robot."""
NO_STEP_LIMIT = 2**31 - 1
"""The env's step limit in a driving session (2.8 years at 24 Hz: none that a session reaches)."""
POSE_TYPES = ("geometry_msgs/msg/PoseStamped", "geometry_msgs/PoseStamped")
"""The type names a goal may come as (ROS 2's, and the short one Foxglove's panels advertise)."""
TWIST_TYPES = ("geometry_msgs/msg/Twist", "geometry_msgs/Twist")
"""The type names a teleop command may come as."""
MAX_JSON_BYTES = 64 * 1024
"""The longest JSON message read (bytes)."""


class GoalPoseTask(NavigationTask):
    """Navigation to a goal that is given while the env runs (see the module docstring).

    The episode starts with the robot's own start point as its goal (it waits there), unless
    ``reset`` gets ``options={"goal": (x, y)}``; :meth:`set_goal` moves the goal; the episode
    never ends."""

    def _choose_episode(self, scene: Any, rng: np.random.Generator, options: dict[str, Any]
                        ) -> tuple[tuple[float, float, float], tuple[tuple[float, float], ...]]:
        start, goals = super()._choose_episode(scene, rng, options)
        return start, (goals if "goal" in options else ((float(start[0]), float(start[1])),))

    def set_goal(self, scene: Any, goal: tuple[float, float]) -> None:
        """Head for ``goal`` (x, y m) from now on: the distance, the heading error and the
        progress term are measured to it from this moment."""
        self._head_for(scene, goal)
        self._success = self.distance < self._goal_radius

    def end(self, scene: Any) -> tuple[bool, bool, str | None]:
        """Never: a driving session goes on until it is stopped."""
        return False, False, None


register_task(TASK_NAME, GoalPoseTask)


# ---------------------------------------------------------------------------------------
# reading what clients publish

@dataclass(frozen=True)
class GoalRequest:
    """A goal point as published: ``x``, ``y`` (m) in ``frame``."""

    frame: str
    x: float
    y: float


@dataclass(frozen=True)
class TeleopRequest:
    """A teleop command: forward speed ``v`` (m/s) and yaw rate ``w`` (rad/s, counter-clockwise +)."""

    v: float
    w: float


def _json(data: bytes) -> Any:
    if len(data) > MAX_JSON_BYTES:
        raise ValueError(f"{len(data)} bytes of JSON, more than {MAX_JSON_BYTES}")
    try:
        return json.loads(bytes(data).decode("utf-8"), parse_constant=_no_constant)
    except UnicodeDecodeError as exc:
        raise ValueError(f"JSON that is not UTF-8 ({exc.reason})") from None
    except json.JSONDecodeError as exc:
        raise ValueError(f"not JSON ({exc.msg} at character {exc.pos})") from None
    except RecursionError:
        raise ValueError("JSON nested too deeply") from None


def _no_constant(name: str) -> Any:
    raise ValueError(f"JSON with {name} in it (not a number)")


def _field(message: Any, path: str) -> Any:
    value = message
    for part in path.split("."):
        if not isinstance(value, dict) or part not in value:
            raise ValueError(f"no field {path!r}")
        value = value[part]
    return value


MAX_VALUE = 1.0e6
"""The largest magnitude a number of a client's message may have (m, m/s, rad/s): far past any
world (``limits.world_size``) and any robot's speed, short of what a float32 action overflows."""


def _number(message: Any, path: str) -> float:
    value = _field(message, path)
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise ValueError(f"field {path!r} is {type(value).__name__}, not a number")
    try:
        out = float(value)
    except OverflowError:  # a JSON integer of hundreds of digits
        raise ValueError(f"field {path!r} is an integer too large for a float") from None
    if not math.isfinite(out) or abs(out) > MAX_VALUE:
        raise ValueError(f"field {path!r} is {out:g}, not a finite number of at most {MAX_VALUE:g} in size")
    return out


def _message(kind: tuple[str, ...], encoding: str, schema_name: str, data: bytes) -> Any:
    if schema_name not in kind:
        raise ValueError(f"its type is {schema_name!r}, not {kind[0]}")
    if encoding == "cdr":
        return decode(kind[0], data)
    if encoding == "json":
        return _json(data)
    raise ValueError(f"encoding {encoding!r} is not cdr or json")


def read_goal(encoding: str, schema_name: str, data: bytes) -> GoalRequest:
    """The goal in a ``PoseStamped`` message (``cdr`` or ``json``).

    Raises:
        ValueError: not such a message, or its frame or point is missing, empty or not finite.
    """
    message = _message(POSE_TYPES, encoding, schema_name, data)
    frame = _field(message, "header.frame_id")
    if not isinstance(frame, str) or not frame:
        raise ValueError(f"field 'header.frame_id' is {frame!r}, not a frame's name")
    return GoalRequest(frame.lstrip("/"), _number(message, "pose.position.x"), _number(message, "pose.position.y"))


def read_twist(encoding: str, schema_name: str, data: bytes) -> TeleopRequest:
    """The command in a ``Twist`` message (``cdr`` or ``json``).

    Raises:
        ValueError: not such a message, or ``linear.x`` or ``angular.z`` is missing or not finite.
    """
    message = _message(TWIST_TYPES, encoding, schema_name, data)
    return TeleopRequest(_number(message, "linear.x"), _number(message, "angular.z"))


# ---------------------------------------------------------------------------------------
# where a goal lies

def frames_in_map(scene: Any) -> dict[str, tuple[float, float, float]]:
    """Each frame of the stream's ``/tf`` tree as a 2-D pose (x, y, yaw) in ``map`` now."""
    truth = tuple(float(v) for v in scene.pose)
    odometry = [float(v) for v in scene.sensors.odometry.read()[:3]]
    geometry = scene.geometry
    out = {"map": (0.0, 0.0, 0.0), "odom": compose(truth, inverse((odometry[0], odometry[1], odometry[2]))),
           "base_link": truth, "laser": compose(truth, (float(geometry.lidar_mount[0]), float(geometry.lidar_mount[1]), 0.0))}
    if geometry.camera_mount is not None:
        out["camera_link"] = compose(truth, (float(geometry.camera_mount[0]), float(geometry.camera_mount[1]), 0.0))
    return out


def goal_refusal(layout: Any, x: float, y: float) -> str | None:
    """Why a goal at (``x``, ``y``) in ``map`` cannot be driven to (outside the floor, inside an
    obstacle), or None."""
    if not layout.on_floor(x, y):
        x0, y0, x1, y1 = layout.bounds
        return f"it lies outside the world (its floor spans x {x0:g} to {x1:g} m, y {y0:g} to {y1:g} m)"
    for obstacle in layout.obstacles:
        if float(obstacle.distance(np.array(x), np.array(y))) <= 0.0:
            return f"it lies inside {('a ' + obstacle.label) if obstacle.label else 'an obstacle'}"
    return None


# ---------------------------------------------------------------------------------------
# the session

class LiveControl:
    """One robot driven from Foxglove (see the module docstring).

    Args:
        env: a single-robot env made with ``task_name="goal_pose"`` (:class:`GoalPoseTask`) and a
            step limit no session reaches (:data:`NO_STEP_LIMIT`); the session puts it behind the
            shield and streams it (:class:`~bulletnav.ros.record.McapRecorder`), and closes it.
        policy: the controller that drives to a goal (a :class:`~bulletnav.policy.Policy`: PID +
            A*, move_base DWA, a trained model ...); its ``path``, if it has one, is ``/plan``.
        live: a driving stream (:class:`~bulletnav.ros.live.LiveServer` made with ``control``).
        record: also record the session into this ``.mcap`` file (None: no recording).
        overwrite: replace an existing ``record`` file.
        on_event: called with one line (simulated time first) for each goal taken, refused or
            reached, each teleop burst and each collision; the CLI prints them.
        hold_s: seconds of simulated time one ``/cmd_vel`` message drives the robot.

    Raises:
        BulletnavError: ``live`` does not take client messages, or the env's task is not
            :class:`GoalPoseTask`.
    """

    def __init__(self, env: Any, policy: Any, live: LiveServer, record: str | Path | None = None,
                 overwrite: bool = False, on_event: Callable[[str], None] | None = None,
                 hold_s: float = TELEOP_HOLD_S) -> None:
        if live.control is None:
            raise BulletnavError("LiveControl needs a driving stream: LiveServer(..., control=OriginPolicy())")
        if not isinstance(env.unwrapped.task, GoalPoseTask):
            raise BulletnavError(f"LiveControl needs an env made with task_name={TASK_NAME!r} "
                                 f"(its task is {type(env.unwrapped.task).__name__})")
        self.shield = ShieldWrapper(env)
        self.env = McapRecorder(self.shield, record, plan=lambda: getattr(policy, "path", None), overwrite=overwrite,
                                live=live)
        self.policy = policy
        self.live = live
        self.on_event = on_event
        self.hold_s = float(hold_s)
        self.scene = env.unwrapped.scene
        self._task: GoalPoseTask = env.unwrapped.task
        self.goals_taken = 0
        self.goals_refused = 0
        self.goals_reached = 0
        self.messages_refused = 0
        self.teleop_messages = 0
        self.collisions = 0
        self.steps = 0
        self._obs: Any = None
        self._info: dict[str, Any] = {}
        self._driving = False
        self._since: tuple[float, float] = (0.0, 0.0)  # (time s, path length m) the current goal was taken at
        self._teleop: tuple[TeleopRequest, float] | None = None  # the command and the time it holds until
        self._burst = {"messages": 0, "steps": 0, "replaced": 0, "collisions": 0}
        self._warned: set[tuple[int, str]] = set()
        self._touching = False

    @property
    def time_s(self) -> float:
        """Simulated seconds since the reset."""
        return self.steps * self.scene.control_dt

    @property
    def driving(self) -> bool:
        """True while the controller drives to a goal not yet reached."""
        return self._driving

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> dict[str, Any]:
        """Start the session: the world and the robot (seeded; ``options`` as the env's ``reset``
        takes them, e.g. ``{"start": (x, y, yaw)}``), waiting for a goal; returns ``info``."""
        self._obs, self._info = self.env.reset(seed=seed, options=options)
        self.policy.reset(self._info)
        self.steps = 0
        self._driving = False
        self._teleop = None
        return self._info

    def _event(self, text: str) -> None:
        line = f"{self.time_s:8.2f} s  {text}"
        log.info("live control: %s", line)
        if self.on_event is not None:
            self.on_event(line)

    # ------------------------------------------------------------------ messages
    def _take(self, message: ClientMessage) -> None:
        if message.topic not in (GOAL_TOPIC, TELEOP_TOPIC):
            if (message.client, message.topic) not in self._warned:
                self._warned.add((message.client, message.topic))
                self.live.status(f"bulletnav takes goals on {GOAL_TOPIC} (PoseStamped) and teleop on {TELEOP_TOPIC} "
                                 f"(Twist); what client {message.client} publishes on {message.topic} is ignored", "warning")
            return
        try:
            request = (read_goal if message.topic == GOAL_TOPIC else read_twist)(
                message.encoding, message.schema_name, message.data)
        except (ValueError, KeyError, OverflowError, RecursionError) as exc:
            self.messages_refused += 1
            text = f"refused a {message.topic} message of client {message.client} ({message.encoding}): {exc}"
            log.warning("live control: %s", text)
            self.live.status(text, "error")
            self._event(text)
            return
        if isinstance(request, GoalRequest):
            self._goal(message, request)
        else:
            self._steer(message, request)

    def _goal(self, message: ClientMessage, request: GoalRequest) -> None:
        frames = frames_in_map(self.scene)
        shown = request.frame if request.frame in frames else repr(request.frame[:64])  # a client's text, quoted and cut
        where = f"({request.x:.2f}, {request.y:.2f}) in {shown}"
        if request.frame not in frames:
            why = f"its frame {request.frame[:64]!r} is not one of the stream's ({', '.join(frames)})"
            goal = None
        else:
            goal = compose(frames[request.frame], (request.x, request.y, 0.0))[:2]
            why = goal_refusal(self.scene.layout, goal[0], goal[1])
            if request.frame != "map":
                where += f", ({goal[0]:.2f}, {goal[1]:.2f}) in map"
        if why is not None or goal is None:
            self.goals_refused += 1
            text = f"refused goal {where} from client {message.client}: {why}"
            self.live.status(text, "error")
            self._event(text)
            return
        self._task.set_goal(self.scene, goal)
        self._info = {**self._info, "goal": goal}
        self.policy.reset(self._info)  # the controller replans (a navigator's map starts again from the scan)
        self._teleop = None
        self._driving = True
        self._since = (self.time_s, float(self._info.get("path_length", 0.0)))
        self.goals_taken += 1
        self._event(f"goal {where} taken from client {message.client} ({message.encoding}): driving there")

    def _steer(self, message: ClientMessage, request: TeleopRequest) -> None:
        if self._teleop is None:
            self._burst = {"messages": 0, "steps": 0, "replaced": 0, "collisions": 0}
            self._event(f"teleop from client {message.client} ({message.encoding}): v {request.v:.2f} m/s, "
                        f"w {request.w:.2f} rad/s, {self.hold_s:g} s a message, through the shield"
                        + ("; the goal is dropped" if self._driving else ""))
        self._burst["messages"] += 1
        self.teleop_messages += 1
        self._driving = False
        self._teleop = (request, self.time_s + self.hold_s)

    # ------------------------------------------------------------------ stepping
    def _action(self) -> Any:
        if self._teleop is not None and self.time_s < self._teleop[1] - 1e-9:
            request = self._teleop[0]
            (v_lo, v_hi), (w_lo, w_hi) = self.scene.command_limits  # what the robot can do (the shield then decides)
            return self.scene.action_for(min(max(request.v, v_lo), v_hi), min(max(request.w, w_lo), w_hi))
        if self._teleop is not None:
            b = self._burst
            self._event(f"teleop ended: {b['messages']} message(s), {b['steps']} steps, the shield replaced "
                        f"{b['replaced']} command(s), {b['collisions']} steps touching; waiting for a goal")
            self._teleop = None
        if self._driving:
            return self.policy.act(self._obs, self._info)
        return self.scene.action_for(0.0, 0.0)

    def step(self) -> dict[str, Any]:
        """Take in what clients published, then one env step; returns its ``info``."""
        for message in self.live.receive():
            self._take(message)
        action = self._action()
        teleop = self._teleop is not None
        self._obs, _, _, _, self._info = self.env.step(action)
        self.steps += 1
        info = self._info
        touching = bool(info.get("collision"))
        if touching and not self._touching:
            self.collisions += 1
            self._event(f"collision at ({info['pose'][0]:.2f}, {info['pose'][1]:.2f})")
        self._touching = touching
        if teleop:
            self._burst["steps"] += 1
            self._burst["replaced"] += bool(info.get("shield", {}).get("intervened"))
            self._burst["collisions"] += touching
        if self._driving and info.get("is_success"):
            self._driving = False
            self.goals_reached += 1
            goal = info["goal"]
            text = (f"reached goal ({goal[0]:.2f}, {goal[1]:.2f}) in {self.time_s - self._since[0]:.2f} s, "
                    f"{float(info['path_length']) - self._since[1]:.2f} m driven; waiting for the next")
            self.live.status(text, "info")
            self._event(text)
        return info

    def run(self, seconds: float | None = None) -> int:
        """Step until ``seconds`` of wall-clock time have passed (None: until interrupted); returns
        the steps taken."""
        end = None if seconds is None else time.perf_counter() + seconds
        start = self.steps
        while end is None or time.perf_counter() < end:
            self.step()
        return self.steps - start

    def close(self) -> None:
        """Finish the recording (if any) and close the env."""
        self.env.close()

    def abort(self) -> None:
        """Drop the recording (if any) and close the env."""
        self.env.abort()
        self.env.close()


__all__ = ["GOAL_TOPIC", "NO_STEP_LIMIT", "TASK_NAME", "TELEOP_HOLD_S", "TELEOP_TOPIC", "GoalPoseTask", "GoalRequest",
           "LiveControl", "TeleopRequest", "frames_in_map", "goal_refusal", "read_goal", "read_twist"]
