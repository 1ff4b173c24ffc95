"""``bulletnav benchmark``: every controller of a suite on the same seeded episodes of every world."""

from __future__ import annotations

import argparse
import json
import sys

from bulletnav.cli import interrupts
from bulletnav.cli.args import COUNT, NON_NEGATIVE, add_command
from bulletnav.cli.output import EpisodeBar, print_json
from bulletnav.errors import BulletnavError


def register(sub) -> None:
    """Add ``benchmark`` to ``sub`` (``build_parser``'s subparsers)."""
    bm = add_command(sub, "benchmark", "every controller of a suite on the same seeded episodes of every world: "
                                       "results.json + report.html")
    bm.add_argument("suite", nargs="?", default="quick", metavar="SUITE",
                    help="a shipped suite (quick, standard, barn, barn-quick, barn-heldout, shield-random) or a suite YAML file "
                         "(default quick)")
    bm.add_argument("--out", metavar="DIR", help="output directory (default runs/benchmark/<suite name>)")
    bm.add_argument("--workers", type=COUNT, default=1, help="local worker processes (default 1); rows are the same for any count")
    bm.add_argument("--address", metavar="HOST:PORT", help="run the episodes as tasks on this Ray cluster")
    bm.add_argument("--resume", action="store_true", help="go on with an interrupted run in DIR (finished episodes are kept)")
    bm.add_argument("--force", action="store_true",
                    help="start afresh in a DIR that holds an earlier run or results (they are replaced); without it "
                         "such a DIR is refused")
    bm.add_argument("--compare", metavar="RESULTS",
                    help="print this run's figures beside another run's results (a results.json, or .json.gz, such as the "
                         "committed docs/benchmark/results.json): episodes that ended the same way, rows identical, each "
                         "cell's figures against that run's 95 %% intervals")
    bm.add_argument("--controllers", nargs="+", metavar="NAME",
                    help="run only these of the suite's controllers this time (names as in the suite); the others' "
                         "episodes are left for a later --resume")
    bm.add_argument("--json", action="store_true", help="print the results record as JSON")
    bm.add_argument("--report-only", action="store_true", help="rebuild DIR/report.html from DIR/results.json, run nothing")
    bm.add_argument("--screenshots", action="store_true",
                    help="also save the report as Chromium shows it: DIR/headline.png and DIR/world.png at 1280 px, "
                         "DIR/report_1400.png and DIR/report_390.png (the headline at 1400 and 390 px); needs playwright "
                         "and chromium")
    bm.add_argument("--screenshot-tab", type=NON_NEGATIVE, default=0, metavar="K", help="the world tab of world.png (default 0)")
    bm.add_argument("--trust-code", action="store_true",
                    help="import and run the module named by a suite's class: entries (it runs that module's code)")
    bm.set_defaults(func=cmd_benchmark)


def cmd_benchmark(args: argparse.Namespace) -> int:
    """Every controller of a suite on the same seeded episodes of every world: results.json + report.html."""
    from pathlib import Path

    from bulletnav.benchmark.compare import load_results
    from bulletnav.benchmark.suite import load_suite

    suite = load_suite(args.suite, trust_code=args.trust_code)
    out = Path(args.out) if args.out else suite.out_dir("runs/benchmark")
    other = load_results(args.compare) if args.compare else None  # a bad file is refused before anything runs
    if args.report_only:  # the report (and screenshots) again from DIR/results.json
        return _report_only(args, out, other)
    earlier: list[int] = []  # the episodes an earlier run had finished (the progress's first count)
    results, report = _run(args, suite, out, earlier)
    if args.json:
        print_json(_with_comparison(results, other))
    else:
        _print_table(args, suite, results, out, report, earlier[0] if earlier else 0)
        _print_comparison(args, results, other)
    _screenshots(args, report, out)
    return 0


def _with_comparison(results: dict, other: dict | None) -> dict:
    """``results`` with ``comparison`` (:func:`~bulletnav.benchmark.compare.compare_results`) when
    ``--compare`` gave another run (only printed: results.json stays the run's own)."""
    from bulletnav.benchmark.compare import compare_results

    return results if other is None else {**results, "comparison": compare_results(results, other)}


def _print_comparison(args: argparse.Namespace, results: dict, other: dict | None) -> None:
    from bulletnav.benchmark.compare import compare_results, comparison_lines

    if other is not None:
        print("\n" + "\n".join(comparison_lines(compare_results(results, other), args.compare)))


def _report_only(args: argparse.Namespace, out, other: dict | None = None) -> int:
    from bulletnav.benchmark.report import write_report
    from bulletnav.viz.plots import draw_layout

    results_file = out / "results.json"
    if not results_file.is_file():
        raise BulletnavError(f"{results_file}: no results to report (run the suite first)")
    results = json.loads(results_file.read_text())
    report = write_report(results, out / "report.html", draw_layout)
    if args.json:
        print_json(_with_comparison(results, other))
    else:
        print(f"report:  {report}")
        _print_comparison(args, results, other)
    _screenshots(args, report, out)
    return 0


def _screenshots(args: argparse.Namespace, report, out) -> None:
    """``--screenshots``: the report in Chromium; their paths on stdout (on stderr with ``--json``)."""
    from bulletnav.benchmark.report import screenshots

    for shot in (screenshots(report, out, tab=args.screenshot_tab) if args.screenshots else []):
        print(f"screenshot: {shot}", file=sys.stderr if args.json else sys.stdout)


def interrupted_note(log, total: int, what: str = "episodes") -> str:
    """The line of an interrupted run that keeps its rows in ``log`` (an ``episodes.jsonl``; a
    ``benchmark`` or ``fleet-compare``): how many of ``total`` are kept and the command that goes on."""
    from bulletnav.runs import read_rows

    if not log.is_file():
        return (f"interrupted before the first of {total} {what} finished; nothing kept; run again with: "
                f"{interrupts.rerun_command()}")
    kept = len(read_rows(log))
    return (f"interrupted after {kept} of {total} {what}; rows kept in {log}; continue with: "
            f"{interrupts.continue_command()}")


def _run(args: argparse.Namespace, suite, out, earlier: list[int]):
    """Run the suite (a progress bar on stderr, none with ``--json``); ``(results, report path)``.
    ``earlier`` gets the number of episodes an earlier run had finished."""
    from bulletnav.benchmark.report import write_report
    from bulletnav.benchmark.runner import run_suite
    from bulletnav.viz.plots import draw_layout

    interrupts.on_interrupt(lambda: interrupted_note(out / "episodes.jsonl", suite.total))
    with EpisodeBar(f"benchmark {suite.name}", show=not args.json) as bar:

        def progress(done: int, total: int) -> None:
            if not earlier:
                earlier.append(done)
            bar.update(done, total)

        results = run_suite(suite, out, workers=args.workers, address=args.address, resume=args.resume, progress=progress,
                            controllers=args.controllers, force=args.force)
    return results, write_report(results, out / "report.html", draw_layout)


def _print_table(args: argparse.Namespace, suite, results: dict, out, report, earlier: int = 0) -> None:
    from bulletnav.benchmark.report import best_controllers

    controllers = [c["name"] for c in results["suite"]["controllers"]]
    cells = {(c["world"], c["controller"]): c["summary"] for c in results["cells"]}
    best = best_controllers(results)
    wall, workers = results["provenance"]["wall_time_s"], results["provenance"]["workers"]
    timing = (f"{suite.total} episodes ({earlier} from the earlier run), {wall:.0f} s this run" if earlier
              else f"{suite.total} episodes in {wall:.0f} s")
    worlds = [w for w in results["suite"]["worlds"] if not w.get("group")]
    print(f"\nbenchmark {suite.name}: {timing} ({workers} workers)" +
          ("; success / collisions / SPL per world and controller" if worlds else ""))
    for section in results.get("barn", []):
        _print_barn(section)
    if not worlds:
        print(f"results: {out / 'results.json'}\nreport:  {report}")
        return
    print("| world | " + " | ".join(controllers) + " |")
    print("|---" * (len(controllers) + 1) + "|")
    for w in worlds:
        row = []
        for c in controllers:
            s = cells[(w["name"], c)]
            if not s["episodes"]:  # a controller left out with --controllers
                row.append("-")
                continue
            mark = " **best**" if best.get(w["name"]) == c else ""
            row.append(f"{s['success']['mean'] * 100:.1f} % / {s['collision']['mean'] * 100:.1f} % / "
                       f"{s['spl']['mean']:.3f}{mark}")
        print(f"| {w['name']} | " + " | ".join(row) + " |")
    print(f"results: {out / 'results.json'}\nreport:  {report}")


def _print_barn(section: dict) -> None:
    """A BARN group's overall table (report_test.py's figures with their intervals) and lines."""
    def fig(cell: dict, pct: bool) -> str:
        if cell["mean"] is None:
            return "-"
        scale, digits, unit = (100, 1, " %") if pct else (1, 3, "")
        if cell["lo"] is None:  # a published summary: no interval
            return f"{cell['mean'] * scale:.{digits}f}{unit}"
        return (f"{cell['mean'] * scale:.{digits}f}{unit} [{cell['lo'] * scale:.{digits}f}, "
                f"{cell['hi'] * scale:.{digits}f}]")

    print(f"\nBARN {section['group']}: {len(section['worlds'])} worlds x {section['runs']} runs, as BARN's report_test.py "
          "summarises (means over worlds of per-world means; 95 % intervals)")
    print("| controller | worlds | success | collisions | time-outs | BARN time (s) | BARN metric |")
    print("|---|---|---|---|---|---|---|")
    for e in section["controllers"]:
        o = e["overall"]
        name = f"{e['name']} (published: {e['note']})" if e["source"] == "published" else e["name"]
        print(f"| {name} | {o['worlds']} | {fig(o['success'], True)} | {fig(o['collision'], True)} | "
              f"{fig(o['timeout'], True)} | {fig(o['time_s'], False)} | {fig(o['metric'], False)} |")
    print(f"BARN metric: {section['metric']}")
    for e in section["controllers"]:
        print(f"{e['name']}: {e['overall']['line'] or 'no runs'}")
        a = e.get("agreement")
        if a:
            ratio = "-" if a["time_ratio"] is None else f"{a['time_ratio']:.2f}"
            print(f"  against {a['with']}: success {a['success_points']:+.1f} points, time ratio {ratio}, success within "
                  f"0.3 in {a['worlds_within']} of {a['worlds']} worlds (need {a['worlds_needed']}): "
                  f"{'agrees' if a['agrees'] else 'does not agree'}")
    print(f"DWA over all 50 test worlds: {section['dwa_all_line']}")
