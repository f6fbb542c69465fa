"""Record each episode of an autoscoop environment in the episode-record format (:mod:`autoscoop.envs.records`).

:class:`EpisodeRecorder` is a Gymnasium wrapper: wrap the environment, run episodes as usual, and
:meth:`EpisodeRecorder.save` the one that just ended. Whoever drives the environment (evaluation, the
demo, manual control) writes the same format.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import gymnasium as gym
import numpy as np

from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.envs.records import EpisodeRecord, episode_meta


def record_name(seed: int) -> str:
    """File name of the record of the episode started from ``seed``."""
    return f"episode_{seed:05d}.npz"


class EpisodeRecorder(gym.Wrapper):
    """Keeps the time series of the current episode; :meth:`save` writes it with its outcome.

    Args:
        env: an autoscoop environment (``make_scoop_env``), possibly wrapped.
        meta: metadata stored in every record (e.g. ``{"policy": "heuristic", "source": "eval"}``).
    """

    def __init__(self, env: gym.Env, meta: dict[str, Any] | None = None) -> None:
        super().__init__(env)
        self.base_meta = dict(meta or {})
        self.record = EpisodeRecord()
        self._return = 0.0
        self._last_info: dict[str, Any] = {}
        self._seed = -1

    def reset(self, *, seed: int | None = None, options: dict | None = None) -> tuple[np.ndarray, dict]:
        obs, info = self.env.reset(seed=seed, options=options)
        scoop = self.env.unwrapped
        sim, config = scoop.sim, scoop.config
        particles = sim.particle_positions
        meta = episode_meta(config, control_period_s=config.env.control_period_s,
                            time_limit_s=config.env.max_episode_s,
                            pile_angle_deg=sim.pile_angle_deg,  # this episode's (a mix of piles)
                            **{**self.base_meta, "seed": seed})
        meta["world"] = dict(info.get("world") or {})  # a randomised world's draws: a failure traced to its world
        meta["start"] = {
            "state": np.asarray(obs, dtype=float).round(6).tolist(),
            "lift_rad": sim.lift_rad, "tilt_rad": sim.tilt_rad,
            "tip_world_m": sim.tip_world.round(6).tolist(),
            "particles_xz_m": particles[:, [0, 2]].round(4).tolist(),
        }
        self.record = EpisodeRecord(meta=meta)
        self._return, self._last_info = 0.0, dict(info)
        self._seed = -1 if seed is None else int(seed)
        return obs, info

    def step(self, action: np.ndarray) -> tuple[np.ndarray, float, bool, bool, dict]:
        obs, reward, terminated, truncated, info = self.env.step(action)
        sim = self.env.unwrapped.sim
        failed = bool(info.get("physics_error", False))
        nan3 = [math.nan] * 3
        self.record.append(
            time_s=float(info["elapsed_s"]),
            state=np.asarray(obs, dtype=float),
            action=np.clip(np.asarray(action, dtype=float).reshape(-1), -1.0, 1.0),
            reward=float(reward),
            reward_progress=float(info["reward_progress"]),
            reward_mass=float(info["reward_mass"]),
            particles_in_bucket=int(info["particles_in_bucket"]),
            mass_in_bucket_kg=float(info["mass_in_bucket_kg"]),
            lift_rad=math.nan if failed else sim.lift_rad,
            tilt_rad=math.nan if failed else sim.tilt_rad,
            lift_torque_nm=float(info["lift_torque_nm"]),
            tilt_torque_nm=float(info["tilt_torque_nm"]),
            tip_world_m=nan3 if failed else sim.tip_world,
            penetrating=bool(info["penetrating"]),
        )
        self._return += float(reward)
        self._last_info = dict(info)
        return obs, reward, terminated, truncated, info

    def outcome(self) -> EpisodeOutcome:
        """The current episode's outcome so far (the same numbers evaluation reports); seed ``-1`` when
        the episode was reset without one."""
        return EpisodeOutcome.from_info(self._last_info, seed=self._seed, steps=len(self.record),
                                        episode_return=self._return)

    def save(self, path: str | Path, **extra_meta: Any) -> Path:
        """Write the current episode's record, its outcome added to the metadata."""
        self.record.meta.update(extra_meta)
        self.record.meta["outcome"] = self.outcome().as_dict()
        return self.record.save(path)
