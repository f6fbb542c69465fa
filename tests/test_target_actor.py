"""``keep_target_actor``: a run can evaluate, keep and export DDPG's target actor (the Polyak average of the
actor's weights) instead of the actor it trails; the target's actions are the same from SB3 and from the
safe file."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from stable_baselines3 import DDPG, SAC

from autoscoop.agents.loading import SB3Policy
from autoscoop.agents.policy_files import ActorPolicy, PolicyFileError, actor_from_sb3
from autoscoop.agents.sb3_policies import PaperPolicy, PaperSACPolicy
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.training.checkpoints import save_safe_actor
from autoscoop.training.factories import keep_target_actor

SMALL = {"pile.variants": 1}


def test_the_key_needs_an_algorithm_with_a_target_actor():
    assert keep_target_actor({"algo": "ddpg"}) is False
    assert keep_target_actor({"algo": "ddpg", "keep_target_actor": True}) is True
    assert keep_target_actor({"algo": "td3", "keep_target_actor": True}) is True
    for algo in ("sac", "tqc", "ppo"):
        with pytest.raises(ValueError, match="keep_target_actor needs ddpg or td3"):
            keep_target_actor({"algo": algo, "keep_target_actor": True})
    with pytest.raises(ValueError, match="must be true or false"):
        keep_target_actor({"algo": "ddpg", "keep_target_actor": "yes"})


@pytest.fixture()
def model_with_a_target_apart():
    """A DDPG model of the paper's policy whose target actor differs from its actor."""
    env = make_scoop_env(ScoopConfig().with_overrides(SMALL))
    model = DDPG(PaperPolicy, env, buffer_size=100)
    with torch.no_grad():
        for parameter in model.policy.actor_target.parameters():
            parameter.add_(0.05 * torch.randn_like(parameter))
    yield model, env
    env.close()


def test_the_target_actor_acts_alike_from_sb3_and_from_its_safe_file(model_with_a_target_apart, tmp_path):
    model, env = model_with_a_target_apart
    obs, _ = env.reset(seed=0)
    online, target = SB3Policy(model, "online"), SB3Policy(model, "target", target=True)
    assert not np.allclose(online.act(obs), target.act(obs)), "the fixture's target differs from the actor"
    assert save_safe_actor(model, tmp_path / "target.safetensors", {"state_frame": "chassis"}, target=True)
    from_file = ActorPolicy(tmp_path / "target.safetensors")
    assert from_file.metadata["target_actor"] is True
    for seed in range(3):
        obs, _ = env.reset(seed=seed)
        np.testing.assert_allclose(from_file.act(obs), target.act(obs), atol=1e-6)
    assert save_safe_actor(model, tmp_path / "online.safetensors", {"state_frame": "chassis"})
    assert "target_actor" not in ActorPolicy(tmp_path / "online.safetensors").metadata


def test_sac_has_no_target_actor_to_keep(tmp_path):
    env = make_scoop_env(ScoopConfig().with_overrides(SMALL))
    try:
        model = SAC(PaperSACPolicy, env, buffer_size=100)
        with pytest.raises(PolicyFileError, match="no target actor"):
            actor_from_sb3(model, target=True)
        assert not save_safe_actor(model, tmp_path / "actor.safetensors", {}, target=True)
    finally:
        env.close()
