"""A private ``rosmaster`` on a free loopback port, for tests, benchmarks and ``ros sim --with-master``.

Everything stays on 127.0.0.1: the master's URI, ``ROS_HOSTNAME`` and ``ROS_IP`` point there, and
``ROS_HOME`` is a temporary folder, so runs neither see nor disturb another ROS graph.
"""

from __future__ import annotations

import os
import shutil
import socket
import subprocess
import tempfile
import time
import xmlrpc.client
from pathlib import Path

LOOPBACK = "127.0.0.1"


def free_port() -> int:
    """A TCP port on the loopback interface that nobody listens on now."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind((LOOPBACK, 0))
        return int(sock.getsockname()[1])


class RosMaster:
    """Start ``rosmaster --core`` on a free port; stop it on :meth:`stop` (or leaving a ``with`` block).

    Attributes:
        uri: ``http://127.0.0.1:PORT/``.
        env: the environment for ROS processes that use this master (a copy of ``os.environ``).
    """

    def __init__(self, port: int | None = None, startup_timeout_s: float = 15.0) -> None:
        executable = shutil.which("rosmaster")
        if executable is None:
            from autoscoop.deploy.ros1 import INSTALL_HINT  # noqa: PLC0415

            raise RuntimeError(f"rosmaster not found: {INSTALL_HINT}")
        self.port = port or free_port()
        self.uri = f"http://{LOOPBACK}:{self.port}/"
        self._home = tempfile.mkdtemp(prefix="autoscoop-ros-")
        self.env = {**os.environ, "ROS_MASTER_URI": self.uri, "ROS_HOSTNAME": LOOPBACK, "ROS_IP": LOOPBACK,
                    "ROS_HOME": self._home, "ROS_LOG_DIR": str(Path(self._home) / "log"), "PYTHONUNBUFFERED": "1"}
        self._log = open(Path(self._home) / "rosmaster.log", "w")
        self.process = subprocess.Popen([executable, "--core", "-p", str(self.port), "-w", "3"], env=self.env,
                                        stdout=self._log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL)
        deadline = time.monotonic() + startup_timeout_s
        while True:
            try:
                code, _, _ = xmlrpc.client.ServerProxy(self.uri).getPid("/autoscoop_probe")
                if code == 1:
                    break
            except OSError:
                pass
            if self.process.poll() is not None or time.monotonic() > deadline:
                self.stop()
                raise RuntimeError(f"rosmaster did not start on port {self.port}; see {self._home}/rosmaster.log")
            time.sleep(0.05)

    def use_here(self) -> None:
        """Point this process's ROS environment variables at this master (before ``rospy.init_node``)."""
        for key in ("ROS_MASTER_URI", "ROS_HOSTNAME", "ROS_IP", "ROS_HOME", "ROS_LOG_DIR"):
            os.environ[key] = self.env[key]

    def stop(self) -> None:
        """Stop the master and remove its temporary folder."""
        if self.process.poll() is None:
            self.process.terminate()
            try:
                self.process.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        self._log.close()
        shutil.rmtree(self._home, ignore_errors=True)

    def __enter__(self) -> RosMaster:
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop()
