"""Run ``python -m autoscoop.cli ARGS`` without paying for Python's start and the heavy imports each time.

The doc-command tests (tests/test_doc_commands_*.py) run about eighty command lines; a fresh interpreter spends
seconds importing torch, Stable-Baselines3, Gymnasium and MuJoCo before each does its work. This server imports
those libraries once (never ``autoscoop``'s own modules: the machine is chosen per process, when
``autoscoop.core.kinematics`` is first imported) and forks a child per command. The child is a process of its
own as ``subprocess.Popen(..., start_new_session=True)`` makes one: its own session, folder, environment and
output files; it runs the command line as ``python -m autoscoop.cli`` would and leaves the way an interpreter
does (``atexit``, threads joined, output flushed), so what the test sees is what a user's shell would see.

Protocol, one connection per command on a Unix socket: the client sends one JSON line ``{"argv", "cwd", "env",
"stdout", "stderr"}`` (the two output paths may be the same file; with ``"code"`` the child runs that source as
``python -c CODE ARGV...`` would, instead of the command line); the server answers ``{"pid": N}`` once the
child runs, then ``{"returncode": C}`` when it ends (C as ``Popen.returncode``: negative for a signal).
:class:`ForkedProcess` is the client, with the part of ``Popen``'s interface the test uses.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

PRELOAD = ("numpy", "torch", "torch._dynamo", "gymnasium", "mujoco", "stable_baselines3", "sb3_contrib", "pydantic", "yaml",
           "safetensors", "onnx", "tqdm", "filelock", "xml.etree.ElementTree", "matplotlib", "matplotlib.pyplot",
           "mpl_toolkits.mplot3d")
"""Imported once by the server (matplotlib with the tests' MPLBACKEND, Agg); none reads the command's
environment when imported, none starts a thread
(onnxruntime does: its exit handler would wait forever in a forked child)."""


def _preload() -> None:
    import importlib

    import autoscoop  # noqa: F401 - points MUJOCO_GL at an off-screen backend before mujoco loads
    for name in PRELOAD:
        with contextlib.suppress(ImportError):
            importlib.import_module(name)


def _child(request: dict) -> None:
    """In the forked child: become the command's process (session, folder, environment, output files)."""
    os.setsid()
    os.chdir(request["cwd"])
    os.environ.clear()
    os.environ.update(request["env"])
    out = os.open(request["stdout"], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    err = out if request["stderr"] == request["stdout"] else os.open(
        request["stderr"], os.O_WRONLY | os.O_CREAT | os.O_APPEND, 0o644)
    os.dup2(out, 1)
    os.dup2(err, 2)
    devnull = os.open(os.devnull, os.O_RDONLY)
    os.dup2(devnull, 0)
    sys.stdin = open(0, closefd=False)
    sys.stdout.reconfigure(write_through=True)
    sys.stderr.reconfigure(write_through=True)
    if request.get("code") is None:
        sys.argv = [str(Path(__file__).resolve().parents[1] / "autoscoop" / "cli.py"), *request["argv"]]
        sys.path[0] = request["cwd"]
    else:
        sys.argv = ["-c", *request["argv"]]
        sys.path[0] = ""


def _answer(connection: socket.socket, pid: int) -> None:
    """Tell the client the child's pid, then its exit status when it ends."""
    with connection:
        connection.sendall(json.dumps({"pid": pid}).encode() + b"\n")
        _, status = os.waitpid(pid, 0)
        with contextlib.suppress(OSError):
            connection.sendall(json.dumps({"returncode": os.waitstatus_to_exitcode(status)}).encode() + b"\n")


def _exit_with_client() -> None:
    """End the server when the test closes its stdin (raw reads: a thread inside ``sys.stdin.read`` holds the
    reader's lock, and a child forked meanwhile would wait for it forever when it closes ``sys.stdin``)."""
    while os.read(0, 4096):
        pass
    os._exit(0)


def serve(path: str) -> dict | None:
    """Serve until the client side closes stdin; returns a request in a forked child (None in the server)."""
    _preload()
    listener = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
    listener.bind(path)
    listener.listen(16)
    threading.Thread(target=_exit_with_client, daemon=True).start()
    print("ready", flush=True)
    while True:
        connection, _ = listener.accept()
        request = json.loads(connection.makefile("rb").readline())
        sys.stdout.flush()
        sys.stderr.flush()
        pid = os.fork()
        if pid == 0:
            listener.close()
            connection.close()
            _child(request)
            return request
        threading.Thread(target=_answer, args=(connection, pid), daemon=True).start()


class ForkServer:
    """The server process, started once; :meth:`spawn` runs one command line in a forked child of it."""

    def __init__(self, folder: Path, env: dict[str, str]) -> None:
        self.path = str(folder / "fork.sock")
        self.process = subprocess.Popen([sys.executable, __file__, self.path], stdin=subprocess.PIPE,
                                        stdout=subprocess.PIPE, env=env, text=True)
        assert self.process.stdout.readline().strip() == "ready", "the fork server did not start"

    def spawn(self, argv: list[str], cwd: Path, env: dict[str, str], stdout: Path, stderr: Path,
              code: str | None = None) -> ForkedProcess:
        return ForkedProcess(self.path, {"argv": list(argv), "cwd": str(cwd), "env": dict(env), "code": code,
                                         "stdout": str(stdout), "stderr": str(stderr)})

    def close(self) -> None:
        self.process.stdin.close()
        self.process.wait(timeout=30)


class ForkedProcess:
    """A command running in a child of the fork server, with ``Popen``'s ``pid``, ``returncode``, ``poll``,
    ``wait``, ``send_signal`` and ``kill``."""

    def __init__(self, server_path: str, request: dict) -> None:
        self.connection = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        self.connection.connect(server_path)
        self.connection.sendall(json.dumps(request).encode() + b"\n")
        self.received = b""
        self.pid = json.loads(self._line(None))["pid"]
        self.returncode: int | None = None

    def _line(self, timeout: float | None) -> bytes:
        """The server's next line; subprocess.TimeoutExpired when none is whole within ``timeout`` s."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while b"\n" not in self.received:
            left = None if deadline is None else max(0.0, deadline - time.monotonic())
            if not select.select([self.connection], [], [], left)[0]:
                raise subprocess.TimeoutExpired(["autoscoop"], timeout)
            chunk = self.connection.recv(4096)
            assert chunk, "the fork server closed the connection"
            self.received += chunk
        line, self.received = self.received.split(b"\n", 1)
        return line

    def wait(self, timeout: float | None = None) -> int:
        if self.returncode is None:
            self.returncode = json.loads(self._line(timeout))["returncode"]
            self.connection.close()
        return self.returncode

    def poll(self) -> int | None:
        if self.returncode is None:
            with contextlib.suppress(subprocess.TimeoutExpired):
                self.wait(timeout=0.001)
        return self.returncode

    def send_signal(self, signum: int) -> None:
        if self.returncode is None:
            with contextlib.suppress(ProcessLookupError):
                os.kill(self.pid, signum)

    def kill(self) -> None:
        self.send_signal(signal.SIGKILL)


if __name__ == "__main__" and (_request := serve(sys.argv[1])) is not None:
    # the forked child: the command line, as ``python -m autoscoop.cli`` (or ``python -c``) runs it (its
    # SystemExit ends the child; an exception escaping it prints its traceback and exits 1, as Python does)
    if _request.get("code") is None:
        import runpy

        runpy.run_module("autoscoop.cli", run_name="__main__", alter_sys=True)
    else:
        exec(compile(_request["code"], "<string>", "exec"), {"__name__": "__main__", "__builtins__": __builtins__})
