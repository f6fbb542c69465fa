"""The Stable-Baselines3 algorithms ``autoscoop train --algo`` offers, by name."""

from __future__ import annotations

from sb3_contrib import TQC
from stable_baselines3 import DDPG, PPO, SAC, TD3
from stable_baselines3.common.base_class import BaseAlgorithm

ALGORITHMS: dict[str, type[BaseAlgorithm]] = {"ddpg": DDPG, "td3": TD3, "sac": SAC, "tqc": TQC, "ppo": PPO}
"""ddpg is the paper's; td3 and sac are its successors; tqc (sb3-contrib) is SAC with distributional critics
whose highest quantiles are dropped; ppo is on-policy (no replay buffer)."""
