"""DDPG whose actor is held near a reference actor while it learns: fine-tuning without forgetting.

The actor's loss is TD3+BC's (Fujimoto and Gu, "A Minimalist Approach to Offline Reinforcement Learning", 2021)
with the reference actor's action where TD3+BC has the dataset's::

    loss = -lambda * Q(s, pi(s)) + mean((pi(s) - pi_ref(s))^2),    lambda = alpha / mean|Q(s, pi(s))|

over each batch of replayed states ``s``, actions in SB3's normalised units ([-1, 1] per joint). ``alpha`` weighs
what the critic says against staying where the reference is: the critic's gradient moves the actor only as far
as its advantage outweighs the pull back. ``lambda`` is scale-free (the Q values' mean absolute value is not
differentiated through), so one ``alpha`` serves any reward scale. Everything else is Stable-Baselines3's
DDPG (its ``TD3.train`` with one critic and no policy delay); without a reference it is DDPG unchanged.
"""

from __future__ import annotations

import copy

import numpy as np
import torch
import torch.nn.functional as F
from stable_baselines3 import DDPG
from stable_baselines3.common.utils import polyak_update


class AnchoredDDPG(DDPG):
    """:class:`stable_baselines3.DDPG` with the actor's loss pulled toward a frozen reference actor."""

    anchor_alpha: float = 0.0
    """weight of the critic's term against the pull to the reference (TD3+BC's alpha; 2.5 there)."""
    anchor_actor: torch.nn.Module | None = None
    """the frozen reference actor; ``None``: plain DDPG."""

    def set_anchor(self, actor: torch.nn.Module, alpha: float) -> None:
        """Hold the actor near a frozen copy of ``actor`` with weight ``alpha`` > 0 on the critic's term."""
        if not alpha > 0.0:
            raise ValueError(f"anchor alpha = {alpha} must be above 0")
        self.anchor_actor = copy.deepcopy(actor).requires_grad_(False).eval()
        self.anchor_alpha = float(alpha)

    def train(self, gradient_steps: int, batch_size: int = 100) -> None:
        if self.anchor_actor is None:
            super().train(gradient_steps, batch_size)
            return
        self.policy.set_training_mode(True)
        self._update_learning_rate([self.actor.optimizer, self.critic.optimizer])
        actor_losses, critic_losses, drifts = [], [], []
        for _ in range(gradient_steps):
            self._n_updates += 1
            replay = self.replay_buffer.sample(batch_size, env=self._vec_normalize_env)
            discounts = replay.discounts if replay.discounts is not None else self.gamma
            with torch.no_grad():
                next_actions = self.actor_target(replay.next_observations).clamp(-1, 1)
                next_q = torch.cat(self.critic_target(replay.next_observations, next_actions), dim=1)
                next_q, _ = torch.min(next_q, dim=1, keepdim=True)
                target_q = replay.rewards + (1 - replay.dones) * discounts * next_q
            critic_loss = sum(F.mse_loss(q, target_q) for q in self.critic(replay.observations, replay.actions))
            critic_losses.append(critic_loss.item())
            self.critic.optimizer.zero_grad()
            critic_loss.backward()
            self.critic.optimizer.step()

            actions = self.actor(replay.observations)
            q = self.critic.q1_forward(replay.observations, actions)
            with torch.no_grad():
                reference = self.anchor_actor(replay.observations)
                weight = self.anchor_alpha / q.abs().mean().clamp_min(1e-6)
            drift = F.mse_loss(actions, reference)
            actor_loss = -weight * q.mean() + drift
            actor_losses.append(actor_loss.item())
            drifts.append(drift.item())
            self.actor.optimizer.zero_grad()
            actor_loss.backward()
            self.actor.optimizer.step()
            polyak_update(self.critic.parameters(), self.critic_target.parameters(), self.tau)
            polyak_update(self.actor.parameters(), self.actor_target.parameters(), self.tau)
            polyak_update(self.critic_batch_norm_stats, self.critic_batch_norm_stats_target, 1.0)
            polyak_update(self.actor_batch_norm_stats, self.actor_batch_norm_stats_target, 1.0)
        self.logger.record("train/n_updates", self._n_updates, exclude="tensorboard")
        self.logger.record("train/actor_loss", np.mean(actor_losses))
        self.logger.record("train/critic_loss", np.mean(critic_losses))
        self.logger.record("train/anchor_drift", np.mean(drifts))
