"""Soak test over ROS 2: ``autoscoop ros2 controller`` and ``autoscoop ros2 sim`` on Cyclone DDS, with faults injected.

The ROS 2 twin of ``ros_soak.py``, with the same faults, draws and verdicts (its functions): the
controller (``--policy heuristic``, the default robot config), the simulator (episodes until stopped,
its sensor topics remapped into ``sim/``) and, in a process of its own, a relay (this script with
``--relay``: ``ros2_probe.Ros2FaultRelay`` from ``tests/``) that passes the simulator's sensor
messages on to the controller's topics and breaks one input at a time while a scoop runs (silence, a
frozen stamp, stamps 10 s old or 100 s ahead, out of order, NaN, a burst with garbage, estop, or the
relay killed and restarted). All on 127.0.0.1 in a DDS domain of its own. This process listens to the
controller's commands and its latched ``~/status``.

Reported as ``ros_soak.py`` does: faults injected and caught within 0.75 s, the worst time to a stop,
bad commands (non-finite or outside the limits: must be 0), commands with a non-zero speed while the
status said stopped (must be 0), and the controller's memory at the start and the end.

    .venv/bin/python benchmarks/ros2_soak.py --minutes 10 --json benchmarks/results/deploy/ros2_soak.json
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
import threading
import time
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np
import ros_soak
from ros_soak import Listener, RelayProcess, draw_fault, evaluate, moving_while_stopped, rss_kb, stops

from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros2.controller_node import NODE_NAME
from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, TOPIC_QOS, Ros2Node, loopback_environment
from autoscoop.deploy.ros2.messages import MESSAGE_TYPES, Bool, String

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the stand-in robot is a test harness
from ros2_probe import Ros2FaultRelay
from ros_probe import RELAY_FAULTS, SENSOR_TOPICS, STAMPED_TOPICS

SOURCE = "sim"
"""The namespace the simulator's sensor topics are remapped into."""


def relay_main(seed: int) -> int:
    """``--relay``: relay the simulator's sensors; read one fault per line (JSON) on stdin, answer each."""
    relay = Ros2FaultRelay(SOURCE, seed=seed)
    relay.wait_connected()
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        print(json.dumps(relay.inject(**json.loads(line))), flush=True)
    relay.close()
    return 0


class Listener2(Listener):
    """``ros_soak.Listener`` on ROS 2: the controller's commands and status, and the last stamp of each stamped
    sensor input, as they arrive."""

    def __init__(self, config: RobotNodeConfig) -> None:
        limits = config.limits
        self.bounds = {"cmd_vel": (-limits.max_speed_mps, limits.max_speed_mps),
                       "lift_command": (limits.lift_min_rad, limits.lift_max_rad),
                       "tilt_command": (limits.tilt_min_rad, limits.tilt_max_rad)}
        self.lock = threading.Lock()
        self.counts = dict.fromkeys(self.bounds, 0)
        self.bad: list[tuple[float, str, float]] = []
        self.speeds: list[tuple[float, float]] = []
        self.status: list[tuple[float, str]] = []
        self.reading_time: dict[str, float] = {}
        self.scoops = 0
        self.node = node = Ros2Node("autoscoop_soak")
        topics = config.topics
        for key, value in (("cmd_vel", lambda m: m.linear.x), ("lift_command", lambda m: m.data),
                           ("tilt_command", lambda m: m.data)):
            node.subscription(getattr(topics, key), MESSAGE_TYPES[key], COMMANDS, partial(self._command, key, value))
        node.subscription(topics.scoop, Bool, COMMANDS, self._scoop)
        node.subscription(f"/{NODE_NAME}/status", String, LATCHED, self._status)
        for name in STAMPED_TOPICS:
            node.subscription(getattr(topics, name), MESSAGE_TYPES[name], TOPIC_QOS[name], partial(self._reading, name))

    def _reading(self, topic: str, msg: Any) -> None:
        self.reading_time[topic] = time.monotonic() - (time.time() - msg.header.stamp.to_seconds())


def soak(minutes: float, seed: int = 0, policy: str = "heuristic", work: Path | None = None) -> dict:
    """Run the soak for ``minutes``; the figures (times in s, memory in kB)."""
    config = RobotNodeConfig()
    period, timeout = config.control.control_period_s, config.control.input_timeout_s
    work = work or Path(tempfile.mkdtemp(prefix="autoscoop-ros2-soak-"))
    work.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    env = loopback_environment()
    os.environ.update({key: env[key] for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")})  # this process's participant
    cli = [sys.executable, "-m", "autoscoop.cli", "ros2"]
    remap = [f"{name}:={SOURCE}/{getattr(config.topics, name)}" for name in SENSOR_TOPICS]
    logs = {name: open(work / f"{name}.log", "w") for name in ("controller", "sim", "relay")}
    faults: list[dict] = []
    rss: list[tuple[float, int]] = []
    controller = subprocess.Popen([*cli, "controller", "--policy", policy], env=env, stdout=logs["controller"],
                                  stderr=subprocess.STDOUT)
    sim = subprocess.Popen([*cli, "sim", "--episodes", "0", *remap], env=env, stdout=logs["sim"],
                           stderr=subprocess.STDOUT)
    relay = None
    listener = Listener2(config)
    try:
        relay = RelayProcess(env, seed, logs["relay"], script=__file__)
        if not listener.wait_running(for_s=2.0, timeout_s=120.0):
            raise RuntimeError(f"no scoop ran; see the logs in {work}")
        started = time.monotonic()
        deadline = started + 60.0 * minutes
        rss.append((0.0, rss_kb(controller.pid)))
        next_sample = started + 10.0
        restarts = 0
        while time.monotonic() < deadline:
            if not listener.wait_running(for_s=float(rng.uniform(0.5, 2.0)), timeout_s=30.0):
                continue
            kind, topic, duration = draw_fault(rng)
            if kind == "restart":
                restarts += 1
                begun = time.monotonic()
                relay.kill()
                time.sleep(0.05)  # what was in flight has arrived
                t0 = min(listener.reading_time.values())  # the first input to go stale: the oldest last reading
                relay = RelayProcess(env, seed + restarts, logs["relay"], script=__file__)
                record = {"kind": "restart", "topic": "restart", "t0": t0, "started": begun,
                          "ended": time.monotonic(), "bad_messages": 0}
            else:
                record = relay.inject(kind, topic, duration)
            faults.append(record)
            if time.monotonic() >= next_sample:
                rss.append((time.monotonic() - started, rss_kb(controller.pid)))
                next_sample += 10.0
        time.sleep(2 * (timeout + period))  # the last fault's stop arrives
        rss.append((time.monotonic() - started, rss_kb(controller.pid)))
        elapsed = time.monotonic() - started
    finally:
        if relay is not None:
            relay.kill()
        for process in (sim, controller):
            process.terminate()
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                process.kill()
        for log in logs.values():
            log.close()
        listener.node.close()
    with listener.lock:
        status, speeds = list(listener.status), list(listener.speeds)
        counts, bad = dict(listener.counts), list(listener.bad)
    result = evaluate(faults, status, timeout + period)
    stopped, unexplained = stops(status, faults, timeout + period)
    start_kb, end_kb = rss[0][1], rss[-1][1]
    return {
        "middleware": "ROS 2 (Cyclone DDS, loopback)", "minutes": elapsed / 60.0, "policy": policy, "seed": seed,
        "scoops": listener.scoops, "commands": {**counts, "total": sum(counts.values())}, "bad_commands": len(bad),
        "bad": bad[:20], "moving_while_stopped": moving_while_stopped(speeds, status),
        "faults": result, "stops": stopped, "stops_not_injected": len(unexplained),
        "stops_not_injected_reasons": unexplained[:20],
        "controller_rss_kb": {"start": start_kb, "end": end_kb, "growth_pct": 100.0 * (end_kb - start_kb) / start_kb,
                              "samples": rss},
        "control_period_s": period, "input_timeout_s": timeout, "faults_known": RELAY_FAULTS,
        "fault_log": faults, "work_dir": str(work),
        "status_log": [(round(t - started, 4), text[:160]) for t, text in status],
        "note": "as ros_soak.py: time to stop = the controller's ~/status turning to fault (naming the input) or "
                "estop, as received here, minus when the input turned bad",
    }


def main() -> int:
    return ros_soak.main(soak, relay_main, __doc__)


if __name__ == "__main__":
    sys.exit(main())
