"""``teleop config``: print the documented defaults, or check a config file."""

from __future__ import annotations

import argparse

from teleop.commands.common import add_config_options, config_from_args


def register(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Add the ``config`` subcommand."""
    p = sub.add_parser("config", help="print the documented default config, or check a file")
    add_config_options(p)
    p.add_argument("--defaults", action="store_true",
                   help="print the documented defaults (what config/default.toml holds)")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Print defaults or validate ``--config``/``--set``."""
    from teleop.config import default_toml

    if args.defaults:
        print(default_toml(), end="")
        return 0
    config_from_args(args)
    print(f"{args.config or '<defaults>'}: ok")
    return 0
