"""What the user reads: no PyBullet build banner from bulletnav, YAML errors as ``FILE:LINE:COL:``
for every kind of user YAML file, one meaning (simulated seconds) for ``--frame-at``."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

import bulletnav
from bulletnav.errors import ConfigError, LayoutError

ROOT = Path(bulletnav.__file__).resolve().parent.parent
BANNER = "pybullet build time"
HANG_S = 120
"""A generous hang detector for a fresh interpreter that imports bulletnav (about a second alone)."""


def _fresh(*argv: str) -> subprocess.CompletedProcess:
    """``python argv`` in a fresh interpreter, stdout and stderr captured (pipes: C stdio fully buffered)."""
    env = {k: v for k, v in os.environ.items() if k != "PYTHONSTARTUP"}
    try:
        return subprocess.run([sys.executable, *argv], capture_output=True, text=True, cwd=ROOT, env=env,
                              timeout=HANG_S)
    except subprocess.TimeoutExpired:
        pytest.fail(f"hang: python {' '.join(argv)} did not end in {HANG_S} s")


@pytest.mark.slow
def test_pybullet_banner_never_reaches_the_terminal(tmp_path):
    # the reference: pybullet itself prints its banner on a first import (else this test proves nothing)
    plain = _fresh("-c", "import pybullet")
    assert BANNER in plain.stdout + plain.stderr
    runs = {
        "help": (_fresh("-m", "bulletnav.cli", "--help"), 0),
        "failing command": (_fresh("-m", "bulletnav.cli", "map", str(tmp_path / "missing.mcap")), 2),
        "import": (_fresh("-c", "import bulletnav, pybullet; print('imported')"), 0),
    }
    for name, (run, rc) in runs.items():
        assert run.returncode == rc, (name, run.stderr)
        assert BANNER not in run.stdout and BANNER not in run.stderr, name
    assert runs["help"][0].stdout.startswith("usage: bulletnav")
    assert runs["failing command"][0].stderr.strip() == f"bulletnav map: error: {tmp_path / 'missing.mcap'}: no such bag file"
    # what the program prints itself still arrives, on both streams
    both = _fresh("-c", "import sys; print('out'); print('err', file=sys.stderr); import bulletnav; print('after')")
    assert both.stdout.split() == ["out", "after"] and both.stderr.split() == ["err"]


def test_output_of_another_thread_while_pybullet_loads_is_delayed_not_lost():
    """A thread that writes to both descriptors all through ``import bulletnav`` (which imports
    pybullet with 1 and 2 held aside): every byte arrives, on its own stream; the banner does not."""
    code = (
        "import os, sys, threading, time\n"
        "go, stop, n = threading.Event(), threading.Event(), [0]\n"
        "def spam():\n"
        "    go.set()\n"
        "    while not stop.is_set():\n"
        "        os.write(1, b'o'); os.write(2, b'e'); n[0] += 1; time.sleep(0.0005)\n"
        "t = threading.Thread(target=spam); t.start(); go.wait()\n"
        "import bulletnav\n"
        "time.sleep(0.05); stop.set(); t.join()\n"
        "os.write(1, b' %d' % n[0])\n")
    run = _fresh("-c", code)
    assert run.returncode == 0, run.stderr
    assert BANNER not in run.stdout and BANNER not in run.stderr
    written, count = run.stdout.split()
    assert written == "o" * int(count) and run.stderr == "e" * int(count)


# A syntax error at a position counted by hand: line 3 (``  c: 3``), column 4 (the ``:`` after ``c``)
# breaks the flow sequence opened on line 2, column 8.
BROKEN = "name: x\nitems: [1, 2\n  c: 3\n"


def _loaders(tmp_path: Path) -> dict[str, tuple]:
    from bulletnav.benchmark.suite import SuiteError, load_suite
    from bulletnav.fleet.stations import load_world
    from bulletnav.rl.hyperparams import load_hyperparams
    from bulletnav.sim.layout import load_layout
    from bulletnav.sweep.spec import SweepSpec

    return {
        "layout": (load_layout, LayoutError),
        "fleet world with stations": (load_world, LayoutError),
        "suite": (lambda p: load_suite(str(p)), SuiteError),
        "sweep": (SweepSpec.from_file, ConfigError),
        "hyperparameters": (lambda p: load_hyperparams("ppo", path=p), ConfigError),
    }


def test_yaml_errors_name_file_line_and_column(tmp_path):
    for kind, (load, error) in _loaders(tmp_path).items():
        path = tmp_path / f"{kind.replace(' ', '_')}.yaml"
        path.write_text(BROKEN)
        with pytest.raises(error) as caught:
            load(path)
        message = str(caught.value)
        assert message.startswith(f"{path}:3:4: not valid YAML: "), (kind, message)
        assert "line 2, column 8" in message and "<unicode string>" not in message and "\n" not in message, message


@pytest.mark.parametrize("text, where", [
    ("a: 1\n  b: 2\n", "2:4"),                       # a mapping value where none may stand
    ("a: 1\nb: *nowhere\n", "2:4"),                  # an alias never defined
    ("a: 1\nb: !!python/object:os.system x\n", "2:4"),  # a Python tag, refused by safe_load
    ("a: [1,\n    !!int many]\n", "2:5"),           # a value the tag's constructor refuses
    ('a: "open\n', "2:1"),                           # a quoted scalar the file ends inside
])
def test_yaml_error_positions(tmp_path, text, where):
    from bulletnav.sim.layout import load_layout

    path = tmp_path / "world.yaml"
    path.write_text(text)
    with pytest.raises(LayoutError, match="^" + re.escape(f"{path}:{where}: not valid YAML: ")):
        load_layout(path)


def test_navigate_says_its_shortest_path_runs_to_the_goal_centre(capsys):
    """In the empty world the shortest path is the straight line from the start to the goal's
    centre; the episode succeeds on entering the goal zone (0.5 m round the centre), so the robot
    drives less than it, and the line says which shortest path it prints."""
    import math

    import gymnasium as gym

    from bulletnav.cli import main
    from bulletnav.config import asset_path

    world = str(asset_path("worlds", "empty.yaml"))
    env = gym.make("bulletnav/Warehouse-v0", world=world)
    try:
        env.reset(seed=0)
        scene = env.unwrapped.scene
        straight = math.dist(scene.start[:2], scene.goal)
        zone = scene.goal_radius
    finally:
        env.close()
    assert main(["navigate", "--world", world, "--episodes", "1", "--seed", "0"]) == 0
    line = capsys.readouterr().out.splitlines()[0]
    found = re.search(r"SUCCESS .* driven +([\d.]+) m +shortest to goal centre +([\d.]+) m +SPL 1\.00", line)
    assert found, line
    driven, shortest = float(found[1]), float(found[2])
    assert shortest == pytest.approx(straight, abs=0.01)  # printed to 0.01 m
    assert straight - zone - 0.1 <= driven < shortest


def test_frame_at_means_simulated_seconds_in_every_command(capsys):
    from bulletnav.cli import build_parser, main

    parser = build_parser()
    commands = {a.dest: a for a in parser._actions if a.dest == "command"}["command"].choices
    users = {name: sub for name, sub in commands.items()
             if any("--frame-at" in action.option_strings for action in sub._actions)}
    assert set(users) == {"fleet", "replay"}
    for name, sub in users.items():
        action = next(a for a in sub._actions if "--frame-at" in a.option_strings)
        assert action.metavar == "S" and "simulated seconds" in action.help, name
        assert action.type("2.5") == 2.5 and action.type("0") == 0.0  # seconds, fractions too
    for argv in (["replay", "x.mcap", "--frame-at", "2"], ["fleet", "--frame-at", "2"]):
        assert main(argv) == 2  # a time without a --frame PNG
        assert "--frame-at is the time of the --frame PNG: pass --frame too" in capsys.readouterr().err


@pytest.mark.parametrize(("argv0", "shown"), [("/home/u/.venv/bin/bulletnav", "bulletnav"),
                                                ("/x/bulletnav/cli/__main__.py", "bulletnav"),
                                                ("scripts/run.py", "scripts/run.py")])
def test_the_command_recorded_is_the_one_typed(monkeypatch, argv0, shown):
    """Results record ``bulletnav ARGS`` for the console script and ``python -m bulletnav.cli`` alike."""
    from bulletnav.provenance import command_line

    monkeypatch.setattr(sys, "argv", [argv0, "fleet-compare", "--robots", "4"])
    assert command_line() == f"{shown} fleet-compare --robots 4"
