"""BARN's score and summary, as the BARN challenge's own scripts compute them.

Source: github.com/Daffan/the-barn-challenge (MIT license), commit bf5a226 (2026-03-04):
``run.py`` lines 13-27 and 172-187 (the start and goal, the grid-cell-to-metre conversion,
the reference path's length, the score) and ``report_test.py`` lines 8-85 (the summary over
an out file). This module is the code base's one definition of the score:
:func:`barn_metric` (the benchmark's ``barn_score`` and BARN summaries,
:mod:`bulletnav.benchmark.metrics` and :mod:`bulletnav.benchmark.barn`, call it).
``t_opt`` is the reference path's length over 2 m/s; BARN clips the time to
[2 t_opt, 8 t_opt] (before 2026-03-04 its lower clip was 4 t_opt: ``low=4``).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass

import numpy as np

from bulletnav.errors import BulletnavError

CYLINDER_RADIUS_M = 0.075
"""Radius of every BARN obstacle cylinder (m): ``RADIUS`` in run.py line 20."""
CELL_M = 2 * CYLINDER_RADIUS_M
"""Side of one cell of BARN's grid (m): a cylinder's diameter, run.py lines 24-25."""
PATH_ORIGIN_M = (-CYLINDER_RADIUS_M - 30 * CELL_M, CYLINDER_RADIUS_M + 5)
"""World position (m) of path cell (0, 0): run.py's ``r_shift`` and ``c_shift`` (lines 21-22)."""
INFO_KEYS = ("world_idx", "barn_time_s", "barn_metric")
"""What ``bulletnav/BARN-v0``'s last ``info`` of an episode adds for scoring: the BARN world,
BARN's clock (s) and the env's score of the episode (t_opt from run.py's start)."""
START = (-2.25, 3.0, 1.57)
"""Start pose (x m, y m, yaw rad) run.py sets for the static worlds 0-299 (line 46)."""
GOAL_OFFSET = (0.0, 10.0)
"""The goal relative to the start (m), run.py line 47."""
REPORT_START = (-2.0, 3.0)
"""The start report_test.py measures reference paths from (line 8): run.py's start until 2024-02-04."""
GOAL_RADIUS_M = 1.0
"""Success: within this distance (m) of the goal (run.py line 145)."""
CLOCK_START_M = 0.1
"""BARN's clock starts when the robot is first this far (m) from its start (run.py line 134)."""
TIME_LIMIT_S = 100.0
"""An episode is a time-out at this clock time (s), run.py lines 145 and 165."""
REFERENCE_SPEED = 2.0
"""t_opt = reference-path length / this speed (m/s): run.py line 185, the Jackal's top speed."""
TEST_WORLDS = tuple(range(0, 300, 6))
"""The 50 test worlds whose rows report_test.py summarises (line 42): 0, 6, ..., 294."""


class BarnFileError(BulletnavError, ValueError):
    """A BARN data or out file is malformed (the message names the file and line)."""


def path_cells_to_metres(cells: np.ndarray) -> np.ndarray:
    """BARN's path grid cells (k x 2 integers, as in ``path_N.npy``) as world points (k x 2, m)."""
    cells = np.asarray(cells, dtype=float).reshape(-1, 2)
    return cells * CELL_M + np.asarray(PATH_ORIGIN_M)


def reference_path_length(cells: np.ndarray, start: Sequence[float] = START[:2]) -> float:
    """Length (m) of a world's reference path with the legs from ``start`` and to its goal
    (``start`` + :data:`GOAL_OFFSET`), summed segment by segment as run.py lines 176-182 do."""
    sx, sy = float(start[0]), float(start[1])
    points = np.vstack([[sx, sy], path_cells_to_metres(cells), [sx + GOAL_OFFSET[0], sy + GOAL_OFFSET[1]]])
    # BARN's compute_distance, term for term (run.py line 17), so sums match to the last bit
    return float(sum(((b[0] - a[0]) ** 2 + (b[1] - a[1]) ** 2) ** 0.5 for a, b in zip(points[:-1], points[1:], strict=False)))


def optimal_time(cells: np.ndarray, start: Sequence[float] = START[:2]) -> float:
    """t_opt (s): the reference path's length (:func:`reference_path_length`) over 2 m/s."""
    return reference_path_length(cells, start) / REFERENCE_SPEED


def barn_metric(success: bool, time_s: float, t_opt: float, low: float = 2.0, high: float = 8.0) -> float:
    """BARN's score of one episode: success x t_opt / clip(time, low t_opt, high t_opt).

    Args:
        success: whether the episode reached the goal (no collision, no time-out).
        time_s: BARN's clock at the episode's end (s).
        t_opt: the world's optimal time (s), see :func:`optimal_time`.
        low: lower clip as a multiple of t_opt (BARN's: 2; 4 before 2026-03-04).
        high: upper clip as a multiple of t_opt (BARN's: 8).
    """
    if not success:
        return 0.0
    return float(t_opt / min(max(float(time_s), low * t_opt), high * t_opt))


@dataclass(frozen=True)
class OutRow:
    """One line of a BARN out file (run.py line 191): ``world success collided timeout time metric``."""

    world: int
    """BARN world index."""
    success: bool
    """Reached the goal."""
    collided: bool
    """Ended in a collision."""
    timeout: bool
    """Ended at the time limit."""
    time_s: float
    """BARN's clock at the end (s)."""


def parse_out(text: str, name: str = "out file") -> list[OutRow]:
    """The rows of a BARN out file (the sixth column, a metric, is recomputed, never read)."""
    rows = []
    for n, line in enumerate(text.splitlines(), 1):
        fields = line.split()
        if not fields:
            continue
        try:
            world, success, collided, timeout = (int(f) for f in fields[:4])
            rows.append(OutRow(world, bool(success), bool(collided), bool(timeout), float(fields[4])))
        except (ValueError, IndexError):
            raise BarnFileError(f"{name}: line {n}: not 'world success collided timeout time metric': {line!r}") from None
    return rows


@dataclass(frozen=True)
class Summary:
    """The five figures report_test.py prints (line 79), each a mean over worlds of per-world means."""

    time_s: float
    """Mean over worlds of the mean time of successful runs (worlds without one are left out)."""
    metric: float
    """Mean over worlds of the mean score."""
    success: float
    """Mean over worlds of the success rate."""
    collision: float
    """Mean over worlds of the collision rate."""
    timeout: float
    """Mean over worlds of the time-out rate."""

    def line(self) -> str:
        """The summary as report_test.py prints it (4 decimals)."""
        return (f"Avg Time: {self.time_s:.4f}, Avg Metric: {self.metric:.4f}, Avg Success: {self.success:.4f}, "
                f"Avg Collision: {self.collision:.4f}, Avg Timeout: {self.timeout:.4f}")


def by_world(rows: Iterable[OutRow]) -> dict[int, list[OutRow]]:
    """``rows`` grouped by world index, the worlds in the order they first appear."""
    worlds: dict[int, list[OutRow]] = {}
    for row in rows:
        worlds.setdefault(row.world, []).append(row)
    return worlds


def summarise(rows: Iterable[OutRow], t_opt: dict[int, float], low: float = 2.0) -> Summary:
    """report_test.py's summary of ``rows`` (lines 53-85), ``t_opt`` the optimal time per world.

    report_test.py measures t_opt from :data:`REPORT_START`, not run.py's :data:`START`."""
    worlds = by_world(rows)

    def mean_of(f) -> float:
        return float(np.mean([np.mean([f(r) for r in runs]) for runs in worlds.values()]))

    times = [np.mean([r.time_s for r in runs if r.success]) for runs in worlds.values() if any(r.success for r in runs)]
    return Summary(float(np.mean(times)),
                   mean_of(lambda r: barn_metric(r.success, r.time_s, t_opt[r.world], low=low)),
                   mean_of(lambda r: r.success), mean_of(lambda r: r.collided), mean_of(lambda r: r.timeout))
