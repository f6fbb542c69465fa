"""A ROS 1 bag of a node's topics (``rosbag record``'s format), written with ``rosbags``.

Each message is stored as rospy serialised it, on a connection with its type's ROS 1 definition and
MD5 sum (``rosbags``' ROS 1 type store), timed by the wall clock when written. The bag is written
beside its final name and renamed into place when closed (:class:`~autoscoop.deploy.bag_file.BagFile`);
``rosbag``, ``rosbags`` and ``autoscoop replay`` read it.
"""

from __future__ import annotations

import io
import time
from pathlib import Path
from typing import Any

from autoscoop.deploy.bag_file import BagFile


class Ros1BagLog(BagFile):
    """rospy messages to a ROS 1 bag, from any thread; :meth:`close` completes it.

    Args:
        path: the ``.bag`` file to write (replaced when complete).
    """

    def __init__(self, path: str | Path) -> None:
        from rosbags.rosbag1 import Writer  # noqa: PLC0415 - the ros2 extra brings rosbags
        from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415

        super().__init__(path)
        self.writer = Writer(self.temporary)
        self.writer.open()
        self.typestore = get_typestore(Stores.ROS1_NOETIC)
        self.connections: dict[str, Any] = {}

    def write(self, topic: str, message: Any) -> None:
        """Append a rospy ``message`` on ``topic`` (resolved), now. Ignored once closed."""
        stamp = time.time_ns()
        buffer = io.BytesIO()
        message.serialize(buffer)
        package = type(message).__module__.split(".")[0]  # genpy classes live in e.g. sensor_msgs.msg._JointState
        name = type(message).__name__

        def add() -> None:
            if topic not in self.connections:
                self.connections[topic] = self.writer.add_connection(topic, f"{package}/msg/{name}",
                                                                     typestore=self.typestore)
            self.writer.write(self.connections[topic], stamp, buffer.getvalue())
        self.append(add)

    def finish(self) -> None:
        self.writer.close()
