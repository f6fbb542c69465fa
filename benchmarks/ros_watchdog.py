"""Watchdog and estop latency of ``autoscoop ros controller`` on a real rosmaster (ROS 1).

Starts a private rosmaster on a free port, the controller (``--policy heuristic``, default robot
config) as its own process, and a stand-in robot in this process. Each watchdog trial starts a scoop,
waits until the robot drives, stops publishing ``joint_states`` at a random phase of the control
period, and measures the time from the last ``joint_states`` message to the first zero ``cmd_vel``.
The requirement: within ``input_timeout_s`` + one control period (0.5 + 0.25 s) in every trial.
Each estop trial measures ``estop`` true -> zero ``cmd_vel`` (requirement: one control period).

    .venv/bin/python benchmarks/ros_watchdog.py --trials 100 --json benchmarks/results/deploy/ros_watchdog.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros1 import import_rospy
from autoscoop.deploy.ros1.master import RosMaster

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the stand-in robot is a test harness
from ros_probe import RobotProbe, estop_trial, latency_summary, watchdog_trial


def measure(trials: int, estop_trials: int, seed: int = 0, log: Path | None = None) -> dict:
    """Run the trials against a fresh master and controller; latencies in seconds."""
    config = RobotNodeConfig()
    period, timeout = config.control.control_period_s, config.control.input_timeout_s
    rng = np.random.default_rng(seed)
    with RosMaster() as master:
        master.use_here()
        out = open(log, "w") if log else subprocess.DEVNULL
        controller = subprocess.Popen([sys.executable, "-m", "autoscoop.cli", "ros", "controller", "--policy",
                                       "heuristic"], env=master.env, stdout=out, stderr=subprocess.STDOUT)
        try:
            rospy = import_rospy()
            rospy.init_node("watchdog_probe", anonymous=True, disable_signals=True)
            probe = RobotProbe(rate_hz=50.0)
            probe.wait_for_controller()
            watchdog = [watchdog_trial(probe, rng.uniform(0.0, period)) for _ in range(trials)]
            estop = [estop_trial(probe, rng.uniform(0.0, period)) for _ in range(estop_trials)]
            probe.close()
        finally:
            controller.terminate()
            controller.wait(timeout=10)
    bound = timeout + period
    return {
        "watchdog": {**latency_summary(watchdog), "bound_s": bound,
                     "within_bound": int(np.sum(np.asarray(watchdog) <= bound)), "latencies_s": watchdog},
        "estop": {**latency_summary(estop), "bound_s": period,
                  "within_bound": int(np.sum(np.asarray(estop) <= period)), "latencies_s": estop},
        "control_period_s": period, "input_timeout_s": timeout, "sensor_rate_hz": 50.0,
        "note": "latency = first zero cmd_vel received by the probe - last joint_states sent (watchdog), "
                "or - estop sent (estop); both include ROS transport both ways",
    }


def main(measure_trials=measure, description: str = __doc__) -> int:
    """The command line around ``measure_trials(trials, estop_trials, log=...)`` (this file's :func:`measure`, or
    another middleware's with the same results); exit 0 when every trial met its bound."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--trials", type=int, default=100, help="watchdog trials (default 100)")
    parser.add_argument("--estop-trials", type=int, default=20, help="estop trials (default 20)")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--log", type=Path, help="write the controller's output here")
    args = parser.parse_args()
    started = time.monotonic()
    result = measure_trials(args.trials, args.estop_trials, log=args.log)
    for name in ("watchdog", "estop"):
        r = result[name]
        print(f"{name}: {r['within_bound']}/{r['n']} within {r['bound_s']:.3f} s; median {r['median_s'] * 1e3:.1f} ms, "
              f"p99 {r['p99_s'] * 1e3:.1f} ms, max {r['max_s'] * 1e3:.1f} ms")
    for fault, r in result["watchdog"].get("by_fault", {}).items():
        print(f"  {fault}: {r['within_bound']}/{r['n']}, median {r['median_s'] * 1e3:.1f} ms, max {r['max_s'] * 1e3:.1f} ms")
    print(f"({time.monotonic() - started:.0f} s)")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.json}")
    ok = all(result[n]["within_bound"] == result[n]["n"] for n in ("watchdog", "estop"))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
