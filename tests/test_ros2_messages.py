"""The ROS 2 message types' CDR bytes against an independent ROS 2 serialiser (``rosbags``, ROS 2 Humble).

What we send must be what a ROS 2 node sends for the same message, and what a ROS 2 node sends must
decode to the same message here. Skipped where the ``ros2`` extra is not installed.
"""

import dataclasses

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

pytest.importorskip("cyclonedds")
pytest.importorskip("rosbags")

from cyclonedds.idl import IdlStruct
from rosbags.typesys import Stores, get_typestore

from autoscoop.deploy.ros2 import messages as m

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)


def to_rosbags(message):
    """The same message as a ``rosbags`` object, field by field (numbers in numpy arrays, as rosbags keeps them)."""
    cls = TYPESTORE.types[m.ROS_TYPE_NAMES[type(message)]]
    values = {}
    for f in dataclasses.fields(message):
        value = getattr(message, f.name)
        if isinstance(value, IdlStruct):
            value = to_rosbags(value)
        elif isinstance(value, list) and not all(isinstance(v, str) for v in value):
            value = np.asarray(value, dtype=np.float64)
        elif isinstance(value, list) and not value and f.name != "name":
            value = np.asarray(value, dtype=np.float64)
        values[f.name] = value
    return cls(**values)


def stamped(sec=1_700_000_000, nanosec=123_456_789, frame="odom"):
    return m.Header(stamp=m.Time(sec=sec, nanosec=nanosec), frame_id=frame)


def covariance(offset):
    return [offset + 0.5 * i for i in range(36)]


EXAMPLES = [
    m.Time(sec=17, nanosec=999_999_999),
    stamped(),
    m.Vector3(1.5, -2.25, 3.0),
    m.Point(0.1, 0.2, 0.3),
    m.Quaternion(0.0, 0.1, 0.0, 0.995),
    m.Pose(m.Point(1.0, 2.0, 3.0), m.Quaternion(0.0, 0.0, 0.7071, 0.7071)),
    m.PoseWithCovariance(m.Pose(), covariance(1.0)),
    m.Twist(m.Vector3(0.1, 0.0, 0.0), m.Vector3(0.0, 0.0, -0.3)),
    m.TwistWithCovariance(m.Twist(m.Vector3(0.05)), covariance(-2.0)),
    m.Odometry(stamped(), "base_link",
               m.PoseWithCovariance(m.Pose(m.Point(0.4, 0.0, 0.1), m.Quaternion(0.0, 0.02, 0.0, 0.9998)),
                                    covariance(0.0)),
               m.TwistWithCovariance(m.Twist(m.Vector3(0.1, 0.0, 0.0)), covariance(3.0))),
    m.JointState(stamped(frame=""), ["lift", "tilt"], [0.125, -0.3]),
    m.JointState(stamped(frame="base"), ["lift", "tilt", "x"], [0.1, 0.2, 0.3], [1.0, 2.0, 3.0], [-1.0, 0.0, 1.0]),
    m.JointState(),
    m.Range(stamped(frame="bucket_tip"), m.Range.INFRARED, 0.0625, 0.0, 4.0, 0.75),
    m.Float64(-12.345),
    m.Bool(True),
    m.Bool(False),
    m.String("running: policy default"),
]


def test_every_type_of_the_loop_has_an_example_and_a_ros2_name():
    assert {type(e) for e in EXAMPLES} == set(m.ROS_TYPE_NAMES)
    assert set(m.MESSAGE_TYPES.values()) <= set(m.ROS_TYPE_NAMES)
    assert m.ROS_TYPE_NAMES[m.JointState] == "sensor_msgs/msg/JointState"
    assert m.JointState.__idl_typename__ == "sensor_msgs::msg::dds_::JointState_"
    assert m.ROS_TYPE_NAMES[m.Time] == "builtin_interfaces/msg/Time"


@pytest.mark.parametrize("message", EXAMPLES, ids=lambda e: type(e).__name__)
def test_cdr_bytes_equal_rosbags_both_ways(message):
    name = m.ROS_TYPE_NAMES[type(message)]
    theirs = bytes(TYPESTORE.serialize_cdr(to_rosbags(message), name))
    ours = message.serialize()
    assert ours == theirs
    assert type(message).deserialize(theirs) == message
    decoded = TYPESTORE.deserialize_cdr(ours, name)
    assert bytes(TYPESTORE.serialize_cdr(decoded, name)) == ours


def test_a_wrong_layout_would_be_caught():
    """The comparison can fail: a message with a field missing serialises differently."""
    @dataclasses.dataclass
    class RangeWithoutFieldOfView(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
        header: m.Header = dataclasses.field(default_factory=m.Header)
        radiation_type: m.uint8 = 0
        min_range: m.float32 = 0.0
        max_range: m.float32 = 4.0
        range: m.float32 = 0.5

    good = m.Range(stamped(), 1, 0.0, 0.0, 4.0, 0.5)
    theirs = bytes(TYPESTORE.serialize_cdr(to_rosbags(good), "sensor_msgs/msg/Range"))
    assert RangeWithoutFieldOfView(good.header, 1, 0.0, 4.0, 0.5).serialize() != theirs


finite = st.floats(allow_nan=False, allow_infinity=False, width=64)


@given(names=st.lists(st.text(alphabet=st.characters(min_codepoint=32, max_codepoint=0x2FF), max_size=12), max_size=4),
       data=st.data(), sec=st.integers(0, 2**31 - 1), nanosec=st.integers(0, 999_999_999))
def test_any_joint_state_matches_rosbags(names, data, sec, nanosec):
    positions = data.draw(st.lists(finite, min_size=len(names), max_size=len(names)))
    message = m.JointState(stamped(sec, nanosec, "f"), names, positions)
    theirs = bytes(TYPESTORE.serialize_cdr(to_rosbags(message), "sensor_msgs/msg/JointState"))
    assert message.serialize() == theirs
    assert m.JointState.deserialize(theirs) == message


@given(seconds=st.floats(0.0, 2.0**31 - 1.0))
def test_time_from_seconds_round_trips_to_the_nanosecond(seconds):
    stamp = m.Time.from_seconds(seconds)
    assert 0 <= stamp.nanosec < m.NANOSECONDS_PER_SECOND
    assert abs(stamp.to_seconds() - seconds) <= 1e-9 + 1e-15 * seconds


def test_a_range_from_iron_or_jazzy_decodes_with_its_variance_ignored():
    """Iron added a trailing ``variance`` to sensor_msgs/Range: a newer robot's bytes still give our fields."""
    jazzy = get_typestore(Stores.ROS2_JAZZY)
    header = jazzy.types["std_msgs/msg/Header"](stamp=jazzy.types["builtin_interfaces/msg/Time"](sec=5, nanosec=6),
                                                frame_id="tip")
    theirs = bytes(jazzy.serialize_cdr(jazzy.types["sensor_msgs/msg/Range"](
        header=header, radiation_type=1, field_of_view=0.5, min_range=0.0, max_range=4.0, range=0.75, variance=0.25),
        "sensor_msgs/msg/Range"))
    assert len(theirs) == len(m.Range().serialize()) + 8  # the float32 and its padding
    assert m.Range.deserialize(theirs) == m.Range(m.Header(m.Time(5, 6), "tip"), 1, 0.5, 0.0, 4.0, 0.75)
