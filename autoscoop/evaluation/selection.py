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
