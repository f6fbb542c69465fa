"""``autoscoop eval``: run a controller for N episodes and report fill factor, cycle time, success, spillage.

Exit code 3 when no episode succeeded (no scoop reached the terminal point loaded), after the table and the files
are written; --allow-empty makes that 0. Usage and input errors exit 2.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from autoscoop.agents.loading import load_policy
from autoscoop.commands import (
    check_output_file,
    config_from_args,
    options,
    prepare_records_dir,
    records_dir_lock,
    warn_if_frame_overridden,
    write_json,
)
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import config_for_policy
from autoscoop.envs import worlds_help
from autoscoop.evaluation.evaluate import evaluate, format_table, summarize


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("eval", help="evaluate a controller over N episodes",
                                   description=__doc__, epilog=worlds_help())
    options.add_policy_option(parser)
    options.add_episodes_option(parser, default=100)
    options.add_seed_option(parser)
    options.add_json_option(parser, "the summary (and each episode)")
    parser.add_argument("--records", type=Path, metavar="DIR",
                        help="save each episode's record here (redraw figures with `autoscoop report DIR`); "
                             "the folder must be new or empty, unless --overwrite")
    options.add_overwrite_option(parser, "with --records: first remove the folder's episode_*.npz records")
    options.add_trust_option(parser)
    options.add_allow_empty_option(parser)
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    config = config_from_args(args)
    if args.json:  # fail before the first episode, not after the last
        check_output_file(args.json, "--json")
    if not args.records:
        return _run(args, config)
    with records_dir_lock(args.records):  # held from the empty-folder check to the last record
        prepare_records_dir(args.records, args.overwrite)
        return _run(args, config)


def _run(args: argparse.Namespace, config: ScoopConfig) -> int:
    policy = load_policy(args.policy, config, trust=args.trust)
    warn_if_frame_overridden(args, policy, config)
    results = evaluate(policy, config, args.episodes, seed=args.seed, records_dir=args.records,
                       records_meta={"policy": args.policy})
    summary = summarize(results, config_for_policy(policy, config), args.policy)  # the frame it ran in
    print(format_table(summary))
    if args.json:
        write_json(args.json, summary)
        print(f"wrote {args.json}")
    if args.records:
        print(f"wrote {args.episodes} episode records to {args.records}")
    if not any(result.success for result in results):
        reached = sum(result.reached for result in results)
        return options.nothing_done("eval", f"no episode succeeded: none of {len(results)} reached the terminal point "
                                            f"loaded ({reached} reached it with too little in the bucket)",
                                    args.allow_empty)
    return 0
