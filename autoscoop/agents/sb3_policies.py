"""The paper's actor-critic as a Stable-Baselines3 policy for DDPG and TD3, SAC and sb3-contrib's TQC (policy
subclasses, not forks)."""

from __future__ import annotations

from typing import Any

import gymnasium as gym
import torch
from sb3_contrib.tqc.policies import Actor as TQCActor
from sb3_contrib.tqc.policies import Critic as TQCCritic
from sb3_contrib.tqc.policies import TQCPolicy
from stable_baselines3.common.policies import ContinuousCritic
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from stable_baselines3.sac.policies import Actor as SACActor
from stable_baselines3.sac.policies import SACPolicy
from stable_baselines3.td3.policies import Actor, TD3Policy
from torch import nn

from autoscoop.agents.networks import PAPER_LAYERS, PaperQNetwork, StateNormalizer, paper_mlp
from autoscoop.core.state import actor_input_size


class NormalizedState(BaseFeaturesExtractor):
    """Features = the actor's input (the state, or a history of ``history_steps`` states and commands) under
    the fixed normalisation of :mod:`autoscoop.core.state`."""

    def __init__(self, observation_space: gym.spaces.Box, history_steps: int = 1) -> None:
        super().__init__(observation_space, features_dim=int(observation_space.shape[0]))
        self.normalizer = StateNormalizer(history_steps)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.normalizer(observations)


class RobotState(BaseFeaturesExtractor):
    """The actor's features under an asymmetric critic: the robot's input only (the observation's first
    :func:`~autoscoop.core.state.actor_input_size` numbers), normalised; the privileged rest is dropped."""

    def __init__(self, observation_space: gym.spaces.Box, history_steps: int = 1) -> None:
        size = actor_input_size(history_steps)
        super().__init__(observation_space, features_dim=size)
        self.size = size
        self.normalizer = StateNormalizer(history_steps)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return self.normalizer(observations[:, :self.size])


class PrivilegedState(BaseFeaturesExtractor):
    """The critic's features under an asymmetric critic: the normalised actor input, then the simulator's
    privileged numbers as they are (:mod:`autoscoop.envs.privileged`; each of order one)."""

    def __init__(self, observation_space: gym.spaces.Box, history_steps: int = 1) -> None:
        super().__init__(observation_space, features_dim=int(observation_space.shape[0]))
        self.size = actor_input_size(history_steps)
        self.normalizer = StateNormalizer(history_steps)

    def forward(self, observations: torch.Tensor) -> torch.Tensor:
        return torch.cat([self.normalizer(observations[:, :self.size]), observations[:, self.size:]], dim=1)


def is_privileged(observation_space: gym.spaces.Space, history_steps: int = 1) -> bool:
    """Whether observations carry privileged numbers after the actor's input (an asymmetric critic's training)."""
    return int(observation_space.shape[0]) > actor_input_size(history_steps)


class PaperActorSB3(Actor):
    """SB3 actor whose mu is the paper's 100-80-60 network with layer normalisation and a tanh output."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        action_dim = int(self.action_space.shape[0])
        self.mu = nn.Sequential(paper_mlp(self.features_dim, self.net_arch), nn.Linear(self.net_arch[-1], action_dim),
                                nn.Tanh())


class PaperCriticSB3(ContinuousCritic):
    """SB3 critic(s) with the paper's merge: the action joins after the critic's first layer."""

    def __init__(self, *args: Any, net_arch: list[int], **kwargs: Any) -> None:
        super().__init__(*args, net_arch=net_arch, **kwargs)
        action_dim = int(self.action_space.shape[0])
        features_dim = int(self.features_extractor.features_dim)
        for idx in range(self.n_critics):
            delattr(self, f"qf{idx}")
        self.q_networks = []
        for idx in range(self.n_critics):
            q_net = PaperQNetwork(features_dim, action_dim, net_arch)
            self.add_module(f"qf{idx}", q_net)
            self.q_networks.append(q_net)

    def forward(self, obs: torch.Tensor, actions: torch.Tensor) -> tuple[torch.Tensor, ...]:
        with torch.set_grad_enabled(not self.share_features_extractor):
            features = self.extract_features(obs, self.features_extractor)
        return tuple(q_net(features, actions) for q_net in self.q_networks)

    def q1_forward(self, obs: torch.Tensor, actions: torch.Tensor) -> torch.Tensor:
        with torch.no_grad():
            features = self.extract_features(obs, self.features_extractor)
        return self.q_networks[0](features, actions)


class _PaperDefaults:
    """What the paper's SB3 policies share: its hidden layers, the state normalisation, its critic."""

    def __init__(self, *args: Any, history_steps: int = 1, **kwargs: Any) -> None:
        self.history_steps = int(history_steps)
        kwargs.setdefault("net_arch", list(PAPER_LAYERS))
        kwargs.setdefault("features_extractor_class", NormalizedState)
        kwargs.setdefault("features_extractor_kwargs", {"history_steps": self.history_steps})
        super().__init__(*args, **kwargs)

    def _get_constructor_parameters(self) -> dict[str, Any]:
        return {**super()._get_constructor_parameters(), "history_steps": self.history_steps}

    def make_critic(self, features_extractor: BaseFeaturesExtractor | None = None) -> PaperCriticSB3:
        if is_privileged(self.observation_space, self.history_steps):  # the critic sees all; never the actor's
            features_extractor = PrivilegedState(self.observation_space, self.history_steps)
        critic_kwargs = self._update_features_extractor(self.critic_kwargs, features_extractor)
        return PaperCriticSB3(**critic_kwargs).to(self.device)

    def actor_features(self, features_extractor: BaseFeaturesExtractor | None) -> BaseFeaturesExtractor | None:
        """The actor's features extractor: the state only, when observations carry privileged numbers."""
        if is_privileged(self.observation_space, self.history_steps):
            return RobotState(self.observation_space, self.history_steps)
        return features_extractor


class PaperPolicy(_PaperDefaults, TD3Policy):
    """TD3Policy with the paper's actor and critic (used by DDPG and TD3)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("activation_fn", nn.ReLU)
        super().__init__(*args, **kwargs)

    def make_actor(self, features_extractor: BaseFeaturesExtractor | None = None) -> PaperActorSB3:
        actor_kwargs = self._update_features_extractor(self.actor_kwargs, self.actor_features(features_extractor))
        return PaperActorSB3(**actor_kwargs).to(self.device)


class PaperSACActor(SACActor):
    """SAC's squashed-Gaussian actor with the paper's hidden layers (its mean action has the PaperActor's shape)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.latent_pi = paper_mlp(self.features_dim, self.net_arch)


class PaperSACPolicy(_PaperDefaults, SACPolicy):
    """SACPolicy with the paper's hidden layers for the actor and the paper's critics."""

    def make_actor(self, features_extractor: BaseFeaturesExtractor | None = None) -> PaperSACActor:
        actor_kwargs = self._update_features_extractor(self.actor_kwargs, self.actor_features(features_extractor))
        return PaperSACActor(**actor_kwargs).to(self.device)


class PaperTQCActor(TQCActor):
    """TQC's squashed-Gaussian actor with the paper's hidden layers (its mean action has the PaperActor's shape)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self.latent_pi = paper_mlp(self.features_dim, self.net_arch)


class PaperTQCPolicy(_PaperDefaults, TQCPolicy):
    """sb3-contrib's TQCPolicy with the paper's hidden layers for the actor; its critics are TQC's own quantile
    networks (``n_critics`` of them, ``n_quantiles`` outputs each), on the privileged features when the critic is
    asymmetric."""

    def make_actor(self, features_extractor: BaseFeaturesExtractor | None = None) -> PaperTQCActor:
        actor_kwargs = self._update_features_extractor(self.actor_kwargs, self.actor_features(features_extractor))
        return PaperTQCActor(**actor_kwargs).to(self.device)

    def make_critic(self, features_extractor: BaseFeaturesExtractor | None = None) -> TQCCritic:
        if is_privileged(self.observation_space, self.history_steps):  # the critic sees all; never the actor's
            features_extractor = PrivilegedState(self.observation_space, self.history_steps)
        critic_kwargs = self._update_features_extractor(self.critic_kwargs, features_extractor)
        return TQCCritic(**critic_kwargs).to(self.device)
