"""Success per stress case and seed, and the median over seeds: the recipe's reliability table.

Reads the JSON files of ``autoscoop stress --policy RUN --episodes 30 --seed 1000 --json FILE`` (one per
training seed) and prints a Markdown table: the nominal fill factor, the success rate of each case, the
cases held, and the median row the acceptance reads (each case's median success >= 0.85).

    .venv/bin/python release/seed_table.py s10=runs/a/stress30.json s11=runs/b/stress30.json ...
"""

from __future__ import annotations

import argparse
import json
import statistics

from autoscoop.evaluation.stress import case_names


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", nargs="+", metavar="NAME=FILE", help="a row's name and its stress JSON")
    args = parser.parse_args()
    cases = case_names()
    print("| run | nominal fill | " + " | ".join(cases) + " | cases held |")
    print("|---|--:|" + "--:|" * len(cases) + "--:|")
    fills, success = [], {case: [] for case in cases}
    for item in args.runs:
        name, sep, path = item.partition("=")
        if not sep:
            parser.error(f"{item!r}: expected NAME=FILE")
        with open(path) as handle:
            rows = {row["case"]: row for row in json.load(handle)["rows"]}
        missing = [case for case in cases if case not in rows]
        if missing:
            parser.error(f"{path} has no row for {missing}")
        fills.append(rows["nominal"]["stats"]["fill_factor_mean"])
        for case in cases:
            success[case].append(rows[case]["stats"]["success_rate"])
        held = sum(rows[case]["passed"] for case in cases)
        print(f"| {name} | {fills[-1]:.2f} | " + " | ".join(f"{success[c][-1]:.2f}" for c in cases)
              + f" | {held} of {len(cases)} |")
    print(f"| median | {statistics.median(fills):.2f} | "
          + " | ".join(f"{statistics.median(success[c]):.2f}" for c in cases) + " | |")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
