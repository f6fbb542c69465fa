"""Does stopping the cut by the load reading hold heavy earth without shrinking the nominal scoop?

The actors trained so far cut one volume of every earth: eighteen particles of 0.4 kg overload the bucket, and
a smaller cut leaves the nominal pile short of its fill. A loader's operator (and a commercial bucket-fill
assist) ends the cut by the weight: once the load cell reads near the rated load, curl. This wraps a policy
so that, once the state's fill factor w (index 0) has reached ``--threshold``, the tilt command curls at
least ``--curl`` of the tilt range per control period (and, with ``--stop-drive``, the drive stops pushing
in) for the rest of the episode; everything else is the policy's own. The environment, the reward and the
true load are untouched: it measures whether such a governor, with today's actors, moves the particle count
of heavy earth and leaves the nominal pile alone.

    .venv/bin/python experiments/load_governor_probe.py --policy default --thresholds none,0.9,0.95 \\
        --cases nominal,heavy,randomized --episodes 50 --json out/governor.json
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.core.state import ACTION_NAMES, STATE_NAMES
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.stress import select_cases
from autoscoop.evaluation.summary import outcome_statistics

FILL_INDEX = STATE_NAMES.index("w")
TILT_ACTION = ACTION_NAMES.index("tilt")
DRIVE_ACTION = ACTION_NAMES.index("drive")
LIFT_ACTION = ACTION_NAMES.index("lift")
TIP_HEIGHT = STATE_NAMES.index("tip_z")


class LoadGovernor:
    """A policy whose tilt curls (and drive stops pushing) once its load reading w has reached ``threshold``."""

    def __init__(self, policy: Any, threshold: float, curl: float, stop_drive: bool) -> None:
        self.policy, self.threshold, self.curl, self.stop_drive = policy, threshold, curl, stop_drive
        self.name = f"{policy.name} (curl from w {threshold:g})"
        self.state_frame = getattr(policy, "state_frame", None)
        self.tripped = False

    def reset(self) -> None:
        self.policy.reset()
        self.tripped = False

    def act(self, observation: np.ndarray) -> np.ndarray:
        action = np.array(self.policy.act(observation), dtype=np.float32, copy=True)
        self.tripped = self.tripped or float(observation[FILL_INDEX]) >= self.threshold
        if self.tripped:
            action[TILT_ACTION] = min(action[TILT_ACTION], -self.curl)
            if self.stop_drive:
                action[DRIVE_ACTION] = min(action[DRIVE_ACTION], 0.0)
                action[LIFT_ACTION] = min(action[LIFT_ACTION], -0.5)
        return action


class LoadShedder:
    """A policy that, while its load reading w is above ``threshold``, holds the drive and the arm and tips the
    bucket forward by ``tip`` of the tilt range per control period, so that the heap's top rolls back onto the
    pile; below it, the policy acts."""

    def __init__(self, policy: Any, threshold: float, tip: float, above_m: float = -np.inf) -> None:
        self.policy, self.threshold, self.tip, self.above_m = policy, threshold, tip, above_m
        self.name = f"{policy.name} (shed above w {threshold:g})"
        self.state_frame = getattr(policy, "state_frame", None)
        self.shedding_steps = 0

    def reset(self) -> None:
        self.policy.reset()
        self.shedding_steps = 0

    def act(self, observation: np.ndarray) -> np.ndarray:
        action = np.array(self.policy.act(observation), dtype=np.float32, copy=True)
        if float(observation[FILL_INDEX]) > self.threshold and float(observation[TIP_HEIGHT]) >= self.above_m:
            self.shedding_steps += 1
            action[:] = 0.0
            action[TILT_ACTION] = self.tip
        return action


def summary(outcomes: list) -> dict[str, Any]:
    """The figures this probe prints and keeps, from the project's own episode statistics."""
    stats = outcome_statistics(o.as_dict() for o in outcomes)
    cycle = stats["cycle_time_mean"]
    return {"episodes": len(outcomes), "success": stats["success_rate"], "fill": stats["fill_factor_mean"],
            "volumetric": stats["volumetric_fill_mean"], "overload": stats["overload_rate"],
            "particles_mean": stats["particles_mean"], "particles_std": stats["particles_std"],
            "cycle_s": None if math.isnan(cycle) else cycle}


def load_arrival(policy: Any, config: ScoopConfig, episodes: int, seed: int) -> dict[str, float]:
    """How the load comes into the bucket, per control period: the largest share of the episode's peak particle
    count that came in over one period, and the periods from the first particle to 90 % of the peak."""
    env = make_scoop_env(config)
    jumps, spans = [], []
    try:
        for k in range(episodes):
            counts: list[int] = []
            rollout(policy, env, seed + k, observers=[lambda *step, into=counts: into.append(int(step[4]["particles_in_bucket"]))])
            peak = max(counts, default=0)
            if peak == 0:
                continue
            steps = np.diff([0, *counts])
            jumps.append(float(steps.max()) / peak)
            first = next(i for i, c in enumerate(counts) if c > 0)
            spans.append(next(i for i, c in enumerate(counts) if c >= 0.9 * peak) - first + 1)
    finally:
        env.close()
    return {"largest_jump_share_mean": float(np.mean(jumps)), "largest_jump_share_min": float(np.min(jumps)),
            "periods_to_90pct_mean": float(np.mean(spans)),
            "periods_to_90pct_share_1": float(np.mean(np.array(spans) == 1)),
            "periods_to_90pct_share_le2": float(np.mean(np.array(spans) <= 2))}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", required=True)
    parser.add_argument("--thresholds", default="none,0.95", help="comma-separated w thresholds; none: no governor")
    parser.add_argument("--curl", type=float, default=0.2, help="least curl per control period, share of the range")
    parser.add_argument("--stop-drive", action="store_true", help="also stop the drive pushing in and raise the arm once tripped")
    parser.add_argument("--shed-above-m", type=float, default=-np.inf,
                        help="shed only with the tip at least this high (m, the state's tip_z): out of the pile")
    parser.add_argument("--shed", type=float, default=None,
                        help="shed instead: above the threshold, tip forward this share of the tilt range a period")
    parser.add_argument("--cases", default="nominal,heavy", help="stress cases, comma-separated")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument("--arrival", action="store_true",
                        help="instead: how the load arrives per control period (the policy alone, no governor)")
    args = parser.parse_args()
    results: dict[str, dict[str, Any]] = {}
    if args.arrival:
        for case in select_cases(args.cases):
            config = case.config(ScoopConfig())
            row = load_arrival(load_policy(args.policy, config), config, args.episodes, args.seed)
            results.setdefault("arrival", {})[case.name] = row
            print(f"{case.name:>11}: " + ", ".join(f"{key} {value:.2f}" for key, value in row.items()), flush=True)
        if args.json:
            write_json_atomically(args.json, {"policy": args.policy, "episodes": args.episodes, "seed": args.seed,
                                              "results": results})
        return 0
    for threshold_text in args.thresholds.split(","):
        for case in select_cases(args.cases):
            config = case.config(ScoopConfig())
            policy = load_policy(args.policy, config)
            if threshold_text != "none":
                policy = (LoadShedder(policy, float(threshold_text), args.shed, args.shed_above_m) if args.shed is not None else
                          LoadGovernor(policy, float(threshold_text), args.curl, args.stop_drive))
            row = summary(evaluate(policy, config, args.episodes, seed=args.seed, progress=False))
            results.setdefault(threshold_text, {})[case.name] = row
            print(f"w from {threshold_text:>5} {case.name:>11}: success {row['success']:.2f} fill {row['fill']:.3f} "
                  f"vol {row['volumetric']:.3f} overload {row['overload']:.2f} particles "
                  f"{row['particles_mean']:.1f} ± {row['particles_std']:.1f} cycle {row['cycle_s'] or math.nan:.2f}", flush=True)
    if args.json:
        write_json_atomically(args.json, {"policy": args.policy, "curl": args.curl, "stop_drive": args.stop_drive,
                                          "episodes": args.episodes, "seed": args.seed, "results": results})
    print(json.dumps({"done": True}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
