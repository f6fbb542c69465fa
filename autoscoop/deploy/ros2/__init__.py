"""ROS 2 front ends over Cyclone DDS: the controller and the simulator on ROS 2 topics, without rclpy.

ROS 2 is DDS on the wire. A Cyclone DDS participant that follows ROS 2's conventions (``rt/`` topic
prefix, ``pkg::msg::dds_::Type_`` type names, the message layouts and QoS profiles of ROS 2) talks
to ROS 2 nodes on ``rmw_cyclonedds_cpp`` and, through DDS interoperability, to the others:

- :mod:`.messages`: the message types, defined once;
- :mod:`.graph`: names (namespaces, ``~``, remappings, ``rt/``), QoS profiles, ``ROS_DOMAIN_ID``;
- :mod:`.controller_node`, :mod:`.sim_node`: the nodes.

This package's modules import ``cyclonedds`` (the ``ros2`` extra); this file does not, so a command
can say how to install it.
"""

from __future__ import annotations

import importlib.util

INSTALL_HINT = ("ROS 2 support needs the ros2 extra: `pip install 'autoscoop[ros2]'` "
                "(cyclonedds, rosbags, mcap, mcap-ros2-support)")


class Ros2Unavailable(RuntimeError):
    """``cyclonedds`` cannot be imported; the message says how to install it."""


def ros2_available() -> bool:
    """Whether the Cyclone DDS binding (with its C library) is installed here."""
    return importlib.util.find_spec("cyclonedds") is not None


def require_ros2() -> None:
    """Raise :class:`Ros2Unavailable`, with the install command, unless :func:`ros2_available`."""
    if not ros2_available():
        raise Ros2Unavailable(INSTALL_HINT)
