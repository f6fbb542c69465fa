"""``autoscoop shift``: a loader's shift, scoop after scoop from one pile into a hopper: tonnes per hour, energy per tonne.

Each cycle: the policy scoops (an ordinary episode, on the pile as the last scoop left it), then a script backs
out, drives to the hopper, dumps into it and returns to the pile's retreating toe. Prints the totals per policy
(mean ± std over the shifts); --json keeps every cycle of every shift; --out writes shift.md (per-cycle and total
tables, the conditions the figures hold under) and its figures; --video films the first shift. --compare runs more
policies on the same shifts, side by side. The pile and the hopper are the shift.* config keys (`autoscoop config` lists them).

Exit code 3 when no policy delivered anything into the hopper in any shift, after the totals and the files are
written (a policy of --compare that delivered nothing is named on stderr); --allow-empty makes that 0. Usage and
input errors exit 2.
"""

from __future__ import annotations

import argparse
import shlex
import sys
import time
from pathlib import Path

from autoscoop.commands import check_output_dir, check_output_file, config_from_args, options, write_json
from autoscoop.core.safe_files import atomic_output
from autoscoop.evaluation.shift import run_shifts
from autoscoop.evaluation.shift_film import SHIFT_FPS, ShiftFilm

DEFAULT_CYCLES = 15


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("shift", help="a loader's shift: cycles of scoop, carry, dump, return; t/h and kJ/t",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    options.add_policy_option(parser, accepts=options.POLICY_HELP + ", the scoop's controller")
    parser.add_argument("--compare", nargs="+", default=[], metavar="POLICY",
                        help="more policies to run on the same shifts, side by side")
    parser.add_argument("--cycles", type=options.POSITIVE, default=DEFAULT_CYCLES, metavar="N",
                        help=f"loading cycles per shift (1 or more; default {DEFAULT_CYCLES})")
    options.add_seed_option(parser, what="seed of the first shift")
    parser.add_argument("--shifts", type=options.POSITIVE, default=1, metavar="N",
                        help="shifts per policy, seeds SEED, SEED+1, ... (1 or more; default 1)")
    options.add_workers_option(parser)
    options.add_json_option(parser, "every cycle of every shift, the totals and the conditions")
    options.add_out_option(parser, None, what="folder for shift.md and its figures")
    parser.add_argument("--video", type=Path, metavar="FILE.mp4",
                        help="film the first shift (the --policy's, on --seed) from the side to this MP4, "
                             f"{SHIFT_FPS:g} frames per simulated second")
    options.add_trust_option(parser)
    options.add_allow_empty_option(parser)
    options.add_config_args(parser)
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    started = time.perf_counter()
    config = config_from_args(args)
    if args.json:  # fail before the first cycle, not after the last
        check_output_file(args.json, "--json")
    if args.out:
        check_output_dir(args.out, "--out")
    if args.video:
        check_output_file(args.video, "--video")
    specs = list(dict.fromkeys([args.policy, *args.compare]))
    seeds = list(range(args.seed, args.seed + args.shifts))
    film = ShiftFilm() if args.video else None
    shifts = run_shifts(specs, config, args.cycles, seeds, workers=args.workers, trust=args.trust, film=film)

    from autoscoop.report.shift import format_totals, summarize_totals, write_shift_report  # noqa: PLC0415

    print(format_totals(shifts))
    command = "autoscoop " + shlex.join(sys.argv[1:]) if sys.argv[1:2] == ["shift"] else ""
    if args.json:
        by_policy = {spec: summarize_totals([s for s in shifts if s["policy"] == spec]) for spec in specs}
        write_json(args.json, {"command": command, "cycles": args.cycles, "seeds": seeds, "summary": by_policy,
                               "conditions": shifts[0]["conditions"], "config": config.to_dict(), "shifts": shifts})
        print(f"wrote {args.json}")
    if args.out:
        for path in write_shift_report(shifts, args.out, command=command):
            print(f"wrote {path}")
    if film is not None:
        from autoscoop.report.video import write_mp4  # noqa: PLC0415 - optional dependency (extra "media")

        with atomic_output(args.video) as tmp:  # a failed encoding leaves the previous video
            write_mp4(film.frames, tmp, fps=film.fps)
        print(f"wrote {args.video} ({len(film.frames)} frames)")
    print(f"shift took {time.perf_counter() - started:.0f} s")
    return _judge_delivery(shifts, specs, args.allow_empty)


def _judge_delivery(shifts: list[dict], specs: list[str], allow_empty: bool) -> int:
    """0 when some policy delivered into the hopper; the policies that delivered nothing are named either way."""
    idle = [spec for spec in specs
            if not any(shift["totals"].get("delivered_kg", 0.0) > 0 for shift in shifts if shift["policy"] == spec)]
    if len(idle) < len(specs):
        for spec in idle:
            print(f"warning: {spec} delivered nothing into the hopper in any shift", file=sys.stderr)
        return 0
    return options.nothing_done("shift", f"no scoop was delivered: {', '.join(specs)} put nothing into the hopper in "
                                         f"{len(shifts) // len(specs)} shift(s)", allow_empty)
