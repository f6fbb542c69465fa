"""Pick the policy to ship among training snapshots, on selection seeds apart from the reported ones.

Every periodic evaluation of a run leaves its actor in ``RUN_DIR/evaluated/``. This script runs each
candidate (snapshot files, run directories, or ``default``) on the three public piles with seeds
from ``--seed`` (default 5000: the reported evaluations use seeds 0-99, so the choice does not fit
them), and ranks the candidates by their worst success over the piles, then their mean delivered
fill (fill factor of successful episodes, zero for failures).

    .venv/bin/python release/select_policy.py runs/acc2-s0/ddpg-s0/evaluated/episode_00{4,5,6,7,8}*.safetensors default
"""

from __future__ import annotations

import argparse
import json
import sys
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np


def score(candidate: str, angles: list[float], episodes: int, seed: int, overrides: dict | None = None) -> dict:
    from autoscoop.agents.loading import load_policy  # noqa: PLC0415 - in the worker process
    from autoscoop.core.config import ScoopConfig  # noqa: PLC0415 - in the worker process
    from autoscoop.evaluation.evaluate import evaluate  # noqa: PLC0415 - in the worker process

    row = {"policy": candidate, "piles": {}}
    for angle in angles:
        config = ScoopConfig().with_overrides({**(overrides or {}), "pile.angle_deg": angle})
        results = evaluate(load_policy(candidate, config), config, episodes, seed=seed, progress=False)
        success = [r.success for r in results]
        cycles = [r.cycle_time_s for r in results if r.success]
        row["piles"][f"{angle:g}"] = {
            "success": float(np.mean(success)), "fill": float(np.mean([r.fill_factor for r in results])),
            "delivered_fill": float(np.mean([r.fill_factor if r.success else 0.0 for r in results])),
            "cycle_s": float(np.mean(cycles)) if cycles else float("nan")}
    piles = row["piles"].values()
    row["worst_success"] = min(p["success"] for p in piles)
    row["mean_delivered_fill"] = float(np.mean([p["delivered_fill"] for p in piles]))
    return row


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("candidates", nargs="+", help="policy files, run directories or 'default'")
    parser.add_argument("--angles", type=float, nargs="+", default=[25.0, 32.0, 40.0])
    parser.add_argument("--episodes", type=int, default=30, help="episodes per pile and candidate")
    parser.add_argument("--seed", type=int, default=5000, help="first selection seed (reports use 0-99)")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE",
                        help="config override for every pile, e.g. env.mass_source=torque (repeatable)")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    from autoscoop.core.config import ScoopConfig, parse_set_args  # noqa: PLC0415

    overrides = parse_set_args(args.overrides)
    ScoopConfig().with_overrides(overrides)  # a bad key or value fails here, before any work
    n = len(args.candidates)
    with ProcessPoolExecutor(args.workers) as pool:
        rows = list(pool.map(score, args.candidates, [args.angles] * n, [args.episodes] * n, [args.seed] * n,
                             [overrides] * n))
    rows.sort(key=lambda r: (r["worst_success"], r["mean_delivered_fill"]), reverse=True)
    for r in rows:
        piles = "  ".join(f"{a}°: {p['fill']:.2f}/{p['success']:.2f}/{p['cycle_s']:.1f}s" for a, p in r["piles"].items())
        print(f"{r['worst_success']:.2f} {r['mean_delivered_fill']:.3f}  {piles}  {r['policy']}")
    if args.json:
        args.json.write_text(json.dumps({"angles": args.angles, "episodes": args.episodes, "seed": args.seed,
                                         "set": args.overrides, "ranking": rows}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
