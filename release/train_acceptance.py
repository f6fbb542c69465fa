"""The paper recipe's acceptance: `autoscoop train --recipe paper`, per seed; time it; evaluate each policy.

Run by hand (long): ``.venv/bin/python release/train_acceptance.py --seeds 0 1 2 --out runs/acceptance``.
Writes ``OUT/summary.json`` with each seed's wall time and evaluation (100 episodes on the default
pile) and the median fill factor and success rate over seeds.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from pathlib import Path


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--episodes", type=int, default=100, help="evaluation episodes per seed")
    parser.add_argument("--out", type=Path, default=Path("runs/acceptance"))
    parser.add_argument("--eval-only", action="store_true", help="evaluate existing runs without training")
    args = parser.parse_args()
    cli = [sys.executable, "-m", "autoscoop.cli"]
    results = []
    for seed in args.seeds:
        run_dir = args.out / f"ddpg-s{seed}"
        wall = None
        if not args.eval_only:
            start = time.time()
            subprocess.run([*cli, "train", "--recipe", "paper", "--seed", str(seed), "--out", str(run_dir), "--no-progress"], check=True)
            wall = time.time() - start
        eval_json = run_dir / "eval_default_pile.json"
        subprocess.run([*cli, "eval", "--policy", str(run_dir), "--episodes", str(args.episodes),
                        "--seed", "1000", "--json", str(eval_json)], check=True, stdout=subprocess.DEVNULL)
        summary = json.loads(eval_json.read_text())
        info = json.loads((run_dir / "run.json").read_text())
        results.append({"seed": seed, "train_wall_s": wall if wall is not None else info.get("wall_s"),
                        **{k: summary[k] for k in ("fill_factor_mean", "fill_factor_std", "cycle_time_mean",
                                                   "cycle_time_std", "success_rate", "episodes")}})
        print(json.dumps(results[-1]), flush=True)
    out = {"seeds": results,
           "median_fill_factor": statistics.median(r["fill_factor_mean"] for r in results),
           "median_success_rate": statistics.median(r["success_rate"] for r in results),
           "max_train_wall_s": max(r["train_wall_s"] or 0 for r in results)}
    (args.out / "summary.json").write_text(json.dumps(out, indent=2) + "\n")
    print(json.dumps({k: v for k, v in out.items() if k != "seeds"}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
