"""The robot's configuration for the controller node: limits, timeouts, calibration, topic names.

One YAML file (``autoscoop ros controller --robot robot.yaml``), every section optional::

    control:   {control_period_s: 0.25, input_timeout_s: 0.5, max_future_stamp_s: 0.1, episode_s: 8.0, ...}
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

import re
from collections.abc import Mapping
from pathlib import Path
from typing import Any, Literal, Self

import numpy as np
from pydantic import Field, ValidationInfo, field_validator, model_validator

from autoscoop.core import kinematics
from autoscoop.core.config import ConfigError, ConfigModel, numbers, read_yaml_file, setting


class ControlSection(ConfigModel):
    """Timing of the control loop and of an episode."""

    section = "control"
    control_period_s: float = setting(0.25, "s", "time between policy steps (the policy's training period)", 0.02, 1.0)
    input_timeout_s: float = setting(0.5, "s", "an input older than this stops the robot (watchdog): by its header "
                                          "stamp where it has one, else by its arrival", 0.02, 5.0)
    max_future_stamp_s: float = setting(0.1, "s", "a message stamped further ahead of the node's clock than this "
                                                  "stops the robot (clock skew allowed between machines)", 0.0, 5.0)
    episode_s: float = setting(8.0, "s", "a scoop ends after this long (the training episode limit)", 0.5, 600.0)
    start_pose_tolerance_rad: float = setting(0.05, "rad", "a scoop's arm targets start at the task's start pose "
                                                           "(robot.start_lift_rad, start_tilt_rad) when both joints "
                                                           "are this close to it, else at the measured angles",
                                              0.0, 1.5)
    auto_start: bool = setting(False, "-", "start the first scoop as soon as every input is fresh, "
                                           "without waiting for the scoop topic")


class LimitsSection(ConfigModel):
    """Limits every published command is clamped to (the robot's, at most the model's)."""

    section = "limits"
    max_speed_mps: float = setting(0.1, "m/s", "drive speed limit, forward and back", 0.0, 0.5)
    max_accel_mps2: float = setting(0.8, "m/s^2", "largest change of the commanded speed per second (a stop is "
                                                  "never limited)", 0.01, 10.0)
    lift_min_rad: float = setting(kinematics.LIFT_RANGE_RAD[0], "rad", "lowest lift command (arm highest)",
                                  *kinematics.LIFT_RANGE_RAD)
    lift_max_rad: float = setting(kinematics.LIFT_RANGE_RAD[1], "rad", "highest lift command (arm lowest)",
                                  *kinematics.LIFT_RANGE_RAD)
    tilt_min_rad: float = setting(kinematics.TILT_RANGE_RAD[0], "rad", "lowest tilt command (bucket curled)",
                                  *kinematics.TILT_RANGE_RAD)
    tilt_max_rad: float = setting(kinematics.TILT_RANGE_RAD[1], "rad", "highest tilt command (edge down)",
                                  *kinematics.TILT_RANGE_RAD)
    lift_rate_radps: float = setting(0.4, "rad/s", "fastest change of the lift command", 0.01, 3.0)
    tilt_rate_radps: float = setting(1.0, "rad/s", "fastest change of the tilt command", 0.01, 5.0)

    @model_validator(mode="after")
    def _min_below_max(self) -> Self:
        for joint in ("lift", "tilt"):
            low, high = getattr(self, f"{joint}_min_rad"), getattr(self, f"{joint}_max_rad")
            if not low < high:
                raise ConfigError(f"limits.{joint}_min_rad = {low} must be below limits.{joint}_max_rad = {high}")
        return self


class SensorsSection(ConfigModel):
    """What a plausible reading is; anything else stops the robot like a stale input."""

    section = "sensors"
    lift_joint: str = setting("lift", "-", "name of the lift joint in joint_states")
    tilt_joint: str = setting("tilt", "-", "name of the tilt joint in joint_states")
    joint_margin_rad: float = setting(0.05, "rad", "a joint reading this far outside its range is a sensor fault",
                                      0.0, 0.5)
    max_speed_reading_mps: float = setting(1.0, "m/s", "an odometry speed above this is a sensor fault", 0.05, 10.0)
    max_range_m: float = setting(10.0, "m", "a pile_range reading above this (or above the message's max_range) is "
                                            "no reading", 0.1, 100.0)
    max_torque_nm: float = setting(200.0, "N*m", "a joint torque reading above this (either sign) is a sensor fault",
                                   1.0, 5000.0)

    @model_validator(mode="after")
    def _two_joints(self) -> Self:
        if self.lift_joint == self.tilt_joint or not self.lift_joint or not self.tilt_joint:
            raise ConfigError(f"sensors.lift_joint and sensors.tilt_joint must be two different non-empty names, got "
                              f"{self.lift_joint!r} and {self.tilt_joint!r}")
        return self


class EstopSection(ConfigModel):
    """The software stop topic (never a substitute for the hardware emergency stop)."""

    section = "estop"
    required: bool = setting(False, "-", "refuse to move until an estop=false message arrives, and stop when "
                                         "estop messages go stale (a heartbeat)")


class PayloadSection(ConfigModel):
    """The state's payload mass: from the joint torques (autoscoop.core.payload, paper eq. 8 or eq. 4), or reported."""

    section = "payload"
    source: Literal["torque", "topic"] = setting(
        "torque", "-", "mass from the joint torques through the estimator (torque), or as reported on "
        "payload_mass by a load cell or the simulator (topic)")
    method: Literal["eq8", "eq4"] = setting(
        "eq8", "-", "torque estimator: eq8 (lift_torque and bucket_torque, the arm's static equilibrium, as in "
        "training) or eq4 (bucket_torque alone, the paper's lever-arm formula; far more sensitive to the pile's push)")
    calibration: str = setting("", "-", "payload calibration YAML (autoscoop payload calibrate); empty: nominal")
    rated_load_kg: float = setting(7.0, "kg", "rated bucket load: the state's w = mass / rated load", 0.1, 100.0)
    empty_below_kg: float = setting(0.35, "kg", "estimates below this read 0: the estimate's swing with an empty "
                                                "bucket while driving (+-0.65 kg in simulation)", 0.0, 5.0)

    @field_validator("calibration")
    @classmethod
    def _calibration_file_exists(cls, path: str) -> str:
        if path and not Path(path).is_file():
            raise ValueError("is not a file")
        return path


_GRAPH_NAME = re.compile(r"^~?/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")


class TopicsSection(ConfigModel):
    """Topic names; relative by default so that a launch file (or ``name:=new``) can remap them."""

    section = "topics"
    joint_states: str = setting("joint_states", "-", "sensor_msgs/JointState in: lift and tilt positions (rad, or "
                                                     "raw potentiometer readings)")
    odom: str = setting("odom", "-", "nav_msgs/Odometry in: twist.twist.linear.x is the forward speed (m/s)")
    pile_range: str = setting("pile_range", "-", "sensor_msgs/Range in: distance from the bucket tip to the pile (m)")
    bucket_torque: str = setting("bucket_torque", "-", "std_msgs/Float64 in: torque at the tilt joint (N*m)")
    lift_torque: str = setting("lift_torque", "-", "std_msgs/Float64 in: torque at the lift joint (N*m), used by "
                                                   "payload.method = eq8")
    payload_mass: str = setting("payload_mass", "-", "std_msgs/Float64 in: mass in the bucket (kg), used when "
                                                     "payload.source = topic")
    estop: str = setting("estop", "-", "std_msgs/Bool in: true stops the robot until false")
    scoop: str = setting("scoop", "-", "std_msgs/Bool in: true starts a scoop, false ends it")
    cmd_vel: str = setting("cmd_vel", "-", "geometry_msgs/Twist out: linear.x forward speed (m/s)")
    lift_command: str = setting("lift_controller/command", "-", "std_msgs/Float64 out: lift position command (rad)")
    tilt_command: str = setting("tilt_controller/command", "-", "std_msgs/Float64 out: tilt position command (rad)")

    @field_validator("*")
    @classmethod
    def _ros_name(cls, name: str, info: ValidationInfo) -> str:
        if not _GRAPH_NAME.match(name):
            raise ValueError(f"is not a valid ROS name (letters, digits, _ and /, starting with a letter); "
                             f"default {TOPIC_DEFAULTS[info.field_name]!r}")
        return name

    @model_validator(mode="after")
    def _one_topic_each(self) -> Self:
        names: dict[str, str] = {}
        for key, value in self.to_dict().items():
            if value in names:
                raise ConfigError(f"topics.{key} and topics.{names[value]} are both {value!r}; each needs its own")
            names[value] = key
        return self


TOPIC_DEFAULTS = {name: f.default for name, f in TopicsSection.model_fields.items()}
"""Default name of each topic, by key."""


class PotentiometerCalibration(ConfigModel):
    """A joint's raw potentiometer reading <-> angle, piecewise linear through measured points.

    Outside the measured span the end segments are extended (the joint-range check then catches a
    broken sensor).

    Attributes:
        raw: readings at the calibration points (any unit the driver reports), strictly monotonic.
        rad: joint angles at those points, rad, strictly monotonic, as many as ``raw``.
    """

    raw: numbers() = setting(..., "-", "readings at the calibration points, strictly monotonic", min_length=2)
    rad: numbers() = setting(..., "rad", "joint angles at those points, strictly monotonic", min_length=2)

    @field_validator("raw", "rad")
    @classmethod
    def _monotonic(cls, points: tuple[float, ...]) -> tuple[float, ...]:
        steps = np.diff(np.asarray(points, dtype=float))
        if not (np.all(steps > 0) or np.all(steps < 0)):
            raise ValueError("must be strictly increasing or strictly decreasing")
        return points

    @field_validator("rad")
    @classmethod
    def _as_many_as_raw(cls, rad: tuple[float, ...], info: ValidationInfo) -> tuple[float, ...]:
        raw = info.data.get("raw")
        if raw is not None and len(raw) != len(rad):
            raise ValueError(f"must have the same length as raw ({len(raw)} points)")
        return rad

    @classmethod
    def parse(cls, key: str, data: Any) -> PotentiometerCalibration | None:
        """From the YAML mapping ``{raw: [...], rad: [...]}``; ``None`` for null (already radians)."""
        return None if data is None else cls.from_dict(data, prefix=key)

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


_CALIBRATION_DOC = "null (readings in radians) or {raw: [...], rad: [...]}: reading <-> angle, piecewise linear"


class PotentiometerSection(ConfigModel):
    """The joints' potentiometer calibrations; null: that joint's joint_states are already in radians."""

    section = "potentiometer"
    lift: PotentiometerCalibration | None = setting(None, "-", f"lift joint: {_CALIBRATION_DOC}")
    tilt: PotentiometerCalibration | None = setting(None, "-", f"tilt joint: {_CALIBRATION_DOC}")

    @model_validator(mode="before")
    @classmethod
    def _lift_and_tilt_only(cls, data: Any) -> Any:
        if not isinstance(data, Mapping) or set(data) - {"lift", "tilt"}:
            raise ConfigError(f"potentiometer must be a mapping with keys lift and/or tilt, got {data!r}")
        return data


class RobotNodeConfig(ConfigModel):
    """Everything the controller node needs to know about the robot; validated when built."""

    label = "robot config"
    control: ControlSection = Field(default_factory=ControlSection, description="the control loop")
    limits: LimitsSection = Field(default_factory=LimitsSection, description="command limits")
    sensors: SensorsSection = Field(default_factory=SensorsSection, description="plausible readings")
    estop: EstopSection = Field(default_factory=EstopSection, description="the software stop")
    payload: PayloadSection = Field(default_factory=PayloadSection, description="the payload mass")
    topics: TopicsSection = Field(default_factory=TopicsSection, description="topic names")
    potentiometers: PotentiometerSection = Field(default_factory=PotentiometerSection, alias="potentiometer",
                                                 description="joint reading calibrations (YAML key: potentiometer)")

    @model_validator(mode="after")
    def _timeout_fits_the_period(self) -> Self:
        if self.control.input_timeout_s < self.control.control_period_s / 10:
            raise ConfigError(f"control.input_timeout_s = {self.control.input_timeout_s} s is shorter than a tenth of "
                              f"control.control_period_s = {self.control.control_period_s} s")
        return self

    @property
    def lift_potentiometer(self) -> PotentiometerCalibration | None:
        """The lift joint's calibration, or ``None`` (readings already in radians)."""
        return self.potentiometers.lift

    @property
    def tilt_potentiometer(self) -> PotentiometerCalibration | None:
        """The tilt joint's calibration, or ``None`` (readings already in radians)."""
        return self.potentiometers.tilt

    def potentiometer(self, joint: str) -> PotentiometerCalibration | None:
        """The calibration of ``lift`` or ``tilt``, or ``None`` (readings already in radians)."""
        return getattr(self.potentiometers, joint)


def robot_config_from_dict(data: Mapping[str, Any]) -> RobotNodeConfig:
    """Build a validated config from a nested dict (missing keys take defaults)."""
    return RobotNodeConfig.from_dict(data)


def robot_yaml(config: RobotNodeConfig) -> str:
    """The whole robot file as YAML text, every key written (what a node announces and its bag keeps)."""
    import yaml  # noqa: PLC0415

    return yaml.safe_dump(config.to_dict(), sort_keys=False)


def robot_from_yaml(text: str, source: str) -> RobotNodeConfig:
    """A robot file from YAML text (:func:`robot_yaml`'s), checked; ``source`` names where it came from.

    Raises:
        ConfigError: naming ``source`` and the offending key.
    """
    import yaml  # noqa: PLC0415

    try:
        data = yaml.safe_load(text) or {}
    except yaml.YAMLError as error:
        raise ConfigError(f"robot file in {source}: not YAML ({error})") from None
    if not isinstance(data, Mapping):
        raise ConfigError(f"robot file in {source}: not a mapping of sections")
    try:
        return robot_config_from_dict(data)
    except ConfigError as error:
        raise ConfigError(f"robot file in {source}: {error}") from None


def joint_readings(config: RobotNodeConfig) -> str:
    """How the robot's ``joint_states`` carry the two joints: names and units (radians, or the potentiometer
    calibration), one line. Two nodes that must understand each other's readings have the same line."""
    parts = []
    for joint in ("lift", "tilt"):
        name = getattr(config.sensors, f"{joint}_joint")
        pot = config.potentiometer(joint)
        unit = "radians" if pot is None else (f"raw potentiometer readings, {list(pot.raw)} <-> {list(pot.rad)} rad")
        parts.append(f"{joint} joint {name!r} in {unit}")
    return "; ".join(parts)


def load_robot_config(path: str | Path | None) -> RobotNodeConfig:
    """Read and check the robot's YAML; ``None`` gives the defaults (simulated robot, readings in radians).

    Raises:
        ConfigError: naming the file and the offending key.
    """
    if path is None:
        return RobotNodeConfig()
    path = Path(path)
    data = read_yaml_file(path, "robot config") or {}
    try:
        return robot_config_from_dict(data)
    except ConfigError as error:
        raise ConfigError(f"robot config {path}: {error}") from None
