"""Every command line of every other page of docs/ runs, scaled down, and does what its text says (tests/doc_command_runner.py,
whose fixtures tests/conftest.py loads)."""

import pytest
from doc_command_runner import group_commands, run_doc_command

COMMANDS = group_commands("other")


@pytest.mark.parametrize("command", COMMANDS, ids=lambda command: command.id)
def test_the_doc_command_runs_as_written(command, pages, request):
    run_doc_command(command, pages, request)
