"""``autoscoop bench --n-envs N``: aggregate env steps/s of N subprocess environments against one, and the ratio."""

import json

import pytest

from autoscoop.cli import main

RATE_KEYS = ("env_steps_per_s_1", "env_steps_per_s_n", "per_env_steps_per_s_n", "scaling_ratio")


def test_bench_n_envs_reports_both_rates_and_their_quotient(tmp_path, capsys):
    out = tmp_path / "vec.json"
    argv = ["bench", "--n-envs", "2", "--steps", "5", "--repeats", "2", "--set", "pile.variants=1",
            "--json", str(out)]
    assert main(argv) == 0
    result = json.loads(out.read_text())
    for key in (*RATE_KEYS, "n_envs", "vec_env", "repeats", "steps_per_env", "actions", "cpu", "cpu_count",
                "usable_cores", "mujoco_version", "config"):
        assert key in result, key
    assert result["n_envs"] == 2 and result["steps_per_env"] == 5 and result["actions"] == "random"
    assert result["vec_env"].startswith("SubprocVecEnv")
    assert result["env_steps_per_s_1"] > 0 and result["env_steps_per_s_n"] > 0
    assert result["scaling_ratio"] == pytest.approx(result["env_steps_per_s_n"] / result["env_steps_per_s_1"])
    assert result["per_env_steps_per_s_n"] == pytest.approx(result["env_steps_per_s_n"] / 2)
    assert len(result["repeats"]) == 2
    for repeat in result["repeats"]:
        assert repeat["n1"]["env_steps"] == 5 and repeat["n2"]["env_steps"] == 10
        assert repeat["scaling_ratio"] == pytest.approx(repeat["n2"]["env_steps_per_s"] / repeat["n1"]["env_steps_per_s"])
    printed = capsys.readouterr().out
    assert "scaling ratio" in printed and "2 envs" in printed


def test_bench_n_envs_one_is_its_own_baseline(tmp_path):
    out = tmp_path / "one.json"
    assert main(["bench", "--n-envs", "1", "--steps", "3", "--repeats", "1", "--actions", "fixed",
                 "--set", "pile.variants=1", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["vec_env"] == "DummyVecEnv" and result["scaling_ratio"] == 1.0
    assert result["env_steps_per_s_n"] == result["env_steps_per_s_1"]


def test_bench_n_envs_checks_its_arguments_before_measuring(tmp_path, capsys):
    with pytest.raises(SystemExit) as usage_error:  # argparse refuses the count
        main(["bench", "--n-envs", "0", "--json", str(tmp_path / "x.json")])
    assert usage_error.value.code == 2 and "argument --n-envs" in capsys.readouterr().err
    assert main(["bench", "--n-envs", "2", "--json", str(tmp_path)]) == 2  # a folder: refused before any env starts
    assert "--json" in capsys.readouterr().err
    assert not (tmp_path / "x.json").exists()


def test_make_vec_env_subprocesses_step_as_the_same_envs_in_process():
    """``train --n-envs 2``'s environments: seeded ``seed`` and ``seed + 1``, stepping exactly as in one process."""
    import numpy as np
    from stable_baselines3.common.vec_env import DummyVecEnv

    from autoscoop.core.config import ScoopConfig
    from autoscoop.core.state import ACTION_SIZE
    from autoscoop.envs.scoop import make_scoop_env
    from autoscoop.training.factories import make_vec_env

    config = ScoopConfig().with_overrides({"pile.variants": 1})
    actions = np.random.default_rng(3).uniform(-1, 1, size=(12, 2, ACTION_SIZE)).astype(np.float32)
    sub = make_vec_env(config, 2, seed=7)
    single = make_vec_env(config, 1, seed=7)
    second = DummyVecEnv([lambda: make_scoop_env(config)])
    second.seed(8)
    try:
        obs = sub.reset()
        np.testing.assert_array_equal(obs[0], single.reset()[0])
        np.testing.assert_array_equal(obs[1], second.reset()[0])
        for step_actions in actions:
            obs, rewards, dones, _ = sub.step(step_actions)
            obs_0, rewards_0, dones_0, _ = single.step(step_actions[:1])
            obs_1, rewards_1, dones_1, _ = second.step(step_actions[1:])
            np.testing.assert_array_equal(obs, np.concatenate([obs_0, obs_1]))
            # SubprocVecEnv stacks the rewards as float64, DummyVecEnv keeps them in a float32 buffer
            np.testing.assert_allclose(rewards, np.concatenate([rewards_0, rewards_1]), rtol=1e-6)
            np.testing.assert_array_equal(dones, np.concatenate([dones_0, dones_1]))
    finally:
        for vec in (sub, single, second):
            vec.close()


@pytest.mark.parametrize("argv, flag, mode", [
    (["payload", "--n-envs", "2"], "--n-envs", "payload"),
    (["payload", "--repeats", "2"], "--repeats", "payload"),
    (["--steps", "5"], "--steps", "speed"),
    (["--actions", "fixed"], "--actions", "speed"),
    (["--calibration", "cal.yaml"], "--calibration", "speed"),
    (["--n-envs", "2", "--episodes", "3"], "--episodes", "scaling"),
    (["--n-envs", "2", "--records", "recs"], "--records", "scaling"),
])
def test_an_option_of_another_mode_is_refused_before_any_measurement(argv, flag, mode, tmp_path, capsys, monkeypatch):
    from autoscoop.commands import bench_cmd

    monkeypatch.chdir(tmp_path)
    measured = []
    monkeypatch.setattr(bench_cmd, "run_bench", lambda *a, **k: measured.append("speed"))
    monkeypatch.setattr(bench_cmd, "run_vec_bench", lambda *a, **k: measured.append("scaling"))
    assert main(["bench", *argv, "--json", str(tmp_path / "b.json")]) == 2
    err = capsys.readouterr().err
    assert f"{flag} is an option of" in err and f"not of {mode}" in err
    assert measured == [] and not any(tmp_path.iterdir())
