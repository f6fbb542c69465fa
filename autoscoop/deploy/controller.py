"""The controller node's logic, free of ROS: readings in, clamped commands out, one scoop at a time.

A front end (``autoscoop.deploy.ros1.controller_node``, or a test) feeds it each message as plain
numbers with the time it arrived (and, for a message with a header, its
:class:`~autoscoop.deploy.safety.Stamp`), and calls :meth:`ControllerCore.update` whenever
:meth:`ControllerCore.next_wakeup` comes or a message may have changed things; every
:class:`~autoscoop.deploy.safety.Command` it returns is to be published at once.

Per control period (``control.control_period_s``, 0.25 s) while a scoop runs and every input is
healthy, it builds the 12-number state with :func:`autoscoop.core.state.build_state` (mass from the joint
torques, averaged over the period by :class:`autoscoop.core.payload.ReadingAverage` as in the environment,
through the payload estimator), asks the policy for an action, moves the targets with
:func:`autoscoop.core.state.advance_targets` (the environment's scaling) and clamps the command to the
robot's limits. Otherwise:

| situation                                  | speed | arm                                  |
|--------------------------------------------|-------|--------------------------------------|
| no scoop running (``idle``)                | 0     | no command (controllers hold)        |
| an input stale, missing or bad (``fault``) | 0     | the last command, held               |
| ``estop`` true (``estop``)                 | 0     | the last command, held               |

An input is stale when its newest reading is older than ``control.input_timeout_s``: by the header
stamp for ``joint_states``, ``odom`` and ``pile_range`` (a stamp that stops advancing goes stale; one
too old, too far ahead of the node's clock or out of order is bad), by arrival for the others.
A fault or an estop is published the moment it is seen (the watchdog's expiry is a wake-up time),
not at the next control period; the scoop resumes when every input is healthy again.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from autoscoop.core import kinematics
from autoscoop.core.config import ScoopConfig
from autoscoop.core.payload import (
    PayloadCalibration,
    PayloadEstimator,
    PayloadReading,
    ReadingAverage,
    reported_mass_kg,
)
from autoscoop.core.policy import Policy, state_frame_of
from autoscoop.core.reward import is_penetrating
from autoscoop.core.state import (
    CommandLimits,
    Measurements,
    advance_targets,
    build_state,
    validate_action,
)
from autoscoop.deploy.robot_config import RobotNodeConfig
from autoscoop.deploy.safety import Command, CommandLimiter, InputWatchdog, Stamp
from autoscoop.envs.outcome import EpisodeOutcome
from autoscoop.envs.records import EpisodeRecord, episode_meta

SENSOR_INPUTS = ("joint_states", "odom", "pile_range")
"""Inputs the watchdog always requires fresh; also the payload's (per ``payload.source`` and
``payload.method``: ``bucket_torque`` (the tilt torque) and ``lift_torque``, ``bucket_torque``, or
``payload_mass``), and ``estop`` when ``estop.required``."""
WAKE_SLACK_S = 1e-4
"""A wake-up this close before a deadline counts as on time (timers fire a little early or late)."""
REPEAT_LOG_S = 1.0
"""While the robot stays stopped, a changed reason is logged at most this often, s (a sensor sending
garbage at 50 Hz would otherwise write a line per message); ``~status`` has every change."""
STOPPED_MODES = ("fault", "estop")


def payload_inputs(payload: Any) -> tuple[str, ...]:
    """The inputs the payload mass needs, for a ``payload`` section of the robot config."""
    if payload.source == "topic":
        return ("payload_mass",)
    return ("bucket_torque", "lift_torque") if payload.method == "eq8" else ("bucket_torque",)


class MassFromTorque(Protocol):
    """Payload mass (kg) from a reading of the joint torques at the measured joint angles and chassis pitch."""

    def __call__(self, reading: PayloadReading) -> float: ...


class PayloadMass:
    """The node's mass input: :class:`autoscoop.core.payload.PayloadEstimator`, eq. 8 (both joints) or eq. 4 (bucket).

    Eq. 8 is what the environment's torque sensor uses (``env.mass_source = torque``), and both report
    through :func:`autoscoop.core.payload.reported_mass_kg`: estimates below ``empty_below_kg`` (0 in the
    environment) read 0; where the estimate is undefined (eq. 4 with the payload's centre right above
    the joint) the last report is kept.

    Args:
        calibration: payload calibration YAML (``autoscoop payload calibrate``); empty: the nominal one.
        empty_below_kg: the estimator's noise floor, kg.
        method: ``eq8`` or ``eq4``.
    """

    def __init__(self, calibration: str | Path = "", empty_below_kg: float = 0.0, method: str = "eq8") -> None:
        cal = PayloadCalibration.load(calibration) if calibration else PayloadCalibration()
        self.estimator = PayloadEstimator(cal, method=method)
        self.empty_below_kg = empty_below_kg
        self._last = 0.0

    def __call__(self, reading: PayloadReading) -> float:
        mass = self.estimator.mass_kg(reading)
        self._last = reported_mass_kg(mass, self._last, self.empty_below_kg)
        return self._last


class DelayLog:
    """The last ``size`` transport delays of one input, s, in a ring allocated (and touched) up front, so
    that a node running for days does not grow: 100 000 delays (35 min at 48 Hz) are 0.8 MB."""

    def __init__(self, size: int = 100_000) -> None:
        self._ring = np.full(size, np.nan)
        self._next = 0
        self.count = 0

    def append(self, delay_s: float) -> None:
        self._ring[self._next] = delay_s
        self._next = (self._next + 1) % len(self._ring)
        self.count = min(self.count + 1, len(self._ring))

    def values(self) -> np.ndarray:
        """The delays kept (in no particular order once the ring has wrapped), s."""
        return self._ring[:self.count]


@dataclass
class _Episode:
    index: int
    start: float
    record: EpisodeRecord
    targets: np.ndarray
    pending_action: np.ndarray | None = None
    previous: Measurements | None = None
    faults: int = 0
    mass_kg: float = 0.0


class ControllerCore:
    """The node's logic; see the module docstring.

    Args:
        config: the robot's configuration (validated).
        policy: the controller (``Policy``: ``reset()``, ``act(state)``).
        task: the scene config the policy was made for (its action scaling and speed limit).
        mass_from_torque: the payload estimator; defaults to :class:`PayloadMass` with the config's calibration.
        record_dir: write one episode record per scoop here (``None``: no records).
        log: ``log(level, text)`` with level ``info``, ``warn`` or ``error``.
        policy_name: the policy as given on the command line, for records.
    """

    def __init__(self, config: RobotNodeConfig, policy: Policy, task: ScoopConfig | None = None,
                 mass_from_torque: MassFromTorque | None = None, record_dir: str | Path | None = None,
                 log: Callable[[str, str], None] | None = None, policy_name: str | None = None) -> None:
        self.config = config
        self.policy = policy
        self.level_state = state_frame_of(policy) == "level"
        """whether the state's tip and joint positions are levelled by the chassis pitch (the policy's frame)"""
        self.policy_name = policy_name or getattr(policy, "name", "policy")
        self.task = task or ScoopConfig()
        self.task_limits = CommandLimits.for_robot(self.task.robot)
        self.period_s = config.control.control_period_s
        self.limiter = CommandLimiter(config.limits, self.period_s)
        inputs = SENSOR_INPUTS + payload_inputs(config.payload) + (("estop",) if config.estop.required else ())
        self.watchdog = InputWatchdog(inputs, config.control.input_timeout_s, config.control.max_future_stamp_s)
        self.mass_from_torque = mass_from_torque or PayloadMass(config.payload.calibration,
                                                                config.payload.empty_below_kg, config.payload.method)
        self.readings = ReadingAverage()
        """the payload's readings, each field averaged over the messages since the last control period"""
        self.record_dir = None if record_dir is None else Path(record_dir)
        self.log = log or (lambda level, text: None)
        margin = config.sensors.joint_margin_rad
        self._joint_bounds = {"lift": (kinematics.LIFT_RANGE_RAD[0] - margin, kinematics.LIFT_RANGE_RAD[1] + margin),
                              "tilt": (kinematics.TILT_RANGE_RAD[0] - margin, kinematics.TILT_RANGE_RAD[1] + margin)}
        self.lift_rad = math.nan
        self.tilt_rad = math.nan
        self.speed_mps = math.nan
        self.range_m = math.nan
        self.lift_torque_nm = math.nan
        self.tilt_torque_nm = math.nan
        self.chassis_pitch_rad = 0.0
        self.reported_mass_kg = math.nan
        self.estop_engaged = False
        self.episode: _Episode | None = None
        self.episodes_done = 0
        self.saved: list[Path] = []
        self.mode = "idle"
        self.reason = ""
        self.last_command: np.ndarray | None = None
        """(speed, lift, tilt) last published; lift and tilt NaN until an arm command is published."""
        self._start_requested = bool(config.control.auto_start)
        self._next_control = -math.inf
        self._stop_logged = -math.inf
        self.delays: dict[str, DelayLog] = {}
        """each stamped input's transport delays (stamp -> arrival), s"""

    # ---------------------------------------------------------------- inputs (each with its arrival time)
    def joint_states(self, names: Sequence[str], positions: Sequence[float], now: float,
                     stamp: Stamp | None = None) -> bool:
        """``sensor_msgs/JointState``: names and positions (raw readings where a potentiometer is calibrated).

        The sensor inputs take the arrival time ``now`` (s, monotonic) and, for a stamped message, its
        ``stamp``; they return whether the reading was taken (``False``: refused, which stops the robot at
        once, or a repeated stamp, which is ignored)."""
        values = {}
        for joint in ("lift", "tilt"):
            name = getattr(self.config.sensors, f"{joint}_joint")
            try:
                index = list(names).index(name)
                reading = float(positions[index])
            except (ValueError, IndexError, TypeError):
                self.watchdog.invalid("joint_states", f"no position for joint {name!r}")
                return False
            pot = self.config.potentiometer(joint)
            angle = pot.to_rad(reading) if (pot is not None and math.isfinite(reading)) else reading
            low, high = self._joint_bounds[joint]
            if not math.isfinite(angle):
                self.watchdog.invalid("joint_states", f"{joint} reading is {reading}")
                return False
            if not low <= angle <= high:
                self.watchdog.invalid("joint_states", f"{joint} = {angle:.3f} rad is outside [{low:.3f}, {high:.3f}]")
                return False
            values[joint] = angle
        if not self.watchdog.valid("joint_states", now, stamp):
            return False
        self.lift_rad, self.tilt_rad = values["lift"], values["tilt"]
        self.readings.add(self._reading(), ("lift_rad", "tilt_rad"))
        return True

    def odometry(self, speed_mps: float, now: float, chassis_pitch_rad: float = 0.0, stamp: Stamp | None = None) -> bool:
        """``nav_msgs/Odometry``: forward speed, m/s, and the chassis pitch of its orientation, rad (nose down +)."""
        if not self._within("odom", speed_mps, self.config.sensors.max_speed_reading_mps, "m/s", now, stamp):
            return False
        self.speed_mps = float(speed_mps)
        pitch = float(chassis_pitch_rad)
        self.chassis_pitch_rad = pitch if math.isfinite(pitch) and abs(pitch) < 0.5 * math.pi else 0.0
        self.readings.add(self._reading(), ("chassis_pitch_rad",))
        return True

    def pile_range(self, range_m: float, now: float, min_range_m: float = 0.0, max_range_m: float = math.inf,
                   stamp: Stamp | None = None) -> bool:
        """``sensor_msgs/Range``: distance from the tip to the pile, m; outside [min, max] is no reading (REP 117)."""
        low = min_range_m if math.isfinite(min_range_m) else 0.0
        high = self.config.sensors.max_range_m
        if math.isfinite(max_range_m) and low < max_range_m < high:
            high = max_range_m
        if not math.isfinite(range_m) or not (max(low, 0.0) <= range_m <= high):
            self.watchdog.invalid("pile_range", f"range {range_m} m is not within [{max(low, 0.0):g}, {high:g}] m")
            return False
        if not self.watchdog.valid("pile_range", now, stamp):
            return False
        self.range_m = float(range_m)
        return True

    def bucket_torque(self, tilt_torque_nm: float, now: float) -> bool:
        """``std_msgs/Float64`` on ``bucket_torque``: torque at the tilt (bucket) joint, N*m."""
        if not self._within("bucket_torque", tilt_torque_nm, self.config.sensors.max_torque_nm, "N*m", now):
            return False
        self.tilt_torque_nm = float(tilt_torque_nm)
        self.readings.add(self._reading(), ("tilt_torque_nm",))
        return True

    def lift_torque(self, lift_torque_nm: float, now: float) -> bool:
        """``std_msgs/Float64`` on ``lift_torque``: torque at the lift joint, N*m (``payload.method: eq8``)."""
        if not self._within("lift_torque", lift_torque_nm, self.config.sensors.max_torque_nm, "N*m", now):
            return False
        self.lift_torque_nm = float(lift_torque_nm)
        self.readings.add(self._reading(), ("lift_torque_nm",))
        return True

    def payload_mass(self, mass_kg: float, now: float) -> bool:
        """``std_msgs/Float64``: mass in the bucket, kg, as a load cell (or the simulator) reports it."""
        if not self._within("payload_mass", mass_kg, 5.0 * self.config.payload.rated_load_kg, "kg", now):
            return False
        self.reported_mass_kg = float(mass_kg)
        return True

    def _within(self, name: str, value: float, limit: float, unit: str, now: float,
                stamp: Stamp | None = None) -> bool:
        """Mark input ``name`` bad unless ``value`` is finite and within +-``limit``; else whether the
        watchdog takes the reading (its stamp, if any, checked)."""
        try:
            number = float(value)
        except (TypeError, ValueError):
            number = math.nan
        if not math.isfinite(number) or abs(number) > limit:
            self.watchdog.invalid(name, f"{value} {unit} is not within +-{limit:g} {unit}")
            return False
        return self.watchdog.valid(name, now, stamp)

    def estop(self, engaged: bool, now: float) -> None:
        """``std_msgs/Bool``: true stops the robot until a false arrives."""
        self.estop_engaged = bool(engaged)
        if "estop" in self.watchdog.names:
            self.watchdog.valid("estop", now)

    def scoop(self, start: bool, now: float) -> None:
        """``std_msgs/Bool``: true starts a scoop (ending one that runs), false ends the running one."""
        if self.episode is not None:
            self._end_episode("restarted" if start else "stopped by the scoop topic", now)
        self._start_requested = bool(start)
        if start:
            self._next_control = now

    def transport_delay(self, name: str, delay_s: float) -> None:
        """Note how long a stamped message took from its stamp to its arrival, s (for reports)."""
        log = self.delays.get(name)
        if log is None:
            log = self.delays[name] = DelayLog()
        log.append(delay_s)

    # ---------------------------------------------------------------- the loop
    def next_wakeup(self, now: float) -> float:
        """When :meth:`update` must run next after ``now``: the next control period, an input going stale,
        the scoop's end."""
        times = [self._next_control, self.watchdog.next_expiry(now) + WAKE_SLACK_S]
        if self.episode is not None:
            times.append(self.episode.start + self.config.control.episode_s)
        return min(times)

    def update(self, now: float) -> Command | None:
        """Advance to ``now``; the command to publish, or ``None`` when nothing needs publishing now."""
        control = now >= self._next_control - WAKE_SLACK_S
        if control:  # keep the period's phase; skip periods missed while the machine was busy
            following = self._next_control + self.period_s if math.isfinite(self._next_control) else now + self.period_s
            while following <= now + WAKE_SLACK_S:
                following += self.period_s
            self._next_control = following
        if self.episode is not None and now - self.episode.start >= self.config.control.episode_s - WAKE_SLACK_S:
            self._end_episode("time limit", now)
            control = True
        problems = self.watchdog.problems(now)
        if self.estop_engaged:
            mode, reason = "estop", "estop engaged"
        elif problems:
            mode, reason = "fault", "; ".join(problems)
        else:
            mode, reason = ("running" if (self.episode is not None or self._start_requested) else "idle"), ""
        changed = (mode, reason) != (self.mode, self.reason)
        if changed:
            self._log_transition(mode, reason, now)
        self.mode, self.reason = mode, reason
        if mode == "running":
            if self._start_requested and self.episode is None:
                self._start_episode(now)
                control = True
            if not control:
                return None
            return self._publish(self._policy_step(now))
        if not (control or changed):
            return None
        if self.episode is not None:
            self.episode.faults += int(changed)
            self.episode.previous = None  # the next state's changes restart from zero
        return self._publish(self._stopped(mode, reason))

    # ---------------------------------------------------------------- internals
    def _reading(self) -> PayloadReading:
        """The latest payload readings (the fields a message brought are added to :attr:`readings`)."""
        return PayloadReading(lift_rad=self.lift_rad, tilt_rad=self.tilt_rad, lift_torque_nm=self.lift_torque_nm,
                              tilt_torque_nm=self.tilt_torque_nm, chassis_pitch_rad=self.chassis_pitch_rad)

    def _measurements(self) -> Measurements:
        if self.config.payload.source == "topic":
            mass = max(self.reported_mass_kg, 0.0)
        else:
            mean = self.readings.take()
            mass = float(self.mass_from_torque(self.readings.latest if mean is None else mean))
        # a policy trained in the level frame gets the arm's points turned by the odometry's chassis pitch
        pitch = self.chassis_pitch_rad if self.level_state else 0.0
        return Measurements(mass_kg=mass if math.isfinite(mass) else 0.0, pile_distance_m=self.range_m,
                            speed_mps=self.speed_mps, lift_rad=self.lift_rad, tilt_rad=self.tilt_rad,
                            chassis_pitch_rad=pitch)

    def _stopped(self, mode: str, reason: str) -> Command:
        arm = None
        if self.episode is not None and self.last_command is not None:
            arm = self.limiter.hold(self.last_command[1:])
        if arm is None:
            return Command(0.0, None, None, mode, reason)
        return Command(0.0, float(arm[0]), float(arm[1]), mode, reason)

    def _policy_step(self, now: float) -> Command:
        episode = self.episode
        measured = self._measurements()
        state = build_state(measured, episode.previous, self.config.payload.rated_load_kg)
        try:
            if not np.all(np.isfinite(state)):
                raise ValueError(f"state is not finite: {state.tolist()}")
            action = validate_action(self.policy.act(state))
        except Exception as error:
            self._log_transition("fault", f"policy error: {error}", now)
            episode.previous = None
            return self._stopped("fault", f"policy error: {error}")
        if episode.pending_action is not None:
            self._append_step(now, state, episode.pending_action)
        else:
            episode.record.meta["start"] = {"state": state.astype(float).round(6).tolist(), "lift_rad": self.lift_rad,
                                            "tilt_rad": self.tilt_rad, "tip_world_m": [math.nan] * 3}
        episode.previous = measured
        episode.mass_kg = measured.mass_kg
        episode.pending_action = action
        episode.targets = advance_targets(episode.targets, action, self.task_limits)
        last = self.last_command
        if last is not None and not np.all(np.isfinite(last[1:])):
            last = np.array([last[0], self.lift_rad, self.tilt_rad])
        out = self.limiter.clamp(episode.targets, last)
        return Command(float(out[0]), float(out[1]), float(out[2]), "running")

    def _publish(self, command: Command) -> Command:
        if not self.limiter.contains(command):  # last guard: never let a bad number out
            self.log("error", f"refused an out-of-limit command {command}; stopping")
            command = Command(0.0, None, None, "fault", "internal: out-of-limit command refused")
        published = command.as_array()
        if self.last_command is not None and command.lift_rad is None:  # the arm keeps its last command
            published[1:] = self.last_command[1:]
        self.last_command = published
        return command

    def _start_episode(self, now: float) -> None:
        self._start_requested = False
        self.policy.reset()
        self.readings.restart()
        arm = self._start_arm()
        targets = np.clip([0.0, *arm], self.task_limits.low, self.task_limits.high)
        index = self.episodes_done
        meta = episode_meta(self.task, control_period_s=self.period_s, time_limit_s=self.config.control.episode_s,
                            source="ros controller", policy=self.policy_name, episode=index,
                            wall_time_start=time.time(), robot_config=self.config.to_dict())
        self.episode = _Episode(index=index, start=now, record=EpisodeRecord(meta=meta), targets=targets)
        self.last_command = np.array([0.0 if self.last_command is None else self.last_command[0], *targets[1:]])
        self.log("info", f"scoop {index} started ({self.policy_name}), arm targets from lift {targets[1]:.3f}, "
                         f"tilt {targets[2]:.3f} rad")

    def _start_arm(self) -> tuple[float, float]:
        """Where the scoop's arm targets start: the task's start pose (the setpoints the robot holds the arm
        at before a scoop, as in training; the arm sags a little below them) when the measured angles are
        within ``control.start_pose_tolerance_rad`` of it, else the measured angles."""
        pose = (self.task.robot.start_lift_rad, self.task.robot.start_tilt_rad)
        tolerance = self.config.control.start_pose_tolerance_rad
        if abs(self.lift_rad - pose[0]) <= tolerance and abs(self.tilt_rad - pose[1]) <= tolerance:
            return pose
        return self.lift_rad, self.tilt_rad

    def _append_step(self, now: float, state: np.ndarray, action: np.ndarray) -> None:
        nan = math.nan
        self.episode.record.append(
            time_s=now - self.episode.start, state=state.astype(float), action=action, reward=nan,
            reward_progress=nan, reward_mass=nan, particles_in_bucket=nan, mass_in_bucket_kg=nan,
            lift_rad=self.lift_rad, tilt_rad=self.tilt_rad, lift_torque_nm=self.lift_torque_nm,
            tilt_torque_nm=self.tilt_torque_nm,
            tip_world_m=[nan, nan, nan],
            penetrating=is_penetrating(self.range_m + self.task.pile.radius_m, self.task.reward))

    def _end_episode(self, why: str, now: float) -> None:
        episode, self.episode = self.episode, None
        self.episodes_done += 1
        rated = self.config.payload.rated_load_kg
        unmeasured: Any = math.nan  # the robot counts no particles: particles and spilled are NaN, not counts
        outcome = EpisodeOutcome(seed=-1, fill_factor=episode.mass_kg / rated, mass_kg=episode.mass_kg,
                                 particles=unmeasured, success=False, cycle_time_s=None, spilled=unmeasured,
                                 physics_error=False, steps=len(episode.record), episode_return=math.nan)
        episode.record.meta["outcome"] = {
            **outcome.as_dict(), "ended": why, "faults": episode.faults, "duration_s": now - episode.start,
            "note": "the robot's own view: mass is the payload estimate, penetrating is judged from pile_range; "
                    "success and spillage are not measured",
        }
        episode.record.meta["transport_delay_s"] = self.delay_summary()
        self.log("info", f"scoop {episode.index} ended ({why}) after {now - episode.start:.2f} s, "
                         f"{len(episode.record)} steps, payload estimate {episode.mass_kg:.2f} kg")
        if self.record_dir is not None and len(episode.record) > 0:
            path = episode.record.save(self.record_dir / f"robot_episode_{episode.index:05d}.npz")
            self.saved.append(path)
            self.log("info", f"wrote {path}")

    def _log_transition(self, mode: str, reason: str, now: float) -> None:
        """Log a stop and a recovery at once; a changed reason while stopped, at most every ``REPEAT_LOG_S``."""
        if mode in STOPPED_MODES:
            if mode != self.mode:
                self.log("warn", f"stopping (zero velocity, arm held): {reason}")
            elif now - self._stop_logged < REPEAT_LOG_S:
                return
            else:
                self.log("warn", f"still stopped: {reason}")
            self._stop_logged = now
        elif self.mode in STOPPED_MODES:
            self.log("info", f"inputs healthy again: {mode}")

    def delay_summary(self) -> dict[str, Any]:
        """Median, 99th percentile and max of each stamped input's transport delay, s."""
        out = {}
        for name, log in self.delays.items():
            a = log.values()
            if len(a):
                out[name] = {"median": float(np.median(a)), "p99": float(np.percentile(a, 99)),
                             "max": float(a.max()), "n": len(a)}
        return out

    def close(self, now: float) -> None:
        """End a running scoop (its record is written)."""
        if self.episode is not None:
            self._end_episode("node shut down", now)
