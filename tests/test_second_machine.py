"""A second machine (``compact``) runs through the same commands; a policy or run of one machine is refused on
another. A process runs one machine, so each case here runs autoscoop in a process of its own."""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
from pathlib import Path

import forked
import pytest
import yaml

from autoscoop.cli import main
from autoscoop.core.machine import MACHINE_ENV, load_machine

ROOT = Path(__file__).resolve().parent.parent
KOMODO_POLICY = ROOT / "autoscoop" / "policies" / "default.safetensors"


def autoscoop(*args: str, machine: str | None = None, timeout: int = 240) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k != MACHINE_ENV}
    if machine is not None:
        env[MACHINE_ENV] = machine
    return forked.run([sys.executable, "-m", "autoscoop.cli", *args], capture_output=True, text=True,
                      timeout=timeout, env=env, check=False)


def python(code: str, machine: str) -> str:
    env = {**os.environ, MACHINE_ENV: machine}
    return forked.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, env=env,
                      check=True).stdout


def test_the_scripted_scoop_fills_the_compact_bucket(tmp_path):
    out = tmp_path / "eval.json"
    done = autoscoop("eval", "--machine", "compact", "--policy", "heuristic", "--episodes", "3", "--json", str(out))
    assert done.returncode == 0, done.stderr
    result = json.loads(out.read_text())
    assert result["success_rate"] == 1.0
    assert 0.5 <= result["fill_factor_mean"] <= 1.05
    assert result["mass_kg_mean"] > 10.0  # a 23.6 kg bucket, not the Komodo's 7 kg one


def test_the_world_follows_the_machine():
    code = ("from autoscoop.core.config import ScoopConfig, ROBOT_PRESET\n"
            "from autoscoop.evaluation.stress import CASES, NOMINAL_CYCLE_TIME_S\n"
            "from autoscoop.sim.scene import WHEEL_RADIUS_M\n"
            "c = ScoopConfig()\n"
            "print(c.reward.rated_load_kg, c.pile.radius_m, c.pile.particle_mass_kg, c.robot.max_speed_mps,"
            " c.robot.start_lift_rad, WHEEL_RADIUS_M, NOMINAL_CYCLE_TIME_S, ROBOT_PRESET['particle_radius_m'][1])\n"
            "print({case.name: case.overrides for case in CASES}['heavy'], {case.name: case.overrides for case in CASES}['gap_0.3'])\n")
    compact, komodo = python(code, "compact").splitlines(), python(code, "komodo").splitlines()
    assert compact[0].split() == ["23.625", "0.051", "1.0125", "0.122474487139", "0.28", "0.1905", "6.12372", "0.0525"]
    assert compact[1] == "{'pile.particle_mass_kg': 1.35} {'robot.start_gap_m': 0.45}"
    assert komodo[0].split() == ["7.0", "0.034", "0.3", "0.1", "0.23", "0.127", "5.0", "0.035"]
    assert komodo[1] == "{'pile.particle_mass_kg': 0.4} {'robot.start_gap_m': 0.3}"


def test_a_komodo_policy_is_refused_on_the_compact():
    done = autoscoop("eval", "--machine", "compact", "--policy", str(KOMODO_POLICY), "--episodes", "1")
    assert done.returncode == 2
    assert "a policy for machine 'komodo', but this run's machine is 'compact'" in done.stderr
    assert "Traceback" not in done.stderr


def test_the_refusal_names_a_shipped_machine_by_name_and_a_users_machine_by_its_folder():
    from autoscoop.core.machine import MachineError, refuse_other_machine

    komodo = load_machine("komodo")
    with pytest.raises(MachineError, match=r"pass --machine compact to run it"):
        refuse_other_machine({"machine": "compact"}, komodo, "--policy p")
    # a user's machine is found by its folder, not its name: a bare name would not load
    with pytest.raises(MachineError, match=r"pass --machine DIR \(the folder of the machine.yaml named 'wombat'\)"):
        refuse_other_machine({"machine": "wombat"}, komodo, "--policy p")
    refuse_other_machine({"machine": "komodo"}, komodo, "--policy p")  # its own machine: no error


def test_adapt_refuses_a_policy_of_another_machine_before_simulating(tmp_path):
    done = autoscoop("adapt", "--machine", "compact", "--policy", str(KOMODO_POLICY), "--episodes", "2",
                     "--out", str(tmp_path / "run"), timeout=120)
    assert done.returncode == 2
    assert "a policy for machine 'komodo'" in done.stderr
    assert "--from-machine komodo (a warm start across machines)" in done.stderr
    assert not (tmp_path / "run" / "run.json").exists()


def test_adapt_warm_starts_one_machine_from_another_in_its_own_worlds(tmp_path):
    run = tmp_path / "run"
    done = autoscoop("adapt", "--machine", "compact", "--policy", "default", "--from-machine", "komodo",
                     "--episodes", "2", "--eval-every", "2", "--eval-episodes", "2", "--candidates", "0",
                     "--critic-warmup-steps", "1", "--out", str(run), "--no-progress")
    assert done.returncode == 0, done.stderr
    info = json.loads((run / "run.json").read_text())
    assert info["machine"] == "compact" and info["adapt"]["from_machine"] == "komodo"
    assert info["init_from"] == str((run / "start.safetensors").resolve())
    target, held = (yaml.safe_load((run / name).read_text()) for name in ("config.yaml", "held.yaml"))
    assert target["pile"]["particle_mass_kg"] == 1.0125 and target["reward"]["rated_load_kg"] == 23.625
    assert target["reward"]["distance_scale_m"] == 0.3  # the recipe's setting, as train lays it over the machine's
    assert target["randomize"]["preset"] == "none" and held["randomize"]["preset"] == "robot"
    assert json.loads((run / "policy.json").read_text())["machine"] == "compact"  # now the compact's controller
    assert info["adapt"]["length_scale"] == 1.35  # the compact's lift arm over the Komodo's
    start = json.loads((run / "start.json").read_text())
    assert start["rescaled_from"] == {"machine": "komodo", "length_scale": 1.35,
                                      "sha256": hashlib.sha256(KOMODO_POLICY.read_bytes()).hexdigest()}
    first = (run / "evaluations.csv").read_text().splitlines()[1].split(",")
    assert first[0] == "0" and float(first[3]) > 0.0  # the rescaled start scoops on the compact (unscaled: never)


def test_a_run_records_its_machine_and_resume_refuses_another(tmp_path):
    run = tmp_path / "run"
    done = autoscoop("train", "--machine", "compact", "--episodes", "3", "--demo-episodes", "1", "--seed", "0",
                     "--out", str(run), "--no-progress", "--checkpoint-every", "1")
    assert done.returncode in (0, 3), done.stderr
    info = json.loads((run / "run.json").read_text())
    assert info["machine"] == "compact"
    assert info["machine_sha256"] == load_machine("compact").digest
    assert json.loads((run / "policy.json").read_text())["machine"] == "compact"
    info["status"] = "running"
    (run / "run.json").write_text(json.dumps(info))
    done = autoscoop("train", "--resume", str(run))  # komodo, the default machine
    assert done.returncode == 2
    assert "a policy for machine 'compact', but this run's machine is 'komodo'" in done.stderr


def test_a_process_runs_one_machine(capsys):
    import autoscoop.core.kinematics  # noqa: F401 - this process has chosen komodo

    assert main(["eval", "--machine", "compact", "--episodes", "1"]) == 2
    assert "already runs machine komodo" in capsys.readouterr().err


def test_machine_new_scales_the_world_with_the_machine(tmp_path):
    assert main(["machine", "new", "half", "--like", "komodo", "--scale", "0.5", "--out", str(tmp_path / "half")]) == 0
    data = yaml.safe_load((tmp_path / "half" / "machine.yaml").read_text())
    assert data["scene"]["pile.radius_m"] == pytest.approx(0.017)
    assert data["scene"]["pile.particle_mass_kg"] == pytest.approx(0.0375)
    assert data["robot_preset"]["start_gap_m"] == pytest.approx([0.025, 0.16])
    assert data["scripted_scoop"]["contact_gap_m"] == pytest.approx(0.01)
    assert "default_policy" not in data
    assert (tmp_path / "half" / "scene.xml").read_text().count('<include file="loader.xml"/>') == 1
