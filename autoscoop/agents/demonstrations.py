"""Scripted scoops as demonstrations: transitions of the heuristic controller in an off-policy replay buffer.

An off-policy learner (DDPG, TD3, SAC) learns its critic from whatever is in its replay buffer. On a
pile that random exploration rarely gets into the bucket, a few scripted scoops show the critic
early that a full bucket at the terminal point pays more than hovering near it.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from autoscoop.agents.loading import heuristic_for
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env

DEMONSTRATION_SEED = 900_000
"""Episode seeds of demonstrations start here, apart from training (seed) and evaluation seeds."""


def add_scripted_demonstrations(replay_buffer: Any, config: ScoopConfig, episodes: int,
                                seed: int = DEMONSTRATION_SEED) -> int:
    """Run ``episodes`` scripted episodes and add every transition to ``replay_buffer``.

    Args:
        replay_buffer: a Stable-Baselines3 ``ReplayBuffer`` (its ``n_envs`` transitions are added at once).
        config: the training environment's config (reward as trained, not as evaluated).
        episodes: scripted episodes to run.
        seed: seed of the first episode; the others follow.

    Returns:
        The number of transitions added (a last remainder short of ``n_envs`` is left out).
        Time-limit ends are stored as not done, so the learner bootstraps them as it does its own.
    """
    if episodes < 0:
        raise ValueError(f"demonstration episodes = {episodes}; must be >= 0")
    env = make_scoop_env(config)
    controller = heuristic_for(config)
    pending: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]] = []
    added = 0
    n_envs = replay_buffer.n_envs
    try:
        for episode in range(episodes):
            obs, _ = env.reset(seed=seed + episode)
            controller.reset()
            while True:
                action = np.clip(controller.act(obs), -1.0, 1.0).astype(np.float32)
                next_obs, reward, terminated, truncated, _ = env.step(action)
                pending.append((obs, next_obs, action, float(reward), bool(terminated)))
                obs = next_obs
                if len(pending) == n_envs:
                    _add(replay_buffer, pending)
                    added += n_envs
                    pending = []
                if terminated or truncated:
                    break
    finally:
        env.close()
    return added


def _add(replay_buffer: Any, transitions: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]]) -> None:
    obs, next_obs, action, reward, done = (np.array(column) for column in zip(*transitions))
    replay_buffer.add(obs, next_obs, action, reward, done, [{} for _ in transitions])
