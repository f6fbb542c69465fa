"""How high the bucket's tip rides on the approach: the tip's height before it first reaches the pile.

An operator drives at the pile with the bucket low. A controller that lifts its tip in front of the pile
and drops it again before it cuts wastes a second of the cycle and the lift's energy. This reads
episode records (``autoscoop eval --records DIR``), takes each episode's highest tip above the ground
(world z, m; the records' ``tip_world_m``) over the steps before the tip first reaches the pile (eq. 7's
``penetrating``, that step included), and reports the share of episodes that stayed below the bar.

    .venv/bin/autoscoop eval --policy default --episodes 100 --records out/approach-default
    .venv/bin/python benchmarks/approach_height.py out/approach-default --below-m 0.08 --json out/approach.json
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from autoscoop.envs.records import load_record


def approach_height_m(tip_world_m: np.ndarray, penetrating: np.ndarray) -> float:
    """The tip's highest z (m) over the steps up to the first one that reaches the pile (all steps if none does)."""
    reached = np.flatnonzero(np.asarray(penetrating, dtype=bool))
    last = int(reached[0]) + 1 if len(reached) else len(penetrating)
    return float(np.max(np.asarray(tip_world_m, dtype=float)[:last, 2]))


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("records", type=Path, help="a folder of episode records (autoscoop eval --records)")
    parser.add_argument("--below-m", type=float, default=0.08, help="the bar on the approach height, m (0.08)")
    parser.add_argument("--json", type=Path, help="write the figures to this JSON file")
    args = parser.parse_args()
    paths = sorted(args.records.glob("*.npz"))
    if not paths:
        print(f"{args.records}: no episode records (*.npz)", file=sys.stderr)
        return 2
    heights = []
    for path in paths:
        steps = load_record(path).arrays()
        heights.append(approach_height_m(steps["tip_world_m"], steps["penetrating"]))
    heights_m = np.array(heights)
    result = {"records": str(args.records), "episodes": len(heights), "below_m": args.below_m,
              "share_below": float(np.mean(heights_m < args.below_m)),
              "approach_height_m_mean": float(heights_m.mean()), "approach_height_m_std": float(heights_m.std()),
              "approach_height_m_max": float(heights_m.max())}
    print(f"{len(heights)} episodes: approach height {result['approach_height_m_mean']:.3f} +- "
          f"{result['approach_height_m_std']:.3f} m (max {result['approach_height_m_max']:.3f}); "
          f"{result['share_below']:.0%} stay below {args.below_m} m")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        tmp = args.json.with_name(f".{args.json.name}.tmp")
        tmp.write_text(json.dumps(result, indent=2) + "\n")
        tmp.replace(args.json)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
