"""``autoscoop``: the one command line. Each sub-command lives in ``autoscoop.commands``."""

from __future__ import annotations

import argparse
import importlib
import os
import sys

from autoscoop.core.machine import MACHINE_ENV, MachineError, load_machine
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
WITHOUT_MACHINE = {"machine"}
"""Commands that take no ``--machine`` (``machine check`` and ``new`` name their machine as an argument)."""
MACHINE_HELP = ("the loader: a shipped machine's name (komodo) or a machine folder (docs/machines.md); "
                "default: $AUTOSCOOP_MACHINE, else komodo")


class CommandParser(argparse.ArgumentParser):
    """An argparse parser that remembers its sub-command groups, so the leaves can be found (every sub-parser
    made from it is one too)."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.subcommand_groups: list[argparse.Action] = []

    def add_subparsers(self, **kwargs):
        group = super().add_subparsers(**kwargs)
        self.subcommand_groups.append(group)
        return group


def leaf_parsers(parser: argparse.ArgumentParser) -> list[argparse.ArgumentParser]:
    """The parsers under ``parser`` that run something (those with no sub-commands of their own)."""
    groups = getattr(parser, "subcommand_groups", [])
    if not groups:
        return [parser]
    return [leaf for group in groups for child in dict.fromkeys(group.choices.values()) for leaf in leaf_parsers(child)]


def select_machine(argv: list[str]) -> None:
    """Choose the machine of this process from ``--machine`` before any module reads it (it is read once, when
    ``autoscoop.core.kinematics`` is first imported); worker processes inherit it through ``$AUTOSCOOP_MACHINE``.

    Raises:
        MachineError: the machine is not valid, or this process already runs another one.
    """
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("--machine")
    known, _ = pre.parse_known_args(argv)
    if known.machine is None:
        return
    machine = load_machine(known.machine)
    loaded = sys.modules.get("autoscoop.core.kinematics")
    if loaded is not None and loaded.MACHINE.digest != machine.digest:
        raise MachineError(f"--machine {known.machine}: this process already runs machine {loaded.MACHINE.name}; "
                           "a machine is chosen once per process (run autoscoop again)")
    os.environ[MACHINE_ENV] = str(machine.folder)


def build_parser() -> argparse.ArgumentParser:
    parser = CommandParser(prog="autoscoop", description="A wheel loader that learns to scoop.")
    parser.add_argument("--version", action="version", version=f"autoscoop {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(name).register(subparsers)
    for command, child in subparsers.choices.items():
        if command not in WITHOUT_MACHINE:
            for leaf in leaf_parsers(child):
                leaf.add_argument("--machine", metavar="NAME|DIR", help=MACHINE_HELP)
    return parser


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    try:
        select_machine(argv)
    except MachineError as error:
        print(f"autoscoop: error: {error}", file=sys.stderr)
        return 2
    try:
        from autoscoop.core.config import ConfigError  # noqa: PLC0415 - after the machine is chosen
    except ValueError as error:  # the machine's scene or robot_preset does not fit the config schema
        print(f"autoscoop: error: {error}", file=sys.stderr)
        return 2
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
