"""``bulletnav navigate``: classical navigation (PID, A*, RRT) scored on env episodes."""

from __future__ import annotations

import argparse

import numpy as np

from bulletnav.cli.args import (
    COUNT,
    DEFAULT_ENV_ID,
    MIN_SPEED,
    add_command,
    add_episode_outputs,
    add_live_args,
    add_mission_args,
    add_physics_arg,
    add_shield_arg,
    add_world_args,
)
from bulletnav.cli.envs import make_env, shielded
from bulletnav.cli.episodes import (
    add_world_idx_arg,
    barn_episode_line,
    barn_report_lines,
    episode_world_label,
    run_with_visuals,
    world_idx_kwargs,
)
from bulletnav.cli.output import fmt, outcome, print_json, refuse_existing_files, safety_line, shield_line
from bulletnav.errors import BulletnavError


def register(sub) -> None:
    """Add ``navigate`` to ``sub`` (``build_parser``'s subparsers)."""
    nav = add_command(sub, "navigate", "classical navigation (PID, A*, RRT, ROS move_base DWA) scored on env episodes")
    nav.add_argument("--planner", choices=["none", "astar", "rrt", "dwa"], default="astar",
                     help="planner on the lidar map: none (PID at the goal), astar or rrt (default astar); dwa: ROS "
                          "move_base with navfn and the DWA local planner, BARN's parameters (docs/classical-navigation.md)")
    nav.add_argument("--dwa-params", metavar="FILE", default=None,
                     help="with --planner dwa: move_base parameters laid over BARN's, a YAML of the same namespaces, or a "
                          "shipped set: barn (BARN's, the default), barn-2ms (the Jackal's full 2.0 m/s) or barn-per-cell "
                          "(scores per costmap cell, the other way ROS can read BARN's file)")
    nav.add_argument("--min-speed", type=MIN_SPEED, default=None, metavar="M",
                     help="lowest speed the robot may command, m/s <= 0 (negative: it may back up; default 0, and with "
                          "--planner dwa the parameters' escape_vel, -0.5 m/s for BARN's, so its escapes can back up)")
    nav.add_argument("--lidar-rays", type=COUNT, default=None, metavar="N",
                     help="lidar rays per scan (default: the env's; 720 is the BARN Jackal's full UST-10 scan)")
    nav.add_argument("--episodes", type=COUNT, default=10, help="episodes to run (default 10)")
    add_world_args(nav)
    add_world_idx_arg(nav)
    add_mission_args(nav)
    nav.add_argument("--pose", choices=["truth", "odometry"], default="truth",
                     help="pose for mapping and steering (default truth)")
    nav.add_argument("--gui", action="store_true", help="watch in the PyBullet GUI (needs a display)")
    nav.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    add_shield_arg(nav)
    add_physics_arg(nav)
    add_episode_outputs(nav)
    add_live_args(nav)
    nav.set_defaults(func=cmd_navigate)


def cmd_navigate(args: argparse.Namespace) -> int:
    """Classical navigation (PID, optionally with A* or RRT) scored on env episodes."""
    from bulletnav.evaluation import summarize

    refuse_existing_files(args, "video", "plot", "record")
    if args.dwa_params is not None and args.planner != "dwa":
        raise BulletnavError(f"--dwa-params {args.dwa_params}: move_base's parameters are for --planner dwa "
                             f"(not {args.planner})")
    extra: dict = {}
    if args.lidar_rays is not None:
        extra["lidar_rays"] = args.lidar_rays
    if args.min_speed is not None:
        extra["min_speed"] = args.min_speed
    nav, title, stops = _controller(args, extra)
    env = shielded(args, make_env(args, **world_idx_kwargs(args), **extra))
    label = episode_world_label(args, env)
    nav = nav(env.unwrapped.scene)

    def line(r) -> None:
        if args.planner == "dwa":
            stops.append(nav.stop_reason)
        if not args.json:
            plans = f"plan {fmt(float(np.median(r.plan_ms)), '.3f')} ms x{len(r.plan_ms)}" if r.plan_ms else "no planner"
            stop = f"  {nav.stop_reason}" if args.planner == "dwa" and nav.stop_reason else ""
            print(f"episode {r.episode:3d}/{args.episodes} seed {r.seed}: {outcome(r):9s} steps {r.steps:4d} "
                  f"sim {r.sim_time:5.1f} s  driven {r.path_length:5.2f} m  shortest to goal centre {r.shortest_path:5.2f} m  "
                  f"SPL {r.spl:.2f}  {plans}  replans {r.replans}{stop}")
            barn = barn_episode_line(r)
            if barn:
                print(f"    {barn}")

    results, written, layout_size = run_with_visuals(args, env, nav, line, f"{title} (seed {args.seed})")
    summary = summarize(results)
    from bulletnav.benchmark.barn import episode_figures

    figures = episode_figures(results)
    if figures is not None:
        summary["barn"] = figures
    summary.update(planner=args.planner, seed=args.seed, pose_source=args.pose, env_id=args.env_id,
                   world=label, world_size=layout_size, perturb=args.perturb, shield=args.shield,
                   physics=args.physics or "default")
    if args.planner == "dwa":
        summary.update(dwa_params=args.dwa_params or "barn", min_speed=extra.get("min_speed", 0.0), stop_reasons=stops)
    if args.json:
        print_json(summary)
        return 0
    _print_report(args, summary, results, written)
    return 0


def _controller(args: argparse.Namespace, extra: dict):
    """(a factory of the controller from the scene view, the report's title, the DWA's stop
    reasons per episode); for ``dwa`` it also adds ``min_speed`` = ``escape_vel`` to ``extra``
    unless ``--min-speed`` was given."""
    if args.planner == "dwa":
        from bulletnav.control.dwa import MoveBaseDWA, dwa_env_kwargs, load_dwa_params

        params = load_dwa_params(args.dwa_params)
        extra.update(dwa_env_kwargs(params, extra))
        return (lambda scene: MoveBaseDWA(scene, params, pose_source=args.pose)), "move_base DWA", []
    from bulletnav.control.navigator import Navigator, NavigatorConfig

    def navigator(scene):
        return Navigator(scene, NavigatorConfig(planner=args.planner, pose_source=args.pose))

    return navigator, f"PID + {args.planner}", []


def _print_report(args: argparse.Namespace, summary: dict, results, written: list[str]) -> None:
    env_name = "" if args.env_id == DEFAULT_ENV_ID else f"{args.env_id} | "
    shift = (f" | perturb {args.perturb}" if args.perturb else "") + (" | shield" if args.shield else "")
    print(f"\nplanner {args.planner} | {env_name}{summary['world']} | episodes {summary['episodes']} | seed {args.seed}{shift}")
    print(f"success rate   {summary['success_rate'] * 100:5.1f} %   collisions {summary['collision_rate'] * 100:5.1f} %   "
          f"SPL {summary['spl']:.3f}")
    print(f"steps          {summary['mean_length']:.1f} +/- {summary['std_length']:.1f}   "
          f"sim time to goal {fmt(summary['mean_sim_time_success'])} s   "
          f"path length {fmt(summary['mean_path_length_success'])} m (successes)")
    print(f"planning       median {fmt(summary['plan_ms_median'], '.3f')} ms  p95 {fmt(summary['plan_ms_p95'], '.3f')} ms  "
          f"calls {summary['plan_calls']}  replans/episode {summary['replans_mean']:.1f}")
    print(f"safety         {safety_line(summary)}")
    if args.shield:
        print(f"shield         {shield_line(summary)}")
    if any(r.goals_total > 1 for r in results):
        print(f"mission        progress {summary['progress'] * 100:.1f} %   PPL {summary['ppl']:.3f}   "
              f"goals per minute {summary['goals_per_minute']:.2f}")
    for text in barn_report_lines(summary.get("barn")):
        print(text)
    for w in written:
        print(w)
