"""The README's recipe table lists exactly the recipes of the one registry (``autoscoop/training/recipes/``), the
shipped one marked as the default, so a recipe added or removed shows up there too (docs/training.md's table:
tests/test_recipes.py)."""

from __future__ import annotations

import re
from pathlib import Path

from autoscoop.training.recipes import RECIPES, SHIPPED_RECIPE

ROOT = Path(__file__).resolve().parents[1]
ROW = re.compile(r"^\| `(?P<name>[a-z_]+)`(?P<mark>[^|]*)\|")


def recipe_rows(markdown: str, heading: str) -> dict[str, str]:
    """The first table under ``heading``: recipe name -> the rest of its first cell (e.g. "(default)")."""
    section = markdown.split(heading, 1)[1]
    rows, in_table = {}, False
    for line in section.splitlines():
        match = ROW.match(line)
        if match:
            rows[match["name"]] = match["mark"].strip()
            in_table = True
        elif in_table and not line.startswith("|"):
            break
    return rows


def test_the_row_reader_reads_a_table():
    text = "## Recipes\n| recipe | base |\n|---|---|\n| `a` (default) | `b` |\n| `b` | the YAML |\n\n| `c` | x |\n"
    assert recipe_rows(text, "## Recipes") == {"a": "(default)", "b": ""}


def test_the_readme_lists_the_registry_and_marks_the_shipped_recipe():
    rows = recipe_rows((ROOT / "README.md").read_text(encoding="utf-8"), "## Train")
    assert sorted(rows) == sorted(RECIPES)
    assert [name for name, mark in rows.items() if "default" in mark] == [SHIPPED_RECIPE]

