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

import gymnasium as gym
import numpy as np
import torch
from stable_baselines3 import DDPG
from stable_baselines3.common.buffers import ReplayBuffer
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.noise import OrnsteinUhlenbeckActionNoise, VectorizedActionNoise
from stable_baselines3.common.vec_env import DummyVecEnv

from autoscoop.agents.sb3_policies import PaperPolicy
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.settings import load_recipe


class Successes(BaseCallback):
    """Collects each ended episode's success (of the first environment only with ``first_only``);
    stops after ``episodes``."""

    def __init__(self, episodes: int, first_only: bool = False) -> None:
        super().__init__()
        self.episodes, self.successes, self.first_only = episodes, [], first_only

    def _on_step(self) -> bool:
        pairs = list(zip(self.locals["dones"], self.locals["infos"]))
        for done, info in pairs[:1] if self.first_only else pairs:
            if done:
                self.successes.append(bool(info["success"]))
        return len(self.successes) < self.episodes


class FirstEnvironmentBuffer(ReplayBuffer):
    """A replay buffer that keeps the first environment's transitions only (``--store first``)."""

    def __init__(self, *args: object, n_envs: int = 1, **kwargs: object) -> None:
        super().__init__(*args, n_envs=1, **kwargs)

    def add(self, obs, next_obs, action, reward, done, infos) -> None:
        super().add(obs[:1], next_obs[:1], action[:1], reward[:1], done[:1], infos[:1])


class IdleEnv(gym.Env):
    """A stand-in second environment (``--second idle``): zeros for 32 steps, nothing else."""

    observation_space = gym.spaces.Box(-np.inf, np.inf, (12,), np.float32)
    action_space = gym.spaces.Box(-1.0, 1.0, (3,), np.float32)

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        super().reset(seed=seed)
        self.steps = 0
        return np.zeros(12, np.float32), {}

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.steps += 1
        return np.zeros(12, np.float32), 0.0, False, self.steps >= 32, {"success": False}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--n-envs", type=int, default=2)
    parser.add_argument("--policy", choices=["paper", "mlp"], default="paper")
    parser.add_argument("--no-noise", action="store_true")
    parser.add_argument("--task", choices=["scoop", "pendulum"], default="scoop")
    parser.add_argument("--episodes", type=int, default=400)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--store", choices=["all", "first"], default="all",
                        help="first: keep only the first environment's transitions, count only its episodes")
    parser.add_argument("--second", choices=["scoop", "idle"], default="scoop",
                        help="idle: the second environment is a stand-in (with --store first it changes nothing "
                             "the learner sees; only the draws of its exploration noise remain)")
    args = parser.parse_args()
    torch.set_num_threads(1)
    n = args.n_envs
    if args.task == "pendulum":
        from stable_baselines3.common.evaluation import evaluate_policy  # noqa: PLC0415

        vec = DummyVecEnv([partial(gym.make, "Pendulum-v1") for _ in range(n)])
        vec.seed(args.seed)
        model = DDPG("MlpPolicy", vec, seed=args.seed, learning_starts=1000, gradient_steps=n, verbose=0)
        model.learn(12_000)
        print(n, "environments, Pendulum mean return:", evaluate_policy(model, gym.make("Pendulum-v1"), 5)[0])
        return
    spec = load_recipe("ddpg", "paper")
    config = ScoopConfig().with_overrides(spec["env"])
    factories = [partial(make_scoop_env, config) for _ in range(n)]
    if n > 1 and args.second == "idle":
        factories[1:] = [IdleEnv] * (n - 1)
    vec = DummyVecEnv(factories)
    vec.seed(args.seed)
    noise = None
    if not args.no_noise:
        base = OrnsteinUhlenbeckActionNoise(np.zeros(3), np.full(3, spec["noise"]["sigma_start"]),
                                            theta=spec["noise"]["theta"], dt=1.0)
        noise = VectorizedActionNoise(base, n) if n > 1 else base
    policy = "MlpPolicy" if args.policy == "mlp" else PaperPolicy
    hyperparams = dict(spec["hyperparams"])
    if args.store == "first" and n > 1:
        hyperparams["replay_buffer_class"] = FirstEnvironmentBuffer
    model = DDPG(policy, vec, action_noise=noise, seed=args.seed, device="cpu", **hyperparams)
    watch = Successes(args.episodes, first_only=args.store == "first")
    model.learn(10**8, callback=watch)
    rates = [round(float(np.mean(watch.successes[a:a + 50])), 2) for a in range(0, args.episodes, 50)]
    print(n, "environments, training success per 50 episodes:", rates, flush=True)


if __name__ == "__main__":
    main()
