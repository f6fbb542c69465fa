"""The sensor link between the robot's sensors and its controller: transport delay and Gaussian noise.

One implementation for every place readings are produced: the environment (``sensor.*`` config
keys, applied to the policy's state) and ``autoscoop ros sim`` (applied to the messages it
publishes; its ``--delay-s`` / ``--*-noise-*`` options are the same keys). The reward and the
metrics always use true values.

Noise is drawn in a fixed order per set of readings (lift angle, tilt angle, speed, range, tilt
torque, lift torque), one draw per noisy reading and none for a noise of zero, so a link without
noise consumes no random numbers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from autoscoop.core.config import SensorConfig


@dataclass(frozen=True)
class SensorNoise:
    """Standard deviations of the Gaussian noise on each reading.

    Attributes:
        joint_rad: on each joint angle (lift, tilt), rad.
        speed_mps: on the odometry speed, m/s.
        range_m: on the range from the bucket tip to the pile, m (the result is kept >= 0).
        torque_nm: on each joint torque sample (bucket and lift), N*m.
    """

    joint_rad: float = 0.0
    speed_mps: float = 0.0
    range_m: float = 0.0
    torque_nm: float = 0.0

    def __post_init__(self) -> None:
        for name in ("joint_rad", "speed_mps", "range_m", "torque_nm"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and 0.0 <= value <= 10.0):
                raise ValueError(f"noise {name} = {value} must be a finite number in [0, 10]")

    @classmethod
    def from_config(cls, sensor: SensorConfig) -> SensorNoise:
        """The noise of a ``sensor`` config section."""
        return cls(joint_rad=sensor.joint_noise_rad, speed_mps=sensor.speed_noise_mps,
                   range_m=sensor.range_noise_m, torque_nm=sensor.torque_noise_nm)

    @property
    def silent(self) -> bool:
        """Whether every reading is exact."""
        return not (self.joint_rad or self.speed_mps or self.range_m or self.torque_nm)


@dataclass(frozen=True)
class RawReadings:
    """One set of raw readings, before or after the link's noise.

    Attributes:
        lift_rad: lift angle, rad (positive lowers the arm).
        tilt_rad: tilt angle, rad (positive tips the cutting edge down).
        speed_mps: forward speed from wheel odometry, m/s.
        range_m: distance from the bucket tip to the pile, m (NaN when unknown).
        tilt_torque_nm: torque at the tilt (bucket) joint, N*m.
        lift_torque_nm: torque at the lift joint, N*m.
    """

    lift_rad: float
    tilt_rad: float
    speed_mps: float
    range_m: float
    tilt_torque_nm: float
    lift_torque_nm: float


def _draw(rng: np.random.Generator, std: float) -> float:
    return float(rng.normal(0.0, std)) if std else 0.0


def add_noise(readings: RawReadings, noise: SensorNoise, rng: np.random.Generator,
              torque_samples: int = 1) -> RawReadings:
    """The readings as the controller gets them: each plus Gaussian noise of the link's std.

    Args:
        readings: the true readings.
        noise: the link's noise.
        rng: the noise source (nothing is drawn for a noise of zero).
        torque_samples: how many torque samples ``readings`` averages (the environment's load cell
            averages a control period of physics steps): the torque noise's std is divided by its
            square root, as averaging that many independently noisy samples would give.

    Returns:
        New readings; the range stays >= 0 and a NaN range stays NaN.
    """
    torque_std = noise.torque_nm / math.sqrt(max(1, int(torque_samples)))
    lift = readings.lift_rad + _draw(rng, noise.joint_rad)
    tilt = readings.tilt_rad + _draw(rng, noise.joint_rad)
    speed = readings.speed_mps + _draw(rng, noise.speed_mps)
    distance = readings.range_m
    if noise.range_m and math.isfinite(distance):
        distance = max(0.0, distance + _draw(rng, noise.range_m))
    return replace(readings, lift_rad=lift, tilt_rad=tilt, speed_mps=speed, range_m=distance,
                   tilt_torque_nm=readings.tilt_torque_nm + _draw(rng, torque_std),
                   lift_torque_nm=readings.lift_torque_nm + _draw(rng, torque_std))


def delay_steps(delay_s: float, timestep_s: float) -> int:
    """A transport delay in whole physics steps: ``delay_s`` honoured to the step (rounded to the nearest).

    Raises:
        ValueError: a negative or non-finite delay, or a step that is not positive.
    """
    if not (math.isfinite(delay_s) and delay_s >= 0.0):
        raise ValueError(f"sensor delay must be a finite number of seconds >= 0, got {delay_s}")
    if not (math.isfinite(timestep_s) and timestep_s > 0.0):
        raise ValueError(f"physics step must be a positive number of seconds, got {timestep_s}")
    return int(round(delay_s / timestep_s + 1e-9))
