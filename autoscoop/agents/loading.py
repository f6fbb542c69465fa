"""Turn a ``--policy`` argument into a controller."""

from __future__ import annotations

from autoscoop.agents.base import Policy
from autoscoop.agents.heuristic import HeuristicParams, HeuristicScooper
from autoscoop.config import ScoopConfig


class PolicyError(ValueError):
    """A policy argument that cannot be loaded; the message says why and what is accepted."""


def heuristic_for(config: ScoopConfig) -> HeuristicScooper:
    """The scripted baseline, aimed at the config's terminal point and control period."""
    return HeuristicScooper(HeuristicParams(
        terminal_dx_m=config.reward.terminal_dx_m, terminal_z_m=config.reward.terminal_z_m,
        control_period_s=config.env.control_period_s))


def load_policy(spec: str, config: ScoopConfig, trust: bool = False) -> Policy:
    """A controller from ``heuristic`` (the scripted baseline); trained policies plug in here too.

    Args:
        spec: ``heuristic``, ``default`` (the shipped policy) or a policy file.
        config: the scene it will run in.
        trust: allow loading pickled files (SB3 zips) from outside a run directory.

    Raises:
        PolicyError: if ``spec`` names nothing loadable.
    """
    if spec == "heuristic":
        return heuristic_for(config)
    raise PolicyError(f"unknown policy {spec!r}; use 'heuristic'")
