"""Fleets of robots: ``fleet`` (a controller on seeded episodes), ``fleet-train`` (parameter-shared
PPO fine-tuning) and ``fleet-compare`` (every controller, with and without the shield)."""

from __future__ import annotations

import argparse
import sys

from bulletnav.cli import interrupts
from bulletnav.cli.args import (
    COUNT,
    FLEET_ROBOTS,
    MCAP_FILE,
    MODEL_FILE,
    PNG_FILE,
    SEED,
    VIDEO_FILE,
    add_command,
    add_fleet_world_args,
    add_live_args,
    add_overwrite_arg,
    non_negative_seconds,
    positive_seconds,
)
from bulletnav.cli.envs import fleet_world_kwargs
from bulletnav.cli.live import start_live
from bulletnav.cli.output import EpisodeBar, fmt, holds_run, print_json, refuse_existing_files

SUMMARY_KEYS = ("throughput_per_hour", "throughput_per_robot_per_hour", "errands", "legs", "collisions_robot_robot",
                "collisions_static", "collisions_mover", "collisions_person", "deadlocks", "min_separation_m",
                "errand_time_s", "near_misses", "intimate_s", "personal_s", "shield_rate")
"""The summary figures ``fleet --json`` prints beside its settings and per-episode rows."""


def register(sub) -> None:
    """Add ``fleet``, ``fleet-train`` and ``fleet-compare`` to ``sub`` (``build_parser``'s subparsers)."""
    _register_fleet(sub)
    _register_fleet_train(sub)
    _register_fleet_compare(sub)


def _register_fleet(sub) -> None:
    fl = add_command(sub, "fleet", "a fleet of robots running pick-and-drop errands: throughput, collisions, deadlocks")
    fl.add_argument("--robots", type=FLEET_ROBOTS, default=4, help="robots in the warehouse, 1 to 16 (default 4)")
    fl.add_argument("--controller", choices=["independent", "coordinated", "policy"], default="independent",
                    help="independent: PID + A* on each robot's lidar map; coordinated: windowed prioritized "
                         "space-time planning (WHCA*) tracked by PID; policy: a single-robot model on every robot "
                         "(default independent)")
    fl.add_argument("--model", default=None, metavar="PATH", type=MODEL_FILE,
                    help="policy: the model (default models/ppo_dynamic.zip); the fleet takes its env settings")
    fl.add_argument("--shield", action="store_true",
                    help="every robot behind the safety shield, the other robots shown to it as movers")
    fl.add_argument("--episodes", type=COUNT, default=1, help="episodes (default 1), episode k seeded SEED + k")
    fl.add_argument("--seed", type=SEED, default=0, help="first episode's seed (default 0)")
    fl.add_argument("--duration", type=positive_seconds, default=180.0, metavar="S",
                    help="simulated seconds per episode (default 180)")
    fl.add_argument("--dynamic", action="store_true", help="add forklifts, walking workers and pallet events")
    add_fleet_world_args(fl, "the fleet's aisle warehouse, WarehouseAisles-v0's settings")
    fl.add_argument("--json", action="store_true", help="print one JSON object (summary keys plus per-episode rows)")
    fl.add_argument("--record", type=MCAP_FILE, metavar="PATH",
                    help="also write the episodes as ROS 2 messages, one namespace per robot (/robot_<i>/scan, ...), "
                         "into PATH, an MCAP file (docs/ros.md)")
    fl.add_argument("--video", type=VIDEO_FILE, metavar="PATH",
                    help="top-down video of the first episode (episode 0), every robot in its colour with its errand "
                         "(.mp4, or .gif held in memory until written: short runs only; one frame per control step)")
    fl.add_argument("--plot", type=PNG_FILE, metavar="PNG",
                    help="every robot's path over the first episode (episode 0), stations and the map")
    fl.add_argument("--frame", type=PNG_FILE, metavar="PNG", help="one video frame of the first episode (episode 0) as a PNG")
    fl.add_argument("--frame-at", type=non_negative_seconds, default=None, metavar="S",
                    help="simulated seconds into the episode of the --frame (default: half the --duration)")
    add_overwrite_arg(fl, "--video, --plot, --frame and --record files")
    add_live_args(fl)
    fl.set_defaults(func=cmd_fleet)


def _register_fleet_train(sub) -> None:
    ft = add_command(sub, "fleet-train", "fine-tune a single-robot model in the fleet: parameter-shared PPO, every robot one slot")
    ft.add_argument("--init-from", required=True, metavar="MODEL", type=MODEL_FILE,
                    help="the single-robot PPO model to start from (its weights, statistics and env settings)")
    ft.add_argument("--timesteps", type=COUNT, required=True, help="total agent steps (summed over the robots)")
    ft.add_argument("--seed", type=SEED, default=0, help="random seed of the run (default 0)")
    ft.add_argument("--out", required=True, metavar="DIR", help="run directory, e.g. runs/fleet_s1")
    ft.add_argument("--robots", type=FLEET_ROBOTS, default=4, help="robots per fleet, 1 to 16 (default 4)")
    ft.add_argument("--fleets", type=COUNT, default=1, help="fleets stepped in this process (default 1)")
    ft.add_argument("--dynamic", action="store_true", help="add forklifts, walking workers and pallet events")
    ft.add_argument("--duration", type=positive_seconds, default=60.0, metavar="S",
                    help="simulated seconds per training episode (default 60)")
    ft.add_argument("--hyperparams", metavar="YAML",
                    help="hyperparameter file (default rl/hyperparams/ppo_dynamic_finetune_movers.yml; its "
                         "bulletnav/WarehouseDynamic-v0 entry)")
    ft.add_argument("--reward-collision", type=float, default=None, metavar="R",
                    help="reward per counted collision, robot-robot included (default: the hyperparameter file's)")
    ft.add_argument("--layouts-every", type=COUNT, default=None, metavar="N",
                    help="a new warehouse every N episodes of a fleet (default: the model's setting)")
    ft.add_argument("--checkpoint-freq", type=COUNT, default=20_000, help="checkpoint every N agent steps (default 20000)")
    ft.add_argument("--resume", action="store_true", help="continue from DIR/checkpoints/last.zip")
    ft.add_argument("--overwrite", action="store_true",
                    help="train into an --out DIR that holds another run, replacing its files (default: refuse)")
    ft.add_argument("--no-progress", action="store_true", help="no progress bar")
    ft.set_defaults(func=cmd_fleet_train)


def _register_fleet_compare(sub) -> None:
    fc = add_command(sub, "fleet-compare", "every fleet controller, with and without the shield, on the same seeded "
                                           "episodes: comparison.json + comparison.md")
    fc.add_argument("--robots", type=FLEET_ROBOTS, nargs="+", default=[4, 8], help="fleet sizes (default 4 8)")
    fc.add_argument("--controllers", nargs="+", metavar="SPEC",
                    default=["independent", "coordinated", "policy=models/ppo_dynamic.zip", "policy=models/ppo_fleet.zip"],
                    help="independent, coordinated or policy=MODEL.zip (default: the two classical ones, "
                         "the shipped single-robot policy zero-shot and the fleet-trained one)")
    fc.add_argument("--shield", choices=["off", "on", "both"], default="both",
                    help="each controller without the shield, with it, or both (default both)")
    fc.add_argument("--episodes", type=COUNT, default=40, help="episodes per controller and size (default 40)")
    fc.add_argument("--seed", type=SEED, default=1000, help="first episode's seed (default 1000)")
    fc.add_argument("--duration", type=positive_seconds, default=120.0, metavar="S",
                    help="simulated seconds per episode (default 120)")
    fc.add_argument("--dynamic", action="store_true", help="add forklifts, walking workers and pallet events")
    fc.add_argument("--workers", type=COUNT, default=1, help="worker processes (default 1); rows are the same for any count")
    fc.add_argument("--out", default="runs/fleet-compare", help="output directory (default runs/fleet-compare)")
    fc.add_argument("--resume", action="store_true", help="go on with the episodes already in --out")
    fc.add_argument("--tables-only", action="store_true",
                    help="run nothing: write comparison.json/.md from the rows in --out (same settings), on the "
                         "episodes every entry has at each size (a run stopped early)")
    fc.add_argument("--json", action="store_true", help="print the settings, per-cell summaries and provenance as JSON")
    fc.set_defaults(func=cmd_fleet_compare)


# ---------------------------------------------------------------------------------------
# fleet

def _check_fleet_args(args: argparse.Namespace) -> None:
    from bulletnav.errors import ConfigError

    if args.model is not None and args.controller != "policy":
        raise ConfigError(f"--model is for --controller policy, not {args.controller}")
    if args.frame_at is not None and not args.frame:
        raise ConfigError("--frame-at is the time of the --frame PNG: pass --frame too")
    if args.frame_at is not None and args.frame_at > args.duration:
        raise ConfigError(f"--frame-at {args.frame_at:g} s is after the episode's end (--duration {args.duration:g} s)")
    refuse_existing_files(args, "video", "plot", "frame", "record")


def _fleet_env_kwargs(args: argparse.Namespace, model: str) -> dict:
    """The fleet env's kwargs: the policy model's env settings (``--controller policy``) under the
    world options, robots, duration and movers."""
    env_kwargs: dict[str, object] = {}
    if args.controller == "policy":
        import torch

        from bulletnav.fleet.controllers import model_env_kwargs

        env_kwargs = dict(model_env_kwargs(model))
        # one thread, as fleet-compare's workers (the same arithmetic as their rows): a forward
        # pass of a few robots is too small for two, and two threads beside other work spend
        # their time waiting for each other (a 40-episode run took 46 CPU-min and was not done)
        torch.set_num_threads(1)
    env_kwargs.update(fleet_world_kwargs(args, args.env_id))
    env_kwargs.update(num_robots=args.robots, duration_s=args.duration, dynamic=args.dynamic)
    return env_kwargs


def _fleet_hooks(args: argparse.Namespace, live) -> tuple:
    """``(visuals, recorder)``: the video/plot/frame writer and the ROS 2 publisher (``--record``
    and/or ``--live``) ``args`` ask for (or None)."""
    visuals = recorder = None
    if args.video or args.plot or args.frame:
        from bulletnav.viz.fleet import FleetVisuals

        visuals = FleetVisuals(video=args.video, frame=args.frame, frame_at_s=args.frame_at, plot=args.plot, episode=0,
                               title=f"{args.controller}{' + shield' if args.shield else ''}, seed {args.seed}")
    if args.record or live is not None:
        from bulletnav.ros.fleet_record import FleetMcapRecorder

        recorder = FleetMcapRecorder(args.record, overwrite=True, live=live)
    return visuals, recorder


def cmd_fleet(args: argparse.Namespace) -> int:
    """Run a fleet controller on seeded fleet episodes; print the metrics (``--json``) or a table."""
    from bulletnav.fleet.controllers import DEFAULT_FLEET_MODEL, make_controller
    from bulletnav.fleet.metrics import run_fleet_episodes

    _check_fleet_args(args)
    model = args.model or DEFAULT_FLEET_MODEL
    env_kwargs = _fleet_env_kwargs(args, model)
    live = start_live(args)  # a port in use is refused before any file is opened
    try:
        visuals, recorder = _fleet_hooks(args, live)
    except BaseException:
        if live is not None:
            live.close()
        raise
    hooks = [h for h in (visuals, recorder) if h is not None]

    def on_step(env, infos) -> None:
        for hook in hooks:
            hook(env, infos)

    ok = False
    try:
        result = run_fleet_episodes(
            env_kwargs, lambda env: make_controller(args.controller, env, shield=args.shield,
                                                    model=model if args.controller == "policy" else None),
            episodes=args.episodes, seed=args.seed, on_step=on_step if hooks else None)
        ok = True
    finally:
        written = visuals.close(ok) if visuals is not None else []
        if recorder is not None:
            written = [*written, *recorder.close(ok)]
        if live is not None:
            live.close()
    s = result["summary"]
    if args.json:
        print_json({"command": "fleet", "controller": args.controller, "shield": args.shield, "robots": args.robots,
                    "duration_s": args.duration, "dynamic": args.dynamic, "episodes": args.episodes, "seed": args.seed,
                    "env_id": args.env_id, "world": args.world, "layout_style": args.layout_style,
                    "obstacles": args.obstacles, "model": model if args.controller == "policy" else None,
                    **{k: s[k] for k in SUMMARY_KEYS}, "rows": result["episodes"]})
        for w in written:
            print(w, file=sys.stderr)
        return 0
    _print_fleet_table(args, result)
    for w in written:
        print(w)
    return 0


def _rate(value: float, duration_s: float, width: int = 0) -> str:
    """``value`` errands/h as the table prints it, or ``-`` for an episode shorter than a typical errand
    (:data:`bulletnav.fleet.metrics.TYPICAL_ERRAND_S`)."""
    from bulletnav.fleet.metrics import rate_counts

    return f"{value:{width}.1f}" if rate_counts(duration_s) else f"{'-':>{width}s}"


def _print_fleet_table(args: argparse.Namespace, result: dict) -> None:
    from bulletnav.fleet.metrics import TYPICAL_ERRAND_S, rate_counts

    s = result["summary"]
    print(f"fleet: {args.robots} robots, {args.controller}{' + shield' if args.shield else ''}, "
          f"{args.episodes} episodes of {args.duration:g} s{' (dynamic)' if args.dynamic else ''}, seeds {args.seed}..")
    print(f"{'ep':>3s} {'seed':>6s} {'errands':>7s} {'per h':>7s} {'robot':>5s} {'static':>6s} {'mover':>5s} "
          f"{'person':>6s} {'dlock':>5s} {'min sep m':>9s} {'errand s':>8s}")
    for r in result["episodes"]:
        print(f"{r['episode']:3d} {r['seed']:6d} {r['errands']:7d} {_rate(r['throughput_per_hour'], args.duration, 7)} "
              f"{r['collisions_robot_robot']:5d} {r['collisions_static']:6d} {r['collisions_mover']:5d} "
              f"{r['collisions_person']:6d} {r['deadlocks']:5d} {fmt(r['min_separation_m']):>9s} "
              f"{fmt(r['errand_time_s'], '.1f'):>8s}")
    rate = (f"{s['throughput_per_hour']:.1f} errands/h ({s['throughput_per_robot_per_hour']:.1f} per robot)"
            if rate_counts(args.duration) else
            f"errands/h: run too short ({args.duration:g} s; an errand takes ~{TYPICAL_ERRAND_S:g} s), {s['errands']} errands")
    print(f"all: {rate}, "
          f"collisions robot {s['collisions_robot_robot']}, static {s['collisions_static']}, mover "
          f"{s['collisions_mover']}, person {s['collisions_person']}; deadlocks {s['deadlocks']}; "
          f"min separation {fmt(s['min_separation_m'])} m; errand time {fmt(s['errand_time_s'], '.1f')} s")


# ---------------------------------------------------------------------------------------
# fleet-compare and fleet-train

def cmd_fleet_compare(args: argparse.Namespace) -> int:
    """Every fleet controller, with and without the shield, on the same seeded episodes."""
    from pathlib import Path

    from bulletnav.fleet.compare import parse_entries, run_comparison

    entries = parse_entries(args.controllers, args.shield)
    env_kwargs = {"duration_s": args.duration, "dynamic": args.dynamic}
    if not args.tables_only:
        from bulletnav.cli.benchmark import interrupted_note

        total = len(entries) * len(args.robots) * args.episodes
        interrupts.on_interrupt(lambda: interrupted_note(Path(args.out) / "episodes.jsonl", total))
    with EpisodeBar("fleet-compare", show=not args.json) as bar:
        results = run_comparison(Path(args.out), entries, robots=args.robots, episodes=args.episodes, seed=args.seed,
                                 env_kwargs=env_kwargs, workers=args.workers, resume=args.resume, progress=bar.update,
                                 run=not args.tables_only)
    if args.json:
        print_json({k: results[k] for k in ("settings", "cells", "provenance")})
        return 0
    print((Path(args.out) / "comparison.md").read_text())
    print(f"written: {Path(args.out) / 'comparison.json'}, {Path(args.out) / 'comparison.md'}")
    return 0


def cmd_fleet_train(args: argparse.Namespace) -> int:
    """Fine-tune a single-robot model in the fleet with parameter-shared PPO (``bulletnav.fleet.training``)."""
    from pathlib import Path

    from bulletnav.errors import RunError
    from bulletnav.fleet.training import FleetTrainConfig, train_fleet
    from bulletnav.provenance import command_line

    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a run directory")
    if not args.resume and not args.overwrite and holds_run(out):
        raise RunError(f"--out {out} already holds a run: pass --resume to continue it, --overwrite to train into it "
                       "anyway, or choose another --out")
    overrides = {}
    if args.reward_collision is not None:
        overrides["reward_collision"] = args.reward_collision
    if args.layouts_every is not None:
        overrides["layouts_every"] = args.layouts_every
    cfg = FleetTrainConfig(
        init_from=Path(args.init_from), out=out, timesteps=args.timesteps, seed=args.seed, num_robots=args.robots,
        dynamic=args.dynamic, fleets=args.fleets, duration_s=args.duration,
        hyperparams=Path(args.hyperparams) if args.hyperparams else None, env_overrides=overrides or None,
        resume=args.resume, checkpoint_freq=args.checkpoint_freq, command=command_line(),
        progress_bar=not args.no_progress)
    from bulletnav.cli.train import interrupted_note

    interrupts.on_interrupt(lambda: interrupted_note(out))
    record = train_fleet(cfg)
    print(f"fleet-trained PPO for {record['total_timesteps']} agent steps in {record['wall_time_s']:.0f} s "
          f"({record['fleets']} fleet(s) of {args.robots} robots, seed {record['seed']})")
    if record.get("throughput"):
        t = record["throughput"]
        print(f"throughput     {t['env_steps_per_s']:.0f} agent steps/s; wall time in env {t['env_share'] * 100:.0f} %, "
              f"learner {t['learner_share'] * 100:.0f} %")
    print(f"model:          {out / 'model.zip'} (+ model.safetensors, model.json)")
    print(f"episodes:       {out / 'episodes.json'}")
    print(f"run record:     {out / 'run.json'}")
    return 0
