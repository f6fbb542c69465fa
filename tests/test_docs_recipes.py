"""The docs' recipe tables list the recipes of the one registry (``autoscoop/training/recipes/``), with each
one's base and the shipped recipe marked as the default, so a recipe added or rebased shows up here."""

from __future__ import annotations

import re
from pathlib import Path

import pytest
import yaml

from autoscoop.training.recipes import RECIPES, SHIPPED_RECIPE

ROOT = Path(__file__).resolve().parents[1]
RECIPE_FOLDER = ROOT / "autoscoop" / "training" / "recipes"
ROW = re.compile(r"^\| `(?P<name>[a-z_]+)`(?P<mark>[^|]*)\|(?P<second>[^|]*)\|")


def recipe_rows(markdown: str, heading: str) -> dict[str, tuple[str, str]]:
    """The first table under ``heading``: recipe name -> (the rest of its first cell, its second cell)."""
    section = markdown.split(heading, 1)[1]
    rows, in_table = {}, False
    for line in section.splitlines():
        match = ROW.match(line)
        if match:
            rows[match["name"]] = (match["mark"].strip(), match["second"].strip())
            in_table = True
        elif in_table and not line.startswith("|"):
            break
    return rows


def declared_base(name: str) -> str | None:
    """The ``base`` a recipe file names, if any."""
    return (yaml.safe_load((RECIPE_FOLDER / f"{name}.yaml").read_text()) or {}).get("base")


def test_the_row_reader_reads_a_table():
    text = "## Recipes\n| recipe | base |\n|---|---|\n| `a` (default) | `b` |\n| `b` | the YAML |\n\n| `c` | x |\n"
    assert recipe_rows(text, "## Recipes") == {"a": ("(default)", "`b`"), "b": ("", "the YAML")}


@pytest.mark.parametrize("page, heading", [("docs/training.md", "## Recipes"), ("README.md", "## Train")])
def test_a_recipe_table_lists_the_registry_and_marks_the_shipped_recipe(page, heading):
    rows = recipe_rows((ROOT / page).read_text(encoding="utf-8"), heading)
    assert sorted(rows) == sorted(RECIPES)
    assert [name for name, (mark, _) in rows.items() if "default" in mark] == [SHIPPED_RECIPE]


def test_the_training_page_gives_each_recipes_base():
    rows = recipe_rows((ROOT / "docs/training.md").read_text(encoding="utf-8"), "## Recipes")
    for name, (_, base_cell) in rows.items():
        base = declared_base(name)
        assert base_cell == (f"`{base}`" if base else "the algorithm's YAML"), name
