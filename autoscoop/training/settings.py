"""The algorithm's settings: its YAML from ``autoscoop/training/hyperparams/``, a recipe from
``autoscoop/training/recipes/`` laid over it, and ``--hyper`` overrides."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from autoscoop.agents.algorithms import ALGORITHMS
from autoscoop.core.config import ScoopConfig
from autoscoop.core.safe_files import parse_yaml
from autoscoop.training.recipes import SHIPPED_RECIPE, algorithm_yaml, check_recipe, lay_over, recipe_overlay


def load_hyperparams(algo: str) -> dict[str, Any]:
    """The algorithm's YAML from the package (``autoscoop/training/hyperparams/ALGO.yaml``)."""
    if algo not in ALGORITHMS:
        raise ValueError(f"--algo {algo!r} is not offered; choose one of {sorted(ALGORITHMS)}")
    return algorithm_yaml(algo)


def load_recipe(algo: str, recipe: str = SHIPPED_RECIPE) -> dict[str, Any]:
    """The algorithm's YAML with a recipe (:mod:`autoscoop.training.recipes`, its bases included) laid over it:
    the keys of the recipe's sections (``env``, ``hyperparams``, ``noise``, ``schedule``) are laid over the
    algorithm's, its other top-level keys (``episodes``, ``demo_episodes``, ``curriculum``) set.

    Raises:
        ValueError: an unknown algorithm or recipe, naming the ones offered.
    """
    check_recipe(recipe)
    merged = lay_over(load_hyperparams(algo), recipe_overlay(recipe))
    return {**merged, "env": merged.get("env") or {}, "recipe": recipe}


@dataclass(frozen=True)
class SelectionSettings:
    """A recipe's ``selection`` section: after training, the ``candidates`` best snapshots by the periodic
    evaluation (in the last curriculum world) run every stress case ``episodes`` times from seed ``seed``,
    and the run keeps the one that falls least short (:mod:`autoscoop.evaluation.selection`)."""

    candidates: int
    episodes: int
    seed: int


def selection_settings(spec: dict[str, Any]) -> SelectionSettings | None:
    """The YAML's ``selection`` section, ``None`` without one.

    Raises:
        ValueError: a missing or non-integer key, or one below its minimum (candidates, episodes >= 1; seed >= 0).
    """
    section = spec.get("selection")
    if not section:
        return None
    values = {}
    for key, least in (("candidates", 1), ("episodes", 1), ("seed", 0)):
        value = section.get(key) if isinstance(section, dict) else None
        if not isinstance(value, int) or isinstance(value, bool) or value < least:
            raise ValueError(f"selection.{key} must be a whole number >= {least}, got {value!r}")
        values[key] = value
    return SelectionSettings(**values)


def curriculum_stages(spec: dict[str, Any]) -> list[tuple[int, dict[str, Any]]]:
    """A recipe's ``curriculum``: (episode, ``randomize.*`` keys) stages, in episode order. From the end of
    that episode on, training (and its periodic evaluation) runs in the world those keys make.

    Raises:
        ValueError: a stage without a positive ``episode``, or with keys outside ``randomize``.
    """
    stages = []
    for stage in spec.get("curriculum") or []:
        episode, keys = stage.get("episode"), dict(stage.get("set") or {})
        if not isinstance(episode, int) or episode < 1:
            raise ValueError(f"curriculum stage {stage!r}: 'episode' must be a whole number >= 1")
        bad = sorted(key for key in keys if not str(key).startswith("randomize."))
        if bad:
            raise ValueError(f"curriculum stage at episode {episode}: only randomize.* keys can change, got {bad}")
        stages.append((episode, keys))
    return sorted(stages, key=lambda item: item[0])


def config_at(config: ScoopConfig, spec: dict[str, Any], episodes_done: int) -> ScoopConfig:
    """The training world after ``episodes_done`` episodes: ``config`` with every stage begun by then applied."""
    for episode, keys in curriculum_stages(spec):
        if episode <= episodes_done:
            config = config.with_overrides(keys)
    return config


def with_hyper_overrides(spec: dict[str, Any], overrides: dict[str, str]) -> dict[str, Any]:
    """The algorithm's settings with ``section.key=value`` overrides (``hyperparams.learning_rate=3e-4``,
    ``noise.sigma_start=0.05``); only keys the YAML already has, values parsed as YAML scalars of the same type.

    Raises:
        ValueError: an unknown key, or a value of another type than the YAML's.
    """
    out = {name: dict(section) if isinstance(section, dict) else section for name, section in spec.items()}
    for dotted, text in overrides.items():
        section, _, key = dotted.partition(".")
        if not isinstance(out.get(section), dict) or key not in out[section]:
            known = sorted(f"{name}.{k}" for name, sec in out.items() if isinstance(sec, dict) for k in sec)
            raise ValueError(f"--hyper {dotted}: not a setting of this algorithm; known: {', '.join(known)}")
        old = out[section][key]
        value = parse_yaml(text, f"--hyper {dotted}")
        if isinstance(old, float) and not isinstance(value, bool):
            try:  # YAML reads 3e-4 as a string
                value = float(text)
            except ValueError:
                pass
        if type(value) is not type(old):
            raise ValueError(f"--hyper {dotted}={text}: expected a {type(old).__name__} like {old!r}")
        out[section][key] = value
    return out
