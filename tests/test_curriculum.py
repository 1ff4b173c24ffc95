"""Curriculum: promotion and demotion on a fake success stream, stage changes reaching
sub-process envs during a real (short) training, and checkpoints that resume in the stage."""

from __future__ import annotations

import json
import logging
import math

import gymnasium as gym
import numpy as np
import pytest

import bulletnav  # noqa: F401
from bulletnav.config import asset_path
from bulletnav.rl.curriculum import Curriculum, CurriculumCallback

EMPTY = str(asset_path("worlds", "empty.yaml"))
SPEC = {"window": 4, "promote": 0.75, "demote": 0.25, "min_episodes": 6,
        "stages": [{"max_goal_distance": 3.0}, {"forklifts": 1}, {}]}


def test_promotion_waits_for_min_episodes_and_the_window_rate():
    c = Curriculum.from_spec(SPEC)
    changes = [c.record(s) for s in [1, 1, 1, 1, 1]]
    assert changes == [None] * 5 and c.stage == 0  # 5 < min_episodes
    assert c.record(True) == 1 and c.stage == 1 and c.success_rate is None  # the window starts afresh
    for s in [1, 0, 1, 0, 1]:
        assert c.record(s) is None  # rate 0.5 or 0.6: stays
    assert c.stage == 1


def test_demotion_below_the_threshold_and_no_move_past_the_ends():
    c = Curriculum.from_spec(SPEC)
    for _ in range(20):
        c.record(False)
    assert c.stage == 0  # nowhere to demote to
    for _ in range(6):
        c.record(True)
    assert c.stage == 1
    moves = [c.record(False) for _ in range(6)]
    assert moves.count(0) == 1 and c.stage == 0  # once 6 episodes in the stage, the window reads 0.0
    c2 = Curriculum.from_spec({**SPEC, "demote": None})
    for _ in range(12):
        c2.record(True)
    assert c2.stage == 2
    for _ in range(30):
        c2.record(True)
        c2.record(False)
    assert c2.stage == 2  # the last stage holds, and without demote nothing goes back


def test_state_round_trips():
    c = Curriculum.from_spec(SPEC)
    for s in [1] * 6 + [1, 0, 1]:
        c.record(s)
    d = Curriculum.from_spec(SPEC)
    d.restore(json.loads(json.dumps(c.state())))
    assert (d.stage, d.episodes_in_stage, list(d.recent)) == (c.stage, c.episodes_in_stage, list(c.recent))
    # By hand from the rules: promoted on the 6th success, then 3 episodes of stage 1 in the window.
    assert (d.stage, d.episodes_in_stage, list(d.recent)) == (1, 3, [1, 0, 1])
    assert d.record(True) == c.record(True)
    # Episodes 5 and 6 of stage 1 succeed: the window [1, 1, 1, 1] >= 0.75 at min_episodes, so the
    # restored curriculum promotes on the second, as the original does.
    assert [d.record(True) for _ in range(2)] == [c.record(True) for _ in range(2)] == [None, 2]


@pytest.mark.parametrize("spec, message", [
    ({**SPEC, "stages": [{"lidar_rays": 18}, {}]}, r"stages\[0\]: lidar_rays cannot change between episodes"),
    ({**SPEC, "promote": 1.5}, "promote must be a success rate in"),
    ({**SPEC, "min_episodes": 2}, r"min_episodes must be an integer >= window \(4\)"),
    ({**SPEC, "stages": [{}]}, "at least 2"),
    ({**SPEC, "promte": 0.5}, "unknown field"),
])
def test_bad_curricula_are_refused_by_field(spec, message):
    with pytest.raises(ValueError, match=message):
        Curriculum.from_spec(spec)


def test_set_episode_config_changes_the_next_episodes_and_restores():
    env = gym.make("bulletnav/Warehouse-v0", world=EMPTY)
    env.unwrapped.set_episode_config(min_goal_distance=1.0, max_goal_distance=1.5, perturb="heavy")
    for seed in range(5):
        _, info = env.reset(seed=seed)
        assert 1.0 <= info["initial_distance"] <= 1.5 and info["shift"]["mass_scale"] == 1.5
        (x, y, _), (gx, gy) = info["pose"], info["goal"]  # the distance is the straight one
        assert info["initial_distance"] == pytest.approx(math.hypot(gx - x, gy - y), abs=1e-9)
    env.unwrapped.set_episode_config()
    _, info = env.reset(seed=0)
    assert info["initial_distance"] >= 2.0 and "shift" not in info
    with pytest.raises(ValueError, match="lidar_rays cannot change between episodes"):
        env.unwrapped.set_episode_config(lidar_rays=18)
    env.close()


@pytest.mark.slow
def test_stages_reach_subprocess_envs_during_training():
    """Stage 0 makes every episode succeed at once, stage 1 (heavy robot, far goals, 10-step
    episodes) makes none: the curriculum promotes, the envs report the shift, it demotes."""
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback
    from stable_baselines3.common.vec_env import SubprocVecEnv, VecMonitor

    from bulletnav.rl.envs import make_env_fn

    kwargs = {"world": EMPTY, "normalize_actions": True, "max_episode_steps": 10}
    venv = VecMonitor(SubprocVecEnv([make_env_fn(kwargs)] * 2, start_method="forkserver"))
    venv.seed(0)
    spec = {"window": 2, "min_episodes": 2, "promote": 0.9, "demote": 0.1,
            "stages": [{"min_goal_distance": 0.0, "max_goal_distance": 0.3}, {"perturb": "heavy"}]}
    curriculum = CurriculumCallback(Curriculum.from_spec(spec))
    curriculum.send_stage(venv)
    seen = []

    class Probe(BaseCallback):
        def _on_step(self) -> bool:
            seen.append((curriculum.curriculum.stage, ["shift" in i for i in self.locals["infos"]]))
            return True

    model = PPO("MlpPolicy", venv, n_steps=32, batch_size=32, n_epochs=1, seed=0, device="cpu")
    model.learn(160, callback=[Probe(), curriculum])  # the probe sees each step before the curriculum counts it
    venv.close()
    stages = [s for s, _ in seen]
    assert 1 in stages and stages.index(1) > 0
    assert any(all(flags) for s, flags in seen if s == 1)  # both sub-process envs run the heavy robot
    assert any(s == 0 for s in stages[stages.index(1):])  # and were demoted again


def test_training_checkpoints_the_stage_and_resumes_in_it(tmp_path, caplog):
    from bulletnav.rl.train import TrainConfig, train

    hp = tmp_path / "ppo.yml"
    hp.write_text(
        "bulletnav/Warehouse-v0:\n  policy: MlpPolicy\n  n_envs: 2\n"
        f"  env_kwargs: {{normalize_actions: true, world: {EMPTY}, max_episode_steps: 10}}\n"
        "  n_steps: 32\n  batch_size: 32\n  n_epochs: 1\n"
        "  curriculum: {window: 2, min_episodes: 2, promote: 0.9,"
        " stages: [{min_goal_distance: 0.0, max_goal_distance: 0.3}, {}]}\n"
        "  randomize: {floor_friction: [0.6, 1.0]}\n")
    out = tmp_path / "run"
    common = dict(algo="ppo", out=out, seed=0, eval_freq=10_000, eval_episodes=1, checkpoint_freq=64,
                  progress_bar=False, vec_env="dummy", hyperparams=hp)
    record = train(TrainConfig(timesteps=128, **common))
    assert record["curriculum_final"]["stage"] == 1
    saved = json.loads((out / "checkpoints" / "last.json").read_text())
    assert saved["curriculum"]["stage"] == 1 and record["env_kwargs"]["randomize"] == {"floor_friction": [0.6, 1.0]}
    with caplog.at_level(logging.INFO, logger="bulletnav.rl.curriculum"):
        train(TrainConfig(timesteps=192, resume=True, **common))
    assert "training starts in stage 1 of 2" in caplog.text
    assert np.isfinite(json.loads((out / "run.json").read_text())["total_timesteps"])
