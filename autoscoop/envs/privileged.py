"""What only the simulator knows, beside the robot's state: the observation of a critic that sees it.

An asymmetric actor-critic (training only): the critic judges the actor's actions knowing the true
load, the drawn material and the sensor link, while the actor sees only the 12-number state the
robot senses (:mod:`autoscoop.core.state`), so that only the actor ships. The wrapper appends
these numbers to the state; the actor's network reads the first
:data:`~autoscoop.core.state.STATE_SIZE` of them (:mod:`autoscoop.agents.sb3_policies`).

| index | name                | meaning                                                      | unit |
|-------|---------------------|--------------------------------------------------------------|------|
| 12    | true_fill           | counted mass in the bucket / rated load (the reward's w)     | -    |
| 13    | volumetric_fill     | particles' volume / bucket capacity                          | -    |
| 14    | relative_density    | particle mass / 0.3 kg (the paper's material)                | -    |
| 15    | torque_mass         | 1 when the state's w is the torque estimate, else 0          | -    |
| 16    | sensor_delay        | sensor.delay_s / 0.05 s                                      | -    |
| 17    | tip_to_pile         | true tip-to-pile distance (no range noise)                   | m    |
| 18    | tip_to_terminal     | tip to the terminal point, in the arm's plane                | m    |
| 19    | time_used           | elapsed time / env.max_episode_s (the time limit is near)    | -    |

A physics failure's numbers (NaN) read as 0.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium as gym
import numpy as np

from autoscoop.core.config import PileConfig

PRIVILEGED_NAMES = ("true_fill", "volumetric_fill", "relative_density", "torque_mass", "sensor_delay",
                    "tip_to_pile", "tip_to_terminal", "time_used")
"""The numbers appended to the state, in order (the module docstring gives their meaning)."""
PRIVILEGED_SIZE = len(PRIVILEGED_NAMES)
NOMINAL_PARTICLE_MASS_KG = PileConfig().particle_mass_kg
"""the paper's material, kg per particle: relative_density 1."""
NOMINAL_DELAY_S = 0.05
"""the scale of sensor_delay: the link of the stress suite's delay case, s."""


def privileged_features(info: dict[str, Any], config: Any) -> np.ndarray:
    """The privileged numbers of one step, from its ``info`` and the episode's config."""
    values = (info.get("fill_factor", 0.0), info.get("volumetric_fill", 0.0),
              config.pile.particle_mass_kg / NOMINAL_PARTICLE_MASS_KG, float(config.env.mass_source == "torque"),
              config.sensor.delay_s / NOMINAL_DELAY_S, info.get("tip_to_pile_m", 0.0),
              info.get("tip_to_terminal_m", 0.0), info.get("elapsed_s", 0.0) / config.env.max_episode_s)
    return np.array([v if math.isfinite(v) else 0.0 for v in map(float, values)], dtype=np.float32)


class PrivilegedObservation(gym.Wrapper):
    """Observations of the robot's state (or the actor's input of :mod:`autoscoop.envs.history`), then
    :data:`PRIVILEGED_NAMES`.

    Args:
        env: an autoscoop environment (``make_scoop_env``), whose ``unwrapped.episode_config`` is the
            episode's world.
    """

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        size = int(env.observation_space.shape[0]) + PRIVILEGED_SIZE
        self.observation_space = gym.spaces.Box(-np.inf, np.inf, shape=(size,), dtype=np.float32)

    def reset(self, **kwargs: Any) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(**kwargs)
        return self._extended(obs, info), info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        return self._extended(obs, info), reward, terminated, truncated, info

    def _extended(self, obs: np.ndarray, info: dict[str, Any]) -> np.ndarray:
        extra = privileged_features(info, self.env.unwrapped.episode_config)
        return np.concatenate([np.asarray(obs, dtype=np.float32), extra])
