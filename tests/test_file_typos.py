"""Every kind of file a user hands bulletnav, with a misspelt key and with a wrong type: one line
naming the file, the place and the key (with the nearest valid key for a misspelling), exit
status 2, and nothing started (no env worker, no model)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from bulletnav.cli import main
from bulletnav.filekinds import HEAD, KINDS, sniff, wrong_kind

HYPER = "bulletnav/Warehouse-v0:\n  policy: MlpPolicy\n  n_envs: 2\n{}\n"
SUITE = ("name: t\nepisodes: 1\nseed: 1\nworlds:\n  - {{env: bulletnav/Warehouse-v0}}\n"
         "controllers:\n  - {{name: a, type: navigator, planner: astar}}\n{}\n")
LAYOUT = "name: l\nsize: [8, 8]\nobstacles:\n  - {{type: box, center: [1, 1], size: [0.5, 0.5, 1]}}\n{}\n"
MAP = "image: m.pgm\nresolution: 0.1\norigin: [0, 0, 0]\nnegate: 0\noccupied_thresh: 0.65\nfree_thresh: 0.196\n{}\n"
SDF = ("<?xml version='1.0'?><sdf version='1.9'><world name='w'><model name='m'><static>true</static>"
       "<link name='l'><collision name='c'><geometry>{}</geometry></collision></link></model></world></sdf>")

# (kind, file name, text, the command, what the one line must say)
CASES = [
    ("hyperparameters: misspelt algorithm key", "h.yml", HYPER.format("  n_epoch: 5"), "train",
     ["unknown PPO hyperparameter 'n_epoch' (did you mean 'n_epochs'?)", "bulletnav/Warehouse-v0"]),
    ("hyperparameters: misspelt env keyword", "h.yml", HYPER.format("  env_kwargs: {reward_headng: 0.02}"), "train",
     ["env_kwargs: unknown keyword of bulletnav/Warehouse-v0 'reward_headng' (did you mean 'reward_heading'?)"]),
    ("hyperparameters: misspelt normalize key", "h.yml", HYPER.format("  normalize: {norm_rew: true}"), "train",
     ["normalize: unknown VecNormalize key 'norm_rew' (did you mean 'norm_reward'?)"]),
    ("hyperparameters: misspelt policy_kwargs key", "h.yml", HYPER.format("  policy_kwargs: {net_arc: [64]}"), "train",
     ["policy_kwargs: unknown argument of ActorCriticPolicy 'net_arc' (did you mean 'net_arch'?)"]),
    ("hyperparameters: wrong type", "h.yml", HYPER.format("  n_steps: many"), "train",
     ["bulletnav/Warehouse-v0.n_steps must be a number, got 'many'"]),
    ("hyperparameters: policy of a wrong type", "h.yml", HYPER.replace("policy: MlpPolicy", "policy: 5").format(
        "  policy_kwargs: {net_arch: [64]}"), "train", ["bulletnav/Warehouse-v0.policy must name a policy class", "got 5"]),
    ("hyperparameters: wrong env keyword type", "h.yml", HYPER.format("  env_kwargs: {lidar_rays: lots}"), "train",
     ["env_kwargs", "lidar_rays"]),
    ("suite: misspelt key", "s.yaml", SUITE.format("episods: 3"), "benchmark", ["episods"]),
    ("suite: wrong type", "s.yaml", SUITE.replace("episodes: 1", "episodes: one").format(""), "benchmark", ["episodes"]),
    ("layout: misspelt key", "l.yaml", LAYOUT.format("wall_heigth: 2"), "navigate", ["wall_heigth"]),
    ("layout: wrong type", "l.yaml", LAYOUT.replace("size: [8, 8]", "size: big").format(""), "navigate", ["size"]),
    ("map_server: misspelt key", "m.yaml", MAP.replace("resolution", "resolutoin").format(""), "navigate",
     ["unknown map field 'resolutoin' (did you mean 'resolution'?)"]),
    ("map_server: wrong type", "m.yaml", MAP.replace("resolution: 0.1", "resolution: fine").format(""), "navigate",
     ["field 'resolution' must be a finite number, got 'fine'"]),
    ("SDF: misspelt shape", "w.world", SDF.format("<boxx><size>1 1 1</size></boxx>"), "navigate", ["model 'm'"]),
    ("SDF: wrong type", "w.world", SDF.format("<box><size>one 1 1</size></box>"), "navigate", ["<size>", "'one 1 1'"]),
]


@pytest.mark.parametrize("kind, name, text, command, needles", CASES, ids=[c[0] for c in CASES])
def test_a_misspelt_key_or_a_wrong_type_is_one_line_and_exit_2(kind, name, text, command, needles, tmp_path, capsys,
                                                              monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "m.pgm").write_bytes(b"P5\n40 40\n255\n" + np.pad(np.full((38, 38), 254, np.uint8), 1).tobytes())
    path = tmp_path / name
    path.write_text(text)
    argv = {"train": ["train", "--algo", "ppo", "--hyperparams", name, "--timesteps", "256", "--out", "run"],
            "benchmark": ["benchmark", name, "--out", "bench"],
            "navigate": ["navigate", "--world", name, "--episodes", "1"]}[command]
    code = main(argv)
    err = capsys.readouterr().err.strip()
    assert code == 2, (kind, err)
    assert err.count("\n") == 0 and err.startswith(f"bulletnav {command}: error: ") and name in err, (kind, err)
    for needle in needles:
        assert needle in err, (kind, err)
    assert not Path(tmp_path / "run").exists() and not Path(tmp_path / "bench" / "episodes.jsonl").exists()


@pytest.mark.slow  # two env worker processes start (and one dies)
def test_an_env_that_a_worker_cannot_build_is_one_line_not_a_connection_reset(tmp_path):
    """A value the file check cannot see (a layout file that is not there) fails in each env
    worker: the worker ends quietly, the training process builds the env itself and prints its
    error as one line, exit 2. It was 65-181 lines of worker tracebacks ending in
    ``ConnectionResetError``."""
    import subprocess
    import sys

    hp = tmp_path / "h.yml"
    hp.write_text(HYPER.format(f"  env_kwargs: {{world: {tmp_path / 'nothere.yaml'}}}"))
    run = subprocess.run([sys.executable, "-m", "bulletnav.cli", "train", "--algo", "ppo", "--hyperparams", str(hp),
                          "--timesteps", "4096", "--vec-env", "subproc", "--out", str(tmp_path / "run")],
                         capture_output=True, text=True, timeout=600)
    assert run.returncode == 2, run.stderr[-2000:]
    assert "Traceback" not in run.stderr and "ConnectionResetError" not in run.stderr
    errors = [line for line in run.stderr.splitlines() if "error" in line]
    assert errors == [f"bulletnav train: error: {tmp_path / 'nothere.yaml'}: cannot read layout file "
                      "(No such file or directory)"], run.stderr


# every kind of file, as it would be written, for the wrong-option matrix below
KIND_FILES = {
    "layout": ("l.yaml", LAYOUT.format("")),
    "map": ("m.yaml", MAP.format("")),
    "gazebo": ("w.world", SDF.format("<box><size>1 1 1</size></box>")),
    "suite": ("s.yaml", SUITE.format("")),
    "hyperparams": ("h.yml", HYPER.format("")),
    "model": ("m.zip", None),
    "image": ("m.pgm", None),
    "recording": ("r.mcap", None),
}
WANTED = {  # the option each command takes a file at, and what its line says the file is not
    "world": (["navigate", "--world", "{}", "--episodes", "1"], "not a world"),
    "suite": (["benchmark", "{}", "--out", "bench"], "not a benchmark suite"),
    "hyperparams": (["train", "--algo", "ppo", "--hyperparams", "{}", "--timesteps", "256", "--out", "run"],
                    "not a hyperparameter file"),
    "model": (["evaluate", "--model", "{}", "--episodes", "1"], "not a model"),
}
WORLDS = {"layout", "map", "gazebo"}
WRONG = [(kind, wanted) for kind in KIND_FILES for wanted in WANTED
         if not (kind == wanted or (wanted == "world" and kind in WORLDS) or (wanted == "world" and kind in ("model", "image")))]


def _write_kind(tmp_path: Path, kind: str) -> str:
    import zipfile

    (tmp_path / "m.pgm").write_bytes(b"P5\n40 40\n255\n" + np.pad(np.full((38, 38), 254, np.uint8), 1).tobytes())
    name, text = KIND_FILES[kind]
    if kind == "model":
        with zipfile.ZipFile(tmp_path / name, "w") as zf:
            zf.writestr("data", "{}")
    elif kind == "recording":
        (tmp_path / name).write_bytes(b"\x89MCAP0\r\n" + bytes(64))
    elif text is not None:
        (tmp_path / name).write_text(text)
    return name


@pytest.mark.parametrize("kind, wanted", WRONG, ids=[f"{k} as {w}" for k, w in WRONG])
def test_a_file_given_where_another_kind_belongs_is_named_for_what_it_is(kind, wanted, tmp_path, capsys, monkeypatch):
    """A world given as a suite, a suite as hyperparameters, hyperparameters as a model, ...:
    one line that says what the file is and where it goes, exit status 2, nothing started.
    (A model or an image given as a world has its own line: tests/test_userworld.py.)"""
    monkeypatch.chdir(tmp_path)
    name = _write_kind(tmp_path, kind)
    template, not_what = WANTED[wanted]
    command = template[0]
    code = main([a.format(name) for a in template])
    err = capsys.readouterr().err.strip()
    assert code == 2, (kind, wanted, err)
    what = KINDS[kind][0]
    assert err == f"bulletnav {command}: error: {name}: {what}, {not_what}: {KINDS[kind][1]}", err
    assert not Path(tmp_path / "run").exists() and not Path(tmp_path / "bench").exists()


def test_each_kind_is_told_by_its_bytes_and_a_misspelt_file_of_a_kind_stays_its_kind(tmp_path):
    for kind in KIND_FILES:
        assert sniff(tmp_path / _write_kind(tmp_path, kind)) == kind, kind
    rl_zoo = tmp_path / "zoo.yml"
    rl_zoo.write_text("CartPole-v1:\n  n_timesteps: 1000\n  policy: MlpPolicy\n")
    assert sniff(rl_zoo) == "hyperparams"
    wrapper = tmp_path / "site.yaml"
    wrapper.write_text("map: m.yaml\nstart: [1, 1, 0]\ngoal: [2, 2]\n")
    assert sniff(wrapper) == "map" and wrong_kind(wrapper, "world") is None
    typo = tmp_path / "typo.yaml"  # 'world' for 'worlds': no kind for sure; the suite reader names the field
    typo.write_text(SUITE.replace("worlds:", "world:").format(""))
    assert sniff(typo) is None
    big = tmp_path / "big.yaml"  # longer than the head read: not decoded
    big.write_text(LAYOUT.format("#" + "x" * (HEAD + 10)))
    assert sniff(big) is None
