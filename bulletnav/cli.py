"""The ``bulletnav`` command: thin subcommands over the library. Only this module prints."""

from __future__ import annotations

import argparse
import json
import logging
import sys
from collections.abc import Sequence

import numpy as np

from bulletnav.errors import BulletnavError
from bulletnav.rl.envs import EVALUATE_OBSTACLES

DEFAULT_ENV_ID = "bulletnav/Warehouse-v0"
"""The env every subcommand uses unless ``--env`` names another."""


class _Parser(argparse.ArgumentParser):
    """Usage errors as one line, ``bulletnav CMD: error: ...`` (exit 2), like the library's errors."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def _int_type(minimum: int, maximum: int | None = None, what: str = "a whole number"):
    """An argparse type: an integer in ``[minimum, maximum]``, else one line naming the value and what is allowed."""
    allowed = f"{what} from {minimum} to {maximum}" if maximum is not None else f"{what} >= {minimum}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {value}")
        return value

    parse.__name__ = "int"  # argparse's fallback message names the type
    return parse


COUNT = _int_type(1)
"""Episodes, envs, workers, rounds, resets, frequencies: at least 1."""
NON_NEGATIVE = _int_type(0)
"""Seeds, obstacle counts, indices, and counts where 0 means "none" or "the default"."""
SEED = _int_type(0, 2**32 - 1, "a seed, a whole number")


def _non_negative_seconds(text: str) -> float:
    """Seconds >= 0 (``--frame-at``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text!r}") from None
    if not 0 <= value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected seconds >= 0, got {text!r}")
    return value


def FRACTION(text: str) -> float:
    """A rate in (0, 1] (``--stop-at-success``)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a rate above 0 and at most 1, got {text!r}") from None
    if not 0 < value <= 1:
        raise argparse.ArgumentTypeError(f"expected a rate above 0 and at most 1, got {text!r}")
    return value


def _positive_seconds(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}") from None
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(f"expected seconds > 0, got {text!r}")
    return value


def _file_type(suffixes: tuple[str, ...], what: str):
    """An argparse type: a file path ending in one of ``suffixes`` (checked before anything runs)."""

    def parse(text: str) -> str:
        from pathlib import Path

        suffix = Path(text).suffix.lower()
        if suffix not in suffixes:
            raise argparse.ArgumentTypeError(f"{text!r}: {what} is written as {' or '.join(suffixes)}, "
                                             f"not {suffix or 'a name without a suffix'!r}")
        return text

    parse.__name__ = "path"
    return parse


VIDEO_FILE = _file_type((".mp4", ".gif"), "a video")
PNG_FILE = _file_type((".png",), "a plot")
MCAP_FILE = _file_type((".mcap",), "a ROS 2 recording")
DATASET_HELP = ("also write the episodes (observations, actions, rewards, terminations, truncations, infos' scalars) "
                "as the Minari dataset NAME ([namespace/]name-vN) under MINARI_DATASETS_PATH (docs/datasets.md)")
RECORD_HELP = ("also write every episode as ROS 2 messages (scan, odom, imu, tf, cmd_vel, goal, plan, maps, movers) "
               "into PATH, an MCAP file (docs/ros.md)")


class _EnvIdAction(argparse.Action):
    """``--env ID``; also records that it was given (``env_given``), so a model's own env can be the default."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        namespace.env_given = True


def _add_env_arg(parser: argparse.ArgumentParser, default_help: str = DEFAULT_ENV_ID) -> None:
    parser.add_argument("--env", dest="env_id", default=DEFAULT_ENV_ID, metavar="ID", action=_EnvIdAction,
                        help=f"registered bulletnav env id, e.g. bulletnav/WarehouseAisles-v0 (default {default_help})")
    parser.set_defaults(env_given=False)


def _add_overwrite_arg(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace {what} that already exist (default: refuse, so one run never replaces another's)")


def _add_obstacles_arg(parser: argparse.ArgumentParser, default: str = "the env's; 31 on Warehouse-v0") -> None:
    parser.add_argument("--obstacles", type=NON_NEGATIVE, default=None, metavar="K",
                        help=f"obstacles in a procedural warehouse (default: {default})")


def _add_shield_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--shield", action="store_true",
                        help="behind the safety shield: a command whose stopping sweep would touch what the lidar sees or "
                             "a mover is replaced by the closest safe one (reports how often)")


def _add_trust_pickle_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trust-pickle", action="store_true",
                        help="let the model's pickled entries and a *_vecnormalize.pkl be unpickled: that RUNS CODE the "
                             "files hold; only for files you trust (default: never; see docs/safety.md)")


def _add_physics_arg(parser: argparse.ArgumentParser) -> None:
    from bulletnav.config import PHYSICS_PROFILES

    parser.add_argument("--physics", choices=list(PHYSICS_PROFILES), default=None,
                        help="physics profile: default (240 Hz) or fast (the measured cheaper rate, "
                             "docs/performance/physics.md); default: the model's, else the env's")


def _add_world_args(parser: argparse.ArgumentParser) -> None:
    _add_env_arg(parser)
    parser.add_argument("--world", metavar="FILE", help="YAML layout (default: procedural warehouse)")
    _add_obstacles_arg(parser)
    parser.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")


def bulletnav_env_ids() -> list[str]:
    """The Gymnasium ids that bulletnav registers (``bulletnav/...``)."""
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the envs)

    return sorted(env_id for env_id in gym.registry if env_id.startswith("bulletnav/"))


def check_env_id(env_id: str) -> None:
    """Raise :class:`BulletnavError` naming ``env_id`` and the known ids unless bulletnav registers it."""
    ids = bulletnav_env_ids()
    if env_id not in ids:
        raise BulletnavError(f"unknown env id {env_id!r}; bulletnav env ids: {', '.join(ids)}")


def _world_kwargs(args: argparse.Namespace, obstacles: int | None = None) -> dict:
    """``num_obstacles`` (``--obstacles``, else ``obstacles`` when given) and ``world`` (``--world``) for gym.make."""
    kwargs = {}
    if args.obstacles is not None:
        obstacles = args.obstacles
    if obstacles is not None:
        kwargs["num_obstacles"] = obstacles
    if args.world:
        kwargs["world"] = args.world
    if getattr(args, "goals", None) is not None:  # a mission of K goals on any env
        kwargs.update(task_name="mission", goals=args.goals)
    if getattr(args, "order", None) is not None:
        kwargs.update(task_name="mission", goal_order=args.order)
    if getattr(args, "perturb", None) is not None:  # a named evaluation shift, on any env and controller
        kwargs["perturb"] = args.perturb
    if getattr(args, "physics", None) is not None:  # a named physics profile
        kwargs["physics"] = args.physics
    return kwargs


def _add_mission_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--goals", type=COUNT, default=None, metavar="K",
                        help="a mission of K goals (1-8) on any env (default: the env's own task)")
    parser.add_argument("--order", choices=["fixed", "free"], default=None,
                        help="mission goal order: fixed (as given) or free (any; default free)")
    from bulletnav.envs.shifts import PERTURBATIONS

    parser.add_argument("--perturb", choices=list(PERTURBATIONS), default=None, metavar="NAME",
                        help=f"evaluate under a named shift of robot, floor or sensors: {', '.join(PERTURBATIONS)} "
                             "(the same episodes; default none)")


def _world_label(args: argparse.Namespace, obstacles: int | None = None) -> str:
    """The report's name of the warehouses: the layout file, or the procedural obstacle count."""
    if args.world:
        return args.world
    if args.obstacles is not None:
        obstacles = args.obstacles
    if obstacles is None and args.env_id == DEFAULT_ENV_ID:
        from bulletnav.config import WorldConfig

        obstacles = WorldConfig().num_obstacles
    return f"procedural ({obstacles} obstacles)" if obstacles is not None else "procedural"


def _safety_line(s: dict) -> str:
    """One report line of the safety metrics of :func:`bulletnav.evaluation.summarize`."""
    separation = s["min_separation_m"]
    separation_text = "n/a (no movers)" if separation != separation else f"{separation:.2f} m"
    return (f"collisions static {s['collision_static_rate'] * 100:.1f} %  dynamic {s['collision_dynamic_rate'] * 100:.1f} %   "
            f"timeouts {s['timeout_rate'] * 100:.1f} %   min separation {separation_text}   "
            f"near misses {s['near_miss_rate'] * 100:.1f} % of steps   episode time {s['episode_time_s']:.1f} s")


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark and print its JSON (``--json``) or a short table."""
    if args.what == "env" and args.against:
        from bulletnav.bench.reset_bench import REGISTERED, bench_against

        result = bench_against(args.against, (args.env_id,) if args.env_id else REGISTERED, rounds=args.rounds,
                               resets=args.resets, steps=args.steps or 6000, seed=args.seed)
        lines = [f"{'id':32s} {'reset ms before':>16s} {'after':>7s} {'steps/s with resets before':>27s} {'after':>8s} "
                 f"{'speed-up':>9s}"]
        lines += [f"{env_id:32s} {r['before']['reset_ms']:16.2f} {r['after']['reset_ms']:7.2f} "
                  f"{r['before']['steps_per_s_with_resets']:27.1f} {r['after']['steps_per_s_with_resets']:8.1f} "
                  f"{r['speedup']['steps_per_s_with_resets']:8.3f}x" for env_id, r in result["ids"].items()]
    elif args.what == "env" and args.vec:
        from bulletnav.bench.reset_bench import bench_vec

        result = bench_vec(env_id=args.env_id or DEFAULT_ENV_ID, steps=args.steps or 1000, seed=args.seed)
        kinds = ("sync", "async", "sb3_dummy", "sb3_subproc")
        lines = [f"{result['env_id']}: env steps/s, {result['vector_steps']} vector steps each, resets included",
                 f"{'envs':>5s} " + " ".join(f"{k:>12s}" for k in kinds)]
        lines += [f"{row['num_envs']:5d} " + " ".join(f"{row[f'{k}_steps_per_s']:12.1f}" for k in kinds)
                  for row in result["rows"]]
    elif args.what == "env":
        from bulletnav.bench.env_bench import STATIC_REFERENCE, bench_env
        from bulletnav.bench.reset_bench import REGISTERED, bench_ids

        env_id = args.env_id or DEFAULT_ENV_ID
        if env_id == DEFAULT_ENV_ID or env_id in STATIC_REFERENCE:  # the step-cost ratio, then resets
            result = bench_env(steps=args.steps or 6000, seed=args.seed, env_id=env_id)
        else:
            check_env_id(env_id)
            result = {"benchmark": "env_resets", "env_id": env_id}
        result["ids"] = bench_ids((args.env_id,) if args.env_id else REGISTERED, resets=args.resets,
                                  steps=args.steps or 6000, seed=args.seed)
        if result["benchmark"] == "env_resets":
            lines = []
        elif result["benchmark"] == "env_pair":
            lines = [
                f"{result['env_id']:32s} {result['env_steps_per_s']:8.1f} steps/s  (reset {result['reset_ms_mean']:.1f} ms)",
                f"{result['reference_id']:32s} {result['reference_steps_per_s']:8.1f} steps/s  "
                f"(reset {result['reference_reset_ms_mean']:.1f} ms)",
                f"step cost ratio {result['cost_ratio']:.3f} (median over {result['steps'] // result['block']} blocks; "
                f"target <= 1.3)",
            ]
        else:
            lines = [
                f"env  {result['env_steps_per_s']:8.1f} steps/s   (gym.make, random actions, headless, lidar obs)",
                f"raw  {result['raw_steps_per_s']:8.1f} steps/s   (same physics, rays and state queries, plain PyBullet)",
                f"lean {result['physics_and_rays_steps_per_s']:8.1f} steps/s   (physics and rays only; "
                f"ratio {result['ratio_physics_and_rays']:.3f})",
                f"ratio env/raw {result['ratio']:.3f} (median over {result['steps'] // result['block']} blocks; "
                f"regression guard >= {result['ratio_guard']}), overhead {result['env_overhead_us_per_step']:.1f} us/step",
            ]
        lines.append(f"{'id':32s} {'reset ms':>9s} {'raw ms':>7s} {'steps/s with resets':>20s} {'in reset':>9s}")
        lines += [f"{env_id:32s} {r['reset_ms']:9.2f} {r['raw_reset_ms']:7.2f} {r['steps_per_s_with_resets']:20.1f} "
                  f"{r['reset_share'] * 100:8.1f}%" for env_id, r in result["ids"].items()]
    elif args.what == "physics":
        from bulletnav.bench.physics_bench import POLICY_MODEL, bench_physics, bench_rates

        result = bench_physics(steps=args.steps or 3000, seed=args.seed)
        lines = [f"{'setting':34s} {'us/step':>8s} {'speed':>6s} {'3 s dist':>8s} {'drift mm':>8s} {'yaw err %':>9s}"]
        for row in result["settings"]:
            lines.append(f"{row['setting']:34s} {row['us_per_physics_step']:8.1f} {row['speed_vs_pybullet_default']:6.2f} "
                         f"{row['straight_3s_distance_m']:8.4f} {row['max_sideways_drift_mm']:8.2f} {row['yaw_rate_error_pct']:9.2f}")
        rates = bench_rates(rates=args.rates, steps=args.steps or 6000, seed=args.seed, model=args.model or POLICY_MODEL,
                            policy_episodes=args.policy_episodes)
        result["rates"] = rates
        lines += ["", f"physics rates at {rates['control_hz']} Hz control, against {rates['reference_hz']} Hz "
                      f"(policy: {rates['policy_model'] or 'not run'}, {rates['policy_episodes']} episodes from seed "
                      f"{rates['policy_seed']})",
                  f"{'Hz':>4s} {'ms/step':>8s} {'speed':>6s} {'straight %':>10s} {'turn %':>7s} {'arc %':>6s} "
                  f"{'slip %':>7s} {'plate':>6s} {'in mm':>6s} {'success':>8s} {'coll.':>6s} {'qualifies':>9s}"]
        for row in rates["rows"]:
            pol = row.get("policy")
            t = row["tunnelling"]
            lines.append(f"{row['physics_hz']:4d} {row['ms_per_env_step']:8.3f} {row['speedup_vs_reference']:6.2f} "
                         f"{row['straight_error_pct']:10.3f} {row['turn_error_pct']:7.3f} "
                         f"{max(row['arc_heading_error_pct'], row['arc_endpoint_error_pct']):6.3f} "
                         f"{row['wheel_slip_pct']:7.3f} {'hit' if t['collision_registered'] else 'MISSED':>6s} "
                         f"{t['penetration_at_report_mm']:6.2f} "
                         + (f"{pol['success_rate'] * 100:7.1f}% {pol['collision_rate'] * 100:5.1f}% " if pol else
                            f"{'-':>8s} {'-':>6s} ")
                         + f"{'-' if row['qualifies'] is None else ('yes' if row['qualifies'] else 'no'):>9s}")
        lines.append(f"qualifying as a fast profile: {', '.join(f'{hz} Hz' for hz in rates['qualifying_hz']) or 'none'}")
    elif args.what == "planners":
        from bulletnav.bench.planner_bench import bench_navigation

        result = bench_navigation(episodes=args.episodes, seed=args.seed or 1000)
        micro = result["standard_problems"]
        lines = ["standard problems (ms per plan): " + ", ".join(f"{k} {v}" for k, v in micro.items()),
                 f"navigation, {result['episodes']} episodes (seed {result['seed']}), PID follower + lidar map:",
                 f"{'planner':8s} {'success':>7s} {'coll.':>6s} {'SPL':>6s} {'plan med ms':>11s} {'p95 ms':>7s} "
                 f"{'replans':>7s} {'sim time s':>10s} {'path m':>7s}"]
        for name, row in result["navigation"].items():
            lines.append(f"{name:8s} {row['success_rate']:7.2f} {row['collision_rate']:6.2f} {row['spl']:6.3f} "
                         f"{row['plan_ms_median']:11.3f} {row['plan_ms_p95']:7.3f} {row['replans_per_episode']:7.1f} "
                         f"{row['sim_time_to_goal_s']:10.2f} {row['path_length_m']:7.2f}")
        lines.append(f"paired: {result['paired']}")
    elif args.what == "shield":
        from bulletnav.bench.shield_bench import DEFAULT_ENV, bench_shield

        result = bench_shield(steps=args.steps or 3000, seed=args.seed, env_id=args.env_id or DEFAULT_ENV, driver=args.driver,
                              model=args.model)
        d, s = result["decision_ms"], result["env_step_ms"]
        lines = [f"shield decision per step ({result['env_id']}, {result['steps']} steps, driver {result['driver']}, "
                 f"acted on {result['intervention_rate'] * 100:.1f} %):",
                 f"  all      mean {d['mean']:.3f} ms  median {d['median']:.3f} ms  p99 {d['p99']:.3f} ms  max {d['max']:.3f} ms",
                 f"  passed   mean {result['decision_passed_ms']['mean']:.3f} ms   "
                 f"replaced mean {result['decision_vetoed_ms']['mean']:.3f} ms   "
                 f"crept ({result['decision_creep_ms']['n']} steps) mean {result['decision_creep_ms']['mean']:.3f} ms",
                 f"  env step mean {s['mean']:.3f} ms; decision / env step {result['ratio_decision_to_env_step']:.3f}; "
                 f"target mean < 1 ms: {'met' if result['meets_target'] else 'NOT met'}; "
                 f"collisions {result['collisions']} in {result['episodes']} episodes"]
    elif args.what == "gui":
        from bulletnav.bench.gui_bench import bench_gui

        result = bench_gui(steps=args.steps or 100, seed=args.seed)
        lines = [f"GUI frames per second with the A* navigator driving (median of {result['repeats']} x "
                 f"{result['steps']} steps, real-time pacing off, DISPLAY={result['display']}):",
                 f"  throttled dashboard    {result['fps_throttled']:6.2f}",
                 f"  unthrottled dashboard  {result['fps_unthrottled']:6.2f}",
                 f"  no dashboard           {result['fps_no_dashboard']:6.2f}"]
    elif args.what == "fleet":
        from bulletnav.bench.fleet_bench import bench_fleet

        result = bench_fleet(steps=args.steps or 480, seed=args.seed)
        lines = [f"fleet wall time per control step ({result['steps']} steps after {result['warmup']} warm-up, "
                 f"seed {result['seed']}; ratios: per robot, against N = 1 with the same controller):",
                 f"{'controller':>12s} {'robots':>6s} {'step ms':>8s} {'env ms':>7s} {'ctrl ms':>8s} {'ms/robot':>9s} "
                 f"{'vs N=1':>7s} {'env vs N=1':>10s} {'x real time':>11s}"]
        for row in result["sizes"]:
            ratio = "-" if row["per_robot_ratio"] is None else f"{row['per_robot_ratio']:.2f}"
            env_ratio = "-" if row["env_per_robot_ratio"] is None else f"{row['env_per_robot_ratio']:.2f}"
            lines.append(f"{row['controller']:>12s} {row['robots']:6d} {row['step_ms']:8.2f} {row['env_ms']:7.2f} "
                         f"{row['controller_ms']:8.2f} {row['per_robot_ms']:9.2f} {ratio:>7s} {env_ratio:>10s} "
                         f"{row['realtime_factor']:11.1f}")
    else:  # pragma: no cover - argparse restricts the choices
        raise AssertionError(args.what)
    from bulletnav.provenance import provenance

    result = {**result, **provenance()}
    print(_json(result) if args.json else "\n".join(lines))
    return 0


def _make_env(args: argparse.Namespace, **extra):
    import gymnasium as gym

    import bulletnav  # noqa: F401  (registers the env)

    kwargs = dict(_world_kwargs(args), **extra)
    if getattr(args, "layout_style", None):
        kwargs["layout_style"] = args.layout_style
    return gym.make(args.env_id, render_mode="human" if getattr(args, "gui", False) else None, **kwargs)


def _shielded(args: argparse.Namespace, env):
    """``env`` behind the safety shield (``--shield``), else itself."""
    if not getattr(args, "shield", False):
        return env
    from bulletnav.control.shield import ShieldWrapper

    return ShieldWrapper(env)


def _shield_line(s: dict) -> str:
    """One report line of the shield's figures of :func:`bulletnav.evaluation.summarize`."""
    return (f"replaced the command on {s['shield_rate'] * 100:.2f} % of steps, "
            f"mean change {_fmt(s['shield_change_mean'], '.3f')} m/s (wheel rim speeds, when it acted)")


def _json(obj) -> str:
    """Strict JSON: NaN (nothing to average) becomes null."""

    def clean(o):
        if isinstance(o, float) and o != o:
            return None
        if isinstance(o, dict):
            return {k: clean(v) for k, v in o.items()}
        if isinstance(o, (list, tuple)):
            return [clean(v) for v in o]
        return o

    return json.dumps(clean(obj), allow_nan=False)


class _Visuals:
    """Optional episode video, trajectory plot and GUI dashboard, fed by run_episodes' hooks.

    They only read the simulation, so switching them on leaves the episodes unchanged."""

    def __init__(self, env, policy, video: str | None, plot: str | None, gui: bool, shield: bool = False) -> None:
        from bulletnav.viz import Dashboard, EpisodeRecorder, TrajectoryLog

        self.policy = policy
        self.recorder = EpisodeRecorder(video, shield=shield) if video else None
        self.log = TrajectoryLog() if plot else None
        self.plot = plot
        self.dashboard = Dashboard(env) if gui else None

    def _path(self):
        return getattr(self.policy, "path", None)

    def on_reset(self, env, info) -> None:
        if self.recorder is not None:
            self.recorder.on_reset(env, info, path=self._path())
        if self.log is not None:
            self.log.on_reset(env, info)
        if self.dashboard is not None:
            self.dashboard.on_reset()

    def on_step(self, env, info) -> None:
        if self.recorder is not None:
            self.recorder.on_step(env, info, self._path())
        if self.log is not None:
            self.log.on_step(env, info)
        if self.dashboard is not None:
            self.dashboard.on_step(self._path(), info)

    def on_episode(self, result) -> None:
        if self.log is not None:
            self.log.on_episode(result)

    def close(self, title: str = "", ok: bool = True) -> list[str]:
        """Finish the video and write the plot; when the episodes did not finish (``ok`` off),
        drop the unfinished video and write nothing."""
        from bulletnav.viz import plot_trajectories

        if not ok:
            if self.recorder is not None:
                self.recorder.abort()
            return []
        written = []
        if self.recorder is not None:
            self.recorder.close()
            written.append(f"video:      {self.recorder.path} ({self.recorder.frames_written} frames)")
        if self.log is not None and self.plot:
            plot_trajectories(self.log, self.plot, title=title)
            written.append(f"trajectory: {self.plot}")
        return written


def _run_with_visuals(args, env, policy, line, title: str):
    from bulletnav.evaluation import run_episodes

    visuals = _Visuals(env, policy, getattr(args, "video", None), getattr(args, "plot", None), getattr(args, "gui", False),
                       getattr(args, "shield", False))
    sizes: list[list[float]] = []

    def on_reset(env, info) -> None:
        if not sizes:
            sizes.append([float(x) for x in env.unwrapped.scene.layout.size])
        visuals.on_reset(env, info)

    def on_episode(r) -> None:
        visuals.on_episode(r)
        line(r)

    recorder = dataset = None
    if getattr(args, "dataset", None):
        from bulletnav.datasets import DatasetRecorder

        env = dataset = DatasetRecorder(env, args.dataset)
    if getattr(args, "record", None):
        from bulletnav.ros.record import McapRecorder

        env = recorder = McapRecorder(env, args.record, plan=lambda: _planned_path(policy), overwrite=True)
    ok = False
    try:
        results = run_episodes(env, policy, args.episodes, args.seed, on_episode=on_episode,
                               on_step=visuals.on_step, on_reset=on_reset)
        if dataset is not None:
            dataset.save(algorithm=title)
        ok = True
    finally:
        try:
            written = visuals.close(title, ok)
            if recorder is not None and not ok:
                recorder.abort()
        finally:
            env.close()
    if recorder is not None:
        written = [*written, f"recording: {args.record} (ROS 2 MCAP, {recorder.episodes} episodes)"]
    if dataset is not None:
        written = [*written, f"dataset: {args.dataset} (Minari, {len(dataset.buffers)} episodes)"]
    return results, written, (sizes[0] if sizes else None)


def _planned_path(policy):
    """The classical planner's current path under ``policy`` (a Navigator, or one behind a shield), or None."""
    for _ in range(3):
        if hasattr(policy, "path"):
            return policy.path
        policy = getattr(policy, "policy", None) or getattr(policy, "inner", None)
        if policy is None:
            return None
    return None


def _outcome(r) -> str:
    return "SUCCESS" if r.success else ("COLLISION" if r.collision else "TIMEOUT")


def _fmt(x: float, spec: str = ".2f") -> str:
    return "n/a" if x != x else format(x, spec)  # NaN when nothing to average


def _holds_run(path) -> bool:
    """Whether ``path`` is there and not an empty folder (it then holds another run's outputs)."""
    from pathlib import Path

    path = Path(path)
    return path.exists() and (not path.is_dir() or any(path.iterdir()))


def _refuse_existing_files(args: argparse.Namespace, *options: str) -> None:
    """Output files (``--video``, ``--plot``) that exist already are refused unless ``--overwrite``."""
    from pathlib import Path

    for option in options:
        value = getattr(args, option, None)
        if value and Path(value).exists() and not getattr(args, "overwrite", False):
            raise BulletnavError(f"--{option} {value}: the file already exists (another run's?); pass --overwrite "
                                 "to replace it, or choose another name")


def cmd_navigate(args: argparse.Namespace) -> int:
    """Classical navigation (PID, optionally with A* or RRT) scored on env episodes."""
    from bulletnav.control.navigator import Navigator, NavigatorConfig
    from bulletnav.evaluation import summarize

    _refuse_existing_files(args, "video", "plot", "record")
    env = _shielded(args, _make_env(args))
    nav = Navigator(env.unwrapped.scene, NavigatorConfig(planner=args.planner, pose_source=args.pose))

    def line(r) -> None:
        if not args.json:
            plans = f"plan {_fmt(float(np.median(r.plan_ms)), '.3f')} ms x{len(r.plan_ms)}" if r.plan_ms else "no planner"
            print(f"episode {r.episode:3d}/{args.episodes} seed {r.seed}: {_outcome(r):9s} steps {r.steps:4d} "
                  f"sim {r.sim_time:5.1f} s  driven {r.path_length:5.2f} m  shortest {r.shortest_path:5.2f} m  "
                  f"SPL {r.spl:.2f}  {plans}  replans {r.replans}")

    results, written, layout_size = _run_with_visuals(args, env, nav, line, f"PID + {args.planner} (seed {args.seed})")
    summary = summarize(results)
    summary.update(planner=args.planner, seed=args.seed, pose_source=args.pose, env_id=args.env_id,
                   world=_world_label(args), world_size=layout_size, perturb=args.perturb, shield=args.shield,
                   physics=args.physics or "default")
    if args.json:
        print(_json(summary))
        return 0
    env_name = "" if args.env_id == DEFAULT_ENV_ID else f"{args.env_id} | "
    shift = (f" | perturb {args.perturb}" if args.perturb else "") + (" | shield" if args.shield else "")
    print(f"\nplanner {args.planner} | {env_name}{summary['world']} | episodes {summary['episodes']} | seed {args.seed}{shift}")
    print(f"success rate   {summary['success_rate'] * 100:5.1f} %   collisions {summary['collision_rate'] * 100:5.1f} %   "
          f"SPL {summary['spl']:.3f}")
    print(f"steps          {summary['mean_length']:.1f} +/- {summary['std_length']:.1f}   "
          f"sim time to goal {_fmt(summary['mean_sim_time_success'])} s   "
          f"path length {_fmt(summary['mean_path_length_success'])} m (successes)")
    print(f"planning       median {_fmt(summary['plan_ms_median'], '.3f')} ms  p95 {_fmt(summary['plan_ms_p95'], '.3f')} ms  "
          f"calls {summary['plan_calls']}  replans/episode {summary['replans_mean']:.1f}")
    print(f"safety         {_safety_line(summary)}")
    if args.shield:
        print(f"shield         {_shield_line(summary)}")
    if any(r.goals_total > 1 for r in results):
        print(f"mission        progress {summary['progress'] * 100:.1f} %   PPL {summary['ppl']:.3f}   "
              f"goals per minute {summary['goals_per_minute']:.2f}")
    for w in written:
        print(w)
    return 0


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


def _rollout_note(args: argparse.Namespace) -> str | None:
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


def cmd_train(args: argparse.Namespace) -> int:
    import logging
    from pathlib import Path

    from bulletnav.errors import RunError
    from bulletnav.provenance import command_line
    from bulletnav.rl.train import TrainConfig, train
    from bulletnav.viz.compare import plot_learning_curve

    logging.getLogger("bulletnav.rl.curriculum").setLevel(logging.INFO)  # stage changes on the console
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise RunError(f"--out {out}: is a file, not a run directory")
    if not args.resume and not args.overwrite and _holds_run(out):
        names = ", ".join(sorted(p.name for p in out.iterdir())[:4])
        raise RunError(f"--out {out} already holds a run ({names}, ...): pass --resume to continue it, --overwrite to "
                       "train into it anyway (files of the same names are replaced), or choose another --out")
    if args.algo == "bc" or args.dataset:
        return _train_bc(args, out)
    note = _rollout_note(args)
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
        init_from=Path(args.init_from) if args.init_from else None, trust_pickle=args.trust_pickle,
        stop_at_success=args.stop_at_success, **extra,
    )
    record = train(cfg, plot_curve=plot_learning_curve)
    final = record.get("final_eval") or {}
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
    return 0


def _load_for_evaluation(args: argparse.Namespace, model_path: str) -> tuple:
    """The model at ``model_path`` and the env to evaluate it on, checked to fit each other.

    The env is ``--env``, else the one the model's sidecar records (``env_id``), with the
    model's env settings on top. Returns ``(model, meta, vecnorm, env, env_kwargs, default_obstacles)``.

    Raises:
        ModelError: the model cannot be loaded, or its spaces are not the env's.
    """
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.rl.compat import check_model_fits
    from bulletnav.rl.envs import evaluation_env_kwargs
    from bulletnav.rl.io import load_model

    model, meta, vecnorm = load_model(model_path, algo=getattr(args, "algo", None),
                                      trust_pickle=getattr(args, "trust_pickle", False))
    recorded = meta.get("env_id")
    if not getattr(args, "env_given", True) and isinstance(recorded, str) and recorded != args.env_id:
        check_env_id(recorded)  # the model's own env, unless --env names another
        args.env_id = recorded
    # the model's env settings on top of the chosen env; on Warehouse-v0 the benchmark's obstacle count
    default_obstacles = EVALUATE_OBSTACLES if args.env_id == DEFAULT_ENV_ID else None
    env_kwargs = evaluation_env_kwargs(meta.get("env_kwargs", {}))
    env_kwargs.update(_world_kwargs(args, default_obstacles))
    env = _shielded(args, gym.make(args.env_id, render_mode="human" if args.gui else None, **env_kwargs))
    try:
        check_model_fits(model, env, model_path, args.env_id)
    except BaseException:
        env.close()
        raise
    return model, meta, vecnorm, env, env_kwargs, default_obstacles


def _evaluate_report(args: argparse.Namespace, model_path: str, loaded: tuple | None = None) -> dict:
    """Evaluate ``model_path`` as ``args`` say (``loaded``: :func:`_load_for_evaluation`'s, if done
    already); print the article's report (or JSON)."""
    from bulletnav.evaluation import SAFETY_KEYS, SHIELD_KEYS, summarize
    from bulletnav.rl.policy import SB3Policy

    model, meta, vecnorm, env, env_kwargs, default_obstacles = loaded or _load_for_evaluation(args, model_path)
    algo = str(meta.get("algo", getattr(args, "algo", None) or "?")).upper()
    bar = "=" * 60
    if not args.json:
        env_name = "" if args.env_id == DEFAULT_ENV_ID else f", {args.env_id}"
        shift = (f", perturb {args.perturb}" if args.perturb else "") + (", shield" if args.shield else "")
        print(f"{bar}\nRunning {args.episodes} evaluation episodes ({algo} {model_path}, seed {args.seed}{env_name}{shift})\n{bar}")

    def line(r) -> None:
        if args.json:
            return
        mark = "\u2713 SUCCESS" if r.success else ("\u2717 COLLISION" if r.collision else "\u2717 TIMEOUT")
        print(f"--- Episode {r.episode}/{args.episodes} (seed {r.seed}) ---")
        print(f"Initial distance to goal: {r.initial_distance:.2f}m")
        print(f"{mark} | Steps: {r.steps} | Reward: {r.reward:.1f} | Final distance: {r.final_distance:.2f}m | "
              f"Distance traveled: {r.path_length:.2f}m")

    results, written, layout_size = _run_with_visuals(args, env, SB3Policy(model, vecnorm), line, f"{algo} (seed {args.seed})")
    s = summarize(results)
    keys = ("episodes", "success_rate", "mean_reward", "std_reward", "mean_length", "std_length", "mean_distance",
            "std_distance", "collision_rate", "spl", *SAFETY_KEYS, *SHIELD_KEYS, "progress", "ppl", "goals_per_minute",
            "per_episode")
    out = {k: s[k] for k in keys}
    out.update(model=str(model_path), seed=args.seed, env_id=args.env_id,
               world=_world_label(args, default_obstacles), world_size=layout_size, perturb=args.perturb, shield=args.shield,
               physics=env_kwargs.get("physics", "default"), physics_hz=env.unwrapped.config.physics.physics_hz)
    if args.json:
        print(_json(out))
        return out
    n_success = round(s["success_rate"] * s["episodes"])
    print(f"\n{bar}\nEVALUATION RESULTS\n"
          f"Success rate: {n_success}/{s['episodes']} ({s['success_rate'] * 100:.1f}%)\n"
          f"Average reward:         {s['mean_reward']:.2f} \u00b1 {s['std_reward']:.2f}\n"
          f"Average episode length: {s['mean_length']:.1f} \u00b1 {s['std_length']:.1f} steps\n"
          f"Average distance:        {s['mean_distance']:.2f}m \u00b1 {s['std_distance']:.2f}m\n"
          f"Collision rate: {s['collision_rate'] * 100:.1f}%   SPL: {s['spl']:.3f}\n"
          f"Safety: {_safety_line(s)}")
    if args.shield:
        print(f"Shield: {_shield_line(s)}")
    if any(r.goals_total > 1 for r in results):
        print(f"Mission: progress {s['progress'] * 100:.1f} %   PPL {s['ppl']:.3f}   "
              f"goals per minute {s['goals_per_minute']:.2f}")
    print(bar)
    for w in written:
        print(w)
    return out


def cmd_compare(args: argparse.Namespace) -> int:
    """Learning curves of several training runs in one PNG and a table of their results."""
    from pathlib import Path

    from bulletnav.viz.compare import REACH_SUCCESS, compare_runs

    rate = REACH_SUCCESS if args.reach is None else args.reach
    rows = compare_runs([Path(r) for r in args.runs], Path(args.out), group_by=args.group_by, reach=rate)
    if args.json:
        print(_json(rows))
        return 0
    reach = f"first >= {rate * 100:.0f} % at (steps, s)"
    head = {"algo": "algorithm", "hyperparams": "hyperparameters", "start": "start"}[args.group_by]
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


def cmd_evaluate(args: argparse.Namespace) -> int:
    _refuse_existing_files(args, "video", "plot", "record")
    _evaluate_report(args, args.model)
    return 0


DEFAULT_MODEL = "models/ppo_warehouse.zip"
SHIPPED_MODELS = {"bulletnav/Warehouse-v0": DEFAULT_MODEL, "bulletnav/WarehouseMission-v0": "models/ppo_mission.zip",
                  "bulletnav/WarehouseDynamic-v0": "models/ppo_dynamic.zip"}
"""The model ``demo`` runs on each env id when ``--model`` is not given (others: ``DEFAULT_MODEL``)."""


def cmd_demo(args: argparse.Namespace) -> int:
    """The main job: the shipped PPO policy on evaluation episodes, with video and plot."""
    import time
    from pathlib import Path

    from bulletnav.errors import ModelError

    shipped = args.model is None
    if shipped:
        args.model = SHIPPED_MODELS.get(args.env_id, DEFAULT_MODEL)
    model = Path(args.model)
    if not model.is_file():
        packaged = Path(__file__).resolve().parent.parent / args.model
        if shipped and packaged.is_file():
            model = packaged
        else:
            raise ModelError(f"{args.model}: model file not found (train one with `bulletnav train`)")
    _refuse_existing_files(args, "video", "record")
    if args.out is not None and Path(args.out).exists() and not Path(args.out).is_dir():
        raise BulletnavError(f"--out {args.out}: is a file, not a folder")
    if args.out is not None and _holds_run(args.out) and not args.overwrite:
        raise BulletnavError(f"--out {args.out} already holds a run ({', '.join(sorted(p.name for p in Path(args.out).iterdir())[:3])}"
                             "): pass --overwrite to replace its files, or choose another folder (without --out every "
                             f"demo gets a new folder beside {DEFAULT_DEMO_OUT})")
    loaded = _load_for_evaluation(args, str(model))  # the model fits the env before any folder is made
    try:
        out, created = _demo_folder(args.out)
    except BaseException:
        loaded[3].close()
        raise
    if args.out is None and out != Path(DEFAULT_DEMO_OUT):
        print(f"{DEFAULT_DEMO_OUT} holds an earlier demo: this one writes to {out}/", file=sys.stderr if args.json else sys.stdout)
    args.video = args.video or str(out / "episodes.mp4")
    args.plot = str(out / "trajectories.png")
    t0 = time.perf_counter()
    try:
        _evaluate_report(args, str(model), loaded)
    except BaseException:
        if created and not _holds_run(out):
            out.rmdir()  # nothing written: no empty folder left behind
        raise
    print(f"demo finished in {time.perf_counter() - t0:.0f} s; results in {out}/")
    return 0


def _view_fleet(args: argparse.Namespace) -> int:
    """``view --robots N``: a fleet in the GUI, each robot tinted in its colour with its goal marked,
    driving its errands with PID + A* (the independent controller)."""
    import time

    from bulletnav.fleet.controllers import make_controller
    from bulletnav.fleet.env import FleetEnv
    from bulletnav.viz.fleet import FleetDashboard

    kwargs = _fleet_world_kwargs(args, args.env_id if args.env_given else None)
    env = FleetEnv(num_robots=args.robots, render_mode="human", dynamic=args.dynamic, **kwargs)
    try:
        controller = make_controller("independent", env)
        observations, infos = env.reset(seed=args.seed)
        controller.reset(infos)
        dashboard = FleetDashboard(env)
        dashboard.on_reset(infos)
        t_end = time.perf_counter() + args.seconds
        steps = 0
        while time.perf_counter() < t_end:
            observations, _, _, _, infos = env.step(controller.act(observations, infos))
            dashboard.on_step(infos)
            steps += 1
            if not env.agents:  # the episode's duration is over
                observations, infos = env.reset()
                controller.reset(infos)
                dashboard.on_reset(infos)
        errands = sum(int(info["errands_completed"]) for info in infos.values())
        print(f"viewed a fleet of {args.robots} robots for {args.seconds:g} s ({steps} control steps, "
              f"{steps / args.seconds:.1f} steps/s; {errands} errands done this episode)")
    finally:
        env.close()
    return 0


DEFAULT_DEMO_OUT = "runs/demo"
"""Where ``demo`` writes without ``--out``; when it holds an earlier demo, ``runs/demo-2``, ``-3``, ..."""


def _demo_folder(out: str | None):
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
            if path.is_dir() and not _holds_run(path):
                return path, False
    raise AssertionError("unreachable")


def cmd_view(args: argparse.Namespace) -> int:
    """Open a warehouse in the PyBullet GUI with the dashboard; the robot turns in place (with
    ``--robots N``: a fleet running its errands)."""
    import time

    if args.robots is not None:
        return _view_fleet(args)
    if args.dynamic:
        raise BulletnavError("view --dynamic is for a fleet (--robots N); for one robot pass --env bulletnav/WarehouseDynamic-v0")

    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.viz import Dashboard

    kwargs = _world_kwargs(args)
    if args.layout_style:
        kwargs["layout_style"] = args.layout_style
    env = gym.make(args.env_id, render_mode="human", **kwargs)
    try:
        env.reset(seed=args.seed)
        dashboard = Dashboard(env)
        dashboard.on_reset()
        t_end = time.perf_counter() + args.seconds
        steps = 0
        turn = np.array([0.0, 0.5], dtype=np.float32)  # turning in place shows the lidar sweep and camera
        while time.perf_counter() < t_end:
            _, _, terminated, truncated, _ = env.step(turn)
            dashboard.on_step()
            steps += 1
            if terminated or truncated:  # the time limit (1000 steps on Warehouse-v0)
                env.reset()
                dashboard.on_reset()
        print(f"viewed {env.unwrapped.scene.layout.name or 'procedural'} warehouse for {args.seconds:g} s "
              f"({steps} control steps, {steps / args.seconds:.1f} steps/s with the dashboard)")
    finally:
        env.close()
    return 0


def cmd_benchmark(args: argparse.Namespace) -> int:
    """Every controller of a suite on the same seeded episodes of every world: results.json + report.html."""
    from pathlib import Path

    from tqdm import tqdm

    from bulletnav.benchmark.report import best_controllers, screenshots, write_report
    from bulletnav.benchmark.runner import run_suite
    from bulletnav.benchmark.suite import load_suite
    from bulletnav.viz.plots import draw_layout

    suite = load_suite(args.suite)
    out = Path(args.out or f"runs/benchmark/{suite.name}")
    if args.report_only:  # the report (and screenshots) again from DIR/results.json
        results_file = out / "results.json"
        if not results_file.is_file():
            raise BulletnavError(f"{results_file}: no results to report (run the suite first)")
        results = json.loads(results_file.read_text())
        report = write_report(results, out / "report.html", draw_layout)
        print(f"report:  {report}")
        for shot in (screenshots(report, out, tab=args.screenshot_tab) if args.screenshots else []):
            print(f"screenshot: {shot}")
        return 0
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if args.json:
            return
        if bar is None:
            bar = tqdm(total=total, initial=done, unit="episode", desc=f"benchmark {suite.name}", file=sys.stderr)
        bar.update(done - bar.n)

    try:
        results = run_suite(suite, out, workers=args.workers, address=args.address, resume=args.resume, progress=progress)
    finally:
        if bar is not None:
            bar.close()
    report = write_report(results, out / "report.html", draw_layout)
    if args.json:
        print(_json(results))
        return 0
    controllers = [c["name"] for c in results["suite"]["controllers"]]
    cells = {(c["world"], c["controller"]): c["summary"] for c in results["cells"]}
    best = best_controllers(results)
    print(f"\nbenchmark {suite.name}: {suite.total} episodes in {results['provenance']['wall_time_s']:.0f} s "
          f"({args.workers} workers); success / collisions / SPL per world and controller")
    print("| world | " + " | ".join(controllers) + " |")
    print("|---" * (len(controllers) + 1) + "|")
    for w in results["suite"]["worlds"]:
        row = []
        for c in controllers:
            s = cells[(w["name"], c)]
            mark = " **best**" if best.get(w["name"]) == c else ""
            row.append(f"{s['success']['mean'] * 100:.1f} % / {s['collision']['mean'] * 100:.1f} % / "
                       f"{s['spl']['mean']:.3f}{mark}")
        print(f"| {w['name']} | " + " | ".join(row) + " |")
    print(f"results: {out / 'results.json'}\nreport:  {report}")
    for shot in (screenshots(report, out, tab=args.screenshot_tab) if args.screenshots else []):
        print(f"screenshot: {shot}")
    return 0


def cmd_sweep(args: argparse.Namespace) -> int:
    from pathlib import Path

    from bulletnav.provenance import command_line
    from bulletnav.sweep.results import config_label
    from bulletnav.sweep.run import SweepOptions, run_sweep
    from bulletnav.sweep.spec import SweepSpec

    spec = SweepSpec.from_file(args.file)
    opts = SweepOptions(out=Path(args.out), address=args.address, storage=args.storage, resume=args.resume,
                        optimize=args.optimize, num_cpus=args.num_cpus, command=command_line())
    try:
        record = run_sweep(spec, opts)
    except KeyboardInterrupt:  # a second Ctrl-C, while Ray Tune was saving its state
        print(f"bulletnav sweep: interrupted; continue with: bulletnav sweep {args.file} --out {args.out} --resume",
              file=sys.stderr)
        return 130
    resume_hint = f"bulletnav sweep: interrupted; continue with: bulletnav sweep {args.file} --out {args.out} --resume"
    if args.json:
        print(_json(record))
        if record["interrupted"]:
            print(resume_hint, file=sys.stderr)
        return 130 if record["interrupted"] else 0
    pct = (lambda x: "-" if x is None else f"{x * 100:.1f} %") if spec.metric in ("success_rate", "collision_rate") \
        else (lambda x: "-" if x is None else f"{x:.3f}")
    print(f"sweep {spec.name}: {len(record['trials'])} trials, {record['wall_time_s']:.0f} s "
          f"({spec.metric} on {spec.evaluation_episodes} held-out episodes from seed {spec.evaluation_seed})")
    print("| trial | config | seed | status | timesteps | " + spec.metric + " | node |")
    print("|---|---|---|---|---|---|---|")
    for r in record["trials"]:
        cfg = config_label(r["config"])
        note = f" ({r['error']})" if r["error"] else ""
        print(f"| {r['trial']} | {cfg} | {r['seed']} | {r['status']}{note} | {r['timesteps'] or '-'} | "
              f"{pct(r.get(spec.metric))} | {(r['node'] or '-')[:8]} |")
    print(f"\n| config | seeds | mean {spec.metric} | 95 % CI (bootstrap) | min | max |")
    print("|---|---|---|---|---|---|")
    for s in record["summary"]:
        ci = f"{pct(s['ci95'][0])} - {pct(s['ci95'][1])}" if s["ci95"] else ("- (one seed)" if s["n"] == 1 else "-")
        print(f"| {s['label']} | {s['n']} | {pct(s['mean'])} | {ci} | {pct(s['min'])} | {pct(s['max'])} |")
    if record.get("best"):
        print(f"\nbest: {record['best']['config']} -> {record['best']['hyperparams']}")
    for name, path in record["files"].items():
        print(f"{name + ':':9} {path}")
    if record["interrupted"]:
        print(f"{record['interrupted']} trial(s) unfinished", file=sys.stderr)
        print(resume_hint, file=sys.stderr)
        return 130
    return 0


def cmd_convert_model(args: argparse.Namespace) -> int:
    from pathlib import Path

    from bulletnav.rl.safe import convert_model, weights_path

    path = Path(args.model)
    meta = convert_model(path, trust_pickle=args.trust_pickle)
    print(f"wrote {weights_path(path)} and {path.with_suffix('.json')} ({meta['policy']['algo'].upper()}, "
          f"{meta['policy']['class'].rsplit('.', 1)[1]}, statistics: {'yes' if meta['normalization'] else 'none'}); "
          "every loader now reads these and never unpickles")
    return 0


FLEET_ROBOTS = _int_type(1, 16, "a robot count, a whole number")
"""Robots in a fleet: 1 to 16 (``bulletnav.fleet.MAX_ROBOTS``)."""


def cmd_fleet(args: argparse.Namespace) -> int:
    """Run a fleet controller on seeded fleet episodes; print the metrics (``--json``) or a table."""
    from bulletnav.errors import ConfigError
    from bulletnav.fleet.controllers import DEFAULT_MODEL, make_controller, model_env_kwargs
    from bulletnav.fleet.metrics import run_fleet_episodes

    if args.model is not None and args.controller != "policy":
        raise ConfigError(f"--model is for --controller policy, not {args.controller}")
    if args.frame_at is not None and not args.frame:
        raise ConfigError("--frame-at is the time of the --frame PNG: pass --frame too")
    if args.frame_at is not None and args.frame_at > args.duration:
        raise ConfigError(f"--frame-at {args.frame_at:g} s is after the episode's end (--duration {args.duration:g} s)")
    _refuse_existing_files(args, "video", "plot", "frame", "record")
    model = args.model or DEFAULT_MODEL
    env_kwargs: dict[str, object] = {}
    if args.controller == "policy":
        import torch

        env_kwargs = dict(model_env_kwargs(model))
        # one thread, as fleet-compare's workers (the same arithmetic as their rows): a forward
        # pass of a few robots is too small for two, and two threads beside other work spend
        # their time waiting for each other (a 40-episode run took 46 CPU-min and was not done)
        torch.set_num_threads(1)
    env_kwargs.update(_fleet_world_kwargs(args, args.env_id))
    env_kwargs.update(num_robots=args.robots, duration_s=args.duration, dynamic=args.dynamic)
    visuals = None
    if args.video or args.plot or args.frame:
        from bulletnav.viz.fleet import FleetVisuals

        visuals = FleetVisuals(video=args.video, frame=args.frame, frame_at_s=args.frame_at, plot=args.plot, episode=0,
                               title=f"{args.controller}{' + shield' if args.shield else ''}, seed {args.seed}")
    recorder = None
    if args.record:
        from bulletnav.ros.fleet_record import FleetMcapRecorder

        recorder = FleetMcapRecorder(args.record, overwrite=True)
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
    s = result["summary"]
    keys = ("throughput_per_hour", "throughput_per_robot_per_hour", "errands", "legs", "collisions_robot_robot",
            "collisions_static", "collisions_mover", "collisions_person", "deadlocks", "min_separation_m",
            "errand_time_s", "near_misses", "intimate_s", "personal_s", "shield_rate")
    out = {"command": "fleet", "controller": args.controller, "shield": args.shield, "robots": args.robots,
           "duration_s": args.duration, "dynamic": args.dynamic, "episodes": args.episodes, "seed": args.seed,
           "env_id": args.env_id, "world": args.world, "layout_style": args.layout_style, "obstacles": args.obstacles,
           "model": model if args.controller == "policy" else None, **{k: s[k] for k in keys},
           "rows": result["episodes"]}
    if args.json:
        print(_json(out))
        for w in written:
            print(w, file=sys.stderr)
        return 0
    print(f"fleet: {args.robots} robots, {args.controller}{' + shield' if args.shield else ''}, "
          f"{args.episodes} episodes of {args.duration:g} s{' (dynamic)' if args.dynamic else ''}, seeds {args.seed}..")
    print(f"{'ep':>3s} {'seed':>6s} {'errands':>7s} {'per h':>7s} {'robot':>5s} {'static':>6s} {'mover':>5s} "
          f"{'person':>6s} {'dlock':>5s} {'min sep m':>9s} {'errand s':>8s}")
    for r in result["episodes"]:
        print(f"{r['episode']:3d} {r['seed']:6d} {r['errands']:7d} {r['throughput_per_hour']:7.1f} "
              f"{r['collisions_robot_robot']:5d} {r['collisions_static']:6d} {r['collisions_mover']:5d} "
              f"{r['collisions_person']:6d} {r['deadlocks']:5d} {_fmt(r['min_separation_m']):>9s} "
              f"{_fmt(r['errand_time_s'], '.1f'):>8s}")
    print(f"all: {s['throughput_per_hour']:.1f} errands/h ({s['throughput_per_robot_per_hour']:.1f} per robot), "
          f"collisions robot {s['collisions_robot_robot']}, static {s['collisions_static']}, mover "
          f"{s['collisions_mover']}, person {s['collisions_person']}; deadlocks {s['deadlocks']}; "
          f"min separation {_fmt(s['min_separation_m'])} m; errand time {_fmt(s['errand_time_s'], '.1f')} s")
    for w in written:
        print(w)
    return 0


def _fleet_world_kwargs(args: argparse.Namespace, env_id: str | None) -> dict:
    """The fleet env's world arguments: ``env_id`` (``--env``: its registered settings instead of
    the fleet's aisle warehouse), ``--world``, ``--layout-style``, ``--obstacles``."""
    kwargs: dict = {}
    if env_id is not None:
        import gymnasium as gym

        from bulletnav.envs.warehouse import make_config

        kwargs["config"] = make_config(None, **gym.spec(env_id).kwargs)
    if args.world:
        kwargs["world"] = args.world
    if getattr(args, "layout_style", None):
        kwargs["layout_style"] = args.layout_style
    if args.obstacles is not None:
        kwargs["num_obstacles"] = args.obstacles
    return kwargs


def _add_fleet_world_args(parser: argparse.ArgumentParser, env_default: str) -> None:
    from bulletnav.sim.generators import WORLDS

    parser.add_argument("--env", dest="env_id", default=None, metavar="ID",
                        help=f"start from this registered bulletnav env's settings (default {env_default})")
    parser.add_argument("--world", metavar="FILE", help="YAML layout, with its stations: if it names them "
                                                        "(default: a procedural warehouse)")
    parser.add_argument("--layout-style", choices=sorted(WORLDS), default=None,
                        help="procedural layout generator (default: the env's, aisles; pick stations need racks)")
    _add_obstacles_arg(parser, "the env's")


def cmd_map(args: argparse.Namespace) -> int:
    """Map a ROS 2 bag with bulletnav's lidar mapper; optionally plan on it."""
    from bulletnav.ros.bagmap import build_map, plan_path, read_bag, write_map_png

    _refuse_existing_files(args, "out")
    data = read_bag(args.bag, scan_topic=args.scan_topic, odom_topic=args.odom_topic)
    bag_map = build_map(data, resolution=args.resolution)
    goal = tuple(args.plan_to) if args.plan_to else None
    path = plan_path(bag_map, goal) if goal else None
    if args.out:
        write_map_png(bag_map, args.out, path, goal, title=f"{args.bag}: {bag_map.scans_used} scans")
    state = bag_map.mapper.state()
    summary = {"bag": str(args.bag), "scan_topic": args.scan_topic, "pose_source": data.pose_source,
               "fixed_frame": data.fixed_frame, "scans": bag_map.scans_used, "scans_without_pose": bag_map.scans_skipped,
               "resolution_m": args.resolution, "cells": list(state.shape),
               "occupied_cells": int((state > 0).sum()), "free_cells": int((state == 0).sum()),
               "plan_to": list(goal) if goal else None, "path_found": None if goal is None else path is not None,
               "path_length_m": (None if not path else float(sum(np.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(path, path[1:])))),
               "out": args.out}
    if args.json:
        print(_json(summary))
        return 0
    print(f"{args.bag}: {bag_map.scans_used} scans on {args.scan_topic} placed by {data.pose_source} "
          f"({data.fixed_frame} frame), {summary['occupied_cells']} occupied and {summary['free_cells']} free cells "
          f"of {args.resolution:g} m")
    if goal:
        print(f"A* to ({goal[0]:g}, {goal[1]:g}): " + (f"{summary['path_length_m']:.2f} m" if path else "no path"))
    if args.out:
        print(f"map: {args.out}")
    return 0


def cmd_replay(args: argparse.Namespace) -> int:
    """Draw a recording's episodes from the file alone."""
    import tempfile
    from pathlib import Path

    from bulletnav.ros.replay import replay

    _refuse_existing_files(args, "video", "plot", "frame", "panel")
    if args.panel and not (args.video or args.plot or args.frame):
        from bulletnav.ros.replay import panel_view

        summary = {"recording": args.recording, "panel": panel_view(args.recording, args.panel, at_s=args.panel_at)}
        print(_json(summary) if args.json else f"panel: {args.panel} (t = {summary['panel']['time_s']:.2f} s)")
        return 0
    video = args.video
    scratch = None
    if args.frame and not video:
        scratch = tempfile.mkdtemp(prefix="bulletnav-replay-")
        video = str(Path(scratch) / "replay.mp4")
    try:
        summary = replay(args.recording, video=video, plot=args.plot)
        if args.frame:
            import imageio.v3 as iio

            from bulletnav.files import save_image

            frames = summary["frames"]
            at = frames // 2 if args.frame_at is None else min(args.frame_at, frames) - 1
            image = iio.imread(video, index=at)
            save_image(image, args.frame)  # a PNG whatever the name's suffix
            summary["frame"], summary["frame_index"] = args.frame, at
    finally:
        if scratch is not None:
            import shutil

            shutil.rmtree(scratch, ignore_errors=True)
    if args.panel:
        from bulletnav.ros.replay import panel_view

        summary["panel"] = panel_view(args.recording, args.panel, at_s=args.panel_at)["out"]
    if not args.video:
        summary["video"] = None
    if args.json:
        print(_json(summary))
        return 0
    print(f"{args.recording}: {summary['episodes']} episodes, steps {summary['steps']}, outcomes {summary['outcomes']}")
    for key in ("video", "plot", "frame", "panel"):
        if summary.get(key):
            print(f"{key}: {summary[key]}")
    return 0


def cmd_fleet_compare(args: argparse.Namespace) -> int:
    """Every fleet controller, with and without the shield, on the same seeded episodes."""
    from pathlib import Path

    from tqdm import tqdm

    from bulletnav.fleet.compare import parse_entries, run_comparison

    entries = parse_entries(args.controllers, args.shield)
    env_kwargs = {"duration_s": args.duration, "dynamic": args.dynamic}
    bar = None

    def progress(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, initial=done, unit="episode", desc="fleet-compare", file=sys.stderr,
                       disable=args.json)
        bar.update(done - bar.n)

    try:
        results = run_comparison(Path(args.out), entries, robots=args.robots, episodes=args.episodes, seed=args.seed,
                                 env_kwargs=env_kwargs, workers=args.workers, resume=args.resume, progress=progress,
                                 run=not args.tables_only)
    finally:
        if bar is not None:
            bar.close()
    if args.json:
        print(_json({k: results[k] for k in ("settings", "cells", "provenance")}))
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
    if not args.resume and not args.overwrite and _holds_run(out):
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


def _hz_list(text: str) -> tuple[int, ...]:
    """``--rates``: comma-separated positive integers (Hz)."""
    try:
        rates = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated rates in Hz, e.g. 240,120, got {text!r}") from None
    if not rates or min(rates) <= 0:
        raise argparse.ArgumentTypeError(f"rates must be positive integers (Hz), got {text!r}")
    return rates


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="bulletnav",
        description="PyBullet warehouse navigation: classical and learned controllers on the same episodes.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def add(name: str, help_: str) -> argparse.ArgumentParser:
        return sub.add_parser(name, help=help_, description=help_)

    nav = add("navigate", "classical navigation (PID, A*, RRT) scored on env episodes")
    nav.add_argument("--planner", choices=["none", "astar", "rrt"], default="astar",
                     help="planner on the lidar map: none (PID at the goal), astar or rrt (default astar)")
    nav.add_argument("--episodes", type=COUNT, default=10, help="episodes to run (default 10)")
    _add_world_args(nav)
    _add_mission_args(nav)
    nav.add_argument("--pose", choices=["truth", "odometry"], default="truth",
                     help="pose for mapping and steering (default truth)")
    nav.add_argument("--gui", action="store_true", help="watch in the PyBullet GUI (needs a display)")
    nav.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    _add_shield_arg(nav)
    _add_physics_arg(nav)
    nav.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="record every episode to PATH (.mp4 or .gif)")
    nav.add_argument("--plot", type=PNG_FILE, metavar="PNG", help="write all episodes' paths over their maps")
    nav.add_argument("--record", type=MCAP_FILE, metavar="PATH", help=RECORD_HELP)
    nav.add_argument("--dataset", metavar="NAME", help=DATASET_HELP)
    _add_overwrite_arg(nav, "--video, --plot and --record files")
    nav.set_defaults(func=cmd_navigate)

    tr = add("train", "train an SB3 agent (hyperparameters from rl/hyperparams/<algo>.yml)")
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
    _add_env_arg(tr)
    tr.add_argument("--out", required=True, metavar="DIR", help="run directory, e.g. runs/ppo")
    tr.add_argument("--resume", action="store_true", help="continue from DIR/checkpoints/last.zip")
    tr.add_argument("--overwrite", action="store_true",
                    help="train into an --out DIR that holds another run, replacing its files (default: refuse)")
    tr.add_argument("--init-from", metavar="MODEL",
                    help="fine-tune: start from this model's weights with this run's settings (steps count from 0)")
    tr.add_argument("--eval-freq", type=COUNT, default=25_000, help="evaluate every N timesteps (default 25000)")
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
    _add_trust_pickle_arg(tr)
    _add_physics_arg(tr)
    tr.set_defaults(func=cmd_train)

    sw = add("sweep", "train a sweep file's trials (grid x seeds, or --optimize N) on Ray Tune, locally or on a cluster")
    sw.add_argument("file", metavar="SWEEP.yaml", help="sweep file (see docs/sweeps/ and bulletnav/sweep/spec.py)")
    sw.add_argument("--out", default="runs/sweeps", metavar="DIR",
                    help="results: DIR/<name>/ gets the tables, plot and (without --storage) the trials (default runs/sweeps)")
    sw.add_argument("--resume", action="store_true",
                    help="continue the interrupted sweep: finished trials are kept, unfinished ones resume")
    sw.add_argument("--optimize", type=COUNT, metavar="N",
                    help="N trials of Optuna's TPE over the file's search: block, bad ones stopped early")
    sw.add_argument("--address", metavar="HOST:PORT",
                    help="join this Ray cluster (default: RAY_ADDRESS if set, else a local Ray on this machine's cores)")
    sw.add_argument("--storage", metavar="PATH|URI",
                    help="where trials and their checkpoints live, reachable from every node (default --out)")
    sw.add_argument("--num-cpus", type=COUNT, metavar="N", help="CPUs of the local Ray (default: all)")
    sw.add_argument("--json", action="store_true", help="print the results record as JSON")
    sw.set_defaults(func=cmd_sweep)

    ev = add("evaluate", "evaluate a trained model (deterministic actions)")
    ev.add_argument("--model", required=True, metavar="PATH", help="model zip written by train")
    ev.add_argument("--algo", choices=["ppo", "sac", "td3", "a2c"], default=None,
                    help="only needed when the .json beside the model is missing")
    ev.add_argument("--episodes", type=COUNT, default=10, help="episodes to run (default 10)")
    _add_env_arg(ev, "the env the model's .json names, else " + DEFAULT_ENV_ID)
    ev.add_argument("--world", metavar="FILE", help="YAML layout (default: procedural warehouse)")
    _add_mission_args(ev)
    _add_obstacles_arg(ev, "31 on Warehouse-v0, else the model's or the env's")
    ev.add_argument("--seed", type=SEED, default=1000, help="episode k uses env seed S + k (default 1000)")
    ev.add_argument("--gui", action="store_true", help="watch in the PyBullet GUI (needs a display)")
    _add_trust_pickle_arg(ev)
    ev.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    _add_shield_arg(ev)
    _add_physics_arg(ev)
    ev.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="record every episode to PATH (.mp4 or .gif)")
    ev.add_argument("--plot", type=PNG_FILE, metavar="PNG", help="write all episodes' paths over their maps")
    ev.add_argument("--record", type=MCAP_FILE, metavar="PATH", help=RECORD_HELP)
    ev.add_argument("--dataset", metavar="NAME", help=DATASET_HELP)
    _add_overwrite_arg(ev, "--video, --plot and --record files")
    ev.set_defaults(func=cmd_evaluate)

    cmp_ = add("compare", "plot several training runs' learning curves and tabulate them")
    cmp_.add_argument("runs", nargs="+", metavar="RUN_DIR", help="directories written by train")
    cmp_.add_argument("--out", type=PNG_FILE, default="docs/algorithms.png", metavar="PNG",
                      help="figure to write (default docs/algorithms.png)")
    cmp_.add_argument("--group-by", choices=("algo", "hyperparams", "start"), default="algo",
                      help="colour and summarize runs by algorithm (default), by hyperparameter file "
                           "(ablations of one algorithm), or by start (scratch, or the --init-from model)")
    cmp_.add_argument("--reach", type=FRACTION, default=None, metavar="RATE",
                      help="the table's 'first reached' column: the first evaluation with this success rate "
                           "(0-1, default 0.8)")
    cmp_.add_argument("--json", action="store_true", help="print the table as JSON")
    cmp_.set_defaults(func=cmd_compare)

    demo = add("demo", "the main job: the shipped PPO policy, report, video and trajectory plot")
    demo.add_argument("--model", help=f"model zip (default: the shipped model for --env, {DEFAULT_MODEL} on "
                      "Warehouse-v0, models/ppo_mission.zip on WarehouseMission-v0, models/ppo_dynamic.zip on "
                      "WarehouseDynamic-v0)")
    demo.add_argument("--episodes", type=COUNT, default=5, help="episodes to run (default 5)")
    demo.add_argument("--seed", type=SEED, default=2024, help="episode k uses env seed S + k (default 2024)")
    _add_env_arg(demo, "the env the model's .json names, else " + DEFAULT_ENV_ID)
    demo.add_argument("--world", metavar="FILE", help="YAML layout (default: procedural warehouse)")
    _add_mission_args(demo)
    _add_obstacles_arg(demo, "31 on Warehouse-v0, else the model's or the env's")
    demo.add_argument("--out", default=None, metavar="DIR",
                      help="output directory; one that holds a run is refused without --overwrite (default: "
                           "runs/demo, or runs/demo-2, -3, ... when it holds an earlier demo)")
    demo.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="video file (default DIR/episodes.mp4)")
    demo.add_argument("--record", type=MCAP_FILE, metavar="PATH", help=RECORD_HELP)
    _add_overwrite_arg(demo, "the files of an --out DIR, a --video or a --record")
    demo.add_argument("--gui", action="store_true", help="watch live in the PyBullet GUI")
    demo.add_argument("--json", action="store_true", help="print one JSON object instead of the report")
    _add_shield_arg(demo)
    _add_physics_arg(demo)
    _add_trust_pickle_arg(demo)
    demo.set_defaults(func=cmd_demo, algo=None)

    conv = add("convert-model", "write the pickle-free files (NAME.safetensors + the sidecar's policy and statistics) "
                                "beside an SB3 model zip")
    conv.add_argument("model", metavar="MODEL", help="SB3 model zip (with its .json and statistics beside it, if any)")
    _add_trust_pickle_arg(conv)
    conv.set_defaults(func=cmd_convert_model)

    view = add("view", "look at a warehouse in the PyBullet GUI")
    _add_env_arg(view)
    view.add_argument("--world", metavar="FILE", help="YAML layout (default: procedural warehouse)")
    _add_obstacles_arg(view)
    view.add_argument("--seed", type=SEED, default=0, help="warehouse seed (default 0)")
    view.add_argument("--seconds", type=_positive_seconds, default=30.0, help="how long to show it (default 30)")
    view.add_argument("--robots", type=FLEET_ROBOTS, default=None, metavar="N",
                      help="show a fleet of N robots (1 to 16) driving errands with PID + A*, each in its own colour "
                           "with its goal marked (default: one robot turning in place; --env then defaults to the "
                           "fleet's aisle warehouse)")
    view.add_argument("--dynamic", action="store_true", help="with --robots: add forklifts, workers and pallet events")
    from bulletnav.sim.generators import WORLDS

    view.add_argument("--layout-style", choices=sorted(WORLDS), default=None,
                      help="with --robots: procedural layout generator (default the env's)")
    view.set_defaults(func=cmd_view)

    bm = add("benchmark", "every controller of a suite on the same seeded episodes of every world: results.json + report.html")
    bm.add_argument("suite", nargs="?", default="quick", metavar="SUITE",
                    help="a shipped suite (quick, standard) or a suite YAML file (default quick)")
    bm.add_argument("--out", metavar="DIR", help="output directory (default runs/benchmark/<suite name>)")
    bm.add_argument("--workers", type=COUNT, default=1, help="local worker processes (default 1); rows are the same for any count")
    bm.add_argument("--address", metavar="HOST:PORT", help="run the episodes as tasks on this Ray cluster")
    bm.add_argument("--resume", action="store_true", help="go on with an interrupted run in DIR (finished episodes are kept)")
    bm.add_argument("--json", action="store_true", help="print the results record as JSON")
    bm.add_argument("--report-only", action="store_true", help="rebuild DIR/report.html from DIR/results.json, run nothing")
    bm.add_argument("--screenshots", action="store_true",
                    help="also save DIR/headline.png and DIR/world.png, the report in Chromium (needs playwright and chromium)")
    bm.add_argument("--screenshot-tab", type=NON_NEGATIVE, default=0, metavar="K", help="the world tab of world.png (default 0)")
    bm.set_defaults(func=cmd_benchmark)

    fl = add("fleet", "a fleet of robots running pick-and-drop errands: throughput, collisions, deadlocks")
    fl.add_argument("--robots", type=FLEET_ROBOTS, default=4, help="robots in the warehouse, 1 to 16 (default 4)")
    fl.add_argument("--controller", choices=["independent", "coordinated", "policy"], default="independent",
                    help="independent: PID + A* on each robot's lidar map; coordinated: windowed prioritized "
                         "space-time planning (WHCA*) tracked by PID; policy: a single-robot model on every robot "
                         "(default independent)")
    fl.add_argument("--model", default=None, metavar="PATH", type=_file_type((".zip",), "a model"),
                    help="policy: the model (default models/ppo_dynamic.zip); the fleet takes its env settings")
    fl.add_argument("--shield", action="store_true",
                    help="every robot behind the safety shield, the other robots shown to it as movers")
    fl.add_argument("--episodes", type=COUNT, default=1, help="episodes (default 1), episode k seeded SEED + k")
    fl.add_argument("--seed", type=SEED, default=0, help="first episode's seed (default 0)")
    fl.add_argument("--duration", type=_positive_seconds, default=180.0, metavar="S",
                    help="simulated seconds per episode (default 180)")
    fl.add_argument("--dynamic", action="store_true", help="add forklifts, walking workers and pallet events")
    _add_fleet_world_args(fl, "the fleet's aisle warehouse, WarehouseAisles-v0's settings")
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
    fl.add_argument("--frame-at", type=_non_negative_seconds, default=None, metavar="S",
                    help="simulated seconds into the episode of the --frame (default: half the --duration)")
    _add_overwrite_arg(fl, "--video, --plot, --frame and --record files")
    fl.set_defaults(func=cmd_fleet)

    ft = add("fleet-train", "fine-tune a single-robot model in the fleet: parameter-shared PPO, every robot one slot")
    ft.add_argument("--init-from", required=True, metavar="MODEL", type=_file_type((".zip",), "a model"),
                    help="the single-robot PPO model to start from (its weights, statistics and env settings)")
    ft.add_argument("--timesteps", type=COUNT, required=True, help="total agent steps (summed over the robots)")
    ft.add_argument("--seed", type=SEED, default=0, help="random seed of the run (default 0)")
    ft.add_argument("--out", required=True, metavar="DIR", help="run directory, e.g. runs/fleet_s1")
    ft.add_argument("--robots", type=FLEET_ROBOTS, default=4, help="robots per fleet, 1 to 16 (default 4)")
    ft.add_argument("--fleets", type=COUNT, default=1, help="fleets stepped in this process (default 1)")
    ft.add_argument("--dynamic", action="store_true", help="add forklifts, walking workers and pallet events")
    ft.add_argument("--duration", type=_positive_seconds, default=60.0, metavar="S",
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

    fc = add("fleet-compare", "every fleet controller, with and without the shield, on the same seeded episodes: "
                              "comparison.json + comparison.md")
    fc.add_argument("--robots", type=FLEET_ROBOTS, nargs="+", default=[4, 8], help="fleet sizes (default 4 8)")
    fc.add_argument("--controllers", nargs="+", metavar="SPEC",
                    default=["independent", "coordinated", "policy=models/ppo_dynamic.zip", "policy=models/ppo_fleet.zip"],
                    help="independent, coordinated or policy=MODEL.zip (default: the two classical ones, "
                         "the shipped single-robot policy zero-shot and the fleet-trained one)")
    fc.add_argument("--shield", choices=["off", "on", "both"], default="both",
                    help="each controller without the shield, with it, or both (default both)")
    fc.add_argument("--episodes", type=COUNT, default=40, help="episodes per controller and size (default 40)")
    fc.add_argument("--seed", type=SEED, default=1000, help="first episode's seed (default 1000)")
    fc.add_argument("--duration", type=_positive_seconds, default=120.0, metavar="S",
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

    mp = add("map", "bulletnav's lidar mapper (and A*) on a ROS 2 bag's LaserScan and Odometry (or TF)")
    mp.add_argument("bag", metavar="BAG.mcap", help="an MCAP file of ROS 2 messages (CDR)")
    mp.add_argument("--scan-topic", default="/scan", help="sensor_msgs/msg/LaserScan topic (default /scan)")
    mp.add_argument("--odom-topic", default="/odom",
                    help="nav_msgs/msg/Odometry topic (default /odom; without it the /tf chain to the scan's frame)")
    mp.add_argument("--resolution", type=_positive_seconds, default=0.1, metavar="M", help="cell size in m (default 0.1)")
    mp.add_argument("--out", type=PNG_FILE, default=None, metavar="PNG", help="write the map (and path) as a PNG")
    mp.add_argument("--plan-to", type=float, nargs=2, metavar=("X", "Y"), default=None,
                    help="plan an A* path on the map from the last scan's position to (X, Y) m")
    mp.add_argument("--json", action="store_true", help="print one JSON object")
    _add_overwrite_arg(mp, "an --out file")
    mp.set_defaults(func=cmd_map)

    rp = add("replay", "draw a recorded episode (a --record MCAP file) from the file alone: the live video and plot")
    rp.add_argument("recording", metavar="PATH.mcap", help="a recording written by --record")
    rp.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="write the episodes' video (.mp4 or .gif)")
    rp.add_argument("--plot", type=PNG_FILE, metavar="PNG", help="write every episode's path over its map")
    rp.add_argument("--frame", type=PNG_FILE, metavar="PNG", help="write one frame of the video (see --frame-at)")
    rp.add_argument("--frame-at", type=COUNT, default=None, metavar="N",
                    help="the video frame --frame writes (default: the middle one)")
    rp.add_argument("--panel", type=PNG_FILE, metavar="PNG",
                    help="draw what docs/foxglove_layout.json's 3D panel shows (top-down, from the messages) at --panel-at")
    rp.add_argument("--panel-at", type=_positive_seconds, default=None, metavar="S",
                    help="simulated seconds into the first episode for --panel (default: its middle)")
    rp.add_argument("--json", action="store_true", help="print one JSON object")
    _add_overwrite_arg(rp, "--video, --plot, --frame and --panel files")
    rp.set_defaults(func=cmd_replay)

    bench = add("bench", "benchmarks (print JSON with --json)")
    bench.add_argument("what", choices=["env", "physics", "planners", "gui", "shield", "fleet"],
                       help="env: env vs raw PyBullet loop; physics: solver settings and physics rates; planners: A* vs RRT; "
                            "gui: dashboard frame rate (needs a display: xvfb-run -a); shield: the safety "
                            "shield's decision time per step against the env step (default env WarehouseDynamic-v0); fleet: wall "
                            "time per control step at 1, 2, 4, 8, 16 robots, each on PID + A* (default 480 steps)")
    bench.add_argument("--episodes", type=COUNT, default=50, help="navigation episodes per planner (planners)")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    bench.add_argument("--steps", type=NON_NEGATIVE, default=0, help="steps to time (default: the benchmark's own)")
    bench.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")
    bench.add_argument("--env", dest="env_id", default=None, metavar="ID",
                       help="env: Warehouse-v0 against raw PyBullet, or WarehouseDynamic-v0 against "
                            "WarehouseAisles-v0 (default Warehouse-v0); shield: any env (default WarehouseDynamic-v0)")
    bench.add_argument("--resets", type=COUNT, default=200, help="env: resets timed per id (default 200)")
    bench.add_argument("--against", metavar="COMMIT",
                       help="env: the same reset and throughput measurements of COMMIT's code, interleaved with this "
                            "checkout's in one run (before/after)")
    bench.add_argument("--rounds", type=COUNT, default=3, help="env --against: rounds of both sides (default 3)")
    bench.add_argument("--vec", action="store_true",
                       help="env: vectorised steps/s at 1, 2 and 4 envs (make_vec sync/async, SB3 Dummy/SubprocVecEnv)")
    bench.add_argument("--driver", choices=["ram", "navigator", "policy"], default="ram",
                       help="shield: who drives, a forward-pushing random driver (default), PID + A*, or a trained "
                            "model (--model)")
    bench.add_argument("--model", default=None, metavar="PATH",
                       help="shield: the model --driver policy drives with; physics: the policy evaluated at each "
                            "physics rate (default models/ppo_warehouse.zip)")
    bench.add_argument("--rates", type=_hz_list, default=(240, 120, 96, 48), metavar="HZ,HZ,...",
                       help="physics: physics rates to compare at 24 Hz control, the first the reference "
                            "(default 240,120,96,48)")
    bench.add_argument("--policy-episodes", type=NON_NEGATIVE, default=200, metavar="N",
                       help="physics: the policy's episodes at each rate, seeds 1000000.. (default 200; 0 skips it)")
    bench.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        if getattr(args, "env_id", None) is not None:
            check_env_id(args.env_id)
        return int(args.func(args) or 0)
    except BulletnavError as exc:
        print(f"bulletnav {args.command}: error: {' '.join(str(exc).split())}", file=sys.stderr)  # one line
        return 2


if __name__ == "__main__":
    sys.exit(main())
