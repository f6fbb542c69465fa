"""``autoscoop stress``: run a controller over the stress cases (other piles, materials, start, sensing,
a randomised world), the same seeds in each, and say plainly which of the suite's thresholds hold."""

from __future__ import annotations

import argparse
import os
import time

from autoscoop.agents.loading import load_policy
from autoscoop.commands import check_output_dir, check_output_file, config_from_args, options, write_json
from autoscoop.core.version import __version__, dependency_versions
from autoscoop.envs import worlds_help
from autoscoop.evaluation.stress import case_names, run_stress, select_cases
from autoscoop.report.stress import stress_table, verdict, write_stress_report


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("stress", help="run a controller over the stress cases and check the thresholds",
                                   description=__doc__, epilog=worlds_help("the paper's world, and each case's "
                                                                           "keys over them"))
    options.add_policy_option(parser)
    options.add_episodes_option(parser, default=100, what="episodes per case")
    options.add_seed_option(parser, what="seed of the first episode; each case runs seeds SEED..SEED+EPISODES-1")
    parser.add_argument("--cases", default=None, metavar="NAME,NAME",
                        help=f"which cases (default: all): {', '.join(case_names())}")
    options.add_workers_option(parser)
    options.add_json_option(parser, "the rows (statistics, thresholds, pass flags, each episode)")
    options.add_out_option(parser, None, "folder for stress.md (the table) and stress.png (the heat map); without "
                                         "--json and --out the table is printed only")
    options.add_trust_option(parser)
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    cases = select_cases(args.cases)
    config = config_from_args(args)
    if args.json:  # fail before the first episode, not after the last
        check_output_file(args.json, "--json")
    if args.out:
        check_output_dir(args.out, "--out")
        for name in ("stress.md", "stress.png"):
            check_output_file(args.out / name, "--out")
    load_policy(args.policy, config, trust=args.trust)  # a bad --policy fails now, before any worker starts
    start = time.perf_counter()
    rows = run_stress(args.policy, config, args.episodes, seed=args.seed, cases=cases, workers=args.workers,
                      trust=args.trust)
    wall_s = time.perf_counter() - start
    print(stress_table(rows))  # first: the measurements are shown even if writing the files fails (a full disk)
    print(verdict(rows))
    seeds = list(range(args.seed, args.seed + args.episodes))
    if args.json:
        write_json(args.json, {
            "policy": args.policy, "episodes": args.episodes, "seeds": seeds, "workers": args.workers,
            "cpu_count": os.cpu_count(), "wall_time_s": wall_s, "all_passed": all(r.passed for r in rows),
            "autoscoop_version": __version__, "dependencies": dependency_versions(), "config": config.to_dict(),
            "rows": [r.as_dict() for r in rows]})
        print(f"wrote {args.json}")
    if args.out:
        intro = (f"`{args.policy}`, {args.episodes} episodes per case (seeds {seeds[0]}–{seeds[-1]}), "
                 f"{wall_s:.0f} s wall time on {os.cpu_count()} CPUs with {args.workers} worker(s).")
        files = write_stress_report(rows, args.out, title=f"Stress suite: {args.policy}", intro=intro)
        print(f"wrote {files.markdown} and {files.figure}")
    return 0
