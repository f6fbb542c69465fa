"""Why does DDPG with two environments not learn to scoop? A repro without autoscoop's training code.

Plain Stable-Baselines3 DDPG (no autoscoop callback, no noise schedule, no checkpoints) on
``N`` scoop environments in one ``DummyVecEnv``, the paper recipe's hyperparameters, until 400
episodes have ended; it prints the training success of each block of 50 episodes. On Pendulum-v1
(``--task pendulum``) the same SB3 learns with one or two environments.

Measured 2026-12-02 (SB3 2.9.2, seed 0): scoop, 1 environment: 0.02, 0.16, 0.76, 0.72, 0.86, 0.80,
0.84, 0.82; 2 environments: 0.00 in every block, also with SB3's MlpPolicy and with both
environments reset with the same seed (the same piles). (``--no-noise`` fails with one environment
too: it needs the exploration noise.)
Pendulum, 12,000 steps: mean return -162 with 1 environment, -170 with 2 (both learned). So the
cause lies with two scoop environments, not with autoscoop's training loop or SB3's vectorised DDPG.

    .venv/bin/python benchmarks/n_envs_learning_repro.py --n-envs 2 [--policy mlp] [--no-noise]
"""

from __future__ import annotations

import argparse
from functools import partial

import numpy as np
import torch
from stable_baselines3 import DDPG
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise, VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv

from autoscoop.agents.sb3_policies import PaperPolicy
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.settings import load_recipe


class Successes(BaseCallback):
    """Collects each ended episode's success; stops after ``episodes``."""

    def __init__(self, episodes: int) -> None:
        super().__init__()
        self.episodes, self.successes = episodes, []

    def _on_step(self) -> bool:
        for done, info in zip(self.locals["dones"], self.locals["infos"]):
            if done:
                self.successes.append(bool(info["success"]))
        return len(self.successes) < self.episodes


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--policy", choices=["paper", "mlp"], default="paper")
    parser.add_argument("--no-noise", action="store_true")
    parser.add_argument("--task", choices=["scoop", "pendulum"], default="scoop")
    parser.add_argument("--episodes", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    torch.set_num_threads(1)
    n = args.n_envs
    if args.task == "pendulum":
        import gymnasium as gym  # noqa: PLC0415
        from stable_baselines3.common.evaluation import evaluate_policy  # noqa: PLC0415

        vec = DummyVecEnv([partial(gym.make, "Pendulum-v1") for _ in range(n)])
        vec.seed(args.seed)
        model = DDPG("MlpPolicy", vec, seed=args.seed, learning_starts=1000, gradient_steps=n, verbose=0)
        model.learn(12_000)
        print(n, "environments, Pendulum mean return:", evaluate_policy(model, gym.make("Pendulum-v1"), 5)[0])
        return
    spec = load_recipe("ddpg", "paper")
    config = ScoopConfig().with_overrides(spec["env"])
    vec = DummyVecEnv([partial(make_scoop_env, config) for _ in range(n)])
    vec.seed(args.seed)
    noise = None
    if not args.no_noise:
        base = OrnsteinUhlenbeckActionNoise(np.zeros(3), np.full(3, spec["noise"]["sigma_start"]),
                                            theta=spec["noise"]["theta"], dt=1.0)
        noise = VectorizedActionNoise(base, n) if n > 1 else base
    policy = "MlpPolicy" if args.policy == "mlp" else PaperPolicy
    model = DDPG(policy, vec, action_noise=noise, seed=args.seed, device="cpu", **spec["hyperparams"])
    watch = Successes(args.episodes)
    model.learn(10**8, callback=watch)
    rates = [round(float(np.mean(watch.successes[a:a + 50])), 2) for a in range(0, args.episodes, 50)]
    print(n, "environments, training success per 50 episodes:", rates)


if __name__ == "__main__":
    main()
