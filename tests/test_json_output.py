"""``--json``'s contract: every command that has the option prints exactly one JSON document on
stdout, and everything else (notes, progress, file lists, PyBullet's own messages, the GUI's
included) on stderr.

``json.loads`` must take the whole of what the process wrote to file descriptor 1 -- Python's
prints, C code's writes (PyBullet), and C stdio buffers flushed when the process ends. Each
command runs with the smallest arguments that still do its work (one short episode, a one-world
suite). To spare ten fresh interpreters their imports (ten seconds each on a loaded machine), one
driver process (:data:`DRIVER`) imports ``bulletnav.cli``, every ``bulletnav`` module (but Ray's, sweep) and the
heavy libraries once, and forks a child per command: the child points file descriptors 1 and 2 at
files of its own, runs ``bulletnav.cli.main(argv)``, then does what a process's end writes -- the
atexit handlers, then Python's and C's stdio buffers flushed -- and leaves with ``os._exit``
(tearing the imported modules down took the child five seconds), so each file holds all that the
command's process wrote. The commands' own lazy imports run inside ``--json``'s redirection in a
fresh process too, so importing them early hides nothing; ``navigate`` also runs as a user runs it
(``python -m bulletnav.cli`` in a fresh process, to its interpreter's real end), and so does the
GUI case. ``sweep`` starts Ray, which costs a minute: its ``--json`` stdout is checked whole by the
test named in :data:`COVERED_ELSEWHERE`, which runs a sweep through the command line anyway. The
timeouts only catch a hang.
"""

from __future__ import annotations

import ast
import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

import hang
from bulletnav.cli import build_parser
from hang import HANG_S, hang_message

ROOT = Path(__file__).resolve().parents[1]
SHORT = {"name": "short", "size": [6.0, 6.0], "obstacles": [], "start": [0.0, 0.0, 0.0], "goal": [0.8, 0.0]}
"""An empty room with the goal 0.8 m ahead of the start: an episode of about 20 steps."""
SHIPPED = str(ROOT / "models" / "ppo_warehouse.zip")
RUNS = ROOT / "docs" / "results" / "compare"

SUITE = {"name": "json", "episodes": 1, "seed": 7000,
         "worlds": [{"name": "short", "env": "bulletnav/Warehouse-v0", "kwargs": {"world": "{tmp}/short.yaml"}}],
         "controllers": [{"name": "PID", "type": "navigator", "planner": "none"}]}

NAVIGATE = ["navigate", "--planner", "none", "--episodes", "1", "--world", "{tmp}/short.yaml"]
CASES = {
    "navigate": NAVIGATE,
    "evaluate": ["evaluate", "--model", SHIPPED, "--episodes", "1", "--world", "{tmp}/short.yaml"],
    "compare": ["compare", str(RUNS / "ppo_s0"), str(RUNS / "a2c_s0"), "--out", "{tmp}/curves.png"],
    "demo": ["demo", "--episodes", "1", "--world", "{tmp}/short.yaml", "--out", "{tmp}/demo"],
    "benchmark": ["benchmark", "{tmp}/suite.yaml", "--out", "{tmp}/benchmark"],
    "fleet": ["fleet", "--robots", "1", "--duration", "2"],
    "fleet-compare": ["fleet-compare", "--robots", "1", "--controllers", "independent", "--shield", "off",
                      "--episodes", "1", "--duration", "2", "--out", "{tmp}/fleet-compare"],
    "map": ["map", "{tmp}/run.mcap", "--out", "{tmp}/map.png"],
    "replay": ["replay", "{tmp}/run.mcap", "--plot", "{tmp}/paths.png"],
    "bench": ["bench", "env", "--env", "bulletnav/WarehouseAisles-v0", "--resets", "1", "--steps", "10"],
}
"""The cheapest real run of each command that has ``--json`` (``{tmp}``: the test's folder), in
the driver's order; ``--json`` is added."""

RECORD = [*NAVIGATE, "--record", "{tmp}/run.mcap"]
"""One short PID episode recorded as ROS 2 messages, for ``map`` and ``replay`` (run first)."""

COVERED_ELSEWHERE = {
    "sweep": ("tests/test_sweep.py", "test_sweep_interrupted_with_ctrl_c_resumes_without_rerunning_finished_trials"),
}
"""Commands whose ``--json`` stdout another test runs and ``json.loads`` whole (each starts Ray)."""

DRIVER = r"""
import atexit, ctypes, importlib, json, os, pkgutil, signal, sys, time, traceback

plan = json.loads(sys.argv[1])
import bulletnav.cli  # as `bulletnav` imports it; then what the commands import inside them
for name in plan["preload"]:
    importlib.import_module(name)
for module in pkgutil.walk_packages(bulletnav.__path__, "bulletnav."):
    if not module.name.startswith("bulletnav.sweep"):  # Ray, and its allocator's thread: sweep is not run here
        importlib.import_module(module.name)
libc = ctypes.CDLL(None)
done = {}
for step in plan["steps"]:
    sys.stdout.flush()
    sys.stderr.flush()
    libc.fflush(None)  # nothing of this process's buffers may reach the child's files
    t0 = time.perf_counter()
    pid = os.fork()
    if pid == 0:  # the command's process: its fd 1 and 2 are files; it ends as `bulletnav` ends
        for fd, path in ((1, step["out"]), (2, step["err"])):
            f = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            os.dup2(f, fd)
            os.close(f)
        signal.alarm(plan["hang_s"])
        try:
            code = bulletnav.cli.main(step["argv"])
        except SystemExit as exc:  # argparse's exit, say
            code = exc.code if isinstance(exc.code, int) else 1
        except BaseException:
            traceback.print_exc()
            code = 1
        atexit._run_exitfuncs()  # then the writes of a process's end, without tearing the modules down
        sys.stdout.flush()
        sys.stderr.flush()
        libc.fflush(None)
        os._exit(code)
    _, status, use = os.wait4(pid, 0)
    done[step["name"]] = {"code": os.waitstatus_to_exitcode(status), "wall_s": time.perf_counter() - t0,
                          "cpu_s": use.ru_utime + use.ru_stime}
with open(plan["result"], "w") as f:
    json.dump(done, f)
"""
"""The driver: ``python -c DRIVER PLAN``; each step's command in a forked child (see the module
docstring), its exit status, wall time and CPU time written to ``PLAN["result"]``."""

PRELOAD = ["stable_baselines3", "matplotlib", "imageio.v2"]
"""Libraries the commands import inside themselves: imported once in the driver, not per child."""


def _json_commands() -> set[str]:
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    return {name for name, p in sub.choices.items() if any("--json" in a.option_strings for a in p._actions)}


def test_every_command_with_json_is_run_here():
    assert _json_commands() == set(CASES) | set(COVERED_ELSEWHERE)
    assert not set(CASES) & set(COVERED_ELSEWHERE)
    for command, (path, test) in COVERED_ELSEWHERE.items():
        text = (ROOT / path).read_text()
        (fn,) = [n for n in ast.parse(text).body if isinstance(n, ast.FunctionDef) and n.name == test]
        source = ast.get_source_segment(text, fn)
        assert f'"{command}"' in source and '"--json"' in source, f"{path}::{test} does not run {command} --json"
        whole = [n for n in ast.walk(fn) if isinstance(n, ast.Call) and ast.unparse(n.func) == "json.loads"
                 and len(n.args) == 1 and isinstance(n.args[0], ast.Attribute) and n.args[0].attr == "stdout"]
        assert whole, f"{path}::{test} does not json.loads the whole of its stdout"


def _write_inputs(folder: Path) -> str:
    (folder / "short.yaml").write_text(yaml.safe_dump(SHORT))
    (folder / "suite.yaml").write_text(yaml.safe_dump(json.loads(json.dumps(SUITE).replace("{tmp}", str(folder)))))
    return str(folder / "short.yaml")


@pytest.fixture(scope="module")
def driven(tmp_path_factory) -> dict:
    """Every case of :data:`CASES` run by one :data:`DRIVER`: ``{command: (exit status, stdout,
    stderr)}``, stdout and stderr as the command's process wrote them."""
    folder = tmp_path_factory.mktemp("json")
    _write_inputs(folder)
    steps = [{"name": "record", "argv": [a.format(tmp=folder) for a in RECORD]}]
    steps += [{"name": c, "argv": [*(a.format(tmp=folder) for a in argv), "--json"]} for c, argv in CASES.items()]
    for s in steps:
        s["out"], s["err"] = str(folder / f"{s['name']}.stdout"), str(folder / f"{s['name']}.stderr")
    plan = {"steps": steps, "preload": PRELOAD, "hang_s": int(HANG_S), "result": str(folder / "result.json")}
    driver = hang.run([sys.executable, "-c", DRIVER, json.dumps(plan)], "the JSON driver's commands", cwd=ROOT,
                      timeout=HANG_S * 3)
    assert driver.returncode == 0, driver.stderr[-3000:]
    status = json.loads((folder / "result.json").read_text())
    assert status["record"]["code"] == 0, (folder / "record.stderr").read_text()[-3000:]
    return {s["name"]: (status[s["name"]]["code"], Path(s["out"]).read_text(), Path(s["err"]).read_text())
            for s in steps}


def _one_document(code: int, stdout: str, stderr: str):
    assert code != -signal.SIGALRM, hang_message("the command (its SIGALRM hang limit)", HANG_S, stdout, stderr)
    assert code == 0, stderr[-3000:]
    try:
        return json.loads(stdout)
    except json.JSONDecodeError as exc:
        raise AssertionError(f"stdout is not one JSON document ({exc}):\n{stdout[-3000:]}") from None


def _run(argv: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    return hang.run([sys.executable, "-m", "bulletnav.cli", *argv, "--json"], f"bulletnav {argv[0]} --json", cwd=ROOT,
                    env=env)


FRESH = "navigate-fresh-process"
"""``navigate`` as a user runs it: ``python -m bulletnav.cli`` in its own process, from its imports to its exit."""


@pytest.mark.slow
@pytest.mark.parametrize("command", [*CASES, FRESH])
def test_json_is_the_whole_of_stdout(command, request, tmp_path):
    if command == FRESH:
        world = _write_inputs(tmp_path)
        done = _run([a.format(tmp=tmp_path) for a in NAVIGATE])
        doc = _one_document(done.returncode, done.stdout, done.stderr)
        assert doc["episodes"] == 1 and doc["world"] == world
        return
    doc = _one_document(*request.getfixturevalue("driven")[command])
    assert isinstance(doc, (dict, list)) and doc


@pytest.mark.slow
def test_the_gui_keeps_off_stdout_with_json(display, tmp_path):
    """PyBullet's GUI thread prints its OpenGL and thread messages on file descriptor 1: with
    ``--json`` they reach stderr, and stdout is the document alone (at 052a810 stdout began with
    ``argv[0]=``, ``startThreads creating 1 threads.``, ...)."""
    world = _write_inputs(tmp_path)
    done = _run(["navigate", "--gui", "--planner", "none", "--episodes", "1", "--world", world],
                env={**os.environ, "DISPLAY": display})
    doc = _one_document(done.returncode, done.stdout, done.stderr)
    assert doc["episodes"] == 1 and doc["world"] == world
    # the GUI did print: its messages are on stderr (PyBullet names the OpenGL version it got)
    assert "startThreads creating 1 threads." in done.stderr, done.stderr[-2000:]
