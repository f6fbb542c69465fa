"""Configuration: frozen pydantic models with defaults, units and checked ranges; YAML in and out.

Every field is declared with :func:`setting`: its default, its unit, its allowed range (or, through
its type, its choices) and a one-line description. Values are checked when a config is built, so a
bad value fails at once with a :class:`ConfigError` naming the dotted key (``pile.angle_deg``) and
what is allowed. Overrides use dotted keys, as on the command line: ``--set pile.angle_deg=28``.

:class:`ConfigModel` is the one schema mechanism of the package: the task config here and the
robot node's config (:mod:`autoscoop.deploy.robot_config`) are both built from it.
"""

from __future__ import annotations

import difflib
import math
import types
import typing
from collections.abc import Mapping
from pathlib import Path
from typing import Any, ClassVar, Literal, Self

import yaml
from pydantic import BaseModel, ConfigDict, Field, ValidationError, model_validator
from pydantic.fields import FieldInfo

from autoscoop.core import kinematics
from autoscoop.core.safe_files import UnsafeInputError, parse_yaml, quote, read_yaml, write_text_atomically

_MACHINE = kinematics.MACHINE
"""The machine this process runs: its actuator limits, friction, task lengths, rated load and control period are
the defaults of those settings, and its ``scene`` section replaces the defaults it names (see the end)."""


class ConfigError(ValueError):
    """A configuration key or value is not allowed; the message names the dotted key and what is allowed.

    Attributes:
        details: pydantic's error records behind the message (locations relative to the model that
            was built), empty for a check written by hand.
    """

    def __init__(self, message: str, details: list[dict[str, Any]] | None = None) -> None:
        super().__init__(message)
        self.details = details or []


def setting(default: Any, unit: str, doc: str, low: float | None = None, high: float | None = None,
            **field: Any) -> Any:
    """A config field: default, unit (``-`` for none), one-line meaning and, for numbers, the range [low, high].

    Numbers and booleans are strict (an int is taken for a float and becomes a float; a string, or a
    bool for a number, is refused), floats must be finite. Choices are given by the field's type
    (``Literal[...]`` or ``bool``); a tuple's item range by its item type. ``field`` goes to
    :func:`pydantic.Field` (e.g. ``min_length``).
    """
    kind = type(default)
    checks: dict[str, Any] = {"strict": True} if kind in (bool, int, float) else {}
    if kind in (int, float):
        checks.update({"ge": low, "le": high})
    if kind is float:
        checks["allow_inf_nan"] = False
    return Field(default, description=doc, json_schema_extra={"unit": unit, "low": low, "high": high},
                 **checks, **field)


def numbers(low: float | None = None, high: float | None = None) -> Any:
    """Type of a list of finite numbers, each in [low, high] (written and held as a tuple of floats)."""
    return tuple[typing.Annotated[float, Field(strict=True, allow_inf_nan=False, ge=low, le=high)], ...]


class ConfigModel(BaseModel):
    """Base of every config model: frozen, unknown keys refused, values checked when built.

    A field whose type is another ``ConfigModel`` is a section (null or missing: its defaults);
    other fields are declared with :func:`setting`. Any failure, when built directly, through
    :meth:`from_dict` or :meth:`replace`, raises :class:`ConfigError` naming the dotted key.
    """

    model_config = ConfigDict(frozen=True, extra="forbid")

    section: ClassVar[str] = ""
    """Dotted key prefix of this model's fields when it is built on its own (``pile``)."""
    label: ClassVar[str] = "config"
    """What errors call this config (``unknown config key(s) ...``)."""

    def __init__(self, /, **values: Any) -> None:
        # pydantic calls this for nested sections too; an inner ConfigError carries its error records
        # (``details``) and the outermost model rebuilds the message with the full dotted key.
        try:
            super().__init__(**values)
        except ValidationError as error:
            raise _config_error(type(self), error.errors(), type(self).section) from None

    @model_validator(mode="before")
    @classmethod
    def _null_section_takes_defaults(cls, data: Any) -> Any:
        if isinstance(data, Mapping):
            sections = {key for key, _, f in _fields(cls) if _section_type(f.annotation)}
            return {key: value for key, value in data.items() if not (value is None and key in sections)}
        return data

    @classmethod
    def from_dict(cls, data: Mapping[str, Any], prefix: str | None = None) -> Self:
        """Build a validated config from a nested dict (missing keys take defaults).

        Args:
            data: keys of this model; sections as nested mappings.
            prefix: dotted key of ``data`` in error messages (default: the model's ``section``).
        """
        prefix = cls.section if prefix is None else prefix
        if not isinstance(data, Mapping):
            raise ConfigError(f"{prefix or cls.label} must be a mapping of keys, got {type(data).__name__}")
        try:
            return cls(**{str(key): value for key, value in data.items()})
        except ConfigError as error:
            if not error.details or prefix == cls.section:
                raise
            raise _config_error(cls, error.details, prefix) from None

    def replace(self, **changes: Any) -> Self:
        """A validated copy with some fields changed, e.g. ``config.replace(pile=config.pile.replace(variants=1))``."""
        keys = {name: key for key, name, _ in _fields(type(self))}
        values = {key: getattr(self, name) for name, key in keys.items()}
        values.update({keys.get(name, name): value for name, value in changes.items()})
        return type(self)(**values)

    def to_dict(self) -> dict[str, Any]:
        """Plain nested dict, as written to YAML (tuples as lists)."""
        return self.model_dump(mode="json", by_alias=True)

    @classmethod
    def dotted_keys(cls, prefix: str = "") -> list[str]:
        """Every dotted key this model accepts, sections expanded."""
        out = []
        for key, _, f in _fields(cls):
            sub = _section_type(f.annotation)
            out += sub.dotted_keys(f"{prefix}{key}.") if sub else [f"{prefix}{key}"]
        return out

    def describe(self, prefix: str = "") -> str:
        """Table of every key with its value, unit, allowed values and meaning."""
        rows = []
        for key, name, f in _fields(type(self)):
            value = getattr(self, name)
            if _section_type(f.annotation):
                rows.append(value.describe(f"{prefix}{key}."))
                continue
            extra = f.json_schema_extra or {}
            choices = _choices(f.annotation)
            allowed = (f"{choices}" if choices is not None else "text" if f.annotation is str
                       else f"[{extra.get('low')}, {extra.get('high')}]" if extra.get("low") is not None else "-")
            rows.append(f"{prefix + key:<30} {value!s:<10} {extra.get('unit', '-'):<6} {allowed:<16} {f.description}")
        return "\n".join(rows)


def _fields(model: type[ConfigModel]) -> list[tuple[str, str, FieldInfo]]:
    """(key as written in YAML, attribute name, field) of each field of ``model``."""
    return [(f.alias or name, name, f) for name, f in model.model_fields.items()]


def _section_type(annotation: Any) -> type[ConfigModel] | None:
    return annotation if isinstance(annotation, type) and issubclass(annotation, ConfigModel) else None


def _model_in(annotation: Any) -> type[ConfigModel] | None:
    """The config model in a field's type (``X`` or ``X | None``), if any."""
    if typing.get_origin(annotation) in (typing.Union, types.UnionType):
        return next(filter(None, map(_section_type, typing.get_args(annotation))), None)
    return _section_type(annotation)


def _choices(annotation: Any) -> list | None:
    if annotation is bool:
        return [False, True]
    return list(typing.get_args(annotation)) if typing.get_origin(annotation) is Literal else None


def _config_error(model: type[ConfigModel], details: list[dict[str, Any]], prefix: str = "") -> ConfigError:
    """The :class:`ConfigError` for pydantic's error records from building ``model``: pydantic's own words for
    the first record after its dotted key (``prefix`` first; ``[i]`` for a list item) and the value given,
    then the field's allowed range and unit where it has one. Unknown keys of one section are named together,
    with the section's known keys; a check written by hand (a validator's ``ValueError``) keeps its words.
    """
    details = [inner for record in details for inner in _flattened(record)]
    first, head = details[0], [part for part in prefix.split(".") if part]
    where, _, leaf = _located(model, first["loc"])
    key = ".".join(head + where) or model.label
    reason = (first.get("ctx") or {}).get("error")
    if first["type"] == "extra_forbidden":
        section, holder, _ = _located(model, first["loc"][:-1])
        bad = [str(d["loc"][-1]) for d in details if d["type"] == "extra_forbidden" and d["loc"][:-1] == first["loc"][:-1]]
        known = [k for k, _, _ in _fields(holder)] if holder else []
        if not head + section:
            return ConfigError(f"unknown {model.label} section(s) {sorted(bad)}; known: {known}", details)
        dotted = sorted(".".join([*head, *section, name]) for name in bad)
        return ConfigError(f"unknown {model.label} key(s) {dotted}; known in {'.'.join(head + section)}: {known}", details)
    if first["type"] == "value_error":  # a check written by hand: its words (after the key, unless it names it)
        named = isinstance(reason, ConfigError) or leaf is None
        return ConfigError(str(reason) if named else f"{key} = {quote(first['input'])} {reason}", details)
    extra = (leaf.json_schema_extra or {}) if leaf is not None else {}
    unit = "" if extra.get("unit", "-") == "-" else f" {extra['unit']}"
    allowed = f" (allowed [{extra['low']}, {extra['high']}]{unit})" if extra.get("low") is not None else ""
    item = "".join(f"[{part}]" for part in first["loc"] if isinstance(part, int))
    return ConfigError(f"{key}{item} = {quote(first['input'])}: {first['msg']}{allowed}", details)


def _flattened(record: dict[str, Any]) -> list[dict[str, Any]]:
    """A section's own error records in place of the one that carries them, located from the outer model."""
    inner = (record.get("ctx") or {}).get("error")
    if not (isinstance(inner, ConfigError) and inner.details):
        return [record]
    return [{**d, "loc": (*record["loc"], *d["loc"])} for d in inner.details]


def _located(model: type[ConfigModel], loc: tuple) -> tuple[list[str], type[ConfigModel] | None, FieldInfo | None]:
    """The key parts of ``loc`` (list indices left out), the section there (if one) and the field there (if not)."""
    parts, owner, leaf = [], model, None
    for part in loc:
        if isinstance(part, int) or owner is None:
            continue
        leaf = next((f for key, _, f in _fields(owner) if key == part), None)
        parts.append(str(part))
        owner = _model_in(leaf.annotation) if leaf is not None else None
    return parts, owner, None if owner is not None else leaf


PILE_ANGLE_RANGE_DEG = (15.0, 60.0)
PileAngles = numbers(*PILE_ANGLE_RANGE_DEG)


class RobotConfig(ConfigModel):
    """The loader: start pose and actuator limits."""

    section = "robot"
    start_gap_m: float = setting(0.10, "m", "gap between the bucket tip and the pile's toe at the start", 0.0, 0.6)
    start_lift_rad: float = setting(0.23, "rad", "lift angle at the start: a larger one lowers the arm (the default holds the Komodo's level bucket just off the ground; a machine's scene sets its own, and `machine check` prints where the bucket starts)",
                                    *kinematics.LIFT_RANGE_RAD)
    start_tilt_rad: float = setting(0.0, "rad", "tilt angle at the start", *kinematics.TILT_RANGE_RAD)
    start_gap_jitter_m: float = setting(0.01, "m", "largest random change of the start gap in each episode", 0.0, 0.1)
    max_speed_mps: float = setting(_MACHINE.actuators.drive.max_speed_mps, "m/s", "drive speed limit, forward and back", 0.01, 0.5)
    lift_speed_radps: float = setting(_MACHINE.actuators.lift.max_speed_radps, "rad/s", "fastest lift setpoint motion (linear actuator speed)", 0.05, 3.0)
    tilt_speed_radps: float = setting(_MACHINE.actuators.tilt.max_speed_radps, "rad/s", "fastest tilt setpoint motion (linear actuator speed)", 0.05, 5.0)
    lift_torque_limit_nm: float = setting(_MACHINE.actuators.lift.torque_limit_nm, "N*m", "lift actuator torque bound (a heavy pile can stall it)", 1.0, 100000.0)
    tilt_torque_limit_nm: float = setting(_MACHINE.actuators.tilt.torque_limit_nm, "N*m", "tilt actuator torque bound", 1.0, 100000.0)
    wheel_torque_limit_nm: float = setting(_MACHINE.actuators.drive.wheel_torque_limit_nm, "N*m", "torque bound of each wheel motor", 0.5, 10000.0)
    ground_friction: float = setting(_MACHINE.wheels.ground_friction, "-", "wheel-ground sliding friction coefficient", 0.05, 2.0)
    bucket_friction: float = setting(0.4, "-", "sliding friction between the steel bucket and a particle", 0.05, 2.0)


class PileConfig(ConfigModel):
    """The pile of spherical particles in front of the robot."""

    section = "pile"
    angle_deg: float = setting(32.0, "deg", "mean slope of the pile's front face", *PILE_ANGLE_RANGE_DEG)
    angle_mix_deg: PileAngles = setting(
        (), "deg", "if given, each pile variant takes one of these face slopes in turn "
        "(training on a mix of piles); empty: always angle_deg", *PILE_ANGLE_RANGE_DEG)
    n_particles: int = setting(72, "-", "number of particles", 1, 1000)
    radius_m: float = setting(0.034, "m", "particle radius", 0.01, 0.08)
    particle_mass_kg: float = setting(0.3, "kg", "mass of one particle", 0.01, 5.0)
    friction: float = setting(1.0, "-", "sliding friction of particle contacts", 0.0, 2.0)
    rolling: bool = setting(True, "-", "particles may roll (free joints, spin damped by rolling_damping_nms); "
                            "false: they slide without turning (three slide joints each): a 1.3-1.6x faster "
                            "scene, but a stiffer pile (scripted fill 0.63 instead of 0.71) that the shipped "
                            "policy was not trained on")
    rolling_damping_nms: float = setting(0.5, "N*m*s/rad", "damping of particle spin when pile.rolling: the rolling "
                                         "resistance of angular gravel", 0.0, 10.0)
    across: int = setting(8, "-", "particles per row across the pile (y)", 1, 20)
    max_layers: int = setting(0, "-", "most layers of the stack, the bottom row as long as they need (a long pile, as a "
                              "shift's); 0: the smallest pyramid that holds the particles", 0, 20)
    jitter_m: float = setting(0.003, "m", "largest random offset of a particle's start position", 0.0, 0.02)
    settle_s: float = setting(1.0, "s", "physics time a new pile settles (then on until it rests, at most 3 s more)", 0.0, 5.0)
    variants: int = setting(16, "-", "distinct jittered piles per environment, each settled once and then reused", 1, 1024)


class RewardConfig(ConfigModel):
    """Paper eq. 5-7: shaped distance reward plus a mass bonus at the terminal point."""

    section = "reward"
    c_w: float = setting(10.0, "-", "weight c_w of the mass bonus c_w * w_t paid on reaching the terminal point", 0.0, 1000.0)
    epsilon_m: float = setting(0.10, "m", "tolerance epsilon: the tip within it of the terminal point has reached "
                               "it (a success when loaded: scoop.min_fill)", 0.001, 0.5)
    delta_m: float = setting(0.06, "m", "Delta: the tip within it of a particle centre is 'penetrating'", 0.001, 0.5)
    distance_scale_m: float = setting(1.0, "m", "distances are divided by it inside tanh (1 m: the paper's eq. 5)", 0.01, 10.0)
    terminal_dx_m: float = setting(_MACHINE.task.terminal_dx_m, "m", "terminal point x from the pile's toe (over the pile, where a scoop ends, raised clear of it)", -1.0, 1.0)
    terminal_z_m: float = setting(_MACHINE.task.terminal_height_m, "m", "terminal point height above the ground", 0.0, 1.0)
    rated_load_kg: float = setting(_MACHINE.bucket.rated_load_kg, "kg", "rated bucket load; fill factor = mass in bucket / rated load", 0.1, 100.0)
    fill_measure: Literal["mass", "scoop"] = setting(
        "mass", "-", "what the bonus pays for: mass (c_w * min(w, 1), the paper's) or scoop (c_w * min(max(w, "
        "volumetric fill), 1): a bucket full by volume pays as much as one full by mass)")
    c_overload: float = setting(0.0, "-", "the bonus falls by c_overload * (w - overload_from) for mass above "
                                "overload_from", 0.0, 1000.0)
    overload_from: float = setting(1.0, "-", "fill factor w from which mass costs c_overload per unit (1: the rated "
                                   "load; below 1 the bonus peaks short of it, a margin for heavy earth)", 0.5, 2.0)
    c_pitch: float = setting(0.0, "1/deg", "each step costs c_pitch per degree of nose-down chassis pitch beyond "
                             "pitch_from_deg (0: off, the paper's reward)", 0.0, 100.0)
    pitch_from_deg: float = setting(8.0, "deg", "nose-down chassis pitch from which c_pitch costs (a heavy load "
                                    "lifted far forward tips the loader onto its front wheels)", 0.0, 45.0)
    c_action_change: float = setting(0.0, "-", "each step costs c_action_change times the action's change from "
                                     "the last step (mean of the squared halved changes: 0 to 1; 0: off, the "
                                     "paper's reward)", 0.0, 100.0)
    c_approach_height: float = setting(0.0, "1/m", "until the tip first reaches the pile, each step costs "
                                       "c_approach_height per metre of tip height above approach_height_from_m "
                                       "(an operator approaches with the bucket low; 0: off, the paper's "
                                       "reward)", 0.0, 1000.0)
    approach_height_from_m: float = setting(0.06, "m", "tip height above the ground from which "
                                            "c_approach_height costs", 0.0, 0.5)
    c_overload_step: float = setting(0.0, "-", "each step costs c_overload_step * (w - scoop.overload_fill) for "
                                     "mass in the bucket above an overload (an overload is cheapest to shed "
                                     "while the bucket is still at the pile; 0: off, the paper's reward)", 0.0, 1000.0)
    c_energy: float = setting(0.0, "1/J", "each control period costs c_energy per joule of the actuators' positive "
                              "mechanical work in it (wheels, lift and tilt; what a shift reports as energy per "
                              "tonne; 0: off, the paper's reward)", 0.0, 10.0)
    c_success: float = setting(0.0, "-", "paid once on reaching the terminal point loaded, a success as "
                               "scoop.min_fill defines it (the bonus c_w * w grows with the load but has no step "
                               "where a scoop starts to count; 0: off, the paper's reward)", 0.0, 1000.0)
    c_time: float = setting(0.0, "-", "each control period costs c_time (the progress term pays up to 1 a "
                            "period, so hovering short of the terminal point pays nearly as much as reaching it "
                            "late; c_time 1 makes every period cost; 0: off, the paper's reward)", 0.0, 10.0)


class EnvConfig(ConfigModel):
    """Episode timing, physics step and where the state's mass comes from."""

    section = "env"
    control_period_s: float = setting(_MACHINE.control.period_s, "s", "time between actions (a whole number of physics steps)", 0.02, 1.0)
    max_episode_s: float = setting(8.0, "s", "episode time limit", 0.5, 60.0)
    timestep_s: float = setting(_MACHINE.control.period_s / _MACHINE.control.physics_steps_per_period, "s", "MuJoCo physics step (a divisor of the control period)", 0.0005, 0.04)
    mass_source: Literal["truth", "torque"] = setting(
        "truth", "-", "the state's w_t from counting particles (truth) or from the joint torques (torque); "
        "the reward always counts")
    load_cell_noise_nm: float = setting(0.2, "N*m", "std of torque noise when mass_source = torque", 0.0, 20.0)

    @model_validator(mode="after")
    def _whole_physics_steps(self) -> Self:
        period, step = self.control_period_s, self.timestep_s
        if period < step:
            raise ConfigError(f"env.control_period_s = {period} must be at least env.timestep_s = {step}")
        ratio = period / step
        if abs(ratio - round(ratio)) > 1e-9:
            raise ConfigError(f"env.control_period_s = {period} s must be a whole number of env.timestep_s = {step} s "
                              f"(it is {ratio:.6g} steps); e.g. env.timestep_s = {period / math.ceil(ratio)}")
        if self.max_episode_s / period < 1:
            raise ConfigError("env.max_episode_s must be at least one env.control_period_s")
        return self


class SensorConfig(ConfigModel):
    """What the policy's readings go through on their way from the sensors: transport delay and noise.

    The same link as ``autoscoop ros sim``'s options (``--delay-s``, ``--joint-noise-rad``, ...): the
    environment applies it to the state (:mod:`autoscoop.core.sensing`), the ROS simulator to the
    messages it publishes. The reward and the metrics always use the true values.
    """

    section = "sensor"
    delay_s: float = setting(0.0, "s", "every reading reaches the policy this late (honoured to the physics "
                             "step: rounded to a whole number of env.timestep_s)", 0.0, 2.0)
    odometry_window_steps: int = setting(2, "steps", "the odometry speed is the wheels' mean speed over this many "
                                         "physics steps (their angle change, as an encoder counts it); 1 reads the "
                                         "instantaneous wheel speed, which rings at the physics step while the "
                                         "wheels push into the pile", 1, 12)
    joint_noise_rad: float = setting(0.0, "rad", "std of the noise on each joint angle reading (lift, tilt)", 0.0, 0.1)
    speed_noise_mps: float = setting(0.0, "m/s", "std of the noise on the odometry speed", 0.0, 0.1)
    range_noise_m: float = setting(0.0, "m", "std of the noise on the range to the pile (kept >= 0)", 0.0, 0.1)
    torque_noise_nm: float = setting(0.0, "N*m", "std of the noise on each joint torque sample (one per physics "
                                     "step; the load cell averages them over the control period)", 0.0, 10.0)
    level_with_imu: bool = setting(False, "-", "the state's tip and bucket-joint positions are turned by the IMU's "
                                   "chassis pitch into the level frame (z: height above level ground while the "
                                   "loader rocks; the policy file says so as state_frame: level); false: the "
                                   "paper's chassis frame")


class ScoopTaskConfig(ConfigModel):
    """When an episode counts as a scoop, and when as an overload."""

    section = "scoop"
    min_fill: float = setting(0.5, "-", "success: the terminal point reached with the mass fill factor or the "
                              "volumetric fill, whichever is higher, at least this", 0.0, 2.0)
    overload_fill: float = setting(1.05, "-", "an episode ending with a fill factor above this is an overload", 0.5, 3.0)


class ShiftConfig(ConfigModel):
    """A loader's shift (``autoscoop shift``): one big pile, the hopper the loader fills from it, the scripted phases.

    The hopper is added to the scene only for a shift; a single scoop never sees these keys.
    """

    section = "shift"
    pile_particles: int = setting(630, "-", "particles in the shift's pile (630 of 0.3 kg, 189 kg: 27 full scoops of "
                                  "the rated load, so 15 cycles do not run out of pile); its slope and particles are "
                                  "pile.*", 1, 1000)
    pile_across: int = setting(7, "-", "particles per row across the shift's pile (7: 0.48 m, the bucket's width; the "
                               "loader cannot steer aside to reach more)", 1, 20)
    pile_layers: int = setting(3, "-", "layers of the shift's pile (3: the single scoop's pile height, the pile "
                               "longer instead)", 1, 20)
    haul_distance_m: float = setting(0.6, "m", "from the pile's toe back to the hopper's centre, along the loader's "
                                     "path", 0.0, 5.0)
    hopper_length_m: float = setting(0.5, "m", "inner length of the hopper along the loader's path", 0.2, 2.0)
    hopper_width_m: float = setting(0.7, "m", "inner width of the hopper across the loader's path", 0.3, 2.0)
    hopper_height_m: float = setting(0.10, "m", "height of the hopper's rim above the ground", 0.02, 1.0)
    phase_limit_s: float = setting(20.0, "s", "time limit of each scripted phase (back out, drive to the hopper, "
                                   "dump, curl back, return)", 1.0, 120.0)


def _range(low: float, high: float, unit: str, doc: str) -> Any:
    return setting((), unit, doc + "; [low, high] drawn uniformly per episode (equal ends: a fixed value; "
                   "empty: the preset's)", low, high, max_length=2)


def _probability(doc: str) -> Any:
    return setting((), "-", doc + "; [p] (empty: the preset's)", 0.0, 1.0, max_length=1)


ROBOT_PRESET: dict[str, tuple[float, ...]] = {
    "pile_angle_deg": (24.0, 42.0),
    "particle_mass_kg": (0.18, 0.42),
    "particle_friction": (0.55, 1.35),
    "particle_radius_m": (0.033, 0.035),
    "n_particles": (64.0, 80.0),
    "start_gap_m": (0.05, 0.32),
    "ground_friction": (0.6, 1.2),
    "bucket_friction": (0.25, 0.6),
    "torque_limit_scale": (0.85, 1.15),
    "actuator_speed_scale": (0.85, 1.15),
    "torque_source_probability": (0.5,),
    "torque_offset_nm": (-0.3, 0.3),
    "load_cell_noise_nm": (0.1, 0.4),
    "sensor_delay_s": (0.0, 0.07),
    "joint_noise_rad": (0.0, 0.003),
    "speed_noise_mps": (0.0, 0.003),
    "range_noise_m": (0.0, 0.005),
    "torque_noise_nm": (0.0, 0.3),
    "prescooped_probability": (0.2,),
    "prescoop_particles": (6.0, 14.0),
}
"""The ``robot`` preset: the ranges the shipped policy is trained on (documented in docs/randomize.md); the ranges
a machine's ``robot_preset`` names replace these when it runs (``_apply_machine_preset``)."""


class RandomizeConfig(ConfigModel):
    """A randomised world: ranges drawn once per episode (domain randomisation).

    ``preset`` names a set of ranges: ``none`` (the default: nothing is drawn, the paper's world to
    the bit) or ``robot`` (:data:`ROBOT_PRESET`). A range given here replaces the preset's; a
    number is taken as a fixed value (both ends equal). Draws happen in
    :mod:`autoscoop.sim.world`; each episode's draws are in ``info["world"]`` and its record.
    """

    section = "randomize"
    preset: Literal["none", "robot"] = setting("none", "-", "a named set of ranges: none (the paper's world) "
                                               "or robot (the ranges the shipped policy is trained on)")
    pile_angle_deg: PileAngles = _range(*PILE_ANGLE_RANGE_DEG, "deg", "pile face slope")
    particle_mass_kg: numbers(0.01, 5.0) = _range(0.01, 5.0, "kg", "mass of one particle (material density)")
    particle_friction: numbers(0.0, 2.0) = _range(0.0, 2.0, "-", "sliding friction of particle contacts")
    particle_radius_m: numbers(0.01, 0.1) = _range(0.01, 0.1, "m", "particle radius (a bank of scenes: "
                                                  "drawn to the millimetre)")
    n_particles: numbers(8, 200) = _range(8, 200, "-", "number of particles (drawn to a whole row of pile.across)")
    start_gap_m: numbers(0.0, 0.6) = _range(0.0, 0.6, "m", "start gap between tip and pile toe")
    ground_friction: numbers(0.05, 2.0) = _range(0.05, 2.0, "-", "wheel-ground friction")
    bucket_friction: numbers(0.05, 2.0) = _range(0.05, 2.0, "-", "bucket-particle friction")
    torque_limit_scale: numbers(0.2, 5.0) = _range(0.2, 5.0, "-", "factor on the lift, tilt and wheel torque limits")
    actuator_speed_scale: numbers(0.2, 5.0) = _range(0.2, 5.0, "-", "factor on the lift and tilt actuator speeds")
    torque_source_probability: numbers(0.0, 1.0) = _probability(
        "probability that an episode's state mass is the torque estimate (else the counted mass)")
    torque_offset_nm: numbers(-10.0, 10.0) = _range(-10.0, 10.0, "N*m", "constant offset of each joint torque reading "
                                                 "(a miscalibrated load cell), drawn for lift and tilt")
    load_cell_noise_nm: numbers(0.0, 20.0) = _range(0.0, 20.0, "N*m", "env.load_cell_noise_nm")
    sensor_delay_s: numbers(0.0, 2.0) = _range(0.0, 2.0, "s", "sensor.delay_s")
    joint_noise_rad: numbers(0.0, 0.1) = _range(0.0, 0.1, "rad", "sensor.joint_noise_rad")
    speed_noise_mps: numbers(0.0, 0.1) = _range(0.0, 0.1, "m/s", "sensor.speed_noise_mps")
    range_noise_m: numbers(0.0, 0.1) = _range(0.0, 0.1, "m", "sensor.range_noise_m")
    torque_noise_nm: numbers(0.0, 10.0) = _range(0.0, 10.0, "N*m", "sensor.torque_noise_nm")
    prescooped_probability: numbers(0.0, 1.0) = _probability(
        "probability that the pile was scooped once before (its face cut back as a scoop leaves it)")
    prescoop_particles: numbers(1, 100) = _range(1, 100, "-", "how many particles the earlier scoop took (the lowest of the face first)")

    @model_validator(mode="before")
    @classmethod
    def _numbers_are_fixed_values(cls, data: Any) -> Any:
        if not isinstance(data, Mapping):
            return data
        out = dict(data)
        for key, value in data.items():
            field = cls.model_fields.get(str(key))
            if field is not None and key != "preset" and isinstance(value, (int, float)) and not isinstance(value, bool):
                out[key] = [value] if _max_length(field) == 1 else [value, value]
        return out

    @model_validator(mode="after")
    def _ranges_ordered(self) -> Self:
        for name, field in type(self).model_fields.items():
            value = getattr(self, name)
            if name == "preset" or not value:
                continue
            if _max_length(field) == 2 and (len(value) != 2 or value[0] > value[1]):
                raise ConfigError(f"randomize.{name} = {list(value)} must be empty or [low, high] with low <= high")
        return self

    def ranges(self) -> dict[str, tuple[float, ...]]:
        """The ranges in force: the preset's, replaced by those given here; quantities not drawn are left out."""
        out = dict(ROBOT_PRESET) if self.preset == "robot" else {}
        out.update({name: tuple(getattr(self, name)) for name in type(self).model_fields
                    if name != "preset" and getattr(self, name)})
        return out

    @property
    def active(self) -> bool:
        """Whether anything is drawn per episode."""
        return bool(self.ranges())


def _max_length(field: FieldInfo) -> int | None:
    return next((m.max_length for m in field.metadata if getattr(m, "max_length", None) is not None), None)


class ScoopConfig(ConfigModel):
    """Everything that defines a scooping scene and task."""

    robot: RobotConfig = Field(default_factory=RobotConfig, description="the loader")
    pile: PileConfig = Field(default_factory=PileConfig, description="the pile")
    reward: RewardConfig = Field(default_factory=RewardConfig, description="the reward")
    env: EnvConfig = Field(default_factory=EnvConfig, description="the episode and physics")
    sensor: SensorConfig = Field(default_factory=SensorConfig, description="sensor delay and noise")
    scoop: ScoopTaskConfig = Field(default_factory=ScoopTaskConfig, description="what counts as a scoop")
    randomize: RandomizeConfig = Field(default_factory=RandomizeConfig, description="the randomised world")
    shift: ShiftConfig = Field(default_factory=ShiftConfig, description="a loader's shift: pile, hopper, phases")

    @property
    def max_episode_steps(self) -> int:
        """Number of actions in one episode before the time limit."""
        return round(self.env.max_episode_s / self.env.control_period_s)

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return max(1, round(self.env.control_period_s / self.env.timestep_s))

    def with_overrides(self, overrides: Mapping[str, Any]) -> ScoopConfig:
        """A copy with dotted keys replaced, e.g. ``{"pile.angle_deg": 28}``; string values are parsed as YAML."""
        sections = self.to_dict()
        for key, value in overrides.items():
            section, _, name = str(key).partition(".")
            if section not in sections or name not in sections[section]:
                close = difflib.get_close_matches(str(key), all_keys(), n=3)
                hint = (f"did you mean {' or '.join(close)}?" if close else
                        f"known in {section}: {', '.join(sections[section])}" if section in sections else
                        f"known sections: {', '.join(sections)} (`autoscoop config` lists every key)")
                raise ConfigError(f"unknown config key {quote(key)}; {hint}")
            sections[section][name] = _parse_scalar(value) if isinstance(value, str) else value
        return ScoopConfig.from_dict(sections)


def all_keys() -> list[str]:
    """Every dotted key a config accepts."""
    return ScoopConfig.dotted_keys()


def _parse_scalar(text: str) -> Any:
    """A ``--set`` value as YAML (without aliases or duplicate keys: :func:`~autoscoop.core.safe_files.parse_yaml`);
    the text itself where it is not such YAML."""
    try:
        return parse_yaml(text, "--set value")
    except UnsafeInputError:
        return text


def from_dict(data: Mapping[str, Any]) -> ScoopConfig:
    """Build a validated config from a nested dict (missing keys take defaults)."""
    return ScoopConfig.from_dict(data)


def read_yaml_file(path: str | Path, what: str = "config file") -> Any:
    """The parsed contents of a YAML file (``None`` if empty), read within bounds
    (:func:`autoscoop.core.safe_files.read_yaml`: size cap, no aliases, no duplicate keys).

    Raises:
        ConfigError: naming the file when it is missing, a folder, unreadable, too large or not accepted
            YAML (with the line and column).
    """
    try:
        return read_yaml(path, what)
    except UnsafeInputError as error:
        raise ConfigError(str(error)) from None


def overrides_from_yaml(path: str | Path) -> dict[str, Any]:
    """The keys a YAML file sets, as dotted keys (nested sections or dotted keys at the top level).

    Raises:
        ConfigError: the file is missing, a folder or not valid YAML (naming the file and line), or
            its top level is not a mapping of sections.
    """
    data = read_yaml_file(path) or {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    out: dict[str, Any] = {}
    for key, value in data.items():
        if "." in str(key):
            out[str(key)] = value
        elif isinstance(value, dict):
            out.update({f"{key}.{name}": item for name, item in value.items()})
        else:
            raise ConfigError(f"{path}: section {key!r} must be a mapping of keys; known sections: "
                              f"{list(ScoopConfig.model_fields)}")
    return out


def load_yaml(path: str | Path) -> ScoopConfig:
    """Read a config from YAML: the defaults with the file's keys applied (validated).

    Raises:
        ConfigError: naming the file (and, for a YAML syntax error, the line), then the key.
    """
    overrides = overrides_from_yaml(path)
    try:
        return ScoopConfig().with_overrides(overrides)
    except ConfigError as error:
        raise ConfigError(f"config file {path}: {error}", error.details) from None


def save_yaml(config: ScoopConfig, path: str | Path) -> None:
    """Write a config as nested YAML (atomically: a failed write leaves the previous file)."""
    write_text_atomically(path, yaml.safe_dump(config.to_dict(), sort_keys=False))


def parse_set_args(pairs: list[str] | None) -> dict[str, Any]:
    """``["pile.angle_deg=28", ...]`` -> ``{"pile.angle_deg": "28", ...}`` (values parsed later)."""
    out: dict[str, Any] = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set expects key=value, got {pair!r}")
        out[key.strip()] = value.strip()
    return out


def _apply_machine_scene(machine_scene: Mapping[str, Any], source: str) -> None:
    """Make the machine's ``scene`` settings the defaults of their keys (every section and ``ScoopConfig()``).

    Raises:
        ConfigError: a key that does not exist or a value out of its range, naming ``source``.
    """
    if not machine_scene:
        return
    sections = {field.default_factory.section: field.default_factory
                for field in ScoopConfig.model_fields.values()}
    try:
        checked = ScoopConfig().with_overrides(dict(machine_scene))
    except ConfigError as error:
        raise ConfigError(f"{source}: scene: {error}", error.details) from None
    for key in machine_scene:
        section, _, name = str(key).partition(".")
        model = sections[section]
        model.model_fields[name].default = getattr(getattr(checked, section), name)
        model.model_rebuild(force=True)


def _apply_machine_preset(machine_preset: Mapping[str, Any], source: str) -> None:
    """Replace the ``robot`` preset's ranges that the machine's ``robot_preset`` names.

    Raises:
        ConfigError: a name that is not a preset range, or a range outside its key's bounds, naming ``source``.
    """
    for name, values in machine_preset.items():
        if name not in ROBOT_PRESET:
            raise ConfigError(f"{source}: robot_preset.{name}: not a range of the robot preset; known: "
                              f"{', '.join(ROBOT_PRESET)}")
        try:
            RandomizeConfig(**{name: list(values)})
        except ConfigError as error:
            raise ConfigError(f"{source}: robot_preset: {error}", error.details) from None
        ROBOT_PRESET[name] = tuple(float(v) for v in values)


_apply_machine_scene(_MACHINE.scene, str(_MACHINE.folder or _MACHINE.name))
_apply_machine_preset(_MACHINE.robot_preset, str(_MACHINE.folder or _MACHINE.name))
