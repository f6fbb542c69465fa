"""A robot's log replayed through the controller core, offline: what it would have commanded beside what was commanded.

:func:`read_log` reads a ROS 1 ``.bag``, a ROS 2 bag folder or an MCAP file (``rosbags``), keeps the
controller's topics (names from the robot YAML's ``topics``, in a namespace) and checks them: every
input the configuration needs and ``scoop`` present, each with its ROS message type, and the stamped
inputs stamped. ROS 2 messages are decoded with :mod:`autoscoop.deploy.ros2.messages` (the types the
ROS 2 nodes use), ROS 1 messages by ``rosbags``.

:class:`Replay` hands each recorded input to a :class:`~autoscoop.deploy.controller.ControllerCore` at its
log time (its header stamp judged against that time, as the node judges it against its clock on
arrival) through the same callbacks as the nodes (:class:`~autoscoop.deploy.controller_loop.ControllerLoop`),
and updates the core:

- ``recorded`` schedule (a log with ``cmd_vel``): at the times of the recorded commands. On a log of
  ``autoscoop ros2 controller --bag`` (inputs and commands on the controller's own clock) the same
  policy then reproduces the commands sent;
- ``own`` schedule: at the core's own wake-ups (control periods, inputs going stale), as a live node would.

Each update is a :class:`ReplayedCommand`: the command that was sent (where the log has one) and the
one the core made, with the watchdog's verdict (``mode``, ``reason``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from autoscoop.deploy.controller import ControllerCore, payload_inputs
from autoscoop.deploy.controller_loop import ControllerLoop
from autoscoop.deploy.robot_config import TopicsSection
from autoscoop.deploy.safety import Command

STAMPED_INPUTS = ("joint_states", "odom", "pile_range")
COMMAND_TOPICS = ("cmd_vel", "lift_command", "tilt_command")
ROS_TYPES = {
    "joint_states": "sensor_msgs/msg/JointState", "odom": "nav_msgs/msg/Odometry", "pile_range": "sensor_msgs/msg/Range",
    "bucket_torque": "std_msgs/msg/Float64", "lift_torque": "std_msgs/msg/Float64", "payload_mass": "std_msgs/msg/Float64",
    "estop": "std_msgs/msg/Bool", "scoop": "std_msgs/msg/Bool", "cmd_vel": "geometry_msgs/msg/Twist",
    "lift_command": "std_msgs/msg/Float64", "tilt_command": "std_msgs/msg/Float64",
}
"""The ROS message type of each of the controller's topics, as ``rosbags`` names it (ROS 1 and ROS 2 alike)."""
COMMAND_GROUP_S = 0.005
"""Arm commands logged this soon after a ``cmd_vel`` belong to the same command (s)."""


class LogError(ValueError):
    """A log the replay cannot use: unreadable, a topic missing or of the wrong type, inputs without stamps."""


@dataclass(frozen=True)
class LoggedMessage:
    """One message of the log: its topic key, log time (ns since the epoch) and the decoded message."""

    key: str
    time_ns: int
    message: Any


def _expand(name: str, namespace: str) -> str:
    if name.startswith("/"):
        return name
    prefix = "/" + namespace.strip("/") if namespace.strip("/") else ""
    return f"{prefix}/{name.lstrip('~/')}"


def read_log(path: str | Path, topics: TopicsSection, needed: Sequence[str], namespace: str = "/") -> list[LoggedMessage]:
    """The controller's messages of a log, in log-time order.

    Args:
        path: a ROS 1 ``.bag`` file, a ROS 2 bag folder (``metadata.yaml``) or an ``.mcap`` file.
        topics: the controller's topic names (the robot YAML's ``topics``).
        needed: the topic keys that must be in the log.
        namespace: the namespace the relative names lie in.

    Raises:
        LogError: unreadable, a needed topic missing, a topic of the wrong type, or stamped inputs without stamps.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError  # noqa: PLC0415 - the ros2 extra

    from autoscoop.deploy.ros2.messages import MESSAGE_TYPES  # noqa: PLC0415

    path = Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    by_name = {_expand(getattr(topics, key), namespace): key for key in ROS_TYPES}
    try:
        with AnyReader([path]) as reader:
            present = {c.topic: c.msgtype for c in reader.connections}
            for key in needed:
                name = _expand(getattr(topics, key), namespace)
                if name not in present:
                    raise LogError(f"{path}: no topic {name} (topics.{key}, {ROS_TYPES[key]}); the log has "
                                   + (", ".join(sorted(present)) or "no topics"))
            for name, msgtype in present.items():
                key = by_name.get(name)
                if key is not None and msgtype != ROS_TYPES[key]:
                    raise LogError(f"{path}: topic {name} (topics.{key}) is {msgtype}, expected {ROS_TYPES[key]}")
            wanted = [c for c in reader.connections if c.topic in by_name]
            log = []
            for connection, time_ns, raw in reader.messages(connections=wanted):
                key = by_name[connection.topic]
                if getattr(connection.ext, "serialization_format", None) == "cdr":
                    message = MESSAGE_TYPES[key].deserialize(bytes(raw))
                else:
                    message = reader.deserialize(raw, connection.msgtype)
                log.append(LoggedMessage(key, int(time_ns), message))
    except (AnyReaderError, OSError, KeyError, ValueError) as error:
        if isinstance(error, LogError):
            raise
        raise LogError(f"{path}: not a readable ROS 1 bag, ROS 2 bag or MCAP file ({error})") from None
    for key in STAMPED_INPUTS:
        stamps = [m.message.header.stamp for m in log if m.key == key]
        if stamps and not any(s.sec or s.nanosec for s in stamps):
            raise LogError(f"{path}: {_expand(getattr(topics, key), namespace)} carries no header stamps (all zero); "
                           "the controller judges its inputs by their stamps")
    log.sort(key=lambda m: m.time_ns)
    return log


ROBOT_TOPIC_NODES = ("autoscoop_controller", "autoscoop_sim")
"""The nodes whose ``~/robot`` (std_msgs/String, the robot file as YAML) a log may hold, the controller's first."""


def robot_file_in_log(path: str | Path, namespace: str = "/") -> tuple[str, str] | None:
    """The robot file a log was recorded with: ``(topic, YAML text)`` of the last ``~/robot`` message of the
    controller (or else the simulator) in ``namespace``; ``None`` when the log holds none.

    Raises:
        LogError: the log cannot be read.
    """
    from rosbags.highlevel import AnyReader, AnyReaderError  # noqa: PLC0415 - the ros2 extra

    from autoscoop.deploy.ros2.messages import String  # noqa: PLC0415

    path = Path(path)
    if not path.exists():
        raise LogError(f"{path}: no such file or folder")
    try:
        with AnyReader([path]) as reader:
            for node in ROBOT_TOPIC_NODES:
                topic = _expand(f"{node}/robot", namespace)
                wanted = [c for c in reader.connections if c.topic == topic and c.msgtype == "std_msgs/msg/String"]
                if not wanted:
                    continue  # (no connections would read every message)
                text = None
                for connection, _, raw in reader.messages(connections=wanted):
                    if getattr(connection.ext, "serialization_format", None) == "cdr":
                        text = String.deserialize(bytes(raw)).data
                    else:
                        text = reader.deserialize(raw, connection.msgtype).data
                if text is not None:
                    return topic, text
    except (AnyReaderError, OSError, KeyError, ValueError) as error:
        raise LogError(f"{path}: not a readable ROS 1 bag, ROS 2 bag or MCAP file ({error})") from None
    return None


@dataclass(frozen=True)
class ReplayedCommand:
    """One update of the replayed core: what was commanded then (NaN where the log has none) and what the
    core commanded (NaN arm: no arm command), with its mode and reason.

    Attributes:
        time_s: since the log's first message, s.
    """

    time_s: float
    sent_speed_mps: float
    sent_lift_rad: float
    sent_tilt_rad: float
    speed_mps: float
    lift_rad: float
    tilt_rad: float
    mode: str
    reason: str

    FIELDS = ("time_s", "sent_speed_mps", "sent_lift_rad", "sent_tilt_rad", "speed_mps", "lift_rad", "tilt_rad",
              "mode", "reason")


class Replay(ControllerLoop):
    """A :class:`ControllerLoop` whose clock is the log's: inputs go in at their log times, updates happen on a schedule.

    Args:
        core: the controller, idle.
    """

    def __init__(self, core: ControllerCore) -> None:
        super().__init__(core, "replay", clock=lambda: self.now)
        self.now = 0.0
        self.ros_now = 0.0
        self.commands: list[Command] = []

    def header_seconds(self, header: Any) -> float:
        return header.stamp.sec + header.stamp.nanosec / 1e9

    def ros_time(self) -> float:
        return self.ros_now

    def publish(self, command: Command) -> None:
        self.commands.append(command)

    def shutting_down(self) -> bool:
        return True  # no live loop: :meth:`run` drives the core

    def log_info(self, text: str) -> None:
        pass

    def _at(self, time_ns: int, start_ns: int) -> None:
        self.now = (time_ns - start_ns) / 1e9
        self.ros_now = time_ns / 1e9

    def _update(self) -> Command | None:
        command = self.core.update(self.now)
        if command is not None:
            self.publish(command)
        return command

    def _wake_until(self, time_ns: int, start_ns: int, on_command: Callable[[Command], None]) -> None:
        """Update the core at each of its wake-ups up to ``time_ns`` (ns since the epoch)."""
        while True:
            wake_s = self.core.next_wakeup(self.now)
            if not math.isfinite(wake_s) or start_ns + wake_s * 1e9 > time_ns:
                return
            self.now, self.ros_now = wake_s, (start_ns + wake_s * 1e9) / 1e9
            command = self._update()
            if command is not None:
                on_command(command)

    def run(self, log: Sequence[LoggedMessage], schedule: str = "recorded") -> list[ReplayedCommand]:
        """Replay ``log`` (:func:`read_log`) through the core; one row per update that commanded, beside the
        command sent then (on the own schedule: the latest logged before it).

        Args:
            log: the messages, in log-time order.
            schedule: ``recorded`` (update at the logged commands' times) or ``own`` (at the core's wake-ups).
        """
        if schedule not in ("recorded", "own"):
            raise ValueError(f"schedule must be 'recorded' or 'own', got {schedule!r}")
        if not log:
            return []
        start = log[0].time_ns
        callbacks = self.input_callbacks(payload_inputs(self.core.config.payload))
        rows: list[ReplayedCommand] = []
        sent: list[float] | None = None

        def row(command: Command, sent_values: Iterable[float]) -> ReplayedCommand:
            speed, lift, tilt = sent_values
            return ReplayedCommand(self.now, speed, lift, tilt, command.speed_mps,
                                   math.nan if command.lift_rad is None else command.lift_rad,
                                   math.nan if command.tilt_rad is None else command.tilt_rad,
                                   command.mode, command.reason)

        last_command_ns = None
        latest_sent = [math.nan] * 3  # the commands in force (own schedule)
        for item in log:
            if schedule == "own":
                self._wake_until(item.time_ns, start, lambda command: rows.append(row(command, tuple(latest_sent))))
            if item.key in COMMAND_TOPICS:
                value = item.message.linear.x if item.key == "cmd_vel" else item.message.data
                latest_sent[COMMAND_TOPICS.index(item.key)] = float(value)
                if schedule == "own":
                    continue
                if item.key == "cmd_vel":
                    self._at(item.time_ns, start)
                    sent = [float(item.message.linear.x), math.nan, math.nan]
                    last_command_ns = item.time_ns
                    command = self._update()
                    rows.append(row(command if command is not None else Command(math.nan, None, None, "none", ""),
                                    sent))
                elif rows and last_command_ns is not None and item.time_ns - last_command_ns <= COMMAND_GROUP_S * 1e9:
                    index = 1 if item.key == "lift_command" else 2
                    previous = rows[-1]
                    values = [previous.sent_speed_mps, previous.sent_lift_rad, previous.sent_tilt_rad]
                    values[index] = float(item.message.data)
                    rows[-1] = ReplayedCommand(previous.time_s, *values, previous.speed_mps, previous.lift_rad,
                                               previous.tilt_rad, previous.mode, previous.reason)
                continue
            callback = callbacks.get(item.key)
            if callback is not None:
                self._at(item.time_ns, start)
                callback(item.message)
        self.core.close(self.now)
        return rows


def differences(rows: Sequence[ReplayedCommand]) -> dict[str, float]:
    """The largest difference between the sent and the replayed commands, per channel (NaN: none compared)."""
    out = {}
    for channel in ("speed_mps", "lift_rad", "tilt_rad"):
        pairs = [(getattr(r, f"sent_{channel}"), getattr(r, channel)) for r in rows]
        diffs = [abs(a - b) for a, b in pairs if math.isfinite(a) and math.isfinite(b)]
        out[channel] = max(diffs) if diffs else math.nan
    return out


def rows_as_csv(rows: Sequence[ReplayedCommand]) -> str:
    """The rows as CSV text (a header line, then one line per row; numbers with 9 significant digits)."""
    import csv  # noqa: PLC0415
    import io  # noqa: PLC0415

    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(ReplayedCommand.FIELDS)
    for r in rows:
        writer.writerow([f"{v:.9g}" if isinstance(v, float) else v for v in (getattr(r, f) for f in ReplayedCommand.FIELDS)])
    return buffer.getvalue()
