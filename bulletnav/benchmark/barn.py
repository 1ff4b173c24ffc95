"""A benchmark's BARN worlds summarised as BARN does, beside BARN's published DWA rows.

The worlds of a suite's ``barn_worlds`` entry (one per BARN index, :mod:`bulletnav.benchmark.suite`)
form a group. For each controller of the suite, and for BARN's own move_base DWA rows
(``res/dwa_out.txt``, :func:`bulletnav.barn.data.dwa_rows`: measured by BARN in Gazebo, not run
here) over the same worlds, the group's section of ``results.json`` holds:

- per BARN world: the success, collision and time-out rates, BARN time (the mean clock of the
  successful runs) and BARN metric (mean over the runs), each with a 95 % percentile-bootstrap
  interval over the world's runs (:func:`bulletnav.benchmark.metrics.bootstrap_interval`, the
  benchmark's interval of every cell);
- overall: the five figures of BARN's ``report_test.py`` (:func:`bulletnav.barn.metric.summarise`:
  means over worlds of per-world means; the time over worlds with a success), each with a 95 %
  percentile bootstrap that resamples the runs within every world (the worlds stay the same,
  as BARN's test worlds do), and the summary line as report_test.py prints it.

Every metric here is report_test.py's: success x t_opt / clip(t, 2 t_opt, 8 t_opt) of the run's
BARN clock t, t_opt measured from report_test.py's start (-2, 3) (:data:`~bulletnav.barn.metric.REPORT_START`),
so the controllers' figures and DWA's are computed alike. (A row's own ``barn_metric``, the
env's, measures t_opt from run.py's start (-2.25, 3); the two differ by under 2 %.)
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.barn.metric import REPORT_START, OutRow, barn_metric, by_world, optimal_time, summarise
from bulletnav.benchmark.metrics import BOOTSTRAP_RESAMPLES, BOOTSTRAP_SEED, bootstrap_interval

DWA_NAME = "DWA (BARN's rows)"
"""The name of the DWA row (:data:`bulletnav.barn.data.PUBLISHED`'s first)."""
DWA_NOTE = "measured by BARN in Gazebo (move_base DWA), not run here"
"""What the DWA row is, printed wherever it is shown."""
AGREEMENT = {"success_points": 10.0, "time_ratio": 0.3, "world_success": 0.3, "worlds": 35}
"""How close a bulletnav controller must come to a published one to agree with it: overall
success within 10 points, mean time of successes within 30 %, per-world success within 0.3 in at
least 35 worlds (of BARN's 50 test worlds; scaled to the worlds both ran)."""
FIGURES = ("success", "collision", "timeout", "time_s", "metric")
"""The figures per world and overall, in report_test.py's terms."""
INTERVALS = ("95 % percentile bootstrap (2,000 resamples, fixed seed): per world over its runs; overall over "
             "the runs resampled within each world, the worlds kept")
"""How the intervals are made (the report prints it)."""


METRIC_LABEL = ("success x t_opt / clip(t, 2 t_opt, 8 t_opt), t = BARN's clock, t_opt from report_test.py's start "
                "(-2, 3) (bulletnav.barn.metric, BARN's run.py and report_test.py). Not the episode rows' own "
                "barn_metric (episodes.jsonl, results.json's episodes): that is the env's, t_opt from run.py's start "
                "(-2.25, 3), under 2 % apart")
"""The BARN tables' metric, as the report and the CLI label it: which t_opt, and which figure it is not."""


@functools.lru_cache(maxsize=1)
def report_t_opt() -> dict[int, float]:
    """t_opt (s) of every BARN world as report_test.py computes it (from :data:`REPORT_START`)."""
    from bulletnav.barn.data import N_WORLDS, load_world

    return {i: optimal_time(load_world(i).path_cells, REPORT_START) for i in range(N_WORLDS)}


def out_rows(rows: Iterable[dict[str, Any]]) -> list[OutRow]:
    """Benchmark rows of ``bulletnav/BARN-v0`` episodes as BARN out-file rows (BARN's clock as the time)."""
    return [OutRow(int(r["world_idx"]), bool(r["success"]), bool(r["collision"]), bool(r["timeout"]),
                   float(r["barn_time_s"])) for r in rows]


def episode_figures(results: Iterable[Any]) -> dict[str, Any] | None:
    """BARN's figures of ``navigate`` / ``evaluate`` episodes (:class:`~bulletnav.evaluation.EpisodeResult`
    with ``barn_info``), by the code the benchmark's BARN tables use (:func:`out_rows`,
    :func:`report_t_opt`, :func:`~bulletnav.barn.metric.summarise`): per episode the BARN world,
    clock, t_opt and metric; in total report_test.py's five figures and its line, and the
    metric's definition. None when no episode is a BARN one."""
    rows = [{"world_idx": r.barn_info["world_idx"], "success": r.success, "collision": r.collision,
             "timeout": r.timeout, "barn_time_s": r.barn_info["barn_time_s"]} for r in results if r.barn_info]
    if not rows:
        return None
    t_opt = report_t_opt()
    runs = out_rows(rows)
    per = [{"world_idx": row["world_idx"], "barn_time_s": run.time_s, "t_opt_s": t_opt[row["world_idx"]],
            "barn_metric": barn_metric(run.success, run.time_s, t_opt[row["world_idx"]])} for row, run in zip(rows, runs)]
    total = summarise(runs, t_opt)
    return {"per_episode": per,
            "summary": {"success": total.success, "collision": total.collision, "timeout": total.timeout,
                        "time_s": total.time_s, "metric": total.metric, "line": total.line()},
            "metric": METRIC_LABEL}


def _by_world(rows: Iterable[OutRow]) -> dict[int, list[OutRow]]:
    return dict(sorted(by_world(rows).items()))


def _values(runs: list[OutRow], t_opt: float) -> dict[str, np.ndarray]:
    """Per run: each figure's value (the time NaN for a run that did not succeed)."""
    return {"success": np.array([r.success for r in runs], dtype=float),
            "collision": np.array([r.collided for r in runs], dtype=float),
            "timeout": np.array([r.timeout for r in runs], dtype=float),
            "time_s": np.array([r.time_s if r.success else math.nan for r in runs], dtype=float),
            "metric": np.array([barn_metric(r.success, r.time_s, t_opt) for r in runs], dtype=float)}


def _stat(values: np.ndarray) -> dict[str, Any]:
    kept = values[~np.isnan(values)]
    if len(kept) == 0:
        return {"mean": None, "lo": None, "hi": None, "n": 0}
    lo, hi = bootstrap_interval(values)
    return {"mean": float(kept.mean()), "lo": lo, "hi": hi, "n": int(len(kept))}


def per_world(rows: Iterable[OutRow], t_opt: dict[int, float] | None = None) -> list[dict[str, Any]]:
    """Per BARN world (by index): its runs and each of :data:`FIGURES` as ``{"mean", "lo", "hi", "n"}``
    (``time_s`` over the successful runs only)."""
    t_opt = report_t_opt() if t_opt is None else t_opt
    out = []
    for world, runs in _by_world(rows).items():
        values = _values(runs, t_opt[world])
        out.append({"world": world, "runs": len(runs), **{f: _stat(values[f]) for f in FIGURES}})
    return out


def overall(rows: Iterable[OutRow], t_opt: dict[int, float] | None = None, resamples: int = BOOTSTRAP_RESAMPLES,
            seed: int = BOOTSTRAP_SEED) -> dict[str, Any]:
    """report_test.py's five figures of ``rows`` (:func:`bulletnav.barn.metric.summarise`) with
    95 % intervals (runs resampled within each world), its printed ``line`` and the ``worlds`` count."""
    t_opt = report_t_opt() if t_opt is None else t_opt
    rows = list(rows)
    worlds = _by_world(rows)
    if not worlds:
        return {"worlds": 0, "runs": 0, "line": None, **{f: {"mean": None, "lo": None, "hi": None, "n": 0} for f in FIGURES}}
    summary = summarise(rows, t_opt)
    means = {"success": summary.success, "collision": summary.collision, "timeout": summary.timeout,
             "time_s": summary.time_s, "metric": summary.metric}
    rng = np.random.default_rng(seed)
    boot = {f: np.zeros((len(worlds), resamples)) for f in FIGURES}
    for w, (world, runs) in enumerate(worlds.items()):
        values = _values(runs, t_opt[world])
        pick = rng.integers(0, len(runs), size=(resamples, len(runs)))
        for f in FIGURES:
            drawn = values[f][pick]
            if f == "time_s":  # the mean time of the resample's successes; NaN (left out) without one
                ok = ~np.isnan(drawn)
                count = ok.sum(axis=1)
                boot[f][w] = np.where(count > 0, np.where(ok, drawn, 0.0).sum(axis=1) / np.maximum(count, 1), np.nan)
            else:
                boot[f][w] = drawn.mean(axis=1)
    out: dict[str, Any] = {"worlds": len(worlds), "runs": len(rows), "line": summary.line()}
    for f in FIGURES:
        over = boot[f]
        with np.errstate(invalid="ignore"):
            samples = np.nanmean(over, axis=0) if f == "time_s" else over.mean(axis=0)
        samples = samples[~np.isnan(samples)]
        lo, hi = (np.percentile(samples, [2.5, 97.5]) if len(samples) else (math.nan, math.nan))
        mean = means[f]
        out[f] = {"mean": None if math.isnan(mean) else float(mean), "lo": float(lo), "hi": float(hi),
                  "n": len(worlds) if f != "time_s" else sum(any(r.success for r in runs) for runs in worlds.values())}
    return out


def agreement(ours: dict[str, Any], theirs: dict[str, Any]) -> dict[str, Any] | None:
    """How far entry ``ours`` (a section's controller) stands from ``theirs`` (a published one with
    rows), by :data:`AGREEMENT`'s three figures: the success difference (points), the ratio of the
    mean times of successes, and the worlds whose success rates are within 0.3 of each other (over
    the worlds both ran). None when they share no world."""
    mine = {p["world"]: p["success"]["mean"] for p in ours["per_world"]}
    other = {p["world"]: p["success"]["mean"] for p in theirs["per_world"]}
    both = sorted(set(mine) & set(other))
    if not both:
        return None
    close = [w for w in both if abs(mine[w] - other[w]) <= AGREEMENT["world_success"] + 1e-9]
    a, b = ours["overall"], theirs["overall"]
    points = 100.0 * (a["success"]["mean"] - b["success"]["mean"])
    ratio = (a["time_s"]["mean"] / b["time_s"]["mean"]) if a["time_s"]["mean"] and b["time_s"]["mean"] else None
    need = math.ceil(AGREEMENT["worlds"] * len(both) / 50)
    return {"with": theirs["name"], "success_points": points, "time_ratio": ratio, "worlds": len(both),
            "worlds_within": len(close), "worlds_apart": [w for w in both if w not in close], "worlds_needed": need,
            "agrees": (abs(points) <= AGREEMENT["success_points"] and ratio is not None
                       and abs(ratio - 1.0) <= AGREEMENT["time_ratio"] and len(close) >= need)}


def published_entries(indices: list[int]) -> list[dict[str, Any]]:
    """The published results (:data:`bulletnav.barn.data.PUBLISHED`) on ``indices``, as section
    entries: per world and overall from their rows, or the published summary line alone (only
    where the group is BARN's 50 test worlds, which it was measured on)."""
    from bulletnav.barn.data import PUBLISHED, TEST_WORLDS, published_rows

    out = []
    for pub in PUBLISHED:
        entry: dict[str, Any] = {"name": pub.name, "source": "published", "origin": pub.source, "note": pub.note,
                                 "clip": pub.clip}
        if pub.rows_file is not None:
            published = by_world(published_rows(pub))
            rows = [r for i in sorted(set(indices) & set(published)) for r in published[i]]
            entry.update(per_world=per_world(rows), overall=overall(rows),
                         all_line=summarise(published_rows(pub), report_t_opt()).line())
        elif sorted(indices) == sorted(TEST_WORLDS) and pub.reported is not None:
            rep = pub.reported
            entry.update(per_world=[], overall={
                "worlds": len(TEST_WORLDS), "runs": None, "line": None,
                **{f: {"mean": rep[f], "lo": None, "hi": None, "n": len(TEST_WORLDS)} for f in FIGURES}})
        else:
            continue
        out.append(entry)
    return out


def barn_sections(worlds: list[dict[str, Any]], controllers: list[str] | list[dict[str, Any]],
                  rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """One section per BARN group of a results record (``worlds``: the suite's world entries;
    ``controllers``: its controllers' names, or their entries with ``name`` and ``type``;
    ``rows``: its episode rows): every controller's per-world and overall figures, then the
    published results'. A ``dwa`` controller's entry also holds its :func:`agreement` with BARN's
    DWA rows (the same planner, measured by BARN in Gazebo)."""
    from bulletnav.barn.data import dwa_rows

    groups: dict[str, list[int]] = {}
    names: dict[str, str] = {}
    for w in worlds:
        if w.get("group"):
            groups.setdefault(w["group"], []).append(int(w["barn_world"]))
            names[w["name"]] = w["group"]
    sections = []
    for group, indices in groups.items():
        entries = []
        published = published_entries(indices)
        dwa = next(e for e in published if e["name"] == DWA_NAME)
        for c in controllers:
            name, kind = (c, None) if isinstance(c, str) else (c["name"], c.get("type"))
            mine = out_rows(r for r in rows if r["controller"] == name and names.get(r["world"]) == group)
            entry = {"name": name, "source": "bulletnav", "per_world": per_world(mine), "overall": overall(mine)}
            if kind == "dwa" and mine:
                entry["agreement"] = agreement(entry, dwa)
            entries.append(entry)
        entries += published
        all_dwa = dwa_rows()
        sections.append({
            "group": group, "worlds": indices, "runs": next((w["episodes"] for w in worlds if w.get("group") == group), 0),
            "intervals": INTERVALS,
            "metric": METRIC_LABEL,
            "dwa_worlds": [p["world"] for p in dwa["per_world"]],
            "agreement_rule": AGREEMENT,
            "dwa_all_line": summarise(all_dwa, report_t_opt()).line(),
            "controllers": entries,
        })
    return sections


def plot_metric(section: dict[str, Any], path: Path) -> Path:
    """A PNG of each controller's per-world mean BARN metric (dots, with their 95 % intervals)
    against the world index, DWA's rows beside them (black diamonds), written atomically to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    colours = ["#0072B2", "#D55E00", "#009E73", "#CC79A7", "#E69F00", "#56B4E9", "#F0E442"]
    markers = ["o", "s", "^", "v", "P", "X", "<", ">"]
    entries = [e for e in section["controllers"] if e["per_world"]]  # a result published as a summary has no dots
    n = len(entries)
    step = min(6.0, max(1.0, _spacing(section["worlds"])))
    width = 0.7 * step
    fig, ax = plt.subplots(figsize=(max(8.0, 0.22 * len(section["worlds"]) + 3), 4.6))
    for k, entry in enumerate(entries):
        dwa = entry["source"] == "published"
        shift = (k - (n - 1) / 2) * width / max(1, n - 1)
        xs = [p["world"] + shift for p in entry["per_world"] if p["metric"]["mean"] is not None]
        ys = [p["metric"]["mean"] for p in entry["per_world"] if p["metric"]["mean"] is not None]
        lo = [p["metric"]["mean"] - p["metric"]["lo"] if p["metric"]["lo"] is not None else 0.0
              for p in entry["per_world"] if p["metric"]["mean"] is not None]
        hi = [p["metric"]["hi"] - p["metric"]["mean"] if p["metric"]["hi"] is not None else 0.0
              for p in entry["per_world"] if p["metric"]["mean"] is not None]
        mean = entry["overall"]["metric"]["mean"]
        label = f"{entry['name']}{' (published, not run here)' if dwa else ''}: mean {mean:.3f}" if mean is not None \
            else entry["name"]
        black = dwa and entry["name"] == DWA_NAME
        ax.errorbar(xs, ys, yerr=[lo, hi], fmt="D" if dwa else markers[k % len(markers)], ms=5 if dwa else 4,
                    color="#000000" if black else "#8C8C8C" if dwa else colours[k % len(colours)], elinewidth=0.8,
                    capsize=0, label=label, zorder=3 if dwa else 2)
    ax.axhline(0.5, color="#B4B4B4", lw=0.8, ls=":")
    return _save_per_world(fig, ax, path, "BARN metric (mean of the world's runs)", (-0.02, 0.52),
                           f"BARN metric per world: {section['group']} ({len(section['worlds'])} worlds x {section['runs']} "
                           "runs; bars: 95 % intervals)", 7.5)


def _save_per_world(fig: Any, ax: Any, path: Path, ylabel: str, ylim: tuple[float, float], title: str,
                    legend_size: float) -> Path:
    """A per-world plot's axes, grid and legend below it, written atomically to ``path``; the figure closed."""
    import matplotlib.pyplot as plt

    from bulletnav.files import save_figure

    ax.set_xlabel("BARN world index")
    ax.set_ylabel(ylabel)
    ax.set_ylim(*ylim)
    ax.set_title(title, fontsize=10)
    ax.grid(axis="y", color="#E0E0E0", lw=0.6)
    ax.legend(fontsize=legend_size, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2, frameon=False)
    try:
        save_figure(fig, path, format="png", dpi=110, bbox_inches="tight")
    finally:
        plt.close(fig)
    return path


def _spacing(worlds: list[int]) -> float:
    """The smallest gap between consecutive world indices (the room each world's dots share)."""
    ordered = sorted(worlds)
    return float(min((b - a for a, b in zip(ordered, ordered[1:], strict=False)), default=6))


def plot_success_pair(section: dict[str, Any], ours: str, theirs: str, path: Path) -> Path:
    """A PNG of two entries' per-world success rates (``ours``, a bulletnav controller, and
    ``theirs``, a published one) against the world index, the worlds where they differ by more
    than :data:`AGREEMENT`'s 0.3 marked, written atomically to ``path``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt


    by_name = {e["name"]: e for e in section["controllers"]}
    a = {p["world"]: p["success"]["mean"] for p in by_name[ours]["per_world"]}
    b = {p["world"]: p["success"]["mean"] for p in by_name[theirs]["per_world"]}
    worlds = sorted(set(a) & set(b))
    fig, ax = plt.subplots(figsize=(max(8.0, 0.22 * len(worlds) + 3), 4.2))
    apart = [w for w in worlds if abs(a[w] - b[w]) > AGREEMENT["world_success"] + 1e-9]
    for w in apart:
        ax.axvspan(w - 2.5, w + 2.5, color="#F4D6C8", lw=0, zorder=0)
    ax.vlines(worlds, [min(a[w], b[w]) for w in worlds], [max(a[w], b[w]) for w in worlds], color="#B4B4B4", lw=0.8)
    ax.plot(worlds, [a[w] for w in worlds], "o", color="#0072B2", ms=5, label=f"{ours} (bulletnav)")
    ax.plot(worlds, [b[w] for w in worlds], "D", color="#000000", ms=4, label=f"{theirs} (published, not run here)")
    return _save_per_world(fig, ax, path, "success rate (runs of the world)", (-0.05, 1.05),
                           f"Success per world: {ours} vs {theirs}; within 0.3 in {len(worlds) - len(apart)} of "
                           f"{len(worlds)} worlds (shaded: apart)", 8)
