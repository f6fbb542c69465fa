"""Shared test set-up."""

import tempfile

import forked
import pytest

# Import the package before any test module imports mujoco: on a machine without a display,
# ``import autoscoop`` points MUJOCO_GL at an off-screen backend, and mujoco reads it only once.
import autoscoop  # noqa: F401

pytest_plugins = ["doc_command_runner"]  # the doc commands' fixtures (pages, spare_run, ros1_env)

LONGEST_FIRST = ("test_doc_commands_readme.py", "test_doc_commands_training.py", "test_doc_commands_robot.py",
                 "test_doc_commands_other.py", "test_sweep.py", "test_train.py", "test_resume.py",
                 "test_second_machine.py", "test_adapt.py")
"""The test files that take longest (minutes, seconds), started first: with ``make test``'s workers
(``--dist loadfile``) the long ones do not end up alone at the end of the run."""


def pytest_collection_modifyitems(items):
    def rank(item):
        name = item.path.name
        return LONGEST_FIRST.index(name) if name in LONGEST_FIRST else len(LONGEST_FIRST)

    items.sort(key=rank)  # stable: each file keeps its order


@pytest.fixture(autouse=True, scope="session")
def temporary_files_inside_pytests_folder(tmp_path_factory):
    """What libraries write to the temporary folder lands in pytest's own, which pytest cleans (a model that
    learns without a log folder makes Stable-Baselines3 create an empty ``SB3-<date>`` folder there)."""
    tempfile.tempdir = str(tmp_path_factory.mktemp("tempfile"))
    yield
    forked.close()  # the fork server of the tests' command lines (tests/forked.py), if one started
    tempfile.tempdir = None
