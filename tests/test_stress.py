"""``autoscoop stress``: the cases are the acceptance's, the thresholds judge rows right, the command writes
its JSON, table and heat map, workers change nothing, and bad options fail before any episode."""

from __future__ import annotations

import json
import math
import os

import mujoco
import numpy as np
import pytest

from autoscoop.agents.loading import load_policy
from autoscoop.cli import main
from autoscoop.core.config import ScoopConfig
from autoscoop.evaluation import stress as stress_module
from autoscoop.evaluation.evaluate import evaluate
from autoscoop.evaluation.stress import CASES, StressRow, run_stress, select_cases
from autoscoop.report.stress import result_text, scaled_margin, stress_table

ACCEPTANCE = {
    "nominal": {},
    "angle_25": {"pile.angle_deg": 25.0},
    "angle_40": {"pile.angle_deg": 40.0},
    "light": {"pile.particle_mass_kg": 0.2},
    "heavy": {"pile.particle_mass_kg": 0.4},
    "friction_0.6": {"pile.friction": 0.6},
    "friction_1.3": {"pile.friction": 1.3},
    "gap_0.3": {"robot.start_gap_m": 0.3},
    "torque_mass": {"env.mass_source": "torque"},
    "delay_noise": {"sensor.delay_s": 0.05, "sensor.joint_noise_rad": 0.002, "sensor.speed_noise_mps": 0.002,
                    "sensor.range_noise_m": 0.003, "sensor.torque_noise_nm": 0.2},
    "randomized": {"randomize.preset": "robot"},
}


def test_the_cases_are_the_acceptances_with_its_thresholds():
    assert {case.name: dict(case.overrides) for case in CASES} == ACCEPTANCE
    assert [case.name for case in CASES] == list(ACCEPTANCE)
    assert ScoopConfig().pile.angle_deg == 32.0  # nominal is the 32° pile
    thresholds = {case.name: {(t.metric, t.op, t.value) for t in case.thresholds} for case in CASES}
    assert thresholds.pop("nominal") == {("fill_factor_mean", ">=", 0.75), ("success_rate", ">=", 0.97),
                                         ("cycle_time_mean", "<=", 5.0)}
    for name, found in thresholds.items():
        assert found == {("success_rate", ">=", 0.90), ("volumetric_fill_mean", ">=", 0.60),
                         ("overload_rate", "<=", 0.05)}, name
    for case in CASES:  # every case is a valid config
        case.config(ScoopConfig())


def _row(name: str, **stats: float) -> StressRow:
    case = select_cases([name])[0]
    base = {"fill_factor_mean": 0.8, "fill_factor_std": 0.05, "volumetric_fill_mean": 0.7, "volumetric_fill_std": 0.05,
            "success_rate": 0.98, "reached_rate": 1.0, "cycle_time_mean": 4.8, "cycle_time_std": 0.3,
            "overload_rate": 0.0}
    return StressRow(case, {**base, **stats})


def test_pass_and_fail_follow_the_thresholds():
    assert _row("nominal").passed
    assert _row("nominal", fill_factor_mean=0.75, success_rate=0.97, cycle_time_mean=5.0).passed  # at the line holds
    slow = _row("nominal", cycle_time_mean=5.01)
    assert not slow.passed and [c.threshold.metric for c in slow.failures()] == ["cycle_time_mean"]
    assert result_text(slow) == "FAIL: cycle time 5.01 s > 5 s"
    assert not _row("nominal", cycle_time_mean=math.nan).passed  # no success at all: no cycle time, a fail
    assert _row("light", fill_factor_mean=0.4, cycle_time_mean=9.0).passed  # nominal's bars do not apply
    heavy = _row("heavy", success_rate=0.89, overload_rate=0.06, volumetric_fill_mean=0.59)
    assert {c.threshold.metric for c in heavy.failures()} == {"success_rate", "overload_rate", "volumetric_fill_mean"}
    assert not _row("torque_mass", volumetric_fill_mean=math.nan).passed
    table = stress_table([_row("nominal"), heavy]).splitlines()
    assert len(table) == 4 and "| pass |" in table[2]
    assert "**0.89**" in table[3] and "**FAIL: success 0.89 < 0.9;" in table[3]
    overload = {c.threshold.metric: c for c in heavy.checks}["overload_rate"]
    assert -1.0 <= scaled_margin(overload) < 0 < scaled_margin(_row("angle_25").checks[2]) <= 1.0


def test_bad_cases_and_unwritable_outputs_fail_before_any_episode(tmp_path, capsys, monkeypatch):
    def no_episodes(*args, **kwargs):
        raise AssertionError("an episode ran")

    monkeypatch.setattr(stress_module, "run_case", no_episodes)
    json_file = tmp_path / "s.json"
    assert main(["stress", "--policy", "heuristic", "--episodes", "1", "--cases", "nominal,steep",
                 "--json", str(json_file), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert "'steep'" in err and "known cases: nominal, angle_25" in err and "randomized" in err
    blocker = tmp_path / "a_file"
    blocker.write_text("")
    for out in (blocker, blocker / "sub"):
        assert main(["stress", "--policy", "heuristic", "--episodes", "1", "--cases", "nominal",
                     "--json", str(json_file), "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert "--out" in err and str(out) in err
    if os.geteuid() != 0:  # root writes anywhere
        locked = tmp_path / "locked"
        locked.mkdir(mode=0o500)
        assert main(["stress", "--policy", "heuristic", "--episodes", "1", "--json", str(json_file),
                     "--out", str(locked / "out")]) == 2
        assert "not writable" in capsys.readouterr().err
    assert not json_file.exists()


def test_the_command_writes_json_table_and_heat_map(tmp_path, capsys):
    json_file, out = tmp_path / "stress.json", tmp_path / "out"
    assert main(["stress", "--policy", "heuristic", "--episodes", "2", "--seed", "3", "--cases", "light,nominal",
                 "--json", str(json_file), "--out", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "| nominal |" in printed and "| light |" in printed and "cases hold" in printed
    data = json.loads(json_file.read_text())
    assert data["policy"] == "heuristic" and data["episodes"] == 2 and data["seeds"] == [3, 4]
    assert data["cpu_count"] == os.cpu_count() and data["wall_time_s"] > 0
    # the libraries a figure can move with are named, read from what is installed
    assert data["dependencies"]["mujoco"] == mujoco.__version__ and data["dependencies"]["numpy"] == np.__version__
    assert [row["case"] for row in data["rows"]] == ["nominal", "light"]  # the suite's order
    for row in data["rows"]:
        assert [e["seed"] for e in row["episodes_detail"]] == [3, 4]
        assert row["passed"] == all(check["passed"] for check in row["checks"])
        for key in ("fill_factor_mean", "fill_factor_std", "volumetric_fill_mean", "volumetric_fill_std",
                    "cycle_time_mean", "success_rate", "reached_rate", "overload_rate"):
            assert key in row["stats"]
    assert data["rows"][1]["overrides"] == {"pile.particle_mass_kg": 0.2}
    # the nominal row is what `autoscoop eval` measures for the same seeds
    config = ScoopConfig()
    expected = evaluate(load_policy("heuristic", config), config, 2, seed=3, progress=False)
    assert data["rows"][0]["episodes_detail"] == json.loads(json.dumps([o.as_dict() for o in expected]))
    table = (out / "stress.md").read_text()
    assert table.count("| nominal |") == 1 and table.count("| light |") == 1 and "stress.png" in table
    assert (out / "stress.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_workers_give_the_same_rows_as_serial():
    config = ScoopConfig()
    cases = select_cases("angle_25,gap_0.3")
    serial = run_stress("heuristic", config, 2, seed=1, cases=cases, workers=1, progress=False)
    parallel = run_stress("heuristic", config, 2, seed=1, cases=cases, workers=2, progress=False)
    assert [r.as_dict() for r in parallel] == [r.as_dict() for r in serial]
    with pytest.raises(ValueError, match="workers"):
        run_stress("heuristic", config, 1, cases=cases, workers=0)
