"""The one interface every controller offers to evaluation, the demo and the ROS node."""

from __future__ import annotations

from typing import Any, Protocol

import numpy as np


class Policy(Protocol):
    """A controller that maps the 12-number state to a 3-number action in [-1, 1].

    A controller may also carry ``state_frame`` (one of :data:`autoscoop.core.state.STATE_FRAMES`):
    the frame of the tip and joint positions it was trained on. Where it does, :func:`state_frame_of`
    says so and the environment (the rollout loop) and the ROS node build the state in that frame;
    where it does not (the scripted controller, a learner during training), they leave the frame alone.
    """

    name: str

    def reset(self) -> None:
        """Forget the previous episode (called before each episode)."""

    def act(self, observation: np.ndarray) -> np.ndarray:
        """The action for this state: (drive, lift, tilt), each in [-1, 1]."""


def state_frame_of(policy: object) -> str | None:
    """The state frame a controller declares (``chassis`` or ``level``), or ``None`` where it declares none.

    Raises:
        ValueError: if it declares a frame that is not one of :data:`autoscoop.core.state.STATE_FRAMES`.
    """
    from autoscoop.core.state import STATE_FRAMES  # noqa: PLC0415 - numpy-only, but keeps this module a protocol

    frame = getattr(policy, "state_frame", None)
    if frame is not None and frame not in STATE_FRAMES:
        raise ValueError(f"policy {getattr(policy, 'name', policy)!r}: state_frame {frame!r} is not one of {STATE_FRAMES}")
    return frame


def config_for_policy(policy: object, config: Any) -> Any:
    """``config`` (a :class:`~autoscoop.core.config.ScoopConfig`) with ``sensor.level_with_imu`` set to the frame
    the policy declares (:func:`state_frame_of`); unchanged where it declares none or already matches."""
    frame = state_frame_of(policy)
    if frame is None or config.sensor.level_with_imu == (frame == "level"):
        return config
    return config.with_overrides({"sensor.level_with_imu": frame == "level"})
