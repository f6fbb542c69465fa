"""What every middleware front end of the controller shares: message fields to the core, under a lock, and the loop.

A front end (``ros1.controller_node``, ``ros2.controller_node``) subclasses :class:`ControllerLoop`,
subscribes its ``on_*`` callbacks to the topics, and supplies the few things that differ between
middlewares: the stamp of a header, the node's ROS clock, how to publish a command, and whether the
node is shutting down. The messages it hands over need only the fields of the standard ROS message
types (``msg.header``, ``msg.position``, ``msg.data`` ...), which ROS 1 and ROS 2 share.
"""

from __future__ import annotations

import math
import threading
import time
from collections.abc import Callable
from typing import Any

from autoscoop.core.payload import pitch_from_quaternion
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.safety import Command, Stamp

LONGEST_SLEEP_S = 0.1
"""The loop never sleeps longer than this, so a shutdown is noticed quickly."""


def status_line(command: Command) -> str:
    """The node's status for a command: its mode, and why the robot is stopped (``fault: odom stale``)."""
    return command.mode + (f": {command.reason}" if command.reason else "")


class ControllerLoop:
    """One callback per input, and :meth:`spin` for the loop, around a :class:`ControllerCore`.

    Every callback hands its message to the core under one lock with the time it arrived (and its
    stamp, where it has a header), and wakes the loop when the message may stop the robot (a refused
    reading, ``estop``, ``scoop``); the loop runs :meth:`ControllerCore.update` at the core's wake-up
    times and publishes what it returns.

    Args:
        core: the controller's logic, built and checked.
        node_name: the node's name, for the log.
        clock: monotonic seconds, for the watchdog.
    """

    def __init__(self, core: ControllerCore, node_name: str, clock: Callable[[], float] = time.monotonic) -> None:
        self.core = core
        self.node_name = node_name
        self.clock = clock
        self.lock = threading.Lock()
        """held while the core is used: the callbacks run on the middleware's threads"""
        self.wake = threading.Event()
        self.update_time = math.nan
        """the core's clock at the update whose command :meth:`publish` is publishing, s"""

    # ---------------------------------------------------------------- what a middleware supplies
    def header_seconds(self, header: Any) -> float:
        """A message header's stamp, s on the sender's ROS clock (0: not stamped)."""
        raise NotImplementedError

    def ros_time(self) -> float:
        """The node's ROS clock now, s."""
        raise NotImplementedError

    def publish(self, command: Command) -> None:
        """Publish a command the core returned."""
        raise NotImplementedError

    def shutting_down(self) -> bool:
        """Whether the node is going down (the loop ends)."""
        raise NotImplementedError

    def log_info(self, text: str) -> None:
        """Log a line at the info level."""
        raise NotImplementedError

    def observe(self, name: str, msg: Any, now: float) -> None:
        """Called, under the lock, with every input message as it is handed to the core at ``now`` (the
        core's clock), by topic key; a recorder overrides it. Nothing by default."""

    # ---------------------------------------------------------------- callbacks (the middleware's threads)
    def _stamped(self, name: str, msg: Any, handler: Callable[[float, Stamp], bool]) -> None:
        """Feed a message with a header: its stamp and the ROS clock are read with the arrival time; the
        transport delay (stamp -> arrival) of each reading taken is noted for the records."""
        def with_stamp(now: float) -> bool:
            stamp = Stamp(self.header_seconds(msg.header), self.ros_time())
            taken = handler(now, stamp)
            if taken:
                self.core.transport_delay(name, stamp.age_s)
            return taken
        self._feed(name, msg, with_stamp)

    def _feed(self, name: str, msg: Any, handler: Callable[[float], bool | None], always_wake: bool = False) -> None:
        with self.lock:
            now = self.clock()
            self.observe(name, msg, now)
            ok = handler(now)
        if always_wake or ok is False:
            self.wake.set()

    def on_joint_states(self, msg: Any) -> None:
        """``sensor_msgs/JointState``."""
        self._stamped("joint_states", msg, lambda now, stamp: self.core.joint_states(msg.name, msg.position, now, stamp))

    def on_odom(self, msg: Any) -> None:
        """``nav_msgs/Odometry``: the forward speed, and the chassis pitch of the orientation."""
        q = msg.pose.pose.orientation
        self._stamped("odom", msg, lambda now, stamp: self.core.odometry(
            msg.twist.twist.linear.x, now, pitch_from_quaternion(q.w, q.x, q.y, q.z), stamp))

    def on_range(self, msg: Any) -> None:
        """``sensor_msgs/Range``."""
        self._stamped("pile_range", msg, lambda now, stamp: self.core.pile_range(
            msg.range, now, msg.min_range, msg.max_range, stamp))

    def on_tilt_torque(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``bucket_torque``: the tilt torque, N*m."""
        self._feed("bucket_torque", msg, lambda now: self.core.bucket_torque(msg.data, now))

    def on_lift_torque(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``lift_torque``, N*m."""
        self._feed("lift_torque", msg, lambda now: self.core.lift_torque(msg.data, now))

    def on_mass(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``payload_mass``, kg."""
        self._feed("payload_mass", msg, lambda now: self.core.payload_mass(msg.data, now))

    def on_estop(self, msg: Any) -> None:
        """``std_msgs/Bool``."""
        self._feed("estop", msg, lambda now: self.core.estop(msg.data, now), always_wake=True)

    def on_scoop(self, msg: Any) -> None:
        """``std_msgs/Bool``."""
        self._feed("scoop", msg, lambda now: self.core.scoop(msg.data, now), always_wake=True)

    def input_callbacks(self, needed_payload: tuple[str, ...]) -> dict[str, Callable[[Any], None]]:
        """The callback of each input topic (keys of ``robot_config.TOPIC_DEFAULTS``), the payload's
        only where ``needed_payload`` (:func:`~autoscoop.deploy.controller.payload_inputs`) names them."""
        payload = {"bucket_torque": self.on_tilt_torque, "lift_torque": self.on_lift_torque,
                   "payload_mass": self.on_mass}
        return {"joint_states": self.on_joint_states, "odom": self.on_odom, "pile_range": self.on_range,
                **{name: callback for name, callback in payload.items() if name in needed_payload},
                "estop": self.on_estop, "scoop": self.on_scoop}

    # ---------------------------------------------------------------- the loop
    def run_loop(self) -> None:
        """Run until :meth:`shutting_down`: update the core at its wake-up times and publish its commands."""
        core, clock = self.core, self.clock
        self.log_info(f"{self.node_name}: policy {core.policy_name}, control period {core.period_s:g} s, "
                      f"input timeout {core.config.control.input_timeout_s:g} s; waiting for inputs")
        while not self.shutting_down():
            self.wake.clear()
            with self.lock:
                now = clock()
                command = core.update(now)
                wake_at = core.next_wakeup(now)
            if command is not None:
                self.update_time = now
                self.publish(command)
            self.wake.wait(min(max(wake_at - clock(), 0.0), LONGEST_SLEEP_S))
