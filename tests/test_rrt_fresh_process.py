"""RRT in fresh interpreters: the first call, numba compilation included, plans like any other.

RRT is bounded by iterations only, so compile time cannot change a result. A child process
plans a set of seeded narrow-passage problems with no warm-up, its first ``rrt`` call being the
first problem, and must solve >= 99.5 % of them; this process must find the same paths, bit
for bit. A second child gets an empty numba cache (``NUMBA_CACHE_DIR``), so its first call
compiles every kernel, and must find them too. No timing assertions.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import shapely

from bulletnav.bench.planner_bench import narrow_problem
from bulletnav.planning import rrt

ROOT = Path(__file__).resolve().parents[1]
N_PROBLEMS = 200
PROBLEM_SEED = 2024

#: Child script: load the problems, then plan them in order with no warm-up before, so the first
#: rrt call of the process is the first problem. The problems come from a file because making
#: them needs A*, whose compilation would dominate a cold child's run time. Prints the paths as
#: JSON (floats round-trip exactly).
SCRIPT = """
import json
import sys

import numpy as np

from bulletnav.planning import OccupancyGrid, rrt
from bulletnav.planning.rrt import _grow

data = np.load(sys.argv[1])
seed, res, origin = int(data["seed"]), float(data["resolution"]), tuple(data["origin"].tolist())
compiled_before = len(_grow.signatures)
paths = []
for i, (occ, s, g) in enumerate(zip(data["occupied"], data["starts"].tolist(), data["goals"].tolist())):
    paths.append(rrt(OccupancyGrid(occ, res, origin), tuple(s), tuple(g), np.random.default_rng([seed, i])))
print(json.dumps({"compiled_before_first_call": compiled_before, "paths": paths}))
"""


@pytest.fixture(scope="module")
def problems():
    rng = np.random.default_rng(PROBLEM_SEED)
    return [narrow_problem(rng) for _ in range(N_PROBLEMS)]


@pytest.fixture(scope="module")
def problem_file(problems, tmp_path_factory) -> Path:
    grid = problems[0][0]
    assert all(g.resolution == grid.resolution and g.origin == grid.origin for g, _, _ in problems)
    path = tmp_path_factory.mktemp("problems") / "narrow.npz"
    np.savez(path, seed=PROBLEM_SEED, resolution=grid.resolution, origin=np.array(grid.origin),
             occupied=np.stack([g.occupied for g, _, _ in problems]),
             starts=np.array([s for _, s, _ in problems]), goals=np.array([g for _, _, g in problems]))
    return path


def shapely_clear(grid, path) -> bool:
    """Whether the polyline stays inside the grid and touches no occupied cell, by Shapely: each
    occupied cell is the closed square of side ``resolution`` about its centre."""
    ix, iy = np.nonzero(grid.occupied)
    r, (ox, oy) = grid.resolution, grid.origin
    cx, cy = ox + ix * r, oy + iy * r
    cells = shapely.STRtree(shapely.box(cx - r / 2, cy - r / 2, cx + r / 2, cy + r / 2))
    line = shapely.LineString(path)
    x0, x1, y0, y1 = grid.bounds
    return shapely.box(x0, y0, x1, y1).covers(line) and len(cells.query(line, predicate="intersects")) == 0


def run_child(problem_file: Path, cache_dir: Path | None) -> dict:
    """Run :data:`SCRIPT` on ``problem_file`` in a new interpreter; ``cache_dir`` replaces numba's on-disk cache."""
    env = dict(os.environ)
    if cache_dir is not None:
        env["NUMBA_CACHE_DIR"] = str(cache_dir)
    done = subprocess.run([sys.executable, "-c", SCRIPT, str(problem_file)], cwd=ROOT, env=env, capture_output=True,
                          text=True, check=False)
    assert done.returncode == 0, done.stderr
    return json.loads(done.stdout.strip().splitlines()[-1])


def as_paths(raw: list) -> list:
    return [None if p is None else [tuple(q) for q in p] for p in raw]


@pytest.fixture(scope="module")
def fresh(problem_file) -> dict:
    """A child with numba's ordinary on-disk cache (what a user's new process gets)."""
    return run_child(problem_file, None)


def test_first_call_in_fresh_process_solves_narrow_passage(fresh, problems, report):
    assert fresh["compiled_before_first_call"] == 0  # nothing compiled or loaded the kernel before
    paths = as_paths(fresh["paths"])
    grid, start, goal = problems[0]
    first = paths[0]
    assert first is not None
    assert first[0] == start and first[-1] == goal
    assert all(grid.segment_free(p, q) for p, q in zip(first[:-1], first[1:]))
    for (grid, start, goal), path in zip(problems, paths):
        if path is not None:
            assert path[0] == start and path[-1] == goal
            assert all(grid.segment_free(p, q) for p, q in zip(path[:-1], path[1:]))
    # Against Shapely: every found path clears the occupied cells, where most straight lines
    # from start to goal do not (the passage must be found); no path is shorter than that line.
    blocked = 0
    for (grid, start, goal), path in zip(problems, paths):
        blocked += not shapely_clear(grid, [start, goal])
        if path is not None:
            assert shapely_clear(grid, path)
            assert shapely.LineString(path).length >= np.hypot(goal[0] - start[0], goal[1] - start[1])
    assert blocked > N_PROBLEMS // 2
    solved = sum(path is not None for path in paths)
    report("narrow-passage problems solved in a fresh process, first call included", f"{solved}/{N_PROBLEMS}")
    assert solved >= 0.995 * N_PROBLEMS


def test_same_paths_in_this_process(fresh, problems):
    here = [rrt(grid, s, g, np.random.default_rng([PROBLEM_SEED, i])) for i, (grid, s, g) in enumerate(problems)]
    assert here == as_paths(fresh["paths"])


@pytest.mark.slow  # compiling every kernel from scratch takes 5-10 s
def test_compiling_inside_the_first_call_changes_nothing(fresh, problem_file, tmp_path):
    cold = run_child(problem_file, tmp_path / "numba_cache")  # an empty cache: the first rrt call compiles
    assert cold["compiled_before_first_call"] == 0
    assert cold["paths"] == fresh["paths"]
