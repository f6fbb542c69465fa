"""ROS 2 messages as Cyclone DDS types: the layouts of ROS 2 Humble, under ROS 2's DDS type names.

Each class is a ``cyclonedds.idl.IdlStruct`` whose type name is the one ``rmw_cyclonedds_cpp`` gives
the message (``sensor_msgs::msg::dds_::JointState_``) and whose fields are the message's, in order,
with the same IDL types, so its CDR bytes are those a ROS 2 node sends and reads
(``tests/test_ros2_messages.py`` checks them against ``rosbags``' serialiser).

:data:`ROS_TYPE_NAMES` gives each class its ROS 2 name (``sensor_msgs/msg/JointState``), and
:data:`MESSAGE_TYPES` the class each of the controller's topics carries (keys of
``robot_config.TOPIC_DEFAULTS``). No ``from __future__ import annotations`` here: Cyclone DDS reads the
fields' annotations as types. Only this module and its package's siblings import ``cyclonedds``.
"""

import math
from dataclasses import dataclass, field

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import array, float32, float64, int32, sequence, uint8, uint32

NANOSECONDS_PER_SECOND = 1_000_000_000


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    """``builtin_interfaces/Time``: seconds and nanoseconds since the epoch of the sender's clock."""

    sec: int32 = 0
    nanosec: uint32 = 0

    @classmethod
    def from_seconds(cls, seconds: float) -> "Time":
        """The stamp of ``seconds`` (s since the epoch, >= 0), to the nanosecond below."""
        whole = math.floor(seconds)
        nanosec = min(int(round((seconds - whole) * NANOSECONDS_PER_SECOND)), NANOSECONDS_PER_SECOND - 1)
        return cls(sec=int(whole), nanosec=nanosec)

    def to_seconds(self) -> float:
        """The stamp in seconds (0.0: not stamped)."""
        return self.sec + self.nanosec / NANOSECONDS_PER_SECOND


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    """``std_msgs/Header``: when the reading was taken and in which frame."""

    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    """``geometry_msgs/Vector3``."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    """``geometry_msgs/Point``, m."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    """``geometry_msgs/Quaternion`` (x, y, z, w order on the wire; identity by default)."""

    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    """``geometry_msgs/Pose``."""

    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    """``geometry_msgs/PoseWithCovariance`` (a 6x6 row-major covariance)."""

    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    """``geometry_msgs/Twist``: linear (m/s) and angular (rad/s) velocity."""

    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    """``geometry_msgs/TwistWithCovariance``."""

    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    """``nav_msgs/Odometry``: the pose in ``header.frame_id``, the twist in ``child_frame_id``."""

    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class JointState(IdlStruct, typename="sensor_msgs::msg::dds_::JointState_"):
    """``sensor_msgs/JointState``: names and positions (rad), optional velocities and efforts."""

    header: Header = field(default_factory=Header)
    name: sequence[str] = field(default_factory=list)
    position: sequence[float64] = field(default_factory=list)
    velocity: sequence[float64] = field(default_factory=list)
    effort: sequence[float64] = field(default_factory=list)


@dataclass
class Range(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    """``sensor_msgs/Range`` as in ROS 2 Humble: a distance (m) with the sensor's limits (Jazzy adds
    a trailing ``variance``)."""

    ULTRASOUND = 0
    INFRARED = 1

    header: Header = field(default_factory=Header)
    radiation_type: uint8 = 0
    field_of_view: float32 = 0.0
    min_range: float32 = 0.0
    max_range: float32 = 0.0
    range: float32 = 0.0


@dataclass
class Float64(IdlStruct, typename="std_msgs::msg::dds_::Float64_"):
    """``std_msgs/Float64``."""

    data: float64 = 0.0


@dataclass
class Bool(IdlStruct, typename="std_msgs::msg::dds_::Bool_"):
    """``std_msgs/Bool``."""

    data: bool = False


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    """``std_msgs/String``."""

    data: str = ""


ROS_TYPE_NAMES: dict[type, str] = {
    cls: cls.__idl_typename__.replace("::msg::dds_::", "/msg/").rstrip("_")
    for cls in (Time, Header, Vector3, Point, Quaternion, Pose, PoseWithCovariance, Twist, TwistWithCovariance,
                Odometry, JointState, Range, Float64, Bool, String)
}
"""Each message class's ROS 2 name, e.g. ``JointState`` -> ``sensor_msgs/msg/JointState``."""

MESSAGE_TYPES: dict[str, type] = {
    "joint_states": JointState, "odom": Odometry, "pile_range": Range, "bucket_torque": Float64,
    "lift_torque": Float64, "payload_mass": Float64, "estop": Bool, "scoop": Bool, "cmd_vel": Twist,
    "lift_command": Float64, "tilt_command": Float64,
}
"""The message class of each of the controller's topics (keys of ``robot_config.TOPIC_DEFAULTS``)."""
