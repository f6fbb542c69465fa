"""How much a policy flips its commands: the mean action change u_t per control period, per case.

u_t is ``reward.c_action_change``'s measure (``autoscoop/core/reward.py``, ``action_change``): the mean
over drive, lift and tilt of ((a_t - a_t-1) / 2)^2, 0 for a steady command and 1 for a full flip of all
three, a_-1 = 0. Prints, per policy and case, the mean u_t and the share of steps with u_t > 0.5.

    .venv/bin/python experiments/action_flips.py runs/RUN_A runs/RUN_B --cases nominal,heavy --episodes 10
"""

from __future__ import annotations

import argparse

import numpy as np

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.reward import action_change
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.stress import select_cases


def _recorder(actions: list[np.ndarray]):
    """A step observer appending each action to ``actions``."""
    def observe(_step: int, _obs: np.ndarray, action: np.ndarray, _reward: float, _info: dict) -> None:
        actions.append(np.asarray(action))
    return observe


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("policies", nargs="+", help="policy specs (a run directory, a file, default)")
    parser.add_argument("--cases", default="nominal,heavy", help="stress cases, comma-separated")
    parser.add_argument("--episodes", type=int, default=10)
    parser.add_argument("--seed", type=int, default=1000)
    args = parser.parse_args()
    print("| policy | case | mean u_t | steps with u_t > 0.5 |")
    print("|---|---|--:|--:|")
    for spec in args.policies:
        for case in select_cases(args.cases):
            config = case.config(ScoopConfig())
            policy, env = load_policy(spec, config), make_scoop_env(config)
            changes: list[float] = []
            for seed in range(args.seed, args.seed + args.episodes):
                actions: list[np.ndarray] = []
                rollout(policy, env, seed, [_recorder(actions)])
                for previous, action in zip([np.zeros(3), *actions[:-1]], actions, strict=True):
                    changes.append(action_change(previous, action))
            env.close()
            u = np.array(changes)
            print(f"| {spec} | {case.name} | {u.mean():.3f} | {np.mean(u > 0.5):.2f} |", flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
