"""Nothing lost: a training and a benchmark killed (SIGKILL, no clean-up) at several moments leave
only whole files under their names (temporary files are hidden, ``.name...``), and ``--resume``
then finishes; the resumed benchmark's rows are an uninterrupted run's."""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import pytest

import hang
from hang import HANG_S

ROOT = Path(__file__).resolve().parents[1]
TINY = ROOT / "tests" / "data" / "benchmark_tiny.yaml"
GOLDEN = ROOT / "tests" / "golden" / "benchmark_tiny.json"

TRAIN = ["train", "--algo", "ppo", "--timesteps", "4096", "--n-envs", "2", "--vec-env", "dummy",
         "--checkpoint-freq", "512", "--eval-freq", "1024", "--eval-episodes", "1", "--no-progress"]


def _start(*args: str) -> subprocess.Popen:
    """The CLI in its own process group, so that a kill takes its workers with it."""
    return subprocess.Popen([sys.executable, "-m", "bulletnav.cli", *args], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, start_new_session=True)


def _kill(proc: subprocess.Popen) -> bool:
    """SIGKILL the run and its workers; whether it was still running."""
    running = proc.poll() is None
    try:
        os.killpg(proc.pid, signal.SIGKILL)
    except ProcessLookupError:
        pass  # it had finished
    hang.communicate(proc, "a SIGKILLed run (its pipes never closed)")
    return running


def _wait_for(proc: subprocess.Popen, ready, timeout: float = HANG_S) -> None:
    t_end = time.monotonic() + timeout
    while not ready() and proc.poll() is None:
        if time.monotonic() >= t_end:
            _kill(proc)
            pytest.fail(f"the run never got to the point to kill it in {timeout:.0f} s: a hang? (a hang detector, "
                        "not a speed check)", pytrace=False)
        time.sleep(0.02)


def _check_whole(folder: Path) -> int:
    """Every file whose name does not start with '.' is complete; returns how many were checked."""
    checked = 0
    for path in folder.rglob("*"):
        if not path.is_file() or path.name.startswith(".") or any(p.startswith(".") for p in path.relative_to(folder).parts):
            continue
        if path.suffix == ".json":
            json.loads(path.read_text())
        elif path.suffix == ".zip":
            with zipfile.ZipFile(path) as zf:
                assert zf.testzip() is None, path
        elif path.suffix == ".safetensors":
            from safetensors.numpy import load_file

            load_file(str(path))
        elif path.suffix == ".png":
            from PIL import Image

            with Image.open(path) as im:
                im.load()
        elif path.suffix == ".jsonl":  # append-only: only a torn last line may be incomplete (dropped on resume)
            for line in path.read_text().splitlines()[:-1]:
                json.loads(line)
        else:
            continue
        checked += 1
    return checked


@pytest.mark.slow
def test_a_killed_training_leaves_whole_files_and_resumes(tmp_path):
    out = tmp_path / "run"
    rng = random.Random(2024)
    killed = []
    first = _start(*TRAIN, "--out", str(out))  # killed as its first checkpoint appears
    _wait_for(first, lambda: (out / "checkpoints" / "last.zip").exists())
    assert _kill(first)
    assert _check_whole(out) >= 2
    for delay in (rng.uniform(0.5, 3.0), rng.uniform(3.0, 6.0)):  # killed at seeded moments of a resumed run
        proc = _start(*TRAIN, "--out", str(out), "--resume")
        time.sleep(delay)
        killed.append(_kill(proc))
        _check_whole(out)
    done = _start(*TRAIN, "--out", str(out), "--resume")
    _, err = hang.communicate(done, "the resumed training")
    assert done.returncode == 0, err[-2000:]
    assert _check_whole(out) >= 5
    assert json.loads((out / "run.json").read_text())["total_timesteps"] >= 4096
    assert (out / "model.zip").is_file()
    # the final model read with zipfile and json (SB3's zip layout, no bulletnav code): it was
    # trained through the whole budget of 4096 steps
    with zipfile.ZipFile(out / "model.zip") as zf:
        trained = json.loads(zf.read("data"))["num_timesteps"]
    assert trained >= 4096
    assert killed == [True, True]  # both resumed runs were killed while running


@pytest.mark.slow
def test_a_killed_benchmark_leaves_whole_files_and_resumes_to_the_same_rows(tmp_path):
    out = tmp_path / "bench"
    argv = ["benchmark", str(TINY), "--out", str(out), "--workers", "1", "--json"]
    log = out / "episodes.jsonl"
    for rows in (1, 5):  # killed once some rows are written, then again in the resumed run
        proc = _start(*argv, *(["--resume"] if log.exists() else []))
        _wait_for(proc, lambda n=rows: log.is_file() and log.read_text().count("\n") >= n)
        assert _kill(proc)
        assert not (out / "results.json").exists() or json.loads((out / "results.json").read_text())
        _check_whole(out)
    done = _start(*argv, "--resume")
    _, err = hang.communicate(done, "the resumed benchmark")
    assert done.returncode == 0, err[-2000:]
    _check_whole(out)
    expected = json.loads(GOLDEN.read_text())["episodes"]
    assert json.loads((out / "results.json").read_text())["episodes"] == expected


def _tiny_model_and_stats():
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("CartPole-v1")]))
    return PPO("MlpPolicy", venv, n_steps=16, batch_size=16, device="cpu", seed=0), venv


def _checkpoint_set(out: Path) -> tuple[int, int, float]:
    """The step of the weights, of ``last.json`` and the statistics' first mean, read back."""
    from stable_baselines3 import PPO

    from bulletnav.rl.safe import load_zip

    folder = out / "checkpoints"
    model = load_zip(folder / "last.zip", PPO)
    stats = json.loads((folder / "last_vecnormalize.json").read_text())
    return int(model.num_timesteps), json.loads((folder / "last.json").read_text())["timesteps"], stats["obs"]["mean"][0]


def _read_set_with_other_readers(out: Path) -> tuple[int, int, float, dict]:
    """The same set read without bulletnav: ``last.zip`` through zipfile and json (SB3's zip
    layout: a ``data`` JSON, ``policy.pth`` a torch state dict, read with ``weights_only``), the
    JSON files through json. Returns (weights' step, last.json's step, first mean, weights)."""
    import io

    import torch

    folder = out / "checkpoints"
    with zipfile.ZipFile(folder / "last.zip") as zf:
        steps = json.loads(zf.read("data"))["num_timesteps"]
        weights = torch.load(io.BytesIO(zf.read("policy.pth")), weights_only=True, map_location="cpu")
    stats = json.loads((folder / "last_vecnormalize.json").read_text())
    return steps, json.loads((folder / "last.json").read_text())["timesteps"], stats["obs"]["mean"][0], weights


def _shift_weights(model, by: float) -> None:
    """Make the next checkpoint's weights differ from the previous one's."""
    import torch

    with torch.no_grad():
        for param in model.policy.parameters():
            param.add_(by)


def _same_weights(read: dict, model) -> bool:
    import torch

    mine = model.policy.state_dict()
    return read.keys() == mine.keys() and all(torch.equal(read[k], mine[k]) for k in mine)


class _Killed(BaseException):
    """Stands for a SIGKILL: nothing after it runs."""


@pytest.mark.parametrize("moves", [0, 1, 2])
def test_a_checkpoint_interrupted_after_its_commit_is_completed_whole(tmp_path, monkeypatch, moves):
    """Weights, statistics and step count of a checkpoint are one set: a run killed while moving
    a committed set into place (after 0, 1 or 2 of its 3 files) leaves a set that
    ``finish_checkpoint`` completes, never weights of one step beside statistics of another."""
    from bulletnav.rl import callbacks

    model, venv = _tiny_model_and_stats()
    venv.obs_rms.mean[0] = 1.5
    callbacks.save_checkpoint(model, tmp_path, venv, {"wall_time": 1.0})
    assert _checkpoint_set(tmp_path) == (0, 0, 1.5)
    model.num_timesteps, venv.obs_rms.mean[0] = 512, 2.5  # the next checkpoint: other weights and statistics
    _shift_weights(model, 0.25)
    real, done = os.replace, []

    def replace(src, dst):
        if Path(src).parent.name == ".pending" and Path(dst).parent.name == "checkpoints":  # a move into place
            if len(done) == moves:
                raise _Killed
            done.append(src)
        real(src, dst)

    monkeypatch.setattr(os, "replace", replace)
    with pytest.raises(_Killed):
        callbacks.save_checkpoint(model, tmp_path, venv)
    monkeypatch.setattr(os, "replace", real)
    assert callbacks.finish_checkpoint(tmp_path) is True
    assert _checkpoint_set(tmp_path) == (512, 512, 2.5)
    # read back with zipfile, json and torch (no bulletnav code): the hand-set step, statistics
    # and the shifted weights, all of the second set
    *figures, weights = _read_set_with_other_readers(tmp_path)
    assert tuple(figures) == (512, 512, 2.5) and _same_weights(weights, model)
    assert not (tmp_path / "checkpoints" / ".pending").exists()
    assert callbacks.finish_checkpoint(tmp_path) is False  # nothing left to do


def test_a_checkpoint_interrupted_before_its_commit_leaves_the_previous_set(tmp_path, monkeypatch):
    from bulletnav.rl import callbacks

    model, venv = _tiny_model_and_stats()
    venv.obs_rms.mean[0] = 1.5
    callbacks.save_checkpoint(model, tmp_path, venv)
    first = {k: v.clone() for k, v in model.policy.state_dict().items()}
    model.num_timesteps, venv.obs_rms.mean[0] = 512, 2.5
    _shift_weights(model, 0.25)
    real = callbacks.write_json

    def write_json(path, data):
        if Path(path).name == "COMMIT":
            raise _Killed
        real(path, data)

    monkeypatch.setattr(callbacks, "write_json", write_json)
    with pytest.raises(_Killed):
        callbacks.save_checkpoint(model, tmp_path, venv)
    assert (tmp_path / "checkpoints" / ".pending" / "last.zip").is_file()  # the new set was written, not committed
    assert callbacks.finish_checkpoint(tmp_path) is False
    assert _checkpoint_set(tmp_path) == (0, 0, 1.5)
    assert not (tmp_path / "checkpoints" / ".pending").exists()
    # read back with zipfile, json and torch: the first set whole, its weights the unshifted ones
    *figures, weights = _read_set_with_other_readers(tmp_path)
    assert tuple(figures) == (0, 0, 1.5)
    assert weights.keys() == first.keys() and all(bool((weights[k] == first[k]).all()) for k in first)
    assert not _same_weights(weights, model)


def test_a_checkpoint_without_statistics_removes_the_older_sets(tmp_path):
    """A committed set without normalisation statistics does not leave an older set's beside it."""
    from bulletnav.rl import callbacks

    model, venv = _tiny_model_and_stats()
    callbacks.save_checkpoint(model, tmp_path, venv)
    callbacks.save_checkpoint(model, tmp_path, None)
    assert sorted(p.name for p in (tmp_path / "checkpoints").iterdir()) == ["last.json", "last.zip"]


def test_a_checkpoint_commit_naming_other_files_is_refused(tmp_path):
    from bulletnav.errors import ModelError
    from bulletnav.rl import callbacks

    pending = tmp_path / "checkpoints" / ".pending"
    pending.mkdir(parents=True)
    (pending / "COMMIT").write_text(json.dumps({"files": ["../../outside.txt"]}))
    with pytest.raises(ModelError, match="COMMIT: not a checkpoint commit record"):
        callbacks.finish_checkpoint(tmp_path)
