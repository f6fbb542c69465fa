"""``subprocess.run`` and ``subprocess.Popen`` for the tests' own Python command lines, without Python's start.

A test that runs ``[sys.executable, "-m", "autoscoop.cli", ...]`` or ``[sys.executable, "-c", CODE, ...]`` in a
fresh interpreter spends seconds importing torch, Stable-Baselines3, Gymnasium and MuJoCo before the command
does anything. :func:`run` and :class:`Popen` take the same arguments as ``subprocess``'s and run such a line in
a child of this test process's fork server (tests/fork_server.py, started on first use, closed at exit): a
process of its own (session, folder, environment, output) that ends as an interpreter does, so what the test
sees (exit code, output, files, signals) is what a fresh interpreter would give. Any other command line, or one
that feeds stdin, goes to ``subprocess`` unchanged.
"""

from __future__ import annotations

import atexit
import os
import shutil
import signal
import subprocess
import sys
import tempfile
from pathlib import Path

from fork_server import ForkServer

_SERVER: list[ForkServer] = []


def server() -> ForkServer:
    """This process's fork server, started on first use."""
    if not _SERVER:
        folder = Path(tempfile.mkdtemp(prefix="fork-", dir="/tmp"))  # a short path: a Unix socket's is 107 bytes
        _SERVER.append(ForkServer(folder, dict(os.environ, MPLBACKEND="Agg")))
        atexit.register(close, folder)
    return _SERVER[0]


def close(folder: Path | None = None) -> None:
    """Stop the fork server, if one started."""
    if _SERVER:
        _SERVER.pop().close()
    if folder is not None:
        shutil.rmtree(folder, ignore_errors=True)


def _forkable(args) -> tuple[str | None, list[str]] | None:
    """(code or None, the arguments after it) for a line the fork server can run; None for any other."""
    args = [os.fspath(a) for a in args] if not isinstance(args, (str, bytes)) else None
    if not args or args[0] != sys.executable or len(args) < 2:
        return None
    if args[1:3] == ["-m", "autoscoop.cli"]:
        return None, args[3:]
    if args[1] == "-c" and len(args) >= 3:
        return args[2], args[3:]
    return None


def _output_path(target, folder: Path, name: str) -> Path:
    if target == subprocess.PIPE:
        return folder / name
    if target in (None, subprocess.DEVNULL):
        return Path(os.devnull)
    if hasattr(target, "name") and isinstance(target.name, str):  # an open file
        target.flush()
        return Path(target.name)
    raise ValueError(f"forked.Popen: unsupported output target {target!r}")


class Popen:
    """``subprocess.Popen`` for a forkable line (see the module): ``pid``, ``returncode``, ``poll``, ``wait``,
    ``communicate``, ``send_signal``, ``terminate``, ``kill``; ``stdout``/``stderr`` as ``PIPE``, ``STDOUT``,
    ``DEVNULL``, ``None`` (discarded) or an open file."""

    def __new__(cls, args, **kwargs):
        if _forkable(args) is None or kwargs.get("stdin") not in (None, subprocess.DEVNULL):
            return subprocess.Popen(args, **kwargs)
        return super().__new__(cls)

    def __init__(self, args, *, stdout=None, stderr=None, stdin=None, env=None, cwd=None, text=False,
                 start_new_session=True) -> None:
        code, argv = _forkable(args)
        self.args, self.text = args, text
        self.folder = Path(tempfile.mkdtemp(prefix="forked-"))
        out = _output_path(stdout, self.folder, "stdout")
        err = out if stderr == subprocess.STDOUT else _output_path(stderr, self.folder, "stderr")
        self.pipes = {"stdout": out if stdout == subprocess.PIPE else None,
                      "stderr": err if stderr == subprocess.PIPE else None}
        for path in (out, err):
            if path != Path(os.devnull):
                path.touch()
        self.process = server().spawn(argv, Path(cwd or os.getcwd()), dict(os.environ if env is None else env),
                                       out, err, code=code)
        self.pid = self.process.pid

    @property
    def returncode(self) -> int | None:
        return self.process.returncode

    def poll(self) -> int | None:
        return self.process.poll()

    def wait(self, timeout: float | None = None) -> int:
        return self.process.wait(timeout)

    def communicate(self, input=None, timeout: float | None = None):
        assert input is None, "forked.Popen has no stdin"
        self.wait(timeout)
        return self._read("stdout"), self._read("stderr")

    def _read(self, name: str):
        path = self.pipes[name]
        if path is None:
            return None
        data = path.read_bytes()
        return data.decode(errors="replace") if self.text else data

    def send_signal(self, signum: int) -> None:
        self.process.send_signal(signum)

    def terminate(self) -> None:
        self.send_signal(signal.SIGTERM)

    def kill(self) -> None:
        self.process.kill()

    def __enter__(self) -> Popen:
        return self

    def __exit__(self, *exc) -> None:
        if self.returncode is None:
            self.wait()
        shutil.rmtree(self.folder, ignore_errors=True)


def run(args, *, capture_output: bool = False, timeout: float | None = None, check: bool = False, input=None,
        **kwargs) -> subprocess.CompletedProcess:
    """``subprocess.run`` for a forkable line (see the module); any other goes to ``subprocess.run``."""
    if _forkable(args) is None or input is not None or kwargs.get("stdin") not in (None, subprocess.DEVNULL):
        return subprocess.run(args, capture_output=capture_output, timeout=timeout, check=check, input=input, **kwargs)
    if capture_output:
        kwargs["stdout"] = kwargs["stderr"] = subprocess.PIPE
    with Popen(args, **kwargs) as process:
        try:
            stdout, stderr = process.communicate(timeout=timeout)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
            raise
    done = subprocess.CompletedProcess(args, process.returncode, stdout, stderr)
    if check:
        done.check_returncode()
    return done
