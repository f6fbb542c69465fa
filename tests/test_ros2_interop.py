"""Our ROS 2 topics against the official ROS 2 definitions: message names, fields and QoS.

No ROS 2 installation is available here (Debian bookworm ships no rclpy: ``apt-cache search rclpy`` finds
nothing), so the nodes cannot meet an ``rclpy`` node. Instead each message type the nodes send or
receive is compared with the official ROS 2 Humble definition that ``rosbags``' type store carries
(the ``.msg`` files of ``common_interfaces`` and ``rcl_interfaces``): the ``.msg`` text written from our
IDL struct (field names, types, order, constants) must equal the text ``rosbags`` generates, the DDS
type name must be ``rmw_cyclonedds_cpp``'s for that type, and the CDR bytes equal ``rosbags``' (in
test_ros2_messages.py). The QoS of each topic is compared with the ROS 2 profiles documented in
``rmw/qos_profiles.h`` (``rmw_qos_profile_sensor_data``, ``rmw_qos_profile_default``) and the
latched convention (``rclcpp::QoS(1).transient_local()``). Skipped where the ``ros2`` extra is missing.
"""

import dataclasses
import typing

import pytest

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags")

from cyclonedds.core import Policy
from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, sequence
from rosbags.typesys import Stores, get_typestore

from autoscoop.deploy.robot_config import TOPIC_DEFAULTS
from autoscoop.deploy.ros2 import messages as m
from autoscoop.deploy.ros2.graph import COMMANDS, LATCHED, SENSOR_DATA, TOPIC_QOS

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)

OFFICIAL_TOPIC_TYPES = {
    "joint_states": "sensor_msgs/msg/JointState", "odom": "nav_msgs/msg/Odometry", "pile_range": "sensor_msgs/msg/Range",
    "bucket_torque": "std_msgs/msg/Float64", "lift_torque": "std_msgs/msg/Float64", "payload_mass": "std_msgs/msg/Float64",
    "estop": "std_msgs/msg/Bool", "scoop": "std_msgs/msg/Bool", "cmd_vel": "geometry_msgs/msg/Twist",
    "lift_command": "std_msgs/msg/Float64", "tilt_command": "std_msgs/msg/Float64",
}
"""The type each topic has on a ROS 2 robot: cmd_vel a Twist (as teleop_twist_keyboard and Nav2 send it),
joint position controllers' commands Float64, ..."""

ROS2_PROFILES = {
    # rmw/qos_profiles.h: history, depth, reliability, durability
    "rmw_qos_profile_sensor_data": ("keep_last", 5, "best_effort", "volatile"),
    "rmw_qos_profile_default": ("keep_last", 10, "reliable", "volatile"),
    "latched (rclcpp::QoS(1).transient_local())": ("keep_last", 1, "reliable", "transient_local"),
}
EXPECTED_PROFILE = {
    "joint_states": "rmw_qos_profile_sensor_data", "odom": "rmw_qos_profile_sensor_data",
    "pile_range": "rmw_qos_profile_sensor_data", "bucket_torque": "rmw_qos_profile_sensor_data",
    "lift_torque": "rmw_qos_profile_sensor_data", "payload_mass": "rmw_qos_profile_sensor_data",
    "scoop": "rmw_qos_profile_default", "cmd_vel": "rmw_qos_profile_default",
    "lift_command": "rmw_qos_profile_default", "tilt_command": "rmw_qos_profile_default",
    "estop": "latched (rclcpp::QoS(1).transient_local())",
}


def _field_type(hint, name):
    """The .msg spelling of one field's type from its IDL annotation."""
    if isinstance(hint, type) and issubclass(hint, IdlStruct):
        return m.ROS_TYPE_NAMES[hint].replace("/msg/", "/")
    if hint is bool:
        return "bool"
    if hint is str:
        return "string"
    kind = typing.get_args(hint)[1] if typing.get_origin(hint) is typing.Annotated else None
    if isinstance(kind, str):
        return kind
    if isinstance(kind, sequence):
        return _field_type(kind.subtype, name) + "[]"
    if isinstance(kind, array):
        return _field_type(kind.subtype, name) + f"[{kind.length}]"
    raise AssertionError(f"field {name}: no .msg spelling for {hint!r}")


def msg_text(cls, constants):
    """The ``.msg`` text of our IDL struct, in the layout ``rosbags`` generates: constants, then fields."""
    hints = typing.get_type_hints(cls, include_extras=True)
    lines = [f"{ctype} {cname}={getattr(cls, cname)}" for cname, ctype, _ in constants]
    lines += [f"{_field_type(hints[f.name], f.name)} {f.name}" for f in dataclasses.fields(cls)]
    return "\n".join(lines)


def official_text(name):
    """The first block of ``rosbags``' generated definition (the type itself, without its dependencies)."""
    text, _ = TYPESTORE.generate_msgdef(name, ros_version=2)
    return text.split("\n" + "=" * 80)[0].strip()


@pytest.mark.parametrize("cls", sorted(m.ROS_TYPE_NAMES, key=lambda c: c.__name__), ids=lambda c: c.__name__)
def test_each_message_is_the_official_ros2_definition_field_for_field(cls):
    name = m.ROS_TYPE_NAMES[cls]
    constants, _ = TYPESTORE.fielddefs[name]
    assert msg_text(cls, constants) == official_text(name)
    package, _, short = name.split("/")
    assert cls.__idl_typename__ == f"{package}::msg::dds_::{short}_"  # rmw_cyclonedds_cpp's type name


def test_a_field_renamed_would_be_caught():
    @dataclasses.dataclass
    class Misnamed(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
        value: m.float64 = 0.0

    assert msg_text(Misnamed, []) != official_text("std_msgs/msg/Float64")


def test_each_topic_carries_its_official_type():
    assert set(OFFICIAL_TOPIC_TYPES) == set(TOPIC_DEFAULTS) == set(m.MESSAGE_TYPES)
    for key, cls in m.MESSAGE_TYPES.items():
        assert m.ROS_TYPE_NAMES[cls] == OFFICIAL_TOPIC_TYPES[key], key
        assert OFFICIAL_TOPIC_TYPES[key] in TYPESTORE.types  # a type ROS 2 defines


def profile(qos):
    """(history, depth, reliability, durability) of a Cyclone DDS QoS, in rmw's words."""
    history, reliability, durability = qos[Policy.History], qos[Policy.Reliability], qos[Policy.Durability]
    words = {"KeepLast": "keep_last", "KeepAll": "keep_all", "BestEffort": "best_effort", "Reliable": "reliable",
             "Volatile": "volatile", "TransientLocal": "transient_local"}
    return (words[type(history).__name__.split(".")[-1]], getattr(history, "depth", None),
            words[type(reliability).__name__.split(".")[-1]], words[type(durability).__name__.split(".")[-1]])


def test_each_topics_qos_is_the_ros2_profile_for_its_kind():
    assert set(TOPIC_QOS) == set(EXPECTED_PROFILE)
    for key, qos in TOPIC_QOS.items():
        assert profile(qos) == ROS2_PROFILES[EXPECTED_PROFILE[key]], key
    assert profile(SENSOR_DATA) != profile(COMMANDS) != profile(LATCHED)
