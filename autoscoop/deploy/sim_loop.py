"""What every middleware front end of the simulator shares: commands queued, readings delayed, episodes in real time.

A front end (``ros1.sim_node``, ``ros2.sim_node``) subclasses :class:`SimLoop`, subscribes
:meth:`SimLoop.on_speed`, :meth:`SimLoop.on_lift` and :meth:`SimLoop.on_tilt` to the command topics,
and supplies what differs between middlewares: the sensor messages of a set of readings, how to
publish one and the ``scoop`` flag, how to wait for a controller, and whether the node is going down.

Between episodes the scene is reset and the physics held still while the new scene's readings are
published (so the controller's inputs are fresh); commands that arrive while it is held are ignored.
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
from typing import Any, Protocol

import numpy as np

from autoscoop.core.config import ConfigError
from autoscoop.deploy.robot_config import joint_readings, robot_from_yaml, robot_yaml
from autoscoop.deploy.sim_bridge import DelayLine, SensorReadings, SimBridge
from autoscoop.envs.outcome import EpisodeOutcome

SETTLE_S = 0.5
"""Readings of a reset scene are published this long (plus the delay) before the episode starts."""
FIRST_COMMAND_TIMEOUT_S = 2.0
"""After ``scoop`` true, the physics waits this long at most for the controller's first command."""


class BagLog(Protocol):
    """Where a node records its topics (an MCAP file for ROS 2, a ROS 1 bag)."""

    def write(self, topic: str, message: Any) -> None: ...

    def close(self) -> None: ...


class RobotMismatch(ConfigError):
    """The controller and the simulator were given robot files that read the joints differently."""


@dataclass
class SimRunStats:
    """How the node kept time: per episode, the simulated and the wall-clock duration."""

    sim_s: list[float] = field(default_factory=list)
    wall_s: list[float] = field(default_factory=list)
    late_steps: int = 0
    commands_received: int = 0
    """commands taken from the controller while episodes ran."""
    controller_policy: str | None = None
    """the controller's policy name, when it is the autoscoop controller."""
    controller_robot: str | None = None
    """the controller's robot file (YAML text), when it is the autoscoop controller."""

    def as_dict(self) -> dict[str, float]:
        sim, wall = float(np.sum(self.sim_s)), float(np.sum(self.wall_s))
        return {"simulated_s": sim, "wall_s": wall, "real_time_factor": sim / wall if wall > 0 else math.nan,
                "late_steps": self.late_steps, "commands_received": self.commands_received}


class SimLoop:
    """The simulator behind the robot's topics: one method per command callback and per phase of an episode.

    Commands arrive on the middleware's threads and queue under :attr:`lock` while the episode is
    live; :meth:`run` applies them in order before each physics step and publishes each step's
    readings through a :class:`DelayLine`.

    Args:
        bridge: the simulator.
        delay_s: delay of every sensor message, s; default: the bridge's ``sensor.delay_s``.
        log: a bag (``write(topic, message)``, ``close()``) that gets every message published, when
            published, and every command, when it arrived; closed when :meth:`run` ends.
    """

    def __init__(self, bridge: SimBridge, delay_s: float | None = None, log: BagLog | None = None) -> None:
        self.bridge = bridge
        self.log = log
        self.delay_s = bridge.task_config.sensor.delay_s if delay_s is None else delay_s
        self.topics = bridge.robot.topics
        self.lock = threading.Lock()
        self.arrived: list[tuple[str, float]] = []
        """commands received since the last step, applied in order before the next one"""
        self.first_arrival: float | None = None
        """when the episode's first command arrived (monotonic s)"""
        self.live = threading.Event()
        """set while an episode runs: commands are taken only then"""
        self.line = DelayLine(self.delay_s)
        self.stats = SimRunStats()

    # ---------------------------------------------------------------- what a middleware supplies
    def messages(self, r: SensorReadings) -> list[tuple[str, object]]:
        """The sensor messages of one set of readings, stamped now, by topic key."""
        raise NotImplementedError

    def publish_sensor(self, name: str, msg: object) -> None:
        """Publish a sensor message on the topic of key ``name``."""
        raise NotImplementedError

    def publish_scoop(self, start: bool) -> object:
        """Publish ``scoop``: true when an episode starts, false when it ends; the message published."""
        raise NotImplementedError

    def topic_name(self, key: str) -> str:
        """The resolved name of the topic of key ``key`` (for the bag)."""
        raise NotImplementedError

    def wait_for_controller(self, timeout_s: float) -> None:
        """Wait until a controller listens to ``scoop``; note its policy and robot file in :attr:`stats` where
        it tells them.

        Raises:
            TimeoutError: none within ``timeout_s``.
        """
        raise NotImplementedError

    def shutting_down(self) -> bool:
        """Whether the node is going down (the episodes end)."""
        raise NotImplementedError

    def log_info(self, text: str) -> None:
        """Log a line at the info level."""
        raise NotImplementedError

    def close_transport(self) -> None:
        """Unsubscribe, and let the middleware go."""
        raise NotImplementedError

    def robot_message(self, text: str) -> tuple[str, object]:
        """The node's own robot file (YAML ``text``) as a ``std_msgs/String`` and the topic it is logged on."""
        raise NotImplementedError

    # ---------------------------------------------------------------- the robot file both nodes share
    def check_controller_robot(self) -> None:
        """Refuse to run against a controller that reads ``joint_states`` in other units or joint names.

        Raises:
            RobotMismatch: the controller's robot file (:attr:`SimRunStats.controller_robot`) describes the
                joints otherwise than this simulator's.
        """
        if self.stats.controller_robot is None:
            return  # not the autoscoop controller: nothing to compare with
        theirs = joint_readings(robot_from_yaml(self.stats.controller_robot, "the controller's announcement"))
        ours = joint_readings(self.bridge.robot)
        if theirs != ours:
            raise RobotMismatch(f"the controller reads joint_states as: {theirs}; this simulator publishes: {ours}. "
                                f"Give both nodes the same robot file (--robot FILE)")

    # ---------------------------------------------------------------- commands (the middleware's threads)
    def _command(self, name: str, value: float) -> None:
        if self.live.is_set():
            with self.lock:
                self.arrived.append((name, float(value)))
                self.stats.commands_received += 1
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

    def command_callbacks(self) -> dict[str, Callable[[Any], None]]:
        """The callback of each command topic, by topic key (each message logged first, with a log)."""
        callbacks = {"cmd_vel": self.on_speed, "lift_command": self.on_lift, "tilt_command": self.on_tilt}
        return {key: self._logged(key, callback) for key, callback in callbacks.items()}

    def record(self, key: str, msg: object) -> None:
        """Log ``msg`` on the topic of key ``key``, now (without a log, nothing)."""
        if self.log is not None:
            self.log.write(self.topic_name(key), msg)

    def _logged(self, key: str, callback: Callable[[Any], None]) -> Callable[[Any], None]:
        if self.log is None:
            return callback

        def record_then_call(msg: Any) -> None:
            self.record(key, msg)
            callback(msg)
        return record_then_call

    def _take_commands(self) -> list[tuple[str, float]]:
        with self.lock:
            received, self.arrived = self.arrived, []
        return received

    # ---------------------------------------------------------------- sensors
    def sample(self, r: SensorReadings) -> None:
        """Queue the messages of ``r`` on the delay line."""
        now = time.monotonic()
        for item in self.messages(r):
            self.line.push(now, item)

    def publish_due(self) -> None:
        """Publish the messages whose delay has passed."""
        for name, msg in self.line.pop_due(time.monotonic()):
            self.publish_sensor(name, msg)
            self.record(name, msg)

    def wait_until(self, deadline: float) -> None:
        """Publish due messages until ``deadline`` (monotonic s)."""
        while not self.shutting_down():
            now = time.monotonic()
            self.publish_due()
            if now >= deadline:
                return
            time.sleep(max(0.0, min(deadline, self.line.next_due()) - time.monotonic()))

    def first_command(self, deadline: float) -> float:
        """When the controller's first command of the episode arrived (or the deadline, if none did)."""
        while time.monotonic() < deadline and not self.shutting_down():
            self.publish_due()
            with self.lock:
                if self.first_arrival is not None:
                    return self.first_arrival
            time.sleep(0.0005)
        return deadline

    # ---------------------------------------------------------------- episodes
    def episode(self, seed: int) -> tuple[EpisodeOutcome | None, float]:
        """One episode: reset and settle, ``scoop`` true, physics in real time, ``scoop`` false.

        Returns:
            The outcome (``None`` when the node went down before the episode ended) and the simulated time, s.
        """
        bridge, period = self.bridge, self.bridge.sensor_period_s
        self.live.clear()
        readings = bridge.reset(seed)
        with self.lock:
            self.arrived.clear()
            self.first_arrival = None
        hold_until = time.monotonic() + SETTLE_S + self.delay_s
        tick = time.monotonic()
        while time.monotonic() < hold_until and not self.shutting_down():
            self.sample(readings)
            tick += period
            self.wait_until(tick)
        self.live.set()
        self.record("scoop", self.publish_scoop(True))
        tick = self.first_command(time.monotonic() + FIRST_COMMAND_TIMEOUT_S) + period / 2
        self.wait_until(tick)
        start_wall = time.monotonic()
        while not bridge.done and not self.shutting_down():
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
        self.record("scoop", self.publish_scoop(False))
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
        results: list[EpisodeOutcome] = []
        try:
            self.wait_for_controller(wait_for_controller_s)
            self.check_controller_robot()
            if self.log is not None:
                topic, message = self.robot_message(robot_yaml(self.bridge.robot))
                self.log.write(topic, message)
            index = 0
            while not self.shutting_down() and (episodes == 0 or index < episodes):
                result, sim_s = self.episode(seed + index)
                if result is None:
                    break
                results.append(result)
                self.log_info(f"episode {index} (seed {result.seed}): fill {result.fill_factor:.2f}, "
                              f"success {result.success}, {sim_s:.2f} s")
                if on_episode is not None:
                    on_episode(result)
                index += 1
        finally:
            self.close_transport()
            if self.log is not None:
                self.log.close()
        return results, self.stats
