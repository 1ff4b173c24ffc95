"""A fleet's episodes as ROS 2 messages: ``bulletnav fleet --record PATH.mcap``.

:class:`FleetMcapRecorder` is :func:`~bulletnav.fleet.metrics.run_fleet_episodes`' ``on_step``
hook (it only reads): every robot gets its own namespace, as a multi-robot ROS 2 system names
them: ``/robot_<i>/scan``, ``/robot_<i>/odom``, ``/robot_<i>/imu``, ``/robot_<i>/goal_pose``,
in the frames ``robot_<i>/odom``, ``robot_<i>/base_link`` and ``robot_<i>/laser``, their transforms
on the global ``/tf`` (``map -> robot_<i>/odom -> robot_<i>/base_link``) and ``/tf_static`` (the
mounts), so one TF tree holds the fleet; ``/clock``, ``/movers`` and ``/map_truth`` are the fleet's. The messages
are those of :mod:`bulletnav.ros.record` (one robot's builder, reused), and episodes follow each
other on one time line, each an ``episode`` metadata record (seed, stamps, errands, legs and
collisions per kind). Commands are not recorded (the hook sees what the robots did, not what
they were told).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from bulletnav.ros.outputs import McapFile, Ros2Outputs
from bulletnav.ros.record import goal_message, movers_message, robot_messages, stamp, static_mounts, truth_map_message


class FleetMcapRecorder:
    """``on_step(env, infos)`` hook writing a fleet's episodes into ``path`` and/or streaming them
    to ``live`` (see the module docstring).

    Args:
        path: the ``.mcap`` file; None: no recording (``live`` only).
        overwrite: replace an existing file (else refused).
        gap_s: seconds of the time line between one episode's end and the next one's start.
        live: a :class:`~bulletnav.ros.live.LiveServer` to stream to (paced at its speed); the
            caller starts and stops it.
    """

    def __init__(self, path: str | Path | None, overwrite: bool = False, gap_s: float = 1.0, live: Any = None) -> None:
        self.out = Ros2Outputs(None if path is None else McapFile(path, overwrite), live)
        self.path = None if path is None else Path(path)
        self.gap_s = float(gap_s)
        self.episodes = 0
        """Episodes recorded so far."""
        self._start_ns = 0
        self._last_ns = 0
        self._goals: list[tuple[float, float] | None] = []
        self._last_infos: dict[str, dict[str, Any]] | None = None
        self._view: Any = None
        self._view_env: Any = None

    def __call__(self, env: Any, infos: dict[str, dict[str, Any]]) -> None:
        from bulletnav.fleet.view import FleetView

        if self._view is None or self._view_env is not env:
            self._view, self._view_env = FleetView(env), env
        view = self._view
        agents = list(env.possible_agents)
        time_s = float(next(iter(infos.values()))["time_s"]) if infos else 0.0
        if time_s == 0.0:
            self._begin(view, agents, infos)
            return
        ns = self._start_ns + int(round(time_s * 1e9))
        self._last_ns = ns
        t = stamp(ns)
        out = self.out
        if out.wants("/clock"):
            out.write("/clock", {"clock": t}, ns)
        dt = view.control_dt
        for i, agent in enumerate(agents):
            robot_messages(out.write, view.robot(i), ns, dt, prefix=f"robot_{i}", wants=out.wants)
            self._goal(i, infos.get(agent, {}), ns)
        if view.dynamic and out.wants("/movers"):
            out.write("/movers", movers_message(t, view.movers), ns)
        self._last_infos = infos
        out.pace(ns)

    def _begin(self, view: Any, agents: list[str], infos: dict[str, dict[str, Any]]) -> None:
        self._end()
        ns = self._start_ns = (self._last_ns + int(round(self.gap_s * 1e9))) if self.episodes else 0
        self._last_ns = ns
        mounts = []
        for i in range(len(agents)):
            mounts += static_mounts(ns, view.robot(i).geometry, prefix=f"robot_{i}")
        self.out.pace(ns)
        self.out.write("/tf_static", {"transforms": mounts}, ns)
        self.out.write("/map_truth", truth_map_message(ns, view), ns)
        self._goals = [None] * len(agents)
        for i, agent in enumerate(agents):
            self._goal(i, infos.get(agent, {}), ns)
        self._episode = {"index": self.episodes, "start_ns": ns, "robots": len(agents)}
        self._last_infos = infos
        self.episodes += 1

    def _goal(self, i: int, info: dict[str, Any], ns: int) -> None:
        goal = info.get("goal")
        if goal is None:
            return
        goal = (float(goal[0]), float(goal[1]))
        if goal != self._goals[i]:
            self._goals[i] = goal
            self.out.write(f"/robot_{i}/goal_pose", goal_message(ns, goal), ns)

    def _end(self) -> None:
        if not self.episodes or self._last_infos is None:
            return
        infos = self._last_infos.values()
        data = {**self._episode, "end_ns": self._last_ns,
                "errands": sum(int(i.get("errands_completed", 0)) for i in infos),
                "legs": sum(int(i.get("legs_completed", 0)) for i in infos)}
        for kind in ("collisions_robot", "collisions_static", "collisions_mover", "collisions_person"):
            data[kind] = sum(int(i.get(kind, 0)) for i in infos)
        self.out.add_metadata("episode", {k: str(v) for k, v in data.items()})
        self._last_infos = None

    def close(self, ok: bool = True) -> list[str]:
        """Finish the file (``ok``) or drop it; the lines the CLI prints."""
        if not ok:
            self.out.abort()
            return []
        self._end()
        self.out.close()
        if self.path is None:
            return []
        return [f"recording: {self.path} (ROS 2 MCAP, {self.episodes} episodes, one namespace per robot)"]


__all__ = ["FleetMcapRecorder"]
