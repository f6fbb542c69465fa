"""How a command line of the README and docs/*.md is run, scaled down, and checked against what its text says.

The test files ``tests/test_doc_commands_*.py`` each run the pages of one group of :data:`PAGE_GROUPS` (so
``make test``'s workers share them); tests/test_doc_commands.py tests the rules; tests/conftest.py loads this
module's fixtures. The lines are read from the pages' ```bash blocks (tests/doc_commands.py), so a page that
changes is tested as it now reads. Each page runs in a temporary folder of its own, in the page's order, as a reader
on a clean clone would: a later line reads what an earlier one made (``runs/RUN``, ``out/robot.mcap``).
The rules (fewer episodes, outputs in the temporary folder, the few lines not run and why) are in
tests/doc_commands.py and docs/layout.md#commands-in-these-docs-are-tested.
"""

from __future__ import annotations

import contextlib
import json
import os
import random
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import forked
import pytest
from doc_commands import (
    OUTPUT_OPTIONS,
    PAGES,
    ROOT,
    DocCommand,
    command_words,
    expected_exit,
    has_placeholder,
    is_node,
    is_sim,
    option_value,
    outputs,
    page_commands,
    placeholder_glob,
    program,
    scaled,
    segments,
    set_option,
    shell_line,
    skip_reasons,
)

COMMANDS = [command for page in PAGES for command in page_commands(page)]
REASONS = {page: skip_reasons([c for c in COMMANDS if c.page == page]) for page in PAGES}
TIMEOUT_S = 240
PAGE_GROUPS = {"readme": ("README.md",), "robot": ("docs/robot.md", "docs/bringup.md"),
               "training": ("docs/training.md", "docs/adapt.md", "docs/sweep.md", "docs/performance.md")}
"""The pages each test file runs, about equal in time; every other page runs in the group ``other``."""
OTHER_GROUP = "other"
DOMAIN_BLOCK = 8
"""Each group's ROS 2 commands use a DDS domain of their own, drawn from a block of 8 from domain 200 on (loopback
only): no other group, and no other test run that draws another, hears them."""


def group_pages(group: str) -> list[str]:
    """The pages of ``group`` (``other``: every page no group names)."""
    named = {page for pages in PAGE_GROUPS.values() for page in pages}
    return list(PAGE_GROUPS[group]) if group != OTHER_GROUP else [page for page in PAGES if page not in named]


def group_commands(group: str) -> list[DocCommand]:
    return [command for command in COMMANDS if command.page in group_pages(group)]


def group_of(page: str) -> str:
    return next((group for group, pages in PAGE_GROUPS.items() if page in pages), OTHER_GROUP)


def ros2_domain(page: str) -> int:
    groups = [*PAGE_GROUPS, OTHER_GROUP]
    return 200 + DOMAIN_BLOCK * groups.index(group_of(page)) + DOMAIN_DRAW


DOMAIN_DRAW = random.Random().randrange(DOMAIN_BLOCK)
ROS_FIGURES = {"fill_factor_mean": 0.65, "success_rate": 0.9}
"""What the README says of the shipped policy over ROS (fill 0.739-0.761, success 1.00), with room for 3 scoops."""


class Page:
    """One page's temporary folder and what its commands left: the runs made (and by which command line),
    the controller node running in the background for the simulator that follows it."""

    def __init__(self, folder: Path, logs: Path) -> None:
        self.folder, self.logs, self.runs = folder, logs, 0
        self.made_runs: dict[str, list[str]] = {}
        self.node: tuple[subprocess.Popen, list[str], DocCommand, Path] | None = None

    def start_node(self, argv: list[str], command: DocCommand, env: dict[str, str]) -> None:
        """Start a controller node in the background, its output to a file (a pipe would be held open by
        the simulator's worker processes of a node that had to be killed)."""
        log = self.logs / f"node-{command.line}.log"
        process = start([*launcher("autoscoop"), *argv[1:]], self.folder, env, log, log)
        self.node = (process, argv, command, log)

    def stop_node(self) -> tuple[int, str, list[str]]:
        process, argv, _, log = self.node
        self.node = None
        process.send_signal(signal.SIGTERM)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait()
        return process.returncode, log.read_text(errors="replace"), argv


def start(cmd: list[str], cwd: Path, env: dict[str, str], stdout: Path, stderr: Path):
    """Start ``cmd`` in a session of its own, its output appended to files: ``autoscoop`` lines in a child of the
    fork server (the same process a shell would start, without the seconds of imports), others with Popen."""
    autoscoop = launcher("autoscoop")
    if cmd[:len(autoscoop)] == autoscoop:
        stdout.touch()
        stderr.touch()
        return forked.server().spawn(cmd[len(autoscoop):], cwd, env, stdout, stderr)
    with stdout.open("ab") as out, stderr.open("ab") as err:
        return subprocess.Popen(cmd, cwd=cwd, env=env, stdout=out, stderr=subprocess.STDOUT if stderr == stdout else err,
                                start_new_session=True)


@pytest.fixture(scope="module")
def pages(tmp_path_factory):
    made = {}
    for page in PAGES:
        name = page.replace("/", "_").replace(".", "_")
        made[page] = Page(tmp_path_factory.mktemp(name), tmp_path_factory.mktemp(f"{name}-logs"))
    yield made
    for page in made.values():
        if page.node:
            page.stop_node()


@pytest.fixture(scope="module")
def spare_run(tmp_path_factory):
    """A tiny finished run, for a ``runs/RUN`` that a page reads before any of its commands trains one."""
    folder = tmp_path_factory.mktemp("spare") / "runs" / "paper-spare"
    run = forked.run([*launcher("autoscoop"), "train", "--recipe", "paper", "--episodes", "3", "--no-progress",
                      "--out", str(folder)], capture_output=True, text=True, timeout=TIMEOUT_S, env=base_env())
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-2000:]
    return folder


@pytest.fixture(scope="module")
def ros1_env():
    from autoscoop.deploy.ros1 import INSTALL_HINT, ros_available

    if not ros_available():
        pytest.skip(f"ROS 1 is not available here: {INSTALL_HINT}")
    from autoscoop.deploy.ros1.master import RosMaster

    with RosMaster() as master:
        yield dict(master.env, PYTHONUNBUFFERED="1")


def base_env() -> dict[str, str]:
    return dict(os.environ, PYTHONUNBUFFERED="1", MPLBACKEND="Agg")


def ros2_env(page: str) -> dict[str, str]:
    pytest.importorskip("cyclonedds", reason="the ros2 extra is not installed")
    from autoscoop.deploy.ros2.graph import LOOPBACK_CONFIG

    return dict(base_env(), CYCLONEDDS_URI=LOOPBACK_CONFIG, ROS_DOMAIN_ID=str(ros2_domain(page)))


def launcher(name: str) -> list[str]:
    """How a program of the docs runs here: the venv's ``autoscoop`` as ``python -m autoscoop.cli``."""
    return {"autoscoop": [sys.executable, "-m", "autoscoop.cli"], "python": [sys.executable]}[name]


def resolve(argv: list[str], page: Page, spare: callable) -> list[str]:
    """Placeholders filled from what the page's earlier commands made; a path the repository holds (and the
    page's folder does not, and the command does not write) read from the repository."""
    resolved = []
    for index, word in enumerate(argv):
        before = argv[index - 1] if index else ""
        if has_placeholder(word):
            pattern = placeholder_glob(word)
            found = sorted(page.folder.glob(pattern), key=lambda p: p.stat().st_mtime)
            if not found and pattern == "runs/*":
                target = page.folder / "runs" / spare().name
                shutil.copytree(spare(), target)
                found = [target]
            assert found, f"{word}: no earlier command of the page made anything like {pattern}"
            word = found[-1].relative_to(page.folder).as_posix()
        elif (index and before not in OUTPUT_OPTIONS and not word.startswith("-") and ("/" in word or "." in word)
              and not (page.folder / word).exists() and (ROOT / word).exists()):
            word = str(ROOT / word)
        resolved.append(word)
    return resolved


def run(cmd: list[str], page: Page, env: dict[str, str]) -> subprocess.CompletedProcess:
    """Run ``cmd`` in the page's folder, its output to files (a pipe would be held open by the simulators'
    worker processes), in a session of its own that is killed whole when it ends or runs past TIMEOUT_S."""
    page.runs += 1
    out, err = page.logs / f"{page.runs}.out", page.logs / f"{page.runs}.err"
    process = start(cmd, page.folder, env, out, err)
    try:
        process.wait(timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        process.kill()
        process.wait()
    finally:
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, signal.SIGKILL)  # what it left running: workers, a background node
    text = (out.read_text(errors="replace"), err.read_text(errors="replace"))
    assert process.returncode != -signal.SIGKILL, f"ran past {TIMEOUT_S} s: {shell_line([(cmd, '')])}\n{tail(*text)}"
    return subprocess.CompletedProcess(cmd, process.returncode, *text)


def run_line(argv: list[str], page: Page, env: dict[str, str]) -> subprocess.CompletedProcess:
    """One command (``autoscoop ...``, ``python script.py ...``) as the venv runs it here."""
    return run([*launcher(program(argv)), *argv[1:]], page, env)


def tail(*texts: str) -> str:
    return "\n".join(text[-2500:] for text in texts if text)


def missing_outputs(argv: list[str], folder: Path) -> list[str]:
    """The outputs a command line names that are not there, or are empty folders."""
    missing = []
    for path in outputs(argv):
        target = folder / path
        if not target.exists() or (target.is_dir() and not any(target.iterdir())):
            missing.append(path)
    return missing


def runs_in(folder: Path) -> set[str]:
    return {p.relative_to(folder).as_posix() for p in folder.glob("runs/*") if (p / "run.json").exists()}


def cut_short(run_dir: str, page: Page, env: dict[str, str]) -> None:
    """Make ``run_dir`` a run interrupted by kill -9, as ``train --resume``'s and ``adapt --resume``'s comments
    say it was: its command again, into the same folder, killed (with its simulators' workers) once it has
    written its first checkpoint."""
    made = page.made_runs.get(run_dir)
    assert made, f"{run_dir}: no earlier command of the page trained it"
    shutil.rmtree(page.folder / run_dir)
    argv = set_option(set_option(set_option(made, "--episodes", "12"), "--checkpoint-every", "2"), "--out", run_dir)
    log = page.logs / "cut_short.log"
    process = start([*launcher("autoscoop"), *argv[1:]], page.folder, env, log, log)
    state = page.folder / run_dir / "checkpoint" / "state.json"
    deadline = time.monotonic() + TIMEOUT_S
    while not state.exists() and process.poll() is None and time.monotonic() < deadline:
        time.sleep(0.02)
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(process.pid, signal.SIGKILL)
    process.wait()
    assert state.exists() and process.returncode == -signal.SIGKILL, f"{run_dir} was not cut short at a checkpoint"


def ros_figures_short(summary_path: Path) -> dict[str, float]:
    """The figures of a ``sim --json`` summary below :data:`ROS_FIGURES` (empty when all hold)."""
    summary = json.loads(summary_path.read_text())
    return {key: summary[key] for key, bar in ROS_FIGURES.items() if summary[key] < bar}


def check_pair(sim_argv: list[str], sim: subprocess.CompletedProcess, page: Page) -> None:
    """Stop the controller node that ran beside ``sim``; it leaves cleanly, writes what it says, and the
    shipped policy scoops as the README says it does over ROS."""
    code, log, node_argv = page.stop_node()
    assert code == 0 and "Traceback" not in log, tail(log)
    assert missing_outputs(node_argv, page.folder) == [], tail(log)
    summary_path = option_value(sim_argv, "--json")
    if option_value(node_argv, "--policy") == "default" and summary_path:
        low = ros_figures_short(page.folder / summary_path)
        assert not low, f"the shipped policy over ROS: {low}, below {ROS_FIGURES}\n{tail(sim.stdout, log)}"


def partner_sim(node_argv: list[str]) -> list[str]:
    """The simulator the test runs beside a controller line that no simulator line follows."""
    argv = ["autoscoop", command_words(node_argv)[0], "sim", "--episodes", "1", "--json", "partner_sim.json"]
    robot = option_value(node_argv, "--robot")
    return [*argv, "--robot", robot] if robot else argv


def environment(argv: list[str], request, page: str) -> dict[str, str]:
    """The environment a command of ``page`` runs in: a private rosmaster's for ROS 1, loopback DDS in the page
    group's domain for ROS 2."""
    words = command_words(argv)
    script = Path(argv[1]).name if program(argv) == "python" and len(argv) > 1 else ""
    if words[:1] == ("ros",) or script.startswith("ros_"):
        return request.getfixturevalue("ros1_env")
    if words[:1] == ("ros2",) or script.startswith("ros2_"):
        return ros2_env(page)
    return base_env()


def check_shell_line(command: DocCommand, page: Page, request) -> None:
    """A line of several commands (``a && b``, ``node & sim; kill $!``) or of a plain shell tool (``sed``):
    each command scaled and resolved, then the line run by ``bash`` as written. It must exit as its comment
    says and write what each command names; a controller beside a simulator must scoop as the README says."""
    parts = [(resolve(scaled(argv), page, lambda: request.getfixturevalue("spare_run")), operator)
             for argv, operator in segments(command.argv)]
    envs = [environment(argv, request, command.page) for argv, _ in parts if program(argv) in ("autoscoop", "python")]
    env = next((env for env in envs if {"ROS_DOMAIN_ID", "ROS_MASTER_URI"} & env.keys()), base_env())
    venv = Path(sys.executable).parent
    line = shell_line([([str(venv / program(argv)), *argv[1:]] if program(argv) in ("autoscoop", "python")
                        else argv, operator) for argv, operator in parts])
    done = run(["bash", "-c", line], page, env)
    expected = expected_exit(command.comment)
    assert done.returncode == expected, f"{line}\nexit {done.returncode}, expected {expected}:\n{tail(done.stdout, done.stderr)}"
    assert "Traceback" not in done.stderr, tail(done.stderr)
    for argv, _ in parts:
        assert missing_outputs(argv, page.folder) == [], tail(done.stdout, done.stderr)
    nodes = [argv for argv, _ in parts if is_node(argv)]
    sims = [argv for argv, _ in parts if is_sim(argv) and option_value(argv, "--json")]
    if nodes and sims and option_value(nodes[0], "--policy") == "default":
        low = ros_figures_short(page.folder / option_value(sims[0], "--json"))
        assert not low, f"the shipped policy over ROS: {low}, below {ROS_FIGURES}\n{tail(done.stdout)}"


def check_command(command: DocCommand, page: Page, request) -> None:
    """Run one command line of a page, scaled, and check it did what its text says (AssertionError if not)."""
    commands = segments(command.argv)
    if len(commands) != 1 or program(commands[0][0]) not in ("autoscoop", "python"):
        check_shell_line(command, page, request)
        return
    words = command_words(command.argv)
    env = environment(list(command.argv), request, command.page)
    argv = resolve(scaled(command.argv), page, lambda: request.getfixturevalue("spare_run"))
    for path in outputs(argv):
        assert not Path(path).is_absolute() or not Path(path).is_relative_to(ROOT), path

    if is_node(argv):
        assert page.node is None, "a controller is already running for this page"
        page.start_node(argv, command, env)
        following = [c for c in COMMANDS if c.page == command.page and c.line > command.line][:1]
        if following and is_sim(following[0].argv) and command_words(following[0].argv)[0] == words[0]:
            return  # the simulator line that follows runs beside it, and stops it
        partner = partner_sim(argv)
        sim = run_line(partner, page, env)
        assert sim.returncode == 0, tail(sim.stdout, sim.stderr)
        check_pair(partner, sim, page)
        return

    before = runs_in(page.folder)
    trains = words in (("train",), ("adapt",))
    if trains and "--resume" in argv:
        cut_short(option_value(argv, "--resume"), page, env)
    done = run_line(argv, page, env)
    expected = expected_exit(command.comment)
    try:
        assert done.returncode == expected, f"exit {done.returncode}, expected {expected}:\n{tail(done.stdout, done.stderr)}"
        assert "Traceback" not in done.stderr, tail(done.stderr)
        assert missing_outputs(argv, page.folder) == [], tail(done.stdout, done.stderr)
    finally:
        if is_sim(argv) and page.node is not None:
            check_pair(argv, done, page)
    if trains:
        for run_dir in runs_in(page.folder) - before:
            page.made_runs[run_dir] = argv
        resumed = option_value(argv, "--resume")
        if resumed:
            status = json.loads((page.folder / resumed / "run.json").read_text())["status"]
            assert status == "finished", status


def run_doc_command(command: DocCommand, pages: dict[str, Page], request) -> None:
    """The test of one command line: skipped for its reason, else run and checked."""
    reason = REASONS[command.page].get(command.line)
    if reason:
        pytest.skip(reason)
    check_command(command, pages[command.page], request)
