"""Scripted scoops as demonstrations: transitions of the heuristic controller in an off-policy replay buffer.

An off-policy learner (DDPG, TD3, SAC) learns its critic from whatever is in its replay buffer. On a
pile that random exploration rarely gets into the bucket, a few scripted scoops show the critic
early that a full bucket at the terminal point pays more than hovering near it.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import gymnasium as gym
import numpy as np

from autoscoop.agents.loading import heuristic_for
from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env

DEMONSTRATION_SEED = 900_000
"""Episode seeds of demonstrations start here, apart from training (seed) and evaluation seeds."""


def add_scripted_demonstrations(replay_buffer: Any, config: ScoopConfig, episodes: int,
                                seed: int = DEMONSTRATION_SEED,
                                make_env: Callable[[ScoopConfig], gym.Env] = make_scoop_env,
                                time_limit_ends_return: bool = False) -> int:
    """Run ``episodes`` scripted episodes and add every transition to ``replay_buffer``.

    Args:
        replay_buffer: a Stable-Baselines3 ``ReplayBuffer`` (its ``n_envs`` transitions are added at once).
        config: the training environment's config (reward as trained, not as evaluated).
        episodes: scripted episodes to run.
        seed: seed of the first episode; the others follow.
        make_env: builds the environment from the config: the one training steps (its observations are
            the replay buffer's; the heuristic reads the state at their start).
        time_limit_ends_return: store time-limit ends as done, as a buffer that does not bootstrap them
            (``handle_timeout_termination=False``) stores the learner's own.

    Returns:
        The number of transitions added (a last remainder short of ``n_envs`` is left out).
        Time-limit ends are stored as not done (unless ``time_limit_ends_return``), so the learner treats them
        as it does its own.
    """
    if episodes < 0:
        raise ValueError(f"demonstration episodes = {episodes}; must be >= 0")
    config = demonstration_config(config)
    env = make_env(config)
    controller = _ClippedFloat32(heuristic_for(config))
    pending: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]] = []
    added = 0
    n_envs = replay_buffer.n_envs

    def collect(step: int, obs: np.ndarray, action: np.ndarray, reward: float, next_obs: np.ndarray,
                terminated: bool, truncated: bool, info: dict[str, Any]) -> None:
        nonlocal pending, added
        pending.append((obs, next_obs, action, reward, terminated or (truncated and time_limit_ends_return)))
        if len(pending) == n_envs:
            _add(replay_buffer, pending)
            added += n_envs
            pending = []

    try:
        for episode in range(episodes):
            rollout(controller, env, seed + episode, transition_observers=(collect,))
    finally:
        env.close()
    return added


def demonstration_config(config: ScoopConfig) -> ScoopConfig:
    """The world the scripted scoops are run in: the training world, with the counted mass in the state.

    The scripted controller ends its fill phase on the state's w; with the torque estimate (offset,
    noisy, late) it lifts early or late. Its demonstrations show how to scoop, in every drawn world
    of a ``randomize`` section, but read the mass as the counting sensor does.
    """
    config = config.replace(env=config.env.replace(mass_source="truth"))
    if config.randomize.active:
        config = config.replace(randomize=config.randomize.replace(torque_source_probability=(0.0,)))
    return config


class _ClippedFloat32:
    """The controller's actions clipped to [-1, 1] as float32: the actions the replay buffer stores."""

    def __init__(self, policy: Policy) -> None:
        self.policy = policy
        self.name = policy.name

    def reset(self) -> None:
        self.policy.reset()

    def act(self, observation: np.ndarray) -> np.ndarray:
        return np.clip(self.policy.act(observation), -1.0, 1.0).astype(np.float32)


def _add(replay_buffer: Any, transitions: list[tuple[np.ndarray, np.ndarray, np.ndarray, float, bool]]) -> None:
    obs, next_obs, action, reward, done = (np.array(column) for column in zip(*transitions))
    replay_buffer.add(obs, next_obs, action, reward, done, [{} for _ in transitions])
