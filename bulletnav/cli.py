"""The ``bulletnav`` command: thin subcommands over the library. Only this module prints."""

from __future__ import annotations

import argparse
import json
import logging
import math
import sys
from collections.abc import Sequence

import numpy as np

from bulletnav.errors import BulletnavError


def _add_world_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--world", metavar="FILE", help="YAML layout (default: procedural warehouse)")
    parser.add_argument("--obstacles", type=int, default=31, metavar="K", help="obstacles in a procedural warehouse (default 31)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (default 0)")


def cmd_demo(args: argparse.Namespace) -> int:
    """Interim demo: build a warehouse, drive a scripted go-to-goal route, print sensor readings."""
    from bulletnav.config import SamplerConfig, WorldConfig
    from bulletnav.sim.layout import generate_warehouse, load_layout
    from bulletnav.sim.sampler import FreeSpace, sample_start_goal
    from bulletnav.sim.simulation import Simulation

    rng = np.random.default_rng(args.seed)
    layout = load_layout(args.world) if args.world else generate_warehouse(rng, WorldConfig(num_obstacles=args.obstacles))
    free = FreeSpace.build(layout, SamplerConfig())
    start, goal = sample_start_goal(free, rng, SamplerConfig())
    if layout.start is not None:
        start = layout.start
    if layout.goal is not None:
        goal = layout.goal
    sim = Simulation(gui=args.gui)
    try:
        sim.reset(layout, start, rng)
        print(f"warehouse {layout.name or 'procedural'}: {len(layout.obstacles)} obstacles on "
              f"{layout.size[0]:g} x {layout.size[1]:g} m (seed {args.seed})")
        print(f"start ({start[0]:.2f}, {start[1]:.2f}, {start[2]:.2f})  goal ({goal[0]:.2f}, {goal[1]:.2f})")
        print(f"{'t[s]':>5} {'x':>6} {'y':>6} {'yaw':>6} | {'odo x':>6} {'odo y':>6} | {'lidar min':>9} "
              f"{'ahead':>6} | {'gyro z':>6} {'acc x':>6} | {'depth c':>7}")
        for step in range(args.steps):
            x, y, yaw = sim.robot.pose()
            ranges = sim.sensors["lidar"].read()
            heading = math.remainder(math.atan2(goal[1] - y, goal[0] - x) - yaw, 2 * math.pi)
            # Scripted route: turn toward the goal; when something is close ahead, blend in a
            # turn toward the side with more room (the article's simple avoidance).
            ahead = float(min(ranges[0], ranges[1], ranges[-1]))
            safety = 0.9
            if ahead < safety:
                n = len(ranges)
                left, right = float(ranges[1 : n // 4].mean()), float(ranges[-(n // 4) :].mean())
                weight = 1.0 - ahead / safety
                heading = (1 - weight) * heading + weight * (math.pi / 2 if left >= right else -math.pi / 2)
            v = 0.0 if abs(heading) > 0.8 else 0.4 * min(1.0, max(0.05, (ahead - 0.25) / 0.75))
            w = float(np.clip(2.0 * heading, -1.5, 1.5))
            if step % args.print_every == 0:
                odo = sim.sensors["odometry"].read()
                imu = sim.sensors["imu"].read()
                depth = sim.sensors["camera"].read().depth
                print(f"{sim.clock.time:5.1f} {x:6.2f} {y:6.2f} {yaw:6.2f} | {odo[0]:6.2f} {odo[1]:6.2f} | "
                      f"{ranges.min():9.2f} {ahead:6.2f} | {imu[5]:6.2f} {imu[0]:6.2f} | {depth[120, 160]:7.2f}")
            if math.hypot(goal[0] - x, goal[1] - y) < 0.5:
                print(f"goal reached after {sim.clock.time:.1f} s")
                break
            if sim.in_collision():
                print(f"collision at t={sim.clock.time:.1f} s")
                break
            sim.step(v, w)
        else:
            print(f"stopped after {args.steps} steps, {math.hypot(goal[0] - x, goal[1] - y):.2f} m from the goal")
    finally:
        sim.close()
    return 0


def cmd_bench(args: argparse.Namespace) -> int:
    """Run a benchmark and print its JSON (``--json``) or a short table."""
    if args.what == "env":
        from bulletnav.bench.env_bench import bench_env

        result = bench_env(steps=args.steps or 6000, seed=args.seed)
        lines = [
            f"env  {result['env_steps_per_s']:8.1f} steps/s   (gym.make, random actions, headless, lidar obs)",
            f"raw  {result['raw_steps_per_s']:8.1f} steps/s   (same physics steps and ray casts, plain PyBullet)",
            f"ratio env/raw {result['ratio']:.3f} (median over {result['steps'] // result['block']} blocks), "
            f"overhead {result['env_overhead_us_per_step']:.1f} us/step, reset {result['reset_ms_mean']:.2f} ms",
        ]
    elif args.what == "physics":
        from bulletnav.bench.physics_bench import bench_physics

        result = bench_physics(steps=args.steps or 3000, seed=args.seed)
        lines = [f"{'setting':34s} {'us/step':>8s} {'speed':>6s} {'3 s dist':>8s} {'drift mm':>8s} {'yaw err %':>9s}"]
        for row in result["settings"]:
            lines.append(f"{row['setting']:34s} {row['us_per_physics_step']:8.1f} {row['speed_vs_pybullet_default']:6.2f} "
                         f"{row['straight_3s_distance_m']:8.4f} {row['max_sideways_drift_mm']:8.2f} {row['yaw_rate_error_pct']:9.2f}")
    else:  # pragma: no cover - argparse restricts the choices
        raise AssertionError(args.what)
    print(json.dumps(result) if args.json else "\n".join(lines))
    return 0


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="bulletnav", description=__doc__)
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True)

    demo = sub.add_parser("demo", help="build a warehouse and drive the robot, printing sensor readings")
    _add_world_args(demo)
    demo.add_argument("--steps", type=int, default=600, help="control steps at most (24 per second)")
    demo.add_argument("--print-every", type=int, default=48, help="print a reading every N steps")
    demo.add_argument("--gui", action="store_true", help="watch in the PyBullet GUI (needs a display)")
    demo.set_defaults(func=cmd_demo)

    bench = sub.add_parser("bench", help="benchmarks (print JSON with --json)")
    bench.add_argument("what", choices=["env", "physics"], help="env: env vs raw PyBullet loop; physics: solver settings")
    bench.add_argument("--json", action="store_true", help="print one JSON object")
    bench.add_argument("--steps", type=int, default=0, help="steps to time (default: the benchmark's own)")
    bench.add_argument("--seed", type=int, default=0)
    bench.set_defaults(func=cmd_bench)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    try:
        return int(args.func(args) or 0)
    except BulletnavError as exc:
        print(f"bulletnav {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
