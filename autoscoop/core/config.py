"""Configuration: frozen dataclasses with defaults, units and checked ranges; YAML in and out.

Every field declares its unit, its allowed range (or choices) and a one-line description in its
metadata. Values are checked when a config is built, so a bad value fails at once with a message
naming the dotted key (``pile.angle_deg``) and the allowed range. Overrides use dotted keys, as on
the command line: ``--set pile.angle_deg=28``.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Mapping

import yaml

from autoscoop.core import kinematics


class ConfigError(ValueError):
    """A configuration key or value is not allowed; the message names the key and the range."""


def _field(default: Any, unit: str, doc: str, low: float | None = None, high: float | None = None,
           choices: tuple | None = None) -> Any:
    return field(default=default, metadata={"unit": unit, "doc": doc, "low": low, "high": high,
                                            "choices": choices})


class _Section:
    """Mixin: validate every field against its metadata after construction."""

    _section: str = ""

    def __post_init__(self) -> None:
        for f in dataclasses.fields(self):
            _check(f"{self._section}.{f.name}", getattr(self, f.name), f)


def _check(key: str, value: Any, f: dataclasses.Field) -> None:
    meta = f.metadata
    if meta.get("choices") is not None:
        if value not in meta["choices"]:
            raise ConfigError(f"{key} = {value!r} is not allowed; choose one of {list(meta['choices'])}")
        return
    expected = type(f.default)
    if expected is tuple:
        if not isinstance(value, tuple) or not all(isinstance(v, (int, float)) and not isinstance(v, bool)
                                                   and math.isfinite(v) for v in value):
            raise ConfigError(f"{key} = {value!r} must be a list of numbers, each in [{meta['low']}, {meta['high']}] {meta['unit']}")
        for item in value:
            if not meta["low"] <= item <= meta["high"]:
                raise ConfigError(f"{key} holds {item!r}, out of range; allowed [{meta['low']}, {meta['high']}] {meta['unit']}")
        return
    if expected is int and (isinstance(value, bool) or not isinstance(value, int)):
        raise ConfigError(f"{key} = {value!r} must be an integer in [{meta['low']}, {meta['high']}]")
    if expected is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{key} = {value!r} must be a number in [{meta['low']}, {meta['high']}] {meta['unit']}")
        if not math.isfinite(value):
            raise ConfigError(f"{key} = {value!r} must be finite, in [{meta['low']}, {meta['high']}] {meta['unit']}")
    low, high = meta.get("low"), meta.get("high")
    if (low is not None and value < low) or (high is not None and value > high):
        raise ConfigError(f"{key} = {value!r} is out of range; allowed [{low}, {high}] {meta['unit']}")


@dataclass(frozen=True)
class RobotConfig(_Section):
    """The loader: start pose and actuator limits."""

    _section = "robot"
    start_gap_m: float = _field(0.10, "m", "gap between the bucket tip and the pile's toe at the start", 0.0, 0.6)
    start_lift_rad: float = _field(0.23, "rad", "lift angle at the start (0.23: bucket floor level, just off the ground)",
                                   *kinematics.LIFT_RANGE_RAD)
    start_tilt_rad: float = _field(0.0, "rad", "tilt angle at the start", *kinematics.TILT_RANGE_RAD)
    start_gap_jitter_m: float = _field(0.01, "m", "largest random change of the start gap in each episode", 0.0, 0.1)
    max_speed_mps: float = _field(0.1, "m/s", "drive speed limit, forward and back", 0.01, 0.5)
    lift_speed_radps: float = _field(0.4, "rad/s", "fastest lift setpoint motion (linear actuator speed)", 0.05, 3.0)
    tilt_speed_radps: float = _field(1.0, "rad/s", "fastest tilt setpoint motion (linear actuator speed)", 0.05, 5.0)
    lift_torque_limit_nm: float = _field(150.0, "N*m", "lift actuator torque bound (a heavy pile can stall it)", 1.0, 1000.0)
    tilt_torque_limit_nm: float = _field(40.0, "N*m", "tilt actuator torque bound", 1.0, 500.0)
    wheel_torque_limit_nm: float = _field(12.0, "N*m", "torque bound of each wheel motor", 0.5, 100.0)
    ground_friction: float = _field(0.9, "-", "wheel-ground sliding friction coefficient", 0.05, 2.0)
    bucket_friction: float = _field(0.4, "-", "sliding friction between the steel bucket and a particle", 0.05, 2.0)


@dataclass(frozen=True)
class PileConfig(_Section):
    """The pile of spherical particles in front of the robot."""

    _section = "pile"
    angle_deg: float = _field(32.0, "deg", "mean slope of the pile's front face", 15.0, 60.0)
    angle_mix_deg: tuple = _field((), "deg", "if given, each pile variant takes one of these face slopes in turn "
                                  "(training on a mix of piles); empty: always angle_deg", 15.0, 60.0)
    n_particles: int = _field(72, "-", "number of particles", 1, 400)
    radius_m: float = _field(0.034, "m", "particle radius", 0.01, 0.08)
    particle_mass_kg: float = _field(0.3, "kg", "mass of one particle", 0.01, 5.0)
    friction: float = _field(1.0, "-", "sliding friction of particle contacts", 0.0, 2.0)
    rolling: bool = _field(True, "-", "particles may roll (free joints, spin damped by rolling_damping_nms); "
                           "false: they slide without turning (three slide joints each): a 1.3-1.6x faster "
                           "scene, but a stiffer pile (scripted fill 0.63 instead of 0.71) that the shipped "
                           "policy was not trained on", choices=(False, True))
    rolling_damping_nms: float = _field(0.5, "N*m*s/rad", "damping of particle spin when pile.rolling: the rolling "
                                        "resistance of angular gravel", 0.0, 10.0)
    across: int = _field(8, "-", "particles per row across the pile (y)", 1, 20)
    jitter_m: float = _field(0.003, "m", "largest random offset of a particle's start position", 0.0, 0.02)
    settle_s: float = _field(1.0, "s", "physics time a new pile settles (then on until it rests, at most 3 s more)", 0.0, 5.0)
    variants: int = _field(16, "-", "distinct jittered piles per environment, each settled once and then reused", 1, 1024)


@dataclass(frozen=True)
class RewardConfig(_Section):
    """Paper eq. 5-7: shaped distance reward plus a mass bonus at the terminal point."""

    _section = "reward"
    c_w: float = _field(10.0, "-", "weight c_w of the mass bonus c_w * w_t paid on reaching the terminal point", 0.0, 1000.0)
    epsilon_m: float = _field(0.10, "m", "tolerance epsilon: the tip within it of the terminal point is success", 0.001, 0.5)
    delta_m: float = _field(0.06, "m", "Delta: the tip within it of a particle centre is 'penetrating'", 0.001, 0.5)
    distance_scale_m: float = _field(1.0, "m", "distances are divided by it inside tanh (1 m: the paper's eq. 5)", 0.01, 10.0)
    terminal_dx_m: float = _field(0.20, "m", "terminal point x from the pile's toe (over the pile, where a scoop ends, raised clear of it)", -1.0, 1.0)
    terminal_z_m: float = _field(0.30, "m", "terminal point height above the ground", 0.0, 1.0)
    rated_load_kg: float = _field(7.0, "kg", "rated bucket load; fill factor = mass in bucket / rated load", 0.1, 100.0)


@dataclass(frozen=True)
class EnvConfig(_Section):
    """Episode timing, physics step and where the state's mass comes from."""

    _section = "env"
    control_period_s: float = _field(0.25, "s", "time between actions", 0.02, 1.0)
    max_episode_s: float = _field(8.0, "s", "episode time limit", 0.5, 60.0)
    timestep_s: float = _field(0.25 / 12, "s", "MuJoCo physics step (a divisor of the control period)", 0.0005, 0.04)
    mass_source: str = _field("truth", "-", "the state's w_t from counting particles (truth) or from the joint "
                              "torques (torque); the reward always counts",
                              choices=("truth", "torque"))
    load_cell_noise_nm: float = _field(0.2, "N*m", "std of torque noise when mass_source = torque", 0.0, 20.0)


@dataclass(frozen=True)
class ScoopConfig:
    """Everything that defines a scooping scene and task."""

    robot: RobotConfig = field(default_factory=RobotConfig)
    pile: PileConfig = field(default_factory=PileConfig)
    reward: RewardConfig = field(default_factory=RewardConfig)
    env: EnvConfig = field(default_factory=EnvConfig)

    def __post_init__(self) -> None:
        steps = self.env.max_episode_s / self.env.control_period_s
        if self.env.control_period_s < self.env.timestep_s:
            raise ConfigError(f"env.control_period_s = {self.env.control_period_s} must be at least "
                              f"env.timestep_s = {self.env.timestep_s}")
        if steps < 1:
            raise ConfigError("env.max_episode_s must be at least one env.control_period_s")

    @property
    def max_episode_steps(self) -> int:
        """Number of actions in one episode before the time limit."""
        return int(round(self.env.max_episode_s / self.env.control_period_s))

    @property
    def substeps(self) -> int:
        """Physics steps per control period."""
        return max(1, int(round(self.env.control_period_s / self.env.timestep_s)))

    def to_dict(self) -> dict[str, dict[str, Any]]:
        """Plain nested dict, as written to YAML (tuples as lists)."""
        def plain(value: Any) -> Any:
            return list(value) if isinstance(value, tuple) else value
        return {name: {f.name: plain(getattr(getattr(self, name), f.name)) for f in dataclasses.fields(getattr(self, name))}
                for name in SECTIONS}

    def with_overrides(self, overrides: Mapping[str, Any]) -> "ScoopConfig":
        """A copy with dotted keys replaced, e.g. ``{"pile.angle_deg": 28}``; string values are parsed as YAML."""
        sections = {name: dict(values) for name, values in self.to_dict().items()}
        for key, value in overrides.items():
            section, _, name = str(key).partition(".")
            if section not in SECTIONS or name not in sections[section]:
                raise ConfigError(f"unknown config key {key!r}; known keys: {', '.join(all_keys())}")
            if isinstance(value, str):
                value = _parse_scalar(value)
            default = sections[section][name]
            if isinstance(default, float) and isinstance(value, int) and not isinstance(value, bool):
                value = float(value)
            sections[section][name] = value
        return from_dict(sections)

    def describe(self) -> str:
        """Table of every key with its value, unit and range."""
        rows = []
        for section, cls in SECTIONS.items():
            for f in dataclasses.fields(cls):
                meta = f.metadata
                allowed = (f"{list(meta['choices'])}" if meta["choices"] else f"[{meta['low']}, {meta['high']}]")
                rows.append(f"{section}.{f.name:<24} {getattr(getattr(self, section), f.name)!s:<10} "
                            f"{meta['unit']:<6} {allowed:<16} {meta['doc']}")
        return "\n".join(rows)


SECTIONS = {"robot": RobotConfig, "pile": PileConfig, "reward": RewardConfig, "env": EnvConfig}


def all_keys() -> list[str]:
    """Every dotted key a config accepts."""
    return [f"{s}.{f.name}" for s, cls in SECTIONS.items() for f in dataclasses.fields(cls)]


def _parse_scalar(text: str) -> Any:
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


def from_dict(data: Mapping[str, Any]) -> ScoopConfig:
    """Build a validated config from a nested dict (missing keys take defaults)."""
    unknown = set(data) - set(SECTIONS)
    if unknown:
        raise ConfigError(f"unknown config section(s) {sorted(unknown)}; known: {list(SECTIONS)}")
    parts = {}
    for section, cls in SECTIONS.items():
        values = dict(data.get(section) or {})
        names = {f.name for f in dataclasses.fields(cls)}
        bad = set(values) - names
        if bad:
            raise ConfigError(f"unknown config key(s) {sorted(f'{section}.{b}' for b in bad)}; known keys: {', '.join(all_keys())}")
        for f in dataclasses.fields(cls):
            if f.name in values and isinstance(f.default, float) and isinstance(values[f.name], int) \
                    and not isinstance(values[f.name], bool):
                values[f.name] = float(values[f.name])
            if f.name in values and isinstance(f.default, tuple) and isinstance(values[f.name], (list, tuple)):
                values[f.name] = tuple(float(v) if isinstance(v, int) and not isinstance(v, bool) else v
                                       for v in values[f.name])
        parts[section] = cls(**values)
    return ScoopConfig(**parts)


def overrides_from_yaml(path: str | Path) -> dict[str, Any]:
    """The keys a YAML file sets, as dotted keys (nested sections or dotted keys at the top level)."""
    data = yaml.safe_load(Path(path).read_text()) or {}
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: expected a mapping of sections, got {type(data).__name__}")
    out: dict[str, Any] = {}
    for key, value in data.items():
        if "." in str(key):
            out[str(key)] = value
        elif isinstance(value, dict):
            out.update({f"{key}.{name}": item for name, item in value.items()})
        else:
            raise ConfigError(f"{path}: section {key!r} must be a mapping of keys; known sections: {list(SECTIONS)}")
    return out


def load_yaml(path: str | Path) -> ScoopConfig:
    """Read a config from YAML: the defaults with the file's keys applied (validated)."""
    return ScoopConfig().with_overrides(overrides_from_yaml(path))


def save_yaml(config: ScoopConfig, path: str | Path) -> None:
    """Write a config as nested YAML."""
    Path(path).write_text(yaml.safe_dump(config.to_dict(), sort_keys=False))


def parse_set_args(pairs: list[str] | None) -> dict[str, Any]:
    """``["pile.angle_deg=28", ...]`` -> ``{"pile.angle_deg": "28", ...}`` (values parsed later)."""
    out: dict[str, Any] = {}
    for pair in pairs or []:
        key, sep, value = pair.partition("=")
        if not sep or not key:
            raise ConfigError(f"--set expects key=value, got {pair!r}")
        out[key.strip()] = value.strip()
    return out
