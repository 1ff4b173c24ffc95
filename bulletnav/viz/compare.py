"""Learning curves: one run's curve, and several runs compared in one figure with a table."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from bulletnav.errors import RunError
from bulletnav.files import save_figure


def plot_learning_curve(history: list[dict[str, Any]], path: Path, title: str = "") -> None:
    """Success rate and mean evaluation reward against timesteps, one PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    steps = [h["timesteps"] for h in history]
    fig, ax1 = plt.subplots(figsize=(7, 4), dpi=100)
    ax1.plot(steps, [h["success_rate"] for h in history], "o-", color="tab:green", label="success rate")
    ax1.plot(steps, [h["collision_rate"] for h in history], "s--", color="tab:red", label="collision rate")
    ax1.set_xlabel("timesteps")
    ax1.set_ylabel("rate")
    ax1.set_ylim(-0.02, 1.02)
    ax2 = ax1.twinx()
    ax2.plot(steps, [h["mean_reward"] for h in history], "^-", color="tab:blue", label="mean reward")
    ax2.set_ylabel("mean evaluation reward")
    lines = ax1.get_lines() + ax2.get_lines()
    ax1.legend(lines, [ln.get_label() for ln in lines], loc="lower right")
    ax1.grid(alpha=0.3)
    ax1.set_title(title)
    fig.tight_layout()
    try:
        save_figure(fig, path, format="png", dpi=fig.dpi)  # a unique temp file beside it, renamed; removed on failure
    finally:
        plt.close(fig)


REACH_SUCCESS = 0.8
"""Success rate whose first crossing ``compare`` reports as the sample-efficiency mark."""


def _steps_label(value: float, _pos: int) -> str:
    """Tick label for a timestep count: 0, 250k, 1.5M."""
    if abs(value) >= 1e6:
        return f"{value / 1e6:g}M"
    return f"{value / 1e3:g}k" if abs(value) >= 1e3 else f"{value:g}"


GROUPS = ("algo", "hyperparams", "start", "physics")
"""What ``compare_runs`` colours runs by: the algorithm, the hyperparameter file's name
(``ppo_dynamic_curriculum`` for ``--hyperparams .../ppo_dynamic_curriculum.yml``; the
algorithm's default file where ``train`` was given none), where the weights started:
``scratch``, or ``from NAME`` for a run with ``--init-from`` (NAME the model file's stem, or
its folder's name for a run's ``model.zip``: ``from bc`` for ``runs/bc/model.zip``), or the
physics profile it trained in (``env_kwargs``' ``physics``: ``default``, ``fast``, ``kinematic``)."""


def run_group(record: dict[str, Any], group_by: str) -> str:
    """The group a training run's ``run.json`` record belongs to (see :data:`GROUPS`)."""
    import shlex

    if group_by not in GROUPS:
        raise ValueError(f"group_by must be one of {', '.join(GROUPS)}, got {group_by!r}")
    if group_by == "algo":
        return str(record["algo"])
    if group_by == "physics":
        return f"physics={(record.get('env_kwargs') or {}).get('physics', 'default')}"
    if group_by == "start":
        init = record.get("init_from")
        if not init:
            return "scratch"
        path = Path(init)
        return f"from {path.parent.name if path.stem == 'model' and path.parent.name else path.stem}"
    words = shlex.split(record.get("command", ""))
    for i, word in enumerate(words):
        if word == "--hyperparams" and i + 1 < len(words):
            return Path(words[i + 1]).stem
        if word.startswith("--hyperparams="):
            return Path(word.split("=", 1)[1]).stem
    return f"{record['algo']} (default)"


def compare_runs(run_dirs: list[Path], out_png: Path, group_by: str = "algo",
                 reach: float = REACH_SUCCESS) -> list[dict[str, Any]]:
    """Learning curves of several runs in one PNG (success rate against timesteps and
    against wall-clock time, mean reward against timesteps; one colour per group -- algorithm
    or hyperparameter file, see :data:`GROUPS` --, one line per seed) and one summary row per
    run: final and best evaluation, wall time, and when the in-training evaluation first
    reached ``reach`` (:data:`REACH_SUCCESS` by default)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.ticker import FuncFormatter

    rows = []
    if group_by not in GROUPS:
        raise ValueError(f"group_by must be one of {', '.join(GROUPS)}, got {group_by!r}")
    for run in run_dirs:  # before the figure exists: a refused call leaves no open figure behind
        for name in ("eval_history.json", "run.json"):
            if not (run / name).is_file():
                raise RunError(f"{run}: not a finished training run (no {name})")
    fig, (ax1, ax3, ax2) = plt.subplots(1, 3, figsize=(15, 4), dpi=100)
    colours: dict[str, Any] = {}  # one colour per group; its seeds share it, each its own line style
    styles = ("o-", "s--", "^:", "d-.")
    seen: dict[str, int] = {}
    for run in run_dirs:
        history = json.loads((run / "eval_history.json").read_text())
        record = json.loads((run / "run.json").read_text())
        group = run_group(record, group_by)
        colour = colours.setdefault(group, f"C{len(colours) % 10}")
        style = styles[seen.get(group, 0) % len(styles)]
        seen[group] = seen.get(group, 0) + 1
        label = f"{group.upper() if group_by == 'algo' else group} seed {record['seed']}"
        steps = [h["timesteps"] for h in history]
        ax1.plot(steps, [h["success_rate"] for h in history], style, color=colour, alpha=0.8, ms=3, label=label)
        ax2.plot(steps, [h["mean_reward"] for h in history], style, color=colour, alpha=0.8, ms=3, label=label)
        ax3.plot([h["wall_time"] / 60 for h in history], [h["success_rate"] for h in history], style, color=colour,
                 alpha=0.8, ms=3, label=label)
        final = history[-1]
        best = max(history, key=lambda h: h["success_rate"])
        reached = next((h for h in history if h["success_rate"] >= reach), None)
        rows.append({"run": str(run), "algo": record["algo"], "group": group, "seed": record["seed"],
                     "timesteps": record["total_timesteps"],
                     # a resumed run's wall_time_s times only its last part; wall_time_total_s (newer
                     # runs) and the history's clock run from the start
                     "wall_time_s": max([record.get("wall_time_total_s", record["wall_time_s"]),
                                         *(h.get("wall_time", 0.0) for h in history)]),
                     "final_success": final["success_rate"], "final_collisions": final["collision_rate"],
                     "final_reward": round(final["mean_reward"], 2), "best_success": best["success_rate"],
                     "best_at": best["timesteps"],
                     "reached_at": reached["timesteps"] if reached else None,
                     "reached_wall_s": round(reached["wall_time"]) if reached else None})
    for ax, name in ((ax1, "success rate (20 unseen episodes)"), (ax2, "mean evaluation reward")):
        ax.set_xlabel("timesteps")
        ax.set_ylabel(name)
    ax3.set_xlabel("wall-clock time (min)")
    ax3.set_ylabel("success rate (20 unseen episodes)")
    for ax in (ax1, ax2, ax3):
        ax.grid(alpha=0.3)
    for ax in (ax1, ax2):  # 400k, not 400000: the labels of a 1.5M-step run stay apart
        ax.xaxis.set_major_formatter(FuncFormatter(_steps_label))
    for ax in (ax1, ax3):
        ax.set_ylim(-0.02, 1.02)
    ax1.legend(loc="lower right" if len(run_dirs) > 4 else "upper left", fontsize="small" if len(run_dirs) > 4 else None)
    fig.tight_layout()
    try:
        save_figure(fig, out_png, format="png", dpi=fig.dpi)
    finally:
        plt.close(fig)
    return rows
