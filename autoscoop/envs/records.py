"""Episode records: the time series of one episode in one compact file (``.npz``, no pickle).

Every step stores the fields in :data:`STEP_FIELDS`; the file also holds a JSON ``meta`` string
(policy, seed, pile, config, outcome). Evaluation, the ROS controller and manual control all write
this format; reports, figures and the payload calibration read it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

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
    with np.load(Path(path), allow_pickle=False) as data:
        missing = set(STEP_FIELDS) - set(data.files)
        if missing:
            raise ValueError(f"{path}: not an autoscoop episode record (missing {sorted(missing)})")
        record = EpisodeRecord(meta=json.loads(str(data["meta"])))
        record.steps = {name: data[name].tolist() for name in STEP_FIELDS}
    return record


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot store {type(value).__name__} in a record's meta")
