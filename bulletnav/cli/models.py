"""``bulletnav convert-model``: a model's pickle-free files beside its SB3 zip."""

from __future__ import annotations

import argparse

from bulletnav.cli.args import add_command, add_trust_pickle_arg


def register(sub) -> None:
    """Add ``convert-model`` to ``sub`` (``build_parser``'s subparsers)."""
    conv = add_command(sub, "convert-model", "write the pickle-free files (NAME.safetensors + the sidecar's policy and "
                                             "statistics) beside an SB3 model zip")
    conv.add_argument("model", metavar="MODEL", help="SB3 model zip (with its .json and statistics beside it, if any)")
    add_trust_pickle_arg(conv)
    conv.set_defaults(func=cmd_convert_model)


def cmd_convert_model(args: argparse.Namespace) -> int:

    from bulletnav.rl.io import model_file
    from bulletnav.rl.safe import convert_model, weights_path

    path = model_file(args.model)
    meta = convert_model(path, trust_pickle=args.trust_pickle)
    print(f"wrote {weights_path(path)} and {path.with_suffix('.json')} ({meta['policy']['algo'].upper()}, "
          f"{meta['policy']['class'].rsplit('.', 1)[1]}, statistics: {'yes' if meta['normalization'] else 'none'}); "
          "every loader now reads these and never unpickles")
    return 0
