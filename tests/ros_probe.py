"""Stand-ins on the controller's topics, for tests and benchmarks of ``autoscoop ros controller`` (test-only: not shipped in the package).

:class:`RobotProbe` is a stand-in robot (watchdog latency, estop, fuzzed messages): it plays the
robot's sensors at a fixed rate with values one can change or stop per topic, or replace by
arbitrary messages, and timestamps every command it receives on its own monotonic clock.
:class:`FaultRelay` passes another node's sensor messages (``autoscoop ros sim``'s, remapped) on
to the controller, with faults injected on demand (``benchmarks/ros_soak.py``). Call
:func:`rospy.init_node` before building either.
"""

from __future__ import annotations

import copy
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from typing import Any

import numpy as np

from autoscoop.deploy.robot_config import TopicsSection
from autoscoop.deploy.ros1 import import_rospy, message_class, publishers, subscribers

SENSOR_TOPICS = ("joint_states", "odom", "pile_range", "bucket_torque", "lift_torque")
STAMPED_TOPICS = ("joint_states", "odom", "pile_range")
"""The sensor topics whose messages carry a header stamp."""


@dataclass(frozen=True)
class Received:
    """One command as the probe received it: its arrival time (monotonic s), topic and value."""

    time_s: float
    topic: str
    value: float


class RobotProbe:
    """Publishes the robot's sensors at ``rate_hz`` and records the controller's commands.

    Args:
        rate_hz: sensor publication rate.
        topics: topic names (the controller's defaults).
        lift_rad, tilt_rad, speed_mps, range_m, lift_torque_nm, tilt_torque_nm: the readings published
            (``tilt_torque_nm`` on ``bucket_torque``).
    """

    def __init__(self, rate_hz: float = 50.0, topics: TopicsSection | None = None, lift_rad: float = 0.23,
                 tilt_rad: float = 0.0, speed_mps: float = 0.0, range_m: float = 0.3, lift_torque_nm: float = -20.0,
                 tilt_torque_nm: float = -1.0) -> None:
        self.rospy = import_rospy()
        from geometry_msgs.msg import Twist
        from nav_msgs.msg import Odometry
        from sensor_msgs.msg import JointState, Range
        from std_msgs.msg import Bool, Float64

        self.msg = {"JointState": JointState, "Odometry": Odometry, "Range": Range, "Float64": Float64,
                    "Bool": Bool, "Twist": Twist}
        topics = topics or TopicsSection()
        self.period_s = 1.0 / rate_hz
        self.values = {"lift": lift_rad, "tilt": tilt_rad, "speed": speed_mps, "range": range_m,
                       "lift_torque": lift_torque_nm, "tilt_torque": tilt_torque_nm}
        self.start_bookkeeping()
        self.publishers = {**publishers(topics, SENSOR_TOPICS), **publishers(topics, ("estop", "scoop"), queue_size=10)}
        self.subscribers = list(subscribers(topics, {
            "cmd_vel": self._record("cmd_vel", lambda m: m.linear.x),
            "lift_command": self._record("lift", lambda m: m.data),
            "tilt_command": self._record("tilt", lambda m: m.data)}, queue_size=None).values())
        self._thread = threading.Thread(target=self._run, name="robot-probe", daemon=True)
        self._thread.start()

    def start_bookkeeping(self) -> None:
        """What the probe keeps, whatever the middleware: topics on and off, last sends, commands received."""
        self.enabled = {name: True for name in SENSOR_TOPICS}
        self.last_published: dict[str, float] = {}
        self.custom: dict[str, Callable[[], Any]] = {}
        """Per topic, a function that returns the next message to publish instead of the normal one."""
        self.received: list[Received] = []
        self.errors: list[str] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()

    # ---------------------------------------------------------------- publishing
    def normal_message(self, topic: str) -> Any:
        """The message ``topic`` carries with the current values."""
        v, stamp = self.values, self.rospy.Time.now()
        if topic == "joint_states":
            msg = self.msg["JointState"](name=["lift", "tilt"], position=[v["lift"], v["tilt"]])
        elif topic == "odom":
            msg = self.msg["Odometry"]()
            msg.twist.twist.linear.x = v["speed"]
        elif topic == "pile_range":
            msg = self.msg["Range"](min_range=0.0, max_range=4.0, range=v["range"])
        elif topic == "lift_torque":
            return self.msg["Float64"](v["lift_torque"])
        else:  # bucket_torque
            return self.msg["Float64"](v["tilt_torque"])
        msg.header.stamp = stamp
        return msg

    def _run(self) -> None:
        tick = time.monotonic()
        while not self._stop.is_set() and not self.rospy.is_shutdown():
            for topic in SENSOR_TOPICS:
                if not self.enabled[topic]:
                    continue
                make = self.custom.get(topic)
                try:
                    self.publishers[topic].publish(make() if make else self.normal_message(topic))
                except (self.rospy.ROSException, ValueError, OverflowError, TypeError) as error:
                    self.errors.append(f"{topic}: {error}")  # a message that cannot even be serialised
                    continue
                self.last_published[topic] = time.monotonic()
            tick += self.period_s
            time.sleep(max(0.0, tick - time.monotonic()))

    def publish(self, topic: str, message: Any) -> float:
        """Publish one message on ``estop``, ``scoop`` or a sensor topic; the monotonic time it was sent."""
        self.publishers[topic].publish(message)
        return time.monotonic()

    def wait_for_controller(self, timeout_s: float = 30.0) -> None:
        """Wait until the controller is connected to every topic (both ways)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_num_connections() > 0 for p in self.publishers.values()) and \
                    all(s.get_num_connections() > 0 for s in self.subscribers):
                return
            time.sleep(0.05)
        raise TimeoutError("the controller did not connect to the probe's topics")

    # ---------------------------------------------------------------- commands
    def _record(self, topic: str, value: Callable[[Any], float]) -> Callable[[Any], None]:
        def callback(msg: Any) -> None:
            now = time.monotonic()
            with self._lock:
                self.received.append(Received(now, topic, float(value(msg))))
        return callback

    def commands(self, topic: str, since: float = -math.inf) -> list[Received]:
        """Commands received on ``cmd_vel``, ``lift`` or ``tilt`` at or after ``since``."""
        with self._lock:
            return [r for r in self.received if r.topic == topic and r.time_s >= since]

    def wait_for_command(self, topic: str, predicate: Callable[[float], bool], since: float,
                         timeout_s: float = 5.0) -> Received | None:
        """The first command on ``topic`` after ``since`` whose value satisfies ``predicate`` (None on timeout)."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            for r in self.commands(topic, since):
                if predicate(r.value):
                    return r
            time.sleep(0.002)
        return None

    def close(self) -> None:
        """Stop publishing and unsubscribe."""
        self._stop.set()
        self._thread.join(timeout=2)
        for s in self.subscribers:
            s.unregister()
        for p in self.publishers.values():
            p.unregister()


# -------------------------------------------------------------------- latency trials
def start_moving(probe: RobotProbe, timeout_s: float = 3.0) -> None:
    """Start a scoop and wait until the controller drives forward."""
    sent = probe.publish("scoop", probe.msg["Bool"](True))
    if probe.wait_for_command("cmd_vel", lambda v: v > 0.0, since=sent, timeout_s=timeout_s) is None:
        raise RuntimeError("the controller did not start driving after scoop=true")


def watchdog_trial(probe: RobotProbe, phase_s: float, timeout_s: float = 3.0) -> float:
    """Stop ``joint_states`` while the robot drives; seconds from the last message to a zero ``cmd_vel``.

    Args:
        probe: the stand-in robot, connected to a running controller.
        phase_s: wait this long after the robot starts driving before stopping (spreads the stop over
            the control period).
        timeout_s: give up after this long without a zero command.
    """
    start_moving(probe)
    time.sleep(phase_s)
    probe.enabled["joint_states"] = False
    stopped = time.monotonic()
    time.sleep(2 * probe.period_s)  # the publishing thread finishes a round that may have begun
    last = probe.last_published["joint_states"]
    zero = probe.wait_for_command("cmd_vel", lambda v: v == 0.0, since=min(last, stopped), timeout_s=timeout_s)
    probe.enabled["joint_states"] = True
    if zero is None:
        raise RuntimeError(f"no zero cmd_vel within {timeout_s} s of stopping joint_states")
    return zero.time_s - last


def estop_trial(probe: RobotProbe, phase_s: float, timeout_s: float = 3.0) -> float:
    """Engage ``estop`` while the robot drives; seconds to a zero ``cmd_vel``; releases it again."""
    start_moving(probe)
    time.sleep(phase_s)
    sent = probe.publish("estop", probe.msg["Bool"](True))
    zero = probe.wait_for_command("cmd_vel", lambda v: v == 0.0, since=sent, timeout_s=timeout_s)
    probe.publish("estop", probe.msg["Bool"](False))
    if zero is None:
        raise RuntimeError(f"no zero cmd_vel within {timeout_s} s of estop")
    return zero.time_s - sent


STAMP_FAULTS = {"frozen": None, "old": -10.0, "future": 100.0, "out_of_order": -0.2}
"""Stamp faults of :func:`stamp_trial`: the shift of each new stamp, s (``frozen``: one message re-published)."""


def stamp_trial(probe: RobotProbe, kind: str, timeout_s: float = 2.0) -> float:
    """Give ``joint_states`` bad stamps (:data:`STAMP_FAULTS`) while the robot drives; seconds to a zero ``cmd_vel``.

    Measured from the frozen reading's stamp (``frozen``) or the first shifted message; ``inf`` when no
    zero command came within ``timeout_s``. Good stamps again afterwards.
    """
    start_moving(probe)
    frozen = probe.normal_message("joint_states")
    shift = STAMP_FAULTS[kind]
    t0 = time.monotonic()

    def make() -> Any:
        if shift is None:
            return frozen
        msg = probe.normal_message("joint_states")
        msg.header.stamp += probe.rospy.Duration.from_sec(shift)
        return msg

    probe.custom["joint_states"] = make
    zero = probe.wait_for_command("cmd_vel", lambda v: v == 0.0, since=t0, timeout_s=timeout_s)
    probe.custom.pop("joint_states")
    time.sleep(0.3)  # fresh again
    return math.inf if zero is None else zero.time_s - t0


def latency_summary(values: list[float]) -> dict[str, float]:
    """Median, 99th percentile, max and count of latencies, s."""
    import numpy as np

    a = np.asarray(values, dtype=float)
    return {"n": len(a), "median_s": float(np.median(a)), "p99_s": float(np.percentile(a, 99)),
            "max_s": float(a.max()), "min_s": float(a.min())}


# -------------------------------------------------------------------- a relay with faults on demand
RELAY_FAULTS = {
    "silence": "the topic stops",
    "frozen": "the last message is re-published, stamp and all, instead of new ones",
    "old": "stamps 10 s in the past",
    "future": "stamps 100 s ahead of the clock",
    "out_of_order": "after each message the one before it again (two publishers, one lagging)",
    "nan": "values NaN",
    "burst": "each message 20 times back to back, a third of the copies NaN, inf or far out of range",
    "estop": "estop true, then false",
}
"""What :meth:`FaultRelay.inject` can do to a topic (the stamp faults on stamped topics only)."""
BURST_COPIES = 20
BAD_VALUES = (math.nan, math.inf, -math.inf, 1e6)


@dataclass
class _Fault:
    kind: str
    topic: str
    t0: float | None = None
    """when the input turns bad (monotonic s): the first faulty message, or the reading it freezes"""
    bad_messages: int = 0
    previous: Any = None

    def sent_bad(self) -> None:
        self.bad_messages += 1
        if self.t0 is None:
            self.t0 = time.monotonic()


def with_value(topic: str, msg: Any, value: float) -> Any:
    """A copy of a sensor message with its reading (the joint positions: both) replaced by ``value``."""
    out = copy.deepcopy(msg)
    if topic == "joint_states":
        out.position = [value] * len(out.position)
    elif topic == "odom":
        out.twist.twist.linear.x = value
    elif topic == "pile_range":
        out.range = value
    else:
        out.data = value
    return out


class FaultRelay:
    """Relays ``{source}/TOPIC`` to ``TOPIC`` for each sensor topic; :meth:`inject` breaks one for a while.

    Args:
        source: namespace the simulator's sensor topics are remapped into (``joint_states:=sim/joint_states``).
        topics: the controller's topic names.
        seed: for the burst's random copies.
    """

    def __init__(self, source: str = "sim", topics: TopicsSection | None = None, seed: int = 0) -> None:
        self.rospy = rospy = import_rospy()
        from std_msgs.msg import Bool

        self.bool = Bool
        self.topics = topics = topics or TopicsSection()
        self.rng = np.random.default_rng(seed)
        self.lock = threading.Lock()
        self.fault: _Fault | None = None
        self.last: dict[str, Any] = {}
        """the last message relayed unchanged, per topic"""
        self.last_sent: dict[str, float] = {}
        """when it was relayed (monotonic s)"""
        self.relayed = 0
        self.publishers = {**publishers(topics, SENSOR_TOPICS), **publishers(topics, ("estop",))}
        self.subscribers = [rospy.Subscriber(f"{source}/{getattr(topics, name)}", message_class(name),
                                             partial(self._relay, name), queue_size=50, tcp_nodelay=True)
                            for name in SENSOR_TOPICS]

    def wait_connected(self, timeout_s: float = 60.0) -> None:
        """Wait until the simulator publishes to the relay and the controller listens to it."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if all(p.get_num_connections() > 0 for p in self.publishers.values()) and \
                    all(s.get_num_connections() > 0 for s in self.subscribers) and len(self.last) == len(SENSOR_TOPICS):
                return
            time.sleep(0.05)
        raise TimeoutError("the relay is not connected to both the simulator and the controller")

    def _relay(self, topic: str, msg: Any) -> None:
        with self.lock:
            fault = self.fault if self.fault is not None and self.fault.topic == topic else None
            out = [(msg, False)] if fault is None else self._faulty(fault, topic, msg)
            for message, bad in out:
                if bad:
                    fault.sent_bad()
                self.publishers[topic].publish(message)
            if fault is None:
                self.last[topic], self.last_sent[topic] = msg, time.monotonic()
                self.relayed += 1

    def shifted(self, msg: Any, seconds: float) -> Any:
        """A copy of a stamped message with its stamp moved by ``seconds``."""
        out = copy.deepcopy(msg)
        out.header.stamp += self.rospy.Duration.from_sec(seconds)
        return out

    def stamp_age(self, msg: Any) -> float:
        """How old a stamped message's reading is now, by the ROS clock, s."""
        return self.rospy.get_time() - msg.header.stamp.to_sec()

    def _faulty(self, fault: _Fault, topic: str, msg: Any) -> list[tuple[Any, bool]]:
        """What goes out instead of ``msg``: (message, whether it is a faulty one)."""
        kind = fault.kind
        if kind == "silence":
            return []
        if kind == "frozen":
            return [(self.last[topic], False)]  # the same reading: the input goes stale at its stamp
        if kind in ("old", "future"):
            return [(self.shifted(msg, -10.0 if kind == "old" else 100.0), True)]
        if kind == "out_of_order":
            previous, fault.previous = fault.previous or self.last[topic], msg
            return [(msg, False), (previous, True)]
        if kind == "nan":
            return [(with_value(topic, msg, math.nan), True)]
        out = []  # burst
        for _ in range(BURST_COPIES):
            bad = self.rng.random() < 1 / 3
            out.append((with_value(topic, msg, float(self.rng.choice(BAD_VALUES))) if bad else msg, bad))
        return out

    def inject(self, kind: str, topic: str, duration_s: float) -> dict[str, Any]:
        """Break ``topic`` (``estop`` for an estop) the way ``kind`` says for ``duration_s``; then relay again.

        Returns:
            ``kind``, ``topic``, ``t0`` (when the input turned bad, monotonic s: the first faulty
            message; for ``silence`` the last one relayed, for ``frozen`` the frozen reading's stamp),
            ``started`` and ``ended`` (monotonic s) and ``bad_messages``.
        """
        if kind not in RELAY_FAULTS:
            raise ValueError(f"unknown fault {kind!r}; known: {sorted(RELAY_FAULTS)}")
        started = time.monotonic()
        fault = _Fault(kind, topic)
        with self.lock:
            if kind == "silence":
                fault.t0 = self.last_sent[topic]
            elif kind == "frozen":
                fault.t0 = started - self.stamp_age(self.last[topic])
            self.fault = fault
        if kind == "estop":
            self.publishers["estop"].publish(self.bool(True))
            fault.sent_bad()
        time.sleep(duration_s)
        with self.lock:
            self.fault = None
        if kind == "estop":
            self.publishers["estop"].publish(self.bool(False))
        return {"kind": kind, "topic": topic, "t0": fault.t0, "started": started, "ended": time.monotonic(),
                "bad_messages": fault.bad_messages}

    def close(self) -> None:
        """Stop relaying."""
        for s in self.subscribers:
            s.unregister()
        for p in self.publishers.values():
            p.unregister()
