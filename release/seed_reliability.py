"""Is the training recipe reliable? The stress suite over the policies of several training seeds.

Runs ``autoscoop stress``'s cases (``autoscoop.evaluation.stress``) for each run directory's kept
policy and reports, per seed, its nominal fill and success and each case's success, then the median
over seeds of each case's success, with each run's training wall time (``run.json``).

The reliability bar: every seed reaches nominal fill >= 0.70 and success >= 0.90, and the median
over seeds meets success >= 0.85 on every stress case.

    .venv/bin/python release/seed_reliability.py runs/robot-s10 runs/robot-s11 ... --episodes 50 \\
        --workers 2 --json out/seed_reliability.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path

from autoscoop.core.config import ScoopConfig
from autoscoop.evaluation.stress import CASES, run_stress

NOMINAL_FILL, NOMINAL_SUCCESS, MEDIAN_SUCCESS = 0.70, 0.90, 0.85


def seed_row(run: Path, episodes: int, workers: int) -> dict:
    """One run's figures: its stress rows' success, volumetric fill and overload per case, and nominal fill."""
    info = json.loads((run / "run.json").read_text())
    rows = run_stress(str(run / "policy.safetensors"), ScoopConfig(), episodes, workers=workers)
    stats = {row.case.name: row.stats for row in rows}
    nominal = stats["nominal"]
    return {
        "run": str(run), "seed": info["seed"], "recipe": info.get("recipe"), "episodes": info["episodes"],
        "wall_s": info.get("wall_s"), "best_episode": info.get("best_episode"),
        "nominal_fill": nominal["fill_factor_mean"], "nominal_success": nominal["success_rate"],
        "holds_nominal": nominal["fill_factor_mean"] >= NOMINAL_FILL and nominal["success_rate"] >= NOMINAL_SUCCESS,
        "success": {name: s["success_rate"] for name, s in stats.items()},
        "volumetric_fill": {name: s["volumetric_fill_mean"] for name, s in stats.items()},
        "overload": {name: s["overload_rate"] for name, s in stats.items()},
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("runs", type=Path, nargs="+", help="finished run directories (their policy.safetensors)")
    parser.add_argument("--episodes", type=int, default=50, help="episodes per case (seeds 0..N-1)")
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--json", type=Path, required=True)
    args = parser.parse_args()
    per_seed = []
    for run in args.runs:
        per_seed.append(seed_row(run, args.episodes, args.workers))
        row = per_seed[-1]
        print(f"{run}: seed {row['seed']}, {row['wall_s']} s; nominal fill {row['nominal_fill']:.3f}, "
              f"success {row['nominal_success']:.2f}", flush=True)
    names = [case.name for case in CASES]
    median = {name: statistics.median(s["success"][name] for s in per_seed) for name in names}
    result = {"episodes_per_case": args.episodes, "seeds": [s["seed"] for s in per_seed], "per_seed": per_seed,
              "median_success": median,
              "all_seeds_hold_nominal": all(s["holds_nominal"] for s in per_seed),
              "median_holds_every_case": all(v >= MEDIAN_SUCCESS for v in median.values())}
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(result, indent=2) + "\n")
    print("| seed | training wall s | nominal fill | " + " | ".join(names) + " |")
    print("|---|--:|--:|" + "--:|" * len(names))
    for s in per_seed:
        print(f"| {s['seed']} | {s['wall_s']} | {s['nominal_fill']:.2f} | "
              + " | ".join(f"{s['success'][n]:.2f}" for n in names) + " |")
    print("| median | | | " + " | ".join(f"{median[n]:.2f}" for n in names) + " |")
    print(f"every seed holds nominal: {result['all_seeds_hold_nominal']}; "
          f"median success >= {MEDIAN_SUCCESS} on every case: {result['median_holds_every_case']}")
    return 0 if result["all_seeds_hold_nominal"] and result["median_holds_every_case"] else 1


if __name__ == "__main__":
    sys.exit(main())
