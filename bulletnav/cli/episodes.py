"""Single-robot episodes as ``navigate``, ``evaluate`` and ``demo`` run them: optional video, plot,
GUI dashboard, ROS 2 recording and Minari dataset around the library's ``run_episodes``, and the
evaluation report of a trained model."""

from __future__ import annotations

import argparse

from bulletnav import BARN_ENV_ID
from bulletnav.barn.data import N_WORLDS
from bulletnav.cli import interrupts
from bulletnav.cli.args import DEFAULT_ENV_ID, int_type
from bulletnav.cli.envs import check_env_id, shielded, world_kwargs, world_label
from bulletnav.cli.live import start_live
from bulletnav.cli.output import print_json, safety_line, shield_line
from bulletnav.errors import BulletnavError
from bulletnav.rl.envs import EVALUATE_OBSTACLES

_WORLD_INDEX = int_type(0, N_WORLDS - 1, "a BARN world index, a whole number")


def WORLD_IDX(text: str) -> int | tuple[int, ...]:  # noqa: N802  (an argparse type, named as the others)
    """``--world-idx``'s type: one BARN world (``7``), a pool by name (``test``, ``train``) or a
    comma list (``0,6,12``); a pool comes back as its indices, else one line naming what is wrong."""
    from bulletnav.barn.data import POOLS, world_pool
    from bulletnav.errors import LayoutError

    text = text.strip()
    if text in POOLS:
        return POOLS[text]
    if "," not in text:
        return _WORLD_INDEX(text)
    try:
        return world_pool([_WORLD_INDEX(part.strip()) for part in text.split(",")], what="--world-idx")
    except LayoutError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


WORLD_IDX.__name__ = "world selection"


def add_world_idx_arg(parser: argparse.ArgumentParser) -> None:
    """``--world-idx``: the BARN world(s) of the episodes (``--env bulletnav/BARN-v0`` only)."""
    parser.add_argument("--world-idx", type=WORLD_IDX, default=None, metavar="N|test|train|N,N,...",
                        help=f"BARN world(s), with --env {BARN_ENV_ID} only: one world 0-{N_WORLDS - 1} for every "
                             "episode (default 1, the first non-test world), or several: test (BARN's 50 test "
                             "worlds 0, 6, ..., 294), train (the 250 others) or a list such as 0,6,12; episode k "
                             "then runs the list's world k mod its length (--episodes 500 --world-idx test: each "
                             "test world 10 times, seeds S to S + 499)")


def world_idx_kwargs(args: argparse.Namespace) -> dict:
    """``{"world_idx": N}`` (or the pool's indices) for ``--world-idx`` on BARN-v0, nothing without it.

    Raises:
        BulletnavError: ``--world-idx`` with another env (the message names it).
    """
    index = getattr(args, "world_idx", None)
    if index is None:
        return {}
    if args.env_id != BARN_ENV_ID:
        from bulletnav.barn.data import POOLS

        names = {pool: name for name, pool in POOLS.items()}
        shown = index if isinstance(index, int) else names.get(tuple(index), ",".join(map(str, index)))
        raise BulletnavError(f"--world-idx {shown}: picks BARN worlds, so it needs --env {BARN_ENV_ID} "
                             f"(not {args.env_id})")
    return {"world_idx": index}


def world_cycle(args: argparse.Namespace):
    """``reset_options`` for :func:`~bulletnav.evaluation.run_episodes`: with several worlds in
    ``--world-idx``, episode k's reset picks world k mod their count; None otherwise."""
    pool = getattr(args, "world_idx", None)
    if pool is None or isinstance(pool, int):
        return None
    return lambda k: {"world_idx": pool[k % len(pool)]}


def worlds_label(index: int | tuple[int, ...]) -> str:
    """``BARN world 7``, ``BARN's 50 test worlds``, ``BARN's 250 training worlds`` or ``BARN worlds 0, 6, 12``."""
    from bulletnav.barn.data import TEST_WORLDS, TRAIN_WORLDS

    if isinstance(index, int):
        return f"BARN world {index}"
    if tuple(index) == TEST_WORLDS:
        return "BARN's 50 test worlds"
    if tuple(index) == TRAIN_WORLDS:
        return "BARN's 250 training worlds"
    return "BARN worlds " + ", ".join(map(str, index))


def episode_world_label(args: argparse.Namespace, env, obstacles: int | None = None) -> str:
    """The report's name of the world: ``BARN world N`` on BARN-v0 (the env's own index), else
    :func:`~bulletnav.cli.envs.world_label`'s (layout file or procedural)."""
    given = getattr(args, "world_idx", None)
    if given is not None and not isinstance(given, int):
        return worlds_label(given)
    index = getattr(env.unwrapped, "world_idx", None)
    if index is not None:
        return f"BARN world {index}"
    return world_label(args, obstacles)


class Visuals:
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


def run_with_visuals(args, env, policy, line, title: str):
    """``args.episodes`` episodes of ``policy`` on ``env`` from ``args.seed``, ``line(result)`` after
    each, with the outputs ``args`` ask for. Returns ``(results, written, layout size)``, where
    ``written`` lists the files written, one report line each."""
    from bulletnav.evaluation import run_episodes

    try:
        live = start_live(args)  # first: a port in use is refused before any file is opened
    except BaseException:
        env.close()
        raise
    visuals = Visuals(env, policy, getattr(args, "video", None), getattr(args, "plot", None), getattr(args, "gui", False),
                      getattr(args, "shield", False))
    sizes: list[list[float]] = []

    def on_reset(env, info) -> None:
        if not sizes:
            sizes.append([float(x) for x in env.unwrapped.scene.layout.size])
        visuals.on_reset(env, info)

    finished: list = []

    def on_episode(r) -> None:
        visuals.on_episode(r)
        line(r)
        finished.append(r)

    recorder = dataset = None
    if getattr(args, "dataset", None):
        from bulletnav.datasets import DatasetRecorder

        env = dataset = DatasetRecorder(env, args.dataset)
    if getattr(args, "record", None) or live is not None:
        from bulletnav.ros.record import McapRecorder

        env = recorder = McapRecorder(env, getattr(args, "record", None), plan=lambda: planned_path(policy), overwrite=True,
                                      live=live)
    outputs = [name for name, given in (("video", getattr(args, "video", None)), ("plot", getattr(args, "plot", None)),
                                        ("recording", getattr(args, "record", None)), ("dataset", getattr(args, "dataset", None)))
               if given]
    interrupts.on_interrupt(lambda: interrupted_note(len(finished), args.episodes, outputs))
    ok = False
    try:
        results = run_episodes(env, policy, args.episodes, args.seed, on_episode=on_episode,
                               on_step=visuals.on_step, on_reset=on_reset, reset_options=world_cycle(args))
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
            if live is not None:
                live.close()
    if recorder is not None and getattr(args, "record", None):
        written = [*written, f"recording: {args.record} (ROS 2 MCAP, {recorder.episodes} episodes)"]
    if dataset is not None:
        written = [*written, f"dataset: {args.dataset} (Minari, {len(dataset.buffers)} episodes)"]
    return results, written, (sizes[0] if sizes else None)


def interrupted_note(done: int, episodes: int, outputs: list[str]) -> str:
    """The line of an interrupted ``navigate``, ``evaluate`` or ``demo``: the episodes finished
    (their lines are above), that their files are not written, and the command to run again."""
    dropped = (f"; no {' / '.join(outputs)} written (an unfinished run's are dropped)" if outputs else "")
    return (f"interrupted after {done} of {episodes} episodes{dropped}; nothing can be resumed; run again with: "
            f"{interrupts.rerun_command()}")


def planned_path(policy):
    """The classical planner's current path under ``policy`` (a Navigator, or one behind a shield), or None."""
    for _ in range(3):
        if hasattr(policy, "path"):
            return policy.path
        policy = getattr(policy, "policy", None) or getattr(policy, "inner", None)
        if policy is None:
            return None
    return None


def load_for_evaluation(args: argparse.Namespace, model_path: str) -> tuple:
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
    env_kwargs.update(world_kwargs(args, default_obstacles))
    env_kwargs.update(world_idx_kwargs(args))
    env = shielded(args, gym.make(args.env_id, render_mode="human" if args.gui else None, **env_kwargs))
    try:
        check_model_fits(model, env, model_path, args.env_id)
    except BaseException:
        env.close()
        raise
    return model, meta, vecnorm, env, env_kwargs, default_obstacles


def trained_physics(meta: dict) -> str:
    """The physics profile a model's sidecar records it was trained with (``env_kwargs``), ``"default"`` where none."""
    kwargs = meta.get("env_kwargs")
    physics = kwargs.get("physics") if isinstance(kwargs, dict) else None
    return physics if isinstance(physics, str) else "default"


REPORT_KEYS = ("episodes", "success_rate", "mean_reward", "std_reward", "mean_length", "std_length", "mean_distance",
               "std_distance", "collision_rate", "spl")
"""The evaluation report's summary keys before the safety and shield ones."""
BAR = "=" * 60


def barn_episode_line(r) -> str | None:
    """An episode's BARN figures as the benchmark's tables compute them (None off BARN-v0)."""
    if r.barn_info is None:  # not a BARN episode: return before importing anything (an interrupt
        return None          # between the episode's line and its count must find nothing in between)
    from bulletnav.benchmark.barn import episode_figures

    figures = episode_figures([r])
    if figures is None:
        return None
    e = figures["per_episode"][0]
    return (f"BARN world {e['world_idx']}: clock {e['barn_time_s']:.2f} s  t_opt {e['t_opt_s']:.2f} s  "
            f"metric {e['barn_metric']:.4f}")


def barn_report_lines(figures: dict | None) -> list[str]:
    """The run's BARN figures (report_test.py's summary line and the metric's definition)."""
    if figures is None:
        return []
    return [f"BARN (report_test.py) {figures['summary']['line']}", f"BARN metric: {figures['metric']}"]


def _episode_line(args: argparse.Namespace):
    """The report's lines of one episode (nothing with ``--json``)."""

    def line(r) -> None:
        if args.json:
            return
        mark = "\u2713 SUCCESS" if r.success else ("\u2717 COLLISION" if r.collision else "\u2717 TIMEOUT")
        print(f"--- Episode {r.episode}/{args.episodes} (seed {r.seed}) ---")
        print(f"Initial distance to goal: {r.initial_distance:.2f}m")
        print(f"{mark} | Steps: {r.steps} | Reward: {r.reward:.1f} | Final distance: {r.final_distance:.2f}m | "
              f"Distance traveled: {r.path_length:.2f}m")
        barn = barn_episode_line(r)
        if barn:
            print(barn)

    return line


def _print_results(args: argparse.Namespace, s: dict, results, written: list[str]) -> None:
    n_success = round(s["success_rate"] * s["episodes"])
    print(f"\n{BAR}\nEVALUATION RESULTS\n"
          f"Success rate: {n_success}/{s['episodes']} ({s['success_rate'] * 100:.1f}%)\n"
          f"Average reward:         {s['mean_reward']:.2f} \u00b1 {s['std_reward']:.2f}\n"
          f"Average episode length: {s['mean_length']:.1f} \u00b1 {s['std_length']:.1f} steps\n"
          f"Average distance:        {s['mean_distance']:.2f}m \u00b1 {s['std_distance']:.2f}m\n"
          f"Collision rate: {s['collision_rate'] * 100:.1f}%   SPL: {s['spl']:.3f}\n"
          f"Safety: {safety_line(s)}")
    if args.shield:
        print(f"Shield: {shield_line(s)}")
    if any(r.goals_total > 1 for r in results):
        print(f"Mission: progress {s['progress'] * 100:.1f} %   PPL {s['ppl']:.3f}   "
              f"goals per minute {s['goals_per_minute']:.2f}")
    for text in barn_report_lines(s.get("barn")):
        print(text)
    print(BAR)
    for w in written:
        print(w)


def evaluate_report(args: argparse.Namespace, model_path: str, loaded: tuple | None = None) -> dict:
    """Evaluate ``model_path`` as ``args`` say (``loaded``: :func:`load_for_evaluation`'s, if done
    already); print the article's report (or JSON)."""
    from bulletnav.evaluation import SAFETY_KEYS, SHIELD_KEYS, summarize
    from bulletnav.rl.policy import SB3Policy

    model, meta, vecnorm, env, env_kwargs, default_obstacles = loaded or load_for_evaluation(args, model_path)
    algo = str(meta.get("algo", getattr(args, "algo", None) or "?")).upper()
    if not args.json:
        env_name = "" if args.env_id == DEFAULT_ENV_ID else f", {args.env_id}"
        if getattr(env.unwrapped, "world_idx", None) is not None:
            given = getattr(args, "world_idx", None)
            env_name += ", " + worlds_label(given if given is not None else env.unwrapped.world_idx)
        shift = (f", perturb {args.perturb}" if args.perturb else "") + (", shield" if args.shield else "")
        print(f"{BAR}\nRunning {args.episodes} evaluation episodes ({algo} {model_path}, seed {args.seed}{env_name}{shift})\n{BAR}")
        trained = trained_physics(meta)
        if trained != env_kwargs.get("physics", "default"):
            print(f"The model was trained with physics={trained}; these episodes run with "
                  f"physics={env_kwargs.get('physics', 'default')} (--physics chooses).")
    label = episode_world_label(args, env, default_obstacles)
    results, written, layout_size = run_with_visuals(args, env, SB3Policy(model, vecnorm), _episode_line(args),
                                                     f"{algo} (seed {args.seed})")
    from bulletnav.benchmark.barn import episode_figures

    s = summarize(results)
    figures = episode_figures(results)
    if figures is not None:
        s["barn"] = figures
    keys = (*REPORT_KEYS, *SAFETY_KEYS, *SHIELD_KEYS, "progress", "ppl", "goals_per_minute", "per_episode")
    out = {k: s[k] for k in keys}
    if figures is not None:
        out["barn"] = figures
    out.update(model=str(model_path), seed=args.seed, env_id=args.env_id,
               world=label, world_size=layout_size, perturb=args.perturb, shield=args.shield,
               physics=env_kwargs.get("physics", "default"), physics_hz=env.unwrapped.config.physics.physics_hz,
               trained_physics=trained_physics(meta))
    if args.json:
        print_json(out)
        return out
    _print_results(args, s, results, written)
    return out
