"""Fill factor over ROS (``autoscoop ros sim`` + ``autoscoop ros controller``) against ``autoscoop eval``.

Starts a private rosmaster (``--ros 2``: Cyclone DDS on the loopback interface in a DDS domain of its
own, with ``autoscoop ros2 sim`` + ``autoscoop ros2 controller``), the controller and the simulator (same pile, same seeds as evaluation),
runs N episodes in real time, then evaluates the same policy for the same seeds without ROS, with
the same sensor link (``sensor.delay_s`` and the noise keys) and the same mass source, and prints both with the topics' delay (stamp -> arrival, measured by the controller) and the
simulator's real-time factor. Acceptance: mean fill factors within 10 points.

    .venv/bin/python benchmarks/ros_vs_eval.py --episodes 20 --json out/ros_vs_eval.json
    .venv/bin/python benchmarks/ros_vs_eval.py --episodes 20 --delay-s 0.05 --noise   # a harsher link
    .venv/bin/python benchmarks/ros_vs_eval.py --ros 2 --episodes 20 --delay-s 0.05 --noise   # over ROS 2
"""

from __future__ import annotations

import argparse
import contextlib
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from autoscoop.agents.loading import load_policy
from autoscoop.commands.ros_cmd import LINK_OPTIONS
from autoscoop.core.config import ScoopConfig
from autoscoop.deploy.ros1.master import RosMaster
from autoscoop.deploy.ros2.graph import loopback_environment
from autoscoop.envs.records import load_record
from autoscoop.evaluation.evaluate import evaluate, summarize

NOISE = ["--joint-noise-rad", "0.002", "--speed-noise-mps", "0.002", "--range-noise-m", "0.003",
         "--torque-noise-nm", "0.2"]


def eval_config(delay_s: float, noise: bool, robot_config: Path | None = None) -> ScoopConfig:
    """The environment that predicts the ROS run: the same sensor link (``sensor.*``: the delay, and the
    noise of :data:`NOISE`) and the mass the controller uses (the torque estimate, as the controller's
    default ``payload.source: torque``, averaged over the control period with no extra load-cell noise;
    the counted mass for ``payload.source: topic``)."""
    from autoscoop.deploy.robot_config import load_robot_config  # noqa: PLC0415

    source = load_robot_config(robot_config).payload.source if robot_config else "torque"
    keys: dict[str, object] = {"sensor.delay_s": delay_s,
                               "env.mass_source": "torque" if source == "torque" else "truth",
                               "env.load_cell_noise_nm": 0.0}
    if noise:
        key_of = {flag: key for flag, key, _, _ in LINK_OPTIONS}  # ros sim's option -> the config key it sets
        keys.update({key_of[flag]: float(value) for flag, value in zip(NOISE[::2], NOISE[1::2], strict=True)})
    return ScoopConfig().with_overrides(keys)


def measure(policy: str, episodes: int, delay_s: float, noise: bool, seed: int = 0,
            robot_config: Path | None = None, ros_version: int = 1) -> dict:
    work = Path(tempfile.mkdtemp(prefix="autoscoop-ros-vs-eval-"))
    cli = [sys.executable, "-m", "autoscoop.cli"]
    command, records = ("ros", "--records") if ros_version == 1 else ("ros2", "--records")
    with RosMaster() if ros_version == 1 else contextlib.nullcontext() as master:
        env = master.env if ros_version == 1 else loopback_environment()
        robot = ["--robot", str(robot_config)] if robot_config else []
        controller = subprocess.Popen([*cli, command, "controller", "--policy", policy, records, str(work / "robot"),
                                       *robot],
                                      env=env, stdout=open(work / "controller.log", "w"),
                                      stderr=subprocess.STDOUT)
        started = time.monotonic()
        try:
            sim = subprocess.run([*cli, command, "sim", "--episodes", str(episodes), "--seed", str(seed), "--json",
                                  str(work / "ros.json"), "--delay-s", str(delay_s), *(NOISE if noise else []), *robot],
                                 env=env, capture_output=True, text=True, timeout=60 + 15 * episodes)
        finally:
            controller.terminate()
            controller.wait(timeout=15)
        if sim.returncode != 0:
            raise RuntimeError(f"{command} sim failed:\n{sim.stdout[-2000:]}\n{sim.stderr[-2000:]}")
        ros_wall = time.monotonic() - started
    ros = json.loads((work / "ros.json").read_text())
    config = eval_config(delay_s, noise, robot_config)
    results = evaluate(load_policy(policy, config), config, episodes, seed=seed, progress=False)
    ev = summarize(results, config, policy)
    last = sorted((work / "robot").glob("*.npz"))[-1]  # the controller's delay statistics cover the whole run
    delay_stats = load_record(last).meta.get("transport_delay_s", {})
    keys = ("fill_factor_mean", "fill_factor_std", "success_rate", "cycle_time_mean", "cycle_time_std",
            "mass_kg_mean", "spillage_mean")
    return {
        "ros_version": ros_version, "policy": policy, "robot_config": str(robot_config) if robot_config else None, "episodes": episodes,
        "seed": seed, "delay_s": delay_s, "noise": noise,
        "ros": {k: ros[k] for k in keys}, "eval": {k: ev[k] for k in keys},
        "fill_difference_points": 100 * (ros["fill_factor_mean"] - ev["fill_factor_mean"]),
        "per_episode_fill": {"ros": [e["fill_factor"] for e in ros["episodes_detail"]],
                             "eval": [r.fill_factor for r in results]},
        "transport_delay_s": delay_stats, "ros_timing": ros["ros"], "ros_wall_s": ros_wall, "work_dir": str(work),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--policy", default="heuristic")
    parser.add_argument("--episodes", type=int, default=20)
    parser.add_argument("--delay-s", type=float, default=0.0, help="extra delay of every sensor message, s")
    parser.add_argument("--noise", action="store_true", help="sensor noise: " + " ".join(NOISE))
    parser.add_argument("--robot", type=Path, metavar="FILE.yaml",
                        help="the robot file both nodes take, e.g. with payload: {source: topic} (the simulator's "
                             "true mass)")
    parser.add_argument("--ros", type=int, choices=(1, 2), default=1,
                        help="ROS 1 (a private rosmaster) or ROS 2 (Cyclone DDS on loopback); default 1")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args()
    r = measure(args.policy, args.episodes, args.delay_s, args.noise, robot_config=args.robot,
                ros_version=args.ros)
    for side in ("ros", "eval"):
        s = r[side]
        cycle = "n/a" if s["cycle_time_mean"] is None else f"{s['cycle_time_mean']:.2f} +- {s['cycle_time_std']:.2f} s"
        print(f"{side:>4}: fill {s['fill_factor_mean']:.3f} +- {s['fill_factor_std']:.3f}, "
              f"success {s['success_rate']:.2f}, cycle {cycle}")
    print(f"difference {r['fill_difference_points']:+.1f} points over {args.episodes} episodes "
          f"(ROS {args.ros}, sensor delay {args.delay_s} s, noise {args.noise})")
    for name, s in r["transport_delay_s"].items():
        print(f"  {name}: stamp -> controller median {s['median'] * 1e3:.1f} ms, p99 {s['p99'] * 1e3:.1f} ms, "
              f"max {s['max'] * 1e3:.1f} ms")
    timing = r["ros_timing"]
    print(f"  simulator real-time factor {timing['real_time_factor']:.2f}, late steps {timing['late_steps']}")
    if args.json:
        args.json.parent.mkdir(parents=True, exist_ok=True)
        args.json.write_text(json.dumps(r, indent=2) + "\n")
        print(f"wrote {args.json}")
    return 0 if abs(r["fill_difference_points"]) <= 10 else 1


if __name__ == "__main__":
    sys.exit(main())
