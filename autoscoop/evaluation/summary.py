"""Statistics over episodes, the way every report of autoscoop gives them: mean and standard deviation.

One place for ``autoscoop eval``'s summary and for the reports built from episode records: both hand
in :meth:`autoscoop.envs.outcome.EpisodeOutcome.as_dict` mappings (a record's ``outcome`` metadata),
with the keys ``mass_kg``, ``particles``, ``fill_factor``, ``cycle_time_s`` (``None`` when the
episode did not succeed), ``success``, ``spilled`` and ``physics_error``.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np


def mean_std(values: Iterable[float]) -> tuple[float, float]:
    """Mean and (population) standard deviation; both NaN when there are no values."""
    values = list(values)
    if not values:
        return math.nan, math.nan
    return float(np.mean(values)), float(np.std(values))


def rate(flags: Iterable[bool]) -> float:
    """The share of true flags; NaN when there are none."""
    flags = list(flags)
    return float(np.mean(flags)) if flags else math.nan


def outcome_statistics(outcomes: Iterable[Mapping[str, Any]]) -> dict[str, float]:
    """Summary of episode outcomes.

    Returns:
        ``episodes``; ``{key}_mean`` and ``{key}_std`` for ``mass_kg`` (kg), ``particles``,
        ``fill_factor`` (mass / rated load), ``cycle_time`` (s, successful episodes only) and
        ``spillage`` (particles that left the bucket), ``volumetric_fill`` (solid volume / capacity;
        episodes that measured it); ``success_rate`` (reached loaded), ``reached_rate`` (reached the
        terminal point, loaded or not) and ``overload_rate`` (fill factor above ``scoop.overload_fill``),
        NaN with no episodes; ``physics_errors`` (a count).
    """
    outcomes = list(outcomes)
    out: dict[str, float] = {"episodes": len(outcomes)}
    for key, values in (
        ("fill_factor", [float(o["fill_factor"]) for o in outcomes]),
        ("mass_kg", [float(o["mass_kg"]) for o in outcomes]),
        ("particles", [float(o["particles"]) for o in outcomes]),
        ("cycle_time", [float(o["cycle_time_s"]) for o in outcomes if o["cycle_time_s"] is not None]),
        ("spillage", [float(o["spilled"]) for o in outcomes]),
    ):
        out[f"{key}_mean"], out[f"{key}_std"] = mean_std(values)
    fills = [float(o["volumetric_fill"]) for o in outcomes if o.get("volumetric_fill") is not None]
    out["volumetric_fill_mean"], out["volumetric_fill_std"] = mean_std(v for v in fills if math.isfinite(v))
    out["success_rate"] = rate(bool(o["success"]) for o in outcomes)
    out["reached_rate"] = rate(bool(o.get("reached", o["success"])) for o in outcomes)
    out["overload_rate"] = rate(bool(o.get("overloaded", False)) for o in outcomes)
    out["physics_errors"] = int(sum(bool(o["physics_error"]) for o in outcomes))
    return out
