"""The stress suite: one controller over the worlds and sensing it must hold on.

Each :class:`StressCase` is a set of config overrides applied on top of the user's config, with the
thresholds it must hold: the nominal world (32° pile) must scoop well (fill factor
>= 0.75, success >= 0.97, cycle time no longer than the machine's target: 5 s on the Komodo); every other world must still scoop (success >= 0.90,
volumetric fill >= 0.60, overload rate <= 0.05). :func:`run_stress` runs every chosen case for the same
seeds ``seed .. seed + episodes - 1`` and returns one :class:`StressRow` per case with its statistics
(:func:`autoscoop.evaluation.summary.outcome_statistics`), each threshold's pass or fail, and the
episodes' outcomes. Cases can run in parallel worker processes; the numbers are the same as serial.

The terms are those of :mod:`autoscoop.envs.definitions`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from tqdm import tqdm

from autoscoop.agents.loading import load_policy
from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import quote
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.summary import outcome_statistics
from autoscoop.evaluation.workers import worker_pool

OPERATORS: dict[str, Callable[[float, float], bool]] = {">=": lambda v, t: v >= t, "<=": lambda v, t: v <= t}


@dataclass(frozen=True)
class Threshold:
    """One requirement on a case's statistic: ``metric op value`` (e.g. ``success_rate >= 0.9``).

    Attributes:
        metric: a key of :func:`~autoscoop.evaluation.summary.outcome_statistics` (``fill_factor_mean``,
            ``success_rate``, ``cycle_time_mean`` (s), ...).
        op: ``>=`` or ``<=``.
        value: the threshold, in the metric's unit.
    """

    metric: str
    op: str
    value: float

    def holds(self, measured: float) -> bool:
        """Whether ``measured`` meets it; a missing (NaN) value never does."""
        return not math.isnan(measured) and OPERATORS[self.op](measured, self.value)

    def __str__(self) -> str:
        return f"{METRIC_NAMES.get(self.metric, self.metric)} {self.op} {self.value:g}{unit_suffix(self.metric)}"


@dataclass(frozen=True)
class StressCase:
    """One world of the suite.

    Attributes:
        name: short id for ``--cases`` (e.g. ``angle_25``).
        label: what it is, for tables and figures.
        overrides: dotted config keys applied on top of the user's config (empty: the config's world).
        thresholds: what must hold in it.
    """

    name: str
    label: str
    overrides: Mapping[str, Any]
    thresholds: tuple[Threshold, ...]

    def config(self, base: ScoopConfig) -> ScoopConfig:
        """``base`` with this case's overrides (validated)."""
        return base.with_overrides(dict(self.overrides)) if self.overrides else base


METRIC_NAMES = {
    "fill_factor_mean": "fill factor", "volumetric_fill_mean": "volumetric fill", "success_rate": "success",
    "reached_rate": "reached", "cycle_time_mean": "cycle time", "overload_rate": "overload",
}
"""The statistics the suite shows (tables and heat map), in order, with their names."""
METRIC_UNITS = {"cycle_time_mean": "s"}
"""Units of the statistics that have one (the others are fractions)."""


def unit_suffix(metric: str) -> str:
    """`` s`` for a statistic in seconds; empty for a fraction."""
    return f" {METRIC_UNITS[metric]}" if metric in METRIC_UNITS else ""


def metric_header(metric: str) -> str:
    """A column heading: the name, with its unit in brackets (``cycle time (s)``)."""
    return METRIC_NAMES[metric] + (f" ({METRIC_UNITS[metric]})" if metric in METRIC_UNITS else "")

NOMINAL_CYCLE_TIME_S = kinematics.MACHINE.task.target_cycle_time_s
"""The nominal world's cycle-time bar: the machine's ``task.target_cycle_time_s`` (the Komodo's: the paper's 5 s)."""
NOMINAL_THRESHOLDS = (Threshold("fill_factor_mean", ">=", 0.75), Threshold("success_rate", ">=", 0.97),
                      Threshold("cycle_time_mean", "<=", NOMINAL_CYCLE_TIME_S))
"""The nominal world must scoop well: fill factor >= 0.75, success >= 0.97, cycle time no longer than the bar."""
STRESS_THRESHOLDS = (Threshold("success_rate", ">=", 0.90), Threshold("volumetric_fill_mean", ">=", 0.60),
                     Threshold("overload_rate", "<=", 0.05))
"""Every other world must still scoop: success >= 0.90, volumetric fill >= 0.60, overload <= 5 %."""

SENSOR_LINK = {"sensor.delay_s": 0.05, "sensor.joint_noise_rad": 0.002, "sensor.speed_noise_mps": 0.002,
               "sensor.range_noise_m": 0.003, "sensor.torque_noise_nm": 0.2}
"""A realistic link: readings 50 ms late, joint 0.002 rad, speed 0.002 m/s, range 0.003 m, torque 0.2 N*m noise."""

LIGHT_MASS_SHARE, HEAVY_MASS_SHARE = 2.0 / 3.0, 4.0 / 3.0
"""The light and heavy materials: particles of 2/3 and 4/3 the nominal particle's mass (0.2 and 0.4 kg on the
Komodo's 0.3 kg)."""
LONG_GAP_SHARE = 3.0
"""The long start gap: 3 times the nominal gap (0.3 m on the Komodo's 0.1 m)."""


def _stress(name: str, label: str, overrides: Mapping[str, Any]) -> StressCase:
    return StressCase(name, label, dict(overrides), STRESS_THRESHOLDS)


def _nice(value: float) -> float:
    """``value`` to 6 significant digits (2/3 of 0.3 kg is 0.2 kg, not 0.19999999999999998)."""
    return float(format(value, ".6g"))


_NOMINAL = ScoopConfig()
_LIGHT_KG = _nice(LIGHT_MASS_SHARE * _NOMINAL.pile.particle_mass_kg)
_HEAVY_KG = _nice(HEAVY_MASS_SHARE * _NOMINAL.pile.particle_mass_kg)
_LONG_GAP_M = _nice(LONG_GAP_SHARE * _NOMINAL.robot.start_gap_m)

CASES: tuple[StressCase, ...] = (
    StressCase("nominal", f"nominal ({_NOMINAL.pile.angle_deg:g}° pile)", {}, NOMINAL_THRESHOLDS),
    _stress("angle_25", "25° pile", {"pile.angle_deg": 25.0}),
    _stress("angle_40", "40° pile", {"pile.angle_deg": 40.0}),
    _stress("light", f"lighter material ({_LIGHT_KG:g} kg particles)", {"pile.particle_mass_kg": _LIGHT_KG}),
    _stress("heavy", f"heavier material ({_HEAVY_KG:g} kg particles)", {"pile.particle_mass_kg": _HEAVY_KG}),
    _stress("friction_0.6", "particle friction 0.6", {"pile.friction": 0.6}),
    _stress("friction_1.3", "particle friction 1.3", {"pile.friction": 1.3}),
    _stress("gap_0.3", f"start gap {_LONG_GAP_M:g} m", {"robot.start_gap_m": _LONG_GAP_M}),
    _stress("torque_mass", "mass from joint torques", {"env.mass_source": "torque"}),
    _stress("delay_noise", "sensor delay 0.05 s + noise", SENSOR_LINK),
    _stress("randomized", "randomised world (robot preset)", {"randomize.preset": "robot"}),
)
"""The suite's cases, in order: nominal; 25° and 40° piles; particles of 2/3 and 4/3 the nominal mass; particle
friction 0.6 and 1.3; three times the nominal start gap; the mass from the joint torques; sensor delay 0.05 s
with noise; the ``robot`` randomised world. The case names are the Komodo's (``gap_0.3``: 0.3 m there); the
lengths and masses follow the machine's nominal world."""


def case_names() -> list[str]:
    """The names of :data:`CASES`, in order."""
    return [case.name for case in CASES]


def select_cases(names: str | Iterable[str] | None = None) -> list[StressCase]:
    """The cases named (comma-separated text or a list; ``None``: all), in the suite's order.

    Raises:
        ValueError: a name that is not a case, or no name at all (``--cases ""``); the message lists the known ones.
    """
    if names is None:
        return list(CASES)
    wanted = [n.strip() for n in (names.split(",") if isinstance(names, str) else names) if n.strip()]
    if not wanted:
        raise ValueError(f"--cases {quote(names)} names no case; name one or more of: {', '.join(case_names())} "
                         "(or leave --cases out for all)")
    unknown = [n for n in wanted if n not in case_names()]
    if unknown:
        raise ValueError(f"unknown stress case(s) {', '.join(map(repr, unknown))}; "
                         f"known cases: {', '.join(case_names())}")
    return [case for case in CASES if case.name in wanted]


@dataclass(frozen=True)
class Check:
    """A threshold with what was measured against it."""

    threshold: Threshold
    measured: float

    @property
    def passed(self) -> bool:
        """Whether the measured value meets the threshold."""
        return self.threshold.holds(self.measured)

    def as_dict(self) -> dict[str, Any]:
        """Plain types for JSON."""
        t = self.threshold
        return {"metric": t.metric, "op": t.op, "threshold": t.value, "measured": self.measured,
                "passed": self.passed}


@dataclass
class StressRow:
    """One case's result.

    Attributes:
        case: the case.
        stats: :func:`~autoscoop.evaluation.summary.outcome_statistics` of its episodes (``fill_factor_mean``
            and ``_std``, ``volumetric_fill_*``, ``cycle_time_*`` (s, successes), ``success_rate``,
            ``reached_rate``, ``overload_rate``, ``mass_kg_*``, ...).
        outcomes: the episodes, in seed order.
    """

    case: StressCase
    stats: dict[str, float]
    outcomes: list[EpisodeOutcome] = field(default_factory=list)

    @property
    def checks(self) -> list[Check]:
        """Each of the case's thresholds against its statistic."""
        return [Check(t, float(self.stats.get(t.metric, math.nan))) for t in self.case.thresholds]

    @property
    def passed(self) -> bool:
        """Whether every threshold holds."""
        return all(c.passed for c in self.checks)

    def failures(self) -> list[Check]:
        """The thresholds that do not hold."""
        return [c for c in self.checks if not c.passed]

    def as_dict(self) -> dict[str, Any]:
        """Plain types for JSON: the case, its statistics, checks, pass flag and each episode."""
        return {"case": self.case.name, "label": self.case.label, "overrides": dict(self.case.overrides),
                "stats": dict(self.stats), "checks": [c.as_dict() for c in self.checks], "passed": self.passed,
                "episodes_detail": [o.as_dict() for o in self.outcomes]}


def row_from_outcomes(case: StressCase, outcomes: Sequence[EpisodeOutcome]) -> StressRow:
    """A case's row from its episodes."""
    return StressRow(case, outcome_statistics(o.as_dict() for o in outcomes), list(outcomes))


def run_case(policy: str, config: ScoopConfig, case: StressCase, episodes: int, seed: int = 0,
             trust: bool = False, progress: bool = True) -> list[EpisodeOutcome]:
    """Run one case: ``episodes`` episodes, seeds ``seed, seed + 1, ...``, in ``config`` under the case's overrides.

    The policy is loaded under the case's config, as ``autoscoop eval --set ...`` would load it (the
    scripted controller takes its terminal point and speed limits from the config) and run by
    :func:`autoscoop.evaluation.evaluate.evaluate`, with the case named on the progress bar.
    """
    case_config = case.config(config)
    controller = load_policy(policy, case_config, trust=trust)
    return evaluate(controller, case_config, episodes, seed=seed, progress=progress, label=f"stress {case.name}")


def _run_case_in_worker(policy: str, config: dict[str, Any], case: StressCase, episodes: int, seed: int,
                        trust: bool) -> list[EpisodeOutcome]:
    """:func:`run_case` in a worker process: the config as a dict, no progress bar."""
    return run_case(policy, ScoopConfig.from_dict(config), case, episodes, seed, trust=trust, progress=False)


def run_stress(policy: str, config: ScoopConfig, episodes: int, seed: int = 0,
               cases: Sequence[StressCase] | None = None, workers: int = 1, trust: bool = False,
               progress: bool = True) -> list[StressRow]:
    """Run ``policy`` over the stress cases, the same seeds in each.

    Args:
        policy: a ``--policy`` argument (``default``, ``heuristic``, a file or run folder); each case
            (and each worker process) loads it itself.
        config: the world every case starts from (the user's ``--config``/``--set``); each case's
            overrides go on top.
        episodes: episodes per case, seeds ``seed .. seed + episodes - 1``.
        cases: which (default: all of :data:`CASES`).
        workers: worker processes (1: run here, a progress bar per case; more: cases run in parallel,
            processes of :func:`~autoscoop.evaluation.workers.worker_pool`, one bar over the cases). The results are the same either way.
        trust: allow a pickled SB3 zip from outside its run directory.
        progress: show the progress bars.

    Returns:
        one :class:`StressRow` per case, in the order of ``cases``.
    """
    if episodes < 1:
        raise ValueError(f"episodes must be at least 1, got {episodes}")
    if workers < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    cases = list(CASES if cases is None else cases)
    for case in cases:  # every config error before the first episode
        case.config(config)
    if workers == 1 or len(cases) == 1:
        return [row_from_outcomes(case, run_case(policy, config, case, episodes, seed, trust, progress))
                for case in cases]
    with worker_pool(min(workers, len(cases))) as pool:
        futures = [pool.submit(_run_case_in_worker, policy, config.to_dict(), case, episodes, seed, trust)
                   for case in cases]
        bar = tqdm(total=len(cases), desc=f"stress ({min(workers, len(cases))} workers)", unit="case",
                   disable=not progress)
        rows = []
        with bar:
            for case, future in zip(cases, futures, strict=True):  # in order: a row as soon as its case is done
                rows.append(row_from_outcomes(case, future.result()))
                bar.set_postfix_str(f"{case.name}: {'pass' if rows[-1].passed else 'FAIL'}")
                bar.update()
    return rows
