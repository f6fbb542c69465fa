"""The watchdog judges a stamped input's age by its header stamp (issue 14, item 1).

A driver that re-publishes a frozen reading, stamps its readings 10 s late or 100 s early, or
publishes them out of order must stop the robot within ``input_timeout_s`` + one control period,
as a silent one does. The core is driven without ROS, its ROS clock offset from its monotonic
clock (as on the robot: wall time against uptime); one test does the same over a real rosmaster.
"""

import json
import math
import re
import subprocess
import sys
from pathlib import Path

import forked
import pytest

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ConfigError, ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig, robot_config_from_dict
from autoscoop.deploy.ros1 import ros_available
from autoscoop.deploy.safety import InputWatchdog, Stamp

TASK = ScoopConfig()
CONFIG = RobotNodeConfig()
PERIOD, TIMEOUT = CONFIG.control.control_period_s, CONFIG.control.input_timeout_s
BOUND = TIMEOUT + PERIOD
ROS_OFFSET_S = 1.7e9 + 0.123
"""The node's ROS clock minus its monotonic clock, s."""
SENSOR_PERIOD_S = 0.02
STAMPED = ("joint_states", "odom", "pile_range")


def feed(core, now, header=None, only=None):
    """One message on every input (or on ``only``); stamped ones carry ``header(now)`` (default: now on
    the ROS clock)."""
    stamp = Stamp(now + ROS_OFFSET_S if header is None else header(now), now + ROS_OFFSET_S)
    calls = {"joint_states": lambda: core.joint_states(["lift", "tilt"], [0.23, 0.0], now, stamp),
             "odom": lambda: core.odometry(0.05, now, 0.0, stamp),
             "pile_range": lambda: core.pile_range(0.3, now, 0.0, 4.0, stamp),
             "bucket_torque": lambda: core.bucket_torque(-1.0, now),
             "lift_torque": lambda: core.lift_torque(-20.0, now)}
    return {name: call() for name, call in calls.items() if only is None or name in only}


def drive(core, start, until, faulty=None, header=None, log=None):
    """Sensors every 20 ms (``faulty`` with stamps from ``header``), updates at the core's wake-ups."""
    healthy = [name for name in STAMPED + ("bucket_torque", "lift_torque") if name != faulty]
    t, next_feed = start, start
    while True:
        t_next = min(core.next_wakeup(t), next_feed)
        if t_next > until:
            return
        t = max(t, t_next)
        if t >= next_feed:
            feed(core, t, only=healthy)
            if faulty is not None:
                feed(core, t, header=header, only=[faulty])
            next_feed += SENSOR_PERIOD_S
        command = core.update(t)
        if command is not None and log is not None:
            log.append((t, command))


def running_core():
    """A core driving forward (the heuristic's first phase) at t = 2 s."""
    core = ControllerCore(CONFIG, load_policy("heuristic", TASK), TASK)
    log = []
    core.scoop(True, 0.0)
    drive(core, 0.0, 2.0, log=log)
    assert log[-1][1].mode == "running" and log[-1][1].speed_mps > 0
    return core


def first_stop(log, after):
    return next((t for t, c in log if t >= after and c.speed_mps == 0.0 and c.mode == "fault"), math.inf)


FAULTS = {
    "frozen": lambda t0: lambda now: t0 + ROS_OFFSET_S,  # the driver re-publishes one reading
    "10 s old": lambda t0: lambda now: now - 10.0 + ROS_OFFSET_S,
    "100 s ahead": lambda t0: lambda now: now + 100.0 + ROS_OFFSET_S,
    "out of order": lambda t0: lambda now: 2 * t0 - now + ROS_OFFSET_S,  # going backwards from t0
}


@pytest.mark.parametrize("fault", list(FAULTS))
@pytest.mark.parametrize("topic", STAMPED)
def test_a_bad_stamp_stops_the_robot_within_timeout_plus_one_period(topic, fault):
    core, log, t0 = running_core(), [], 2.0
    feed(core, t0)  # the last good reading, at t0
    drive(core, t0 + SENSOR_PERIOD_S, t0 + 3.0, faulty=topic, header=FAULTS[fault](t0), log=log)
    stop = first_stop(log, t0)
    assert stop <= t0 + BOUND, (topic, fault, stop, log[:5])
    assert all(c.speed_mps == 0.0 for t, c in log if t >= stop), "it stays stopped while the fault lasts"
    assert topic in core.reason
    if fault == "frozen":  # stale exactly when the frozen reading is input_timeout_s old
        assert stop == pytest.approx(t0 + TIMEOUT, abs=1e-3)
    else:  # refused at once
        assert stop == pytest.approx(t0 + SENSOR_PERIOD_S, abs=1e-6)
    drive(core, t0 + 3.0, t0 + 4.0, log=log)  # good stamps again: it drives on
    assert log[-1][1].mode == "running" and log[-1][1].speed_mps > 0


def test_the_reasons_say_what_is_wrong_with_the_stamp():
    dog = InputWatchdog(("a",), timeout_s=0.5, max_future_s=0.1)
    assert dog.valid("a", 10.0, Stamp(100.0, 100.0))
    assert not dog.valid("a", 10.02, Stamp(100.0, 100.02))  # a repeat: ignored, not bad
    assert dog.problems(10.3) == [] and dog.problems(10.51)[0].startswith("a: stale")
    assert not dog.valid("a", 10.6, Stamp(90.0, 100.6))
    assert dog.problems(10.6) == ["a: stamped over 0.5 s ago"]
    assert not dog.valid("a", 10.7, Stamp(200.7, 100.7))
    assert dog.problems(10.7) == ["a: stamped over 0.1 s ahead of the node's clock"]
    assert dog.valid("a", 10.8, Stamp(100.8, 100.8)) and not dog.valid("a", 10.81, Stamp(100.7, 100.81))
    assert dog.problems(10.81) == ["a: stamped before the last accepted message (out of order)"]
    assert not dog.valid("a", 10.9, Stamp(0.0, 100.9))
    assert dog.problems(10.9) == ["a: message not stamped (header.stamp 0): its age cannot be judged"]


def test_a_stamp_slightly_ahead_counts_as_taken_on_arrival():
    dog = InputWatchdog(("a",), timeout_s=0.5, max_future_s=0.1)
    assert dog.valid("a", 1.0, Stamp(100.08, 100.0))  # within the skew allowed
    assert dog.next_expiry(1.0) == pytest.approx(1.5)  # not 1.58: an early stamp buys no time
    assert dog.valid("a", 1.1, Stamp(100.12, 100.1))
    assert dog.next_expiry(1.1) == pytest.approx(1.6)


def test_a_late_stamp_expires_early():
    dog = InputWatchdog(("a",), timeout_s=0.5)
    assert dog.valid("a", 1.0, Stamp(99.7, 100.0))  # 0.3 s in transit
    assert dog.next_expiry(1.0) == pytest.approx(1.2) and dog.problems(1.21)


def test_after_the_input_went_stale_its_stamps_may_start_over():
    """A clock stepped back (a restarted simulation's clock) stops the robot once, not forever."""
    dog = InputWatchdog(("a",), timeout_s=0.5)
    assert dog.valid("a", 1.0, Stamp(500.0, 500.0))
    assert not dog.valid("a", 1.2, Stamp(10.2, 10.2))  # out of order while the last one is fresh
    assert dog.valid("a", 1.6, Stamp(10.6, 10.6)) and dog.problems(1.6) == []


@pytest.mark.parametrize("fault, reason", [("10 s old", "odom: stamped over 0.5 s ago"),
                                           ("frozen", "odom: stale (no valid message for over 0.5 s)")])
def test_a_run_of_bad_stamps_is_one_fault_not_one_per_message(fault, reason):
    core, warnings, log = running_core(), [], []
    core.log = lambda level, text: warnings.append(text) if level == "warn" else None
    drive(core, 2.0, 3.0, faulty="odom", header=FAULTS[fault](2.0), log=log)
    assert warnings == [f"stopping (zero velocity, arm held): {reason}"]
    assert len(log) <= 1 + 1.0 / PERIOD + 1  # the stop, then one command per control period


def test_garbage_at_sensor_rate_writes_a_line_a_second_not_one_per_message():
    """A log line per message would flood the log (and block a node whose output nobody reads)."""
    core, warnings = running_core(), []
    core.log = lambda level, text: warnings.append(text) if level == "warn" else None
    for k in range(150):  # 3 s of odometry garbage, a different value each time, at 50 Hz
        t = 2.0 + 0.02 * k
        feed(core, t, only=["joint_states", "pile_range", "bucket_torque", "lift_torque"])
        core.odometry(5.0 + k, t, 0.0, Stamp(t + ROS_OFFSET_S, t + ROS_OFFSET_S))
        command = core.update(t)
        assert command is None or command.speed_mps == 0.0
    assert warnings[0] == "stopping (zero velocity, arm held): odom: 5.0 m/s is not within +-1 m/s"
    assert len(warnings) == 3 and all(w.startswith("still stopped: odom: ") for w in warnings[1:])
    assert core.reason == "odom: 154.0 m/s is not within +-1 m/s"  # ~status has the latest


def test_transport_delays_are_kept_in_a_ring_that_does_not_grow():
    core = running_core()
    for i in range(250_000):
        core.transport_delay("odom", 0.001 * (i % 7))
    log = core.delays["odom"]
    assert log.count == 100_000 and log.values().nbytes == 800_000
    assert core.delay_summary()["odom"]["max"] == pytest.approx(0.006)


def test_unstamped_messages_on_a_stamped_input_stop_the_robot():
    core = running_core()
    core.joint_states(["lift", "tilt"], [0.23, 0.0], 2.01, Stamp(0.0, 2.01 + ROS_OFFSET_S))
    command = core.update(2.01)
    assert command.speed_mps == 0.0 and "joint_states: message not stamped" in command.reason


def test_the_future_stamp_bound_is_a_checked_config_key():
    assert CONFIG.control.max_future_stamp_s == 0.1
    config = robot_config_from_dict({"control": {"max_future_stamp_s": 1.0}})
    core = ControllerCore(config, load_policy("heuristic", TASK), TASK)
    assert core.watchdog.max_future_s == 1.0
    with pytest.raises(ConfigError, match=re.escape("control.max_future_stamp_s = -1: Input should be greater than or "
                                                   "equal to 0 (allowed [0.0, 5.0] s)")):
        robot_config_from_dict({"control": {"max_future_stamp_s": -1}})
    assert "control.max_future_stamp_s" in RobotNodeConfig().describe()


# -------------------------------------------------------------------- over a real rosmaster
PROBE = """
import json
import sys
sys.path.insert(0, TESTS_DIR)
from autoscoop.deploy.ros1 import import_rospy
from ros_probe import STAMP_FAULTS, RobotProbe, stamp_trial
rospy = import_rospy()
rospy.init_node("autoscoop_stamp_probe", anonymous=True, disable_signals=True)
probe = RobotProbe(rate_hz=50.0)
probe.wait_for_controller(timeout_s=60)
print(json.dumps({kind: stamp_trial(probe, kind) for kind in STAMP_FAULTS}))
probe.close()
""".replace("TESTS_DIR", repr(str(Path(__file__).resolve().parent)))
"""The stand-in robot, in a process of its own (rospy allows one node per process, and the other ROS
tests' node lives in pytest's)."""


@pytest.mark.skipif(not ros_available(), reason="ROS 1 is not available here")
def test_over_ros_bad_stamps_stop_the_robot_within_timeout_plus_one_period():
    from autoscoop.deploy.ros1.master import RosMaster

    with RosMaster() as master:
        controller = forked.Popen([sys.executable, "-m", "autoscoop.cli", "ros", "controller", "--policy",
                                   "heuristic"], env=master.env, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True)
        try:
            probe = forked.run([sys.executable, "-c", PROBE], env=master.env, capture_output=True, text=True,
                               timeout=120)
        finally:
            controller.terminate()
            log, _ = controller.communicate(timeout=15)
    assert probe.returncode == 0, probe.stdout[-2000:] + probe.stderr[-3000:]
    delays = json.loads(probe.stdout.strip().splitlines()[-1])
    print(f"bad stamps over ROS, s to a zero cmd_vel: {delays}")
    assert all(d <= BOUND for d in delays.values()), delays
    assert delays["frozen"] >= TIMEOUT - 0.05, delays  # stale when the reading is input_timeout_s old
    assert "Traceback" not in log, log[-3000:]
