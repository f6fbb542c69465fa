"""How far the loader drifts sideways during scoops: the largest |y| of the bucket tip per episode.

The state has no lateral position, so this is what a 3-D distance to the terminal point would punish
that the policy cannot see. Also counts the episodes whose tip came within epsilon of the terminal
point in the arm's plane (x, z) and the ones that did in 3-D.

    .venv/bin/python tools/lateral_drift.py --policy default --episodes 100 --set pile.angle_deg=40
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig, parse_set_args
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
    for seed in range(args.seed, args.seed + args.episodes):
        obs, _ = env.reset(seed=seed)
        policy.reset()
        y, reached_planar, reached_3d = 0.0, False, False
        while True:
            obs, _, terminated, truncated, _ = env.step(policy.act(obs))
            offset = sim.tip_world - terminal
            y = max(y, abs(offset[1]))
            reached_planar |= bool(np.hypot(offset[0], offset[2]) <= config.reward.epsilon_m)
            reached_3d |= bool(np.linalg.norm(offset) <= config.reward.epsilon_m)
            if terminated or truncated:
                break
        largest.append(y)
        planar += reached_planar
        spatial += reached_3d
    largest = np.array(largest)
    print(f"{args.policy}, {args.episodes} episodes from seed {args.seed}, pile {config.pile.angle_deg:g} deg: "
          f"largest |y| of the tip per episode mean {largest.mean() * 100:.1f} cm, p90 "
          f"{np.percentile(largest, 90) * 100:.1f} cm, max {largest.max() * 100:.1f} cm; "
          f"within epsilon in x-z {planar}, in 3-D {spatial} (the episode ends at the first x-z reach)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
