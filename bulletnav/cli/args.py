"""The argument types and option groups that several commands share.

Every type checks its value before anything runs and refuses it in one line naming the value and
what is allowed (argparse prints ``bulletnav CMD: error: ...`` and exits with status 2)."""

from __future__ import annotations

import argparse

from bulletnav.errors import BulletnavError
from bulletnav.ros.live import SPEED_RANGE

DEFAULT_ENV_ID = "bulletnav/Warehouse-v0"
"""The env every subcommand uses unless ``--env`` names another."""


class Parser(argparse.ArgumentParser):
    """Usage errors as one line, ``bulletnav CMD: error: ...`` (exit 2), like the library's errors."""

    def error(self, message: str):  # type: ignore[override]
        self.exit(2, f"{self.prog}: error: {message} (see {self.prog} --help)\n")


def add_command(sub, name: str, help_: str) -> argparse.ArgumentParser:
    """A subcommand ``name`` on ``sub`` (``build_parser``'s subparsers), its help also its description."""
    return sub.add_parser(name, help=help_, description=help_)


# ---------------------------------------------------------------------------------------
# argument types

def int_type(minimum: int, maximum: int | None = None, what: str = "a whole number"):
    """An argparse type: an integer in ``[minimum, maximum]``, else one line naming the value and what is allowed."""
    allowed = f"{what} from {minimum} to {maximum}" if maximum is not None else f"{what} >= {minimum}"

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {text!r}") from None
        if value < minimum or (maximum is not None and value > maximum):
            raise argparse.ArgumentTypeError(f"expected {allowed}, got {value}")
        return value

    parse.__name__ = "int"  # argparse's fallback message names the type
    return parse


COUNT = int_type(1)
"""Episodes, envs, workers, rounds, resets, frequencies: at least 1."""
NON_NEGATIVE = int_type(0)
"""Seeds, obstacle counts, indices, and counts where 0 means "none" or "the default"."""
SEED = int_type(0, 2**32 - 1, "a seed, a whole number")
FLEET_ROBOTS = int_type(1, 16, "a robot count, a whole number")
"""Robots in a fleet: 1 to 16 (``bulletnav.fleet.MAX_ROBOTS``)."""


def float_type(accept, what: str, name: str):
    """An argparse type: a float for which ``accept(value)`` holds, else the one line
    ``expected WHAT, got 'TEXT'``."""

    def parse(text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}") from None
        if not accept(value):
            raise argparse.ArgumentTypeError(f"expected {what}, got {text!r}")
        return value

    parse.__name__ = parse.__qualname__ = name
    return parse


_INF = float("inf")
non_negative_seconds = float_type(lambda v: 0 <= v < _INF, "seconds >= 0", "non_negative_seconds")
"""Seconds >= 0 (``--frame-at``)."""
FRACTION = float_type(lambda v: 0 < v <= 1, "a rate above 0 and at most 1", "FRACTION")
"""A rate in (0, 1] (``--stop-at-success``)."""
positive_seconds = float_type(lambda v: 0 < v < _INF, "seconds > 0", "positive_seconds")
"""Seconds > 0, finite (``--duration``, ``--seconds``)."""
finite_metres = float_type(lambda v: -1.0e6 <= v <= 1.0e6, "a finite coordinate in m (within 1,000 km)", "finite_metres")
"""A coordinate in metres, finite (``map --plan-to X Y``)."""
MIN_SPEED = float_type(lambda v: -_INF < v <= 0, "a speed <= 0 m/s", "MIN_SPEED")
"""``--min-speed``: the lowest commanded speed, m/s <= 0 (negative: the robot may back up)."""
speed_factor = float_type(lambda v: v == 0 or SPEED_RANGE[0] <= v <= SPEED_RANGE[1],
                          "a speed of 0 (as fast as it goes) or 0.001-1000 (1: real time)", "speed_factor")
"""``--speed``: simulated seconds per wall-clock second, 0 (unpaced) or within :data:`SPEED_RANGE`."""


def hz_list(text: str) -> tuple[int, ...]:
    """``--rates``: comma-separated positive integers (Hz)."""
    try:
        rates = tuple(int(x) for x in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected comma-separated rates in Hz, e.g. 240,120, got {text!r}") from None
    if not rates or min(rates) <= 0:
        raise argparse.ArgumentTypeError(f"rates must be positive integers (Hz), got {text!r}")
    return rates


def file_type(suffixes: tuple[str, ...], what: str):
    """An argparse type: a file path ending in one of ``suffixes`` (checked before anything runs)."""

    def parse(text: str) -> str:
        from pathlib import Path

        suffix = Path(text).suffix.lower()
        if suffix not in suffixes:
            raise argparse.ArgumentTypeError(f"{text!r}: {what} is written as {' or '.join(suffixes)}, "
                                             f"not {suffix or 'a name without a suffix'!r}")
        return text

    parse.__name__ = "path"
    return parse


VIDEO_FILE = file_type((".mp4", ".gif"), "a video")
PNG_FILE = file_type((".png",), "a plot")
MCAP_FILE = file_type((".mcap",), "a ROS 2 recording")
MODEL_FILE = file_type((".zip",), "a model")
DATASET_HELP = ("also write the episodes (observations, actions, rewards, terminations, truncations, infos' scalars) "
                "as the Minari dataset NAME ([namespace/]name-vN) under MINARI_DATASETS_PATH (docs/datasets.md)")
RECORD_HELP = ("also write every episode as ROS 2 messages (scan, odom, imu, tf, cmd_vel, goal, plan, maps, movers) "
               "into PATH, an MCAP file (docs/ros.md)")


# ---------------------------------------------------------------------------------------
# option groups

class EnvIdAction(argparse.Action):
    """``--env ID``; also records that it was given (``env_given``), so a model's own env can be the default."""

    def __call__(self, parser, namespace, values, option_string=None) -> None:
        setattr(namespace, self.dest, values)
        namespace.env_given = True


def add_env_arg(parser: argparse.ArgumentParser, default_help: str = DEFAULT_ENV_ID) -> None:
    parser.add_argument("--env", dest="env_id", default=DEFAULT_ENV_ID, metavar="ID", action=EnvIdAction,
                        help=f"registered bulletnav env id, e.g. bulletnav/WarehouseAisles-v0 (default {default_help})")
    parser.set_defaults(env_given=False)


def add_overwrite_arg(parser: argparse.ArgumentParser, what: str) -> None:
    parser.add_argument("--overwrite", action="store_true",
                        help=f"replace {what} that already exist (default: refuse, so one run never replaces another's)")


def add_episode_outputs(parser: argparse.ArgumentParser) -> None:
    """The files an episode-running command can write beside its report (``navigate``, ``evaluate``):
    ``--video``, ``--plot``, ``--record``, ``--dataset`` and ``--overwrite``."""
    parser.add_argument("--video", type=VIDEO_FILE, metavar="PATH", help="record every episode to PATH (.mp4 or .gif)")
    parser.add_argument("--plot", type=PNG_FILE, metavar="PNG", help="write all episodes' paths over their maps")
    parser.add_argument("--record", type=MCAP_FILE, metavar="PATH", help=RECORD_HELP)
    parser.add_argument("--dataset", metavar="NAME", help=DATASET_HELP)
    add_overwrite_arg(parser, "--video, --plot and --record files")


def live_address(text: str) -> str:
    """``--live``: ``[HOST:]PORT`` (checked before anything runs)."""
    from bulletnav.ros.live import parse_address

    try:
        parse_address(text)
    except BulletnavError as e:
        raise argparse.ArgumentTypeError(str(e).split(": ", 1)[1]) from None
    return text


def add_live_args(parser: argparse.ArgumentParser) -> None:
    """``--live [HOST:]PORT`` and ``--speed X`` (``navigate``, ``evaluate``, ``demo``, ``fleet``, ``view``)."""
    parser.add_argument("--live", type=live_address, metavar="[HOST:]PORT",
                        help="stream the run's ROS 2 messages (those of --record) to Foxglove: a Foxglove WebSocket "
                             "server on PORT, on 127.0.0.1 unless HOST is given (0.0.0.0 lets any machine that reaches "
                             "the port watch); the run then goes at real time (see --speed)")
    parser.add_argument("--speed", type=speed_factor, default=None, metavar="X",
                        help="with --live: simulated seconds per wall-clock second (default 1, real time; 0: as fast as it goes)")


def live_origin(text: str) -> str:
    """``--live-allow-origin``: an origin as a browser sends it (checked before anything runs)."""
    from bulletnav.ros.live_gate import normalize_origin

    try:
        return normalize_origin(text)
    except BulletnavError as e:
        raise argparse.ArgumentTypeError(f"{text!r}: {str(e).split(': ', 1)[1]}") from None


def add_live_control_args(parser: argparse.ArgumentParser) -> None:
    """``--live-control`` and ``--live-allow-origin ORIGIN`` (``view``): Foxglove drives the robot."""
    parser.add_argument("--live-control", action="store_true",
                        help="with --live: let Foxglove drive one robot that waits for goals: /goal_pose (the 3D panel's "
                             "Publish pose) sets the goal, /cmd_vel (the Teleop panel) drives it for 0.5 s a message, "
                             "always through the safety shield; web pages of other sites cannot connect (docs/ros.md)")
    parser.add_argument("--live-allow-origin", type=live_origin, action="append", default=None, metavar="ORIGIN",
                        help="with --live-control: also let web pages of ORIGIN (scheme://host[:port]) connect and drive "
                             "(repeatable; allowed always: no Origin, i.e. Foxglove's desktop app and scripts, loopback "
                             "pages and https://app.foxglove.dev)")


def add_obstacles_arg(parser: argparse.ArgumentParser, default: str = "the env's; 31 on Warehouse-v0") -> None:
    parser.add_argument("--obstacles", type=NON_NEGATIVE, default=None, metavar="K",
                        help=f"obstacles in a procedural warehouse (default: {default})")


def add_shield_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--shield", action="store_true",
                        help="behind the safety shield: a command whose stopping sweep would touch what the lidar sees or "
                             "a mover is replaced by the closest safe one (reports how often)")


def add_trust_pickle_arg(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--trust-pickle", action="store_true",
                        help="let the model's pickled entries and a *_vecnormalize.pkl be unpickled: that RUNS CODE the "
                             "files hold; only for files you trust (default: never; see docs/safety.md)")


def add_physics_arg(parser: argparse.ArgumentParser) -> None:
    from bulletnav.config import PHYSICS_PROFILES

    parser.add_argument("--physics", choices=list(PHYSICS_PROFILES), default=None,
                        help="physics profile: default (240 Hz), fast (the measured cheaper rate, "
                             "docs/performance/physics.md) or kinematic (no physics engine: exact kinematics and "
                             "closed-form lidar and contacts, docs/env.md); default: the model's, else the env's")


def add_world_args(parser: argparse.ArgumentParser) -> None:
    add_env_arg(parser)
    parser.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world (default: procedural)")
    add_obstacles_arg(parser)
    parser.add_argument("--seed", type=SEED, default=0, help="random seed (default 0)")


def add_mission_args(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--goals", type=COUNT, default=None, metavar="K",
                        help="a mission of K goals (1-8) on any env (default: the env's own task)")
    parser.add_argument("--order", choices=["fixed", "free"], default=None,
                        help="mission goal order: fixed (as given) or free (any; default free)")
    from bulletnav.envs.shifts import PERTURBATIONS

    parser.add_argument("--perturb", choices=list(PERTURBATIONS), default=None, metavar="NAME",
                        help=f"evaluate under a named shift of robot, floor or sensors: {', '.join(PERTURBATIONS)} "
                             "(the same episodes; default none)")


def add_fleet_world_args(parser: argparse.ArgumentParser, env_default: str) -> None:
    from bulletnav.sim.generators import WORLDS

    parser.add_argument("--env", dest="env_id", default=None, metavar="ID",
                        help=f"start from this registered bulletnav env's settings (default {env_default})")
    parser.add_argument("--world", metavar="FILE", help="layout YAML, map_server map YAML or Gazebo .world, with "
                                                        "its stations: if it names them (default: a procedural warehouse)")
    parser.add_argument("--layout-style", choices=sorted(WORLDS), default=None,
                        help="procedural layout generator (default: the env's, aisles; pick stations need racks)")
    add_obstacles_arg(parser, "the env's")
