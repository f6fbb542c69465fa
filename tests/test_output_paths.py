"""``bench --json``, ``compare --out`` and ``demo --out`` check where they will write before any work:
a path that cannot be written is exit 2 with a message naming it, and nothing has run."""

import os

import pytest

from autoscoop.cli import main
from autoscoop.commands import bench_cmd, compare_cmd, demo_cmd, payload_cmd


def _refuse(*args, **kwargs):
    raise AssertionError("work started before the output path was checked")


@pytest.fixture
def no_work(monkeypatch):
    """Fail the test if a command gets as far as measuring, loading a policy or running an episode."""
    monkeypatch.setattr(bench_cmd, "run_bench", _refuse)
    monkeypatch.setattr(payload_cmd, "run_payload_bench_cmd", _refuse)
    for module in (compare_cmd, demo_cmd):
        monkeypatch.setattr(module, "evaluate", _refuse)
        monkeypatch.setattr(module, "load_policy", _refuse)


@pytest.fixture
def blocker(tmp_path):
    """A plain file, to put a path under."""
    path = tmp_path / "file"
    path.write_text("")
    return path


@pytest.mark.parametrize("target", [[], ["payload"]])
def test_bench_json_is_checked_before_measuring(target, tmp_path, blocker, capsys, no_work):
    assert main(["bench", *target, "--json", str(tmp_path)]) == 2
    assert f"--json {tmp_path}: is a folder" in capsys.readouterr().err
    bad = blocker / "sub" / "bench.json"
    assert main(["bench", *target, "--json", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "is not a folder" in err and "Traceback" not in err


@pytest.mark.parametrize("command", ["compare", "demo"])
def test_an_out_folder_that_is_a_file_or_under_one_is_refused_before_any_episode(command, blocker, capsys, no_work):
    assert main([command, "--episodes", "1", "--out", str(blocker)]) == 2
    assert f"--out {blocker}: is a file, not a folder" in capsys.readouterr().err
    under = blocker / "out"
    assert main([command, "--episodes", "1", "--out", str(under)]) == 2
    err = capsys.readouterr().err
    assert f"--out {under}: cannot be created, {blocker} is not a folder" in err and "Traceback" not in err


@pytest.mark.parametrize("command, blocked", [
    ("compare", "records"), ("compare", "summary.json"), ("demo", "records"), ("demo", "summary.json"),
    ("demo", "report.md")])
def test_what_is_written_under_out_is_checked_too(command, blocked, tmp_path, capsys, no_work):
    out = tmp_path / "out"
    out.mkdir()
    if blocked.endswith((".json", ".md")):  # a folder where the file goes
        (out / blocked).mkdir()
    else:  # a file where the folder goes
        (out / blocked).write_text("")
    assert main([command, "--episodes", "1", "--policies" if command == "compare" else "--policy", "heuristic",
                 "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert str(out / blocked) in err and "Traceback" not in err


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root may write anywhere")
@pytest.mark.parametrize("command", ["compare", "demo"])
def test_a_read_only_parent_is_refused(command, tmp_path, capsys, no_work):
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        assert main([command, "--episodes", "1", "--out", str(locked / "out")]) == 2
        assert f"folder {locked} is not writable" in capsys.readouterr().err
    finally:
        locked.chmod(0o700)


def test_good_paths_pass_the_checks(tmp_path):
    from autoscoop.commands import check_output_dir, check_output_file

    check_output_dir(tmp_path / "new" / "deeper", "--out")
    check_output_dir(tmp_path, "--out")
    check_output_file(tmp_path / "new" / "x.json", "--json")


def test_ros_sim_json_is_checked_before_any_episode(tmp_path, capsys, monkeypatch):
    """``ros sim --json`` into a folder fails at once (exit 2), before the simulator or ROS start."""
    from autoscoop.deploy import sim_bridge

    def refuse(*args, **kwargs):
        raise AssertionError("the simulator started before the output path was checked")

    monkeypatch.setattr(sim_bridge, "SimBridge", refuse)
    assert main(["ros", "sim", "--episodes", "1", "--json", str(tmp_path)]) == 2
    assert str(tmp_path) in capsys.readouterr().err
