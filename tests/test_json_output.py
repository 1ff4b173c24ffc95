"""``--json``'s contract: every command that has the option prints exactly one JSON document on
stdout, and everything else (notes, progress, file lists, PyBullet's own messages, the GUI's
included) on stderr.

Each command runs as a user runs it, in a fresh process, with the smallest arguments that still do
its work (one short episode, a one-world suite, a 256-step sweep); ``json.loads`` must take the
whole of stdout. A process ends by flushing C's stdio buffers, so PyBullet's messages written while
the command ran would reach stdout only then: only a separate process shows them. The timeouts
only catch a hang.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from bulletnav.cli import build_parser, main

ROOT = Path(__file__).resolve().parents[1]
SHORT = {"name": "short", "size": [6.0, 6.0], "obstacles": [], "start": [0.0, 0.0, 0.0], "goal": [0.8, 0.0]}
"""An empty room with the goal 0.8 m ahead of the start: an episode of about 20 steps."""
SHIPPED = str(ROOT / "models" / "ppo_warehouse.zip")
RUNS = ROOT / "docs" / "results" / "compare"
HANG_S = 600

SWEEP = {"algo": "ppo", "timesteps": 128, "n_envs": 1, "grid": {"n_steps": [64], "batch_size": [64]},
         "env_kwargs": {"world": "{tmp}/short.yaml"}, "eval_freq": 128, "eval_episodes": 1, "checkpoint_freq": 128,
         "evaluation": {"episodes": 1, "seed": 1000}}
"""A sweep that trains for real but in seconds: one trial of two PPO updates in the short room."""
SUITE = {"name": "json", "episodes": 1, "seed": 7000,
         "worlds": [{"name": "short", "env": "bulletnav/Warehouse-v0", "kwargs": {"world": "{tmp}/short.yaml"}}],
         "controllers": [{"name": "PID", "type": "navigator", "planner": "none"}]}

CASES = {
    "navigate": ["navigate", "--planner", "none", "--episodes", "1", "--world", "{tmp}/short.yaml"],
    "evaluate": ["evaluate", "--model", SHIPPED, "--episodes", "1", "--world", "{tmp}/short.yaml"],
    "compare": ["compare", str(RUNS / "ppo_s0"), str(RUNS / "a2c_s0"), "--out", "{tmp}/curves.png"],
    "demo": ["demo", "--episodes", "1", "--world", "{tmp}/short.yaml", "--out", "{tmp}/demo"],
    "sweep": ["sweep", "{tmp}/sweep.yaml", "--out", "{tmp}/sweeps", "--num-cpus", "1"],
    "benchmark": ["benchmark", "{tmp}/suite.yaml", "--out", "{tmp}/benchmark"],
    "fleet": ["fleet", "--robots", "1", "--duration", "2"],
    "fleet-compare": ["fleet-compare", "--robots", "1", "--controllers", "independent", "--shield", "off",
                      "--episodes", "1", "--duration", "2", "--out", "{tmp}/fleet-compare"],
    "map": ["map", "{recording}", "--out", "{tmp}/map.png"],
    "replay": ["replay", "{recording}", "--plot", "{tmp}/paths.png"],
    "bench": ["bench", "env", "--env", "bulletnav/WarehouseAisles-v0", "--resets", "1", "--steps", "10"],
}
"""The cheapest real run of each command that has ``--json`` (``{tmp}``: the test's folder)."""


def _json_commands() -> set[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return {name for name, p in sub.choices.items() if any("--json" in a.option_strings for a in p._actions)}


def test_every_command_with_json_is_run_here():
    assert _json_commands() == set(CASES)


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Path:
    """One short PID episode recorded as ROS 2 messages, for ``map`` and ``replay``."""
    folder = tmp_path_factory.mktemp("recording")
    path = folder / "run.mcap"
    assert main(["navigate", "--planner", "none", "--episodes", "1", "--world", _write_short(folder), "--record", str(path)]) == 0
    return path


def _write_short(folder: Path) -> str:
    (folder / "short.yaml").write_text(yaml.safe_dump(SHORT))
    return str(folder / "short.yaml")


def _run(argv: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "bulletnav.cli", *argv, "--json"], cwd=ROOT, capture_output=True,
                          text=True, timeout=HANG_S, env=env)


def _one_document(done: subprocess.CompletedProcess):
    assert done.returncode == 0, done.stderr[-3000:]
    try:
        return json.loads(done.stdout)
    except json.JSONDecodeError as exc:
        raise AssertionError(f"stdout is not one JSON document ({exc}):\n{done.stdout[-3000:]}") from None


@pytest.mark.slow
@pytest.mark.parametrize("command", sorted(CASES))
def test_json_is_the_whole_of_stdout(command, tmp_path, request):
    _write_short(tmp_path)
    for name, data in (("sweep", SWEEP), ("suite", SUITE)):
        (tmp_path / f"{name}.yaml").write_text(yaml.safe_dump(json.loads(json.dumps(data).replace("{tmp}", str(tmp_path)))))
    recording = request.getfixturevalue("recording") if command in ("map", "replay") else ""
    argv = [a.format(tmp=tmp_path, recording=recording) for a in CASES[command]]
    doc = _one_document(_run(argv))
    assert isinstance(doc, (dict, list)) and doc


@pytest.mark.slow
def test_the_gui_keeps_off_stdout_with_json(display, tmp_path):
    """PyBullet's GUI thread prints its OpenGL and thread messages on file descriptor 1: with
    ``--json`` they reach stderr, and stdout is the document alone (at 052a810 stdout began with
    ``argv[0]=``, ``startThreads creating 1 threads.``, ...)."""
    world = _write_short(tmp_path)
    done = _run(["navigate", "--gui", "--planner", "none", "--episodes", "1", "--world", world],
                env={**os.environ, "DISPLAY": display})
    doc = _one_document(done)
    assert doc["episodes"] == 1 and doc["world"] == world
    # the GUI did print: its messages are on stderr (PyBullet names the OpenGL version it got)
    assert "startThreads creating 1 threads." in done.stderr, done.stderr[-2000:]
