"""``autoscoop stress``: run a controller over the stress cases (other piles, materials, start, sensing,
a randomised world), the same seeds in each, and say plainly which of the acceptance's thresholds hold."""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from autoscoop.agents.loading import load_policy
from autoscoop.commands import (
    add_config_args,
    check_output_dir,
    check_output_file,
    config_from_args,
    seed_int,
    write_json,
)
from autoscoop.core.version import __version__
from autoscoop.evaluation.stress import case_names, run_stress, select_cases
from autoscoop.report.stress import stress_table, verdict, write_stress_report


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("stress", help="run a controller over the stress cases and check the thresholds",
                                   description=__doc__)
    parser.add_argument("--policy", default="default", help="default (shipped policy), heuristic or a policy file")
    parser.add_argument("--episodes", type=int, default=100, help="episodes per case (default 100)")
    parser.add_argument("--seed", type=seed_int, default=0,
                        help="seed of the first episode; each case runs seeds SEED..SEED+EPISODES-1 (default 0)")
    parser.add_argument("--cases", default=None, metavar="NAME,NAME",
                        help=f"which cases (default: all): {', '.join(case_names())}")
    parser.add_argument("--workers", type=int, default=1,
                        help="run cases in this many worker processes (default 1; results are the same)")
    parser.add_argument("--json", type=Path, required=True, metavar="FILE",
                        help="write the rows (statistics, thresholds, pass flags, each episode) here")
    parser.add_argument("--out", type=Path, required=True, metavar="DIR",
                        help="write stress.md (the table) and stress.png (the heat map) into this folder")
    parser.add_argument("--trust", action="store_true", help="allow loading a pickled SB3 zip from outside its run directory")
    add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {args.episodes}")
    if args.workers < 1:
        raise ValueError(f"--workers must be at least 1, got {args.workers}")
    cases = select_cases(args.cases)
    config = config_from_args(args)
    check_output_file(args.json, "--json")  # fail before the first episode, not after the last
    check_output_dir(args.out, "--out")
    for name in ("stress.md", "stress.png"):
        check_output_file(args.out / name, "--out")
    load_policy(args.policy, config, trust=args.trust)  # a bad --policy fails now, before any worker starts
    start = time.perf_counter()
    rows = run_stress(args.policy, config, args.episodes, seed=args.seed, cases=cases, workers=args.workers,
                      trust=args.trust)
    wall_s = time.perf_counter() - start
    seeds = list(range(args.seed, args.seed + args.episodes))
    write_json(args.json, {
        "policy": args.policy, "episodes": args.episodes, "seeds": seeds, "workers": args.workers,
        "cpu_count": os.cpu_count(), "wall_time_s": wall_s, "all_passed": all(r.passed for r in rows),
        "autoscoop_version": __version__, "config": config.to_dict(), "rows": [r.as_dict() for r in rows]})
    intro = (f"`{args.policy}`, {args.episodes} episodes per case (seeds {seeds[0]}–{seeds[-1]}), "
             f"{wall_s:.0f} s wall time on {os.cpu_count()} CPUs with {args.workers} worker(s).")
    files = write_stress_report(rows, args.out, title=f"Stress suite: {args.policy}", intro=intro)
    print(stress_table(rows))
    print(verdict(rows))
    print(f"wrote {args.json}, {files.markdown} and {files.figure}")
    return 0
