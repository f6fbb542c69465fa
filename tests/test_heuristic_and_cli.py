"""The scripted baseline scoops; the command line evaluates and benchmarks."""

import json

import numpy as np
import pytest

from autoscoop.agents.loading import heuristic_for
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.rollout import rollout
from autoscoop.envs.scoop import make_scoop_env

SCRIPTED_FILL_32DEG = 0.71
"""The scripted scoop's mean fill factor on the default 32° pile (README: 0.71 ± 0.06 over 100 episodes;
seeds 0-2 measured 0.729 each)."""


def test_heuristic_scoops_and_reaches_the_terminal_point():
    config = ScoopConfig()
    env = make_scoop_env(config)
    results = [rollout(heuristic_for(config), env, seed) for seed in range(3)]
    # 0.1 is about three standard errors of a three-episode mean: a scoop that fills a fifth less fails.
    assert np.mean([r.fill_factor for r in results]) == pytest.approx(SCRIPTED_FILL_32DEG, abs=0.1)
    assert all(r.success for r in results)
    assert not any(r.physics_error for r in results)


def test_eval_command_writes_the_summary(tmp_path, capsys):
    out = tmp_path / "eval.json"
    assert main(["eval", "--policy", "heuristic", "--episodes", "2", "--set", "pile.angle_deg=28",
                 "--json", str(out)]) == 0
    summary = json.loads(out.read_text())
    for key in ("episodes", "fill_factor_mean", "fill_factor_std", "mass_kg_mean", "cycle_time_mean", "cycle_time_std",
                "success_rate", "spillage_mean", "physics_errors", "config"):
        assert key in summary
    assert summary["episodes"] == 2 and summary["config"]["pile"]["angle_deg"] == 28.0
    assert "fill factor" in capsys.readouterr().out


def test_bad_input_gives_a_clear_error_and_exit_code(capsys):
    assert main(["eval", "--episodes", "1", "--set", "pile.angle_deg=99"]) == 2
    assert "pile.angle_deg = 99: Input should be less than or equal to 60 (allowed [15.0, 60.0] deg)" in capsys.readouterr().err
    assert main(["eval", "--policy", "nonsense", "--episodes", "1"]) == 2


def test_bench_command_reports_the_three_speeds(tmp_path):
    import os

    cores = os.sched_getaffinity(0)
    out = tmp_path / "bench.json"
    assert main(["bench", "--episodes", "1", "--repeats", "1", "--set", "pile.variants=1", "--json", str(out)]) == 0
    result = json.loads(out.read_text())
    assert result["physics_steps_per_s"] > 0 and result["env_steps_per_s"] > 0 and result["realtime_factor"] > 0
    assert os.sched_getaffinity(0) == cores  # the pin to one core is undone
    assert result["cpu"] and result["cpu_count"] >= 1  # which machine gave the figures
    import mujoco

    assert result["mujoco_version"] == mujoco.__version__


def test_the_heuristic_scales_its_speed_with_the_configs_limit():
    from autoscoop.agents.loading import heuristic_for
    from autoscoop.core.config import ScoopConfig

    faster = ScoopConfig().with_overrides({"robot.max_speed_mps": 0.2})
    assert heuristic_for(faster).params.limits.max_speed_mps == 0.2
    assert heuristic_for(ScoopConfig()).params.limits.max_speed_mps == ScoopConfig().robot.max_speed_mps
