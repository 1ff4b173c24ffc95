"""``bulletnav sweep``: a sweep file's trials on Ray Tune, each the project's own training.

Local by default (an embedded Ray with this machine's cores, shut down on exit and on
Ctrl-C); with an address it joins an existing cluster, and a storage path or URI keeps the
experiment where every node sees it. Each trial runs :func:`~bulletnav.rl.train.train`
(checkpoints included), reports its in-training evaluations to Tune (early stopping sees
them), then scores the final model on held-out episodes (:func:`~bulletnav.rl.evaluate.evaluate_model`).
A trial's training checkpoints travel with its Tune checkpoints, so a resumed sweep
(``resume=True``) continues unfinished trials from their last checkpoint and never reruns
finished ones; a trial that raises is recorded with its error and the others go on.
"""

from __future__ import annotations

import json
import logging
import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from ray import tune

from bulletnav.errors import ConfigError, RunError
from bulletnav.files import write_bytes
from bulletnav.provenance import git_commit, machine
from bulletnav.sweep.results import config_label, summarize_configs, write_results
from bulletnav.sweep.spec import SweepSpec

log = logging.getLogger(__name__)

RUN_FILES = ("model.zip", "model.safetensors", "model.json", "model_vecnormalize.json", "run.json", "config.json", "eval_history.json",
             "heldout.json", "learning_curve.png", "hyperparams.yml")
"""What a finished trial keeps in its last Tune checkpoint."""


@dataclass(frozen=True)
class SweepOptions:
    """How to run a sweep (the sweep file says what to run)."""

    out: Path
    """Local results directory: the tables and plot go to ``out/<name>``; so does the Ray
    experiment unless ``storage`` is given."""
    address: str | None = None
    """A running Ray cluster to join (``host:port`` or ``auto``); None: ``RAY_ADDRESS`` if
    set, else an embedded local Ray."""
    storage: str | None = None
    """Where the Ray experiment (trial checkpoints and state) lives: a path every node can
    reach or a bucket URI. Default ``out``."""
    resume: bool = False
    """Continue the interrupted sweep of the same name: finished trials are kept, unfinished
    ones continue from their checkpoints, failed ones stay failed."""
    optimize: int | None = None
    """Run this many trials of Optuna's TPE over the file's ``search:`` (with early stopping)
    instead of the grid."""
    num_cpus: int | None = None
    """CPUs of the embedded local Ray (default: all of this machine's)."""
    command: str = ""


def run_sweep(spec: SweepSpec, opts: SweepOptions) -> dict[str, Any]:
    """Run (or resume) the sweep; write its tables, plot and, with ``optimize``, the best
    hyperparameter file; return the results record.

    Raises:
        ConfigError: ``optimize`` without a ``search:`` block, or the base hyperparameters
            are missing the env id.
        RunError: the experiment exists and ``resume`` is off, or ``resume`` finds none.
    """
    import ray

    from bulletnav.rl.hyperparams import load_hyperparams

    if opts.optimize is not None and not spec.search:
        raise ConfigError(f"sweep {spec.name!r}: --optimize needs a 'search:' block of distributions")
    if opts.optimize is not None and opts.optimize < 1:
        raise ConfigError(f"sweep {spec.name!r}: --optimize needs N >= 1 trials (got {opts.optimize})")
    base = load_hyperparams(spec.algo, env_id=spec.env_id, path=spec.hyperparams)
    storage = opts.storage or str(Path(opts.out).resolve())
    local_storage = "://" not in storage
    results_dir = spec.results_dir(opts.out, storage if local_storage else None)  # refused if either leads out
    experiment = f"{storage.rstrip('/')}/{spec.name}"
    exists = tune.Tuner.can_restore(experiment) if local_storage or opts.resume else False
    if exists and not opts.resume:
        raise RunError(f"{experiment}: a sweep named {spec.name!r} is already there; --resume continues it "
                       "(or give it another name or --out)")
    if opts.resume and not exists:
        raise RunError(f"{experiment}: no sweep to resume")
    started, commit = time.time(), git_commit()  # the code the sweep starts with (trials record their own)
    own_ray = not ray.is_initialized()
    if own_ray:
        address = opts.address or os.environ.get("RAY_ADDRESS")
        if address:
            ray.init(address=address, log_to_driver=False)
        else:
            # "local": a new embedded Ray even when another one runs on this machine (plain
            # ray.init() would join the newest local cluster, someone else's sweep included)
            ray.init(address="local", num_cpus=opts.num_cpus or os.cpu_count(), include_dashboard=False,
                     log_to_driver=False)
    _STARTED.clear()
    _ENDED.clear()
    try:
        trainable = tune.with_resources(tune.with_parameters(_trial, spec=spec.to_dict(), base=base), dict(spec.resources))
        if opts.resume:
            tuner = tune.Tuner.restore(experiment, trainable=trainable, resume_unfinished=True,
                                       resume_errored=False, restart_errored=False)
        else:
            tuner = tune.Tuner(trainable, param_space=_param_space(spec, opts.optimize),
                               tune_config=_tune_config(spec, opts.optimize),
                               run_config=tune.RunConfig(name=spec.name, storage_path=storage, verbose=0,
                                                         failure_config=tune.FailureConfig(max_failures=0),
                                                         checkpoint_config=tune.CheckpointConfig(num_to_keep=2),
                                                         callbacks=[TrialWatch()]))
        grid = tuner.fit()
    finally:
        if own_ray:
            ray.shutdown()
    # Ray Tune ends fit() quietly on Ctrl-C: trials that started in this run and neither
    # completed nor failed were cut short
    cut = _STARTED - _ENDED
    rows = [_row(r, spec, cut) for r in grid]
    interrupted = sum(r["status"] == "interrupted" for r in rows)
    rows.sort(key=lambda r: (json.dumps(r["config"], sort_keys=True), r["seed"]))
    summary = summarize_configs(rows, spec.metric, spec.mode)
    record: dict[str, Any] = {
        "name": spec.name, "command": opts.command, "spec": spec.to_dict(), "experiment": experiment,
        "address": opts.address or os.environ.get("RAY_ADDRESS") or "local", "optimize": opts.optimize,
        "resumed": opts.resume, "interrupted": interrupted, "git_commit": commit, "machine": machine(), "ray": ray.__version__,
        "wall_time_s": round(time.time() - started, 1),
    }
    if opts.optimize is not None:
        best = _best(rows, spec)
        if best is not None:
            path = results_dir / "best_hyperparams.yml"
            write_best_hyperparams(path, spec, base, best)
            record["best"] = {"trial": best["trial"], "config": best["config"], spec.metric: best[spec.metric],
                              "hyperparams": str(path)}
    record["files"] = {k: str(v) for k, v in write_results(results_dir, rows, summary, record).items()}
    return {**record, "summary": summary, "trials": rows}


_STARTED: set[str] = set()
_ENDED: set[str] = set()
"""Trial ids that started, and that completed or failed, in this process's latest
:func:`run_sweep` (module-level: a resumed sweep restores the :class:`TrialWatch` it was
started with from Ray's saved state, and that copy must report here)."""


class TrialWatch(tune.Callback):
    """Records which trials start and which end (complete or fail), so that trials cut short
    by Ctrl-C are told from trials stopped early by the scheduler."""

    def on_trial_start(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        _STARTED.add(trial.trial_id)

    def on_trial_complete(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        _ENDED.add(trial.trial_id)

    def on_trial_error(self, iteration: int, trials: list, trial: Any, **info: Any) -> None:
        _ENDED.add(trial.trial_id)


def _param_space(spec: SweepSpec, optimize: int | None) -> dict[str, Any]:
    if optimize is not None:  # Optuna samples the hyperparameters; the first seed trains them all
        space = {}
        for key, dist in spec.search.items():
            kind, args = next(iter(dist.items()))
            space[key] = tune.choice(args) if kind == "choice" else getattr(tune, kind)(*args)
        return {"hp": space, "seed": spec.seeds[0]}
    return {"hp": tune.grid_search(spec.configurations()), "seed": tune.grid_search(list(spec.seeds))}


def _tune_config(spec: SweepSpec, optimize: int | None):
    if optimize is None:
        return tune.TuneConfig(num_samples=1, trial_name_creator=trial_name, trial_dirname_creator=trial_name)
    import optuna
    from ray.tune.schedulers import ASHAScheduler, FIFOScheduler, MedianStoppingRule
    from ray.tune.search.optuna import OptunaSearch

    es = spec.early_stopping
    if es.scheduler == "asha":
        scheduler = ASHAScheduler(time_attr="timesteps", max_t=spec.timesteps, grace_period=es.grace_period,
                                  reduction_factor=es.reduction_factor)
    elif es.scheduler == "median":
        scheduler = MedianStoppingRule(time_attr="timesteps", grace_period=es.grace_period)
    else:
        scheduler = FIFOScheduler()
    search = OptunaSearch(sampler=optuna.samplers.TPESampler(seed=spec.seeds[0]))
    return tune.TuneConfig(search_alg=search, scheduler=scheduler, metric=spec.metric, mode=spec.mode,
                           num_samples=optimize, trial_name_creator=trial_name, trial_dirname_creator=trial_name)


def trial_name(trial: Any) -> str:
    """``<trial id>_seed<seed>``: short, unique, and says which seed it trains."""
    return f"{trial.trial_id}_seed{trial.config.get('seed')}"


def _trial(config: dict[str, Any], spec: dict[str, Any], base: dict[str, Any]) -> None:
    """One trial, inside a Ray worker: train (resuming from the trial's checkpoint), report
    each in-training evaluation, score the model on the held-out episodes, report that."""
    import ray

    from bulletnav.rl.evaluate import evaluate_model
    from bulletnav.rl.train import TrainConfig, train
    from bulletnav.viz.compare import plot_learning_curve

    sweep = SweepSpec.from_record(spec)
    overrides = dict(config.get("hp") or {})
    seed = int(config["seed"])
    node = ray.get_runtime_context().get_node_id()
    out = Path(tune.get_context().get_trial_dir()) / "run"
    out.mkdir(parents=True, exist_ok=True)
    resume = False
    checkpoint = tune.get_checkpoint()
    if checkpoint is not None:  # a resumed sweep: this trial's training state from its last report
        checkpoint.to_directory(str(out))
        from bulletnav.rl.callbacks import finish_checkpoint

        finish_checkpoint(out)
        resume = (out / "checkpoints" / "last.zip").is_file()
    hp_file = out / "hyperparams.yml"  # the base hyperparameters, so no node needs the driver's files
    write_bytes(hp_file, yaml.safe_dump({sweep.env_id: base}, sort_keys=False).encode())

    def report(row: dict[str, Any]) -> None:
        if row["timesteps"] >= sweep.timesteps:
            return  # the end of training: the held-out evaluation below is the last report
        with tempfile.TemporaryDirectory() as tmp:
            for name in ("checkpoints", "eval_history.json", "config.json"):
                src = out / name
                if src.is_dir():
                    shutil.copytree(src, Path(tmp) / name)
                elif src.is_file():
                    shutil.copy2(src, Path(tmp) / name)
            tune.report({**row, "final": 0, "node": node}, checkpoint=tune.Checkpoint.from_directory(tmp))

    t0 = time.time()
    record = train(TrainConfig(
        algo=sweep.algo, timesteps=sweep.timesteps, out=out, seed=seed, n_envs=sweep.n_envs, resume=resume,
        eval_freq=sweep.eval_freq, eval_episodes=sweep.eval_episodes, checkpoint_freq=sweep.checkpoint_freq,
        progress_bar=False, vec_env=sweep.vec_env, env_overrides=sweep.env_kwargs or None, hyperparams=hp_file,
        command=f"bulletnav sweep ({sweep.name}: {config_label(overrides)}, seed {seed})", env_id=sweep.env_id,
        overrides=overrides or None, on_evaluation=report), plot_curve=plot_learning_curve)
    held_out = evaluate_model(out / "model.zip", sweep.env_id, sweep.evaluation_episodes, sweep.evaluation_seed)
    keep = {k: v for k, v in held_out.items() if k != "per_episode"}
    write_bytes(out / "heldout.json", json.dumps({"episodes": sweep.evaluation_episodes,
                                                  "seed": sweep.evaluation_seed, **keep}, indent=2, default=float).encode())
    metrics = {k: float(held_out[k]) for k in ("success_rate", "collision_rate", "timeout_rate", "spl", "mean_reward",
                                               "mean_length") if k in held_out}
    with tempfile.TemporaryDirectory() as tmp:
        for name in RUN_FILES:
            if (out / name).is_file():
                shutil.copy2(out / name, Path(tmp) / name)
        tune.report({**metrics, "timesteps": int(record["total_timesteps"]), "final": 1, "node": node,
                     "wall_time_s": round(record.get("wall_time_total_s", time.time() - t0), 1),
                     "heldout_episodes": sweep.evaluation_episodes}, checkpoint=tune.Checkpoint.from_directory(tmp))


def _row(result: Any, spec: SweepSpec, cut: set[str]) -> dict[str, Any]:
    """One trial's row of the table, from its Tune result: ``finished`` (trained and scored on
    the held-out episodes), ``error``, ``stopped`` (early stopping ended it), ``interrupted``
    (its trial id is in ``cut``: ``--resume`` continues it) or ``not run``."""
    m = result.metrics or {}
    config = dict((result.config or {}).get("hp") or {})
    trial_id = m.get("trial_id") or Path(str(result.path)).name.split("_seed")[0]
    if result.error is not None:
        status = "error"
    elif m.get("final") == 1:
        status = "finished"
    elif trial_id in cut:
        status = "interrupted"
    elif m:  # its metrics are its last in-training evaluation's
        status = "stopped"
    else:
        status = "not run"
    model = None
    if status == "finished" and result.checkpoint is not None:
        model = f"{result.checkpoint.path.rstrip('/')}/model.zip"
    error = None
    if result.error is not None:
        lines = [ln for ln in str(result.error).strip().splitlines() if ln.strip()]
        error = lines[-1] if lines else type(result.error).__name__
    return {
        "trial": Path(str(result.path)).name if result.path else None, "config": config,
        "seed": (result.config or {}).get("seed"), "status": status, "timesteps": m.get("timesteps"),
        "wall_time_s": m.get("wall_time_s"), "node": m.get("node"), "model": model, "error": error,
        **{k: m.get(k) for k in ("success_rate", "collision_rate", "timeout_rate", "spl", "mean_reward", "mean_length")},
    }


def _best(rows: list[dict[str, Any]], spec: SweepSpec) -> dict[str, Any] | None:
    done = [r for r in rows if r["status"] == "finished" and r.get(spec.metric) is not None]
    if not done:
        return None
    return (max if spec.mode == "max" else min)(done, key=lambda r: r[spec.metric])


def write_best_hyperparams(path: Path, spec: SweepSpec, base: dict[str, Any], best: dict[str, Any]) -> None:
    """The best trial's hyperparameters as a file ``bulletnav train --hyperparams`` takes
    (the base entry with the trial's values set, under the sweep's env id)."""
    from bulletnav.rl.hyperparams import apply_overrides

    hp = apply_overrides(base, best["config"], where=f"sweep {spec.name}")
    if spec.env_kwargs:
        hp["env_kwargs"] = {**hp.get("env_kwargs", {}), **spec.env_kwargs}
    head = (f"# Best of sweep {spec.name!r} ({spec.metric} {best[spec.metric]:.3f} on {spec.evaluation_episodes} held-out "
            f"episodes from seed {spec.evaluation_seed}; trial {best['trial']}, seed {best['seed']}).\n"
            f"# Train with: bulletnav train --algo {spec.algo} --env {spec.env_id} --hyperparams {path}\n")
    write_bytes(path, (head + yaml.safe_dump({spec.env_id: hp}, sort_keys=False)).encode())
