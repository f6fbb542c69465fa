"""Why a 50 ms link broke the first shipped policy over ROS: the wheels' speed alternates from one physics step to the next.

The controller's loop against the simulator in one process (no ROS), its readings passed through a
delay line in simulated time, as ``ros sim --delay-s`` does. It prints the odometry speed of each
physics step and, per control period, the speed the controller used beside the odometry at that
instant. With ``--odometry-window-steps 1`` (the instantaneous wheel speed, the odometry of the first
versions) the reading alternates between about 0.3 and 0.05 m/s on successive physics steps while the
wheels push the bucket along (their velocity servos, kv 30 against a 12 N*m bound at a 1/48 s step,
ring at the step). The environment samples at the end of each control period (12 steps: always the
same phase); a 50 ms link over ROS (2.4 steps) lands the controller on the other phase, so a policy
trained on the one phase reads a speed about 0.25 m/s too high and keeps scooping. The default
odometry (``sensor.odometry_window_steps = 2``: the mean over two steps, as an encoder counts the
wheels' angle) reads the same on either phase.

    .venv/bin/python experiments/odometry_phase.py --delay-s 0.05 --odometry-window-steps 1 --policy heuristic
"""

from __future__ import annotations

import argparse

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.sim_bridge import SimBridge, run_without_ros


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--delay-s", type=float, default=0.05)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--odometry-window-steps", type=int, default=ScoopConfig().sensor.odometry_window_steps)
    parser.add_argument("--policy", default="default")
    args = parser.parse_args()
    task = ScoopConfig().with_overrides({"sensor.odometry_window_steps": args.odometry_window_steps})
    core = ControllerCore(RobotNodeConfig(), load_policy(args.policy, task), task)
    bridge = SimBridge(task)
    odometry: list[float] = []
    used: list[tuple[float, float]] = []

    def watch(core: ControllerCore, bridge: SimBridge) -> None:
        used.append((round(core.speed_mps, 3), round(bridge.env.unwrapped.sim.odometry_speed_mps, 3)))

    bridge.env.unwrapped.sim.add_substep_observer(
        lambda: odometry.append(round(bridge.env.unwrapped.sim.odometry_speed_mps, 3)))
    result, _ = run_without_ros(bridge, core, args.seed, start_s=1000.0, delay_s=args.delay_s, on_command=watch)
    print(f"delay {args.delay_s} s, seed {args.seed}: fill {result.fill_factor:.3f}, success {result.success}, "
          f"{result.steps} control periods")
    print("odometry per physics step (m/s), the first 40:", odometry[:40])
    print("(speed the controller used, odometry then) per control period, the first 12:", used[:12])


if __name__ == "__main__":
    main()
