"""``bulletnav view``: a warehouse in the PyBullet GUI with the dashboard, one robot or a fleet;
with ``--live ... --live-control``, one robot driven from Foxglove."""

from __future__ import annotations

import argparse

import numpy as np

from bulletnav.cli import interrupts
from bulletnav.cli.args import (
    FLEET_ROBOTS,
    MCAP_FILE,
    SEED,
    add_command,
    add_env_arg,
    add_live_args,
    add_live_control_args,
    add_obstacles_arg,
    add_overwrite_arg,
    add_trust_pickle_arg,
    positive_seconds,
)
from bulletnav.cli.envs import fleet_world_kwargs, world_kwargs
from bulletnav.cli.live import start_live
from bulletnav.cli.output import refuse_existing_files
from bulletnav.errors import BulletnavError

CONTROLLERS = {"astar": "PID + A*", "rrt": "PID + RRT", "pid": "PID", "dwa": "move_base DWA"}
"""``--controller``'s names (anything else is a model file) and how the report names them."""
DEFAULT_SECONDS = 30.0
"""How long ``view`` shows a warehouse without ``--seconds`` (a driving session: until Ctrl-C)."""


def register(sub) -> None:
    """Add ``view`` to ``sub`` (``build_parser``'s subparsers)."""
    from bulletnav.sim.generators import WORLDS

    view = add_command(sub, "view", "look at a warehouse in the PyBullet GUI")
    add_env_arg(view)
    view.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world (default: procedural)")
    add_obstacles_arg(view)
    view.add_argument("--seed", type=SEED, default=0, help="warehouse seed (default 0)")
    view.add_argument("--seconds", type=positive_seconds, default=None,
                      help=f"how long to show it (default {DEFAULT_SECONDS:g}; with --live-control: until Ctrl-C)")
    view.add_argument("--robots", type=FLEET_ROBOTS, default=None, metavar="N",
                      help="show a fleet of N robots (1 to 16) driving errands with PID + A*, each in its own colour "
                           "with its goal marked (default: one robot turning in place; --env then defaults to the "
                           "fleet's aisle warehouse)")
    view.add_argument("--dynamic", action="store_true", help="with --robots: add forklifts, workers and pallet events")
    view.add_argument("--layout-style", choices=sorted(WORLDS), default=None,
                      help="with --robots: procedural layout generator (default the env's)")
    add_live_args(view)
    add_live_control_args(view)
    view.add_argument("--controller", default=None, metavar="NAME|MODEL",
                      help="with --live-control: what drives to a goal: astar (PID + A*, the default), rrt (PID + RRT), "
                           "pid (PID straight at it), dwa (ROS move_base DWA, BARN's parameters) or a model zip written "
                           "by train (or its run folder)")
    view.add_argument("--record", type=MCAP_FILE, metavar="PATH",
                      help="with --live-control: also record the session into PATH, an MCAP file (docs/ros.md)")
    add_overwrite_arg(view, "--record files")
    add_trust_pickle_arg(view)
    view.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    """Open a warehouse in the PyBullet GUI with the dashboard; the robot turns in place (with
    ``--robots N``: a fleet running its errands). With ``--live``: no GUI, the same run streamed
    to Foxglove instead."""
    if args.dynamic and args.robots is None:
        raise BulletnavError("view --dynamic is for a fleet (--robots N); for one robot pass --env bulletnav/WarehouseDynamic-v0")
    _check_control_args(args)
    refuse_existing_files(args, "record")
    control = _control_env(args) if args.live_control else None  # a model or env that cannot load: before the port
    try:
        live = start_live(args)
    except BaseException:
        if control is not None:
            control[0].close()
        raise
    try:
        if control is not None:
            return _view_control(args, live, *control)
        if args.seconds is None:
            args.seconds = DEFAULT_SECONDS
        return _view_fleet(args, live) if args.robots is not None else _view_one(args, live)
    finally:
        if live is not None:
            live.close()


def _check_control_args(args: argparse.Namespace) -> None:
    """The options of a driving session: none of them without ``--live-control``, no fleet with it."""
    if not args.live_control:
        given = [f"--{name.replace('_', '-')}" for name in ("controller", "record", "trust_pickle") if getattr(args, name)]
        if given:
            raise BulletnavError(f"{', '.join(given)}: for a session driven from Foxglove: give --live [HOST:]PORT "
                                 "--live-control too")
    elif args.robots is not None:
        raise BulletnavError("--live-control drives one robot: leave out --robots")


def _view_one(args: argparse.Namespace, live) -> int:
    import time

    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.viz import Dashboard

    kwargs = world_kwargs(args)
    if args.layout_style:
        kwargs["layout_style"] = args.layout_style
    env = gym.make(args.env_id, render_mode=None if live else "human", **kwargs)
    if live is not None:
        from bulletnav.ros.record import McapRecorder

        env = McapRecorder(env, None, live=live)
    try:
        env.reset(seed=args.seed)
        dashboard = Dashboard(env) if live is None else _NoDashboard()
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
        shown = "streamed" if live else "viewed"
        print(f"{shown} {env.unwrapped.scene.layout.name or 'procedural'} warehouse for {args.seconds:g} s "
              f"({steps} control steps, {steps / args.seconds:.1f} steps/s with the {'stream' if live else 'dashboard'})")
    finally:
        env.close()
    return 0


class _NoDashboard:
    """The dashboard's hooks doing nothing (``--live``: Foxglove is the dashboard)."""

    def on_reset(self, *args) -> None:
        pass

    def on_step(self, *args) -> None:
        pass


def _view_fleet(args: argparse.Namespace, live) -> int:
    """``view --robots N``: a fleet in the GUI, each robot tinted in its colour with its goal marked,
    driving its errands with PID + A* (the independent controller); with ``--live`` streamed instead."""
    import time

    from bulletnav.fleet.controllers import make_controller
    from bulletnav.fleet.env import FleetEnv
    from bulletnav.viz.fleet_gui import FleetDashboard

    kwargs = fleet_world_kwargs(args, args.env_id if args.env_given else None)
    env = FleetEnv(num_robots=args.robots, render_mode=None if live else "human", dynamic=args.dynamic, **kwargs)
    stream = None
    if live is not None:
        from bulletnav.ros.fleet_record import FleetMcapRecorder

        stream = FleetMcapRecorder(None, live=live)
    try:
        controller = make_controller("independent", env)
        observations, infos = env.reset(seed=args.seed)
        controller.reset(infos)
        dashboard = FleetDashboard(env) if live is None else _NoDashboard()
        dashboard.on_reset(infos)
        if stream is not None:
            stream(env, infos)
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
            if stream is not None:
                stream(env, infos)
        errands = sum(int(info["errands_completed"]) for info in infos.values())
        print(f"{'streamed' if live else 'viewed'} a fleet of {args.robots} robots for {args.seconds:g} s ({steps} control "
              f"steps, {steps / args.seconds:.1f} steps/s; {errands} errands done this episode)")
    finally:
        if stream is not None:
            stream.close(ok=False)
        env.close()
    return 0


def _control_policy(args: argparse.Namespace):
    """``(env kwargs, make(env) -> policy, name)`` of ``--controller``: a navigator, DWA or a model
    (loaded as ``evaluate`` loads one, its env settings under the env's; the env id its own
    unless ``--env`` is given)."""
    name = args.controller or "astar"
    if name in ("astar", "rrt", "pid"):
        from bulletnav.control.navigator import Navigator, NavigatorConfig

        config = NavigatorConfig(planner="none" if name == "pid" else name)
        return {}, (lambda env: Navigator(env.unwrapped.scene, config)), CONTROLLERS[name]
    if name == "dwa":
        from bulletnav.control.dwa import MoveBaseDWA, dwa_env_kwargs, load_dwa_params

        params = load_dwa_params(None)
        return dwa_env_kwargs(params, {}), (lambda env: MoveBaseDWA(env.unwrapped.scene, params)), CONTROLLERS[name]
    from pathlib import Path

    from bulletnav.cli.envs import check_env_id
    from bulletnav.rl.compat import check_model_fits
    from bulletnav.rl.envs import evaluation_env_kwargs
    from bulletnav.rl.io import load_model, model_file
    from bulletnav.rl.policy import SB3Policy

    path = model_file(name)
    if not path.exists() and not Path(name).suffix:
        raise BulletnavError(f"--controller {name}: neither one of {', '.join(CONTROLLERS)} nor a model file")
    model, meta, vecnorm = load_model(path, trust_pickle=args.trust_pickle)
    recorded = meta.get("env_id")
    if not args.env_given and isinstance(recorded, str) and recorded != args.env_id:
        check_env_id(recorded)  # the model's own env, unless --env names another
        args.env_id = recorded

    def policy(env):
        check_model_fits(model, env, path, args.env_id)
        return SB3Policy(model, vecnorm)

    return evaluation_env_kwargs(meta.get("env_kwargs", {})), policy, f"{str(meta.get('algo', 'model')).upper()} {path}"


def _control_env(args: argparse.Namespace) -> tuple:
    """``(env, policy, name)`` of a driving session: the env with the goal task
    (:class:`~bulletnav.ros.live_control.GoalPoseTask`, no step limit) and ``--controller``."""
    import gymnasium as gym

    import bulletnav  # noqa: F401
    from bulletnav.ros.live_control import NO_STEP_LIMIT, TASK_NAME

    kwargs, make_policy, name = _control_policy(args)
    kwargs.update(world_kwargs(args))
    kwargs["task_name"] = TASK_NAME
    try:
        env = gym.make(args.env_id, max_episode_steps=NO_STEP_LIMIT, **kwargs)
    except (TypeError, ValueError) as exc:  # an env whose own task cannot be replaced (BARN-v0)
        raise BulletnavError(f"--env {args.env_id} cannot take goals from Foxglove: {str(exc).split(' was raised ')[0]}") from None
    try:
        return env, make_policy(env), name
    except BaseException:
        env.close()
        raise


def _view_control(args: argparse.Namespace, live, env, policy, name: str) -> int:
    """``view --live ... --live-control``: one robot waiting for goals from Foxglove
    (:class:`~bulletnav.ros.live_control.LiveControl`), until ``--seconds`` or Ctrl-C."""
    from bulletnav.ros.live_control import GOAL_TOPIC, TELEOP_TOPIC, LiveControl

    try:
        session = LiveControl(env, policy, live, record=args.record, overwrite=args.overwrite,
                              on_event=lambda line: print(line, flush=True))
    except BaseException:
        env.close()
        raise
    until = "Ctrl-C" if args.seconds is None else f"{args.seconds:g} s"
    print(f"driving with {name} behind the safety shield until {until}: publish {GOAL_TOPIC} (3D panel: Publish pose) "
          f"or {TELEOP_TOPIC} (Teleop panel)", flush=True)

    def summary() -> str:
        kept = f"; recording: {args.record}" if args.record else ""
        return (f"drove {session.time_s:.1f} s of simulated time ({session.steps} steps): {session.goals_taken} goal(s) "
                f"taken, {session.goals_reached} reached, {session.goals_refused} refused, {session.collisions} "
                f"collision(s){kept}")

    interrupts.on_interrupt(lambda: f"interrupted: {summary()}")
    try:
        session.reset(seed=args.seed)
        session.run(args.seconds)
    except KeyboardInterrupt:
        with interrupts.deferred():
            session.close()  # the session up to now is whole: its recording is kept
        raise
    except BaseException:
        session.abort()
        raise
    session.close()
    print(summary())
    return 0
