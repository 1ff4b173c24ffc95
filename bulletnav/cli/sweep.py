"""``bulletnav sweep``: a sweep file's training trials on Ray Tune, locally or on a cluster."""

from __future__ import annotations

import argparse
import sys

from bulletnav.cli import interrupts
from bulletnav.cli.args import COUNT, add_command
from bulletnav.cli.output import print_json


def register(sub) -> None:
    """Add ``sweep`` to ``sub`` (``build_parser``'s subparsers)."""
    sw = add_command(sub, "sweep", "train a sweep file's trials (grid x seeds, or --optimize N) on Ray Tune, locally or on a cluster")
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


def cmd_sweep(args: argparse.Namespace) -> int:
    from pathlib import Path

    from bulletnav.provenance import command_line
    from bulletnav.sweep.run import SweepOptions, run_sweep
    from bulletnav.sweep.spec import SweepSpec

    spec = SweepSpec.from_file(args.file)
    opts = SweepOptions(out=Path(args.out), address=args.address, storage=args.storage, resume=args.resume,
                        optimize=args.optimize, num_cpus=args.num_cpus, command=command_line())
    experiment = f"{(args.storage or str(Path(args.out).resolve())).rstrip('/')}/{spec.name}"
    # a second Ctrl-C, while Ray Tune was saving its state, or a SIGTERM: the trials' own checkpoints are kept
    interrupts.on_interrupt(lambda: f"interrupted; finished trials and checkpoints kept in {experiment}; "
                                    f"continue with: {interrupts.continue_command()}")
    interrupts.library_handles_signals()  # Ray Tune takes Ctrl-C itself: its first one saves and ends the sweep
    record = run_sweep(spec, opts)
    if args.json:
        print_json(record)
    else:
        _print_tables(spec, record)
    if record["interrupted"]:  # Ray Tune ends fit() quietly on the first Ctrl-C
        unfinished = record["interrupted"]
        print(f"bulletnav sweep: interrupted with {unfinished} of {len(record['trials'])} trials unfinished; "
              f"finished trials and checkpoints kept in {record['experiment']}; continue with: "
              f"{interrupts.continue_command()}", file=sys.stderr)
        return interrupts.EXIT_INTERRUPTED  # Ray Tune took the Ctrl-C itself
    return 0


def _print_tables(spec, record: dict) -> None:
    from bulletnav.sweep.results import config_label

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
