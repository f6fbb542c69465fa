"""Choose the policy a run keeps among its snapshots, on a validation suite.

A training run's periodic evaluation scores each snapshot on 10 episodes of its current world: enough
to follow learning, too few to rank snapshots whose success differs by a few points, and blind to the
worlds at the edges of the randomised ranges (light and heavy earth, the steepest piles). The
validation suite runs the best few snapshots by that score over every stress case of
:mod:`autoscoop.evaluation.stress`, ``episodes`` each, on seeds from ``seed`` (20000 in the recipes:
apart from the periodic evaluation's 10000 on and from the seeds 0-99 that reports use), and ranks them
by how far they fall short of the stress suite's thresholds, summed over the cases
(:func:`total_shortfall`); the mean delivered fill breaks ties.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.core.config import ScoopConfig
from autoscoop.evaluation.stress import CASES, StressCase, StressRow, run_stress

SHORTFALL_SCALES = {"fill_factor_mean": 1.0, "volumetric_fill_mean": 1.0, "success_rate": 1.0,
                    "overload_rate": 1.0, "cycle_time_mean": 5.0}
"""what one unit of shortfall is, per metric: a point of a rate or fill counts as 0.01, a second of cycle time
as 0.2 (cycle times are about 5 s)."""


def threshold_shortfall(row: StressRow) -> float:
    """How far one case falls short of its thresholds: the sum over them of the missing margin, each divided
    by its :data:`SHORTFALL_SCALES` (0 when every threshold holds; a NaN statistic, e.g. no successful
    episode's cycle time, counts as one whole unit)."""
    total = 0.0
    for check in row.checks:
        if check.passed:
            continue
        scale = SHORTFALL_SCALES.get(check.threshold.metric, 1.0)
        gap = abs(check.measured - check.threshold.value) if math.isfinite(check.measured) else scale
        total += gap / scale
    return total


def total_shortfall(rows: Sequence[StressRow]) -> float:
    """:func:`threshold_shortfall` summed over the cases: 0 when every case holds."""
    return float(sum(threshold_shortfall(row) for row in rows))


def delivered_fill(row: StressRow) -> float:
    """A case's mean delivered fill: the fill factor, capped at the rated load, of successful episodes, 0 for the rest."""
    return float(np.mean([o.delivered_fill for o in row.outcomes])) if row.outcomes else 0.0


@dataclass
class Ranked:
    """One candidate's validation: its file, the stress rows, and what ranks it."""

    name: str
    path: Path
    rows: list[StressRow]

    @property
    def shortfall(self) -> float:
        return total_shortfall(self.rows)

    @property
    def cases_passed(self) -> int:
        return sum(row.passed for row in self.rows)

    @property
    def mean_delivered_fill(self) -> float:
        return float(np.mean([delivered_fill(row) for row in self.rows]))

    def summary(self) -> dict[str, Any]:
        """Plain types for JSON: the ranking figures and each case's statistics and pass flag."""
        return {"name": self.name, "path": str(self.path), "shortfall": round(self.shortfall, 4),
                "cases_passed": self.cases_passed, "cases": len(self.rows),
                "mean_delivered_fill": round(self.mean_delivered_fill, 4),
                "by_case": {row.case.name: {"passed": row.passed, "success_rate": row.stats["success_rate"],
                                            "fill_factor_mean": row.stats["fill_factor_mean"],
                                            "volumetric_fill_mean": row.stats["volumetric_fill_mean"],
                                            "overload_rate": row.stats["overload_rate"],
                                            "cycle_time_mean": row.stats["cycle_time_mean"]}
                            for row in self.rows}}


def rank_candidates(candidates: Sequence[tuple[str, Path]], episodes: int, seed: int, workers: int = 1,
                    progress: bool = True) -> list[Ranked]:
    """Run each ``(name, policy file)`` over every stress case (``episodes`` each, seeds ``seed`` on) and
    return them best first: the least :func:`total_shortfall`, then the highest mean delivered fill, then
    the order given."""
    if not candidates:
        raise ValueError("no candidates to rank")
    ranked = []
    for name, path in candidates:
        if progress:
            print(f"validation: {name}", flush=True)
        rows = run_stress(str(path), ScoopConfig(), episodes, seed=seed, workers=workers, progress=False)
        ranked.append(Ranked(name, Path(path), rows))
    order = sorted(range(len(ranked)), key=lambda i: (round(ranked[i].shortfall, 9),
                                                      -ranked[i].mean_delivered_fill, i))
    return [ranked[i] for i in order]


REGRESSION_TOLERANCE = 0.03
"""how far a fine-tuned policy may fall below the policy it started from, in success and in volumetric fill, in a
case that policy holds, before it counts as having lost ground."""


def regression_from(rows: Sequence[StressRow], reference: Sequence[StressRow],
                    tolerance: float = REGRESSION_TOLERANCE) -> float:
    """How far ``rows`` fall below ``reference`` (the same cases) where the reference holds: per case, the success
    and the volumetric fill lost beyond ``tolerance``, summed, in the units of :func:`threshold_shortfall` (a
    point of a rate or fill is 0.01), so that a candidate's ground lost and its shortfall weigh alike (0: no case
    lost ground; a NaN statistic counts as one whole unit)."""
    by_name = {row.case.name: row for row in reference}
    total = 0.0
    for row in rows:
        before = by_name.get(row.case.name)
        if before is None or not before.passed:
            continue
        for metric in ("success_rate", "volumetric_fill_mean"):
            lost = float(before.stats[metric]) - float(row.stats[metric]) - tolerance
            total += max(lost, 0.0) if math.isfinite(lost) else 1.0
    return total


@dataclass
class RankedForTarget(Ranked):
    """A fine-tuned candidate's validation: the target world's row first, then every stress case."""

    regression: float = 0.0
    """:func:`regression_from` the starting policy's validation (0 for the starting policy itself)."""

    @property
    def target_passed(self) -> bool:
        return self.rows[0].passed

    @property
    def score(self) -> float:
        """What ranks it, lower first: the target world's shortfall, the other cases' and the ground lost."""
        return self.shortfall + self.regression

    def summary(self) -> dict[str, Any]:
        return {**super().summary(), "target_passed": self.target_passed, "regression": round(self.regression, 4),
                "score": round(self.score, 4)}


def rank_for_target(candidates: Sequence[tuple[str, Path]], target: StressCase, episodes: int, seed: int,
                    workers: int = 1, progress: bool = True) -> list[RankedForTarget]:
    """Validate fine-tuned candidates on ``target`` (the world they were adapted for) and every stress case,
    ``episodes`` each on seeds ``seed`` on, and return them best first by :attr:`RankedForTarget.score`, then the
    mean delivered fill, then the order given. The first candidate is the starting policy: the reference of
    :func:`regression_from`."""
    if not candidates:
        raise ValueError("no candidates to rank")
    validated = []
    for name, path in candidates:
        if progress:
            print(f"validation: {name}", flush=True)
        validated.append((name, Path(path), run_stress(str(path), ScoopConfig(), episodes, seed=seed, workers=workers,
                                                       progress=False, cases=[target, *CASES])))
    reference = validated[0][2][1:]
    ranked = [RankedForTarget(name, path, rows, regression=regression_from(rows[1:], reference))
              for name, path, rows in validated]
    order = sorted(range(len(ranked)), key=lambda i: (round(ranked[i].score, 9), -ranked[i].mean_delivered_fill, i))
    return [ranked[i] for i in order]


BOOTSTRAP_DRAWS = 1000
"""paired bootstrap draws of a confirmation."""


def confidence_of_gain(start: Sequence[StressRow], candidate: Sequence[StressRow], draws: int = BOOTSTRAP_DRAWS,
                       seed: int = 0) -> float:
    """How sure a validation is that ``candidate`` scores better than ``start``: the share of paired bootstrap
    draws in which its :attr:`RankedForTarget.score` (the target world's row first, then every stress case;
    the ground lost counted against the start's same draw) is below the start's.

    Both ran the same seeds in every case, so a draw resamples each case's episode indices once and takes those
    episodes of both: what the two do differently on the same pile is what is resampled, not the piles.

    Raises:
        ValueError: the two do not hold the same cases, or a case's episodes are not the same seeds.
    """
    if [r.case.name for r in start] != [r.case.name for r in candidate]:
        raise ValueError("the start and the candidate must be validated on the same cases, in the same order")
    for a, b in zip(start, candidate, strict=True):
        if [o.seed for o in a.outcomes] != [o.seed for o in b.outcomes] or not a.outcomes:
            raise ValueError(f"case {a.case.name}: the start and the candidate must run the same seeds")
    rng = np.random.default_rng(seed)
    start_draws, candidate_draws = [], []
    for a, b in zip(start, candidate, strict=True):
        picks = rng.integers(0, len(a.outcomes), size=(draws, len(a.outcomes)))
        start_draws.append(_drawn_statistics(a.outcomes, picks))
        candidate_draws.append(_drawn_statistics(b.outcomes, picks))
    better = 0
    for k in range(draws):
        start_rows = [StressRow(row.case, stats[k]) for row, stats in zip(start, start_draws, strict=True)]
        candidate_rows = [StressRow(row.case, stats[k]) for row, stats in zip(candidate, candidate_draws, strict=True)]
        start_score = total_shortfall(start_rows)
        candidate_score = total_shortfall(candidate_rows) + regression_from(candidate_rows[1:], start_rows[1:])
        better += candidate_score < start_score - 1e-9
    return better / draws


DRAWN_METRICS = ("success_rate", "fill_factor_mean", "volumetric_fill_mean", "overload_rate", "cycle_time_mean")
"""the statistics the stress thresholds and the ground lost read, as :func:`outcome_statistics` defines them."""


def _drawn_statistics(outcomes: Sequence[Any], picks: np.ndarray) -> list[dict[str, float]]:
    """:data:`DRAWN_METRICS` of each draw (a row of ``picks``, indices into ``outcomes``), as
    :func:`~autoscoop.evaluation.summary.outcome_statistics` computes them: the cycle time over successful
    episodes, the volumetric fill over the episodes that measured it (NaN when none)."""
    success = np.array([bool(o.success) for o in outcomes])[picks]
    fill = np.array([float(o.fill_factor) for o in outcomes])[picks]
    overload = np.array([bool(o.overloaded) for o in outcomes])[picks]
    cycle = np.array([np.nan if o.cycle_time_s is None else float(o.cycle_time_s) for o in outcomes])[picks]
    volume = np.array([np.nan if o.volumetric_fill is None else float(o.volumetric_fill) for o in outcomes])[picks]
    with np.errstate(invalid="ignore"):
        columns = (success.mean(axis=1), fill.mean(axis=1), _nanmean_rows(volume), overload.mean(axis=1),
                   _nanmean_rows(cycle))
    return [dict(zip(DRAWN_METRICS, map(float, values), strict=True)) for values in zip(*columns, strict=True)]


def _nanmean_rows(values: np.ndarray) -> np.ndarray:
    """Each row's mean over its finite values; NaN for a row with none."""
    finite = np.isfinite(values)
    counts = finite.sum(axis=1)
    totals = np.where(finite, values, 0.0).sum(axis=1)
    return np.where(counts > 0, totals / np.maximum(counts, 1), np.nan)
