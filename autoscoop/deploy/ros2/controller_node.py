"""``autoscoop ros2 controller``: the controller as a ROS 2 node on Cyclone DDS (front end of ControllerCore).

Subscribes and publishes the topics of ``autoscoop ros controller`` (names from the robot YAML's
``topics``, relative to the node's namespace, remappable with ``from:=to``), with ROS 2's QoS
(:mod:`autoscoop.deploy.ros2.graph`); publishes ``~/status`` (std_msgs/String, latched: the mode and why
the robot is stopped) and ``~/policy`` (std_msgs/String, latched: the policy's name, which ``ros2 sim``
reads for its summary) and ``~/robot`` (std_msgs/String, latched: the robot file as YAML, which ``ros2 sim``
checks its readings' units against, and which the bag keeps for ``autoscoop replay``). The e-stop is read twice, transient-local (the latched value of a
transient-local publisher) and volatile (a publisher with the default profile): either way it is heard.

Stamps are judged on the ROS 2 clock (the system clock, as ROS 2 nodes without ``use_sim_time``).
All logic is in :mod:`autoscoop.deploy.controller`; the callbacks and the loop in
:mod:`autoscoop.deploy.controller_loop`.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from autoscoop.deploy.controller import ControllerCore, payload_inputs
from autoscoop.deploy.controller_loop import ControllerLoop, status_line
from autoscoop.deploy.robot_config import robot_yaml
from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, TOPIC_QOS, Ros2Node
from autoscoop.deploy.ros2.mcap_log import McapLog, monotonic_offset_ns, wall_clock_ns
from autoscoop.deploy.ros2.messages import MESSAGE_TYPES, Float64, String, Twist, Vector3
from autoscoop.deploy.safety import Command

NODE_NAME = "autoscoop_controller"
LOG_LEVELS = ("info", "warn", "error")


class ControllerNode(ControllerLoop):
    """The Cyclone DDS front end of a :class:`ControllerCore`.

    Args:
        core: the controller's logic, built and checked.
        remaps: ``from:=to`` arguments (``__ns:=``, ``__node:=`` included).
        node_name: the node's name.
        namespace: the node's namespace (default: ``__ns:=``, ``ROS_NAMESPACE`` or ``/``).
        clock: monotonic seconds, for the watchdog.
        ros_clock: the ROS 2 clock, s since the epoch (the system clock).
        log: where to record every input as handed to the core and every command as the core made it,
            each at that moment of the core's clock put on the wall clock (so a replay sees the same order).
    """

    def __init__(self, core: ControllerCore, remaps: Iterable[str] = (), node_name: str = NODE_NAME,
                 namespace: str | None = None, clock: Callable[[], float] = time.monotonic,
                 ros_clock: Callable[[], float] = time.time, log: McapLog | None = None) -> None:
        self.node = node = Ros2Node(node_name, remaps, namespace)
        super().__init__(core, node.name, clock)
        self.ros_clock = ros_clock
        self.log = log
        self.clock_offset_ns = monotonic_offset_ns()
        self.stopping = threading.Event()
        self.last_status: str | None = None
        core.log = lambda level, text: print(f"[{level if level in LOG_LEVELS else 'info'}] {text}", flush=True)
        topics = core.config.topics
        self.commands = {key: node.publisher(getattr(topics, key), MESSAGE_TYPES[key], COMMANDS)
                         for key in ("cmd_vel", "lift_command", "tilt_command")}
        self.status = node.publisher("~/status", String, LATCHED)
        node.publisher("~/policy", String, LATCHED).write(String(core.policy_name))
        robot = String(robot_yaml(core.config))
        node.publisher("~/robot", String, LATCHED).write(robot)
        if log is not None:
            log.write(node.resolve("~/robot"), robot)
        for key, callback in self.input_callbacks(payload_inputs(core.config.payload)).items():
            node.subscription(getattr(topics, key), MESSAGE_TYPES[key], TOPIC_QOS[key], callback)
        node.subscription(topics.estop, MESSAGE_TYPES["estop"], COMMANDS, self.on_estop)

    # ---------------------------------------------------------------- ControllerLoop's hooks
    def header_seconds(self, header: Any) -> float:
        return header.stamp.to_seconds()

    def ros_time(self) -> float:
        return self.ros_clock()

    def shutting_down(self) -> bool:
        return self.stopping.is_set()

    def log_info(self, text: str) -> None:
        print(f"[info] {text}", flush=True)

    def observe(self, name: str, msg: Any, now: float) -> None:
        self._record(name, msg, now)

    def _record(self, key: str, message: Any, now: float) -> None:
        if self.log is not None:
            topic = self.node.resolve(getattr(self.core.config.topics, key))
            self.log.write(topic, message, wall_clock_ns(now, self.clock_offset_ns))

    def _write(self, key: str, message: Any) -> None:
        self.commands[key].write(message)
        self._record(key, message, self.update_time)

    def publish(self, command: Command) -> None:
        """Publish a command: the speed always, the arm when it has one, the status when it changed."""
        self._write("cmd_vel", Twist(linear=Vector3(x=command.speed_mps)))
        if command.lift_rad is not None:
            self._write("lift_command", Float64(command.lift_rad))
            self._write("tilt_command", Float64(command.tilt_rad))
        text = status_line(command)
        if text != self.last_status:
            self.status.write(String(text))
            self.last_status = text

    def spin(self) -> int:
        """Run until :meth:`stop` (or Ctrl-C); the exit code. Ends a running scoop (its record is written),
        stops the robot once more and leaves the DDS domain on the way out."""
        try:
            self.run_loop()
        except KeyboardInterrupt:
            pass
        finally:
            self.close()
        return 0

    def stop(self) -> None:
        """Ask :meth:`spin` to return (from any thread)."""
        self.stopping.set()
        self.wake.set()

    def close(self) -> None:
        """End the scoop, publish a last stop, and delete the node's participant."""
        with self.lock:
            self.core.close(self.clock())
        self.update_time = self.clock()
        self._write("cmd_vel", Twist())
        self.node.close()
        if self.log is not None:
            self.log.close()
