"""Re-rank a finished run's snapshots with another validation than its recipe's (more candidates, more episodes).

The recipe's ``selection`` (``autoscoop/evaluation/selection.py``) validates the 8 best snapshots of the last
curriculum world 20 times per stress case. This asks whether a bigger validation would keep another snapshot:
it ranks the best ``--candidates`` snapshots with ``--episodes`` per case on the same validation seeds (20000
on) and writes every candidate's figures; the run itself (its ``policy.*`` and ``selection.json``) is not
touched. Run the pick it names through ``autoscoop stress --episodes 100`` to see whether it is better.

    .venv/bin/python release/reselect.py runs/smooth-s10 --candidates 16 --episodes 40 --json out/reselect.json
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path


def main() -> int:
    from autoscoop.commands.train_cmd import rank_run_snapshots  # noqa: PLC0415 - torch is slow to import
    from autoscoop.training.settings import SelectionSettings  # noqa: PLC0415

    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("run_dir", type=Path)
    parser.add_argument("--candidates", type=int, default=16)
    parser.add_argument("--episodes", type=int, default=40, help="episodes per stress case and candidate")
    parser.add_argument("--seed", type=int, default=20000, help="first validation seed (the recipes' 20000)")
    parser.add_argument("--json", type=Path, required=True)
    args = parser.parse_args()
    if args.candidates < 1 or args.episodes < 1:
        parser.error("--candidates and --episodes must be at least 1")

    started = time.time()
    _, ranked, _ = rank_run_snapshots(args.run_dir, SelectionSettings(args.candidates, args.episodes, args.seed))
    if not ranked:
        parser.error(f"{args.run_dir}: no evaluated snapshot in its last curriculum world")
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps({"run": str(args.run_dir), "candidates": args.candidates,
                                     "episodes": args.episodes, "seed": args.seed,
                                     "wall_s": round(time.time() - started, 1),
                                     "ranked": [r.summary() for r in ranked]}, indent=1))
    for r in ranked:
        print(f"{r.name}: {r.cases_passed} of {len(r.rows)} cases, shortfall {r.shortfall:.3f}, "
              f"delivered fill {r.mean_delivered_fill:.3f}")
    print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
