"""``autoscoop ros controller``: the controller as a ROS 1 node (rospy front end of ControllerCore).

Subscribes (relative names, remappable with ``name:=new``): ``joint_states``, ``odom``,
``pile_range``, ``bucket_torque`` and ``lift_torque`` (``bucket_torque`` alone with ``payload.method: eq4``,
``payload_mass`` instead with ``payload.source: topic``), ``estop``,
``scoop``. Publishes: ``cmd_vel``,
``lift_controller/command``, ``tilt_controller/command``, and ``~status`` (std_msgs/String, latched:
the mode and why the robot is stopped). All logic is in :mod:`autoscoop.deploy.controller`; this
module converts messages and keeps time.
"""

from __future__ import annotations

import threading
import time
from typing import Callable

from autoscoop.deploy.controller import ControllerCore, payload_inputs
from autoscoop.core.payload import pitch_from_quaternion
from autoscoop.deploy.ros1 import import_rospy
from autoscoop.deploy.safety import Command

NODE_NAME = "autoscoop_controller"
LONGEST_SLEEP_S = 0.1
"""The loop never sleeps longer than this, so a shutdown is noticed quickly."""


def run_controller_node(core: ControllerCore, argv: list[str] | None = None, node_name: str = NODE_NAME,
                        clock: Callable[[], float] = time.monotonic) -> int:
    """Run the node until ROS shuts down (Ctrl-C, SIGTERM, ``rosnode kill``); return an exit code.

    Args:
        core: the controller's logic, built and checked.
        argv: command-line arguments with ROS remappings (``name:=new``); default ``sys.argv``.
        node_name: the node's name (``__name:=`` overrides it).
        clock: monotonic seconds, for the watchdog.
    """
    rospy = import_rospy()
    from geometry_msgs.msg import Twist  # noqa: PLC0415
    from nav_msgs.msg import Odometry  # noqa: PLC0415
    from sensor_msgs.msg import JointState, Range  # noqa: PLC0415
    from std_msgs.msg import Bool, Float64, String  # noqa: PLC0415

    rospy.init_node(node_name, argv=argv, anonymous=False)
    levels = {"info": rospy.loginfo, "warn": rospy.logwarn, "error": rospy.logerr}
    core.log = lambda level, text: levels.get(level, rospy.loginfo)(text)
    topics = core.config.topics
    lock = threading.Lock()
    wake = threading.Event()
    rospy.set_param("~policy", core.policy_name)

    def stamped_delay(name: str, header) -> None:  # noqa: ANN001 - std_msgs/Header
        stamp = header.stamp.to_sec()
        if stamp > 0:
            core.transport_delay(name, rospy.get_time() - stamp)

    def feed(handler: Callable[[float], bool | None], always_wake: bool = False) -> None:
        with lock:
            ok = handler(clock())
        if always_wake or ok is False:
            wake.set()

    def on_joint_states(msg: JointState) -> None:
        stamped_delay("joint_states", msg.header)
        feed(lambda now: core.joint_states(msg.name, msg.position, now))

    def on_odom(msg: Odometry) -> None:
        stamped_delay("odom", msg.header)
        q = msg.pose.pose.orientation
        feed(lambda now: core.odometry(msg.twist.twist.linear.x, now, pitch_from_quaternion(q.w, q.x, q.y, q.z)))

    def on_range(msg: Range) -> None:
        stamped_delay("pile_range", msg.header)
        feed(lambda now: core.pile_range(msg.range, now, msg.min_range, msg.max_range))

    def on_torque(msg: Float64) -> None:
        feed(lambda now: core.bucket_torque(msg.data, now))

    def on_lift_torque(msg: Float64) -> None:
        feed(lambda now: core.lift_torque(msg.data, now))

    def on_mass(msg: Float64) -> None:
        feed(lambda now: core.payload_mass(msg.data, now))

    def on_estop(msg: Bool) -> None:
        feed(lambda now: core.estop(msg.data, now), always_wake=True)

    def on_scoop(msg: Bool) -> None:
        feed(lambda now: core.scoop(msg.data, now), always_wake=True)

    cmd_vel = rospy.Publisher(topics.cmd_vel, Twist, queue_size=10)
    lift_cmd = rospy.Publisher(topics.lift_command, Float64, queue_size=10)
    tilt_cmd = rospy.Publisher(topics.tilt_command, Float64, queue_size=10)
    status = rospy.Publisher("~status", String, queue_size=10, latch=True)
    needed = payload_inputs(core.config.payload)
    subscribers = [
        rospy.Subscriber(topics.joint_states, JointState, on_joint_states, queue_size=10, tcp_nodelay=True),
        rospy.Subscriber(topics.odom, Odometry, on_odom, queue_size=10, tcp_nodelay=True),
        rospy.Subscriber(topics.pile_range, Range, on_range, queue_size=10, tcp_nodelay=True),
        *([rospy.Subscriber(topics.bucket_torque, Float64, on_torque, queue_size=10, tcp_nodelay=True)]
          if "bucket_torque" in needed else []),
        *([rospy.Subscriber(topics.lift_torque, Float64, on_lift_torque, queue_size=10, tcp_nodelay=True)]
          if "lift_torque" in needed else []),
        *([rospy.Subscriber(topics.payload_mass, Float64, on_mass, queue_size=10, tcp_nodelay=True)]
          if "payload_mass" in needed else []),
        rospy.Subscriber(topics.estop, Bool, on_estop, queue_size=10, tcp_nodelay=True),
        rospy.Subscriber(topics.scoop, Bool, on_scoop, queue_size=10, tcp_nodelay=True),
    ]
    rospy.loginfo(f"{node_name}: policy {core.policy_name}, control period {core.period_s:g} s, "
                  f"input timeout {core.config.control.input_timeout_s:g} s; waiting for inputs")

    last_status = None

    def publish(command: Command) -> None:
        nonlocal last_status
        twist = Twist()
        twist.linear.x = command.speed_mps
        cmd_vel.publish(twist)
        if command.lift_rad is not None:
            lift_cmd.publish(Float64(command.lift_rad))
            tilt_cmd.publish(Float64(command.tilt_rad))
        text = command.mode + (f": {command.reason}" if command.reason else "")
        if text != last_status:
            status.publish(String(text))
            last_status = text

    try:
        while not rospy.is_shutdown():
            wake.clear()
            with lock:
                now = clock()
                command = core.update(now)
                wake_at = core.next_wakeup(now)
            if command is not None:
                publish(command)
            wake.wait(min(max(wake_at - clock(), 0.0), LONGEST_SLEEP_S))
    finally:
        for subscriber in subscribers:
            subscriber.unregister()
        with lock:
            core.close(clock())
        if not rospy.is_shutdown():
            rospy.signal_shutdown("controller stopped")
        else:  # one last stop: the node is going away
            try:
                cmd_vel.publish(Twist())
            except rospy.ROSException:
                pass
    return 0
