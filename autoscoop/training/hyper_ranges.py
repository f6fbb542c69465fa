"""The allowed ranges of the algorithms' settings (``hyperparams.*``, ``noise.*``), checked before a run starts.

Stable-Baselines3 and torch accept some values that cannot train (``batch_size: 0`` "finishes" a run that
learned nothing, ``gamma: 2`` diverges) and refuse others late, in words that do not name the setting
(a NaN learning rate). :func:`check_training_settings` refuses them all at once, naming the key and its range,
before a run directory is made.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from autoscoop.core.safe_files import quote


@dataclass(frozen=True)
class Allowed:
    """A setting's range: ``low`` to ``high`` (either end open when ``*_open``), whole numbers when ``whole``;
    ``also`` lists single values allowed besides (SB3's ``gradient_steps: -1``)."""

    low: float
    high: float = math.inf
    low_open: bool = False
    high_open: bool = False
    whole: bool = False
    also: tuple[float, ...] = ()

    def admits(self, value: float) -> bool:
        """Whether ``value`` (a finite number) lies in the range."""
        if value in self.also:
            return True
        above = value > self.low if self.low_open else value >= self.low
        below = value < self.high if self.high_open else value <= self.high
        return above and below

    def describe(self) -> str:
        """The range as ``(0, 1]`` or ``whole numbers in [1, inf)``."""
        span = f"{'(' if self.low_open else '['}{self.low:g}, {self.high:g}{')' if self.high_open else ']'}"
        extra = "".join(f" or {value:g}" for value in self.also)
        return f"{'a whole number' if self.whole else 'a number'} in {span}{extra}"


FRACTION = Allowed(0.0, 1.0, low_open=True)
COUNT = Allowed(1, whole=True)
RANGES: dict[str, Allowed] = {
    "hyperparams.learning_rate": FRACTION,
    "hyperparams.gamma": FRACTION,
    "hyperparams.tau": FRACTION,
    "hyperparams.batch_size": COUNT,
    "hyperparams.buffer_size": COUNT,
    "hyperparams.learning_starts": Allowed(0, whole=True),
    "hyperparams.train_freq": COUNT,
    "hyperparams.gradient_steps": Allowed(1, whole=True, also=(-1,)),
    "hyperparams.policy_delay": COUNT,
    "hyperparams.target_policy_noise": Allowed(0.0),
    "hyperparams.target_noise_clip": Allowed(0.0),
    "hyperparams.n_steps": Allowed(2, whole=True),
    "hyperparams.n_epochs": COUNT,
    "hyperparams.gae_lambda": Allowed(0.0, 1.0),
    "hyperparams.clip_range": Allowed(0.0, low_open=True),
    "hyperparams.ent_coef": Allowed(0.0),
    "noise.sigma_start": Allowed(0.0),
    "noise.sigma_end": Allowed(0.0),
    "noise.theta": Allowed(0.0, low_open=True),
}
"""every numeric setting of the algorithms' YAML (autoscoop/training/hyperparams/) and its range; a string
(SAC's ``ent_coef: auto``) is left to Stable-Baselines3."""
MAX_N_ENVS = 64
"""the most parallel simulators a run may ask for (each is a process)."""


def check_training_settings(spec: dict[str, Any], n_envs: int = 1) -> None:
    """Refuse settings outside :data:`RANGES`, NaN and infinity included, and more than :data:`MAX_N_ENVS`
    simulators.

    Args:
        spec: the algorithm's settings after the recipe and ``--hyper`` (sections ``hyperparams``, ``noise``).
        n_envs: parallel simulators.

    Raises:
        ValueError: naming the first setting out of range, its value and what is allowed.
    """
    if not 1 <= n_envs <= MAX_N_ENVS:
        raise ValueError(f"--n-envs {n_envs} is out of range; allowed whole numbers in [1, {MAX_N_ENVS}]")
    for key, allowed in RANGES.items():
        section, _, name = key.partition(".")
        values = spec.get(section)
        if not isinstance(values, dict) or name not in values or isinstance(values[name], str):
            continue
        value = values[name]
        number = isinstance(value, (int, float)) and not isinstance(value, bool)
        if not number or not math.isfinite(value) or (allowed.whole and not isinstance(value, int)) \
                or not allowed.admits(value):
            raise ValueError(f"{key} = {quote(value)} is out of range; allowed {allowed.describe()}")
