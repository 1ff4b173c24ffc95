"""A benchmark run beside another: a rerun of a suite against the results committed with it.

Episode ``k`` of a world is the same seeded episode in every run, so two runs of the same suite
can be compared row by row (how many episodes ended the same way, how many rows are identical,
every figure) as well as cell by cell (each cell's mean against the other run's 95 % interval).
``bulletnav benchmark SUITE --compare docs/benchmark/results.json`` prints it.
"""

from __future__ import annotations

import gzip
import json
import math
from pathlib import Path
from typing import Any

from bulletnav.errors import BulletnavError

MAX_BYTES = 1 << 30
"""The largest results file read (bytes, after decompressing a ``.gz``): the 4,500-episode BARN
run's is about 15 MB."""

METRICS = ("success", "collision", "timeout", "spl", "barn_score")
"""The cell figures compared, where both runs have them."""

OUTCOMES = ("success", "collision", "timeout")


def load_results(path: str | Path) -> dict[str, Any]:
    """The results record in ``path`` (a ``results.json`` a benchmark wrote, or it gzipped as
    ``.json.gz``, as the docs keep the big ones).

    Raises:
        BulletnavError: not a file, larger than :data:`MAX_BYTES`, not gzip or JSON, or not a
            benchmark's results (no ``cells`` and ``episodes`` lists).
    """
    p = Path(path)
    if not p.is_file():
        raise BulletnavError(f"{p}: no such results file (give a results.json a benchmark wrote, or a .json.gz of one)")
    try:
        with (gzip.open(p, "rb") if p.suffix == ".gz" else p.open("rb")) as f:
            data = f.read(MAX_BYTES + 1)
    except (OSError, EOFError) as exc:
        raise BulletnavError(f"{p}: cannot read it ({exc})") from None
    if len(data) > MAX_BYTES:
        raise BulletnavError(f"{p}: larger than {MAX_BYTES >> 20} MiB: not a benchmark's results")
    try:
        record = json.loads(data)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise BulletnavError(f"{p}: not JSON ({exc}); give a results.json a benchmark wrote") from None
    if not (isinstance(record, dict) and isinstance(record.get("cells"), list) and isinstance(record.get("episodes"), list)):
        raise BulletnavError(f"{p}: not a benchmark's results (no 'cells' and 'episodes' lists)")
    for i, cell in enumerate(record["cells"]):
        if not (isinstance(cell, dict) and isinstance(cell.get("world"), str) and isinstance(cell.get("controller"), str)
                and isinstance(cell.get("summary"), dict)):
            raise BulletnavError(f"{p}: cells[{i}] is not a results cell (world, controller and summary)")
        for name, figure in cell["summary"].items():
            if isinstance(figure, dict) and not all(v is None or (isinstance(v, (int, float)) and not isinstance(v, bool))
                                                    for k, v in figure.items() if k in ("mean", "lo", "hi")):
                raise BulletnavError(f"{p}: cells[{i}].summary.{name} has a mean or interval that is not a number")
    if not all(isinstance(r, dict) for r in record["episodes"]):
        raise BulletnavError(f"{p}: an entry of 'episodes' is not an episode row")
    commit = (record.get("provenance") or {}).get("git_commit") if isinstance(record.get("provenance"), dict) else None
    if commit is not None and not isinstance(commit, str):
        raise BulletnavError(f"{p}: provenance.git_commit is not a commit name")
    return record


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, float) and isinstance(b, float) and math.isnan(a) and math.isnan(b):
        return True
    return a == b


def compare_results(new: dict[str, Any], old: dict[str, Any]) -> dict[str, Any]:
    """``new`` beside ``old`` (two results records).

    Returns:
        ``cells``: for each (world, controller) cell in both, in ``new``'s order, each of
        :data:`METRICS` both have: ``new``, ``old``, ``old_lo``, ``old_hi`` (``old``'s 95 %
        interval) and ``inside`` (``new``'s mean within it); ``outside``: how many figures are
        not; ``only_new`` / ``only_old``: the cells one run lacks; ``episodes``: of the
        episodes in both (same world, controller, episode and seed), how many ended the same
        way (success, collision, time-out) and how many rows are identical in every field.
    """
    def cells(record: dict[str, Any]) -> dict[tuple[str, str], dict[str, Any]]:
        return {(c["world"], c["controller"]): c["summary"] for c in record["cells"]}

    mine, theirs = cells(new), cells(old)
    out_cells, outside = [], 0
    for key, summary in mine.items():
        if key not in theirs:
            continue
        figures = {}
        for m in METRICS:
            a, b = summary.get(m), theirs[key].get(m)
            if not (isinstance(a, dict) and isinstance(b, dict)) or a.get("mean") is None or b.get("mean") is None:
                continue
            lo, hi = b.get("lo", b["mean"]), b.get("hi", b["mean"])
            inside = bool(lo - 1e-9 <= a["mean"] <= hi + 1e-9)
            outside += not inside
            figures[m] = {"new": a["mean"], "old": b["mean"], "old_lo": lo, "old_hi": hi, "inside": inside}
        out_cells.append({"world": key[0], "controller": key[1], "metrics": figures})

    def rows(record: dict[str, Any]) -> dict[tuple, dict[str, Any]]:
        return {(r.get("world"), r.get("controller"), r.get("episode"), r.get("seed")): r for r in record["episodes"]}

    a_rows, b_rows = rows(new), rows(old)
    both = [k for k in a_rows if k in b_rows]
    same = sum(all(_same(a_rows[k].get(f), b_rows[k].get(f)) for f in OUTCOMES) for k in both)
    identical = sum(a_rows[k].keys() == b_rows[k].keys() and all(_same(v, b_rows[k][f]) for f, v in a_rows[k].items())
                    for k in both)
    return {
        "cells": out_cells,
        "outside": outside,
        "only_new": [list(k) for k in mine if k not in theirs],
        "only_old": [list(k) for k in theirs if k not in mine],
        "episodes": {"compared": len(both), "same_outcome": int(same), "identical": int(identical)},
        "old_commit": (old.get("provenance") or {}).get("git_commit"),
        "new_commit": (new.get("provenance") or {}).get("git_commit"),
    }


LABELS = {"success": "success", "collision": "collisions", "timeout": "time-outs", "spl": "SPL", "barn_score": "BARN score"}


def comparison_lines(comparison: dict[str, Any], old_path: str) -> list[str]:
    """The comparison as text: a summary line and a Markdown table, each figure as ``new``
    beside ``old [lo, hi]``, marked ``!`` where ``new`` is outside ``old``'s interval."""
    ep = comparison["episodes"]
    commit = comparison.get("old_commit") or "unknown commit"
    lines = [f"compared with {old_path} ({commit[:12]}): {len(comparison['cells']):,} cells in both, "
             f"{ep['compared']:,} episodes in both: {ep['same_outcome']:,} ended the same way, {ep['identical']:,} rows identical; "
             f"{comparison['outside']} figures outside the committed 95 % interval (marked !)"]
    for side, what in (("only_new", "only in this run"), ("only_old", "only in the committed results")):
        if comparison[side]:
            lines.append(f"cells {what}: " + ", ".join(f"{w} / {c}" for w, c in comparison[side]))
    shown = [m for m in METRICS if any(m in c["metrics"] for c in comparison["cells"])]
    if not shown:
        return lines
    lines.append("| world | controller | " + " | ".join(f"{LABELS[m]}: here / committed [95 %]" for m in shown) + " |")
    lines.append("|---|---|" + "---|" * len(shown))
    for c in comparison["cells"]:
        parts = []
        for m in shown:
            f = c["metrics"].get(m)
            parts.append("" if f is None else
                         f"{'! ' if not f['inside'] else ''}{f['new']:.3f} / {f['old']:.3f} [{f['old_lo']:.3f}, {f['old_hi']:.3f}]")
        lines.append(f"| {c['world']} | {c['controller']} | " + " | ".join(parts) + " |")
    return lines
