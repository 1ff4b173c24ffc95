"""BARN's 300 static worlds as shipped in ``bulletnav/assets/barn/`` (converted by scripts/convert_barn.py).

``barn.npz`` (never pickled; read with ``allow_pickle=False``) holds, for worlds 0-299 in order:

- ``cylinders_um``: every obstacle cylinder's centre (x, y) in micrometres (int32), as the world
  file's ``<pose>`` writes it (6 decimals of a metre), all worlds one after another;
- ``cylinder_offsets``: world ``i``'s cylinders are rows ``cylinder_offsets[i]:cylinder_offsets[i + 1]``;
- ``path_cells``: the reference paths' grid cells (int16) exactly as in BARN's ``path_N.npy``;
- ``path_offsets``: world ``i``'s path is rows ``path_offsets[i]:path_offsets[i + 1]``;
- ``source``: the BARN repository and commit the data was converted from.

``dwa_out.txt`` is BARN's ``res/dwa_out.txt`` verbatim: move_base DWA's 500 runs (10 on each of
the 50 test worlds) measured by BARN in Gazebo. ``lics_ki_out.txt`` is LiCS-KI's ``out.txt``
verbatim (github.com/damanikjosh/the-barn-challenge, commit f7bd87c): the 500 runs its authors
published on the same 50 test worlds, in the same format. :data:`PUBLISHED` lists every published
result bulletnav sets beside its own (:func:`published_rows`).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from bulletnav.barn import metric
from bulletnav.barn.metric import START, OutRow, optimal_time, parse_out
from bulletnav.errors import LayoutError

ASSETS = Path(__file__).resolve().parent.parent / "assets" / "barn"
"""Folder of the shipped BARN data."""
DATA_FILE = ASSETS / "barn.npz"
"""The converted worlds and reference paths."""
DWA_FILE = ASSETS / "dwa_out.txt"
"""BARN's published DWA rows."""
LICS_FILE = ASSETS / "lics_ki_out.txt"
"""LiCS-KI's published rows (ICRA 2024 BARN Challenge winner)."""
N_WORLDS = 300
"""BARN's static worlds: indices 0-299."""
TEST_WORLDS: tuple[int, ...] = metric.TEST_WORLDS
"""BARN's 50 test worlds 0, 6, ..., 294 (:data:`bulletnav.barn.metric.TEST_WORLDS`): BARN's
``report_test.py`` scores the worlds ``idx * 6`` for ``idx`` in 0-49 (its lines 40-51), and its
published DWA rows (``res/dwa_out.txt``) are on exactly these. Never train or tune on them."""
TRAIN_WORLDS: tuple[int, ...] = tuple(i for i in range(N_WORLDS) if i not in TEST_WORLDS)
"""The 250 other static worlds (every index not a multiple of 6): the ones to train and tune on."""
POOLS: dict[str, tuple[int, ...]] = {"train": TRAIN_WORLDS, "test": TEST_WORLDS}
"""World pools by name (``BarnEnv``'s ``world_idx="train"`` / ``"test"``; a benchmark suite's
``barn_worlds`` also takes these names)."""


@dataclass(frozen=True)
class BarnWorld:
    """One static BARN world."""

    index: int
    """World index, 0-299."""
    cylinders: np.ndarray
    """Obstacle cylinders' centres, n x 2 (m), in the world frame."""
    path_cells: np.ndarray
    """The reference path as BARN's grid cells, k x 2 integers (see :func:`bulletnav.barn.metric.path_cells_to_metres`)."""

    @property
    def t_opt(self) -> float:
        """BARN's optimal time (s) from run.py's start: reference path with both legs, over 2 m/s."""
        return optimal_time(self.path_cells, START[:2])


@functools.lru_cache(maxsize=1)
def _arrays() -> dict[str, np.ndarray]:
    with np.load(DATA_FILE, allow_pickle=False) as npz:
        return {k: npz[k] for k in npz.files}


def check_index(world_idx: object) -> int:
    """``world_idx`` as an int in 0-299, or a :class:`~bulletnav.errors.LayoutError` naming it."""
    if isinstance(world_idx, bool) or not isinstance(world_idx, (int, np.integer)) or not 0 <= world_idx < N_WORLDS:
        raise LayoutError(f"BARN world_idx {world_idx!r} is not a BARN static world (an integer 0-{N_WORLDS - 1})")
    return int(world_idx)


def world_pool(spec: object, names: dict[str, tuple[int, ...]] = POOLS, what: str = "BARN world_idx") -> tuple[int, ...]:
    """The worlds a pool ``spec`` names: a name of ``names`` (:data:`POOLS`: ``"train"``,
    :data:`TRAIN_WORLDS`; ``"test"``, :data:`TEST_WORLDS`) or a non-empty sequence of distinct
    indices 0-299, in its order. ``what`` names the value in messages (``BarnEnv``'s
    ``world_idx``; a benchmark suite's ``barn_worlds`` field, which also takes ``"all"``).

    Raises:
        LayoutError: an unknown name, an empty sequence, a repeated or bad index (named).
    """
    if isinstance(spec, str) and spec in names:
        return names[spec]
    if isinstance(spec, np.ndarray):
        spec = spec.tolist()
    if not isinstance(spec, (list, tuple)):
        raise LayoutError(f"{what} {spec!r} is neither an index 0-{N_WORLDS - 1} nor a pool "
                          f"({', '.join(map(repr, names))}) nor a list of indices")
    if not spec:
        raise LayoutError(f"{what} is an empty list: a pool needs at least one world")
    pool = tuple(check_index(i) for i in spec)
    if len(set(pool)) != len(pool):
        twice = sorted({i for i in pool if pool.count(i) > 1})
        raise LayoutError(f"{what} names BARN world(s) {twice} more than once")
    return pool


def load_world(world_idx: int) -> BarnWorld:
    """BARN world ``world_idx`` (0-299) from the shipped data."""
    i = check_index(world_idx)
    a = _arrays()
    c0, c1 = a["cylinder_offsets"][i:i + 2]
    p0, p1 = a["path_offsets"][i:i + 2]
    cylinders = a["cylinders_um"][c0:c1].astype(np.float64) / 1e6
    return BarnWorld(i, cylinders, a["path_cells"][p0:p1].astype(np.int64))


def source() -> str:
    """The BARN repository and commit the shipped data was converted from."""
    return str(_arrays()["source"])


def dwa_rows() -> list[OutRow]:
    """BARN's published move_base DWA rows (``res/dwa_out.txt``)."""
    return parse_out(DWA_FILE.read_text(), str(DWA_FILE))


@dataclass(frozen=True)
class Published:
    """A published BARN result on the 50 test worlds, shown beside bulletnav's as a row of its own."""

    name: str
    """The row's name in tables."""
    source: str
    """Where it comes from (repository, commit, file)."""
    note: str
    """What it is and what differs from a bulletnav run (simulator, speed cap, clip)."""
    rows_file: Path | None = None
    """Its runs, in BARN's out-file format (scored here with report_test.py's formula); None
    where only a summary was published."""
    reported: dict[str, float] | None = None
    """The summary as published, for a result without rows: ``success``, ``collision``,
    ``timeout`` (fractions), ``time_s`` (s) and ``metric`` under the ``clip`` it states."""
    clip: float = 2.0
    """The lower clip of the published metric, in t_opt (report_test.py's today: 2)."""


PUBLISHED: tuple[Published, ...] = (
    Published("DWA (BARN's rows)", "github.com/Daffan/the-barn-challenge bf5a226, res/dwa_out.txt",
              "move_base DWA measured by BARN in Gazebo, max_vel_x 0.5 m/s; not run here", DWA_FILE),
    Published("LiCS-KI 2024 (published rows)", "github.com/damanikjosh/the-barn-challenge f7bd87c, out.txt",
              "ICRA 2024 BARN Challenge winner (a transformer imitating an optimisation-based expert), "
              "measured by its authors in Gazebo; scored here with report_test.py's formula; not run here", LICS_FILE),
    Published("Inventec 2023 (as reported)",
              "github.com/inventec-ai-center/inventec-team-barn-challenge-2023 edeebaa, simulation branch README.md",
              "learned local planner with a recovery state machine, measured by its authors in Gazebo; only the "
              "summary line is published, scored with the 2023 clip of 4 t_opt (metric at most 0.25), so its "
              "metric is not comparable with the 2 t_opt rows; not run here",
              reported={"success": 0.99, "collision": 0.006, "timeout": 0.004, "time_s": 14.0344, "metric": 0.2445},
              clip=4.0),
)
"""The published anchors every BARN table shows beside bulletnav's rows."""


def published_rows(entry: Published) -> list[OutRow]:
    """The runs of a published result (empty for one published as a summary only)."""
    if entry.rows_file is None:
        return []
    return parse_out(entry.rows_file.read_text(), str(entry.rows_file))
