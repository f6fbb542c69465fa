"""A ROS 1 bag of a node's topics (``rosbag record``'s format), written with ``rosbags``.

Each message is stored as rospy serialised it, on a connection with its type's ROS 1 definition and
MD5 sum (``rosbags``' ROS 1 type store), timed by the wall clock when written. The bag is written
beside its final name and renamed into place when closed; ``rosbag``, ``rosbags`` and
``autoscoop replay`` read it.
"""

from __future__ import annotations

import io
import threading
import time
from contextlib import ExitStack
from pathlib import Path
from typing import Any

from autoscoop.core.safe_files import atomic_output


class Ros1BagLog:
    """rospy messages to a ROS 1 bag, from any thread; :meth:`close` completes it.

    Args:
        path: the ``.bag`` file to write (replaced when complete).
    """

    def __init__(self, path: str | Path) -> None:
        from rosbags.rosbag1 import Writer  # noqa: PLC0415 - the ros2 extra brings rosbags
        from rosbags.typesys import Stores, get_typestore  # noqa: PLC0415

        self.path = Path(path)
        self._stack = ExitStack()
        temporary = self._stack.enter_context(atomic_output(self.path))
        self._writer = Writer(temporary)
        self._writer.open()
        self._typestore = get_typestore(Stores.ROS1_NOETIC)
        self._connections: dict[str, Any] = {}
        self._lock = threading.Lock()
        self.count = 0
        self.closed = False

    def write(self, topic: str, message: Any) -> None:
        """Append a rospy ``message`` on ``topic`` (resolved), now. Ignored once closed."""
        stamp = time.time_ns()
        buffer = io.BytesIO()
        message.serialize(buffer)
        package = type(message).__module__.split(".")[0]  # genpy classes live in e.g. sensor_msgs.msg._JointState
        name = type(message).__name__
        with self._lock:
            if self.closed:
                return
            if topic not in self._connections:
                self._connections[topic] = self._writer.add_connection(topic, f"{package}/msg/{name}",
                                                                       typestore=self._typestore)
            self._writer.write(self._connections[topic], stamp, buffer.getvalue())
            self.count += 1

    def close(self) -> None:
        """Finish the bag and move it into place (once)."""
        with self._lock:
            if self.closed:
                return
            self.closed = True
            self._writer.close()
        self._stack.close()
