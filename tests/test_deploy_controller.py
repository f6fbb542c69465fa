"""The controller node's logic without ROS: watchdog, estop, limits, fuzzed readings, records, a scoop."""

import math

import numpy as np
import pytest

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig, robot_config_from_dict
from autoscoop.deploy.safety import CommandLimiter, InputWatchdog
from autoscoop.envs.records import STEP_FIELDS, load_record

TASK = ScoopConfig()
PERIOD, TIMEOUT = 0.25, 0.5


def make_core(config=None, policy=None, **kwargs):
    config = config or RobotNodeConfig()
    return ControllerCore(config, policy or load_policy("heuristic", TASK), TASK, **kwargs)


def feed_all(core, t, lift=0.23, tilt=0.0, joints=True):
    if joints:
        core.joint_states(["lift", "tilt"], [lift, tilt], t)
    core.odometry(0.05, t)
    core.pile_range(0.3, t, 0.0, 4.0)
    core.bucket_torque(-1.0, t)
    core.lift_torque(-20.0, t)


def run(core, t, until, feed=feed_all, sensor_period=0.02, log=None):
    """Drive the core as the ROS front end does: sensors every ``sensor_period``, updates at its wake-ups."""
    next_feed = t
    while True:
        t_next = min(core.next_wakeup(t), next_feed)
        if t_next > until:
            return until
        t = max(t, t_next)
        if t >= next_feed:
            feed(core, t)
            next_feed += sensor_period
        command = core.update(t)
        if command is not None and log is not None:
            log.append((t, command))


def test_watchdog_reports_missing_stale_and_bad_inputs():
    dog = InputWatchdog(("a", "b"), timeout_s=0.5)
    assert dog.problems(0.0) == ["a: no message yet", "b: no message yet"]
    dog.valid("a", 0.0)
    dog.valid("b", 0.2)
    assert dog.problems(0.5) == [] and dog.next_expiry(0.1) == 0.5
    assert dog.problems(0.51) == ["a: stale (no valid message for over 0.5 s)"]
    dog.invalid("b", "NaN")
    assert dog.problems(0.3) == ["b: NaN"]
    dog.valid("b", 0.6)
    assert dog.problems(0.6) == ["a: stale (no valid message for over 0.5 s)"]


def test_limiter_clamps_to_ranges_and_rates():
    limiter = CommandLimiter(RobotNodeConfig().limits, PERIOD)
    out = limiter.clamp(np.array([5.0, 9.0, -9.0]), np.array([0.0, 0.2, 0.0]))
    assert out == pytest.approx([0.1, 0.3, -0.25])  # speed limit; lift rate 0.4 rad/s; tilt rate 1 rad/s
    last = np.array([0.05, 0.2, 0.1])
    assert limiter.clamp(np.array([np.nan, np.inf, -np.inf]), last) == pytest.approx(last)
    assert np.all(np.isfinite(limiter.clamp(np.array([np.nan] * 3), None)))


def test_stale_joint_states_stop_the_robot_within_timeout_plus_one_period():
    core, log = make_core(), []
    feed_all(core, 0.0)
    core.scoop(True, 0.0)
    run(core, 0.0, 2.0, log=log)
    assert log[-1][1].mode == "running" and log[-1][1].speed_mps > 0
    stop = 2.0
    run(core, stop, 4.0, feed=lambda c, t: feed_all(c, t, joints=False), log=log)
    last_joint = max(t for t in np.arange(0.0, stop + 1e-9, 0.02))
    first_zero = next(t for t, c in log if t > stop and c.speed_mps == 0.0)
    assert first_zero - last_joint <= TIMEOUT + 1e-3  # the watchdog's expiry is a wake-up: no period added
    held = [c for t, c in log if t > first_zero]
    assert held and all(c.speed_mps == 0.0 and c.mode == "fault" and c.lift_rad is not None for c in held)
    assert all(c.lift_rad == held[0].lift_rad for c in held)  # the arm is held
    run(core, 4.0, 5.0, log=log)  # fresh again: it resumes
    assert log[-1][1].mode == "running" and log[-1][1].speed_mps > 0


def test_estop_stops_at_once_and_holds_until_cleared():
    core, log = make_core(), []
    feed_all(core, 0.0)
    core.scoop(True, 0.0)
    run(core, 0.0, 1.0, log=log)
    core.estop(True, 1.001)
    command = core.update(1.001)
    assert command.speed_mps == 0.0 and command.mode == "estop"
    run(core, 1.001, 3.0, log=log)
    assert all(c.speed_mps == 0.0 for t, c in log if t > 1.001)
    core.estop(False, 3.0)
    run(core, 3.0, 3.6, log=log)
    assert log[-1][1].mode == "running"


@pytest.mark.parametrize("bad", [
    lambda c, t: c.joint_states(["lift", "tilt"], [float("nan"), 0.0], t),
    lambda c, t: c.joint_states(["lift"], [0.2], t),
    lambda c, t: c.joint_states(["lift", "tilt"], [0.2], t),
    lambda c, t: c.joint_states(["lift", "tilt"], [0.2, 3.0], t),
    lambda c, t: c.odometry(float("inf"), t),
    lambda c, t: c.pile_range(-0.5, t, 0.0, 4.0),
    lambda c, t: c.pile_range(5.0, t, 0.0, 4.0),
    lambda c, t: c.bucket_torque(1e9, t),
    lambda c, t: c.lift_torque(float("nan"), t),
])
def test_an_invalid_reading_stops_the_robot_at_once(bad):
    core = make_core()
    feed_all(core, 0.0)
    core.scoop(True, 0.0)
    run(core, 0.0, 1.0)
    assert bad(core, 1.01) is False
    command = core.update(1.01)
    assert command is not None and command.speed_mps == 0.0 and command.mode == "fault"


def test_potentiometer_readings_become_angles():
    config = robot_config_from_dict({"potentiometer": {"lift": {"raw": [100, 900], "rad": [-0.1, 0.32]}}})
    core = make_core(config)
    raw = 100 + (0.23 + 0.1) / 0.42 * 800
    assert core.joint_states(["tilt", "lift"], [0.0, raw], 0.0)
    assert core.lift_rad == pytest.approx(0.23)


class RandomPolicy:
    """Actions anywhere, including NaN and far outside [-1, 1]."""

    name = "random"

    def __init__(self, rng):
        self.rng = rng

    def reset(self):
        pass

    def act(self, observation):
        a = self.rng.uniform(-3, 3, 3)
        if self.rng.random() < 0.1:
            a[self.rng.integers(3)] = self.rng.choice([np.nan, np.inf, -np.inf])
        return a


BAD_NUMBERS = [np.nan, np.inf, -np.inf, 1e308, -1e308, 5.0, -5.0]


@pytest.mark.parametrize("seed", range(4))
def test_fuzzed_readings_never_yield_a_bad_command(seed):
    rng = np.random.default_rng(seed)
    config = RobotNodeConfig()
    core = make_core(config, policy=RandomPolicy(rng) if seed % 2 else None)
    limiter = CommandLimiter(config.limits, PERIOD)

    def number(good):
        return float(rng.choice(BAD_NUMBERS)) if rng.random() < 0.2 else good

    t, last_running = 0.0, None
    for _ in range(3000):
        t += float(rng.exponential(0.01))
        kind = rng.integers(8)
        if kind == 0:
            names = [n for n in ["lift", "tilt", "wrist"] if rng.random() < 0.9]
            core.joint_states(names, [number(rng.uniform(-0.1, 0.3)) for _ in range(int(rng.integers(0, 4)))], t)
        elif kind == 1:
            core.odometry(number(rng.uniform(-0.1, 0.1)), t)
        elif kind == 2:
            core.pile_range(number(rng.uniform(0, 1)), t, number(0.0), number(4.0))
        elif kind == 3:
            core.bucket_torque(number(rng.uniform(-10, 10)), t)
            core.lift_torque(number(rng.uniform(-60, 0)), t)
        elif kind == 4 and rng.random() < 0.05:
            core.estop(bool(rng.random() < 0.5), t)
        elif kind == 5 and rng.random() < 0.05:
            core.scoop(bool(rng.random() < 0.8), t)
        command = core.update(t)
        if command is None:
            continue
        assert limiter.contains(command), command
        assert math.isfinite(command.speed_mps)
        if command.mode != "running":
            assert command.speed_mps == 0.0
            last_running = None
        else:
            assert not core.watchdog.problems(t) and not core.estop_engaged
            episode = core.episode.index
            if last_running is not None and last_running[0] == episode:  # rate limits hold within a scoop
                step = np.abs(command.as_array() - last_running[1])
                assert np.all(step <= limiter.step + 1e-9), (command, last_running)
            last_running = (episode, command.as_array())


def test_a_policy_that_fails_stops_the_robot_without_crashing():
    class Broken:
        name = "broken"

        def reset(self):
            pass

        def act(self, observation):
            return [np.nan, 0.0, 0.0]

    core, log = make_core(policy=Broken()), []
    feed_all(core, 0.0)
    core.scoop(True, 0.0)
    run(core, 0.0, 1.0, log=log)
    assert log and all(c.speed_mps == 0.0 and "policy error" in c.reason for t, c in log)


def test_the_controller_scoops_the_simulated_pile_and_records_it(tmp_path):
    from autoscoop.deploy.sim_bridge import SimBridge, run_without_ros
    from autoscoop.report.data import load_episodes, summarize_episodes

    core = make_core(record_dir=tmp_path)
    bridge = SimBridge(TASK.with_overrides({"pile.variants": 1}))
    result, _ = run_without_ros(bridge, core, seed=0)
    bridge.close()
    assert result.success and result.fill_factor > 0.25
    (path,) = core.saved
    record = load_record(path)
    assert set(record.steps) == set(STEP_FIELDS) and len(record) >= 15
    assert record.meta["source"] == "ros controller" and record.meta["start"]["state"]
    from dataclasses import fields

    from autoscoop.envs.outcome import EpisodeOutcome

    outcome = record.meta["outcome"]  # an EpisodeOutcome, plus the robot's own keys
    assert {f.name for f in fields(EpisodeOutcome)} <= set(outcome) and outcome["seed"] == -1
    assert outcome["steps"] == len(record) and math.isnan(outcome["particles"]) and outcome["cycle_time_s"] is None
    assert {"autoscoop_version", "pile", "terminal_point_m", "config", "robot_config"} <= set(record.meta)
    a = record.arrays()
    assert np.all(np.isnan(a["tip_world_m"])) and np.all(np.isfinite(a["state"]))
    assert a["penetrating"].max() == 1.0  # judged from the range to the pile
    summary = summarize_episodes(load_episodes([tmp_path]))
    assert summary["episodes"] == 1 and summary["mass_kg_mean"] > 0.5  # the payload estimate


def test_a_scoop_starts_from_the_start_pose_when_the_arm_is_there_else_from_where_it_is():
    core = make_core()
    feed_all(core, 0.0, lift=TASK.robot.start_lift_rad + 0.006)  # the arm sags a little below its setpoint
    core.scoop(True, 0.0)
    core.update(0.0)
    assert core.episode.targets[1] == pytest.approx(TASK.robot.start_lift_rad, abs=1e-6)  # heuristic: lift kept
    core.scoop(False, 0.1)
    feed_all(core, 0.2, lift=0.0, tilt=0.5)
    core.scoop(True, 0.2)
    command = core.update(0.2)
    assert command.lift_rad == pytest.approx(0.0, abs=0.1) and command.tilt_rad == pytest.approx(0.5, abs=0.25)


def test_payload_from_a_topic_replaces_the_torque_estimate():
    core = make_core(robot_config_from_dict({"payload": {"source": "topic"}}))
    assert "payload_mass" in core.watchdog.names and "bucket_torque" not in core.watchdog.names
    feed_all(core, 0.0)
    assert core.payload_mass(3.5, 0.0)
    assert core._measurements().mass_kg == 3.5
    assert not core.payload_mass(float("nan"), 0.1)
    assert core.update(0.1).mode == "fault"


def _held_payload_torques(lift, tilt, mass_kg, pitch=0.0):
    """Joint torques (lift, tilt) that hold the arm, the bucket and ``mass_kg`` at an off-centre point."""
    from autoscoop.core import payload as P

    jac = P.bucket_point_jacobian(lift, tilt, np.array([0.13, 0.02]))  # not the calibration's point: eq. 8 needs none
    return P.gravity_torques(lift, tilt, pitch) + jac.T @ (mass_kg * P.GRAVITY_MPS2 * P.up_in_chassis(pitch))


def test_the_node_weighs_the_payload_with_eq8_averaged_over_the_period_like_the_environment():
    lift, tilt, pitch, mass = 0.0, -0.45, 0.05, 4.2
    tau = _held_payload_torques(lift, tilt, mass, pitch)
    quat = (math.cos(pitch / 2), 0.0, math.sin(pitch / 2), 0.0)  # nose down about +y
    from autoscoop.core.payload import pitch_from_quaternion

    assert pitch_from_quaternion(*quat) == pytest.approx(pitch)
    core = make_core()
    swing = 6.0  # N*m on the bucket torque, alternating: rattling particles; the mean is right

    def feed(c, t):
        k = int(round(t / 0.02))
        c.joint_states(["lift", "tilt"], [lift, tilt], t)
        c.odometry(0.0, t, pitch_from_quaternion(*quat))
        c.pile_range(0.3, t, 0.0, 4.0)
        c.bucket_torque(tau[1] + (swing if k % 2 else -swing), t)
        c.lift_torque(tau[0], t)

    feed(core, 0.0)
    feed(core, 0.02)
    core.scoop(True, 0.02)
    run(core, 0.02, 1.0, feed=feed, sensor_period=0.02)
    w = core.episode.previous.mass_kg
    assert w == pytest.approx(mass, abs=0.35)  # a whole number of swings (+-6 N*m is +-4 kg) averaged per period
    assert core.mass_from_torque.estimator.method == "eq8"


def test_eq8_needs_the_lift_torque_and_eq4_does_not():
    core = make_core()
    t = 0.0
    core.joint_states(["lift", "tilt"], [0.23, 0.0], t)
    core.odometry(0.0, t)
    core.pile_range(0.3, t, 0.0, 4.0)
    core.bucket_torque(-1.0, t)
    core.scoop(True, t)
    command = core.update(t)
    assert command.mode == "fault" and "lift_torque" in command.reason
    eq4 = make_core(robot_config_from_dict({"payload": {"method": "eq4"}}))
    eq4.joint_states(["lift", "tilt"], [0.23, 0.0], t)
    eq4.odometry(0.0, t)
    eq4.pile_range(0.3, t, 0.0, 4.0)
    eq4.bucket_torque(-1.0, t)
    eq4.scoop(True, t)
    assert eq4.update(t).mode == "running"
    with pytest.raises(Exception, match="payload.method"):
        robot_config_from_dict({"payload": {"method": "eq5"}})
