"""Would a looser overload bar let the trained runs hold the stress suite?

An overload is a scoop whose fill factor ends above ``scoop.overload_fill`` (1.05 of the rated load: 19
particles of 0.4 kg). This scores `autoscoop stress --json` files again from their episode records with
the overload counted above ``--overload-above`` instead, every other threshold as the suite has it, and
lists per run the cases held now and with the looser bar, and the cases that still fail.

    .venv/bin/python experiments/overload_bar_whatif.py runs/*/stress100_seed0.json --overload-above 1.10 \\
        --json out/overload_bar_whatif.json
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from autoscoop.core.safe_files import read_json, write_json_atomically
from autoscoop.evaluation.stress import Threshold

MAX_STRESS_BYTES = 64 << 20
"""the largest stress JSON read (100 episodes x 11 cases with their records is about 0.6 MB)."""


def cases_held(rows: list[dict], overload_above: float | None) -> tuple[int, list[str]]:
    """How many cases hold, and which fail, with overload counted above ``overload_above`` (None: as recorded)."""
    failed = []
    for row in rows:
        episodes = row["episodes_detail"]
        ok = True
        for check in row["checks"]:
            measured = check["measured"]
            if check["metric"] == "overload_rate" and overload_above is not None:
                measured = sum(e["fill_factor"] > overload_above for e in episodes) / len(episodes)
            ok &= Threshold(check["metric"], check["op"], check["threshold"]).holds(measured)
        if not ok:
            failed.append(row["case"])
    return len(rows) - len(failed), failed


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("stress_json", type=Path, nargs="+", help="autoscoop stress --json files (with episode records)")
    parser.add_argument("--overload-above", type=float, default=1.10, help="fill factor above which a scoop overloads")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)
    runs = {}
    for path in args.stress_json:
        data = read_json(path, "stress JSON", MAX_STRESS_BYTES)
        if not all("episodes_detail" in row for row in data["rows"]):
            print(f"{path}: no episode records, skipped", file=sys.stderr)
            continue
        now, _ = cases_held(data["rows"], None)
        looser, failing = cases_held(data["rows"], args.overload_above)
        runs[path.parent.name] = {"cases": len(data["rows"]), "held": now, "held_looser": looser, "failing_looser": failing}
        print(f"{path.parent.name}: {now} of {len(data['rows'])} held; {looser} with overload above "
              f"{args.overload_above:g} (failing: {', '.join(failing) or 'none'})")
    if args.json:
        write_json_atomically(args.json, {"overload_above": args.overload_above, "runs": runs}, indent=None)
    return 0


if __name__ == "__main__":
    sys.exit(main())
