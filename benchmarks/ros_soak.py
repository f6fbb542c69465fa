"""Soak test: ``autoscoop ros controller`` and ``autoscoop ros sim`` on a real rosmaster, with faults injected.

Starts a private rosmaster, the controller (``--policy heuristic``, the default robot config), the
simulator (episodes until stopped, its sensor topics remapped into ``sim/``) and, in a process of
its own, a relay (this script with ``--relay``: :class:`ros_probe.FaultRelay` from ``tests/``)
that passes the simulator's sensor messages on to the controller's topics. While a scoop runs,
every 0.5-2 s of healthy driving the relay breaks one input for a while: silence, a frozen stamp,
stamps 10 s old or 100 s ahead, out of order, NaN, a burst with garbage, or estop; now and then the
relay is killed (SIGKILL) and started again (a restarted publisher). This process listens to the
controller's commands and its ``~status``.

A fault is *caught* when the status turns to fault (naming the broken input) or estop within
``input_timeout_s`` + one control period (0.75 s) of the input turning bad: the first faulty
message; for a silence (and a restart) the last message's stamp; for a frozen stamp, the frozen
reading's stamp. The times include ROS transport both ways. Reported: commands received, faults
injected and caught, the worst time to a stop, bad commands (non-finite or outside the limits: must
be 0), commands with a non-zero speed while the status said stopped (must be 0), and the
controller's memory (VmRSS) when the faults begin and at the end.

    .venv/bin/python benchmarks/ros_soak.py --minutes 10 --json benchmarks/results/deploy/ros_soak.json
"""

from __future__ import annotations

import argparse
import json
import math
import queue
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import AbstractContextManager, contextmanager
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.ros1 import import_rospy, subscribers
from autoscoop.deploy.ros1.controller_node import NODE_NAME
from autoscoop.deploy.ros1.master import RosMaster

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests"))  # the stand-in robot is a test harness
from ros_probe import RELAY_FAULTS, SENSOR_TOPICS, STAMPED_TOPICS, FaultRelay

SOURCE = "sim"
"""The namespace the simulator's sensor topics are remapped into."""
WEIGHTS = {"silence": 2, "frozen": 2, "old": 1, "future": 1, "out_of_order": 1, "nan": 2, "burst": 1, "estop": 1,
           "restart": 0.5}
"""How often each fault is drawn (``restart``: the relay killed and started again)."""
DURATION_S = {"silence": (0.8, 1.5), "frozen": (0.8, 1.5), "old": (0.1, 1.0), "future": (0.1, 1.0),
              "out_of_order": (0.1, 1.0), "nan": (0.05, 1.0), "burst": (0.05, 0.3), "estop": (0.3, 1.0)}
"""How long each fault lasts, s (silences and frozen stamps outlast the timeout, so they must stop the robot)."""
STOPPED = ("fault", "estop")
RACE_S = 0.05
"""A command this close to a status change may be of either side of it (two topics, two connections)."""


# ==================================================================== the relay's process
def relay_main(seed: int) -> int:
    """``--relay``: relay the simulator's sensors; read one fault per line (JSON) on stdin, answer each."""
    rospy = import_rospy()
    rospy.init_node("autoscoop_fault_relay", anonymous=False, disable_signals=True)
    return serve_relay(FaultRelay(SOURCE, seed=seed))


def serve_relay(relay: Any) -> int:
    """Once ``relay`` (a FaultRelay) is connected, inject the faults read on stdin (one JSON per line), answering each."""
    relay.wait_connected()
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        print(json.dumps(relay.inject(**json.loads(line))), flush=True)
    relay.close()
    return 0


class RelayProcess:
    """The relay in its own process (``script --relay``): :meth:`inject` sends it a fault and waits for its report."""

    def __init__(self, env: dict, seed: int, log: Any, script: str = __file__) -> None:
        self.process = subprocess.Popen([sys.executable, script, "--relay", "--seed", str(seed)], env=env,
                                        stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=log, text=True)
        self.lines: queue.Queue = queue.Queue()
        threading.Thread(target=self._read, daemon=True).start()
        self._reply(timeout_s=90.0)  # ready

    def _read(self) -> None:
        for line in self.process.stdout:
            self.lines.put(line)

    def _reply(self, timeout_s: float) -> dict:
        try:
            return json.loads(self.lines.get(timeout=timeout_s))
        except queue.Empty:
            raise RuntimeError(f"the relay did not answer within {timeout_s:g} s") from None

    def inject(self, kind: str, topic: str, duration_s: float) -> dict:
        self.process.stdin.write(json.dumps({"kind": kind, "topic": topic, "duration_s": duration_s}) + "\n")
        self.process.stdin.flush()
        return self._reply(timeout_s=duration_s + 30.0)

    def kill(self) -> None:
        """SIGKILL: a publisher that crashes."""
        self.process.kill()
        self.process.wait()


# ==================================================================== this process: the listener
class Listener:
    """The controller's commands and status, and the last stamp of each stamped sensor input, as they arrive."""

    def __init__(self, config: RobotNodeConfig) -> None:
        limits = config.limits
        self.bounds = {"cmd_vel": (-limits.max_speed_mps, limits.max_speed_mps),
                       "lift_command": (limits.lift_min_rad, limits.lift_max_rad),
                       "tilt_command": (limits.tilt_min_rad, limits.tilt_max_rad)}
        self.lock = threading.Lock()
        self.counts = dict.fromkeys(self.bounds, 0)
        self.bad: list[tuple[float, str, float]] = []
        self.speeds: list[tuple[float, float]] = []
        self.status: list[tuple[float, str]] = []
        self.reading_time: dict[str, float] = {}
        """per stamped input, when its newest reading was taken (its stamp, on the monotonic clock)"""
        self.scoops = 0
        self.subscribe(config)

    def subscribe(self, config: RobotNodeConfig) -> None:
        """Listen to the controller's commands and status, ``scoop`` and the stamped inputs (rospy)."""
        self.rospy = rospy = import_rospy()
        from std_msgs.msg import String  # noqa: PLC0415

        self.subscribers = list(subscribers(config.topics, {
            "cmd_vel": partial(self._command, "cmd_vel", lambda m: m.linear.x),
            "lift_command": partial(self._command, "lift_command", lambda m: m.data),
            "tilt_command": partial(self._command, "tilt_command", lambda m: m.data),
            "scoop": self._scoop, **{name: partial(self._reading, name) for name in STAMPED_TOPICS}},
            queue_size=None).values())
        self.subscribers.append(rospy.Subscriber(f"/{NODE_NAME}/status", String, self._status, queue_size=None))

    def close(self) -> None:
        """Stop listening."""
        for subscriber in self.subscribers:
            subscriber.unregister()

    def _command(self, topic: str, value: Any, msg: Any) -> None:
        now, v = time.monotonic(), float(value(msg))
        low, high = self.bounds[topic]
        with self.lock:
            self.counts[topic] += 1
            if not (math.isfinite(v) and low - 1e-9 <= v <= high + 1e-9):
                self.bad.append((now, topic, v))
            if topic == "cmd_vel":
                self.speeds.append((now, v))

    def _status(self, msg: Any) -> None:
        with self.lock:
            self.status.append((time.monotonic(), msg.data))

    def _scoop(self, msg: Any) -> None:
        self.scoops += int(bool(msg.data))

    def _reading(self, topic: str, msg: Any) -> None:
        taken = time.monotonic() - (self.rospy.get_time() - msg.header.stamp.to_sec())
        self.reading_time[topic] = taken

    def mode(self) -> tuple[str, float]:
        """The controller's mode now, and since when (monotonic s)."""
        with self.lock:
            if not self.status:
                return "", math.inf
            t, text = self.status[-1]
        return text.split(":")[0], t

    def wait_running(self, for_s: float, timeout_s: float) -> bool:
        """Wait until a scoop has run healthy for ``for_s``; whether it did within ``timeout_s``."""
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            mode, since = self.mode()
            if mode == "running" and time.monotonic() - since >= for_s:
                return True
            time.sleep(0.01)
        return False


def rss_kb(pid: int) -> int:
    """A process's resident memory (VmRSS), kB."""
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1])
    raise RuntimeError(f"no VmRSS for process {pid}")


# ==================================================================== the soak
def draw_fault(rng: np.random.Generator) -> tuple[str, str, float]:
    kinds = list(WEIGHTS)
    p = np.array([WEIGHTS[k] for k in kinds], dtype=float)
    kind = str(rng.choice(kinds, p=p / p.sum()))
    if kind == "restart":
        return kind, kind, 0.0
    if kind == "estop":
        return kind, kind, float(rng.uniform(*DURATION_S[kind]))
    topics = STAMPED_TOPICS if kind in ("frozen", "old", "future", "out_of_order") else SENSOR_TOPICS
    return kind, str(rng.choice(topics)), float(rng.uniform(*DURATION_S[kind]))


def _restart(relay: RelayProcess, listener: Listener, env: dict, seed: int, log: Any,
             script: str) -> tuple[RelayProcess, dict]:
    started = time.monotonic()
    relay.kill()
    time.sleep(0.05)  # what was in flight has arrived
    t0 = min(listener.reading_time.values())  # the first input to go stale: the oldest last reading
    fresh = RelayProcess(env, seed, log, script)
    return fresh, {"kind": "restart", "topic": "restart", "t0": t0, "started": started, "ended": time.monotonic(),
                   "bad_messages": 0}


def _stop_for(fault: dict, status: list[tuple[float, str]]) -> tuple[float | None, float | None]:
    """When the robot was stopped after this fault began, and when the status named it (monotonic s; None: never).

    Stopped: the status named the fault (fault with its input, or estop), or the scoop had ended
    (``idle``: zero speed too) before it did."""
    names = SENSOR_TOPICS if fault["kind"] == "restart" else (fault["topic"],)
    stopped = None
    for t, text in status:
        if t < fault["started"] or t > fault["ended"] + 5.0:
            continue
        mode, _, reason = text.partition(": ")
        if (mode == "estop" and fault["kind"] == "estop") or (
                mode == "fault" and any(f"{name}:" in reason for name in names)):
            return (t if stopped is None else stopped), t
        if mode == "idle" and stopped is None:
            stopped = t
    return stopped, None


def moving_while_stopped(speeds: list[tuple[float, float]], status: list[tuple[float, str]]) -> int:
    """Non-zero speeds received while the status said stopped, away from any status change."""
    times = [t for t, _ in status]
    count = 0
    for t, v in speeds:
        if v == 0.0:
            continue
        i = int(np.searchsorted(times, t - RACE_S, side="right"))
        near = i < len(times) and times[i] <= t + RACE_S
        if i > 0 and not near and status[i - 1][1].split(":")[0] in STOPPED:
            count += 1
    return count


def stops(status: list[tuple[float, str]], faults: list[dict], bound_s: float) -> tuple[int, list[str]]:
    """How many times the status turned to stopped, and the statuses of those no injected fault explains."""
    windows = [(f["started"], f["ended"] + bound_s) for f in faults]
    count, unexplained = 0, []
    before = ""
    for t, text in status:
        mode = text.split(":")[0]
        if mode in STOPPED and before not in STOPPED:
            count += 1
            if not any(start <= t <= end for start, end in windows):
                unexplained.append(text)
        before = mode
    return count, unexplained


def evaluate(faults: list[dict], status: list[tuple[float, str]], bound_s: float) -> dict:
    """Per fault: when it stopped the robot and when the status named it; per kind and overall: how many
    were caught (named, and stopped within ``bound_s``), the worst times."""
    by_kind: dict[str, dict] = {}
    for fault in faults:
        stopped, named = (None, None) if fault["t0"] is None else _stop_for(fault, status)
        fault["time_to_stop_s"] = None if stopped is None else stopped - fault["t0"]
        fault["time_to_report_s"] = None if named is None else named - fault["t0"]
        fault["caught"] = named is not None and fault["time_to_stop_s"] <= bound_s
        kind = by_kind.setdefault(fault["kind"], {"injected": 0, "caught": 0})
        kind["injected"] += 1
        kind["caught"] += int(fault["caught"])
    for name, kind in by_kind.items():
        for key in ("time_to_stop_s", "time_to_report_s"):
            times = [f[key] for f in faults if f["kind"] == name and f[key] is not None]
            kind[f"worst_{key}"] = max(times, default=None)
            kind[f"median_{key}"] = float(np.median(times)) if times else None
    worst = {key: max((f[key] for f in faults if f[key] is not None), default=None)
             for key in ("time_to_stop_s", "time_to_report_s")}
    return {"injected": len(faults), "caught": sum(f["caught"] for f in faults),
            "worst_time_to_stop_s": worst["time_to_stop_s"], "worst_time_to_report_s": worst["time_to_report_s"],
            "stopped_by_the_scoop_ending": sum(f["time_to_stop_s"] is not None and f["time_to_report_s"] is not None
                                               and f["time_to_stop_s"] < f["time_to_report_s"] for f in faults),
            "bound_s": bound_s, "by_kind": dict(sorted(by_kind.items()))}


@dataclass(frozen=True)
class Middleware:
    """What the soak needs of a middleware: its ``autoscoop`` command, a graph to run in, its listener and relay."""

    command: str
    """``ros`` or ``ros2``"""
    graph: Callable[[], AbstractContextManager[dict]]
    """a context that sets this process up for the middleware and gives the processes' environment"""
    listener: Callable[[RobotNodeConfig], Listener]
    relay_script: str
    """the script whose ``--relay`` runs the relay"""


@contextmanager
def ros1_graph() -> Iterator[dict]:
    """A private rosmaster, this process a node of it; the environment of its processes."""
    with RosMaster() as master:
        master.use_here()
        import_rospy().init_node("autoscoop_soak", anonymous=True, disable_signals=True)
        yield master.env


ROS1 = Middleware("ros", ros1_graph, Listener, __file__)


def soak(minutes: float, seed: int = 0, policy: str = "heuristic", work: Path | None = None,
         middleware: Middleware = ROS1) -> dict:
    """Run the soak for ``minutes`` over ``middleware``; the figures (times in s, memory in kB)."""
    config = RobotNodeConfig()
    period, timeout = config.control.control_period_s, config.control.input_timeout_s
    work = work or Path(tempfile.mkdtemp(prefix=f"autoscoop-{middleware.command}-soak-"))
    work.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(seed)
    cli = [sys.executable, "-m", "autoscoop.cli", middleware.command]
    remap = [f"{name}:={SOURCE}/{getattr(config.topics, name)}" for name in SENSOR_TOPICS]
    logs = {name: open(work / f"{name}.log", "w") for name in ("controller", "sim", "relay")}
    faults: list[dict] = []
    rss: list[tuple[float, int]] = []
    with middleware.graph() as env:
        controller = subprocess.Popen([*cli, "controller", "--policy", policy], env=env,
                                      stdout=logs["controller"], stderr=subprocess.STDOUT)
        sim = subprocess.Popen([*cli, "sim", "--episodes", "0", *remap], env=env, stdout=logs["sim"],
                               stderr=subprocess.STDOUT)
        relay = None
        listener = middleware.listener(config)
        try:
            relay = RelayProcess(env, seed, logs["relay"], middleware.relay_script)
            if not listener.wait_running(for_s=2.0, timeout_s=120.0):
                raise RuntimeError(f"no scoop ran; see the logs in {work}")
            started = time.monotonic()
            deadline = started + 60.0 * minutes
            rss.append((0.0, rss_kb(controller.pid)))
            next_sample = started + 10.0
            restarts = 0
            while time.monotonic() < deadline:
                if not listener.wait_running(for_s=float(rng.uniform(0.5, 2.0)), timeout_s=30.0):
                    continue
                kind, topic, duration = draw_fault(rng)
                if kind == "restart":
                    restarts += 1
                    relay, record = _restart(relay, listener, env, seed + restarts, logs["relay"],
                                             middleware.relay_script)
                else:
                    record = relay.inject(kind, topic, duration)
                faults.append(record)
                if time.monotonic() >= next_sample:
                    rss.append((time.monotonic() - started, rss_kb(controller.pid)))
                    next_sample += 10.0
            time.sleep(2 * (timeout + period))  # the last fault's stop arrives
            rss.append((time.monotonic() - started, rss_kb(controller.pid)))
            elapsed = time.monotonic() - started
        finally:
            if relay is not None:
                relay.kill()
            for process in (sim, controller):
                process.terminate()
                try:
                    process.wait(timeout=15)
                except subprocess.TimeoutExpired:
                    process.kill()
            for log in logs.values():
                log.close()
            listener.close()
    with listener.lock:
        status, speeds = list(listener.status), list(listener.speeds)
        counts, bad = dict(listener.counts), list(listener.bad)
    result = evaluate(faults, status, timeout + period)
    stopped, unexplained = stops(status, faults, timeout + period)
    start_kb, end_kb = rss[0][1], rss[-1][1]
    return {
        "middleware": middleware.command, "minutes": elapsed / 60.0, "policy": policy, "seed": seed,
        "scoops": listener.scoops,
        "commands": {**counts, "total": sum(counts.values())}, "bad_commands": len(bad), "bad": bad[:20],
        "moving_while_stopped": moving_while_stopped(speeds, status),
        "faults": result, "stops": stopped, "stops_not_injected": len(unexplained),
        "stops_not_injected_reasons": unexplained[:20],
        "controller_rss_kb": {"start": start_kb, "end": end_kb, "growth_pct": 100.0 * (end_kb - start_kb) / start_kb,
                              "samples": rss},
        "control_period_s": period, "input_timeout_s": timeout, "faults_known": RELAY_FAULTS,
        "fault_log": faults, "work_dir": str(work),
        "status_log": [(round(t - started, 4), text[:160]) for t, text in status],
        "note": "time to stop = the controller's ~status turning to fault (naming the input) or estop, as received "
                "here (or the scoop ending first: idle, zero speed too), minus when the input turned bad (first faulty message; for silence, frozen stamps and restarts "
                "the stamp of the last good reading); stops: every time the status turned to fault or estop, "
                "stops_not_injected: those outside every injected fault (e.g. the simulator resetting a scene)",
    }


def _ms(seconds: float | None) -> str:
    return "n/a" if seconds is None else f"{seconds * 1e3:.1f} ms"


def print_result(r: dict) -> None:
    f = r["faults"]
    print(f"{r['minutes']:.1f} min, {r['scoops']} scoops, {r['commands']['total']} commands "
          f"({r['commands']['cmd_vel']} cmd_vel); bad commands {r['bad_commands']}, moving while stopped "
          f"{r['moving_while_stopped']}")
    worst = f["worst_time_to_stop_s"]
    print(f"faults: {f['caught']}/{f['injected']} caught within {f['bound_s']:.3f} s; worst time to stop "
          f"{_ms(worst)}, to the status naming the fault {_ms(f['worst_time_to_report_s'])} "
          f"({f['stopped_by_the_scoop_ending']} stopped first by their scoop ending); {r['stops']} stops, "
          f"{r['stops_not_injected']} not injected")
    for kind, k in f["by_kind"].items():
        print(f"  {kind:<13} {k['caught']:>3}/{k['injected']:<3} worst to stop {_ms(k['worst_time_to_stop_s'])}, "
              f"to report {_ms(k['worst_time_to_report_s'])}")
    m = r["controller_rss_kb"]
    print(f"controller memory {m['start'] / 1024:.1f} MiB -> {m['end'] / 1024:.1f} MiB ({m['growth_pct']:+.2f} %)")


def main(middleware: Middleware = ROS1, run_relay=relay_main, description: str = __doc__) -> int:
    """The command line: the soak over ``middleware`` or, with ``--relay``, ``run_relay(seed)`` (this file's, or
    another middleware's); exit 0 when the soak met every bound."""
    parser = argparse.ArgumentParser(description=description, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--minutes", type=float, default=10.0, help="how long to inject faults (default 10)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--policy", default="heuristic", help="the controller's --policy (default heuristic)")
    parser.add_argument("--json", type=Path, help="write the results here")
    parser.add_argument("--work-dir", type=Path, help="the processes' logs go here (default: a temporary folder)")
    parser.add_argument("--relay", action="store_true", help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.relay:
        return run_relay(args.seed)
    if not (args.minutes > 0 and math.isfinite(args.minutes)):
        parser.error(f"--minutes must be a positive number, got {args.minutes}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
    result = soak(args.minutes, args.seed, args.policy, args.work_dir, middleware)
    print_result(result)
    if args.json:
        args.json.write_text(json.dumps(result, indent=2) + "\n")
        print(f"wrote {args.json}")
    f = result["faults"]
    ok = (result["bad_commands"] == 0 and result["moving_while_stopped"] == 0 and f["caught"] == f["injected"]
          and result["controller_rss_kb"]["growth_pct"] < 5.0)
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
