"""The ``bulletnav`` command: thin subcommands over the library. Only this package prints.

One module per command group, each adding its own subcommands (``register``) with their options
and handlers; :func:`build_parser` only assembles them, in the order ``--help`` lists them.
Shared pieces: :mod:`~bulletnav.cli.args` (argument types and option groups),
:mod:`~bulletnav.cli.envs` (the env a command runs on), :mod:`~bulletnav.cli.output` (``--json``'s
one document, report figures, output files) and :mod:`~bulletnav.cli.episodes` (single-robot
episodes with their video, plot and recordings).
"""

from __future__ import annotations

import contextlib
import logging
import sys
from collections.abc import Sequence

from bulletnav.cli import bench, benchmark, evaluate, fleet, interrupts, models, navigate, ros, sweep, train, view
from bulletnav.cli.args import DEFAULT_ENV_ID, Parser
from bulletnav.cli.envs import bulletnav_env_ids, check_env_id
from bulletnav.cli.evaluate import DEFAULT_MODEL, SHIPPED_MODELS
from bulletnav.cli.output import json_mode
from bulletnav.errors import BulletnavError

__all__ = ["DEFAULT_ENV_ID", "DEFAULT_MODEL", "SHIPPED_MODELS", "build_parser", "bulletnav_env_ids", "check_env_id",
           "main"]

COMMAND_GROUPS = (navigate, train, sweep, evaluate, models, view, benchmark, fleet, ros, bench)
"""The command modules, in the order their commands appear in ``bulletnav --help``."""



def build_parser() -> Parser:
    """The ``bulletnav`` parser: ``-v`` and one subcommand from each of :data:`COMMAND_GROUPS`."""
    parser = Parser(
        prog="bulletnav",
        description="PyBullet warehouse navigation: classical and learned controllers on the same episodes.")
    parser.add_argument("-v", "--verbose", action="store_true", help="log debug messages")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    for group in COMMAND_GROUPS:
        group.register(sub)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``bulletnav`` with ``argv`` (default ``sys.argv[1:]``); the exit status: 0, 2 on a
    library error (one line on stderr), or 128 + the signal's number when interrupted (130 for
    Ctrl-C, 143 for SIGTERM: one line on stderr saying what was kept and how to go on,
    :mod:`~bulletnav.cli.interrupts`)."""
    argv = list(sys.argv[1:] if argv is None else argv)
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(level=logging.DEBUG if args.verbose else logging.WARNING, format="%(levelname)s %(name)s: %(message)s")
    interrupts.start(argv, args.command)
    try:
        with interrupts.signals_as_interrupt():
            if getattr(args, "env_id", None) is not None:
                check_env_id(args.env_id)
            with json_mode() if getattr(args, "json", False) else contextlib.nullcontext():
                return int(args.func(args) or 0)
    except BulletnavError as exc:
        if interrupts.received:  # a signal that ended a C call (an SQLite query) as its error
            return _interrupted(args.command)
        print(f"bulletnav {args.command}: error: {' '.join(str(exc).split())}", file=sys.stderr)  # one line
        return 2
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: what was kept and how to go on, one line
        return _interrupted(args.command)


def _interrupted(command: str) -> int:
    with interrupts.deferred():
        print(interrupts.interrupted_line(command), file=sys.stderr, flush=True)
    return interrupts.exit_status()
