"""Gymnasium environments of autoscoop."""

import gymnasium as gym

ENV_ID = "autoscoop/Scoop-v0"


def register_envs() -> None:
    """Register ``autoscoop/Scoop-v0`` (idempotent)."""
    if ENV_ID not in gym.registry:
        gym.register(id=ENV_ID, entry_point="autoscoop.envs.scoop:make_scoop_env")
