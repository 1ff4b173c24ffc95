"""Pictures of a fleet episode: a top-down video, a still frame, a path plot and the GUI view.

Every robot keeps one colour everywhere, :func:`~bulletnav.viz.fleet_robots.robot_colour` (a
fixed qualitative palette of 16, :data:`~bulletnav.viz.fleet_robots.ROBOT_PALETTE`, in robot
order), and every picture shows its current errand. The parts, one module each:

- :mod:`bulletnav.viz.fleet_robots`: the palette, the agents in robot order;
- :mod:`bulletnav.viz.fleet_frames`: the video frames (:class:`~bulletnav.viz.fleet_frames.FleetFrames`);
- :mod:`bulletnav.viz.fleet_paths`: the path plot (:func:`~bulletnav.viz.fleet_paths.plot_fleet`);
- :mod:`bulletnav.viz.fleet_gui`: the GUI view (:class:`~bulletnav.viz.fleet_gui.FleetDashboard`);
- here, :class:`FleetVisuals`: :func:`bulletnav.fleet.metrics.run_fleet_episodes`' ``on_step``
  hook, which writes the video, the still frame and the plot.

Everything reads only the agents' ``infos``, the env's ``stations`` and the read-only
:class:`~bulletnav.fleet.view.FleetView`: recording leaves the episodes unchanged.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path
from typing import Any

from bulletnav.files import save_image
from bulletnav.viz.fleet_frames import FleetFrames
from bulletnav.viz.fleet_paths import FleetTrackLog, plot_fleet
from bulletnav.viz.fleet_robots import fleet_view
from bulletnav.viz.video import VideoWriter

log = logging.getLogger(__name__)


class FleetVisuals:
    """Video, still frame and path plot of one episode of :func:`~bulletnav.fleet.metrics.run_fleet_episodes`,
    fed by its ``on_step`` hook (call the object with ``(env, infos)`` after the reset and every step).

    Args:
        video: ``.mp4`` or ``.gif`` of the episode, one frame per ``stride`` control steps (None: none).
        frame: PNG of the frame at ``frame_at_s`` (None: none).
        frame_at_s: simulated seconds into the episode of the still frame (None: half the duration).
        plot: PNG of every robot's path over the episode (None: none).
        episode: which episode of the run (0: the first).
        title: the strip's and the plot's title (e.g. the controller).
        stride: control steps per video frame (>= 1).
        fps: video frames per second (None: the control rate over ``stride``, real time).
    """

    def __init__(self, video: str | Path | None = None, frame: str | Path | None = None,
                 frame_at_s: float | None = None, plot: str | Path | None = None, episode: int = 0,
                 title: str = "", stride: int = 1, fps: float | None = None) -> None:
        if stride < 1:
            raise ValueError(f"stride must be >= 1, got {stride}")
        self.video_path = Path(video) if video else None
        self.frame_path = Path(frame) if frame else None
        self.frame_at_s = frame_at_s
        self.plot_path = Path(plot) if plot else None
        self.episode = episode
        self.title = title
        self.stride = stride
        self.fps = fps
        self.frames = FleetFrames(title)
        self.log = FleetTrackLog()
        self.video: VideoWriter | None = None
        self.frame_written_at: float | None = None
        """Simulated time (s) of the still frame written, None before."""
        self._seen = -1
        self._env: Any = None
        self._fleet: Any = None
        self._stamp: int | None = None
        self._steps = 0
        self._active = False
        self._frame_due = math.inf
        self._done = False

    @property
    def frames_written(self) -> int:
        return self.video.frames_written if self.video is not None else 0

    def __call__(self, env: Any, infos: dict[str, Any]) -> None:
        if self._env is not env:
            self._env, self._fleet = env, fleet_view(env)
        stamp = self._fleet.episode
        if stamp != self._stamp:  # a reset
            self._stamp = stamp
            self._seen += 1
            if self._active:
                self._finish_episode()
            self._active = self._seen == self.episode
            if self._active:
                self._begin(env, infos)
            return
        if not self._active:
            return
        self._steps += 1
        self.frames.update(infos)
        if self.plot_path is not None:
            self.log.update(infos)
        t = self._fleet.time_s
        frame = None
        if self.video is not None and self._steps % self.stride == 0:
            frame = self.frames.compose()
            self.video.append(frame)
        if self.frame_path is not None and self.frame_written_at is None and t >= self._frame_due - 1e-9:
            save_image(frame if frame is not None else self.frames.compose(), self.frame_path, optimize=True)
            self.frame_written_at = t
        if not env.agents:
            self._finish_episode()

    def _begin(self, env: Any, infos: dict[str, Any]) -> None:
        fleet = self._fleet
        duration = float(env.fleet_config.duration_s)
        self._steps = 0
        self.frames.begin(env, infos, f"episode {self.episode}")
        if self.plot_path is not None:
            self.log.begin(env, infos)
        self._frame_due = duration / 2 if self.frame_at_s is None else float(self.frame_at_s)
        if self.video_path is not None:
            fps = self.fps or max(1.0, 1.0 / fleet.control_dt / self.stride)
            self.video = VideoWriter(self.video_path, fps=fps)
            self.video.append(self.frames.compose())
        if self.frame_path is not None and self._frame_due <= 0.0:
            save_image(self.frames.compose(), self.frame_path, optimize=True)
            self.frame_written_at = 0.0

    def _finish_episode(self) -> None:
        self._active = False
        self._done = True

    def close(self, ok: bool = True) -> list[str]:
        """Finish the video and write the plot; with ``ok`` off (the run failed) drop the video and
        write nothing. Returns one line per file written."""
        written: list[str] = []
        if not ok:
            if self.video is not None:
                self.video.abort()
            return written
        if self.video is not None:
            self.video.close()
            written.append(f"video:  {self.video_path} (episode {self.episode}, {self.video.frames_written} frames)")
        if self.frame_path is not None:
            if self.frame_written_at is None:
                log.warning("no still frame written: episode %d ended before %.1f s", self.episode, self._frame_due)
            else:
                written.append(f"frame:  {self.frame_path} (episode {self.episode} at {self.frame_written_at:.1f} s)")
        if self.plot_path is not None and self.log.track is not None:
            title = f"{self.title}, episode {self.episode}" if self.title else f"episode {self.episode}"
            plot_fleet(self.log.track, self.plot_path, title=title)
            written.append(f"plot:   {self.plot_path} (episode {self.episode})")
        return written


__all__ = ["FleetVisuals"]
