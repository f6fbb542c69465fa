"""Payload from torque in the simulator: static holds, the environment's torque mass source, the CLI."""

import argparse

import numpy as np
import pytest

from autoscoop.agents.loading import heuristic_for
from autoscoop.commands import bench_cmd, payload_cmd
from autoscoop.core import payload as P
from autoscoop.core.config import ScoopConfig
from autoscoop.envs.scoop import ScoopEnv
from autoscoop.evaluation.payload_bench import evaluate_holds, hold_records, run_payload_bench, static_holds

CARRY_POSE = ((-0.10, -0.50),)


def build_parser():
    """The ``bench`` and ``payload`` commands alone (as ``autoscoop.cli`` registers them)."""
    parser = argparse.ArgumentParser(prog="autoscoop")
    subparsers = parser.add_subparsers(dest="command")
    bench_cmd.register(subparsers)
    payload_cmd.register(subparsers)
    return parser


def main(argv):
    """Like ``autoscoop.cli.main``: a ValueError is exit status 2."""
    args = build_parser().parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except ValueError:
        return 2


@pytest.fixture(scope="module")
def holds():
    return static_holds(ScoopConfig(), poses=CARRY_POSE, max_particles=4, seed=0)


def test_static_hold_eq8_within_tolerance_of_the_carried_mass(holds):
    result = evaluate_holds(holds)
    assert result["counts_covered"] == [0, 1, 2, 3, 4]
    assert result["eq8"]["max_abs_error_kg"] <= 0.35 * 0.5
    for row in result["rows"]:
        assert row["eq8_kg"] == pytest.approx(row["true_kg"], abs=0.1)


def test_calibrate_command_writes_a_calibration_the_estimator_loads(holds, tmp_path):
    for i, record in enumerate(hold_records(holds, ScoopConfig())):
        record.save(tmp_path / "records" / f"hold{i}.npz")
    out = tmp_path / "calib.yaml"
    assert main(["payload", "calibrate", str(tmp_path / "records"), "--write", str(out)]) == 0
    estimator = P.PayloadEstimator.from_yaml(out)
    assert estimator.calibration.fit["samples"] == len(holds)
    # one pose: the offsets and the lever arm seen there reproduce the masses
    for s in holds:
        assert estimator.mass_kg(P.PayloadReading(s.lift_rad, s.tilt_rad, s.lift_torque_nm, s.tilt_torque_nm)) == \
            pytest.approx(s.mass_kg, abs=0.1)
    assert main(["payload", "calibrate", str(tmp_path / "missing.npz")]) == 2


def test_bench_target_is_optional():
    parser = build_parser()
    assert parser.parse_args(["bench", "--json", "x.json"]).target is None
    args = parser.parse_args(["bench", "payload", "--json", "x.json", "--episodes", "2"])
    assert args.target == "payload" and args.episodes == 2
    with pytest.raises(SystemExit):
        parser.parse_args(["bench", "speed"])


def test_payload_bench_reports_both_estimators():
    result = run_payload_bench(ScoopConfig(), episodes=1, poses=CARRY_POSE, max_particles=1, progress=False)
    for name in ("eq8", "eq4"):
        assert set(result["static"][name]) == {"mean_abs_error_kg", "max_abs_error_kg", "samples"}
        assert result["moving"][f"{name}_mean"]["last_step"]["samples"] == 1
    assert result["static"]["eq8"]["max_abs_error_kg"] < 0.35


def run_heuristic(env, seed):
    policy = heuristic_for(env.config)
    obs, _ = env.reset(seed=seed)
    policy.reset()
    trace = []
    while True:
        obs, reward, terminated, truncated, info = env.step(policy.act(obs))
        trace.append((obs.copy(), info))
        if terminated or truncated or len(trace) >= env.config.max_episode_steps:
            return trace


OPEN_LOOP_SCOOP = [np.array(a, dtype=np.float32) for a in
                   [[1, 0, 0]] * 12 + [[1, -0.05, -0.15]] * 4 + [[0, -0.5, -0.5]] * 6]
"""A fixed drive-in, curl-and-lift sequence: it never reads w, so both mass sources see the same motion."""


def run_open_loop(env, seed):
    env.reset(seed=seed)
    trace = []
    for action in OPEN_LOOP_SCOOP:
        obs, reward, terminated, truncated, info = env.step(action)
        trace.append((obs.copy(), info))
        if terminated or truncated:
            break
    return trace


def test_torque_mass_source_changes_only_w_and_tracks_the_truth():
    base = {"pile.variants": 1}
    truth = ScoopEnv(**base)
    torque = ScoopEnv(**base, **{"env.mass_source": "torque", "env.load_cell_noise_nm": 0.0})
    a, b = run_open_loop(truth, 0), run_open_loop(torque, 0)
    assert len(a) == len(b)
    assert a[-1][1]["mass_in_bucket_kg"] > 1.0  # it did scoop something
    for (obs_a, info_a), (obs_b, info_b) in zip(a, b):
        np.testing.assert_array_equal(obs_a[1:], obs_b[1:])  # the controller ignores w: same trajectory
        assert info_a["mass_in_bucket_kg"] == info_b["mass_in_bucket_kg"]
        assert obs_b[0] >= 0.0
    rated = torque.config.reward.rated_load_kg
    final_obs, final_info = b[-1]
    assert final_obs[0] * rated == pytest.approx(final_info["mass_in_bucket_kg"], abs=0.5)
    assert len(torque.sim.substep_observers) == 1 and truth.sim.substep_observers == ()


def test_torque_mass_source_with_noise_is_seeded():
    overrides = {"pile.variants": 1, "env.mass_source": "torque", "env.load_cell_noise_nm": 0.5}
    first = [obs[0] for obs, _ in run_heuristic(ScoopEnv(**overrides), 3)[:8]]
    second = [obs[0] for obs, _ in run_heuristic(ScoopEnv(**overrides), 3)[:8]]
    assert first == second


def test_the_reward_pays_for_the_counted_mass_whatever_the_state_sees():
    env = ScoopEnv(**{"pile.variants": 1, "env.mass_source": "torque", "env.load_cell_noise_nm": 0.5})
    obs, info = run_heuristic(env, 3)[-1]
    assert info["success"] and info["mass_in_bucket_kg"] > 1.0
    reward = env.config.reward
    counted_w = np.float32(info["mass_in_bucket_kg"] / reward.rated_load_kg)
    assert abs(obs[0] - counted_w) > 1e-3  # the state's w is the estimate, not the count
    assert info["reward_mass"] == pytest.approx(reward.c_w * float(counted_w), rel=1e-6)
