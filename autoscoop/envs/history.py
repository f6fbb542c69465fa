"""The actor's input as training steps it: the environment's state with a short history of states and commands.

A controller trained with ``history_steps`` k > 1 reads k states and the k commands before them
(:class:`autoscoop.core.state.ActorInputHistory`, the one builder that evaluation, the ONNX runner and
the ROS node use too). During training the learner's observations must be that input, so this wrapper
builds it from the environment's 12-number state and the actions the learner sends.
"""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import numpy as np

from autoscoop.core.state import ActorInputHistory


class ActorInputObservation(gym.Wrapper):
    """Observations of :func:`~autoscoop.core.state.actor_input_size` numbers: the newest state first, then
    the older states, then the commands given (newest first).

    Args:
        env: an autoscoop environment whose observations are the 12-number state.
        history_steps: k, 1 or more (1: the state as it is).
    """

    def __init__(self, env: gym.Env, history_steps: int) -> None:
        super().__init__(env)
        self.history = ActorInputHistory(history_steps)
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(self.history.size,), dtype=np.float32)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(**kwargs)
        self.history.reset()
        return self.history.observe(obs), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        self.history.acted(action)
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self.history.observe(obs), reward, terminated, truncated, info
