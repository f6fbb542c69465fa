"""ROS 1 front ends (rospy): the only modules of autoscoop that import ROS.

ROS 1 comes from Debian's packages, which install into the system Python's
``/usr/lib/python3/dist-packages``; autoscoop runs in its own virtual environment (Python 3.11, as
Debian bookworm's). :func:`import_rospy` makes rospy importable from there: when ``import rospy``
fails it appends that folder (or ``$AUTOSCOOP_ROS_PYTHONPATH``) to the *end* of ``sys.path``, so
the environment's own packages (numpy, yaml) still win, and tries again. Nothing is written into
the virtual environment.
"""

from __future__ import annotations

import importlib
import os
import sys
from collections.abc import Callable, Iterable, Mapping
from types import ModuleType
from typing import Any

DEBIAN_PACKAGES = ("python3-rospy", "python3-rosmaster", "python3-std-msgs", "python3-sensor-msgs",
                   "python3-geometry-msgs", "python3-nav-msgs")
"""Debian packages of ROS 1 that the nodes and their tests need."""
SYSTEM_SITE = "/usr/lib/python3/dist-packages"
INSTALL_HINT = ("ROS 1 is not installed: as root run `apt-get update && apt-get install -y --no-install-recommends "
                + " ".join(DEBIAN_PACKAGES) + "` (Debian bookworm), or set AUTOSCOOP_ROS_PYTHONPATH to the folder "
                "that holds rospy")


MESSAGE_TYPES = {
    "joint_states": ("sensor_msgs.msg", "JointState"), "odom": ("nav_msgs.msg", "Odometry"),
    "pile_range": ("sensor_msgs.msg", "Range"), "bucket_torque": ("std_msgs.msg", "Float64"),
    "lift_torque": ("std_msgs.msg", "Float64"), "payload_mass": ("std_msgs.msg", "Float64"),
    "estop": ("std_msgs.msg", "Bool"), "scoop": ("std_msgs.msg", "Bool"), "cmd_vel": ("geometry_msgs.msg", "Twist"),
    "lift_command": ("std_msgs.msg", "Float64"), "tilt_command": ("std_msgs.msg", "Float64"),
}
"""The message type of each of the controller's topics (keys of ``robot_config.TOPIC_DEFAULTS``)."""


class RosUnavailable(RuntimeError):
    """rospy or a message package cannot be imported; the message says how to install them."""


def import_rospy() -> ModuleType:
    """``rospy``, importable from the virtual environment (see the module docstring).

    Raises:
        RosUnavailable: with the install command, if rospy is not installed.
    """
    try:
        return importlib.import_module("rospy")
    except ImportError:
        pass
    extra = [p for p in (os.environ.get("AUTOSCOOP_ROS_PYTHONPATH", ""), SYSTEM_SITE) if p and os.path.isdir(p)]
    for path in extra:
        if path not in sys.path:
            sys.path.append(path)
    try:
        module = importlib.import_module("rospy")
        for name in ("std_msgs.msg", "sensor_msgs.msg", "geometry_msgs.msg", "nav_msgs.msg"):
            importlib.import_module(name)
        return module
    except ImportError as error:
        raise RosUnavailable(f"{INSTALL_HINT} ({error})") from None


def ros_available() -> bool:
    """Whether rospy, rosmaster and the message packages can be used here."""
    import shutil  # noqa: PLC0415

    try:
        import_rospy()
    except RosUnavailable:
        return False
    return shutil.which("rosmaster") is not None


def message_class(topic: str) -> type:
    """The message class a topic carries (``MESSAGE_TYPES``), e.g. ``message_class("odom")`` is Odometry."""
    module, name = MESSAGE_TYPES[topic]
    return getattr(importlib.import_module(module), name)


def publishers(topics: Any, names: Iterable[str], queue_size: int = 20,
               tcp_nodelay: bool = True) -> dict[str, Any]:
    """One publisher per topic key, on the names in ``topics`` (a TopicsSection); latency-friendly
    (``tcp_nodelay``) unless told otherwise."""
    rospy = import_rospy()
    return {name: rospy.Publisher(getattr(topics, name), message_class(name), queue_size=queue_size,
                                  tcp_nodelay=tcp_nodelay) for name in names}


def subscribers(topics: Any, callbacks: Mapping[str, Callable[[Any], None]],
                queue_size: int | None = 10) -> dict[str, Any]:
    """One latency-friendly (``tcp_nodelay``) subscriber per topic key, on the names in ``topics`` (a TopicsSection).

    Args:
        topics: the topic names (``TopicsSection``).
        callbacks: per topic key (of :data:`MESSAGE_TYPES`), the function called with each message.
        queue_size: messages kept per topic while a callback runs; ``None``: unbounded.

    Returns:
        The subscribers by topic key (``unregister()`` each when done).
    """
    rospy = import_rospy()
    return {name: rospy.Subscriber(getattr(topics, name), message_class(name), callback, queue_size=queue_size,
                                   tcp_nodelay=True) for name, callback in callbacks.items()}
