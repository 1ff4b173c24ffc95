"""What a new user types that the CLI must refuse in one line (exit 2, naming the argument, the
value and what is allowed), or must do right: a model's own env by default, a model and an env
that do not fit, outputs of one run never replacing another's, rollout-sized training."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np
import pytest
from gymnasium import spaces

from bulletnav.cli import build_parser, main
from bulletnav.cli.evaluate import demo_folder
from bulletnav.cli.train import rollout_note
from bulletnav.errors import ModelError
from bulletnav.rl.compat import check_model_fits, space_mismatch

ROOT = Path(__file__).resolve().parents[1]
MODELS = ROOT / "models"
EMPTY = str(ROOT / "bulletnav" / "assets" / "worlds" / "empty.yaml")


def _usage_error(argv: list[str], capsys) -> str:
    """The one stderr line of an argparse refusal (exit 2)."""
    with pytest.raises(SystemExit) as exc:
        main(argv)
    assert exc.value.code == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.strip().splitlines()
    assert len(lines) == 1, captured.err
    return lines[0]


# ------------------------------------------------------------------ counts and numbers


@pytest.mark.parametrize("argv, option, value, allowed", [
    (["evaluate", "--model", "m.zip", "--episodes", "-3"], "--episodes", "-3", ">= 1"),
    (["evaluate", "--model", "m.zip", "--episodes", "0"], "--episodes", "0", ">= 1"),
    (["demo", "--episodes", "0"], "--episodes", "0", ">= 1"),
    (["demo", "--episodes", "-1"], "--episodes", "-1", ">= 1"),
    (["navigate", "--episodes", "0"], "--episodes", "0", ">= 1"),
    (["navigate", "--episodes", "two"], "--episodes", "'two'", ">= 1"),
    (["navigate", "--obstacles", "-1"], "--obstacles", "-1", ">= 0"),
    (["evaluate", "--model", "m.zip", "--obstacles", "-1"], "--obstacles", "-1", ">= 0"),
    (["navigate", "--goals", "0"], "--goals", "0", ">= 1"),
    (["navigate", "--seed", "-1"], "--seed", "-1", "from 0 to 4294967295"),
    (["train", "--out", "r", "--timesteps", "-5"], "--timesteps", "-5", ">= 0"),
    (["train", "--out", "r", "--n-envs", "0"], "--n-envs", "0", ">= 1"),
    (["train", "--out", "r", "--eval-freq", "0"], "--eval-freq", "0", ">= 1"),
    (["train", "--out", "r", "--eval-episodes", "-2"], "--eval-episodes", "-2", ">= 1"),
    (["train", "--out", "r", "--checkpoint-freq", "0"], "--checkpoint-freq", "0", ">= 1"),
    (["sweep", "s.yaml", "--optimize", "0"], "--optimize", "0", ">= 1"),
    (["sweep", "s.yaml", "--num-cpus", "0"], "--num-cpus", "0", ">= 1"),
    (["benchmark", "--workers", "0"], "--workers", "0", ">= 1"),
    (["benchmark", "--screenshot-tab", "-1"], "--screenshot-tab", "-1", ">= 0"),
    (["bench", "env", "--resets", "0"], "--resets", "0", ">= 1"),
    (["bench", "env", "--rounds", "0"], "--rounds", "0", ">= 1"),
    (["bench", "env", "--steps", "-1"], "--steps", "-1", ">= 0"),
    (["bench", "planners", "--episodes", "0"], "--episodes", "0", ">= 1"),
    (["bench", "physics", "--policy-episodes", "-1"], "--policy-episodes", "-1", ">= 0"),
    (["view", "--seconds", "-1"], "--seconds", "'-1'", "seconds > 0"),
    (["view", "--seconds", "nan"], "--seconds", "'nan'", "seconds > 0"),
])
def test_counts_and_numbers_out_of_range_are_one_line(argv, option, value, allowed, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # nothing may be created: checked below
    line = _usage_error(argv, capsys)
    assert line.startswith(f"bulletnav {argv[0]}: error: argument {option}")
    assert f"got {value}" in line and allowed in line
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("argv, option, value, allowed", [
    (["navigate", "--video", "x.avi"], "--video", "'x.avi'", ".mp4 or .gif"),
    (["evaluate", "--model", "m.zip", "--video", "clip"], "--video", "'clip'", ".mp4 or .gif"),
    (["demo", "--video", "x.mov"], "--video", "'x.mov'", ".mp4 or .gif"),
    (["navigate", "--plot", "paths.jpg"], "--plot", "'paths.jpg'", ".png"),
    (["compare", "runs/a", "--out", "curves.pdf"], "--out", "'curves.pdf'", ".png"),
])
def test_output_suffixes_are_checked_when_parsing(argv, option, value, allowed, capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    line = _usage_error(argv, capsys)
    assert line.startswith(f"bulletnav {argv[0]}: error: argument {option}: {value}") and allowed in line
    assert list(tmp_path.iterdir()) == []


def test_zero_timesteps_stay_allowed_and_defaults_parse():
    """``--timesteps 0`` copies a model (``--init-from``); every default passes its own type."""
    args = build_parser().parse_args(["train", "--out", "r", "--timesteps", "0"])
    assert args.timesteps == 0 and args.n_envs is None
    for argv in (["navigate"], ["evaluate", "--model", "m.zip"], ["demo"], ["view"], ["benchmark"], ["bench", "env"]):
        build_parser().parse_args(argv)


# ------------------------------------------------------------------ train: whole rollouts


def _train_args(**over) -> argparse.Namespace:
    argv = ["train", "--out", "r"]
    for key, value in over.items():
        argv += [f"--{key.replace('_', '-')}", str(value)]
    return build_parser().parse_args(argv)


def test_rollout_note_says_how_many_steps_will_be_trained():
    note = rollout_note(_train_args(timesteps=100, n_envs=2))  # ppo.yml: n_steps 512
    assert note == ("--timesteps 100 is not a whole number of rollouts: PPO learns in rollouts of n_steps 512 x 2 envs "
                    "= 1,024 steps, so 1,024 steps will be trained (pass a multiple of 1,024 to train exactly that)")
    assert "3,072 steps will be trained" in rollout_note(_train_args(timesteps=2049, n_envs=2))
    assert rollout_note(_train_args(timesteps=2048, n_envs=2)) is None  # whole rollouts: nothing to say
    assert rollout_note(_train_args(timesteps=0, n_envs=2)) is None  # --init-from copies: no rollout
    assert "A2C learns in rollouts of n_steps 8 x 3 envs = 24 steps, so 120 steps" in \
        rollout_note(_train_args(algo="a2c", timesteps=100, n_envs=3))
    # sac.yml: train_freq 1, so 2 envs collect 2 steps per update: 101 is one short of a whole 102
    assert rollout_note(_train_args(algo="sac", timesteps=101, n_envs=2)) == (
        "--timesteps 101 is not a whole number of rollouts: SAC collects train_freq 1 x 2 envs per update = 2 steps, "
        "so 102 steps will be trained (pass a multiple of 2 to train exactly that)")
    assert rollout_note(_train_args(algo="td3", timesteps=100, n_envs=2)) is None  # 50 updates of 2 steps


def test_rollout_note_reads_train_freq_from_the_hyperparameter_file(tmp_path):
    """``train_freq: [4, step]`` is 4 x n_envs steps per update; ``[1, episode]`` has no fixed step count."""
    def note(freq: str, timesteps: int) -> str | None:
        path = tmp_path / "sac.yml"
        path.write_text(f"bulletnav/Warehouse-v0:\n  policy: MlpPolicy\n  n_envs: 3\n  train_freq: {freq}\n")
        return rollout_note(_train_args(algo="sac", timesteps=timesteps, hyperparams=path))

    assert note("[4, step]", 100) == (
        "--timesteps 100 is not a whole number of rollouts: SAC collects train_freq 4 x 3 envs per update = 12 steps, "
        "so 108 steps will be trained (pass a multiple of 12 to train exactly that)")
    assert note("[4, step]", 96) is None  # 8 updates of 12 steps
    assert note("[1, episode]", 100) is None  # episodes per update: no step count to round to


def test_train_prints_the_note_and_refuses_a_folder_holding_a_run(monkeypatch, tmp_path, capsys):
    from bulletnav.rl import train as train_module

    def fake_train(cfg, plot_curve=None):  # the CLI passes the learning-curve plotter
        raise SystemExit(0)

    monkeypatch.setattr(train_module, "train", fake_train)
    with pytest.raises(SystemExit):
        main(["train", "--out", str(tmp_path / "new"), "--timesteps", "100", "--n-envs", "2"])
    assert "bulletnav train: note: --timesteps 100 is not a whole number of rollouts" in capsys.readouterr().err
    run = tmp_path / "run"
    run.mkdir()
    (run / "run.json").write_text("{}")
    assert main(["train", "--out", str(run), "--timesteps", "1024", "--n-envs", "2"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert err.startswith(f"bulletnav train: error: --out {run} already holds a run (run.json, ...)")
    assert "--resume" in err and "--overwrite" in err
    for extra in (["--resume"], ["--overwrite"]):  # both go on to train (here: the fake)
        with pytest.raises(SystemExit):
            main(["train", "--out", str(run), "--timesteps", "1024", "--n-envs", "2", *extra])


# ------------------------------------------------------------------ a model and its env


@pytest.mark.slow
def test_evaluate_without_env_uses_the_models_own_env(capsys):
    assert main(["evaluate", "--model", str(MODELS / "ppo_mission.zip"), "--episodes", "1", "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["env_id"] == "bulletnav/WarehouseMission-v0" and out["episodes"] == 1
    assert out["per_episode"][0]["goals_total"] > 1


@pytest.mark.parametrize("model, env_id, shapes", [
    ("ppo_warehouse.zip", "bulletnav/WarehouseMission-v0", "the model's has shape (43,), the env's (59,)"),
    ("ppo_mission.zip", "bulletnav/Warehouse-v0", "the model's has shape (62,), the env's (46,)"),
])
def test_a_model_that_does_not_fit_the_env_is_one_line_before_any_episode(model, env_id, shapes, capsys):
    path = str(MODELS / model)
    assert main(["evaluate", "--model", path, "--env", env_id, "--episodes", "1"]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""  # refused before the report's header and its episodes
    assert captured.err == f"bulletnav evaluate: error: {path} does not fit {env_id}: observation space: {shapes} " \
                           "(a model runs on the env and settings it was trained with, which its .json records)\n"


def test_demo_refuses_a_model_of_another_env_before_making_its_folder(tmp_path, capsys):
    out = tmp_path / "demo"
    assert main(["demo", "--model", str(MODELS / "ppo_mission.zip"), "--env", "bulletnav/Warehouse-v0",
                 "--out", str(out)]) == 2
    assert "does not fit bulletnav/Warehouse-v0" in capsys.readouterr().err
    assert not out.exists()


class _Spaces:
    def __init__(self, obs, act):
        self.observation_space, self.action_space = obs, act


def test_check_model_fits_names_shapes_and_bounds():
    box = spaces.Box(0.0, 1.0, (4,), np.float32)
    act = spaces.Box(-1.0, 1.0, (2,), np.float32)
    check_model_fits(_Spaces(box, act), _Spaces(spaces.Box(0.0, 1.0, (4,), np.float32), act), "m.zip", "E-v0")
    with pytest.raises(ModelError, match=r"^m\.zip does not fit E-v0: action space: the model's has shape \(2,\), "
                                         r"the env's \(3,\)"):
        check_model_fits(_Spaces(box, act), _Spaces(box, spaces.Box(-1.0, 1.0, (3,), np.float32)), "m.zip", "E-v0")
    wider = spaces.Box(np.array([0, 0, 0, -2], np.float32), np.ones(4, np.float32), dtype=np.float32)
    assert space_mismatch(box, wider) == ("both have shape (4,) but other bounds (1 differ): low[3] is 0 for the model, "
                                          "-2 for the env")
    assert space_mismatch(spaces.Box(-np.inf, np.inf, (2,), np.float32), spaces.Box(-np.inf, np.inf, (2,), np.float32)) is None
    assert space_mismatch(spaces.Discrete(3), box) == "the model's is a Discrete of shape (), the env's a Box of shape (4,)"
    assert space_mismatch(spaces.Discrete(3), spaces.Discrete(4)) == "the model's is Discrete(3), the env's Discrete(4)"


# ------------------------------------------------------------------ one run never replaces another's


def test_demo_folders_are_per_run_by_default(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert demo_folder(None) == (Path("runs/demo"), True)
    assert demo_folder(None) == (Path("runs/demo"), False)  # empty: still free
    (tmp_path / "runs" / "demo" / "episodes.mp4").write_bytes(b"an earlier demo")
    assert demo_folder(None) == (Path("runs/demo-2"), True)
    (tmp_path / "runs" / "demo-2" / "x").write_bytes(b"")
    (tmp_path / "runs" / "demo-3").write_bytes(b"a file, not a folder")
    assert demo_folder(None) == (Path("runs/demo-4"), True)
    assert (tmp_path / "runs" / "demo" / "episodes.mp4").read_bytes() == b"an earlier demo"


def test_demo_refuses_an_explicit_folder_holding_a_run(tmp_path, capsys):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "episodes.mp4").write_bytes(b"keep me")
    assert main(["demo", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"bulletnav demo: error: --out {out} already holds a run (episodes.mp4): pass --overwrite")
    assert len(err.strip().splitlines()) == 1 and (out / "episodes.mp4").read_bytes() == b"keep me"
    video = tmp_path / "clip.mp4"
    video.write_bytes(b"keep me too")
    assert main(["demo", "--out", str(tmp_path / "new"), "--video", str(video)]) == 2
    assert f"--video {video}: the file already exists" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


@pytest.mark.slow  # one demo episode with its video (about 10 s)
def test_a_second_demo_writes_its_own_folder(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)  # `make demo` twice: runs/demo holds the first
    (tmp_path / "runs" / "demo").mkdir(parents=True)
    (tmp_path / "runs" / "demo" / "episodes.mp4").write_bytes(b"the first demo")
    assert main(["demo", "--episodes", "1"]) == 0
    text = capsys.readouterr().out
    assert "runs/demo holds an earlier demo: this one writes to runs/demo-2/" in text
    assert "results in runs/demo-2/" in text
    assert (tmp_path / "runs" / "demo" / "episodes.mp4").read_bytes() == b"the first demo"
    written = sorted(p.name for p in (tmp_path / "runs" / "demo-2").iterdir())
    assert written == ["episodes.mp4", "trajectories.png"]  # no temporary files left


def test_navigate_refuses_to_replace_a_video_or_plot_without_overwrite(tmp_path, capsys):
    video, plot = tmp_path / "nav.gif", tmp_path / "nav.png"
    plot.write_bytes(b"an earlier plot")
    argv = ["navigate", "--planner", "none", "--episodes", "1", "--world", EMPTY, "--plot", str(plot)]
    assert main([*argv, "--video", str(video)]) == 2
    err = capsys.readouterr().err
    assert err == (f"bulletnav navigate: error: --plot {plot}: the file already exists (another run's?); pass "
                   "--overwrite to replace it, or choose another name\n")
    assert not video.exists() and plot.read_bytes() == b"an earlier plot"
    assert main([*argv, "--overwrite"]) == 0
    assert plot.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["nav.png"]  # no temporary files left


# ------------------------------------------------------------------ files appear whole or not at all


def test_recorder_writes_beside_the_target_and_renames(tmp_path):
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.viz import EpisodeRecorder

    target = tmp_path / "clip.gif"
    target.write_bytes(b"an earlier clip")
    env = gym.make("bulletnav/Warehouse-v0", world=EMPTY)
    try:
        with pytest.raises(RuntimeError, match="stop"):  # an error mid-recording: the earlier file stays
            with EpisodeRecorder(target, stride=5) as rec:
                env.reset(seed=0)
                rec.on_reset(env)
                hidden = [p.name for p in tmp_path.iterdir() if p.name != "clip.gif"]
                assert len(hidden) == 1 and hidden[0].startswith(".clip.gif.") and hidden[0].endswith(".tmp.gif")
                raise RuntimeError("stop")
        assert target.read_bytes() == b"an earlier clip" and [p.name for p in tmp_path.iterdir()] == ["clip.gif"]
        with EpisodeRecorder(target, stride=5) as rec:
            env.reset(seed=0)
            rec.on_reset(env)
            assert target.read_bytes() == b"an earlier clip"  # until close
    finally:
        env.close()
    assert target.read_bytes()[:6] == b"GIF89a" and [p.name for p in tmp_path.iterdir()] == ["clip.gif"]


def test_learning_curve_is_written_whole(tmp_path):
    from bulletnav.viz.compare import plot_learning_curve

    path = tmp_path / "curve.png"
    history = [{"timesteps": t, "success_rate": 0.5, "collision_rate": 0.1, "mean_reward": 1.0} for t in (1, 2)]
    plot_learning_curve(history, path, "t")
    plot_learning_curve(history, path, "t")
    assert path.read_bytes()[:4] == b"\x89PNG" and [p.name for p in tmp_path.iterdir()] == ["curve.png"]
