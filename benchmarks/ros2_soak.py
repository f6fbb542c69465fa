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

import os
import sys
import time
from collections.abc import Iterator
from contextlib import contextmanager
from functools import partial
from pathlib import Path
from typing import Any

import ros_soak
from ros_soak import Listener, Middleware

from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros2.controller_node import NODE_NAME
from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, TOPIC_QOS, Ros2Node, loopback_environment
from autoscoop.deploy.ros2.messages import MESSAGE_TYPES, Bool, String

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the stand-in robot is a test harness
from ros2_probe import Ros2FaultRelay
from ros_probe import STAMPED_TOPICS


def relay_main(seed: int) -> int:
    """``--relay``: relay the simulator's sensors; read one fault per line (JSON) on stdin, answer each."""
    return ros_soak.serve_relay(Ros2FaultRelay(ros_soak.SOURCE, seed=seed))


class Listener2(Listener):
    """``ros_soak.Listener`` on ROS 2: the controller's commands and status, and the last stamp of each stamped
    sensor input, as they arrive."""

    def subscribe(self, config: RobotNodeConfig) -> None:
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

    def close(self) -> None:
        self.node.close()


@contextmanager
def ros2_graph() -> Iterator[dict]:
    """Cyclone DDS on loopback in a domain of its own, for this process and the environment of the others."""
    env = loopback_environment()
    os.environ.update({key: env[key] for key in ("CYCLONEDDS_URI", "ROS_DOMAIN_ID")})  # this process's participants
    yield env


ROS2 = Middleware("ros2", ros2_graph, Listener2, __file__)


def main() -> int:
    return ros_soak.main(ROS2, relay_main, __doc__)


if __name__ == "__main__":
    sys.exit(main())
