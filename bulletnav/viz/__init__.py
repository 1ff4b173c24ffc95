"""Visualisation: a throttled PyBullet-GUI dashboard, episode videos, trajectory plots and
learning curves.

- :class:`Dashboard` draws the camera preview, lidar rays, planned path and goal in the GUI
  (``render_mode="human"``) without slowing it to a crawl.
- :class:`EpisodeRecorder` writes composed frames (map, camera, depth, status) to MP4 or GIF.
- :class:`TrajectoryLog` and :func:`plot_trajectories` draw episodes' paths over their maps.
- :func:`plot_learning_curve` and :func:`compare_runs` draw training runs' evaluations.

In dynamic worlds the dashboard, the videos and the trajectory plots also draw the moving
obstacles and the events (obstacles added or removed); see :mod:`bulletnav.viz.movers`. In
multi-goal missions they number every goal and show which were reached (plots: in what order
and when; videos and dashboard: ``goals 1/3``); see :mod:`bulletnav.viz.mission`.

All of them read only ``info`` and the env's read-only ``scene`` view.
"""

from bulletnav.viz.compare import REACH_SUCCESS, compare_runs, plot_learning_curve
from bulletnav.viz.dashboard import Dashboard, DashboardConfig, simplify_path
from bulletnav.viz.plots import (
    EpisodeTrajectory,
    MoverTrack,
    TrajectoryLog,
    figure_size,
    plot_trajectories,
    trajectory_figure,
)
from bulletnav.viz.video import FRAME_SIZE, EpisodeRecorder, colourize_depth

__all__ = [
    "FRAME_SIZE",
    "REACH_SUCCESS",
    "Dashboard",
    "DashboardConfig",
    "EpisodeRecorder",
    "EpisodeTrajectory",
    "MoverTrack",
    "TrajectoryLog",
    "colourize_depth",
    "compare_runs",
    "figure_size",
    "plot_learning_curve",
    "plot_trajectories",
    "simplify_path",
    "trajectory_figure",
]
