"""``bulletnav bench WHAT``: the benchmarks, each a small function that returns its result record
and the lines of its table (:data:`BENCHES`); ``--json`` prints the record, with provenance."""

from __future__ import annotations

import argparse

from bulletnav.cli.args import COUNT, DEFAULT_ENV_ID, NON_NEGATIVE, SEED, add_command, hz_list
from bulletnav.cli.envs import check_env_id
from bulletnav.cli.output import print_json
from bulletnav.config import PHYSICS_PROFILES


def _env_against(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``env --against COMMIT``: resets and throughput of COMMIT's code and this checkout's, interleaved."""
    from bulletnav.bench.reset_bench import REGISTERED, bench_against

    result = bench_against(args.against, (args.env_id,) if args.env_id else REGISTERED, rounds=args.rounds or 3,
                           resets=args.resets, steps=args.steps or 6000, seed=args.seed)
    lines = [f"{'id':32s} {'reset ms before':>16s} {'after':>7s} {'steps/s with resets before':>27s} {'after':>8s} "
             f"{'speed-up':>9s} {'(CPU time)':>10s}"]
    lines += [f"{env_id:32s} {r['before']['reset_ms']:16.2f} {r['after']['reset_ms']:7.2f} "
              f"{r['before']['steps_per_s_with_resets']:27.1f} {r['after']['steps_per_s_with_resets']:8.1f} "
              f"{r['speedup']['steps_per_s_with_resets']:8.3f}x {r['speedup']['cpu_steps_per_s_with_resets']:9.3f}x"
              for env_id, r in result["ids"].items()]
    return result, lines


def _env_vec(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``env --vec``: vectorised steps/s at 1, 2 and 4 envs."""
    from bulletnav.bench.reset_bench import bench_vec

    result = bench_vec(env_id=args.env_id or DEFAULT_ENV_ID, steps=args.steps or 1000, seed=args.seed)
    kinds = ("sync", "async", "sb3_dummy", "sb3_subproc")
    lines = [f"{result['env_id']}: env steps/s, {result['vector_steps']} vector steps each, resets included",
             f"{'envs':>5s} " + " ".join(f"{k:>12s}" for k in kinds)]
    lines += [f"{row['num_envs']:5d} " + " ".join(f"{row[f'{k}_steps_per_s']:12.1f}" for k in kinds)
              for row in result["rows"]]
    return result, lines


def _env_step_lines(result: dict) -> list[str]:
    """The step-cost lines of :func:`bulletnav.bench.env_bench.bench_env`'s record (none for resets only)."""
    if result["benchmark"] == "env_resets":
        return []
    if result["benchmark"] == "env_pair":
        return [
            f"{result['env_id']:32s} {result['env_steps_per_s']:8.1f} steps/s  (reset {result['reset_ms_mean']:.1f} ms)",
            f"{result['reference_id']:32s} {result['reference_steps_per_s']:8.1f} steps/s  "
            f"(reset {result['reference_reset_ms_mean']:.1f} ms)",
            f"step cost ratio {result['cost_ratio']:.3f} (median over {result['steps'] // result['block']} blocks; "
            f"target <= 1.3)",
        ]
    return [
        f"env  {result['env_steps_per_s']:8.1f} steps/s   (gym.make, random actions, headless, lidar obs)",
        f"raw  {result['raw_steps_per_s']:8.1f} steps/s   (same physics, rays and state queries, plain PyBullet)",
        f"lean {result['physics_and_rays_steps_per_s']:8.1f} steps/s   (physics and rays only; "
        f"ratio {result['ratio_physics_and_rays']:.3f})",
        f"ratio env/raw {result['ratio']:.3f} (median over {result['steps'] // result['block']} blocks; "
        f"regression guard >= {result['ratio_guard']}), overhead {result['env_overhead_us_per_step']:.1f} us/step",
    ]


def _env_profile(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``env --physics NAME``: steps/s of the profile against the default profile, resets included."""
    from bulletnav.bench.env_bench import bench_profile

    env_id = args.env_id or DEFAULT_ENV_ID
    check_env_id(env_id)
    kinematic = args.physics == "kinematic"
    r = bench_profile(args.physics, env_id=env_id, steps=args.steps or 6000, seed=args.seed, parts=kinematic)
    lines = [f"{env_id}: steps/s with resets (gym.make, random actions, episodes ended by the env), median of "
             f"{r['steps'] // r['block']} blocks of {r['block']}",
             f"  physics={r['physics']:10s} {r['steps_per_s']:10.1f} steps/s  ({r['episodes']} episodes)",
             f"  physics={r['reference']:10s} {r['reference_steps_per_s']:10.1f} steps/s  ({r['reference_episodes']} episodes)",
             f"  ratio {r['ratio']:.2f}"]
    if kinematic:
        q = r["parts"]
        lines.append(f"  one kinematic step, us: {q['us_per_step']} = resets {q['resets_us']} + drive and contacts "
                     f"{q['sim_us']} + lidar {q['lidar_us']} + the rest {q['rest_us']} (task, observation, info, "
                     "sensor noise, wrappers)")
    return r, lines


def _env(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``env``: the env's step cost against raw PyBullet (or its reference id), then resets per id;
    ``--against`` and ``--vec`` pick the other env benchmarks."""
    if args.against:
        return _env_against(args)
    if args.vec:
        return _env_vec(args)
    if args.physics is not None:
        return _env_profile(args)
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
    lines = _env_step_lines(result)
    lines.append(f"{'id':32s} {'reset ms':>9s} {'raw ms':>7s} {'steps/s with resets':>20s} {'in reset':>9s}")
    lines += [f"{env_id:32s} {r['reset_ms']:9.2f} {r['raw_reset_ms']:7.2f} {r['steps_per_s_with_resets']:20.1f} "
              f"{r['reset_share'] * 100:8.1f}%" for env_id, r in result["ids"].items()]
    lines += [f"{env_id}: reset ms are seeded resets of world {r['world_idx']} (each rebuilds it: {r['bodies_per_world']} "
              f"bodies); unseeded on the same world {r['unseeded_reset_ms']:.2f} ms, switching world "
              f"{r['switch_reset_ms']:.2f} ms; bare PyBullet's batched cylinders alone {r['raw_cylinders_ms']:.2f} ms"
              for env_id, r in result["ids"].items() if "unseeded_reset_ms" in r]
    return result, lines


def _rate_line(row: dict) -> str:
    """One physics rate's row of ``physics``'s second table."""
    pol = row.get("policy")
    t = row["tunnelling"]
    return (f"{row['physics_hz']:4d} {row['ms_per_env_step']:8.3f} {row['speedup_vs_reference']:6.2f} "
            f"{row['straight_error_pct']:10.3f} {row['turn_error_pct']:7.3f} "
            f"{max(row['arc_heading_error_pct'], row['arc_endpoint_error_pct']):6.3f} "
            f"{row['wheel_slip_pct']:7.3f} {'hit' if t['collision_registered'] else 'MISSED':>6s} "
            f"{t['penetration_at_report_mm']:6.2f} "
            + (f"{pol['success_rate'] * 100:7.1f}% {pol['collision_rate'] * 100:5.1f}% " if pol else
               f"{'-':>8s} {'-':>6s} ")
            + f"{'-' if row['qualifies'] is None else ('yes' if row['qualifies'] else 'no'):>9s}")


def _physics(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``physics``: solver settings, then physics rates against the reference rate."""
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
    lines += [_rate_line(row) for row in rates["rows"]]
    lines.append(f"qualifying as a fast profile: {', '.join(f'{hz} Hz' for hz in rates['qualifying_hz']) or 'none'}")
    return result, lines


def _planners(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``planners``: A* against RRT, standard problems and navigation episodes."""
    from bulletnav.bench.planner_bench import bench_navigation

    result = bench_navigation(episodes=args.episodes or 50, seed=args.seed or 1000)
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
    return result, lines


def _gui(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``gui``: the dashboard's frame rate with the A* navigator driving (needs a display)."""
    from bulletnav.bench.gui_bench import bench_gui

    result = bench_gui(steps=args.steps or 100, seed=args.seed)
    lines = [f"GUI frames per second with the A* navigator driving (median of {result['repeats']} x "
             f"{result['steps']} steps, real-time pacing off, DISPLAY={result['display']}):",
             f"  throttled dashboard    {result['fps_throttled']:6.2f}",
             f"  unthrottled dashboard  {result['fps_unthrottled']:6.2f}",
             f"  no dashboard           {result['fps_no_dashboard']:6.2f}"]
    return result, lines


def _shield(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``shield``: the safety shield's decision time per step against the env step."""
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
    return result, lines


def _fleet(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``fleet``: wall time per control step at 1 to 16 robots."""
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
    return result, lines


def _live(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``live``: what ``--live`` costs an unpaced navigate run, without and with a client."""
    from bulletnav.bench.live_bench import bench_live

    result = bench_live(episodes=args.episodes or 4, rounds=args.rounds or 5, seed=args.seed)
    sps = result["steps_per_s_median"]
    c = result["client"]
    lines = [f"--live's cost: {result['rounds']} rounds x {result['episodes']} navigate episodes (PID + A*, {result['env_id']}, "
             f"seed {result['seed']}, unpaced), the three variants interleaved; ratios: median over rounds of wall time / "
             f"the no-stream run's",
             f"  no stream                {sps['no_stream']:8.1f} steps/s",
             f"  live, no client          {sps['live_no_client']:8.1f} steps/s   ratio {result['ratio_live_no_client']:.3f} "
             f"(target <= 1.05: {'met' if result['meets_target'] else 'NOT met'}); CPU ratio {result['cpu_ratio_live_no_client']:.3f}",
             f"  live, one client (all)   {sps['live_one_client']:8.1f} steps/s   ratio {result['ratio_live_one_client']:.3f} "
             f"({c['frames']} frames, {c['bytes'] / 1e6:.1f} MB to the client on {c['channels']} channels); "
             f"CPU ratio {result['cpu_ratio_live_one_client']:.3f} (the run's process; the client's is apart)"]
    return result, lines


def _kinematic(args: argparse.Namespace) -> tuple[dict, list[str]]:
    """``kinematic``: the kinematic profile beside full physics (scans, manoeuvres, contacts, outcomes)."""
    from pathlib import Path

    from bulletnav.bench.kinematic_bench import bench_kinematic

    out = Path(args.out or "runs/bench-kinematic-pair")
    result = bench_kinematic(out, seeds=range(args.seed, args.seed + (args.episodes or 20)), workers=args.workers)
    lines = ["scans (same seeded reset, noise off): source, rays, share within 1 cm, p99 and largest difference (m)"]
    lines += [f"  {r['source']:11s} {r['rays']:7d} {r['within_1cm']:8.4f} {r['p99_m']:8.4f} {r['max_m']:8.4f}"
              for r in result["scans"]]
    def pct(value: float | None) -> str:
        return "-" if value is None else f"{value:.2f} %"

    lines.append("manoeuvres: end point error against full physics, m (% of the distance), heading error rad "
                 "(% of the turn): fast | kinematic")
    lines += [f"  {r['robot']:8s} {r['manoeuvre']:16s} "
              + " | ".join(f"{r[k]['end_error_m']:.4f} ({pct(r[k]['end_error_pct'])}) {r[k]['heading_error_rad']:.4f} "
                           f"({pct(r[k]['heading_error_pct'])})" for k in ("fast", "kinematic"))
              for r in result["manoeuvres"]]
    lines.append("contacts: first contact step default / fast / kinematic; nose past the face (m), kinematic")
    lines += [f"  {r['target']:14s} {r['default']['first_contact_step']} / {r['fast']['first_contact_step']} / "
              f"{r['kinematic']['first_contact_step']}; {r['kinematic']['nose_past_face_m']:+.4f}" for r in result["contacts"]]
    o = result["outcomes"]
    lines.append(f"outcomes ({o['suite']}, rows in {o['out']}): success and collisions default -> kinematic, same outcome")
    lines += [f"  {p['world']:10s} {p['controller']:9s} {100 * p['default']['success']:5.1f} % -> "
              f"{100 * p['kinematic']['success']:5.1f} %, {100 * p['default']['collision']:5.1f} % -> "
              f"{100 * p['kinematic']['collision']:5.1f} %, same {100 * p['same_outcome']:5.1f} %" for p in o["pairs"]]
    lines.append(f"  same outcome overall: {100 * o['same_outcome_overall']:.1f} %")
    return result, lines


BENCHES = {"env": _env, "physics": _physics, "planners": _planners, "gui": _gui, "shield": _shield, "fleet": _fleet,
           "live": _live, "kinematic": _kinematic}
"""``bench WHAT``'s benchmarks, in the order ``--help`` lists them: each returns ``(record, table lines)``."""


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark and print its JSON (``--json``) or a short table."""
    from bulletnav.provenance import provenance

    result, lines = BENCHES[args.what](args)
    result = {**result, **provenance()}
    if args.json:
        print_json(result)
    else:
        print("\n".join(lines))
    return 0


def register(sub) -> None:
    """Add ``bench`` to ``sub`` (``build_parser``'s subparsers)."""
    bench = add_command(sub, "bench", "benchmarks (print JSON with --json)")
    bench.add_argument("what", choices=list(BENCHES),
                       help="env: env vs raw PyBullet loop; physics: solver settings and physics rates; planners: A* vs RRT; "
                            "gui: dashboard frame rate (needs a display: xvfb-run -a); shield: the safety "
                            "shield's decision time per step against the env step (default env WarehouseDynamic-v0); fleet: wall "
                            "time per control step at 1, 2, 4, 8, 16 robots, each on PID + A* (default 480 steps); "
                            "live: what --live costs an unpaced navigate run, with no client and with one subscribed to "
                            "everything (--episodes per round, default 4; --rounds, default 5); kinematic: the kinematic "
                            "profile beside full physics, scans, manoeuvres, contacts and the kinematic-pair suite's "
                            "outcomes (docs/performance/kinematic.md)")
    bench.add_argument("--episodes", type=COUNT, default=None,
                       help="navigation episodes per planner (planners, default 50); per variant and round (live, "
                            "default 4); seeded resets per world source whose scans are compared (kinematic, default 20)")
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
    bench.add_argument("--rounds", type=COUNT, default=None,
                       help="env --against: rounds of both sides (default 3); live: rounds of the three variants (default 5)")
    bench.add_argument("--physics", choices=list(PHYSICS_PROFILES), default=None,
                       help="env: steps/s of this physics profile (resets included) beside the default profile's in "
                            "the same run (their ratio)")
    bench.add_argument("--vec", action="store_true",
                       help="env: vectorised steps/s at 1, 2 and 4 envs (make_vec sync/async, SB3 Dummy/SubprocVecEnv)")
    bench.add_argument("--driver", choices=["ram", "navigator", "policy"], default="ram",
                       help="shield: who drives, a forward-pushing random driver (default), PID + A*, or a trained "
                            "model (--model)")
    bench.add_argument("--model", default=None, metavar="PATH",
                       help="shield: the model --driver policy drives with; physics: the policy evaluated at each "
                            "physics rate (default models/ppo_warehouse.zip)")
    bench.add_argument("--rates", type=hz_list, default=(240, 120, 96, 48), metavar="HZ,HZ,...",
                       help="physics: physics rates to compare at 24 Hz control, the first the reference "
                            "(default 240,120,96,48)")
    bench.add_argument("--policy-episodes", type=NON_NEGATIVE, default=200, metavar="N",
                       help="physics: the policy's episodes at each rate, seeds 1000000.. (default 200; 0 skips it)")
    bench.add_argument("--out", default=None, metavar="DIR",
                       help="kinematic: the folder of the kinematic-pair suite's rows, resumed when it holds some "
                            "(default runs/bench-kinematic-pair)")
    bench.add_argument("--workers", type=COUNT, default=1, help="kinematic: worker processes of the suite run (default 1)")
    bench.set_defaults(func=cmd_bench)
