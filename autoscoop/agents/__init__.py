"""Controllers: the scripted baseline and (with the train extra) the paper's DDPG policy."""

from autoscoop.agents.heuristic import HeuristicParams, HeuristicScooper
from autoscoop.core.policy import Policy

__all__ = ["HeuristicParams", "HeuristicScooper", "Policy"]
