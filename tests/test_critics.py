"""``critics``: how many critics an off-policy run trains (their targets take the lowest estimate)."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import DDPG

from autoscoop.core.config import ScoopConfig
from autoscoop.envs.privileged import PrivilegedObservation
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.factories import critics, make_policy
from autoscoop.training.settings import load_recipe


def test_the_key_is_a_small_whole_number_for_an_off_policy_algorithm():
    assert critics({"algo": "ddpg"}) is None
    assert critics({"algo": "ddpg", "critics": 2}) == 2
    for bad in (0, 11, 1.5, True, "2"):
        with pytest.raises(ValueError, match=r"critics = .* allowed whole numbers in \[1, 10\]"):
            critics({"algo": "ddpg", "critics": bad})
    with pytest.raises(ValueError, match="critics needs an off-policy algorithm"):
        critics({"algo": "ppo", "critics": 2})


def test_the_twin_critics_recipe_trains_ddpg_with_two_critics_of_the_papers_shape():
    spec = load_recipe("ddpg", "robot_history_deadline_twin_critics")
    assert spec["critics"] == 2 and spec["time_limit_ends_return"] is True  # its base's keys kept
    policy, kwargs = make_policy("ddpg", spec)
    assert kwargs == {"history_steps": 3, "n_critics": 2}
    env = PrivilegedObservation(make_scoop_env(ScoopConfig().with_overrides({"pile.variants": 1})))
    model = DDPG(policy, env, buffer_size=100, policy_kwargs={**kwargs, "history_steps": 1}, device="cpu")
    first, second = model.policy.critic.q_networks
    observation = torch.as_tensor(np.zeros((1, env.observation_space.shape[0]), dtype=np.float32))
    action = torch.zeros((1, 3))
    with torch.no_grad():
        values = model.policy.critic(observation, action)
    assert len(values) == 2 and not torch.equal(values[0], values[1])  # two critics from their own starts
    assert first is not second and len(model.policy.critic_target.q_networks) == 2
    _, plain_kwargs = make_policy("ddpg", load_recipe("ddpg", "robot_history_deadline"))
    assert "n_critics" not in plain_kwargs  # without the key, DDPG's own single critic
