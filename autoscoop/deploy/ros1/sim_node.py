"""``autoscoop ros sim``: the MuJoCo scene as a ROS 1 node behind the robot's topics (like the paper's Gazebo).

Publishes ``joint_states``, ``odom``, ``pile_range``, ``bucket_torque``, ``lift_torque`` and ``payload_mass`` (the true
mass in the bucket, for a controller with ``payload.source: topic``) every sensor period (about 48 Hz)
in real time, each after the configured delay, and ``scoop`` (std_msgs/Bool): true when an
episode starts, false when it ends. Obeys ``cmd_vel``, ``lift_controller/command`` and
``tilt_controller/command``. Between episodes it resets the scene, holds the physics still while it
publishes the new scene's readings (so the controller's inputs are fresh), then starts the next
episode; commands that arrive while it is held are ignored.

The episodes' timing is :class:`~autoscoop.deploy.sim_loop.SimLoop`'s.
"""

from __future__ import annotations

import time
from typing import Any

from autoscoop.deploy.ros1 import import_rospy, publishers, subscribers
from autoscoop.deploy.sim_bridge import SensorReadings, SimBridge
from autoscoop.deploy.sim_loop import BagLog, SimLoop

NODE_NAME = "autoscoop_sim"


class SimNode(SimLoop):
    """The simulator behind the robot's ROS 1 topics: :class:`~autoscoop.deploy.sim_loop.SimLoop` on rospy.

    Args:
        bridge: the simulator.
        delay_s: delay of every sensor message, s; default: the bridge's ``sensor.delay_s``.
        argv: command-line arguments with ROS remappings; default ``sys.argv``.
        node_name: the node's name.
        log: a ROS 1 bag (:class:`~autoscoop.deploy.ros1.bag_log.Ros1BagLog`) for every message published and
            every command received.
    """

    def __init__(self, bridge: SimBridge, delay_s: float | None = None, argv: list[str] | None = None,
                 node_name: str = NODE_NAME, log: BagLog | None = None) -> None:
        super().__init__(bridge, delay_s, log)
        self.rospy = rospy = import_rospy()
        topics = self.topics
        rospy.init_node(node_name, argv=argv, anonymous=False)
        self.sensors = publishers(topics, ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque",
                                           "payload_mass"))
        self.scoop = publishers(topics, ("scoop",), queue_size=10)["scoop"]
        self.subscribers = subscribers(topics, self.command_callbacks())

    # ---------------------------------------------------------------- SimLoop's hooks
    def messages(self, r: SensorReadings) -> list[tuple[str, object]]:
        """The sensor messages of one set of readings, stamped now."""
        from nav_msgs.msg import Odometry  # noqa: PLC0415
        from sensor_msgs.msg import JointState, Range  # noqa: PLC0415
        from std_msgs.msg import Float64  # noqa: PLC0415

        stamp = self.rospy.Time.now()
        joints = JointState(name=list(r.joint_names), position=list(r.joint_positions))
        joints.header.stamp = stamp
        odom = Odometry()
        odom.header.stamp, odom.header.frame_id, odom.child_frame_id = stamp, "odom", "base_link"
        odom.pose.pose.position.x, odom.pose.pose.position.y, odom.pose.pose.position.z = r.chassis_xyz_m
        q = odom.pose.pose.orientation
        q.w, q.x, q.y, q.z = r.chassis_quat_wxyz
        odom.twist.twist.linear.x = r.speed_mps
        distance = Range(radiation_type=Range.INFRARED, field_of_view=0.05, min_range=0.0, max_range=4.0,
                         range=r.range_m)
        distance.header.stamp, distance.header.frame_id = stamp, "bucket_tip"
        return [("joint_states", joints), ("odom", odom), ("pile_range", distance),
                ("bucket_torque", Float64(r.tilt_torque_nm)), ("lift_torque", Float64(r.lift_torque_nm)),
                ("payload_mass", Float64(r.payload_kg))]

    def publish_sensor(self, name: str, msg: Any) -> None:
        self.sensors[name].publish(msg)

    def publish_scoop(self, start: bool) -> Any:
        from std_msgs.msg import Bool  # noqa: PLC0415

        message = Bool(start)
        self.scoop.publish(message)
        return message

    def topic_name(self, key: str) -> str:
        return self.rospy.resolve_name(getattr(self.topics, key))

    def shutting_down(self) -> bool:
        return self.rospy.is_shutdown()

    def log_info(self, text: str) -> None:
        self.rospy.loginfo(text)

    def close_transport(self) -> None:
        for subscriber in self.subscribers.values():
            subscriber.unregister()
        if not self.rospy.is_shutdown():
            self.rospy.signal_shutdown("simulation finished")

    def wait_for_controller(self, timeout_s: float) -> None:
        """Wait until a controller subscribes to ``scoop``; note its ``~policy`` and ``~robot`` parameters if it
        has them."""
        rospy = self.rospy
        waited = time.monotonic()
        while self.scoop.get_num_connections() == 0 and not rospy.is_shutdown():
            if time.monotonic() - waited > timeout_s:
                raise TimeoutError(f"no controller subscribed to {rospy.resolve_name(self.topics.scoop)} within "
                                   f"{timeout_s:g} s; start `autoscoop ros controller`")
            time.sleep(0.05)
        for node in _publishers_of(rospy, self.topics.cmd_vel):
            try:
                self.stats.controller_policy = str(rospy.get_param(f"{node}/policy"))
            except KeyError:
                continue
            try:
                self.stats.controller_robot = str(rospy.get_param(f"{node}/robot"))
            except KeyError:
                pass
            break

    def robot_message(self, text: str) -> tuple[str, object]:
        from std_msgs.msg import String  # noqa: PLC0415

        return self.rospy.resolve_name("~robot"), String(data=text)


def _publishers_of(rospy, topic: str) -> list[str]:
    """Names of the nodes that publish ``topic`` (from the master)."""
    import rosgraph  # noqa: PLC0415 - comes with rospy

    name = rospy.resolve_name(topic)
    try:
        published, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    except (rosgraph.MasterError, OSError):
        return []
    return next((nodes for t, nodes in published if t == name), [])
