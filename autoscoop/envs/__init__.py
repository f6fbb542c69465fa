"""Gymnasium environments of autoscoop: the registered, versioned worlds.

Each id is :class:`autoscoop.envs.scoop.ScoopEnv` with config keys of its own (``gym.spec(ID).kwargs``);
keys given to ``gym.make`` are laid over them. An id's behaviour never changes: a change of observations,
reward or dynamics takes a new version (the class docstring's "Version History").
"""

from collections.abc import Mapping
from typing import Any

import gymnasium as gym

NAMESPACE = "autoscoop"
PAPER_ENV_ID = "autoscoop/Scoop-v1"
"""the paper's world, as the code gives it by default (:class:`autoscoop.core.config.ScoopConfig`)."""
PAPER_WORLDS: dict[str, dict[str, Any]] = {
    PAPER_ENV_ID: {},
    "autoscoop/Scoop-v0": {"sensor.odometry_window_steps": 1},
}
"""the paper's world and its earlier version (its one-step odometry), each with its config keys."""


def register_world(env_id: str, overrides: Mapping[str, Any]) -> None:
    """Register ``env_id`` as the scooping environment with these dotted config keys (idempotent)."""
    if env_id not in gym.registry:
        gym.register(id=env_id, entry_point="autoscoop.envs.scoop:make_scoop_env", kwargs=dict(overrides))


def register_envs() -> None:
    """Register the paper's worlds, :data:`PAPER_WORLDS` (idempotent)."""
    for env_id, overrides in PAPER_WORLDS.items():
        register_world(env_id, overrides)


def registered_worlds() -> dict[str, dict[str, Any]]:
    """Every registered ``autoscoop/`` id with its config keys, by id."""
    return {env_id: dict(spec.kwargs) for env_id, spec in sorted(gym.registry.items())
            if spec.namespace == NAMESPACE}


def worlds_help(laid_over: str = "the paper's world") -> str:
    """How ``--config`` and ``--set`` name the registered worlds: a line for a command's help; ``laid_over``
    says what the command's config starts from."""
    worlds = []
    for env_id, keys in registered_worlds().items():
        settings = " ".join(f"{key}={str(value).lower() if isinstance(value, bool) else value}"
                            for key, value in keys.items()) or "no --set"
        worlds.append(f"{env_id} = {settings}")
    return (f"worlds: episodes run in the config that --config and --set give, laid over {laid_over}; "
            "the registered Gymnasium ids are " + "; ".join(worlds))
