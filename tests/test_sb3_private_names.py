"""Resume reads and writes Stable-Baselines3 attributes that have no public way in: these tests fail the day SB3
renames them or changes their types, instead of a resumed run silently restarting its counters."""

import gymnasium as gym
import numpy as np
import pytest
from stable_baselines3.common.noise import NormalActionNoise, OrnsteinUhlenbeckActionNoise

from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.training.model_state import SB3_COUNTERS


def _fresh_model(algo: str):
    """A model on a small continuous-action world, built as training builds one (no learning)."""
    env = gym.make("Pendulum-v1")
    if algo == "ppo":
        return ALGORITHMS[algo]("MlpPolicy", env, n_steps=16, batch_size=16, device="cpu")
    return ALGORITHMS[algo]("MlpPolicy", env, learning_starts=16, buffer_size=64, device="cpu")


@pytest.mark.parametrize("algo", sorted(ALGORITHMS))
def test_the_counters_resume_keeps_exist_with_their_types(algo):
    model = _fresh_model(algo)
    for name, kind in SB3_COUNTERS.items():
        assert name in vars(model), f"{type(model).__name__} has no attribute {name}: resume would not restore it"
        value = getattr(model, name)
        assert type(value) is kind, f"{type(model).__name__}.{name} is a {type(value).__name__}, not a {kind.__name__}"


def test_the_counters_resume_keeps_are_those_sb3_moves_while_learning():
    model = _fresh_model("td3")
    before = {name: getattr(model, name) for name in SB3_COUNTERS}
    model.learn(40)
    after = {name: getattr(model, name) for name in SB3_COUNTERS}
    assert after["num_timesteps"] == 40 and after["_episode_num"] == before["_episode_num"]  # Pendulum: 200 steps
    assert after["_n_updates"] > before["_n_updates"] and after["_current_progress_remaining"] < 1.0


@pytest.mark.parametrize("noise", [OrnsteinUhlenbeckActionNoise(np.zeros(3), np.full(3, 0.2)),
                                   NormalActionNoise(np.zeros(3), np.full(3, 0.2))])
def test_the_exploration_noise_keeps_its_scale_in_sigma(noise):
    """``model_state`` and the noise schedule set the noise's scale through ``_sigma`` (no public setter)."""
    assert np.array_equal(noise._sigma, np.full(3, 0.2))
    noise._sigma = np.zeros(3)
    assert np.array_equal(noise(), np.zeros(3)), "setting _sigma no longer sets the noise's scale"
    if isinstance(noise, OrnsteinUhlenbeckActionNoise):  # its state, which model_state keeps too
        assert np.array_equal(noise.noise_prev, np.zeros(3))
