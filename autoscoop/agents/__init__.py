"""Controllers: the scripted baseline and (with the train extra) the paper's DDPG policy."""

from autoscoop.core.policy import Policy
from autoscoop.agents.heuristic import HeuristicParams, HeuristicScooper

__all__ = ["HeuristicParams", "HeuristicScooper", "Policy"]
