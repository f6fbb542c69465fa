"""What a bag writer shares, whatever its format: written beside its final name, from any thread, closed once.

:class:`BagFile` holds the temporary file (``core.safe_files.atomic_output``: renamed over the final name
when closed, removed on an error), a lock, and the message count; a format's writer
(``ros1.bag_log``, ``ros2.mcap_log``) opens its library's writer on :attr:`BagFile.temporary`, adds each
message through :meth:`BagFile.append` and completes the file in :meth:`BagFile.finish`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import ExitStack
from pathlib import Path

from autoscoop.core.safe_files import atomic_output


class BagFile:
    """A bag being written to :attr:`temporary`, moved to ``path`` by :meth:`close`.

    Args:
        path: the file to write (replaced when complete).
    """

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)
        self.stack = ExitStack()
        """closes what the writer opened, then moves the file into place"""
        self.temporary = self.stack.enter_context(atomic_output(self.path))
        self.lock = threading.Lock()
        self.count = 0
        self.closed = False

    def append(self, add: Callable[[], None]) -> None:
        """Run ``add`` (which writes one message) under the lock, unless the bag is closed."""
        with self.lock:
            if self.closed:
                return
            add()
            self.count += 1

    def finish(self) -> None:
        """Complete the file (the format's writer); called once, under the lock."""
        raise NotImplementedError

    def close(self) -> None:
        """Finish the file and move it into place (once)."""
        with self.lock:
            if self.closed:
                return
            self.closed = True
            self.finish()
        self.stack.close()
