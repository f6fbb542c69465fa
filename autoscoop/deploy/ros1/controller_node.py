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

import time
from collections.abc import Callable
from typing import Any

from autoscoop.deploy.controller import ControllerCore, payload_inputs
from autoscoop.deploy.controller_loop import ControllerLoop, status_line
from autoscoop.deploy.robot_config import robot_yaml
from autoscoop.deploy.ros1 import import_rospy, publishers, subscribers
from autoscoop.deploy.safety import Command

NODE_NAME = "autoscoop_controller"


class ControllerNode(ControllerLoop):
    """The rospy front end of a :class:`ControllerCore`: the callbacks and the loop of
    :class:`~autoscoop.deploy.controller_loop.ControllerLoop` on rospy's topics.

    Args:
        core: the controller's logic, built and checked.
        argv: command-line arguments with ROS remappings (``name:=new``); default ``sys.argv``.
        node_name: the node's name (``__name:=`` overrides it).
        clock: monotonic seconds, for the watchdog.
    """

    def __init__(self, core: ControllerCore, argv: list[str] | None = None, node_name: str = NODE_NAME,
                 clock: Callable[[], float] = time.monotonic) -> None:
        super().__init__(core, node_name, clock)
        self.rospy = rospy = import_rospy()
        from std_msgs.msg import String  # noqa: PLC0415

        self.last_status: str | None = None
        rospy.init_node(node_name, argv=argv, anonymous=False)
        levels = {"info": rospy.loginfo, "warn": rospy.logwarn, "error": rospy.logerr}
        core.log = lambda level, text: levels.get(level, rospy.loginfo)(text)
        rospy.set_param("~policy", core.policy_name)
        rospy.set_param("~robot", robot_yaml(core.config))  # the simulator checks its readings' units against it
        topics = core.config.topics
        self.commands = publishers(topics, ("cmd_vel", "lift_command", "tilt_command"), queue_size=10,
                                   tcp_nodelay=False)
        self.status = rospy.Publisher("~status", String, queue_size=10, latch=True)
        self.subscribers = subscribers(topics, self.input_callbacks(payload_inputs(core.config.payload)))

    # ---------------------------------------------------------------- ControllerLoop's hooks
    def header_seconds(self, header: Any) -> float:
        return header.stamp.to_sec()

    def ros_time(self) -> float:
        return self.rospy.get_time()

    def shutting_down(self) -> bool:
        return self.rospy.is_shutdown()

    def log_info(self, text: str) -> None:
        self.rospy.loginfo(text)

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
        text = status_line(command)
        if text != self.last_status:
            self.status.publish(String(text))
            self.last_status = text

    def spin(self) -> int:
        """Run until ROS shuts down; the exit code. Ends a running scoop (its record is written) on the way out."""
        try:
            self.run_loop()
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
