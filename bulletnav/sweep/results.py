"""A sweep's results: one row per trial, one summary per configuration (mean and 95 %
bootstrap confidence interval across its seeds), written as CSV, JSON and a plot."""

from __future__ import annotations

import csv
import io
import json
from pathlib import Path
from typing import Any

import numpy as np

from bulletnav.files import write_bytes, write_json

TRIAL_COLUMNS = ("trial", "config", "seed", "status", "timesteps", "wall_time_s", "success_rate", "collision_rate",
                 "timeout_rate", "spl", "mean_reward", "mean_length", "node", "model", "error")
"""Columns of ``trials.csv`` (``config`` is the trial's hyperparameters, as JSON)."""


def config_label(config: dict[str, Any]) -> str:
    """``learning_rate=0.0003, env_kwargs.reward_collision=-40`` (``base`` for no changes;
    floats to 4 significant digits: a label, the exact values are in ``config``)."""
    return ", ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}" for k, v in config.items()) or "base"


def bootstrap_ci(values: Any, level: float = 0.95, resamples: int = 10_000, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap confidence interval of the mean of ``values`` (seeded, so the same
    values give the same interval). One value gives ``(nan, nan)``: no interval from one seed."""
    x = np.asarray(values, dtype=float)
    if x.size < 2:
        return float("nan"), float("nan")
    rng = np.random.default_rng(seed)
    means = x[rng.integers(0, x.size, size=(resamples, x.size))].mean(axis=1)
    lo, hi = np.quantile(means, [(1 - level) / 2, 1 - (1 - level) / 2])
    return float(lo), float(hi)


def summarize_configs(rows: list[dict[str, Any]], metric: str = "success_rate", mode: str = "max") -> list[dict[str, Any]]:
    """One summary per configuration over its finished trials: seeds, mean, 95 % bootstrap CI,
    min and max of ``metric``; best first (by the mean, ``mode`` max or min)."""
    groups: dict[str, dict[str, Any]] = {}
    for row in rows:
        key = json.dumps(row["config"], sort_keys=True)
        g = groups.setdefault(key, {"config": row["config"], "label": config_label(row["config"]), "values": [],
                                    "seeds": [], "trials": 0, "failed": 0})
        g["trials"] += 1
        if row["status"] == "finished" and row.get(metric) is not None:
            g["values"].append(float(row[metric]))
            g["seeds"].append(row["seed"])
        elif row["status"] == "error":
            g["failed"] += 1
    out = []
    for g in groups.values():
        v = g.pop("values")
        lo, hi = bootstrap_ci(v)
        out.append({**g, "n": len(v), "metric": metric, "mean": float(np.mean(v)) if v else None,
                    "ci95": [lo, hi] if len(v) > 1 else None, "min": min(v) if v else None,
                    "max": max(v) if v else None, "values": v})
    sign = -1.0 if mode == "max" else 1.0
    return sorted(out, key=lambda s: (s["mean"] is None, sign * (s["mean"] or 0.0)))


def write_results(out: Path, rows: list[dict[str, Any]], summary: list[dict[str, Any]], record: dict[str, Any]) -> dict[str, Path]:
    """``trials.csv``, ``summary.csv``, ``results.json`` and ``results.png`` in ``out``
    (atomically, so an interrupted write never leaves half a table)."""
    out.mkdir(parents=True, exist_ok=True)
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=TRIAL_COLUMNS, extrasaction="ignore")
    writer.writeheader()
    for row in rows:
        writer.writerow({**row, "config": json.dumps(row["config"], sort_keys=True)})
    write_bytes(out / "trials.csv", buf.getvalue().encode())
    buf = io.StringIO()
    writer = csv.writer(buf)
    writer.writerow(["config", "metric", "seeds", "mean", "ci95_low", "ci95_high", "min", "max", "failed"])
    for s in summary:
        ci = s["ci95"] or [None, None]
        writer.writerow([s["label"], s["metric"], s["n"], s["mean"], ci[0], ci[1], s["min"], s["max"], s["failed"]])
    write_bytes(out / "summary.csv", buf.getvalue().encode())
    write_json(out / "results.json", {**record, "summary": summary, "trials": rows})
    plot = out / "results.png"
    plot_summary(summary, plot, title=record.get("name", "sweep"))
    return {"trials": out / "trials.csv", "summary": out / "summary.csv", "json": out / "results.json", "plot": plot}


def plot_summary(summary: list[dict[str, Any]], path: Path, title: str = "sweep") -> None:
    """One bar per configuration (its mean), the 95 % interval as an error bar and each seed as a dot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    shown = [s for s in summary if s["n"]]
    fig, ax = plt.subplots(figsize=(max(4.5, 1.2 * len(shown) + 2.0), 3.6))
    for i, s in enumerate(shown):
        ax.bar(i, s["mean"], color="#8fb3d9", width=0.6)
        if s["ci95"]:
            lo, hi = s["ci95"]
            ax.errorbar(i, s["mean"], yerr=[[s["mean"] - lo], [hi - s["mean"]]], color="black", capsize=5)
        ax.scatter(np.full(s["n"], i) + np.linspace(-0.15, 0.15, s["n"]), s["values"], color="#1f4e79", s=14, zorder=3)
    ax.set_xticks(range(len(shown)), [s["label"] for s in shown], rotation=20, ha="right", fontsize=8)
    ax.set_xlim(-0.8, max(len(shown), 1) - 0.2)
    ax.set_ylabel(shown[0]["metric"] if shown else "metric")
    ax.set_title(f"{title}\nbars: mean; whiskers: 95 % bootstrap CI; dots: seeds", fontsize=9)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=110)
    plt.close(fig)
    write_bytes(path, buf.getvalue())
