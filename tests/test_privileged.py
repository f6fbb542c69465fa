"""The asymmetric critic: the critic sees the simulator's privileged numbers, the actor only the state."""

from __future__ import annotations

import csv
import json

import numpy as np
import pytest
import torch
from torch import nn

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.state import STATE_SIZE
from autoscoop.envs.privileged import PRIVILEGED_NAMES, PRIVILEGED_SIZE, PrivilegedObservation
from autoscoop.envs.scoop import make_scoop_env

SMALL = {"pile.variants": 2}


def linear_sizes(module: nn.Module) -> list[tuple[int, int]]:
    return [(m.in_features, m.out_features) for m in module.modules() if isinstance(m, nn.Linear)]


def test_observation_is_the_state_then_the_privileged_numbers():
    config = ScoopConfig().with_overrides({**SMALL, "sensor.range_noise_m": 0.01, "pile.particle_mass_kg": 0.2})
    plain, wrapped = make_scoop_env(config), PrivilegedObservation(make_scoop_env(config))
    state, _ = plain.reset(seed=4)
    obs, info = wrapped.reset(seed=4)
    assert obs.shape == (STATE_SIZE + PRIVILEGED_SIZE,) and wrapped.observation_space.contains(obs)
    np.testing.assert_array_equal(obs[:STATE_SIZE], state)  # the same state, noise included
    named = dict(zip(PRIVILEGED_NAMES, obs[STATE_SIZE:]))
    assert named["relative_density"] == pytest.approx(0.2 / 0.3)
    assert named["tip_to_pile"] == pytest.approx(info["tip_to_pile_m"])  # the true range, not the noisy one
    assert obs[5] != pytest.approx(info["tip_to_pile_m"], abs=1e-6)
    for _ in range(6):
        obs, _, _, _, info = wrapped.step(np.array([1.0, 0.2, 0.2], dtype=np.float32))
    named = dict(zip(PRIVILEGED_NAMES, obs[STATE_SIZE:]))
    assert named["true_fill"] == pytest.approx(info["fill_factor"], rel=1e-6)
    assert named["time_used"] == pytest.approx(info["elapsed_s"] / config.env.max_episode_s, rel=1e-6)


@pytest.mark.parametrize("algo", ["ddpg", "sac", "tqc"])
def test_the_actor_reads_the_state_and_the_critic_everything(algo):
    from sb3_contrib import TQC
    from stable_baselines3 import DDPG, SAC

    from autoscoop.agents.policy_files import actor_from_sb3
    from autoscoop.agents.sb3_policies import PaperPolicy, PaperSACPolicy, PaperTQCPolicy

    env = PrivilegedObservation(make_scoop_env(ScoopConfig().with_overrides(SMALL)))
    algo_cls, policy = {"ddpg": (DDPG, PaperPolicy), "sac": (SAC, PaperSACPolicy), "tqc": (TQC, PaperTQCPolicy)}[algo]
    model = algo_cls(policy, env, buffer_size=100)
    critic = model.policy.critic
    merged_later = 0 if algo == "tqc" else 3  # the paper's critic merges the action after its first layer, TQC's at once
    assert linear_sizes(critic)[0] == (STATE_SIZE + PRIVILEGED_SIZE + 3 - merged_later, 100)
    obs = torch.as_tensor(np.random.default_rng(0).normal(size=(4, STATE_SIZE + PRIVILEGED_SIZE)).astype(np.float32))
    other = obs.clone()
    other[:, STATE_SIZE:] += 5.0  # the privileged part changes the critic's value, never the actor's action
    with torch.no_grad():
        action = model.policy.actor(obs) if algo == "ddpg" else model.policy.actor(obs, deterministic=True)
        action_other = model.policy.actor(other) if algo == "ddpg" else model.policy.actor(other, deterministic=True)
        assert torch.equal(action, action_other)
        value, value_other = critic(obs, action), critic(other, action)
        first = (value[0], value_other[0]) if isinstance(value, tuple) else (value, value_other)  # TQC: one tensor
        assert not torch.allclose(*first)
        exported = actor_from_sb3(model)  # the shipped actor: the state's 12 numbers in
        assert linear_sizes(exported)[0] == (STATE_SIZE, 100)
        assert torch.allclose(exported(obs[:, :STATE_SIZE]), action, atol=1e-6)


def test_training_with_a_privileged_critic_writes_an_actor_of_the_state(tmp_path, monkeypatch):
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    original = settings.load_recipe
    monkeypatch.setattr(train_mod, "load_recipe",
                        lambda algo, recipe: {**original(algo, "paper"), "privileged_critic": True,
                                              "demo_episodes": 1})
    out = tmp_path / "run"
    train_mod.train(train_mod.TrainArgs(episodes=4, out=out, progress=False, overrides=SMALL,
                                        eval_every=2, eval_episodes=1, checkpoint_every=2))
    assert json.loads((out / "run.json").read_text())["status"] == "finished"
    assert [row["episode"] for row in csv.DictReader(open(out / "evaluations.csv"))] == ["2", "4"]
    policy = load_policy(str(out), ScoopConfig())
    assert policy.act(np.zeros(STATE_SIZE, dtype=np.float32)).shape == (3,)


def test_a_privileged_critic_needs_the_papers_actor_critic(tmp_path, monkeypatch):
    from autoscoop.training import run as train_mod
    from autoscoop.training import settings

    original = settings.load_recipe
    monkeypatch.setattr(train_mod, "load_recipe",
                        lambda algo, recipe: {**original(algo, "paper"), "privileged_critic": True})
    with pytest.raises(ValueError, match="privileged_critic"):
        train_mod.train(train_mod.TrainArgs(algo="ppo", episodes=2, out=tmp_path / "run", progress=False))
