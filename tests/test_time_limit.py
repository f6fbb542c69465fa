"""``time_limit_ends_return``: a critic that reads the clock stores a time-out as the end of the return."""

from __future__ import annotations

import numpy as np
import pytest
from stable_baselines3 import DDPG
from stable_baselines3.common.buffers import ReplayBuffer

from autoscoop.agents.demonstrations import add_scripted_demonstrations
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.factories import replay_buffer_settings, time_limit_ends_return
from autoscoop.training.settings import load_recipe

SHORT = {"pile.variants": 1, "env.max_episode_s": 1.0}
"""one pile, a 1-s limit: the scripted scoop (several seconds) is cut off by the time limit every time."""


def test_the_key_needs_the_critic_that_reads_the_time():
    assert time_limit_ends_return({}) is False and replay_buffer_settings({}) == {}
    spec = {"privileged_critic": True, "time_limit_ends_return": True}
    assert time_limit_ends_return(spec) is True
    assert replay_buffer_settings(spec) == {"handle_timeout_termination": False}
    with pytest.raises(ValueError, match="needs privileged_critic"):
        time_limit_ends_return({"time_limit_ends_return": True})
    for bad in ("yes", 1, None):
        with pytest.raises(ValueError, match="time_limit_ends_return .* must be true or false"):
            time_limit_ends_return({"privileged_critic": True, "time_limit_ends_return": bad})


def test_the_deadline_recipe_sets_it_and_sb3_stops_bootstrapping_time_outs():
    spec = load_recipe("ddpg", "robot_history_deadline")
    assert time_limit_ends_return(spec) and spec["privileged_critic"]
    assert not time_limit_ends_return(load_recipe("ddpg", "robot_history"))
    env = make_scoop_env(ScoopConfig().with_overrides(SHORT))
    try:
        model = DDPG("MlpPolicy", env, buffer_size=100, learning_starts=0,
                     replay_buffer_kwargs=replay_buffer_settings(spec))
        assert model.replay_buffer.handle_timeout_termination is False
    finally:
        env.close()


@pytest.mark.parametrize("ends", [False, True])
def test_demonstrations_store_time_outs_as_the_learner_does(ends):
    config = ScoopConfig().with_overrides(SHORT)
    env = make_scoop_env(config)
    buffer = ReplayBuffer(100, env.observation_space, env.action_space, n_envs=1)
    env.close()
    added = add_scripted_demonstrations(buffer, config, episodes=2, time_limit_ends_return=ends)
    assert added == config.max_episode_steps * 2, "two scoops, each cut off at the time limit"
    dones = buffer.dones[:buffer.pos, 0]
    ends_at = np.flatnonzero(dones).tolist()
    assert ends_at == ([config.max_episode_steps - 1, 2 * config.max_episode_steps - 1] if ends else [])
