"""The robot's configuration for the controller node: limits, timeouts, calibration, topic names.

One YAML file (``autoscoop ros controller --config robot.yaml``), every section optional::

    control:   {control_period_s: 0.25, input_timeout_s: 0.5, episode_s: 8.0, auto_start: false}
    limits:    {max_speed_mps: 0.1, lift_min_rad: -0.1, lift_max_rad: 0.32, ...}
    sensors:   {lift_joint: lift, tilt_joint: tilt, joint_margin_rad: 0.05, ...}
    estop:     {required: false}
    payload:   {calibration: "", rated_load_kg: 7.0}
    topics:    {joint_states: joint_states, cmd_vel: cmd_vel, ...}
    potentiometer:
      lift: {raw: [312, 790], rad: [-0.10, 0.32]}   # reading <-> angle, piecewise linear
      tilt: null                                     # null: joint_states already in radians

Every field has a default, a unit and a checked range; a bad value fails at start-up with a message
naming the dotted key and what is allowed (as :mod:`autoscoop.core.config` does for the scene).
"""

from __future__ import annotations

import dataclasses
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from autoscoop.core import kinematics
from autoscoop.core.config import ConfigError, _field, _Section

_BOOL = (True, False)


@dataclass(frozen=True)
class ControlSection(_Section):
    """Timing of the control loop and of an episode."""

    _section = "control"
    control_period_s: float = _field(0.25, "s", "time between policy steps (the policy's training period)", 0.02, 1.0)
    input_timeout_s: float = _field(0.5, "s", "an input older than this stops the robot (watchdog)", 0.02, 5.0)
    episode_s: float = _field(8.0, "s", "a scoop ends after this long (the training episode limit)", 0.5, 600.0)
    start_pose_tolerance_rad: float = _field(0.05, "rad", "a scoop's arm targets start at the task's start pose "
                                                          "(robot.start_lift_rad, start_tilt_rad) when both joints "
                                                          "are this close to it, else at the measured angles",
                                             0.0, 1.5)
    auto_start: bool = _field(False, "-", "start the first scoop as soon as every input is fresh, "
                                          "without waiting for the scoop topic", choices=_BOOL)


@dataclass(frozen=True)
class LimitsSection(_Section):
    """Limits every published command is clamped to (the robot's, at most the model's)."""

    _section = "limits"
    max_speed_mps: float = _field(0.1, "m/s", "drive speed limit, forward and back", 0.0, 0.5)
    max_accel_mps2: float = _field(0.8, "m/s^2", "largest change of the commanded speed per second (a stop is "
                                                 "never limited)", 0.01, 10.0)
    lift_min_rad: float = _field(kinematics.LIFT_RANGE_RAD[0], "rad", "lowest lift command (arm highest)",
                                 *kinematics.LIFT_RANGE_RAD)
    lift_max_rad: float = _field(kinematics.LIFT_RANGE_RAD[1], "rad", "highest lift command (arm lowest)",
                                 *kinematics.LIFT_RANGE_RAD)
    tilt_min_rad: float = _field(kinematics.TILT_RANGE_RAD[0], "rad", "lowest tilt command (bucket curled)",
                                 *kinematics.TILT_RANGE_RAD)
    tilt_max_rad: float = _field(kinematics.TILT_RANGE_RAD[1], "rad", "highest tilt command (edge down)",
                                 *kinematics.TILT_RANGE_RAD)
    lift_rate_radps: float = _field(0.4, "rad/s", "fastest change of the lift command", 0.01, 3.0)
    tilt_rate_radps: float = _field(1.0, "rad/s", "fastest change of the tilt command", 0.01, 5.0)


@dataclass(frozen=True)
class SensorsSection(_Section):
    """What a plausible reading is; anything else stops the robot like a stale input."""

    _section = "sensors"
    lift_joint: str = _field("lift", "-", "name of the lift joint in joint_states")
    tilt_joint: str = _field("tilt", "-", "name of the tilt joint in joint_states")
    joint_margin_rad: float = _field(0.05, "rad", "a joint reading this far outside its range is a sensor fault",
                                     0.0, 0.5)
    max_speed_reading_mps: float = _field(1.0, "m/s", "an odometry speed above this is a sensor fault", 0.05, 10.0)
    max_range_m: float = _field(10.0, "m", "a pile_range reading above this (or above the message's max_range) is "
                                          "no reading", 0.1, 100.0)
    max_torque_nm: float = _field(200.0, "N*m", "a joint torque reading above this (either sign) is a sensor fault",
                                  1.0, 5000.0)


@dataclass(frozen=True)
class EstopSection(_Section):
    """The software stop topic (never a substitute for the hardware emergency stop)."""

    _section = "estop"
    required: bool = _field(False, "-", "refuse to move until an estop=false message arrives, and stop when "
                                        "estop messages go stale (a heartbeat)", choices=_BOOL)


@dataclass(frozen=True)
class PayloadSection(_Section):
    """The state's payload mass: from the joint torques (autoscoop.core.payload, paper eq. 8 or eq. 4), or reported."""

    _section = "payload"
    source: str = _field("torque", "-", "mass from the joint torques through the estimator (torque), or as "
                                        "reported on payload_mass by a load cell or the simulator (topic)",
                         choices=("torque", "topic"))
    method: str = _field("eq8", "-", "torque estimator: eq8 (lift_torque and bucket_torque, the arm's static "
                                     "equilibrium, as in training) or eq4 (bucket_torque alone, the paper's "
                                     "lever-arm formula; far more sensitive to the pile's push)",
                         choices=("eq8", "eq4"))
    calibration: str = _field("", "-", "payload calibration YAML (autoscoop payload calibrate); empty: nominal")
    rated_load_kg: float = _field(7.0, "kg", "rated bucket load: the state's w = mass / rated load", 0.1, 100.0)
    empty_below_kg: float = _field(0.35, "kg", "estimates below this read 0: the estimate's swing with an empty "
                                               "bucket while driving (+-0.65 kg in simulation)", 0.0, 5.0)


TOPIC_DEFAULTS = {
    "joint_states": "joint_states", "odom": "odom", "pile_range": "pile_range", "bucket_torque": "bucket_torque",
    "lift_torque": "lift_torque", "payload_mass": "payload_mass", "estop": "estop", "scoop": "scoop", "cmd_vel": "cmd_vel",
    "lift_command": "lift_controller/command", "tilt_command": "tilt_controller/command",
}
_TOPIC_DOCS = {
    "joint_states": "sensor_msgs/JointState in: lift and tilt positions (rad, or raw potentiometer readings)",
    "odom": "nav_msgs/Odometry in: twist.twist.linear.x is the forward speed (m/s)",
    "pile_range": "sensor_msgs/Range in: distance from the bucket tip to the pile (m)",
    "bucket_torque": "std_msgs/Float64 in: torque at the tilt joint (N*m)",
    "lift_torque": "std_msgs/Float64 in: torque at the lift joint (N*m), used by payload.method = eq8",
    "payload_mass": "std_msgs/Float64 in: mass in the bucket (kg), used when payload.source = topic",
    "estop": "std_msgs/Bool in: true stops the robot until false",
    "scoop": "std_msgs/Bool in: true starts a scoop, false ends it",
    "cmd_vel": "geometry_msgs/Twist out: linear.x forward speed (m/s)",
    "lift_command": "std_msgs/Float64 out: lift position command (rad)",
    "tilt_command": "std_msgs/Float64 out: tilt position command (rad)",
}
_GRAPH_NAME = re.compile(r"^~?/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


@dataclass(frozen=True)
class TopicsSection:
    """Topic names; relative by default so that a launch file (or ``name:=new``) can remap them."""

    joint_states: str = TOPIC_DEFAULTS["joint_states"]
    odom: str = TOPIC_DEFAULTS["odom"]
    pile_range: str = TOPIC_DEFAULTS["pile_range"]
    bucket_torque: str = TOPIC_DEFAULTS["bucket_torque"]
    lift_torque: str = TOPIC_DEFAULTS["lift_torque"]
    payload_mass: str = TOPIC_DEFAULTS["payload_mass"]
    estop: str = TOPIC_DEFAULTS["estop"]
    scoop: str = TOPIC_DEFAULTS["scoop"]
    cmd_vel: str = TOPIC_DEFAULTS["cmd_vel"]
    lift_command: str = TOPIC_DEFAULTS["lift_command"]
    tilt_command: str = TOPIC_DEFAULTS["tilt_command"]

    def __post_init__(self) -> None:
        names = {}
        for f in dataclasses.fields(self):
            value = getattr(self, f.name)
            if not isinstance(value, str) or not _GRAPH_NAME.match(value):
                raise ConfigError(f"topics.{f.name} = {value!r} is not a valid ROS name (letters, digits, _ and /, "
                                  f"starting with a letter); default {TOPIC_DEFAULTS[f.name]!r}")
            if value in names:
                raise ConfigError(f"topics.{f.name} and topics.{names[value]} are both {value!r}; each needs its own")
            names[value] = f.name


@dataclass(frozen=True)
class PotentiometerCalibration:
    """A joint's raw potentiometer reading <-> angle, piecewise linear through measured points.

    Outside the measured span the end segments are extended (the joint-range check then catches a
    broken sensor).

    Attributes:
        raw: readings at the calibration points (any unit the driver reports), strictly monotonic.
        rad: joint angles at those points, rad, strictly monotonic.
    """

    raw: tuple[float, ...]
    rad: tuple[float, ...]

    @classmethod
    def parse(cls, key: str, data: Any) -> "PotentiometerCalibration | None":
        """From the YAML mapping ``{raw: [...], rad: [...]}``; ``None`` for null (already radians)."""
        if data is None:
            return None
        if not isinstance(data, Mapping) or set(data) != {"raw", "rad"}:
            raise ConfigError(f"{key} must be null or a mapping {{raw: [...], rad: [...]}}, got {data!r}")
        values = {}
        for name in ("raw", "rad"):
            seq = data[name]
            if not isinstance(seq, (list, tuple)) or len(seq) < 2:
                raise ConfigError(f"{key}.{name} must be a list of at least 2 numbers, got {seq!r}")
            if any(isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) for v in seq):
                raise ConfigError(f"{key}.{name} must hold finite numbers only, got {seq!r}")
            steps = np.diff(np.asarray(seq, dtype=float))
            if not (np.all(steps > 0) or np.all(steps < 0)):
                raise ConfigError(f"{key}.{name} must be strictly increasing or strictly decreasing, got {seq!r}")
            values[name] = tuple(float(v) for v in seq)
        if len(values["raw"]) != len(values["rad"]):
            raise ConfigError(f"{key}.raw and {key}.rad must have the same length, got "
                              f"{len(values['raw'])} and {len(values['rad'])}")
        return cls(values["raw"], values["rad"])

    def to_rad(self, reading: float) -> float:
        """Angle (rad) of a raw reading."""
        return _piecewise(reading, self.raw, self.rad)

    def to_raw(self, angle_rad: float) -> float:
        """Raw reading of an angle (rad); what a simulator publishes to mimic the sensor."""
        return _piecewise(angle_rad, self.rad, self.raw)


def _piecewise(x: float, xs: tuple[float, ...], ys: tuple[float, ...]) -> float:
    xp, yp = np.asarray(xs), np.asarray(ys)
    if xp[0] > xp[-1]:
        xp, yp = xp[::-1], yp[::-1]
    i = int(np.clip(np.searchsorted(xp, x) - 1, 0, len(xp) - 2))
    return float(yp[i] + (x - xp[i]) * (yp[i + 1] - yp[i]) / (xp[i + 1] - xp[i]))


SECTIONS = {"control": ControlSection, "limits": LimitsSection, "sensors": SensorsSection, "estop": EstopSection,
            "payload": PayloadSection, "topics": TopicsSection}


@dataclass(frozen=True)
class RobotNodeConfig:
    """Everything the controller node needs to know about the robot; validated when built."""

    control: ControlSection = field(default_factory=ControlSection)
    limits: LimitsSection = field(default_factory=LimitsSection)
    sensors: SensorsSection = field(default_factory=SensorsSection)
    estop: EstopSection = field(default_factory=EstopSection)
    payload: PayloadSection = field(default_factory=PayloadSection)
    topics: TopicsSection = field(default_factory=TopicsSection)
    lift_potentiometer: PotentiometerCalibration | None = None
    tilt_potentiometer: PotentiometerCalibration | None = None

    def __post_init__(self) -> None:
        lim = self.limits
        for joint in ("lift", "tilt"):
            low, high = getattr(lim, f"{joint}_min_rad"), getattr(lim, f"{joint}_max_rad")
            if not low < high:
                raise ConfigError(f"limits.{joint}_min_rad = {low} must be below limits.{joint}_max_rad = {high}")
        for key, value in (("sensors.lift_joint", self.sensors.lift_joint),
                           ("sensors.tilt_joint", self.sensors.tilt_joint),
                           ("payload.calibration", self.payload.calibration)):
            if not isinstance(value, str):
                raise ConfigError(f"{key} = {value!r} must be a string")
        if self.sensors.lift_joint == self.sensors.tilt_joint or not self.sensors.lift_joint \
                or not self.sensors.tilt_joint:
            raise ConfigError(f"sensors.lift_joint and sensors.tilt_joint must be two different non-empty names, got "
                              f"{self.sensors.lift_joint!r} and {self.sensors.tilt_joint!r}")
        if self.control.input_timeout_s < self.control.control_period_s / 10:
            raise ConfigError(f"control.input_timeout_s = {self.control.input_timeout_s} s is shorter than a tenth of "
                              f"control.control_period_s = {self.control.control_period_s} s")
        if self.payload.calibration and not Path(self.payload.calibration).is_file():
            raise ConfigError(f"payload.calibration = {self.payload.calibration!r}: no such file")

    def potentiometer(self, joint: str) -> PotentiometerCalibration | None:
        """The calibration of ``lift`` or ``tilt``, or ``None`` (readings already in radians)."""
        return getattr(self, f"{joint}_potentiometer")

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict, as in the YAML."""
        out: dict[str, Any] = {name: dataclasses.asdict(getattr(self, name)) for name in SECTIONS}
        pots = (("lift", self.lift_potentiometer), ("tilt", self.tilt_potentiometer))
        out["potentiometer"] = {joint: (None if cal is None else {"raw": list(cal.raw), "rad": list(cal.rad)})
                                for joint, cal in pots}
        return out

    def describe(self) -> str:
        """Every key with its value, unit, allowed range and meaning."""
        rows = []
        for section, cls in SECTIONS.items():
            for f in dataclasses.fields(cls):
                value = getattr(getattr(self, section), f.name)
                key = f"{section}.{f.name}"
                if cls is TopicsSection:
                    rows.append(f"{key:<30} {value!s:<33} {_TOPIC_DOCS[f.name]}")
                    continue
                meta = f.metadata
                allowed = (f"{list(meta['choices'])}" if meta["choices"] else "text" if isinstance(f.default, str)
                           else f"[{meta['low']}, {meta['high']}]")
                rows.append(f"{key:<30} {value!s:<10} {meta['unit']:<6} {allowed:<16} {meta['doc']}")
        rows.append("potentiometer.lift, potentiometer.tilt: null (radians) or {raw: [...], rad: [...]}")
        return "\n".join(rows)


def robot_config_from_dict(data: Mapping[str, Any]) -> RobotNodeConfig:
    """Build a validated config from a nested dict (missing keys take defaults)."""
    if not isinstance(data, Mapping):
        raise ConfigError(f"robot config must be a mapping of sections, got {type(data).__name__}")
    known = [*SECTIONS, "potentiometer"]
    unknown = set(data) - set(known)
    if unknown:
        raise ConfigError(f"unknown robot config section(s) {sorted(unknown)}; known: {known}")
    parts: dict[str, Any] = {}
    for section, cls in SECTIONS.items():
        values = data.get(section) or {}
        if not isinstance(values, Mapping):
            raise ConfigError(f"robot config section {section!r} must be a mapping, got {values!r}")
        values = dict(values)
        names = [f.name for f in dataclasses.fields(cls)]
        bad = set(values) - set(names)
        if bad:
            raise ConfigError(f"unknown robot config key(s) {sorted(f'{section}.{b}' for b in bad)}; "
                              f"known in {section}: {names}")
        for f in dataclasses.fields(cls):
            if f.name in values and isinstance(f.default, float) and isinstance(values[f.name], int) \
                    and not isinstance(values[f.name], bool):
                values[f.name] = float(values[f.name])
        parts[section] = cls(**values)
    pots = data.get("potentiometer") or {}
    if not isinstance(pots, Mapping) or set(pots) - {"lift", "tilt"}:
        raise ConfigError(f"potentiometer must be a mapping with keys lift and/or tilt, got {pots!r}")
    for joint in ("lift", "tilt"):
        parts[f"{joint}_potentiometer"] = PotentiometerCalibration.parse(f"potentiometer.{joint}", pots.get(joint))
    return RobotNodeConfig(**parts)


def load_robot_config(path: str | Path | None) -> RobotNodeConfig:
    """Read and check the robot's YAML; ``None`` gives the defaults (simulated robot, readings in radians).

    Raises:
        ConfigError: naming the file and the offending key.
    """
    if path is None:
        return RobotNodeConfig()
    path = Path(path)
    if not path.is_file():
        raise ConfigError(f"robot config {path}: no such file")
    try:
        data = yaml.safe_load(path.read_text()) or {}
    except yaml.YAMLError as error:
        raise ConfigError(f"robot config {path}: not valid YAML ({error})") from None
    try:
        return robot_config_from_dict(data)
    except ConfigError as error:
        raise ConfigError(f"robot config {path}: {error}") from None
