"""``bulletnav train``: an SB3 agent (PPO, SAC, TD3, A2C), or behaviour cloning from a dataset."""

from __future__ import annotations

import argparse
import sys

from bulletnav.cli import interrupts
from bulletnav.cli.args import (
    COUNT,
    FRACTION,
    NON_NEGATIVE,
    SEED,
    add_command,
    add_env_arg,
    add_physics_arg,
    add_trust_pickle_arg,
)
from bulletnav.cli.output import holds_run
from bulletnav.errors import BulletnavError


def register(sub) -> None:
    """Add ``train`` to ``sub`` (``build_parser``'s subparsers)."""
    tr = add_command(sub, "train", "train an SB3 agent (hyperparameters from rl/hyperparams/<algo>.yml)")
    tr.add_argument("--algo", choices=["ppo", "sac", "td3", "a2c", "bc"], default="ppo",
                    help="algorithm (default ppo); bc: behaviour cloning from --dataset into PPO's network")
    tr.add_argument("--dataset", metavar="NAME", help="bc: the Minari dataset to clone (docs/datasets.md)")
    tr.add_argument("--epochs", type=COUNT, default=20, help="bc: passes over the dataset (default 20)")
    tr.add_argument("--fit-std", action="store_true",
                    help="bc: fit the policy's action spread too (default: hold it at PPO's log_std_init, so PPO "
                         "fine-tuning from the model explores)")
    tr.add_argument("--timesteps", type=NON_NEGATIVE, default=None,
                    help="total environment steps (default: the hyperparameter file's n_timesteps, else 500000)")
    tr.add_argument("--n-envs", type=COUNT, default=None, help="parallel envs (default: the hyperparameter file's, 4)")
    tr.add_argument("--seed", type=SEED, default=0, help="random seed of the run (default 0)")
    add_env_arg(tr)
    tr.add_argument("--out", required=True, metavar="DIR", help="run directory, e.g. runs/ppo")
    tr.add_argument("--resume", action="store_true", help="continue from DIR/checkpoints/last.zip")
    tr.add_argument("--overwrite", action="store_true",
                    help="train into an --out DIR that holds another run, replacing its files (default: refuse)")
    tr.add_argument("--init-from", metavar="MODEL",
                    help="fine-tune: start from this model's weights with this run's settings (steps count from 0)")
    tr.add_argument("--eval-freq", type=COUNT, default=None,
                    help="evaluate every N timesteps (default 25000, or a fifth of --timesteps when that is under 125000: "
                         "at least five points on the learning curve); the end of training is always evaluated")
    tr.add_argument("--eval-episodes", type=COUNT, default=20, help="unseen episodes per evaluation (default 20)")
    tr.add_argument("--checkpoint-freq", type=COUNT, default=25_000, help="checkpoint every N timesteps (default 25000)")
    tr.add_argument("--stop-at-success", type=FRACTION, default=None, metavar="RATE",
                    help="stop at the first in-training evaluation with this success rate (0-1; the start is "
                         "evaluated too); run.json records the steps and wall time it took")
    tr.add_argument("--vec-env", choices=["auto", "subproc", "dummy"], default="auto",
                    help="one process per env (subproc), all in this one (dummy), or auto (default): subprocesses "
                         "for several envs on a machine with more than one core")
    tr.add_argument("--hyperparams", metavar="YAML",
                    help="hyperparameter file to use instead of the packaged rl/hyperparams/<algo>.yml (same format)")
    tr.add_argument("--no-progress", action="store_true", help="no progress bar")
    tr.add_argument("--shield", action="store_true",
                    help="train (and evaluate during training) behind the safety shield, so the policy learns with it")
    add_trust_pickle_arg(tr)
    add_physics_arg(tr)
    tr.set_defaults(func=cmd_train)


def _train_bc(args: argparse.Namespace, out) -> int:
    """``train --algo bc --dataset NAME``: behaviour cloning into PPO's network."""
    from bulletnav.provenance import command_line
    from bulletnav.rl.bc import BCConfig, train_bc

    if args.algo != "bc" or not args.dataset:
        raise BulletnavError("--dataset goes with --algo bc, and --algo bc needs --dataset NAME")
    if args.resume or args.init_from or args.shield or args.hyperparams:
        raise BulletnavError("--algo bc takes --dataset, --epochs, --seed and --out (not --resume, --init-from, --shield "
                             "or --hyperparams)")
    record = train_bc(BCConfig(dataset=args.dataset, out=out, epochs=args.epochs, seed=args.seed, fit_std=args.fit_std,
                               command=command_line()))
    final = record["final"]
    val = f", validation NLL {final['val_nll']:.3f}, action MSE {final['val_action_mse']:.4f}" if "val_nll" in final else ""
    print(f"behaviour-cloned {args.dataset} ({record['episodes']} episodes, {record['samples']} training pairs) for "
          f"{record['epochs']} epochs in {record['wall_time_s']:.0f} s: train NLL {final['train_nll']:.3f}{val}")
    print(f"model: {out / 'model.zip'} (PPO's network; evaluate it, or fine-tune with train --algo ppo --init-from)")
    return 0


def rollout_note(args: argparse.Namespace) -> str | None:
    """The steps ``train`` will really take when ``--timesteps`` is not a whole number of rollouts.

    SB3 learns in whole rollouts: PPO and A2C collect ``n_steps`` x ``n_envs`` steps each, SAC and
    TD3 ``train_freq`` x ``n_envs``; ``learn`` goes on until the count is reached or passed."""
    if args.resume:
        return None  # the run's recorded settings and its steps so far decide; train reports the total
    from bulletnav.rl.hyperparams import load_hyperparams

    hp = load_hyperparams(args.algo, env_id=args.env_id, path=args.hyperparams)
    try:
        n_envs = int(args.n_envs or hp.get("n_envs", 4))
        timesteps = int(args.timesteps if args.timesteps is not None else hp.get("n_timesteps", 500_000))
        if args.algo in ("ppo", "a2c"):
            n_steps = int(hp.get("n_steps", 2048 if args.algo == "ppo" else 5))
            per, why = n_steps * n_envs, f"{args.algo.upper()} learns in rollouts of n_steps {n_steps} x {n_envs} envs"
        else:
            freq = hp.get("train_freq", 1)
            if isinstance(freq, (list, tuple)):
                if len(freq) != 2 or str(freq[1]) != "step":
                    return None  # episodes per rollout: no fixed step count
                freq = freq[0]
            per, why = int(freq) * n_envs, f"{args.algo.upper()} collects train_freq {int(freq)} x {n_envs} envs per update"
    except (TypeError, ValueError, OverflowError):
        return None  # a malformed value: training itself says what is wrong with it
    if timesteps <= 0 or per <= 0 or timesteps % per == 0:
        return None
    trained = -(-timesteps // per) * per
    label = "--timesteps" if args.timesteps is not None else "the hyperparameter file's n_timesteps"
    return (f"{label} {timesteps:,} is not a whole number of rollouts: {why} = {per:,} steps, so "
            f"{trained:,} steps will be trained (pass a multiple of {per:,} to train exactly that)")


def _check_out(args: argparse.Namespace):
    """``--out`` as a Path: a run directory, one holding a run only with ``--resume`` or ``--overwrite``."""
    from pathlib import Path

    from bulletnav.errors import RunError

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a run directory")
    if not args.resume and not args.overwrite and holds_run(out):
        names = ", ".join(sorted(p.name for p in out.iterdir())[:4])
        raise RunError(f"--out {out} already holds a run ({names}, ...): pass --resume to continue it, --overwrite to "
                       "train into it anyway (files of the same names are replaced), or choose another --out")
    return out


def cmd_train(args: argparse.Namespace) -> int:
    import logging
    from pathlib import Path

    from bulletnav.provenance import command_line
    from bulletnav.rl.io import model_file
    from bulletnav.rl.train import TrainConfig, train
    from bulletnav.viz.compare import plot_learning_curve

    logging.getLogger("bulletnav.rl.curriculum").setLevel(logging.INFO)  # stage changes on the console
    out = _check_out(args)
    if args.algo == "bc" or args.dataset:
        return _train_bc(args, out)
    note = rollout_note(args)
    if note:
        print(f"bulletnav train: note: {note}", file=sys.stderr)
    extra = {"env_id": args.env_id}
    if args.physics is not None:  # into the training and in-training evaluation envs, and the run record
        extra["env_overrides"] = {"physics": args.physics}
    cfg = TrainConfig(
        algo=args.algo, timesteps=args.timesteps, out=out, seed=args.seed, n_envs=args.n_envs,
        resume=args.resume, eval_freq=args.eval_freq, eval_episodes=args.eval_episodes,
        checkpoint_freq=args.checkpoint_freq, progress_bar=not args.no_progress, vec_env=args.vec_env,
        hyperparams=Path(args.hyperparams) if args.hyperparams else None, command=command_line(), shield=args.shield,
        init_from=model_file(args.init_from) if args.init_from else None, trust_pickle=args.trust_pickle,
        stop_at_success=args.stop_at_success, **extra,
    )
    interrupts.on_interrupt(lambda: interrupted_note(out))
    _print_record(args, cfg, train(cfg, plot_curve=plot_learning_curve))
    return 0


def kept_checkpoint(out) -> int | None:
    """The step count of the checkpoint a resume of ``out`` would start from (a committed set
    still in ``checkpoints/.pending`` is completed first), or None without one."""
    import json

    for path in (out / "checkpoints" / ".pending" / "COMMIT", out / "checkpoints" / "last.json"):
        try:
            return int(json.loads(path.read_text())["timesteps"])
        except (OSError, ValueError, KeyError, TypeError):
            continue
    return None


def interrupted_note(out) -> str:
    """The line of an interrupted ``train`` (and ``fleet-train``): the checkpoint kept and the
    command that goes on from it, or that there is none yet."""
    import json

    try:
        total = int(json.loads((out / "config.json").read_text())["timesteps"])
        of = f" of {total:,}"
    except (OSError, ValueError, KeyError, TypeError):
        of = ""
    steps = kept_checkpoint(out)
    if steps is None:
        again = interrupts.rerun_command(add=["--overwrite"] if holds_run(out) else [])
        return f"interrupted before the first checkpoint; nothing to resume; run again with: {again}"
    return (f"interrupted; checkpoint at {steps:,}{of} steps kept in {out / 'checkpoints' / 'last.zip'}; "
            f"continue with: {interrupts.continue_command()}")


def _print_record(args: argparse.Namespace, cfg, record: dict) -> None:
    final = record.get("final_eval") or {}
    if record.get("resumed_from"):  # the whole run's steps, and this run's time apart from the whole's
        print(f"trained {args.algo.upper()} for {record['total_timesteps']} timesteps ({record['resumed_from']} from "
              f"the earlier run), {record['wall_time_s']:.0f} s this run, {record['wall_time_total_s']:.0f} s in all "
              f"({record['n_envs']} envs, seed {args.seed})")
    else:
        print(f"trained {args.algo.upper()} for {record['total_timesteps']} timesteps in {record['wall_time_s']:.0f} s "
              f"({record['n_envs']} envs, seed {args.seed})")
    if record.get("throughput"):
        t = record["throughput"]
        print(f"throughput     {t['env_steps_per_s']:.0f} env steps/s; wall time in env {t['env_share'] * 100:.0f} %, "
              f"learner {t['learner_share'] * 100:.0f} %, evaluation {t['eval_share'] * 100:.0f} %")
    if args.stop_at_success is not None:
        hit = record.get("reached_success")
        print(f"target success {args.stop_at_success * 100:.0f} %: " + (
            f"reached at {hit['timesteps']} steps, {hit['wall_time']:.0f} s" if hit else "not reached in the budget"))
    if final:
        print(f"final evaluation ({args.eval_episodes} unseen episodes): success {final['success_rate'] * 100:.0f} %, "
              f"collisions {final['collision_rate'] * 100:.0f} %, mean reward {final['mean_reward']:.1f}")
    print(f"model:          {cfg.out / 'model.zip'}")
    print(f"run record:     {cfg.out / 'run.json'}")
    print(f"learning curve: {cfg.out / 'learning_curve.png'}")
    print(f"tensorboard:    tensorboard --logdir {cfg.out / 'tb'}")
