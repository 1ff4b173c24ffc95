"""``bulletnav replay PATH.mcap``: a recorded episode drawn from the recording alone.

:func:`replay` reads a file written by :class:`~bulletnav.ros.record.McapRecorder` (the layout,
start and goals from each episode's ``episode-<k>.json`` attachment; the robot's pose from
``/tf``; ``/scan``, ``/goal_pose``, ``/plan``, ``/movers``, ``/reward`` per step; the outcome
from the episode's metadata) and feeds :class:`~bulletnav.viz.video.EpisodeRecorder` and the
path plot the same read-only scene interface the live env gives them: the frames are the live
video's, but for the camera panel ("camera disabled": images are not recorded yet) and the
pallet events (not recorded yet). Nothing in the
file is executed: the attachment is JSON, parsed by the layout loader that checks every field.
"""

from __future__ import annotations

import json
import math
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.errors import BulletnavError
from bulletnav.ros.record import compose, message_yaw


@dataclass(frozen=True)
class _Mover:
    kind: str
    pose: tuple[float, float, float]
    size: tuple[float, float, float]
    path: tuple = ()
    yielding: bool = False
    speed: float = 0.0


@dataclass(frozen=True)
class _Geometry:
    radius: float


@dataclass(frozen=True)
class _LidarConfig:
    max_range: float


class _Lidar:
    """The recorded scan as the drawing code reads a lidar."""

    def __init__(self, scene: ReplayScene) -> None:
        self.scene = scene
        self.config = _LidarConfig(5.0)
        self.ranges = np.zeros(0)
        self.angles = np.zeros(0)

    def read(self) -> np.ndarray:
        return self.ranges

    def hit_points(self, ranges: np.ndarray) -> np.ndarray:
        x, y, yaw = self.scene.pose
        mx, my = self.scene.mount
        ox, oy = x + mx * math.cos(yaw) - my * math.sin(yaw), y + mx * math.sin(yaw) + my * math.cos(yaw)
        a = self.angles + yaw
        r = np.asarray(ranges, dtype=np.float64)
        return np.stack([ox + r * np.cos(a), oy + r * np.sin(a)], axis=1)


@dataclass(frozen=True)
class _Sensors:
    lidar: _Lidar
    camera: None = None


class ReplayScene:
    """The read-only scene interface (``env.unwrapped.scene``) of a recorded episode's step."""

    def __init__(self, episode: dict[str, Any], index: int) -> None:
        from bulletnav.sim.layout import parse_layout

        self.episode = index
        self.layout = parse_layout(episode["layout"], where=f"episode {index} layout")
        self.start = tuple(float(v) for v in episode["start"])
        self.goals = tuple((float(g[0]), float(g[1])) for g in episode["goals"])
        self.goal = self.goals[0] if self.goals else None
        self.goal_radius = float(episode["goal_radius"])
        self.geometry = _Geometry(float(episode["robot_radius"]))
        self.mount = tuple(float(v) for v in episode.get("lidar_mount", (0.0, 0.0, 0.0)))[:2]
        self.control_dt = float(episode["control_dt"])
        self.sensors = _Sensors(_Lidar(self))
        self.pose: tuple[float, float, float] = self.start  # type: ignore[assignment]
        self.steps = 0
        self.routes = [tuple((float(x), float(y)) for x, y in r) for r in episode.get("mover_routes", [])]
        first = episode["steps"][0] if episode["steps"] else {}
        self.dynamic = bool(first.get("dynamic", False))
        self.movers: tuple[_Mover, ...] = self.with_routes(first.get("movers", ()))
        self.events: tuple = ()

    def with_routes(self, movers: tuple[_Mover, ...]) -> tuple[_Mover, ...]:
        """``movers`` (in marker order) with the routes the episode's attachment recorded."""
        return tuple(_Mover(m.kind, m.pose, m.size, self.routes[i] if i < len(self.routes) else ())
                     for i, m in enumerate(movers))


class _Spec:
    def __init__(self, max_episode_steps: int | None) -> None:
        self.max_episode_steps = max_episode_steps


class _Env:
    """What the drawing code reads of an env: ``unwrapped.scene`` and ``spec``."""

    def __init__(self, scene: ReplayScene, max_episode_steps: int | None) -> None:
        self.scene = scene
        self.unwrapped = self
        self.spec = _Spec(max_episode_steps)


def read_recording(path: str | Path) -> list[dict[str, Any]]:
    """The episodes of a bulletnav recording: each a dict of its attachment record, metadata
    and per-step messages (``steps``: list of dicts with ``pose``, ``ranges``, ``angles``,
    ``range_max``, ``goal``, ``plan``, ``movers``, ``reward``).

    Raises:
        BulletnavError: missing, unreadable or truncated file, or not a bulletnav recording.
    """
    from mcap.exceptions import McapError
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    path = Path(path)
    if not path.is_file():
        raise BulletnavError(f"{path}: no such recording")
    episodes: list[dict[str, Any]] = []
    by_time: dict[int, dict[str, Any]] = defaultdict(dict)
    try:
        with open(path, "rb") as f:
            reader = make_reader(f, decoder_factories=[DecoderFactory()])
            for att in reader.iter_attachments():
                if att.name.startswith("episode-") and att.media_type == "application/json":
                    episodes.append({**json.loads(att.data), "start_ns": att.log_time})
            meta = [dict(m.metadata) for m in reader.iter_metadata() if m.name == "episode"]
            topics = ["/tf", "/scan", "/goal_pose", "/plan", "/movers", "/reward"]
            for _, channel, message, msg in reader.iter_decoded_messages(topics=topics, log_time_order=True):
                by_time[message.log_time][channel.topic] = msg
    except McapError as exc:
        raise BulletnavError(f"{path}: not a readable MCAP file ({exc})") from exc
    except (EOFError, ValueError, KeyError, IndexError, json.JSONDecodeError) as exc:
        raise BulletnavError(f"{path}: not a readable recording ({type(exc).__name__}: {exc})") from exc
    if not episodes:
        raise BulletnavError(f"{path}: no episode-<k>.json attachment: not a recording bulletnav wrote "
                             "(`bulletnav map` reads any bag)")
    episodes.sort(key=lambda e: e["start_ns"])
    meta.sort(key=lambda m: int(m.get("start_ns", 0)))
    for k, ep in enumerate(episodes):
        ep["meta"] = meta[k] if k < len(meta) else {}
        end = int(ep["meta"].get("end_ns", 2**62))
        nxt = episodes[k + 1]["start_ns"] if k + 1 < len(episodes) else 2**63
        steps = []
        goal, plan = None, None
        for t in sorted(x for x in by_time if ep["start_ns"] <= x <= min(end, nxt - 1)):
            msgs = by_time[t]
            if "/goal_pose" in msgs:
                p = msgs["/goal_pose"].pose.position
                goal = (float(p.x), float(p.y))
            if "/plan" in msgs:
                plan = [(float(ps.pose.position.x), float(ps.pose.position.y)) for ps in msgs["/plan"].poses]
            if "/tf" in msgs and "/scan" in msgs:
                steps.append(_step(path, t, msgs, goal, plan))
        ep["steps"] = steps
    return episodes


def _step(path: Path, t: int, msgs: dict[str, Any], goal: tuple[float, float] | None,
          plan: list[tuple[float, float]] | None) -> dict[str, Any]:
    """One step of a recording from its messages at ``t`` ns (``/tf`` and ``/scan``, the movers
    and the reward where present) and the last goal and plan.

    Raises:
        BulletnavError: the ``/tf`` lacks the map -> odom -> base_link chain.
    """
    tf = {(tr.header.frame_id, tr.child_frame_id): tr.transform for tr in msgs["/tf"].transforms}
    links = [tf.get(("map", "odom")), tf.get(("odom", "base_link"))]
    if any(x is None for x in links):
        raise BulletnavError(f"{path}: /tf at {t} ns lacks map -> odom -> base_link")
    pose = (0.0, 0.0, 0.0)
    for tr in links:
        pose = compose(pose, (float(tr.translation.x), float(tr.translation.y), message_yaw(tr.rotation)))
    scan = msgs["/scan"]
    n = len(scan.ranges)
    movers = []
    if "/movers" in msgs:
        for m in msgs["/movers"].markers:
            if m.action != 0:
                continue
            movers.append(_Mover(m.ns, (float(m.pose.position.x), float(m.pose.position.y), message_yaw(m.pose.orientation)),
                                 (float(m.scale.x), float(m.scale.y), float(m.scale.z))))
    return {"pose": pose, "ranges": np.asarray(scan.ranges, dtype=np.float64),
            "angles": float(scan.angle_min) + float(scan.angle_increment) * np.arange(n),
            "range_max": float(scan.range_max), "goal": goal, "plan": plan,
            "movers": tuple(movers), "dynamic": "/movers" in msgs,
            "reward": float(msgs["/reward"].data) if "/reward" in msgs else 0.0}


def frame_step(episode: dict[str, Any], at_s: float | None) -> int:
    """The step of ``episode`` (one of :func:`read_recording`'s) whose frame shows simulated time
    ``at_s`` (0: the reset frame; the nearest step, ``at_s / control_dt`` rounded); None: the
    middle step.

    Raises:
        ConfigError: ``at_s`` is after the episode's end or negative.
    """
    from bulletnav.errors import ConfigError

    steps = len(episode["steps"])
    dt = float(episode["control_dt"])
    if at_s is None:
        return steps // 2
    if not 0.0 <= at_s <= steps * dt + 0.5 * dt:
        raise ConfigError(f"a frame at {at_s:g} s is outside the first episode (0 to {steps * dt:.2f} s, {steps} steps)")
    return min(int(round(at_s / dt)), steps)


def replay(path: str | Path, video: str | Path | None = None, plot: str | Path | None = None,
           stride: int = 1, frame: str | Path | None = None, frame_at_s: float | None = None) -> dict[str, Any]:
    """Draw every episode of the recording ``path``: the live video's frames into ``video``
    (.mp4 or .gif), the path plot into ``plot`` (.png) and, with ``frame`` (a PNG), the first
    episode's frame at ``frame_at_s`` simulated seconds (:func:`frame_step`; None: its middle),
    exactly as composed (``video`` must be given with ``frame``: the frames are drawn for it).
    Returns a summary (``frame_step``, ``frame_time_s``: where the frame was taken).

    Raises:
        ConfigError: ``frame_at_s`` is outside the first episode.
    """
    from bulletnav.viz.video import EpisodeRecorder

    if frame is not None and not video:
        raise ValueError("replay(frame=...) draws the frame for the video: give video too")
    episodes = read_recording(path)
    at_step = frame_step(episodes[0], frame_at_s) if frame is not None else -1
    recorder = EpisodeRecorder(video, stride=stride) if video else None
    tracks = []
    taken = None
    ok = False
    try:
        for k, ep in enumerate(episodes):
            scene = ReplayScene(ep, k)
            env = _Env(scene, ep.get("max_episode_steps"))
            steps, meta = ep["steps"], ep["meta"]
            if recorder is not None:
                recorder.on_reset(env, {})
                if k == 0 and at_step == 0:
                    taken = recorder.last_frame
            track = [scene.start[:2]]
            for i, st in enumerate(steps, 1):
                scene.steps = i
                scene.pose = st["pose"]
                if st["goal"] is not None:
                    scene.goal = st["goal"]
                scene.movers, scene.dynamic = scene.with_routes(st["movers"]), st["dynamic"]
                lidar = scene.sensors.lidar
                lidar.ranges, lidar.angles, lidar.config = st["ranges"], st["angles"], _LidarConfig(st["range_max"])
                last = i == len(steps)
                info = {"reward_recorded": st["reward"],
                        "distance_to_goal": math.dist(st["pose"][:2], scene.goal) if scene.goal else math.nan,
                        "is_success": last and meta.get("is_success") == "True",
                        "collision": last and meta.get("collision") == "True"}
                track.append(st["pose"][:2])
                if recorder is not None:
                    recorder.on_step(env, info, path=st["plan"])
                    if k == 0 and i == at_step:
                        taken = recorder.compose(env, path=st["plan"]) if i % stride else recorder.last_frame
            tracks.append({"episode": k, "layout": scene.layout, "start": scene.start, "goal": scene.goal,
                           "path": track, "outcome": meta.get("end_reason", "")})
        ok = True
    finally:
        if recorder is not None:
            recorder.close() if ok else recorder.abort()
    if plot:
        _plot(tracks, plot)
    summary = {"recording": str(path), "episodes": len(episodes), "steps": [len(e["steps"]) for e in episodes],
               "outcomes": [e["meta"].get("end_reason") for e in episodes], "video": str(video) if video else None,
               "frames": recorder.frames_written if recorder is not None else 0, "plot": str(plot) if plot else None}
    if frame is not None and taken is not None:
        from bulletnav.files import save_image

        save_image(taken, frame)  # a PNG whatever the name's suffix
        summary.update(frame=str(frame), frame_step=at_step, frame_time_s=at_step * float(episodes[0]["control_dt"]))
    return summary


def _plot(tracks: list[dict[str, Any]], out: str | Path) -> None:
    """Every episode's path over its map, one panel each, written beside ``out`` and renamed."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bulletnav.viz.video import MapView

    n = len(tracks)
    cols = min(n, 3)
    rows = -(-n // cols)
    fig, axes = plt.subplots(rows, cols, figsize=(5 * cols, 5 * rows), squeeze=False)
    for ax, tr in zip(axes.flat, tracks):
        view = MapView(tr["layout"])
        ax.imshow(np.asarray(view.render_static()))
        px = view.to_px(tr["path"])
        ax.plot([p[0] for p in px], [p[1] for p in px], color="tab:blue", lw=1.5)
        (sx, sy), = view.to_px(tr["start"][:2])
        ax.plot([sx], [sy], "s", color="tab:green", ms=7)
        if tr["goal"] is not None:
            (gx, gy), = view.to_px(tr["goal"])
            ax.plot([gx], [gy], "*", color="tab:red", ms=12)
        ax.set_title(f"episode {tr['episode'] + 1}: {tr['outcome']}")
        ax.axis("off")
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    from bulletnav.files import save_figure

    try:
        fig.tight_layout()
        save_figure(fig, out, format="png", dpi=100)
    finally:
        plt.close(fig)




def panel_view(path: str | Path, out: str | Path, at_s: float | None = None, episode: int = 0, span_m: float = 14.0) -> dict:
    """What the shipped Foxglove layout's 3D panel (``bulletnav/assets/foxglove_layout.json``)
    shows at ``at_s`` simulated seconds into ``episode`` (default: its middle), drawn top-down from the recording's own messages: the
    true map (``/map_truth``) under the lidar map (``/map``, the last one before that time), the
    scan placed through ``/tf`` and ``/tf_static``, the plan, the goal, the movers' markers and the
    robot with its trajectory, in a ``span_m`` window that follows the robot as the panel does
    (``followTf: base_link``, ``follow-position``). For when Foxglove itself cannot be run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from bulletnav.files import save_figure

    episodes = read_recording(path)
    if not 0 <= episode < len(episodes):
        raise BulletnavError(f"{path}: no episode {episode} (it holds {len(episodes)})")
    ep = episodes[episode]
    steps = ep["steps"]
    if not steps:
        raise BulletnavError(f"{path}: episode {episode} has no steps")
    dt = float(ep["control_dt"])
    k = len(steps) // 2 if at_s is None else min(max(int(round(at_s / dt)) - 1, 0), len(steps) - 1)
    t_ns = ep["start_ns"] + int(round((k + 1) * dt * 1e9))
    maps = _maps_until(path, ep["start_ns"], t_ns)
    st = steps[k]
    x, y, yaw = st["pose"]
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.set_facecolor("#1e1f24")
    _draw_maps(ax, maps)
    _draw_step(ax, ep, steps, k)
    ax.set_xlim(x - span_m / 2, x + span_m / 2)
    ax.set_ylim(y - span_m / 2, y + span_m / 2)
    ax.set_aspect("equal")
    ax.set_xlabel("map x (m)")
    ax.set_ylabel("map y (m)")
    ax.set_title(f"3D panel, top-down, t = {(k + 1) * dt:.2f} s (episode {episode + 1})")
    ax.legend(loc="upper right", fontsize=8, facecolor="#2a2c33", labelcolor="white")
    try:
        fig.tight_layout()
        save_figure(fig, out, format="png", dpi=100)
    finally:
        plt.close(fig)
    return {"episode": episode, "step": k + 1, "time_s": (k + 1) * dt, "out": str(out)}


def _draw_maps(ax: Any, maps: dict[str, tuple[np.ndarray, float, tuple[float, float]]]) -> None:
    """The true map under the lidar map (its seen-free cells tinted), as the panel draws them."""
    import matplotlib

    for name, colour, alpha in (("/map_truth", "#8a8f99", 0.9), ("/map", "#e0e0e0", 0.5)):
        grid = maps.get(name)
        if grid is None:
            continue
        cells, res, (ox, oy) = grid
        rgba = np.zeros((*cells.shape, 4))
        occ = cells == 100
        rgba[occ] = matplotlib.colors.to_rgba(colour, alpha)
        if name == "/map":
            rgba[cells == 0] = (0.35, 0.45, 0.6, 0.25)  # seen free
        ax.imshow(rgba, origin="lower", extent=(ox, ox + cells.shape[1] * res, oy, oy + cells.shape[0] * res),
                  interpolation="nearest", zorder=1 if name == "/map_truth" else 2)


def _draw_step(ax: Any, ep: dict[str, Any], steps: list[dict[str, Any]], k: int) -> None:
    """Step ``k`` of the episode: the trajectory so far, the plan, the scan through the lidar
    mount, the movers' markers, the goal and the robot."""
    from matplotlib.patches import Circle, Polygon

    from bulletnav.sim.movers import box_corners

    st = steps[k]
    x, y, yaw = st["pose"]
    traj = np.array([s["pose"][:2] for s in steps[: k + 1]])
    ax.plot(traj[:, 0], traj[:, 1], color="#33b5ff", lw=1.5, zorder=3, label="trajectory (/tf)")
    if st["plan"]:
        plan = np.array(st["plan"])
        ax.plot(plan[:, 0], plan[:, 1], color="#ff66ff", lw=2, zorder=4, label="/plan")
    mx, my = ep.get("lidar_mount", (0.0, 0.0))[:2]
    lx, ly = x + mx * math.cos(yaw) - my * math.sin(yaw), y + mx * math.sin(yaw) + my * math.cos(yaw)
    r = st["ranges"]
    hit = np.isfinite(r) & (r < st["range_max"] - 1e-6)
    a = st["angles"][hit] + yaw
    ax.scatter(lx + r[hit] * np.cos(a), ly + r[hit] * np.sin(a), s=12, color="#ff4d4d", zorder=5, label="/scan")
    for m in st["movers"]:
        if m.kind == "worker":
            ax.add_patch(Circle(m.pose[:2], m.size[0] / 2, color="#3380ff", zorder=5))
        else:
            ax.add_patch(Polygon(box_corners(m.pose[:2], m.pose[2], m.size[0], m.size[1]), color="#ff9900", zorder=5))
    if st["goal"] is not None:
        ax.plot(*st["goal"], marker="*", ms=16, color="#33cc66", zorder=6, ls="none", label="/goal_pose")
    tri = [(x + 0.3 * math.cos(yaw), y + 0.3 * math.sin(yaw)), (x + 0.18 * math.cos(yaw + 2.4), y + 0.18 * math.sin(yaw + 2.4)),
           (x + 0.18 * math.cos(yaw - 2.4), y + 0.18 * math.sin(yaw - 2.4))]
    ax.add_patch(Polygon(tri, color="white", zorder=7))


def _maps_until(path: str | Path, start_ns: int, t_ns: int) -> dict[str, tuple[np.ndarray, float, tuple[float, float]]]:
    """The last ``/map_truth`` and ``/map`` at or before ``t_ns`` from ``start_ns`` on, as (cells
    [row = y, column = x], resolution, origin corner)."""
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out = {}
    with open(path, "rb") as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _message, msg in reader.iter_decoded_messages(topics=["/map_truth", "/map"], starting_at=start_ns,
                                                                      ending_at=t_ns, log_time_order=True):
            info = msg.info
            cells = np.asarray(msg.data, dtype=np.int16).reshape(info.height, info.width)
            out[channel.topic] = (cells, float(info.resolution), (float(info.origin.position.x), float(info.origin.position.y)))
    return out


__all__ = ["ReplayScene", "frame_step", "panel_view", "read_recording", "replay"]
