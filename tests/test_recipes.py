"""The recipe registry: one YAML file a recipe, bases that inherit, the CLI and the sweep reading the same list."""

import argparse
import json
from pathlib import Path

import pytest
import yaml

from autoscoop.training import recipes
from autoscoop.training.recipes import RECIPES, SHIPPED_RECIPE, recipe_overlay

PINNED = Path(__file__).parent / "data" / "recipes_merged.json"
"""every algorithm's merged settings for each recipe, as they were before the recipes inherited."""


@pytest.mark.parametrize("recipe", sorted(json.loads(PINNED.read_text())["ddpg"]))
def test_a_recipes_merged_settings_are_pinned_for_every_algorithm(recipe):
    from autoscoop.training.settings import load_recipe

    pinned = json.loads(PINNED.read_text())
    for algo in pinned:
        assert json.loads(json.dumps(load_recipe(algo, recipe))) == pinned[algo][recipe], (algo, recipe)


def test_the_registry_is_the_folders_yaml_files_with_the_paper_and_the_shipped_recipe():
    folder = Path(recipes.__file__).parent
    assert RECIPES == tuple(sorted(path.stem for path in folder.glob("*.yaml")))
    assert {"paper", SHIPPED_RECIPE} <= set(RECIPES)
    assert all(recipes.recipe_summary(name) for name in RECIPES)


@pytest.mark.parametrize("recipe", [name for name in RECIPES if "base" in yaml.safe_load(
    (Path(recipes.__file__).parent / f"{name}.yaml").read_text())])
def test_a_recipe_with_a_base_names_only_what_it_changes(recipe):
    own = yaml.safe_load((Path(recipes.__file__).parent / f"{recipe}.yaml").read_text())
    base = recipe_overlay(own["base"])
    for key, value in own.items():
        if key in recipes.RECIPE_KEYS:
            continue
        if isinstance(value, dict):
            for name, setting in value.items():
                assert (base.get(key) or {}).get(name, object()) != setting, f"{recipe}: {key}.{name} repeats its base"
        else:
            assert base.get(key, object()) != value, f"{recipe}: {key} repeats its base"


def test_bases_are_laid_under_a_recipe_and_their_description_keys_left_out():
    smooth = recipe_overlay("robot_smooth")
    assert smooth["episodes"] == 5000 and smooth["demo_episodes"] == 50
    assert smooth["env"]["sensor.level_with_imu"] is True and smooth["env"]["reward.c_action_change"] == 1.0
    assert not set(recipes.RECIPE_KEYS) & set(smooth)


def test_a_base_that_is_unknown_or_leads_back_is_refused(monkeypatch):
    files = {"a": {"base": "b"}, "b": {"base": "a"}, "c": {"base": "nope"}}
    monkeypatch.setattr(recipes, "RECIPES", ("a", "b", "c"))
    monkeypatch.setattr(recipes, "_recipe_file", lambda name: files[name])
    with pytest.raises(ValueError, match="circle"):
        recipe_overlay("a")
    with pytest.raises(ValueError, match="--recipe 'nope'"):
        recipe_overlay("c")


def test_train_offers_every_recipe_with_the_shipped_one_as_the_default(capsys):
    from autoscoop.commands import train_cmd

    parser = argparse.ArgumentParser()
    train_cmd.register(parser.add_subparsers())
    with pytest.raises(SystemExit):
        parser.parse_args(["train", "--help"])
    text = "".join(capsys.readouterr().out.split())  # argparse wraps lines, at hyphens too
    for name in RECIPES:
        assert parser.parse_args(["train", "--recipe", name]).recipe == name
        line = f"{name}{' (default)' if name == SHIPPED_RECIPE else ''}: {recipes.recipe_summary(name)}"
        assert "".join(line.split()) in text
    assert train_cmd.DEFAULTS["recipe"] == SHIPPED_RECIPE


def test_a_sweep_space_takes_the_registered_recipes_only():
    from autoscoop.training.sweep_space import SweepSpace

    for name in RECIPES:
        assert SweepSpace(recipe=name).recipe == name
    with pytest.raises(ValueError, match="recipe"):
        SweepSpace(recipe="fast")


def test_the_training_docs_list_every_registered_recipe_with_its_base_and_episodes():
    from autoscoop.training.settings import load_recipe

    table = [line for line in (Path(__file__).resolve().parents[1] / "docs" / "training.md").read_text().splitlines()
             if line.startswith("| `")]
    for name in RECIPES:
        rows = [line for line in table if line.startswith(f"| `{name}` ")]
        assert len(rows) == 1, f"docs/training.md lists recipe {name} {len(rows)} times"
        cells = [cell.strip() for cell in rows[0].split("|")[1:-1]]
        base = yaml.safe_load((Path(recipes.__file__).parent / f"{name}.yaml").read_text()).get("base")
        assert cells[1] == (f"`{base}`" if base else "the algorithm's YAML")
        assert cells[3] == str(load_recipe("ddpg", name)["episodes"])
        assert ("**default**" in cells[0]) == (name == SHIPPED_RECIPE)
