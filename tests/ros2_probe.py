"""A stand-in robot on the controller's ROS 2 topics, for tests and benchmarks of ``autoscoop ros2 controller``
(test-only: not shipped in the package).

:class:`Ros2RobotProbe` offers what ``ros_probe.RobotProbe`` offers on ROS 1 (sensors at a fixed rate,
each topic stoppable or replaced by made-up messages, every command timestamped on arrival), so the
latency trials of ``ros_probe`` (``watchdog_trial``, ``estop_trial``) run on ROS 2 unchanged;
:func:`stamp_trial` is ROS 2's (stamps are ``builtin_interfaces/Time``). :class:`Ros2FaultRelay` is
``ros_probe.FaultRelay`` on ROS 2 (``benchmarks/ros2_soak.py``). Run them with the environment of
:func:`autoscoop.deploy.ros2.graph.loopback_environment` and the controller in the same domain.
"""

from __future__ import annotations

import dataclasses
import math
import threading
import time
from typing import Any

from ros_probe import FaultRelay, RobotProbe, start_moving

from autoscoop.deploy.robot_config import TopicsSection
from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, TOPIC_QOS, Ros2Node
from autoscoop.deploy.ros2.messages import Bool, Float64, Time, Twist
from autoscoop.deploy.ros2.sim_node import sensor_messages
from autoscoop.deploy.sim_bridge import SensorReadings

SENSOR_TOPICS = ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque")
STAMP_FAULTS = {"frozen": None, "stale": -10.0, "future": 100.0}
"""Stamp faults of :func:`stamp_trial`: the shift of each new stamp, s (``frozen``: one message re-published)."""


class _Writer:
    """A DDS writer with rospy's ``publish``, for the ROS 1 harness's code."""

    def __init__(self, writer: Any) -> None:
        self.writer = writer

    def publish(self, message: Any) -> None:
        self.writer.write(message)


class Ros2RobotProbe(RobotProbe):
    """``ros_probe.RobotProbe`` on ROS 2: publishes the robot's sensors at ``rate_hz`` and records the
    controller's commands (``commands``, ``wait_for_command``, ``publish`` are RobotProbe's).

    Args:
        rate_hz: sensor publication rate.
        topics: topic names (the controller's defaults).
        namespace: the namespace of the topics.
    """

    msg = {"Bool": Bool, "Float64": Float64, "Twist": Twist}

    def __init__(self, rate_hz: float = 50.0, topics: TopicsSection | None = None,
                 namespace: str = "/") -> None:
        self.node = node = Ros2Node("robot_probe", namespace=namespace)
        topics = topics or TopicsSection()
        self.period_s = 1.0 / rate_hz
        self.readings = SensorReadings(0.0, ("lift", "tilt"), (0.23, 0.0), 0.0, 0.3, -1.0, -20.0, 0.0,
                                       (0.0, 0.0, 0.13), (1.0, 0.0, 0.0, 0.0))
        self.start_bookkeeping()
        self.writers = {name: node.publisher(getattr(topics, name), type(msg), TOPIC_QOS[name])
                        for name, msg in sensor_messages(self.readings, 1.0) if name in SENSOR_TOPICS}
        self.writers["estop"] = node.publisher(topics.estop, Bool, LATCHED)
        self.writers["scoop"] = node.publisher(topics.scoop, Bool, COMMANDS)
        self.publishers = {name: _Writer(writer) for name, writer in self.writers.items()}
        node.subscription(topics.cmd_vel, Twist, COMMANDS, self._record("cmd_vel", lambda m: m.linear.x))
        node.subscription(topics.lift_command, Float64, COMMANDS, self._record("lift", lambda m: m.data))
        node.subscription(topics.tilt_command, Float64, COMMANDS, self._record("tilt", lambda m: m.data))
        self._thread = threading.Thread(target=self._run, name="robot-probe", daemon=True)
        self._thread.start()

    def normal_message(self, topic: str) -> Any:
        """The message ``topic`` carries now, freshly stamped on the ROS 2 clock."""
        return dict(sensor_messages(self.readings, time.time()))[topic]

    def _run(self) -> None:
        tick = time.monotonic()
        while not self._stop.is_set():
            for topic in SENSOR_TOPICS:
                if not self.enabled[topic]:
                    continue
                make = self.custom.get(topic)
                self.writers[topic].write(make() if make else self.normal_message(topic))
                self.last_published[topic] = time.monotonic()
            tick += self.period_s
            time.sleep(max(0.0, tick - time.monotonic()))

    def wait_for_controller(self, timeout_s: float = 30.0) -> None:
        """Wait until the controller reads every topic the probe publishes."""
        deadline = time.monotonic() + timeout_s
        for writer in self.writers.values():
            if not self.node.wait_for_subscriber(writer, max(0.0, deadline - time.monotonic())):
                raise TimeoutError("the controller did not connect to the probe's topics")
        time.sleep(0.2)  # and the probe to its commands

    def close(self) -> None:
        """Stop publishing and leave the domain."""
        self._stop.set()
        self._thread.join(timeout=2)
        self.node.close()


def stamp_trial(probe: Ros2RobotProbe, kind: str, timeout_s: float = 2.0) -> float:
    """Give ``joint_states`` bad stamps (:data:`STAMP_FAULTS`) while the robot drives; seconds from the first
    bad message to a zero ``cmd_vel`` (``inf`` when none came within ``timeout_s``). Good stamps again afterwards."""
    start_moving(probe)
    frozen = probe.normal_message("joint_states")
    shift = STAMP_FAULTS[kind]
    t0 = time.monotonic()

    def make() -> Any:
        if shift is None:
            return frozen
        return shifted(probe.normal_message("joint_states"), shift)

    probe.custom["joint_states"] = make
    zero = probe.wait_for_command("cmd_vel", lambda v: v == 0.0, since=t0, timeout_s=timeout_s)
    probe.custom.pop("joint_states")
    time.sleep(0.3)  # fresh again
    return math.inf if zero is None else zero.time_s - t0


def shifted(msg: Any, seconds: float) -> Any:
    """A copy of a stamped ROS 2 message with its stamp moved by ``seconds``."""
    return dataclasses.replace(msg, header=dataclasses.replace(
        msg.header, stamp=Time.from_seconds(msg.header.stamp.to_seconds() + seconds)))


class Ros2FaultRelay(FaultRelay):
    """Relays ``{source}/TOPIC`` to ``TOPIC`` for each sensor topic on ROS 2; :meth:`inject` breaks one for a while.

    Args:
        source: namespace the simulator's sensor topics are remapped into (``joint_states:=sim/joint_states``).
        topics: the controller's topic names.
        seed: for the burst's random copies.
    """

    def __init__(self, source: str = "sim", topics: TopicsSection | None = None, seed: int = 0) -> None:
        import numpy as np

        self.node = node = Ros2Node("autoscoop_fault_relay")
        self.bool = Bool
        self.topics = topics = topics or TopicsSection()
        self.rng = np.random.default_rng(seed)
        self.lock = threading.Lock()
        self.fault = None
        self.last: dict[str, Any] = {}
        self.last_sent: dict[str, float] = {}
        self.relayed = 0
        kinds = dict(sensor_messages(SensorReadings(0.0, ("lift", "tilt"), (0.0, 0.0), 0.0, 0.0, 0.0, 0.0, 0.0,
                                                    (0.0, 0.0, 0.0), (1.0, 0.0, 0.0, 0.0)), 1.0))
        self.writers = {name: node.publisher(getattr(topics, name), type(kinds[name]), TOPIC_QOS[name])
                        for name in SENSOR_TOPICS}
        self.writers["estop"] = node.publisher(topics.estop, Bool, LATCHED)
        self.publishers = {name: _Writer(writer) for name, writer in self.writers.items()}
        self.readers = [node.subscription(f"{source}/{getattr(topics, name)}", type(kinds[name]), TOPIC_QOS[name],
                                          lambda msg, name=name: self._relay(name, msg)) for name in SENSOR_TOPICS]

    def shifted(self, msg: Any, seconds: float) -> Any:
        return shifted(msg, seconds)

    def stamp_age(self, msg: Any) -> float:
        return time.time() - msg.header.stamp.to_seconds()

    def wait_connected(self, timeout_s: float = 60.0) -> None:
        """Wait until the simulator publishes to the relay and the controller listens to it."""
        deadline = time.monotonic() + timeout_s
        for writer in self.writers.values():
            if not self.node.wait_for_subscriber(writer, max(0.0, deadline - time.monotonic())):
                raise TimeoutError("the controller does not listen to the relay")
        while len(self.last) < len(SENSOR_TOPICS):
            if time.monotonic() > deadline:
                raise TimeoutError("the simulator does not publish to the relay")
            time.sleep(0.05)

    def close(self) -> None:
        """Stop relaying."""
        self.node.close()
