"""Figures over training seeds that do not hang on one lucky or unlucky seed: the interquartile mean and its
bootstrap interval (the method of Agarwal et al., "Deep Reinforcement Learning at the Edge of the Statistical
Precipice", NeurIPS 2021, as the ``rliable`` library computes it, written once here in numpy)."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np


def interquartile_mean(values: Sequence[float]) -> float:
    """The mean of the middle half of ``values``: ``int(n / 4)`` values dropped at each end, as
    ``scipy.stats.trim_mean(values, 0.25)`` and so rliable's ``aggregate_iqm`` compute it (5 seeds: the middle 3).

    Raises:
        ValueError: no values, or one that is not finite.
    """
    data = np.sort(np.asarray(values, dtype=float).ravel())
    if data.size == 0 or not np.all(np.isfinite(data)):
        raise ValueError(f"the interquartile mean needs finite values; got {list(values)!r}")
    cut = int(0.25 * data.size)
    return float(np.mean(data[cut:data.size - cut]))


def bootstrap_interval(values_by_task: Sequence[Sequence[float]], reps: int = 2000, confidence: float = 0.95,
                       seed: int = 0) -> tuple[float, float]:
    """A ``confidence`` percentile interval of the interquartile mean over all runs of all tasks, from a
    stratified bootstrap: each replicate resamples the runs (seeds) of each task with replacement, task by task.

    Args:
        values_by_task: per task (a stress case, a world), one value per run (seed).
        reps: bootstrap replicates.
        confidence: the interval's coverage, in (0, 1).
        seed: the resampling's random seed (the same call gives the same interval).
    """
    if not 0.0 < confidence < 1.0:
        raise ValueError(f"confidence must lie in (0, 1); got {confidence}")
    tasks = [np.asarray(task, dtype=float) for task in values_by_task]
    if not tasks or any(task.size == 0 for task in tasks):
        raise ValueError("every task needs at least one run")
    generator = np.random.default_rng(seed)
    replicates = np.empty(reps)
    for rep in range(reps):
        drawn = [task[generator.integers(0, task.size, task.size)] for task in tasks]
        replicates[rep] = interquartile_mean(np.concatenate(drawn))
    tail = (1.0 - confidence) / 2.0 * 100.0
    low, high = np.percentile(replicates, [tail, 100.0 - tail])
    return float(low), float(high)


def seed_reliability(by_seed: Sequence[dict[str, dict]], metrics: Sequence[str] = ("success_rate", "volumetric_fill_mean"),
                     reps: int = 2000, seed: int = 0) -> dict[str, dict]:
    """Per case, over the runs of one recipe (one per training seed): each metric's interquartile mean over
    seeds and its 95 % bootstrap interval (resampling the seeds), and the share of seeds whose run holds the case.

    Args:
        by_seed: per seed, ``{case: {metric: value, ..., "passed": bool}}`` (the stress suite's per-case figures).
        metrics: the figures to aggregate.

    Returns:
        ``{case: {metric: {"iqm", "low", "high"}, "share_passed": float, "seeds": n}}``, cases in the first seed's order.

    Raises:
        ValueError: no seeds, or seeds that do not report the same cases.
    """
    if not by_seed:
        raise ValueError("seed reliability needs at least one seed's figures")
    cases = list(by_seed[0])
    if any(set(run) != set(cases) for run in by_seed):
        raise ValueError(f"every seed must report the same cases; the first reports {cases}")
    table = {}
    for case in cases:
        row: dict = {"seeds": len(by_seed),
                     "share_passed": float(np.mean([bool(run[case]["passed"]) for run in by_seed]))}
        for metric in metrics:
            values = [float(run[case][metric]) for run in by_seed]
            low, high = bootstrap_interval([values], reps=reps, seed=seed)
            row[metric] = {"iqm": interquartile_mean(values), "low": low, "high": high}
        table[case] = row
    return table
