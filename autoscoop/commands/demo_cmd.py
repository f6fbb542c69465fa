"""``autoscoop demo``: show the loader scooping on the default pile and print its metrics."""

from __future__ import annotations

import argparse

from autoscoop.agents.loading import load_policy
from autoscoop.commands import add_config_args, config_from_args
from autoscoop.evaluate import evaluate, format_table, summarize


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("demo", help="run the built-in controller on the default pile", description=__doc__)
    parser.add_argument("--policy", default="heuristic", help="controller to show (default: heuristic)")
    parser.add_argument("--episodes", type=int, default=10, help="episodes to run")
    add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    policy = load_policy(args.policy, config)
    print(format_table(summarize(evaluate(policy, config, args.episodes), config, args.policy)))
    return 0
