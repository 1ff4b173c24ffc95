"""Every command's ``--help``, byte for byte as ``bulletnav <cmd> --help`` printed it at a
100-column terminal before ``bulletnav/cli.py`` was split into the ``bulletnav/cli/`` package
(issue 52): the split moved code, not options, defaults or help text.

The snapshots in tests/data/cli_help/ were written by the console script itself
(``COLUMNS=100 bulletnav <cmd> --help > <cmd>.txt``, ``bulletnav.txt`` for the top level); the
test rebuilds each help in this process. A deliberate change to a command's options rewrites its
snapshot: ``python tests/test_cli_help.py --update``, and the diff shows the change.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

import pytest

import hang
from bulletnav.cli import build_parser

SNAPSHOTS = Path(__file__).resolve().parent / "data" / "cli_help"
TOP = "bulletnav"
"""The snapshot name of the top-level help."""
COLUMNS = "100"


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    assert len(actions) == 1
    return dict(actions[0].choices)


def helps() -> dict[str, str]:
    """``{name: help text}`` of the top-level parser and every subcommand (COLUMNS must be set)."""
    parser = build_parser()
    return {TOP: parser.format_help(), **{name: sub.format_help() for name, sub in _subparsers(parser).items()}}


SNAPSHOT_NAMES = sorted(p.stem for p in SNAPSHOTS.glob("*.txt"))


def test_every_command_has_a_snapshot_and_every_snapshot_a_command(monkeypatch):
    monkeypatch.setenv("COLUMNS", COLUMNS)
    assert len(SNAPSHOT_NAMES) >= 16  # the top level and 15 commands at the split
    assert sorted(helps()) == SNAPSHOT_NAMES


@pytest.mark.parametrize("name", SNAPSHOT_NAMES)
def test_help_is_the_snapshot_byte_for_byte(monkeypatch, name):
    monkeypatch.setenv("COLUMNS", COLUMNS)
    got = helps().get(name)
    assert got is not None, f"no command {name!r} (snapshot {name}.txt)"
    assert got == (SNAPSHOTS / f"{name}.txt").read_text(), f"`bulletnav {name} --help` differs from its snapshot"


def test_the_console_script_prints_the_snapshot():
    """The in-process help is the one a user sees (one command, as a subprocess)."""
    done = hang.run([sys.executable, "-m", "bulletnav.cli", "map", "--help"], "bulletnav map --help",
                    env={**os.environ, "COLUMNS": COLUMNS})
    assert done.returncode == 0 and done.stdout == (SNAPSHOTS / "map.txt").read_text()


if __name__ == "__main__" and sys.argv[1:] == ["--update"]:
    os.environ["COLUMNS"] = COLUMNS
    for stale in SNAPSHOTS.glob("*.txt"):
        stale.unlink()
    for name, text in helps().items():
        (SNAPSHOTS / f"{name}.txt").write_text(text)
        print(f"wrote {SNAPSHOTS / name}.txt")
