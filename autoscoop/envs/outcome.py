"""What one episode came to: the one typed outcome every part of autoscoop reports.

Evaluation, the episode recorder, the benchmarks, the scripted demonstrations, the tools and the ROS
side (the simulator node and the controller's records) all build it here, from the environment's
``info`` (:meth:`EpisodeOutcome.from_info`), so that a number means the same everywhere.

The terms are defined in :mod:`autoscoop.envs.definitions`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any


@dataclass(frozen=True)
class EpisodeOutcome:
    """The outcome of one episode.

    Attributes:
        seed: the seed the episode was reset with (``-1`` where there was none, e.g. on the robot).
        fill_factor: mass in the bucket at the end / rated load.
        mass_kg: mass in the bucket at the end, kg.
        particles: particles in the bucket at the end.
        success: the tip reached the terminal point within the time limit, loaded (see above).
        cycle_time_s: seconds from the start to success; ``None`` when the episode did not succeed.
        spilled: particles that were in the bucket and are not at the end.
        physics_error: the simulation diverged (the episode ended there).
        steps: control steps taken.
        episode_return: sum of the rewards.
        reached: the tip reached the terminal point within the time limit, loaded or not.
        volumetric_fill: the particles' solid volume at the end / the bucket's capacity (NaN where unknown:
            a record from the robot, or one written before this was measured).
        overloaded: the fill factor ended above ``scoop.overload_fill``.
        world: a randomised world's draws for this episode (``info["world"]``; empty: the config's world).
    """

    seed: int
    fill_factor: float
    mass_kg: float
    particles: int
    success: bool
    cycle_time_s: float | None
    spilled: int
    physics_error: bool
    steps: int
    episode_return: float
    reached: bool = False
    volumetric_fill: float = math.nan
    overloaded: bool = False
    world: dict[str, Any] = field(default_factory=dict)

    @property
    def delivered_fill(self) -> float:
        """The fill factor this scoop delivered: capped at the rated load (as the reward pays) when it succeeded,
        0 when it did not."""
        return min(self.fill_factor, 1.0) if self.success else 0.0

    @classmethod
    def from_info(cls, info: Mapping[str, Any], *, seed: int, steps: int, episode_return: float) -> EpisodeOutcome:
        """The outcome from the last ``info`` of an episode of an ``autoscoop/`` environment (or an info of the same keys)."""
        success = bool(info.get("success", False))
        cycle = info.get("cycle_time_s")
        cycle = None if cycle is None or not success or not math.isfinite(float(cycle)) else float(cycle)
        return cls(seed=int(seed), fill_factor=float(info.get("fill_factor", 0.0)),
                   mass_kg=float(info.get("mass_in_bucket_kg", 0.0)),
                   particles=int(info.get("particles_in_bucket", 0)), success=success, cycle_time_s=cycle,
                   spilled=int(info.get("spilled", 0)), physics_error=bool(info.get("physics_error", False)),
                   steps=int(steps), episode_return=float(episode_return),
                   reached=bool(info.get("reached", success)),
                   volumetric_fill=float(info.get("volumetric_fill", math.nan)),
                   overloaded=bool(info.get("overloaded", False)), world=dict(info.get("world") or {}))

    @classmethod
    def from_dict(cls, data: Mapping[str, Any]) -> EpisodeOutcome:
        """Read back :meth:`as_dict` (a record's ``outcome`` metadata); a NaN cycle time reads as ``None``."""
        cycle = data.get("cycle_time_s")
        cycle = None if cycle is None or not math.isfinite(float(cycle)) else float(cycle)
        return cls(seed=int(data.get("seed", -1)), fill_factor=float(data["fill_factor"]),
                   mass_kg=float(data["mass_kg"]), particles=int(data["particles"]), success=bool(data["success"]),
                   cycle_time_s=cycle, spilled=int(data["spilled"]), physics_error=bool(data["physics_error"]),
                   steps=int(data.get("steps", 0)), episode_return=float(data.get("episode_return", 0.0)),
                   reached=bool(data.get("reached", data["success"])),
                   volumetric_fill=_number(data.get("volumetric_fill")),
                   overloaded=bool(data.get("overloaded", False)), world=dict(data.get("world") or {}))

    def as_dict(self) -> dict[str, Any]:
        """Plain types for JSON (``cycle_time_s`` is ``null`` when the episode did not succeed)."""
        return asdict(self)


def _number(value: Any) -> float:
    """A stored number; ``None`` (JSON's null for NaN) reads as NaN."""
    return math.nan if value is None else float(value)
