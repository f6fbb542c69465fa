"""Why does DDPG with two environments not learn to scoop? A repro without autoscoop's training code.

Plain Stable-Baselines3 DDPG (no autoscoop callback, no noise schedule, no checkpoints) on
``N`` scoop environments in one ``DummyVecEnv``, the paper recipe's hyperparameters, until 400
episodes have ended; it prints the training success of each block of 50 episodes. On Pendulum-v1
(``--task pendulum``) the same SB3 learns with one or two environments.

Measured (SB3 2.9.2, seed 0): scoop, 1 environment: 0.02, 0.16, 0.76, 0.72, 0.86, 0.80,
0.84, 0.82; 2 environments: 0.00 in every block, also with SB3's MlpPolicy and with both
environments reset with the same seed (the same piles). (``--no-noise`` fails with one environment
too: it needs the exploration noise.)
Pendulum, 12,000 steps: mean return -162 with 1 environment, -170 with 2 (both learned). So the
cause lies with two scoop environments, not with autoscoop's training loop or SB3's vectorised DDPG.

Measured again in a later session, 300 episodes, seeds 0-7: 1 environment learned in 4 of 8
seeds (0, 1, 4, 6: success 0.84, 0.86, 0.94, 0.82 in the last 50 episodes); 2 environments in 0 of 8,
and in 0 of 8 with ``--gradient-steps 2`` (one update per transition, as with one environment). With
150 episodes of the kept environment counted (seeds 0-5): storing the first environment's transitions
only (``--store first``; the second acts but is not learned from) learned in 1 of 6 (seed 3), the second's
only (``--store second``) in 1 of 6 (seed 3), one environment alone in 2 of 6 (seeds 0, 1); ``--store first --second
idle`` (a stand-in second environment of zeros) gives seed 0's run bit for bit as ``--store first``, so
acting in two environments and the second's exploration noise do not break learning. Both environments'
transitions in a one-environment buffer (``--store flat --gradient-steps 2``) did not learn (seeds 0, 1),
so SB3's two-environment buffer layout is not the cause either. What breaks it is learning from both
environments' transitions at once; why is still open. With 50 scripted scoops in the replay buffer
(``autoscoop train --recipe robot --n-envs 2``) two environments do learn (seed 10).

    .venv/bin/python experiments/n_envs_learning_repro.py --n-envs 2 [--policy mlp] [--no-noise] [--episodes 300]
        [--seed S] [--gradient-steps 2] [--store first|second|flat] [--second idle]
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
    """Collects each ended episode's success (of environment ``only`` alone when given); stops after ``episodes``."""

    def __init__(self, episodes: int, only: int | None = None) -> None:
        super().__init__()
        self.episodes, self.successes, self.only = episodes, [], only

    def _on_step(self) -> bool:
        pairs = list(zip(self.locals["dones"], self.locals["infos"]))
        for done, info in pairs if self.only is None else pairs[self.only:self.only + 1]:
            if done:
                self.successes.append(bool(info["success"]))
        return len(self.successes) < self.episodes


class OneLayoutBuffer(ReplayBuffer):
    """A replay buffer in the one-environment layout that keeps the transitions of the environments in
    ``KEEP`` (``--store first``: the first only; ``second``: the second only; ``flat``: every one, a row each)."""

    KEEP: slice = slice(0, 1)

    def __init__(self, *args: object, n_envs: int = 1, **kwargs: object) -> None:
        super().__init__(*args, n_envs=1, **kwargs)

    def add(self, obs, next_obs, action, reward, done, infos) -> None:
        for i in range(len(obs))[self.KEEP]:
            super().add(obs[i:i + 1], next_obs[i:i + 1], action[i:i + 1], reward[i:i + 1], done[i:i + 1],
                        infos[i:i + 1])


BUFFERS = {"first": type("FirstOnly", (OneLayoutBuffer,), {"KEEP": slice(0, 1)}),
           "second": type("SecondOnly", (OneLayoutBuffer,), {"KEEP": slice(1, 2)}),
           "flat": type("EveryOne", (OneLayoutBuffer,), {"KEEP": slice(None)})}


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
    parser.add_argument("--gradient-steps", type=int, default=None,
                        help="gradient steps per vector step (default: the recipe's, 1; N for one per transition)")
    parser.add_argument("--store", choices=["all", "first", "second", "flat"], default="all",
                        help="first / second: keep only that environment's transitions and count only its "
                             "episodes; flat: keep both in a one-environment buffer, a row each (count the first's)")
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
    if args.gradient_steps is not None:
        hyperparams["gradient_steps"] = args.gradient_steps
    if args.store != "all" and n > 1:
        hyperparams["replay_buffer_class"] = BUFFERS[args.store]
    model = DDPG(policy, vec, action_noise=noise, seed=args.seed, device="cpu", **hyperparams)
    watch = Successes(args.episodes, only={"all": None, "second": 1}.get(args.store, 0) if n > 1 else None)
    model.learn(10**8, callback=watch)
    rates = [round(float(np.mean(watch.successes[a:a + 50])), 2) for a in range(0, args.episodes, 50)]
    print(n, "environments, training success per 50 episodes:", rates, flush=True)


if __name__ == "__main__":
    main()
