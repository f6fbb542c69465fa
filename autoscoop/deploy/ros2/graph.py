"""ROS 2's graph conventions on Cyclone DDS: names, QoS profiles, the domain, and one participant per node.

Names follow ROS 2: a relative name (``joint_states``) lies in the node's namespace
(``/loader1/joint_states``), a private one (``~/status``) under the node
(``/loader1/autoscoop_controller/status``), an absolute one (``/joint_states``) where it says;
remappings ``from:=to`` match the expanded name, and ``__ns:=`` / ``__node:=`` set the namespace and the
node's name. On DDS a topic ``/a/b`` is ``rt/a/b``.

QoS, as ROS 2 nodes use it: sensor readings best effort, keep last 5 (``rclcpp::SensorDataQoS``);
commands reliable, keep last 10 (the default profile); the e-stop and the status reliable and
transient-local, keep last 1 (a latched topic: a late subscriber gets the last value).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from cyclonedds.core import Listener, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from autoscoop.core.config import ConfigError

DDS_TOPIC_PREFIX = "rt"
"""ROS 2 topics are DDS topics ``rt/<name without its leading slash>``."""
MAX_DOMAIN_ID = 232
"""The largest DDS domain id (ROS 2 recommends 0 to 101 on Linux)."""
RELIABLE_BLOCKING_S = 0.1
"""How long a reliable write may block on a full history, s."""

SENSOR_DATA = Qos(Policy.Reliability.BestEffort, Policy.Durability.Volatile, Policy.History.KeepLast(5))
"""Sensor readings: best effort, keep last 5, volatile (``rclcpp::SensorDataQoS``)."""
COMMANDS = Qos(Policy.Reliability.Reliable(duration(seconds=RELIABLE_BLOCKING_S)), Policy.Durability.Volatile,
               Policy.History.KeepLast(10))
"""Commands and events: reliable, keep last 10, volatile (ROS 2's default profile)."""
LATCHED = Qos(Policy.Reliability.Reliable(duration(seconds=RELIABLE_BLOCKING_S)), Policy.Durability.TransientLocal,
              Policy.History.KeepLast(1))
"""Latched state (e-stop, status): reliable, transient-local, keep last 1."""

TOPIC_QOS = {
    "joint_states": SENSOR_DATA, "odom": SENSOR_DATA, "pile_range": SENSOR_DATA, "bucket_torque": SENSOR_DATA,
    "lift_torque": SENSOR_DATA, "payload_mass": SENSOR_DATA, "estop": LATCHED, "scoop": COMMANDS,
    "cmd_vel": COMMANDS, "lift_command": COMMANDS, "tilt_command": COMMANDS,
}
"""The QoS of each of the controller's topics (keys of ``robot_config.TOPIC_DEFAULTS``)."""

LOOPBACK_CONFIG = ("<CycloneDDS><Domain><General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
                   "<AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address=\"127.0.0.1\"/>"
                   "</Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>60"
                   "</MaxAutoParticipantIndex></Discovery></Domain></CycloneDDS>")
"""A ``CYCLONEDDS_URI`` that keeps DDS on 127.0.0.1 (unicast discovery), for tests and benchmarks."""


def loopback_environment(domain: int | None = None) -> dict[str, str]:
    """A copy of ``os.environ`` for ROS 2 processes that stay on 127.0.0.1 in a domain of their own
    (default: a random one in [100, 199], so two runs at once do not hear each other)."""
    import random  # noqa: PLC0415

    chosen = random.SystemRandom().randint(100, 199) if domain is None else domain
    return {**os.environ, "CYCLONEDDS_URI": LOOPBACK_CONFIG, "ROS_DOMAIN_ID": str(chosen), "PYTHONUNBUFFERED": "1"}


def domain_id(environ: Mapping[str, str] | None = None) -> int:
    """The DDS domain: ``ROS_DOMAIN_ID`` as ROS 2 reads it (unset or empty: 0).

    Raises:
        ConfigError: not an integer in [0, 232].
    """
    text = (os.environ if environ is None else environ).get("ROS_DOMAIN_ID", "").strip()
    if not text:
        return 0
    if not text.isdigit() or int(text) > MAX_DOMAIN_ID:
        raise ConfigError(f"ROS_DOMAIN_ID={text!r}: must be an integer in [0, {MAX_DOMAIN_ID}]")
    return int(text)


def expand_name(name: str, namespace: str, node: str) -> str:
    """The fully qualified ROS 2 name of ``name`` for a node ``node`` in ``namespace`` (``/`` or ``/a/b``)."""
    namespace = "/" + namespace.strip("/") if namespace.strip("/") else ""
    if name.startswith("/"):
        return name
    if name.startswith("~"):
        rest = name[1:].lstrip("/")
        return f"{namespace}/{node}" + (f"/{rest}" if rest else "")
    return f"{namespace}/{name}"


def dds_topic(fully_qualified: str) -> str:
    """The DDS topic of a ROS 2 topic: ``/a/b`` -> ``rt/a/b``."""
    return f"{DDS_TOPIC_PREFIX}{fully_qualified}"


def parse_remaps(arguments: Iterable[str]) -> tuple[dict[str, str], str | None, str | None]:
    """Split ``from:=to`` arguments into name remappings, the namespace (``__ns``) and the node name (``__node``).

    Returns:
        The remappings (names as given), the namespace or ``None``, the node's name or ``None``.
    """
    remaps: dict[str, str] = {}
    namespace = node = None
    for argument in arguments:
        source, _, target = argument.partition(":=")
        if source == "__ns":
            namespace = target
        elif source in ("__node", "__name"):
            node = target
        elif source.startswith("_") and not source.startswith("__"):
            raise ConfigError(f"{argument!r}: ROS 1 private parameters are not read by the ROS 2 nodes; "
                              "set them in the robot YAML")
        else:
            remaps[source] = target
    return remaps, namespace, node


def take_all(reader: DataReader, message_type: type, limit: int = 64) -> list[Any]:
    """Every message waiting in ``reader`` (samples that are not messages, such as disposals, skipped)."""
    return [sample for sample in reader.take(N=limit) if isinstance(sample, message_type)]


class Ros2Node:
    """A ROS 2 node on Cyclone DDS: one domain participant, names resolved as ROS 2 does, writers and readers.

    Args:
        name: the node's name (``__node:=`` in ``remaps`` overrides it).
        remaps: ``from:=to`` arguments (:func:`parse_remaps`).
        namespace: the node's namespace; default ``__ns:=`` in ``remaps``, else ``ROS_NAMESPACE``, else ``/``.
        domain: the DDS domain; default :func:`domain_id`.
    """

    def __init__(self, name: str, remaps: Iterable[str] = (), namespace: str | None = None,
                 domain: int | None = None) -> None:
        rules, remapped_namespace, remapped_name = parse_remaps(remaps)
        self.name = remapped_name or name
        self.namespace = namespace or remapped_namespace or os.environ.get("ROS_NAMESPACE", "") or "/"
        self.domain = domain_id() if domain is None else domain
        self.remaps = {self._expand(source): self._expand(target) for source, target in rules.items()}
        self.participant = DomainParticipant(self.domain)
        self._topics: dict[str, Topic] = {}
        self.readers: list[DataReader] = []
        self.writers: list[DataWriter] = []

    def _expand(self, name: str) -> str:
        return expand_name(name, self.namespace, self.name)

    def resolve(self, name: str) -> str:
        """The fully qualified name of topic ``name`` after this node's remappings."""
        expanded = self._expand(name)
        return self.remaps.get(expanded, expanded)

    def _topic(self, name: str, message_type: type) -> Topic:
        topic = dds_topic(self.resolve(name))
        if topic not in self._topics:
            self._topics[topic] = Topic(self.participant, topic, message_type)
        return self._topics[topic]

    def publisher(self, name: str, message_type: type, qos: Qos) -> DataWriter:
        """A writer of ``message_type`` on topic ``name`` (resolved) with ``qos``."""
        writer = DataWriter(self.participant, self._topic(name, message_type), qos=qos)
        self.writers.append(writer)
        return writer

    def subscription(self, name: str, message_type: type, qos: Qos,
                     callback: Callable[[Any], None] | None = None) -> DataReader:
        """A reader of topic ``name`` (resolved) with ``qos`` that calls ``callback`` with each message, on a
        Cyclone DDS thread; without a callback, read it with :func:`take_all`."""
        def on_data_available(reader: DataReader) -> None:
            for message in take_all(reader, message_type):
                callback(message)

        listener = None if callback is None else Listener(on_data_available=on_data_available)
        reader = DataReader(self.participant, self._topic(name, message_type), qos=qos, listener=listener)
        self.readers.append(reader)
        return reader

    def wait_for_subscriber(self, writer: DataWriter, timeout_s: float) -> bool:
        """Wait until ``writer`` has a matched reader; whether it did within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while writer.get_publication_matched_status().current_count == 0:
            if time.monotonic() > deadline:
                return False
            time.sleep(0.02)
        return True

    def close(self) -> None:
        """Delete the participant and everything it holds: no callback runs after this returns."""
        for reader in self.readers:
            reader.set_listener(None)
        self.readers.clear()
        self.writers.clear()
        self._topics.clear()
        self.participant.__del__()  # the binding has no close(): deleting the participant deletes its entities
