"""The one interface every controller offers to evaluation, the demo and the ROS node."""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Policy(Protocol):
    """A controller that maps the 12-number state to a 3-number action in [-1, 1]."""

    name: str

    def reset(self) -> None:
        """Forget the previous episode (called before each episode)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action for this state: (drive, lift, tilt), each in [-1, 1]."""
