"""Re-score the ``barn_score`` field of committed benchmark records with BARN's current clip.

``barn_score`` (bulletnav/benchmark/metrics.py) is BARN's score S t_opt / clip(t, low t_opt,
8 t_opt) with t_opt = bulletnav's shortest path / the robot's top speed. It used BARN's old lower
clip 4 t_opt; it now calls :func:`bulletnav.barn.metric.barn_metric` with BARN's current 2 t_opt
(BARN's run.py since 2024-02-04, report_test.py since 2026-03-04). Every input of the score is
in each committed row already (``success``, ``time_s``, ``shortest_path_m``) except the top speed,
which is read from the cell's env exactly as the runner reads it
(``scene.command_limits[0][1]`` of :func:`bulletnav.benchmark.runner.make_cell`), so no episode is
run again. Per file this rewrites:

- each row's ``barn_score``;
- each cell's ``summary.barn_score`` (mean and 95 % bootstrap interval, as ``cell_summary`` does);
- ``metrics.barn_score`` (the definition text) where the record has one;

and nothing else, which it checks: it compares the new record with the old one and refuses to
write if any other field differs. It also checks the top speed on every old row the 4 t_opt clip
left unclipped (there old = t_opt / t).

    .venv/bin/python scripts/rescore_barn_score.py tests/data/benchmark_tiny.yaml tests/golden/benchmark_tiny.json \\
        bulletnav/benchmark/suites/standard.yaml docs/benchmark/results.json
"""

from __future__ import annotations

import json
import math
import re
import sys
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.barn.metric import barn_metric
from bulletnav.benchmark.metrics import METRICS, bootstrap_interval
from bulletnav.benchmark.runner import make_cell
from bulletnav.benchmark.suite import load_suite
from bulletnav.files import write_bytes


def top_speeds(suite_file: str) -> dict[tuple[str, str], float]:
    """(world, controller) -> the robot's top speed in that cell's env, as the runner reads it."""
    suite = load_suite(suite_file)
    out = {}
    for world in suite.worlds:
        for controller in suite.controllers:
            env, _ = make_cell(world, controller)
            try:
                out[(world.name, controller.name)] = float(env.unwrapped.scene.command_limits[0][1])
            finally:
                env.close()
    return out


def new_score(row: dict[str, Any], top_speed: float) -> float:
    """``barn_score`` of a row as :func:`bulletnav.benchmark.metrics.episode_metrics` now computes it."""
    shortest = row["shortest_path_m"]
    ok = bool(row["success"]) and shortest is not None and shortest > 0 and math.isfinite(shortest)
    return barn_metric(True, row["time_s"], shortest / top_speed) if ok else 0.0


def differences(old: Any, new: Any, path: str = "") -> list[str]:
    """The paths where two decoded JSON documents differ."""
    if isinstance(old, dict) and isinstance(new, dict):
        keys = sorted(set(old) | set(new))
        return [d for k in keys for d in differences(old.get(k, "<missing>"), new.get(k, "<missing>"), f"{path}.{k}")]
    if isinstance(old, list) and isinstance(new, list) and len(old) == len(new):
        return [d for i, (a, b) in enumerate(zip(old, new, strict=True)) for d in differences(a, b, f"{path}[{i}]")]
    return [] if old == new and type(old) is type(new) else [path]


def rescore(suite_file: str, results_file: str) -> None:
    text = Path(results_file).read_text()
    old = json.loads(text)
    assert json.dumps(old, indent=1) + "\n" == text, f"{results_file}: not in the runner's JSON layout"
    record = json.loads(text)
    speeds = top_speeds(suite_file)
    checked = 0
    for row in record["episodes"]:
        speed = speeds[(row["world"], row["controller"])]
        was = row["barn_score"]
        if row["success"] and 1 / 8 < was < 1 / 4:  # unclipped under the old rule: old = t_opt / t
            assert abs(was - row["shortest_path_m"] / speed / row["time_s"]) < 1e-12, row
            checked += 1
        row["barn_score"] = new_score(row, speed)
    for cell in record["cells"]:
        values = np.array([r["barn_score"] for r in record["episodes"]
                           if r["world"] == cell["world"] and r["controller"] == cell["controller"]], dtype=float)
        lo, hi = bootstrap_interval(values)
        cell["summary"]["barn_score"] = {"mean": float(values.mean()), "lo": lo, "hi": hi, "n": int(len(values))}
    if "metrics" in record:
        record["metrics"]["barn_score"] = METRICS["barn_score"]
    changed = differences(old, record)
    allowed = re.compile(r"^(\.episodes\[\d+\]\.barn_score|\.cells\[\d+\]\.summary\.barn_score\.(mean|lo|hi|n)"
                         r"|\.metrics\.barn_score)$")
    other = [p for p in changed if not allowed.match(p)]
    assert not other, f"{results_file}: fields other than barn_score would change: {other[:5]}"
    write_bytes(Path(results_file), (json.dumps(record, indent=1) + "\n").encode())
    rows = sum(p.startswith(".episodes[") for p in changed)
    cells = len({p.split(".summary")[0] for p in changed if p.startswith(".cells[")})
    print(f"{results_file}: {rows} of {len(record['episodes'])} rows' barn_score changed, "
          f"{cells} of {len(record['cells'])} cells' summary.barn_score, "
          f"metrics.barn_score {'changed' if '.metrics.barn_score' in changed else 'absent'}; "
          f"top speed checked on {checked} unclipped old rows; no other field changed")


if __name__ == "__main__":
    args = sys.argv[1:]
    if not args or len(args) % 2:
        sys.exit(__doc__)
    for i in range(0, len(args), 2):
        rescore(args[i], args[i + 1])
