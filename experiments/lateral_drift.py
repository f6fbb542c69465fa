"""How far the loader drifts sideways during scoops: the largest |y| of the bucket tip per episode.

The state has no lateral position, so this is what a 3-D distance to the terminal point would punish
that the policy cannot see. Also counts the episodes whose tip came within epsilon of the terminal
point in the arm's plane (x, z) and the ones that did in 3-D.

    .venv/bin/python experiments/lateral_drift.py --policy default --episodes 100 --set pile.angle_deg=40
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig, parse_set_args
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default")
    parser.add_argument("--episodes", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE")
    args = parser.parse_args()
    config = ScoopConfig().with_overrides(parse_set_args(args.overrides))
    env = make_scoop_env(config)
    sim = env.unwrapped.sim
    policy = load_policy(args.policy, config)
    terminal = np.array([config.reward.terminal_dx_m, 0.0, config.reward.terminal_z_m])
    largest, planar, spatial = [], 0, 0
    episode = {"y": 0.0, "planar": False, "3d": False}

    def watch_tip(step: int, obs: np.ndarray, action: np.ndarray, reward: float, info: dict) -> None:
        offset = sim.tip_world - terminal
        episode["y"] = max(episode["y"], abs(offset[1]))
        episode["planar"] |= bool(np.hypot(offset[0], offset[2]) <= config.reward.epsilon_m)
        episode["3d"] |= bool(np.linalg.norm(offset) <= config.reward.epsilon_m)

    for seed in range(args.seed, args.seed + args.episodes):
        episode.update(y=0.0, planar=False, **{"3d": False})
        rollout(policy, env, seed, observers=(watch_tip,))
        largest.append(episode["y"])
        planar += episode["planar"]
        spatial += episode["3d"]
    largest = np.array(largest)
    print(f"{args.policy}, {args.episodes} episodes from seed {args.seed}, pile {config.pile.angle_deg:g} deg: "
          f"largest |y| of the tip per episode mean {largest.mean() * 100:.1f} cm, p90 "
          f"{np.percentile(largest, 90) * 100:.1f} cm, max {largest.max() * 100:.1f} cm; "
          f"within epsilon in x-z {planar}, in 3-D {spatial} (the episode ends at the first x-z reach)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
