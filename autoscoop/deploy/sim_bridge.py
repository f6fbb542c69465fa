"""The simulator behind the robot's topics, free of ROS: commands in, sensor readings out, per physics step.

:class:`SimBridge` runs the scoop environment (:class:`autoscoop.envs.scoop.ScoopEnv`) with its
control period shortened to the sensor period (one or a few physics steps, about 48 Hz). A received
speed command is the wheels' target at once; a received joint position command starts the servo's
setpoint moving toward it as the environment moves it: at ``(command - setpoint) / control period``,
bounded by the actuator's speed, until it gets there or the next command arrives. With one command
per control period this is exactly the environment's servo, so only the topics' timing differs.
Each step yields the readings the robot's sensors give (joint positions, wheel-odometry speed, range
from the tip to the pile, joint torques), with Gaussian noise, and the episode ends as in evaluation
(success or the time limit), with the same metrics.
"""

from __future__ import annotations

import heapq
import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from autoscoop.core.config import ScoopConfig, SensorConfig
from autoscoop.core.payload import pitch_from_quaternion
from autoscoop.core.sensing import RawReadings, SensorNoise, add_noise
from autoscoop.core.state import CommandLimits, advance_targets, servo_rate
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.envs.scoop import make_scoop_env

MIN_SENSOR_PERIOD_S = 0.02
"""Sensors are published at most this often: every physics step, or every few when steps are shorter."""


@dataclass(frozen=True)
class SensorReadings:
    """What the robot's sensors report after one step (noise included).

    Attributes:
        time_s: simulated time since the episode's start, s.
        joint_names: names in ``joint_states`` (lift, tilt).
        joint_positions: lift and tilt readings: rad, or raw where the robot config calibrates a potentiometer.
        speed_mps: forward speed from wheel odometry, m/s.
        range_m: distance from the bucket tip to the pile, m.
        tilt_torque_nm: torque at the tilt (bucket) joint, N*m.
        lift_torque_nm: torque at the lift joint, N*m.
        payload_kg: mass of the particles inside the bucket, kg (what a perfect load cell would report).
        chassis_xyz_m: chassis centre in the world (pile) frame, m (for the odometry pose).
        chassis_quat_wxyz: chassis orientation, unit quaternion (w, x, y, z): the IMU, its pitch with the
            joints' noise (``sensor.joint_noise_rad``) as the environment reads it.
    """

    time_s: float
    joint_names: tuple[str, str]
    joint_positions: tuple[float, float]
    speed_mps: float
    range_m: float
    tilt_torque_nm: float
    lift_torque_nm: float
    payload_kg: float
    chassis_xyz_m: tuple[float, float, float]
    chassis_quat_wxyz: tuple[float, float, float, float]


class SimBridge:
    """The scoop simulator driven by position and speed commands, read through the robot's sensors.

    Args:
        config: the scene (pile, robot limits, episode length) and the sensor link (``sensor.*``: its
            noise here, its delay in the ROS node, :class:`~autoscoop.deploy.ros1.sim_node.SimNode`).
        noise: sensor noise; default: the config's ``sensor`` section (the environment's link).
        robot: the robot's node config: joint names and potentiometer calibration of the readings
            (default: joints ``lift``/``tilt`` in radians).
        seed: seed of the noise.
    """

    def __init__(self, config: ScoopConfig | None = None, noise: SensorNoise | None = None,
                 robot: RobotNodeConfig | None = None, seed: int = 0) -> None:
        config = config or ScoopConfig()
        self.task_config = config
        timestep = config.env.timestep_s
        self.sensor_period_s = timestep * max(1, math.ceil(MIN_SENSOR_PERIOD_S / timestep - 1e-9))
        # the bridge applies the link itself, to the messages: the environment inside reads exact values
        # (its odometry, a property of the sensor itself, is the task's)
        self.config = config.with_overrides({"env.control_period_s": self.sensor_period_s}).replace(
            sensor=SensorConfig(odometry_window_steps=config.sensor.odometry_window_steps))
        self.env = make_scoop_env(self.config)
        self.noise = noise or SensorNoise.from_config(config.sensor)
        self.robot = robot or RobotNodeConfig()
        self.rng = np.random.default_rng(seed)
        # the IMU's pitch noise (the joints' std, as in the environment) from a stream of its own, so
        # that the other readings draw the same noise as before the IMU was noisy
        self._imu_rng = np.random.default_rng([seed, 1])
        self.limits = CommandLimits.for_robot(config.robot)
        self._span = self.limits.high - self.limits.low
        self.servo_period_s = config.env.control_period_s
        self._servo_speed = np.array([config.robot.lift_speed_radps, config.robot.tilt_speed_radps])
        self._targets = np.zeros(3)
        self._goal = np.zeros(3)
        self._rate = np.zeros(2)
        self._info: dict[str, Any] = {}
        self.seed = 0
        self.steps = 0
        self.done = True

    @property
    def start_command(self) -> np.ndarray:
        """(speed, lift, tilt) the robot holds at an episode's start: still, arm in the start pose."""
        robot = self.config.robot
        return np.array([0.0, robot.start_lift_rad, robot.start_tilt_rad])

    def reset(self, seed: int) -> SensorReadings:
        """A new episode (the scene reset, a fresh settled pile) from ``seed``; its first readings."""
        _, self._info = self.env.reset(seed=seed)
        self._targets = self.start_command
        self._goal, self._rate = self.start_command, np.zeros(2)
        self.seed, self.steps, self.done = seed, 0, False
        return self.readings()

    def command_speed(self, speed_mps: float) -> None:
        """A ``cmd_vel`` arrived: the wheels' speed target, m/s (clipped to the limit; non-finite ignored)."""
        if math.isfinite(speed_mps):
            self._goal[0] = float(np.clip(speed_mps, self.limits.low[0], self.limits.high[0]))

    def command_joint(self, joint: str, position_rad: float) -> None:
        """A joint position command arrived (``lift`` or ``tilt``, rad): start the setpoint's ramp toward it."""
        index = {"lift": 1, "tilt": 2}[joint]
        if not math.isfinite(position_rad):
            return
        goal = float(np.clip(position_rad, self.limits.low[index], self.limits.high[index]))
        self._goal[index] = goal
        self._rate[index - 1] = float(servo_rate(goal, self._setpoints()[index - 1], self.servo_period_s,
                                                 self._servo_speed[index - 1]))

    def step(self, command: np.ndarray | None = None) -> SensorReadings:
        """Advance one sensor period; the new readings. After the episode ends, steps do nothing.

        Args:
            command: (speed m/s, lift rad, tilt rad) received just now, or ``None`` when nothing arrived.
        """
        if command is not None:
            self.command_speed(command[0])
            self.command_joint("lift", command[1])
            self.command_joint("tilt", command[2])
        if self.done:
            return self.readings()
        setpoints = self._setpoints()
        desired = self._goal.copy()
        for k in range(2):  # where each setpoint should be after this step: one step further along its ramp
            remaining = self._goal[k + 1] - setpoints[k]
            move = self._rate[k] * self.sensor_period_s
            if abs(remaining) > abs(move) and np.sign(remaining) == np.sign(move):
                desired[k + 1] = setpoints[k] + move
        action = np.clip((desired - self._targets) / self._span, -1.0, 1.0)
        self._targets = advance_targets(self._targets, action, self.limits)
        _, _, terminated, truncated, self._info = self.env.step(action)
        self.steps += 1
        self.done = bool(terminated or truncated)
        return self.readings()

    def _setpoints(self) -> np.ndarray:
        sim = self.env.unwrapped.sim
        return np.array([sim.lift_setpoint_rad, sim.tilt_setpoint_rad])

    def readings(self) -> SensorReadings:
        """The sensors' view of the scene now, with noise."""
        sim, info = self.env.unwrapped.sim, self._info
        true = RawReadings(lift_rad=sim.lift_rad, tilt_rad=sim.tilt_rad, speed_mps=sim.odometry_speed_mps,
                           range_m=float(info.get("tip_to_pile_m", math.nan)), tilt_torque_nm=sim.tilt_torque_nm,
                           lift_torque_nm=sim.lift_torque_nm)
        sensed = add_noise(true, self.noise, self.rng)  # one sample per sensor period
        positions = []
        for joint, angle in (("lift", sensed.lift_rad), ("tilt", sensed.tilt_rad)):
            pot = self.robot.potentiometer(joint)
            positions.append(pot.to_raw(angle) if pot is not None else angle)
        speed, distance = sensed.speed_mps, sensed.range_m
        torque, lift_torque = sensed.tilt_torque_nm, sensed.lift_torque_nm
        position, rotation = sim.chassis_pose
        quat = np.empty(4)
        import mujoco  # noqa: PLC0415 - already loaded by the simulator

        mujoco.mju_mat2Quat(quat, rotation.reshape(-1))
        if self.noise.joint_rad:  # the IMU's pitch, read as the environment reads it (sensor.level_with_imu)
            half = 0.5 * float(self._imu_rng.normal(0.0, self.noise.joint_rad))
            noisy = np.empty(4)
            mujoco.mju_mulQuat(noisy, quat, np.array([math.cos(half), 0.0, math.sin(half), 0.0]))
            quat = noisy
        return SensorReadings(
            time_s=sim.elapsed_s, joint_names=(self.robot.sensors.lift_joint, self.robot.sensors.tilt_joint),
            joint_positions=(float(positions[0]), float(positions[1])), speed_mps=float(speed), range_m=distance,
            tilt_torque_nm=float(torque), lift_torque_nm=float(lift_torque), payload_kg=float(info.get("mass_in_bucket_kg", 0.0)),
            chassis_xyz_m=tuple(float(v) for v in position),
            chassis_quat_wxyz=tuple(float(v) for v in quat))

    def result(self) -> EpisodeOutcome:
        """The episode's metrics, as ``autoscoop eval`` reports them (``steps`` in control periods; no return)."""
        info = self._info
        period = self.task_config.env.control_period_s
        steps = int(round(float(info.get("elapsed_s", 0.0)) / period))
        return EpisodeOutcome.from_info(info, seed=self.seed, steps=steps, episode_return=math.nan)

    def close(self) -> None:
        """Free the simulator."""
        self.env.close()


class DelayLine:
    """Items that come out ``delay_s`` after they went in, in order: a sensor's transport delay."""

    def __init__(self, delay_s: float) -> None:
        if not (math.isfinite(delay_s) and delay_s >= 0.0):
            raise ValueError(f"delay must be a finite number of seconds >= 0, got {delay_s}")
        self.delay_s = float(delay_s)
        self._heap: list[tuple[float, int, Any]] = []
        self._count = itertools.count()

    def push(self, now: float, item: Any) -> None:
        """Put ``item`` in at ``now``."""
        heapq.heappush(self._heap, (now + self.delay_s, next(self._count), item))

    def pop_due(self, now: float) -> list[Any]:
        """Every item whose time has come by ``now``, oldest first."""
        out = []
        while self._heap and self._heap[0][0] <= now:
            out.append(heapq.heappop(self._heap)[2])
        return out

    def next_due(self) -> float:
        """When the next item comes out (``inf`` if none)."""
        return self._heap[0][0] if self._heap else math.inf

    def clear(self) -> None:
        """Drop everything in flight."""
        self._heap.clear()


def feed_readings(core: Any, r: SensorReadings, now: float) -> None:
    """Hand one set of readings to ``core`` (a :class:`~autoscoop.deploy.controller.ControllerCore`) at
    ``now`` (its clock, s), as the ROS node's callbacks do, one input at a time."""
    core.joint_states(r.joint_names, r.joint_positions, now)
    core.odometry(r.speed_mps, now, pitch_from_quaternion(*r.chassis_quat_wxyz))
    core.pile_range(r.range_m, now, 0.0, 4.0)
    core.bucket_torque(r.tilt_torque_nm, now)
    core.lift_torque(r.lift_torque_nm, now)
    core.payload_mass(r.payload_kg, now)


def run_without_ros(bridge: SimBridge, core: Any, seed: int, start_s: float = 0.0, delay_s: float = 0.0,
                    on_command: Callable[[Any, SimBridge], None] | None = None) -> tuple[EpisodeOutcome, float]:
    """One episode of ``core`` (a :class:`~autoscoop.deploy.controller.ControllerCore`) against the
    simulator in one process, on simulated time: the ROS loop without its transport.

    The controller gets every sensor period's readings and is updated at each (its control periods
    fall on sensor periods); over ROS only the messages' delays and the clocks differ. With
    ``delay_s``, the readings reach it through a :class:`DelayLine` in simulated time, after the
    reset scene has been read for that long (as ``ros sim`` holds it), like ``ros sim --delay-s``.

    Args:
        bridge: the simulator.
        core: the controller, idle (its scoop starts here).
        seed: the episode's seed.
        start_s: the controller's clock at the episode's start (it must never go back).
        delay_s: transport delay of every reading, s.
        on_command: called with ``(core, bridge)`` after each command the controller publishes is applied.

    Returns:
        The episode's result and the controller's clock at its end.
    """
    readings = bridge.reset(seed)
    line = DelayLine(delay_s)
    period = bridge.sensor_period_s
    now = start_s

    def publish(r: SensorReadings, at: float) -> None:
        line.push(at, r)
        for due in line.pop_due(at):
            feed_readings(core, due, at)

    publish(readings, now)
    for _ in range(math.ceil(delay_s / period - 1e-9)):  # the still scene, until its readings have arrived
        now += period
        publish(readings, now)
    start = now
    core.scoop(True, now)
    while not bridge.done:
        published = core.update(now)
        if published is not None:
            bridge.command_speed(published.speed_mps)
            if published.lift_rad is not None:
                bridge.command_joint("lift", published.lift_rad)
                bridge.command_joint("tilt", published.tilt_rad)
            if on_command is not None:
                on_command(core, bridge)
        readings = bridge.step()
        now = start + readings.time_s
        publish(readings, now)
    core.scoop(False, now)
    return bridge.result(), now
