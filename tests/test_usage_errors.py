"""Every usage error of every command exits 2 with a one-line message naming what is wrong, and no traceback.

The count and number options are found by walking the parser, so a new command or option joins the table by
itself; a test makes sure none of them escapes it with a bare ``int`` or ``float`` type.
"""

import argparse

import pytest

from autoscoop.cli import build_parser, main
from autoscoop.commands.options import AtLeast, NumberIn


def _commands(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(argv prefix, parser) of every command and sub-command that runs something."""
    children = [action for action in parser._actions if isinstance(action, argparse._SubParsersAction)]
    for action in children:
        for name, child in action.choices.items():
            yield from _commands(child, (*path, name))
    if not children:
        yield path, parser


COMMANDS = list(_commands(build_parser()))


def _checked_options():
    """(argv prefix, flag, a value its type refuses) of every option with a checked number type."""
    for path, parser in COMMANDS:
        for action in parser._actions:
            if not action.option_strings:
                continue
            flag = action.option_strings[0]
            if isinstance(action.type, AtLeast):
                yield pytest.param(path, flag, str(action.type.minimum - 1), id=" ".join([*path, flag]))
            elif isinstance(action.type, NumberIn):
                low, high = action.type.low, action.type.high
                bad = str(low - 1) if low is not None else str(high + 1) if high is not None else "nan"
                yield pytest.param(path, flag, bad, id=" ".join([*path, flag]))


def _run(argv: list[str], capsys) -> tuple[int, str]:
    """Exit code and stderr of ``autoscoop ARGV``, in this process (argparse's usage errors raise SystemExit)."""
    try:
        code = main(argv)
    except SystemExit as exit_:
        code = exit_.code
    return code, capsys.readouterr().err


def _assert_usage_error(argv: list[str], named: str, capsys) -> None:
    code, err = _run(argv, capsys)
    assert code == 2, f"autoscoop {' '.join(argv)}: exit {code}, stderr {err!r}"
    assert "Traceback" not in err
    last = err.strip().splitlines()[-1]
    assert last.startswith(f"autoscoop {argv[0]}") and "error:" in last and named in last, err


def test_the_table_covers_every_command():
    names = {" ".join(path) for path, _ in COMMANDS}
    assert {"eval", "stress", "compare", "demo", "bench", "train", "sweep", "teleop", "export", "ros sim",
            "ros controller", "payload calibrate", "report", "config"} <= names


def test_every_integer_and_number_option_has_a_checked_type():
    loose = [f"{' '.join(path)} {action.option_strings[0]}" for path, parser in COMMANDS for action in parser._actions
             if action.option_strings and action.type in (int, float)]
    assert not loose, f"options whose value nothing checks: {loose} (use autoscoop.commands.options.AtLeast/NumberIn)"


@pytest.mark.parametrize(("path", "flag", "bad"), list(_checked_options()))
def test_a_value_out_of_range_is_a_usage_error_naming_the_option(path, flag, bad, capsys):
    _assert_usage_error([*path, flag, bad], f"argument {flag}", capsys)


@pytest.mark.parametrize(("path", "flag"), [pytest.param(path, flag, id=" ".join([*path, flag]))
                                            for path, parser in COMMANDS for action in parser._actions
                                            if isinstance(action.type, AtLeast)
                                            for flag in action.option_strings[:1]])
def test_a_count_that_is_not_a_number_is_a_usage_error(path, flag, capsys):
    _assert_usage_error([*path, flag, "many"], f"argument {flag}", capsys)


def test_every_command_with_episodes_refuses_zero_or_a_negative_count(capsys):
    with_episodes = [path for path, parser in COMMANDS if "--episodes" in parser._option_string_actions]
    assert len(with_episodes) >= 8
    for path in with_episodes:
        minimum = parser_of(path)._option_string_actions["--episodes"].type.minimum
        _assert_usage_error([*path, "--episodes", str(minimum - 1)], "argument --episodes", capsys)


def parser_of(path: tuple[str, ...]) -> argparse.ArgumentParser:
    return dict(COMMANDS)[path]


@pytest.mark.parametrize(("argv", "named"), [
    (["bench", "--episodes", "0"], "--episodes"),  # 0 moving scoops is a payload bench; no speed without episodes
    (["eval", "--policy", "nonsense", "--episodes", "1"], "nonsense"),
    (["stress", "--policy", "nonsense", "--json", "{tmp}/s.json", "--out", "{tmp}/s"], "nonsense"),
    (["compare", "--policies", "heuristic", "nonsense", "--out", "{tmp}/c"], "nonsense"),
    (["demo", "--policy", "nonsense", "--out", "{tmp}/d"], "nonsense"),
    (["export", "--policy", "nonsense", "--onnx", "{tmp}/x.onnx"], "nonsense"),
    (["ros", "controller", "--policy", "nonsense", "--check"], "nonsense"),
    (["stress", "--cases", "nonsense", "--json", "{tmp}/s.json", "--out", "{tmp}/s"], "nonsense"),
    (["export", "--onnx", "{tmp}/x.txt"], "argument --onnx"),
    (["ros", "sim", "not_a_remap"], "not_a_remap"),
    (["eval", "--set", "pile.angle_deg"], "key=value"),
    (["payload"], "ACTION"),
    (["ros"], "NODE"),
])
def test_a_bad_choice_is_refused_before_any_work(argv, named, tmp_path, capsys):
    _assert_usage_error([arg.replace("{tmp}", str(tmp_path)) for arg in argv], named, capsys)
    assert not any(tmp_path.iterdir()), "a refused command wrote something"


REQUIRED = {"stress": ["--json", "{tmp}/s.json", "--out", "{tmp}/s"], "export": ["--onnx", "{tmp}/x.onnx"],
            "train": ["--out", "{tmp}/run"], "compare": ["--out", "{tmp}/c"], "demo": ["--out", "{tmp}/d"],
            "teleop": ["--out", "{tmp}/m"], "replay": ["{tmp}/log.mcap", "--out", "{tmp}/r"]}
"""what a command needs besides ``--set`` to get as far as reading its config, all under the test's folder."""


@pytest.mark.parametrize("path", [pytest.param(path, id=" ".join(path)) for path, parser in COMMANDS
                                  if "--set" in parser._option_string_actions])
def test_every_command_refuses_an_unknown_config_key(path, tmp_path, capsys):
    extra = [arg.replace("{tmp}", str(tmp_path)) for arg in REQUIRED.get(" ".join(path), [])]
    _assert_usage_error([*path, *extra, "--set", "pile.angel_deg=30"], "pile.angel_deg", capsys)
    assert not any(tmp_path.iterdir()), "a refused command wrote something"
