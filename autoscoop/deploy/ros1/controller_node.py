"""``autoscoop ros controller``: the controller as a ROS 1 node (rospy front end of ControllerCore).

Subscribes (relative names, remappable with ``name:=new``): ``joint_states``, ``odom``, ``pile_range``,
``bucket_torque`` (the tilt torque) and ``lift_torque`` (``bucket_torque`` alone with ``payload.method: eq4``,
``payload_mass`` instead with ``payload.source: topic``), ``estop``, ``scoop``. Publishes: ``cmd_vel``,
``lift_controller/command``, ``tilt_controller/command``, and ``~status`` (std_msgs/String, latched:
the mode and why the robot is stopped). All logic is in :mod:`autoscoop.deploy.controller`; this
module (:class:`ControllerNode`) converts messages and keeps time: each message goes to the core with
its arrival on the monotonic clock and, for ``joint_states``, ``odom`` and ``pile_range``, its header
stamp with the ROS clock (``rospy.get_time()``) at arrival, so the watchdog judges their age by the stamp.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from typing import Any

from autoscoop.core.payload import pitch_from_quaternion
from autoscoop.deploy.controller import ControllerCore, payload_inputs
from autoscoop.deploy.ros1 import import_rospy, publishers, subscribers
from autoscoop.deploy.safety import Command, Stamp

NODE_NAME = "autoscoop_controller"
LONGEST_SLEEP_S = 0.1
"""The loop never sleeps longer than this, so a shutdown is noticed quickly."""


class ControllerNode:
    """The rospy front end of a :class:`ControllerCore`: one callback per input, :meth:`spin` for the loop.

    Every callback hands its message to the core under one lock with the time it arrived (and its
    stamp, where it has a header), and wakes the loop when the message may stop the robot (a refused
    reading, ``estop``, ``scoop``); the loop runs
    :meth:`ControllerCore.update` at the core's wake-up times and publishes what it returns.

    Args:
        core: the controller's logic, built and checked.
        argv: command-line arguments with ROS remappings (``name:=new``); default ``sys.argv``.
        node_name: the node's name (``__name:=`` overrides it).
        clock: monotonic seconds, for the watchdog.
    """

    def __init__(self, core: ControllerCore, argv: list[str] | None = None, node_name: str = NODE_NAME,
                 clock: Callable[[], float] = time.monotonic) -> None:
        self.rospy = rospy = import_rospy()
        from std_msgs.msg import String  # noqa: PLC0415

        self.core = core
        self.clock = clock
        self.node_name = node_name
        self.lock = threading.Lock()
        """held while the core is used: the callbacks run on rospy's threads"""
        self.wake = threading.Event()
        self.last_status: str | None = None
        rospy.init_node(node_name, argv=argv, anonymous=False)
        levels = {"info": rospy.loginfo, "warn": rospy.logwarn, "error": rospy.logerr}
        core.log = lambda level, text: levels.get(level, rospy.loginfo)(text)
        rospy.set_param("~policy", core.policy_name)
        topics = core.config.topics
        self.commands = publishers(topics, ("cmd_vel", "lift_command", "tilt_command"), queue_size=10,
                                   tcp_nodelay=False)
        self.status = rospy.Publisher("~status", String, queue_size=10, latch=True)
        payload = {"bucket_torque": self.on_tilt_torque, "lift_torque": self.on_lift_torque,
                   "payload_mass": self.on_mass}
        needed = payload_inputs(core.config.payload)
        self.subscribers = subscribers(topics, {
            "joint_states": self.on_joint_states, "odom": self.on_odom, "pile_range": self.on_range,
            **{name: callback for name, callback in payload.items() if name in needed},
            "estop": self.on_estop, "scoop": self.on_scoop})

    # ---------------------------------------------------------------- callbacks (rospy's threads)
    def _stamped(self, name: str, header: Any, handler: Callable[[float, Stamp], bool]) -> None:
        """Feed a message with a header: its stamp and the ROS clock are read with the arrival time; the
        transport delay (stamp -> arrival) of each reading taken is noted for the records."""
        def with_stamp(now: float) -> bool:
            stamp = Stamp(header.stamp.to_sec(), self.rospy.get_time())
            taken = handler(now, stamp)
            if taken:
                self.core.transport_delay(name, stamp.age_s)
            return taken
        self._feed(with_stamp)

    def _feed(self, handler: Callable[[float], bool | None], always_wake: bool = False) -> None:
        with self.lock:
            ok = handler(self.clock())
        if always_wake or ok is False:
            self.wake.set()

    def on_joint_states(self, msg: Any) -> None:
        """``sensor_msgs/JointState``."""
        self._stamped("joint_states", msg.header,
                      lambda now, stamp: self.core.joint_states(msg.name, msg.position, now, stamp))

    def on_odom(self, msg: Any) -> None:
        """``nav_msgs/Odometry``: the forward speed, and the chassis pitch of the orientation."""
        q = msg.pose.pose.orientation
        self._stamped("odom", msg.header, lambda now, stamp: self.core.odometry(
            msg.twist.twist.linear.x, now, pitch_from_quaternion(q.w, q.x, q.y, q.z), stamp))

    def on_range(self, msg: Any) -> None:
        """``sensor_msgs/Range``."""
        self._stamped("pile_range", msg.header, lambda now, stamp: self.core.pile_range(
            msg.range, now, msg.min_range, msg.max_range, stamp))

    def on_tilt_torque(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``bucket_torque``: the tilt torque, N*m."""
        self._feed(lambda now: self.core.bucket_torque(msg.data, now))

    def on_lift_torque(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``lift_torque``, N*m."""
        self._feed(lambda now: self.core.lift_torque(msg.data, now))

    def on_mass(self, msg: Any) -> None:
        """``std_msgs/Float64`` on ``payload_mass``, kg."""
        self._feed(lambda now: self.core.payload_mass(msg.data, now))

    def on_estop(self, msg: Any) -> None:
        """``std_msgs/Bool``."""
        self._feed(lambda now: self.core.estop(msg.data, now), always_wake=True)

    def on_scoop(self, msg: Any) -> None:
        """``std_msgs/Bool``."""
        self._feed(lambda now: self.core.scoop(msg.data, now), always_wake=True)

    # ---------------------------------------------------------------- the loop
    def publish(self, command: Command) -> None:
        """Publish a command: the speed always, the arm when it has one, the status when it changed."""
        from geometry_msgs.msg import Twist  # noqa: PLC0415
        from std_msgs.msg import Float64, String  # noqa: PLC0415

        twist = Twist()
        twist.linear.x = command.speed_mps
        self.commands["cmd_vel"].publish(twist)
        if command.lift_rad is not None:
            self.commands["lift_command"].publish(Float64(command.lift_rad))
            self.commands["tilt_command"].publish(Float64(command.tilt_rad))
        text = command.mode + (f": {command.reason}" if command.reason else "")
        if text != self.last_status:
            self.status.publish(String(text))
            self.last_status = text

    def spin(self) -> int:
        """Run until ROS shuts down; the exit code. Ends a running scoop (its record is written) on the way out."""
        rospy, core, clock = self.rospy, self.core, self.clock
        rospy.loginfo(f"{self.node_name}: policy {core.policy_name}, control period {core.period_s:g} s, "
                      f"input timeout {core.config.control.input_timeout_s:g} s; waiting for inputs")
        try:
            while not rospy.is_shutdown():
                self.wake.clear()
                with self.lock:
                    now = clock()
                    command = core.update(now)
                    wake_at = core.next_wakeup(now)
                if command is not None:
                    self.publish(command)
                self.wake.wait(min(max(wake_at - clock(), 0.0), LONGEST_SLEEP_S))
        finally:
            self.close()
        return 0

    def close(self) -> None:
        """Unsubscribe, end the scoop, and stop the robot once more if ROS is going down."""
        from geometry_msgs.msg import Twist  # noqa: PLC0415

        rospy = self.rospy
        for subscriber in self.subscribers.values():
            subscriber.unregister()
        with self.lock:
            self.core.close(self.clock())
        if not rospy.is_shutdown():
            rospy.signal_shutdown("controller stopped")
        else:  # one last stop: the node is going away
            try:
                self.commands["cmd_vel"].publish(Twist())
            except rospy.ROSException:
                pass
