"""Bad input fails at once with exit code 2 and a message naming the option, file or key; no traceback."""

import sys

import forked
import pytest

from autoscoop.cli import main
from autoscoop.commands import evaluate_cmd
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import make_scoop_env


@pytest.fixture
def no_episodes(monkeypatch):
    """Fail the test if ``autoscoop eval`` gets as far as running an episode."""
    def refuse(*args, **kwargs):
        raise AssertionError("an episode ran before the bad input was refused")

    monkeypatch.setattr(evaluate_cmd, "evaluate", refuse)


@pytest.mark.parametrize("command", [["eval"], ["compare"], ["demo"], ["teleop"], ["train"], ["ros", "sim"]])
def test_a_negative_seed_is_refused_naming_the_option_and_range(command, capsys):
    with pytest.raises(SystemExit) as exit_:
        main([*command, "--seed", "-1"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert "argument --seed" in err and "0 or more" in err and "-1" in err


def test_seed_zero_is_still_allowed():
    from autoscoop.cli import build_parser

    assert build_parser().parse_args(["eval", "--seed", "0"]).seed == 0


def test_a_missing_config_file_is_named(tmp_path, capsys, no_episodes):
    missing = tmp_path / "nope.yaml"
    assert main(["eval", "--episodes", "1", "--config", str(missing)]) == 2
    err = capsys.readouterr().err
    assert str(missing) in err and "no such file" in err and "Traceback" not in err


def test_a_folder_as_config_file_is_named(tmp_path, capsys, no_episodes):
    assert main(["eval", "--episodes", "1", "--config", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "is a folder" in err


def test_a_yaml_syntax_error_names_the_file_and_line(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("pile:\n  angle_deg: 28\n  n_particles: [1, 2\nenv: {}\n")
    done = forked.run([sys.executable, "-m", "autoscoop.cli", "config", "--config", str(bad)],
                      capture_output=True, text=True, timeout=120)
    assert done.returncode == 2
    assert str(bad) in done.stderr and "not valid YAML at line 4" in done.stderr
    assert "Traceback" not in done.stderr


def test_a_bad_value_in_a_config_file_names_the_file_and_key(tmp_path, capsys):
    bad = tmp_path / "c.yaml"
    bad.write_text("pile:\n  angle_deg: 99\n")
    assert main(["config", "--config", str(bad)]) == 2
    err = capsys.readouterr().err
    assert str(bad) in err and "pile.angle_deg = 99: Input should be less than or equal to 60" in err


def test_eval_refuses_a_non_empty_records_folder(tmp_path, capsys, no_episodes):
    (tmp_path / "episode_00007.npz").write_bytes(b"an older run")
    assert main(["eval", "--episodes", "1", "--records", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert str(tmp_path) in err and "not empty" in err and "--overwrite" in err
    assert (tmp_path / "episode_00007.npz").exists()


def test_eval_overwrite_leaves_other_files_and_refuses(tmp_path, capsys, no_episodes):
    (tmp_path / "episode_00007.npz").write_bytes(b"an older run")
    (tmp_path / "notes.txt").write_text("mine")
    assert main(["eval", "--episodes", "1", "--records", str(tmp_path), "--overwrite"]) == 2
    assert "notes.txt" in capsys.readouterr().err
    assert (tmp_path / "notes.txt").exists() and not (tmp_path / "episode_00007.npz").exists()


def test_eval_records_that_is_a_file_is_refused(tmp_path, capsys, no_episodes):
    target = tmp_path / "records"
    target.write_text("")
    assert main(["eval", "--episodes", "1", "--records", str(target)]) == 2
    assert f"--records {target}: is a file" in capsys.readouterr().err


def test_eval_overwrite_replaces_the_old_records(tmp_path):
    (tmp_path / "episode_00007.npz").write_bytes(b"an older run")
    assert main(["eval", "--episodes", "1", "--set", "pile.variants=1", "--records", str(tmp_path),
                 "--overwrite"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == [".autoscoop.lock", "episode_00000.npz"]  # the lock stays


def test_eval_checks_the_json_path_before_the_first_episode(tmp_path, capsys, no_episodes):
    assert main(["eval", "--episodes", "1", "--json", str(tmp_path)]) == 2
    assert f"--json {tmp_path}: is a folder" in capsys.readouterr().err
    blocker = tmp_path / "file"
    blocker.write_text("")
    assert main(["eval", "--episodes", "1", "--json", str(blocker / "sub" / "out.json")]) == 2
    err = capsys.readouterr().err
    assert str(blocker / "sub" / "out.json") in err and "is not a folder" in err


def test_reset_refuses_unknown_options_and_keeps_none_and_empty():
    env = make_scoop_env(ScoopConfig().with_overrides({"pile.variants": 1, "pile.n_particles": 8}))
    try:
        obs_none, _ = env.reset(seed=3, options=None)
        obs_empty, _ = env.reset(seed=3, options={})
        assert (obs_none == obs_empty).all()
        with pytest.raises(ValueError, match=r"unknown option\(s\) \['pile_angle', 'start'\]"):
            env.reset(seed=3, options={"start": 1, "pile_angle": 30})
    finally:
        env.close()
