"""Does a policy scoop as well when w_t comes from the joint torques as when it counts particles?

Runs the same policy over the same seeds twice, with ``env.mass_source=truth`` and ``=torque``,
and prints the fill factor of each (mean +- std), their difference in points (the acceptance:
at most 5), and how far the w_t the policy saw under ``torque`` was from the truth.

    .venv/bin/python benchmarks/compare_mass_source.py --policy default --episodes 100 --json out/mass_source.json
    .venv/bin/python benchmarks/compare_mass_source.py --policy heuristic --episodes 30   # the mechanism check

The scripted ``heuristic`` does not read w_t, so its two figures agree exactly; a learned policy is
the real test. Extra ``--set key=value`` overrides apply to both runs (e.g. env.load_cell_noise_nm=0.5).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig, parse_set_args
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env

ACCEPTANCE_POINTS = 5.0


def run(policy_spec: str, config: ScoopConfig, episodes: int, seed: int, trust: bool) -> dict:
    """Fill factors per episode, and (w_t x rated load - true mass) at every step and the last."""
    policy = load_policy(policy_spec, config, trust=trust)
    env = make_scoop_env(config)
    rated = config.reward.rated_load_kg
    fills, w_errors, w_errors_last = [], [], []

    def w_error(step: int, obs: np.ndarray, action: np.ndarray, reward: float, next_obs: np.ndarray,
                terminated: bool, truncated: bool, info: dict) -> None:
        if info["physics_error"]:
            return
        w_errors.append(float(next_obs[0]) * rated - info["mass_in_bucket_kg"])
        if terminated or truncated:
            w_errors_last.append(w_errors[-1])

    try:
        for i in range(episodes):
            fills.append(rollout(policy, env, seed + i, transition_observers=(w_error,)).fill_factor)
    finally:
        env.close()
    return {"fill_factor_mean": float(np.mean(fills)), "fill_factor_std": float(np.std(fills)),
            "fill_factors": fills,
            "w_abs_error_kg_mean": float(np.mean(np.abs(w_errors))) if w_errors else math.nan,
            "w_abs_error_kg_last_step_mean": float(np.mean(np.abs(w_errors_last))) if w_errors_last else math.nan}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default", help="heuristic, default, or a policy file")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--trust", action="store_true", help="allow an SB3 zip from outside its run directory")
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    parser.add_argument("--json", type=Path, help="write both summaries here")
    args = parser.parse_args(argv)
    base = ScoopConfig().with_overrides(parse_set_args(args.overrides))
    results = {}
    for source in ("truth", "torque"):
        config = base.with_overrides({"env.mass_source": source})
        results[source] = run(args.policy, config, args.episodes, args.seed, args.trust)
        r = results[source]
        print(f"{source:<6}  fill factor {r['fill_factor_mean']:.3f} +- {r['fill_factor_std']:.3f}   "
              f"|w*rated - true| mean {r['w_abs_error_kg_mean']:.3f} kg, "
              f"last step {r['w_abs_error_kg_last_step_mean']:.3f} kg")
    gap = 100.0 * abs(results["torque"]["fill_factor_mean"] - results["truth"]["fill_factor_mean"])
    verdict = "pass" if gap <= ACCEPTANCE_POINTS else "FAIL"
    print(f"policy {args.policy}, {args.episodes} episodes, noise {base.env.load_cell_noise_nm} N*m: "
          f"torque - truth fill gap {gap:.1f} points (acceptance <= {ACCEPTANCE_POINTS:g}): {verdict}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps({"policy": args.policy, "episodes": args.episodes, "seed": args.seed,
                                         "gap_points": gap, "verdict": verdict, "config": base.to_dict(),
                                         **results}, indent=2) + "\n")
    return 0 if gap <= ACCEPTANCE_POINTS else 1


if __name__ == "__main__":
    sys.exit(main())
