"""The command lines of the README and docs/*.md, read from their ```bash blocks, and how the test suite
scales each one down (tests/test_doc_commands_*.py run them; docs/layout.md#commands-in-these-docs-are-tested
states the same rules for a reader).

A command is one line of a ``bash`` fence (a trailing ``\\`` joins the next line); a line that is only a
comment is none. What follows an unquoted ``#`` is the command's comment: the test reads an expected exit
code from it ("exits 3"), otherwise the command must exit 0.
"""

from __future__ import annotations

import re
import shlex
from dataclasses import dataclass, field
from pathlib import Path

from markdown_it import MarkdownIt

ROOT = Path(__file__).resolve().parents[1]
PAGES = ["README.md", *sorted(p.relative_to(ROOT).as_posix() for p in (ROOT / "docs").glob("*.md"))]
"""The pages whose commands run: the README and docs/*.md (docs/experiments/ records what was tried)."""

EPISODES = 1
"""``--episodes N`` of every command that takes it, unless :data:`EPISODES_BY_COMMAND` says otherwise."""
EPISODES_BY_COMMAND = {("train",): 3, ("adapt",): 2, ("ros", "sim"): 3, ("ros2", "sim"): 3}
"""train: 3 episodes (no evaluation, no selection); adapt: 2 (an evaluation after each); the ROS simulators:
3 scoops, as the README's figures over ROS are judged (fill >= 0.65, success >= 0.9)."""
SCALED = {"--cycles": "1", "--shifts": "1", "--repeats": "1", "--steps": "200", "--check-states": "1000",
          "--demo-episodes": "2",
          "--trials": "3", "--estop-trials": "2", "--seeds": "0", "--worlds": "heavy", "--workers": "1"}
"""Other options set to a small value where a command line gives them (``--seeds`` takes one seed for all;
``--workers 1``: a few episodes do not pay for starting worker processes, and the results do not depend on it,
which tests/test_stress.py checks)."""
MANY_VALUES = ("--seeds",)
"""Options that take several words (``--seeds 0 1 2 3 4``): scaling replaces them all."""
ADAPT_SCALED = {"--eval-every": "1", "--eval-episodes": "1", "--candidates": "1", "--validation-episodes": "1",
                "--workers": "1"}
"""``adapt``: 2 episodes, an evaluation of one episode after each, one candidate validated beside the starting
policy at one episode a world, in this process (its default two workers do not pay for one episode a case)."""
RESUME_SETTINGS = {("adapt",): {"--candidates": "1", "--validation-episodes": "1", "--workers": "1"}}
"""What a resume takes beside the run's own settings: ``adapt --resume`` validates as its command line says."""
SETTINGS = {("adapt",): ADAPT_SCALED, ("benchmarks/shift_speed.py",): {"--cycles": "2"},
            ("benchmarks/adapt_worlds.py",): {"--episodes": "1", "--workers": "1", "--adapt-args": " ".join(
                f"{option} {value}" for option, value in {"--episodes": "2", **ADAPT_SCALED}.items())}}
"""Options set (replaced or added) on one command or script: keyed as :func:`command_key` names it."""
ADDED = {("adapt",): ["--episodes"], ("eval",): ["--episodes"], ("compare",): ["--episodes"], ("stress",): ["--episodes"],
         ("train",): ["--episodes", "--demo-episodes"], ("ros", "sim"): ["--episodes"], ("ros2", "sim"): ["--episodes"],
         ("shift",): ["--cycles", "--shifts"], ("bench",): ["--repeats", "--episodes"],
         ("bench", "payload"): ["--episodes"], ("export",): ["--check-states"]}
"""Options added (at the scaled value) where a command leaves them at their default; ``bench --n-envs``
takes ``--steps`` instead of ``--episodes``. ``train --resume`` and ``adapt --resume`` take none: a resume keeps the run's settings."""
ALLOW_EMPTY = {("eval",), ("shift",), ("replay",), ("ros", "sim"), ("ros2", "sim")}
"""The commands that exit 3 when nothing was achieved: they get ``--allow-empty`` where their ``--policy`` is a
run the test trained (``runs/...``), whose 3 episodes scoop nothing; with any other policy they must succeed."""
TRAINED_RUNS = ("runs/",)
"""Where a page's trained runs live: a ``--policy`` under one of these is such a run."""
BENCH_PAYLOAD_EPISODES = "0"
"""``bench payload``: the static holds only (its moving scoops are the eval's)."""
OUTPUT_OPTIONS = ("--json", "--out", "--records", "--onnx", "--bag", "--write", "--video")
"""Options whose value the command writes: a relative one lands in the page's temporary folder, and must
exist (and, a folder, not be empty) after the command."""
PLACEHOLDERS = ("RUN", "TIME", "TRIAL_ID")
"""Words of a path that stand for what an earlier command made: matched as ``*`` in the temporary folder,
the newest match taken."""

SKIPPED = [
    (("make",), "installs the venv and runs the demo or the whole suite, of which this test is a part"),
    (("pip", "install"), "installs packages: `make test` has installed every extra"),
    (("apt-get",), "installs Debian packages: `make test` does (tools/system_deps.sh, as root)"),
    (("rosmaster",), "the test starts a private rosmaster on a free port for the ROS 1 commands (RosMaster)"),
    (("tensorboard",), "a web server that runs until stopped"),
    (("ray",), "starts or stops a Ray cluster across machines"),
    (("autoscoop", "teleop"), "needs a display and a person at the keys (tests/test_teleop.py drives it headless)"),
    (("autoscoop", "sweep"), "the example space needs 4 trials of more than 100 episodes each (its ASHA grace "
                             "period): minutes on 2 cores; tests/test_sweep.py runs sweeps and --resume on a small space"),
    (("benchmarks/physics_variants.py", "--instructions"), "runs under valgrind's callgrind: 40 s for one episode "
                                                           "on the project's 2-core host"),
]
"""(words the command line holds, why it is not run). Kept short: everything else runs."""


@dataclass(frozen=True)
class DocCommand:
    """One command line of a page.

    Attributes:
        page: the page, relative to the repository root (POSIX).
        line: 1-based line of the command in the page.
        text: the command as written, continuation lines joined, without its comment.
        comment: what follows its unquoted ``#`` ("" if none).
    """

    page: str
    line: int
    text: str
    comment: str = ""
    argv: tuple[str, ...] = field(default=(), compare=False)

    @property
    def id(self) -> str:
        """A short, unique test id: ``page:line:command subcommand``."""
        words = command_words(self.argv)
        if not words:
            words = self.argv[1:2] if program(self.argv) == "python" else self.argv[:1]
        return f"{self.page}:{self.line}:{' '.join(words)}"


def split_comment(line: str) -> tuple[str, str]:
    """``line`` split at its first ``#`` outside quotes and not inside a word: (command, comment)."""
    quote = None
    for index, char in enumerate(line):
        if quote:
            quote = None if char == quote else quote
        elif char in "'\"":
            quote = char
        elif char == "#" and (index == 0 or line[index - 1].isspace()):
            return line[:index].rstrip(), line[index + 1:].strip()
    return line.rstrip(), ""


def extract(markdown: str, page: str) -> list[DocCommand]:
    """The command lines of the ``bash`` fences of ``markdown``, in order."""
    commands = []
    for token in MarkdownIt("commonmark").parse(markdown):
        if token.type != "fence" or token.info.split()[:1] != ["bash"] or token.map is None:
            continue
        pending, start = "", 0
        for offset, raw in enumerate(token.content.splitlines()):
            line_no = token.map[0] + 2 + offset
            if not pending:
                start = line_no
            if raw.rstrip().endswith("\\"):
                pending += raw.rstrip()[:-1] + " "
                continue
            text, comment = split_comment(pending + raw)
            pending = ""
            if text.strip():
                commands.append(DocCommand(page, start, " ".join(text.split()), comment, tokens(text)))
    return commands


OPERATORS = ("&&", "||", ";", "&", "|")
"""The shell's list and pipe operators: a line holding one runs in ``bash`` as written, each of its commands
scaled."""
PLAIN_WORD = re.compile(r"[\w@%+=:,./$!-]+")


def tokens(text: str) -> tuple[str, ...]:
    """A command line's words as the shell splits them, with each operator of :data:`OPERATORS` a word."""
    lexer = shlex.shlex(text, posix=True, punctuation_chars=";&|")
    lexer.whitespace_split = True
    return tuple(lexer)


def segments(argv: tuple[str, ...] | list[str]) -> list[tuple[list[str], str]]:
    """The commands of a line, each with the operator that follows it ("" for the last)."""
    found, current = [], []
    for word in argv:
        if word in OPERATORS:
            found.append((current, word))
            current = []
        else:
            current.append(word)
    if current:
        found.append((current, ""))
    return found


def shell_line(parts: list[tuple[list[str], str]]) -> str:
    """Commands and operators joined back into one ``bash`` line (a word quoted only where it needs it, so
    that ``$!`` stays the shell's)."""
    words = []
    for argv, operator in parts:
        words += [word if PLAIN_WORD.fullmatch(word) else shlex.quote(word) for word in argv]
        words += [operator] if operator else []
    return " ".join(words)


def page_commands(page: str) -> list[DocCommand]:
    """The command lines of one page of :data:`PAGES`."""
    return extract((ROOT / page).read_text(encoding="utf-8"), page)


def program(argv: tuple[str, ...] | list[str]) -> str:
    """What runs: ``autoscoop``, ``python``, or the first word as written (``make``, ``ray`` ...)."""
    name = Path(argv[0]).name
    return {"autoscoop": "autoscoop", "python": "python", "python3": "python", "pip": "pip"}.get(name, argv[0])


def command_key(argv: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """What :data:`SETTINGS` and :data:`ADDED` are keyed by: an autoscoop command's words, a script's path."""
    if argv and program(argv) == "python" and len(argv) > 1:
        return (argv[1],)
    return command_words(argv)


def command_words(argv: tuple[str, ...] | list[str]) -> tuple[str, ...]:
    """An autoscoop command line's command and sub-command words, e.g. ``("ros2", "sim")``, ``("eval",)``."""
    if not argv or program(argv) != "autoscoop":
        return ()
    words = []
    for word in argv[1:3]:
        if word.startswith("-") or "/" in word or "." in word:
            break
        words.append(word)
    if words and words[0] not in ("ros", "ros2", "bench", "payload"):
        words = words[:1]
    return tuple(words)


def skip_reason(argv: tuple[str, ...] | list[str]) -> str | None:
    """Why a command line is not run (:data:`SKIPPED`), or None."""
    words = [program(argv), *argv[1:]]
    for needles, reason in SKIPPED:
        if all(needle in words for needle in needles):
            return reason
    return None


def skip_reasons(commands: list[DocCommand]) -> dict[int, str]:
    """Why each command of one page that is not run is not (by line): :data:`SKIPPED`, and a command that
    reads what a skipped one of the page writes (``eval --policy sweeps/s1/best.safetensors``), unless the
    repository holds it (``benchmarks/results/...``: a clean clone reads the committed file)."""
    reasons, unmade = {}, []
    for command in commands:
        reason = skip_reason(command.argv)
        read = [path for path, _ in unmade if any(word.startswith(path) for word in command.argv[1:])]
        if reason is None and read:
            reason = f"reads {read[0]}, which line {dict(unmade)[read[0]]} writes and is not run"
        if reason is not None:
            reasons[command.line] = reason
            unmade += [(path, command.line) for path in outputs(command.argv) if not (ROOT / path).exists()]
    return reasons


def is_node(argv) -> bool:
    """A controller node: it runs until stopped, so the test runs it beside a simulator and then stops it
    (``--check`` checks its files and exits, as any command)."""
    return command_words(argv) in (("ros", "controller"), ("ros2", "controller")) and "--check" not in argv


def is_sim(argv) -> bool:
    """A simulator node: it ends after its episodes."""
    return command_words(argv) in (("ros", "sim"), ("ros2", "sim"))


def option_value(argv, option: str) -> str | None:
    """The value of ``option`` in ``argv`` (its last), or None."""
    value = None
    for index, word in enumerate(argv[:-1]):
        if word == option:
            value = argv[index + 1]
    return value


def set_option(argv: list[str], option: str, value: str) -> list[str]:
    """``argv`` with ``option`` set to ``value``: replaced where given (all its words, for one of
    :data:`MANY_VALUES`), else added before any ``from:=to`` remap."""
    if option in argv:
        argv = list(argv)
        at = argv.index(option) + 1
        end = at + 1
        while option in MANY_VALUES and end < len(argv) and not argv[end].startswith("-"):
            end += 1
        argv[at:end] = [value]
        return argv
    remaps = [index for index, word in enumerate(argv) if ":=" in word]
    at = remaps[0] if remaps else len(argv)
    return [*argv[:at], option, value, *argv[at:]]


def scaled(argv: tuple[str, ...] | list[str]) -> list[str]:
    """A command line scaled down by the documented rules (module docstring, docs/layout.md)."""
    argv, words = list(argv), command_words(argv)
    if words in (("train",), ("adapt",)) and "--resume" in argv:
        for option, value in RESUME_SETTINGS.get(words, {}).items():
            argv = set_option(argv, option, value)
        return argv
    episodes = str(EPISODES_BY_COMMAND.get(words, EPISODES))
    if words == ("bench", "payload"):
        episodes = BENCH_PAYLOAD_EPISODES
    if "--episodes" in argv:
        argv = set_option(argv, "--episodes", episodes)
    for option, value in SCALED.items():
        if option in argv:
            argv = set_option(argv, option, value)
    for option in ADDED.get(words, []):
        if option == "--episodes" and words == ("bench",) and "--n-envs" in argv:
            option = "--steps"
        if option not in argv:
            argv = set_option(argv, option, episodes if option == "--episodes" else SCALED[option])
    for option, value in SETTINGS.get(command_key(argv), {}).items():
        argv = set_option(argv, option, value)
    policy = option_value(argv, "--policy") or ""
    if words in ALLOW_EMPTY and policy.startswith(TRAINED_RUNS) and "--allow-empty" not in argv:
        argv = [*argv, "--allow-empty"]
    return argv


def expected_exit(comment: str) -> int:
    """The exit code a command's comment names ("exits 3"), else 0."""
    found = re.search(r"\bexits? (?:with )?(?:code )?(\d+)\b", comment)
    return int(found.group(1)) if found else 0


def outputs(argv) -> list[str]:
    """The paths a command line says it writes (values of :data:`OUTPUT_OPTIONS`)."""
    return [argv[index + 1] for index, word in enumerate(argv[:-1]) if word in OUTPUT_OPTIONS]


def has_placeholder(word: str) -> bool:
    """Whether a word holds a :data:`PLACEHOLDERS` word."""
    return any(re.search(rf"(?<![A-Za-z]){name}(?![A-Za-z])", word) for name in PLACEHOLDERS)


def placeholder_glob(word: str) -> str:
    """``runs/ddpg-s12-TIME`` -> ``runs/ddpg-s12-*``."""
    for name in PLACEHOLDERS:
        word = re.sub(rf"(?<![A-Za-z]){name}(?![A-Za-z])", "*", word)
    return word
