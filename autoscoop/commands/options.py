"""The options several ``autoscoop`` commands share, each declared once here, with checked types.

A command adds the ones it takes (``add_episodes_option(parser, default=100)``), giving only what differs
(its default, the words of its help). Counts and numbers are checked by their ``type=``: a bad value is a
usage error that argparse reports naming the option (``argument --episodes: must be 1 or more; got 0``),
exit code 2, before the command starts.
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path


class AtLeast:
    """``type=`` of an integer option whose value must be ``minimum`` or more (a count, a seed)."""

    def __init__(self, minimum: int) -> None:
        self.minimum = minimum

    def __call__(self, text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be an integer, {self.minimum} or more; got {text!r}") from None
        if value < self.minimum:
            raise argparse.ArgumentTypeError(f"must be {self.minimum} or more; got {value}")
        return value


class NumberIn:
    """``type=`` of a number option whose value must be finite and in [low, high] (``None``: unbounded)."""

    def __init__(self, low: float | None = None, high: float | None = None, unit: str = "") -> None:
        self.low, self.high, self.unit = low, high, unit

    def _span(self) -> str:
        low = "-inf" if self.low is None else f"{self.low:g}"
        high = "inf" if self.high is None else f"{self.high:g}"
        return f"[{low}, {high}]" + (f" {self.unit}" if self.unit else "")

    def __call__(self, text: str) -> float:
        try:
            value = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"must be a number in {self._span()}; got {text!r}") from None
        if not math.isfinite(value) or (self.low is not None and value < self.low) \
                or (self.high is not None and value > self.high):
            raise argparse.ArgumentTypeError(f"must be in {self._span()}; got {text}")
        return value


POSITIVE = AtLeast(1)
"""a count that must be 1 or more: episodes, workers, repeats."""
NON_NEGATIVE = AtLeast(0)
"""a seed, or a count where 0 means none (or: until stopped)."""
POSITIVE_SECONDS = NumberIn(1e-3, None, "s")
"""a duration, at least a millisecond."""

POLICY_HELP = "heuristic, default (the shipped policy) or a policy file"
"""what ``--policy`` accepts in most commands (see :func:`autoscoop.agents.loading.load_policy`)."""
TRUST_HELP = "allow an SB3 .zip as the policy: loading one unpickles it, which can run code"


def add_policy_option(parser: argparse.ArgumentParser, default: str = "default", accepts: str = POLICY_HELP) -> None:
    """``--policy NAME``: the controller to run (``accepts``: what the command takes)."""
    parser.add_argument("--policy", default=default, help=f"{accepts} (default {default})")


def add_trust_option(parser: argparse.ArgumentParser, why: str = TRUST_HELP) -> None:
    """``--trust``: allow a policy file that runs pickle when loaded."""
    parser.add_argument("--trust", action="store_true", help=why)


def add_episodes_option(parser: argparse.ArgumentParser, default: int | None, what: str = "number of episodes",
                        minimum: int = 1) -> None:
    """``--episodes N``: a count of at least ``minimum`` (0 only where the command gives 0 a meaning)."""
    shown = "" if default is None else f" (default {default})"
    parser.add_argument("--episodes", type=AtLeast(minimum), default=default, metavar="N", help=f"{what}{shown}")


def add_seed_option(parser: argparse.ArgumentParser, default: int | None = 0,
                    what: str = "seed of the first episode", shown_default: int | None = None) -> None:
    """``--seed N``: 0 or more (``shown_default``: the default the help names when ``default`` is ``None``)."""
    shown = default if default is not None else shown_default
    shown = "" if shown is None else f"; default {shown}"
    parser.add_argument("--seed", type=NON_NEGATIVE, default=default, metavar="N", help=f"{what} (0 or more{shown})")


def add_workers_option(parser: argparse.ArgumentParser, default: int = 1) -> None:
    """``--workers N``: processes that share the work; the results do not depend on it."""
    parser.add_argument("--workers", type=POSITIVE, default=default, metavar="N",
                        help=f"run in this many worker processes (default {default}; the results are the same)")


def add_overwrite_option(parser: argparse.ArgumentParser, what: str) -> None:
    """``--overwrite``: replace what an earlier run left where this one writes (``what``: which files, and where)."""
    parser.add_argument("--overwrite", action="store_true", help=what)


def add_json_option(parser: argparse.ArgumentParser, what: str, required: bool = False) -> None:
    """``--json FILE``: where the command writes its results (``what``: what goes in)."""
    parser.add_argument("--json", type=Path, required=required, metavar="FILE", help=f"write {what} to this JSON file")


def add_out_option(parser: argparse.ArgumentParser, default: Path | None, what: str = "output folder",
                   required: bool = False) -> None:
    """``--out DIR``: the folder the command writes into."""
    shown = f" (default {default})" if default is not None else ""
    parser.add_argument("--out", type=Path, default=default, required=required, metavar="DIR", help=f"{what}{shown}")


def add_set_option(parser: argparse.ArgumentParser,
                   what: str = "override one config key, e.g. --set pile.angle_deg=28 (repeatable)") -> None:
    """Repeatable ``--set key=value`` (into ``args.overrides``)."""
    parser.add_argument("--set", dest="overrides", action="append", default=[], metavar="KEY=VALUE", help=what)


def add_config_args(parser: argparse.ArgumentParser) -> None:
    """``--config FILE.yaml`` and repeatable ``--set key=value``: the scene and task config."""
    parser.add_argument("--config", type=Path, metavar="FILE.yaml",
                        help="YAML file with config sections (robot, pile, reward, env)")
    add_set_option(parser)


EXIT_NOTHING_DONE = 3
"""Exit code of a run that ran to its end and achieved nothing: every update a fault, no scoop reached the
terminal point, or no message arrived (``--allow-empty`` turns it into 0). Usage and input errors exit 2."""

ROBOT_FILE_HELP = "the robot's YAML: topics, limits, timeouts, calibration, units (docs/robot.example.yaml)"
"""what ``--robot FILE`` holds wherever a command reads the robot file."""


def add_robot_option(parser: argparse.ArgumentParser, required: bool = False, what: str = ROBOT_FILE_HELP) -> None:
    """``--robot FILE``: the robot file (topics, limits, calibration), the one spelling every command uses."""
    parser.add_argument("--robot", type=Path, required=required, metavar="FILE.yaml", help=what)


def add_allow_empty_option(parser: argparse.ArgumentParser) -> None:
    """``--allow-empty``: exit 0 even when the run achieved nothing (see :data:`EXIT_NOTHING_DONE`)."""
    parser.add_argument("--allow-empty", action="store_true",
                        help=f"exit 0 even when no scoop reached the terminal point, every update was a fault or "
                             f"no message arrived (otherwise exit {EXIT_NOTHING_DONE})")


def nothing_done(command: str, why: str, allow_empty: bool) -> int:
    """Print why a run achieved nothing and return its exit code (``EXIT_NOTHING_DONE``, or 0 with ``--allow-empty``)."""
    print(f"autoscoop {command}: {why}", file=sys.stderr)
    return 0 if allow_empty else EXIT_NOTHING_DONE


class _RetiredOption(argparse.Action):
    """An old spelling that is refused with a message naming the new one (no silent alias)."""

    def __init__(self, option_strings, dest, instead: str = "", **kwargs):
        self.instead = instead
        super().__init__(option_strings, dest, nargs="?", help=argparse.SUPPRESS, **kwargs)

    def __call__(self, parser, namespace, values, option_string=None):
        parser.error(f"{option_string} is no longer an option here: {self.instead}")


def retire_option(parser: argparse.ArgumentParser, old: str, instead: str) -> None:
    """Refuse ``old`` on ``parser`` with a usage error (exit 2) that says ``instead`` (the new spelling)."""
    parser.add_argument(old, action=_RetiredOption, instead=instead, dest=f"retired_{old.strip('-').replace('-', '_')}",
                        default=None)
