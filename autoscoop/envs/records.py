"""Episode records: the time series of one episode in one compact file (``.npz``, no pickle).

Every step stores the fields in :data:`STEP_FIELDS`; the file also holds a JSON ``meta`` string
(policy, seed, pile, config, outcome). Evaluation, the ROS controller and manual control all write
this format; reports, figures and the payload calibration read it. The metadata every record shares
is built by :func:`episode_meta`, so that the simulator's records and the robot's say the same things
the same way.
"""

from __future__ import annotations

import json
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
from pydantic import BaseModel, ConfigDict, ValidationError

from autoscoop.core.safe_files import atomic_output, quote
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
        """Write the record as a compressed ``.npz`` (atomically: a failed write leaves no half file)."""
        path = Path(path)
        with atomic_output(path) as tmp:
            np.savez_compressed(tmp, meta=np.array(json.dumps(self.meta, default=_json_default)), **self.arrays())
        return path


MAX_RECORD_BYTES = 64 << 20
"""cap of a record file, bytes (an 8 s episode is about 30 KB)."""
MAX_RECORD_ARRAY_BYTES = 256 << 20
"""cap of a record's arrays once decompressed, bytes (refused before decompressing)."""
ROBOT_SOURCE = "ros controller"
"""``meta["source"]`` of the robot's records, whose rewards, masses and some measurements may be unknown (NaN)."""
UNKNOWN_ON_ROBOT = ("reward", "reward_progress", "reward_mass", "particles_in_bucket", "mass_in_bucket_kg",
                    "lift_rad", "tilt_rad", "lift_torque_nm", "tilt_torque_nm")
"""fields a robot's record may hold NaN in (not measured there); ``tip_world_m`` may be NaN in any record."""
STEP_WIDTHS = {"state": 12, "action": 3, "tip_world_m": 3}
"""the fields with several numbers per step; the others hold one."""


def load_record(path: str | Path) -> EpisodeRecord:
    """Read a record written by :meth:`EpisodeRecord.save` (no pickle is ever loaded), checking it first:
    its size (before decompressing), metadata, version, and arrays (one row per step, the same number of
    steps in each, finite numbers where a value is always known).

    Raises:
        ValueError: the file is missing, too large, not a record, or fails a check (the message names the file
            and the field).
    """
    path = Path(path)
    _check_record_size(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            missing = set(STEP_FIELDS) - set(data.files)
            if missing:
                raise ValueError(f"{path}: not an autoscoop episode record (missing {sorted(missing)})")
            meta = json.loads(str(data["meta"]))
            arrays = {name: data[name] for name in STEP_FIELDS}
    except ValueError as error:  # numpy's "pickled data" refusal, bad JSON metadata, our own message
        raise ValueError(str(error) if str(path) in str(error) else
                         f"{path}: not a readable autoscoop episode record ({quote(str(error))})") from None
    except (OSError, EOFError, KeyError, zipfile.BadZipFile, RecursionError) as error:  # missing, truncated, garbage
        raise ValueError(f"{path}: not a readable autoscoop episode record "
                         f"({type(error).__name__}: {quote(str(error))})") from None
    check_record_meta(meta, path)
    check_record_arrays(arrays, path, robot=meta.get("source") == ROBOT_SOURCE)
    record = EpisodeRecord(meta=meta)
    record.steps = {name: arrays[name].tolist() for name in STEP_FIELDS}
    return record


def _check_record_size(path: Path) -> None:
    try:
        size = path.stat().st_size
        if size > MAX_RECORD_BYTES:
            raise ValueError(f"{path}: larger than {MAX_RECORD_BYTES} bytes; not an episode record autoscoop writes")
        with zipfile.ZipFile(path) as archive:
            unpacked = sum(info.file_size for info in archive.infolist())
    except (OSError, zipfile.BadZipFile) as error:
        raise ValueError(f"{path}: not a readable autoscoop episode record ({type(error).__name__}: "
                         f"{quote(str(error))})") from None
    if unpacked > MAX_RECORD_ARRAY_BYTES:
        raise ValueError(f"{path}: its arrays would take {unpacked} bytes once decompressed (more than "
                         f"{MAX_RECORD_ARRAY_BYTES}); refused before decompressing")


class _MetaPart(BaseModel):
    """Part of a record's metadata: the keys readers use, typed; any others kept as they are."""

    model_config = ConfigDict(extra="allow")


class PileMeta(_MetaPart):
    angle_deg: float | None = None
    n_particles: int | None = None
    radius_m: float | None = None


class StartMeta(_MetaPart):
    state: list[float] | None = None
    lift_rad: float | None = None
    tilt_rad: float | None = None
    tip_world_m: tuple[float, float, float] | None = None
    particles_xz_m: list[tuple[float, float]] | None = None


class OutcomeMeta(_MetaPart):
    seed: int | None = None
    fill_factor: float
    mass_kg: float
    particles: int | float
    success: bool
    cycle_time_s: float | None = None
    spilled: int | float = 0
    physics_error: bool = False
    steps: int = 0
    episode_return: float | None = None


class RecordMeta(_MetaPart):
    """The metadata of an episode record (:func:`episode_meta`, the recorders' additions), as readers use it."""

    policy: str | None = None
    source: str | None = None
    seed: int | None = None
    autoscoop_version: str | None = None
    static: bool | None = None
    pile: PileMeta | None = None
    terminal_point_m: tuple[float, float] | None = None
    control_period_s: float | None = None
    time_limit_s: float | None = None
    config: dict[str, dict[str, Any]] | None = None
    start: StartMeta | None = None
    outcome: OutcomeMeta | None = None


def check_record_meta(meta: Any, path: Path) -> None:
    """A record's metadata: a JSON object whose known keys have their types (:class:`RecordMeta`), written by
    this autoscoop's major (0.x: minor) version or an older one.

    Raises:
        ValueError: naming the file and the field.
    """
    if not isinstance(meta, dict):
        raise ValueError(f"{path}: field meta must be a JSON object, got {quote(meta)}")
    try:
        RecordMeta.model_validate(meta)
    except ValidationError as error:
        first = error.errors()[0]
        key = ".".join(str(part) for part in first["loc"])
        raise ValueError(f"{path}: field meta.{key} = {quote(first.get('input'))}: {first['msg']}") from None
    written = meta.get("autoscoop_version")
    if written is None:
        return
    found, ours = _release(written), _release(__version__)
    if found is None:
        raise ValueError(f"{path}: field meta.autoscoop_version {quote(written)} is not a version")
    if ours is not None and found > ours:
        raise ValueError(f"{path}: written by autoscoop {quote(written)}, newer than this one ({__version__}); "
                         "its format may differ: read it with that version or newer")


def _release(text: Any) -> tuple[int, ...] | None:
    """The compatibility part of a version: (major,) from 1.0 on, (0, minor) before; ``None`` if not a version."""
    match = re.match(r"(\d+)\.(\d+)", text) if isinstance(text, str) else None
    if match is None:
        return None
    major, minor = int(match[1]), int(match[2])
    return (major,) if major else (0, minor)


def check_record_arrays(arrays: dict[str, np.ndarray], path: Path, robot: bool = False) -> None:
    """A record's arrays: numbers, at least one step, the same number of steps in each, the widths of
    :data:`STEP_WIDTHS`, no infinity, and NaN only where a value may be unknown (``tip_world_m``; on the robot,
    :data:`UNKNOWN_ON_ROBOT`).

    Raises:
        ValueError: naming the file and the first field that fails.
    """
    steps = None
    for name in STEP_FIELDS:
        array = arrays[name]
        if array.dtype.kind not in "biuf":
            raise ValueError(f"{path}: field {name} holds {array.dtype} values, not numbers")
        width = STEP_WIDTHS.get(name)
        if array.ndim == 0 or array.shape != ((len(array),) if width is None else (len(array), width)):
            expected = "one number per step" if width is None else f"{width} numbers per step"
            raise ValueError(f"{path}: field {name} has shape {array.shape}, expected {expected}")
        if steps is None:
            steps = len(array)
            if steps == 0:
                raise ValueError(f"{path}: field {name} is empty; a record holds at least one step")
        elif len(array) != steps:
            raise ValueError(f"{path}: field {name} has {len(array)} steps, {next(iter(STEP_FIELDS))} has {steps}; "
                             "a record's fields must have one row per step")
        values = array.astype(float)
        if np.isinf(values).any():
            raise ValueError(f"{path}: field {name} holds an infinite value")
        may_be_unknown = name == "tip_world_m" or (robot and name in UNKNOWN_ON_ROBOT)
        if not may_be_unknown and np.isnan(values).any():
            raise ValueError(f"{path}: field {name} holds NaN (not a number) where a value is always known")


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"cannot store {type(value).__name__} in a record's meta")
