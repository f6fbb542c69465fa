"""How well did runs learn, episode for episode? Their periodic evaluations over one window of episodes.

Each run's ``evaluations.csv`` (10 episodes of the run's world every 50 training episodes) is averaged over the
evaluations whose episode lies in ``(--from, --to]``: success, delivered fill (the mass fill of the successful
scoops, 0 for a failure) and fill factor. Two runs compared over the same window learned at the same pace when
these agree; a run stopped early is compared on the window it reached.

    .venv/bin/python experiments/periodic_evaluations.py runs/A runs/B --from 600 --to 2300 --json F
"""

from __future__ import annotations

import argparse
import math
from pathlib import Path

from autoscoop.core.safe_files import write_json_atomically
from autoscoop.training.sweep_results import read_evaluations


def window_means(run: Path, after: int, until: int) -> dict[str, float | int]:
    """Means of the run's periodic evaluations with ``after < episode <= until``, and their count."""
    rows = [row for row in read_evaluations(run) if after < int(row["episode"]) <= until]
    if not rows:
        raise SystemExit(f"{run}: no periodic evaluation between episodes {after} and {until}")
    means: dict[str, float | int] = {"evaluations": len(rows)}
    for key in ("success", "delivered_fill", "fill_factor"):
        values = [float(row[key]) for row in rows if not math.isnan(float(row[key]))]
        means[key] = round(sum(values) / len(values), 4)
    return means


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("runs", nargs="+", type=Path, help="run directories (each with evaluations.csv)")
    parser.add_argument("--from", dest="after", type=int, default=600, help="first episode, exclusive (default 600)")
    parser.add_argument("--to", dest="until", type=int, required=True, help="last episode, inclusive")
    parser.add_argument("--json", type=Path, help="write the figures here")
    args = parser.parse_args()
    figures = {}
    for run in args.runs:
        figures[run.name] = window_means(run, args.after, args.until)
        print(f"{run.name}: {figures[run.name]}")
    if args.json:
        write_json_atomically(args.json, {"window": [args.after, args.until], "runs": figures}, indent=None)


if __name__ == "__main__":
    main()
