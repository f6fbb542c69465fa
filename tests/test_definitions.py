"""Definitions in one place: every generated report prints the lines of ``autoscoop.envs.definitions``, and
docs/definitions.md carries them as they are; no history (issue numbers, dates) in the package."""

import re
from pathlib import Path

import pytest

from autoscoop.core.config import ScoopConfig
from autoscoop.envs.definitions import DEFINITIONS, definition_lines
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.evaluation.evaluate import format_table, summarize
from autoscoop.evaluation.stress import StressRow, select_cases
from autoscoop.report.stress import STRESS_TERMS, write_stress_report

ROOT = Path(__file__).resolve().parents[1]
HISTORY = re.compile(r"\bissue\s*#?\d|\b20\d\d-\d\d-\d\d\b|shipped before|shipped actor of", re.IGNORECASE)
"""what a user's text must not carry: issue numbers, dates, what was shipped before."""


def test_docs_definitions_carries_every_generated_line():
    text = (ROOT / "docs" / "definitions.md").read_text()
    for line in definition_lines():
        assert line in text


def test_success_is_defined_as_reached_loaded_with_the_configs_threshold():
    config = ScoopConfig()
    assert DEFINITIONS["success"].startswith("reached loaded")
    assert f"`scoop.min_fill` ({config.scoop.min_fill:g})" in DEFINITIONS["success"]
    assert f"({config.scoop.overload_fill:g})" in DEFINITIONS["overload"]
    with pytest.raises(KeyError):
        definition_lines(["speed"])


def _outcome(seed: int, success: bool) -> EpisodeOutcome:
    return EpisodeOutcome(seed=seed, fill_factor=0.7, mass_kg=4.9, particles=16, success=success,
                          cycle_time_s=5.0 if success else None, spilled=1, physics_error=False, steps=20,
                          episode_return=10.0, reached=True, volumetric_fill=0.64)


def test_the_eval_table_defines_its_terms_in_plain_text():
    summary = summarize([_outcome(0, True), _outcome(1, False)], ScoopConfig(), "heuristic")
    table = format_table(summary)
    for line in definition_lines(markdown=False):
        assert line in table
    assert "÷" not in table and "`" not in table
    assert "success rate" in format_table(summary, definitions=False)
    assert "success:" not in format_table(summary, definitions=False)


def test_stress_md_defines_its_terms_and_carries_no_history(tmp_path):
    case = select_cases(["nominal"])[0]
    row = StressRow(case, {"fill_factor_mean": 0.8, "fill_factor_std": 0.05, "volumetric_fill_mean": 0.7,
                           "volumetric_fill_std": 0.05, "success_rate": 0.98, "reached_rate": 1.0,
                           "cycle_time_mean": 4.8, "cycle_time_std": 0.3, "overload_rate": 0.0})
    text = write_stress_report([row], tmp_path).markdown.read_text()
    for line in definition_lines(STRESS_TERMS):
        assert line in text
    assert not HISTORY.search(text)


def test_the_package_carries_no_issue_numbers_dates_or_shipped_before():
    found = []
    for path in sorted((ROOT / "autoscoop").rglob("*")):
        if path.suffix not in (".py", ".yaml", ".md", ".xml", ".json", ".txt"):
            continue
        for number, line in enumerate(path.read_text(errors="replace").splitlines(), 1):
            if HISTORY.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)
