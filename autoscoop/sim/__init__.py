"""MuJoCo side of autoscoop: the scene builder and named accessors. Simulation only, no plotting."""

from autoscoop.sim.pile import pile_layout
from autoscoop.sim.scene import ScoopSim

__all__ = ["ScoopSim", "pile_layout"]
