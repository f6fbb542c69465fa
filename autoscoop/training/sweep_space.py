"""A sweep's search space: the YAML file ``autoscoop sweep --space`` reads, checked before any trial starts.

The file names config keys (``--set`` keys, under ``config``) and algorithm keys (``--hyper`` keys, under
``hyper``), each with a fixed value or one of Ray Tune's distributions, and the seeds::

    algo: ddpg                 # the algorithm (its YAML is autoscoop/training/hyperparams/ALGO.yaml)
    recipe: paper              # laid over it (autoscoop/training/recipes/NAME.yaml; default paper)
    seeds: [0, 1]              # a grid: every setting is trained with each seed
    config:
      pile.variants: 2                              # fixed: every trial
      reward.c_w: {choice: [30, 50]}                # drawn from a list
    hyper:
      hyperparams.learning_rate: {loguniform: [1.0e-4, 1.0e-3]}
      noise.sigma_start: {grid: [0.1, 0.15]}        # every value, in every trial set
    train: {eval_every: 50, eval_episodes: 10, checkpoint_every: 50}
    asha: {grace_period: 100, reduction_factor: 2}  # optional: stop poor trials early

A bad key or value fails here, naming it (:class:`autoscoop.core.config.ConfigError`, exit 2): config keys
and values are checked with the package's config schema, algorithm keys with the algorithm's YAML
(:func:`autoscoop.training.settings.with_hyper_overrides`), each value a distribution can give (its list's
items, a range's ends). Nothing here imports Ray: :mod:`autoscoop.training.sweep` turns a space into Tune's.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Mapping
from pathlib import Path
from typing import Annotated, Any, Literal

from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator

from autoscoop.core.config import ConfigError, ConfigModel, ScoopConfig, read_yaml_file, setting
from autoscoop.training.recipes import PAPER_RECIPE, RECIPES, algorithm_names
from autoscoop.training.settings import load_recipe, with_hyper_overrides

DISTRIBUTIONS = ("choice", "uniform", "loguniform", "grid")
"""The distributions a setting can name: ``choice`` (one item of a list, drawn), ``uniform`` and ``loguniform``
(a number drawn in [low, high], evenly or evenly in its logarithm) and ``grid`` (every item of a list)."""
RANDOM = ("choice", "uniform", "loguniform")
"""The distributions that draw: a trial set of the grid is repeated with new draws (``--trials``)."""
_EXPONENT_NUMBER = re.compile(r"[-+]?(\d+\.?\d*|\.\d+)[eE][-+]?\d+")
"""``1e-4``: YAML 1.1 (PyYAML) reads it as text; here it is taken as the number it means."""


class Distribution(BaseModel):
    """One setting of the space: a fixed value (``kind`` ``fixed``) or one of :data:`DISTRIBUTIONS`.

    Written in YAML as the plain value (fixed) or a mapping of one distribution to its argument:
    ``{choice: [30, 50]}``, ``{uniform: [25, 40]}``, ``{loguniform: [1.0e-4, 1.0e-3]}``, ``{grid: [1, 2]}``.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    kind: Literal["fixed", "choice", "uniform", "loguniform", "grid"]
    values: tuple[Any, ...]
    """fixed: (the value,); choice and grid: the items; uniform and loguniform: (low, high)."""

    @model_validator(mode="before")
    @classmethod
    def _from_yaml(cls, data: Any) -> Any:
        if isinstance(data, Mapping) and set(data) == {"kind", "values"}:  # as written by to_dict()
            return data
        if not isinstance(data, Mapping):
            return {"kind": "fixed", "values": (_number_from_text(data),)}
        if len(data) != 1:
            raise ValueError(f"must be a value or one distribution of {list(DISTRIBUTIONS)}, "
                             f"got a mapping with keys {sorted(map(str, data))}")
        name, argument = next(iter(data.items()))
        if name not in DISTRIBUTIONS:
            raise ValueError(f"{name!r} is not a distribution; use one of {list(DISTRIBUTIONS)}")
        if name in ("choice", "grid"):
            if not isinstance(argument, list) or not argument:
                raise ValueError(f"{name} needs a non-empty list of values, got {argument!r}")
            return {"kind": name, "values": tuple(_number_from_text(v) for v in argument)}
        ends = [_number_from_text(v) for v in argument] if isinstance(argument, list) else None
        if not (ends and len(ends) == 2 and all(_is_number(v) for v in ends)):
            raise ValueError(f"{name} needs [low, high], two numbers, got {argument!r}")
        low, high = float(ends[0]), float(ends[1])
        if not low < high:
            raise ValueError(f"{name} needs low < high, got [{low:g}, {high:g}]")
        if name == "loguniform" and low <= 0:
            raise ValueError(f"loguniform needs 0 < low < high, got [{low:g}, {high:g}]")
        return {"kind": name, "values": (low, high)}

    @property
    def swept(self) -> bool:
        """Whether trials differ in it (not fixed)."""
        return self.kind != "fixed"

    def candidates(self) -> tuple[Any, ...]:
        """The values to check: a fixed value, a list's items, a range's ends (floats, as the draws are)."""
        return self.values

    def grid_size(self) -> int:
        """How many trial sets it makes: the list's length for ``grid``, 1 otherwise."""
        return len(self.values) if self.kind == "grid" else 1

    def describe(self) -> str:
        """``choice [30, 50]``, ``loguniform [0.0001, 0.001]``, ``= 2`` (fixed)."""
        if self.kind == "fixed":
            return f"= {self.values[0]!r}"
        return f"{self.kind} [{', '.join(f'{v:g}' if _is_number(v) else repr(v) for v in self.values)}]"


def _is_number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _number_from_text(value: Any) -> Any:
    return float(value) if isinstance(value, str) and _EXPONENT_NUMBER.fullmatch(value.strip()) else value


class TrialSettings(ConfigModel):
    """How each trial trains (the ``train`` section), besides ``--episodes``: as ``autoscoop train``'s options."""

    section = "train"
    label = "sweep space"

    eval_every: int = setting(50, "episodes", "episodes between periodic evaluations (each is reported to Tune)", 1)
    eval_episodes: int = setting(10, "episodes", "episodes per evaluation (fixed seeds)", 1)
    checkpoint_every: int = setting(50, "episodes", "episodes between checkpoints (a resumed trial continues there)", 1)


class AshaSettings(ConfigModel):
    """Tune's ASHA scheduler (the ``asha`` section): stops trials whose score trails at each rung."""

    section = "asha"
    label = "sweep space"

    grace_period: int = setting(100, "episodes", "episodes a trial trains before ASHA may stop it", 1)
    reduction_factor: int = setting(2, "-", "1 in this many trials goes on at each rung", 2)


Seed = Annotated[int, Field(strict=True, ge=0)]


class SweepSpace(BaseModel):
    """The whole space file, validated (see the module's docstring)."""

    model_config = ConfigDict(frozen=True, extra="forbid")

    algo: Literal[algorithm_names()] = "ddpg"  # type: ignore[valid-type]  # the algorithms' YAML files, as train --algo
    """the algorithm; ``hyper`` keys are those of its YAML."""
    recipe: Literal[RECIPES] = PAPER_RECIPE  # type: ignore[valid-type]  # the registry's names
    """the recipe laid over the algorithm's YAML (as ``autoscoop train --recipe``; one of
    :data:`autoscoop.training.recipes.RECIPES`); a space without one trains the paper's, quick to try."""
    seeds: tuple[Seed, ...] = Field((0,), min_length=1)
    """training seeds, a grid: every trial set is trained with each."""
    draw_seed: Seed = 0
    """seed of Tune's draws (choice, uniform, loguniform): the same file draws the same trials."""
    config: dict[str, Distribution] = Field(default_factory=dict)
    """config keys (``--set`` keys, dotted: ``reward.c_w``) and their values or distributions."""
    hyper: dict[str, Distribution] = Field(default_factory=dict)
    """algorithm keys (``--hyper`` keys: ``hyperparams.learning_rate``) and their values or distributions."""
    train: TrialSettings = Field(default_factory=TrialSettings)
    """how each trial trains and evaluates."""
    asha: AshaSettings | None = None
    """ASHA early stopping; ``None`` (no ``asha`` section): every trial runs its episodes."""

    def swept(self) -> dict[str, Distribution]:
        """The settings trials differ in, config keys then algorithm keys (by key as written; seeds aside)."""
        return {**{k: d for k, d in self.config.items() if d.swept}, **{k: d for k, d in self.hyper.items() if d.swept}}

    def fixed(self) -> dict[str, Any]:
        """The settings every trial shares (config keys then algorithm keys)."""
        return {k: d.values[0] for k, d in {**self.config, **self.hyper}.items() if not d.swept}

    def grid_size(self) -> int:
        """Trial sets one pass over the grid makes: seeds times the lengths of the ``grid`` lists."""
        return len(self.seeds) * math.prod(d.grid_size() for d in (*self.config.values(), *self.hyper.values()))

    def draws(self) -> bool:
        """Whether any setting is drawn (so repeating the grid gives new trials)."""
        return any(d.kind in RANDOM for d in (*self.config.values(), *self.hyper.values()))

    def to_dict(self) -> dict[str, Any]:
        """Plain data (JSON), from which :func:`space_from_dict` rebuilds it."""
        return self.model_dump(mode="json")


def load_space(path: str | Path) -> SweepSpace:
    """Read and check a space file (see :func:`check_space`).

    Raises:
        ConfigError: naming the file, then the key (``config.reward.c_w``, ``hyper...``, ``train.eval_every``).
    """
    data = read_yaml_file(path, "space file")
    try:
        return space_from_dict(data if data is not None else {})
    except ConfigError as error:
        raise ConfigError(f"space file {path}: {error}", error.details) from None


def space_from_dict(data: Any) -> SweepSpace:
    """Build and check a space from plain data (the YAML file's, or :meth:`SweepSpace.to_dict`'s).

    Raises:
        ConfigError: naming the key.
    """
    if not isinstance(data, Mapping):
        raise ConfigError(f"expected a mapping of keys ({', '.join(SweepSpace.model_fields)}), "
                          f"got {type(data).__name__}")
    data = dict(data)
    sections = {"train": TrialSettings, "asha": AshaSettings}
    for name, model in sections.items():  # built first: their errors name the dotted key and its range
        if data.get(name) is not None and not isinstance(data[name], model):
            data[name] = model.from_dict(data[name])
    for name in ("config", "hyper"):
        if data.get(name) is None:
            data.pop(name, None)
    try:
        space = SweepSpace.model_validate(data)
    except ValidationError as error:
        raise _space_error(error) from None
    check_space(space)
    return space


def _space_error(error: ValidationError) -> ConfigError:
    """The :class:`ConfigError` for the first of pydantic's records, naming the key (``config.reward.c_w``)."""
    first = error.errors()[0]
    parts = [str(part) for part in first["loc"] if not isinstance(part, int)]
    key = ".".join(parts) or "space"
    if first["type"] == "extra_forbidden":
        known = list(SweepSpace.model_fields) if len(parts) == 1 else []
        return ConfigError(f"unknown key {key!r}" + (f"; known: {known}" if known else ""))
    if first["type"] == "value_error":
        return ConfigError(f"{key} = {first['input']!r}: {first['ctx']['error']}")
    if first["type"] == "dict_type":
        return ConfigError(f"{key} must be a mapping of keys to values or distributions, got {first['input']!r}")
    return ConfigError(f"{key} = {first['input']!r}: {first['msg']}")


def check_space(space: SweepSpace) -> None:
    """Check every key and every value a trial could get, with the config schema and the algorithm's YAML.

    Fixed values are checked together (as every trial has them), then each swept value on top of them.

    Raises:
        ConfigError: naming the section (``config``, ``hyper``) and the key, and what is allowed.
    """
    both = sorted(set(space.config) & set(space.hyper))
    if both:
        raise ConfigError(f"{both} listed under both config and hyper; a key belongs to one")
    spec = load_recipe(space.algo, space.recipe)
    base = dict(spec.get("env") or {})
    fixed_config = {k: d.values[0] for k, d in space.config.items() if not d.swept}
    fixed_hyper = {k: hyper_text(d.values[0]) for k, d in space.hyper.items() if not d.swept}
    try:
        ScoopConfig().with_overrides({**base, **fixed_config})
        for key, dist in space.config.items():
            for value in dist.candidates():
                ScoopConfig().with_overrides({**base, **fixed_config, key: value})
    except ConfigError as error:
        raise ConfigError(f"config: {error}{_draw_note(error)}", error.details) from None
    try:
        with_hyper_overrides(spec, fixed_hyper)
        for key, dist in space.hyper.items():
            for value in dist.candidates():
                with_hyper_overrides(spec, {**fixed_hyper, key: hyper_text(value)})
    except ValueError as error:
        raise ConfigError(f"hyper: {error}{_draw_note(error)}") from None


def _draw_note(error: Exception) -> str:
    text = str(error)
    return " (uniform and loguniform draw floats)" if "integer" in text or "expected a int" in text else ""


def hyper_text(value: Any) -> str:
    """A value as ``--hyper`` text (JSON, which YAML reads back as the same value)."""
    return json.dumps(value)


def plan_trials(space: SweepSpace, trials: int) -> int:
    """Tune's ``num_samples`` for ``trials`` trials in all: passes over the grid (:meth:`SweepSpace.grid_size`).

    Raises:
        ValueError: naming ``--trials`` when it is not a whole number of passes, or repeats a grid without draws.
    """
    grid = space.grid_size()
    if trials < 1:
        raise ValueError(f"--trials must be at least 1, got {trials}")
    if trials % grid:
        raise ValueError(f"--trials {trials}: the space's grid has {grid} trial sets (seeds x grid lists), so "
                         f"--trials must be a multiple of {grid}")
    if trials > grid and not space.draws():
        raise ValueError(f"--trials {trials}: the space draws nothing (no choice, uniform or loguniform), so "
                         f"trials beyond its {grid} grid sets would repeat them; use --trials {grid}")
    return trials // grid


def check_episodes(space: SweepSpace, episodes: int) -> None:
    """Raises ValueError naming ``--episodes`` (at least 1) or ``asha.grace_period`` (below ``episodes``)."""
    if episodes < 1:
        raise ValueError(f"--episodes must be at least 1, got {episodes}")
    if space.asha is not None and space.asha.grace_period >= episodes:
        raise ValueError(f"asha.grace_period = {space.asha.grace_period} episodes is not below --episodes {episodes}: "
                         "ASHA could never stop a trial; lower it or leave out the asha section")
