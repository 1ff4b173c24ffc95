"""Opening a model never runs its code: crafted files are refused before anything in them runs,
the shipped models load from the pickle-free format, and the safe readers agree with SB3's."""

from __future__ import annotations

import base64
import hashlib
import io
import json
import pickle
import shutil
import zipfile
from pathlib import Path

import numpy as np
import pytest
import torch

from bulletnav.cli import main
from bulletnav.errors import ModelError
from bulletnav.rl import safe
from bulletnav.rl.io import load_model

ROOT = Path(__file__).resolve().parents[1]
SHIPPED = ["ppo_warehouse", "ppo_dynamic", "ppo_mission"]


class _Payload:
    """Unpickling this creates ``marker``: what a hostile model file would do instead."""

    def __init__(self, marker: Path) -> None:
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


def _rewrite_zip(src: Path, dst: Path, change) -> None:
    """Copy an SB3 zip, passing its ``data`` JSON through ``change``."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            blob = zin.read(item.filename)
            if item.filename == "data":
                blob = json.dumps(change(json.loads(blob))).encode()
            zout.writestr(item, blob)


def _plain_sidecar(name: str, dst: Path) -> None:
    """The sidecar as it was before the safe format: env id and settings, no policy or statistics."""
    meta = json.loads((ROOT / "models" / f"{name}.json").read_text())
    dst.write_text(json.dumps({k: v for k, v in meta.items() if k not in ("format", "policy", "normalization")}))


def _zip_only(tmp_path: Path, name: str = "ppo_warehouse") -> Path:
    """A shipped model's SB3 zip with a plain sidecar (no safe files, no statistics), as a
    third party shares it."""
    dst = tmp_path / f"{name}.zip"
    shutil.copy(ROOT / "models" / f"{name}.zip", dst)
    _plain_sidecar(name, dst.with_suffix(".json"))
    return dst


def _crafted_zip(tmp_path: Path, marker: Path, key: str = "policy_class") -> Path:
    model = tmp_path / "crafted.zip"

    def change(data):
        data[key] = {":type:": "<class 'abc.ABCMeta'>",
                     ":serialized:": base64.b64encode(pickle.dumps(_Payload(marker))).decode()}
        return data

    _rewrite_zip(ROOT / "models" / "ppo_warehouse.zip", model, change)
    _plain_sidecar("ppo_warehouse", model.with_suffix(".json"))
    return model


def _numpy_actions(weights: Path, obs: np.ndarray) -> np.ndarray:
    """The deterministic actions of ppo_warehouse's policy computed here with NumPy from the raw
    arrays that safetensors' own reader gives: the observation followed by exp(-clearance / 0.15)
    per ray (clearance = 5 m x lidar entry less the stored footprint, at least 0; SB3's
    ClearanceFeatures defaults), two tanh layers of 128, the action layer, clipped to [-1, 1]."""
    from safetensors.numpy import load_file

    w = {k: v.astype(np.float64) for k, v in load_file(weights).items()}
    x = obs.astype(np.float64)
    clearance = np.maximum(x[:, :36] * 5.0 - w["pi_features_extractor.footprint"], 0.0)
    h = np.concatenate([x, np.exp(-clearance / 0.15)], axis=1)
    for layer in ("mlp_extractor.policy_net.0", "mlp_extractor.policy_net.2"):
        h = np.tanh(h @ w[f"{layer}.weight"].T + w[f"{layer}.bias"])
    return np.clip(h @ w["action_net.weight"].T + w["action_net.bias"], -1.0, 1.0)


def _evaluate(model: Path, capsys, *extra: str) -> tuple[int, str]:
    rc = main(["evaluate", "--model", str(model), "--algo", "ppo", "--episodes", "1", "--json", *extra])
    return rc, capsys.readouterr().err


# ------------------------------------------------------------------------------ hostile files
def test_a_crafted_zip_entry_is_refused_and_never_runs(tmp_path, capsys):
    marker = tmp_path / "pwned"
    model = _crafted_zip(tmp_path, marker)
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and not marker.exists()
    assert str(model) in err and "'policy_class'" in err and "not a bare class reference" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    # the payload is live: SB3's own loader runs it (in this test's tmp dir only)
    from stable_baselines3 import PPO

    with pytest.raises(Exception):  # noqa: B017 - the file object it returns is not a policy class
        PPO.load(model, device="cpu")
    assert marker.exists()


@pytest.mark.parametrize("key", ["policy_kwargs", "observation_space", "lr_schedule", "some_new_entry"])
def test_a_payload_in_any_entry_never_runs(tmp_path, capsys, key):
    marker = tmp_path / "pwned"
    model = _crafted_zip(tmp_path, marker, key)
    rc, err = _evaluate(model, capsys)
    assert not marker.exists()
    if key == "lr_schedule":  # rebuilt from the file's text, never unpickled: the model still acts
        assert rc == 0
    else:
        assert rc == 2 and str(model) in err and repr(key) in err


def test_a_crafted_vecnormalize_pickle_is_refused_and_never_runs(tmp_path, capsys):
    marker = tmp_path / "pwned"
    model = _zip_only(tmp_path)
    (tmp_path / "ppo_warehouse_vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and not marker.exists()
    assert "ppo_warehouse_vecnormalize.pkl" in err and "stored as a pickle" in err and "--trust-pickle" in err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1
    # --trust-pickle does what its help says: opens it (and so runs it)
    _evaluate(model, capsys, "--trust-pickle")
    assert marker.exists()


def test_a_pickle_beside_safe_files_is_never_opened(tmp_path, capsys):
    marker = tmp_path / "pwned"
    for suffix in (".zip", ".safetensors", ".json", "_vecnormalize.json"):
        shutil.copy(ROOT / "models" / f"ppo_warehouse{suffix}", tmp_path / f"ppo_warehouse{suffix}")
    (tmp_path / "ppo_warehouse_vecnormalize.pkl").write_bytes(pickle.dumps(_Payload(marker)))
    rc, _ = _evaluate(tmp_path / "ppo_warehouse.zip", capsys)
    assert rc == 0 and not marker.exists()
    # What loaded is what the safe file holds: its actions against a NumPy forward pass from the
    # raw arrays, on 256 observations drawn over the observation space.
    model, _, _ = load_model(tmp_path / "ppo_warehouse.zip")
    space = model.observation_space
    obs = np.random.default_rng(1).uniform(space.low, space.high, (256, *space.shape)).astype(np.float32)
    np.testing.assert_allclose(model.predict(obs, deterministic=True)[0],
                               _numpy_actions(tmp_path / "ppo_warehouse.safetensors", obs), atol=1e-5)


def test_a_crafted_tensor_file_is_refused(tmp_path, capsys):
    marker = tmp_path / "pwned"
    model = tmp_path / "crafted.zip"
    buf = io.BytesIO()
    torch.save({"x": _Payload(marker)}, buf)
    with zipfile.ZipFile(ROOT / "models" / "ppo_warehouse.zip") as zin, zipfile.ZipFile(model, "w") as zout:
        for item in zin.infolist():
            zout.writestr(item, buf.getvalue() if item.filename == "policy.pth" else zin.read(item.filename))
    _plain_sidecar("ppo_warehouse", model.with_suffix(".json"))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and not marker.exists() and str(model) in err and "Traceback" not in err
    assert "weights_only" in err.lower() or "unpickl" in err.lower(), err


def test_safe_files_that_were_tampered_with_are_refused(tmp_path, capsys):
    for suffix in (".zip", ".safetensors", ".json"):
        shutil.copy(ROOT / "models" / f"ppo_warehouse{suffix}", tmp_path / f"m{suffix}")
    model = tmp_path / "m.zip"
    weights = tmp_path / "m.safetensors"
    blob = bytearray(weights.read_bytes())
    blob[-1] ^= 0xFF
    weights.write_bytes(bytes(blob))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and "SHA-256" in err
    # The digest the sidecar records is hashlib's SHA-256 of the shipped file, and the flipped byte
    # gives another: the check compares the file with the real digest.
    recorded = json.loads((tmp_path / "m.json").read_text())["policy"]["weights_sha256"]
    assert hashlib.sha256((ROOT / "models" / "ppo_warehouse.safetensors").read_bytes()).hexdigest() == recorded
    assert hashlib.sha256(bytes(blob)).hexdigest() != recorded
    shutil.copy(ROOT / "models" / "ppo_warehouse.safetensors", weights)
    meta = json.loads((tmp_path / "m.json").read_text())
    meta["policy"]["class"] = "os.system"
    (tmp_path / "m.json").write_text(json.dumps(meta))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and "'os.system'" in err and "not a class bulletnav rebuilds" in err
    meta["policy"]["class"] = "stable_baselines3.common.policies.ActorCriticPolicy"
    meta["policy"]["kwargs"]["activation_fn"] = {"class": "subprocess.Popen"}
    (tmp_path / "m.json").write_text(json.dumps(meta))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and "'subprocess.Popen'" in err
    del meta["policy"]["kwargs"]["activation_fn"]
    meta["policy"]["hyperparameters"]["_setup_model"] = 1
    (tmp_path / "m.json").write_text(json.dumps(meta))
    rc, err = _evaluate(model, capsys)
    assert rc == 2 and "_setup_model" in err


def test_pickle_globals_reads_names_without_importing():
    raw = pickle.dumps(_Payload(Path("/nonexistent/x")))
    names, consts = safe.pickle_globals(base64.b64encode(raw).decode())
    assert names == ["io.open"] and "/nonexistent/x" in consts
    names, consts = safe.pickle_globals(base64.b64encode(pickle.dumps(zipfile.ZipFile)).decode())
    assert names == ["zipfile.ZipFile"] and consts == []


# ------------------------------------------------------------------------------ shipped models, safe readers
@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_models_load_from_the_safe_format_and_act_as_the_zip(name, tmp_path):
    path = ROOT / "models" / f"{name}.zip"
    model, meta, norm = load_model(path)
    assert meta["format"] == safe.FORMAT and safe.has_safe(path, meta)
    assert not list((ROOT / "models").glob("*.pkl"))
    from_zip, _, _ = load_model(_zip_only(tmp_path, name), algo="ppo")  # SB3's zip, nothing unpickled
    rng = np.random.default_rng(0)
    space = model.observation_space
    obs = rng.uniform(space.low, space.high, (64, *space.shape)).astype(np.float32)
    np.testing.assert_array_equal(model.predict(obs, deterministic=True)[0], from_zip.predict(obs, deterministic=True)[0])
    for (k, a), (k2, b) in zip(model.policy.state_dict().items(), from_zip.policy.state_dict().items()):
        assert k == k2 and torch.equal(a, b), k
    assert model.observation_space == from_zip.observation_space and model.action_space == from_zip.action_space
    assert norm is not None and norm.norm_obs is False  # reward statistics only: observations pass unchanged


def test_normalizer_matches_vecnormalize_arithmetic():
    import gymnasium as gym
    from stable_baselines3.common.running_mean_std import RunningMeanStd
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), norm_obs=True, clip_obs=2.5)
    rng = np.random.default_rng(3)
    venv.obs_rms = RunningMeanStd(shape=(3,))
    venv.obs_rms.mean, venv.obs_rms.var, venv.obs_rms.count = rng.normal(size=3), rng.uniform(0.1, 4, 3), 123.0
    stats = safe.stats_to_json(venv)
    again = json.loads(json.dumps(stats))  # through the text form
    norm = safe.ObsNormalizer(safe.check_stats(again, "test"))
    obs = rng.normal(scale=5, size=(50, 3)).astype(np.float32)
    np.testing.assert_array_equal(norm.normalize_obs(obs), venv.normalize_obs(obs))
    applied = safe.apply_stats(VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")])), again)
    np.testing.assert_array_equal(applied.normalize_obs(obs), venv.normalize_obs(obs))
    venv.close()
    applied.close()


def test_convert_model_needs_trust_for_a_pickle_and_reproduces_the_shipped_files(tmp_path, capsys):
    import gymnasium as gym
    from stable_baselines3.common.vec_env import DummyVecEnv, VecNormalize

    model = _zip_only(tmp_path)
    shipped = json.loads((ROOT / "models" / "ppo_warehouse.json").read_text())
    shutil.copy(ROOT / "models" / "ppo_warehouse.json", tmp_path / "ppo_warehouse.json")
    stats = shipped["normalization"]
    venv = VecNormalize(DummyVecEnv([lambda: gym.make("Pendulum-v1")]), norm_obs=False, norm_reward=True)
    safe.apply_stats(venv, stats)
    (tmp_path / "ppo_warehouse_vecnormalize.pkl").write_bytes(pickle.dumps(venv))
    assert main(["convert-model", str(model)]) == 2
    assert "stored as a pickle" in capsys.readouterr().err and not (tmp_path / "ppo_warehouse.safetensors").exists()
    assert main(["convert-model", str(model), "--trust-pickle"]) == 0
    assert (tmp_path / "ppo_warehouse.safetensors").read_bytes() == (ROOT / "models" / "ppo_warehouse.safetensors").read_bytes()
    assert json.loads((tmp_path / "ppo_warehouse.json").read_text()) == shipped
    (tmp_path / "ppo_warehouse_vecnormalize.pkl").unlink()
    loaded, meta, _ = load_model(model)
    assert meta["normalization"] == stats


def test_broken_statistics_and_sidecars_are_clear_errors(tmp_path):
    model = _zip_only(tmp_path)
    (tmp_path / "ppo_warehouse_vecnormalize.json").write_text('{"obs": null}')
    with pytest.raises(ModelError, match="malformed normalization statistics"):
        load_model(model, algo="ppo")
    (tmp_path / "ppo_warehouse_vecnormalize.json").write_text("[[[[")
    with pytest.raises(ModelError, match="not valid JSON"):
        load_model(model, algo="ppo")
    (tmp_path / "ppo_warehouse_vecnormalize.json").unlink()
    (tmp_path / "ppo_warehouse.json").write_text('["a list"]')
    with pytest.raises(ModelError, match="must be a JSON object"):
        load_model(model, algo="ppo")


@pytest.mark.parametrize("name,message", [
    ("os.system", "may name classes of bulletnav"),
    ("subprocess.Popen", "may name classes of bulletnav"),
    ("torch.nn.functional.relu", "not a class"),
    ("bulletnav.rl.policies.NoSuchPolicy", "cannot be imported"),
])
def test_hyperparameter_files_name_only_allowed_classes(tmp_path, name, message):
    from bulletnav.errors import ConfigError
    from bulletnav.rl.hyperparams import import_name, policy_class

    with pytest.raises(ConfigError, match=message):
        import_name(name)
    with pytest.raises(ConfigError, match=message):
        policy_class({"policy": name})
    assert import_name("torch.nn.ReLU") is torch.nn.ReLU


def test_a_pickled_schedule_function_is_not_run_and_the_model_still_acts(tmp_path):
    """RL Zoo saves linear schedules as pickled functions: the model loads without running them."""
    import math

    model = tmp_path / "zoo.zip"
    function = {":type:": "<class 'function'>", ":serialized:": base64.b64encode(pickle.dumps(math.sqrt)).decode()}

    def change(data):
        data["learning_rate"] = function
        data["clip_range"] = {":type:": "<class 'function'>", ":serialized:": function[":serialized:"]}
        return data

    _rewrite_zip(ROOT / "models" / "ppo_warehouse.zip", model, change)
    _plain_sidecar("ppo_warehouse", model.with_suffix(".json"))
    loaded, _, _ = load_model(model)
    shipped, _, _ = load_model(ROOT / "models" / "ppo_warehouse.zip")
    obs = np.zeros((4, *loaded.observation_space.shape), dtype=np.float32)
    np.testing.assert_array_equal(loaded.predict(obs, deterministic=True)[0], shipped.predict(obs, deterministic=True)[0])
    # and acts as the weights say: against a NumPy forward pass from the shipped safe file's arrays
    space = loaded.observation_space
    obs = np.random.default_rng(2).uniform(space.low, space.high, (64, *space.shape)).astype(np.float32)
    np.testing.assert_allclose(loaded.predict(obs, deterministic=True)[0],
                               _numpy_actions(ROOT / "models" / "ppo_warehouse.safetensors", obs), atol=1e-5)
    assert loaded.learning_rate == 0.0
    with pytest.raises(ModelError, match="pickled function"):
        loaded.clip_range(1.0)
