"""Record and replay: N episodes recorded over ROS 2 (MCAP, both nodes) and ROS 1 (``ros sim --bag``), replayed.

Runs ``autoscoop ros2 sim`` + ``autoscoop ros2 controller`` with ``--record`` (Cyclone DDS on loopback,
a DDS domain of its own), opens both MCAP files with ``rosbags`` and with ``mcap``'s ROS 2 decoder
(every message decoded), and replays each with the same policy and no link delay (``autoscoop replay``);
then the same over ROS 1 (a private rosmaster, ``ros sim --bag``), when ROS 1 is installed. Reported per
log: messages, episodes (scoops started), updates compared and the largest difference between the
commands sent and the replayed ones (the requirement: at most 1e-6).

    .venv/bin/python benchmarks/record_replay.py --episodes 3 --policy default --json benchmarks/results/deploy/record_replay.json
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.highlevel import AnyReader

from autoscoop.deploy.ros1 import ros_available
from autoscoop.deploy.ros1.master import RosMaster
from autoscoop.deploy.ros2.graph import loopback_environment

CLI = [sys.executable, "-m", "autoscoop.cli"]
TOLERANCE = 1e-6


def run_pair(command: str, policy: str, episodes: int, env: dict, controller_args: list[str],
             sim_args: list[str], work: Path) -> None:
    """The controller in the background, the simulator for ``episodes``; raises when the simulator fails."""
    with open(work / f"{command}_controller.log", "w") as log:
        controller = subprocess.Popen([*CLI, command, "controller", "--policy", policy, *controller_args], env=env,
                                      stdout=log, stderr=subprocess.STDOUT)
        try:
            sim = subprocess.run([*CLI, command, "sim", "--episodes", str(episodes), *sim_args], env=env,
                                 capture_output=True, text=True, timeout=120 + 15 * episodes)
        finally:
            controller.terminate()
            controller.wait(timeout=20)
    if sim.returncode != 0:
        raise RuntimeError(f"{command} sim failed:\n{sim.stdout[-2000:]}\n{sim.stderr[-2000:]}")


def opened(path: Path) -> dict:
    """Messages and topics as ``rosbags`` reads them, and (MCAP) as ``mcap``'s ROS 2 decoder decodes them."""
    with AnyReader([path]) as reader:
        decoded = sum(1 for c, _, raw in reader.messages() if reader.deserialize(raw, c.msgtype) is not None)
        scoops = [reader.deserialize(raw, c.msgtype).data for c, _, raw in reader.messages()
                  if c.topic.endswith("/scoop")]
    out = {"rosbags_messages": decoded, "topics": sorted({c.topic for c in reader.connections}),
           "scoops_started": sum(bool(s) for s in scoops)}
    if path.suffix == ".mcap":
        with open(path, "rb") as stream:
            out["mcap_ros2_messages"] = sum(1 for _ in make_reader(
                stream, decoder_factories=[DecoderFactory()]).iter_decoded_messages())
    return out


def replayed(path: Path, policy: str, work: Path) -> dict:
    out = work / f"replay_{path.stem}"
    run = subprocess.run([*CLI, "replay", str(path), "--policy", policy, "--out", str(out), "--json",
                          str(out / "summary.json")], capture_output=True, text=True, timeout=300)
    if run.returncode != 0:
        raise RuntimeError(f"replay of {path} failed:\n{run.stdout[-2000:]}\n{run.stderr[-2000:]}")
    return json.loads((out / "summary.json").read_text())


def measure(policy: str, episodes: int, work: Path) -> dict:
    results = {}
    env = loopback_environment()
    run_pair("ros2", policy, episodes, env, ["--bag", str(work / "ros2_controller.mcap")],
             ["--bag", str(work / "ros2_sim.mcap")], work)
    logs = [work / "ros2_controller.mcap", work / "ros2_sim.mcap"]
    if ros_available():
        with RosMaster() as master:
            run_pair("ros", policy, episodes, master.env, [], ["--bag", str(work / "ros1_sim.bag")], work)
        logs.append(work / "ros1_sim.bag")
    for path in logs:
        summary = replayed(path, policy, work)
        results[path.name] = {**opened(path), "updates": summary["updates"], "verdicts": summary["verdicts"],
                              "max_difference": summary["max_difference"]}
    return {"policy": policy, "episodes": episodes, "tolerance": TOLERANCE, "logs": results, "work_dir": str(work)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="default")
    parser.add_argument("--episodes", type=int, default=3)
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    r = measure(args.policy, args.episodes, Path(tempfile.mkdtemp(prefix="autoscoop-record-replay-")))
    ok = True
    for name, log in r["logs"].items():
        worst = max((v for v in log["max_difference"].values() if v is not None), default=None)
        ok &= worst is not None and worst <= TOLERANCE and log["scoops_started"] == args.episodes
        decoded = f", mcap ROS 2 decoder {log['mcap_ros2_messages']}" if "mcap_ros2_messages" in log else ""
        print(f"{name}: {log['rosbags_messages']} messages (rosbags{decoded}), {log['scoops_started']} episodes, "
              f"{log['updates']} updates, largest difference {worst}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(r, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
