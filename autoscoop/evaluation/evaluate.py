"""Run a controller for N episodes and measure it the way earth-moving people do.

The terms (fill factor, volumetric fill, reached, success, cycle time, overload, spillage) are those of
:mod:`autoscoop.envs.definitions`, which the table prints below its rows.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from autoscoop.core.config import ScoopConfig
from autoscoop.core.policy import Policy
from autoscoop.core.version import __version__, dependency_versions
from autoscoop.envs.definitions import definition_lines
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env
from autoscoop.evaluation.recorder import EpisodeRecorder, record_name
from autoscoop.evaluation.summary import outcome_statistics


def evaluate(policy: Policy, config: ScoopConfig, episodes: int, seed: int = 0,
             progress: bool = True, records_dir: str | Path | None = None,
             records_meta: dict[str, Any] | None = None, label: str | None = None) -> list[EpisodeOutcome]:
    """Run ``episodes`` episodes with seeds ``seed, seed + 1, ...``; show a progress bar.

    With ``records_dir``, each episode's record (``autoscoop.envs.records``) is saved there as
    ``episode_SEED.npz``, with ``records_meta`` (and the policy's name) in its metadata. ``label``
    names the progress bar (default ``eval POLICY``).
    """
    env = make_scoop_env(config)
    if records_dir is not None:
        env = EpisodeRecorder(env, {"policy": policy.name, "source": "eval", **(records_meta or {})})
    results: list[EpisodeOutcome] = []
    bar = tqdm(range(episodes), desc=label or f"eval {policy.name}", unit="ep", disable=not progress)
    try:
        for i in bar:
            results.append(rollout(policy, env, seed + i))
            if records_dir is not None:
                env.save(Path(records_dir) / record_name(seed + i))
            fills = [r.fill_factor for r in results]
            bar.set_postfix(fill=f"{np.mean(fills):.2f}", success=f"{np.mean([r.success for r in results]):.2f}")
    finally:
        env.close()
    return results


def summarize(results: list[EpisodeOutcome], config: ScoopConfig, policy_name: str) -> dict[str, Any]:
    """Summary statistics (mean and standard deviation over episodes) with the config used; each
    episode's outcome under ``episodes_detail`` (``cycle_time_s`` ``None`` where it did not succeed)."""
    outcomes = [r.as_dict() for r in results]
    return {
        "policy": policy_name,
        **outcome_statistics(outcomes),
        "pile": {"angle_deg": config.pile.angle_deg, "n_particles": config.pile.n_particles},
        "autoscoop_version": __version__,
        "dependencies": dependency_versions(),
        "config": config.to_dict(),
        "episodes_detail": outcomes,
    }


def format_table(summary: dict[str, Any], definitions: bool = True) -> str:
    """The summary as a small text table (mean +- std), and below it, with ``definitions``, what its terms mean
    (:func:`autoscoop.envs.definitions.definition_lines`)."""
    def pm(key: str, digits: int = 3) -> str:
        mean, std = summary[f"{key}_mean"], summary[f"{key}_std"]
        return "n/a" if math.isnan(mean) else f"{mean:.{digits}f} +- {std:.{digits}f}"

    rows = [
        ("policy", summary["policy"]),
        ("pile", f"{summary['pile']['angle_deg']:g} deg, {summary['pile']['n_particles']} particles"),
        ("episodes", str(summary["episodes"])),
        ("fill factor", pm("fill_factor")),
        ("mass in bucket (kg)", pm("mass_kg", 2)),
        ("cycle time (s, successes)", pm("cycle_time", 2)),
        ("volumetric fill", pm("volumetric_fill")),
        ("success rate (reached loaded)", f"{summary['success_rate']:.3f}"),
        ("reached rate", f"{summary['reached_rate']:.3f}"),
        ("overload rate", f"{summary['overload_rate']:.3f}"),
        ("spillage (particles)", pm("spillage", 2)),
        ("physics errors", str(summary["physics_errors"])),
    ]
    width = max(len(name) for name, _ in rows)
    table = "\n".join(f"{name:<{width}}  {value}" for name, value in rows)
    return table + "\n\n" + "\n".join(definition_lines(markdown=False)) if definitions else table
