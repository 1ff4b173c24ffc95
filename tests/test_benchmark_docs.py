"""The suite example of docs/benchmark.md runs as written: "my model beside PID + A* and PPO,
with and without the shield", with a copy of the shipped policy as the user's run folder and
one episode a cell."""

from __future__ import annotations

import re
import shutil
from pathlib import Path

import pytest
import yaml

from bulletnav.benchmark.runner import run_suite
from bulletnav.benchmark.suite import parse_suite

ROOT = Path(__file__).resolve().parents[1]
MARK = "<!-- suite example: my-model -->"


def _example() -> str:
    text = (ROOT / "docs" / "benchmark.md").read_text()
    match = re.search(re.escape(MARK) + r"\s*```yaml\n(.*?)```", text, re.S)
    assert match, f"docs/benchmark.md lost its example suite (after {MARK})"
    return match.group(1)


@pytest.mark.slow
def test_the_docs_example_suite_runs_as_written(tmp_path):
    raw = yaml.safe_load(_example())
    mine = [c for c in raw["controllers"] if c["type"] == "model" and c["model"] != "shipped"]
    assert mine and {c["model"] for c in mine} == {"runs/my-ppo"}  # the run folder train writes
    run = tmp_path / "my-ppo"  # "bulletnav train --out" lays out a run folder so
    run.mkdir()
    for src, dst in (("ppo_warehouse.zip", "model.zip"), ("ppo_warehouse.json", "model.json"),
                     ("ppo_warehouse.safetensors", "model.safetensors"),
                     ("ppo_warehouse_vecnormalize.json", "model_vecnormalize.json")):
        shutil.copy(ROOT / "models" / src, run / dst)
    for c in mine:
        c["model"] = str(run)
    raw["episodes"] = 1
    suite = parse_suite(raw, str(tmp_path / "my_model.yaml"), "0" * 64)
    results = run_suite(suite, tmp_path / "out", workers=1)
    names = [c["name"] for c in raw["controllers"]]
    assert {(r["world"], r["controller"]) for r in results["episodes"]} == {
        (w["name"], n) for w in raw["worlds"] for n in names}
    assert {"PID + A* + shield", "mine + shield"} <= set(names) and len(names) == 6
