"""``autoscoop ros sim``: the MuJoCo scene as a ROS 1 node behind the robot's topics (like the paper's Gazebo).

Publishes ``joint_states``, ``odom``, ``pile_range``, ``bucket_torque``, ``lift_torque`` and ``payload_mass`` (the true
mass in the bucket, for a controller with ``payload.source: topic``) every sensor period (about 48 Hz)
in real time, each after the configured delay, and ``scoop`` (std_msgs/Bool): true when an
episode starts, false when it ends. Obeys ``cmd_vel``, ``lift_controller/command`` and
``tilt_controller/command``. Between episodes it resets the scene, holds the physics still while it
publishes the new scene's readings (so the controller's inputs are fresh), then starts the next
episode; commands that arrive while it is held are ignored.

The episode's physics starts half a sensor period after the controller's first command: the
controller's later commands (one per control period, on its own clock) then arrive between two
physics steps, not on their edges, and each takes effect at the start of a control period, as in
the environment. Without that, whether a command lands one step earlier or later is a coin toss
that the scripted baseline, which dead-reckons from odometry, is sensitive to.
"""

from __future__ import annotations

import math
import threading
import time
from dataclasses import dataclass, field
from typing import Callable

import numpy as np

from autoscoop.deploy.ros1 import import_rospy, publishers
from autoscoop.deploy.sim_bridge import DelayLine, SensorReadings, SimBridge
from autoscoop.evaluation.evaluate import EpisodeResult

NODE_NAME = "autoscoop_sim"
SETTLE_S = 0.5
"""Readings of a reset scene are published this long (plus the delay) before the episode starts."""
FIRST_COMMAND_TIMEOUT_S = 2.0
"""After ``scoop`` true, the physics waits this long at most for the controller's first command."""


@dataclass
class SimRunStats:
    """How the node kept time: per episode, the simulated and the wall-clock duration."""

    sim_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    late_steps: int = 0
    controller_policy: str | None = None
    """the controller's ``~policy`` parameter, when it is the autoscoop controller."""

    def as_dict(self) -> dict[str, float]:
        sim, wall = float(np.sum(self.sim_s)), float(np.sum(self.wall_s))
        return {"simulated_s": sim, "wall_s": wall, "real_time_factor": sim / wall if wall > 0 else math.nan,
                "late_steps": self.late_steps}


def run_sim_node(bridge: SimBridge, episodes: int, seed: int = 0, delay_s: float = 0.0,
                 wait_for_controller_s: float = 60.0, on_episode: Callable[[EpisodeResult], None] | None = None,
                 argv: list[str] | None = None, node_name: str = NODE_NAME) -> tuple[list[EpisodeResult], SimRunStats]:
    """Run ``episodes`` episodes (0: until shut down) against whatever controller obeys the topics.

    Args:
        bridge: the simulator.
        episodes: how many; 0 runs until ROS shuts down.
        seed: seed of the first episode (then ``seed + 1``, ...), as in ``autoscoop eval``.
        delay_s: delay of every sensor message, s.
        wait_for_controller_s: give up when no controller subscribes to ``scoop`` within this long.
        on_episode: called with each episode's result.
        argv: command-line arguments with ROS remappings; default ``sys.argv``.
        node_name: the node's name.

    Returns:
        The episodes' results and the timing statistics.
    """
    rospy = import_rospy()
    from geometry_msgs.msg import Twist  # noqa: PLC0415
    from nav_msgs.msg import Odometry  # noqa: PLC0415
    from sensor_msgs.msg import JointState, Range  # noqa: PLC0415
    from std_msgs.msg import Bool, Float64  # noqa: PLC0415

    rospy.init_node(node_name, argv=argv, anonymous=False)
    topics = bridge.robot.topics
    lock = threading.Lock()
    arrived: list[tuple[str, float]] = []
    """commands received since the last step, applied in order before the next one"""
    live = threading.Event()

    first_arrival: list[float] = []

    def on_command(name: str, value: Callable[[object], float]) -> Callable[[object], None]:
        def callback(msg: object) -> None:
            if live.is_set():
                with lock:
                    arrived.append((name, float(value(msg))))
                    if not first_arrival:
                        first_arrival.append(time.monotonic())
        return callback

    def first_command(deadline: float) -> float:
        """When the controller's first command of the episode arrived (or the deadline, if none did)."""
        while time.monotonic() < deadline and not rospy.is_shutdown():
            publish_due()
            with lock:
                if first_arrival:
                    return first_arrival[0]
            time.sleep(0.0005)
        return deadline

    sensors = publishers(topics, ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque",
                                  "payload_mass"))
    scoop = publishers(topics, ("scoop",), queue_size=10)["scoop"]
    subscribers = [
        rospy.Subscriber(topics.cmd_vel, Twist, on_command("speed", lambda m: m.linear.x), queue_size=10,
                         tcp_nodelay=True),
        rospy.Subscriber(topics.lift_command, Float64, on_command("lift", lambda m: m.data), queue_size=10,
                         tcp_nodelay=True),
        rospy.Subscriber(topics.tilt_command, Float64, on_command("tilt", lambda m: m.data), queue_size=10,
                         tcp_nodelay=True)]
    line = DelayLine(delay_s)

    def messages(r: SensorReadings) -> list[tuple[str, object]]:
        stamp = rospy.Time.now()
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
                ("bucket_torque", Float64(r.torque_nm)), ("lift_torque", Float64(r.lift_torque_nm)),
                ("payload_mass", Float64(r.payload_kg))]

    def publish_due() -> None:
        for name, msg in line.pop_due(time.monotonic()):
            sensors[name].publish(msg)

    def wait_until(deadline: float) -> None:
        while not rospy.is_shutdown():
            now = time.monotonic()
            publish_due()
            if now >= deadline:
                return
            time.sleep(max(0.0, min(deadline, line.next_due()) - time.monotonic()))

    def sample(r: SensorReadings) -> None:
        now = time.monotonic()
        for item in messages(r):
            line.push(now, item)

    results: list[EpisodeResult] = []
    stats = SimRunStats()
    period = bridge.sensor_period_s
    try:
        waited = time.monotonic()
        while scoop.get_num_connections() == 0 and not rospy.is_shutdown():
            if time.monotonic() - waited > wait_for_controller_s:
                raise TimeoutError(f"no controller subscribed to {rospy.resolve_name(topics.scoop)} within "
                                   f"{wait_for_controller_s:g} s; start `autoscoop ros controller`")
            time.sleep(0.05)
        for node in _publishers_of(rospy, topics.cmd_vel):
            try:
                stats.controller_policy = str(rospy.get_param(f"{node}/policy"))
                break
            except KeyError:
                continue
        index = 0
        while not rospy.is_shutdown() and (episodes == 0 or index < episodes):
            live.clear()
            readings = bridge.reset(seed + index)
            with lock:
                arrived.clear()
                first_arrival.clear()
            hold_until = time.monotonic() + SETTLE_S + delay_s
            tick = time.monotonic()
            while time.monotonic() < hold_until and not rospy.is_shutdown():
                sample(readings)
                tick += period
                wait_until(tick)
            live.set()
            scoop.publish(Bool(True))
            tick = first_command(time.monotonic() + FIRST_COMMAND_TIMEOUT_S) + period / 2
            wait_until(tick)
            start_wall = time.monotonic()
            while not bridge.done and not rospy.is_shutdown():
                with lock:
                    received, arrived[:] = list(arrived), []
                for name, value in received:
                    if name == "speed":
                        bridge.command_speed(value)
                    else:
                        bridge.command_joint(name, value)
                readings = bridge.step()
                sample(readings)
                tick += period
                if time.monotonic() > tick:
                    stats.late_steps += 1
                    tick = max(tick, time.monotonic() - 2 * period)  # behind: catch up a little, never in a burst
                wait_until(tick)
            live.clear()
            scoop.publish(Bool(False))
            if not bridge.done:
                break
            result = bridge.result()
            stats.sim_s.append(readings.time_s)
            stats.wall_s.append(time.monotonic() - start_wall)
            results.append(result)
            rospy.loginfo(f"episode {index} (seed {result.seed}): fill {result.fill_factor:.2f}, "
                          f"success {result.success}, {readings.time_s:.2f} s")
            if on_episode is not None:
                on_episode(result)
            index += 1
    finally:
        for subscriber in subscribers:
            subscriber.unregister()
        if not rospy.is_shutdown():
            rospy.signal_shutdown("simulation finished")
    return results, stats


def _publishers_of(rospy, topic: str) -> list[str]:  # noqa: ANN001 - the rospy module
    """Names of the nodes that publish ``topic`` (from the master)."""
    import rosgraph  # noqa: PLC0415 - comes with rospy

    name = rospy.resolve_name(topic)
    try:
        published, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    except (rosgraph.MasterError, OSError):
        return []
    return next((nodes for t, nodes in published if t == name), [])
