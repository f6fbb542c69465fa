"""Episode records: the time series of one episode in one compact file (``.npz``, no pickle).

Every step stores the fields in :data:`STEP_FIELDS`; the file also holds a JSON ``meta`` string
(policy, seed, pile, config, outcome). Evaluation, the ROS controller and manual control all write
this format; reports, figures and the payload calibration read it. The metadata every record shares
is built by :func:`episode_meta`, so that the simulator's records and the robot's say the same things
the same way.
"""

from __future__ import annotations

import json
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from autoscoop.core.version import __version__

if TYPE_CHECKING:
    from autoscoop.core.config import ScoopConfig

STEP_FIELDS: dict[str, str] = {
    "time_s": "time since the episode start at the end of the step, s",
    "state": "the 12-number state after the step (autoscoop.core.state.STATE_NAMES)",
    "action": "the action of the step, 3 numbers in [-1, 1] (drive, lift, tilt)",
    "reward": "reward of the step",
    "reward_progress": "P_t, paper eq. 5",
    "reward_mass": "c_w * w_t on reaching the terminal point, else 0",
    "particles_in_bucket": "particles inside the bucket",
    "mass_in_bucket_kg": "true mass inside the bucket, kg",
    "lift_rad": "measured lift angle, rad",
    "tilt_rad": "measured tilt angle, rad",
    "lift_torque_nm": "actuator torque at the lift joint, N*m",
    "tilt_torque_nm": "actuator torque at the tilt (bucket) joint, N*m",
    "tip_world_m": "bucket tip in the world (pile) frame, (x, y, z) m; NaN where unknown (robot)",
    "penetrating": "paper eq. 7",
}


def episode_meta(config: ScoopConfig, *, control_period_s: float, time_limit_s: float,
                 pile_angle_deg: float | None = None, **extra: Any) -> dict[str, Any]:
    """The metadata every episode record carries, after ``extra`` (which it overrides where keys clash).

    Args:
        config: the task's configuration (the pile, the terminal point; stored whole under ``config``).
        control_period_s: the controller's period, s.
        time_limit_s: the episode's time limit, s.
        pile_angle_deg: this episode's pile angle when it is not ``config.pile.angle_deg`` (a mix of piles).
        extra: the writer's own keys, first in the dict (``policy``, ``source``, ``seed``, ...).

    Returns:
        ``extra``, then ``autoscoop_version``, ``pile`` (``angle_deg``, ``n_particles``, ``radius_m``),
        ``terminal_point_m`` ((dx, z) m), ``control_period_s``, ``time_limit_s`` and ``config``.
    """
    pile = config.pile
    return {
        **extra,
        "autoscoop_version": __version__,
        "pile": {"angle_deg": pile.angle_deg if pile_angle_deg is None else pile_angle_deg,
                 "n_particles": pile.n_particles, "radius_m": pile.radius_m},
        "terminal_point_m": [config.reward.terminal_dx_m, config.reward.terminal_z_m],
        "control_period_s": control_period_s,
        "time_limit_s": time_limit_s,
        "config": config.to_dict(),
    }


@dataclass
class EpisodeRecord:
    """One episode's time series (arrays with one row per step) and its metadata."""

    meta: dict[str, Any] = field(default_factory=dict)
    steps: dict[str, list] = field(default_factory=lambda: {name: [] for name in STEP_FIELDS})

    def append(self, **values: Any) -> None:
        """Add one step; every field of :data:`STEP_FIELDS` must be given."""
        missing = set(STEP_FIELDS) - set(values)
        if missing:
            raise ValueError(f"record step is missing {sorted(missing)}")
        for name in STEP_FIELDS:
            self.steps[name].append(values[name])

    def arrays(self) -> dict[str, np.ndarray]:
        """The steps as numpy arrays (float64; booleans as 0/1)."""
        return {name: np.asarray(values, dtype=float) for name, values in self.steps.items()}

    def __len__(self) -> int:
        return len(self.steps["time_s"])

    def save(self, path: str | Path) -> Path:
        """Write the record as a compressed ``.npz``."""
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez_compressed(path, meta=np.array(json.dumps(self.meta, default=_json_default)), **self.arrays())
        return path


def load_record(path: str | Path) -> EpisodeRecord:
    """Read a record written by :meth:`EpisodeRecord.save` (no pickle is ever loaded)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = set(STEP_FIELDS) - set(data.files)
            if missing:
                raise ValueError(f"{path}: not an autoscoop episode record (missing {sorted(missing)})")
            record = EpisodeRecord(meta=json.loads(str(data["meta"])))
            record.steps = {name: data[name].tolist() for name in STEP_FIELDS}
    except ValueError as error:  # numpy's "pickled data" refusal, bad JSON metadata, our own message
        raise ValueError(str(error) if str(path) in str(error) else
                         f"{path}: not a readable autoscoop episode record ({error})") from error
    except (OSError, EOFError, KeyError, zipfile.BadZipFile) as error:  # missing, truncated, garbage
        raise ValueError(f"{path}: not a readable autoscoop episode record "
                         f"({type(error).__name__}: {error})") from error
    return record


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot store {type(value).__name__} in a record's meta")
