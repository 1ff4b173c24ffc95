"""Reinforcement learning: smoke training of every algorithm through the CLI, save/load,
seeded determinism, evaluation output and model-file errors, atomic checkpoints; the policy
protocol the SB3 adapter shares with the navigator; the training-only ``collision_terminates``
option and the upgrade of hyperparameter files that still say ``collision_terminal``."""

from __future__ import annotations

import json
import logging
import math
import os
import re
import statistics
import subprocess
import zipfile
from dataclasses import asdict
from pathlib import Path

import gymnasium as gym
import numpy as np
import pytest
import torch
import yaml

import bulletnav  # noqa: F401
from bulletnav.cli import main
from bulletnav.config import asset_path
from bulletnav.control.navigator import Navigator, NavigatorConfig
from bulletnav.errors import ModelError
from bulletnav.evaluation import run_episodes
from bulletnav.policy import Policy
from bulletnav.provenance import command_line
from bulletnav.rl.callbacks import EVAL_KEYS
from bulletnav.rl.envs import EVAL_SEED_BASE, evaluation_env_kwargs, make_env_fn
from bulletnav.rl.hyperparams import load_hyperparams, upgrade_hyperparams
from bulletnav.rl.io import atomic_save_model, load_model
from bulletnav.rl.policy import SB3Policy
from bulletnav.rl.train import auto_eval_freq
from rollouts import episode_rows

ENV_ID = "bulletnav/Warehouse-v0"
ROOT = Path(__file__).resolve().parents[1]
EMPTY = str(asset_path("worlds", "empty.yaml"))
EVAL_EPISODES = 2
"""``--eval-episodes`` of every run trained here."""
_HEAD: dict[Path, str] = {}
"""The checkout's HEAD when each run started (a commit may land while it trains)."""


def _train(tmp_path: Path, algo: str, seed: int = 0, steps: int = 1024, name: str | None = None, extra=()) -> Path:
    out = tmp_path / (name or algo)
    argv = ["train", "--algo", algo, "--timesteps", str(steps), "--n-envs", "2", "--seed", str(seed),
            "--out", str(out), "--eval-freq", str(max(steps, 1)), "--eval-episodes", str(EVAL_EPISODES),
            "--checkpoint-freq", "512", "--no-progress", *extra]
    _HEAD[out] = _head_commit()
    assert main(argv) == 0
    return out


def _weights(model_zip: Path) -> dict:
    """The policy's tensors as a model zip stores them."""
    return torch.load(zipfile.ZipFile(model_zip).open("policy.pth"), weights_only=True)


def _evaluate_json(capsys, model: Path, episodes: int, seed: int) -> dict:
    """``bulletnav evaluate --json`` on ``model`` for episodes ``seed .. seed + episodes - 1``."""
    capsys.readouterr()
    assert main(["evaluate", "--model", str(model), "--episodes", str(episodes), "--seed", str(seed), "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def _head_commit() -> str:
    done = subprocess.run(["git", "rev-parse", "HEAD"], cwd=ROOT, capture_output=True, text=True, timeout=120)
    return done.stdout.strip() if done.returncode == 0 else "unknown"


def _landed_between(commit: str, first: str) -> bool:
    """``commit`` is ``first`` or a commit made after it on the way to today's HEAD (commits may
    land while a run trains)."""
    def ancestor(a: str, b: str) -> bool:
        return subprocess.run(["git", "merge-base", "--is-ancestor", a, b], cwd=ROOT, capture_output=True,
                              timeout=120).returncode == 0

    return commit == first or (ancestor(first, commit) and ancestor(commit, "HEAD"))


@pytest.fixture(scope="module")
def ppo_run(tmp_path_factory):
    return _train(tmp_path_factory.mktemp("rl"), "ppo")


@pytest.mark.slow
@pytest.mark.parametrize("algo", ["sac", "td3", "a2c"])
def test_short_training_of_each_algorithm_then_evaluate(tmp_path, capsys, algo):
    out = _train(tmp_path, algo, steps=600)
    _check_run_dir(out, algo)
    # `bulletnav evaluate --json` on the saved model: the whole of stdout one document, its episodes
    # those asked for, and its figures the recorded final evaluation's
    _check_final_evaluation(out, capsys)


def _check_run_dir(out: Path, algo: str) -> None:
    for name in ("model.zip", "model.json", "run.json", "config.json", "learning_curve.png", "eval_history.json",
                 "checkpoints/last.zip"):
        assert (out / name).is_file(), name
    run = json.loads((out / "run.json").read_text())
    meta = json.loads((out / "model.json").read_text())
    history = json.loads((out / "eval_history.json").read_text())
    assert run["algo"] == algo and run["seed"] == 0 and run["total_timesteps"] >= 512
    assert meta["algo"] == algo and meta["timesteps"] == run["total_timesteps"]
    # the settings trained with are the packaged file's (collision_terminates included)
    packaged = load_hyperparams(algo)
    assert run["env_kwargs"] == meta["env_kwargs"] == packaged["env_kwargs"]
    # provenance: this checkout's HEAD, this process's command line, and the training's wall time
    # in seconds to 0.1 s (how long it took is a benchmark's business: no bound on it here)
    assert _landed_between(run["git_commit"].removesuffix("-dirty"), _HEAD[out]), (run["git_commit"], _HEAD[out])
    assert run["command"] == command_line()
    assert run["wall_time_s"] > 0.0 and run["wall_time_s"] == round(run["wall_time_s"], 1)
    assert run["final_eval"] == history[-1] and history[-1]["timesteps"] == run["total_timesteps"]
    assert any((out / "tb").rglob("events.out.tfevents.*"))


def _check_final_evaluation(out: Path, capsys) -> None:
    """The recorded final evaluation is the saved model's: `bulletnav evaluate` on model.zip
    for the same unseen episodes (seeds from EVAL_SEED_BASE) gives the same figures."""
    final = json.loads((out / "run.json").read_text())["final_eval"]
    evaluated = _evaluate_json(capsys, out / "model.zip", EVAL_EPISODES, EVAL_SEED_BASE)
    assert evaluated["episodes"] == EVAL_EPISODES
    assert [r["seed"] for r in evaluated["per_episode"]] == [EVAL_SEED_BASE + k for k in range(EVAL_EPISODES)]
    for key in EVAL_KEYS:
        assert final[key] == pytest.approx(evaluated[key], rel=1e-9, abs=1e-12), (
            f"{key}: run.json's final evaluation {final[key]} differs from `bulletnav evaluate` on the saved "
            f"model {evaluated[key]} (same seeds): the recorded evaluation is not of the saved model")
    # and against a second computation that shares no evaluation code: the episodes stepped here
    rows = episode_rows(out / "model.zip", EVAL_EPISODES, EVAL_SEED_BASE)
    n = len(rows)
    assert final["success_rate"] == sum(r["success"] for r in rows) / n
    assert final["collision_rate"] == sum(r["collision"] for r in rows) / n
    assert final["mean_reward"] == pytest.approx(statistics.fmean(r["reward"] for r in rows), rel=1e-9)
    assert final["std_reward"] == pytest.approx(statistics.pstdev(r["reward"] for r in rows), rel=1e-6, abs=1e-9)
    assert final["mean_length"] == pytest.approx(statistics.fmean(r["steps"] for r in rows), rel=1e-12)


def test_the_evaluation_period_is_a_fifth_of_a_short_run_and_25000_steps_of_a_long_one():
    assert [auto_eval_freq(t) for t in (1, 4, 8_000, 8_001, 124_999, 125_000, 500_000)] == [
        1, 1, 1_600, 1_601, 25_000, 25_000, 25_000]


@pytest.mark.slow
def test_a_run_shorter_than_the_evaluation_period_draws_a_curve_of_five_points(tmp_path):
    """1,024 steps with no --eval-freq: evaluated every 205 steps (a fifth), the end included, so
    the learning curve has five points; run.json says the period it used."""
    out = tmp_path / "short"
    assert main(["train", "--algo", "ppo", "--timesteps", "1024", "--n-envs", "2", "--vec-env", "dummy", "--out", str(out),
                 "--eval-episodes", "1", "--checkpoint-freq", "512", "--no-progress"]) == 0
    record = json.loads((out / "run.json").read_text())
    steps = [row["timesteps"] for row in json.loads((out / "eval_history.json").read_text())]
    assert record["eval_freq"] == 205 and len(steps) >= 5 and steps[-1] == record["total_timesteps"] == 1024
    assert [s // 205 for s in steps[:-1]] == [1, 2, 3, 4] and (out / "learning_curve.png").is_file()  # (2 envs: even counts)


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
def test_ppo_final_evaluation_is_the_saved_models(ppo_run, capsys):
    # 1024 steps with --eval-freq 1024: the last in-training evaluation falls on the final timestep
    _check_final_evaluation(ppo_run, capsys)


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
def test_ppo_run_and_evaluate_report(ppo_run, capsys):
    _check_run_dir(ppo_run, "ppo")
    assert (ppo_run / "model_vecnormalize.json").is_file()  # reward normalisation stats beside the model, as numbers
    assert (ppo_run / "model.safetensors").is_file() and json.loads((ppo_run / "model.json").read_text())["format"]
    assert not list(ppo_run.rglob("*.pkl"))  # no pickle anywhere in a run
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
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


@pytest.mark.slow
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
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
    # the wall clock runs on from the first part's: the total is the first part's (its checkpoint)
    # plus this part's, each rounded to 0.1 s; the new checkpoint counts on from the first part's
    first = json.loads((ppo_run / "checkpoints" / "last.json").read_text())["wall_time"]
    assert record["wall_time_total_s"] == pytest.approx(first + record["wall_time_s"], abs=0.1 + 1e-9)
    assert json.loads((run / "checkpoints" / "last.json").read_text())["wall_time"] >= first


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
def test_init_from_starts_a_new_run_from_a_models_weights(ppo_run, tmp_path, capsys):
    def weights(run: Path) -> dict:
        return _weights(run / "model.zip")

    # no steps: the saved model is the one it started from, statistics included
    copy = _train(tmp_path, "ppo", steps=0, name="copy", extra=("--init-from", str(ppo_run / "model.zip")))
    a, b = weights(ppo_run), weights(copy)
    assert all(torch.equal(a[k], b[k]) for k in a)
    r1 = json.loads((ppo_run / "model_vecnormalize.json").read_text())["ret"]
    r2 = json.loads((copy / "model_vecnormalize.json").read_text())["ret"]
    assert r1["count"] == r2["count"] and r1["var"] == r2["var"]
    record = json.loads((copy / "run.json").read_text())
    assert record["init_from"] == str(ppo_run / "model.zip") and record["resumed_from"] is None
    # one rollout more: it learns on from those weights (not from fresh ones: the module's run
    # is one rollout of a fresh start with the same seed, and its weights are not these)
    tuned = _train(tmp_path, "ppo", steps=512, name="tuned", extra=("--init-from", str(ppo_run / "model.zip")))
    c = weights(tuned)
    assert any(not torch.equal(c[k], a[k]) for k in a)
    assert json.loads((tuned / "run.json").read_text())["total_timesteps"] == 1024
    # a model of other spaces is refused by name
    capsys.readouterr()
    assert main(["train", "--timesteps", "0", "--n-envs", "2", "--out", str(tmp_path / "bad"), "--no-progress",
                 "--init-from", str(ROOT / "models" / "ppo_mission.zip")]) == 2
    assert re.search(r"ppo_mission\.zip: its observation_space has shape \(62,\), this run's \(43,\)", capsys.readouterr().err)


@pytest.mark.slow
def test_stop_at_success_stops_when_an_evaluation_reaches_the_rate(tmp_path, capsys):
    shipped = ROOT / "models" / "ppo_warehouse.zip"
    weights = _weights
    # a start that already succeeds is evaluated before its first update and stops there:
    # the saved model is the start, and the record says at what steps and time it got there
    run = _train(tmp_path, "ppo", steps=4096, name="reached",
                 extra=("--init-from", str(shipped), "--stop-at-success", "0.5"))
    record = json.loads((run / "run.json").read_text())
    hit = record["reached_success"]
    assert hit["timesteps"] == 0 and hit["success_rate"] >= 0.5 and hit["wall_time"] > 0
    # (SB3 steps the envs once before its callback can stop it; no update follows)
    assert record["total_timesteps"] == 2 and record["stop_at_success"] == 0.5
    history = json.loads((run / "eval_history.json").read_text())
    assert [row["timesteps"] for row in history] == [0]
    a, b = weights(shipped), weights(run / "model.zip")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert "target success 50 %: reached at 0 steps" in capsys.readouterr().out
    # a fresh network does not reach 100 %: the whole budget is trained, the start evaluated too
    run = _train(tmp_path, "ppo", steps=1024, name="unreached", extra=("--stop-at-success", "1"))
    record = json.loads((run / "run.json").read_text())
    assert record["reached_success"] is None and record["total_timesteps"] == 1024
    assert [row["timesteps"] for row in json.loads((run / "eval_history.json").read_text())] == [0, 1024]
    assert "not reached in the budget" in capsys.readouterr().out
    # compare groups the two by their start and reads the rate the table asks for
    assert main(["compare", str(tmp_path / "reached"), str(run), "--group-by", "start", "--reach", "0.5",
                 "--out", str(tmp_path / "curves.png"), "--json"]) == 0
    rows = {r["group"]: r for r in json.loads(capsys.readouterr().out)}
    assert rows["from ppo_warehouse"]["reached_at"] == 0 and rows["scratch"]["reached_at"] is None
    assert (tmp_path / "curves.png").is_file()
    # a rate outside (0, 1] is refused by name
    with pytest.raises(SystemExit):
        main(["train", "--stop-at-success", "90", "--out", str(tmp_path / "bad")])
    assert "--stop-at-success: expected a rate above 0 and at most 1, got '90'" in capsys.readouterr().err


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
def test_hyperparams_file_replaces_the_packaged_one(tmp_path, capsys):
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


@pytest.mark.slow  # uses the module's smoke PPO training (14 s), or trains itself
def test_sb3_policy_and_navigator_run_the_same_episodes(ppo_run, capsys):
    """Both controllers are :class:`~bulletnav.policy.Policy` objects driven by the one
    ``run_episodes``: given the same seeds they get the same warehouses, starts and goals,
    and the adapter's episodes are exactly what ``bulletnav evaluate`` reports."""
    seed, episodes = 1000, 3
    model, meta, vecnorm = load_model(ppo_run / "model.zip")

    def run(env, policy):
        seen = []

        def on_reset(e, info):
            scene = e.unwrapped.scene
            seen.append({"layout": scene.layout, "start": scene.start, "goal": scene.goal,
                         "initial_distance": info["initial_distance"], "pose": tuple(float(v) for v in info["pose"])})

        return run_episodes(env, policy, episodes, seed, on_reset=on_reset), seen

    # the model acts in its evaluation env (normalised actions); the navigator in the default one
    rl_env = gym.make(ENV_ID, **evaluation_env_kwargs(meta["env_kwargs"]))
    nav_env = gym.make(ENV_ID)
    try:
        sb3 = SB3Policy(model, vecnorm)
        nav = Navigator(nav_env.unwrapped.scene, NavigatorConfig(planner="astar"))
        assert isinstance(sb3, Policy) and isinstance(nav, Policy)
        rl_results, rl_seen = run(rl_env, sb3)
        nav_results, nav_seen = run(nav_env, nav)
    finally:
        rl_env.close()
        nav_env.close()
    assert rl_seen == nav_seen  # same layouts, starts, goals and initial distances
    for r, n, ep in zip(rl_results, nav_results, rl_seen):
        assert r.seed == n.seed and r.initial_distance == n.initial_distance and r.shortest_path == n.shortest_path
        # independent of the env's bookkeeping: the straight line from the start to the goal
        assert r.initial_distance == pytest.approx(math.dist(ep["start"][:2], ep["goal"]), abs=1e-9)
        assert ep["pose"] == pytest.approx(ep["start"], abs=1e-6)  # the robot stood at the start
    assert len({ep["layout"] for ep in rl_seen}) == episodes  # three different warehouses

    # the adapter under run_episodes is what `bulletnav evaluate` runs: same episodes, same figures
    evaluated = _evaluate_json(capsys, ppo_run / "model.zip", episodes, seed)
    for r, row in zip(rl_results, evaluated["per_episode"]):
        mine = {k: v for k, v in asdict(r).items() if k not in ("wall_time", "plan_ms")}
        theirs = {k: v for k, v in row.items() if k != "wall_time"}
        assert mine == pytest.approx(theirs, rel=1e-12), r.episode


def _drive_into_the_wall(env) -> tuple[int, bool, bool, dict]:
    """Full speed straight at the east wall of the empty room, 1.35 m from the robot's nose."""
    env.reset(seed=0, options={"start": (3.5, 0.0, 0.0), "goal": (-3.0, 0.0)})
    forward = env.action_space.high.copy()  # top speed...
    forward[1] = 0.0  # ...and no turning (0 is the middle of the yaw range, normalised or not)
    for k in range(1, 301):
        _, _, terminated, truncated, info = env.step(forward)
        if terminated or truncated:
            return k, terminated, truncated, info
    raise AssertionError("no collision within 300 steps")


def test_collision_terminates_reaches_the_training_envs_and_evaluation_drops_it():
    env_kwargs = load_hyperparams("ppo")["env_kwargs"]
    assert env_kwargs["collision_terminates"] is True  # the shipped file asks for it
    train_env = make_env_fn({**env_kwargs, "world": EMPTY})()
    try:
        steps, terminated, truncated, info = _drive_into_the_wall(train_env)
    finally:
        train_env.close()
    assert terminated and not truncated  # a real end: bootstrapped as terminal by the learner
    assert info["collision"] and info["end_reason"] == "collision" and not info["is_success"]
    # where the wall is: the body's front face (0.15 m ahead of its centre) at the room's 5 m half-width
    assert 5.0 - 0.15 - 0.03 <= info["pose"][0] <= 5.0 - 0.15 + 0.005

    eval_kwargs = evaluation_env_kwargs({**env_kwargs, "world": EMPTY})
    assert "collision_terminates" not in eval_kwargs
    assert not any(k.startswith("reward_") for k in eval_kwargs)
    eval_env = gym.make(ENV_ID, **eval_kwargs)
    try:
        eval_steps, eval_terminated, eval_truncated, eval_info = _drive_into_the_wall(eval_env)
    finally:
        eval_env.close()
    # the same drive into the same wall, ended by the env's own rule: a collision truncates
    assert (eval_steps, eval_terminated, eval_truncated) == (steps, False, True)
    assert eval_info["collision"] and eval_info["end_reason"] == "collision"
    np.testing.assert_array_equal(eval_info["pose"], info["pose"])


@pytest.mark.parametrize("flag", [True, False])
def test_old_collision_terminal_key_is_upgraded(tmp_path, caplog, flag):
    today = load_hyperparams("ppo")
    old = {k: v for k, v in today.items() if k != "env_kwargs"}
    old["env_kwargs"] = {k: v for k, v in today["env_kwargs"].items() if k != "collision_terminates"}
    old["collision_terminal"] = flag  # how hyperparameter files said it before the env option existed
    path = tmp_path / "old.yml"
    path.write_text(yaml.safe_dump({ENV_ID: old}))
    with caplog.at_level(logging.WARNING, logger="bulletnav.rl.hyperparams"):
        upgraded = load_hyperparams("ppo", path=path)
    assert "collision_terminal" not in upgraded
    assert upgraded["env_kwargs"]["collision_terminates"] is flag
    if flag:
        assert upgraded == today  # exactly the packaged file's settings
    assert "collision_terminal" in caplog.text and str(path) in caplog.text
    assert upgrade_hyperparams(old) == upgraded and "collision_terminal" in old  # the input is left as it was
    assert upgrade_hyperparams(today) == today  # today's form passes through
    # and the upgraded settings reach the training env
    env = make_env_fn({**upgraded["env_kwargs"], "world": EMPTY})()
    try:
        assert env.unwrapped.config.task.collision_terminates is flag
        _, terminated, truncated, _ = _drive_into_the_wall(env)
    finally:
        env.close()
    assert (terminated, truncated) == (flag, not flag)


def test_compare_groups_runs_by_hyperparameter_file():
    from bulletnav.viz.compare import run_group

    record = {"algo": "ppo", "command": "bulletnav train --algo ppo --hyperparams 'my dir/ppo_dynamic_both.yml' --seed 1"}
    assert run_group(record, "algo") == "ppo"
    assert run_group(record, "hyperparams") == "ppo_dynamic_both"
    assert run_group({"algo": "sac", "command": "bulletnav train --hyperparams=x/sac_fast.yaml"}, "hyperparams") == "sac_fast"
    assert run_group({"algo": "sac", "command": "bulletnav train --algo sac"}, "hyperparams") == "sac (default)"
    assert run_group({"algo": "ppo", "init_from": None}, "start") == "scratch"
    assert run_group({"algo": "ppo", "init_from": "runs/bc/model.zip"}, "start") == "from bc"
    assert run_group({"algo": "ppo", "init_from": "models/ppo_dynamic.zip"}, "start") == "from ppo_dynamic"
    assert run_group({"algo": "ppo", "env_kwargs": {"physics": "kinematic"}}, "physics") == "physics=kinematic"
    assert run_group({"algo": "ppo", "env_kwargs": {"layouts_every": 4}}, "physics") == "physics=default"
    with pytest.raises(ValueError, match="group_by must be one of algo, hyperparams, start, physics"):
        run_group(record, "arm")


@pytest.mark.slow
def test_run_record_says_where_the_time_went(ppo_run):
    """``run.json``'s throughput: env steps per second of the training's wall time and the
    shares of that time in the envs, in evaluation and in the learner (they add up to 1), and
    the vector env 'auto' chose (2 envs on this machine's cores)."""
    import os

    record = json.loads((ppo_run / "run.json").read_text())
    t = record["throughput"]
    assert t["env_share"] + t["eval_share"] + t["learner_share"] == pytest.approx(1.0, abs=2e-4)
    assert 0 < t["env_share"] < 1 and 0 < t["eval_share"] < 1 and 0 < t["learner_share"] < 1
    # the rate is the steps learning took over the time it ran (a rate, not a bound on time)
    assert t["env_steps_per_s"] * t["seconds"] == pytest.approx(record["total_timesteps"], rel=0.01)
    assert record["vec_env"] == ("subproc" if (os.cpu_count() or 1) > 1 else "dummy")


def test_vec_env_choice():
    from bulletnav.rl.train import resolve_vec_env

    assert resolve_vec_env("subproc", 1) == resolve_vec_env("auto", 1) == "dummy"
    assert resolve_vec_env("dummy", 4) == "dummy" and resolve_vec_env("subproc", 4) == "subproc"
    with pytest.raises(ValueError, match="vec_env must be"):
        resolve_vec_env("threads", 4)
