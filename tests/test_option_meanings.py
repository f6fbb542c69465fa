"""One meaning per option name across every command: ``--config`` is the scene settings wherever it appears,
``--robot`` the robot file, ``--bag`` a recorded bag, ``--records`` a folder of episode records, and so on.

The parser tree of ``autoscoop`` is walked (sub-sub-commands such as ``ros2 sim`` and ``payload calibrate``
included), so a new command or option joins the check by itself. Each option name that more than one command
takes, and each name listed in :data:`MEANINGS` wherever it appears, must match its entry there: what it does
(the argparse action), what it parses (its ``type``), how its help spells its value (the metavar) and where the
value lands (``dest``); its help must name its kind of thing (:attr:`Meaning.words`). Old spellings a command
refuses (``retire_option``) are not options and are left out.
"""

from __future__ import annotations

import argparse
from collections import defaultdict
from dataclasses import dataclass

from autoscoop.cli import build_parser

ANY = "any"
"""a :class:`Meaning` field that may differ between commands without changing the meaning (the check of a bag's
format follows the middleware: a ROS 1 bag there, MCAP for ROS 2)."""


@dataclass(frozen=True)
class Meaning:
    """What one option name means wherever it appears."""

    what: str
    """the meaning, in words (for the reader of this table and of a failure)."""
    action: str = "store"
    """the argparse action: store, store_true, append."""
    type: str | None = None
    """the name of its ``type=`` (``Path``, ``AtLeast``, ``NumberIn``; ``None``: a string), or ANY."""
    metavar: str | None = None
    """how its value is written in the help (``None``: argparse's default)."""
    dest: str | None = None
    """where its value lands in the namespace (``None``: the name without dashes)."""
    words: tuple[str, ...] = ()
    """one of these must be in its help (case-insensitive): the kind of thing it names."""


MEANINGS: dict[str, Meaning] = {
    "--config": Meaning("the scene and task settings: a YAML file of config sections", type="Path",
                        metavar="FILE.yaml", words=("config",)),
    "--set": Meaning("one scene or task config key, repeatable", action="append", metavar="KEY=VALUE",
                     dest="overrides", words=("config",)),
    "--machine": Meaning("the loader this process runs: a shipped machine's name or a machine folder",
                         metavar="NAME|DIR", words=("machine",)),
    "--robot": Meaning("the robot file: topics, limits, timeouts, calibration, units", type="Path",
                       metavar="FILE.yaml", words=("robot",)),
    "--bag": Meaning("a recorded bag file (the node's topics; ROS 1 bag or MCAP)", type=ANY,
                     metavar="FILE", words=("bag",)),
    "--records": Meaning("a folder of episode records", type="Path", metavar="DIR", words=("record",)),
    "--out": Meaning("the folder the command writes into", type="Path", metavar="DIR",
                     words=("folder", "directory")),
    "--json": Meaning("a JSON file the command writes its results to", type="Path", metavar="FILE", words=("json",)),
    "--write": Meaning("a YAML file the command writes (a config, a calibration)", type="Path", metavar="FILE.yaml",
                       words=("write",)),
    "--calibration": Meaning("a payload calibration YAML to read", type="Path", metavar="FILE.yaml",
                             words=("calibration",)),
    "--policy": Meaning("the controller to run: default, heuristic or a policy file", words=("default",)),
    "--trust": Meaning("allow a policy file that unpickles when loaded", action="store_true", words=("zip",)),
    "--episodes": Meaning("a count of episodes (or scoops)", type="AtLeast", metavar="N"),
    "--seed": Meaning("a seed, 0 or more", type="AtLeast", metavar="N", words=("seed",)),
    "--workers": Meaning("worker processes sharing the work", type="AtLeast", metavar="N", words=("process",)),
    "--n-envs": Meaning("simulators stepped together", type="AtLeast", metavar="N", words=("environments",
                                                                                           "simulators")),
    "--overwrite": Meaning("replace the records an earlier run left", action="store_true", words=("record",)),
    "--resume": Meaning("continue the interrupted run (or sweep) in this folder", type="Path", metavar="RUN_DIR",
                        words=("continue",)),
    "--checkpoint-every": Meaning("episodes between checkpoints", type="AtLeast", metavar="N",
                                  words=("checkpoint",)),
    "--eval-every": Meaning("episodes between evaluations", type="AtLeast", metavar="N", words=("evaluation",)),
    "--eval-episodes": Meaning("episodes per periodic evaluation", type="AtLeast", metavar="N", words=("evaluation",)),
    "--no-progress": Meaning("no progress bar", action="store_true", words=("progress",)),
    "--check": Meaning("check the configuration and the policy, and exit", action="store_true", words=("check",)),
    "--label": Meaning("the policy's name in the summary", words=("name",)),
    "--wait-s": Meaning("how long to wait for the other side, s", type="NumberIn", words=("within",)),
    "--delay-s": Meaning("the delay of every sensor message, s (sensor.delay_s)", type="NumberIn", metavar="S",
                         words=("delay",)),
    "--joint-noise-rad": Meaning("noise on the joint angles, rad", type="NumberIn", metavar="RAD", words=("noise",)),
    "--range-noise-m": Meaning("noise on the range to the pile, m", type="NumberIn", metavar="M", words=("noise",)),
    "--speed-noise-mps": Meaning("noise on the odometry speed, m/s", type="NumberIn", metavar="M_S",
                                 words=("noise",)),
    "--torque-noise-nm": Meaning("noise on the joint torques, N*m", type="NumberIn", metavar="N_M", words=("noise",)),
    "--allow-empty": Meaning("exit 0 even when the run achieved nothing", action="store_true", words=("exit 0",)),
}
"""the one meaning of each option name more than one command takes."""

ACTIONS = {argparse._StoreAction: "store", argparse._StoreTrueAction: "store_true",
           argparse._AppendAction: "append", argparse._StoreConstAction: "store_const"}
LEFT_OUT = {"--help", "--version"}


def _parsers(parser: argparse.ArgumentParser, path: tuple[str, ...] = ()):
    """(command words, parser) of the top parser and every command and sub-command under it."""
    yield path, parser
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, child in action.choices.items():
                yield from _parsers(child, (*path, name))


def _type_name(kind: object) -> str | None:
    if kind is None:
        return None
    return getattr(kind, "__name__", None) or type(kind).__name__


def _uses() -> dict[str, list[tuple[str, argparse.Action]]]:
    """Every option name with the commands that take it and its action there (refused old spellings left out)."""
    uses: dict[str, list[tuple[str, argparse.Action]]] = defaultdict(list)
    for path, parser in _parsers(build_parser()):
        for action in parser._actions:
            if action.help == argparse.SUPPRESS or isinstance(action, argparse._SubParsersAction):
                continue
            for flag in action.option_strings:
                if flag.startswith("--") and flag not in LEFT_OUT:
                    uses[flag].append((" ".join(path) or "autoscoop", action))
    return uses


def _signature(flag: str, action: argparse.Action) -> dict[str, str | None]:
    return {"action": ACTIONS.get(type(action), type(action).__name__), "type": _type_name(action.type),
            "metavar": action.metavar, "dest": action.dest}


def _expected(flag: str, meaning: Meaning) -> dict[str, str | None]:
    return {"action": meaning.action, "type": meaning.type, "metavar": meaning.metavar,
            "dest": meaning.dest or flag.lstrip("-").replace("-", "_")}


def test_the_walk_finds_the_sub_sub_commands():
    commands = {command for uses in _uses().values() for command, _ in uses}
    assert {"eval", "train", "ros controller", "ros sim", "ros2 controller", "ros2 sim", "payload calibrate",
            "replay", "export", "bench"} <= commands


def test_every_option_that_several_commands_take_has_one_entry_in_the_table():
    shared = {flag: sorted(command for command, _ in uses) for flag, uses in _uses().items() if len(uses) > 1}
    missing = {flag: commands for flag, commands in shared.items() if flag not in MEANINGS}
    assert not missing, f"options several commands take, with no entry in MEANINGS (add one): {missing}"


def test_each_option_name_has_one_meaning_in_every_command():
    wrong = []
    for flag, uses in sorted(_uses().items()):
        meaning = MEANINGS.get(flag)
        if meaning is None:
            continue
        expected = _expected(flag, meaning)
        for command, action in uses:
            actual = _signature(flag, action)
            for field, value in expected.items():
                if value != ANY and actual[field] != value:
                    wrong.append(f"{command} {flag}: {field} is {actual[field]!r}, {meaning.what} has {value!r}")
            help_text = (action.help or "").lower()
            if meaning.words and not any(word in help_text for word in meaning.words):
                wrong.append(f"{command} {flag}: its help {action.help!r} names none of {meaning.words} "
                             f"({meaning.what})")
    assert not wrong, "options with more than one meaning:\n" + "\n".join(wrong)


def test_the_check_finds_an_option_with_a_second_meaning():
    parser = argparse.ArgumentParser()
    action = parser.add_argument("--config", type=str, metavar="ROBOT.yaml", help="the robot's file")
    actual = _signature("--config", action)
    assert actual != _expected("--config", MEANINGS["--config"])
    assert actual["metavar"] == "ROBOT.yaml" and actual["type"] == "str"
