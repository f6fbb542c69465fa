"""``autoscoop``: the one command line. Each sub-command lives in ``autoscoop.commands``."""

from __future__ import annotations

import argparse
import importlib
import sys

from autoscoop.core.config import ConfigError
from autoscoop.core.safe_files import describe_os_error
from autoscoop.core.version import __version__

COMMANDS = [
    "autoscoop.commands.demo_cmd",
    "autoscoop.commands.report_cmd",
    "autoscoop.commands.compare_cmd",
    "autoscoop.commands.teleop_cmd",
    "autoscoop.commands.evaluate_cmd",
    "autoscoop.commands.stress_cmd",
    "autoscoop.commands.shift_cmd",
    "autoscoop.commands.train_cmd",
    "autoscoop.commands.adapt_cmd",
    "autoscoop.commands.sweep_cmd",
    "autoscoop.commands.bench_cmd",
    "autoscoop.commands.config_cmd",
    "autoscoop.commands.payload_cmd",
    "autoscoop.commands.machine_cmd",
    "autoscoop.commands.export_cmd",
    "autoscoop.commands.ros_cmd",
    "autoscoop.commands.ros2_cmd",
    "autoscoop.commands.replay_cmd",
]
"""Modules that each offer ``register(subparsers)``; a new command adds one line here."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="autoscoop", description="A wheel loader that learns to scoop.")
    parser.add_argument("--version", action="version", version=f"autoscoop {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(name).register(subparsers)
    return parser


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not getattr(args, "func", None):
        parser.print_help()
        return 2
    try:
        return int(args.func(args) or 0)
    except (ConfigError, ValueError) as error:
        print(f"autoscoop {args.command}: error: {error}", file=sys.stderr)
        return 2
    except OSError as error:  # a full disk, a read-only folder, a file that went away: the path and the reason
        print(f"autoscoop {args.command}: error: {describe_os_error(error)}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print(f"autoscoop {args.command}: interrupted", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
