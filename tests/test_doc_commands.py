"""The rules by which the command lines of README.md and docs/*.md are run (tests/doc_commands.py,
tests/doc_command_runner.py); the lines themselves run in tests/test_doc_commands_*.py, a group of pages each."""

from __future__ import annotations

import pytest
from doc_command_runner import COMMANDS, PAGE_GROUPS, REASONS, Page, check_command, group_commands, ros2_domain
from doc_commands import (
    expected_exit,
    extract,
    has_placeholder,
    is_node,
    placeholder_glob,
    scaled,
    segments,
    shell_line,
    skip_reason,
    skip_reasons,
    tokens,
)


def test_every_page_runs_in_exactly_one_group_and_each_group_in_a_dds_domain_of_its_own():
    groups = [*PAGE_GROUPS, "other"]
    assert sorted(c.id for group in groups for c in group_commands(group)) == sorted(c.id for c in COMMANDS)
    assert all(group_commands(group) for group in groups)
    domains = {ros2_domain(pages[0]) for pages in PAGE_GROUPS.values()} | {ros2_domain("docs/shift.md")}
    assert len(domains) == len(groups) and all(0 <= d <= 232 for d in domains)


# ---------------------------------------------------------------- the rules themselves
def test_commands_are_read_from_bash_fences_with_continuations_and_comments():
    page = ("text `autoscoop no` here\n\n```bash\n# only a comment\nautoscoop eval --episodes 100 # exits 3\n"
            "autoscoop shift --cycles 15 \\\n    --json 'out/a b.json'   # two lines\n```\n\n```python\nimport x\n```\n"
            "```\nautoscoop plain-fence\n```\n")
    found = extract(page, "p.md")
    assert [(c.line, c.text, c.comment) for c in found] == [
        (5, "autoscoop eval --episodes 100", "exits 3"),
        (6, "autoscoop shift --cycles 15 --json 'out/a b.json'", "two lines")]
    assert found[1].argv == ("autoscoop", "shift", "--cycles", "15", "--json", "out/a b.json")
    assert expected_exit(found[0].comment) == 3 and expected_exit(found[1].comment) == 0


def test_a_doc_line_that_does_not_do_what_it_says_fails(tmp_path, request):
    (tmp_path / "page").mkdir()
    (tmp_path / "logs").mkdir()
    page = Page(tmp_path / "page", tmp_path / "logs")
    wrong = extract("```bash\n.venv/bin/autoscoop eval --policy heuristic --set pile.angle_deg=999\n"
                    "mkdir -p out && false\n"
                    ".venv/bin/autoscoop config   # exits 3\n```\n", "p.md")
    assert len(wrong) == 3
    for command in wrong:
        with pytest.raises(AssertionError):
            check_command(command, page, request)


def test_lines_of_several_commands_are_split_at_the_shell_operators():
    argv = tokens("a --x 1 & b --y 'q r'; kill $!; wait $!")
    assert segments(argv) == [(["a", "--x", "1"], "&"), (["b", "--y", "q r"], ";"), (["kill", "$!"], ";"),
                              (["wait", "$!"], "")]
    assert shell_line(segments(argv)) == "a --x 1 & b --y 'q r' ; kill $! ; wait $!"
    assert shell_line(segments(tokens("sed -i 's|a: \"\"|a: b|' f"))) == "sed -i 's|a: \"\"|a: b|' f"


def test_scaling_rules():
    assert scaled(["autoscoop", "eval", "--policy", "default", "--episodes", "100"])[-1] == "1"
    assert scaled(["autoscoop", "eval"]) == ["autoscoop", "eval", "--episodes", "1"]
    assert scaled(["autoscoop", "adapt", "--policy", "default"])[4:6] == ["--episodes", "2"]
    assert scaled(["autoscoop", "train", "--seed", "12"]) == ["autoscoop", "train", "--seed", "12", "--episodes", "3",
                                                             "--demo-episodes", "2"]
    assert scaled(["autoscoop", "train", "--resume", "runs/x"]) == ["autoscoop", "train", "--resume", "runs/x"]
    assert scaled(["autoscoop", "ros2", "sim", "a:=b"]) == ["autoscoop", "ros2", "sim", "--episodes", "3", "a:=b"]
    assert scaled(["autoscoop", "bench", "--n-envs", "2"]) == ["autoscoop", "bench", "--n-envs", "2", "--repeats", "1",
                                                              "--steps", "200"]
    assert scaled(["autoscoop", "shift", "--cycles", "15"]) == ["autoscoop", "shift", "--cycles", "1", "--shifts", "1"]
    assert skip_reason(("tensorboard", "--logdir", "runs")) and skip_reason((".venv/bin/pip", "install", "x"))
    assert skip_reason((".venv/bin/autoscoop", "eval")) is None
    assert scaled(["python", "benchmarks/adapt_worlds.py", "--seeds", "0", "1", "2", "--out", "o"])[2:6] == [
        "--seeds", "0", "--out", "o"]
    assert scaled(["autoscoop", "adapt", "--resume", "runs/x"])[-6:] == ["--candidates", "1", "--validation-episodes",
                                                                         "1", "--workers", "1"]
    assert scaled(["autoscoop", "eval", "--policy", "runs/RUN"])[-1] == "--allow-empty"
    assert scaled(["autoscoop", "eval", "--policy", "default"])[-1] != "--allow-empty"
    assert not is_node(["autoscoop", "ros2", "controller", "--check"]) and is_node(["autoscoop", "ros", "controller"])
    assert placeholder_glob("runs/ddpg-s12-TIME") == "runs/ddpg-s12-*" and not has_placeholder("runs/RUNNING")


def test_a_command_that_reads_a_skipped_commands_output_is_skipped_with_it():
    commands = extract("```bash\nautoscoop sweep --out sweeps/s1\nautoscoop eval --policy sweeps/s1/best.x\n"
                       "autoscoop eval --policy default\n```\n", "p.md")
    assert sorted(skip_reasons(commands)) == [2, 3]


def test_most_doc_commands_run():
    skipped = sum(len(reasons) for reasons in REASONS.values())
    assert len(COMMANDS) >= 40 and skipped <= len(COMMANDS) // 3, (len(COMMANDS), skipped)
    assert {c.page for c in COMMANDS} >= {"README.md", "docs/robot.md", "docs/training.md", "docs/shift.md"}
