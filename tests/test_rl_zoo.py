"""One hyperparameter file for ``bulletnav train`` and RL Zoo: the files name the network in
RL Zoo's form, which must build exactly the network of the old form, and RL Zoo must train
with them as they are."""

from __future__ import annotations

import sys
from pathlib import Path

import gymnasium as gym
import pytest
import torch

import bulletnav  # noqa: F401
import hang
from bulletnav.rl.algos import algo_class
from bulletnav.rl.features import ClearanceFeatures
from bulletnav.rl.hyperparams import load_hyperparams, model_kwargs, policy_class

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("algo", ["ppo", "a2c", "sac", "td3"])
def test_the_rl_zoo_form_builds_the_network_of_the_old_form_to_the_bit(algo):
    """``policy: bulletnav.rl.policies.Clearance*Policy`` against ``MlpPolicy`` with
    ``features_extractor_class: ClearanceFeatures`` (how the shipped models were made): the
    same seed gives the same initial weights, so training is unchanged by the new form."""
    hp = load_hyperparams(algo)
    assert "." in hp["policy"] and "features_extractor_class" not in hp.get("policy_kwargs", {})
    env = gym.make("bulletnav/Warehouse-v0", **{k: v for k, v in hp["env_kwargs"].items() if k != "layouts_every"})
    kwargs = model_kwargs(hp, env.action_space.shape[0])
    if "buffer_size" in kwargs:
        kwargs["buffer_size"] = 1000  # the weights do not depend on it; the memory does
    cls = algo_class(algo)
    new = cls(policy_class(hp), env, seed=0, device="cpu", **kwargs)
    old_kwargs = {**kwargs, "policy_kwargs": {**kwargs.get("policy_kwargs", {}), "features_extractor_class": ClearanceFeatures}}
    old = cls("MlpPolicy", env, seed=0, device="cpu", **old_kwargs)
    a, b = new.policy.state_dict(), old.policy.state_dict()
    assert list(a) == list(b) and all(torch.equal(a[k], b[k]) for k in a)
    assert isinstance(new.policy.features_extractor if algo in ("ppo", "a2c") else new.actor.features_extractor,
                      ClearanceFeatures)
    env.close()


@pytest.mark.slow
def test_rl_zoo_trains_ppo_with_the_projects_hyperparameter_file(tmp_path):
    """The RL Zoo command of README and docs/learning.md, with a small budget: it leaves a model with the project's
    network and hyperparameters."""
    pytest.importorskip("rl_zoo3")
    from stable_baselines3 import PPO

    conf = ROOT / "bulletnav" / "rl" / "hyperparams" / "ppo.yml"
    cmd = [sys.executable, "-m", "rl_zoo3.train", "--algo", "ppo", "--env", "bulletnav/Warehouse-v0",
           "--gym-packages", "bulletnav", "-conf", str(conf), "-n", "2048", "--seed", "0", "-f", str(tmp_path / "logs"),
           "--eval-freq", "-1", "--vec-env", "dummy"]
    done = hang.run(cmd, "RL Zoo's train", cwd=tmp_path)
    assert done.returncode == 0, done.stdout[-3000:] + done.stderr[-3000:]
    (model_path,) = (tmp_path / "logs" / "ppo").glob("bulletnav-Warehouse-v0_*/bulletnav-Warehouse-v0.zip")
    assert (model_path.parent / "bulletnav-Warehouse-v0" / "vecnormalize.pkl").is_file()  # normalize: from the file
    model = PPO.load(model_path, device="cpu")
    hp = load_hyperparams("ppo")
    assert model.num_timesteps == 2048
    assert isinstance(model.policy.features_extractor, ClearanceFeatures)
    assert (model.n_steps, model.batch_size, model.n_epochs, model.gamma, model.gae_lambda) == (
        hp["n_steps"], hp["batch_size"], hp["n_epochs"], hp["gamma"], hp["gae_lambda"])
    assert model.lr_schedule(1.0) == hp["learning_rate"]  # RL Zoo wraps the constant in a schedule
    assert [layer.out_features for layer in model.policy.mlp_extractor.policy_net if hasattr(layer, "out_features")] == [128, 128]
    assert model.observation_space.shape == (43,)  # ClearanceFeatures' input: the env's own observation
