"""The paper's Fig. 8 from a training run's ``episodes.csv``: reward, fill factor, cycle time per episode."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from autoscoop.core.safe_files import atomic_output


def _moving_average(values: np.ndarray, window: int) -> np.ndarray:
    out = np.full(len(values), np.nan)
    for i in range(len(values)):
        chunk = values[max(0, i - window + 1):i + 1]
        chunk = chunk[~np.isnan(chunk)]
        if len(chunk):
            out[i] = chunk.mean()
    return out


def read_episodes(csv_path: str | Path) -> dict[str, np.ndarray]:
    """The columns of ``episodes.csv`` the curve draws: ``episode``, ``reward``, ``fill_factor``, ``success`` (0 or 1)
    and ``cycle_time_s`` (s from the start until success; NaN for an episode that did not succeed, even where an
    older log gave it the time it took to reach the terminal point empty)."""
    with open(csv_path, newline="") as handle:
        rows = list(csv.DictReader(handle))
    success = np.array([int(r["success"]) for r in rows], dtype=float)
    cycle = np.array([float(r["cycle_time_s"]) if r["cycle_time_s"] not in ("", "nan") else math.nan for r in rows])
    return {"episode": np.array([int(r["episode"]) for r in rows]),
            "reward": np.array([float(r["reward"]) for r in rows]),
            "fill_factor": np.array([float(r["fill_factor"]) for r in rows]),
            "success": success, "cycle_time_s": np.where(success > 0, cycle, math.nan)}


def plot_learning_curve(csv_path: str | Path, png_path: str | Path, window: int = 25) -> Path:
    """Draw three stacked panels (normalised reward, fill factor, cycle time of successes) against episode; the
    failed episodes, which have no cycle time, are counted apart in the third panel's title."""
    import matplotlib  # noqa: PLC0415

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt  # noqa: PLC0415

    columns = read_episodes(csv_path)
    episode, reward, fill = columns["episode"], columns["reward"], columns["fill_factor"]
    cycle, success = columns["cycle_time_s"], columns["success"]
    failed = int(len(success) - success.sum())
    span = reward.max() - reward.min() if len(reward) else 1.0
    reward_norm = (reward - reward.min()) / (span if span > 0 else 1.0)

    fig, axes = plt.subplots(3, 1, figsize=(7, 7.5), sharex=True)
    panels = [(axes[0], reward_norm, "normalised reward", "A"), (axes[1], fill, "fill factor", "B"),
              (axes[2], cycle, "cycle time (s)", "C")]
    axes[2].set_title(f"successes only; {failed} of {len(success)} episodes failed (no cycle time)", fontsize=9)
    for ax, values, label, letter in panels:
        ax.plot(episode, values, ".", color="0.7", markersize=3, label="episode")
        ax.plot(episode, _moving_average(values, window), color="C0", label=f"mean of {window}")
        ax.set_ylabel(label)
        ax.set_title(letter, loc="left", fontweight="bold")
        ax.grid(alpha=0.3)
    axes[1].plot(episode, _moving_average(success, window), color="C2", label="success rate")
    axes[1].set_ylim(0, 1.05)
    axes[0].legend(loc="lower right", fontsize=8)
    axes[1].legend(loc="lower right", fontsize=8)
    axes[2].set_xlabel("episode")
    fig.suptitle("Learning curve (cf. paper Fig. 8)")
    fig.tight_layout()
    png_path = Path(png_path)
    with atomic_output(png_path) as tmp:
        fig.savefig(tmp, dpi=120)
    plt.close(fig)
    return png_path
