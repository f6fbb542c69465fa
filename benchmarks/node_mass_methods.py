"""The controller node's payload mass methods against each other, without ROS (simulated time).

Runs the node's logic (:class:`autoscoop.deploy.controller.ControllerCore`) against the simulator in one
process (:func:`autoscoop.deploy.sim_bridge.run_without_ros`) with each ``payload`` setting: eq. 8 from
both joint torques (the default), eq. 4 from the bucket torque alone, and the simulator's true mass on
``payload_mass`` (``source: topic``). Same pile and seeds for each.

    .venv/bin/python benchmarks/node_mass_methods.py --policy default --episodes 20
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import robot_config_from_dict
from autoscoop.deploy.sim_bridge import SimBridge, run_without_ros

SETTINGS = {"eq8": {"payload": {"method": "eq8"}}, "eq4": {"payload": {"method": "eq4"}},
            "topic": {"payload": {"source": "topic"}}}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    task = ScoopConfig()
    out = {"policy": args.policy, "episodes": args.episodes, "seed": args.seed, "methods": {}}
    for name, settings in SETTINGS.items():
        robot = robot_config_from_dict(settings)
        bridge = SimBridge(task, robot=robot)
        core = ControllerCore(robot, load_policy(args.policy, task), task)
        now, results = 0.0, []
        for seed in range(args.seed, args.seed + args.episodes):
            result, now = run_without_ros(bridge, core, seed, now + 1.0)
            results.append(result)
        bridge.close()
        fill = np.array([r.fill_factor for r in results])
        success = float(np.mean([r.success for r in results]))
        out["methods"][name] = {"fill_factor_mean": float(fill.mean()), "fill_factor_std": float(fill.std()),
                                "success_rate": success}
        print(f"{name:6s} fill {fill.mean():.3f} ± {fill.std():.3f}  success {success:.2f}", flush=True)
    if args.json:
        args.json.write_text(json.dumps(out, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
