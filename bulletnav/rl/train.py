"""``bulletnav train``: Stable-Baselines3 on a bulletnav env with periodic evaluation, atomic
checkpoints, resume and a run record. The learning-curve plot is drawn by the caller's
``plot_curve`` (the CLI and sweeps pass :func:`bulletnav.viz.compare.plot_learning_curve`):
training sits below :mod:`bulletnav.viz` and does not import it."""

from __future__ import annotations

import json
import logging
import os
import platform
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav import ENV_ID
from bulletnav.errors import ModelError
from bulletnav.files import write_json
from bulletnav.provenance import git_commit, machine
from bulletnav.rl.algos import algo_class
from bulletnav.rl.callbacks import (
    CheckpointCallback,
    EvaluationCallback,
    ThroughputCallback,
    TimedVecEnv,
    finish_checkpoint,
    save_checkpoint,
)
from bulletnav.rl.envs import EVAL_SEED_BASE, make_env_fn
from bulletnav.rl.hyperparams import apply_overrides, load_hyperparams, model_kwargs, policy_class, upgrade_hyperparams
from bulletnav.rl.io import atomic_save_model, atomic_save_vecnormalize
from bulletnav.rl.safe import apply_stats, load_stats, load_zip, save_safe, stats_to_json, zip_spaces
from bulletnav.rl.sidecar import read_sidecar, sidecar_path, vecnormalize_path

log = logging.getLogger(__name__)


EVAL_FREQ = 25_000
"""In-training evaluations' default period (timesteps) for a run of at least 5 times as many steps."""


def auto_eval_freq(timesteps: int) -> int:
    """The evaluation period (timesteps) when none is given: :data:`EVAL_FREQ`, or a fifth of a
    run shorter than 5 times that (rounded up), so its learning curve has at least five points
    (the last at the end of training)."""
    return EVAL_FREQ if timesteps >= 5 * EVAL_FREQ else max(1, -(-int(timesteps) // 5))


@dataclass(frozen=True)
class TrainConfig:
    algo: str
    timesteps: int | None
    """Total environment steps; None takes the hyperparameter file's ``n_timesteps`` (RL
    Zoo's key), else 500,000."""
    out: Path
    seed: int = 0
    n_envs: int | None = None
    """Parallel envs (SubprocVecEnv); None takes the hyperparameter file's value."""
    resume: bool = False
    eval_freq: int | None = None
    """Evaluate every this many timesteps (summed over envs); the end of training is evaluated
    too. None: :func:`auto_eval_freq` (every 25,000, or a fifth of a shorter run)."""
    eval_episodes: int = 20
    checkpoint_freq: int = 25_000
    progress_bar: bool = True
    vec_env: str = "auto"
    """'subproc' (one process per env), 'dummy' (all in this process) or 'auto': subprocesses
    when there are several envs and more than one CPU core (they step in parallel; measured
    with ``bulletnav bench env --vec``), else this process."""
    env_overrides: dict | None = None
    """Extra env keyword arguments on top of the hyperparameter file's."""
    hyperparams: Path | None = None
    """A hyperparameter YAML file to use instead of ``rl/hyperparams/<algo>.yml`` (same format)."""
    command: str = ""
    env_id: str = ENV_ID
    """The registered env to train on; its entry in the hyperparameter file is used."""
    shield: bool = False
    """Train (and evaluate during training) behind the safety shield (``ShieldWrapper``)."""
    init_from: Path | None = None
    """Fine-tune: start from this model's weights (and its reward-normalisation statistics)
    instead of fresh ones, with this run's hyperparameters; the step count starts at 0. The
    model must have been trained with the same algorithm, observation and action spaces."""
    overrides: dict[str, Any] | None = None
    """Hyperparameters set on top of the file's (a sweep's trial); a dotted key reaches into a
    mapping, e.g. ``{"learning_rate": 1e-4, "env_kwargs.reward_collision": -40.0}``."""
    on_evaluation: Callable[[dict[str, Any]], None] | None = None
    """Called with every evaluation row (timesteps, wall_time, success_rate, ...) as it is
    recorded; a sweep reports them to Ray Tune for early stopping."""
    stop_at_success: float | None = None
    """Stop at the first in-training evaluation whose success rate reaches this (0-1), the
    model also evaluated before its first update; the run records the steps and wall time it
    took (``reached_success``). None trains the whole budget."""
    trust_pickle: bool = False
    """Let ``--resume`` / ``--init-from`` files be unpickled (older checkpoints with a
    ``*_vecnormalize.pkl``, zips with entries bulletnav does not rebuild): runs their code."""


def resolve_vec_env(vec_env: str, n_envs: int) -> str:
    """The vector env a run uses: ``"subproc"`` or ``"dummy"`` (see :attr:`TrainConfig.vec_env`).

    Raises:
        ValueError: ``vec_env`` is not 'auto', 'subproc' or 'dummy'.
    """
    if vec_env not in ("auto", "subproc", "dummy"):
        raise ValueError(f"vec_env must be 'auto', 'subproc' or 'dummy', got {vec_env!r}")
    if n_envs < 2:
        return "dummy"  # one env gains nothing from a process of its own
    if vec_env == "auto":
        return "subproc" if (os.cpu_count() or 1) > 1 else "dummy"
    return vec_env


def _make_vec_env(cfg: TrainConfig, env_kwargs: dict[str, Any], n_envs: int, shield: bool = False):
    from stable_baselines3.common.vec_env import DummyVecEnv, SubprocVecEnv, VecMonitor

    fns = [make_env_fn(env_kwargs, cfg.env_id, shield) for _ in range(n_envs)]
    if resolve_vec_env(cfg.vec_env, n_envs) == "subproc":
        try:
            venv = SubprocVecEnv([IgnoringInterrupts(fn) for fn in fns], start_method="forkserver")
        except (EOFError, ConnectionError) as exc:  # a worker could not build its env: build it here to name why
            raise _why_no_env(fns[0], cfg.env_id, exc) from None
    else:
        venv = DummyVecEnv(fns)
    venv.seed(cfg.seed)
    return VecMonitor(TimedVecEnv(venv))


class IgnoringInterrupts:
    """An env factory for a worker process that first makes the process ignore SIGINT: a
    Ctrl-C at the terminal reaches the whole process group, and the training process alone
    handles it (it stops the workers; none prints a traceback)."""

    def __init__(self, fn: Callable[[], Any]) -> None:
        self.fn = fn

    def __call__(self) -> Any:
        from bulletnav.runs import ignore_interrupts

        ignore_interrupts()
        try:
            return self.fn()
        except Exception:  # noqa: BLE001 -- quietly: the training process builds one env itself and names the error
            from bulletnav.stdio import exit_now

            exit_now(WORKER_ENV_FAILED)


WORKER_ENV_FAILED = 3
"""Exit status of an env worker process that could not build its env (it prints nothing; the
training process then builds the env itself and raises its error as one line)."""


def _why_no_env(fn: Callable[[], Any], env_id: str, lost: BaseException) -> Exception:
    """The error an env worker died of, found by building its env in this process: a
    bulletnav error as it is, any other as a ConfigError naming the env id (one line either way)."""
    from bulletnav.errors import BulletnavError, ConfigError

    try:
        env = fn()
    except BulletnavError as exc:
        return exc
    except Exception as exc:  # noqa: BLE001 -- a TypeError or ValueError of the env's keywords
        return ConfigError(f"{env_id}: its env cannot be made: {' '.join(str(exc).split())}")
    env.close()
    return BulletnavError(f"{env_id}: an env worker process ended while starting ({type(lost).__name__}), though the "
                          "env builds in this process: out of memory or processes?")


def stop_workers(venv: Any) -> None:
    """Stop the env worker processes under ``venv``'s wrappers at once (after a Ctrl-C the
    training process may be half-way through a step's replies, so ``close`` could wait on a
    reply that never comes); nothing for envs in this process."""
    inner = venv
    while inner is not None and not hasattr(inner, "processes"):
        inner = getattr(inner, "venv", None)
    if inner is None:
        venv.close()
        return
    for process in inner.processes:
        process.terminate()
    for process in inner.processes:
        process.join()
    for remote in inner.remotes:
        remote.close()
    inner.closed = True


def progress_bar_callback() -> Any:
    """A progress bar (tqdm's rich bar, as SB3's) as a callback of ours (``learn(progress_bar=True)``
    keeps its own out of reach), so an interrupted run can close it (:func:`close_progress_bar`)
    before the command says where it stopped. Its total is rounded up to whole rollouts: PPO and
    A2C learn ``n_steps x n_envs`` steps at a time, so a run ends past the steps asked for (SB3's
    own bar read e.g. 16,384/15,000)."""
    from stable_baselines3.common.callbacks import BaseCallback
    from tqdm.rich import tqdm

    class _Bar(BaseCallback):
        pbar = None

        def _on_training_start(self) -> None:
            rollout = int(getattr(self.model, "n_steps", 1)) * int(self.model.n_envs)
            steps = self.locals["total_timesteps"] - self.model.num_timesteps
            self.pbar = tqdm(total=-(-steps // rollout) * rollout)

        def _on_step(self) -> bool:
            self.pbar.update(self.training_env.num_envs)
            return True

        def _on_training_end(self) -> None:
            self.pbar.refresh()
            self.pbar.close()

    return _Bar()


def close_progress_bar(bar: Any) -> None:
    """Draw an interrupted run's progress bar a last time and stop it (nothing for None, or a bar not started)."""
    pbar = getattr(bar, "pbar", None)
    if pbar is not None:
        pbar.close()


def _timer(venv: Any) -> TimedVecEnv:
    """The :class:`TimedVecEnv` under the run's wrappers (VecNormalize, VecMonitor)."""
    while not isinstance(venv, TimedVecEnv):
        venv = venv.venv
    return venv


PlotCurve = Callable[[list[dict[str, Any]], Path, str], None]
"""``plot_curve(history, path, title)``: draws the evaluation history to a PNG
(:func:`bulletnav.viz.compare.plot_learning_curve`)."""


def train(cfg: TrainConfig, plot_curve: PlotCurve | None = None) -> dict[str, Any]:
    """Train, evaluate and save; returns the run record (also written to ``out/run.json``).
    ``plot_curve`` draws ``out/learning_curve.png`` from the evaluations (None: no plot)."""
    import torch
    from stable_baselines3.common.vec_env import VecNormalize

    torch.set_num_threads(1)  # 2 cores: more threads slow PPO down and starve the env workers
    hp, env_kwargs, shield = _run_settings(cfg)
    n_envs = int(cfg.n_envs or hp.get("n_envs", 4))
    timesteps = int(cfg.timesteps if cfg.timesteps is not None else hp.get("n_timesteps", 500_000))
    cfg.out.mkdir(parents=True, exist_ok=True)
    venv = _make_vec_env(cfg, env_kwargs, n_envs, shield)
    normalize = hp.get("normalize") or None
    ckpt = cfg.out / "checkpoints" / "last.zip"
    history: list[dict[str, Any]] = []
    start_steps = 0
    if cfg.resume:
        model, venv, history = _resumed_model(cfg, ckpt, venv, normalize)
        start_steps = int(model.num_timesteps)
    else:
        model, venv = _new_model(cfg, hp, venv, normalize)
    vecnorm = venv if isinstance(venv, VecNormalize) else None
    # the training's wall clock runs on across resumes: from the checkpoint's record, or (older
    # checkpoints) from the last in-training evaluation's
    prior = _prior_wall_time(ckpt, history) if cfg.resume else 0.0
    eval_freq = cfg.eval_freq if cfg.eval_freq is not None else auto_eval_freq(timesteps)
    evaluation = EvaluationCallback(cfg.out, eval_freq, cfg.eval_episodes, env_kwargs, history, env_id=cfg.env_id,
                                    shield=shield, started=time.time() - prior, on_row=cfg.on_evaluation,
                                    stop_at_success=cfg.stop_at_success)
    throughput = ThroughputCallback(_timer(venv), evaluation)
    curriculum = _curriculum_callback(cfg, hp, venv)
    callbacks = [evaluation, throughput] + ([curriculum] if curriculum is not None else [])

    def state() -> dict[str, Any]:
        extra: dict[str, Any] = {"wall_time": round(time.time() - evaluation.started, 1)}
        if curriculum:
            extra["curriculum"] = curriculum.curriculum.state()
        return extra

    checkpoints = CheckpointCallback(cfg.out, cfg.checkpoint_freq, state)
    record: dict[str, Any] = {
        "command": cfg.command, "algo": cfg.algo, "env_id": cfg.env_id, "seed": cfg.seed, "timesteps": timesteps,
        "n_envs": n_envs, "vec_env": resolve_vec_env(cfg.vec_env, n_envs), "hyperparams": hp,
        "env_kwargs": env_kwargs, "shield": shield, "eval_freq": eval_freq,
        "git_commit": git_commit(), "machine": machine(), "torch_threads": torch.get_num_threads(),
        "resumed_from": start_steps or None,
        "init_from": str(cfg.init_from) if cfg.init_from is not None else None,
        "versions": _versions(),
    }
    write_json(cfg.out / "config.json", record)
    t0 = time.time()
    remaining = max(timesteps - start_steps, 0)
    if remaining:
        _learn(model, cfg, remaining, [checkpoints, *callbacks], venv, evaluation)
    wall = time.time() - t0
    timing = throughput.summary() if remaining else None
    save_checkpoint(model, cfg.out, vecnorm, state())
    final_path = cfg.out / "model.zip"
    _save_and_evaluate(model, final_path, vecnorm, evaluation, history, bool(remaining))
    venv.close()
    if curriculum is not None:
        record["curriculum_final"] = curriculum.curriculum.state()
    record.update(throughput=timing)
    record.update(wall_time_s=round(wall, 1), wall_time_total_s=round(prior + wall, 1), total_timesteps=int(model.num_timesteps),
                  final_eval=history[-1] if history else None, eval_seeds=f"{EVAL_SEED_BASE}..",
                  stop_at_success=cfg.stop_at_success, reached_success=evaluation.reached)
    meta = {"algo": cfg.algo, "env_id": cfg.env_id, "env_kwargs": env_kwargs, "shield": shield, "seed": cfg.seed,
            "timesteps": int(model.num_timesteps), "git_commit": record["git_commit"], "command": cfg.command}
    write_json(sidecar_path(final_path), save_safe(model, final_path, vecnorm, meta))
    write_json(cfg.out / "run.json", record)
    if history and plot_curve is not None:
        plot_curve(history, cfg.out / "learning_curve.png", f"{cfg.algo.upper()} seed {cfg.seed}")
    return record


def _prior_wall_time(ckpt: Path, history: list[dict[str, Any]]) -> float:
    """The resumed training's wall time so far (s): the checkpoint record's, or (older
    checkpoints) the last in-training evaluation's."""
    record = ckpt.with_suffix(".json")
    last = json.loads(record.read_text()) if record.is_file() else {}
    return float(last.get("wall_time", history[-1]["wall_time"] if history else 0.0))


def _learn(model: Any, cfg: TrainConfig, steps: int, callbacks: list, venv: Any, evaluation: EvaluationCallback) -> None:
    """``model.learn`` for ``steps`` more steps (with a progress bar if ``cfg`` asks). On Ctrl-C
    or SIGTERM the last checkpoint stands: the bar is closed, the env workers and the evaluation
    env are stopped, and the interrupt goes on up."""
    bar = progress_bar_callback() if cfg.progress_bar else None
    try:
        model.learn(total_timesteps=steps, callback=[*callbacks, *([bar] if bar else [])],
                    reset_num_timesteps=not cfg.resume, tb_log_name=cfg.algo)
    except KeyboardInterrupt:
        close_progress_bar(bar)
        stop_workers(venv)
        evaluation.close()
        raise


def _run_settings(cfg: TrainConfig) -> tuple[dict[str, Any], dict[str, Any], bool]:
    """The run's hyperparameters, env settings and shield: ``cfg``'s (the hyperparameter file
    with its overrides), or the recorded ones of a resumed run (it keeps the settings it started with)."""
    hp = apply_overrides(load_hyperparams(cfg.algo, env_id=cfg.env_id, path=cfg.hyperparams), cfg.overrides)
    env_kwargs = {**hp.get("env_kwargs", {}), **(cfg.env_overrides or {})}
    if hp.get("randomize"):  # domain randomization: the hyperparameter file's randomize: block
        env_kwargs.setdefault("randomize", hp["randomize"])
    shield = cfg.shield
    recorded = cfg.out / "config.json"
    if cfg.resume and recorded.is_file():
        original = json.loads(recorded.read_text())
        hp = upgrade_hyperparams(original["hyperparams"], str(recorded))
        env_kwargs = {**hp.get("env_kwargs", {}), **original["env_kwargs"]}
        shield = bool(original.get("shield", False))
    return hp, env_kwargs, shield


def _resumed_model(cfg: TrainConfig, ckpt: Path, venv: Any, normalize: dict[str, Any] | None) -> tuple[Any, Any, list[dict[str, Any]]]:
    """The model of the last checkpoint on ``venv`` (normalized with the checkpoint's
    statistics), the env it learns on, and the evaluations up to it.

    Raises:
        ModelError: no checkpoint to resume from.
    """
    from stable_baselines3.common.vec_env import VecNormalize

    finish_checkpoint(cfg.out)  # a run killed while writing its last checkpoint
    if not ckpt.is_file():
        raise ModelError(f"{ckpt}: no checkpoint to resume from")
    if normalize:
        venv = apply_stats(VecNormalize(venv, **normalize), _checkpoint_stats(ckpt, cfg.trust_pickle))
    model = load_zip(ckpt, algo_class(cfg.algo), env=venv, trust_pickle=cfg.trust_pickle)
    history = []
    hist_file = cfg.out / "eval_history.json"
    if hist_file.is_file():
        history = [row for row in json.loads(hist_file.read_text()) if row["timesteps"] <= int(model.num_timesteps)]
    return model, venv, history


def _new_model(cfg: TrainConfig, hp: dict[str, Any], venv: Any, normalize: dict[str, Any] | None) -> tuple[Any, Any]:
    """A new model on ``venv`` (normalized with ``normalize``), started from ``cfg.init_from``'s
    weights and normalization statistics where given, and the env it learns on."""
    from stable_baselines3.common.vec_env import VecNormalize

    if cfg.init_from is not None:
        _check_spaces(cfg.init_from, venv)
    if normalize:
        stats = load_stats(Path(cfg.init_from), read_sidecar(cfg.init_from), cfg.trust_pickle) if cfg.init_from else None
        venv = VecNormalize(venv, **normalize)
        if isinstance(stats, dict):
            apply_stats(venv, stats)
        elif stats is not None:  # a trusted, unpickled VecNormalize
            venv.obs_rms, venv.ret_rms = stats.obs_rms, stats.ret_rms
        venv.training, venv.norm_reward = True, bool(normalize.get("norm_reward", True))
    model = algo_class(cfg.algo)(policy_class(hp), venv, seed=cfg.seed, device="cpu", verbose=0,
                                 tensorboard_log=str(cfg.out / "tb"), **model_kwargs(hp, venv.action_space.shape[0]))
    if cfg.init_from is not None:
        _load_weights(model, cfg.init_from)
    return model, venv


def _curriculum_callback(cfg: TrainConfig, hp: dict[str, Any], venv: Any) -> Any:
    """The curriculum of the hyperparameters (restored from the last checkpoint on a resume),
    its first stage sent to the envs before their first reset; None without one."""
    from bulletnav.rl.curriculum import Curriculum, CurriculumCallback

    if not hp.get("curriculum"):
        return None
    curriculum = CurriculumCallback(Curriculum.from_spec(hp["curriculum"], where=f"{cfg.algo} {cfg.env_id} curriculum"))
    if cfg.resume:
        state = json.loads((cfg.out / "checkpoints" / "last.json").read_text()).get("curriculum")
        if state:
            curriculum.curriculum.restore(state)
    curriculum.send_stage(venv)  # before the envs' first reset in learn()
    return curriculum


def _save_and_evaluate(model: Any, final_path: Path, vecnorm: Any, evaluation: Any, history: list[dict[str, Any]],
                       learned: bool) -> None:
    """Save ``model.zip`` (and its normalization statistics), then evaluate the saved model
    unless the last evaluation already did (``learned``: this call trained)."""
    atomic_save_model(model, final_path)
    if vecnorm is not None:
        atomic_save_vecnormalize(vecnorm, vecnormalize_path(final_path))
    stopped = evaluation.reached is not None  # learn() stopped before updating on that rollout
    if history and history[-1]["timesteps"] == model.num_timesteps and learned and not stopped:
        # that evaluation ran inside the last rollout, before the last update: evaluate the
        # model that is saved instead, so the record and model.zip agree
        history.pop()
    if not stopped and (not history or history[-1]["timesteps"] != model.num_timesteps):
        evaluation.evaluate(model)  # (a stopped run's weights are those of its last evaluation)
    evaluation.close()


def _check_spaces(path: Path, venv) -> None:
    """A model to fine-tune from must have this run's observation and action spaces."""
    if not Path(path).is_file():
        raise ModelError(f"{path}: model file not found (--init-from)")
    spaces = dict(zip(("observation_space", "action_space"), zip_spaces(Path(path))))
    for name in ("observation_space", "action_space"):
        theirs, ours = spaces.get(name), getattr(venv, name)
        if theirs is not None and (getattr(theirs, "shape", None) != getattr(ours, "shape", None) or theirs != ours):
            shapes = getattr(theirs, "shape", None), getattr(ours, "shape", None)
            what = f"has shape {shapes[0]}, this run's {shapes[1]}" if shapes[0] != shapes[1] else "has other bounds than this run's"
            raise ModelError(f"{path}: its {name} {what} (--init-from needs the same spaces: same env and settings)")


def _checkpoint_stats(ckpt: Path, trust_pickle: bool) -> dict[str, Any]:
    stats = load_stats(ckpt, {}, trust_pickle)
    if stats is None:
        raise ModelError(f"{ckpt}: no normalization statistics beside it ({vecnormalize_path(ckpt).name})")
    if not isinstance(stats, dict):  # a trusted pickle from an older checkpoint
        stats = stats_to_json(stats)
    return stats


def _load_weights(model, path: Path) -> None:
    """Copy a saved model's network weights (and optimizer state) into ``model``."""
    try:
        model.set_parameters(str(path), exact_match=True, device="cpu")
    except (RuntimeError, ValueError) as e:
        raise ModelError(f"{path}: its weights do not fit this run's {type(model).__name__} policy: {e}") from e


def _versions() -> dict[str, str]:
    import gymnasium
    import stable_baselines3
    import torch

    return {"python": platform.python_version(), "torch": torch.__version__, "stable_baselines3": stable_baselines3.__version__,
            "gymnasium": gymnasium.__version__, "numpy": np.__version__}
