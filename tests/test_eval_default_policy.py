"""``eval`` runs the shipped policy unless told otherwise, as every other command that takes ``--policy`` does."""

import argparse
import json

from autoscoop.cli import build_parser, main


def _subparsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _subparsers(sub, (*path, name))


def test_every_command_that_takes_a_policy_defaults_to_the_shipped_one():
    defaults = {" ".join(path): action.default for path, parser in _subparsers(build_parser())
                for action in parser._actions if "--policy" in action.option_strings}
    assert "eval" in defaults and "stress" in defaults
    assert {command: default for command, default in defaults.items() if default != "default"} == {}


def test_eval_without_a_policy_gives_the_figures_of_the_shipped_policy(tmp_path):
    plain, named = tmp_path / "plain.json", tmp_path / "named.json"
    assert main(["eval", "--episodes", "1", "--set", "pile.variants=1", "--json", str(plain)]) == 0
    assert main(["eval", "--policy", "default", "--episodes", "1", "--set", "pile.variants=1", "--json", str(named)]) == 0
    plain_summary, named_summary = json.loads(plain.read_text()), json.loads(named.read_text())
    assert plain_summary["policy"] == "default"
    assert plain_summary["fill_factor_mean"] == named_summary["fill_factor_mean"]
    assert plain_summary["episodes_detail"] == named_summary["episodes_detail"]
