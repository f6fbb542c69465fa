"""The training recipes: one YAML file each in this folder, and the registry every consumer reads
(``autoscoop train --recipe``'s choices and help, a sweep's ``recipe``, the docs, the worlds of
:data:`RECIPE_WORLDS`).

A recipe is laid over an algorithm's YAML (``autoscoop/training/hyperparams/ALGO.yaml``). Its file holds:

* ``summary``: one line saying what it trains, shown by ``autoscoop train --help``;
* ``base`` (optional): the recipe it starts from; it then names only what it changes;
* the keys it sets: ``episodes``, ``demo_episodes``, ``privileged_critic``, ``curriculum``, ``selection``,
  and sections (``env``, ``hyperparams``, ``noise``, ...) laid over its base's and the algorithm's key by key.

Adding a recipe is adding its file here. This module reads YAML only (no torch), so that the package can
register the worlds recipes train in when it is imported.
"""

from __future__ import annotations

from importlib import resources
from typing import Any

import yaml

from autoscoop.envs import register_world

PAPER_RECIPE = "paper"
"""the paper's recipe: its DDPG in its world, from random weights, 800 episodes."""
SHIPPED_RECIPE = "robot_smooth"
"""the recipe of the shipped ``default`` policy: what plain ``autoscoop train`` runs."""
DEFAULT_EPISODES = 800
"""training episodes of a run when neither ``--episodes`` nor its recipe names a count (the paper's)."""
RECIPE_KEYS = ("summary", "base")
"""keys that describe a recipe file rather than set anything; they stay out of the merged settings."""


def _folder() -> Any:
    return resources.files(__name__)


def recipe_names() -> tuple[str, ...]:
    """The recipes in this folder (``NAME.yaml``), sorted by name."""
    return tuple(sorted(entry.name.removesuffix(".yaml") for entry in _folder().iterdir()
                        if entry.name.endswith(".yaml")))


RECIPES = recipe_names()
"""the registered recipes, sorted by name."""


def check_recipe(name: str) -> None:
    """Raise ``ValueError`` naming the recipes offered when ``name`` is not one of them."""
    if name not in RECIPES:
        raise ValueError(f"--recipe {name!r} is not offered; choose one of {list(RECIPES)}")


def _recipe_file(name: str) -> dict[str, Any]:
    check_recipe(name)
    return yaml.safe_load((_folder() / f"{name}.yaml").read_text()) or {}


def recipe_summary(name: str) -> str:
    """The recipe's one-line ``summary``."""
    return str(_recipe_file(name).get("summary", ""))


def lay_over(settings: dict[str, Any], overlay: dict[str, Any]) -> dict[str, Any]:
    """``settings`` with ``overlay`` laid over it: a section (a mapping in both) key by key, any other key replaced."""
    merged = {**settings, **overlay}
    for name, section in overlay.items():
        if isinstance(section, dict) and isinstance(settings.get(name), dict):
            merged[name] = {**settings[name], **section}
    return merged


def recipe_overlay(name: str) -> dict[str, Any]:
    """What the recipe sets, its bases' keys included (a base's keys first, the recipe's laid over them).

    Raises:
        ValueError: an unknown recipe or base, or bases that lead back to the recipe.
    """
    chain = [name]
    while (base := _recipe_file(chain[-1]).get("base")) is not None:
        if base in chain:
            raise ValueError(f"recipe {name!r}: its bases go round in a circle ({' -> '.join([*chain, base])})")
        check_recipe(base)
        chain.append(base)
    overlay: dict[str, Any] = {}
    for link in reversed(chain):
        own = {key: value for key, value in _recipe_file(link).items() if key not in RECIPE_KEYS}
        overlay = lay_over(overlay, own)
    return overlay


def algorithm_names() -> tuple[str, ...]:
    """The algorithms with a YAML in ``autoscoop/training/hyperparams/``, sorted: ``train --algo``'s choices,
    read without torch (:data:`autoscoop.agents.algorithms.ALGORITHMS` maps the same names to their classes)."""
    folder = resources.files("autoscoop") / "training" / "hyperparams"
    return tuple(sorted(entry.name.removesuffix(".yaml") for entry in folder.iterdir() if entry.name.endswith(".yaml")))


def algorithm_yaml(algo: str) -> dict[str, Any]:
    """The algorithm's YAML as it stands in the package (``autoscoop/training/hyperparams/ALGO.yaml``)."""
    text = (resources.files("autoscoop") / "training" / "hyperparams" / f"{algo}.yaml").read_text()
    return yaml.safe_load(text) or {}


def training_world(recipe: str, algo: str = "ddpg") -> dict[str, Any]:
    """The config keys of the world a recipe trains in at its end: the algorithm's ``env`` keys, the
    recipe's, and every ``curriculum`` stage's, in that order (dotted keys, as ``--set`` takes them)."""
    spec = lay_over(algorithm_yaml(algo), recipe_overlay(recipe))
    world = dict(spec.get("env") or {})
    for stage in sorted(spec.get("curriculum") or [], key=lambda item: item.get("episode", 0)):
        world.update(stage.get("set") or {})
    return world


def recipes_help() -> str:
    """Every recipe with its summary, the shipped one marked as the default: the text of ``--recipe``'s help."""
    lines = [f"{name}{' (default)' if name == SHIPPED_RECIPE else ''}: {recipe_summary(name)}" for name in RECIPES]
    return "; ".join(lines)


RECIPE_WORLDS = {"autoscoop/ScoopRobot-v1": ("robot_smooth", "ddpg")}
"""Gymnasium ids registered from a recipe: the world that recipe trains in at its end, with that algorithm's
``env`` keys (:func:`training_world`). ``autoscoop/ScoopRobot-v1`` is the world the shipped ``default`` policy is
trained in. The recipe's merged settings are pinned by the tests, so the world under an id stays as it is."""


def register_recipe_worlds() -> None:
    """Register the ids of :data:`RECIPE_WORLDS` (idempotent)."""
    for env_id, (recipe, algo) in RECIPE_WORLDS.items():
        register_world(env_id, training_world(recipe, algo))
