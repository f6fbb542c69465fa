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
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from autoscoop.deploy.ros1 import import_rospy, publishers, subscribers
from autoscoop.deploy.sim_bridge import DelayLine, SensorReadings, SimBridge
from autoscoop.envs.outcome import EpisodeOutcome

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


class SimNode:
    """The simulator behind the robot's topics: one method per callback and per phase of an episode.

    Commands (``cmd_vel``, ``lift_controller/command``, ``tilt_controller/command``) arrive on rospy's
    threads and queue under :attr:`lock` while the episode is live; :meth:`run` applies them in order
    before each physics step and publishes each step's readings through a :class:`DelayLine`.

    Args:
        bridge: the simulator.
        delay_s: delay of every sensor message, s; default: the bridge's ``sensor.delay_s``.
        argv: command-line arguments with ROS remappings; default ``sys.argv``.
        node_name: the node's name.
    """

    def __init__(self, bridge: SimBridge, delay_s: float | None = None, argv: list[str] | None = None,
                 node_name: str = NODE_NAME) -> None:
        self.rospy = rospy = import_rospy()
        self.bridge = bridge
        self.delay_s = bridge.task_config.sensor.delay_s if delay_s is None else delay_s
        self.topics = topics = bridge.robot.topics
        self.lock = threading.Lock()
        self.arrived: list[tuple[str, float]] = []
        """commands received since the last step, applied in order before the next one"""
        self.first_arrival: float | None = None
        """when the episode's first command arrived (monotonic s)"""
        self.live = threading.Event()
        """set while an episode runs: commands are taken only then"""
        self.line = DelayLine(self.delay_s)
        self.stats = SimRunStats()
        rospy.init_node(node_name, argv=argv, anonymous=False)
        self.sensors = publishers(topics, ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque",
                                           "payload_mass"))
        self.scoop = publishers(topics, ("scoop",), queue_size=10)["scoop"]
        self.subscribers = subscribers(topics, {"cmd_vel": self.on_speed, "lift_command": self.on_lift,
                                                "tilt_command": self.on_tilt})

    # ---------------------------------------------------------------- commands (rospy's threads)
    def _command(self, name: str, value: float) -> None:
        if self.live.is_set():
            with self.lock:
                self.arrived.append((name, float(value)))
                if self.first_arrival is None:
                    self.first_arrival = time.monotonic()

    def on_speed(self, msg: Any) -> None:
        """``geometry_msgs/Twist`` on ``cmd_vel``: ``linear.x``, m/s."""
        self._command("speed", msg.linear.x)

    def on_lift(self, msg: Any) -> None:
        """``std_msgs/Float64`` on the lift command, rad."""
        self._command("lift", msg.data)

    def on_tilt(self, msg: Any) -> None:
        """``std_msgs/Float64`` on the tilt command, rad."""
        self._command("tilt", msg.data)

    def _take_commands(self) -> list[tuple[str, float]]:
        with self.lock:
            received, self.arrived = self.arrived, []
        return received

    # ---------------------------------------------------------------- sensors
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

    def sample(self, r: SensorReadings) -> None:
        """Queue the messages of ``r`` on the delay line."""
        now = time.monotonic()
        for item in self.messages(r):
            self.line.push(now, item)

    def publish_due(self) -> None:
        """Publish the messages whose delay has passed."""
        for name, msg in self.line.pop_due(time.monotonic()):
            self.sensors[name].publish(msg)

    def wait_until(self, deadline: float) -> None:
        """Publish due messages until ``deadline`` (monotonic s)."""
        while not self.rospy.is_shutdown():
            now = time.monotonic()
            self.publish_due()
            if now >= deadline:
                return
            time.sleep(max(0.0, min(deadline, self.line.next_due()) - time.monotonic()))

    def first_command(self, deadline: float) -> float:
        """When the controller's first command of the episode arrived (or the deadline, if none did)."""
        while time.monotonic() < deadline and not self.rospy.is_shutdown():
            self.publish_due()
            with self.lock:
                if self.first_arrival is not None:
                    return self.first_arrival
            time.sleep(0.0005)
        return deadline

    # ---------------------------------------------------------------- episodes
    def wait_for_controller(self, timeout_s: float) -> None:
        """Wait until a controller subscribes to ``scoop``; note its ``~policy`` parameter if it has one."""
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
                break
            except KeyError:
                continue

    def episode(self, seed: int) -> tuple[EpisodeOutcome | None, float]:
        """One episode: reset and settle, ``scoop`` true, physics in real time, ``scoop`` false.

        Returns:
            The outcome (``None`` when ROS shut down before the episode ended) and the simulated time, s.
        """
        from std_msgs.msg import Bool  # noqa: PLC0415

        rospy, bridge, period = self.rospy, self.bridge, self.bridge.sensor_period_s
        self.live.clear()
        readings = bridge.reset(seed)
        with self.lock:
            self.arrived.clear()
            self.first_arrival = None
        hold_until = time.monotonic() + SETTLE_S + self.delay_s
        tick = time.monotonic()
        while time.monotonic() < hold_until and not rospy.is_shutdown():
            self.sample(readings)
            tick += period
            self.wait_until(tick)
        self.live.set()
        self.scoop.publish(Bool(True))
        tick = self.first_command(time.monotonic() + FIRST_COMMAND_TIMEOUT_S) + period / 2
        self.wait_until(tick)
        start_wall = time.monotonic()
        while not bridge.done and not rospy.is_shutdown():
            for name, value in self._take_commands():
                if name == "speed":
                    bridge.command_speed(value)
                else:
                    bridge.command_joint(name, value)
            readings = bridge.step()
            self.sample(readings)
            tick += period
            if time.monotonic() > tick:
                self.stats.late_steps += 1
                tick = max(tick, time.monotonic() - 2 * period)  # behind: catch up a little, never in a burst
            self.wait_until(tick)
        self.live.clear()
        self.scoop.publish(Bool(False))
        if not bridge.done:
            return None, readings.time_s
        self.stats.sim_s.append(readings.time_s)
        self.stats.wall_s.append(time.monotonic() - start_wall)
        return bridge.result(), readings.time_s

    def run(self, episodes: int, seed: int = 0, wait_for_controller_s: float = 60.0,
            on_episode: Callable[[EpisodeOutcome], None] | None = None) -> tuple[list[EpisodeOutcome], SimRunStats]:
        """Run ``episodes`` episodes (0: until shut down), seeds ``seed``, ``seed + 1``, ...; then unsubscribe.

        Returns:
            The episodes' outcomes and the timing statistics.
        """
        rospy = self.rospy
        results: list[EpisodeOutcome] = []
        try:
            self.wait_for_controller(wait_for_controller_s)
            index = 0
            while not rospy.is_shutdown() and (episodes == 0 or index < episodes):
                result, sim_s = self.episode(seed + index)
                if result is None:
                    break
                results.append(result)
                rospy.loginfo(f"episode {index} (seed {result.seed}): fill {result.fill_factor:.2f}, "
                              f"success {result.success}, {sim_s:.2f} s")
                if on_episode is not None:
                    on_episode(result)
                index += 1
        finally:
            for subscriber in self.subscribers.values():
                subscriber.unregister()
            if not rospy.is_shutdown():
                rospy.signal_shutdown("simulation finished")
        return results, self.stats


def _publishers_of(rospy, topic: str) -> list[str]:
    """Names of the nodes that publish ``topic`` (from the master)."""
    import rosgraph  # noqa: PLC0415 - comes with rospy

    name = rospy.resolve_name(topic)
    try:
        published, _, _ = rosgraph.Master(rospy.get_name()).getSystemState()
    except (rosgraph.MasterError, OSError):
        return []
    return next((nodes for t, nodes in published if t == name), [])
