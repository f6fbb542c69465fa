"""A run that achieved nothing fails: ``eval`` with no successful episode and ``shift`` with nothing delivered exit
``EXIT_NOTHING_DONE`` after saying why, unless ``--allow-empty``; what they write is written either way."""

import json

import pytest

from autoscoop.cli import main
from autoscoop.commands.options import EXIT_NOTHING_DONE

TOO_SHORT = ["--set", "env.max_episode_s=0.5", "--set", "pile.variants=1"]
"""two control periods: no scoop reaches the terminal point, and the bucket stays empty."""
SMALL_SHIFT = ["--set", "shift.pile_particles=72", "--set", "shift.phase_limit_s=1"]


@pytest.mark.parametrize("allow_empty", [False, True])
def test_eval_with_no_successful_episode_exits_nothing_done(tmp_path, capsys, allow_empty):
    out = tmp_path / "eval.json"
    code = main(["eval", "--episodes", "2", *TOO_SHORT, "--json", str(out),
                 *(["--allow-empty"] if allow_empty else [])])
    assert code == (0 if allow_empty else EXIT_NOTHING_DONE)
    assert "autoscoop eval: no episode succeeded: none of 2 reached the terminal point" in capsys.readouterr().err
    assert json.loads(out.read_text())["success_rate"] == 0.0


def test_eval_with_a_successful_episode_exits_0(capsys):
    assert main(["eval", "--episodes", "1", "--set", "pile.variants=1"]) == 0
    assert "no episode succeeded" not in capsys.readouterr().err


@pytest.mark.parametrize("allow_empty", [False, True])
def test_a_shift_that_delivered_nothing_exits_nothing_done(tmp_path, capsys, allow_empty):
    out = tmp_path / "shift.json"
    code = main(["shift", "--policy", "heuristic", "--cycles", "1", *SMALL_SHIFT, *TOO_SHORT, "--json", str(out),
                 *(["--allow-empty"] if allow_empty else [])])
    assert code == (0 if allow_empty else EXIT_NOTHING_DONE)
    assert "autoscoop shift: no scoop was delivered: heuristic put nothing into the hopper" in capsys.readouterr().err
    assert json.loads(out.read_text())["shifts"][0]["totals"]["delivered_kg"] == 0.0


def test_the_help_of_eval_and_shift_names_the_exit_code(capsys):
    for command in ("eval", "shift"):
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = " ".join(capsys.readouterr().out.split())
        assert f"Exit code {EXIT_NOTHING_DONE} when" in text and "--allow-empty" in text
