"""Watchdog and estop latency of ``autoscoop ros2 controller`` over ROS 2 (Cyclone DDS on loopback).

The ROS 2 twin of ``ros_watchdog.py``: the controller (``--policy heuristic``, default robot config)
as its own process in a DDS domain of its own, a stand-in robot (``tests/ros2_probe.py``) in this one.
The watchdog trials are spread over four faults of ``joint_states`` while the robot drives: silenced
(publishing stops at a random phase of the control period; measured from the last message), frozen
(one message re-published, stamp and all), stale (stamps 10 s old) and future-stamped (100 s ahead;
these three measured from the first bad message). The requirement: a zero ``cmd_vel`` within
``input_timeout_s`` + one control period (0.5 + 0.25 s) in every trial. Each estop trial measures
``estop`` true -> zero ``cmd_vel`` (requirement: one control period).

    .venv/bin/python benchmarks/ros2_watchdog.py --trials 100 --json benchmarks/results/deploy/ros2_watchdog.json
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros2.graph import loopback_environment

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the stand-in robot is a test harness
import ros_watchdog
from ros2_probe import Ros2RobotProbe, stamp_trial
from ros_probe import estop_trial, latency_summary, watchdog_trial

FAULTS = ("silenced", "frozen", "stale", "future")


def measure(trials: int, estop_trials: int, seed: int = 0, log: Path | None = None) -> dict:
    """Run the trials against a fresh controller; latencies in seconds, per fault."""
    config = RobotNodeConfig()
    period, timeout = config.control.control_period_s, config.control.input_timeout_s
    rng = np.random.default_rng(seed)
    env = loopback_environment()
    os.environ.update({key: env[key] for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")})  # the probe's participant too
    out = open(log, "w") if log else subprocess.DEVNULL
    controller = subprocess.Popen([sys.executable, "-m", "autoscoop.cli", "ros2", "controller", "--policy",
                                   "heuristic"], env=env, stdout=out, stderr=subprocess.STDOUT)
    latencies: dict[str, list[float]] = {fault: [] for fault in FAULTS}
    try:
        probe = Ros2RobotProbe(rate_hz=50.0)
        probe.wait_for_controller(timeout_s=60)
        for index in range(trials):
            fault = FAULTS[index % len(FAULTS)]
            if fault == "silenced":
                latencies[fault].append(watchdog_trial(probe, rng.uniform(0.0, period)))
            else:
                time.sleep(rng.uniform(0.0, period))
                latencies[fault].append(stamp_trial(probe, fault))
        estop = [estop_trial(probe, rng.uniform(0.0, period)) for _ in range(estop_trials)]
        probe.close()
    finally:
        controller.terminate()
        controller.wait(timeout=15)
    bound = timeout + period
    every = [value for values in latencies.values() for value in values]
    return {
        "watchdog": {**latency_summary(every), "bound_s": bound, "within_bound": int(np.sum(np.asarray(every) <= bound)),
                     "by_fault": {fault: {**latency_summary(values), "within_bound": int(np.sum(np.asarray(values) <= bound)),
                                          "latencies_s": values} for fault, values in latencies.items() if values}},
        "estop": {**latency_summary(estop), "bound_s": period,
                  "within_bound": int(np.sum(np.asarray(estop) <= period)), "latencies_s": estop},
        "control_period_s": period, "input_timeout_s": timeout, "sensor_rate_hz": 50.0, "middleware": "ROS 2 (Cyclone DDS)",
        "note": "latency = first zero cmd_vel received by the probe - last joint_states sent (silenced), first bad "
                "joint_states sent (frozen, stale, future) or estop sent; DDS transport both ways included",
    }


def main() -> int:
    return ros_watchdog.main(measure, __doc__)


if __name__ == "__main__":
    sys.exit(main())
