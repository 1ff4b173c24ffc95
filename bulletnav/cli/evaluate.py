"""Trained models judged: ``evaluate`` (one model), ``compare`` (training runs side by side) and
``demo`` (the shipped policy, with report, video and plot)."""

from __future__ import annotations

import argparse
import sys

from bulletnav.benchmark.suite import SHIPPED_MODELS
from bulletnav.cli.args import (
    COUNT,
    DEFAULT_ENV_ID,
    FRACTION,
    MCAP_FILE,
    PNG_FILE,
    RECORD_HELP,
    SEED,
    VIDEO_FILE,
    add_command,
    add_env_arg,
    add_episode_outputs,
    add_live_args,
    add_mission_args,
    add_obstacles_arg,
    add_overwrite_arg,
    add_physics_arg,
    add_shield_arg,
    add_trust_pickle_arg,
)
from bulletnav.cli.episodes import add_world_idx_arg, evaluate_report, load_for_evaluation
from bulletnav.cli.output import holds_run, print_json, refuse_existing_files
from bulletnav.errors import BulletnavError

DEFAULT_MODEL = SHIPPED_MODELS[DEFAULT_ENV_ID]
"""The model ``demo`` runs when ``--model`` is not given and ``--env`` has no shipped model of its own
(``SHIPPED_MODELS``, the benchmark's ``model: shipped`` table)."""
DEFAULT_DEMO_OUT = "runs/demo"
"""Where ``demo`` writes without ``--out``; when it holds an earlier demo, ``runs/demo-2``, ``-3``, ..."""
MODEL_ENV_HELP = "the env the model's .json names, else " + DEFAULT_ENV_ID


def register(sub) -> None:
    """Add ``evaluate``, ``compare`` and ``demo`` to ``sub`` (``build_parser``'s subparsers)."""
    _register_evaluate(sub)
    _register_compare(sub)
    _register_demo(sub)


def _register_evaluate(sub) -> None:
    ev = add_command(sub, "evaluate", "evaluate a trained model (deterministic actions)")
    ev.add_argument("--model", required=True, metavar="PATH", help="model zip written by train")
    ev.add_argument("--algo", choices=["ppo", "sac", "td3", "a2c"], default=None,
                    help="only needed when the .json beside the model is missing")
    ev.add_argument("--episodes", type=COUNT, default=10, help="episodes to run (default 10)")
    add_env_arg(ev, MODEL_ENV_HELP)
    ev.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world (default: procedural)")
    add_world_idx_arg(ev)
    add_mission_args(ev)
    add_obstacles_arg(ev, "31 on Warehouse-v0, else the model's or the env's")
    ev.add_argument("--seed", type=SEED, default=1000, help="episode k uses env seed S + k (default 1000)")
    ev.add_argument("--gui", action="store_true", help="watch in the PyBullet GUI (needs a display)")
    add_trust_pickle_arg(ev)
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    add_shield_arg(ev)
    add_physics_arg(ev)
    add_episode_outputs(ev)
    add_live_args(ev)
    ev.set_defaults(func=cmd_evaluate)


def _register_compare(sub) -> None:
    cmp_ = add_command(sub, "compare", "plot several training runs' learning curves and tabulate them")
    cmp_.add_argument("runs", nargs="+", metavar="RUN_DIR", help="directories written by train")
    cmp_.add_argument("--out", type=PNG_FILE, default="docs/algorithms.png", metavar="PNG",
                      help="figure to write (default docs/algorithms.png)")
    cmp_.add_argument("--group-by", choices=("algo", "hyperparams", "start", "physics"), default="algo",
                      help="colour and summarize runs by algorithm (default), by hyperparameter file "
                           "(ablations of one algorithm), by start (scratch, or the --init-from model), or by "
                           "the physics profile trained in")
    cmp_.add_argument("--reach", type=FRACTION, default=None, metavar="RATE",
                      help="the table's 'first reached' column: the first evaluation with this success rate "
                           "(0-1, default 0.8)")
    cmp_.add_argument("--json", action="store_true", help="print the table as JSON")
    cmp_.set_defaults(func=cmd_compare)


def _register_demo(sub) -> None:
    demo = add_command(sub, "demo", "the main job: the shipped PPO policy, report, video and trajectory plot")
    shipped = ", ".join(f"{path} on {env_id.split('/')[-1]}" for env_id, path in SHIPPED_MODELS.items())
    demo.add_argument("--model", help=f"model zip (default: the shipped model for --env, {shipped})")
    demo.add_argument("--episodes", type=COUNT, default=5, help="episodes to run (default 5)")
    demo.add_argument("--seed", type=SEED, default=2024, help="episode k uses env seed S + k (default 2024)")
    add_env_arg(demo, MODEL_ENV_HELP)
    demo.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world (default: procedural)")
    add_mission_args(demo)
    add_obstacles_arg(demo, "31 on Warehouse-v0, else the model's or the env's")
    demo.add_argument("--out", default=None, metavar="DIR",
                      help="output directory; one that holds a run is refused without --overwrite (default: "
                           "runs/demo, or runs/demo-2, -3, ... when it holds an earlier demo)")
    demo.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="video file (default DIR/episodes.mp4)")
    demo.add_argument("--record", type=MCAP_FILE, metavar="PATH", help=RECORD_HELP)
    add_overwrite_arg(demo, "the files of an --out DIR, a --video or a --record")
    demo.add_argument("--gui", action="store_true", help="watch live in the PyBullet GUI")
    add_live_args(demo)
    demo.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    add_shield_arg(demo)
    add_physics_arg(demo)
    add_trust_pickle_arg(demo)
    demo.set_defaults(func=cmd_demo, algo=None)


def cmd_evaluate(args: argparse.Namespace) -> int:
    refuse_existing_files(args, "video", "plot", "record")
    evaluate_report(args, str(run_model(args.model)))
    return 0


def run_model(model: str):
    """``--model``'s file: itself, or a run directory's ``model.zip`` (:func:`bulletnav.rl.io.model_file`),
    with a line saying which file a run directory gave."""
    from pathlib import Path

    from bulletnav.rl.io import model_file

    path = model_file(model)
    if path != Path(model):
        print(f"--model {model}: loading {path}")
    return path


def cmd_compare(args: argparse.Namespace) -> int:
    """Learning curves of several training runs in one PNG and a table of their results."""
    from pathlib import Path

    from bulletnav.viz.compare import REACH_SUCCESS, compare_runs

    rate = REACH_SUCCESS if args.reach is None else args.reach
    rows = compare_runs([Path(r) for r in args.runs], Path(args.out), group_by=args.group_by, reach=rate)
    if args.json:
        print_json(rows)
        return 0
    reach = f"first >= {rate * 100:.0f} % at (steps, s)"
    head = {"algo": "algorithm", "hyperparams": "hyperparameters", "start": "start", "physics": "physics"}[args.group_by]
    name = (lambda r: r["group"].upper()) if args.group_by == "algo" else (lambda r: r["group"])
    print(f"| {head} | seed | timesteps | wall time (s) | final success | final collisions | final reward | "
          f"best success (at) | {reach} |")
    print("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        reached = f"{r['reached_at']}, {r['reached_wall_s']}" if r["reached_at"] is not None else "never"
        print(f"| {name(r)} | {r['seed']} | {r['timesteps']} | {r['wall_time_s']:.0f} | "
              f"{r['final_success'] * 100:.0f} % | {r['final_collisions'] * 100:.0f} % | {r['final_reward']:.1f} | "
              f"{r['best_success'] * 100:.0f} % ({r['best_at']}) | {reached} |")
    by_group: dict[str, list[dict]] = {}
    for r in rows:
        by_group.setdefault(r["group"], []).append(r)
    if any(len(v) > 1 for v in by_group.values()):
        print(f"\n| {head} | seeds | final success, mean (min-max) | wall time (s), mean |")
        print("|---|---|---|---|")
        for rs in by_group.values():
            final = [r["final_success"] * 100 for r in rs]
            print(f"| {name(rs[0])} | {len(rs)} | {sum(final) / len(final):.0f} % ({min(final):.0f}-{max(final):.0f} %) | "
                  f"{sum(r['wall_time_s'] for r in rs) / len(rs):.0f} |")
    print(f"\nlearning curves: {args.out}")
    return 0


def _demo_model(args: argparse.Namespace):
    """The model file ``demo`` runs: ``--model``, else the shipped one for ``--env`` (found beside
    the package when not in the working directory)."""
    from pathlib import Path

    from bulletnav.errors import ModelError

    shipped = args.model is None
    if shipped:
        args.model = SHIPPED_MODELS.get(args.env_id, DEFAULT_MODEL)
    model = Path(args.model) if shipped else run_model(args.model)
    if not model.is_file():
        packaged = Path(__file__).resolve().parents[2] / args.model
        if shipped and packaged.is_file():
            model = packaged
        else:
            raise ModelError(f"{args.model}: model file not found (train one with `bulletnav train`)")
    return model


def _check_demo_out(args: argparse.Namespace) -> None:
    from pathlib import Path

    refuse_existing_files(args, "video", "record")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise BulletnavError(f"--out {args.out}: is a file, not a folder")
    if args.out is not None and holds_run(args.out) and not args.overwrite:
        raise BulletnavError(f"--out {args.out} already holds a run ({', '.join(sorted(p.name for p in Path(args.out).iterdir())[:3])}"
                             "): pass --overwrite to replace its files, or choose another folder (without --out every "
                             f"demo gets a new folder beside {DEFAULT_DEMO_OUT})")


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the shipped PPO policy on evaluation episodes, with video and plot."""
    import time
    from pathlib import Path

    model = _demo_model(args)
    _check_demo_out(args)
    loaded = load_for_evaluation(args, str(model))  # the model fits the env before any folder is made
    try:
        out, created = demo_folder(args.out)
    except BaseException:
        loaded[3].close()
        raise
    notes = sys.stderr if args.json else sys.stdout  # --json: stdout is the JSON document alone
    if args.out is None and out != Path(DEFAULT_DEMO_OUT):
        print(f"{DEFAULT_DEMO_OUT} holds an earlier demo: this one writes to {out}/", file=notes)
    args.video = args.video or str(out / "episodes.mp4")
    args.plot = str(out / "trajectories.png")
    t0 = time.perf_counter()
    try:
        evaluate_report(args, str(model), loaded)
    except BaseException:
        if created and not holds_run(out):
            out.rmdir()  # nothing written: no empty folder left behind
        raise
    print(f"demo finished in {time.perf_counter() - t0:.0f} s; results in {out}/", file=notes)
    return 0


def demo_folder(out: str | None):
    """``(folder, created)``: ``out`` (made if missing), or without it the first of ``runs/demo``,
    ``runs/demo-2``, ... that is missing or empty, claimed with an exclusive ``mkdir`` (two demos
    started together get two folders)."""
    import itertools
    from pathlib import Path

    if out is not None:
        path = Path(out)
        created = not path.exists()
        path.mkdir(parents=True, exist_ok=True)
        return path, created
    base = Path(DEFAULT_DEMO_OUT)
    for k in itertools.count(1):
        path = base if k == 1 else base.with_name(f"{base.name}-{k}")
        try:
            path.mkdir(parents=True)
            return path, True
        except FileExistsError:
            if path.is_dir() and not holds_run(path):
                return path, False
    raise AssertionError("unreachable")
