"""Visualisation: a throttled PyBullet-GUI dashboard, episode videos and trajectory plots.

- :class:`Dashboard` draws the camera preview, lidar rays, planned path and goal in the GUI
  (``render_mode="human"``) without slowing it to a crawl.
- :class:`EpisodeRecorder` writes composed frames (map, camera, depth, status) to MP4 or GIF.
- :class:`TrajectoryLog` and :func:`plot_trajectories` draw episodes' paths over their maps.
"""

from bulletnav.viz.dashboard import Dashboard, DashboardConfig, compare_gui_fps, gui_fps, simplify_path
from bulletnav.viz.plots import EpisodeTrajectory, TrajectoryLog, figure_size, plot_trajectories
from bulletnav.viz.video import FRAME_SIZE, EpisodeRecorder, colourize_depth, with_reset_hooks

__all__ = [
    "FRAME_SIZE",
    "Dashboard",
    "DashboardConfig",
    "EpisodeRecorder",
    "EpisodeTrajectory",
    "TrajectoryLog",
    "colourize_depth",
    "compare_gui_fps",
    "figure_size",
    "gui_fps",
    "plot_trajectories",
    "simplify_path",
    "with_reset_hooks",
]
