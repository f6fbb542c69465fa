"""Episode records as tables: load them, group them, summarise them (mean and std over episodes).

Definitions as in ``autoscoop.evaluation.evaluate`` and docs/definitions.md: the cycle time is averaged
over successful episodes only; standard deviations are over episodes (``numpy.std``, ddof = 0), as
``autoscoop eval`` prints them, so both report the same numbers for the same episodes.
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from autoscoop.core.phases import PhaseSpans, phase_spans
from autoscoop.core.state import STATE_NAMES, STATE_SIZE
from autoscoop.envs.records import EpisodeRecord, load_record
from autoscoop.evaluation.summary import outcome_statistics

MANUAL = "manual"
"""The controller label of records made by hand (``autoscoop teleop``)."""
_SPEED = STATE_NAMES.index("v")
"""Index of the forward drive speed in the state."""


@dataclass(frozen=True)
class Episode:
    """One loaded record, where it came from, and its series ready to plot."""

    path: Path
    record: EpisodeRecord

    @property
    def meta(self) -> dict:
        return self.record.meta

    @property
    def controller(self) -> str:
        """``manual`` for records made by hand, else the policy as given on the command line."""
        if self.meta.get("source") == "teleop":
            return MANUAL
        return str(self.meta.get("policy", "unknown"))

    @property
    def angle_deg(self) -> float:
        return float(self.meta.get("pile", {}).get("angle_deg", math.nan))

    @property
    def outcome(self) -> dict:
        return self.meta.get("outcome", {})

    def series(self) -> dict[str, np.ndarray]:
        """Time series with the episode's start prepended where it is known (torques have no start).

        Keys: ``t`` (s), ``tip_x``, ``tip_z`` (world / pile frame, m), ``v`` (m/s), ``lift``, ``tilt``
        (rad), and per step only: ``t_step``, ``tilt_torque``, ``lift_torque`` (N*m), ``particles``,
        ``mass_kg``, ``penetrating``.
        """
        a = self.record.arrays()
        start = self.meta.get("start")
        t, tip = a["time_s"], a["tip_world_m"].reshape(-1, 3)
        v, lift, tilt = a["state"].reshape(-1, STATE_SIZE)[:, _SPEED], a["lift_rad"], a["tilt_rad"]
        if start:
            t = np.concatenate([[0.0], t])
            tip = np.vstack([start["tip_world_m"], tip])
            v = np.concatenate([[start["state"][_SPEED]], v])
            lift = np.concatenate([[start["lift_rad"]], lift])
            tilt = np.concatenate([[start["tilt_rad"]], tilt])
        return {"t": t, "tip_x": tip[:, 0], "tip_z": tip[:, 2], "v": v, "lift": lift, "tilt": tilt,
                "t_step": a["time_s"], "tilt_torque": a["tilt_torque_nm"], "lift_torque": a["lift_torque_nm"],
                "particles": a["particles_in_bucket"], "mass_kg": a["mass_in_bucket_kg"],
                "penetrating": a["penetrating"]}

    def phases(self) -> PhaseSpans:
        """Approach, fill and exit, from when the tip penetrated the pile."""
        a = self.record.arrays()
        return phase_spans(a["penetrating"], a["time_s"])

    def pile_xz(self) -> np.ndarray | None:
        """Particle centres (x, z) at the start, m, or ``None`` if the record lacks them."""
        start = self.meta.get("start") or {}
        points = start.get("particles_xz_m")
        return None if points is None else np.asarray(points, dtype=float).reshape(-1, 2)


def find_record_files(paths: Iterable[str | Path]) -> list[Path]:
    """The ``.npz`` files named, and those under the folders named (recursively), sorted."""
    found: list[Path] = []
    for entry in paths:
        entry = Path(entry)
        if entry.is_dir():
            found.extend(sorted(entry.rglob("*.npz")))
        elif entry.is_file():
            found.append(entry)
        else:
            raise ValueError(f"{entry}: no such record file or folder")
    return found


def load_episodes(paths: Iterable[str | Path]) -> list[Episode]:
    """Load every record in ``paths`` (files or folders).

    Raises:
        ValueError: if nothing is found, a file is not an episode record, or a record has no outcome to report
            (``meta.outcome``).
    """
    files = find_record_files(paths)
    if not files:
        raise ValueError("no episode records (*.npz) found")
    episodes = [Episode(path=f, record=load_record(f)) for f in files]
    for episode in episodes:
        if not episode.outcome:
            raise ValueError(f"{episode.path}: field meta.outcome is missing; a report needs each episode's outcome "
                             "(records of static holds are for autoscoop payload calibrate)")
    return episodes


def group_episodes(episodes: Iterable[Episode]) -> dict[tuple[str, float], list[Episode]]:
    """Episodes by (controller, pile angle), in first-seen order."""
    groups: dict[tuple[str, float], list[Episode]] = defaultdict(list)
    for episode in episodes:
        groups[(episode.controller, episode.angle_deg)].append(episode)
    return dict(groups)


def summarize_episodes(episodes: list[Episode]) -> dict[str, float]:
    """Mean and std over episodes of mass (kg), particles, fill factor, cycle time (successes), spillage;
    the success rate; and how many episodes, physics errors and the longest time limit."""
    out = outcome_statistics(e.outcome for e in episodes)
    out["time_limit_s"] = max((float(e.meta.get("time_limit_s", math.nan)) for e in episodes), default=math.nan)
    return out
