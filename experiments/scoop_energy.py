"""Where a scoop's energy goes: the actuators' positive mechanical work per scoop, wheels, lift and tilt.

A shift (``autoscoop shift``) reports energy per delivered tonne over whole cycles. This runs single scoops on
the nominal pile (or a stress case) with the shift's work meter attached and splits each scoop's work by
actuator, so that two scoops' energy can be told apart by where it is spent: driving into the pile, lifting
the load, or turning the bucket (J per scoop, mean ± std over the episodes, seeds from ``--seed``).

    .venv/bin/python experiments/scoop_energy.py --policies default,heuristic --episodes 50 --json out/energy.json
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import config_for_policy
from autoscoop.core.safe_files import write_json_atomically
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.stress import select_cases
from autoscoop.sim.scene import WHEELS
from autoscoop.sim.work_meter import ACTUATORS, WorkMeter

GROUPS = {"wheels": [ACTUATORS.index(name) for name in WHEELS], "lift": [ACTUATORS.index("lift")],
          "tilt": [ACTUATORS.index("tilt")]}


def scoop_energy(policy: Any, config: ScoopConfig, episodes: int, seed: int) -> dict[str, Any]:
    """Each scoop's positive work by actuator group (J) and its outcome, over ``episodes`` episodes."""
    env = make_scoop_env(config_for_policy(policy, config))
    sim = env.unwrapped.sim
    meter = WorkMeter(sim.model, sim.data)
    sim.add_substep_observer(meter)
    rows = []
    try:
        for k in range(episodes):
            meter.reset()
            outcome = rollout(policy, env, seed + k)
            work = meter.positive_work_by_actuator_j
            rows.append({group: float(work[index].sum()) for group, index in GROUPS.items()}
                        | {"total": float(work.sum()), "success": outcome.success, "mass_kg": outcome.mass_kg,
                           "steps": outcome.steps})
    finally:
        sim.remove_substep_observer(meter)
        env.close()
    summary = {key: {"mean": float(np.mean([r[key] for r in rows])), "std": float(np.std([r[key] for r in rows]))}
               for key in (*GROUPS, "total", "mass_kg", "steps")}
    summary["success"] = float(np.mean([r["success"] for r in rows]))
    return summary


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policies", default="default,heuristic", help="comma-separated policies")
    parser.add_argument("--case", default="nominal", help="a stress case (default nominal)")
    parser.add_argument("--episodes", type=int, default=30)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args()
    config = select_cases(args.case)[0].config(ScoopConfig())
    results = {}
    for name in args.policies.split(","):
        row = scoop_energy(load_policy(name, config), config, args.episodes, args.seed)
        results[name] = row
        print(f"{name}: " + ", ".join(f"{key} {row[key]['mean']:.1f} ± {row[key]['std']:.1f}"
                                      for key in (*GROUPS, "total", "mass_kg", "steps")) + f", success {row['success']:.2f}",
              flush=True)
    if args.json:
        write_json_atomically(args.json, {"case": args.case, "episodes": args.episodes, "seed": args.seed,
                                          "unit": "J per scoop (positive actuator work)", "results": results})
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
