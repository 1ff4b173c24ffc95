"""Reinforcement learning: smoke training of every algorithm through the CLI, save/load,
seeded determinism, evaluation output and model-file errors, atomic checkpoints."""

from __future__ import annotations

import json
import os
import zipfile
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch

import bulletnav  # noqa: F401
from bulletnav.cli import main
from bulletnav.errors import ModelError
from bulletnav.rl.common import atomic_save_model, load_model

ENV_ID = "bulletnav/Warehouse-v0"


def _train(tmp_path: Path, algo: str, seed: int = 0, steps: int = 1024, name: str | None = None, extra=()) -> Path:
    out = tmp_path / (name or algo)
    argv = ["train", "--algo", algo, "--timesteps", str(steps), "--n-envs", "2", "--seed", str(seed),
            "--out", str(out), "--eval-freq", str(steps), "--eval-episodes", "2", "--checkpoint-freq", "512",
            "--no-progress", *extra]
    assert main(argv) == 0
    return out


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory):
    return _train(tmp_path_factory.mktemp("rl"), "ppo")


@pytest.mark.parametrize("algo", ["sac", "td3", "a2c"])
def test_short_training_of_each_algorithm_then_evaluate(tmp_path, capsys, algo):
    out = _train(tmp_path, algo, steps=600)
    _check_run_dir(out, algo)
    assert main(["evaluate", "--model", str(out / "model.zip"), "--episodes", "1", "--json"]) == 0
    result = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert result["episodes"] == 1


def _check_run_dir(out: Path, algo: str) -> None:
    for name in ("model.zip", "model.json", "run.json", "config.json", "learning_curve.png", "eval_history.json",
                 "checkpoints/last.zip"):
        assert (out / name).is_file(), name
    run = json.loads((out / "run.json").read_text())
    assert run["algo"] == algo and run["seed"] == 0 and run["total_timesteps"] >= 512
    assert run["git_commit"] and run["wall_time_s"] > 0 and run["final_eval"]["success_rate"] >= 0
    assert run["command"]
    assert any((out / "tb").rglob("events.out.tfevents.*"))


def test_ppo_run_and_evaluate_report(ppo_run, capsys):
    _check_run_dir(ppo_run, "ppo")
    assert (ppo_run / "model_vecnormalize.pkl").is_file()  # reward normalisation stats beside the model
    assert main(["evaluate", "--model", str(ppo_run / "model.zip"), "--episodes", "2", "--seed", "5"]) == 0
    text = capsys.readouterr().out
    for piece in ("Running 2 evaluation episodes", "Initial distance to goal", "EVALUATION RESULTS",
                  "Success rate:", "Average reward:", "Average episode length:", "Average distance:", "SPL"):
        assert piece in text
    assert main(["evaluate", "--model", str(ppo_run / "model.zip"), "--episodes", "2", "--json"]) == 0
    result = json.loads(capsys.readouterr().out)
    for key in ("episodes", "success_rate", "mean_reward", "std_reward", "mean_length", "std_length",
                "mean_distance", "std_distance", "collision_rate", "spl", "per_episode"):
        assert key in result
    assert len(result["per_episode"]) == 2


def test_save_load_predict_gives_identical_actions(ppo_run, tmp_path):
    model, meta, _ = load_model(ppo_run / "model.zip")
    env = gym.make(ENV_ID, **meta["env_kwargs"])
    obs = np.stack([env.reset(seed=s)[0] for s in range(8)])
    env.close()
    before = model.predict(obs, deterministic=True)[0]
    copy = tmp_path / "copy.zip"
    atomic_save_model(model, copy)
    (tmp_path / "copy.json").write_text(json.dumps(meta))
    again, _, _ = load_model(copy)
    np.testing.assert_array_equal(before, again.predict(obs, deterministic=True)[0])


def test_two_seeded_ppo_runs_give_identical_parameters(ppo_run, tmp_path):
    other = _train(tmp_path, "ppo", seed=0, name="again")
    a = torch.load(zipfile.ZipFile(ppo_run / "model.zip").open("policy.pth"), weights_only=True)
    b = torch.load(zipfile.ZipFile(other / "model.zip").open("policy.pth"), weights_only=True)
    assert a.keys() == b.keys()
    for k in a:
        assert torch.equal(a[k], b[k]), k
    different = _train(tmp_path, "ppo", seed=1, name="seed1")
    c = torch.load(zipfile.ZipFile(different / "model.zip").open("policy.pth"), weights_only=True)
    assert any(not torch.equal(a[k], c[k]) for k in a)


def test_resume_continues_from_the_checkpoint(ppo_run, tmp_path):
    import shutil

    run = tmp_path / "resumed"
    shutil.copytree(ppo_run, run)
    done = json.loads((run / "run.json").read_text())["total_timesteps"]  # whole rollouts: >= the 1024 asked
    target = done + 2048
    assert main(["train", "--algo", "ppo", "--timesteps", str(target), "--n-envs", "2", "--out", str(run), "--resume",
                 "--eval-freq", "100000", "--eval-episodes", "1", "--no-progress"]) == 0
    record = json.loads((run / "run.json").read_text())
    assert record["resumed_from"] == done and record["total_timesteps"] >= target
    assert record["hyperparams"] == json.loads((ppo_run / "config.json").read_text())["hyperparams"]


def test_bad_model_files_give_clear_errors(tmp_path, ppo_run, capsys):
    missing = tmp_path / "nope.zip"
    truncated = tmp_path / "truncated.zip"
    truncated.write_bytes((ppo_run / "model.zip").read_bytes()[:3000])
    not_a_model = tmp_path / "layout.zip"
    with zipfile.ZipFile(not_a_model, "w") as zf:
        zf.writestr("hello.txt", "hi")
    text = tmp_path / "notes.zip"
    text.write_text("this is not a model")
    cases = [(missing, "not found"), (truncated, "not a model archive"), (not_a_model, "not a Stable-Baselines3 model"),
             (text, "not a model archive")]
    for path, message in cases:
        assert main(["evaluate", "--model", str(path), "--algo", "ppo"]) == 2
        err = capsys.readouterr().err
        assert str(path) in err and message in err and "Traceback" not in err
    # wrong kind: a PPO model loaded as SAC
    assert main(["evaluate", "--model", str(ppo_run / "model.zip"), "--algo", "sac"]) == 2
    assert "cannot load as SAC" in capsys.readouterr().err
    with pytest.raises(ModelError):
        load_model(missing)


def test_interrupted_checkpoint_write_leaves_the_old_model_intact(ppo_run, tmp_path, monkeypatch):
    model, _, _ = load_model(ppo_run / "model.zip")
    target = tmp_path / "last.zip"
    atomic_save_model(model, target)
    good = target.read_bytes()

    def crash(fd):  # the process dies after writing part of the new file, before the rename
        raise KeyboardInterrupt

    monkeypatch.setattr(os, "fsync", crash)
    with pytest.raises(KeyboardInterrupt):
        atomic_save_model(model, target)
    monkeypatch.undo()
    assert target.read_bytes() == good
    assert [p.name for p in tmp_path.iterdir()] == ["last.zip"]  # no temp file left behind
    (tmp_path / "last.json").write_text(json.dumps({"algo": "ppo"}))
    load_model(target)  # still a valid model


def test_compare_plots_runs_and_tabulates(ppo_run, tmp_path, capsys):
    png = tmp_path / "curves.png"
    assert main(["compare", str(ppo_run), "--out", str(png)]) == 0
    text = capsys.readouterr().out
    total = json.loads((ppo_run / "run.json").read_text())["total_timesteps"]
    assert f"| PPO | 0 | {total} |" in text and png.stat().st_size > 10_000
    history = json.loads((ppo_run / "eval_history.json").read_text())
    reached = next((h for h in history if h["success_rate"] >= 0.8), None)  # a tiny run: usually never
    assert "first >= 80 % at (steps, s)" in text
    assert (f"| {reached['timesteps']}, {round(reached['wall_time'])} |" if reached else "| never |") in text
    assert "final success, mean" not in text  # one seed per algorithm: no summary table
    assert main(["compare", str(ppo_run), str(ppo_run), "--out", str(png)]) == 0
    assert "| PPO | 2 |" in capsys.readouterr().out
    assert main(["compare", str(tmp_path / "missing"), "--out", str(png)]) == 2
    assert "not a finished training run" in capsys.readouterr().err


def test_hyperparams_file_replaces_the_packaged_one(tmp_path, capsys):
    import yaml

    from bulletnav.rl.common import load_hyperparams

    hp = load_hyperparams("ppo")
    hp.update(n_steps=64, batch_size=64, n_epochs=1)
    hp["env_kwargs"] = {**hp["env_kwargs"], "reward_collision": -7.0}
    conf = tmp_path / "mine.yml"
    conf.write_text(yaml.safe_dump({ENV_ID: hp}))
    out = _train(tmp_path, "ppo", steps=256, extra=("--hyperparams", str(conf)))
    record = json.loads((out / "run.json").read_text())
    assert record["hyperparams"]["n_steps"] == 64 and record["env_kwargs"]["reward_collision"] == -7.0
    assert record["total_timesteps"] == 256  # 2 envs x 64 steps x 2 rollouts

    bad = {"missing.yml": None, "other.yml": yaml.safe_dump({"CartPole-v1": {"policy": "MlpPolicy"}}),
           "broken.yml": "bulletnav/Warehouse-v0: [unclosed"}
    for name, text in bad.items():
        path = tmp_path / name
        if text is not None:
            path.write_text(text)
        capsys.readouterr()
        argv = ["train", "--algo", "ppo", "--timesteps", "64", "--out", str(tmp_path / "never"), "--hyperparams", str(path)]
        assert main(argv) == 2, name
        err = capsys.readouterr().err
        assert name in err and "Traceback" not in err, err
    assert not (tmp_path / "never").exists()
