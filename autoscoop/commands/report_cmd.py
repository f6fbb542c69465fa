"""``autoscoop report RECORDS``: redraw the table and figures from saved episode records, without simulating.

RECORDS are record files (``.npz``) or folders holding them (searched recursively), as written by
``autoscoop eval --records``, ``autoscoop demo``, ``autoscoop compare`` and ``autoscoop teleop``.
Episodes are grouped by controller and pile angle; OUT/report.md gets the paper's Table 2 in our data,
Fig. 9 and Fig. 11 per controller and, with several pile angles, Fig. 13.
"""

from __future__ import annotations

import argparse
import shlex
from pathlib import Path

from autoscoop.commands import options


def register(subparsers: argparse._SubParsersAction) -> None:
    parser = subparsers.add_parser("report", help="redraw tables and figures from episode records",
                                   description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("records", nargs="+", type=Path, help="record files or folders of them")
    options.add_out_option(parser, Path("out/report"))
    parser.add_argument("--title", default="autoscoop report", help="heading of report.md")
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from autoscoop.report.data import group_episodes, load_episodes  # noqa: PLC0415 - matplotlib when needed
    from autoscoop.report.markdown import results_table, write_report  # noqa: PLC0415

    episodes = load_episodes(args.records)
    command = "autoscoop report " + " ".join(shlex.quote(str(p)) for p in args.records) + f" --out {args.out}"
    files = write_report(episodes, args.out, title=args.title, command=command)
    print(results_table(group_episodes(episodes), paper=False))
    print("\n".join(f"wrote {path}" for path in [files.markdown, *files.figures]))
    return 0
