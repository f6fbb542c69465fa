"""``autoscoop config``: print every config key with its value, unit and allowed range, or write YAML."""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.commands import config_from_args, options
from autoscoop.core.config import save_yaml


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("config", help="show or write the configuration", description=__doc__)
    parser.add_argument("--write", type=Path, metavar="FILE.yaml", help="write the (overridden) config to this YAML file")
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    if args.write:
        save_yaml(config, args.write)
        print(f"wrote {args.write}")
    else:
        print(config.describe())
    return 0
