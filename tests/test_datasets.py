"""Minari datasets (``--dataset NAME``): episodes written through the CLI come back from
``minari.load_dataset`` step for step, ``recover_environment()`` rebuilds an env that passes
Gymnasium's and SB3's checkers and replays the same episode from the stored seed; names are
checked before any episode runs."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("minari")

import gymnasium as gym  # noqa: E402
import minari  # noqa: E402

import bulletnav  # noqa: E402,F401
from bulletnav.cli import main  # noqa: E402
from bulletnav.datasets import DatasetRecorder, check_name  # noqa: E402
from bulletnav.errors import BulletnavError  # noqa: E402

NAME = "bulletnav/aisles-astar-test-v0"


@pytest.fixture()
def store(tmp_path, monkeypatch):
    monkeypatch.setenv("MINARI_DATASETS_PATH", str(tmp_path / "minari"))
    return tmp_path / "minari"


@pytest.mark.slow
def test_navigate_dataset_round_trip(store, capsys):
    assert main(["navigate", "--env", "bulletnav/WarehouseAisles-v0", "--planner", "astar", "--episodes", "2",
                 "--seed", "5", "--json", "--dataset", NAME]) == 0
    capsys.readouterr()
    ds = minari.load_dataset(NAME)
    assert ds.total_episodes == 2
    episodes = list(ds.iterate_episodes())
    assert [int(e.id) for e in episodes] == [0, 1]
    env = ds.recover_environment()
    try:
        assert env.spec.id == "bulletnav/WarehouseAisles-v0"
        from gymnasium.utils.env_checker import check_env
        from stable_baselines3.common.env_checker import check_env as sb3_check_env

        check_env(env.unwrapped, skip_render_check=True)
        sb3_check_env(env.unwrapped, warn=False)
        # the stored episode is the env's: same reset observation from its seed, same rewards when
        # its actions are replayed
        first = episodes[0]
        obs, _ = env.reset(seed=5)
        np.testing.assert_array_equal(obs, first.observations[0])
        rewards = []
        for a in first.actions:
            obs, r, terminated, truncated, info = env.step(a)
            rewards.append(r)
        np.testing.assert_allclose(rewards, first.rewards, rtol=0, atol=1e-9)
        np.testing.assert_array_equal(obs, first.observations[-1])
        assert bool(first.terminations[-1]) == terminated and bool(info["is_success"])
    finally:
        env.close()
    assert first.observations.shape[0] == first.actions.shape[0] + 1
    assert set(first.infos) >= {"distance_to_goal", "is_success", "collision", "path_length"}
    assert first.infos["distance_to_goal"].shape == (first.actions.shape[0] + 1,)


def test_names_are_checked_before_running(store, capsys):
    with pytest.raises(BulletnavError, match="name-vN"):
        check_name("no version")
    # by hand from Minari's documented id form [namespace/]name-vN (a namespace of 2 or more
    # letters, digits, '_', '-' or '/'): no dots, no spaces, a version number at the end
    for good in ("bulletnav/a-v0", "x-v12", "ns/sub/name_1-v3"):
        assert check_name(good) == good
    for bad in ("../x-v0", "bulletnav/../x-v0", "bulletnav/x-v", "bulletnav/x", "x y-v0", "a/x-v0", "/x-v0",
                "bulletnav/x-v-1"):
        with pytest.raises(BulletnavError, match="name-vN"):
            check_name(bad)
    env = gym.make("bulletnav/WarehouseAisles-v0", max_episode_steps=5)
    try:
        rec = DatasetRecorder(env, "bulletnav/short-test-v0")
        rec.reset(seed=0)
        for _ in range(5):
            rec.step(env.action_space.sample())
        rec.save(algorithm="random")
        assert minari.load_dataset("bulletnav/short-test-v0").total_steps == 5
        with pytest.raises(BulletnavError, match="already exists"):
            DatasetRecorder(env, "bulletnav/short-test-v0")
    finally:
        env.close()
    assert main(["navigate", "--episodes", "1", "--dataset", "bulletnav/short-test-v0"]) == 2
    assert "already exists" in capsys.readouterr().err


@pytest.mark.slow
def test_behaviour_cloning_from_a_dataset(store, tmp_path, capsys):
    """``train --algo bc``: PPO's network fitted to the expert's actions; the validation loss
    falls, and the model is saved like every model (evaluate runs it)."""
    assert main(["navigate", "--env", "bulletnav/WarehouseAisles-v0", "--planner", "astar", "--episodes", "3",
                 "--seed", "7", "--json", "--dataset", "bulletnav/bc-test-v0"]) == 0
    out = tmp_path / "bc"
    assert main(["train", "--algo", "bc", "--dataset", "bulletnav/bc-test-v0", "--epochs", "4", "--out", str(out)]) == 0
    assert "behaviour-cloned bulletnav/bc-test-v0" in capsys.readouterr().out
    import json

    history = json.loads((out / "history.json").read_text())
    assert len(history) == 4 and history[-1]["val_nll"] < history[0]["val_nll"]
    record = json.loads((out / "run.json").read_text())
    assert record["algo"] == "bc" and record["episodes"] == 3 and record["validation_episodes"] == 1
    from bulletnav.rl.io import load_model

    model, meta, _ = load_model(out / "model.zip")
    assert meta["trained_by"] == "bc" and meta["algo"] == "ppo" and "render_mode" not in meta["env_kwargs"]
    # PPO's env for the id: its action scale ([-1, 1]) although the expert drove in physical units
    assert meta["env_kwargs"]["normalize_actions"] is True
    assert np.allclose(model.action_space.low, -1.0) and np.allclose(model.action_space.high, 1.0)
    # the spread is held at PPO's log_std_init (-0.5) unless --fit-std: fine-tuning explores
    assert np.allclose(model.policy.log_std.detach().numpy(), -0.5) and record["log_std"] == [-0.5, -0.5]
    fitted = tmp_path / "bc_std"
    assert main(["train", "--algo", "bc", "--dataset", "bulletnav/bc-test-v0", "--epochs", "4", "--fit-std",
                 "--out", str(fitted)]) == 0
    log_std = json.loads((fitted / "run.json").read_text())["log_std"]
    assert max(abs(v + 0.5) for v in log_std) > 1e-3, log_std  # fitted with the mean (the 1,000-episode run: -2.5, -2.1)
    assert main(["evaluate", "--model", str(out / "model.zip"), "--env", "bulletnav/WarehouseAisles-v0",
                 "--episodes", "1", "--json"]) == 0
    # and PPO fine-tunes it
    ppo = tmp_path / "ppo"
    assert main(["train", "--algo", "ppo", "--env", "bulletnav/WarehouseAisles-v0", "--init-from", str(out / "model.zip"),
                 "--timesteps", "512", "--n-envs", "1", "--eval-freq", "100000", "--eval-episodes", "1",
                 "--out", str(ppo), "--no-progress"]) == 0
    assert json.loads((ppo / "run.json").read_text())["init_from"] == str(out / "model.zip")
    capsys.readouterr()
    assert main(["train", "--algo", "bc", "--out", str(tmp_path / "x")]) == 2
    assert "needs --dataset" in capsys.readouterr().err


def test_image_observations_are_refused(store):
    env = gym.make("bulletnav/WarehouseAisles-v0", camera_obs=True)
    try:
        with pytest.raises(BulletnavError, match="vector observations"):
            DatasetRecorder(env, "bulletnav/camera-test-v0")
    finally:
        env.close()


def test_shielded_episodes_store_the_executed_actions(store):
    """Behind the shield wrapper the dataset holds what the robot was sent: the shield's
    replacement wherever it acted (mapped onto the action space), the policy's action elsewhere."""
    from bulletnav.control.shield import ShieldWrapper

    env = ShieldWrapper(gym.make("bulletnav/WarehouseDynamic-v0", normalize_actions=True, max_episode_steps=150))
    try:
        rec = DatasetRecorder(env, "bulletnav/shielded-test-v0")
        rng = np.random.default_rng(0)
        rec.reset(seed=4)
        raw, vetoes = [], []
        for _ in range(150):
            a = np.array([1.0, rng.uniform(-0.2, 0.2)], dtype=np.float32)  # full speed ahead, into whatever is there
            _, _, terminated, truncated, info = rec.step(a)
            raw.append(a)
            vetoes.append(info["shield"])
            if terminated or truncated:
                break
        ep = rec.buffers[0]
        acted = [k for k, d in enumerate(vetoes) if d["intervened"]]
        assert acted  # the shield had to act
        (v_lo, v_hi), (w_lo, w_hi) = env.unwrapped.scene.command_limits
        changed = 0
        for k in acted:
            v = 2 * (vetoes[k]["v"] - v_lo) / (v_hi - v_lo) - 1
            w = 2 * (vetoes[k]["w"] - w_lo) / (w_hi - w_lo) - 1
            assert ep.actions[k] == pytest.approx([v, w], abs=1e-6)
            changed += not np.allclose(ep.actions[k], raw[k])
        assert changed == len(acted)  # every replacement differs from what the policy asked
        untouched = [k for k in range(len(raw)) if k not in acted]
        np.testing.assert_array_equal(ep.actions[untouched], np.asarray(raw)[untouched])
    finally:
        env.close()
