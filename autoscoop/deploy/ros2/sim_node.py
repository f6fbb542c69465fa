"""``autoscoop ros2 sim``: the MuJoCo scene as a ROS 2 node on Cyclone DDS, behind the robot's topics.

Publishes what ``autoscoop ros sim`` publishes (``joint_states``, ``odom``, ``pile_range``,
``bucket_torque``, ``lift_torque``, ``payload_mass`` every sensor period, best effort; ``scoop``,
reliable), stamped on the ROS 2 clock (the system clock), and obeys ``cmd_vel``,
``lift_controller/command`` and ``tilt_controller/command``. The episodes' timing is
:class:`~autoscoop.deploy.sim_loop.SimLoop`'s. A controller counts as present once it reads
``scoop``; the autoscoop controller's policy name is read from its latched ``autoscoop_controller/policy``,
and its robot file from ``autoscoop_controller/robot``: a controller that reads the joints in other units
(raw potentiometer readings against radians) is refused before the first scoop.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable, Iterable
from typing import Any

from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, TOPIC_QOS, Ros2Node, take_all
from autoscoop.deploy.ros2.mcap_log import McapLog
from autoscoop.deploy.ros2.messages import (
    MESSAGE_TYPES,
    Bool,
    Float64,
    Header,
    JointState,
    Odometry,
    Point,
    Pose,
    PoseWithCovariance,
    Quaternion,
    Range,
    String,
    Time,
    Twist,
    TwistWithCovariance,
    Vector3,
)
from autoscoop.deploy.sim_bridge import SensorReadings, SimBridge
from autoscoop.deploy.sim_loop import SimLoop

NODE_NAME = "autoscoop_sim"
CONTROLLER_NODE = "autoscoop_controller"
SENSOR_TOPICS = ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque", "payload_mass")
POLICY_WAIT_S = 1.0
"""How long the latched policy name and robot file of a controller that has appeared are waited for, s."""


def sensor_messages(r: SensorReadings, stamp_s: float) -> list[tuple[str, Any]]:
    """The ROS 2 sensor messages of one set of readings, stamped ``stamp_s`` (s on the ROS 2 clock), by topic key."""
    stamp = Time.from_seconds(stamp_s)
    x, y, z = r.chassis_xyz_m
    w, qx, qy, qz = r.chassis_quat_wxyz
    odom = Odometry(header=Header(stamp, "odom"), child_frame_id="base_link",
                    pose=PoseWithCovariance(pose=Pose(Point(x, y, z), Quaternion(qx, qy, qz, w))),
                    twist=TwistWithCovariance(twist=Twist(linear=Vector3(x=r.speed_mps))))
    return [("joint_states", JointState(header=Header(stamp, ""), name=list(r.joint_names),
                                        position=[float(p) for p in r.joint_positions])),
            ("odom", odom),
            ("pile_range", Range(header=Header(stamp, "bucket_tip"), radiation_type=Range.INFRARED,
                                 field_of_view=0.05, min_range=0.0, max_range=4.0, range=float(r.range_m))),
            ("bucket_torque", Float64(float(r.tilt_torque_nm))), ("lift_torque", Float64(float(r.lift_torque_nm))),
            ("payload_mass", Float64(float(r.payload_kg)))]


class SimNode(SimLoop):
    """The simulator behind the robot's ROS 2 topics: :class:`~autoscoop.deploy.sim_loop.SimLoop` on Cyclone DDS.

    Args:
        bridge: the simulator.
        delay_s: delay of every sensor message, s; default: the bridge's ``sensor.delay_s``.
        remaps: ``from:=to`` arguments (``__ns:=``, ``__node:=`` included).
        node_name: the node's name.
        namespace: the node's namespace (default: ``__ns:=``, ``ROS_NAMESPACE`` or ``/``).
        ros_clock: the ROS 2 clock, s since the epoch (the system clock).
        log: where to record every message published (when published) and every command (when it arrived).
    """

    def __init__(self, bridge: SimBridge, delay_s: float | None = None, remaps: Iterable[str] = (),
                 node_name: str = NODE_NAME, namespace: str | None = None,
                 ros_clock: Callable[[], float] = time.time, log: McapLog | None = None) -> None:
        super().__init__(bridge, delay_s, log)
        self.node = node = Ros2Node(node_name, remaps, namespace)
        self.ros_clock = ros_clock
        self.stopping = threading.Event()
        self.sensors = {key: node.publisher(getattr(self.topics, key), MESSAGE_TYPES[key], TOPIC_QOS[key])
                        for key in SENSOR_TOPICS}
        self.scoop = node.publisher(self.topics.scoop, Bool, COMMANDS)
        for key, callback in self.command_callbacks().items():
            node.subscription(getattr(self.topics, key), MESSAGE_TYPES[key], TOPIC_QOS[key], callback)

    # ---------------------------------------------------------------- SimLoop's hooks
    def messages(self, r: SensorReadings) -> list[tuple[str, object]]:
        return sensor_messages(r, self.ros_clock())

    def publish_sensor(self, name: str, msg: Any) -> None:
        self.sensors[name].write(msg)

    def publish_scoop(self, start: bool) -> Bool:
        message = Bool(start)
        self.scoop.write(message)
        return message

    def topic_name(self, key: str) -> str:
        return self.node.resolve(getattr(self.topics, key))

    def shutting_down(self) -> bool:
        return self.stopping.is_set()

    def log_info(self, text: str) -> None:
        print(f"[info] {text}", flush=True)

    def wait_for_controller(self, timeout_s: float) -> None:
        if not self.node.wait_for_subscriber(self.scoop, timeout_s):
            raise TimeoutError(f"no controller subscribed to {self.node.resolve(self.topics.scoop)} within "
                               f"{timeout_s:g} s (ROS_DOMAIN_ID {self.node.domain}); start `autoscoop ros2 controller`")
        policy = self.node.subscription(f"{CONTROLLER_NODE}/policy", String, LATCHED)
        robot = self.node.subscription(f"{CONTROLLER_NODE}/robot", String, LATCHED)
        deadline = time.monotonic() + POLICY_WAIT_S
        while time.monotonic() < deadline and (self.stats.controller_policy is None
                                               or self.stats.controller_robot is None):
            names, robots = take_all(policy, String), take_all(robot, String)
            if names:
                self.stats.controller_policy = names[-1].data
            if robots:
                self.stats.controller_robot = robots[-1].data
            time.sleep(0.02)

    def robot_message(self, text: str) -> tuple[str, String]:
        return self.node.resolve("~/robot"), String(text)

    def stop(self) -> None:
        """Ask :meth:`run` to end after the current step (from any thread)."""
        self.stopping.set()

    def close_transport(self) -> None:
        self.node.close()
