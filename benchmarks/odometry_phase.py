"""Why a 50 ms link breaks the shipped policy over ROS: the wheels' speed alternates from one physics step to the next.

The controller's loop against the simulator in one process (no ROS), its readings passed through a
delay line in simulated time, as ``ros sim --delay-s`` does. It prints the odometry speed of each
physics step and, per control period, the speed the controller used beside the odometry at that
instant. The odometry alternates between about 0.3 and 0.05 m/s on successive physics steps from the
first steps on (the wheels' velocity servos, kv 30 against a 12 N*m bound at a 1/48 s step,
ring at the step). The environment samples at the end of each control period (12 steps: always the
same phase); a 50 ms link over ROS (2.4 steps) lands the controller on the other phase, so the policy
reads a speed about 0.25 m/s too high and keeps scooping. ``autoscoop eval --set sensor.delay_s=X``
with an odd number of steps (X = 1/48 s) shows the same.

    .venv/bin/python benchmarks/odometry_phase.py --delay-s 0.05
"""

from __future__ import annotations

import argparse

from autoscoop.agents.loading import load_policy
from autoscoop.core.config import ScoopConfig
from autoscoop.core.payload import pitch_from_quaternion
from autoscoop.deploy.controller import ControllerCore
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.sim_bridge import DelayLine, SensorReadings, SimBridge

HOLD_STEPS = 30
"""Sensor periods of the still scene before the scoop starts (the ROS simulator's hold)."""


def feed(core: ControllerCore, r: SensorReadings, now: float) -> None:
    """Hand one set of readings to the controller at ``now`` (its clock, s)."""
    core.joint_states(r.joint_names, r.joint_positions, now)
    core.odometry(r.speed_mps, now, pitch_from_quaternion(*r.chassis_quat_wxyz))
    core.pile_range(r.range_m, now, 0.0, 4.0)
    core.bucket_torque(r.tilt_torque_nm, now)
    core.lift_torque(r.lift_torque_nm, now)
    core.payload_mass(r.payload_kg, now)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--delay-s", type=float, default=0.05)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    task = ScoopConfig()
    core = ControllerCore(RobotNodeConfig(), load_policy("default", task), task)
    bridge = SimBridge(task)
    line = DelayLine(args.delay_s)
    now, period = 1000.0, bridge.sensor_period_s
    readings = bridge.reset(args.seed)
    for _ in range(HOLD_STEPS):
        line.push(now, readings)
        now += period
        for due in line.pop_due(now):
            feed(core, due, now)
    core.scoop(True, now)
    odometry, used = [], []
    while not bridge.done:
        command = core.update(now)
        if command is not None:
            bridge.command_speed(command.speed_mps)
            if command.lift_rad is not None:
                bridge.command_joint("lift", command.lift_rad)
                bridge.command_joint("tilt", command.tilt_rad)
            used.append((round(core.speed_mps, 3), round(bridge.env.unwrapped.sim.odometry_speed_mps, 3)))
        readings = bridge.step()
        odometry.append(round(readings.speed_mps, 3))
        now += period
        line.push(now, readings)
        for due in line.pop_due(now):
            feed(core, due, now)
    result = bridge.result()
    print(f"delay {args.delay_s} s, seed {args.seed}: fill {result.fill_factor:.3f}, success {result.success}, "
          f"{result.steps} control periods")
    print("odometry per physics step (m/s), the first 40:", odometry[:40])
    print("(speed the controller used, odometry then) per control period, the first 12:", used[:12])


if __name__ == "__main__":
    main()
