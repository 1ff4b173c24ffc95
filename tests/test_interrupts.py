"""Ctrl-C (SIGINT to the process group, as a terminal sends it) and SIGTERM (to the command's
process alone, as ``kill`` sends it) in the long commands: exit 130 (143 for SIGTERM), exactly one line on stderr
after the signal, naming what was kept and how to go on (no traceback, nothing from the workers),
the workers gone, every file whole, and ``--resume`` finishing the run and reporting all of it.

Real subprocesses in their own session, signalled once they have made progress (a row or a
checkpoint on disk, an episode's line on stdout), never after a fixed sleep. The time limits are
hang detectors (tests/hang.py), not speed checks."""

from __future__ import annotations

import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import hang
from hang import HANG_S

ROOT = Path(__file__).resolve().parents[1]

LINE = re.compile(r"^bulletnav (?P<command>[\w-]+): interrupted(?P<what>.*); (?P<how>continue with|run again with): "
                  r"(?P<again>bulletnav .+)$")
"""The one line of an interrupted command."""

SUITE = """name: interrupts
episodes: 6
seed: 7000
worlds:
  - {name: scattered, env: bulletnav/Warehouse-v0, kwargs: {num_obstacles: 20}}
controllers:
  - {name: PID, type: navigator, planner: none}
"""
"""Six PID episodes of one world: with one worker they are written three at a time, with two
two at a time (``plan_chunks``), so a run signalled at its first rows has more to do."""


def _as_in_a_terminal() -> None:
    """In the child before exec: SIGINT and SIGTERM at their defaults, as a command typed in a
    terminal starts. A test run started in the background (``nohup make test &``) has SIGINT
    ignored, the child would inherit that, and a command started ignoring SIGINT rightly keeps
    ignoring it (the CLI honours it), so the Ctrl-C under test would never arrive."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


class Run:
    """A ``bulletnav`` command in a session of its own, stdout and stderr to files."""

    def __init__(self, tmp: Path, *args: str, name: str = "run") -> None:
        self.out, self.err = tmp / f"{name}.stdout", tmp / f"{name}.stderr"
        with self.out.open("wb") as out, self.err.open("wb") as err:
            self.proc = subprocess.Popen([sys.executable, "-m", "bulletnav.cli", *args], cwd=ROOT, stdout=out,
                                         stderr=err, start_new_session=True, preexec_fn=_as_in_a_terminal,
                                         env={**os.environ, "PYTHONUNBUFFERED": "1"})  # stdout's lines as printed
        self.mark = 0

    def wait_for(self, ready, what: str) -> None:
        """Poll until ``ready()``; fail as a hang past the limit, or if the run ended first."""
        t_end = time.monotonic() + HANG_S
        while not ready():
            if self.proc.poll() is not None:
                pytest.fail(f"the run ended (exit {self.proc.returncode}) before {what}:\n{self.err.read_text()[-3000:]}")
            if time.monotonic() > t_end:
                self.kill()
                pytest.fail(hang.hang_message(f"a run waiting for {what}", HANG_S, self.out.read_text(),
                                              self.err.read_text()), pytrace=False)
            time.sleep(0.02)

    def signal(self, sig: int, group: bool = True) -> None:
        """Send ``sig`` to the whole process group (a terminal's Ctrl-C) or to the command alone."""
        self.mark = self.err.stat().st_size
        if group:
            os.killpg(self.proc.pid, sig)
        else:
            os.kill(self.proc.pid, sig)

    def finish(self, what: str) -> int:
        try:
            return self.proc.wait(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            self.kill()
            pytest.fail(hang.hang_message(what, HANG_S, self.out.read_text(), self.err.read_text()), pytrace=False)

    def kill(self) -> None:
        try:
            os.killpg(self.proc.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
        self.proc.wait()

    def lines_after_signal(self) -> list[str]:
        """stderr's lines after the signal as a terminal shows them (a progress bar's ``\\r``
        redraws overwrite each other), the empty ones left out."""
        text = self.err.read_bytes()[self.mark:].decode(errors="replace")
        return [shown for line in text.split("\n") if (shown := line.rsplit("\r", 1)[-1].strip())]

    def group_gone(self) -> bool:
        try:
            os.killpg(self.proc.pid, 0)
        except ProcessLookupError:
            return True
        return False


def interrupted(run: Run, command: str, code: int = 130) -> re.Match:
    """The run ended with ``code`` (128 + the signal: 130 for Ctrl-C, 143 for SIGTERM) and one
    line after the signal, of the interrupted form."""
    status = run.finish(f"bulletnav {command} after its signal")
    lines = run.lines_after_signal()
    assert "Traceback" not in run.err.read_text(), run.err.read_text()[-3000:]
    assert status == code, run.err.read_text()[-3000:]
    assert len(lines) == 1, lines
    match = LINE.match(lines[0])
    assert match and match["command"] == command, lines[0]
    t_end = time.monotonic() + HANG_S  # its workers (and the forkserver) follow it out
    while not run.group_gone():
        assert time.monotonic() < t_end, "hang: worker processes still running after the command ended"
        time.sleep(0.05)
    return match


def rows_of(path: Path) -> list[dict]:
    """Every line of a JSON-lines file, each whole (a torn line fails the test)."""
    text = path.read_text()
    assert text.endswith("\n"), "the last row is torn"
    return [json.loads(line) for line in text.splitlines()]


def whole_json(folder: Path) -> None:
    for path in folder.rglob("*.json"):
        json.loads(path.read_text())
    assert not list(folder.rglob(".*.tmp*")), "a temporary file was left behind"


def rows_ready(log: Path, n: int):
    return lambda: log.is_file() and log.read_text().count("\n") >= n



def ctrl_c_after_first_rows(run, command: str, log, total: int) -> tuple[dict, int]:
    """Ctrl-C once ``run`` has written its first rows to ``log``: its interrupted line (see
    :func:`interrupted`), which must count the rows the file holds, some but not all of ``total``,
    and that count."""
    run.wait_for(rows_ready(log, 1), "its first rows")
    run.signal(signal.SIGINT)
    match = interrupted(run, command)
    kept = len(rows_of(log))
    assert 0 < kept < total
    assert match["what"] == f" after {kept} of {total} episodes; rows kept in {log}"
    return match, kept


@pytest.mark.slow
def test_benchmark_ctrl_c_says_how_to_resume_and_the_resume_reports_the_whole_run(tmp_path):
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE)
    out = tmp_path / "bench dir"  # a space: the continue command quotes it
    log = out / "episodes.jsonl"
    run = Run(tmp_path, "benchmark", str(suite), "--out", str(out))
    match, kept = ctrl_c_after_first_rows(run, "benchmark", log, 6)
    assert match["how"] == "continue with"
    assert match["again"] == f"bulletnav benchmark {suite} --out '{out}' --resume"
    whole_json(out)
    assert not (out / "results.json").exists()

    again = shlex.split(match["again"])[1:]  # the printed command, as a shell would split it
    done = hang.run([sys.executable, "-m", "bulletnav.cli", *again], "the resumed benchmark", cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    assert f"benchmark interrupts: 6 episodes ({kept} from the earlier run), " in done.stdout
    assert " s this run (1 workers)" in done.stdout
    rows = rows_of(log)
    assert sorted(r["episode"] for r in rows) == list(range(6))  # each episode once: none lost, none run twice
    assert len(json.loads((out / "results.json").read_text())["episodes"]) == 6


@pytest.mark.slow
def test_benchmark_sigterm_with_two_workers_stops_them_and_keeps_whole_rows(tmp_path):
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE)
    out = tmp_path / "bench"
    log = out / "episodes.jsonl"
    run = Run(tmp_path, "benchmark", str(suite), "--out", str(out), "--workers", "2")
    run.wait_for(rows_ready(log, 1), "its first rows")
    run.signal(signal.SIGTERM, group=False)  # the command alone: it must stop its workers itself
    match = interrupted(run, "benchmark", 143)
    kept = len(rows_of(log))
    assert match["what"] == f" after {kept} of 6 episodes; rows kept in {log}"
    assert match["again"] == f"bulletnav benchmark {suite} --out {out} --workers 2 --resume"
    whole_json(out)


@pytest.mark.slow
def test_benchmark_ctrl_c_with_two_workers_prints_nothing_from_them(tmp_path):
    suite = tmp_path / "suite.yaml"
    suite.write_text(SUITE)
    out = tmp_path / "bench"
    run = Run(tmp_path, "benchmark", str(suite), "--out", str(out), "--workers", "2", "--json")
    run.wait_for(rows_ready(out / "episodes.jsonl", 1), "its first rows")
    run.signal(signal.SIGINT)  # the whole group, workers too, as a terminal's Ctrl-C
    interrupted(run, "benchmark")
    assert run.out.read_text() == ""  # --json: no document for an unfinished run
    rows_of(out / "episodes.jsonl")


HYPERPARAMS = """bulletnav/Warehouse-v0:
  policy: MlpPolicy
  env_kwargs: {normalize_actions: true, max_episode_steps: 200}
  normalize: {norm_obs: false, norm_reward: true, gamma: 0.99}
  n_steps: 128
  batch_size: 128
  n_epochs: 1
"""
"""PPO in rollouts of 128 steps per env, one pass each, 200-step episodes: a small training."""


@pytest.mark.slow  # two trainings with env worker processes: ~20 s of CPU
def test_train_ctrl_c_keeps_the_checkpoint_and_resumes_from_it(tmp_path):
    hp = tmp_path / "ppo.yml"
    hp.write_text(HYPERPARAMS)
    out = tmp_path / "run"
    argv = ["train", "--algo", "ppo", "--timesteps", "1024", "--n-envs", "2", "--vec-env", "subproc", "--hyperparams",
            str(hp), "--checkpoint-freq", "256", "--eval-freq", "100000", "--eval-episodes", "1", "--no-progress",
            "--out", str(out)]
    run = Run(tmp_path, *argv)
    run.wait_for(lambda: (out / "checkpoints" / "last.json").is_file(), "its first checkpoint")
    run.signal(signal.SIGINT)  # the env worker processes get it too, as from a terminal
    match = interrupted(run, "train")
    steps = json.loads((out / "checkpoints" / "last.json").read_text())["timesteps"]
    assert 0 < steps < 1024
    assert match["what"] == f"; checkpoint at {steps:,} of 1,024 steps kept in {out / 'checkpoints' / 'last.zip'}"
    assert match["again"] == "bulletnav " + " ".join([*argv, "--resume"])
    whole_json(out)
    done = hang.run([sys.executable, "-m", "bulletnav.cli", *argv, "--resume"], "the resumed training", cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    record = json.loads((out / "run.json").read_text())
    assert record["resumed_from"] == steps and record["total_timesteps"] >= 1024
    assert (f"trained PPO for {record['total_timesteps']} timesteps ({steps} from the earlier run), "
            f"{record['wall_time_s']:.0f} s this run, ") in done.stdout


@pytest.mark.slow
def test_fleet_compare_ctrl_c_says_how_to_resume_and_resumes(tmp_path):
    out = tmp_path / "compare"
    log = out / "episodes.jsonl"
    argv = ["fleet-compare", "--robots", "2", "--controllers", "independent", "--shield", "off", "--episodes", "3",
            "--duration", "10", "--out", str(out)]
    run = Run(tmp_path, *argv)
    match, _ = ctrl_c_after_first_rows(run, "fleet-compare", log, 3)
    assert match["again"] == "bulletnav " + " ".join([*argv, "--resume"])
    whole_json(out)
    done = hang.run([sys.executable, "-m", "bulletnav.cli", *argv, "--resume", "--json"], "the resumed comparison", cwd=ROOT)
    assert done.returncode == 0, done.stderr[-3000:]
    assert sorted(r["episode"] for r in rows_of(log)) == [0, 1, 2]  # each once: none lost, none run twice


def test_navigate_ctrl_c_says_what_ran_and_that_nothing_resumes(tmp_path):
    argv = ["navigate", "--planner", "astar", "--episodes", "50", "--plot", str(tmp_path / "paths.png")]
    run = Run(tmp_path, *argv)
    run.wait_for(lambda: "episode   1/50" in run.out.read_text(), "its first episode")
    run.signal(signal.SIGINT)
    match = interrupted(run, "navigate")
    done = run.out.read_text().count("/50 seed ")
    assert match["what"] == (f" after {done} of 50 episodes; no plot written (an unfinished run's are dropped); "
                             "nothing can be resumed")
    assert match["how"] == "run again with" and match["again"] == "bulletnav " + " ".join(argv)
    assert not (tmp_path / "paths.png").exists()


@pytest.mark.slow
def test_dataset_recording_sigterm_writes_no_half_dataset(tmp_path, monkeypatch):
    minari = tmp_path / "minari"
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(minari))  # the child's datasets folder
    argv = ["evaluate", "--model", "models/ppo_warehouse.zip", "--episodes", "50", "--dataset", "bulletnav/interrupt-test-v0"]
    run = Run(tmp_path, *argv)
    run.wait_for(lambda: "--- Episode 1/50 " in run.out.read_text(), "its first episode")
    run.signal(signal.SIGTERM, group=False)
    match = interrupted(run, "evaluate", 143)
    done = run.out.read_text().count("--- Episode ")
    assert match["what"] == (f" after {done} of 50 episodes; no dataset written (an unfinished run's are dropped); "
                             "nothing can be resumed")
    assert match["again"] == "bulletnav " + " ".join(argv)
    assert not (minari / "bulletnav" / "interrupt-test-v0").exists()


def _signalled(code: str, signals: list[tuple[float, int]], tmp_path: Path) -> tuple[int, str, float]:
    """Run ``code`` in a fresh interpreter (signals at their defaults, as typed in a terminal);
    after it prints ``ready`` send each ``(delay_s, signal)``; return its exit status, stderr and
    the seconds from the last signal to its end."""
    err = tmp_path / "err"
    with err.open("wb") as e:
        proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, stderr=e,
                                preexec_fn=_as_in_a_terminal)
        assert proc.stdout.readline().strip() == b"ready"
        for delay, sig in signals:
            time.sleep(delay)
            proc.send_signal(sig)
        sent = time.monotonic()
        try:
            status = proc.wait(timeout=HANG_S)
        except subprocess.TimeoutExpired:
            proc.kill()
            pytest.fail(f"hang: the process outlived its signals by {HANG_S} s")
        return status, err.read_text(), time.monotonic() - sent


ENDLESS_QUERY = """
import sqlite3, sys
from bulletnav.cli import interrupts
interrupts.start(["map", "x.db3"], "map")
with interrupts.signals_as_interrupt():
    db = sqlite3.connect(":memory:")
    print("ready", flush=True)
    db.execute("WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c) SELECT count(*) FROM c").fetchone()
"""


def test_a_signal_inside_a_c_call_that_never_returns_ends_the_command_at_once(tmp_path):
    """An endless SQLite query (C code, Python's handlers never run): SIGTERM still ends it within
    the grace second, with the one line and 143."""
    status, err, after = _signalled(ENDLESS_QUERY, [(0.3, signal.SIGTERM)], tmp_path)
    assert status == 143, err
    assert "Traceback" not in err and err.count("\n") == 1, err
    assert err.startswith("bulletnav map: interrupted at once"), err
    assert after < 20.0  # the grace second plus a loaded machine's start; it was endless before


SLOW_CLEANUP = """
import time
from bulletnav.cli import interrupts
interrupts.start(["benchmark"], "benchmark")
with interrupts.signals_as_interrupt():
    try:
        print("ready", flush=True)
        while True:
            time.sleep(0.01)
    except KeyboardInterrupt:
        t = time.monotonic()
        while time.monotonic() - t < 600:  # a cleanup that takes its time (Python code)
            pass
"""


def test_a_second_ctrl_c_during_a_slow_cleanup_ends_the_command_at_once(tmp_path):
    status, err, after = _signalled(SLOW_CLEANUP, [(0.3, signal.SIGINT), (0.5, signal.SIGINT)], tmp_path)
    assert status == 130, err
    assert "Traceback" not in err and err.startswith("bulletnav benchmark: interrupted at once"), err
    assert after < 20.0


HELD = """
import os, signal, sys, time
from bulletnav.cli import interrupts
interrupts.start(["navigate"], "navigate")
print("ready", flush=True)
with interrupts.deferred():
    os.kill(os.getpid(), signal.SIGTERM)
    time.sleep(0.2)
    print("the line, whole", file=sys.stderr, flush=True)
print("not reached", file=sys.stderr, flush=True)
"""


def test_a_signal_while_the_interrupted_line_is_printed_waits_for_it_then_ends_the_process(tmp_path):
    """``deferred()`` holds the signal (the line is not cut) and then acts on it: the process ends
    with 143 (it was dropped before, and the command went on)."""
    status, err, _ = _signalled(HELD, [], tmp_path)
    assert status == 143 and err == "the line, whole\n", err


FORKED = """
import multiprocessing as mp, signal, time
from bulletnav.cli import interrupts
interrupts.start(["bench"], "bench")

def child():
    time.sleep(30)

with interrupts.signals_as_interrupt():
    p = mp.get_context("fork").Process(target=child)
    p.start()
    print("ready", flush=True)
    time.sleep(0.3)
    p.terminate()  # SIGTERM to the child alone: it must not reach the parent through the wakeup pipe
    p.join()
    time.sleep(2.0)
    print("parent lived", flush=True)
"""

LIBRARY = """
import signal, time
from bulletnav.cli import interrupts
interrupts.start(["sweep"], "sweep")
with interrupts.signals_as_interrupt():
    interrupts.library_handles_signals()
    ours = signal.getsignal(signal.SIGINT)
    def tune(signum, frame):  # Ray Tune's first Ctrl-C: take it, put the previous handler back
        signal.signal(signal.SIGINT, ours)
    signal.signal(signal.SIGINT, tune)
    print("ready", flush=True)
    t = time.monotonic()
    while time.monotonic() - t < 2.5:
        pass
    print("library saved and ended", flush=True)
"""


def test_a_forked_child_and_a_library_that_takes_ctrl_c_do_not_end_the_command(tmp_path):
    """A child forked inside a command gets its signal alone (it wrote into the parent's wakeup
    pipe, and the parent ended itself); a library that takes Ctrl-C itself (Ray Tune: it puts our
    handler back after its own) keeps it, and the command goes on."""
    for code, sig, done in ((FORKED, None, "parent lived"), (LIBRARY, signal.SIGINT, "library saved and ended")):
        out = tmp_path / "out"
        with out.open("wb") as o:
            proc = subprocess.Popen([sys.executable, "-c", code], cwd=ROOT, stdout=subprocess.PIPE, stderr=o,
                                    preexec_fn=_as_in_a_terminal)
            assert proc.stdout.readline().strip() == b"ready"
            if sig is not None:
                time.sleep(0.2)
                proc.send_signal(sig)
            rest = proc.stdout.read().decode()
            status = proc.wait(timeout=HANG_S)
        assert status == 0 and done in rest, (status, rest, out.read_text()[-2000:])
        assert "interrupted at once" not in out.read_text()
