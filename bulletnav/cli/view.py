"""``bulletnav view``: a warehouse in the PyBullet GUI with the dashboard, one robot or a fleet."""

from __future__ import annotations

import argparse

import numpy as np

from bulletnav.cli.args import FLEET_ROBOTS, SEED, add_command, add_env_arg, add_live_args, add_obstacles_arg, positive_seconds
from bulletnav.cli.envs import fleet_world_kwargs, world_kwargs
from bulletnav.cli.live import start_live
from bulletnav.errors import BulletnavError


def register(sub) -> None:
    """Add ``view`` to ``sub`` (``build_parser``'s subparsers)."""
    from bulletnav.sim.generators import WORLDS

    view = add_command(sub, "view", "look at a warehouse in the PyBullet GUI")
    add_env_arg(view)
    view.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world (default: procedural)")
    add_obstacles_arg(view)
    view.add_argument("--seed", type=SEED, default=0, help="warehouse seed (default 0)")
    view.add_argument("--seconds", type=positive_seconds, default=30.0, help="how long to show it (default 30)")
    view.add_argument("--robots", type=FLEET_ROBOTS, default=None, metavar="N",
                      help="show a fleet of N robots (1 to 16) driving errands with PID + A*, each in its own colour "
                           "with its goal marked (default: one robot turning in place; --env then defaults to the "
                           "fleet's aisle warehouse)")
    view.add_argument("--dynamic", action="store_true", help="with --robots: add forklifts, workers and pallet events")
    view.add_argument("--layout-style", choices=sorted(WORLDS), default=None,
                      help="with --robots: procedural layout generator (default the env's)")
    add_live_args(view)
    view.set_defaults(func=cmd_view)


def cmd_view(args: argparse.Namespace) -> int:
    """Open a warehouse in the PyBullet GUI with the dashboard; the robot turns in place (with
    ``--robots N``: a fleet running its errands). With ``--live``: no GUI, the same run streamed
    to Foxglove instead."""
    if args.dynamic and args.robots is None:
        raise BulletnavError("view --dynamic is for a fleet (--robots N); for one robot pass --env bulletnav/WarehouseDynamic-v0")
    live = start_live(args)
    try:
        return _view_fleet(args, live) if args.robots is not None else _view_one(args, live)
    finally:
        if live is not None:
            live.close()


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
